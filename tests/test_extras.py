"""The optional dependencies (pyproject's extras): each is imported where it is used, and without it that use fails
in one line naming the extra to install (TensorBoard scalars are simply left out); one version source."""

from __future__ import annotations

import logging
import sys
from pathlib import Path

import pytest

import hcmt
from hcmt.cli import main as cli
from hcmt.errors import InputError, MissingExtra, require, require_installed
from hcmt.training import runtime

ROOT = Path(__file__).resolve().parents[1]


def pyproject() -> dict:
    tomllib = pytest.importorskip("tomllib")  # Python 3.11+
    return tomllib.loads((ROOT / "pyproject.toml").read_text())


def test_a_missing_module_names_its_extra():
    with pytest.raises(MissingExtra) as exc:
        require("hcmt_no_such_module.sub", "viz")
    assert str(exc.value) == "hcmt_no_such_module is not installed (the viz extra); pip install 'hcmt[viz]'"
    assert isinstance(exc.value, InputError) and isinstance(exc.value, ImportError)
    with pytest.raises(MissingExtra, match=r"pip install 'hcmt\[tfrecord\]'"):
        require_installed("tfrecord", "json", "hcmt_no_such_module")
    assert require("json", "viz") is sys.modules["json"]
    require_installed("viz", "json")


def test_pictures_without_matplotlib_are_refused_in_one_line(tmp_path, monkeypatch, capsys):
    _forget([m for m in sys.modules if m == "hcmt.viz" or m.startswith(("hcmt.viz.", "hcmt.cli.viz"))], monkeypatch)
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # what an uninstalled package looks like to import
    (tmp_path / "run").mkdir()
    (tmp_path / "data").mkdir()
    rc = cli(["plot", str(tmp_path / "run"), "--data", str(tmp_path / "data"), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1, err
    assert err[0] == "hcmt plot: error: matplotlib is not installed (the viz extra); pip install 'hcmt[viz]'"


def test_tfrecords_without_the_tfrecord_extra_are_refused_in_one_line(tmp_path, monkeypatch):
    from hcmt.data.tfrecord import iter_records

    path = tmp_path / "train.tfrecord"
    path.write_bytes(bytes(16))
    monkeypatch.setitem(sys.modules, "crc32c", None)
    with pytest.raises(
        MissingExtra,
        match=r"^crc32c is not installed \(the tfrecord extra\); "
        r"pip install 'hcmt\[tfrecord\]'$",
    ):
        next(iter_records(path))


def test_training_without_tensorboard_writes_no_scalars_and_says_so_once(tmp_path, monkeypatch, caplog):
    monkeypatch.setitem(sys.modules, "torch.utils.tensorboard", None)
    monkeypatch.setattr(runtime, "_no_tensorboard_said", False)
    writer = runtime.summary_writer(tmp_path / "tb", None)
    writer.add_scalar("train/loss", 1.0, 1)
    writer.close()
    assert isinstance(writer, runtime._NoScalars) and not (tmp_path / "tb").exists()
    with caplog.at_level(logging.INFO, logger="hcmt.train"):
        runtime._say_no_tensorboard()
        runtime._say_no_tensorboard()
    said = [r.getMessage() for r in caplog.records if "TensorBoard" in r.getMessage()]
    assert said == [
        "no TensorBoard scalars: tensorboard is not installed (pip install 'hcmt[tensorboard]'); log.jsonl has them"
    ]


def test_one_version_source():
    project = pyproject()
    assert "version" not in project["project"] and "version" in project["project"]["dynamic"]
    assert project["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "hcmt.config.VERSION"}
    assert hcmt.__version__ == hcmt.config.VERSION


def test_torch_is_a_range_and_the_makefile_pins_it():
    project = pyproject()
    torch = [d for d in project["project"]["dependencies"] if d.startswith("torch") and "geometric" not in d]
    assert torch == ["torch>=2.4"]
    extras = project["project"]["optional-dependencies"]
    hard = " ".join(project["project"]["dependencies"])
    for name in ("matplotlib", "meshio", "tensorboard", "tfrecord", "crc32c"):
        assert (
            name not in hard
            and any(d.startswith(name) for d in extras["all"])
            and any(d.startswith(name) for d in extras["test"])
        )
    assert "TORCH  ?= torch==2.13.0" in (ROOT / "Makefile").read_text()


def _forget(names: list[str], monkeypatch) -> None:
    """Modules imported afresh by the test, all put back after it: the sys.modules entries and the parent packages'
    attributes, which a fresh import rebinds (else a later test patching ``hcmt.cli.design`` patches a copy)."""
    for name in names:
        parent, _, child = name.rpartition(".")
        if parent in sys.modules and hasattr(sys.modules[parent], child):
            monkeypatch.setattr(sys.modules[parent], child, getattr(sys.modules[parent], child))
        monkeypatch.delitem(sys.modules, name)


def _block_matplotlib(monkeypatch):
    _forget(
        [
            m
            for m in sys.modules
            if m.startswith(
                ("hcmt.viz", "hcmt.cli.viz", "hcmt.design", "hcmt.cli.design", "hcmt.cli.demo", "matplotlib")
            )
        ],
        monkeypatch,
    )
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # what an uninstalled package looks like to import


def test_the_design_check_imports_without_matplotlib(monkeypatch):
    """predict, sweep and demo need matplotlib only for their pictures: their modules import without it."""
    _block_matplotlib(monkeypatch)
    import importlib

    for module in ("hcmt.design.check", "hcmt.design.reports", "hcmt.design.sweep", "hcmt.cli.design", "hcmt.cli.demo"):
        importlib.import_module(module)
    assert "hcmt.viz" not in sys.modules


def test_predict_images_without_matplotlib_is_refused_before_the_model_runs(monkeypatch, capsys):
    _block_matplotlib(monkeypatch)
    assert cli(["predict", "pretrained:impact_plate_small", "--design", "thickness=0.8", "--images"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["hcmt predict: error: matplotlib is not installed (the viz extra); pip install 'hcmt[viz]'"]


@pytest.mark.slow  # rolls out the shipped model on two designs
def test_sweep_without_matplotlib_runs_and_says_no_plot(tmp_path, monkeypatch, capsys):
    _block_matplotlib(monkeypatch)
    assert (
        cli(
            [
                "sweep",
                "pretrained:impact_plate_small",
                "--vary",
                "thickness=0.6:0.7:2",
                "--no-surrogate",
                "--no-progress",
                "--out",
                str(tmp_path / "s"),
                "--json",
                str(tmp_path / "s.json"),
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "no plot: matplotlib is not installed (the viz extra)" in out and (tmp_path / "s.json").is_file()
