"""The neo-Hookean tetrahedron of the Deforming Plate generator against exact results: the patch test, the
tangent against the forces' finite differences, uniaxial stretch at large strain against the closed form."""

import numpy as np
import pytest
from scipy.optimize import brentq

from hcmt.sim.hyper import NeoHookean, lame, von_mises
from hcmt.sim.quasistatic import Newton, advance, newton
from hcmt.sim.tet import box_tets, gradients, surface_nodes

E, NU = 10.0, 0.3


def dofs(nodes, axes=(0, 1, 2)):
    return (3 * np.asarray(nodes)[:, None] + np.asarray(axes)).ravel()


def distorted_box(n=3, seed=0):
    """A unit cube of n^3 hexahedra (6 tetrahedra each) with its interior nodes moved at random."""
    pos, tets = box_tets(*(np.linspace(0, 1, n + 1),) * 3)
    inner = np.setdiff1d(np.arange(len(pos)), surface_nodes(tets))
    pos[inner] += np.random.default_rng(seed).uniform(-0.1, 0.1, (len(inner), 3))
    assert np.all(gradients(pos, tets)[1] > 0)
    return pos, tets, inner


def nh_cauchy(F):
    lam, mu = lame(E, NU)
    J = np.linalg.det(F)
    return (mu * (F @ F.T - np.eye(3)) + lam * np.log(J) * np.eye(3)) / J


def test_patch_uniform_deformation_is_exact():
    """A linear displacement field: zero force at every interior node, the same Cauchy stress in every element
    (the closed form of F), and Newton, given only the boundary nodes, finds the interior nodes of the field."""
    pos, tets, inner = distorted_box()
    F = np.array([[1.3, 0.2, -0.1], [0.05, 0.9, 0.15], [0.1, -0.2, 1.1]])
    x = pos @ F.T + np.array([0.3, -0.2, 0.5])
    body = NeoHookean(pos, tets, E, NU)
    f = body.forces(x)
    scale = np.abs(f).max()
    assert np.abs(f[inner]).max() < 1e-12 * scale
    sigma = body.cauchy(x)
    np.testing.assert_allclose(sigma, np.broadcast_to(nh_cauchy(F), sigma.shape), atol=1e-12 * np.abs(sigma).max())
    np.testing.assert_allclose(body.nodal_von_mises(x), von_mises(nh_cauchy(F)), rtol=1e-12)
    outer = surface_nodes(tets)
    fixed_body = NeoHookean(pos, tets, E, NU, fixed=dofs(outer))
    start = x + np.random.default_rng(3).uniform(-0.03, 0.03, x.shape)  # the interior nodes off the field
    start[outer] = x[outer]
    solved, log = newton(fixed_body, start, [], Newton(rtol=1e-12))
    np.testing.assert_allclose(solved, x, atol=1e-10)
    assert log.iterations <= 6
    print(
        f"patch test: interior force {np.abs(f[inner]).max() / scale:.1e} of the boundary's, stress spread "
        f"{np.ptp(sigma, axis=0).max() / np.abs(sigma).max():.1e}, interior nodes recovered to "
        f"{np.abs(solved - x).max():.1e} in {log.iterations} Newton iterations"
    )


def test_tangent_is_the_derivative_of_the_forces():
    pos, tets, _ = distorted_box(2, seed=1)
    body = NeoHookean(pos, tets, E, NU)
    x = pos + 0.1 * np.random.default_rng(2).normal(size=pos.shape)
    _, K = body.forces(x, tangent=True)
    K = body.assemble(K).toarray()
    eps, cols = 1e-6, np.arange(0, K.shape[0], 5)
    for j in cols:
        step = np.zeros(x.size)
        step[j] = eps
        fd = (body.forces(x + step.reshape(-1, 3)) - body.forces(x - step.reshape(-1, 3))).ravel() / (2 * eps)
        np.testing.assert_allclose(K[:, j], fd, atol=1e-6 * np.abs(K).max())
    np.testing.assert_allclose(K, K.T, atol=1e-12 * np.abs(K).max())


def test_uniaxial_stretch_matches_the_closed_form():
    """A block stretched to 1.5 on rollers (lateral faces free): the lateral stretch solves
    ``mu (l_t - 1/l_t) + lam ln(l l_t^2) / l_t = 0`` and the nominal stress is ``mu (l - 1/l) + lam ln J / l``."""
    pos, tets = box_tets(np.linspace(0, 2, 4), np.linspace(0, 1, 3), np.linspace(0, 1, 3))
    x0, y0, z0 = (np.flatnonzero(pos[:, k] == 0) for k in range(3))
    end = np.flatnonzero(pos[:, 0] == 2)
    body = NeoHookean(
        pos, tets, E, NU, fixed=np.concatenate([dofs(x0, [0]), dofs(y0, [1]), dofs(z0, [2]), dofs(end, [0])])
    )
    stretch = 1.5

    def load(s, y):
        y[end, 0] = 2 * (1 + (stretch - 1) * s)
        return []

    x, log = advance(body, pos.copy(), load, Newton(rtol=1e-12))
    lam, mu = lame(E, NU)
    lt = brentq(lambda t: mu * (t - 1 / t) + lam * np.log(stretch * t * t) / t, 0.3, 1.0)
    nominal = mu * (stretch - 1 / stretch) + lam * np.log(stretch * lt * lt) / stretch
    force = body.forces(x)[end, 0].sum()  # over the 1 x 1 end face
    np.testing.assert_allclose(x[:, 1], pos[:, 1] * lt, atol=1e-10)
    np.testing.assert_allclose(force, nominal * 1.0, rtol=1e-9)
    print(
        f"uniaxial stretch 1.5: lateral stretch {lt:.6f} (error {np.abs(x[:, 1] - pos[:, 1] * lt).max():.1e}), "
        f"nominal stress {nominal:.6f} MPa (relative error {abs(force / nominal - 1):.1e}), "
        f"Newton iterations {log.iterations}"
    )


@pytest.mark.parametrize("poisson", [-1.0, 0.5])
def test_refuses_a_material_without_energy(poisson):
    with pytest.raises(ValueError):
        lame(E, poisson)
