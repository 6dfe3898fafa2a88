"""Test fixtures for the model tests: a structured triangle grid as a :class:`hcmt.graph.batch.Graph`, with a
hand-made hierarchy (every other row and column kept per level, coarse edges = the coarse grid's triangles).

Stand-alone on purpose (no dependency on hcmt.graph's hierarchy builder), so the model invariants are tested on a
hierarchy whose hop distances are known.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.csgraph as csgraph
import torch

from hcmt.graph.batch import Graph
from hcmt.graph.build import frame_graph
from hcmt.graph.hierarchy import build_hierarchy
from hcmt.sim.mesh import preset_mesh


def grid_edges(rows: int, cols: int) -> np.ndarray:
    """Both directions of the edges of a ``rows x cols`` grid split into triangles by one diagonal per square."""
    idx = np.arange(rows * cols).reshape(rows, cols)
    pairs = [
        np.stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()]),  # horizontal
        np.stack([idx[:-1, :].ravel(), idx[1:, :].ravel()]),  # vertical
        np.stack([idx[:-1, :-1].ravel(), idx[1:, 1:].ravel()]),
    ]  # diagonal
    und = np.concatenate(pairs, axis=1)
    return np.concatenate([und, und[::-1]], axis=1).astype(np.int64)


def _features(mesh_pos: np.ndarray, world_pos: np.ndarray, edges: np.ndarray) -> np.ndarray:
    u = mesh_pos[edges[0]] - mesh_pos[edges[1]]
    x = world_pos[edges[0]] - world_pos[edges[1]]
    return np.concatenate([u, np.linalg.norm(u, axis=1, keepdims=True), x, np.linalg.norm(x, axis=1, keepdims=True)], 1)


def grid_graph(
    rows: int = 17, cols: int = 17, levels: int = 2, *, node_in: int = 5, contacts: int = 0, seed: int = 0
) -> Graph:
    """A grid graph with ``levels`` pooled levels, random node features (width ``node_in``), mesh edge features
    ``[u, |u|, x, |x|]`` (width 6) from a slightly perturbed world position, and ``contacts`` random contact
    edges (both directions, width-3 features ``[x_iq, |x_iq|]``)."""
    rng = np.random.default_rng(seed)
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    mesh_pos = np.stack([c.ravel(), r.ravel()], 1).astype(np.float64) * 0.1
    world_pos = mesh_pos + rng.normal(scale=0.01, size=mesh_pos.shape)
    edges = grid_edges(rows, cols)
    level0 = np.arange(rows * cols)  # level-0 index of each level's node
    pool, level_edges, level_features = [], [], []
    shape = (rows, cols)
    for _ in range(levels):
        grid = level0.reshape(shape)
        idx = np.arange(grid.size).reshape(shape)
        keep = idx[::2, ::2]
        pool.append(torch.from_numpy(keep.ravel().copy()))
        level0 = grid[::2, ::2].ravel()
        shape = keep.shape
        e = grid_edges(*shape)
        level_edges.append(torch.from_numpy(e))
        level_features.append(torch.from_numpy(_features(mesh_pos[level0], world_pos[level0], e)).float())
    n = rows * cols
    if contacts:
        i = rng.choice(n, size=contacts, replace=False)
        q = (i + n // 2) % n
        und = np.stack([q, i])
        ce = np.concatenate([und, und[::-1]], axis=1)
        x = world_pos[ce[0]] - world_pos[ce[1]]
        cf = np.concatenate([x, np.linalg.norm(x, axis=1, keepdims=True)], 1)
    else:
        ce, cf = np.zeros((2, 0), np.int64), np.zeros((0, 3))
    return Graph(
        node_features=torch.from_numpy(rng.normal(size=(n, node_in))).float(),
        mesh_edges=torch.from_numpy(edges),
        mesh_features=torch.from_numpy(_features(mesh_pos, world_pos, edges)).float(),
        contact_edges=torch.from_numpy(ce.astype(np.int64)),
        contact_features=torch.from_numpy(cf).float(),
        pool=pool,
        level_edges=level_edges,
        level_features=level_features,
    )


def hop_distance(edges: torch.Tensor, num_nodes: int, source: int) -> np.ndarray:
    """Unweighted shortest-path hop counts from ``source`` over the given edges (inf when unreachable)."""
    e = edges.numpy()
    adj = sp.coo_matrix((np.ones(e.shape[1]), (e[0], e[1])), shape=(num_nodes, num_nodes)).tocsr()
    return csgraph.shortest_path(adj, unweighted=True, indices=source)


def permute_graph(g: Graph, seed: int = 1) -> tuple[Graph, torch.Tensor]:
    """Relabel the nodes of every level and shuffle every edge list; returns the graph and the level-0
    permutation ``perm`` such that new node ``k`` is old node ``perm[k]``."""
    gen = torch.Generator().manual_seed(seed)
    counts = [g.num_nodes] + [len(p) for p in g.pool]
    perms = [torch.randperm(n, generator=gen) for n in counts]
    inverse = [torch.argsort(p) for p in perms]  # old -> new label

    def shuffle(edges, feats, inv):
        order = torch.randperm(edges.shape[1], generator=gen)
        return inv[edges[:, order]], feats[order]

    mesh_edges, mesh_features = shuffle(g.mesh_edges, g.mesh_features, inverse[0])
    contact_edges, contact_features = shuffle(g.contact_edges, g.contact_features, inverse[0])
    pool, level_edges, level_features = [], [], []
    for l, p in enumerate(g.pool):
        # new level-(l+1) node k is old node perms[l+1][k]; its fine index is old p[...] relabelled at level l
        pool.append(inverse[l][p[perms[l + 1]]])
        e, f = shuffle(g.level_edges[l], g.level_features[l], inverse[l + 1])
        level_edges.append(e)
        level_features.append(f)
    return Graph(
        g.node_features[perms[0]],
        mesh_edges,
        mesh_features,
        contact_edges,
        contact_features,
        pool,
        level_edges,
        level_features,
    ), perms[0]


def paper_graph(seed: int = 0, levels: int = 6) -> Graph:
    """A paper-size Impact Plate sample: the ``paper`` preset mesh (about 2,200 nodes), its λ-level hierarchy
    (bi-stride pooling + Delaunay), a randomly perturbed world position and contact radius 0.4 (Table 8);
    Impact Plate node inputs (Table 9): node-type one-hot (9), velocity (2), density, modulus -> width 13."""
    rng = np.random.default_rng(seed)
    mesh = preset_mesh("paper")
    hierarchy = build_hierarchy(mesh["mesh_pos"], mesh["cells"], mesh["node_type"], levels=levels)
    mesh_pos = torch.from_numpy(mesh["mesh_pos"]).float()
    world_pos = mesh_pos + torch.from_numpy(rng.normal(scale=0.01, size=mesh["mesh_pos"].shape)).float()
    n = mesh_pos.shape[0]
    one_hot = torch.nn.functional.one_hot(torch.from_numpy(mesh["node_type"]), 9).float()
    rest = torch.from_numpy(rng.normal(size=(n, 4))).float()
    return frame_graph(torch.cat([one_hot, rest], 1), mesh_pos, world_pos, hierarchy, 0.4)
