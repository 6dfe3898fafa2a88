"""The paper's rollout metrics.

For a predicted trajectory ``pred`` [T, N, D] against ground truth ``true`` [T, N, D] whose frame 0 is the
initial condition, the error at step ``t`` is the RMSE over nodes of the error vector,

    e_t = sqrt( (1/N) Σ_i ||pred_t,i − true_t,i||² ),

and ``rmse_h`` is its mean over steps 1..h (``rmse_all``: over every predicted step). Trajectory values are then
averaged over trajectories. The paper reports them ×10³ (``SCALE``); :func:`rollout_rmse` returns them so scaled.
"""
from __future__ import annotations

import numpy as np

SCALE = 1e3
HORIZONS = {"rmse_1": 1, "rmse_50": 50, "rmse_all": None}


def step_rmse(pred: np.ndarray, true: np.ndarray) -> np.ndarray:
    """[T, N, D] × 2 → [T]: RMSE over nodes of the per-node error vector at each step."""
    pred, true = np.asarray(pred, np.float64), np.asarray(true, np.float64)
    if pred.shape != true.shape:
        raise ValueError(f"prediction shape {pred.shape} differs from ground truth {true.shape}")
    return np.sqrt(((pred - true) ** 2).sum(-1).mean(-1))


def rollout_rmse(pred: np.ndarray, true: np.ndarray, start: int = 1) -> dict[str, float]:
    """rmse_1, rmse_50 and rmse_all (×10³) of one trajectory; ``start`` is the first predicted frame."""
    e = step_rmse(pred, true)[start:]
    out = {}
    for name, h in HORIZONS.items():
        out[name] = float(e[: h if h else len(e)].mean() * SCALE)
    return out


def aggregate(per_trajectory: list[dict[str, float]]) -> dict[str, float]:
    """Mean over trajectories of each metric."""
    keys = per_trajectory[0].keys()
    return {k: float(np.mean([m[k] for m in per_trajectory])) for k in keys}


def mean_std(values) -> dict[str, float]:
    """Mean ± sample standard deviation (ddof=1, as across seeds in the paper's tables; 0 for one value)."""
    v = np.asarray(list(values), np.float64)
    return {"mean": float(v.mean()), "std": float(v.std(ddof=1)) if v.size > 1 else 0.0, "n": int(v.size)}


def summarize_runs(metrics: list[dict]) -> dict:
    """Mean ± std over runs (seeds) of ``metrics.json`` dicts: ``{"position": {"rmse_1": {mean, std, n}, ...},
    "stress": ..., "train_ms_per_step": ..., "inference_ms_per_step": ...}`` (a missing time counts as NaN)."""
    out = {}
    for q in ("position", "stress"):
        if all(q in m for m in metrics):
            out[q] = {k: mean_std(m[q][k] for m in metrics) for k in HORIZONS}
    for key in ("train_ms_per_step", "inference_ms_per_step"):
        out[key] = mean_std(np.nan if m.get(key) is None else m[key] for m in metrics)
    return out


def rollout_details(pred: np.ndarray, true: np.ndarray, start: int, groups: dict[str, np.ndarray]) -> dict:
    """Where the error sits: ``{"by_step": [T - start] error per predicted step (×10³), "groups": {name: rmse_all
    over that group's nodes only (×10³)}}`` for one trajectory; ``groups`` maps a name to a node mask ``[N]``."""
    e = step_rmse(pred, true)[start:] * SCALE
    out = {"by_step": e.tolist(), "groups": {}}
    for name, mask in groups.items():
        out["groups"][name] = float(step_rmse(pred[:, mask], true[:, mask])[start:].mean() * SCALE)
    return out
