"""Design sweeps: one parameter varied over a range, every point predicted (``hcmt sweep``).

An engineer's questions of a sweep are the trend and the limit: does the peak plate stress (and the maximum
deflection) rise or fall with the parameter, steadily or not, and which value is the smallest (or largest) that
keeps the peak below a yield stress ``Y``? :func:`sweep` answers them for the model and, with ``verify``, for the
solver on the same points, and says whether the two agree:

* trend: the change from the first point to the last (% of the first), its sign and whether the series is
  monotonic (every step of the same sign, steps smaller than ``TREND_TOL`` of the series' range counting as flat);
  model and solver agree when their changes have the same sign and the model's size is within
  :data:`TREND_SIZE` (30 %) of the solver's (:func:`trends_agree`, the one rule of the sweep, the judge and the
  model card);
* limit: the parameter values whose peak is below ``Y``; the call is the smallest passing value when passing
  values lie above failing ones (thickness), the largest when below (drop height); the model's call agrees when it
  is within one sweep step of the solver's.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from hcmt.config import plural
from hcmt.design.basics import DESIGN_BATCH, parse_vary  # noqa: F401 (hcmt.design.sweep.parse_vary, as before)
from hcmt.design.check import Check, check_designs
from hcmt.design.readout import chosen
from hcmt.design.reports import finite, to_json
from hcmt.errors import InputError
from hcmt.sim.params import DESIGN_UNITS, Design

#: steps smaller than this share of a series' range count as flat in the monotonicity test
TREND_TOL = 0.02
QUANTITIES = {"peak_plate_stress_mpa": "peak plate stress (MPa)", "max_deflection_mm": "max deflection (mm)"}
#: a trend agrees when its sign is the solver's and its size is within this share of the solver's (a trend of the
#: right sign but half the size would mislead a design choice)
TREND_SIZE = 0.30


def sweep_designs(base: Design, param: str, lo: float, hi: float, n: int) -> list[tuple[str, Design]]:
    """The sweep's designs, each validated before any work (an impossible value is refused in one line)."""
    out = []
    for v in np.round(np.linspace(lo, hi, n), 12):  # 0.9, not 0.8999999999999999
        try:
            out.append((f"{param}={v:.6g}", replace(base, **{param: float(v)}).validate()))
        except ValueError as exc:
            raise InputError(
                f"{param}={lo:g}:{hi:g}:{n}: the point {param}={v:.6g} is impossible: {exc}", param="vary"
            ) from None
    return out


def trend(values: np.ndarray) -> dict:
    """``{"sign": -1 | 0 | 1 (last − first), "monotonic": bool, "change_pct": (last − first) / first}``."""
    v = np.asarray(values, np.float64)
    span = max(float(v.max() - v.min()), 1e-300)
    steps = np.diff(v)
    steps = steps[np.abs(steps) > TREND_TOL * span]
    sign = int(np.sign(v[-1] - v[0])) if abs(v[-1] - v[0]) > TREND_TOL * span else 0
    return {
        "sign": sign,
        "monotonic": bool(np.all(steps > 0) or np.all(steps < 0)),
        "change_pct": float(100.0 * (v[-1] - v[0]) / v[0]) if v[0] else None,
    }


def trends_agree(model: float | None, solver: float | None) -> bool | None:
    """Whether a model's change over a sweep (first to last point, relative: % or a fraction, the same for both)
    agrees with the solver's, the one rule of ``hcmt sweep``, the judge (benchmarks/surrogate/run.py) and the model
    card: the same sign, and the model's size within :data:`TREND_SIZE` (30 %) of the solver's,
    ``|model / solver - 1| <= 0.30`` (+7.3 % against +12.2 % is a miss: 40 % short). A solver's change of 0
    agrees only with a model's of 0; None when either is unknown (a series starting at 0)."""
    if model is None or solver is None:
        return None
    if solver == 0:
        return model == 0
    return bool(np.sign(model) == np.sign(solver) and abs(model / solver - 1) <= TREND_SIZE)


#: the words of :func:`trends_agree`'s rule, as the sweep prints and records it
TREND_RULE = f"the same sign and the model's size within {100 * TREND_SIZE:g} % of the solver's"


def limit_call(params: np.ndarray, peaks: np.ndarray, yield_mpa: float) -> dict:
    """Which parameter values keep the peak below ``yield_mpa``, and the call: the smallest passing value when the
    passing values lie at the top of the range, the largest when at the bottom (``None``: none or all pass)."""
    return limit_of(params, np.asarray(peaks) < yield_mpa)


def limit_of(params: np.ndarray, ok: np.ndarray) -> dict:
    """:func:`limit_call` of the passing mask ``ok``."""
    ok = np.asarray(ok, bool)
    out = {"passing": [float(p) for p in np.asarray(params)[ok]], "call": None, "call_index": None, "side": None}
    if ok.all() or not ok.any():
        out["side"] = "all pass" if ok.all() else "none pass"
        return out
    idx = np.flatnonzero(ok)
    if ok[-1]:  # passing at the high end: the smallest value from which every larger one passes
        first = int(idx[-1])
        while first > 0 and ok[first - 1]:
            first -= 1
        out.update(call=float(params[first]), call_index=first, side="minimum")
    else:
        last = int(idx[0])
        while last + 1 < len(ok) and ok[last + 1]:
            last += 1
        out.update(call=float(params[last]), call_index=last, side="maximum")
    return out


def analyse(check: Check, param: str, yield_mpa: float | None) -> dict:
    """Trends (model, and solver with ``verify``), their agreement, and the limit calls."""
    params = np.array([getattr(p.design, param) for p in check.preds])
    out = {"param": param, "values": params.tolist(), "trend": {}, "limit": None}
    series = {"model": [p.summary for p in check.preds]}
    if check.truth is not None and all(t is not None for t in check.truth):
        series["solver"] = [t.summary for t in check.truth]
    out["readout"] = check.readout  # the model's values: as this read-out reports them (hcmt.design.readout)
    for q in QUANTITIES:
        row = {who: trend([chosen(s, q) for s in rows]) for who, rows in series.items()}
        if "solver" in row:
            row["agree"] = trends_agree(row["model"]["change_pct"], row["solver"]["change_pct"])
            row["rule"] = TREND_RULE
        out["trend"][q] = row
    if yield_mpa is not None:
        # the model alone passes no point outside its training ranges (no interval was measured there)
        trusted = {"model": np.array([p.summary.call_interval_mpa.trusted for p in check.preds])}
        calls = {}
        for who, rows in series.items():
            below = np.array([chosen(s, "peak_plate_stress_mpa") for s in rows]) < yield_mpa
            calls[who] = limit_of(params, below & trusted.get(who, True))
        if "solver" in calls:
            a, b = calls["model"], calls["solver"]
            if a["call_index"] is not None and b["call_index"] is not None:
                calls["within_one_step"] = a["side"] == b["side"] and abs(a["call_index"] - b["call_index"]) <= 1
            else:
                calls["within_one_step"] = a["side"] == b["side"]
            calls["unsafe"] = _unsafe(a, b)
        # the final calls: pass only where the trusted interval (or, where it ran, the solver) says so
        final = [p.summary.final_call for p in check.preds]
        calls["final"] = {
            **limit_of(params, [c == "pass" for c in final]),
            "calls": final,
            "undecided": [float(v) for v, c in zip(params, final) if c == "undecided"],
            "solver_runs": check.solver_runs,
        }
        if "solver" in calls:
            calls["final"]["unsafe"] = _unsafe(calls["final"], calls["solver"])
        out["limit"] = {"yield_mpa": yield_mpa, **calls}
    return out


def _unsafe(model: dict, solver: dict) -> bool:
    """The model passes a parameter value that the solver fails."""
    return bool(set(model["passing"]) - set(solver["passing"]))


def sweep(
    run, param: str, lo: float, hi: float, n: int, base: Design, *, batch: int = DESIGN_BATCH, **options
) -> tuple[Check, dict]:
    """Predict a one-parameter sweep (``batch`` designs per model call, default
    :data:`hcmt.design.basics.DESIGN_BATCH`; None: the whole sweep in one) and analyse it; ``options`` as
    :func:`hcmt.design.check.check_designs` (verify, yield_mpa, surrogate, ...)."""
    designs = sweep_designs(base, param, lo, hi, n)
    check = check_designs(run, designs, batch=n if batch is None else batch, **options)
    analysis = analyse(check, param, options.get("yield_mpa"))
    lo_t, hi_t = run.ranges.get(param, (None, None))
    if lo_t is not None and lo_t == hi_t:
        analysis["not_learned"] = (
            f"the model's training designs held {param} fixed at {lo_t:g}: the trend against it is not learned"
        )
    return check, analysis


def format_analysis(a: dict) -> str:
    word = {1: "rises", -1: "falls", 0: "is flat"}
    lines = []
    for q, label in QUANTITIES.items():
        row = a["trend"][q]
        parts = []
        for who in ("model", "solver"):
            if who in row:
                t = row[who]
                change = f" ({t['change_pct']:+.1f} %)" if t["change_pct"] is not None else ""
                parts.append(f"{who} {word[t['sign']]}{change}{'' if t['monotonic'] else ', not monotonic'}")
        agree = "" if row.get("agree") is None else ("  -> trends agree" if row["agree"] else "  -> TRENDS DISAGREE")
        agree += f" (agree: {row['rule']})" if "rule" in row else ""
        how = "" if a.get("readout", "raw") == "raw" or q != "peak_plate_stress_mpa" else f" [{a['readout']} read-out]"
        lines.append(f"{label}{how} against {a['param']}: " + "; ".join(parts) + agree)
    if a.get("not_learned"):
        lines.append(f"warning: {a['not_learned']}")
    lim = a["limit"]
    if lim:
        names = {"model": "model alone", "solver": "solver", "final": "final calls"}
        for who in ("model", "final", "solver"):
            if who in lim:
                c = lim[who]
                text = f"{c['side']} {a['param']} {c['call']:.6g}" if c["call"] is not None else c["side"]
                extra = ""
                if who == "final":
                    extra = (
                        f" (the solver decided {plural(c['solver_runs'], 'point')} of {len(a['values'])}"
                        + (f"; {plural(len(c['undecided']), 'point')} still undecided" if c["undecided"] else "")
                        + ("; UNSAFE: a final pass the solver fails" if c.get("unsafe") else "")
                        + ")"
                    )
                lines.append(f"below {lim['yield_mpa']:g} MPa, {names[who]}: {text}{extra}")
        if "within_one_step" in lim:
            lines.append(
                "limit calls "
                + ("agree within one sweep step" if lim["within_one_step"] else "DIFFER by more than one sweep step")
                + ("; the model passes a value the solver fails (UNSAFE)" if lim["unsafe"] else "")
            )
    return "\n".join(lines)


def sweep_json(check: Check, analysis: dict, run_source: str, device: str) -> dict:
    return finite({**to_json(check.preds, check.verified, run_source, device, check), "sweep": analysis})


def axis_label(param: str) -> str:
    """The swept parameter with its unit (:data:`hcmt.sim.params.DESIGN_UNITS`), e.g. ``thickness [mm]``."""
    unit = DESIGN_UNITS.get(param)
    return f"{param} [{unit}]" if unit else param


def plot_sweep(check: Check, analysis: dict, out_dir: str | Path, label: str) -> Path:
    """Peak plate stress and maximum deflection against the swept parameter: model, and the solver with verify."""
    from hcmt.viz.meshplot import new_figure, save_figure  # here: matplotlib only for the plot

    x = np.array(analysis["values"])
    fig = new_figure(10, 4)
    axes = fig.subplots(1, 2)
    for ax, (q, name) in zip(axes, QUANTITIES.items()):
        ax.plot(x, [getattr(p.summary, q) for p in check.preds], "o-", label=label)
        if any(chosen(p.summary, q) != getattr(p.summary, q) for p in check.preds):  # a derived read-out, beside it
            ax.plot(x, [chosen(p.summary, q) for p in check.preds], "o:", label=f"{label} ({check.readout} read-out)")
        if check.truth is not None:
            ran = [(v, getattr(t.summary, q)) for v, t in zip(x, check.truth) if t is not None]
            if ran:
                ax.plot(*zip(*ran), "s--", color="k", label="Solver")
        band = [(v, p.summary.surrogate[q]) for v, p in zip(x, check.preds) if q in (p.summary.surrogate or {})]
        if band:
            xs, bs = zip(*band)
            ax.fill_between(xs, [b.lo for b in bs], [b.hi for b in bs], color="C1", alpha=0.25, label="surrogate 95 %")
            ax.plot(xs, [b.mean for b in bs], "-", color="C1", lw=1)
        if q == "peak_plate_stress_mpa" and analysis["limit"]:
            ax.axhline(analysis["limit"]["yield_mpa"], color="r", lw=1, label=f"Y = {analysis['limit']['yield_mpa']:g}")
        ax.set_xlabel(axis_label(analysis["param"]))
        ax.set_ylabel(name)
        ax.grid(alpha=0.3)
        ax.legend()
    return save_figure(fig, Path(out_dir) / f"sweep_{analysis['param']}.png", dpi=120)
