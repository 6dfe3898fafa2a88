"""Prediction.summary is a typed, frozen Summary (hcmt.design.summary) whose JSON keeps the keys (and their order)
the design check wrote as plain dicts: tests/design/summary_json_keys.json was recorded from that code (commit
1b29aa3, the shipped model on one design: with a yield stress; contact read-out with the solver; no surrogate),
with the mesh model's own interval (``model_interval``) added after ``confidence`` since.
Each field's declared type is checked against the values of a real run (:func:`summaries.type_errors`): the
shipped model's check of one design, and a tiny solver run. The model card's region (``confidence``) and the response
surface's answers (``surrogate``) are typed records too (:class:`Confidence`, :class:`SurrogateAnswer`), each writing
its block of the JSON as the plain dicts did: the card's entry, ``{mean, lo, hi}`` per answer."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from pathlib import Path

import pytest

from hcmt.design.summary import Confidence, PlateReadout, Summary, SurrogateAnswer, VerifyRow
from summaries import fake_summary, type_errors

RECORDED = json.loads((Path(__file__).with_name("summary_json_keys.json")).read_text())


def test_a_summary_is_frozen_and_no_mapping():
    s = fake_summary(peak_plate_stress_mpa=612.0, readout="contact")
    assert not isinstance(s, Mapping) and s.peak_plate_stress_mpa == 612.0
    with pytest.raises(TypeError):
        s["peak_plate_stress_mpa"]
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.call = "pass"
    with pytest.raises(TypeError):  # an unknown field is an error, never a silent extra key
        dataclasses.replace(s, contact_peak_plate_stress_mpa=580.0)
    with pytest.raises(TypeError):
        Summary(**{**dataclasses.asdict(s), "made_up": 1})


def test_the_json_writes_the_declared_order_derived_fields_under_their_names_and_leaves_unset_ones_out():
    derived = PlateReadout(580.0, [0.0, 1.0], 0.004, 2, 7, 2, 0.004, [1.0, 580.0], 0.01, "the ball's last touch", 5.0)
    s = dataclasses.replace(
        fake_summary(peak_plate_stress_mpa=612.0, readout="contact", derived=derived),
        yield_margin_mpa=88.0,
        derived_yield_margin_mpa=120.0,
        call="pass",
        model="m",
    )
    j = s.to_json()
    assert j["contact_peak_plate_stress_mpa"] == 580.0 and j["contact_bending_k"] == 5.0
    assert j["contact_yield_margin_mpa"] == 120.0 and "derived" not in j and "derived_yield_margin_mpa" not in j
    assert j["contact_frames"] is None  # a trajectory quantity: always written
    assert j["confidence"] is None and "verify" not in j and "final_call" not in j  # annotated: confidence null
    keys = list(j)
    assert keys.index("readout") < keys.index("contact_peak_plate_stress_mpa") < keys.index("wall_s")
    assert keys.index("yield_margin_mpa") + 1 == keys.index("contact_yield_margin_mpa") < keys.index("call")
    element = dataclasses.replace(derived, window_end_ms=None, window_end_from=None, bending_k=None)
    assert not any(
        k.startswith("element_window") for k in dataclasses.replace(s, readout="element", derived=element).to_json()
    )


def test_every_recorded_key_is_a_declared_field_or_a_derived_read_outs():
    declared = {f.name for f in dataclasses.fields(Summary)}
    derived = {f"{r}_{f.name}" for r in ("contact", "element") for f in dataclasses.fields(PlateReadout)}
    derived |= {"contact_yield_margin_mpa", "element_yield_margin_mpa"}
    for keys in RECORDED.values():
        for k in keys:
            assert k in declared | derived or k in ("name", "design", "notes"), k


def test_the_type_check_finds_a_wrong_type():
    assert type_errors(fake_summary(peak_plate_frame=3)) == []
    assert any("peak_plate_frame" in e for e in type_errors(fake_summary(peak_plate_frame=3.0)))
    assert any("contact_frames" in e for e in type_errors(fake_summary(contact_frames=4)))  # an int: the old type
    # the nested records: a plain dict where a record is declared, and a wrong type inside a record
    block = {"mean": 680.0, "lo": 660.0, "hi": 700.0}
    assert any("Summary.surrogate" in e for e in type_errors(fake_summary(surrogate={"peak_plate_stress_mpa": block})))
    assert any("Summary.confidence" in e for e in type_errors(fake_summary(confidence={"region": "outside"})))
    wrong = {"peak_plate_stress_mpa": SurrogateAnswer(680, 660.0, 700.0)}  # an int mean
    assert any("SurrogateAnswer.mean" in e for e in type_errors(fake_summary(surrogate=wrong)))
    assert any("Confidence.designs" in e for e in type_errors(fake_summary(confidence=Confidence("inside", "", 2.0))))


CARD_ENTRY = {
    "region": "thin",
    "label": "thin plates (lowest fifth of thickness)",
    "designs": 4,
    "peak_plate_stress_error_pct_median": 2.3,
    "peak_plate_stress_error_pct_worst": 4.6,
    "max_deflection_error_pct_median": 4.1,
    "rebound_agreement": 1.0,
}


def test_the_records_write_the_blocks_the_dicts_did():
    """``confidence``: the card's entry as it is (outside: region, label and designs only), null for an annotated
    design the card has no region for; ``surrogate``: ``{answer: {mean, lo, hi}}``."""
    c = Confidence.from_card(CARD_ENTRY)
    assert type_errors(c) == [] and c.to_json() == CARD_ENTRY and list(c.to_json()) == list(CARD_ENTRY)
    outside = Confidence("outside", "outside the training ranges", 0)
    assert outside.to_json() == {"region": "outside", "label": "outside the training ranges", "designs": 0}
    answers = {
        "peak_plate_stress_mpa": SurrogateAnswer(680.0, 660.0, 700.0),
        "max_deflection_mm": SurrogateAnswer(0.15, 0.14, 0.16),
    }
    s = fake_summary(model="m", confidence=c, surrogate=answers)
    j = s.to_json()
    assert j["confidence"] == CARD_ENTRY and list(j["confidence"]) == list(CARD_ENTRY)
    assert j["surrogate"] == {q: dataclasses.asdict(a) for q, a in answers.items()}
    assert [list(v) for v in j["surrogate"].values()] == [["mean", "lo", "hi"]] * 2
    assert fake_summary(model="m").to_json()["confidence"] is None and "surrogate" not in fake_summary().to_json()
    assert "confidence" not in fake_summary().to_json()  # not annotated by the check: left out
    with pytest.raises(dataclasses.FrozenInstanceError):
        answers["peak_plate_stress_mpa"].mean = 1.0


@pytest.mark.slow  # the shipped model on one design, no solver (~15 s on one thread)
def test_a_real_check_holds_a_typed_confidence_and_surrogate():
    """The shipped model's check of a thin plate (a region its card measured) with its own response surface: the
    nested records hold the declared types, and their JSON blocks are the card's entry and ``{mean, lo, hi}``."""
    from hcmt.design.check import check_designs
    from hcmt.design.inputs import design_for, region_of
    from hcmt.inference.run import Run

    run = Run.load("pretrained:impact_plate_small", "cpu")
    design = design_for(run, thickness=0.55)
    assert region_of(design, run.ranges) == "thin"
    (p,) = check_designs(run, [("thin", design)], progress=False, yield_mpa=750.0).preds
    s = p.summary
    assert isinstance(s, Summary) and type_errors(s) == []
    assert isinstance(s.confidence, Confidence) and s.confidence.region == "thin"
    assert s.confidence.peak_plate_stress_error_pct_median is not None
    assert s.surrogate is not None and set(s.surrogate) >= {"peak_plate_stress_mpa", "max_deflection_mm"}
    assert all(isinstance(a, SurrogateAnswer) and a.lo <= a.mean <= a.hi for a in s.surrogate.values())
    entry = next(r for r in run.card["confidence"] if r["region"] == "thin")
    j = s.to_json()
    assert j["confidence"] == entry and list(j["confidence"]) == list(entry)  # the card's entry, as it was written
    assert j["surrogate"] == {q: {"mean": a.mean, "lo": a.lo, "hi": a.hi} for q, a in s.surrogate.items()}


@pytest.mark.slow  # the shipped model on one design three times, and the solver once (~1.5 min on one thread)
def test_the_json_keys_and_every_fields_type_on_a_real_run():
    from hcmt.design.check import check_designs
    from hcmt.design.inputs import design_for
    from hcmt.design.reports import to_json
    from hcmt.design.verification import VerifySummary, verify_row
    from hcmt.inference.run import Run

    run = Run.load("pretrained:impact_plate_small", "cpu")
    designs = [("a", design_for(run, thickness=0.7))]
    for tag, options in (
        ("raw_yield", dict(yield_mpa=750.0)),
        ("contact_verify", dict(yield_mpa=750.0, verify=True, readout="contact")),
        ("plain", dict(surrogate=False)),
    ):
        c = check_designs(run, designs, progress=False, **options)
        assert isinstance(c.preds[0].summary, Summary)
        assert type_errors(c.preds[0].summary) == [], tag
        if c.truth:
            assert type_errors(c.truth[0].summary) == [] and isinstance(c.preds[0].summary.verify, VerifyRow)
            assert type_errors(verify_row(c.preds[0], c.truth[0])[1]) == []  # the physics block: ImpactMetrics
            # the summary over designs: a VerifySummary of Stats, its physics an ImpactSummary, how it was measured
            assert isinstance(c.verified, VerifySummary) and type_errors(c.verified) == []
            assert c.verified.speedup_measured is not None and c.verified.readout_errors  # the contact read-out's
        got = list(to_json(c.preds, c.verified, run.source, "cpu", c)["designs"][0])
        assert got == RECORDED[f"{tag}_json"], tag


def test_a_tiny_simulate_is_typed_and_so_are_its_quantities():
    from hcmt.design.readout import summarize_fields
    from hcmt.sim.driver import SimResult, SolveInfo, simulate
    from hcmt.sim.params import Design, Settings

    r = simulate(Design(thickness=1.0, mesh_size=0.6, plate_half_length=8.0), Settings(frames=4))
    assert isinstance(r, SimResult) and isinstance(r.info, SolveInfo) and not isinstance(r, Mapping)
    assert type_errors(r) == []
    assert type_errors(summarize_fields(r.fields, 0.002, "contact")) == []
    assert type_errors(summarize_fields(r.fields, 0.002, "element")) == []
