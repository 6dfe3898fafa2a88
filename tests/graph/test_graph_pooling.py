"""Bi-stride pooling against a plain breadth-first search, and its halving."""

from collections import deque

import numpy as np

from graph_meshes import annulus, grid_triangles, impact_plate
from hcmt.graph.contact import object_ids
from hcmt.graph.edges import cells_to_edges
from hcmt.graph.pooling import bistride_pool, component_seeds, hop_distance


def bfs(adj, seed):
    dist = {seed: 0}
    queue = deque([seed])
    while queue:
        a = queue.popleft()
        for b in adj[a]:
            if b not in dist:
                dist[b] = dist[a] + 1
                queue.append(b)
    return dist


def adjacency(edges, n):
    adj = [[] for _ in range(n)]
    for a, b in edges.T.tolist():
        adj[a].append(b)
    return adj


def test_hop_distance_equals_breadth_first_search_per_component():
    m = impact_plate("small")
    n = len(m["mesh_pos"])
    edges = cells_to_edges(m["cells"], n)
    obj = object_ids(m["cells"], n)
    seeds = component_seeds(m["mesh_pos"], obj, obj.max() + 1)
    depth = hop_distance(edges, n, seeds)
    adj = adjacency(edges, n)
    for s in seeds:
        for node, d in bfs(adj, int(s)).items():
            assert depth[node] == d


def test_seed_is_the_node_nearest_the_centroid():
    pos, cells = grid_triangles(7, 5)  # odd x odd grid: the centre node is a node
    seeds = component_seeds(pos, np.zeros(len(pos), np.int64), 1)
    assert np.allclose(pos[seeds[0]], pos.mean(0))


def test_kept_nodes_follow_parity_and_every_dropped_node_touches_a_kept_one():
    pos, cells = annulus()
    n = len(pos)
    edges = cells_to_edges(cells, n)
    kept = bistride_pool(edges, n, pos)
    is_kept = np.zeros(n, bool)
    is_kept[kept] = True
    adj = adjacency(edges, n)
    assert all(any(is_kept[b] for b in adj[a]) for a in np.flatnonzero(~is_kept))
    # the smaller parity class is kept whole
    depth = hop_distance(edges, n, component_seeds(pos, np.zeros(n, np.int64), 1))
    classes = [np.flatnonzero(depth % 2 == p) for p in (0, 1)]
    smaller = min(classes, key=len)
    assert is_kept[smaller].all()
    assert abs(len(kept) - n / 2) <= 0.1 * n


def test_pooling_is_per_component_and_halves():
    m = impact_plate("paper")
    n = len(m["mesh_pos"])
    obj = object_ids(m["cells"], n)
    kept = bistride_pool(cells_to_edges(m["cells"], n), n, m["mesh_pos"])
    for o in np.unique(obj):
        ratio = np.sum(obj[kept] == o) / np.sum(obj == o)
        assert 0.4 <= ratio <= 0.6


def test_tiny_components():
    # two isolated nodes and a single edge: each isolated node stays, the edge keeps one end
    edges = cells_to_edges(np.array([[2, 3]]), 4)
    kept = bistride_pool(edges, 4, np.array([[0.0, 0], [5, 5], [1, 0], [2, 0]]))
    assert set(kept[:2].tolist()) == {0, 1} and len(kept) == 3
