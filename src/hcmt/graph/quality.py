"""Cell quality (paper appendix, Table 7): scaled Jacobian and interior angles.

* **Scaled Jacobian** (Verdict's definition, as cited by the paper via Moxey et al.): the minimum over a cell's
  corners of the Jacobian determinant at that corner divided by the product of the corner's edge lengths,
  normalized so that the equilateral triangle and the regular tetrahedron score 1:
  triangle ``2/sqrt(3) * min_k sin(theta_k)``; tetrahedron ``sqrt(2) * min_k det(e1,e2,e3) / (|e1||e2||e3|)``.
  We report its magnitude (orientation-independent: datasets differ in winding); :func:`signed_measure` gives
  the orientation for detecting inverted cells.
* **Angles**: a triangle's three interior angles; for a tetrahedron, the paper's "interior angles within the
  cell" is ambiguous, and we use the six dihedral angles (the standard tetrahedron shape measure; regular 70.53
  degrees).

Triangles may live in 2-D or 3-D space (surfaces). Degenerate cells (a repeated vertex, zero length edge) give
NaN and are left out of the means of :func:`quality_summary`. :func:`check_mesh` validates a mesh before a
hierarchy is built from it (:mod:`hcmt.graph.hierarchy`), warning of the defects it handles.
"""

from __future__ import annotations

import warnings

import numpy as np

from hcmt.errors import DatasetError, InputError
from hcmt.graph.contact import object_ids

# even permutations (i, a, b, c): the corner i with its three edges in an order that keeps the cell's orientation
_TET_CORNERS = np.array([[0, 1, 2, 3], [1, 0, 3, 2], [2, 3, 0, 1], [3, 2, 1, 0]])
_TRI_CORNERS = np.array([[0, 1, 2], [1, 2, 0], [2, 0, 1]])


def signed_measure(pos: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Signed area (triangles in 2-D) or signed volume (tetrahedra in 3-D); unsigned area for triangles in 3-D."""
    pos, cells = np.asarray(pos, np.float64), np.asarray(cells, np.int64)
    e = pos[cells[:, 1:]] - pos[cells[:, :1]]  # [C, k-1, D]
    if cells.shape[1] == 3 and pos.shape[1] == 2:
        return 0.5 * (e[:, 0, 0] * e[:, 1, 1] - e[:, 0, 1] * e[:, 1, 0])
    if cells.shape[1] == 3:
        return 0.5 * np.linalg.norm(np.cross(e[:, 0], e[:, 1]), axis=1)
    if cells.shape[1] == 4 and pos.shape[1] == 3:
        return np.linalg.det(e) / 6.0
    raise InputError(f"cells with {cells.shape[1]} vertices in {pos.shape[1]}-D are not triangles or tetrahedra")


def scaled_jacobian(pos: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Magnitude of the scaled Jacobian of every cell, ``[C]`` in ``[0, 1]`` (NaN for a zero-length edge)."""
    pos, cells = np.asarray(pos, np.float64), np.asarray(cells, np.int64)
    with np.errstate(invalid="ignore", divide="ignore"):
        if cells.shape[1] == 3:
            c = cells[:, _TRI_CORNERS]  # [C, 3 corners, 3]
            e1, e2 = pos[c[..., 1]] - pos[c[..., 0]], pos[c[..., 2]] - pos[c[..., 0]]
            if pos.shape[1] == 2:
                cross = np.abs(e1[..., 0] * e2[..., 1] - e1[..., 1] * e2[..., 0])
            else:
                cross = np.linalg.norm(np.cross(e1, e2), axis=-1)
            sj = cross / (np.linalg.norm(e1, axis=-1) * np.linalg.norm(e2, axis=-1)) * (2 / np.sqrt(3))
        elif cells.shape[1] == 4:
            c = cells[:, _TET_CORNERS]  # [C, 4 corners, 4]
            e = pos[c[..., 1:]] - pos[c[..., :1]]  # [C, 4, 3, 3]
            sj = np.abs(np.linalg.det(e)) / np.prod(np.linalg.norm(e, axis=-1), axis=-1) * np.sqrt(2)
        else:
            raise InputError(f"scaled Jacobian needs triangles or tetrahedra, got {cells.shape[1]} vertices per cell")
    return sj.min(axis=1)


def cell_angles(pos: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Angles in degrees: ``[C, 3]`` interior angles of triangles, ``[C, 6]`` dihedral angles of tetrahedra."""
    pos, cells = np.asarray(pos, np.float64), np.asarray(cells, np.int64)
    with np.errstate(invalid="ignore", divide="ignore"):
        if cells.shape[1] == 3:
            c = cells[:, _TRI_CORNERS]
            e1, e2 = pos[c[..., 1]] - pos[c[..., 0]], pos[c[..., 2]] - pos[c[..., 0]]
            cos = np.sum(e1 * e2, -1) / (np.linalg.norm(e1, axis=-1) * np.linalg.norm(e2, axis=-1))
        elif cells.shape[1] == 4:
            p = pos[cells]  # [C, 4, 3]
            faces = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])  # face k is opposite vertex k
            f = p[:, faces]  # [C, 4, 3, 3]
            n = np.cross(f[:, :, 1] - f[:, :, 0], f[:, :, 2] - f[:, :, 0])
            n /= np.linalg.norm(n, axis=-1, keepdims=True)
            a, b = np.triu_indices(4, 1)  # faces a, b share the edge opposite both vertices a and b
            cos = -np.sum(n[:, a] * n[:, b], -1)  # dihedral angle = pi - angle between the outward normals
        else:
            raise InputError(f"angles need triangles or tetrahedra, got {cells.shape[1]} vertices per cell")
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def quality_summary(pos: np.ndarray, cells: np.ndarray) -> dict[str, float]:
    """Means over non-degenerate cells: ``jacobian`` (scaled Jacobian), ``min_angle`` and ``max_angle`` (each
    cell's smallest and largest angle, degrees), and ``cells`` (how many were measured). NaN when none."""
    cells = np.asarray(cells, np.int64)
    if len(cells) == 0:
        return dict(jacobian=float("nan"), min_angle=float("nan"), max_angle=float("nan"), cells=0)
    sj = scaled_jacobian(pos, cells)
    ang = cell_angles(pos, cells)
    ok = np.isfinite(sj) & np.isfinite(ang).all(1)
    if not ok.any():
        return dict(jacobian=float("nan"), min_angle=float("nan"), max_angle=float("nan"), cells=0)
    return dict(
        jacobian=float(sj[ok].mean()),
        min_angle=float(ang[ok].min(1).mean()),
        max_angle=float(ang[ok].max(1).mean()),
        cells=int(ok.sum()),
    )


# -- the mesh a hierarchy is built from: refused or warned defects ---------------------------------------------
class MeshWarning(UserWarning):
    """A mesh defect that the hierarchy handles (degenerate or inverted cells, unreferenced nodes, ...)."""


def check_mesh(mesh_pos, cells, node_type=None, *, warn: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Validate a mesh; return ``(mesh_pos float64 [N, D], cells int64 [C, k])``.

    Refused (:class:`~hcmt.errors.DatasetError`): wrong shapes, non-finite positions, cell indices out of
    range, cells that are neither triangles nor tetrahedra or have more dimensions than the mesh space.
    Handled, with a :class:`MeshWarning`: cells that repeat a vertex or have zero measure (they give edges but
    no domain for the remeshing filter), inverted cells (orientation opposite to the rest of their object; the
    hierarchy does not depend on orientation), nodes no cell references (each becomes an object of its own,
    kept at every level).
    """
    pos = np.asarray(mesh_pos)
    if pos.ndim != 2 or pos.shape[1] not in (2, 3) or not np.issubdtype(pos.dtype, np.number):
        raise DatasetError(f"shape {list(pos.shape)}; expected [N, 2] or [N, 3] coordinates", field="mesh_pos")
    pos = pos.astype(np.float64)
    if not np.isfinite(pos).all():
        bad = int(np.flatnonzero(~np.isfinite(pos).all(1))[0])
        raise DatasetError(f"node {bad} has a non-finite coordinate", field="mesh_pos")
    c = np.asarray(cells)
    if c.ndim != 2 or c.shape[1] not in (3, 4) or (c.size and not np.issubdtype(c.dtype, np.integer)):
        raise DatasetError(
            f"shape {list(c.shape)} dtype {c.dtype}; expected integer [C, 3] triangles or [C, 4] tetrahedra",
            field="cells",
        )
    c = c.astype(np.int64)
    n = len(pos)
    if c.size and (c.min() < 0 or c.max() >= n):
        raise DatasetError(
            f"cell index out of range [{int(c.min())}, {int(c.max())}]; the mesh has {n} nodes", field="cells"
        )
    if c.shape[1] - 1 > pos.shape[1]:
        raise DatasetError(f"{c.shape[1]}-vertex cells in a {pos.shape[1]}-D mesh space", field="cells")
    if node_type is not None:
        t = np.asarray(node_type)
        if t.reshape(len(t), -1).shape != (n, 1):
            raise DatasetError(f"shape {list(t.shape)}; expected [{n}] or [{n}, 1]", field="node_type")
    if warn:
        warn_defects(pos, c, object_ids(c, n))
    return pos, c


def warn_defects(pos: np.ndarray, cells: np.ndarray, object_id: np.ndarray) -> None:
    """A :class:`MeshWarning` per kind of defect the hierarchy handles: degenerate and inverted cells, nodes no
    cell references."""
    n = len(pos)
    degenerate = np.zeros(len(cells), bool)
    for a, b in zip(*np.triu_indices(cells.shape[1], 1)):  # a repeated vertex: 3 or 6 column comparisons
        degenerate |= cells[:, a] == cells[:, b]
    unreferenced = np.flatnonzero(np.bincount(cells.ravel(), minlength=n) == 0)
    inverted = np.zeros(len(cells), bool)
    if cells.shape[1] - 1 == pos.shape[1] and len(cells):
        vol = signed_measure(pos, cells)
        edge = np.linalg.norm(pos[cells[:, 1:]] - pos[cells[:, :1]], axis=-1).max(1)
        degenerate |= np.abs(vol) <= 1e-12 * edge ** pos.shape[1]
        obj = object_id[cells[:, 0]]
        sign = np.sign(vol)
        majority = np.sign(np.bincount(obj, sign, obj.max() + 1))[obj]
        inverted = (sign != 0) & (majority != 0) & (sign != majority) & ~degenerate
    for count, what in (
        (
            degenerate.sum(),
            "degenerate cells (repeated vertex or zero measure), e.g. cell "
            f"{np.flatnonzero(degenerate)[:3].tolist()}; they give edges but no area",
        ),
        (
            inverted.sum(),
            "inverted cells (orientation opposite to the rest of their object), e.g. "
            f"cell {np.flatnonzero(inverted)[:3].tolist()}; used as they are",
        ),
        (
            len(unreferenced),
            "nodes referenced by no cell, e.g. node "
            f"{unreferenced[:3].tolist()}; each is an object of its own, kept at every level",
        ),
    ):
        if count:
            warnings.warn(f"mesh has {int(count)} {what}", MeshWarning, stacklevel=3)
