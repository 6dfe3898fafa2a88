"""Bad input, round 4 (files): a data file that would run code, an output over another run's results, through a
symlink or onto a dataset's file, refusals that left an empty folder, a generate in progress and a simulated file
beside another run's meta.json. Each case: one line naming the file or flag and what was expected, exit 2,
nothing changed; the API raises InputError (or DatasetError) with the parameter's name."""

import hashlib
import os
import pickle
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest

import hcmt
import hcmt.cli.data
from hcmt.cli import CommandError, check_outputs, main as cli
from hcmt.data.convert import convert
from hcmt.data.format import GENERATE_LOCK, load_dataset, read_meta
from hcmt.errors import DatasetError, InputError
from hcmt.files import folder_lock, lock_holder
from hcmt.inference.rollout_files import check_results_folder
from hcmt.sim.generate import generate_dataset
from refusals import refused

SHIPPED = "pretrained:impact_plate_small"


def snapshot(folder: Path) -> dict:
    """Every file and folder under ``folder`` (hidden ones too) with its bytes' hash."""
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
        for p in sorted(Path(folder).rglob("*"))
    }


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """A tiny generated dataset (1 train, 1 valid, 1 test trajectory of 4 frames)."""
    out = tmp_path_factory.mktemp("round4") / "data"
    generate_dataset(
        out,
        preset="small",
        counts={"train": 1, "valid": 1, "test": 1},
        seed=0,
        settings=hcmt.Settings(frames=4),
        progress=False,
    )
    return out


# -- 1. no code from a data file runs ------------------------------------------------------------------------------
class Payload:
    """What a malicious pickle holds: unpickling it calls ``exec``, which writes ``marker``."""

    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self):
        return exec, (f"open({str(self.marker)!r}, 'w').write('ran')",)


def test_a_pickle_that_would_run_code_is_refused_and_runs_nothing(tmp_path, capsys):
    marker, evil = tmp_path / "ran.txt", tmp_path / "evil.pkl"
    evil.write_bytes(pickle.dumps([{"nodes_grid": Payload(marker)}]))
    with open(evil, "rb") as f:  # the payload is real: a plain unpickler runs it
        pickle.load(f)
    assert marker.read_text() == "ran"
    marker.unlink()
    line = refused(capsys, ["convert", str(evil), str(tmp_path / "out")])
    assert "evil.pkl" in line and "builtins.exec" in line and "runs no code" in line, line
    assert not marker.exists() and not (tmp_path / "out").exists()
    with pytest.raises(DatasetError, match="builtins.exec"):
        convert(evil, tmp_path / "out2")
    assert not marker.exists() and not (tmp_path / "out2").exists()


def ggns_trajectory(steps: int = 3, seed: int = 0) -> dict:
    """One trajectory in the GGNS Deformable Plate layout: numpy arrays and a float in a dict."""
    rng = np.random.default_rng(seed)
    grid = rng.random((4, 2)).astype(np.float32)
    collider = rng.random((3, 2)).astype(np.float32)
    return {
        "nodes_grid": np.stack([grid + 0.01 * t for t in range(steps)]),
        "triangles_grid": np.array([[0, 1, 2], [1, 2, 3]]),
        "nodes_collider": np.stack([collider - 0.01 * t for t in range(steps)]),
        "triangles_collider": np.array([[0, 1, 2]], dtype=np.int32),
        "poisson_ratio": np.float64(0.3),
        "edge_index_grid": [np.arange(4)],
        "name": ("plate", 1),
    }


@pytest.mark.parametrize("protocol", [2, 4, 5])
def test_a_ggns_pickle_of_arrays_in_dicts_and_lists_still_converts(tmp_path, protocol):
    src = tmp_path / "src"
    src.mkdir()
    (src / "train.pkl").write_bytes(pickle.dumps([ggns_trajectory(), ggns_trajectory(seed=1)], protocol=protocol))
    convert(src, tmp_path / "out")
    ds = load_dataset(tmp_path / "out")
    assert ds.splits == ["train"] and len(ds["train"]) == 2
    assert ds["train"][1]["world_pos"].shape == (3, 7, 2) and ds["train"].attrs(0)["poisson_ratio"] == 0.3


# -- 2. no output replaces another run's results -------------------------------------------------------------------
def fake_run(folder: Path) -> Path:
    """A run folder of another model: run.yaml, a checkpoint, its metrics and rollouts."""
    folder.mkdir()
    (folder / "run.yaml").write_text("model: {name: mgn}\n")
    (folder / "checkpoint.pt").write_bytes(b"weights")
    (folder / "metrics_test.json").write_text('{"position": {"rmse_all": 1.0}}')
    with h5py.File(folder / "rollout_test.h5", "w") as f:
        f.attrs["checkpoint"] = "best.pt"
    return folder


def test_evaluate_of_a_shipped_model_refuses_another_run_s_folder(data, tmp_path, capsys):
    run = fake_run(tmp_path / "run")
    before = snapshot(run)
    line = refused(capsys, ["evaluate", SHIPPED, "--data", str(data), "--out", str(run), "--no-progress"])
    assert line.startswith("hcmt evaluate: error: --out ") and "a run folder of another model" in line, line
    assert snapshot(run) == before


def test_a_shipped_model_writes_over_no_other_model_s_rollouts(tmp_path):
    out = tmp_path / "ev"
    out.mkdir()
    with h5py.File(out / "rollout_test.h5", "w") as f:
        f.attrs["checkpoint"] = "another_model.pt"
    with pytest.raises(InputError, match=r"^out .*rollout_test.h5 of another model \(another_model.pt\)") as exc:
        check_results_folder(out, SHIPPED)
    assert exc.value.param == "out"
    with h5py.File(out / "rollout_test.h5", "w") as f:  # its own earlier rollouts: reused or replaced, as before
        f.attrs["checkpoint"] = "impact_plate_small.pt"
    check_results_folder(out, SHIPPED)
    check_results_folder(fake_run(tmp_path / "run"), str(tmp_path / "run"))  # a run writes to itself


# -- 3. no output through a symlink or onto a dataset's file -------------------------------------------------------
def test_an_output_that_is_a_symlink_or_a_file_of_a_dataset_is_refused(data, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("other.json").write_text("{}")
    os.symlink("other.json", "link.json")
    for value, word in (
        ("link.json", "is a symlink (to other.json)"),
        (str(data / "train.h5"), "a file of the dataset"),
        (str(data / "meta.json"), "a file of the dataset"),
    ):
        with pytest.raises(CommandError, match=word.replace("(", r"\(").replace(")", r"\)")):
            check_outputs({"--json": value})
    check_outputs({"--json": "new.json", "--csv": str(data / "new.h5")})  # new files, beside a dataset too


def test_simulate_onto_a_dataset_s_split_file_is_refused_before_the_solver(data, tmp_path, monkeypatch, capsys):
    copy = tmp_path / "d"
    shutil.copytree(data, copy)
    before = snapshot(copy)
    monkeypatch.setattr(hcmt.cli.data, "simulate", lambda *a, **k: pytest.fail("the solver ran"))
    line = refused(capsys, ["simulate", "--frames", "3", "--out", str(copy / "train.h5"), "--no-progress"])
    assert f"--out {copy / 'train.h5'}: a file of the dataset {copy}" in line, line
    assert snapshot(copy) == before


def test_a_json_output_that_is_a_symlink_is_refused(data, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    Path("other.json").write_text('{"kept": 1}')
    os.symlink("other.json", "link.json")
    line = refused(capsys, ["hierarchy", str(data), "--levels", "1", "--json", "link.json", "--no-progress"])
    assert "--json link.json: is a symlink (to other.json)" in line, line
    assert Path("link.json").is_symlink() and Path("other.json").read_text() == '{"kept": 1}'


# -- 4. a refusal leaves no empty --out folder ---------------------------------------------------------------------
@pytest.mark.parametrize("case", ["an empty --data folder", "a missing --split", "a corrupt split file"])
def test_a_refused_evaluate_leaves_no_out_folder(data, tmp_path, capsys, case):
    """The first two are refused in the parse step (before torch), the third by the reader once the command has
    begun: none leaves the --out folder behind."""
    (tmp_path / "empty").mkdir()
    corrupt = tmp_path / "corrupt"
    corrupt.mkdir()
    (corrupt / "meta.json").write_text((Path(data) / "meta.json").read_text())
    (corrupt / "test.h5").write_bytes(b"not an HDF5 file")
    argv = ["evaluate", SHIPPED, "--out", str(tmp_path / "new"), "--no-progress"]
    argv += {
        "an empty --data folder": ["--data", str(tmp_path / "empty")],
        "a missing --split": ["--data", str(data), "--split", "nosuch"],
        "a corrupt split file": ["--data", str(corrupt)],
    }[case]
    line = refused(capsys, argv)
    expected = {
        "an empty --data folder": "no meta.json",
        "a missing --split": "has no nosuch.h5",
        "a corrupt split file": "cannot be read as HDF5",
    }[case]
    assert expected in line, line
    assert not (tmp_path / "new").exists()


def test_generate_refuses_a_fractional_frame_count_before_writing(tmp_path):
    with pytest.raises(InputError, match="frames") as exc:
        generate_dataset(tmp_path / "g" / "d", counts={"train": 1}, settings=hcmt.Settings(frames=2.5), progress=False)
    assert exc.value.param == "frames" and not (tmp_path / "g").exists()
    with pytest.raises(InputError, match="must be an hcmt.Settings"):
        generate_dataset(tmp_path / "g", counts={"train": 1}, settings={"frames": 4}, progress=False)
    assert not (tmp_path / "g").exists()


# -- 5. a generate in progress is locked and named -----------------------------------------------------------------
def busy(pid):
    return InputError(f"busy {pid}")


def test_a_second_generate_on_a_folder_being_generated_is_refused(data, tmp_path, monkeypatch, capsys):
    out = tmp_path / "gen"
    out.mkdir()
    shutil.copy(data / "meta.json", out / "meta.json")  # a generate that has written meta.json, no split yet
    before = snapshot(out)
    with folder_lock(out / GENERATE_LOCK, busy):  # another generate holds the folder (flock: another open file)
        assert lock_holder(out / GENERATE_LOCK) == os.getpid()
        line = refused(
            capsys,
            [
                "generate",
                "impact-plate",
                str(out),
                "--train",
                "1",
                "--valid",
                "1",
                "--test",
                "1",
                "--frames",
                "4",
                "--seed",
                "0",
                "--no-progress",
            ],
        )
        assert (
            line == f"hcmt generate: error: {out}: a generate is writing it (pid {os.getpid()}); wait for it or stop it"
        ), line
        line = refused(capsys, ["info", str(out)])
        assert f"a `hcmt generate` is writing it (pid {os.getpid()})" in line and "rerun" not in line, line
        assert snapshot(out) == {**before, GENERATE_LOCK: snapshot(out)[GENERATE_LOCK]}
    assert not (out / GENERATE_LOCK).exists()
    line = refused(capsys, ["info", str(out)])  # the lock released: interrupted, rerun
    assert "incomplete dataset" in line and "rerun the same `hcmt generate`" in line, line


def test_a_split_not_yet_written_names_the_generate_writing_it(data, tmp_path):
    out = tmp_path / "gen"
    out.mkdir()
    for name in ("meta.json", "train.h5"):  # train done, test still being simulated
        shutil.copy(data / name, out / name)
    with folder_lock(out / GENERATE_LOCK, busy):
        with pytest.raises(
            DatasetError,
            match=f"split 'test' not found; available: \\['train'\\]; a `hcmt "
            f"generate` is writing this dataset \\(pid {os.getpid()}\\)",
        ):
            load_dataset(out)["test"]
    with pytest.raises(DatasetError, match=r"split 'test' not found; available: \['train'\]$"):
        load_dataset(out)["test"]


def test_a_lock_left_by_a_killed_generate_blocks_nothing(data, tmp_path):
    out = tmp_path / "gen"
    out.mkdir()
    (out / GENERATE_LOCK).write_text("999999")  # its process is gone: the kernel released its flock
    assert lock_holder(out / GENERATE_LOCK) is None
    generate_dataset(out, preset="small", counts={"train": 1}, seed=0, settings=hcmt.Settings(frames=4), progress=False)
    assert read_meta(out)["trajectory_length"] == 4 and not (out / GENERATE_LOCK).exists()
    with folder_lock(out / GENERATE_LOCK, busy):
        with pytest.raises(InputError, match=f"a generate is writing it \\(pid {os.getpid()}\\)"):
            generate_dataset(
                out, preset="small", counts={"train": 2}, seed=0, settings=hcmt.Settings(frames=4), progress=False
            )
    assert len(load_dataset(out)["train"]) == 1


# -- 6. a simulated file's meta.json belongs to it -----------------------------------------------------------------
def test_simulate_beside_another_run_s_meta_json_is_refused_and_beside_its_own_kept(
    data, tmp_path, monkeypatch, capsys
):
    copy = tmp_path / "d"
    shutil.copytree(data, copy)
    before = snapshot(copy)
    solver = hcmt.cli.data.simulate
    monkeypatch.setattr(hcmt.cli.data, "simulate", lambda *a, **k: pytest.fail("the solver ran"))
    line = refused(capsys, ["simulate", "--frames", "3", "--out", str(copy / "two.h5"), "--no-progress"])
    assert "meta.json describes other data (trajectory_length 4 there, 3 here)" in line, line
    assert snapshot(copy) == before
    monkeypatch.setattr(hcmt.cli.data, "simulate", solver)  # the dataset's own frames: written, meta.json kept
    assert cli(["simulate", "--frames", "4", "--out", str(copy / "two.h5"), "--no-progress"]) == 0
    assert (copy / "meta.json").read_bytes() == (data / "meta.json").read_bytes()
    assert load_dataset(copy)["two"][0]["world_pos"].shape[0] == 4
    assert cli(["simulate", "--frames", "3", "--out", str(tmp_path / "one" / "one.h5"), "--no-progress"]) == 0
    assert f"wrote {tmp_path / 'one' / 'one.h5'} and {tmp_path / 'one' / 'meta.json'}" in capsys.readouterr().out
    assert read_meta(tmp_path / "one")["trajectory_length"] == 3 and len(load_dataset(tmp_path / "one")["one"]) == 1


def test_simulate_writes_no_meta_json_into_a_folder_of_other_files(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    Path("notes.txt").write_text("mine")
    monkeypatch.setattr(hcmt.cli.data, "simulate", lambda *a, **k: pytest.fail("the solver ran"))
    line = refused(capsys, ["simulate", "--frames", "3", "--out", "one.h5", "--no-progress"])
    assert "--out one.h5: . holds other files and no meta.json" in line and "--out one/one.h5" in line, line
    assert sorted(os.listdir(tmp_path)) == ["notes.txt"]


def test_evaluate_refuses_data_of_another_dataset_instead_of_printing_zeros(data, tmp_path, capsys):
    """A model of one dataset evaluated on another's data (meta.json names it) is refused, where it printed a
    stress RMSE of 0 0 0 and a 0.0 % peak error."""
    other = tmp_path / "other"
    shutil.copytree(data, other)
    meta = (other / "meta.json").read_text().replace('"dataset": "impact_plate"', '"dataset": "sphere_simple"')
    assert '"sphere_simple"' in meta
    (other / "meta.json").write_text(meta)
    line = refused(capsys, ["evaluate", SHIPPED, "--data", str(other), "--out", str(tmp_path / "new"), "--no-progress"])
    assert "dataset impact_plate, but" in line and "holds dataset sphere_simple" in line, line
    assert not (tmp_path / "new").exists()
