"""Tetrahedral meshes of the 3-D Deforming Plate generator: structured boxes (each hexahedron split into six
tetrahedra around its main diagonal), the box mapped onto a ball or a cylinder (the actuators), the boundary
faces, and the linear tetrahedron's shape-function gradients and volumes."""

from __future__ import annotations

import numpy as np

#: Kuhn's split of a hexahedron (corner ``k`` at offset ``(k & 1, k >> 1 & 1, k >> 2 & 1)``) into six tetrahedra
#: around the diagonal 0-7; neighbouring hexahedra split their shared faces the same way (a conforming mesh).
_KUHN = ((1, 3), (1, 5), (2, 3), (2, 6), (4, 5), (4, 6))


def box_tets(xs, ys, zs) -> tuple[np.ndarray, np.ndarray]:
    """Structured tetrahedral mesh of the grid ``xs x ys x zs`` (increasing coordinates, graded or not): nodes
    [N,3] (x slowest) and positively oriented tetrahedra [C,4]."""
    xs, ys, zs = (np.asarray(a, float) for a in (xs, ys, zs))
    nx, ny, nz = len(xs) - 1, len(ys) - 1, len(zs) - 1
    pos = np.stack(np.meshgrid(xs, ys, zs, indexing="ij"), -1).reshape(-1, 3)
    cx, cy, cz = (a.ravel() for a in np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"))
    corner = [((cx + (k & 1)) * (ny + 1) + cy + (k >> 1 & 1)) * (nz + 1) + cz + (k >> 2 & 1) for k in range(8)]
    tets = np.concatenate([np.stack([corner[0], corner[a], corner[b], corner[7]], 1) for a, b in _KUHN])
    return pos, orient(pos, tets)


def orient(pos: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """The tetrahedra with two nodes swapped where needed so that every signed volume is positive."""
    tets = np.array(tets, dtype=np.int64)
    flip = signed_volumes(pos, tets) < 0
    tets[flip, 2], tets[flip, 3] = tets[flip, 3].copy(), tets[flip, 2].copy()
    return tets


def signed_volumes(pos: np.ndarray, tets: np.ndarray) -> np.ndarray:
    p = pos[tets]
    return np.einsum("ci,ci->c", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0])) / 6.0


def gradients(pos: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(dN_a/dX [C,4,3], volume [C]) of linear tetrahedra at ``pos``."""
    p = pos[tets]
    edges = (p[:, 1:] - p[:, :1]).transpose(0, 2, 1)  # [C,3,3], columns X_b - X_0
    inv = np.linalg.inv(edges)  # rows: gradients of N_1..N_3
    grads = np.concatenate([-inv.sum(1, keepdims=True), inv], 1)
    return grads, np.linalg.det(edges) / 6.0


def boundary_faces(tets: np.ndarray) -> np.ndarray:
    """Triangles [F,3] that belong to one tetrahedron only: the mesh's surface."""
    faces = np.concatenate([tets[:, [0, 1, 2]], tets[:, [0, 1, 3]], tets[:, [0, 2, 3]], tets[:, [1, 2, 3]]])
    key = np.sort(faces, 1)
    _, first, count = np.unique(key, axis=0, return_index=True, return_counts=True)
    return faces[first[count == 1]]


def surface_nodes(tets: np.ndarray) -> np.ndarray:
    return np.unique(boundary_faces(tets))


def _unit_grid(n: int) -> tuple[np.ndarray, np.ndarray]:
    g = np.linspace(-1.0, 1.0, n + 1)
    return box_tets(g, g, g)


def ball_tets(center, radius: float, n: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """A ball as the cube ``[-1, 1]^3`` mapped radially (``p |p|_inf / |p|_2``): nodes on its sphere."""
    pos, tets = _unit_grid(n)
    r2 = np.linalg.norm(pos, axis=1)
    scale = np.divide(np.abs(pos).max(1), r2, out=np.ones_like(r2), where=r2 > 0)
    return np.asarray(center, float) + radius * pos * scale[:, None], tets


def cylinder_tets(center, radius: float, length: float, n: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """A cylinder along y: the cube's x-z square mapped radially onto a disk, y scaled to the length."""
    pos, tets = _unit_grid(n)
    xz = pos[:, [0, 2]]
    r2 = np.linalg.norm(xz, axis=1)
    scale = np.divide(np.abs(xz).max(1), r2, out=np.ones_like(r2), where=r2 > 0)
    out = np.stack([radius * xz[:, 0] * scale, 0.5 * length * pos[:, 1], radius * xz[:, 1] * scale], 1)
    return np.asarray(center, float) + out, tets


def block_tets(center, half_size, n: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """A box with half-edges ``half_size`` [3]."""
    pos, tets = _unit_grid(n)
    return np.asarray(center, float) + pos * np.asarray(half_size, float), tets
