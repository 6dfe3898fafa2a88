"""What a solve will cost and whether the solver is trusted for a design, before it runs: the node and substep
estimate from the design's numbers (:func:`estimate`), the size and time limits every command applies
(:func:`check_size`, :func:`check_cost`), the plan from the built mesh (:func:`plan`) and the validated ranges
(:func:`validated_warnings`)."""

from __future__ import annotations

import numpy as np

from hcmt.errors import InputError
from hcmt.sim.families import features
from hcmt.sim.params import MAX_ESTIMATED_SECONDS, Design, Settings
from hcmt.sim.scene import design_mesh, fem_model
from hcmt.sim.solver import stable_time_step

#: cost model of the solver (docs/solver.md, "Speed"): per substep a fixed ~0.4 ms of Python and sparse-product
#: overhead plus ~3e-7 s per node, on one core of the development machine (a 34,768-node design measured 15 ms per
#: substep with the other core busy: 582 s where 1e-7 s per node had estimated 150 s; small meshes stay
#: overhead-bound, so their estimate stays conservative)
SECONDS_PER_SUBSTEP, SECONDS_PER_NODE_SUBSTEP = 4e-4, 3e-7
#: the ranges the solver is validated for (docs/solver.md): outside them, results are not trusted
VALIDATED = {
    "impact_speed": (0.0, 10.0),
    "plate_modulus": (1e3, 1e6),
    "ball_modulus": (1e3, 1e6),
    "plate_poisson": (0.0, 0.45),
    "ball_poisson": (0.0, 0.45),
    "plate_density": (5e-4, 2e-2),
    "ball_density": (5e-4, 2e-2),
}


def validated_warnings(design: Design) -> list[str]:
    """One line per parameter outside the range the solver is validated for."""
    out = []
    for key, (lo, hi) in VALIDATED.items():
        v = getattr(design, key)
        if not lo <= v <= hi:
            unit = " mm/ms (= m/s)" if key == "impact_speed" else ""
            out.append(
                f"{key} = {v:.6g}{unit} is outside the range the solver is validated for ({lo:g} .. {hi:g}; "
                "docs/solver.md): do not trust the result"
            )
    return out


#: the largest mesh any command builds (nodes, from :func:`estimate`): the solver holds every frame (12 bytes per
#: node and frame) and a learned model's step about 160 kB per node (docs/RESULTS.md), so beyond this a design
#: exhausts memory before it could finish
MAX_NODES = 200_000


def estimate(design: Design, settings: Settings = Settings()) -> dict:
    """The cost of a design from its numbers alone, before any array is built: nodes (the plate's structured grid
    ``(L/h + 1)(max(4, t/h) + 1)`` plus the ball's half disk ``π r² / (2 h²) + 2 r / h + 1``), substeps (frames ×
    frame interval ÷ the Courant step ``safety h_min / c``, ``h_min`` = half the plate's layer height or element
    size, ``c`` the faster material's dilatational wave speed) and seconds (:data:`SECONDS_PER_SUBSTEP`,
    :data:`SECONDS_PER_NODE_SUBSTEP`). Floats throughout: a 1e308 mm plate is an infinite estimate, not an
    overflow."""
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        h, L, r = (float(v) for v in (design.mesh_size, design.plate_half_length, design.impactor_radius))
        under = [layer for f in features(design) for layer in f.under(design)]  # a backing's rows
        layers = [(float(t), rho, E, nu) for t, rho, E, nu in [*design.layers, *under]]
        rows = [max(1.0, t / h) for t, *_ in layers]
        rows[0] += max(0.0, 4.0 - sum(rows[: len(design.layers)]))  # at least 4 rows through the panel
        own = [c for c in (f.cost(design, h) for f in features(design)) if c is not None]  # the pen's tip
        hb, impactor = own[0] if own else (h, np.pi * r * r / (2.0 * h * h) + 2.0 * r / h + 1.0)
        nodes = (L / h + 1.0) * (sum(rows) + 1.0) + impactor
        speeds = [np.sqrt(E * (1 - nu) / (rho * (1 + nu) * (1 - 2 * nu))) for _, rho, E, nu in layers]
        ball = np.sqrt(
            design.ball_modulus
            * (1 - design.ball_poisson)
            / (design.ball_density * (1 + design.ball_poisson) * (1 - 2 * design.ball_poisson))
        )
        b1 = settings.bulk_viscosity
        # the Courant step of the fastest element: its half height over its material's wave speed
        h_over_c = min([0.5 * min(h, t / n) / c for (t, *_), n, c in zip(layers, rows, speeds)] + [0.5 * hb / ball])
        dt = settings.safety * h_over_c * (np.sqrt(1 + b1 * b1) - b1)
        substeps = (settings.frames - 1) * np.ceil(settings.frame_dt / dt)
        seconds = substeps * (SECONDS_PER_SUBSTEP + SECONDS_PER_NODE_SUBSTEP * nodes)
    return {"num_nodes": float(nodes), "substeps": float(substeps), "estimated_s": float(seconds)}


def check_size(design: Design, settings: Settings = Settings(), where: str = "") -> dict:
    """:func:`estimate`, refusing (one line with the estimate) a design whose mesh would exceed
    :data:`MAX_NODES` nodes; returns the estimate."""
    e = estimate(design, settings)
    if not e["num_nodes"] <= MAX_NODES:
        n = f"{e['num_nodes']:.3g}" if np.isfinite(e["num_nodes"]) else "an unbounded number of"
        raise InputError(
            f"{where}the design's mesh would have {n} nodes (plate {design.plate_half_length:g} x "
            f"{design.thickness:g} mm, ball radius {design.ball_radius:g} mm at mesh_size "
            f"{design.mesh_size:g} mm), more than the {MAX_NODES:,} any command builds; coarsen the "
            "mesh or shrink the design"
        )
    return e


def check_cost(
    seconds: float, nodes: float, design: Design, force: bool = False, where: str = "", what: str = ""
) -> None:
    """The one cost rule of simulate, generate, predict and sweep: refuse, unless ``force``, a plan estimated at
    over :data:`MAX_ESTIMATED_SECONDS` (one line: the estimate, ``what`` it covers, the mesh, how to go on)."""
    if seconds > MAX_ESTIMATED_SECONDS and not force:
        raise InputError(
            f"{where}about {nodes:.0f} nodes at mesh_size {design.mesh_size:g} mm: estimated "
            f"{seconds:.0f} s{what} exceeds {MAX_ESTIMATED_SECONDS:.0f} s; coarsen the mesh, record fewer "
            "frames or force it (force=True, --force)"
        )


def plan(design: Design, settings: Settings = Settings()) -> dict:
    """What a solve will cost before running it: nodes, cells, substeps, time step and estimated seconds. The
    mesh is built only after :func:`check_size` has refused a design too large to build."""
    design.validate()
    settings.validate()
    check_size(design, settings)
    mesh = design_mesh(design)
    per_frame = int(np.ceil(settings.frame_dt / stable_time_step(fem_model(design, settings, mesh), settings.safety)))
    n, substeps = len(mesh["mesh_pos"]), per_frame * (settings.frames - 1)
    return {
        "num_nodes": n,
        "num_cells": len(mesh["cells"]),
        "substeps": substeps,
        "dt": settings.frame_dt / per_frame,
        "estimated_s": substeps * (SECONDS_PER_SUBSTEP + SECONDS_PER_NODE_SUBSTEP * n),
    }


# -- the recorded window: did it hold the impact? --------------------------------------------------------------------
#: a peak plate stress in the window's last CUT_FRAMES frames, or a last frame still holding CUT_SHARE of it, may be
#: cut by the window's end: thin plates peak late (a 0.5 mm plate dropped from 1,000 mm: 946 MPa at frame 49 of 52,
#: 1,032 MPa at frame 55 of 90; a 0.75 mm plate from 750 mm peaks at frame 39, its last frame 90 % of it)
CUT_FRAMES, CUT_SHARE = 3, 0.95


def fall(design: Design, settings: Settings = Settings()) -> dict:
    """The impactor's free fall in the recorded window (it starts ``gap`` above the plate at ``impact_speed``,
    gravity on): ``window_ms``, ``fallen_mm`` (how far it falls in it), ``touch_frame`` (the frame it reaches the
    plate, counted from 0) and ``touch_height_mm`` (the least drop height that reaches it within the window)."""
    g, v0, gap = settings.gravity, design.impact_speed, design.gap
    window = (settings.frames - 1) * settings.frame_dt
    touch = (np.sqrt(v0 * v0 + 2 * g * gap) - v0) / g if g > 0 else gap / max(v0, 1e-300)
    least = max(0.0, (gap - 0.5 * g * window * window) / window)  # the impact speed that closes the gap in time
    return {
        "window_ms": window,
        "fallen_mm": v0 * window + 0.5 * g * window * window,
        "touch_frame": int(np.ceil(touch / settings.frame_dt - 1e-9)),
        "touch_height_mm": least * least / (2 * g) if g > 0 else float("inf"),
    }


def window_warnings(design: Design, settings: Settings, plate_history: np.ndarray, gap: np.ndarray) -> list[str]:
    """What a solve's recorded window missed, one line each: the impactor never reached the plate (``gap``, [T]
    mm from its lowest point to the plate's top on the axis, stayed above 0), or the peak plate stress
    (``plate_history``, [T] MPa: the plate's largest stress per frame) lies in the window's last frames, where the
    window's end may cut it (:data:`CUT_FRAMES`, :data:`CUT_SHARE`); each says what to change."""
    frames, dt = settings.frames, settings.frame_dt
    window = f"{frames} frames x {dt:g} ms = {(frames - 1) * dt:.3g} ms"
    if float(np.min(gap)) > 0:
        f = fall(design, settings)
        unit = f" (mm: {design.drop_height:g} m is {design.drop_height * 1e3:g})" if design.drop_height < 10 else ""
        return [
            f"the {design.impactor} did not touch the plate in the simulated window ({window}): from drop_height "
            f"{design.drop_height:g} mm it falls {f['fallen_mm']:.2g} of its {design.gap:g} mm gap; raise "
            f"drop_height{unit} above {f['touch_height_mm']:.3g} mm, or record more frames (--frames; it reaches "
            f"the plate at frame {f['touch_frame']})"
        ]
    history = np.asarray(plate_history, float).reshape(-1)
    peak, at = float(history.max()), int(history.argmax())
    if peak > 0 and (at >= frames - CUT_FRAMES or history[-1] >= CUT_SHARE * peak):
        more = max(90, 3 * frames // 2)  # 90: at least the shipped model's window (`hcmt models`)
        return [
            f"the peak plate stress ({peak:.1f} MPa) is at frame {at} ({at * dt:.3g} ms) of a window ending at "
            f"frame {frames - 1} ({(frames - 1) * dt:.3g} ms), which still holds {100 * history[-1] / peak:.0f} % "
            f"of it: the window may cut the peak; record more frames, e.g. --frames {more}"
        ]
    return []


# -- many designs: the solver's total, said before it starts ---------------------------------------------------------
def solver_seconds(designs: list[Design], settings: Settings = Settings(), sample: int = 8) -> float | None:
    """The solver's estimated seconds for ``designs`` one after another on one core: :func:`plan`'s estimate (from
    the built mesh, as ``hcmt simulate`` prints it) of up to ``sample`` designs spread over the list, scaled to all
    of them by :func:`estimate`'s (from their numbers alone: 0.1 ms a design, where a mesh takes 10 ms). None when
    a design is too large to plan (the cost check refuses it, naming it)."""
    if not designs:
        return 0.0
    rough = [estimate(d, settings)["estimated_s"] for d in designs]
    if not np.all(np.isfinite(rough)):
        return None
    picks = sorted({int(i) for i in np.linspace(0, len(designs) - 1, min(sample, len(designs))).round()})
    try:
        planned = sum(plan(designs[i], settings)["estimated_s"] for i in picks)
    except InputError:
        return None
    return planned / max(sum(rough[i] for i in picks), 1e-300) * sum(rough)


def duration(seconds: float) -> str:
    """``42 s``, ``12.5 min``, ``7.5 h``."""
    return (
        f"{seconds:.0f} s"
        if seconds < 120
        else f"{seconds / 60:.1f} min"
        if seconds < 7200
        else f"{seconds / 3600:.1f} h"
    )
