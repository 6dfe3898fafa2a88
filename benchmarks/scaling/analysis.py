"""The scaling study's arithmetic (benchmarks/scaling/run.py writes the points, benchmarks/scaling/report.py words
them): a power law fitted in log-log, its extrapolation, and HCMT's margin over MGN along an axis. Pure numpy."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

#: the errors judged per point: (key in a point's ``errors``, how the report names it)
METRICS = (
    ("position_rmse_all", "position RMSE-all ×10⁻³"),
    ("stress_rmse_all", "stress RMSE-all ×10⁻³"),
    ("peak_error_pct", "peak plate stress error %"),
    ("deflection_error_pct", "max deflection error %"),
    ("ghost_difference", "ghost difference"),
)


def fit_power_law(x, y) -> dict | None:
    """Least squares of ``log y = log c - k log x``: ``{"k", "c", "r2", "points"}`` (``y ≈ c x^-k``), over the
    points with ``x > 0`` and ``y > 0``; None with fewer than two distinct ``x`` among them."""
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    keep = (x > 0) & (y > 0) & np.isfinite(x) & np.isfinite(y)
    x, y = x[keep], y[keep]
    if len(np.unique(x)) < 2:
        return None
    lx, ly = np.log(x), np.log(y)
    slope, intercept = np.polyfit(lx, ly, 1)
    resid = ly - (slope * lx + intercept)
    total = float(((ly - ly.mean()) ** 2).sum())
    r2 = 1.0 - float((resid**2).sum()) / total if total > 0 else 1.0
    return {"k": float(-slope), "c": float(math.exp(intercept)), "r2": r2, "points": int(len(x))}


def extrapolate(fit: dict | None, x: float) -> float | None:
    """The fitted law's value at ``x`` (an extrapolation wherever ``x`` lies outside the fitted points)."""
    return None if fit is None else float(fit["c"] * float(x) ** -fit["k"])


def reaches(fit: dict | None, goal: float) -> float | None:
    """Where the fitted law ``c x^-k`` comes down to ``goal``: ``(c / goal)^(1/k)`` (None when the error does not
    fall, ``k <= 0``)."""
    if fit is None or fit["k"] <= 0:
        return None
    return float((fit["c"] / goal) ** (1.0 / fit["k"]))


def means_by(points: list[dict], model: str, axis: str, metric: str, fixed: dict) -> dict:
    """{axis value: mean over seeds of ``metric``} of ``model``'s points whose other coordinates equal ``fixed``."""
    got: dict = {}
    for p in points:
        if p["model"] != model or any(p[k] != v for k, v in fixed.items()):
            continue
        value = p["errors"].get(metric)
        if value is not None and np.isfinite(value):
            got.setdefault(p[axis], []).append(float(value))
    return {k: float(np.mean(v)) for k, v in sorted(got.items())}


def margin_trend(hcmt: dict, mgn: dict) -> dict | None:
    """HCMT ÷ MGN error at every axis value both hold, and the fitted exponent of that ratio against the axis
    (``k`` > 0: the ratio falls, i.e. HCMT's margin grows); None with fewer than two shared values."""
    shared = sorted(set(hcmt) & set(mgn))
    ratios = {x: hcmt[x] / mgn[x] for x in shared if mgn[x] > 0 and hcmt[x] > 0}
    if len(ratios) < 2:
        return None
    fit = fit_power_law(list(ratios), list(ratios.values()))
    return {"ratios": ratios, "fit": fit}


def run_of(row: dict) -> str:
    """The long run a checkpoint's row belongs to (benchmarks/scaling/long_run.py): its ``--label``, else (rows
    written before labels) its snapshot folder's name."""
    return row.get("run") or Path(row.get("snapshot", "")).name
