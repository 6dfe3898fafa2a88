"""Bi-stride node pooling (paper, "Pooling Method", step i; Cao et al. 2023, BSMS-GNN).

For each connected component of a level's graph: a seed (the node nearest the component's centroid in mesh
space), the breadth-first hop distance of every node from it, and the nodes of one parity class kept: the smaller
of the even-distance and odd-distance classes (ties keep the even class, which holds the seed; a single-node
component keeps its node). Every dropped node is one hop from a kept node.

The parity classes of a small or irregular component can be very unequal (a node and its ring of six: 1 vs 6),
so, as BSMS's reference code does ("enforce n//2 candidates"), when the dropped class is larger by ``delta``
every ``(n_dropped // delta + 1)``-th dropped node in order of hop distance (ties by index) is kept too. The
level then halves: Impact Plate 2208 -> 1108 -> 559 -> 285 -> 148 -> 78 -> 42 in the paper's Table 6.

All components are searched at once: a virtual source node is joined to every seed and one unweighted
shortest-path search (``scipy.sparse.csgraph.dijkstra``) from it gives each node's hop distance + 1.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, dijkstra


def component_seeds(pos: np.ndarray, label: np.ndarray, num_components: int) -> np.ndarray:
    """Per component, the node nearest its centroid (mean node position); ties go to the lowest index."""
    count = np.bincount(label, minlength=num_components).astype(np.float64)
    centroid = np.stack([np.bincount(label, pos[:, k], num_components) for k in range(pos.shape[1])], 1)
    centroid /= np.maximum(count, 1)[:, None]
    dist = np.linalg.norm(pos - centroid[label], axis=1)
    order = np.lexsort((dist, label))  # by component, then distance; stable, so ties go to the lower index
    first = np.r_[True, label[order][1:] != label[order][:-1]]
    return order[first]


def hop_distance(edges: np.ndarray, num_nodes: int, seeds: np.ndarray) -> np.ndarray:
    """Hop distance of every node from the nearest of ``seeds`` (int64; -1 where unreachable)."""
    src = num_nodes  # the virtual source, one hop before every seed
    rows = np.concatenate([edges[0], np.full(len(seeds), src)])
    cols = np.concatenate([edges[1], seeds])
    graph = sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(num_nodes + 1, num_nodes + 1))
    dist = dijkstra(graph, directed=True, indices=src, unweighted=True)[:num_nodes]
    out = np.full(num_nodes, -1, np.int64)
    ok = np.isfinite(dist)
    out[ok] = dist[ok].astype(np.int64) - 1
    return out


def bistride_pool(edges: np.ndarray, num_nodes: int, pos: np.ndarray) -> np.ndarray:
    """Indices (ascending) of the nodes that the next level keeps.

    ``edges`` ``[2, E]`` (both directions) of this level, ``pos`` ``[N, d]`` its nodes' mesh-space positions.
    """
    edges = np.asarray(edges, np.int64)
    adj = sp.csr_matrix((np.ones(edges.shape[1], np.int8), (edges[0], edges[1])), shape=(num_nodes, num_nodes))
    k, label = connected_components(adj, directed=False)
    seeds = component_seeds(np.asarray(pos, np.float64), label, k)
    depth = hop_distance(edges, num_nodes, seeds)
    odd = depth % 2 == 1
    n_odd = np.bincount(label, odd, k)
    n_even = np.bincount(label, ~odd, k)
    keep_odd = (n_odd > 0) & (n_odd < n_even)  # the smaller non-empty class; ties keep the seed's (even) class
    kept = odd == keep_odd[label]
    # BSMS's balancing: strided extra nodes from the larger dropped class, nearest the seed first
    n_kept = np.where(keep_odd, n_odd, n_even)
    n_drop = np.where(keep_odd, n_even, n_odd)
    delta = n_drop - n_kept
    dropped = np.flatnonzero(~kept)
    dropped = dropped[np.lexsort((dropped, depth[dropped], label[dropped]))]  # by component, depth, index
    lab = label[dropped]
    rank = np.arange(len(dropped)) - np.searchsorted(lab, lab)  # position within its component
    stride = n_drop[lab] // np.maximum(delta[lab], 1) + 1
    kept[dropped[(delta[lab] > 0) & (rank % stride == 0)]] = True
    return np.flatnonzero(kept)
