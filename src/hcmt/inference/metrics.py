"""The paper's rollout metrics.

For a predicted trajectory ``pred`` [T, N, D] against ground truth ``true`` [T, N, D] whose frame 0 is the
initial condition, the error at step ``t`` is the RMSE over nodes of the error vector,

    e_t = sqrt( (1/N) Σ_i ||pred_t,i − true_t,i||² ),

and ``rmse_h`` is its mean over steps 1..h (``rmse_all``: over every predicted step). Trajectory values are then
averaged over trajectories. The paper reports them ×10³ (``SCALE``); :func:`rollout_rmse` returns them so scaled.

Beside them, what an engineer reads from an Impact Plate rollout (:func:`impact_metrics` per trajectory,
:func:`summarize_impact` over trajectories): whether the ball rebounds (the sign of its mean vertical velocity over
the window's last step, model vs solver), the peak plate and ball von Mises stress (signed error %), the frame of
the plate's peak (error in frames), the maximum plate deflection ``max |u_y|`` (error %) and the far-field
deflection error (plate nodes beyond half the plate's radius: mean |u_y error| over nodes and predicted frames, in
µm and in % of the solver's largest far-field deflection); and the error by step split into the ball, the contact
zone (plate nodes within half the radius) and the far plate (:func:`impact_groups`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields

import numpy as np

from hcmt.config import plural
from hcmt.errors import InputError
from hcmt.inference import quantities as q
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


@dataclass(frozen=True)
class EvalMetrics:
    """What :func:`hcmt.inference.evaluate.evaluate` measures of a run on a split; :meth:`to_json` is
    ``metrics_<split>.json``. Every RMSE (and ``error_by_step``) is ×``scale``, in ``rmse_units``; ``physics``
    (:func:`summarize_impact`) and ``error_by_step`` only for Impact Plate data with stress, ``stress`` only for
    data with stress (None: not written)."""

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
    physics: dict | None = None
    error_by_step: dict[str, list[float]] | None = None  # the ball, the contact zone, the far plate, by step
    per_trajectory: list[dict] = field(default_factory=list)  # {trajectory, position_rmse_*, ..., physics}

    def to_json(self) -> dict:
        """The metrics file's document: the fields in order, ``position`` / ``stress`` / ``physics`` /
        ``error_by_step`` left out where None."""
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if v is None and f.name in ("position", "stress", "physics", "error_by_step"):
                continue
            out[f.name] = asdict(v) if isinstance(v, Rmse) else v
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


# -- Impact Plate: the physics an engineer reads (each quantity defined once, in hcmt.inference.quantities) -------
@dataclass(frozen=True)
class ImpactMetrics:
    """One Impact Plate trajectory, model against solver (:func:`impact_metrics`): stresses MPa, lengths mm,
    velocities mm per frame; errors signed (model - solver) in % of the solver's value, frames or µm as named.
    :meth:`to_json` is its ``physics`` block in ``metrics_<split>.json``."""

    model_ball_vy_end: float
    model_rebounds: bool
    solver_ball_vy_end: float
    solver_rebounds: bool
    rebound_agrees: bool
    peak_plate_stress_mpa: float
    solver_peak_plate_stress_mpa: float
    peak_plate_stress_error_pct: float
    peak_plate_frame_error: int
    peak_ball_stress_mpa: float
    solver_peak_ball_stress_mpa: float
    peak_ball_stress_error_pct: float
    max_deflection_mm: float
    solver_max_deflection_mm: float
    max_deflection_error_pct: float
    far_deflection_error_um: float  # mean |u_y error| over the far plate's nodes and the predicted frames
    far_deflection_error_pct: float  # that, in % of the solver's largest far-field deflection
    model_ghost_ratio: float
    solver_ghost_ratio: float

    def to_json(self) -> dict:
        """The fields in order, as the metrics file writes them."""
        return asdict(self)


def impact_metrics(pred_pos, pred_stress, true_pos, true_stress, plate: np.ndarray, start: int = 2) -> ImpactMetrics:
    """One Impact Plate trajectory, model (``pred_*``) against solver (``true_*``): positions [T, N, 2] mm,
    stress [T, N, 1] MPa, ``plate`` [N] bool (:func:`plate_mask`), ``start`` the first predicted frame; the rest
    positions are the solver's frame 0. Each quantity as :mod:`hcmt.inference.quantities` defines it."""
    pp, tp = np.asarray(pred_pos, np.float64), np.asarray(true_pos, np.float64)
    rest = tp[0]
    peaks = {}
    for body, mask in (("plate", plate), ("ball", ~plate)):
        (a, fa, _), (b, fb, _) = q.peak(pred_stress, mask), q.peak(true_stress, mask)
        peaks[body] = (a, b, float(100.0 * (a - b) / b), fa - fb)
    a, b = q.max_deflection(pp, rest, plate), q.max_deflection(tp, rest, plate)
    far = q.impact_groups(rest, plate)["far"]
    err = np.abs(q.deflection(pp, rest, far) - q.deflection(tp, rest, far))[start:]
    model_rebounds, solver_rebounds = q.rebounds(pp, plate), q.rebounds(tp, plate)
    return ImpactMetrics(
        model_ball_vy_end=q.ball_vy_end(pp, plate),
        model_rebounds=model_rebounds,
        solver_ball_vy_end=q.ball_vy_end(tp, plate),
        solver_rebounds=solver_rebounds,
        rebound_agrees=model_rebounds == solver_rebounds,
        peak_plate_stress_mpa=peaks["plate"][0],
        solver_peak_plate_stress_mpa=peaks["plate"][1],
        peak_plate_stress_error_pct=peaks["plate"][2],
        peak_plate_frame_error=peaks["plate"][3],
        peak_ball_stress_mpa=peaks["ball"][0],
        solver_peak_ball_stress_mpa=peaks["ball"][1],
        peak_ball_stress_error_pct=peaks["ball"][2],
        max_deflection_mm=a,
        solver_max_deflection_mm=b,
        max_deflection_error_pct=float(100.0 * (a - b) / b),
        far_deflection_error_um=float(err.mean() * 1e3),
        far_deflection_error_pct=float(100.0 * err.mean() / max(q.far_deflection(tp, rest, plate), 1e-12)),
        model_ghost_ratio=q.ghost_ratio(q.body_history(pred_stress, plate), q.peak(pred_stress, plate)[0]),
        solver_ghost_ratio=q.ghost_ratio(q.body_history(true_stress, plate), q.peak(true_stress, plate)[0]),
    )


#: per-trajectory signed errors summarized by :func:`summarize_impact`
SIGNED = (
    "peak_plate_stress_error_pct",
    "peak_ball_stress_error_pct",
    "peak_plate_frame_error",
    "max_deflection_error_pct",
)


def summarize_impact(rows: list[ImpactMetrics]) -> dict:
    """Over trajectories: rebound agreement (fraction, and how many rebound in model and solver); for each signed
    error the median of |error|, the median signed error, the 90th percentile of |error| and the worst (the signed
    error of largest magnitude); the far-field deflection error's median and worst."""
    out = {
        "trajectories": len(rows),
        "rebound_agreement": float(np.mean([r.rebound_agrees for r in rows])),
        "model_rebounds": int(sum(r.model_rebounds for r in rows)),
        "solver_rebounds": int(sum(r.solver_rebounds for r in rows)),
    }
    for key in SIGNED:
        v = np.asarray([getattr(r, key) for r in rows], np.float64)
        out[key] = {
            "median_abs": float(np.median(np.abs(v))),
            "median": float(np.median(v)),
            "p90_abs": float(np.percentile(np.abs(v), 90)),
            "worst": float(v[np.argmax(np.abs(v))]),
        }
    for key in ("far_deflection_error_um", "far_deflection_error_pct"):
        v = np.asarray([getattr(r, key) for r in rows], np.float64)
        out[key] = {"median": float(np.median(v)), "worst": float(v.max())}
    return out


def rebound_words(p: dict) -> str:
    """Whether the ball rebounds, model against solver, over :func:`summarize_impact`'s trajectories, in plain words
    when neither rebounds (an agreement of n/n then says nothing about rebounds)."""
    n = p["trajectories"]
    if p["model_rebounds"] == 0 and p["solver_rebounds"] == 0:
        return f"rebound: neither the model nor the solver rebounds in {n}/{n}"
    return (
        f"rebound agreement {p['rebound_agreement'] * n:.0f}/{n} (the ball rebounds in "
        f"{plural(p['model_rebounds'], 'prediction')}, {plural(p['solver_rebounds'], 'solver run')})"
    )


def format_physics(p: dict) -> list[str]:
    """The lines of :func:`summarize_impact` for a terminal."""

    def err(key, unit=" %"):
        e = p[key]
        return (
            f"median {e['median_abs']:.1f}{unit} (signed {e['median']:+.1f}{unit}, p90 {e['p90_abs']:.1f}{unit}, "
            f"worst {e['worst']:+.1f}{unit})"
        )

    n = p["trajectories"]
    return [
        f"  physics over {plural(n, 'trajectory', 'trajectories')}: {rebound_words(p)}",
        f"    peak plate stress error {err('peak_plate_stress_error_pct')}",
        f"    time of the plate's peak, frames off: {err('peak_plate_frame_error', '')}",
        f"    max deflection error {err('max_deflection_error_pct')}",
        f"    far-field deflection error median {p['far_deflection_error_um']['median']:.1f} µm "
        f"({p['far_deflection_error_pct']['median']:.0f} % of the solver's far-field peak), worst "
        f"{p['far_deflection_error_um']['worst']:.1f} µm",
        f"    ball peak stress error {err('peak_ball_stress_error_pct')}",
    ]
