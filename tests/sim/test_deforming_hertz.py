"""A rigid sphere pressed into a thick neo-Hookean block (the penalty contact of the Deforming Plate generator)
against Hertz: ``F = 4/3 E* sqrt(R) d^1.5``, ``E* = E / (1 - ν²)`` for a rigid indenter."""

import numpy as np

from hcmt.sim.actuator import Sphere
from hcmt.sim.hyper import NeoHookean
from hcmt.sim.quasistatic import Contact, Newton, advance
from hcmt.sim.tet import box_tets

E, NU, R, W = 100.0, 0.3, 10.0, 20.0


def dofs(nodes, axis):
    return 3 * np.asarray(nodes) + axis


def test_rigid_sphere_force_against_hertz():
    """A quarter of a 40 x 40 x 20 block (symmetry rollers on x = 0 and y = 0, bottom on rollers), element size
    0.4 within 2 of the axis, then growing geometrically: a coarse mesh, 3 to 4 elements across the contact radius
    ``a = sqrt(R d)`` = 1 to 1.4. Linear tetrahedra that coarse are stiff and the block is finite, so the force
    comes out above Hertz (measured +13 %; tolerance 15 %); the exponent 1.5 is reproduced within 3 %."""
    fine = np.linspace(0, 2.0, 6)
    xs = np.concatenate([fine, 2.0 * (W / 2.0) ** (np.arange(1, 7) / 6)])
    pos, tets = box_tets(xs, xs, -xs[::-1])
    fixed = np.concatenate(
        [
            dofs(np.flatnonzero(pos[:, 0] == 0), 0),
            dofs(np.flatnonzero(pos[:, 1] == 0), 1),
            dofs(np.flatnonzero(pos[:, 2] == -W), 2),
        ]
    )
    body = NeoHookean(pos, tets, E, NU, fixed=fixed)
    top = np.flatnonzero(pos[:, 2] == 0)
    x, ratios = pos.copy(), []
    for d in (0.1, 0.2):
        contact = Contact(Sphere(np.array([0, 0, R - d]), R), top, k=100 * E * 0.4, curved=True)
        x, log = advance(body, x, lambda s, y, c=contact: [c], Newton(rtol=1e-8))
        force = 4 * contact.force_on_obstacle(x)[2]  # the quarter model's force, times 4
        penetration = -contact.obstacle.distance(x[top])[0].min()
        assert penetration < 0.005 * d  # the penalty's own compliance is negligible against d
        ratios.append(force / (4 / 3 * E / (1 - NU**2) * np.sqrt(R) * d**1.5))
        print(f"Hertz d = {d}: force / Hertz {ratios[-1]:.4f}, Newton iterations {log.iterations}")
    assert all(abs(r - 1) < 0.15 for r in ratios)
    exponent = 1.5 + np.log(ratios[1] / ratios[0]) / np.log(2)
    assert abs(exponent - 1.5) < 0.045
