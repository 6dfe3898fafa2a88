"""Mesh edges from cells, and the raw edge features of the paper (appendix, Table 9).

Direction convention (shared with :mod:`hcmt.graph.batch`): an edge column ``(j, i)`` has sender ``j`` (row 0) and
receiver ``i`` (row 1). Relative vectors are **sender minus receiver**, as in the official HCMT code
(``gather(pos, senders) - gather(pos, receivers)``):

* mesh edge ``(j, i)``: ``m_ij = [u_ij, |u_ij|, x_ij, |x_ij|]`` with ``u_ij = u_j - u_i`` (mesh space) and
  ``x_ij = x_j - x_i`` (world space); width ``d_mesh + 1 + d_world + 1`` (Impact Plate 6, cloth 2+1+3+1 = 7);
* contact edge ``(q, i)``: ``c_iq = [x_iq, |x_iq|]`` with ``x_iq = x_q - x_i``; width ``d_world + 1``.

The order ``[u, |u|, x, |x|]`` follows the paper's Table 9 (the official code stores world first; the models only
see normalized features, so the order matters only for consistency, which this module owns).
"""

from __future__ import annotations

from itertools import combinations

import numpy as np
import torch
from torch import Tensor

from hcmt.errors import InputError


def cells_to_edges(cells: np.ndarray, num_nodes: int | None = None) -> np.ndarray:
    """Unique undirected edges of simplicial cells (triangles ``[C,3]``, tetrahedra ``[C,4]``, segments ``[C,2]``),
    returned in both directions as ``[2, E]`` int64, sorted by (sender, receiver).

    Every pair of a cell's vertices is an edge (a tetrahedron has 6). Pairs with equal indices (a degenerate cell
    that repeats a vertex) are dropped, so such a cell contributes the edges of the lower-dimensional simplex it
    really is.
    """
    cells = np.asarray(cells, dtype=np.int64)
    if cells.ndim != 2 or cells.shape[1] < 2:
        raise InputError(f"cells must be [C, k] with k >= 2 vertices per cell, got shape {list(cells.shape)}")
    if num_nodes is None:
        num_nodes = int(cells.max()) + 1 if cells.size else 0
    pairs = np.concatenate([cells[:, [a, b]] for a, b in combinations(range(cells.shape[1]), 2)])
    return undirected_to_edges(pairs, num_nodes)


def undirected_to_edges(pairs: np.ndarray, num_nodes: int) -> np.ndarray:
    """``[P, 2]`` node pairs (any order, duplicates allowed) -> unique ``[2, E]`` edges in both directions,
    self-loops removed, sorted by (sender, receiver)."""
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    lo, hi = np.minimum(pairs[:, 0], pairs[:, 1]), np.maximum(pairs[:, 0], pairs[:, 1])
    keep = lo != hi
    key = unique_sorted(lo[keep] * num_nodes + hi[keep])  # packed (min, max): one sort removes duplicates
    lo, hi = key // num_nodes, key % num_nodes
    both = np.sort(np.concatenate([key, hi * num_nodes + lo]))  # both directions, packed (sender, receiver)
    return np.stack([both // num_nodes, both % num_nodes])


def unique_sorted(a: np.ndarray) -> np.ndarray:
    """Sorted unique values of an integer array (sort + neighbour test: faster than ``np.unique`` here)."""
    a = np.sort(a)
    return a[np.r_[True, a[1:] != a[:-1]]] if len(a) else a


def relative(pos: Tensor, edges: Tensor) -> Tensor:
    """``pos[sender] - pos[receiver]`` for ``[2, E]`` edges, with its norm appended: ``[E, d + 1]``."""
    d = pos[edges[0]] - pos[edges[1]]
    return torch.cat([d, torch.linalg.vector_norm(d, dim=-1, keepdim=True)], dim=-1)


def mesh_edge_features(mesh_pos: Tensor, world_pos: Tensor, edges: Tensor) -> Tensor:
    """Mesh edge features ``m_ij = [u_ij, |u_ij|, x_ij, |x_ij|]`` (``u_ij = u_j - u_i``, ``x_ij = x_j - x_i``,
    ``j`` the sender), ``[E, d_mesh + d_world + 2]``. Mesh and world dimensions may differ (cloth: 2-D mesh
    space, 3-D world)."""
    return torch.cat([relative(mesh_pos, edges), relative(world_pos, edges)], dim=-1)


def contact_edge_features(world_pos: Tensor, edges: Tensor) -> Tensor:
    """Contact edge features ``c_iq = [x_iq, |x_iq|]`` with ``x_iq = x_q - x_i`` (``q`` the sender),
    ``[C, d_world + 1]``; an empty ``[2, 0]`` edge set gives ``[0, d_world + 1]``."""
    return relative(world_pos, edges)
