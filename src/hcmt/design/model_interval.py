"""Design check, the mesh model's own interval: split-conformal bounds calibrated on held-out solver runs, by where a
design lies against the model's training ranges.

A design's **cell** (:func:`cell_of`) is ``inside`` when every parameter lies in the training ranges; otherwise the
parameters beyond them with their side (``thickness+``: thicker than any training design, ``drop_height-``: lower)
joined by ``,``, and how far out: the largest excess as a share of its range's width, rounded up to
:data:`DISTANCE_STEP` (``thickness+:0.2``: up to a fifth of the thickness range beyond its top).

For each cell and answer (:data:`ANSWERS`: peak plate stress, max deflection) the calibration keeps, from its n
held-out designs, the log ratios ``r = log(solver / model)``, their median ``b`` and the conformal half-width ``w``,
the ``ceil((n + 1)(1 - alpha))``-th smallest ``|r - b|`` (split conformal, Vovk et al. 2005; alpha 0.05): the
interval is ``model * exp(b - w) .. model * exp(b + w)``. The plate stress history gets a simultaneous band
around the model's history allowing :data:`BAND_FRAMES` frames of timing error: from the least of the model's
history within that many frames of ``t``, less ``w_h * model's peak``, to the largest, plus it; ``w_h`` the same
order statistic of each design's largest distance of the solver's history outside that envelope, as a share of the
model's peak. (The median ``b`` comes from the scores it centers, so the 95 % is approximate; the coverage measured
on designs of other seeds is what the model card reports.) The model's answer stays its own; the interval is
beside it.

A cell with fewer than :data:`MIN_DESIGNS` held-out designs (too few for a finite 95 % bound), and a design in no
calibrated cell, gets no interval: its pass / fail call stays undecided (:mod:`hcmt.design.calls`).
:func:`fit` makes a calibration from (design, model summary, solver summary) triples;
``benchmarks/trust/run.py`` fits the shipped model's and measures its coverage on designs of other seeds.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from hcmt.data.runs import beside_model
from hcmt.errors import InputError
from hcmt.files import atomic_path
from hcmt.sim.params import DESIGN_KEYS, Design

#: the answers the interval bounds (each a :class:`hcmt.inference.quantities.ImpactQuantities` field)
ANSWERS = ("peak_plate_stress_mpa", "max_deflection_mm")
#: how far out a cell reaches, in steps of this share of a range's width
DISTANCE_STEP = 0.2
#: the history band's timing tolerance: the time of the plate's peak is a median 2.5 frames off (docs/MODELS.md)
BAND_FRAMES = 2
#: the nominal coverage
LEVEL = 0.95


def min_designs(level: float) -> int:
    """The fewest held-out designs with a finite bound at ``level``: ``ceil((n + 1) level) <= n``."""
    return math.ceil(level / (1 - level) - 1e-9)


#: a cell needs this many held-out designs at :data:`LEVEL`: 19 at 95 %
MIN_DESIGNS = min_designs(LEVEL)


def cell_of(design: Design, ranges: dict[str, tuple[float, float]]) -> str:
    """The design's cell (module docstring): ``inside``, or ``NAME+[,NAME-...]:DISTANCE``. A parameter whose
    training range is a single value is as far out as its change is a share of that value."""
    sides, far = [], 0.0
    for key in sorted(ranges):
        if key not in DESIGN_KEYS:
            continue
        lo, hi = ranges[key]
        v, tol = getattr(design, key), 1e-6 * max(abs(lo), abs(hi), 1e-12)
        if lo - tol <= v <= hi + tol:
            continue
        sides.append(f"{key}{'+' if v > hi else '-'}")
        # a range of one value: how far out as a share of that value
        far = max(far, (v - hi if v > hi else lo - v) / (hi - lo if hi > lo else max(abs(lo), 1e-12)))
    if not sides:
        return "inside"
    return f"{','.join(sides)}:{DISTANCE_STEP * math.ceil(far / DISTANCE_STEP - 1e-9):.1f}"


def conformal_half_width(scores: np.ndarray, level: float = LEVEL) -> float:
    """The ``ceil((n + 1) level)``-th smallest score (inf when that exceeds n): split conformal's bound."""
    s = np.sort(np.asarray(scores, float))
    k = math.ceil((len(s) + 1) * level - 1e-9)
    return float(s[k - 1]) if k <= len(s) else math.inf


@dataclass(frozen=True)
class Cell:
    """One cell's calibration: ``designs`` held out, per answer the center ``b`` and half-width ``w`` of
    ``log(solver / model)``, the history band's ``w_h`` (a share of the model's peak)."""

    designs: int
    center: dict[str, float]
    half_width: dict[str, float]
    band: float


@dataclass(frozen=True)
class ModelInterval:
    """A design's interval from its model's calibration: ``lo``/``hi`` per answer, the history band, the cell
    and the held-out designs behind it. :meth:`to_json` is the design's ``model_interval`` block of the JSON."""

    cell: str
    designs: int
    level: float
    bounds: dict[str, tuple[float, float]]
    history_lo_mpa: list[float]
    history_hi_mpa: list[float]

    def to_json(self) -> dict:
        return {
            "cell": self.cell,
            "held_out_designs": self.designs,
            "level": self.level,
            **{k: {"lo": lo, "hi": hi} for k, (lo, hi) in self.bounds.items()},
            "plate_stress_history_band_mpa": {"lo": self.history_lo_mpa, "hi": self.history_hi_mpa},
        }


@dataclass(frozen=True)
class Calibration:
    """A model's calibration: its cells (:class:`Cell`), the level, what it was fitted on (``source``: seeds,
    command) and the coverage measured on other designs (``measured``, written by the benchmark)."""

    model: str
    level: float
    cells: dict[str, Cell]
    source: dict
    measured: dict | None = None

    def interval(
        self, design: Design, ranges: dict[str, tuple[float, float]], answers: dict[str, float], history: list[float]
    ) -> ModelInterval | None:
        """The interval of a design whose model answers are ``answers`` (:data:`ANSWERS`) and plate stress history
        ``history``, or None when its cell is not calibrated."""
        key = cell_of(design, ranges)
        cell = self.cells.get(key)
        if cell is None or not answers["peak_plate_stress_mpa"] > 0:  # no bound of a ratio to a zero answer
            return None
        bounds = {
            a: (
                float(answers[a] * math.exp(cell.center[a] - cell.half_width[a])),
                float(answers[a] * math.exp(cell.center[a] + cell.half_width[a])),
            )
            for a in ANSWERS
        }
        low, high = envelope(history)
        half = cell.band * float(answers["peak_plate_stress_mpa"])
        return ModelInterval(
            key,
            cell.designs,
            self.level,
            bounds,
            [float(v) for v in np.maximum(low - half, 0.0)],
            [float(v) for v in high + half],
        )

    def reason(self, design: Design, ranges: dict[str, tuple[float, float]]) -> str:
        """Why a design has no interval (its cell, the cells calibrated)."""
        return (
            f"no interval: its cell {cell_of(design, ranges)} was not calibrated (calibrated: "
            f"{', '.join(sorted(self.cells))}); the call stays undecided"
        )

    def to_json(self) -> dict:
        return {
            "format": "hcmt model interval 1",
            "model": self.model,
            "level": self.level,
            "cells": {k: asdict(c) for k, c in sorted(self.cells.items())},
            "source": self.source,
            **({"measured": self.measured} if self.measured is not None else {}),
        }

    def save(self, path: str | Path) -> Path:
        path = Path(path)
        with atomic_path(path) as tmp:
            tmp.write_text(json.dumps(self.to_json(), indent=1) + "\n")
        return path

    @classmethod
    def load(cls, path: str | Path) -> "Calibration":
        """Read a calibration file (plain JSON, no code); anything else is refused naming the file."""
        path = Path(path)
        try:
            raw = json.loads(path.read_text())
            if raw.get("format") != "hcmt model interval 1":
                raise ValueError("not an hcmt model interval file (format)")
            cells = {
                str(k): Cell(
                    int(c["designs"]),
                    {a: float(c["center"][a]) for a in ANSWERS},
                    {a: float(c["half_width"][a]) for a in ANSWERS},
                    float(c["band"]),
                )
                for k, c in raw["cells"].items()
            }
            return cls(
                str(raw["model"]), float(raw["level"]), cells, dict(raw.get("source") or {}), raw.get("measured")
            )
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as e:
            raise InputError(f"{path}: not a model interval calibration ({type(e).__name__}: {e})") from None


def fit(
    triples: list[tuple[Design, object, object]],
    ranges: dict[str, tuple[float, float]],
    model: str,
    source: dict | None = None,
    level: float = LEVEL,
) -> Calibration:
    """A calibration from held-out designs: ``(design, model summary, solver summary)`` triples (summaries with
    :data:`ANSWERS` and ``plate_stress_history_mpa``), grouped by :func:`cell_of`; cells with fewer than
    :func:`min_designs` designs at ``level`` are left out, as are designs whose model answer is not positive (no
    ratio to it)."""
    groups: dict[str, list[tuple[object, object]]] = {}
    for design, m, s in triples:
        if all(float(getattr(m, a)) > 0 for a in ANSWERS):
            groups.setdefault(cell_of(design, ranges), []).append((m, s))
    cells = {}
    for key, pairs in groups.items():
        if len(pairs) < min_designs(level):
            continue
        center, half = {}, {}
        for a in ANSWERS:
            r = np.log([float(getattr(s, a)) / float(getattr(m, a)) for m, s in pairs])
            center[a] = float(np.median(r))
            half[a] = conformal_half_width(np.abs(r - center[a]), level)
        band = conformal_half_width(np.array([history_score(m, s) for m, s in pairs]), level)
        cells[key] = Cell(len(pairs), center, half, band)
    return Calibration(model, level, cells, dict(source or {}))


def envelope(history, frames: int = BAND_FRAMES) -> tuple[np.ndarray, np.ndarray]:
    """The least and the largest of ``history`` within ``frames`` frames of each frame."""
    h = np.asarray(history, float)
    padded = np.pad(h, frames, mode="edge")
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * frames + 1)
    return windows.min(axis=1), windows.max(axis=1)


def history_score(model, solver) -> float:
    """How far the solver's plate stress history leaves the model's :func:`envelope`, at most over the frames
    both hold, as a share of the model's peak."""
    low, high = envelope(model.plate_stress_history_mpa)
    s = np.asarray(solver.plate_stress_history_mpa, float)
    n = min(len(low), len(s))
    out = np.maximum(low[:n] - s[:n], s[:n] - high[:n])
    return float(max(np.max(out), 0.0) / float(model.peak_plate_stress_mpa))


def covers(iv: ModelInterval, solver) -> dict[str, bool]:
    """Whether the interval holds the solver's answers and its whole plate stress history (a history of another
    length is not held)."""
    out = {a: bool(iv.bounds[a][0] <= float(getattr(solver, a)) <= iv.bounds[a][1]) for a in ANSWERS}
    s = np.asarray(solver.plate_stress_history_mpa, float)
    out["plate_stress_history_mpa"] = len(s) == len(iv.history_lo_mpa) and bool(
        np.all((np.asarray(iv.history_lo_mpa) <= s) & (s <= np.asarray(iv.history_hi_mpa)))
    )
    return out


def interval_path(run) -> Path | None:
    """Where a run's own calibration lives: ``hcmt/pretrained/NAME.interval.json`` beside a shipped model,
    ``RUN/interval.json`` in a run folder."""
    return beside_model(run, "interval.json")


def for_run(run, choice: "Calibration | str | Path | bool | None" = True) -> tuple[Calibration | None, str | None]:
    """(calibration, note) for a run: ``True``, the run's own (:func:`interval_path`; a note when it has none);
    a path, that file; a :class:`Calibration`, itself; ``False`` / ``None``, none."""
    if choice is None or choice is False:
        return None, None
    if isinstance(choice, Calibration):
        return choice, None
    if choice is True:
        path = interval_path(run)
        if path is None or not path.is_file():
            where = path.name if path is not None else "no run folder"
            return None, (
                f"{run.source} has no calibrated interval of its own ({where}): its calls fall back to "
                "its answer and the response surface; benchmarks/trust/run.py calibrates one"
            )
        return Calibration.load(path), None
    if isinstance(choice, (str, Path)):
        return Calibration.load(choice), None
    raise InputError(
        f"expected True, False, a path or an hcmt Calibration, got {type(choice).__name__}", param="interval"
    )
