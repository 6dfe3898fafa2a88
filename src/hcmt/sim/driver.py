"""The solver driver: a design's scene (:mod:`hcmt.sim.scene`) started in the explicit solver
(:mod:`hcmt.sim.solver`, :mod:`hcmt.sim.explicit`, :mod:`hcmt.sim.contact`) and run frame by frame into one
trajectory."""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np

from hcmt.errors import InputError
from hcmt.sim.contact import PenaltyContact
from hcmt.sim.cost import check_size
from hcmt.sim.explicit import CentralDifference
from hcmt.sim.params import Design, Settings
from hcmt.sim.scene import design_mesh, fem_model, fixed_dofs, static_fields
from hcmt.sim.solver import FEModel, deformation, nodal_von_mises, stable_time_step


@dataclass(frozen=True)
class SolveInfo:
    """How a solve went: wall and CPU time (s), substeps over the window, the time step (ms), the mesh's size and
    the final energies (mJ: kinetic, strain, contact penalty, gravity potential, ...)."""

    wall_time: float
    cpu_time: float
    substeps: int
    dt: float
    num_nodes: int
    num_cells: int
    energy: dict[str, float]


@dataclass(frozen=True)
class SimResult:
    """One design's solved trajectory (:func:`simulate`): ``fields``, the native-format arrays; ``attrs``, the
    design parameters, its impact speed, the formulation and the family (a trajectory's attributes in the HDF5
    file); ``info``, how the solve went."""

    fields: dict[str, np.ndarray]
    attrs: dict[str, float | str]
    info: SolveInfo


class SolverError(InputError):
    """The solve cannot go on (an element inverted): the design is outside what the solver handles."""


def solver(design: Design, settings: Settings = Settings()) -> tuple[CentralDifference, dict, int]:
    """The solver of a design, started: (the integrator at t = 0 with the impactor at ``v0``, the mesh
    (:func:`design_mesh`), substeps per frame). Boundary conditions :func:`fixed_dofs`, the pen's rod
    ``rigid``, penalty contact between the plate and the impactor."""
    mesh = design_mesh(design)
    X, cells, body = mesh["mesh_pos"], mesh["cells"], mesh["body"]
    model = fem_model(design, settings, mesh)
    substeps = int(np.ceil(settings.frame_dt / stable_time_step(model, settings.safety)))
    dt = settings.frame_dt / substeps  # frames land exactly on substeps
    contact = PenaltyContact(X, cells, body, model.mass, dt, alpha=settings.penalty)
    sim = CentralDifference(
        model,
        fixed_dofs(mesh["node_type"]),
        dt,
        contact=contact,
        gravity=settings.gravity,
        rigid=(mesh["rigid"], design.pen_mass),
    )
    v0 = np.zeros_like(X)
    v0[body == 1, 1] = -design.impact_speed
    sim.start(X, v0)
    return sim, mesh, substeps


def simulate(design: Design, settings: Settings = Settings(), *, progress=None) -> SimResult:
    """Simulate one design, as a :class:`SimResult`: ``fields`` (the native-format arrays: mesh_pos, cells,
    node_type, density, modulus static; world_pos [T,N,2], stress [T,N,1] dynamic; float32/int32), ``attrs`` (the
    design parameters, its impact speed and the formulation) and ``info`` (:class:`SolveInfo`).

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
        # one substep at a time with peak stress: the largest stress between two frames (Settings.peak_stress)
        if k and peak is not None:
            running = np.zeros(N)
            for _ in range(substeps):
                sim.step(1)
                np.maximum(running, nodal_von_mises(model, sim.x), out=running)
            peak[k, :, 0] = running
        elif k:
            sim.step(substeps)
        world_pos[k] = sim.x
        _check_frame(model, sim.x, k, settings.frame_dt)
        stress[k, :, 0] = nodal_von_mises(model, sim.x)
        if peak is not None and k == 0:
            peak[0] = stress[0]
        if progress is not None:
            progress(k)
    fields_ = dict(static_fields(design, mesh, settings.formulation), world_pos=world_pos, stress=stress)
    if peak is not None:
        fields_["stress_max"] = peak
    attrs = {
        **asdict(design),
        "impact_speed": design.impact_speed,
        "formulation": settings.formulation,
        "family": design.family,
    }
    info = SolveInfo(
        wall_time=time.perf_counter() - start,
        cpu_time=time.process_time() - cpu_start,
        substeps=substeps * (T - 1),
        dt=float(dt),
        num_nodes=N,
        num_cells=len(cells),
        energy={k: float(v) for k, v in sim.energies().items()},
    )
    return SimResult(fields_, attrs, info)


def _check_frame(model: FEModel, x: np.ndarray, k: int, frame_dt: float) -> None:
    """Raise :class:`SolverError` if frame ``k``'s positions ``x`` invert an element or are not finite."""
    F11, F12, F21, F22, F33 = deformation(model, x)
    inverted = np.flatnonzero((F11 * F22 - F12 * F21) * F33 <= 0)
    if len(inverted) or not np.isfinite(x).all():
        what = f"element {int(inverted[0])} inverted" if len(inverted) else "positions became non-finite"
        raise SolverError(
            f"solve stopped at frame {k} (t = {k * frame_dt:.4g} ms): {what}; the design "
            "is outside what the explicit solver handles (see the validated ranges in "
            "docs/solver.md)"
        )
