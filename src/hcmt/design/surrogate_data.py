"""The response surface's training data: what a surrogate records of it (:func:`dataset_facts`, the file's
``dataset`` block, checked on reading by :func:`read_facts`), what differs from a model's (:func:`data_differences`,
:func:`range_differences`), and the designs and answers it is fitted on (:func:`dataset_answers`: the solver's
trajectories read by :func:`hcmt.design.readout.summarize_fields`)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from hcmt.data.format import Split, read_meta
from hcmt.design.basics import QUANTITIES
from hcmt.design.readout import summarize_fields
from hcmt.errors import InputError
from hcmt.sim.params import DESIGN_KEYS, DESIGN_UNITS, FIRST_SCENE_KEYS, Design, design_from_attrs

#: the unit of each answer (:data:`hcmt.design.basics.QUANTITIES`)
ANSWER_UNITS = {
    "peak_plate_stress_mpa": "MPa",
    "peak_ball_stress_mpa": "MPa",
    "max_deflection_mm": "mm",
    "peak_plate_t95_ms": "ms",
    "contact_end_ms": "ms",
}


class SurrogateError(InputError):
    """A surrogate file that cannot be used; the message names the file and what is wrong."""


def dataset_facts(meta: dict, split: str, stress_field: str, answers: dict[str, list[float]]) -> dict:
    """What a surrogate records of its training data (its ``dataset`` block): the frame window and interval, the
    families of the split, the stress field, the units of the design parameters and answers, and ``censored``:
    how many runs' window ended before the ball left (or before it touched), whose ``contact_end_ms`` is then the
    window's, not the ball's."""
    frames, dt = window(meta)
    ends = np.asarray(answers.get("contact_end_ms", []), np.float64)
    censored = int(np.sum((ends >= (frames - 0.5) * dt) | (ends <= 1.5 * dt)))
    return {
        "frames": frames,
        "frame_dt_ms": dt,
        "split": split,
        "families": families(meta, split),
        "stress_field": stress_field,
        "units": dict(DESIGN_UNITS),
        "answer_units": dict(ANSWER_UNITS),
        "censored": censored,
        "runs": int(len(ends)),
    }


def window(meta: dict | None) -> tuple[int, float]:
    """(frames, frame interval in ms) of a dataset's meta.json (0, 0.0 when it records none)."""
    settings = ((meta or {}).get("generator") or {}).get("settings") or {}
    return int(settings.get("frames") or 0), float((meta or {}).get("dt") or settings.get("frame_dt") or 0.0)


def families(meta: dict | None, split: str = "train") -> list[str]:
    """The design families of a dataset's split (``mono`` for data made before them)."""
    listed = ((meta or {}).get("families") or {}).get(split) or ((meta or {}).get("generator") or {}).get("families")
    return sorted(set(listed or ["mono"]))


def data_differences(facts: dict, meta: dict, stress_field: str) -> list[str]:
    """What differs between a surrogate's recorded training data (``facts``) and a model's (``meta``)."""
    frames, dt = window(meta)
    out = []
    if facts["frames"] != frames or not math.isclose(facts["frame_dt_ms"], dt, rel_tol=1e-6):
        out.append(
            f"fitted on a window of {facts['frames']} frames of {facts['frame_dt_ms']:g} ms, the model's is "
            f"{frames} frames of {dt:g} ms"
        )
    if facts["stress_field"] != stress_field:
        out.append(f"fitted on {facts['stress_field']!r}, the model learned {stress_field!r}")
    missing = sorted(set(families(meta)) - set(facts["families"]))
    if missing:
        out.append(
            f"fitted on the families {', '.join(facts['families'])}, the model trained on {', '.join(missing)} too"
        )
    units = [
        f"{k} in {u}"
        for k, u in {**facts["units"], **facts["answer_units"]}.items()
        if {**DESIGN_UNITS, **ANSWER_UNITS}.get(k, u) != u
    ]
    if units:
        out.append(f"its units differ ({', '.join(units[:3])})")
    return out


def read_facts(facts, where: str) -> dict:
    """A version 2 file's ``dataset`` block, checked."""
    try:
        out = dict(facts)
        out.update(
            frames=int(out["frames"]),
            frame_dt_ms=float(out["frame_dt_ms"]),
            censored=int(out["censored"]),
            stress_field=str(out["stress_field"]),
            families=[str(f) for f in out["families"]],
            units=dict(out.get("units") or {}),
            answer_units=dict(out.get("answer_units") or {}),
        )
        if (
            out["frames"] < 2
            or not (math.isfinite(out["frame_dt_ms"]) and out["frame_dt_ms"] > 0)
            or out["censored"] < 0
        ):
            raise ValueError("frames >= 2, frame_dt_ms > 0 and censored >= 0 expected")
        return out
    except (KeyError, TypeError, ValueError) as exc:
        what = f"missing key {exc}" if isinstance(exc, KeyError) else str(exc).splitlines()[0][:120]
        raise SurrogateError(
            f'{where}: "dataset" block not usable ({what}); it is written by `hcmt surrogate fit`'
        ) from None


def dataset_answers(
    data: str | Path, split: str = "train", limit: int | None = None, stress_field: str = "stress"
) -> tuple[list[Design], dict[str, list[float]]]:
    """The designs of a dataset split (each trajectory's attributes) and their answers (:data:`QUANTITIES`, read
    off the solver's trajectory by :func:`hcmt.design.readout.summarize_fields`); the first ``limit`` only;
    ``stress_field``: the stress a model learned (``stress_max`` for ``generate --peak-stress`` data)."""
    data = Path(data)
    meta = read_meta(data)
    frame_dt = window(meta)[1]
    designs, answers = [], {q: [] for q in QUANTITIES}
    with Split(data, split, meta) as s:
        count = len(s) if limit is None else min(limit, len(s))
        for i in range(count):
            attrs = s.attrs(i)
            missing = [k for k in DESIGN_KEYS[:FIRST_SCENE_KEYS] if k not in attrs]
            if missing:
                raise InputError(
                    f"{s.path} trajectory {s.names[i]}: no design parameters {missing} in its "
                    "attributes; a surrogate is fitted on hcmt-generated Impact Plate data"
                )
            designs.append(design_from_attrs(attrs))
            fields = s[i]
            if stress_field not in fields:
                raise InputError(
                    f"{s.path} trajectory {s.names[i]}: no field {stress_field!r} (a model that learned "
                    "stress_max needs data made by `hcmt generate --peak-stress`)"
                )
            summary = summarize_fields({**fields, "stress": fields[stress_field]}, frame_dt)
            for q in QUANTITIES:
                answers[q].append(getattr(summary, q))
    return designs, answers


def range_differences(own: dict[str, tuple[float, float]], ranges: dict[str, tuple[float, float]]) -> list[str]:
    """Each parameter whose training range (``own``, a surrogate's) does not cover the model's (``ranges``), or
    is held at another value."""
    out = []
    for k, (lo, hi) in ranges.items():
        if k not in own:
            continue
        a, b = own[k]
        tol = 1e-6 * max(abs(lo), abs(hi), 1e-12)
        if a > lo + tol or b < hi - tol:
            out.append(f"{k} {a:.3g}..{b:.3g} vs {lo:.3g}..{hi:.3g}")
    return out
