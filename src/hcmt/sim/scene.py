"""The Impact Plate scene: design parameters, their sampling and validation, and one simulated trajectory.

A deformable steel ball drops on the centre of a clamped glass panel (paper appendix "Impact Plate"; ANSYS explicit
dynamics there, :mod:`hcmt.sim.solver` here). Half model, symmetry line ``x = 0``. The ball starts ``gap`` above
the plate with the free-fall speed ``v0 = sqrt(2 g H)`` from the drop height ``H`` (the fall itself is not
simulated), so the impact happens inside the recorded window (52 frames x 0.002 ms = 0.104 ms).

Units (written to meta.json): mm, ms, g, hence N, MPa, mJ and mm/ms (= m/s).

Choices where the paper is silent (it lists "plate properties, thickness, density, modulus, drop height, mesh size"):
thickness U(0.5, 1.0) mm and drop height U(500, 1000) mm as its generalization study implies; plate density
U(2.2, 2.8)e-3 g/mm^3 and modulus U(50, 90) GPa (glass is 2.4-2.5e-3 and 60-80 GPa, widened); Poisson 0.20-0.25;
a steel ball (7.75-8.0e-3 g/mm^3, 190-210 GPa, nu 0.3) of radius 3-4 mm; the plate a disk of radius 15 mm
(``paper``) or 12 mm (``small``) clamped at its rim; mesh size drawn per preset so the node count matches
(about 2,200 for ``paper`` as in the paper's Table 6, 400-600 for ``small``).
"""
from __future__ import annotations

import time
from dataclasses import asdict, replace

import numpy as np

from hcmt.errors import InputError
from hcmt.sim.contact import PenaltyContact
from hcmt.sim.mesh import HANDLE, SYMMETRIC, WALL_BOUNDARY, impact_plate_mesh
from hcmt.sim.params import (
    BACKING_DENSITY,
    BACKING_POISSON,
    CONTACT_RADIUS,
    DESIGN_KEYS,
    DESIGN_UNITS,
    EDGES,
    FAMILIES,
    FIRST_SCENE_KEYS,
    GRAVITY,
    MATERIALS,
    MAX_ESTIMATED_SECONDS,
    RANGES,
    RELATIVE,
    UNITS,
    VARIANTS,
    Design,
    Settings,
    describe_family,
    design_key,
    design_values,
    family_ranges,
    parse_design,
    parse_number,
    parse_stack,
    resolve_relative,
)
from hcmt.sim.solver import CentralDifference, build_model, deformation, nodal_von_mises, stable_time_step


def sample_design(rng: np.random.Generator, preset: str = "small", variant: str | None = None,
                  edge_fraction: float = 0.0, family: str = "mono") -> Design:
    """Draw one design: every parameter of the family's ranges (:func:`family_ranges`) uniform, in sorted order,
    a variant's ranges replacing the training ones. With ``edge_fraction`` > 0, that share of designs then has its
    thickness or its drop height redrawn inside :data:`EDGES` (draws after the uniform ones: a design with
    ``edge_fraction`` 0 is the same as before; a ``mono`` design the same as before families existed)."""
    ranges = family_ranges(preset, family, variant)
    names = sorted(ranges)
    u = rng.random(len(names))
    values = resolve_relative({k: float(ranges[k][0] + (ranges[k][1] - ranges[k][0]) * ui)
                               for k, ui in zip(names, u)})
    if edge_fraction > 0 and rng.random() < edge_fraction:
        key = sorted(EDGES)[int(rng.random() < 0.5)]
        (lo, hi), (a, b) = ranges[key], EDGES[key]
        values[key] = float(lo + (hi - lo) * (a + (b - a) * rng.random()))
    return Design(**values)


def design_mesh(design: Design) -> dict[str, np.ndarray]:
    return impact_plate_mesh(design.thickness, design.impactor_radius, design.mesh_size,
                             plate_half_length=design.plate_half_length, gap=design.gap,
                             layers=[layer[0] for layer in design.layers], support_radius=design.support_radius,
                             backing_thickness=design.backing_thickness, impactor=design.impactor)


def cell_materials(design: Design, mesh: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(density, modulus, Poisson) per cell [C] from the mesh's ``cell_layer``: the panel's layers, the backing
    (last), the impactor (-1: the ball_* material)."""
    table = np.array([layer[1:] for layer in design.layers]
                     + ([(BACKING_DENSITY, design.backing_modulus, BACKING_POISSON)] if design.backing_thickness > 0
                        else [])
                     + [(design.ball_density, design.ball_modulus, design.ball_poisson)])
    m = table[mesh["cell_layer"]]  # -1 picks the impactor's row
    return m[:, 0], m[:, 1], m[:, 2]


#: cost model of the solver (docs/solver.md, "Speed"): per substep a fixed ~0.4 ms of Python and sparse-product
#: overhead plus ~3e-7 s per node, on one core of the development machine (a 34,768-node design measured 15 ms per
#: substep with the other core busy: 582 s where 1e-7 s per node had estimated 150 s; small meshes stay
#: overhead-bound, so their estimate stays conservative)
SECONDS_PER_SUBSTEP, SECONDS_PER_NODE_SUBSTEP = 4e-4, 3e-7
#: the ranges the solver is validated for (docs/solver.md): outside them, results are not trusted
VALIDATED = {"impact_speed": (0.0, 10.0), "plate_modulus": (1e3, 1e6), "ball_modulus": (1e3, 1e6),
             "plate_poisson": (0.0, 0.45), "ball_poisson": (0.0, 0.45), "plate_density": (5e-4, 2e-2),
             "ball_density": (5e-4, 2e-2)}


class SolverError(InputError):
    """The solve cannot go on (an element inverted): the design is outside what the solver handles."""


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


def _model(design: Design, settings: Settings, mesh: dict):
    return build_model(mesh["mesh_pos"], mesh["cells"], *cell_materials(design, mesh),
                       formulation=settings.formulation, bulk_viscosity=settings.bulk_viscosity)


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
    per_frame = int(np.ceil(settings.frame_dt / stable_time_step(_model(design, settings, mesh), settings.safety)))
    n, substeps = len(mesh["mesh_pos"]), per_frame * (settings.frames - 1)
    return {"num_nodes": n, "num_cells": len(mesh["cells"]), "substeps": substeps,
            "dt": settings.frame_dt / per_frame,
            "estimated_s": substeps * (SECONDS_PER_SUBSTEP + SECONDS_PER_NODE_SUBSTEP * n)}


def solver(design: Design, settings: Settings = Settings()) -> tuple[CentralDifference, dict, int]:
    """The solver of a design, started: (the integrator at t = 0 with the impactor at ``v0``, the mesh
    (:func:`design_mesh`), substeps per frame). Boundary conditions :func:`fixed_dofs`, the pen's rod
    ``rigid``, penalty contact between the plate and the impactor."""
    mesh = design_mesh(design)
    X, cells, body = mesh["mesh_pos"], mesh["cells"], mesh["body"]
    model = _model(design, settings, mesh)
    substeps = int(np.ceil(settings.frame_dt / stable_time_step(model, settings.safety)))
    dt = settings.frame_dt / substeps  # frames land exactly on substeps
    contact = PenaltyContact(X, cells, body, model.mass, dt, alpha=settings.penalty)
    sim = CentralDifference(model, fixed_dofs(mesh["node_type"]), dt, contact=contact, gravity=settings.gravity,
                            rigid=(mesh["rigid"], design.pen_mass))
    v0 = np.zeros_like(X)
    v0[body == 1, 1] = -design.impact_speed
    sim.start(X, v0)
    return sim, mesh, substeps


def simulate(design: Design, settings: Settings = Settings(), *, progress=None) -> dict:
    """Simulate one design. Returns ``fields`` (the native-format arrays: mesh_pos, cells, node_type, density,
    modulus static; world_pos [T,N,2], stress [T,N,1] dynamic; float32/int32), ``attrs`` (the design parameters,
    its impact speed and the formulation) and ``info`` (wall and CPU time, substeps, time step, final energies).

    Frame k is the state at t = k * frame_dt; frame 0 the initial one. ``stress`` is the nodal von Mises stress
    (MPa): element Cauchy stress, the out-of-plane (hoop) component included, area-averaged to the nodes of its
    own body. With ``settings.peak_stress`` also ``stress_max`` [T,N,1]: each node's largest von Mises stress over
    the solver's substeps since the previous frame (frame 0: its own), the peak a coarse frame interval would
    otherwise step over (docs/RESULTS.md, "Frame interval")."""
    design.validate()
    settings.validate()
    check_size(design, settings)
    start, cpu_start = time.perf_counter(), time.process_time()
    sim, mesh, substeps = solver(design, settings)
    model, X, cells, dt = sim.model, mesh["mesh_pos"], mesh["cells"], sim.dt
    T, N = settings.frames, len(X)
    world_pos = np.empty((T, N, 2), np.float32)
    stress = np.empty((T, N, 1), np.float32)
    peak = np.empty((T, N, 1), np.float32) if settings.peak_stress else None
    for k in range(T):
        if k and peak is None:
            sim.step(substeps)
        elif k:  # one substep at a time: the largest stress between two frames (Settings.peak_stress)
            running = np.zeros(N)
            for _ in range(substeps):
                sim.step(1)
                np.maximum(running, nodal_von_mises(model, sim.x), out=running)
            peak[k, :, 0] = running
        world_pos[k] = sim.x
        F11, F12, F21, F22, F33 = deformation(model, sim.x)
        inverted = np.flatnonzero((F11 * F22 - F12 * F21) * F33 <= 0)
        if len(inverted) or not np.isfinite(sim.x).all():
            what = f"element {int(inverted[0])} inverted" if len(inverted) else "positions became non-finite"
            raise SolverError(f"solve stopped at frame {k} (t = {k * settings.frame_dt:.4g} ms): {what}; the design "
                              "is outside what the explicit solver handles (see the validated ranges in "
                              "docs/solver.md)")
        stress[k, :, 0] = nodal_von_mises(model, sim.x)
        if peak is not None and k == 0:
            peak[0] = stress[0]
        if progress is not None:
            progress(k)
    fields_ = dict(_static_fields(design, mesh, settings.formulation), world_pos=world_pos, stress=stress)
    if peak is not None:
        fields_["stress_max"] = peak
    attrs = {**asdict(design), "impact_speed": design.impact_speed, "formulation": settings.formulation,
             "family": design.family}
    info = dict(wall_time=time.perf_counter() - start, cpu_time=time.process_time() - cpu_start,
                substeps=substeps * (T - 1), dt=dt, num_nodes=N, num_cells=len(cells), energy=sim.energies())
    return dict(fields=fields_, attrs=attrs, info=info)


def fixed_dofs(node_type: np.ndarray) -> np.ndarray:
    """[N, 2] bool: the degrees of freedom a boundary condition holds: SYMMETRIC x (the axis), HANDLE x and y
    (clamped), WALL_BOUNDARY y (a roller: the simply supported ring)."""
    fixed = np.zeros((len(node_type), 2), dtype=bool)
    fixed[node_type == SYMMETRIC, 0] = True
    fixed[node_type == HANDLE] = True
    fixed[node_type == WALL_BOUNDARY, 1] = True
    return fixed


def _static_fields(design: Design, mesh: dict, formulation: str = "axisymmetric") -> dict[str, np.ndarray]:
    """The native-format static fields of a design's mesh: mesh_pos, cells, node_type, density, modulus.

    A node's density and modulus are those of the softest cell it belongs to, so that a soft layer one element
    thick is seen at both its faces. The pen's nodes carry the pen's effective density, its whole mass (tip and
    rod) over the tip's volume: a learned model sees the rod only through it."""
    rho_c, E_c, _ = cell_materials(design, mesh)
    cells = mesh["cells"]
    rank = np.lexsort((rho_c, E_c))  # cells from softest to stiffest
    order = np.empty(len(rank), np.int64)
    order[rank] = np.arange(len(rank))
    node_rank = np.full(len(mesh["mesh_pos"]), len(rank), np.int64)
    np.minimum.at(node_rank, cells.ravel(), np.repeat(order, 3))
    softest = rank[node_rank]
    density, modulus = rho_c[softest], E_c[softest]
    if design.pen_tip_radius > 0:
        tip = mesh["cell_body"] == 1
        p = mesh["mesh_pos"][cells[tip]]
        area = 0.5 * np.abs((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                            - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0]))
        weight = 2 * np.pi * p[:, :, 0].mean(1) if formulation == "axisymmetric" else 1.0  # revolved, or per mm
        volume = float(np.sum(weight * area))
        density = np.where(mesh["body"] == 1, design.ball_density + design.pen_mass / volume, density)
    return dict(
        mesh_pos=mesh["mesh_pos"].astype(np.float32), cells=cells.astype(np.int32),
        node_type=mesh["node_type"].astype(np.int32)[:, None],
        density=density.astype(np.float32)[:, None], modulus=modulus.astype(np.float32)[:, None])


def initial_frames(design: Design, settings: Settings = Settings()) -> dict:
    """The first two frames of a design without a solver run: what a learned model needs to start a rollout.

    Frame 0 is the mesh at rest with the ball ``gap`` above the plate; frame 1 is one ``frame_dt`` later in free
    flight, ``x^1 = x^0 - (v0 dt + g dt^2 / 2) e_y`` for the ball and ``- g dt^2 / 2`` for the plate's unclamped
    nodes (the ball cannot reach the plate in one frame: ``v0 dt < gap`` is checked). The solver's frame 1 agrees
    to float32 precision (tests/design/test_predict.py). Stress is zero in both frames. Returns ``fields`` (static
    fields, ``world_pos [2, N, 2]``, ``stress [2, N, 1]``) and ``attrs``, as :func:`simulate`."""
    design.validate()
    settings.validate()
    check_size(design, settings)
    dt, g = settings.frame_dt, settings.gravity
    fall = first_frame_fall(design, settings)
    if fall >= design.gap:
        raise InputError(f"drop_height {design.drop_height} mm: the ball ({design.impact_speed:.3g} mm/ms) would "
                         f"cross the {design.gap} mm gap within the first frame ({dt} ms); lower drop_height or "
                         "raise gap")
    mesh = design_mesh(design)
    x0 = mesh["mesh_pos"].astype(np.float64)
    x1 = x0.copy()
    ball = mesh["body"] == 1
    x1[ball, 1] -= fall
    x1[~ball & ~fixed_dofs(mesh["node_type"])[:, 1], 1] -= 0.5 * g * dt * dt
    fields_ = dict(_static_fields(design, mesh, settings.formulation), world_pos=np.stack([x0, x1]).astype(np.float32),
                   stress=np.zeros((2, len(x0), 1), np.float32))
    attrs = {**asdict(design), "impact_speed": design.impact_speed, "formulation": settings.formulation,
             "family": design.family}
    return dict(fields=fields_, attrs=attrs)


def first_frame_fall(design: Design, settings: Settings) -> float:
    """How far the ball falls in the first frame, ``v0 dt + g dt^2 / 2`` (mm)."""
    dt = settings.frame_dt
    return design.impact_speed * dt + 0.5 * settings.gravity * dt * dt


def start_frames(design: Design, settings: Settings = Settings()) -> dict:
    """Frames 0 and 1 of a design, what a learned rollout starts from: :func:`initial_frames` (no solver run) when
    the ball cannot reach the plate within the first frame, else the solver's own first frame (a coarse interval:
    at 0.008 ms a ball at 4 mm/ms crosses the 0.02 mm gap within it; the cost is one frame of a solve, in
    ``info``). Returns ``fields``, ``attrs`` and ``info`` ({"solver_frames": 0 or 1, "wall_time"})."""
    if first_frame_fall(design.validate(), settings.validate()) < design.gap:
        return {**initial_frames(design, settings), "info": {"solver_frames": 0, "wall_time": 0.0}}
    r = simulate(design, replace(settings, frames=2))
    f = dict(r["fields"])
    f.pop("stress_max", None)
    return {"fields": f, "attrs": r["attrs"], "info": {"solver_frames": 1, "wall_time": r["info"]["wall_time"]}}


def feature_spec(settings: Settings = Settings()) -> dict:
    """meta.json ``features`` of an Impact Plate dataset."""
    T = settings.frames
    return {
        "mesh_pos": {"type": "static", "shape": [-1, 2], "dtype": "float32"},
        "cells": {"type": "static", "shape": [-1, 3], "dtype": "int32"},
        "node_type": {"type": "static", "shape": [-1, 1], "dtype": "int32"},
        "density": {"type": "static", "shape": [-1, 1], "dtype": "float32"},
        "modulus": {"type": "static", "shape": [-1, 1], "dtype": "float32"},
        "world_pos": {"type": "dynamic", "shape": [T, -1, 2], "dtype": "float32"},
        "stress": {"type": "dynamic", "shape": [T, -1, 1], "dtype": "float32"},
        **({"stress_max": {"type": "dynamic", "shape": [T, -1, 1], "dtype": "float32"}} if settings.peak_stress
           else {}),
    }


__all__ = ["Design", "Settings", "RANGES", "VARIANTS", "FAMILIES", "MATERIALS", "UNITS", "GRAVITY",
           "CONTACT_RADIUS", "sample_design", "family_ranges", "parse_stack", "design_from_attrs", "simulate",
           "initial_frames", "start_frames", "feature_spec", "design_mesh",
           # from hcmt.sim.params, where the command's parsers take them without the solver
           "BACKING_DENSITY", "BACKING_POISSON", "DESIGN_KEYS", "DESIGN_UNITS", "EDGES", "FIRST_SCENE_KEYS",
           "MAX_ESTIMATED_SECONDS", "RELATIVE", "describe_family", "design_key", "design_values", "parse_design",
           "parse_number", "resolve_relative"]


def design_from_attrs(attrs: dict) -> Design:
    """The :class:`Design` of a trajectory's attributes; parameters a dataset made before they existed take their
    default (the first scene's: no layers under the top one, clamped, the ball)."""
    return Design(**{k: float(attrs[k]) for k in DESIGN_KEYS if k in attrs})


def middle_design(meta: dict | None, ranges: dict[str, tuple[float, float]] | None = None) -> Design:
    """The middle of a model's training ranges (``ranges``: min and max of each parameter over its training
    designs), every parameter they do not name at the middle of the training preset's ranges (``hcmt
    simulate``'s defaults for that preset; the preset of a dataset's meta.json, ``paper`` when it names none)."""
    preset = ((meta or {}).get("generator") or {}).get("preset", "paper")
    values = {k: 0.5 * (lo + hi) for k, (lo, hi) in RANGES.get(preset, RANGES["paper"]).items()}
    values.update({k: 0.5 * (float(lo) + float(hi)) for k, (lo, hi) in (ranges or {}).items() if k in DESIGN_KEYS})
    return Design(**values)
