"""The HCMT mesh hierarchy (paper, "Pooling Method" and HMT layer): levels ``G_0 .. G_lambda``.

Level 0 is the mesh. Level ``l+1`` keeps the nodes that bi-stride pooling (:mod:`hcmt.graph.pooling`) selects from
level ``l``, object by object, and gets new edges: Delaunay remeshing (:mod:`hcmt.graph.remesh`, the paper) or,
with ``remesh=False``, the 2-hop connectivity of level ``l`` (the BSMS ablation). The mesh is static within a
trajectory, so the hierarchy is built once per trajectory from ``mesh_pos`` and ``cells`` and cached
(:func:`cached_hierarchy`).

Pooling and unpooling (:func:`pool`, :func:`unpool`) -- the semantics the models use:

* down: ``h_{l+1} = pool(h_l, hierarchy.pool[l]) = h_l[pool[l]]`` (the kept nodes' features);
* up: ``h_l' = unpool(h_{l+1}, h_l, pool[l])``: a copy of the finer level's saved features ``h_l`` with the kept
  nodes' rows **replaced** by the coarse features, as the official HCMT code (``tensor_scatter_nd_update``); the
  dropped nodes keep their saved features. ``unpool(pool(h, i), h, i)`` is ``h`` exactly.
"""

from __future__ import annotations

import hashlib
import os
import warnings
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from hcmt.errors import InputError
from hcmt.files import atomic_path
from hcmt.graph.contact import object_ids
from hcmt.graph.edges import cells_to_edges, undirected_to_edges
from hcmt.graph.pooling import bistride_pool
from hcmt.graph.quality import MeshWarning, check_mesh, warn_defects  # noqa: F401 (read from here too)
from hcmt.graph.remesh import Domain, delaunay_remesh, prepare_domain, two_hop_edges

#: Bump when the algorithm or the file layout changes: cached hierarchies of other versions are not reused.
#: 2: one flat ``.npy`` per hierarchy: a load took 1.3 ms against 8.2 ms for version 1's ``.npz`` of 23 members
#: (cProfile, small preset, a loaded core), paid per training item by the per-item data path
HIERARCHY_VERSION = 2


@dataclass(eq=False)
class Hierarchy:
    """Levels of one mesh, as numpy arrays (level ``l`` numbers its nodes ``0..N_l-1``).

    ``pool[l]`` (``l < lambda``): indices into level ``l`` of the nodes level ``l+1`` keeps (ascending).
    ``edges[l]``: level ``l``'s edges ``[2, E_l]``, both directions (``edges[0]`` the mesh edges).
    ``nodes[l]``: the level-0 index of every level-``l`` node (``nodes[0] = arange(N)``); index ``mesh_pos`` and
    ``world_pos`` with it to get a level's positions.
    ``cells[l]``: level ``l``'s simplices (level 0 the input cells, coarser levels the kept Delaunay simplices;
    ``[0, k]`` without remeshing). ``object_id``: the object (cell-graph component) of every level-0 node.
    """

    pool: list[np.ndarray]
    edges: list[np.ndarray]
    nodes: list[np.ndarray]
    cells: list[np.ndarray]
    object_id: np.ndarray
    remesh: bool = True
    _tensors: dict = field(default_factory=dict, repr=False)  # per-device torch copies (see hcmt.graph.build)

    @property
    def levels(self) -> int:
        return len(self.pool)

    def num_nodes(self, level: int) -> int:
        return int(len(self.nodes[level]))

    def save(self, path: str | os.PathLike) -> None:
        """Write one flat int64 ``.npy`` atomically (temp file beside it, then rename): a header (version, levels,
        remesh, the number of arrays, then each array's ndim and shape) and every array's entries in turn
        (``object_id``, ``pool``, ``edges``, ``nodes``, ``cells``). One read loads it: no zip member per array."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        arrays = [self.object_id, *self.pool, *self.edges, *self.nodes, *self.cells]
        header = [HIERARCHY_VERSION, self.levels, int(self.remesh), len(arrays)]
        for a in arrays:
            header += [a.ndim, *a.shape]
        flat = np.concatenate([np.asarray(header, np.int64), *(np.asarray(a, np.int64).ravel() for a in arrays)])
        with atomic_path(path) as tmp, open(tmp, "wb") as f:
            np.save(f, flat)

    @classmethod
    def load(cls, path: str | os.PathLike) -> "Hierarchy":
        """Read a file written by :meth:`save`; another version or a damaged layout is an :class:`InputError`."""
        flat = np.load(path)
        if flat.ndim != 1 or flat.dtype != np.int64 or flat.shape[0] < 4 or int(flat[0]) != HIERARCHY_VERSION:
            raise InputError(f"{path}: not a hierarchy file of version {HIERARCHY_VERSION}")
        n, remesh, count = (int(v) for v in flat[1:4])
        pos, shapes = 4, []
        for _ in range(count if count == 1 + n + 3 * (n + 1) else 0):
            ndim = int(flat[pos]) if pos < flat.shape[0] else -1
            shapes.append(tuple(int(v) for v in flat[pos + 1 : pos + 1 + max(ndim, 0)]))
            pos += 1 + ndim
            if ndim < 1 or len(shapes[-1]) != ndim or min(shapes[-1]) < 0:
                shapes = []
                break
        sizes = [int(np.prod(shape)) for shape in shapes]
        if not shapes or pos + sum(sizes) != flat.shape[0]:
            raise InputError(f"{path}: a damaged hierarchy file (its header does not match its length)")
        arrays = []
        for shape, size in zip(shapes, sizes):
            arrays.append(flat[pos : pos + size].reshape(shape))
            pos += size
        pool, rest = arrays[1 : 1 + n], arrays[1 + n :]
        return cls(pool, rest[: n + 1], rest[n + 1 : 2 * n + 2], rest[2 * n + 2 :], arrays[0], bool(remesh))


def pool(x, index):
    """Level ``l`` features -> level ``l+1``: the rows of the kept nodes, ``x[index]`` (numpy or torch)."""
    return x[index]


def unpool(coarse, fine, index):
    """Level ``l+1`` features back into level ``l``: a copy of ``fine`` whose rows ``index`` are replaced by
    ``coarse`` (numpy or torch; differentiable in torch)."""
    if hasattr(fine, "index_copy"):  # torch: out-of-place, so autograd sees both inputs
        return fine.index_copy(0, index, coarse)
    out = np.array(fine, copy=True)
    out[index] = coarse
    return out


def build_hierarchy(mesh_pos, cells, node_type=None, levels: int = 1, remesh: bool = True) -> Hierarchy:
    """Build ``levels`` (lambda) pooled levels of a mesh.

    ``mesh_pos`` ``[N, D]`` (mesh space; D = 2 or 3), ``cells`` ``[C, 3|4]``, ``node_type`` ``[N]`` (validated;
    objects come from connectivity, not from types). ``remesh``: Delaunay remeshing (paper) or 2-hop edges
    (BSMS ablation). Deterministic. A level that cannot shrink the mesh at all (every object already a single
    node) is refused; an object that shrinks to one node before the last level stays one node (warned).
    """
    if not isinstance(levels, (int, np.integer)) or levels < 0:
        raise InputError(f"levels must be a non-negative integer, got {levels!r}")
    pos, cells = check_mesh(mesh_pos, cells, node_type, warn=False)
    n0 = len(pos)
    obj = object_ids(cells, n0)
    warn_defects(pos, cells, obj)
    edges = [cells_to_edges(cells, n0)]
    nodes = [np.arange(n0, dtype=np.int64)]
    all_cells = [cells]
    pools: list[np.ndarray] = []
    domains = _domains(pos, cells, obj) if remesh else {}
    k = cells.shape[1]
    for level in range(levels):
        n = len(nodes[-1])
        kept = bistride_pool(edges[-1], n, pos[nodes[-1]])
        if len(kept) == n:
            raise InputError(
                f"levels={levels} is more than this mesh can be pooled: at level {level} every object "
                f"is down to a single node ({n} nodes); use levels <= {level}"
            )
        coarse = nodes[-1][kept]
        if remesh:
            level_cells, pairs = _remesh_level(pos, coarse, obj, domains, edges[-1], n, kept, k)
            level_edges = undirected_to_edges(pairs, len(kept))
        else:
            level_cells = np.zeros((0, k), np.int64)
            level_edges = two_hop_edges(edges[-1], n, kept)
        pools.append(kept.astype(np.int64))
        nodes.append(coarse.astype(np.int64))
        edges.append(level_edges)
        all_cells.append(level_cells)
    _warn_single(obj, nodes, levels)
    return Hierarchy(pools, edges, nodes, all_cells, obj, bool(remesh))


def _domains(pos: np.ndarray, cells: np.ndarray, obj: np.ndarray) -> dict[int, Domain | None]:
    cell_obj = obj[cells[:, 0]] if len(cells) else np.zeros(0, np.int64)
    order = np.argsort(cell_obj, kind="stable")
    ids, starts = np.unique(cell_obj[order], return_index=True)
    groups = np.split(order, starts[1:])
    return {int(o): prepare_domain(pos, cells[g]) for o, g in zip(ids, groups)}  # one per object


def _remesh_level(pos, coarse, obj, domains, fine_edges, n_fine, kept, k):
    """Delaunay remeshing of every object's kept nodes: ``(cells [M, k], pairs [P, 2])`` in the coarse numbering.
    Objects that cannot be remeshed (curved surfaces, no cells) get their 2-hop edges. Connectivity is checked
    for the whole level at once; only an object that came out split is remeshed again with repair."""
    cobj = obj[coarse]
    order = np.argsort(cobj, kind="stable")
    ids, starts = np.unique(cobj[order], return_index=True)
    groups = dict(zip(ids.tolist(), np.split(order, starts[1:])))
    cells_out, pairs_out, fallback = {}, {}, []
    for o, g in groups.items():  # loop over objects
        if domains.get(o) is None:
            fallback.append(g)
            continue
        c, p = delaunay_remesh(pos[coarse[g]], domains[o], connect=False)
        cells_out[o], pairs_out[o] = g[c], g[p]
    m = len(coarse)
    if pairs_out:
        pairs = np.concatenate(list(pairs_out.values()))
        adj = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(m, m))
        label = connected_components(adj, directed=False)[1]
        pieces = np.bincount(np.unique(cobj * m + label) // m)  # connected pieces of every object
        for o in np.flatnonzero(pieces > 1):  # rare: an object split by the filter, or with duplicate points
            if int(o) in pairs_out:
                g = groups[int(o)]
                c, p = delaunay_remesh(pos[coarse[g]], domains[int(o)], connect=True)
                cells_out[int(o)], pairs_out[int(o)] = g[c], g[p]
    out_pairs = list(pairs_out.values())
    if fallback:
        hop = two_hop_edges(fine_edges, n_fine, kept)
        inside = np.zeros(m, bool)
        inside[np.concatenate(fallback)] = True
        out_pairs.append(hop[:, inside[hop[0]] & (hop[0] < hop[1])].T)
    cells = np.concatenate(list(cells_out.values())) if cells_out else np.zeros((0, k), np.int64)
    pairs = np.concatenate(out_pairs) if out_pairs else np.zeros((0, 2), np.int64)
    return cells.astype(np.int64), pairs.astype(np.int64)


def _warn_single(obj: np.ndarray, nodes: list[np.ndarray], levels: int) -> None:
    size0 = np.bincount(obj)
    for level, idx in enumerate(nodes[:-1]):  # one check per level
        size = np.bincount(obj[idx], minlength=len(size0))
        single = np.flatnonzero((size == 1) & (size0 > 1))
        if len(single):
            warnings.warn(
                f"object(s) {single[:5].tolist()} are a single node from level {level} on; levels "
                f"{level + 1}..{levels} cannot pool them further",
                MeshWarning,
                stacklevel=3,
            )
            return


def hierarchy_key(mesh_pos, cells, node_type, levels: int, remesh: bool) -> str:
    """Hash of the mesh and settings (and :data:`HIERARCHY_VERSION`): the cache key."""
    h = hashlib.sha256(f"hcmt-hierarchy v{HIERARCHY_VERSION} levels={int(levels)} remesh={bool(remesh)}".encode())
    for a, dtype in ((mesh_pos, np.float64), (cells, np.int64), (node_type, np.int64)):
        a = np.ascontiguousarray(np.zeros(0) if a is None else a, dtype=dtype)
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()[:32]


_MEMORY: OrderedDict[str, Hierarchy] = OrderedDict()
_MEMORY_SIZE = 256


def hierarchy_cache_dir(dataset_dir: str | os.PathLike) -> Path:
    """Where a dataset's hierarchies are cached: ``DATASET/.cache/hierarchy``."""
    return Path(dataset_dir) / ".cache" / "hierarchy"


def cached_hierarchy(
    mesh_pos,
    cells,
    node_type=None,
    levels: int = 1,
    remesh: bool = True,
    cache_dir: str | os.PathLike | None = None,
    memory: bool = True,
) -> Hierarchy:
    """:func:`build_hierarchy`, memoized in memory and (with ``cache_dir``) on disk as ``<key>.npy``.

    The key hashes the mesh and the settings, so a changed mesh or setting builds anew; an unreadable cache
    file is rebuilt and replaced. ``memory=False`` keeps a hierarchy it reads or builds out of the in-process memo
    (:class:`hcmt.domains.trajectory.SplitReader` keeps its own few)."""
    key = hierarchy_key(mesh_pos, cells, node_type, levels, remesh)
    if key in _MEMORY:
        _MEMORY.move_to_end(key)
        return _MEMORY[key]
    path = Path(cache_dir) / f"{key}.npy" if cache_dir is not None else None
    h = None
    if path is not None and path.is_file():
        try:
            h = Hierarchy.load(path)
        except Exception:  # noqa: BLE001 - any damage to a cache file means: rebuild it
            h = None
    if h is None:
        h = build_hierarchy(mesh_pos, cells, node_type, levels, remesh)
        if path is not None:
            h.save(path)
    if not memory:
        return h
    _MEMORY[key] = h
    if len(_MEMORY) > _MEMORY_SIZE:
        _MEMORY.popitem(last=False)
    return h
