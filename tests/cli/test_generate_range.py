"""``hcmt generate impact-plate --range NAME=LO:HI`` refused in one line naming ``--range`` (exit 2) before the
command loads and before anything is written; a good one reaches generate_dataset as its ``ranges``."""

from __future__ import annotations

import importlib

import pytest

from hcmt.cli import main as cli
from refusals import refused


@pytest.fixture
def no_command_module(monkeypatch):
    """hcmt.cli.data (the generator) may not load: the refusal comes in the parse step."""
    real = importlib.import_module

    def guarded(name, *args, **kwargs):
        assert name != "hcmt.cli.data", f"{name} loaded before the refusal"
        return real(name, *args, **kwargs)

    monkeypatch.setattr(importlib, "import_module", guarded)


@pytest.mark.parametrize(
    "ranges, words",
    [
        (["thickness=0.5"], "expected NAME=LO:HI"),
        (["thickness"], "expected NAME=LO:HI"),
        (["=0.5:1"], "expected NAME=LO:HI"),
        (["thickness=a:1"], "expected NAME=LO:HI"),
        (["foo=1:2"], "foo is not a sampled parameter"),
        (["thickness=1:0.5"], "low <= high"),
        (["thickness=nan:1"], "finite"),
        (["drop_height=500:inf"], "finite"),
        (["thickness=0.6:0.7", "thickness=0.6:0.8"], "thickness is given twice"),
        (["thickness=0.01:1"], "must not exceed thickness"),
        (["mesh_size=0.29:5"], "mesh_size (5.0 mm) must not exceed"),
        (["drop_height=600:700", "plate_half_length=2:12"], "must exceed the ball_radius"),
    ],
)
def test_bad_ranges_are_one_line_naming_the_flag_and_write_nothing(tmp_path, capsys, no_command_module, ranges, words):
    out = tmp_path / "d"
    argv = ["generate", "impact-plate", str(out), "--train", "1", "--frames", "3", "--no-progress"]
    line = refused(capsys, argv + [a for r in ranges for a in ("--range", r)])
    assert line.startswith("hcmt generate: error: ") and "--range" in line and words in line, line
    assert not out.exists() and not any(tmp_path.iterdir())


def test_range_is_an_impact_plate_option(tmp_path, capsys, no_command_module):
    out = tmp_path / "p"
    line = refused(capsys, ["generate", "deforming-plate", str(out), "--range", "thickness=0.6:0.7"])
    assert "--range is an impact-plate option" in line, line
    assert not out.exists()


def test_good_ranges_reach_the_generator(tmp_path, monkeypatch, capsys):
    seen = {}

    def fake(out, **kwargs):
        seen.update(kwargs)
        return {"simulated": 0, "skipped": 0, "splits": {}}

    import hcmt.cli.data

    monkeypatch.setattr(hcmt.cli.data, "generate_dataset", fake)
    assert (
        cli(
            [
                "generate",
                "impact-plate",
                str(tmp_path / "d"),
                "--train",
                "1",
                "--frames",
                "3",
                "--no-progress",
                "--range",
                "thickness=0.6:0.7",
                "--range",
                " drop_height = 550:650",
            ]
        )
        == 0
    )
    assert seen["ranges"] == {"thickness": (0.6, 0.7), "drop_height": (550.0, 650.0)}
    assert cli(["generate", "impact-plate", str(tmp_path / "e"), "--train", "1", "--frames", "3", "--no-progress"]) == 0
    assert not seen["ranges"]
    capsys.readouterr()
