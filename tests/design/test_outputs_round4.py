"""A new user's trial of the outputs (round 4): the response surface named without a machine's path, evaluate's RMSE
at the scale its file stores, plain rebound words, the sweep plot's unit, a --batch help that is true, the err %
column of the chosen read-out, a note where --readout contact changes nothing, and one rule of a trend's agreement
for the sweep, the judge and the model card."""

from __future__ import annotations

import copy
import json
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from hcmt.cli import main as cli
from hcmt.data.runs import PRETRAINED_DIR
from hcmt.design import readout as ro
from hcmt.design.check import Prediction, verify_designs
from hcmt.design.reports import format_table, table_rows
from hcmt.design.surrogate_use import for_run
from hcmt.design.sweep import analyse, format_analysis, plot_sweep, trends_agree
from hcmt.inference.evaluate import format_metrics
from hcmt.inference.metrics import EvalMetrics, Rmse
from hcmt.inference.physics import format_physics, summarize_impact
from hcmt.sim.params import Design
from impact_trajectory import DT, fields
from summaries import fake_metrics, fake_summary

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = SimpleNamespace(source="pretrained:impact_plate_small")  # for_run needs only its name here


# -- 1. the response surface's label -------------------------------------------------------------------------------
def test_the_shipped_surface_is_labelled_by_the_models_name_and_its_runs_not_a_path():
    s, _, _ = for_run(SHIPPED)
    assert "/" in s.source  # the file's record keeps the command that made it, with the machine's folders
    assert s.label == f"pretrained:impact_plate_small's own, fitted on {len(s)} solver runs" and "/" not in s.label
    given, _, _ = for_run(SHIPPED, PRETRAINED_DIR / "impact_plate_small.surrogate.json")
    assert given.label == f"impact_plate_small.surrogate.json, fitted on {len(s)} solver runs"


@pytest.mark.slow  # the shipped model loaded and one design rolled out in-process (~20 s on one thread)
def test_predict_header_names_the_surface_without_a_path(capsys):
    """Needs hcmt.design.check.check_designs to record ``surrogate.label`` (not ``.source``) as Check.surrogate."""
    assert (
        cli(
            [
                "predict",
                "pretrained:impact_plate_small",
                "--design",
                "thickness=0.8",
                "drop_height=700",
                "--no-progress",
                "--threads",
                "1",
            ]
        )
        == 0
    )
    header = capsys.readouterr().out.splitlines()[0]
    assert "response surface: pretrained:impact_plate_small's own, fitted on 480 solver runs" in header
    assert "/" not in header.split("response surface:")[1]


# -- 2. evaluate's RMSE: the table at the file's scale, the file saying it ------------------------------------------
METRICS = EvalMetrics(
    split="test",
    data="d",
    trajectories=2,
    scale=1000.0,
    rmse_units={},
    warnings=[],
    units={"length": "mm", "stress": "MPa"},
    position=Rmse(0.25, 1.5, 3.25),
    stress=Rmse(120.0, 900.0, 2100.0),
    inference_ms_per_step=10.0,
    train_ms_per_step=None,
)


def test_evaluate_prints_the_rmse_at_the_scale_its_file_stores_and_says_it():
    from hcmt.inference.metrics import rmse_units

    assert rmse_units({"length": "mm", "stress": "MPa"}) == {"position": "0.001 mm", "stress": "0.001 MPa"}
    lines = format_metrics(METRICS).splitlines()
    assert "RMSE ×1000" in lines[0] and "metrics_test.json" in lines[0]
    position = next(line for line in lines if line.strip().startswith("position"))
    assert "[0.001 mm]" in position and position.split()[-3:] == ["0.25", "1.5", "3.25"]  # the file's numbers


@pytest.mark.slow  # one solver run and the shipped model's rollout of it (~1 min on one thread)
def test_evaluate_file_records_the_unit_of_its_rmse_and_the_table_prints_its_numbers(tmp_path, capsys):
    data, out = tmp_path / "d", tmp_path / "ev"
    assert cli(["simulate", "--out", str(data / "test.h5"), "--no-progress"]) == 0
    assert (
        cli(["evaluate", "pretrained:impact_plate_small", "--data", str(data), "--out", str(out), "--no-progress"]) == 0
    )
    m = json.loads((out / "metrics_test.json").read_text())
    assert m["scale"] == 1000 and m["rmse_units"] == {"position": "0.001 mm", "stress": "0.001 MPa"}
    row = next(line for line in capsys.readouterr().out.splitlines() if line.strip().startswith("position"))
    assert float(row.split()[-1]) == pytest.approx(m["position"]["rmse_all"], rel=1e-3)


# -- 3. rebound words ----------------------------------------------------------------------------------------------
def _physics(model_rebounds: list[bool], solver_rebounds: list[bool]) -> dict:
    rows = [
        fake_metrics(
            rebound_agrees=a == b,
            model_rebounds=a,
            solver_rebounds=b,
            **dict.fromkeys(
                (
                    "peak_plate_stress_error_pct",
                    "peak_ball_stress_error_pct",
                    "max_deflection_error_pct",
                    "far_deflection_error_um",
                    "far_deflection_error_pct",
                ),
                1.0,
            ),
            peak_plate_frame_error=1,
        )
        for a, b in zip(model_rebounds, solver_rebounds)
    ]
    return summarize_impact(rows)


def test_when_neither_rebounds_the_physics_line_says_so_plainly():
    line = format_physics(_physics([False, False], [False, False]))[0]
    assert line == "  physics over 2 trajectories: rebound: neither the model nor the solver rebounds in 2/2"
    mixed = format_physics(_physics([True, False], [True, True]))[0]
    assert "rebound agreement 1/2 (the ball rebounds in 1 prediction, 2 solver runs)" in mixed


# -- 4. the sweep plot's unit --------------------------------------------------------------------------------------
def test_the_sweep_plots_x_axis_names_the_parameters_unit(monkeypatch, tmp_path):
    pytest.importorskip("matplotlib")
    import hcmt.viz.meshplot as meshplot

    saved = {}
    monkeypatch.setattr(meshplot, "save_figure", lambda fig, path, dpi=120: saved.setdefault("fig", fig) and path)
    preds = [
        SimpleNamespace(design=Design(thickness=t), summary=fake_summary(peak_plate_stress_mpa=s, max_deflection_mm=d))
        for t, s, d in ((0.6, 800.0, 0.2), (0.9, 700.0, 0.1))
    ]
    check = SimpleNamespace(preds=preds, truth=None, readout="raw")
    plot_sweep(check, {"param": "drop_height", "values": [520.0, 990.0], "limit": None}, tmp_path, "HCMT")
    assert [ax.get_xlabel() for ax in saved["fig"].axes] == ["drop_height [mm]"] * 2


# -- 5. sweep --help -----------------------------------------------------------------------------------------------
def test_sweep_help_says_how_its_points_are_batched(capsys):
    with pytest.raises(SystemExit):
        cli(["sweep", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "default 1: one point at a time" in text and "the whole sweep in one batch" in text


def test_sweep_description_does_not_promise_one_batch(capsys):
    """Needs hcmt.cli's command list (src/hcmt/cli/__init__.py) to drop "predicted in one batch"."""
    with pytest.raises(SystemExit):
        cli(["sweep", "--help"])
    assert "predicted in one batch" not in " ".join(capsys.readouterr().out.split())


# -- 6. the err % column is the chosen read-out's ------------------------------------------------------------------
def _pred(name: str, stress_scale: float = 1.0, readout: str = "raw", ghost: bool = True) -> Prediction:
    f = fields()
    if not ghost:  # no stress after the ball has left: the peak comes in contact
        f["stress"][8:] = 0.0
    p = Prediction(
        name,
        Design(),
        f["world_pos"],
        f["stress"] * stress_scale,
        f["mesh_pos"],
        f["cells"],
        f["node_type"],
        1.0,
        modulus=f["modulus"],
    )
    p.summary = ro.summarize_fields(p.fields(), DT, readout, 1.0, 3 * DT if ghost else None)
    return p


def test_the_err_column_is_the_error_of_the_chosen_readouts_peak():
    preds, truth = [_pred("a", readout="element")], [_pred("a", 1.2)]
    verify_designs(preds, truth)
    head, rows = table_rows(preds)
    s = preds[0].summary
    want = 100 * (s.derived.peak_plate_stress_mpa / truth[0].summary.peak_plate_stress_mpa - 1)
    assert "element MPa" in head and "element err %" in head and "err %" not in head
    assert rows[0][head.index("element err %")] == f"{want:+.1f}"
    raw = [_pred("a")]
    verify_designs(raw, [_pred("a", 1.2)])
    assert "err %" in table_rows(raw)[0]  # the raw read-out keeps its column


# -- 7. --readout contact where it changes nothing ------------------------------------------------------------------
def test_contact_readout_says_when_it_changes_nothing():
    same = [_pred("a", readout="contact", ghost=False)]
    assert same[0].summary.derived.peak_plate_stress_mpa == same[0].summary.peak_plate_stress_mpa
    assert "note: --readout contact changes nothing here" in format_table(same)
    ghost = [_pred("a", readout="contact")]  # the raw peak is the ghost after the ball left: contact differs
    assert ghost[0].summary.derived.peak_plate_stress_mpa < ghost[0].summary.peak_plate_stress_mpa
    assert "changes nothing" not in format_table(ghost)
    assert "changes nothing" not in format_table([_pred("a", ghost=False)])


# -- 8. one rule of a trend's agreement ----------------------------------------------------------------------------
def _check(model: list[float], solver: list[float]):
    def mk(v, s):
        return SimpleNamespace(
            design=Design(drop_height=v), summary=fake_summary(peak_plate_stress_mpa=s, max_deflection_mm=s / 1e4)
        )

    heights = [520.0, 755.0, 990.0]
    return SimpleNamespace(
        preds=[mk(v, s) for v, s in zip(heights, model)],
        truth=[mk(v, s) for v, s in zip(heights, solver)],
        readout="raw",
        solver_runs=3,
    )


def test_the_sweep_calls_a_trend_with_the_right_sign_but_40_percent_short_a_miss():
    a = analyse(_check([1000.0, 1040.0, 1073.0], [1000.0, 1060.0, 1122.0]), "drop_height", None)  # +7.3 against +12.2
    row = a["trend"]["peak_plate_stress_mpa"]
    assert row["agree"] is False and trends_agree(7.3, 12.2) is False
    assert "TRENDS DISAGREE" in format_analysis(a).splitlines()[0]
    assert "within 30 % of the solver's" in format_analysis(a).splitlines()[0]


def test_the_judge_and_the_card_count_by_the_sweeps_rule():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import release.card as card_module
    import surrogate.run as judge
    from scaling import long_run_sweeps

    assert judge.trends_agree is trends_agree and long_run_sweeps.trends_agree is trends_agree
    m = json.loads((ROOT / "benchmarks" / "results" / "model_impact_plate_small.json").read_text())
    m = copy.deepcopy(m)
    sweep = next(iter(m["sweeps"].values()))
    t = sweep["trend"]["peak_plate_stress_mpa"]
    t["model"]["change_pct"], t["solver"]["change_pct"], t["agree"] = 7.3, 12.2, True  # as the old sweep stored it
    text = "\n".join(card_module.card("x", m, None, None))
    row = next(line for line in text.splitlines() if "peak plate stress | +7.3 %" in line)
    assert "a miss" in row and "sign right" in row and "size 40 % off" in row
    assert np.isclose(abs(7.3 / 12.2 - 1), 0.40, atol=0.005)
