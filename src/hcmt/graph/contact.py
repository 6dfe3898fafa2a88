"""Contact edges: node pairs closer than the contact radius gamma in world space (paper, "Encoder"; appendix:
``|x_i - x_q| < gamma``), recomputed from world positions at every step.

Which pairs may be in contact (the paper says "two different objects' nodes or self-contacts within an object";
our choice, written here once):

* **objects** are the connected components of the cell graph (:func:`object_ids`), not node types: Impact Plate's
  SYMMETRIC nodes lie on both bodies, so the node type alone cannot tell the ball from the plate;
* a pair of nodes of **different objects** within gamma is a contact;
* an optional **type rule** ``type_pairs`` (unordered node-type pairs) restricts contacts further. The official
  HCMT code connects OBSTACLE and NORMAL nodes only (:data:`OFFICIAL_IMPACT_PLATE_TYPES`); it thereby drops the
  SYMMETRIC nodes on the axis (the ball's lowest node is one). Without a rule every node of another object counts;
* **self-contact** (cloth, ``self_contact=True``) adds pairs inside one object, except those in ``exclude``:
  pairs that are close *on the mesh* (:func:`near_pairs`, within a few mesh hops), which are neighbours, not
  contacts. Mesh edges themselves are within one hop, so contact edges never duplicate mesh edges.

Edges come in both directions, ``[2, C]`` int64, sorted by (sender, receiver). No contact is normal: ``[2, 0]``.
Two search paths: a KD-tree (``scipy.spatial.cKDTree``, float64) on CPU and a blocked dense distance test in
torch for GPU tensors (``method="auto"`` picks by device). They give identical edges on CPU (the dense path runs
in float64 there); on a GPU the final distance test runs in the tensors' dtype, so a pair within float32
rounding of gamma may fall either way.
"""

from __future__ import annotations

from typing import Iterable

import numpy as np
import scipy.sparse as sp
import torch
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree
from torch import Tensor

from hcmt.data.format import NodeType
from hcmt.errors import InputError
from hcmt.graph.edges import cells_to_edges, unique_sorted

OBSTACLE, NORMAL = int(NodeType.OBSTACLE), int(NodeType.NORMAL)
#: The official HCMT code's Impact Plate rule: contact edges between OBSTACLE (ball) and NORMAL (plate) nodes.
OFFICIAL_IMPACT_PLATE_TYPES: tuple[tuple[int, int], ...] = ((OBSTACLE, NORMAL),)

_TYPE_TABLE = 64  # node types are small ints (MeshGraphNets enum < 9); a lookup table covers them


def object_ids(cells: np.ndarray, num_nodes: int) -> np.ndarray:
    """Object index of every node: the connected component of the graph whose edges are the cells' edges
    (labels ``0..K-1`` in order of each component's lowest node). A node no cell references is an object alone."""
    edges = cells_to_edges(cells, num_nodes) if len(cells) else np.zeros((2, 0), np.int64)
    adj = sp.coo_matrix((np.ones(edges.shape[1], np.int8), (edges[0], edges[1])), shape=(num_nodes, num_nodes))
    return connected_components(adj, directed=False)[1].astype(np.int64)


def near_pairs(edges: np.ndarray, num_nodes: int, hops: int) -> np.ndarray:
    """Sorted int64 keys ``a * N + b`` of every ordered pair ``a != b`` at most ``hops`` mesh hops apart: the
    pairs self-contact must exclude. ``edges`` is ``[2, E]`` (both directions)."""
    if hops < 1:
        raise InputError(f"hops must be >= 1, got {hops}")
    edges = np.asarray(edges)
    adj = sp.csr_matrix((np.ones(edges.shape[1], bool), (edges[0], edges[1])), shape=(num_nodes, num_nodes))
    reach = adj.copy()
    for _ in range(hops - 1):  # a few sparse products, one per hop
        reach = reach + reach @ adj
    reach = reach.tocoo()
    keep = reach.row != reach.col
    return np.unique(reach.row[keep].astype(np.int64) * num_nodes + reach.col[keep])


def contact_edges(
    world_pos,
    object_id,
    radius: float,
    *,
    node_type=None,
    type_pairs: Iterable[tuple[int, int]] | None = None,
    self_contact: bool = False,
    exclude=None,
    batch=None,
    method: str = "auto",
):
    """Contact edges ``[2, C]`` (both directions) of all pairs ``|x_i - x_q| < radius`` allowed by the rules in
    the module docstring.

    ``world_pos`` ``[N, d]`` (numpy or torch), ``object_id`` ``[N]``; ``node_type`` ``[N]`` is needed with
    ``type_pairs``; ``exclude`` sorted pair keys ``a * N + b`` (:func:`near_pairs`) dropped from self-contacts;
    ``batch`` ``[N]`` graph index of collated graphs (pairs never cross graphs). Returns the input's array type
    (torch on the input's device). ``method``: ``"kdtree"`` (CPU), ``"dense"`` (torch, blocked), ``"auto"``
    (dense for CUDA tensors, KD-tree otherwise).
    """
    if not radius > 0:
        raise InputError(f"contact radius must be positive, got {radius}")
    if type_pairs is not None and node_type is None:
        raise InputError("type_pairs needs node_type")
    if self_contact and exclude is None:
        raise InputError(
            "self_contact=True needs exclude: the keys of the pairs close on the mesh "
            "(hcmt.graph.contact.near_pairs of the mesh edges), at least the mesh edges themselves"
        )
    is_torch = isinstance(world_pos, Tensor)
    device = world_pos.device if is_torch else None
    if method == "auto":
        method = "dense" if is_torch and world_pos.device.type != "cpu" else "kdtree"
    if method not in ("kdtree", "dense"):
        raise InputError(f"method must be 'auto', 'kdtree' or 'dense', got {method!r}")
    allowed = _type_table(type_pairs)
    if method == "kdtree":
        args = [
            None if a is None else (a.detach().cpu().numpy() if isinstance(a, Tensor) else np.asarray(a))
            for a in (world_pos, object_id, node_type, exclude, batch)
        ]
        edges = _kdtree_contacts(*args[:3], radius, allowed, self_contact, args[3], args[4])
        return torch.from_numpy(edges).to(device) if is_torch else edges
    args = [
        None if a is None else torch.as_tensor(a, device=device)
        for a in (world_pos, object_id, node_type, exclude, batch)
    ]
    edges = _dense_contacts(*args[:3], radius, allowed, self_contact, args[3], args[4])
    return edges if is_torch else edges.numpy()


def _type_table(type_pairs) -> np.ndarray | None:
    if type_pairs is None:
        return None
    table = np.zeros((_TYPE_TABLE, _TYPE_TABLE), bool)
    for a, b in type_pairs:  # a handful of rules
        table[int(a), int(b)] = table[int(b), int(a)] = True
    return table


def _finish(i: np.ndarray, q: np.ndarray, n: int, exclude) -> np.ndarray:
    """Undirected pairs -> both directions, minus excluded keys, unique and sorted."""
    key = unique_sorted(np.concatenate([i * n + q, q * n + i]))
    if exclude is not None and len(exclude):
        key = key[~np.isin(key, exclude, assume_unique=False)]
    return np.stack([key // n, key % n]).astype(np.int64)


def _kdtree_contacts(x, obj, ntype, radius, allowed, self_contact, exclude, batch) -> np.ndarray:
    x = np.asarray(x, np.float64)
    n = len(x)
    obj = np.asarray(obj, np.int64)
    span = int(obj.max()) + 1 if n else 1
    if batch is not None:  # graphs of a batch: one object set per graph; objects of two graphs are never paired
        obj = obj + np.asarray(batch, np.int64) * span
    cand = np.ones(n, bool)
    if allowed is not None:  # only nodes whose type takes part in some rule can be in contact
        cand = allowed.any(1)[np.asarray(ntype, np.int64)]
    order = np.argsort(obj, kind="stable")
    ids = np.unique(obj)
    bounds = np.searchsorted(obj[order], ids, side="left")
    groups = [g[cand[g]] for g in np.split(order, bounds[1:])]  # node indices of each object (a few objects)
    graph = ids // span if batch is not None else np.zeros(len(ids), np.int64)  # each object's graph (ascending)
    last = np.searchsorted(graph, graph, side="right")  # objects a + 1 .. last[a] - 1 share object a's graph
    lo = [x[g].min(0) - radius if len(g) else None for g in groups]
    hi = [x[g].max(0) + radius if len(g) else None for g in groups]
    found_i, found_q = [], []
    for a in range(len(groups)):  # loop over objects, not nodes
        ga = groups[a]
        if not len(ga):
            continue
        if self_contact:
            pairs = cKDTree(x[ga]).query_pairs(radius, output_type="ndarray")
            found_i.append(ga[pairs[:, 0]])
            found_q.append(ga[pairs[:, 1]])
        for b in range(a + 1, int(last[a])):
            gb = groups[b]
            if not len(gb):
                continue
            # bounding boxes (grown by gamma) must overlap; only the nodes inside the other's box can touch it
            ia = ga[np.all((x[ga] >= lo[b]) & (x[ga] <= hi[b]), axis=1)]
            ib = gb[np.all((x[gb] >= lo[a]) & (x[gb] <= hi[a]), axis=1)]
            if not len(ia) or not len(ib):
                continue
            m = cKDTree(x[ia]).sparse_distance_matrix(cKDTree(x[ib]), radius, output_type="ndarray")
            found_i.append(ia[m["i"]])
            found_q.append(ib[m["j"]])
    if not found_i:
        return np.zeros((2, 0), np.int64)
    i, q = np.concatenate(found_i).astype(np.int64), np.concatenate(found_q).astype(np.int64)
    keep = np.linalg.norm(x[i] - x[q], axis=1) < radius  # the KD-tree's test is <=; the paper's is <
    if allowed is not None:
        t = np.asarray(ntype, np.int64)
        keep &= allowed[t[i], t[q]]
    return _finish(i[keep], q[keep], n, exclude)


def _dense_contacts(x, obj, ntype, radius, allowed, self_contact, exclude, batch, block: int = 2048) -> Tensor:
    n = int(x.shape[0])
    x = x.to(torch.float64) if x.device.type == "cpu" else x
    table = None if allowed is None else torch.as_tensor(allowed, device=x.device)
    if table is not None:
        ntype = ntype.long()
    slack = radius * (1 + 1e-5)  # cdist may use a matrix product; exact distances are recomputed below
    found, window = [], _graph_window(batch, n)
    for s in range(0, n, block):  # loop over row blocks (memory: block x N), not over nodes
        e = min(s + block, n)
        lo, hi = (int(window[0][s]), int(window[1][e - 1])) if window is not None else (0, n)
        near = torch.cdist(x[s:e], x[lo:hi]) < slack
        if not self_contact:
            near &= obj[s:e, None] != obj[None, lo:hi]
        if batch is not None:
            near &= batch[s:e, None] == batch[None, lo:hi]
        if table is not None:
            near &= table[ntype[s:e, None], ntype[None, lo:hi]]
        i, q = near.nonzero(as_tuple=True)
        i, q = i + s, q + lo
        keep = (i < q) & (torch.linalg.vector_norm(x[i] - x[q], dim=1) < radius)
        found.append(torch.stack([i[keep], q[keep]]))
    pairs = torch.cat(found, dim=1) if found else torch.zeros((2, 0), dtype=torch.long, device=x.device)
    key = torch.unique(torch.cat([pairs[0] * n + pairs[1], pairs[1] * n + pairs[0]]))  # sorted
    if exclude is not None and exclude.numel():
        exclude = exclude.to(key.device, torch.long)
        pos = torch.searchsorted(exclude, key).clamp_max(exclude.numel() - 1)
        key = key[exclude[pos] != key]
    return torch.stack([key // n, key % n]) if n else torch.zeros((2, 0), dtype=torch.long, device=x.device)


def _graph_window(batch, n: int) -> tuple[Tensor, Tensor] | None:
    """For collated graphs (``batch`` ascending: each graph a contiguous node range), the first and one past the last
    node of every node's graph (on the host), so a row block is tested against its graphs' nodes only, not all ``n``;
    None without a batch or for one in another order."""
    if batch is None or n == 0:
        return None
    b = batch.detach().cpu()
    if not bool((b[1:] >= b[:-1]).all()):
        return None
    return torch.searchsorted(b, b, side="left"), torch.searchsorted(b, b, side="right")
