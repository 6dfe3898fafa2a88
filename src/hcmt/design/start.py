"""The frames a learned model's rollout of a new design starts from (``hcmt predict``, ``sweep``, the design
check): frames 0 and 1 built from the design's scene without a solver run when the ball cannot reach the plate
within the first frame, else the solver's first frame."""

from __future__ import annotations

from dataclasses import asdict, replace

import numpy as np

from hcmt.errors import InputError
from hcmt.sim.cost import check_size
from hcmt.sim.driver import simulate
from hcmt.sim.params import Design, Settings
from hcmt.sim.scene import design_mesh, fixed_dofs, static_fields


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
        raise InputError(
            f"drop_height {design.drop_height} mm: the ball ({design.impact_speed:.3g} mm/ms) would "
            f"cross the {design.gap} mm gap within the first frame ({dt} ms); lower drop_height or "
            "raise gap"
        )
    mesh = design_mesh(design)
    x0 = mesh["mesh_pos"].astype(np.float64)
    x1 = x0.copy()
    ball = mesh["body"] == 1
    x1[ball, 1] -= fall
    x1[~ball & ~fixed_dofs(mesh["node_type"])[:, 1], 1] -= 0.5 * g * dt * dt
    fields_ = dict(
        static_fields(design, mesh, settings.formulation),
        world_pos=np.stack([x0, x1]).astype(np.float32),
        stress=np.zeros((2, len(x0), 1), np.float32),
    )
    attrs = {
        **asdict(design),
        "impact_speed": design.impact_speed,
        "formulation": settings.formulation,
        "family": design.family,
    }
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
    f = dict(r.fields)
    f.pop("stress_max", None)
    return {"fields": f, "attrs": r.attrs, "info": {"solver_frames": 1, "wall_time": r.info.wall_time}}
