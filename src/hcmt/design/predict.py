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

from hcmt.data.format import atomic_path
from hcmt.inference.metrics import format_physics, impact_metrics, plate_mask, rollout_rmse, summarize_impact
from hcmt.inference.rollout import rollout_batch
from hcmt.physics.trajectory import prepare_trajectory
from hcmt.sim.scene import (DESIGN_KEYS, EDGES, MAX_ESTIMATED_SECONDS, Design, Settings, start_frames,
                            middle_design, parse_design, parse_number, plan, simulate)
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


# -- designs -----------------------------------------------------------------------------------------------------
def read_designs_csv(path: str | Path, defaults: Design) -> list[tuple[str, Design]]:
    """Designs from a CSV file: a header of parameter names (optionally a ``name`` column), one design per row,
    every column present and numeric in every row (blank lines are skipped; a UTF-8 BOM and CRLF line ends are
    fine). Anything else is refused naming the file, the line and the column."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such designs file")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not a UTF-8 text file ({exc.reason} at byte {exc.start})") from None
    rows = [(n, r) for n, r in enumerate(csv.reader(text.splitlines()), start=1) if any(c.strip() for c in r)]
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
    out = []
    for n, row in body:
        if len(row) != len(header):
            raise ValueError(f"{path} line {n}: {len(row)} values for {len(header)} columns "
                             f"({', '.join(header)})")
        name, items = f"design_{len(out) + 1}", []
        for col, (h, v) in enumerate(zip(header, row), start=1):
            if h == "name":
                name = v.strip() or name
                continue
            if not v.strip():
                raise ValueError(f"{path} line {n}, column {col} ({h}): missing value")
            items.append(f"{h}={parse_number(v, f'{path} line {n}, column {col} ({h})')}")
        out.append((name, parse_design(items, defaults, where=f"{path} line {n}:")))
    return out


def range_warnings(design: Design, ranges: dict[str, tuple[float, float]]) -> list[str]:
    """One line per parameter outside the training data's range (relative tolerance 1e-6)."""
    out = []
    for key, (lo, hi) in ranges.items():
        if key not in DESIGN_KEYS:
            continue
        v = getattr(design, key)
        tol = 1e-6 * max(abs(lo), abs(hi), 1e-12)
        if v < lo - tol or v > hi + tol:
            span = f"{lo:.6g}" if lo == hi else f"{lo:.6g} .. {hi:.6g}"
            out.append(f"{key} = {v:.6g} is outside the model's training data ({span}); expect larger errors")
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
            compile: str = "none") -> list[Prediction]:
    """Roll the run's model out over each design's recorded window, ``batch`` designs per model call
    (``compile``: as :func:`hcmt.inference.rollout.rollout_batch`)."""
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
        for (name, design), (_, f), r in zip(chunk, built, results):
            p = Prediction(name, design, r["world_pos"].numpy(), r["stress"].numpy(), f["mesh_pos"], f["cells"],
                           f["node_type"].reshape(-1), wall)
            p.summary = summarize(p, settings.frame_dt)
            out.append(p)
    bar.close()
    return out


@dataclass
class Check:
    """The result of :func:`check_designs`: predictions, the solver's runs and their comparison (``verify``)."""

    preds: list[Prediction]
    truth: list[Prediction] | None
    verified: dict | None
    settings: Settings
    wall_s: float


#: a design's mesh larger than this many times the training data's largest is estimated before any work
MESH_FACTOR = 4.0


def cost_check(run, designs: list[tuple[str, Design]], settings: Settings, verify: bool, force: bool) -> None:
    """Refuse designs whose meshes are far beyond the training data's (more than :data:`MESH_FACTOR` times the
    nodes the same design has at the training data's finest ``mesh_size``) when the estimated time (the learned
    rollout's, plus the solver's for ``verify``, :func:`hcmt.sim.scene.plan`) exceeds ``MAX_ESTIMATED_SECONDS``
    (600 s), unless ``force``; as ``hcmt simulate`` does."""
    finest = run.ranges.get("mesh_size", (None, None))[0]
    for name, d in designs:
        if finest is None or d.mesh_size >= finest:
            continue
        cost = plan(d, settings)
        trained = plan(replace(d, mesh_size=finest), settings)["num_nodes"]
        if cost["num_nodes"] <= MESH_FACTOR * trained:
            continue
        # learned rollout: ~1e-4 s per node and step on one CPU thread (HCMT width 64; docs/MODELS.md)
        estimate = 1e-4 * cost["num_nodes"] * (settings.frames - 2) + (cost["estimated_s"] if verify else 0.0)
        if estimate > MAX_ESTIMATED_SECONDS and not force:
            raise ValueError(f"{name}: {cost['num_nodes']} nodes at mesh_size {d.mesh_size:g} mm ({trained} at the "
                             f"training data's finest, {finest:g} mm): estimated {estimate:.0f} s "
                             f"{'(model and solver)' if verify else '(model rollout)'} exceeds "
                             f"{MAX_ESTIMATED_SECONDS:.0f} s; coarsen the mesh or pass --force")


def check_designs(run, designs: list[tuple[str, Design]], *, batch: int = 8, verify: bool = False,
                  yield_mpa: float | None = None, compile: str = "none", progress: bool = True,
                  force: bool = False) -> Check:
    """The design check, the one sequence behind ``hcmt predict``, ``hcmt sweep`` and ``hcmt demo``: cost check,
    prediction (range warnings and the model's name recorded in each summary), yield margin, and with ``verify``
    the solver on the same designs and the comparison."""
    if yield_mpa is not None and not (np.isfinite(yield_mpa) and yield_mpa > 0):
        raise ValueError(f"--yield-mpa must be a number > 0, got {yield_mpa}")
    if batch < 1:
        raise ValueError(f"--batch must be >= 1, got {batch}")
    settings = settings_of(run.meta)
    cost_check(run, designs, settings, verify, force)
    t0 = time.perf_counter()
    preds = predict(run, designs, batch=batch, progress=progress, compile=compile)
    wall = time.perf_counter() - t0
    for p in preds:
        p.summary["model"] = run.source
        p.summary["warnings"] = range_warnings(p.design, run.ranges)
        p.summary["confidence"] = confidence(p.design, run)
    add_margin(preds, yield_mpa)
    truth = verified = None
    if verify:
        field = run.adapter.stress_field  # stress_max: the solver records it as the model learned it
        truth = solve(designs, replace(settings, peak_stress=True) if field == "stress_max" else settings, field)
        verified = verify_designs(preds, truth)
    return Check(preds, truth, verified, settings, wall)


def solve(designs: list[tuple[str, Design]], settings: Settings, stress_field: str = "stress") -> list[Prediction]:
    """The built-in FEM solver on the same designs (the reference for :func:`verify`); ``stress_field``: the field
    the model learned (``stress_max``: the largest stress between frames)."""
    out = []
    for name, design in designs:
        r = simulate(design, settings)
        f = r["fields"]
        p = Prediction(name, design, f["world_pos"], f[stress_field], f["mesh_pos"], f["cells"],
                       f["node_type"].reshape(-1), r["info"]["wall_time"])
        p.summary = summarize(p, settings.frame_dt)
        out.append(p)
    return out


# -- reading off the numbers ---------------------------------------------------------------------------------------
def summarize(p: Prediction, frame_dt: float) -> dict:
    """Peak von Mises stress of plate and ball (MPa, where in mm, when in ms) and maximum plate deflection."""
    plate = plate_mask(p.cells, p.node_type)
    s = p.stress[..., 0]
    out = {}
    for body, mask in (("plate", plate), ("ball", ~plate)):
        nodes = np.flatnonzero(mask)
        t, k = np.unravel_index(np.argmax(s[:, nodes]), (s.shape[0], len(nodes)))
        node = nodes[k]
        out[f"peak_{body}_stress_mpa"] = float(s[t, node])
        out[f"peak_{body}_where_mm"] = [float(v) for v in p.world_pos[t, node]]
        out[f"peak_{body}_when_ms"] = float(t * frame_dt)
        out[f"peak_{body}_frame"] = int(t)
    u_y = np.abs(p.world_pos[:, plate, 1] - p.mesh_pos[None, plate, 1])
    out["max_deflection_mm"] = float(u_y.max())
    out["wall_s"] = float(p.wall_s)
    return out


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
            "solver_wall_s": t.wall_s,
            "speedup": t.wall_s / p.wall_s,
        }
        phys = impact_metrics(p.world_pos, p.stress, t.world_pos, t.stress, plate_mask(t.cells, t.node_type), 2)
        physics.append(phys)
        row.update({k: phys[k] for k in ("model_rebounds", "solver_rebounds", "rebound_agrees",
                                         "peak_plate_frame_error", "peak_ball_stress_error_pct",
                                         "far_deflection_error_um")})
        p.summary["verify"] = row
        rows.append(row)

    def stats(key):
        v = np.abs([r[key] for r in rows]) if key.endswith(("pct", "mm")) else np.array([r[key] for r in rows])
        return {"median": float(np.median(v)), "max": float(v.max()), "mean": float(v.mean())}

    keys = ("peak_plate_stress_error_pct", "peak_plate_location_error_mm", "max_deflection_error_pct",
            "position_rmse_mm", "speedup")
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


def table_rows(preds: list[Prediction]) -> tuple[list[str], list[list[str]]]:
    cols = [c for c in COLUMNS if c[2] != "yield_margin_mpa" or "yield_margin_mpa" in preds[0].summary]
    vcols = VERIFY_COLUMNS if "verify" in preds[0].summary else []
    head = [c[0] for c in cols + vcols]
    rows = []
    for p in preds:
        s = {**p.summary, "name": p.name, **p.summary.get("verify", {})}
        cells = []
        for _, fmt, key in cols + vcols:
            v = s[key]
            cells.append(f"{v[0]:.2f},{v[1]:.2f}" if isinstance(v, list) else fmt.format(v))
        rows.append(cells)
    return head, rows


def _weak(p: Prediction) -> list[str]:
    """A line when the design lies where the model card measured large errors (or outside the ranges)."""
    c = p.summary.get("confidence")
    if not c:
        return []
    if c["region"] == "outside":
        return [f"{p.name}: outside the training ranges: the model card has no measured error there; verify with "
                "the solver (--verify)"]
    med, worst = c["peak_plate_stress_error_pct_median"], c["peak_plate_stress_error_pct_worst"]
    if med <= 10.0 and abs(worst) <= 25.0:
        return []
    return [f"{p.name}: {c['label']}: the model card measured a median peak plate stress error of {med:.1f} % "
            f"(worst {worst:+.1f} %) over {c['designs']} such designs; low confidence, verify with the solver"]


def format_table(preds: list[Prediction], verified: dict | None = None) -> str:
    head, rows = table_rows(preds)
    width = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(head)]
    lines = ["  ".join(h.rjust(w) for h, w in zip(head, width))]
    lines += ["  ".join(c.rjust(w) for c, w in zip(r, width)) for r in rows]
    if verified:
        v = verified
        lines.append(
            f"against the solver over {v['designs']} design(s): peak plate stress error median "
            f"{v['peak_plate_stress_error_pct']['median']:.1f} % (worst {v['peak_plate_stress_error_pct']['max']:.1f} %), "
            f"location median {v['peak_plate_location_error_mm']['median']:.2f} mm, deflection error median "
            f"{v['max_deflection_error_pct']['median']:.1f} % (worst {v['max_deflection_error_pct']['max']:.1f} %), "
            f"speedup median {v['speedup']['median']:.1f}x")
        lines += [line[2:] for line in format_physics(v["physics"])]
    lines += [f"note: {w}" for p in preds for w in _weak(p)]
    return "\n".join(lines)


def csv_rows(preds: list[Prediction]) -> tuple[list[str], list[list]]:
    """One row per design for a machine: the design's parameters, every summary quantity as its own numeric column
    at full precision (positions split into r and y), the verify block's columns, the model and the warnings."""
    head = ["name", *DESIGN_KEYS]
    keys = [k for k in preds[0].summary if k not in ("verify", "warnings", "model", "confidence")]
    vkeys = list(preds[0].summary.get("verify", {}))
    for k in keys:
        head += [k.replace("where_mm", "r_mm"), k.replace("where_mm", "y_mm")] if k.endswith("where_mm") else [k]
    head += [f"verify_{k}" for k in vkeys] + ["model", "warnings"]
    rows = []
    for p in preds:
        row = [p.name, *(getattr(p.design, k) for k in DESIGN_KEYS)]
        for k in keys:
            v = p.summary.get(k)
            row += list(v) if isinstance(v, list) else [v]
        row += [p.summary["verify"].get(k) for k in vkeys] if vkeys else []
        row += [p.summary.get("model", ""), "; ".join(p.summary.get("warnings", []) + _weak(p))]
        rows.append([repr(v) if isinstance(v, float) else v for v in row])  # repr: every digit of a float
    return head, rows


def write_csv(preds: list[Prediction], path: str | Path) -> Path:
    head, rows = csv_rows(preds)
    path = Path(path)
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(head)
        w.writerows(rows)
    return path


def to_json(preds: list[Prediction], verified: dict | None, run_source: str, device: str) -> dict:
    return {"model": run_source, "device": device, "units": {"stress": "MPa", "length": "mm", "time": "ms"},
            "designs": [{"name": p.name, "design": asdict(p.design), **p.summary} for p in preds],
            **({"verify": verified} if verified else {})}


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

