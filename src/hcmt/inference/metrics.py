"""The paper's rollout metrics.

For a predicted trajectory ``pred`` [T, N, D] against ground truth ``true`` [T, N, D] whose frame 0 is the
initial condition, the error at step ``t`` is the RMSE over nodes of the error vector,

    e_t = sqrt( (1/N) Σ_i ||pred_t,i − true_t,i||² ),

and ``rmse_h`` is its mean over steps 1..h (``rmse_all``: over every predicted step). Trajectory values are then
averaged over trajectories. The paper reports them ×10³ (``SCALE``); :func:`rollout_rmse` returns them so scaled.
The Impact Plate physics beside them: :mod:`hcmt.inference.physics`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields

import numpy as np

from hcmt.errors import InputError
from hcmt.inference.physics import ImpactMetrics, ImpactSummary
from hcmt.inference.quantities import impact_groups, plate_mask  # noqa: F401  (their home before quantities)

SCALE = 1e3
HORIZONS = {"rmse_1": 1, "rmse_50": 50, "rmse_all": None}


def rmse_units(units: dict) -> dict[str, str]:
    """The unit of every RMSE a metrics file stores (×:data:`SCALE` of the data's units, as the paper reports them):
    ``{"position": "0.001 mm", "stress": "0.001 MPa"}`` for the data's ``units`` ``{"length": "mm", "stress":
    "MPa"}`` ("data units" where the data names none)."""
    return {
        q: f"{1 / SCALE:g} {units.get(key) or 'data units'}"
        for q, key in (("position", "length"), ("stress", "stress"))
    }


@dataclass(frozen=True)
class Rmse:
    """The paper's three RMSEs of one quantity (×:data:`SCALE` of the data's units): steps 1, 1-50 and all."""

    rmse_1: float
    rmse_50: float
    rmse_all: float

    def to_json(self) -> dict:
        """The three in order, as the metrics file writes them."""
        return asdict(self)


@dataclass(frozen=True)
class TrajectoryMetrics:
    """One trajectory of :func:`hcmt.inference.evaluate.evaluate`: its RMSEs (×:data:`SCALE`; ``stress`` None for
    data without stress) and, for Impact Plate data with stress, its :class:`ImpactMetrics` (else None).
    :meth:`to_json` is its row of ``per_trajectory`` in ``metrics_<split>.json``."""

    trajectory: str
    position: Rmse
    stress: Rmse | None = None
    physics: ImpactMetrics | None = None

    def to_json(self) -> dict:
        """``{trajectory, position_rmse_1, ..., stress_rmse_all, physics}``: each RMSE under its quantity's prefix,
        ``stress_*`` and ``physics`` left out where None."""
        out: dict = {"trajectory": self.trajectory}
        for name, r in (("position", self.position), ("stress", self.stress)):
            if r is not None:
                out.update({f"{name}_{k}": v for k, v in r.to_json().items()})
        if self.physics is not None:
            out["physics"] = self.physics.to_json()
        return out


@dataclass(frozen=True)
class EvalMetrics:
    """What :func:`hcmt.inference.evaluate.evaluate` measures of a run on a split; :meth:`to_json` is
    ``metrics_<split>.json``. Every RMSE (and ``error_by_step``) is ×``scale``, in ``rmse_units``; ``physics``
    (:func:`hcmt.inference.physics.summarize_impact`) and ``error_by_step`` only for Impact Plate data with stress,
    ``stress`` only for data with stress (None: not written); ``per_trajectory``: each trajectory's own
    (:class:`TrajectoryMetrics`)."""

    split: str
    data: str  # the dataset's folder, resolved
    trajectories: int
    scale: float
    rmse_units: dict[str, str]
    units: dict[str, str]  # the data's own (length, stress)
    warnings: list[str]  # how the dataset differs from the run's training data
    position: Rmse | None
    stress: Rmse | None
    inference_ms_per_step: float
    train_ms_per_step: float | None  # None: the run folder records no training time
    physics: ImpactSummary | None = None
    error_by_step: dict[str, list[float]] | None = None  # the ball, the contact zone, the far plate, by step
    per_trajectory: list[TrajectoryMetrics] = field(default_factory=list)

    def to_json(self) -> dict:
        """The metrics file's document: the fields in order, ``position`` / ``stress`` / ``physics`` /
        ``error_by_step`` left out where None."""
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if v is None and f.name in ("position", "stress", "physics", "error_by_step"):
                continue
            if f.name == "per_trajectory":
                v = [row.to_json() for row in v]
            out[f.name] = v.to_json() if isinstance(v, (Rmse, ImpactSummary)) else v
        return out


def step_rmse(pred: np.ndarray, true: np.ndarray) -> np.ndarray:
    """[T, N, D] × 2 → [T]: RMSE over nodes of the per-node error vector at each step."""
    pred, true = np.asarray(pred, np.float64), np.asarray(true, np.float64)
    if pred.shape != true.shape:
        raise InputError(f"prediction shape {pred.shape} differs from ground truth {true.shape}")
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
    for name in ("position", "stress"):
        if all(name in m for m in metrics):
            out[name] = {k: mean_std(m[name][k] for m in metrics) for k in HORIZONS}
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
