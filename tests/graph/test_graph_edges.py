"""Mesh edges from cells and the raw edge features (paper appendix, Table 9)."""

import itertools

import numpy as np
import torch

from graph_meshes import annulus, grid_triangles, tet_box
from hcmt.graph.edges import cells_to_edges, contact_edge_features, mesh_edge_features


def _undirected(edges):
    return {tuple(sorted(p)) for p in edges.T.tolist()}


def test_triangle_edges_are_unique_bidirectional_and_satisfy_euler():
    pos, cells = annulus()
    edges = cells_to_edges(cells, len(pos))
    assert edges.dtype == np.int64 and edges.shape[0] == 2
    assert (edges[0] != edges[1]).all()
    pairs = set(map(tuple, edges.T.tolist()))
    assert len(pairs) == edges.shape[1]  # no duplicates
    assert all((b, a) in pairs for a, b in pairs)  # both directions
    # Euler characteristic of an annulus (one hole): V - E + F = 0
    assert len(pos) - edges.shape[1] // 2 + len(cells) == 0


def test_tetrahedra_give_all_six_edges_and_satisfy_euler():
    pos, cells = tet_box(4, 3, 3)
    edges = cells_to_edges(cells, len(pos))
    expected = {tuple(sorted(p)) for c in cells.tolist() for p in itertools.combinations(c, 2)}
    assert _undirected(edges) == expected
    faces = {tuple(sorted(f)) for c in cells.tolist() for f in itertools.combinations(c, 3)}
    # a solid box is a 3-ball: V - E + F - T = 1
    assert len(pos) - len(expected) + len(faces) - len(cells) == 1


def test_repeated_vertex_cell_contributes_only_real_edges():
    edges = cells_to_edges(np.array([[0, 1, 1], [1, 2, 3]]), 4)
    assert _undirected(edges) == {(0, 1), (1, 2), (1, 3), (2, 3)}


def test_edge_features_layout_direction_and_invariance():
    mesh_pos, cells = grid_triangles(5, 4)
    rng = np.random.default_rng(0)
    world = np.c_[mesh_pos, np.zeros(len(mesh_pos))] + rng.normal(0, 0.01, (len(mesh_pos), 3))
    edges = torch.from_numpy(cells_to_edges(cells, len(mesh_pos)))
    u, x = torch.from_numpy(mesh_pos), torch.from_numpy(world)
    f = mesh_edge_features(u, x, edges)
    assert f.shape == (edges.shape[1], 2 + 1 + 3 + 1)  # cloth-like: 2-D mesh space, 3-D world
    j, i = edges
    torch.testing.assert_close(f[:, :2], u[j] - u[i])  # u_ij = u_j - u_i, sender minus receiver
    torch.testing.assert_close(f[:, 3:6], x[j] - x[i])
    torch.testing.assert_close(f[:, 2], torch.linalg.norm(u[j] - u[i], dim=1))
    torch.testing.assert_close(f[:, 6], torch.linalg.norm(x[j] - x[i], dim=1))
    # a rigid motion of the world leaves the norms unchanged and rotates the vectors
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    moved = mesh_edge_features(u, torch.from_numpy(world @ q.T + 5.0), edges)
    torch.testing.assert_close(moved[:, 6], f[:, 6])
    torch.testing.assert_close(moved[:, 3:6], f[:, 3:6] @ torch.from_numpy(q.T))
    # reversing an edge negates its vectors
    rev = mesh_edge_features(u, x, edges.flip(0))
    torch.testing.assert_close(rev[:, [0, 1, 3, 4, 5]], -f[:, [0, 1, 3, 4, 5]])


def test_contact_features_of_no_contact_are_empty():
    x = torch.rand(10, 2)
    f = contact_edge_features(x, torch.zeros((2, 0), dtype=torch.long))
    assert f.shape == (0, 3)
