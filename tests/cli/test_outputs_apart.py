"""Bad input, round 3: no command writes over one of its inputs or into a folder it reads, however
the path is spelled (hcmt.files.check_apart); a refused resume changes nothing; generate has the cost rule of
simulate; a damaged checkpoint's advice names the other only when that one is readable; a failed predict leaves
none of its outputs."""

import errno
import hashlib
import os
import shutil
from pathlib import Path

import pytest

import hcmt.cli.design as design_cli
from hcmt.cli import main as cli
from hcmt.errors import InputError
from hcmt.files import check_apart, undo_on_error
from hcmt.sim.generate import generate_dataset
from hcmt.sim.params import Settings
from hcmt.training import train

SPELLINGS = ("same", "relative", "dotdot", "symlink")


def spell(path: Path, how: str, cwd: Path) -> str:
    """``path`` as a user might write it: as is, relative to ``cwd``, through ``..``, or through a symlink."""
    path = Path(path).resolve()
    if how == "same":
        return str(path)
    if how == "relative":
        return os.path.relpath(path, cwd)
    if how == "dotdot":
        return str(path.parent / ".." / path.parent.name / path.name)
    link = cwd / f"link_{path.name}"
    if not link.is_symlink():
        link.symlink_to(path, target_is_directory=path.is_dir())
    return str(link)


def snapshot(folder: Path) -> dict:
    """Every file under ``folder`` (or the file itself) with its bytes' hash."""
    folder = Path(folder)
    files = [folder] if folder.is_file() else sorted(p for p in folder.rglob("*") if p.is_file())
    return {str(p): hashlib.sha256(p.read_bytes()).hexdigest() for p in files}


def one_line(capsys, rc) -> str:
    err = [
        line
        for line in capsys.readouterr().err.strip().splitlines()
        if ": warning: " not in line and ": note: " not in line
    ]
    assert rc == 2 and len(err) == 1 and "Traceback" not in err[0] and len(err[0]) <= 300, err
    return err[0]


# -- the rule ------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("how", SPELLINGS + ("hardlink",))
def test_an_output_on_an_input_file_is_refused_however_spelled(tmp_path, monkeypatch, how):
    monkeypatch.chdir(tmp_path)
    data = tmp_path / "d.csv"
    data.write_text("thickness\n0.7\n")
    if how == "hardlink":
        os.link(data, tmp_path / "h.csv")
        out = "h.csv"
    else:
        out = spell(data, how, tmp_path)
    with pytest.raises(InputError, match=r"^--csv .*: the same file as --designs d.csv, which this command reads"):
        check_apart({"--csv": out}, {"--designs": "d.csv"})
    check_apart({"--csv": "other.csv"}, {"--designs": "d.csv"})  # a file beside it is fine


@pytest.mark.parametrize("how", SPELLINGS)
def test_an_output_in_or_on_an_input_folder_is_refused_however_spelled(tmp_path, monkeypatch, how):
    monkeypatch.chdir(tmp_path)
    data = tmp_path / "data"
    data.mkdir()
    (data / "meta.json").write_text("{}")
    with pytest.raises(InputError, match=r"inside DATA data, a folder this command reads"):
        check_apart({"--out": spell(data / "meta.json", how, tmp_path)}, {"DATA": "data"})
    with pytest.raises(InputError, match=r"the same folder as DATA"):
        check_apart({"--out": spell(data, how, tmp_path)}, {"DATA": "data"})
    with pytest.raises(InputError, match=r"holds DATA"):  # a folder the command fills or deletes
        check_apart({"--out": str(tmp_path)}, {"DATA": spell(data, how, tmp_path)}, owned=("--out",))
    check_apart({"--out": str(tmp_path)}, {"DATA": "data"})  # not owned: writing beside the data is fine
    check_apart({"--out": "data2/meta.json", "--json": None}, [("DATA", "data"), ("RUN", None)])


def test_undo_on_error_removes_only_what_the_block_added(tmp_path):
    old = tmp_path / "out" / "old.png"
    old.parent.mkdir()
    old.write_text("kept")
    with pytest.raises(OSError):
        with undo_on_error(tmp_path / "out", tmp_path / "p.csv", None):
            (tmp_path / "out" / "d1").mkdir()
            (tmp_path / "out" / "d1" / "a.png").write_text("new")
            (tmp_path / "p.csv").write_text("new")
            raise OSError(errno.ENOSPC, "No space left on device")
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["old.png", "out"] and old.read_text() == "kept"


# -- the commands --------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def setup(tmp_path_factory, tiny_config, impact_data):
    """A copy of the test run's dataset and a 2-step HCMT run trained on it (checkpoint.pt and best.pt)."""
    root = tmp_path_factory.mktemp("apart")
    shutil.copytree(impact_data, root / "data")
    train(
        tiny_config("train.steps=2", "train.checkpoint_every=1", "train.valid_every=2", "train.valid_trajectories=1"),
        root / "data",
        "hcmt",
        root / "run",
        progress=False,
    )
    (root / "designs.csv").write_text("thickness\n0.7\n0.8\n")
    return root


#: command -> (argv with {out} where the output goes, the input it must not touch, relative to the setup root)
COMMANDS = {
    "surrogate fit --out DATA/meta.json": (["surrogate", "fit", "data", "--out", "{out}"], "data/meta.json"),
    "predict --json DATA/train.h5": (
        ["predict", "run", "--design", "thickness=0.7", "--json", "{out}"],
        "data/train.h5",
    ),
    "predict --csv on --designs": (["predict", "run", "--designs", "designs.csv", "--csv", "{out}"], "designs.csv"),
    "predict --json in RUN": (["predict", "run", "--design", "thickness=0.7", "--json", "{out}"], "run/p.json"),
    "sweep --out DATA": (["sweep", "run", "--vary", "thickness=0.6:0.9:2"], "data"),
    "train --out DATA": (
        [
            "train",
            "--config",
            "impact_plate_cpu",
            "--data",
            "data",
            "--model",
            "hcmt",
            "--out",
            "{out}",
            "--steps",
            "2",
        ],
        "data",
    ),
    "hierarchy --json DATA/meta.json": (["hierarchy", "data", "--levels", "1", "--json", "{out}"], "data/meta.json"),
    "compare --json RUN/run.yaml": (["compare", "run", "--json", "{out}"], "run/run.yaml"),
    "plot --out RUN": (["plot", "run", "--data", "data", "--only", "training"], "run"),
    "export --out DATA/x": (["export", "run", "--data", "data"], "data/x"),
    "evaluate RUN in DATA": (["evaluate", "{out}", "--data", "data"], "data"),
}


@pytest.mark.slow
@pytest.mark.parametrize("how", SPELLINGS)
@pytest.mark.parametrize("case", sorted(COMMANDS))
def test_no_command_writes_over_its_inputs(setup, monkeypatch, capsys, case, how):
    monkeypatch.chdir(setup)
    argv, target = COMMANDS[case]
    target = setup / target
    if case == "evaluate RUN in DATA":  # the run folder (where evaluate writes) inside the dataset
        shutil.copytree(setup / "run", setup / "data" / "run", dirs_exist_ok=True)
        target = setup / "data" / "run"
    before = snapshot(setup)
    out = spell(target, how, setup) if target.exists() else os.path.relpath(target, setup)
    argv = [a.replace("{out}", out) for a in argv]
    if "{out}" not in " ".join(COMMANDS[case][0]):
        argv += ["--out", out]
    line = one_line(
        capsys, cli(argv + (["--no-progress"] if argv[0] in ("predict", "sweep", "plot", "export") else []))
    )
    assert line.startswith(f"hcmt {argv[0]}: error: ") and (
        "this command reads" in line
        or (  # or check_outputs'
            argv[0] == "predict" and ("a file of the dataset" in line or "is a symlink" in line)
        )
    ), line
    after = snapshot(setup)
    assert after == before or set(after) - set(before) <= {str(p) for p in setup.glob("link_*")}
    if case == "evaluate RUN in DATA":
        shutil.rmtree(setup / "data" / "run")


@pytest.mark.slow
def test_a_refused_resume_changes_nothing_and_advises_only_a_readable_checkpoint(setup, tmp_path, capsys):
    run = tmp_path / "run"
    shutil.copytree(setup / "run", run)
    latest = run / "checkpoint.pt"
    latest.write_bytes(latest.read_bytes()[:1000])  # truncated
    before = snapshot(run)
    line = one_line(capsys, cli(["train", "--resume", "--out", str(run), "--steps", "30", "--no-progress"]))
    assert "checkpoint.pt" in line and "best.pt" in line and "copy it over" in line
    assert snapshot(run) == before and "steps: 2\n" in (run / "run.yaml").read_text()
    (run / "best.pt").write_bytes((run / "best.pt").read_bytes()[:1000])  # both damaged: copying helps nothing
    before = snapshot(run)
    line = one_line(capsys, cli(["train", "--resume", "--out", str(run), "--steps", "30", "--no-progress"]))
    assert "copy it over" not in line and "best.pt is damaged too" in line and snapshot(run) == before


def test_generate_refuses_a_plan_over_its_cost_limit(tmp_path, capsys):
    out = tmp_path / "big"
    line = one_line(
        capsys,
        cli(
            [
                "generate",
                "impact-plate",
                str(out),
                "--train",
                "2",
                "--valid",
                "0",
                "--test",
                "0",
                "--frames",
                "1000000",
                "--no-progress",
            ]
        ),
    )
    assert "per trajectory exceeds 600 s" in line and "--force" in line and not out.exists()
    with pytest.raises(InputError, match="exceeds 600 s"):  # the library's rule, the API too
        generate_dataset(out, counts={"train": 1}, settings=Settings(frames=1000000), progress=False)
    assert not out.exists()
    # the same rule as simulate's: one function, one wording
    line = one_line(capsys, cli(["simulate", "--preset", "small", "--frames", "100000", "--no-progress"]))
    assert "exceeds 600 s" in line and "--force" in line


@pytest.mark.slow
def test_a_full_disk_during_predict_leaves_none_of_its_outputs(setup, tmp_path, monkeypatch, capsys):
    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "p.json"))

    monkeypatch.setattr(design_cli, "to_json", full)  # the last output fails, after the images and the CSV
    rc = cli(
        [
            "predict",
            str(setup / "run"),
            "--design",
            "thickness=0.7",
            "--design",
            "thickness=0.8",
            "--images",
            "--out",
            str(tmp_path / "img"),
            "--csv",
            str(tmp_path / "p.csv"),
            "--json",
            str(tmp_path / "p.json"),
            "--no-progress",
        ]
    )
    line = one_line(capsys, rc)
    assert "No space left on device" in line and list(tmp_path.iterdir()) == []
