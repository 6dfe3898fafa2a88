"""The built-in FEM solver against physics: Hertz impact, energy conservation, wave speed, beam theory, objectivity.

Every expected value is an analytic formula (Hertz, Euler-Bernoulli, L/c), never a number produced by the code.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse.linalg import eigsh, spsolve

from hcmt.sim.contact import PenaltyContact
from hcmt.sim.explicit import CentralDifference
from hcmt.sim.mesh import SYMMETRIC, impact_plate_mesh, plate_mesh, preset_mesh
from hcmt.sim.scene import fixed_dofs
from hcmt.sim.solver import (
    build_model,
    internal_force,
    linear_stiffness,
    nodal_von_mises,
    stable_time_step,
    strain_energy,
)
from hertz import contact_history, hertz

STEEL = dict(density=7.85e-3, modulus=200e3, poisson=0.3)  # g/mm^3, MPa
GLASS = dict(density=2.5e-3, modulus=70e3, poisson=0.22)


def two_body_model(mesh, ball, plate, formulation="axisymmetric", bulk_viscosity=0.0):
    cb = mesh["cell_body"]
    props = {k: np.where(cb == 1, ball[k], plate[k]) for k in ("density", "modulus", "poisson")}
    return build_model(
        mesh["mesh_pos"],
        mesh["cells"],
        props["density"],
        props["modulus"],
        props["poisson"],
        formulation=formulation,
        bulk_viscosity=bulk_viscosity,
    )


def test_hertz_sphere_on_thick_block():
    """Axisymmetric steel sphere (R = 10 mm, 5 m/s) on a thick glass block: peak force and contact duration within
    10% of Hertz: 1/E* = (1-nu1^2)/E1 + (1-nu2^2)/E2, d = (15 m v^2 / (16 E* sqrt R))^(2/5),
    F = 4/3 E* sqrt(R) d^(3/2), t_c = 2.94 d / v."""
    R, v, depth = 10.0, 5.0, 10.0
    mesh = impact_plate_mesh(
        depth,
        R,
        0.15,
        plate_half_length=12.0,
        gap=1e-3,
        plate_growth=1.15,
        plate_h_max=1.0,
        plate_y_growth=1.15,
        ball_growth=1.15,
        ball_h_max=1.0,
    )
    model = two_body_model(mesh, STEEL, GLASS)
    X, body = mesh["mesh_pos"], mesh["body"]
    fixed = np.zeros_like(X, dtype=bool)
    fixed[mesh["node_type"] == SYMMETRIC, 0] = True
    fixed[(body == 0) & (X[:, 1] < -depth + 1e-9)] = True  # block resting on a rigid floor
    dt = stable_time_step(model)
    contact = PenaltyContact(X, mesh["cells"], body, model.mass, dt)
    sim = CentralDifference(model, fixed, dt, contact=contact)
    v0 = np.zeros_like(X)
    v0[body == 1, 1] = -v
    sim.start(X, v0)

    m = model.mass[body == 1].sum()
    assert m == pytest.approx(STEEL["density"] * 4 / 3 * np.pi * R**3, rel=0.01)  # half disk revolves to a sphere
    f_max, t_c = hertz(m, R, v)
    _, force, duration = contact_history(sim, contact, body == 1, 1.3 * t_c)
    assert force.max() == pytest.approx(f_max, rel=0.10)
    assert duration == pytest.approx(t_c, rel=0.10)
    assert force[-1] == 0.0  # the ball has bounced off


@pytest.mark.parametrize("formulation", ["axisymmetric", "plane_strain"])
def test_energy_conserved_through_impact(formulation):
    """Without damping, kinetic + strain + penalty (+ gravity potential) energy stays within 0.5% through an impact
    of a steel ball on a clamped glass plate, while a large part of it passes through strain energy."""
    mesh = preset_mesh("small")
    model = two_body_model(mesh, STEEL, GLASS, formulation)
    dt = 0.002 / np.ceil(0.002 / stable_time_step(model))
    contact = PenaltyContact(mesh["mesh_pos"], mesh["cells"], mesh["body"], model.mass, dt)
    sim = CentralDifference(model, fixed_dofs(mesh["node_type"]), dt, contact=contact, gravity=9.81e-3)
    v0 = np.zeros_like(mesh["mesh_pos"])
    v0[mesh["body"] == 1, 1] = -np.sqrt(2 * 9.81e-3 * 1000.0)
    sim.start(mesh["mesh_pos"], v0)
    e0 = sum(sim.energies().values())
    totals, strain = [], []
    for _ in range(51):
        sim.step(int(round(0.002 / dt)))
        e = sim.energies()
        totals.append(sum(e.values()))
        strain.append(e["strain"])
    assert max(strain) > 0.2 * e0  # a real impact happened
    assert np.max(np.abs(np.array(totals) - e0)) < 0.005 * e0


def test_wave_front_arrives_at_L_over_c():
    """Uniaxial-strain bar (lateral motion fixed), end pushed at constant speed: the front (half the imposed
    velocity) reaches x = L at t = L / c, c = sqrt((lambda + 2 mu) / rho), within 2 elements."""
    h, L = 0.1, 15.0
    X, cells = plate_mesh(1.0, 20.0, h, layers=10)
    model = build_model(X, cells, GLASS["density"], GLASS["modulus"], GLASS["poisson"], formulation="plane_strain")
    fixed = np.zeros_like(X, dtype=bool)
    fixed[:, 1] = True
    fixed[X[:, 0] < 1e-9, 0] = True
    v0 = np.zeros_like(X)
    v0[X[:, 0] < 1e-9, 0] = 1.0  # prescribed velocity on the fixed end
    sim = CentralDifference(model, fixed, stable_time_step(model))
    sim.start(X, v0)
    lam, mu = model.lam[0], model.mu[0]
    c = np.sqrt((lam + 2 * mu) / GLASS["density"])
    probe = np.abs(X[:, 0] - L) < 1e-9
    while sim.velocity[probe, 0].mean() < 0.5:
        sim.step(1)
        assert sim.t < 2 * L / c, "wave front never arrived"
    assert abs(sim.t * c - L) < 2 * h


def test_cantilever_static_deflection_matches_beam_theory():
    """Plane-strain cantilever (L = 10, h = 1, 10 layers), tip load P: w = P L^3 / (3 E' I), E' = E / (1 - nu^2),
    within 5%, by a sparse direct solve of the solver's own stiffness (checked to be the tangent of the internal
    force first)."""
    L, P = 10.0, 1.0
    X, cells = plate_mesh(1.0, L, 0.1, layers=10)
    model = build_model(X, cells, GLASS["density"], GLASS["modulus"], GLASS["poisson"], formulation="plane_strain")
    K = linear_stiffness(model)
    u = np.random.default_rng(0).normal(size=X.shape) * 1e-7
    np.testing.assert_allclose(
        internal_force(model, X + u).ravel(), K @ u.ravel(), rtol=0, atol=1e-4 * np.abs(K @ u.ravel()).max()
    )
    free = np.ones_like(X, dtype=bool)
    free[X[:, 0] < 1e-9] = False
    tip = np.flatnonzero(X[:, 0] > L - 1e-9)
    f = np.zeros_like(X)
    f[tip, 1] = -P / (len(tip) - 1)
    f[tip[np.argsort(X[tip, 1])[[0, -1]]], 1] *= 0.5  # trapezoid shares
    U = np.zeros(X.size)
    free = free.ravel()
    U[free] = spsolve(K[free][:, free].tocsc(), f.ravel()[free])
    E_plane = GLASS["modulus"] / (1 - GLASS["poisson"] ** 2)
    w_theory = P * L**3 / (3 * E_plane * (1.0**3 / 12))
    assert -U.reshape(-1, 2)[tip, 1].mean() == pytest.approx(w_theory, rel=0.05)


def test_rigid_motion_gives_no_internal_force():
    """Large rigid rotation + translation (plane strain) and axial translation (axisymmetric): zero force, where a
    1% stretch gives a clearly nonzero one; the SVK energy of the rigid motion is zero too."""
    mesh = preset_mesh("small")
    X = mesh["mesh_pos"]
    for formulation in ("plane_strain", "axisymmetric"):
        model = two_body_model(mesh, STEEL, GLASS, formulation)
        scale = np.abs(internal_force(model, X * 1.01)).max()
        assert scale > 0
        if formulation == "plane_strain":
            a = np.deg2rad(35.0)
            Q = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
            moved = X @ Q.T + [3.0, -2.0]
        else:
            moved = X + [0.0, 5.0]
        assert np.abs(internal_force(model, moved)).max() < 1e-9 * scale
        assert abs(strain_energy(model, moved)) < 1e-12 * strain_energy(model, X * 1.01)


@pytest.mark.parametrize("formulation", ["axisymmetric", "plane_strain"])
def test_time_step_inside_stability_limit(formulation):
    """The Courant step (altitude / c, safety 0.8) satisfies omega_max dt < 2 for the paper mesh, omega_max from
    the largest eigenvalue of M^-1 K (the axisymmetric hoop term included)."""
    mesh = preset_mesh("paper")
    model = two_body_model(mesh, STEEL, GLASS, formulation)
    s = 1 / np.sqrt(np.repeat(model.mass, 2))
    K = linear_stiffness(model)
    w2 = eigsh(
        K.multiply(s[:, None]).multiply(s[None, :]).tocsr(), k=1, which="LA", tol=1e-6, return_eigenvectors=False
    )[0]
    assert np.sqrt(w2) * stable_time_step(model, 0.8) < 2.0 * 0.9


def test_bulk_viscosity_only_dissipates():
    """With linear bulk viscosity on, the total energy never rises (to round-off) and ends below the undamped run."""
    mesh = preset_mesh("small")
    finals = {}
    for b1 in (0.0, 0.2):
        model = two_body_model(mesh, STEEL, GLASS, bulk_viscosity=b1)
        dt = stable_time_step(model)
        contact = PenaltyContact(mesh["mesh_pos"], mesh["cells"], mesh["body"], model.mass, dt)
        sim = CentralDifference(model, fixed_dofs(mesh["node_type"]), dt, contact=contact)
        v0 = np.zeros_like(mesh["mesh_pos"])
        v0[mesh["body"] == 1, 1] = -4.0
        sim.start(mesh["mesh_pos"], v0)
        totals = [sum(sim.energies().values())]
        for _ in range(25):
            sim.step(100)
            totals.append(sum(sim.energies().values()))
        if b1 > 0:
            assert np.all(np.diff(totals) < 1e-3 * totals[0])
        finals[b1] = totals[-1] / totals[0]
    assert finals[0.2] < finals[0.0] - 1e-4  # small: it acts on volumetric rates only, bending is deviatoric


@pytest.mark.parametrize("formulation", ["plane_strain", "axisymmetric"])
def test_von_mises_includes_out_of_plane_stress(formulation):
    """Plane strain stretch eps_xx = e: s_xx = (lambda + 2mu) e, s_yy = s_zz = lambda e, so sigma_vm = 2 mu e;
    axisymmetric radial expansion u_r = e r: s_rr = s_tt = 2(lambda + mu) e, s_zz = 2 lambda e, sigma_vm = 2 mu e.
    Without the out-of-plane component either would be wrong (sqrt of a different combination)."""
    X, cells = plate_mesh(1.0, 5.0, 0.25)
    model = build_model(X, cells, 1e-3, 1000.0, 0.3, formulation=formulation)
    e = 1e-4
    vm = nodal_von_mises(model, X * [1 + e, 1.0])
    np.testing.assert_allclose(vm, 2 * model.mu[0] * e, rtol=1e-3)
