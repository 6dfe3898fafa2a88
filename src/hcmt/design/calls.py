"""Design check, the limit calls: each design's ``call`` (pass / fail / undecided) for a yield stress from the
peak plate stress interval it trusts (:func:`trusted_interval`), the yield margin, and the final call once the
solver ran (:func:`final_calls`)."""

from __future__ import annotations

from dataclasses import replace

from hcmt.design.inputs import outside
from hcmt.design.prediction import Prediction
from hcmt.design.summary import CallInterval, Summary, SurrogateAnswer
from hcmt.errors import InputError

#: the interval the limit calls trust (:func:`trusted_interval`), chosen by measurement (docs/MODELS.md, "Calls")
TRUST = "union"


TRUSTS = ("surrogate", "union", "model", "intersection")


#: without a surrogate, the mesh model's interval is its answer ± this share: the worst peak plate stress error
#: measured on held-out designs inside the training ranges (docs/MODELS.md)
MODEL_BAND = 0.6


def trusted_interval(summary: Summary, trust: str = TRUST) -> tuple[float, float, str]:
    """(lo, hi, what) of the peak plate stress a call trusts (:func:`trusted_bounds`): the mesh model's answer as
    the summary's chosen read-out reports it (:attr:`hcmt.design.summary.Summary.chosen`), the surrogate's
    interval of it where the summary has one."""
    return trusted_bounds(
        summary.chosen.peak_plate_stress_mpa,
        (summary.surrogate or {}).get("peak_plate_stress_mpa"),
        trust,
        model_bounds(summary),
    )


def model_bounds(summary: Summary) -> tuple[float, float] | None:
    """The mesh model's own calibrated interval of its peak plate stress (:mod:`hcmt.design.model_interval`), or
    None: none calibrated for the design's cell, or a derived read-out chosen (the interval bounds the model's own
    answer only)."""
    if summary.model_interval is None or summary.readout != "raw":
        return None
    return summary.model_interval.bounds["peak_plate_stress_mpa"]


def trusted_bounds(
    model: float, surrogate: SurrogateAnswer | None, trust: str = TRUST, interval: tuple[float, float] | None = None
) -> tuple[float, float, str]:
    """(lo, hi, what) of the peak plate stress a call trusts, from the mesh model's answer ``model``, its own
    calibrated ``interval`` (None: none) and the surrogate's answer of it (None: no surrogate):
    ``surrogate``, the surrogate's 95 % interval; ``union``, that interval widened to hold the mesh model's
    interval (its answer where it has none); ``model`` (and whenever there is no surrogate), the mesh model's
    interval, or its answer ± :data:`MODEL_BAND` where it has none; ``intersection``, the part both intervals hold
    (the union where they do not overlap or the model has none; outside the training ranges the model's interval
    alone, :func:`trust_for`)."""
    if trust not in TRUSTS:
        raise InputError(f"must be one of {', '.join(TRUSTS)}, got {trust!r}", param="trust")
    m, s = model, surrogate
    lo, hi = interval if interval is not None else (m, m)
    if s is None or trust == "model":
        if interval is not None:
            return lo, hi, "model interval"
        return m * (1 - MODEL_BAND), m * (1 + MODEL_BAND), "model"
    if trust == "surrogate":
        return s.lo, s.hi, "surrogate"
    if trust == "intersection" and interval is not None and max(s.lo, lo) <= min(s.hi, hi):
        return max(s.lo, lo), min(s.hi, hi), "intersection"  # both calibrated: the surface narrows it
    return min(s.lo, lo), max(s.hi, hi), "union"


def call_of(lo: float, hi: float, yield_mpa: float) -> str:
    """``pass`` only when the whole interval lies below the yield stress, ``fail`` only when it lies above."""
    return "pass" if hi < yield_mpa else "fail" if lo > yield_mpa else "undecided"


def outside_reason(p: Prediction, ranges: dict[str, tuple[float, float]] | None, trust: str = TRUST) -> str | None:
    """Why ``p`` gets no decided call, or None: a design outside the model's training ranges (``ranges``, the
    run's; without them, the region its summary's ``confidence`` records: :func:`hcmt.design.inputs.region_of`)
    whose cell has no calibrated interval of the mesh model (:func:`model_bounds`: its coverage was measured
    there, so it decides, with ``trust`` ``model`` or ``union``; the response surface alone was never calibrated
    outside the ranges)."""
    if model_bounds(p.summary) is not None and trust in ("model", "union"):
        return None
    if ranges is not None:
        keys = outside(p.design, ranges)
        if not keys:
            return None
        where = f" ({', '.join(keys)})"
    elif p.summary.confidence is not None and p.summary.confidence.region == "outside":
        where = ""
    else:
        return None
    return (
        f"outside the model's training ranges{where}: no interval was calibrated there, so neither the model "
        "nor the response surface decides pass or fail; the solver does (--verify)"
    )


def trust_for(design, ranges: dict[str, tuple[float, float]] | None, trust: str) -> str:
    """The trust a design's call uses: ``intersection`` outside the training ranges is the model's interval alone
    (the response surface was never calibrated there, so it narrows nothing)."""
    return "model" if trust == "intersection" and ranges is not None and outside(design, ranges) else trust


def add_calls(
    preds: list[Prediction],
    yield_mpa: float | None,
    trust: str = TRUST,
    ranges: dict[str, tuple[float, float]] | None = None,
) -> None:
    """Each design's ``call`` for ``yield_mpa`` from the trusted interval (:func:`trusted_interval`): ``undecided``
    for a design outside the model's training ranges whatever the interval (:func:`outside_reason`; the interval
    is recorded, with ``trusted`` False and the ``reason``), so ``verify="auto"`` runs the solver on it."""
    if yield_mpa is None:
        return
    for p in preds:
        used = trust_for(p.design, ranges, trust)
        lo, hi, what = trusted_interval(p.summary, used)
        reason = outside_reason(p, ranges, used)
        p.summary = replace(
            p.summary,
            call="undecided" if reason else call_of(lo, hi, yield_mpa),
            call_interval_mpa=CallInterval(float(lo), float(hi), what, p.summary.readout, reason is None, reason),
        )


def final_calls(preds: list[Prediction], truth: list[Prediction | None] | None, yield_mpa: float | None) -> None:
    """``final_call``: the solver's (its peak below the yield stress or not) where it ran, else the call;
    ``verified``: whether the solver ran."""
    if yield_mpa is None:
        return
    for i, p in enumerate(preds):
        t = truth[i] if truth is not None else None
        if t is None:
            p.summary = replace(p.summary, verified=False, final_call=p.summary.call)
        else:
            solver = "pass" if t.summary.peak_plate_stress_mpa < yield_mpa else "fail"
            p.summary = replace(p.summary, verified=True, solver_call=solver, final_call=solver)


def add_margin(preds: list[Prediction], yield_mpa: float | None) -> None:
    """Each design's ``yield_margin_mpa`` (yield - the model's own peak plate stress) and, with a derived
    read-out, ``derived_yield_margin_mpa`` (yield - that read-out's peak)."""
    if yield_mpa is None:
        return
    if not yield_mpa > 0:
        raise InputError(f"must be > 0, got {yield_mpa}", param="yield_mpa")
    for p in preds:
        s = p.summary
        p.summary = replace(
            s,
            yield_margin_mpa=float(yield_mpa - s.peak_plate_stress_mpa),
            derived_yield_margin_mpa=None if s.derived is None else float(yield_mpa - s.derived.peak_plate_stress_mpa),
        )
