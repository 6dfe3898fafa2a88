"""Misuse of the design check, the run files and the other commands (no traceback, no memory blow-up,
no file outside the output folder): each case gives one line and exit 2 (or works, documented), leaves nothing
behind, and the run files are fuzzed."""

import errno
import json
import os
import random
import resource
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import hcmt.inference.rollout_files as rollout_files_module
from conftest import IMPACT_DATA
from hcmt.cli import main as cli
from hcmt.data.runs import PRETRAINED_DIR
from hcmt.design.inputs import design_for, range_warnings, read_designs_csv
from hcmt.errors import RolloutError
from hcmt.inference import run as run_module
from hcmt.inference.run import Run
from hcmt.sim.cost import estimate
from hcmt.sim.params import Design
from hcmt.sim.sampling import middle_design
from hcmt.sim.scene import design_mesh
from hcmt.training import train
from hcmt.viz.meshplot import new_figure, save_figure
from layouts import sphere_simple_tfrecord

pytestmark = pytest.mark.slow  # trained runs, subprocesses under memory limits

FRAMES = IMPACT_DATA["frames"]
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def setup(tmp_path_factory, tiny_config, impact_data):
    """The test run's dataset (conftest; a copy this module may damage) and a 2-step HCMT run with checkpoint.pt,
    best.pt (validation at step 2) and data.json."""
    root = tmp_path_factory.mktemp("misuse")
    shutil.copytree(impact_data, root / "data")
    train(
        tiny_config("train.steps=2", "train.checkpoint_every=1", "train.valid_every=2", "train.valid_trajectories=1"),
        root / "data",
        "hcmt",
        root / "run",
        progress=False,
    )
    assert (root / "run" / "best.pt").is_file() and (root / "run" / "checkpoint.pt").is_file()
    return root


def one_line(capsys, rc) -> str:
    err = [
        line
        for line in capsys.readouterr().err.strip().splitlines()
        if ": warning: " not in line and ": note: " not in line
    ]
    assert rc == 2 and len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


def run_capped(argv: list[str], gib: float = 6.0, seconds: float = 120.0) -> subprocess.CompletedProcess:
    """``hcmt ARGV`` in a child process whose address space is capped (a blow-up fails there, not here)."""
    limit = int(gib * 2**30)

    def cap():
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    return subprocess.run(
        [sys.executable, "-m", "hcmt", *argv], capture_output=True, text=True, timeout=seconds, preexec_fn=cap, cwd=ROOT
    )


# -- 1. memory: the cost estimate comes from the design's numbers -------------------------------------------------
def test_the_estimate_needs_no_mesh_and_matches_it():
    d = Design(thickness=0.8, mesh_size=0.3, ball_radius=3.8, plate_half_length=12.0)
    e = estimate(d)
    assert abs(e["num_nodes"] - len(design_mesh(d)["mesh_pos"])) < 0.05 * e["num_nodes"]
    huge = estimate(Design(thickness=1e308, plate_half_length=1e308))
    assert huge["num_nodes"] == float("inf")  # a float estimate, not an OverflowError


@pytest.mark.parametrize(
    "argv",
    [
        ["predict", "pretrained:impact_plate_small", "--design", "mesh_size=1e-4", "--no-progress"],
        ["predict", "pretrained:impact_plate_small", "--design", "plate_half_length=1e308", "--no-progress"],
        ["predict", "pretrained:impact_plate_small", "--design", "thickness=1e308", "--no-progress"],
        ["simulate", "--mesh-size", "1e-4", "--no-progress"],
        ["simulate", "--thickness", "1e308", "--no-progress"],
    ],
)
def test_a_huge_design_is_refused_before_any_array(argv):
    t0 = time.perf_counter()
    r = run_capped(argv)
    err = [line for line in r.stderr.strip().splitlines() if ": warning: " not in line]
    assert r.returncode == 2 and len(err) == 1 and "Traceback" not in r.stderr, r.stderr
    assert "nodes" in err[0] and time.perf_counter() - t0 < 60


def test_a_huge_design_in_a_csv_is_refused_naming_it(setup, tmp_path, capsys):
    path = tmp_path / "d.csv"
    path.write_text("name,thickness\nok,0.8\nhuge,1e308\n")
    msg = one_line(capsys, cli(["predict", str(setup / "run"), "--designs", str(path), "--no-progress"]))
    assert "huge" in msg and "nodes" in msg


# -- 2. names that would escape --out ------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "name,message",
    [
        ("../../escaped", "outside its own folder"),
        ("a/b", "outside its own"),
        ("..", "outside its own"),
        ("", "is empty"),
        ("tab\tname", "control"),
        ("/abs", "outside its own"),
    ],
)
def test_a_design_name_that_is_a_path_is_refused(setup, tmp_path, capsys, name, message):
    path = tmp_path / "d.csv"
    path.write_text(f"name,thickness\n{name},0.8\n")
    msg = one_line(
        capsys,
        cli(
            [
                "predict",
                str(setup / "run"),
                "--designs",
                str(path),
                "--images",
                "--out",
                str(tmp_path / "imgs"),
                "--no-progress",
            ]
        ),
    )
    assert str(path) in msg and "line 2" in msg and message in msg
    assert not (tmp_path / "imgs").exists() and not (tmp_path.parent / "escaped").exists()


def test_duplicate_names_are_refused(setup, tmp_path, capsys):
    path = tmp_path / "d.csv"
    path.write_text("name,thickness\na,0.8\nb,0.7\na,0.9\n")
    msg = one_line(capsys, cli(["predict", str(setup / "run"), "--designs", str(path), "--no-progress"]))
    assert "line 4" in msg and "already names line 2" in msg


# -- 3. damaged run files ------------------------------------------------------------------------------------------
DAMAGE = {
    "truncated": lambda b: b[: len(b) // 3],
    "random bytes": lambda b: bytes(random.Random(0).randrange(256) for _ in range(2000)),
    "empty": lambda b: b"",
}


def commands(run: Path, data: Path, out: Path) -> dict[str, list[str]]:
    return {
        "predict": ["predict", str(run), "--design", "thickness=0.7", "--no-progress"],
        "rollout": ["rollout", str(run), "--data", str(data), "--split", "test", "--no-progress"],
        "evaluate": ["evaluate", str(run), "--data", str(data), "--split", "test", "--no-progress"],
        "export": [
            "export",
            str(run),
            "--data",
            str(data),
            "--split",
            "test",
            "--out",
            str(out / "vtu"),
            "--no-progress",
        ],
        "plot": [
            "plot",
            str(run),
            "--data",
            str(data),
            "--split",
            "test",
            "--only",
            "contours",
            "--out",
            str(out / "pic"),
            "--no-progress",
        ],
    }


@pytest.mark.parametrize("kind", sorted(DAMAGE))
def test_a_damaged_checkpoint_is_one_line_naming_it_and_the_other(setup, tmp_path, capsys, kind):
    run = tmp_path / "run"
    shutil.copytree(setup / "run", run)
    (run / "best.pt").write_bytes(DAMAGE[kind]((run / "best.pt").read_bytes()))
    for name, argv in commands(run, setup / "data", tmp_path).items():
        msg = one_line(capsys, cli(argv))
        assert str(run / "best.pt") in msg and "checkpoint.pt" in msg, (name, msg)  # the intact one is named
    # the latest checkpoint damaged: --resume names it and the best one
    shutil.copy(setup / "run" / "best.pt", run / "best.pt")
    (run / "checkpoint.pt").write_bytes(DAMAGE[kind]((run / "checkpoint.pt").read_bytes()))
    msg = one_line(capsys, cli(["train", "--resume", "--out", str(run), "--steps", "3", "--no-progress"]))
    assert str(run / "checkpoint.pt") in msg and "best.pt" in msg


@pytest.mark.parametrize("text", ["", "model: [1, 2\n", "x: 1\n", "- a\n- b\n", "\x00\x01binary"])
def test_a_damaged_run_yaml_is_one_line(setup, tmp_path, capsys, text):
    run = tmp_path / "run"
    shutil.copytree(setup / "run", run)
    (run / "run.yaml").write_text(text)
    for name, argv in commands(run, setup / "data", tmp_path).items():
        msg = one_line(capsys, cli(argv))
        assert "run.yaml" in msg, (name, msg)
    msg = one_line(capsys, cli(["train", "--resume", "--out", str(run), "--steps", "3", "--no-progress"]))
    assert "run.yaml" in msg


def test_resuming_a_run_yaml_without_its_config_is_one_line(setup, tmp_path, capsys):
    run = tmp_path / "run"
    shutil.copytree(setup / "run", run)
    (run / "run.yaml").write_text("model: {name: hcmt}\n")
    msg = one_line(capsys, cli(["train", "--resume", "--out", str(run), "--steps", "3", "--no-progress"]))
    assert "run.yaml: no config section" in msg


def test_fuzz_run_files(setup, tmp_path, capsys):
    """Byte flips and cuts of run.yaml, checkpoint.pt, best.pt and data.json, and of a shipped model file: every
    case runs (exit 0) or is one line (exit 2), never a traceback."""
    rng = random.Random(1)
    cases = 0
    for file in ("run.yaml", "checkpoint.pt", "best.pt", "data.json"):
        original = (setup / "run" / file).read_bytes()
        for k in range(8):
            run = tmp_path / f"{file}_{k}"
            shutil.copytree(setup / "run", run)
            (run / file).write_bytes(damaged(original, rng, flips=6 if k < 5 else 0))
            if file == "data.json":
                shutil.move(str(setup / "data"), str(tmp_path / "away"))  # read only when the dataset is gone
            try:
                rc = cli(["predict", str(run), "--design", "thickness=0.7", "--no-progress"])
            finally:
                if file == "data.json":
                    shutil.move(str(tmp_path / "away"), str(setup / "data"))
            err = capsys.readouterr().err
            assert rc in (0, 2) and "Traceback" not in err, (file, k, err)
            if rc == 2:
                assert (
                    len([l for l in err.strip().splitlines() if ": warning: " not in l and ": note: " not in l]) == 1
                ), err
            cases += 1
            shutil.rmtree(run)
    assert cases == 32


def damaged(original: bytes, rng: random.Random, flips: int) -> bytes:
    """1..``flips`` random bytes changed, or (``flips`` 0) the file cut at a random length."""
    if not flips:
        return original[: rng.randrange(len(original))]
    b = bytearray(original)
    for _ in range(rng.randint(1, flips)):
        b[rng.randrange(len(b))] = rng.randrange(256)
    return bytes(b)


def test_fuzz_a_shipped_model_file(tmp_path, monkeypatch, capsys):
    original = (PRETRAINED_DIR / "impact_plate_small.pt").read_bytes()
    rng = random.Random(2)
    for k in range(6):
        path = tmp_path / "impact_plate_small.pt"
        path.write_bytes(damaged(original, rng, flips=4 if k < 4 else 0))
        monkeypatch.setattr(run_module, "available_pretrained", lambda: {"impact_plate_small": path})
        rc = cli(
            ["predict", "pretrained:impact_plate_small", "--design", "thickness=0.7", "--no-surrogate", "--no-progress"]
        )
        err = capsys.readouterr().err
        assert rc in (0, 2) and "Traceback" not in err, err


# -- 4. the solver's warnings travel with --verify -----------------------------------------------------------------
def test_verify_carries_the_solvers_warnings(setup, tmp_path, capsys):
    out = tmp_path / "v.json"
    assert (
        cli(
            [
                "predict",
                str(setup / "run"),
                "--design",
                "plate_poisson=0.47",
                "--verify",
                "--json",
                str(out),
                "--no-progress",
            ]
        )
        == 0
    )
    printed = capsys.readouterr().out
    d = json.loads(out.read_text())["designs"][0]
    assert any("validated" in w for w in d["verify"]["solver_warnings"])
    assert "solver warning: design_1: plate_poisson" in printed


# -- 5, 6. outputs checked before the first is written ------------------------------------------------------------
@pytest.mark.parametrize(
    "extra,message",
    [
        (["--json", "{dir}", "--csv", "{tmp}/t.csv"], "is a folder"),
        (["--json", "{tmp}/x", "--csv", "{tmp}/x"], "the same path as --json"),
        (["--csv", ""], "an empty path"),
        (["--images", "--out", "{tmp}/file.txt"], "is a file; name a folder"),
    ],
)
def test_outputs_are_checked_before_any_is_written(setup, tmp_path, capsys, extra, message):
    (tmp_path / "a_dir").mkdir()
    (tmp_path / "file.txt").write_text("x")
    argv = [a.format(dir=tmp_path / "a_dir", tmp=tmp_path) for a in extra]
    msg = one_line(capsys, cli(["predict", str(setup / "run"), "--design", "thickness=0.7", *argv, "--no-progress"]))
    assert message in msg
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_dir", "file.txt"]  # nothing written


def test_a_picture_on_a_full_disk_leaves_nothing_and_names_the_path(tmp_path, monkeypatch):
    fig = new_figure(2, 2)

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(args[0]))

    monkeypatch.setattr(fig, "savefig", full)
    target = tmp_path / "pics" / "p.png"
    with pytest.raises(OSError) as info:
        save_figure(fig, target)
    assert info.value.filename == str(target) and not any(tmp_path.rglob("*.png*"))
    assert not any(p.is_file() for p in tmp_path.rglob("*"))


def test_plot_refused_for_bad_options_leaves_no_folder(setup, tmp_path, capsys):
    for extra in (["--cmap", "nosuchmap"], ["--frames", "0,999"], ["--frames", "x"]):
        out = tmp_path / "pics"
        msg = one_line(
            capsys,
            cli(
                [
                    "plot",
                    str(setup / "run"),
                    "--data",
                    str(setup / "data"),
                    "--split",
                    "test",
                    "--only",
                    "contours",
                    "--out",
                    str(out),
                    "--no-progress",
                    *extra,
                ]
            ),
        )
        assert not out.exists(), (extra, msg)


# -- 7. threads ---------------------------------------------------------------------------------------------------
def test_threads_above_the_cores_are_refused(capsys):
    """One rule for every count option (hcmt.cli.parsers): above its bound, one line; --threads no longer caps."""
    rc = cli(["predict", "pretrained:impact_plate_small", "--design", "thickness=0.7", "--threads", "1000"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1
    assert f"--threads: expected a whole number from 1 to {len(os.sched_getaffinity(0))}" in err[0]


# -- 8, 9. defaults and a self-contained run folder ----------------------------------------------------------------
def test_defaults_are_the_middle_of_the_models_training_ranges(setup):
    run = Run.load(setup / "run", "cpu")
    d = design_for(run)
    lo, hi = run.ranges["thickness"]
    assert d.thickness == pytest.approx(0.5 * (lo + hi)) and range_warnings(d, run.ranges) == []


def test_a_run_folder_predicts_without_its_dataset(setup, tmp_path, capsys):
    data, run = tmp_path / "data", tmp_path / "run"
    shutil.copytree(setup / "data", data)
    train(Run.load(setup / "run", "cpu").config, data, "hcmt", run, progress=False, overwrite=True)
    shutil.rmtree(data)
    assert (run / "data.json").is_file()
    assert cli(["predict", str(run), "--design", "thickness=0.7", "--no-progress"]) == 0
    (run / "data.json").unlink()
    msg = one_line(capsys, cli(["predict", str(run), "--design", "thickness=0.7", "--no-progress"]))
    assert "not an hcmt-generated" not in msg and "data.json" in msg


# -- 10. silent acceptance ----------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "argv,message",
    [
        (["predict", "{run}", "--design", "thickness=0.7", "thickness=0.8"], "thickness is given twice"),
        (["sweep", "{run}", "--vary", "thickness=0.6:0.8:2", "--design", "thickness=0.7"], "the swept parameter"),
        (
            ["sweep", "{run}", "--vary", "thickness=0.6:0.8:2", "--batch", "0"],
            "argument --batch: expected a whole number",
        ),
        (["hierarchy", "{data}", "--levels", "1", "--trajectories", "-1"], "argument --trajectories: expected a whole"),
        (["predict", "{run}", "--design", "thickness=0.7", "--csv", ""], "--csv: an empty path"),
        (
            ["rollout", "{run}", "--data", "{data}", "--split", "test", "--limit", "0"],
            "argument --limit: expected a whole",
        ),
        (["predict", "impact_plate_small", "--design", "thickness=0.7"], "pretrained:impact_plate_small"),
        (
            ["simulate", "--out", "{tmp}/x.txt", "--mesh-size", "0.5", "--thickness", "0.6", "--ball-radius", "3"],
            "--out must name an .h5 file",
        ),
        (["predict", "{run}", "--design", "thickness=0.7", "--verify", "auto"], "--yield-mpa"),
    ],
)
def test_silent_acceptance_is_refused(setup, tmp_path, capsys, monkeypatch, argv, message):
    monkeypatch.chdir(tmp_path)
    t0 = time.perf_counter()
    argv = [a.format(run=setup / "run", data=setup / "data", tmp=tmp_path) for a in argv]
    msg = one_line(capsys, cli([*argv, "--no-progress"]))
    assert message in msg and time.perf_counter() - t0 < 30
    assert not (tmp_path / "x.txt").exists()


def test_design_before_the_model_and_design_with_designs(setup, tmp_path, capsys):
    out = tmp_path / "p.json"
    path = tmp_path / "d.csv"
    path.write_text("name,thickness\nc,0.9\n")
    assert (
        cli(
            [
                "predict",
                "--design",
                "thickness=0.7",
                str(setup / "run"),
                "--designs",
                str(path),
                "--json",
                str(out),
                "--no-progress",
            ]
        )
        == 0
    )
    assert [d["name"] for d in json.loads(out.read_text())["designs"]] == ["design_1", "c"]  # merged, --design first


def test_an_empty_tfrecord_is_refused(tmp_path, capsys):
    src = tmp_path / "src"
    sphere_simple_tfrecord(src)
    (src / "test.tfrecord").write_bytes(b"")
    msg = one_line(capsys, cli(["convert", str(src), str(tmp_path / "out")]))
    assert "test.tfrecord" in msg and "empty" in msg
    (src / "meta.json").unlink()
    msg = one_line(capsys, cli(["convert", str(src), str(tmp_path / "out2")]))
    assert "no meta.json" in msg


# -- 12. messages ---------------------------------------------------------------------------------------------------
def test_messages_that_said_the_wrong_thing(setup, tmp_path, capsys):
    data = tmp_path / "partial"
    data.mkdir()
    shutil.copy(setup / "data" / "meta.json", data / "meta.json")
    (data / ".parts").mkdir()
    msg = one_line(capsys, cli(["evaluate", str(setup / "run"), "--data", str(data), "--split", "test"]))
    assert "incomplete dataset" in msg and ".parts" in msg
    seed = IMPACT_DATA["seed"]
    msg = one_line(
        capsys,
        cli(
            [
                "generate",
                "impact-plate",
                str(setup / "data"),
                "--preset",
                "small",
                "--train",
                "2",
                "--valid",
                "1",
                "--test",
                "1",
                "--seed",
                str(seed + 1),
                "--frames",
                str(FRAMES),
            ]
        ),
    )
    assert f"seed {seed} there, {seed + 1} asked" in msg


def test_a_closed_pipe_is_not_an_error():
    r = subprocess.run(
        f"{sys.executable} -m hcmt models --json | head -3",
        shell=True,
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
    )
    assert r.stdout.count("\n") == 3 and "error" not in r.stderr.lower() and "Traceback" not in r.stderr


def test_sigterm_during_predict_says_what_happened():
    p = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "hcmt",
            "predict",
            "pretrained:impact_plate_small",
            "--design",
            "thickness=0.7",
            "--verify",
            "--no-progress",
        ],
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )
    time.sleep(6)  # starting (imports) or rolling out: either way one line
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 143 and "interrupted" in err and "Traceback" not in err, err  # 128 + SIGTERM


def test_sigterm_while_starting_exits_143():
    """SIGTERM during the imports (a busy machine: seconds): one line and 128 + 15, not a signal death at exit
    (KeyboardInterrupt raised inside an import re-raised at interpreter exit: exit -2 before)."""
    p = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "hcmt",
            "predict",
            "pretrained:impact_plate_small",
            "--design",
            "thickness=0.7",
            "--no-progress",
        ],
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )
    time.sleep(0.5)
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 143 and "interrupted (SIGTERM)" in err and "Traceback" not in err, err


# -- 13. progress and flags -----------------------------------------------------------------------------------------
def test_every_computing_command_takes_threads_and_no_progress(setup, capsys):
    assert cli(["info", str(setup / "data"), "--threads", "1", "--no-progress"]) == 0
    assert cli(["compare", str(setup / "run"), "--threads", "1", "--no-progress"]) in (0, 2)
    capsys.readouterr()
    assert cli(["models"]) == 0
    assert "mm " in capsys.readouterr().out  # units
    assert {"/predict_out/", "/sweep_out/"} <= set((ROOT / ".gitignore").read_text().split())


def test_one_is_singular(setup, capsys):
    assert cli(["predict", str(setup / "run"), "--design", "thickness=0.7", "--verify", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "1 design," in out and "1 trajectory" in out and "1 trajectories" not in out and "1 predictions" not in out


def test_verify_shows_the_solvers_progress(setup, capsys):
    assert cli(["predict", str(setup / "run"), "--design", "thickness=0.7", "--verify"]) == 0
    assert "solver" in capsys.readouterr().err


def test_fuzz_designs_csv_bytes(setup, tmp_path, capsys):
    """Byte flips, cuts and path-like names in a designs CSV: read_designs_csv returns safe, distinct names or
    raises a one-line ValueError naming the file; a few cases go through `hcmt predict --images` end to end."""
    run = Run.load(setup / "run", "cpu")
    defaults = middle_design(run.meta, run.ranges)
    good = b"name,thickness,drop_height\nalpha,0.7,800\nbeta,0.9,600\n"
    rng = random.Random(3)
    path, cases = tmp_path / "d.csv", 0
    for k in range(240):
        b = bytearray(good)
        kind = k % 4
        if kind == 0:
            for _ in range(rng.randint(1, 4)):
                b[rng.randrange(len(b))] = rng.randrange(256)
        elif kind == 1:
            b = b[: rng.randrange(len(b))]
        elif kind == 2:
            name = rng.choice(["../up", "a/b", "..", ".", "x\\y", "", "beta", "c\x07", "/abs", "ok name"])
            b = bytearray(good.replace(b"alpha", name.encode()))
        else:
            b.insert(rng.randrange(len(b)), rng.choice(b',\n"/\\.\x00'))
        path.write_bytes(bytes(b))
        try:
            designs = read_designs_csv(path, defaults)
        except ValueError as exc:
            assert str(path) in str(exc) and "\n" not in str(exc)
        else:
            names = [n for n, _ in designs]
            assert len(set(names)) == len(names)
            assert all(n and "/" not in n and "\\" not in n and n not in (".", "..") for n in names)
        cases += 1
    assert cases == 240
    for name in ("../../escaped", "a/b"):
        path.write_text(f"name,thickness\n{name},0.8\n")
        assert (
            cli(
                [
                    "predict",
                    str(setup / "run"),
                    "--designs",
                    str(path),
                    "--images",
                    "--out",
                    str(tmp_path / "img"),
                    "--no-progress",
                ]
            )
            == 2
        )
    capsys.readouterr()
    assert not (tmp_path / "img").exists()


def test_the_model_after_verify_and_names_across_design_and_designs(setup, tmp_path, capsys):
    out = tmp_path / "p.json"
    assert (
        cli(
            [
                "predict",
                "--design",
                "thickness=0.8",
                "--verify",
                str(setup / "run"),
                "--json",
                str(out),
                "--no-progress",
            ]
        )
        == 0
    )
    assert "verify" in json.loads(out.read_text())["designs"][0]
    msg = one_line(capsys, cli(["predict", str(setup / "run"), "--verify", "sometimes", "--design", "thickness=0.8"]))
    assert "--verify 'sometimes'" in msg
    path = tmp_path / "d.csv"
    path.write_text("thickness\n0.9\n")  # unnamed rows continue the --design numbering
    assert (
        cli(
            [
                "predict",
                str(setup / "run"),
                "--design",
                "thickness=0.7",
                "--designs",
                str(path),
                "--json",
                str(out),
                "--no-progress",
            ]
        )
        == 0
    )
    assert [d["name"] for d in json.loads(out.read_text())["designs"]] == ["design_1", "design_2"]
    path.write_text("name,thickness\ndesign_1,0.9\n")
    msg = one_line(
        capsys,
        cli(["predict", str(setup / "run"), "--design", "thickness=0.7", "--designs", str(path), "--no-progress"]),
    )
    assert "'design_1' already names --design" in msg


# -- damaged files that the change to tracebacks-for-bugs must keep one line ----------------------------------------
def test_damaged_json_and_log_files_of_a_run_are_one_line(setup, tmp_path, capsys):
    run = tmp_path / "run"
    shutil.copytree(setup / "run", run)
    data = setup / "data"
    (run / "train_stats.json").write_text("garbage{")
    msg = one_line(capsys, cli(["evaluate", str(run), "--data", str(data), "--no-progress"]))
    assert "train_stats.json: damaged, not readable JSON" in msg and "hcmt train" in msg
    (run / "train_stats.json").unlink()
    assert cli(["evaluate", str(run), "--data", str(data), "--no-progress"]) == 0
    capsys.readouterr()
    (run / "metrics_test.json").write_bytes(b'{"broken\xff')
    msg = one_line(capsys, cli(["compare", str(run)]))
    assert "metrics_test.json: damaged" in msg and "hcmt evaluate" in msg
    log = run / "log.jsonl"
    log.write_text(log.read_text() + '{"step": 2, "loss"\n')  # a line cut short
    msg = one_line(capsys, cli(["train", "--resume", "--out", str(run), "--steps", "3", "--no-progress"]))
    assert "log.jsonl, line" in msg and "not a log record" in msg


def test_a_binary_meta_json_or_config_and_a_bad_set_value_are_one_line(setup, tmp_path, capsys):
    data = tmp_path / "data"
    shutil.copytree(setup / "data", data)
    (data / "meta.json").write_bytes(b"\xff\xfe\x00binary")
    msg = one_line(capsys, cli(["info", str(data)]))
    assert "meta.json" in msg and "not valid JSON" in msg
    cfg = tmp_path / "bin.yaml"
    cfg.write_bytes(b"\xff\xfe\x00binary")
    base = ["train", "--data", str(setup / "data"), "--model", "mgn", "--out", str(tmp_path / "r"), "--no-progress"]
    msg = one_line(capsys, cli(base + ["--config", str(cfg)]))
    assert "bin.yaml" in msg and "not a text file" in msg
    msg = one_line(capsys, cli(base + ["--config", "impact_plate_cpu", "--set", "train.lrr=1"]))
    assert "train.lrr: unknown key; did you mean train.lr?" in msg
    msg = one_line(capsys, cli(base + ["--config", "impact_plate_cpu", "--set", "train.lr=[1"]))
    assert "--set 'train.lr=[1': the value '[1' is not a YAML value" in msg
    assert not (tmp_path / "r").exists()


def test_a_diverging_rollout_is_one_line(setup, tmp_path, capsys, monkeypatch):
    """A model that diverges on an input is no bug of hcmt's: one line naming the trajectory and step."""

    def diverge(*args, **kwargs):
        raise RolloutError(
            "trajectory traj_00000: the predicted state became non-finite at step 3 (frame 3 of 8); the model diverged"
        )

    monkeypatch.setattr(rollout_files_module, "rollout_batch", diverge)
    msg = one_line(capsys, cli(["rollout", str(setup / "run"), "--data", str(setup / "data"), "--no-progress"]))
    assert "traj_00000" in msg and "non-finite at step 3" in msg
