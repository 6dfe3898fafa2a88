"""Prediction.summary is a typed Summary (hcmt.design.summary) whose JSON keeps the keys (and their order) the
design check wrote as plain dicts: tests/design/summary_json_keys.json was recorded from that code (commit
1b29aa3, the shipped model on one design: with a yield stress; contact read-out with the solver; no surrogate)."""
from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from hcmt.design.summary import KEYS, Summary

RECORDED = json.loads((Path(__file__).with_name("summary_json_keys.json")).read_text())


def test_typed_fields_and_mapping_agree_and_keep_the_order_set():
    s = Summary.of({"peak_plate_stress_mpa": 612.0, "readout": "contact", "contact_peak_plate_stress_mpa": 580.0})
    s["call"] = "pass"
    s.verified = True  # a typed field set as an attribute is a key too
    assert s.peak_plate_stress_mpa == 612.0 and s["contact_peak_plate_stress_mpa"] == 580.0
    assert s.extra == {"contact_peak_plate_stress_mpa": 580.0}
    assert list(s) == ["peak_plate_stress_mpa", "readout", "contact_peak_plate_stress_mpa", "call", "verified"]
    assert s.to_json() == dict(s) == {**s} and "verify" not in s and s.get("verify") is None
    with pytest.raises(KeyError):
        s["verify"]
    t = copy.deepcopy(s)
    del t["call"]
    assert "call" not in t and t.call is None and "call" in s
    assert "extra" not in KEYS and "final_call" in KEYS


def test_every_recorded_key_but_the_read_outs_is_a_typed_field():
    for keys in RECORDED.values():
        for k in keys:
            assert k in KEYS or k.startswith(("contact_", "element_")) or k in ("name", "design", "notes"), k


@pytest.mark.slow  # the shipped model on one design three times, and the solver once (~1.5 min on one thread)
def test_the_json_keys_are_unchanged():
    from hcmt.design.check import check_designs
    from hcmt.design.inputs import design_for
    from hcmt.design.reports import to_json
    from hcmt.inference.run import Run
    run = Run.load("pretrained:impact_plate_small", "cpu")
    designs = [("a", design_for(run, thickness=0.7))]
    for tag, options in (("raw_yield", dict(yield_mpa=750.0)),
                         ("contact_verify", dict(yield_mpa=750.0, verify=True, readout="contact")),
                         ("plain", dict(surrogate=False))):
        c = check_designs(run, designs, progress=False, **options)
        assert isinstance(c.preds[0].summary, Summary)
        got = list(to_json(c.preds, c.verified, run.source, "cpu", c)["designs"][0])
        assert got == RECORDED[f"{tag}_json"], tag
