"""The mesh model's answer is its own outputs: derived read-outs only under their own names and
only when chosen, the same default answer whatever the surrogate, ``readout`` recorded; each quantity printed
once in ``predict --verify``; the sweep's trends compared by size (a trend of the right sign but the wrong size
misleads)."""

import json
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from hcmt.cli import main as cli
from hcmt.data.runs import PRETRAINED_DIR
from hcmt.design import readout as ro
from hcmt.design.check import Prediction, add_calls, verify_designs
from hcmt.design.reports import csv_rows, format_table, to_json
from hcmt.design.surrogate import dataset_facts
from hcmt.design.sweep import analyse, format_analysis, trends_agree
from hcmt.design.verification import VerifyRow
from hcmt.errors import InputError
from hcmt.inference.run import Run
from hcmt.sim.params import Design
from impact_trajectory import DT, fields
from summaries import fake_summary

CONTACT_KEYS = {
    "contact_peak_plate_stress_mpa",
    "contact_peak_plate_where_mm",
    "contact_peak_plate_when_ms",
    "contact_peak_plate_frame",
    "contact_peak_plate_node",
    "contact_peak_plate_t95_frame",
    "contact_peak_plate_t95_ms",
    "contact_plate_stress_history_mpa",
    "contact_window_end_ms",
    "contact_window_end_from",
    "contact_bending_k",
}


def test_the_default_is_the_models_own_output_and_a_bound_does_not_change_it():
    f = fields()
    raw = ro.summarize_fields(f, DT)
    assert raw.readout == "raw" and raw.peak_plate_stress_mpa == 650.0  # the ghost is the model's output
    assert raw.plate_stress_history_mpa == [0, 0, 200, 400, 500, 300, 0, 0, 650, 650, 650, 650]
    bounded = ro.summarize_fields(f, DT, contact_end_ms=3 * DT)  # a surrogate's bound: only for contact
    assert bounded == raw


def test_each_derived_readout_lies_only_under_its_own_names_and_only_when_chosen():
    f = fields()
    raw = ro.summarize_fields(f, DT)
    contact = ro.summarize_fields(f, DT, "contact", contact_end_ms=3 * DT)
    element = ro.summarize_fields(f, DT, "element")
    assert raw.derived is None
    assert not any(k.startswith(("contact_peak", "contact_plate", "contact_window", "element_")) for k in raw.to_json())
    assert set(contact.to_json()) - set(raw.to_json()) == CONTACT_KEYS
    assert set(element.to_json()) - set(raw.to_json()) == {f"element_{k}" for k in ro.DERIVED_KEYS}
    for derived in (contact, element):  # the default fields stay the model's own
        assert replace(derived, readout="raw", derived=None) == raw
    # the contact read-out: frames 2-3 (the bound), then the bending formula
    assert contact.derived.peak_plate_stress_mpa == 400.0 and contact.derived.peak_plate_frame == 3
    assert contact.derived.window_end_ms == pytest.approx(4 * DT)
    assert "response surface" in contact.derived.window_end_from
    own = ro.summarize_fields(f, DT, "contact")  # no bound: the predicted ball's own window, frames 2-6
    assert own.derived.peak_plate_stress_mpa == 500.0 and "last touch" in own.derived.window_end_from
    history = np.array(contact.derived.plate_stress_history_mpa)
    plate = ro.plate_mask(f["cells"], f["node_type"])
    w = np.abs(f["world_pos"][:, plate, 1] - f["mesh_pos"][None, plate, 1]).max(1)
    np.testing.assert_allclose(history[4:], (ro.BENDING_K * 7e4 * 0.5 * w / 2.0**2)[4:])  # k E t w_max / R^2
    assert ro.chosen(contact, "peak_plate_stress_mpa") == 400.0 and ro.chosen(raw, "peak_plate_stress_mpa") == 650
    assert ro.chosen(contact, "max_deflection_mm") == raw.max_deflection_mm  # not derived: the model's own


def test_an_unknown_readout_is_refused_naming_it():
    with pytest.raises(InputError) as e:
        ro.summarize_fields(fields(), DT, "learned")
    assert e.value.param == "readout" and "raw, contact, element" in str(e.value)


def _pred(name: str, stress_scale: float = 1.0, readout: str = "raw") -> Prediction:
    f = fields()
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
    p.summary = ro.summarize_fields(p.fields(), DT, readout, 1.0, 3 * DT)
    return p


def test_calls_use_the_chosen_readout_and_the_json_and_csv_record_it():
    preds = [_pred("a", readout="contact")]
    add_calls(preds, 450.0, "model")  # no surrogate: the model's band around the contact read-out's 400
    iv = preds[0].summary.call_interval_mpa
    assert iv.model_readout == "contact" and iv.hi == pytest.approx(400 * 1.6)
    check = SimpleNamespace(readout="contact", surrogate=None, solver_runs=0, notes=[])
    doc = to_json(preds, None, "m", "cpu", check)
    assert doc["readout"] == "contact" and doc["designs"][0]["readout"] == "contact"
    head, rows = csv_rows(preds)
    assert rows[0][head.index("readout")] == "contact" and "contact_peak_plate_stress_mpa" in head
    assert not any(h.endswith("history_mpa") for h in head)


def test_verify_prints_each_quantity_once():
    preds, truth = [_pred("a"), _pred("b", 1.1)], [_pred("a", 1.2), _pred("b", 1.0)]
    verified = verify_designs(preds, truth)
    text = format_table(preds, verified)
    for name in ("peak plate stress error", "time of the plate's peak", "rise time", "max deflection error"):
        assert text.count(name) == 1, (name, text)
    row = preds[0].summary.verify
    assert row.peak_plate_stress_error_pct == pytest.approx(100 * (1 / 1.2 - 1))
    assert verified.peak_plate_stress_error_pct.median == verified.physics.peak_plate_stress_error_pct.median_abs


def test_the_verify_block_is_typed_and_its_json_keys_are_the_ones_the_dict_wrote():
    """The verify row (a VerifyRow) writes the keys and order the plain dict did (recorded before the change), a
    derived read-out's error last."""
    preds, truth = [_pred("a", readout="contact")], [_pred("a", 1.2)]
    verify_designs(preds, truth)
    row = preds[0].summary.verify
    assert isinstance(row, VerifyRow) and row.speedup == 1.0
    block = to_json(preds, None, "x", "cpu")["designs"][0]["verify"]
    assert list(block) == [
        "solver_peak_plate_stress_mpa",
        "solver_max_deflection_mm",
        "peak_plate_stress_error_pct",
        "max_deflection_error_pct",
        "model_rebounds",
        "solver_rebounds",
        "rebound_agrees",
        "peak_plate_frame_error",
        "peak_ball_stress_error_pct",
        "far_deflection_error_um",
        "peak_plate_location_error_mm",
        "position_rmse_mm",
        "solver_peak_plate_t95_ms",
        "peak_plate_t95_frame_error",
        "critical_node_history_correlation",
        "solver_wall_s",
        "speedup",
        "solver_warnings",
        "contact_peak_plate_stress_error_pct",
    ]
    assert block == row.to_json() and json.loads(json.dumps(block)) == block


@pytest.mark.parametrize(
    "model, solver, agree",
    [
        (-1.0, -24.0, False),
        (-20.0, -24.0, True),
        (-13.0, -24.0, False),
        (-10.0, -24.0, False),
        (5.0, -5.0, False),
        (1.0, -0.5, False),
        (3.0, 1.2, False),
        (7.3, 12.2, False),
        (9.0, 12.2, True),
        (15.8, 12.2, True),
        (16.0, 12.2, False),
        (0.0, 0.0, True),
        (0.1, 0.0, False),
        (None, 3.0, None),
    ],
)
def test_trends_agree_by_size_not_only_sign(model, solver, agree):
    """The one rule (hcmt.design.sweep.trends_agree): the same sign and the size within 30 % of the solver's."""
    assert trends_agree(model, solver) is agree


def test_the_sweep_says_disagree_for_a_small_change_against_a_large_one():
    values = [0.5, 0.75, 1.0]
    model = [1000.0, 995.0, 990.0]  # -1 %
    solver = [1000.0, 850.0, 760.0]  # -24 %

    def mk(v, s):
        return SimpleNamespace(
            design=Design(thickness=v), summary=fake_summary(peak_plate_stress_mpa=s, max_deflection_mm=0.1 * s / 1000)
        )

    check = SimpleNamespace(
        preds=[mk(v, s) for v, s in zip(values, model)],
        truth=[mk(v, s) for v, s in zip(values, solver)],
        readout="raw",
        solver_runs=3,
    )
    a = analyse(check, "thickness", None)
    row = a["trend"]["peak_plate_stress_mpa"]
    assert row["agree"] is False and row["model"]["sign"] == row["solver"]["sign"] == -1
    line = format_analysis(a).splitlines()[0]
    assert "(-1.0 %)" in line and "(-24.0 %)" in line and "DISAGREE" in line


# -- the shipped model: the same answer whatever the surrogate ----------------------------------------------------
SHIPPED = PRETRAINED_DIR / "impact_plate_small.surrogate.json"
#: a thin plate dropped from high: the shipped surrogate's bound of when the ball leaves falls inside the window
DESIGN = ["thickness=0.55", "drop_height=950"]
SURROGATE_FIELDS = (
    "surrogate",
    "disagreement",
    "disagreement_by_answer",
    "notes",
    "low_confidence",
    "warnings",
    "wall_s",
)


def _another_fitting_surrogate(tmp_path) -> str:
    """The shipped surrogate as a format 2 file of the model's own data, its contact end answers 30 % earlier:
    it fits the model, and its bound of when the ball leaves differs from the shipped one's."""
    doc = json.loads(SHIPPED.read_text())
    run = Run.load("pretrained:impact_plate_small", "cpu")
    doc["version"] = 2
    doc["answers"]["contact_end_ms"] = [0.7 * v for v in doc["answers"]["contact_end_ms"]]
    doc["dataset"] = dataset_facts(run.meta, "train", "stress", doc["answers"])
    path = tmp_path / "other.surrogate.json"
    path.write_text(json.dumps(doc))
    return str(path)


@pytest.mark.slow  # three rollouts of the shipped model
def test_the_default_answer_is_the_same_with_any_surrogate_or_none(tmp_path, capsys):
    """Before: the JSON's plate stress history after contact was a bending formula cut at the surrogate's bound,
    so the same design's answer changed with the surrogate file."""
    answers = {}
    for name, extra in (
        ("shipped", []),
        ("none", ["--no-surrogate"]),
        ("other", ["--surrogate", _another_fitting_surrogate(tmp_path)]),
    ):
        out = tmp_path / f"{name}.json"
        assert (
            cli(
                [
                    "predict",
                    "pretrained:impact_plate_small",
                    "--design",
                    *DESIGN,
                    "--json",
                    str(out),
                    "--no-progress",
                    "--device",
                    "cpu",
                    *extra,
                ]
            )
            == 0
        )
        design = json.loads(out.read_text())["designs"][0]
        answers[name] = {k: v for k, v in design.items() if k not in SURROGATE_FIELDS}
    capsys.readouterr()
    assert "surrogate" in json.loads((tmp_path / "other.json").read_text())["designs"][0]  # it was used
    assert answers["shipped"] == answers["none"] == answers["other"]


@pytest.mark.slow
def test_predict_records_the_readout_and_reports_a_derived_one_under_its_own_names(tmp_path, capsys):
    out = tmp_path / "c.json"
    assert (
        cli(
            [
                "predict",
                "pretrained:impact_plate_small",
                "--design",
                *DESIGN,
                "--json",
                str(out),
                "--no-progress",
                "--device",
                "cpu",
                "--readout",
                "contact",
                "--yield-mpa",
                "900",
            ]
        )
        == 0
    )
    printed = capsys.readouterr().out
    doc = json.loads(out.read_text())
    d = doc["designs"][0]
    assert doc["readout"] == d["readout"] == "contact" and CONTACT_KEYS <= set(d)
    assert d["call_interval_mpa"]["model_readout"] == "contact" and "contact MPa" in printed
    assert (
        cli(
            [
                "predict",
                "pretrained:impact_plate_small",
                "--design",
                *DESIGN,
                "--json",
                str(out),
                "--no-progress",
                "--device",
                "cpu",
            ]
        )
        == 0
    )
    d = json.loads(out.read_text())["designs"][0]
    assert d["readout"] == "raw" and not any(k.startswith(("contact_peak", "contact_plate")) for k in d)
