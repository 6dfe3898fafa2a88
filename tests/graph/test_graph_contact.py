"""Contact edges against a brute-force O(N^2) search."""

import numpy as np
import pytest
import torch

from graph_meshes import NORMAL, OBSTACLE, SYMMETRIC, cloth, plate_and_ball
from hcmt.graph.contact import OFFICIAL_IMPACT_PLATE_TYPES, contact_edges, near_pairs, object_ids
from hcmt.graph.edges import cells_to_edges


def brute_force(x, obj, radius, ntype=None, rule=None, self_contact=False, excluded=(), batch=None):
    """Every ordered pair, tested one by one (reference; small N only)."""
    d = np.linalg.norm(x[:, None] - x[None], axis=-1)
    ok = (d < radius) & ~np.eye(len(x), dtype=bool)
    if not self_contact:
        ok &= obj[:, None] != obj[None]
    if batch is not None:
        ok &= batch[:, None] == batch[None]
    if rule is not None:
        allowed = {tuple(p) for p in rule} | {tuple(p[::-1]) for p in rule}
        ok &= np.array([[(a, b) in allowed for b in ntype] for a in ntype])
    pairs = {(a, b) for a, b in zip(*np.nonzero(ok))} - set(excluded)
    return pairs


def as_set(edges):
    e = edges.numpy() if isinstance(edges, torch.Tensor) else edges
    return set(map(tuple, e.T.tolist()))


@pytest.mark.parametrize("method", ["kdtree", "dense"])
def test_contacts_between_objects_equal_brute_force(method):
    m = plate_and_ball(h=0.1, length=2.0, radius=0.6, gap=0.02)
    x = m["mesh_pos"].copy()
    n_plate = m["n_plate"]
    x[n_plate:, 1] -= 0.05  # push the ball into the plate a little
    obj = object_ids(m["cells"], len(x))
    assert len(np.unique(obj)) == 2
    for radius in (0.03, 0.12, 0.25):
        got = contact_edges(torch.from_numpy(x), torch.from_numpy(obj), radius, method=method)
        assert got.dtype == torch.long and got.shape[0] == 2
        want = brute_force(x, obj, radius)
        assert as_set(got) == want and got.shape[1] == len(want)
        assert len(want) > 0


@pytest.mark.parametrize("method", ["kdtree", "dense"])
def test_type_rule_official_impact_plate(method):
    m = plate_and_ball(h=0.1, length=2.0, radius=0.6, gap=0.02)
    x, t = m["mesh_pos"], m["node_type"]
    obj = object_ids(m["cells"], len(x))
    got = contact_edges(x, obj, 0.2, node_type=t, type_pairs=OFFICIAL_IMPACT_PLATE_TYPES, method=method)
    want = brute_force(x, obj, 0.2, t, OFFICIAL_IMPACT_PLATE_TYPES)
    assert as_set(got) == want and want
    pair_types = {(t[a], t[b]) for a, b in want}
    assert pair_types == {(OBSTACLE, NORMAL), (NORMAL, OBSTACLE)}
    # without the rule the SYMMETRIC nodes on the axis are in contact too
    loose = as_set(contact_edges(x, obj, 0.2, method=method))
    assert any(SYMMETRIC in (t[a], t[b]) for a, b in loose)


def test_radius_is_strict_and_no_contact_is_empty():
    x = np.array([[0.0, 0.0], [0.5, 0.0], [3.0, 0.0]])
    obj = np.array([0, 1, 2])
    for method in ("kdtree", "dense"):
        assert contact_edges(torch.from_numpy(x), torch.from_numpy(obj), 0.5, method=method).shape == (2, 0)
        got = contact_edges(torch.from_numpy(x), torch.from_numpy(obj), 0.5000001, method=method)
        assert as_set(got) == {(0, 1), (1, 0)}
    none = contact_edges(np.array([[0.0, 0], [1, 1]]), np.array([0, 1]), 0.1)
    assert none.shape == (2, 0) and none.dtype == np.int64


@pytest.mark.parametrize("method", ["kdtree", "dense"])
def test_self_contact_of_folded_cloth_excludes_mesh_neighbours(method):
    mesh_pos, cells, world = cloth(12, fold=True)
    n = len(world)
    edges = cells_to_edges(cells, n)
    obj = object_ids(cells, n)
    assert (obj == 0).all()
    excl = near_pairs(edges, n, hops=3)
    radius = 0.06
    got = contact_edges(
        torch.from_numpy(world),
        torch.from_numpy(obj),
        radius,
        self_contact=True,
        exclude=torch.from_numpy(excl),
        method=method,
    )
    excluded = {(int(k // n), int(k % n)) for k in excl}
    want = brute_force(world, obj, radius, self_contact=True, excluded=excluded)
    assert as_set(got) == want and want
    assert not as_set(got) & set(map(tuple, edges.T.tolist()))  # never a mesh edge
    # the contacts join the two halves of the fold, far apart on the mesh
    u = mesh_pos[got[0].numpy()] - mesh_pos[got[1].numpy()]
    assert np.linalg.norm(u, axis=1).min() > 0.1
    flat = contact_edges(cloth(12, fold=False)[2], obj, radius, self_contact=True, exclude=excl, method=method)
    assert flat.shape[1] == 0  # a flat cloth touches nothing


def test_near_pairs_counts_hops():
    # a path 0-1-2-3
    edges = cells_to_edges(np.array([[0, 1], [1, 2], [2, 3]]), 4)
    keys = near_pairs(edges, 4, hops=2)
    pairs = {(int(k // 4), int(k % 4)) for k in keys}
    assert pairs == {(0, 1), (1, 0), (1, 2), (2, 1), (2, 3), (3, 2), (0, 2), (2, 0), (1, 3), (3, 1)}


@pytest.mark.parametrize("method", ["kdtree", "dense"])
def test_batched_world_positions_never_cross_graphs(method):
    rng = np.random.default_rng(1)
    x = rng.uniform(0, 1, (60, 3))
    obj = rng.integers(0, 3, 60)
    batch = np.repeat([0, 1, 2], 20)
    got = contact_edges(torch.from_numpy(x), torch.from_numpy(obj), 0.3, batch=torch.from_numpy(batch), method=method)
    want = brute_force(x, obj, 0.3, batch=batch)
    assert as_set(got) == want and want
    # same positions without the batch vector would connect graphs: the batch really separates them
    assert as_set(contact_edges(x, obj, 0.3, method=method)) != want


def test_kdtree_and_dense_agree_on_random_clouds():
    rng = np.random.default_rng(2)
    x = torch.from_numpy(rng.uniform(0, 1, (500, 2)))
    obj = torch.from_numpy(rng.integers(0, 4, 500))
    t = torch.from_numpy(rng.integers(0, 2, 500))
    for kw in ({}, {"node_type": t, "type_pairs": [(0, 1)]}, {"self_contact": True, "exclude": np.zeros(0, np.int64)}):
        a = contact_edges(x, obj, 0.05, method="kdtree", **kw)
        b = contact_edges(x, obj, 0.05, method="dense", **kw)
        assert torch.equal(a, b)


def test_bad_parameters_are_refused():
    with pytest.raises(ValueError, match="radius"):
        contact_edges(np.zeros((2, 2)), np.array([0, 1]), 0.0)
    with pytest.raises(ValueError, match="node_type"):
        contact_edges(np.zeros((2, 2)), np.array([0, 1]), 0.1, type_pairs=[(0, 1)])
    with pytest.raises(ValueError, match="self_contact=True needs exclude"):
        contact_edges(np.zeros((2, 2)), np.array([0, 0]), 0.1, self_contact=True)
