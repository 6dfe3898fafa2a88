"""The impactors' triangle meshes, Delaunay-triangulated: the ball's half disk ``x >= 0`` of radius ``R`` centred at
``(0, center_y)`` (:func:`ball_mesh`: half rings around the centre, or arcs around the contact pole graded away from
it) and the pen's hemispherical tip, a quarter disk (:func:`pen_tip_mesh`). Cells counter-clockwise, slivers of area
below ``1e-10 h^2`` dropped. Units mm; in the axisymmetric formulation each revolves into a sphere or a hemisphere.

It stands apart from the scene's mesh (:mod:`hcmt.sim.mesh`: the plate's structured grid, supports and node types,
which places these meshes above the plate) because an impactor is meshed by point placement and Delaunay, not on a
grid: a new impactor shape is a new function here.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay


def ball_mesh(
    radius: float, mesh_size: float, center_y: float, *, growth: float = 1.0, h_max: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Half disk ``x >= 0`` of ``radius`` centred at ``(0, center_y)``, Delaunay-triangulated.

    Points lie on arcs around the contact pole ``P0 = (0, center_y - radius)`` (the lowest point); the local size
    ``h(d) = min(mesh_size * growth**k, h_max)`` grows with the arc index, so ``growth = 1`` gives a uniform mesh
    and ``growth > 1`` one that is fine only near the contact. The boundary (arc and symmetry axis) is sampled at
    the same local size, so Delaunay (the half disk is convex) yields a conforming mesh of the domain."""
    h_max = mesh_size if h_max is None else max(h_max, mesh_size)
    c = np.array([0.0, center_y])
    p0 = c - [0.0, radius]
    if growth == 1.0 or h_max == mesh_size:
        return _polar_half_disk(radius, mesh_size, c)
    # arc distances from the pole, spaced by the local size
    rho, h = [0.0], mesh_size
    while rho[-1] < 2 * radius:  # hand-rolled: 1-D series of arc radii (tens of terms)
        rho.append(rho[-1] + h)
        h = min(h * growth, h_max)
    rho = np.asarray(rho)

    def size_at(d):
        return np.interp(d, rho[:-1], np.diff(rho))

    pts = [p0[None]]
    # interior points on arcs around P0 (clipped to inside the ball, away from its boundary)
    for r in rho[1:]:  # hand-rolled: one vectorized arc per radius (tens of arcs)
        hs = size_at(r)
        n = max(int(np.ceil(np.pi * r / hs)), 1)
        phi = np.linspace(0.0, np.pi, 2 * n + 1)[1::2]  # angles measured from +x, in (0, pi) only
        q = p0 + r * np.stack([np.cos(phi), np.sin(phi)], 1)
        q = q[q[:, 0] > 0]
        dist_boundary = np.minimum(radius - np.linalg.norm(q - c, axis=1), q[:, 0])
        pts.append(q[dist_boundary > 0.5 * hs])
    # boundary: the arc from P0 (theta=-pi/2, already present) to the top, then the axis x = 0, both sampled
    # with the size function (position mapped through the cumulative density 1/h)
    fine = np.linspace(-np.pi / 2, np.pi / 2, 4000)
    fine_pts = c + radius * np.stack([np.cos(fine), np.sin(fine)], 1)
    dens = 1.0 / size_at(np.linalg.norm(fine_pts - p0, axis=1))
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * np.diff(fine) * radius)])
    n_arc = max(int(np.round(cum[-1])), 2)
    theta = np.interp(np.linspace(0, cum[-1], n_arc + 1)[1:], cum, fine)
    pts.append(c + radius * np.stack([np.cos(theta), np.sin(theta)], 1))
    fine_y = np.linspace(center_y - radius, center_y + radius, 4000)
    dens = 1.0 / size_at(fine_y - (center_y - radius))
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * np.diff(fine_y))])
    n_ax = max(int(np.round(cum[-1])), 2)
    axis_y = np.interp(np.linspace(0, cum[-1], n_ax + 1)[1:-1], cum, fine_y)
    pts.append(np.stack([np.zeros_like(axis_y), axis_y], 1))
    pos = np.concatenate(pts)
    tri = Delaunay(pos).simplices.astype(np.int64)
    area = _signed_area(pos, tri)
    tri = tri[np.abs(area) > 1e-10 * mesh_size**2]
    return pos, _counter_clockwise(pos, tri)


def _polar_half_disk(radius: float, h: float, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Uniform half disk: concentric half rings around the centre, ``h`` apart, each sampled every ~``h``
    from ``theta = -pi/2`` to ``pi/2`` (both axis points included), then Delaunay. Rings keep the triangles next
    to the arc well shaped (a larger smallest altitude, hence a larger stable time step)."""
    n_rings = max(int(np.round(radius / h)), 2)
    r = radius * np.arange(1, n_rings + 1) / n_rings
    counts = np.maximum(np.round(np.pi * r / h).astype(int), 2)
    ring = np.repeat(np.arange(n_rings), counts + 1)
    k = np.arange(len(ring)) - np.repeat(np.cumsum(counts + 1) - (counts + 1), counts + 1)
    theta = -np.pi / 2 + np.pi * k / counts[ring]
    pos = np.concatenate([c[None], c + r[ring, None] * np.stack([np.cos(theta), np.sin(theta)], 1)])
    pos[np.abs(pos[:, 0]) < 1e-12 * radius, 0] = 0.0
    tri = Delaunay(pos).simplices.astype(np.int64)
    tri = tri[np.abs(_signed_area(pos, tri)) > 1e-10 * h**2]
    return pos, _counter_clockwise(pos, tri)


def _signed_area(pos: np.ndarray, cells: np.ndarray) -> np.ndarray:
    a, b, c = pos[cells[:, 0]], pos[cells[:, 1]], pos[cells[:, 2]]
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))


def _counter_clockwise(pos: np.ndarray, cells: np.ndarray) -> np.ndarray:
    cells = cells.copy()
    cw = _signed_area(pos, cells) < 0
    cells[cw, 1], cells[cw, 2] = cells[cw, 2], cells[cw, 1].copy()
    return cells


def pen_tip_mesh(radius: float, mesh_size: float, center_y: float) -> tuple[np.ndarray, np.ndarray]:
    """The pen's hemispherical tip, a quarter disk ``x >= 0, y <= center_y`` of ``radius`` (a hemisphere when
    revolved): rings around the centre sampled every ~``mesh_size`` from the pole to the flat top face, Delaunay.
    The top face ``y = center_y`` is where the rigid rod holds it (:func:`hcmt.sim.mesh.impact_plate_mesh`'s
    ``rigid``)."""
    n_rings = max(int(np.round(radius / mesh_size)), 2)
    r = radius * np.arange(1, n_rings + 1) / n_rings
    counts = np.maximum(np.round(0.5 * np.pi * r / mesh_size).astype(int), 1)
    ring = np.repeat(np.arange(n_rings), counts + 1)
    k = np.arange(len(ring)) - np.repeat(np.cumsum(counts + 1) - (counts + 1), counts + 1)
    theta = -np.pi / 2 + 0.5 * np.pi * k / counts[ring]
    c = np.array([0.0, center_y])
    pos = np.concatenate([c[None], c + r[ring, None] * np.stack([np.cos(theta), np.sin(theta)], 1)])
    pos[np.abs(pos[:, 0]) < 1e-12 * radius, 0] = 0.0
    pos[np.abs(pos[:, 1] - center_y) < 1e-12 * radius, 1] = center_y
    tri = Delaunay(pos).simplices.astype(np.int64)
    tri = tri[np.abs(_signed_area(pos, tri)) > 1e-10 * mesh_size**2]
    return pos, _counter_clockwise(pos, tri)
