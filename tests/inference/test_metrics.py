"""Metrics against values computed by hand."""

import numpy as np
import pytest

from hcmt.inference.metrics import aggregate, mean_std, rollout_rmse, step_rmse


def test_step_rmse_by_hand():
    true = np.zeros((3, 2, 2))
    pred = np.zeros((3, 2, 2))
    pred[1, 0] = [3.0, 4.0]  # node 0 off by a 3-4-5 vector, node 1 exact: sqrt((25 + 0) / 2)
    pred[2, :] = [1.0, 0.0]  # every node off by 1: 1
    np.testing.assert_allclose(step_rmse(pred, true), [0.0, np.sqrt(12.5), 1.0])


def test_rollout_rmse_horizons_scaled_1e3():
    true = np.zeros((4, 1, 1))
    pred = np.array([0.0, 0.001, 0.002, 0.006]).reshape(4, 1, 1)
    m = rollout_rmse(pred, true)
    assert m["rmse_1"] == pytest.approx(1.0)
    assert m["rmse_50"] == pytest.approx((1 + 2 + 6) / 3)  # fewer than 50 steps: all of them
    assert m["rmse_all"] == pytest.approx(3.0)


def test_aggregate_and_mean_std():
    assert aggregate([{"a": 1.0}, {"a": 3.0}]) == {"a": 2.0}
    ms = mean_std([1.0, 2.0, 3.0])
    assert ms["mean"] == 2.0 and ms["std"] == pytest.approx(1.0) and ms["n"] == 3
    assert mean_std([5.0])["std"] == 0.0


def test_shape_mismatch():
    with pytest.raises(ValueError, match="differs"):
        step_rmse(np.zeros((2, 3, 2)), np.zeros((2, 4, 2)))
