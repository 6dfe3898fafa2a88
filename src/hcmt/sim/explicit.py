"""Explicit time integration of the Impact Plate's FE model (:mod:`hcmt.sim.solver`): the central difference scheme
with a lumped mass, ``M a = f_ext - f_int(x, v) + f_contact(x)``, and the pen's rigid rod.

It stands apart from the solver's operators and constitutive law (:mod:`hcmt.sim.solver`: what the forces of a
configuration are) because it owns the state in time (positions, half-step velocities, the step count), the fixed
degrees of freedom and the rod; the step ``dt`` it is given is bounded by :func:`hcmt.sim.solver.stable_time_step`.
"""

from __future__ import annotations

import numpy as np

from hcmt.errors import InputError
from hcmt.sim.solver import FEModel, internal_force, strain_energy


class CentralDifference:
    """Explicit central-difference integration of ``M a = f_ext - f_int(x, v) + f_contact(x)``:

        v_{n+1/2} = v_{n-1/2} + dt a_n,   x_{n+1} = x_n + dt v_{n+1/2},

    with ``a = 0`` and ``v = 0`` on the fixed degrees of freedom ``fixed`` [N,2] (SYMMETRIC: x, HANDLE: x and y).
    ``gravity`` (mm/ms^2) acts along -y on every node. ``contact`` is any object with ``force(x, v)`` and
    ``energy(x)`` (see :class:`hcmt.sim.contact.PenaltyContact`).

    ``rigid = (nodes [N] bool, mass M)``: those nodes are held by a rigid rod of mass ``M`` (g) that moves along y
    only (the pen): they share one axial acceleration ``a_y = (sum_G f_y - M g) / (sum_G m + M)`` and keep their x."""

    def __init__(
        self,
        model: FEModel,
        fixed: np.ndarray,
        dt: float,
        *,
        contact=None,
        gravity: float = 0.0,
        rigid: tuple[np.ndarray, float] | None = None,
    ):
        if not dt > 0:
            raise InputError(f"time step must be > 0, got {dt}")
        self.model, self.dt, self.contact, self.gravity = model, float(dt), contact, float(gravity)
        self.free = ~np.asarray(fixed, bool)
        self.inv_mass = (1.0 / model.mass)[:, None] * self.free
        self.f_ext = np.zeros((model.num_nodes, 2))
        self.f_ext[:, 1] = -model.mass * self.gravity
        self.rigid, self.rod_mass = None, 0.0
        if rigid is not None and np.any(rigid[0]):
            self.rigid, self.rod_mass = np.flatnonzero(rigid[0]), float(rigid[1])
            if not self.rod_mass >= 0:
                raise InputError(f"rigid rod mass must be >= 0 g, got {rigid[1]}")
            self.inv_mass[self.rigid] = 0.0
            self.rigid_mass = float(model.mass[self.rigid].sum()) + self.rod_mass
        self.t, self.steps = 0.0, 0

    def acceleration(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        f = self.f_ext - internal_force(self.model, x, v)
        if self.contact is not None:
            f += self.contact.force(x, v)
        a = f * self.inv_mass
        if self.rigid is not None:
            a[self.rigid, 1] = (f[self.rigid, 1].sum() - self.rod_mass * self.gravity) / self.rigid_mass
        return a

    def start(self, x0: np.ndarray, v0: np.ndarray) -> None:
        """Initial state: positions ``x0`` and velocities ``v0`` at t = 0. A fixed component keeps its initial
        velocity (zero in the Impact Plate scene; nonzero makes it a prescribed-velocity boundary)."""
        self.x = np.array(x0, float)
        v0 = np.array(v0, float)
        self.a = self.acceleration(self.x, v0)
        self.v_half = v0 - 0.5 * self.dt * self.a  # v_{-1/2}
        self.t, self.steps = 0.0, 0

    def step(self, n: int = 1) -> None:
        x, v, dt = self.x, self.v_half, self.dt
        for _ in range(n):  # the time loop itself (each step fully vectorized)
            v += dt * self.a
            x += dt * v
            self.a = self.acceleration(x, v)
        self.steps += n
        self.t = self.steps * dt

    @property
    def velocity(self) -> np.ndarray:
        """Velocity at the current (integer) time, ``v_n = v_{n-1/2} + dt/2 a_n``."""
        return self.v_half + 0.5 * self.dt * self.a

    def energies(self) -> dict[str, float]:
        """Kinetic, strain, contact-penalty and gravity potential energy (mJ) at the current time."""
        v = self.velocity
        m = self.model.mass
        rod = dict(kinetic=0.0, gravity=0.0)
        if self.rigid is not None:  # the rod moves with its nodes (their mean height)
            j = self.rigid
            rod = dict(
                kinetic=0.5 * self.rod_mass * float(v[j[0], 1]) ** 2,
                gravity=self.rod_mass * self.gravity * float(self.x[j, 1].mean()),
            )
        return dict(
            kinetic=float(0.5 * np.dot(m, (v * v).sum(1))) + rod["kinetic"],
            strain=strain_energy(self.model, self.x),
            contact=self.contact.energy(self.x) if self.contact is not None else 0.0,
            gravity=float(self.gravity * np.dot(m, self.x[:, 1])) + rod["gravity"],
        )
