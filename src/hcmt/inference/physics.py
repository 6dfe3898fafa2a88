"""The Impact Plate physics an engineer reads from a rollout, model against solver (each quantity defined once, in
:mod:`hcmt.inference.quantities`).

Beside the paper's RMSEs (:mod:`hcmt.inference.metrics`), what an engineer reads from an Impact Plate rollout
(:func:`impact_metrics` per trajectory, :func:`summarize_impact` over trajectories): whether the ball rebounds (the
sign of its mean vertical velocity over the window's last step, model vs solver), the peak plate and ball von Mises
stress (signed error %), the frame of the plate's peak (error in frames), the maximum plate deflection
``max |u_y|`` (error %) and the far-field deflection error (plate nodes beyond half the plate's radius: mean
|u_y error| over nodes and predicted frames, in µm and in % of the solver's largest far-field deflection); and the
error by step split into the ball, the contact zone (plate nodes within half the radius) and the far plate
(:func:`hcmt.inference.quantities.impact_groups`).

It stands alone from :mod:`hcmt.inference.metrics` (the paper's RMSEs, for any dataset) because it is Impact Plate's
own, read by evaluation and by the design check's verification alike.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from hcmt.config import plural
from hcmt.inference import quantities as q


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


@dataclass(frozen=True)
class ErrorStats:
    """One signed error over trajectories (:func:`summarize_impact`): the median of |error|, the median signed
    error, the 90th percentile of |error| and the worst (the signed error of largest magnitude)."""

    median_abs: float
    median: float
    p90_abs: float
    worst: float


@dataclass(frozen=True)
class FarFieldStats:
    """The far-field deflection error over trajectories (:func:`summarize_impact`): its median and its worst."""

    median: float
    worst: float


@dataclass(frozen=True)
class ImpactSummary:
    """:func:`summarize_impact` of Impact Plate trajectories, model against solver: how many, the rebound agreement
    (fraction) and how many rebound in model and solver, an :class:`ErrorStats` per signed error of
    :class:`ImpactMetrics` and the far-field deflection error (µm, %). :meth:`to_json` is the ``physics`` block of
    ``metrics_<split>.json`` and of the design check's ``verify``."""

    trajectories: int
    rebound_agreement: float
    model_rebounds: int
    solver_rebounds: int
    # the per-trajectory signed errors, each summarized
    peak_plate_stress_error_pct: ErrorStats
    peak_ball_stress_error_pct: ErrorStats
    peak_plate_frame_error: ErrorStats
    max_deflection_error_pct: ErrorStats
    far_deflection_error_um: FarFieldStats
    far_deflection_error_pct: FarFieldStats

    def to_json(self) -> dict:
        """The fields in order, each record a nested object, as the metrics file writes them."""
        return asdict(self)


def summarize_impact(rows: list[ImpactMetrics]) -> ImpactSummary:
    """Over trajectories: rebound agreement (fraction, and how many rebound in model and solver); for each signed
    error the median of |error|, the median signed error, the 90th percentile of |error| and the worst (the signed
    error of largest magnitude); the far-field deflection error's median and worst."""

    def values(key: str) -> np.ndarray:
        return np.asarray([getattr(r, key) for r in rows], np.float64)

    def signed(key: str) -> ErrorStats:
        v = values(key)
        return ErrorStats(
            median_abs=float(np.median(np.abs(v))),
            median=float(np.median(v)),
            p90_abs=float(np.percentile(np.abs(v), 90)),
            worst=float(v[np.argmax(np.abs(v))]),
        )

    def far(key: str) -> FarFieldStats:
        v = values(key)
        return FarFieldStats(median=float(np.median(v)), worst=float(v.max()))

    return ImpactSummary(
        trajectories=len(rows),
        rebound_agreement=float(np.mean([r.rebound_agrees for r in rows])),
        model_rebounds=int(sum(r.model_rebounds for r in rows)),
        solver_rebounds=int(sum(r.solver_rebounds for r in rows)),
        peak_plate_stress_error_pct=signed("peak_plate_stress_error_pct"),
        peak_ball_stress_error_pct=signed("peak_ball_stress_error_pct"),
        peak_plate_frame_error=signed("peak_plate_frame_error"),
        max_deflection_error_pct=signed("max_deflection_error_pct"),
        far_deflection_error_um=far("far_deflection_error_um"),
        far_deflection_error_pct=far("far_deflection_error_pct"),
    )


def rebound_words(p: ImpactSummary) -> str:
    """Whether the ball rebounds, model against solver, over :func:`summarize_impact`'s trajectories, in plain words
    when neither rebounds (an agreement of n/n then says nothing about rebounds)."""
    n = p.trajectories
    if p.model_rebounds == 0 and p.solver_rebounds == 0:
        return f"rebound: neither the model nor the solver rebounds in {n}/{n}"
    return (
        f"rebound agreement {p.rebound_agreement * n:.0f}/{n} (the ball rebounds in "
        f"{plural(p.model_rebounds, 'prediction')}, {plural(p.solver_rebounds, 'solver run')})"
    )


def format_physics(p: ImpactSummary) -> list[str]:
    """The lines of :func:`summarize_impact` for a terminal."""

    def err(e: ErrorStats, unit=" %"):
        return (
            f"median {e.median_abs:.1f}{unit} (signed {e.median:+.1f}{unit}, p90 {e.p90_abs:.1f}{unit}, "
            f"worst {e.worst:+.1f}{unit})"
        )

    return [
        f"  physics over {plural(p.trajectories, 'trajectory', 'trajectories')}: {rebound_words(p)}",
        f"    peak plate stress error {err(p.peak_plate_stress_error_pct)}",
        f"    time of the plate's peak, frames off: {err(p.peak_plate_frame_error, '')}",
        f"    max deflection error {err(p.max_deflection_error_pct)}",
        f"    far-field deflection error median {p.far_deflection_error_um.median:.1f} µm "
        f"({p.far_deflection_error_pct.median:.0f} % of the solver's far-field peak), worst "
        f"{p.far_deflection_error_um.worst:.1f} µm",
        f"    ball peak stress error {err(p.peak_ball_stress_error_pct)}",
    ]
