"""The mesh model's own interval (hcmt.design.model_interval): cells by distance from the training ranges, the
split-conformal bound against its definition and its coverage on synthetic errors, the file, and the design check
that attaches it and trusts it in the calls."""

import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

import hcmt
from hcmt.design.calls import call_of, outside_reason, trusted_bounds
from hcmt.design.check import check_designs
from hcmt.design.model_interval import (
    ANSWERS,
    BAND_FRAMES,
    MIN_DESIGNS,
    Calibration,
    Cell,
    cell_of,
    conformal_half_width,
    covers,
    fit,
    history_score,
)
from hcmt.design.summary import SurrogateAnswer
from hcmt.errors import InputError
from hcmt.sim.params import DESIGN_KEYS, Design

RANGES = {"thickness": (0.5, 1.0), "drop_height": (500.0, 1000.0), "plate_half_length": (12.0, 12.0)}
BASE = Design(thickness=0.75, drop_height=750.0, plate_half_length=12.0)


@pytest.mark.parametrize(
    "change,cell",
    [
        ({}, "inside"),
        ({"thickness": 1.0}, "inside"),
        ({"thickness": 1.05}, "thickness+:0.2"),
        ({"thickness": 1.1}, "thickness+:0.2"),
        ({"thickness": 1.15}, "thickness+:0.4"),
        ({"thickness": 0.45}, "thickness-:0.2"),
        ({"drop_height": 1300.0}, "drop_height+:0.6"),
        ({"thickness": 1.05, "drop_height": 1150.0}, "drop_height+,thickness+:0.4"),
        ({"plate_half_length": 13.0}, "plate_half_length+:0.2"),
    ],
)
def test_cell_names_the_sides_and_the_distance_out(change, cell):
    assert cell_of(replace(BASE, **change), RANGES) == cell


def test_conformal_bound_is_the_order_statistic_of_its_definition():
    scores = np.random.default_rng(0).permutation(np.arange(1.0, 40.0))  # 39 scores: k = ceil(40 * 0.95) = 38
    assert conformal_half_width(scores) == 38.0
    assert conformal_half_width(np.arange(1.0, MIN_DESIGNS + 1.0)) == MIN_DESIGNS  # the smallest finite case
    assert math.isinf(conformal_half_width(np.arange(1.0, MIN_DESIGNS)))  # one design fewer: no finite bound


def _summary(peak, deflection, history):
    return SimpleNamespace(
        peak_plate_stress_mpa=peak, max_deflection_mm=deflection, plate_stress_history_mpa=list(history)
    )


def _synthetic(rng, n, bias, spread):
    """n (design, model, solver) triples inside the ranges: the solver = the model x exp(bias + noise)."""
    out = []
    for _ in range(n):
        peak, defl = rng.uniform(400, 900), rng.uniform(0.05, 0.3)
        t = np.linspace(0, 1, 30)
        shape = np.sin(np.pi * t) ** 2
        noise = rng.normal(0, spread, 3)
        model = _summary(peak, defl, peak * shape)
        solver = _summary(
            peak * math.exp(bias + noise[0]),
            defl * math.exp(bias / 2 + noise[1]),
            peak * shape * math.exp(bias + noise[2]),
        )
        out.append((BASE, model, solver))
    return out


def test_fitted_interval_covers_95_percent_of_fresh_synthetic_errors_and_learns_the_bias():
    rng = np.random.default_rng(1)
    cal = fit(_synthetic(rng, 200, -0.08, 0.04), RANGES, "synthetic")
    cell = cal.cells["inside"]
    assert cell.designs == 200 and abs(cell.center["peak_plate_stress_mpa"] + 0.08) < 0.01
    hits = {a: 0 for a in (*ANSWERS, "plate_stress_history_mpa")}
    fresh = _synthetic(rng, 2000, -0.08, 0.04)
    for design, model, solver in fresh:
        iv = cal.interval(design, RANGES, {a: getattr(model, a) for a in ANSWERS}, model.plate_stress_history_mpa)
        for k, v in covers(iv, solver).items():
            hits[k] += v
    for k, v in hits.items():
        assert 0.925 <= v / len(fresh) <= 0.985, (k, v)  # nominal 95 %; 2,000 draws: +-1 % sampling error


def test_interval_is_the_model_times_exp_center_plus_minus_half_width():
    cal = Calibration(
        "m",
        0.95,
        {
            "thickness+:0.2": Cell(
                24,
                {"peak_plate_stress_mpa": 0.1, "max_deflection_mm": 0.0},
                {"peak_plate_stress_mpa": 0.05, "max_deflection_mm": 0.2},
                0.1,
            )
        },
        {},
    )
    d = replace(BASE, thickness=1.05)
    history = [0.0, 100.0, 200.0, 300.0, 500.0, 300.0, 100.0, 50.0]
    iv = cal.interval(d, RANGES, {"peak_plate_stress_mpa": 500.0, "max_deflection_mm": 0.1}, history)
    assert iv.bounds["peak_plate_stress_mpa"] == pytest.approx((500 * math.exp(0.05), 500 * math.exp(0.15)))
    assert iv.bounds["max_deflection_mm"] == pytest.approx((0.1 * math.exp(-0.2), 0.1 * math.exp(0.2)))
    near = [history[max(t - BAND_FRAMES, 0) : t + BAND_FRAMES + 1] for t in range(len(history))]  # the envelope
    assert iv.history_lo_mpa == pytest.approx([max(min(w) - 50.0, 0.0) for w in near])  # band 0.1 x the peak 500
    assert iv.history_hi_mpa == pytest.approx([max(w) + 50.0 for w in near])
    assert cal.interval(BASE, RANGES, {"peak_plate_stress_mpa": 500.0, "max_deflection_mm": 0.1}, [1.0]) is None
    assert "inside was not calibrated" in cal.reason(BASE, RANGES)


def test_cells_with_too_few_designs_are_left_out():
    rng = np.random.default_rng(2)
    triples = _synthetic(rng, 40, 0.0, 0.03)
    triples += [(replace(BASE, thickness=1.05), m, s) for _, m, s in _synthetic(rng, MIN_DESIGNS - 1, 0.0, 0.03)]
    assert set(fit(triples, RANGES, "m").cells) == {"inside"}


def test_file_round_trip_and_refusal(tmp_path):
    cal = fit(_synthetic(np.random.default_rng(3), 30, 0.02, 0.03), RANGES, "m", {"seed": 5})
    back = Calibration.load(cal.save(tmp_path / "m.interval.json"))
    assert back == cal
    (tmp_path / "bad.json").write_text('{"format": "something else"}')
    with pytest.raises(InputError, match="bad.json: not a model interval calibration"):
        Calibration.load(tmp_path / "bad.json")


def test_history_score_is_how_far_the_solver_leaves_the_envelope():
    model = _summary(500.0, 0.1, [0.0, 100.0, 500.0, 100.0, 0.0, 0.0, 0.0, 0.0])
    late = _summary(0.0, 0.0, [0.0, 0.0, 100.0, 500.0, 100.0, 0.0, 0.0, 0.0])  # one frame late: inside the envelope
    assert history_score(model, late) == 0.0
    high = _summary(0.0, 0.0, [0.0, 100.0, 600.0, 100.0, 0.0, 0.0, 0.0, 80.0])  # 100 MPa over the peak, 80 late
    assert history_score(model, high) == pytest.approx(100.0 / 500.0)


def test_calls_trust_the_interval_and_decide_outside_only_where_calibrated():
    iv = (600.0, 700.0)
    assert trusted_bounds(650.0, None, "model", iv) == (600.0, 700.0, "model interval")
    assert trusted_bounds(650.0, SurrogateAnswer(640.0, 620.0, 720.0), "union", iv) == (600.0, 720.0, "union")
    assert trusted_bounds(650.0, None, "model", None)[2] == "model"  # no interval: the old band
    assert call_of(*iv, 720.0) == "pass" and call_of(*iv, 650.0) == "undecided"


@pytest.fixture(scope="module")
def shipped():
    return hcmt.load_pretrained("impact_plate_small", "cpu")


@pytest.mark.slow  # rolls the shipped model out
def test_check_attaches_the_interval_and_calls_outside_only_in_calibrated_cells(shipped):
    """Two designs of the shipped model (short window): one inside, one thicker. A calibration with only the
    thicker cell: the thicker design gets that interval (model x exp(b +- w) of its own answer) and a decided call
    although it lies outside the ranges; the inside one gets none and the old rules."""
    ranges = shipped.ranges
    thick = ranges["thickness"][1] + 0.1 * (ranges["thickness"][1] - ranges["thickness"][0])
    designs = [
        ("in", hcmt.design_for(shipped, thickness=0.7, drop_height=700)),
        ("thick", hcmt.design_for(shipped, thickness=thick, drop_height=700)),
    ]
    cell = cell_of(designs[1][1], ranges)
    cal = Calibration(
        shipped.source, 0.95, {cell: Cell(30, {a: 0.1 for a in ANSWERS}, {a: 0.05 for a in ANSWERS}, 0.2)}, {}
    )
    check = check_designs(shipped, designs, yield_mpa=5000.0, surrogate=False, interval=cal, progress=False)
    inside, out = (p.summary for p in check.preds)
    assert inside.model_interval is None and out.model_interval is not None
    lo, hi = out.model_interval.bounds["peak_plate_stress_mpa"]
    assert (lo, hi) == pytest.approx(
        (out.peak_plate_stress_mpa * math.exp(0.05), out.peak_plate_stress_mpa * math.exp(0.15))
    )
    assert out.call == "pass" and out.call_interval_mpa.source == "model interval"
    assert outside_reason(check.preds[1], ranges) is None
    assert outside_reason(check.preds[1], ranges, "surrogate")  # the surface alone was never calibrated out there
    assert out.to_json()["model_interval"]["cell"] == cell
    uncal = check_designs(shipped, designs[1:], yield_mpa=5000.0, surrogate=False, interval=False, progress=False)
    assert uncal.preds[0].summary.call == "undecided"  # outside, no calibrated cell: the solver decides


@pytest.mark.slow  # rolls the shipped model out
def test_fuzz_far_outside_the_ranges_no_decided_call_where_nothing_was_calibrated(shipped):
    """Designs 1-3 parameters beyond the training ranges by half a range to ten ranges, either side, any yield
    stress: the calibrated cells reach 0.4 of a range out, so none of them is decided (the solver decides with
    --verify auto). A small, fast version of benchmarks/trust/run.py --fuzz."""
    rng = np.random.default_rng(52)
    varied = [k for k, (lo, hi) in shipped.ranges.items() if hi > lo and k in DESIGN_KEYS]
    cal = Calibration(
        shipped.source,
        0.95,
        {
            c: Cell(30, {a: 0.0 for a in ANSWERS}, {a: 0.05 for a in ANSWERS}, 0.2)
            for c in ("inside", "thickness+:0.2", "thickness+:0.4")
        },
        {},
    )
    designs = []
    while len(designs) < 4:
        base = hcmt.design_for(shipped)
        change = {}
        for key in rng.choice(varied, size=rng.integers(1, 4), replace=False):
            lo, hi = shipped.ranges[key]
            out = (hi - lo) * rng.uniform(0.5, 10.0)
            change[key] = hi + out if rng.random() < 0.5 or lo - out <= 0 else lo - out
        try:
            d = replace(base, **change).validate()
        except InputError:
            continue
        if d.thickness <= 1.8 and d.ball_radius <= 8:  # keep the meshes small: a fast test
            designs.append((f"far{len(designs)}", d))
    check = check_designs(
        shipped, designs, yield_mpa=float(rng.uniform(300, 3000)), surrogate=True, interval=cal, progress=False, batch=4
    )
    for p in check.preds:
        assert cell_of(p.design, shipped.ranges) not in cal.cells
        assert p.summary.call == "undecided" and p.summary.final_call == "undecided", (p.name, p.design)


def test_a_higher_level_needs_more_designs_and_a_zero_answer_gets_no_interval():
    rng = np.random.default_rng(4)
    triples = _synthetic(rng, 30, 0.0, 0.03)
    assert set(fit(triples, RANGES, "m", level=0.95).cells) == {"inside"}
    assert fit(triples, RANGES, "m", level=0.99).cells == {}  # 99 % needs 99 designs: no cell, no infinite bound
    cal = fit(triples, RANGES, "m")
    assert cal.interval(BASE, RANGES, {"peak_plate_stress_mpa": 0.0, "max_deflection_mm": 0.1}, [0.0]) is None
    iv = cal.interval(BASE, RANGES, {"peak_plate_stress_mpa": 500.0, "max_deflection_mm": 0.1}, [0.0] * 5)
    solver = _summary(500.0, 0.1, [0.0] * 6)  # one frame more than the model's history: not held
    assert covers(iv, solver)["plate_stress_history_mpa"] is False


def test_intersection_narrows_where_both_intervals_overlap_and_falls_back_to_the_union():
    surface = SurrogateAnswer(660.0, 640.0, 690.0)
    assert trusted_bounds(650.0, surface, "intersection", (600.0, 700.0)) == (640.0, 690.0, "intersection")
    assert trusted_bounds(650.0, surface, "intersection", (700.0, 760.0))[:2] == (640.0, 760.0)  # disjoint: union
    assert trusted_bounds(650.0, surface, "intersection", None)[:2] == (640.0, 690.0)  # no interval: union with 650
    assert trusted_bounds(650.0, None, "intersection", (600.0, 700.0))[:2] == (600.0, 700.0)  # no surface: its own
