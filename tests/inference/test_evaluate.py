"""Evaluation's typed results (:func:`hcmt.inference.evaluate.evaluate`): an :class:`EvalMetrics` whose physics is an
:class:`ImpactSummary` and whose rows are :class:`TrajectoryMetrics`, every field of its declared type, and the
metrics file their ``to_json``: the same keys in the same order as before they were typed."""

import json
from dataclasses import replace

import pytest

from hcmt.inference.evaluate import evaluate
from hcmt.inference.metrics import EvalMetrics, Rmse, TrajectoryMetrics
from hcmt.inference.physics import ErrorStats, FarFieldStats, ImpactMetrics, ImpactSummary
from hcmt.inference.run import Run
from summaries import type_errors

pytestmark = pytest.mark.slow  # rolls the shipped model out on the generated dataset

PHYSICS_KEYS = [
    "trajectories",
    "rebound_agreement",
    "model_rebounds",
    "solver_rebounds",
    "peak_plate_stress_error_pct",
    "peak_ball_stress_error_pct",
    "peak_plate_frame_error",
    "max_deflection_error_pct",
    "far_deflection_error_um",
    "far_deflection_error_pct",
]
ROW_KEYS = [
    "trajectory",
    *(f"{q}_{k}" for q in ("position", "stress") for k in ("rmse_1", "rmse_50", "rmse_all")),
    "physics",
]


@pytest.fixture(scope="module")
def evaluated(impact_data, tmp_path_factory):
    """The shipped model evaluated on the test split of the generated dataset (conftest), its results written to a
    folder of this module's."""
    out = tmp_path_factory.mktemp("evaluate")
    run = Run.load("pretrained:impact_plate_small", "cpu").writing_to(out)
    return evaluate(run, impact_data, "test", progress=False), out


def test_evaluate_returns_typed_results_every_field_of_its_type(evaluated):
    m, _ = evaluated
    assert isinstance(m, EvalMetrics) and type_errors(m) == []
    p = m.physics
    assert isinstance(p, ImpactSummary) and p.trajectories == m.trajectories == len(m.per_trajectory) == 1
    assert all(isinstance(getattr(p, k), ErrorStats) for k in PHYSICS_KEYS[4:8])
    assert {type(p.far_deflection_error_um), type(p.far_deflection_error_pct)} == {FarFieldStats}
    row = m.per_trajectory[0]
    assert isinstance(row, TrajectoryMetrics) and isinstance(row.position, Rmse) and isinstance(row.stress, Rmse)
    assert isinstance(row.physics, ImpactMetrics) and type_errors(row) == [] and type_errors(p) == []
    assert m.position == Rmse(row.position.rmse_1, row.position.rmse_50, row.position.rmse_all)  # one trajectory
    wrong_row = replace(row, position=Rmse(1, 2.0, 3.0))  # an int RMSE
    assert any("Rmse.rmse_1" in e for e in type_errors(replace(m, per_trajectory=[wrong_row])))
    assert any("EvalMetrics.physics" in e for e in type_errors(replace(m, physics=replace(p, trajectories=1.0))))


def test_the_metrics_file_is_the_results_to_json_with_the_keys_in_order(evaluated):
    m, out = evaluated
    saved = json.loads((out / "metrics_test.json").read_text())
    assert saved == m.to_json() and list(saved) == list(m.to_json())
    assert list(saved["physics"]) == PHYSICS_KEYS
    assert list(saved["physics"]["peak_plate_stress_error_pct"]) == ["median_abs", "median", "p90_abs", "worst"]
    assert list(saved["physics"]["far_deflection_error_um"]) == ["median", "worst"]
    assert [list(r) for r in saved["per_trajectory"]] == [ROW_KEYS]
    assert saved["per_trajectory"][0]["physics"] == m.per_trajectory[0].physics.to_json()
