"""Small meshes for the graph tests: built here from first principles (scipy Delaunay, structured grids), so the
tests do not depend on the solver's mesher."""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay

NORMAL, OBSTACLE, HANDLE, SYMMETRIC = 0, 1, 3, 7


def _ccw(pos, tri):
    a, b, c = pos[tri[:, 0]], pos[tri[:, 1]], pos[tri[:, 2]]
    area = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    tri = tri[np.abs(area) > 1e-12]
    flip = area[np.abs(area) > 1e-12] < 0
    tri[flip] = tri[flip][:, [0, 2, 1]]
    return tri


def grid_triangles(nx: int, ny: int, lx: float = 1.0, ly: float = 1.0):
    """Structured ``nx x ny`` node grid on ``[0, lx] x [0, ly]``, each quad split by one diagonal."""
    x, y = np.meshgrid(np.linspace(0, lx, nx), np.linspace(0, ly, ny), indexing="xy")
    pos = np.stack([x.ravel(), y.ravel()], 1)
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="xy")
    a = (j * nx + i).ravel()
    cells = np.concatenate([np.stack([a, a + 1, a + nx + 1], 1), np.stack([a, a + nx + 1, a + nx], 1)])
    return pos, cells.astype(np.int64)


def plate_and_ball(h: float = 0.1, length: float = 4.0, thickness: float = 0.5, radius: float = 1.0, gap: float = 0.02):
    """Impact-Plate-like scene: a structured plate ``[0, L] x [-t, 0]`` and a Delaunay half disk above it.
    Symmetry-line nodes are SYMMETRIC on both bodies, the plate's far end HANDLE."""
    nx, ny = int(round(length / h)) + 1, max(int(round(thickness / h)), 4) + 1
    p_pos, p_cells = grid_triangles(nx, ny, length, thickness)
    p_pos[:, 1] -= thickness
    rings = [np.zeros((1, 2))]
    for r in np.arange(h, radius + 1e-9, h):  # concentric half rings
        n = max(int(np.ceil(np.pi * r / h)), 2)
        t = np.linspace(-np.pi / 2, np.pi / 2, n + 1)
        rings.append(r * np.stack([np.cos(t), np.sin(t)], 1))
    b_pos = np.concatenate(rings) + [0.0, radius + gap]
    b_pos[np.abs(b_pos[:, 0]) < 1e-12, 0] = 0.0
    b_cells = _ccw(b_pos, Delaunay(b_pos).simplices.astype(np.int64))
    pos = np.concatenate([p_pos, b_pos])
    cells = np.concatenate([p_cells, b_cells + len(p_pos)])
    node_type = np.r_[np.full(len(p_pos), NORMAL), np.full(len(b_pos), OBSTACLE)]
    node_type[: len(p_pos)][p_pos[:, 0] > length - 1e-9] = HANDLE
    node_type[pos[:, 0] == 0.0] = SYMMETRIC
    return dict(mesh_pos=pos, cells=cells, node_type=node_type, n_plate=len(p_pos))


def impact_plate(preset: str = "small"):
    """The solver's Impact Plate mesh when available (``hcmt.sim.mesh``), else :func:`plate_and_ball`."""
    try:
        from hcmt.sim.mesh import preset_mesh
    except ImportError:
        h = 0.1 if preset == "paper" else 0.25
        return plate_and_ball(h=h, length=15.0, thickness=0.75, radius=3.0)
    m = preset_mesh(preset)
    return dict(mesh_pos=m["mesh_pos"], cells=m["cells"], node_type=m["node_type"])


def tet_box(nx: int = 7, ny: int = 6, nz: int = 5, size=(1.0, 0.8, 0.6)):
    """Structured box of tetrahedra: every cube cut into 6 tetrahedra along its main diagonal (Kuhn)."""
    g = np.stack(np.meshgrid(*(np.linspace(0, s, n) for s, n in zip(size, (nx, ny, nz))), indexing="ij"), -1)
    pos = g.reshape(-1, 3)
    idx = np.arange(nx * ny * nz).reshape(nx, ny, nz)
    corner = idx[:-1, :-1, :-1].ravel()
    off = {(a, b, c): idx[a, b, c] - idx[0, 0, 0] for a in (0, 1) for b in (0, 1) for c in (0, 1)}
    paths = [
        ((1, 0, 0), (1, 1, 0)),
        ((1, 0, 0), (1, 0, 1)),
        ((0, 1, 0), (1, 1, 0)),
        ((0, 1, 0), (0, 1, 1)),
        ((0, 0, 1), (1, 0, 1)),
        ((0, 0, 1), (0, 1, 1)),
    ]
    tets = [np.stack([corner, corner + off[p], corner + off[q], corner + off[(1, 1, 1)]], 1) for p, q in paths]
    cells = np.concatenate(tets).astype(np.int64)
    e = pos[cells[:, 1:]] - pos[cells[:, :1]]
    neg = np.linalg.det(e) < 0
    cells[neg] = cells[neg][:, [0, 2, 1, 3]]
    return pos, cells


def cloth(n: int = 20, fold: bool = True):
    """A square cloth: 2-D mesh space ``[0,1]^2``, 3-D world space; folded over ``x = 0.5`` so the two halves lie
    0.04 apart (self-contact), or flat."""
    mesh_pos, cells = grid_triangles(n, n)
    x, y = mesh_pos[:, 0], mesh_pos[:, 1]
    if fold:
        over = x > 0.5
        world = np.stack([np.where(over, 1.0 - x, x), y, np.where(over, 0.04, 0.0)], 1)
    else:
        world = np.stack([x, y, np.zeros_like(x)], 1)
    return mesh_pos, cells, world


def annulus(h: float = 0.06, r_in: float = 0.5, r_out: float = 1.0):
    """A ring (non-convex, with a hole): Delaunay of ring points with the triangles inside the hole removed."""
    pts = []
    for r in np.arange(r_in, r_out + 1e-9, h):
        n = int(np.ceil(2 * np.pi * r / h))
        t = np.linspace(0, 2 * np.pi, n, endpoint=False)
        pts.append(r * np.stack([np.cos(t), np.sin(t)], 1))
    pos = np.concatenate(pts)
    tri = Delaunay(pos).simplices.astype(np.int64)
    centroid = pos[tri].mean(1)
    tri = tri[np.linalg.norm(centroid, axis=1) > r_in]
    return pos, _ccw(pos, tri)
