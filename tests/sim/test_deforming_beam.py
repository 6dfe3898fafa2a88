"""A cantilever of neo-Hookean tetrahedra against Euler-Bernoulli beam theory (small strain), and Newton's
quadratic convergence at large deflection."""

import numpy as np

from hcmt.sim.hyper import NeoHookean
from hcmt.sim.quasistatic import Newton, NodalForce, advance, newton
from hcmt.sim.tet import box_tets

L, H, E = 10.0, 1.0, 1000.0


def cantilever(layers: int, poisson: float = 0.0):
    """A square beam ``L x H x H`` (``10 layers`` elements along, ``layers`` across), clamped at x = 0; the tip
    nodes and their shares of a unit load (trapezoid weights over the tip face)."""
    xs, ys = np.linspace(0, L, 10 * layers + 1), np.linspace(0, H, layers + 1)
    pos, tets = box_tets(xs, ys, ys)
    clamp, tip = np.flatnonzero(pos[:, 0] == 0), np.flatnonzero(pos[:, 0] == L)
    w = np.full(layers + 1, 1.0 / layers)
    w[[0, -1]] /= 2
    share = w[np.searchsorted(ys, pos[tip, 1])] * w[np.searchsorted(ys, pos[tip, 2])]
    body = NeoHookean(pos, tets, E, poisson, fixed=(3 * clamp[:, None] + np.arange(3)).ravel())
    return body, tip, share


def tip_deflection(layers: int, load: float) -> float:
    body, tip, share = cantilever(layers)
    x, _ = newton(
        body, body.pos.copy(), [NodalForce(tip, -load * share[:, None] * np.array([0, 0, 1.0]))], Newton(rtol=1e-10)
    )
    return float(-(x[tip, 2] - body.pos[tip, 2]).mean())


def test_cantilever_tip_load_matches_euler_bernoulli():
    """Tip deflection ``P L^3 / (3 E I)`` at a load whose deflection is 1e-5 L (small strain). Linear tetrahedra
    are stiff in bending and converge as h^2: 8 layers reach about 95 % (tolerance 7 %), and the Richardson
    extrapolation of 6 and 8 layers (p = 2) is within 2 % of beam theory. ν = 0, so beam theory's only missing
    term is Timoshenko's shear deflection, 0.6 % at L/H = 10."""
    load = 1e-4 * 3 * E * H**4 / 12 / L**2 / 10
    exact = load * L**3 / (3 * E * H**4 / 12)
    w6, w8 = tip_deflection(6, load) / exact, tip_deflection(8, load) / exact
    extrapolated = w8 + (w8 - w6) * (1 / 8**2) / (1 / 6**2 - 1 / 8**2)
    print(
        f"cantilever tip deflection / Euler-Bernoulli: 6 layers {w6:.4f}, 8 layers {w8:.4f}, "
        f"extrapolated {extrapolated:.4f}"
    )
    assert abs(w8 - 1) < 0.07
    assert w6 < w8 < 1.0  # converging from the stiff side
    assert abs(extrapolated - 1) < 0.02


def test_newton_converges_quadratically_at_large_deflection():
    """A tip load bending the beam by about a quarter of its length (2 layers), in 4 load steps: each step ends
    with the residual falling quadratically (``r_k+1 / r_0 <= 50 (r_k / r_0)^2`` once below 1e-2, above
    round-off) to 1e-10 of the force scale."""
    body, tip, share = cantilever(2)
    load = 0.6 * 3 * E * H**4 / 12 / L**2
    x, pairs = body.pos.copy(), []
    for step in range(1, 5):
        force = NodalForce(tip, -(load * step / 4) * share[:, None] * np.array([0, 0, 1.0]))
        x, log = advance(body, x, lambda s, y, f=force: [f], Newton(rtol=1e-10))
        r = np.array(log.residuals) / log.residuals[0]
        assert log.iterations <= 8 and log.substeps == 1
        near = (r[:-1] < 1e-2) & (r[1:] > 1e-9)  # in the region of quadratic convergence, above round-off
        pairs += list(zip(r[:-1][near], r[1:][near]))
        print(
            f"load step {step}: Newton iterations {log.iterations}, relative residuals "
            + ", ".join(f"{v:.1e}" for v in r)
        )
    before, after = np.array(pairs).T
    assert len(pairs) >= 3 and np.all(after <= 50 * before**2), pairs
    assert -(x[tip, 2] - body.pos[tip, 2]).mean() > 0.2 * L  # geometrically nonlinear: rotations of 0.3 rad
