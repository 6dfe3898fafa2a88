"""Remeshing of a pooled level (paper, "Pooling Method", step ii), and the no-remeshing (BSMS) alternative.

**Delaunay remeshing** (:func:`delaunay_remesh`): per object, ``scipy.spatial.Delaunay`` of the kept nodes in
mesh space: triangles for 2-D meshes, tetrahedra for 3-D volume meshes, and triangles in the 2-D mesh space of
surfaces (cloth). A triangle mesh whose mesh space is 3-D is projected onto its best-fit plane when it is
planar; a curved surface mesh cannot be triangulated this way and gets the 2-hop edges instead (our choice).

Delaunay triangulates the convex hull, so simplices outside a non-convex object (notches, holes) must go. Our
filter (a choice; the paper does not say): **a simplex is kept when its centroid lies inside some cell of the
object's original (level-0) mesh** -- a barycentric test against the nearest fine cells (KD-tree on the fine
cells' centroids: 4, then 16, then 128 candidates in 2-D; 8, 32, 128 in 3-D, each pass for the points not found
yet). It needs no length threshold, so it does not depend on the mesh grading. An object whose cells fill their
convex hull (total measure = hull measure: Impact Plate's plate and ball, a cloth square, a box) skips the test:
every simplex of a subset of its nodes lies in that hull. A simplex spanning a hole whose centroid falls in
material would survive; at the node spacings of a level this is rare. Simplices of no measure (slivers that
rounding makes of collinear boundary points) are dropped too.

**Connectivity**: dropping simplices can split an object, and scipy leaves duplicate points out of the
triangulation. Where that happens the shortest dropped Delaunay edges (and each left-out point's edge to its
nearest vertex) that reconnect it are added back: the minimum spanning tree over all Delaunay edges in which the
kept edges cost next to nothing and edges whose midpoint is outside the object cost a thousandfold. An object
with too few or degenerate points for a simplex (at the deepest levels) is chained along its principal axis.
Every object therefore stays connected at every level.

**No remeshing** (:func:`two_hop_edges`, the BSMS ablation): level ``l+1``'s edges join the kept nodes that are
at most two hops apart in level ``l``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, minimum_spanning_tree
from scipy.spatial import ConvexHull, Delaunay, QhullError, cKDTree

from hcmt.graph.edges import undirected_to_edges, unique_sorted
from hcmt.graph.quality import signed_measure

_CANDIDATES = {2: (4, 16, 128), 3: (8, 32, 128)}  # nearest fine cells tested per point, pass by pass
_BARY_TOL = 1e-9
_SLIVER = 1e-10  # a simplex whose measure is below this fraction of (longest edge)^d is a rounding sliver
_PLANAR_TOL = 1e-6  # a surface is planar when its thinnest extent is below this fraction of its largest


@dataclass
class Domain:
    """One object's level-0 cells, prepared for the point-in-mesh test (in the object's remeshing space)."""

    basis: np.ndarray | None  # [3, 2] projection of a planar surface onto its plane, None for full-dimension
    origin: np.ndarray
    convex: bool  # the cells fill their nodes' convex hull: every Delaunay simplex of any subset is inside
    tree: cKDTree | None = None  # over the fine cells' centroids (non-convex objects only)
    v0: np.ndarray | None = None  # [C, d] first vertex of every fine cell
    inv: np.ndarray | None = None  # [C, d, d] inverse of [v1 - v0, ..., vd - v0]

    def project(self, pos: np.ndarray) -> np.ndarray:
        return pos if self.basis is None else (pos - self.origin) @ self.basis

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Whether each point (already projected) lies in some fine cell (boundary included). Candidates: the
        cells with the nearest centroids, more of them for the points not yet found."""
        if self.convex:
            return np.ones(len(points), bool)
        inside = np.zeros(len(points), bool)
        todo = np.arange(len(points))
        for k in _CANDIDATES[points.shape[1]]:  # a few widening passes
            k = min(k, len(self.v0))
            inside[todo] = self._test(points[todo], k)
            todo = todo[~inside[todo]]
            if not len(todo) or k == len(self.v0):
                break
        return inside

    def _test(self, points: np.ndarray, k: int) -> np.ndarray:
        _, cand = self.tree.query(points, k=k)
        cand = cand.reshape(len(points), -1)
        diff = points[:, None, :] - self.v0[cand]  # [m, k, d]
        inv = self.inv[cand]  # [m, k, d, d]
        d = diff.shape[-1]
        # barycentric coordinates lam = inv @ diff, and 1 - sum(lam), all >= 0; written out per component
        # (d <= 3) because einsum and reductions over such short axes are slow
        total = np.zeros(diff.shape[:2])
        inside = np.ones(diff.shape[:2], bool)
        for i in range(d):
            lam = inv[..., i, 0] * diff[..., 0]
            for j in range(1, d):
                lam += inv[..., i, j] * diff[..., j]
            inside &= lam >= -_BARY_TOL
            total += lam
        inside &= total <= 1.0 + _BARY_TOL
        return inside.any(-1)


def prepare_domain(pos: np.ndarray, cells: np.ndarray) -> Domain | None:
    """The domain of one object from its level-0 ``pos`` (all nodes) and ``cells`` (this object's only).

    Returns None when the object cannot be Delaunay-remeshed: no non-degenerate cell, or a curved surface.
    """
    if len(cells) == 0:
        return None
    dim_cell, dim_space = cells.shape[1] - 1, pos.shape[1]
    basis, origin = None, np.zeros(dim_space)
    pts = pos[np.unique(cells)]
    if dim_cell < dim_space:  # a surface (triangles) in 3-D mesh space: planar ones are projected
        origin = pts.mean(0)
        _, s, vt = np.linalg.svd(pts - origin, full_matrices=False)
        if s[-1] > _PLANAR_TOL * s[0]:
            return None
        basis = vt[:dim_cell].T
    elif dim_cell > dim_space:
        return None
    p = pos if basis is None else (pos - origin) @ basis
    verts = p[cells]  # [C, d+1, d]
    mat = np.swapaxes(verts[:, 1:] - verts[:, :1], 1, 2)  # columns v_k - v0
    det = np.linalg.det(mat)
    scale = np.max(np.linalg.norm(verts[:, 1:] - verts[:, :1], axis=-1), axis=1) ** dim_cell
    good = np.abs(det) > 1e-12 * scale  # degenerate cells contain nothing
    if not good.any():
        return None
    verts, mat = verts[good], mat[good]
    try:
        hull = ConvexHull(p[np.unique(cells)]).volume
    except QhullError:
        hull = np.inf
    if abs(np.abs(det[good]).sum() / math.factorial(dim_cell) - hull) <= 1e-9 * hull:
        return Domain(basis, origin, True)
    return Domain(basis, origin, False, cKDTree(verts.mean(1)), verts[:, 0], np.linalg.inv(mat))


def delaunay_remesh(points: np.ndarray, domain: Domain, connect: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Remesh one object's kept nodes (``points`` ``[m, D]``, mesh space): ``(cells [M, d+1], pairs [P, 2])`` in
    local numbering ``0..m-1``: the Delaunay simplices whose centroid is inside ``domain`` (positively oriented),
    and the undirected edges of the level (the cells' edges plus those added to keep the object connected).
    ``connect=False`` skips the connectivity check and repair (for callers that check many objects at once)."""
    p = domain.project(points)
    m, d = p.shape
    empty = np.zeros((0, d + 1), np.int64)
    if m <= d:  # too few points for a simplex
        return empty, chain_pairs(p)
    try:
        tri = Delaunay(p)
    except QhullError:  # a flat point set: joggle it (its slivers are dropped, then reconnected), else chain it
        try:
            tri = Delaunay(p, qhull_options="QJ")
        except QhullError:
            return empty, chain_pairs(p)
    simplices = tri.simplices.astype(np.int64)
    verts = p[simplices]
    keep = domain.contains(verts.mean(1))
    # slivers of (nearly) collinear boundary points, made by rounding: no area, only bad edges
    longest = np.linalg.norm(verts[:, 1:] - verts[:, :1], axis=-1).max(1)
    keep &= np.abs(signed_measure(p, simplices)) > _SLIVER * longest**d
    cells = _orient(p, simplices[keep])
    pairs = _cell_pairs(cells, m)
    if not connect or (not len(tri.coplanar) and _connected(pairs, m)):
        return cells, pairs
    # reconnect through the dropped Delaunay edges, and points qhull left out (duplicates) to their nearest vertex
    candidates = np.concatenate([_cell_pairs(simplices, m), tri.coplanar[:, [0, 2]].astype(np.int64)])
    return cells, _reconnect(p, pairs, candidates, domain)


def _cell_pairs(cells: np.ndarray, m: int) -> np.ndarray:
    """Unique undirected edges ``[P, 2]`` (``a < b``) of simplices."""
    k = cells.shape[1]
    a, b = np.triu_indices(k, 1)
    return _unique_pairs(np.stack([cells[:, a].ravel(), cells[:, b].ravel()], 1), m)


def _connected(pairs: np.ndarray, m: int) -> bool:
    adj = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(m, m))
    return connected_components(adj, directed=False)[0] == 1


def _orient(p: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Swap two vertices of negatively oriented simplices."""
    if len(cells) == 0:
        return cells
    flip = signed_measure(p, cells) < 0
    cells = cells.copy()
    cells[flip, 1], cells[flip, 2] = cells[flip, 2], cells[flip, 1].copy()
    return cells


def chain_pairs(p: np.ndarray) -> np.ndarray:
    """Edges joining points consecutive along their principal axis: a connected path for degenerate sets."""
    if len(p) < 2:
        return np.zeros((0, 2), np.int64)
    centred = p - p.mean(0)
    axis = np.linalg.svd(centred, full_matrices=False)[2][0]
    order = np.argsort(centred @ axis, kind="stable")
    return np.stack([order[:-1], order[1:]], 1).astype(np.int64)


def _reconnect(p: np.ndarray, pairs: np.ndarray, candidates: np.ndarray, domain: Domain) -> np.ndarray:
    """``pairs`` plus the fewest, shortest ``candidates`` that make the point set connected, preferring edges
    through the object (midpoint inside ``domain``) to edges across a gap."""
    m = len(p)
    length = np.linalg.norm(p[candidates[:, 0]] - p[candidates[:, 1]], axis=1) + 1e-300
    through = domain.contains(0.5 * (p[candidates[:, 0]] + p[candidates[:, 1]]))
    kept = np.isin(_keys(candidates, m), _keys(pairs, m))
    # kept edges nearly free, so the tree keeps them; an edge across a gap costs as much as a thousand inside
    weight = np.where(kept, length * 1e-9, np.where(through, length, length * 1e3))
    tree = minimum_spanning_tree(sp.coo_matrix((weight, (candidates[:, 0], candidates[:, 1])), shape=(m, m)))
    tree = tree.tocoo()
    added = np.stack([tree.row, tree.col], 1).astype(np.int64)
    return _unique_pairs(np.concatenate([pairs, added]), m)


def _keys(pairs: np.ndarray, m: int) -> np.ndarray:
    return np.minimum(pairs[:, 0], pairs[:, 1]) * m + np.maximum(pairs[:, 0], pairs[:, 1])


def _unique_pairs(pairs: np.ndarray, m: int) -> np.ndarray:
    key = unique_sorted(_keys(pairs, m))
    return np.stack([key // m, key % m], 1)


def two_hop_edges(edges: np.ndarray, num_nodes: int, kept: np.ndarray) -> np.ndarray:
    """BSMS coarse edges: pairs of ``kept`` nodes at most two hops apart in the finer level's ``edges``; returned
    ``[2, E]`` in both directions, in the coarse numbering (position in ``kept``)."""
    adj = sp.csr_matrix((np.ones(edges.shape[1], bool), (edges[0], edges[1])), shape=(num_nodes, num_nodes))
    sub = adj[kept]
    reach = (sub + sub @ adj)[:, kept].tocoo()
    return undirected_to_edges(np.stack([reach.row, reach.col], 1), len(kept))


def clique_cells(edges: np.ndarray, num_nodes: int, k: int) -> np.ndarray:
    """All ``k``-cliques (``k`` = 3 triangles, 4 tetrahedra) of a graph, ``[M, k]`` with ascending indices.

    Used as the cells of a level *before* remeshing (the 2-hop graph has edges, not cells; its triangles are what
    the paper's "before remeshing" quality can measure)."""
    pairs = edges[:, edges[0] < edges[1]]
    upper = sp.csr_matrix((np.ones(pairs.shape[1], bool), (pairs[0], pairs[1])), shape=(num_nodes, num_nodes))
    cliques = pairs.T  # [M, 2], ascending
    keys = np.sort(pairs[0] * num_nodes + pairs[1])
    for _ in range(k - 2):  # extend each clique by a larger-index node adjacent to all of its nodes
        last = cliques[:, -1]
        counts = np.diff(upper.indptr)[last]
        rep = np.repeat(np.arange(len(cliques)), counts)
        starts = np.repeat(upper.indptr[last], counts)
        nxt = upper.indices[starts + np.arange(len(rep)) - np.repeat(np.cumsum(counts) - counts, counts)]
        ok = np.ones(len(rep), bool)
        for col in range(cliques.shape[1] - 1):  # adjacency by binary search in the sorted edge keys
            key = cliques[rep, col] * num_nodes + nxt
            pos = np.searchsorted(keys, key).clip(max=len(keys) - 1)
            ok &= keys[pos] == key
        cliques = np.concatenate([cliques[rep[ok]], nxt[ok, None]], 1)
    return cliques.astype(np.int64)
