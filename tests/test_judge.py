"""The judge of the model goals (benchmarks/surrogate/run.py): a sweep's trend agrees with the solver's when its sign
is the solver's and its size within 30 % of it, for the model and the response surface alike."""

import sys
from dataclasses import asdict, replace
from pathlib import Path
from types import SimpleNamespace

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
from hcmt.sim.params import Design  # noqa: E402
from surrogate.run import MODEL, trend  # noqa: E402


class LineGP:
    """A response surface whose mean is a given value per design thickness."""

    def __init__(self, means):
        self.means = means

    def predict(self, designs):
        return [{q: SimpleNamespace(mean=v[d.thickness]) for q, v in self.means.items()} for d in designs]


def test_trend_agrees_on_sign_and_size_within_30_percent():
    thin, thick = (replace(Design(), thickness=t) for t in (0.5, 1.0))
    rows = [
        {
            "design": asdict(thin),
            "solver": {"peak_plate_stress_mpa": 100.0, "max_deflection_mm": 2.0},
            "model": {MODEL: {"peak_plate_stress_mpa": 90.0, "max_deflection_mm": 2.2}},
        },
        {
            "design": asdict(thick),
            "solver": {"peak_plate_stress_mpa": 80.0, "max_deflection_mm": 1.5},
            "model": {MODEL: {"peak_plate_stress_mpa": 76.0, "max_deflection_mm": 2.4}},
        },
    ]
    gp = LineGP({"peak_plate_stress_mpa": {0.5: 100.0, 1.0: 95.0}, "max_deflection_mm": {0.5: 2.0, 1.0: 1.4}})
    got = trend(rows, gp)
    peak, defl = got["peak_plate_stress_mpa"], got["max_deflection_mm"]
    assert peak["solver"] == pytest.approx(-0.2) and peak["hcmt"] == pytest.approx(76 / 90 - 1)
    assert peak["hcmt_agrees"] and not peak["gp_agrees"]  # -15.6 % against -20 %: in; -5 % against -20 %: out
    assert not defl["hcmt_agrees"] and defl["gp_agrees"]  # the model's deflection grows where the solver's falls


def test_judge_section_counts_goals_met_and_where_the_response_surface_does_better():
    from surrogate.report import judge

    d = {
        "command": "c",
        "model": "m",
        "seeds": {"in_range": 1, "outside": 2},
        "training_designs": 480,
        "goals": [
            {"goal": "peak", "target": 3.0, "at_least": False, "hcmt": 2.0, "gp": 1.0, "hcmt_met": True},
            {"goal": "rebound", "target": 29, "at_least": True, "hcmt": 28, "gp": None, "hcmt_met": False},
            {"goal": "trends", "target": 10, "at_least": True, "hcmt": 9, "gp": 8, "hcmt_met": False},
        ],
        "trends": {"sweep_600": {"peak_plate_stress_mpa": {"solver": -0.2, "hcmt": -0.25, "gp": None}}},
    }
    lines = []
    judge(lines, d)
    text = "\n".join(lines)
    assert "The model meets 1 of 3 goals" in text and "(2 goals), it does better in 1." in text
    assert "| thickness 0.5 → 1.0 mm at 600 mm | peak plate stress | -20.0 % | -25.0 % | - |" in text
    lines = []
    judge(lines, {})
    assert lines == []  # no judge file: no section


def test_the_note_report_names_the_best_rule_and_judges_hcmts_own_threshold_apart():
    """The rule the benchmark finds best and the threshold hcmt's note ships with (NOTE_DISAGREEMENT) are reported
    side by side; the shipped one is never called the tuned one."""
    from surrogate.report import note

    def rate(hits, large, false, small):
        return {
            "hits": hits,
            "large_errors": large,
            "hit_rate": hits / large if large else None,
            "false_alarms": false,
            "small_errors": small,
            "false_alarm_rate": false / small,
        }

    n = {
        "large_error_pct": 10.0,
        "threshold_pct": 5.0,
        "tuned_on": 36,
        "judged_on": 46,
        "region (the card)": rate(5, 6, 11, 40),
        "model-GP disagreement > 5.0 %": rate(6, 6, 10, 40),
        "shipped_threshold_pct": 10.0,
        "model-GP disagreement > 10.0 % (hcmt's NOTE_DISAGREEMENT)": rate(6, 6, 1, 40),
    }
    lines = []
    note(lines, n)
    text = "\n".join(lines)
    assert "| model-GP disagreement > 10.0 % (hcmt's NOTE_DISAGREEMENT) | 6 / 6 | 1 / 40 |" in text
    assert (
        "fewest false alarms among those that flag at least 80% of the large errors: **model-GP disagreement > "
        "10.0 % (hcmt's NOTE_DISAGREEMENT)**" in text
    )
    assert (
        "hcmt's note uses a model-GP disagreement above 10.0 % (`NOTE_DISAGREEMENT`): on these designs it flagged "
        "6 of 6 large errors with 1 false alarms in 40" in text
    )
    del n["model-GP disagreement > 10.0 % (hcmt's NOTE_DISAGREEMENT)"], n["shipped_threshold_pct"]
    lines = []
    note(lines, n)  # an older result file: the tuned rule, as it was reported then
    assert "**model-GP disagreement > 5.0 %** (`NOTE_DISAGREEMENT`)" in "\n".join(lines)


def test_the_ghost_bullet_says_when_the_learned_ball_leaves_in_words():
    from surrogate.report import when

    same = "at the solver's frame in the median"
    assert when(0.0, False) == same and when(0.4, True) == same
    assert when(14.0, True) == "a median 14 frames later" and when(-3.0, False) == "a median 3 frames earlier"


def test_another_checkpoint_reuses_the_judges_solver_runs_and_rolls_out_only_the_model(tmp_path, monkeypatch):
    """``--solver-from``: a group's solver trajectories come from the first judge's cache (verify off: the solver
    does not run again), the model's from this model; a cache of other designs is refused."""
    import numpy as np

    import surrogate.run as judge_run
    from surrogate.run import CACHED, cache_group

    def traj(seed):
        rng = np.random.default_rng(seed)
        return SimpleNamespace(
            world_pos=rng.random((3, 4, 2)),
            stress=rng.random((3, 4)),
            mesh_pos=rng.random((4, 2)),
            cells=np.arange(6).reshape(2, 3),
            node_type=np.zeros(4),
            modulus=np.ones(4),
            wall_s=float(seed),
        )

    calls = []

    def fake_check(run, designs, *, batch, verify, surrogate, progress):
        calls.append(verify)
        preds = [traj(10 + i) for i in range(len(designs))]
        for p, i in zip(preds, range(len(designs))):
            p.mesh_pos = traj(i).mesh_pos  # the designs' meshes, as the first judge's
        return SimpleNamespace(preds=preds, truth=[traj(i) for i in range(len(designs))] if verify else None)

    monkeypatch.setattr(judge_run, "check_designs", fake_check)
    designs = [("a", None), ("b", None)]
    first = tmp_path / "first"
    first.mkdir()
    cache_group(None, "in_range", designs, first, 8)  # the first judge: model and solver
    assert calls == [True]
    with np.load(first / "in_range.npz") as z:
        assert sorted(z.files) == sorted(f"{i}_{k}" for i in range(2) for k in CACHED)
        solver = {k: z[k] for k in z.files if "solver" in k}
    second = tmp_path / "second"
    second.mkdir()
    path = cache_group(None, "in_range", designs, second, 8, solver_from=first)
    assert calls == [True, False]  # the solver did not run again
    with np.load(path) as z:
        for k, v in solver.items():
            np.testing.assert_array_equal(z[k], v)
        np.testing.assert_array_equal(z["1_model_stress"], traj(11).stress)
        assert z["1_wall"].tolist() == [11.0, 1.0]  # this model's time, the first judge's solver time
    assert cache_group(None, "in_range", designs, second, 8, solver_from=first) == path and len(calls) == 2  # cached
    with pytest.raises(SystemExit, match="the group has 3"):
        cache_group(None, "in_range", designs + [("c", None)], tmp_path, 8, solver_from=first)
