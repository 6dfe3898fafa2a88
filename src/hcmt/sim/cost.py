"""What a solve will cost and whether the solver is trusted for a design, before it runs: the node and substep
estimate from the design's numbers (:func:`estimate`), the size and time limits every command applies
(:func:`check_size`, :func:`check_cost`), the plan from the built mesh (:func:`plan`) and the validated ranges
(:func:`validated_warnings`)."""
from __future__ import annotations

import numpy as np

from hcmt.errors import InputError
from hcmt.sim.params import BACKING_DENSITY, BACKING_POISSON, MAX_ESTIMATED_SECONDS, Design, Settings
from hcmt.sim.scene import design_mesh, fem_model
from hcmt.sim.solver import stable_time_step

#: cost model of the solver (docs/solver.md, "Speed"): per substep a fixed ~0.4 ms of Python and sparse-product
#: overhead plus ~3e-7 s per node, on one core of the development machine (a 34,768-node design measured 15 ms per
#: substep with the other core busy: 582 s where 1e-7 s per node had estimated 150 s; small meshes stay
#: overhead-bound, so their estimate stays conservative)
SECONDS_PER_SUBSTEP, SECONDS_PER_NODE_SUBSTEP = 4e-4, 3e-7
#: the ranges the solver is validated for (docs/solver.md): outside them, results are not trusted
VALIDATED = {"impact_speed": (0.0, 10.0), "plate_modulus": (1e3, 1e6), "ball_modulus": (1e3, 1e6),
             "plate_poisson": (0.0, 0.45), "ball_poisson": (0.0, 0.45), "plate_density": (5e-4, 2e-2),
             "ball_density": (5e-4, 2e-2)}


def validated_warnings(design: Design) -> list[str]:
    """One line per parameter outside the range the solver is validated for."""
    out = []
    for key, (lo, hi) in VALIDATED.items():
        v = getattr(design, key)
        if not lo <= v <= hi:
            unit = " mm/ms (= m/s)" if key == "impact_speed" else ""
            out.append(f"{key} = {v:.6g}{unit} is outside the range the solver is validated for ({lo:g} .. {hi:g}; "
                       "docs/solver.md): do not trust the result")
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
        layers = [(float(t), rho, E, nu) for t, rho, E, nu in design.layers]
        if design.backing_thickness > 0:
            layers.append((float(design.backing_thickness), BACKING_DENSITY, design.backing_modulus,
                           BACKING_POISSON))
        rows = [max(1.0, t / h) for t, *_ in layers]
        rows[0] += max(0.0, 4.0 - sum(rows[:len(design.layers)]))  # at least 4 rows through the panel
        if design.pen_tip_radius > 0:  # quarter disk at min(h, r / 3)
            hb = min(h, r / 3.0)
            impactor = np.pi * r * r / (4.0 * hb * hb) + 2.0 * r / hb + 1.0
        else:
            hb = h
            impactor = np.pi * r * r / (2.0 * h * h) + 2.0 * r / h + 1.0
        nodes = (L / h + 1.0) * (sum(rows) + 1.0) + impactor
        speeds = [np.sqrt(E * (1 - nu) / (rho * (1 + nu) * (1 - 2 * nu))) for _, rho, E, nu in layers]
        ball = np.sqrt(design.ball_modulus * (1 - design.ball_poisson) / (
            design.ball_density * (1 + design.ball_poisson) * (1 - 2 * design.ball_poisson)))
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
        raise InputError(f"{where}the design's mesh would have {n} nodes (plate {design.plate_half_length:g} x "
                         f"{design.thickness:g} mm, ball radius {design.ball_radius:g} mm at mesh_size "
                         f"{design.mesh_size:g} mm), more than the {MAX_NODES:,} any command builds; coarsen the "
                         "mesh or shrink the design")
    return e


def check_cost(seconds: float, nodes: float, design: Design, force: bool = False, where: str = "",
               what: str = "") -> None:
    """The one cost rule of simulate, generate, predict and sweep: refuse, unless ``force``, a plan estimated at
    over :data:`MAX_ESTIMATED_SECONDS` (one line: the estimate, ``what`` it covers, the mesh, how to go on)."""
    if seconds > MAX_ESTIMATED_SECONDS and not force:
        raise InputError(f"{where}about {nodes:.0f} nodes at mesh_size {design.mesh_size:g} mm: estimated "
                         f"{seconds:.0f} s{what} exceeds {MAX_ESTIMATED_SECONDS:.0f} s; coarsen the mesh, record fewer "
                         "frames or force it (force=True, --force)")


def plan(design: Design, settings: Settings = Settings()) -> dict:
    """What a solve will cost before running it: nodes, cells, substeps, time step and estimated seconds. The
    mesh is built only after :func:`check_size` has refused a design too large to build."""
    design.validate()
    settings.validate()
    check_size(design, settings)
    mesh = design_mesh(design)
    per_frame = int(np.ceil(settings.frame_dt / stable_time_step(fem_model(design, settings, mesh), settings.safety)))
    n, substeps = len(mesh["mesh_pos"]), per_frame * (settings.frames - 1)
    return {"num_nodes": n, "num_cells": len(mesh["cells"]), "substeps": substeps,
            "dt": settings.frame_dt / per_frame,
            "estimated_s": substeps * (SECONDS_PER_SUBSTEP + SECONDS_PER_NODE_SUBSTEP * n)}
