"""Design check, its reports: the table and the calls as text, the CSV, the JSON (standard JSON: non-finite numbers
become null) and the contour pictures of a checked design."""

from __future__ import annotations

import csv
from collections.abc import Mapping
from dataclasses import asdict
from pathlib import Path

import numpy as np

from hcmt.config import plural
from hcmt.design.check import Check, Prediction, weak_reasons
from hcmt.design.readout import contact_note, readout_key
from hcmt.design.summary import Summary, SurrogateAnswer
from hcmt.design.verification import VerifySummary
from hcmt.files import atomic_path
from hcmt.inference.physics import format_physics
from hcmt.sim.params import DESIGN_KEYS

# -- output --------------------------------------------------------------------------------------------------------
COLUMNS = [
    ("design", "{}", "name"),
    ("plate MPa", "{:.1f}", "peak_plate_stress_mpa"),
    ("at r,y mm", "{}", "peak_plate_where_mm"),
    ("t ms", "{:.3f}", "peak_plate_when_ms"),
    ("ball MPa", "{:.1f}", "peak_ball_stress_mpa"),
    ("defl. mm", "{:.4f}", "max_deflection_mm"),
    ("margin MPa", "{:.1f}", "yield_margin_mpa"),
    ("wall s", "{:.2f}", "wall_s"),
]


VERIFY_COLUMNS = [
    ("solver MPa", "{:.1f}", "solver_peak_plate_stress_mpa"),
    ("err %", "{:+.1f}", "peak_plate_stress_error_pct"),
    ("loc. err mm", "{:.2f}", "peak_plate_location_error_mm"),
    ("defl. err %", "{:+.1f}", "max_deflection_error_pct"),
    ("pos RMSE mm", "{:.4f}", "position_rmse_mm"),
    ("speedup", "{:.1f}x", "speedup"),
]


def _interval(answer: SurrogateAnswer | None, fmt: str = "{:.0f}") -> str:
    """``mean [lo, hi]`` of a surrogate answer ("-" when there is none)."""
    if answer is None:
        return "-"
    return f"{fmt.format(answer.mean)} [{fmt.format(answer.lo)}, {fmt.format(answer.hi)}]"


def verify_block(summary: Summary) -> dict:
    """A design's verify row as its JSON block (:meth:`hcmt.design.summary.VerifyRow.to_json`; ``{}`` when the
    solver did not run on it)."""
    return summary.verify.to_json() if summary.verify is not None else {}


def verify_columns(readout: str) -> list[tuple[str, str, str]]:
    """:data:`VERIFY_COLUMNS` for a read-out: ``err %`` is the error of the peak the table shows as the model's
    answer for that read-out (``<readout>_peak_plate_stress_error_pct`` for a derived one, headed so)."""
    if readout_key("peak_plate_stress_mpa", readout) == "peak_plate_stress_mpa":
        return VERIFY_COLUMNS
    return [
        (f"{readout} err %", fmt, f"{readout}_{key}") if key == "peak_plate_stress_error_pct" else (h, fmt, key)
        for h, fmt, key in VERIFY_COLUMNS
    ]


def table_rows(preds: list[Prediction]) -> tuple[list[str], list[list[str]]]:
    """The table's head and rows: its columns are the JSON's keys (:meth:`hcmt.design.summary.Summary.to_json`)."""
    first = preds[0].summary
    cols = [c for c in COLUMNS if c[2] != "yield_margin_mpa" or first.yield_margin_mpa is not None]
    if first.derived is not None:  # the chosen derived read-out's peak beside the model's own
        cols.insert(2, (f"{first.readout} MPa", "{:.1f}", readout_key("peak_plate_stress_mpa", first.readout)))
    with_surrogate = any(p.summary.surrogate is not None for p in preds)
    with_interval = any(p.summary.model_interval is not None for p in preds)
    vcols = verify_columns(first.readout) if any(p.summary.verify is not None for p in preds) else []
    head = (
        [c[0] for c in cols[:2]]
        + (["model's own [95 %]"] if with_interval else [])
        + (["surrogate MPa [95 %]"] if with_surrogate else [])
        + [c[0] for c in cols[2:] + vcols]
    )
    rows = []
    for p in preds:
        s = {**p.summary.to_json(), "name": p.name, **verify_block(p.summary)}
        cells = []
        for _, fmt, key in cols + vcols:
            v = s.get(key)
            cells.append("-" if v is None else f"{v[0]:.2f},{v[1]:.2f}" if isinstance(v, list) else fmt.format(v))
        if with_surrogate:
            cells.insert(2, _interval((p.summary.surrogate or {}).get("peak_plate_stress_mpa")))
        if with_interval:
            iv = p.summary.model_interval
            cells.insert(2, "-" if iv is None else "[{:.0f}, {:.0f}]".format(*iv.bounds["peak_plate_stress_mpa"]))
        rows.append(cells)
    return head, rows


def format_table(preds: list[Prediction], verified: VerifySummary | None = None) -> str:
    head, rows = table_rows(preds)
    width = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(head)]
    lines = ["  ".join(h.rjust(w) for h, w in zip(head, width))]
    lines += ["  ".join(c.rjust(w) for c, w in zip(r, width)) for r in rows]
    if verified is not None:
        v = verified
        lines.append(
            f"against the solver over {plural(v.designs, 'design')}: location of the plate's peak median "
            f"{v.peak_plate_location_error_mm.median:.2f} mm off, speedup median {v.speedup.median:.1f}x"
        )
        lines.append(
            f"  rise time (first frame at 95 % of the plate's peak): median "
            f"{v.peak_plate_t95_frame_error.median:.1f} frames off; the critical node's stress history, "
            f"model against solver: correlation median {v.critical_node_history_correlation.median:.2f} "
            f"(lowest {v.critical_node_history_correlation.min:.2f})"
        )
        if v.speedup_measured is not None:
            lines.append(f"  speedup = solver ÷ model wall time per design, {v.speedup_measured.how}")
        lines += [
            f"  {k.split('_peak')[0]} read-out's peak plate stress error median {e.median:.1f} % (worst {e.max:.1f} %)"
            for k, e in v.readout_errors.items()
        ]
        lines += [line[2:] for line in format_physics(v.physics)]
    lines += [
        f"solver warning: {p.name}: {w}" for p in preds for w in verify_block(p.summary).get("solver_warnings", [])
    ]
    lines += [f"note: {w}" for p in preds for w in weak_reasons(p)]
    unchanged = contact_note([p.summary for p in preds])
    return "\n".join(lines + ([f"note: {unchanged}"] if unchanged else []))


def format_calls(preds: list[Prediction], yield_mpa: float, label: str = "design", value=None) -> str:
    """The limit calls as a table: value, model, surrogate ± interval, the interval trusted, call, solver (where
    run) and the final call; then how many designs needed the solver."""
    value = value or (lambda p: p.name)
    readout = preds[0].summary.readout
    model = "model MPa" if readout == "raw" else f"model ({readout}) MPa"
    head = [label, model, "surrogate MPa [95 %]", "trusted [lo, hi]", "call", "solver MPa", "final"]
    rows = []
    for p in preds:
        s, iv = p.summary, p.summary.call_interval_mpa
        solver = s.verify.solver_peak_plate_stress_mpa if s.verify is not None else None
        rows.append(
            [
                str(value(p)),
                f"{s.chosen.peak_plate_stress_mpa:.0f}",
                _interval((s.surrogate or {}).get("peak_plate_stress_mpa")),
                f"{iv.source} [{iv.lo:.0f}, {iv.hi:.0f}]",
                s.call,
                "-" if solver is None else f"{solver:.0f}",
                s.final_call or s.call,
            ]
        )
    width = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(head)]
    lines = [
        f"limit calls for a yield stress of {yield_mpa:g} MPa (pass: the trusted interval lies below it, fail: "
        "above it, undecided: it straddles it, or the design lies outside the training ranges where no interval "
        "of the mesh model was calibrated)"
    ]
    lines += ["  " + "  ".join(h.rjust(w) for h, w in zip(head, width))]
    lines += ["  " + "  ".join(c.rjust(w) for c, w in zip(r, width)) for r in rows]
    undecided = sum(p.summary.call == "undecided" for p in preds)
    ran = sum(bool(p.summary.verified) for p in preds)
    lines.append(
        f"  {undecided} of {len(preds)} undecided; the solver ran on {ran}"
        + ("" if ran >= undecided else " (--verify auto runs it on the undecided ones)")
    )
    return "\n".join(lines)


#: summary keys that are not CSV columns: lists over frames, nested blocks (flattened below) and text
_NOT_COLUMNS = (
    "verify",
    "warnings",
    "model",
    "confidence",
    "surrogate",
    "disagreement_by_answer",
    "call_interval_mpa",
    "contact_frames",
    "readout",
    "contact_window_end_from",
)


def csv_rows(preds: list[Prediction]) -> tuple[list[str], list[list]]:
    """One row per design for a machine: the design's parameters, every summary quantity as its own numeric column
    at full precision (positions split into r and y), the surrogate's answers (``surrogate_<answer>_mean/lo/hi``),
    the calls, the verify block's columns, the model and the warnings. The stress histories are the JSON's."""
    head = ["name", *DESIGN_KEYS]
    blocks = [p.summary.to_json() for p in preds]  # the columns are the JSON's keys
    keys = []
    for block in blocks:
        keys += [k for k in block if k not in _NOT_COLUMNS and not k.endswith("history_mpa") and k not in keys]
    skeys = []
    for p in preds:
        skeys += [q for q in (p.summary.surrogate or {}) if q not in skeys]
    vkeys = []
    for p in preds:
        vkeys += [k for k in verify_block(p.summary) if k not in vkeys and k != "solver_warnings"]
    for k in keys:
        head += [k.replace("where_mm", "r_mm"), k.replace("where_mm", "y_mm")] if k.endswith("where_mm") else [k]
    head += [f"surrogate_{q}_{b}" for q in skeys for b in ("mean", "lo", "hi")]
    head += [f"verify_{k}" for k in vkeys] + ["model", "readout", "warnings"]
    rows = []
    for p, block in zip(preds, blocks):
        row = [p.name, *(getattr(p.design, k) for k in DESIGN_KEYS)]
        for k in keys:
            v = block.get(k)
            row += (list(v) if v else ["", ""]) if k.endswith("where_mm") else [v]
        answers = p.summary.surrogate or {}
        row += [getattr(answers[q], b) if q in answers else None for q in skeys for b in ("mean", "lo", "hi")]
        verify = verify_block(p.summary)
        row += [verify.get(k) for k in vkeys]
        warnings = (p.summary.warnings or []) + verify.get("solver_warnings", []) + weak_reasons(p)
        row += [p.summary.model or "", p.summary.readout, "; ".join(warnings)]
        rows.append([repr(v) if isinstance(v, float) else "" if v is None else v for v in row])  # repr: every digit
    return head, rows


def write_csv(preds: list[Prediction], path: str | Path) -> Path:
    head, rows = csv_rows(preds)
    path = Path(path)
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(head)
        w.writerows(rows)
    return path


def to_json(
    preds: list[Prediction],
    verified: VerifySummary | None,
    run_source: str,
    device: str,
    check: "Check | None" = None,
) -> dict:
    """The design check as JSON: per design its parameters and summary (the model's own answer, a derived
    read-out's fields under their own names, the surrogate's answers, ``disagreement``, the calls, the plate's
    stress history and the notes), the verify summary, the read-out used, the surrogate's source and the solver
    runs."""
    out = {
        "model": run_source,
        "device": device,
        "units": {"stress": "MPa", "length": "mm", "time": "ms"},
        "designs": [
            {"name": p.name, "design": asdict(p.design), **p.summary.to_json(), "notes": weak_reasons(p)} for p in preds
        ],
        **({"verify": verified.to_json()} if verified is not None else {}),
    }
    if check is not None:
        out["readout"] = check.readout
        out["surrogate"] = check.surrogate
        out["solver_runs"] = check.solver_runs
        out["notes"] = check.notes
    return finite(out)


def finite(obj):
    """``obj`` with every NaN or infinite float as None: standard JSON (``jq``, ``JSON.parse``) has no NaN."""
    if isinstance(obj, float):
        return obj if np.isfinite(obj) else None
    if isinstance(obj, Mapping):
        return {k: finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [finite(v) for v in obj]
    return obj


def contour_picture(p: Prediction, truth: Prediction | None, meta: dict, out_dir: str | Path, label: str) -> Path:
    """Stress contours (impact zoom) at the predicted peak-plate-stress frame, and with ``truth`` beside the solver
    at the solver's own peak frame too (one row each, the earlier first, one row when they coincide)."""
    from hcmt.viz.contours import plot_contours  # here: matplotlib only when a picture is asked for
    from hcmt.viz.rollouts import Case, Series

    pred = Series(f"{label} prediction", p.world_pos, p.stress, start=2)
    if truth is not None:
        case = Case(
            p.name, p.mesh_pos, p.cells, p.node_type, Series("Solver", truth.world_pos, truth.stress), [pred], meta
        )
    else:
        case = Case(p.name, p.mesh_pos, p.cells, p.node_type, pred, [], meta)
    frames = {max(int(p.summary.peak_plate_frame), 1)}
    if truth is not None:
        frames.add(max(int(truth.summary.peak_plate_frame), 1))
    paths = plot_contours(case, Path(out_dir) / p.name, sorted(frames))
    return paths[-1]
