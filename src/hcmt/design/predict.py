"""Design check: the peak stress and deflection of new Impact Plate designs from a learned model, no solver run.

For each design (the parameters of ``hcmt simulate``, :class:`hcmt.sim.scene.Design`) the generator's scene code
builds the mesh and the first two frames (:func:`hcmt.sim.scene.initial_frames`: the ball in free flight just above
the plate), the model rolls out over the training data's recorded window (e.g. 52 frames of 0.002 ms), several
designs as one batched graph per step (:func:`hcmt.inference.rollout.rollout_batch`), and :func:`summarize` reads off

* the peak von Mises stress in the plate and in the ball (MPa), where (the node's position, mm) and when (ms);
* the maximum plate deflection ``max |u_y|`` over the plate's nodes and frames (mm);
* the margin to a yield (or design) stress, ``yield - peak plate stress`` (MPa), when one is given.

:func:`verify_designs` compares them with the built-in solver on the same designs; :func:`check_designs` is the
whole sequence (cost check, prediction with range warnings, margin, verification) that ``hcmt predict``, ``hcmt
sweep`` and ``hcmt demo`` share.
"""
from __future__ import annotations

import csv
import time
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

import numpy as np

from tqdm import tqdm

from hcmt.config import plural
from hcmt.data.format import atomic_path
from hcmt.design.readout import history_correlation, summarize_fields
from hcmt.design.surrogate import Surrogate, for_run, side_by_side
from hcmt.inference.metrics import format_physics, impact_metrics, plate_mask, rollout_rmse, summarize_impact
from hcmt.inference.rollout import rollout_batch
from hcmt.physics.trajectory import prepare_trajectory
from hcmt.sim.scene import (DESIGN_KEYS, EDGES, FIRST_SCENE_KEYS, MAX_ESTIMATED_SECONDS, Design, Settings, check_size,
                            middle_design, parse_design, parse_number, simulate, start_frames, validated_warnings)
from hcmt.viz.contours import plot_contours
from hcmt.viz.rollouts import Case, Series

__all__ = ["DESIGN_KEYS", "Check", "Prediction", "check_designs", "middle_design", "parse_design", "predict",
           "read_designs_csv", "verify_designs"]



@dataclass
class Prediction:
    """One design's predicted (or simulated) trajectory and what it was made from."""

    name: str
    design: Design
    world_pos: np.ndarray  # [T, N, 2] mm
    stress: np.ndarray  # [T, N, 1] MPa (von Mises)
    mesh_pos: np.ndarray  # [N, 2]
    cells: np.ndarray  # [C, 3]
    node_type: np.ndarray  # [N]
    wall_s: float  # seconds spent on this design (a batch's wall time split evenly over its designs)
    summary: dict = field(default_factory=dict)
    modulus: np.ndarray | None = None  # [N] MPa (the bending read-out after the ball has left)

    def fields(self) -> dict:
        """The trajectory as :func:`hcmt.design.readout.summarize_fields` reads it."""
        return {"world_pos": self.world_pos, "stress": self.stress, "mesh_pos": self.mesh_pos, "cells": self.cells,
                "node_type": self.node_type, "modulus": self.modulus}


# -- designs -----------------------------------------------------------------------------------------------------
def read_designs_csv(path: str | Path, defaults: Design, first: int = 1,
                     taken: dict[str, str] | None = None) -> list[tuple[str, Design]]:
    """Designs from a CSV file: a header of parameter names (optionally a ``name`` column), one design per row,
    every column present and numeric in every row (blank lines are skipped; a UTF-8 BOM and CRLF line ends are
    fine). Anything else is refused naming the file, the line and the column. Unnamed rows are ``design_<first>``,
    ... ; ``taken``: names already given elsewhere (name -> where), which a row may not take again."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such designs file")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not a UTF-8 text file ({exc.reason} at byte {exc.start})") from None
    try:
        rows = [(n, r) for n, r in enumerate(csv.reader(text.splitlines()), start=1) if any(c.strip() for c in r)]
    except csv.Error as exc:
        raise ValueError(f"{path}: not a readable CSV file ({exc})") from None
    if not rows:
        raise ValueError(f"{path}: no designs (expected a header line of parameter names and one row per design)")
    (head_line, head), body = rows[0], rows[1:]
    header = [h.strip().replace("-", "_") for h in head]
    for col, h in enumerate(header, start=1):
        if h != "name" and h not in DESIGN_KEYS:
            raise ValueError(f"{path} line {head_line}, column {col}: unknown column {h!r} in the header; expected "
                             f"`name` or parameters of {', '.join(DESIGN_KEYS)}")
    if len(set(header)) != len(header):
        raise ValueError(f"{path} line {head_line}: a column appears twice in the header")
    if not body:
        raise ValueError(f"{path}: a header but no designs (one row per design after the header)")
    out, seen = [], dict(taken or {})
    for n, row in body:
        if len(row) != len(header):
            raise ValueError(f"{path} line {n}: {len(row)} values for {len(header)} columns "
                             f"({', '.join(header)})")
        name, items = f"design_{len(out) + first}", []
        for col, (h, v) in enumerate(zip(header, row), start=1):
            if h == "name":
                name = check_name(v.strip(), f"{path} line {n}, column {col} (name)")
                if name in seen:
                    where = seen[name] if isinstance(seen[name], str) else f"line {seen[name]}"
                    raise ValueError(f"{path} line {n}, column {col} (name): {name!r} already names {where}; every "
                                     "design needs its own name")
                seen[name] = n
                continue
            if not v.strip():
                raise ValueError(f"{path} line {n}, column {col} ({h}): missing value")
            items.append(f"{h}={parse_number(v, f'{path} line {n}, column {col} ({h})')}")
        if name in seen and seen[name] != n:
            raise ValueError(f"{path} line {n}: the default name {name!r} is already taken ({seen[name]}); give the "
                             "CSV a name column")
        out.append((name, parse_design(items, defaults, where=f"{path} line {n}:")))
    return out


def check_name(name: str, where: str) -> str:
    """A design name that is safe as a folder name under ``--out`` (pictures are written to ``OUT/NAME/``): not
    empty, no path separator, not ``.`` or ``..``, no control character; else one line naming ``where``."""
    bad = None
    if not name:
        bad = "is empty"
    elif any(c in name for c in "/\\") or name in (".", ".."):
        bad = "would be a path outside its own folder (no '/', '\\', '.' or '..')"
    elif any(ord(c) < 32 or ord(c) == 127 for c in name):
        bad = "holds a control character"
    elif len(name) > 200:
        bad = "is longer than 200 characters"
    if bad:
        raise ValueError(f"{where}: the design name {name!r} {bad}; names become folder names under --out")
    return name


def with_family_defaults(ranges: dict[str, tuple[float, float]]) -> dict[str, tuple[float, float]]:
    """Training ranges with every panel-family parameter they do not name held at its default (a model trained
    before the families existed learned the first scene only); empty ranges stay empty (nothing known)."""
    if not ranges:
        return ranges
    first = {k: (v, v) for k, v in asdict(Design()).items() if k in DESIGN_KEYS[FIRST_SCENE_KEYS:]}
    return {**first, **ranges}


def outside(design: Design, ranges: dict[str, tuple[float, float]]) -> list[str]:
    """The design parameters outside ``ranges`` (relative tolerance 1e-6). A panel-family parameter that
    ``ranges`` do not name (a model trained before the families existed) counts as held at its default, the
    first scene's: one clamped layer struck by the ball."""
    out = []
    for key, (lo, hi) in with_family_defaults(ranges).items():
        tol = 1e-6 * max(abs(lo), abs(hi), 1e-12)
        if key in DESIGN_KEYS and not lo - tol <= getattr(design, key) <= hi + tol:
            out.append(key)
    return out


def range_warnings(design: Design, ranges: dict[str, tuple[float, float]],
                   what: str = "the model's training data") -> list[str]:
    """One line per parameter outside the training data's range (:func:`outside`)."""
    out = []
    ranges = with_family_defaults(ranges)
    for key in outside(design, ranges):
        lo, hi = ranges[key]
        span = f"{lo:.6g}" if lo == hi else f"{lo:.6g} .. {hi:.6g}"
        out.append(f"{key} = {getattr(design, key):.6g} is outside {what} ({span}); expect larger errors")
    return out


def region_of(design: Design, ranges: dict[str, tuple[float, float]]) -> str:
    """Where a design lies in the training ranges, for the model card's measured error by region: ``thin``
    (thickness in the lowest fifth of its range), ``high`` (drop height in the top fifth), ``thin+high``,
    ``inside``, or ``outside`` (a parameter outside the training ranges). The fifths are those of the generator's
    ``--edge-fraction`` (:data:`hcmt.sim.scene.EDGES`)."""
    if range_warnings(design, ranges):
        return "outside"
    parts = []
    for key, name in (("thickness", "thin"), ("drop_height", "high")):
        if key in ranges:
            lo, hi = ranges[key]
            a, b = EDGES[key]
            u = (getattr(design, key) - lo) / max(hi - lo, 1e-12)
            if a <= u <= b and (a > 0 or b < 1):
                parts.append(name)
    return "+".join(parts) or "inside"


def confidence(design: Design, run) -> dict | None:
    """The model card's measured error for the design's region (:func:`region_of`), or None when the card has
    none: ``{"region", "label", "designs", "peak_plate_stress_error_pct_median", ...}``."""
    regions = {r["region"]: r for r in (run.card or {}).get("confidence", [])}
    region = region_of(design, run.ranges)
    if region == "outside":
        return {"region": region, "label": "outside the training ranges", "designs": 0}
    return regions.get(region)


def settings_of(meta: dict | None) -> Settings:
    """The generator settings (frames, frame_dt, formulation, ...) the training data was made with."""
    saved = ((meta or {}).get("generator") or {}).get("settings")
    if not saved:
        raise ValueError("the model's training data is not an hcmt-generated Impact Plate dataset (no generator "
                         "settings in its meta.json): predict needs the recorded window it was trained on")
    return Settings(**{k: v for k, v in saved.items() if k in {f.name for f in fields(Settings)}})


# -- prediction ----------------------------------------------------------------------------------------------------
def design_trajectory(run, name: str, design: Design, settings: Settings):
    """The rollout input of a design: frames 0 and 1 from :func:`hcmt.sim.scene.start_frames` (the solver's first
    frame only when the ball reaches the plate within it), later frames holding only what the boundary conditions
    read (the clamped rim and the symmetry line do not move: frame 0's positions)."""
    start = start_frames(design, settings)
    f = dict(start["fields"])
    x = f["world_pos"]
    f["world_pos"] = np.concatenate([x, np.repeat(x[:1], settings.frames - 2, axis=0)])
    f["stress"] = f[run.adapter.stress_field] = np.zeros((settings.frames, x.shape[1], 1), np.float32)
    levels, remesh = run.hierarchy_spec
    return prepare_trajectory(f, name, run.adapter, levels, remesh, attrs=start["attrs"]), f


def predict(run, designs: list[tuple[str, Design]], batch: int = 8, progress: bool = True,
            compile: str = "none", readout: str = "contact",
            contact_end_ms: list[float | None] | None = None) -> list[Prediction]:
    """Roll the run's model out over each design's recorded window, ``batch`` designs per model call
    (``compile``: as :func:`hcmt.inference.rollout.rollout_batch`); ``readout``: how the plate's stress is read
    (:data:`hcmt.design.readout.READOUTS`; ``contact``: the peak from contact frames, no ghost stress after);
    ``contact_end_ms``: per design, a bound on when the ball leaves (the surrogate's), or None."""
    if batch < 1:
        raise ValueError(f"--batch must be >= 1, got {batch}")
    settings = settings_of(run.meta)
    h = run.adapter.history
    bar = tqdm(total=len(designs) * (settings.frames - 1 - h), desc="predict", unit="step",
               disable=not progress, dynamic_ncols=True)
    out = []
    for first in range(0, len(designs), batch):
        chunk = designs[first:first + batch]
        t0 = time.perf_counter()
        built = [design_trajectory(run, name, d, settings) for name, d in chunk]
        results = rollout_batch(run.model, run.adapter, [tr for tr, _ in built], run.radius, compile=compile,
                                progress=lambda n, k=len(chunk): bar.update(n * k))
        wall = (time.perf_counter() - t0) / len(chunk)
        for k, ((name, design), (_, f), r) in enumerate(zip(chunk, built, results)):
            p = Prediction(name, design, r["world_pos"].numpy(), r["stress"].numpy(), f["mesh_pos"], f["cells"],
                           f["node_type"].reshape(-1), wall, modulus=f["modulus"].reshape(-1))
            end = contact_end_ms[first + k] if contact_end_ms is not None else None
            p.summary = summarize(p, settings.frame_dt, readout, end)
            out.append(p)
    bar.close()
    return out


@dataclass
class Check:
    """The result of :func:`check_designs`: predictions, the solver's runs and their comparison (``verify``).

    ``truth[i]`` is the solver's run of design ``i`` (None where it was not run: ``verify="auto"`` runs the
    solver on the undecided designs only); ``verified`` compares the designs that were run."""

    preds: list[Prediction]
    truth: list[Prediction | None] | None
    verified: dict | None
    settings: Settings
    wall_s: float
    surrogate: str | None = None  # where the surrogate came from (None: no surrogate)
    notes: list[str] = field(default_factory=list)  # one line each: no surrogate, ...

    @property
    def solver_runs(self) -> int:
        return sum(t is not None for t in self.truth or [])


#: the interval the limit calls trust (:func:`trusted_interval`), chosen by measurement (docs/MODELS.md, "Calls")
TRUST = "union"
TRUSTS = ("surrogate", "union", "model")
#: without a surrogate, the mesh model's interval is its answer ± this share: the worst peak plate stress error
#: measured on held-out designs inside the training ranges (docs/MODELS.md)
MODEL_BAND = 0.6


#: the learned rollout's cost on one CPU thread: about 1e-4 s per node and step (HCMT width 64; docs/MODELS.md)
MODEL_SECONDS_PER_NODE_STEP = 1e-4


def cost_check(run, designs: list[tuple[str, Design]], settings: Settings, verify: bool, force: bool) -> None:
    """Refuse, before any array is built, a design whose mesh exceeds :data:`hcmt.sim.scene.MAX_NODES`
    (:func:`hcmt.sim.scene.check_size`: always), and one whose estimated time (the learned rollout's, plus the
    solver's for ``verify``, from :func:`hcmt.sim.scene.estimate`) exceeds ``MAX_ESTIMATED_SECONDS`` (600 s)
    unless ``force``; as ``hcmt simulate`` does."""
    for name, d in designs:
        cost = check_size(d, settings, where=f"{name}: ")
        seconds = MODEL_SECONDS_PER_NODE_STEP * cost["num_nodes"] * (settings.frames - 2) + (
            cost["estimated_s"] if verify else 0.0)
        if seconds > MAX_ESTIMATED_SECONDS and not force:
            raise ValueError(f"{name}: about {cost['num_nodes']:.0f} nodes at mesh_size {d.mesh_size:g} mm: estimated "
                             f"{seconds:.0f} s {'(model and solver)' if verify else '(model rollout)'} exceeds "
                             f"{MAX_ESTIMATED_SECONDS:.0f} s; coarsen the mesh or pass --force")


def check_designs(run, designs: list[tuple[str, Design]], *, batch: int = 8, verify: bool | str = False,
                  yield_mpa: float | None = None, compile: str = "none", progress: bool = True,
                  force: bool = False, surrogate: Surrogate | str | Path | bool | None = True,
                  readout: str = "contact", trust: str = TRUST) -> Check:
    """The design check, the one sequence behind ``hcmt predict``, ``hcmt sweep``, ``hcmt demo`` and
    :func:`predict_designs`: cost check, prediction (range warnings, the model's name and the confidence recorded
    in each summary), the surrogate's answers beside the model's (``surrogate``: True, the run's own; a path or a
    :class:`~hcmt.design.surrogate.Surrogate`; False / None: none; :func:`hcmt.design.surrogate.for_run`), the
    yield margin and the limit calls
    (:func:`add_calls`, ``trust``: which interval they trust), and the solver: on every design with
    ``verify=True``, on the undecided ones only with ``verify="auto"`` (which needs ``yield_mpa``)."""
    if verify not in (True, False, "auto"):
        raise ValueError(f"verify must be True, False or 'auto', got {verify!r}")
    if yield_mpa is not None and not (np.isfinite(yield_mpa) and yield_mpa > 0):
        raise ValueError(f"--yield-mpa must be a number > 0, got {yield_mpa}")
    if verify == "auto" and yield_mpa is None:
        raise ValueError("--verify auto runs the solver on the designs whose call is undecided: it needs "
                         "--yield-mpa Y")
    if batch < 1:
        raise ValueError(f"--batch must be >= 1, got {batch}")
    settings = settings_of(run.meta)
    surrogate, note = for_run(run, surrogate)
    notes = [note] if note else []
    cost_check(run, designs, settings, bool(verify), force)
    intervals = surrogate.predict([d for _, d in designs]) if surrogate is not None else None
    # a design with a parameter the surrogate's training designs held fixed (another family): no surrogate answer
    cannot = [surrogate.cannot_take(d) if surrogate is not None else [] for _, d in designs]
    if intervals is not None:
        intervals = [None if c else iv for iv, c in zip(intervals, cannot)]
    ends = [iv["contact_end_ms"].hi if iv and "contact_end_ms" in iv else None for iv in intervals] \
        if intervals else None
    t0 = time.perf_counter()
    preds = predict(run, designs, batch=batch, progress=progress, compile=compile, readout=readout,
                    contact_end_ms=ends)
    wall = time.perf_counter() - t0
    for i, p in enumerate(preds):
        p.summary["model"] = run.source
        p.summary["warnings"] = range_warnings(p.design, run.ranges)
        p.summary["confidence"] = confidence(p.design, run)
        if cannot[i]:
            p.summary["warnings"].append(
                f"the response surface cannot take {', '.join(cannot[i])} (held fixed over its training designs: "
                "another design family); no surrogate answer for this design, the call trusts the model's band")
        if intervals is not None and intervals[i] is not None:
            p.summary.update(side_by_side(p.summary, intervals[i]))
            # a user's own surrogate has its own training ranges: warn for a parameter outside them too
            own = set(outside(p.design, run.ranges))
            p.summary["warnings"] += range_warnings(
                p.design, {k: r for k, r in surrogate.ranges().items() if k not in own},
                "the response surface's training designs")
        p.summary["low_confidence"] = bool(_weak(p))
    add_margin(preds, yield_mpa)
    add_calls(preds, yield_mpa, trust)
    truth = verified = None
    if verify:
        field_ = run.adapter.stress_field  # stress_max: the solver records it as the model learned it
        solver_settings = replace(settings, peak_stress=True) if field_ == "stress_max" else settings
        chosen = [i for i, p in enumerate(preds) if verify is True or p.summary.get("call") == "undecided"]
        ran = solve([designs[i] for i in chosen], solver_settings, field_, progress=progress)
        truth = [None] * len(preds)
        for i, t in zip(chosen, ran):
            truth[i] = t
        if ran:
            verified = verify_designs([preds[i] for i in chosen], ran)
        final_calls(preds, truth, yield_mpa)
    elif yield_mpa is not None:
        final_calls(preds, None, yield_mpa)
    return Check(preds, truth, verified, settings, wall, surrogate.source if surrogate is not None else None, notes)


def trusted_interval(summary: dict, trust: str = TRUST) -> tuple[float, float, str]:
    """(lo, hi, what) of the peak plate stress a call trusts: ``surrogate``, the surrogate's 95 % interval;
    ``union``, that interval widened to hold the mesh model's answer; ``model`` (and whenever there is no
    surrogate), the mesh model's answer ± :data:`MODEL_BAND`."""
    if trust not in TRUSTS:
        raise ValueError(f"trust must be one of {', '.join(TRUSTS)}, got {trust!r}")
    m = summary["peak_plate_stress_mpa"]
    s = (summary.get("surrogate") or {}).get("peak_plate_stress_mpa")
    if s is None or trust == "model":
        return m * (1 - MODEL_BAND), m * (1 + MODEL_BAND), "model"
    if trust == "surrogate":
        return s["lo"], s["hi"], "surrogate"
    return min(s["lo"], m), max(s["hi"], m), "union"


def call_of(lo: float, hi: float, yield_mpa: float) -> str:
    """``pass`` only when the whole interval lies below the yield stress, ``fail`` only when it lies above."""
    return "pass" if hi < yield_mpa else "fail" if lo > yield_mpa else "undecided"


def add_calls(preds: list[Prediction], yield_mpa: float | None, trust: str = TRUST) -> None:
    """Each design's ``call`` for ``yield_mpa`` from the trusted interval (:func:`trusted_interval`)."""
    if yield_mpa is None:
        return
    for p in preds:
        lo, hi, what = trusted_interval(p.summary, trust)
        p.summary["call"] = call_of(lo, hi, yield_mpa)
        p.summary["call_interval_mpa"] = {"lo": float(lo), "hi": float(hi), "from": what}


def final_calls(preds: list[Prediction], truth: list[Prediction | None] | None, yield_mpa: float | None) -> None:
    """``final_call``: the solver's (its peak below the yield stress or not) where it ran, else the call;
    ``verified``: whether the solver ran."""
    if yield_mpa is None:
        return
    for i, p in enumerate(preds):
        t = truth[i] if truth is not None else None
        p.summary["verified"] = t is not None
        if t is None:
            p.summary["final_call"] = p.summary["call"]
        else:
            p.summary["solver_call"] = "pass" if t.summary["peak_plate_stress_mpa"] < yield_mpa else "fail"
            p.summary["final_call"] = p.summary["solver_call"]


def predict_designs(run, designs: list[tuple[str, Design]], *, surrogate: Surrogate | str | bool | None = True,
                    **options) -> list[Prediction]:
    """The design check of :func:`check_designs` for Python users (``hcmt.predict_designs``): the same cost
    check, range warnings, confidence notes and, with ``surrogate=True`` (default), the run's own response surface
    beside the model (:func:`hcmt.design.surrogate.for_run`; a path: that file; False or None: none)."""
    return check_designs(run, designs, surrogate=surrogate, **options).preds


def solve(designs: list[tuple[str, Design]], settings: Settings, stress_field: str = "stress",
          progress: bool = False) -> list[Prediction]:
    """The built-in FEM solver on the same designs (the reference for :func:`verify`); ``stress_field``: the field
    the model learned (``stress_max``: the largest stress between frames). Each summary carries the solver's own
    warnings (``solver_warnings``: a design outside its validated ranges)."""
    out = []
    for name, design in tqdm(designs, desc="solver", unit="design", disable=not progress or not designs,
                             dynamic_ncols=True):
        r = simulate(design, settings)
        f = r["fields"]
        p = Prediction(name, design, f["world_pos"], f[stress_field], f["mesh_pos"], f["cells"],
                       f["node_type"].reshape(-1), r["info"]["wall_time"], modulus=f["modulus"].reshape(-1))
        p.summary = summarize(p, settings.frame_dt, "learned")  # the solver's stress is the truth
        p.summary["solver_warnings"] = validated_warnings(design)
        out.append(p)
    return out


# -- reading off the numbers ---------------------------------------------------------------------------------------
def summarize(p: Prediction, frame_dt: float, readout: str = "learned", contact_end_ms: float | None = None) -> dict:
    """Peak von Mises stress of plate (from contact frames) and ball (MPa, where in mm, when in ms), the first
    frame at 95 % of the plate's peak, maximum plate deflection and the plate's stress history
    (:func:`hcmt.design.readout.summarize_fields`)."""
    return summarize_fields(p.fields(), frame_dt, readout, p.wall_s, contact_end_ms)


def add_margin(preds: list[Prediction], yield_mpa: float | None) -> None:
    if yield_mpa is None:
        return
    if not yield_mpa > 0:
        raise ValueError(f"--yield-mpa must be > 0, got {yield_mpa}")
    for p in preds:
        p.summary["yield_margin_mpa"] = float(yield_mpa - p.summary["peak_plate_stress_mpa"])


def verify_designs(preds: list[Prediction], truth: list[Prediction]) -> dict:
    """Per design (added to each prediction's summary under ``verify``) and summarized over designs: the
    learned-vs-solver error of peak plate stress (%), of its location (mm), of maximum deflection (%), position
    RMSE over the window (mm, all nodes and predicted frames) and the speedup (solver ÷ prediction wall time)."""
    rows, physics = [], []
    for p, t in zip(preds, truth):
        a, b = p.summary, t.summary
        row = {
            "solver_peak_plate_stress_mpa": b["peak_plate_stress_mpa"],
            "solver_max_deflection_mm": b["max_deflection_mm"],
            "peak_plate_stress_error_pct": 100.0 * (a["peak_plate_stress_mpa"] - b["peak_plate_stress_mpa"])
            / b["peak_plate_stress_mpa"],
            "peak_plate_location_error_mm": float(np.linalg.norm(np.subtract(a["peak_plate_where_mm"],
                                                                             b["peak_plate_where_mm"]))),
            "max_deflection_error_pct": 100.0 * (a["max_deflection_mm"] - b["max_deflection_mm"])
            / b["max_deflection_mm"],
            "position_rmse_mm": rollout_rmse(p.world_pos, t.world_pos, 2)["rmse_all"] / 1e3,
            "solver_peak_plate_t95_ms": b["peak_plate_t95_ms"],
            "peak_plate_t95_frame_error": int(a["peak_plate_t95_frame"] - b["peak_plate_t95_frame"]),
            # the solver's critical node (its peak's node): does the model's stress there rise and fall with it?
            "critical_node_history_correlation": history_correlation(p.stress[..., 0], t.stress[..., 0],
                                                                     b["peak_plate_node"]),
            "solver_wall_s": t.wall_s,
            "speedup": t.wall_s / p.wall_s,
            "solver_warnings": list(b.get("solver_warnings", [])),
        }
        phys = impact_metrics(p.world_pos, p.stress, t.world_pos, t.stress, plate_mask(t.cells, t.node_type), 2)
        physics.append(phys)
        row.update({k: phys[k] for k in ("model_rebounds", "solver_rebounds", "rebound_agrees",
                                         "peak_plate_frame_error", "peak_ball_stress_error_pct",
                                         "far_deflection_error_um")})
        p.summary["verify"] = row
        p.summary["solver_plate_stress_history_mpa"] = b["plate_stress_history_mpa"]
        rows.append(row)

    def stats(key):
        v = np.array([r[key] for r in rows], np.float64)
        v = np.abs(v) if key.endswith(("pct", "mm", "error")) else v
        v = v[np.isfinite(v)] if np.isfinite(v).any() else v
        return {"median": float(np.median(v)), "max": float(v.max()), "min": float(v.min()), "mean": float(v.mean())}

    keys = ("peak_plate_stress_error_pct", "peak_plate_location_error_mm", "max_deflection_error_pct",
            "position_rmse_mm", "peak_plate_t95_frame_error", "critical_node_history_correlation", "speedup")
    return {"designs": len(rows), **{k: stats(k) for k in keys}, "physics": summarize_impact(physics),
            "note": "errors summarized as absolute values (median, max, mean); speedup = solver wall time / "
                    "prediction wall time per design on this machine"}


# -- output --------------------------------------------------------------------------------------------------------
COLUMNS = [("design", "{}", "name"), ("plate MPa", "{:.1f}", "peak_plate_stress_mpa"),
           ("at r,y mm", "{}", "peak_plate_where_mm"), ("t ms", "{:.3f}", "peak_plate_when_ms"),
           ("ball MPa", "{:.1f}", "peak_ball_stress_mpa"), ("defl. mm", "{:.4f}", "max_deflection_mm"),
           ("margin MPa", "{:.1f}", "yield_margin_mpa"), ("wall s", "{:.2f}", "wall_s")]
VERIFY_COLUMNS = [("solver MPa", "{:.1f}", "solver_peak_plate_stress_mpa"),
                  ("err %", "{:+.1f}", "peak_plate_stress_error_pct"),
                  ("loc. err mm", "{:.2f}", "peak_plate_location_error_mm"),
                  ("defl. err %", "{:+.1f}", "max_deflection_error_pct"),
                  ("pos RMSE mm", "{:.4f}", "position_rmse_mm"), ("speedup", "{:.1f}x", "speedup")]


def _interval(block: dict | None, fmt: str = "{:.0f}") -> str:
    """``mean [lo, hi]`` of a surrogate answer ("-" when there is none)."""
    if not block:
        return "-"
    return f"{fmt.format(block['mean'])} [{fmt.format(block['lo'])}, {fmt.format(block['hi'])}]"


def table_rows(preds: list[Prediction]) -> tuple[list[str], list[list[str]]]:
    cols = [c for c in COLUMNS if c[2] != "yield_margin_mpa" or "yield_margin_mpa" in preds[0].summary]
    with_surrogate = any("surrogate" in p.summary for p in preds)
    vcols = VERIFY_COLUMNS if any("verify" in p.summary for p in preds) else []
    head = [c[0] for c in cols[:2]] + (["surrogate MPa [95 %]"] if with_surrogate else []) + \
        [c[0] for c in cols[2:] + vcols]
    rows = []
    for p in preds:
        s = {**p.summary, "name": p.name, **p.summary.get("verify", {})}
        cells = []
        for _, fmt, key in cols + vcols:
            v = s.get(key)
            cells.append("-" if v is None else f"{v[0]:.2f},{v[1]:.2f}" if isinstance(v, list) else fmt.format(v))
        if with_surrogate:
            cells.insert(2, _interval((p.summary.get("surrogate") or {}).get("peak_plate_stress_mpa")))
        rows.append(cells)
    return head, rows


#: the low-confidence note also fires where the mesh model and the surrogate differ by more than this share of
#: the surrogate's estimate (tuned on the shipped model's 18 valid + test designs, judged on 46 held-out ones:
#: docs/MODELS.md, "When the note fires")
NOTE_DISAGREEMENT = 0.10


def _weak(p: Prediction) -> list[str]:
    """The low-confidence note: with a surrogate, where it and the mesh model disagree by more than
    :data:`NOTE_DISAGREEMENT` (measured: it flagged 5 of 5 held-out designs with a peak error above 20 %, and 14
    of 41 others; the card's regions flagged 5 of 5 and 19 of 41: docs/MODELS.md); without one, where the model
    card measured large errors. A design outside the training ranges says so either way."""
    out = []
    c = p.summary.get("confidence")
    if c and c["region"] == "outside":
        out.append(f"{p.name}: outside the training ranges: the model card has no measured error there"
                   + ("" if "verify" in p.summary else "; verify with the solver (--verify)"))
    g = (p.summary.get("surrogate") or {}).get("peak_plate_stress_mpa")
    if g:
        gap = (p.summary["peak_plate_stress_mpa"] - g["mean"]) / g["mean"]
        if abs(gap) > NOTE_DISAGREEMENT:
            out.append(f"{p.name}: the mesh model's peak plate stress is {100 * gap:+.0f} % from the response "
                       f"surface's {g['mean']:.0f} MPa [{g['lo']:.0f}, {g['hi']:.0f}]; low confidence"
                       + ("" if "verify" in p.summary else ", verify with the solver"))
        return out
    if not c or c["region"] == "outside":
        return out
    med, worst = c["peak_plate_stress_error_pct_median"], c["peak_plate_stress_error_pct_worst"]
    if med <= 10.0 and abs(worst) <= 25.0:
        return out
    return out + [f"{p.name}: {c['label']}: the model card measured a median peak plate stress error of {med:.1f} % "
                  f"(worst {worst:+.1f} %) over {c['designs']} such designs; low confidence"
                  + ("" if "verify" in p.summary else ", verify with the solver")]


def format_table(preds: list[Prediction], verified: dict | None = None) -> str:
    head, rows = table_rows(preds)
    width = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(head)]
    lines = ["  ".join(h.rjust(w) for h, w in zip(head, width))]
    lines += ["  ".join(c.rjust(w) for c, w in zip(r, width)) for r in rows]
    if verified:
        v = verified
        lines.append(
            f"against the solver over {plural(v['designs'], 'design')}: peak plate stress error median "
            f"{v['peak_plate_stress_error_pct']['median']:.1f} % (worst {v['peak_plate_stress_error_pct']['max']:.1f} %), "
            f"location median {v['peak_plate_location_error_mm']['median']:.2f} mm, deflection error median "
            f"{v['max_deflection_error_pct']['median']:.1f} % (worst {v['max_deflection_error_pct']['max']:.1f} %), "
            f"speedup median {v['speedup']['median']:.1f}x")
        lines.append(f"  time of the peak (first frame at 95 % of it): median {v['peak_plate_t95_frame_error']['median']:.1f} "
                     f"frames off; the critical node's stress history, model against solver: correlation median "
                     f"{v['critical_node_history_correlation']['median']:.2f} (lowest "
                     f"{v['critical_node_history_correlation']['min']:.2f})")
        lines += [line[2:] for line in format_physics(v["physics"])]
    lines += [f"solver warning: {p.name}: {w}" for p in preds for w in p.summary.get("verify", {}).get(
        "solver_warnings", [])]
    lines += [f"note: {w}" for p in preds for w in _weak(p)]
    return "\n".join(lines)


def format_calls(preds: list[Prediction], yield_mpa: float, label: str = "design", value=None) -> str:
    """The limit calls as a table: value, model, surrogate ± interval, the interval trusted, call, solver (where
    run) and the final call; then how many designs needed the solver."""
    value = value or (lambda p: p.name)
    head = [label, "model MPa", "surrogate MPa [95 %]", "trusted [lo, hi]", "call", "solver MPa", "final"]
    rows = []
    for p in preds:
        s, iv = p.summary, p.summary["call_interval_mpa"]
        solver = (s.get("verify") or {}).get("solver_peak_plate_stress_mpa")
        rows.append([str(value(p)), f"{s['peak_plate_stress_mpa']:.0f}",
                     _interval((s.get("surrogate") or {}).get("peak_plate_stress_mpa")),
                     f"{iv['from']} [{iv['lo']:.0f}, {iv['hi']:.0f}]", s["call"],
                     "-" if solver is None else f"{solver:.0f}", s.get("final_call", s["call"])])
    width = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(head)]
    lines = [f"limit calls for a yield stress of {yield_mpa:g} MPa (pass: the trusted interval lies below it, fail: "
             "above it, undecided: it straddles it)"]
    lines += ["  " + "  ".join(h.rjust(w) for h, w in zip(head, width))]
    lines += ["  " + "  ".join(c.rjust(w) for c, w in zip(r, width)) for r in rows]
    undecided = sum(p.summary["call"] == "undecided" for p in preds)
    ran = sum(bool(p.summary.get("verified")) for p in preds)
    lines.append(f"  {undecided} of {len(preds)} undecided; the solver ran on {ran}"
                 + ("" if ran >= undecided else " (--verify auto runs it on the undecided ones)"))
    return "\n".join(lines)


#: summary keys that are not CSV columns: lists over frames, nested blocks (flattened below) and text
_NOT_COLUMNS = ("verify", "warnings", "model", "confidence", "surrogate", "disagreement_by_answer",
                "call_interval_mpa", "plate_stress_history_mpa", "solver_plate_stress_history_mpa", "contact_frames",
                "stress_readout")


def csv_rows(preds: list[Prediction]) -> tuple[list[str], list[list]]:
    """One row per design for a machine: the design's parameters, every summary quantity as its own numeric column
    at full precision (positions split into r and y), the surrogate's answers (``surrogate_<answer>_mean/lo/hi``),
    the calls, the verify block's columns, the model and the warnings. The stress histories are the JSON's."""
    head = ["name", *DESIGN_KEYS]
    keys = []
    for p in preds:
        keys += [k for k in p.summary if k not in _NOT_COLUMNS and k not in keys]
    skeys = []
    for p in preds:
        skeys += [q for q in (p.summary.get("surrogate") or {}) if q not in skeys]
    vkeys = []
    for p in preds:
        vkeys += [k for k in p.summary.get("verify", {}) if k not in vkeys and k != "solver_warnings"]
    for k in keys:
        head += [k.replace("where_mm", "r_mm"), k.replace("where_mm", "y_mm")] if k.endswith("where_mm") else [k]
    head += [f"surrogate_{q}_{b}" for q in skeys for b in ("mean", "lo", "hi")]
    head += [f"verify_{k}" for k in vkeys] + ["model", "warnings"]
    rows = []
    for p in preds:
        row = [p.name, *(getattr(p.design, k) for k in DESIGN_KEYS)]
        for k in keys:
            v = p.summary.get(k)
            row += (list(v) if v else ["", ""]) if k.endswith("where_mm") else [v]
        block = p.summary.get("surrogate") or {}
        row += [block.get(q, {}).get(b) for q in skeys for b in ("mean", "lo", "hi")]
        row += [p.summary.get("verify", {}).get(k) for k in vkeys]
        warnings = p.summary.get("warnings", []) + p.summary.get("verify", {}).get("solver_warnings", []) + _weak(p)
        row += [p.summary.get("model", ""), "; ".join(warnings)]
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


def to_json(preds: list[Prediction], verified: dict | None, run_source: str, device: str,
            check: "Check | None" = None) -> dict:
    """The design check as JSON: per design its parameters and summary (the surrogate's answers, ``disagreement``,
    the calls, the plate's stress history and the notes), the verify summary, the surrogate's source and the
    solver runs."""
    out = {"model": run_source, "device": device, "units": {"stress": "MPa", "length": "mm", "time": "ms"},
           "designs": [{"name": p.name, "design": asdict(p.design), **p.summary, "notes": _weak(p)} for p in preds],
           **({"verify": verified} if verified else {})}
    if check is not None:
        out["surrogate"] = check.surrogate
        out["solver_runs"] = check.solver_runs
        out["notes"] = check.notes
    return finite(out)


def finite(obj):
    """``obj`` with every NaN or infinite float as None: standard JSON (``jq``, ``JSON.parse``) has no NaN."""
    if isinstance(obj, float):
        return obj if np.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [finite(v) for v in obj]
    return obj


def contour_picture(p: Prediction, truth: Prediction | None, meta: dict, out_dir: str | Path, label: str) -> Path:
    """Stress contours (impact zoom) at the predicted peak-plate-stress frame, and with ``truth`` beside the solver
    at the solver's own peak frame too (one row each, the earlier first, one row when they coincide)."""
    pred = Series(f"{label} prediction", p.world_pos, p.stress, start=2)
    if truth is not None:
        case = Case(p.name, p.mesh_pos, p.cells, p.node_type, Series("Solver", truth.world_pos, truth.stress),
                    [pred], meta)
    else:
        case = Case(p.name, p.mesh_pos, p.cells, p.node_type, pred, [], meta)
    frames = {max(int(p.summary["peak_plate_frame"]), 1)}
    if truth is not None:
        frames.add(max(int(truth.summary["peak_plate_frame"]), 1))
    paths = plot_contours(case, Path(out_dir) / p.name, sorted(frames))
    return paths[-1]

