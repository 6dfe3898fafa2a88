"""Hertz's impact of a sphere on a flat elastic body, and the contact-force history of a solve, for the solver's
impact checks (tests/sim/test_sim_physics.py: the ball; tests/sim/test_sim_families.py: the pen)."""

import numpy as np


def hertz(m: float, R: float, v: float, impactor=(200e3, 0.3), target=(70e3, 0.22)) -> tuple[float, float]:
    """(peak force N, contact duration ms) of a mass ``m`` (g) with a sphere of radius ``R`` (mm) at ``v`` (mm/ms):
    1/E* = (1-nu1^2)/E1 + (1-nu2^2)/E2, d = (15 m v^2 / (16 E* sqrt R))^(2/5), F = 4/3 E* sqrt(R) d^(3/2),
    t_c = 2.94 d / v."""
    e_star = 1 / ((1 - impactor[1] ** 2) / impactor[0] + (1 - target[1] ** 2) / target[0])
    d_max = (15 * m * v**2 / (16 * e_star * np.sqrt(R))) ** 0.4
    return 4 / 3 * e_star * np.sqrt(R) * d_max**1.5, 2.94 * d_max / v


def contact_history(sim, contact, impactor: np.ndarray, until: float, every: int = 1):
    """(time [ms], the impactor's axial contact force [N]) every ``every`` substeps until ``until``, and the
    contact duration (first to last sample with more than 1e-3 of the peak force)."""
    force, time = [], []
    while sim.t < until:
        sim.step(every)
        force.append(contact.contact_force_on(sim.x, impactor)[1])
        time.append(sim.t)
    force, time = np.array(force), np.array(time)
    on = time[force > 1e-3 * force.max()]
    return time, force, on[-1] - on[0]
