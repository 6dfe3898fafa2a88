"""One frame -> Graph: features, levels and contacts as the models consume them."""

import numpy as np
import torch

from graph_meshes import cloth, impact_plate, plate_and_ball
from hcmt.graph.batch import collate
from hcmt.graph.build import frame_graph
from hcmt.graph.contact import OFFICIAL_IMPACT_PLATE_TYPES, contact_edges, near_pairs
from hcmt.graph.edges import mesh_edge_features
from hcmt.graph.hierarchy import build_hierarchy


def _frame(m, h, shift=0.0, **kw):
    n = len(m["mesh_pos"])
    world = m["mesh_pos"].copy()
    world[h.object_id == 1, 1] -= shift  # move the ball down
    return frame_graph(
        torch.ones(n, 4), torch.from_numpy(m["mesh_pos"]).float(), torch.from_numpy(world).float(), h, 0.4, **kw
    )


def test_frame_graph_levels_and_features():
    m = impact_plate("small")
    h = build_hierarchy(m["mesh_pos"], m["cells"], m["node_type"], 4)
    g = _frame(m, h, shift=0.1)
    n = len(m["mesh_pos"])
    assert g.num_nodes == n and g.num_levels == 4
    assert g.mesh_edges.shape[0] == 2 and g.mesh_features.shape == (g.mesh_edges.shape[1], 6)
    assert g.contact_edges.shape[1] > 0 and g.contact_features.shape == (g.contact_edges.shape[1], 3)
    assert (g.contact_features[:, 2] < 0.4).all()
    sizes = [n]
    for level in range(4):
        assert g.pool[level].max() < sizes[-1]
        sizes.append(len(g.pool[level]))
        e = g.level_edges[level]
        assert e.max() < sizes[-1]
        # the level's features are those of its nodes' own positions (level-0 index composes the pools)
        idx = torch.arange(n)
        for l in range(level + 1):
            idx = idx[g.pool[l]]
        x = torch.from_numpy(m["mesh_pos"]).float()[idx]
        torch.testing.assert_close(g.level_features[level][:, :2], x[e[0]] - x[e[1]])
        torch.testing.assert_close(g.level_features[level][:, 2], torch.linalg.norm(x[e[0]] - x[e[1]], dim=1))
    # at rest (world = mesh) the world part of every edge feature equals the mesh part
    torch.testing.assert_close(g.mesh_features[:, :3], g.mesh_features[:, 3:])


def test_contact_rule_and_batching():
    m = plate_and_ball(h=0.1, length=3.0, radius=0.8)
    h = build_hierarchy(m["mesh_pos"], m["cells"], m["node_type"], 3)
    a = _frame(m, h, shift=0.1, node_type=torch.from_numpy(m["node_type"]), type_pairs=OFFICIAL_IMPACT_PLATE_TYPES)
    t = m["node_type"]
    types = {(t[i], t[j]) for i, j in a.contact_edges.T.tolist()}
    assert types == {(0, 1), (1, 0)}
    b = _frame(m, h, shift=0.0)  # resting 0.02 above the plate: still within the radius
    batch = collate([a, b])
    n = a.num_nodes
    assert batch.contact_edges.shape[1] == a.contact_edges.shape[1] + b.contact_edges.shape[1]
    # contact edges of collated world positions equal the per-graph ones offset
    world = torch.cat([torch.from_numpy(m["mesh_pos"]).float()] * 2)
    world[:n][torch.from_numpy(h.object_id == 1), 1] -= 0.1
    obj = torch.from_numpy(np.r_[h.object_id, h.object_id + 2])
    joint = contact_edges(world, obj, 0.4, batch=batch.batch)
    assert torch.equal(
        joint, torch.cat([contact_edges(world[:n], obj[:n], 0.4), contact_edges(world[n:], obj[n:], 0.4) + n], 1)
    )


def test_cloth_frame_has_two_dimensional_mesh_space_and_self_contacts():
    mesh_pos, cells, world = cloth(16, fold=True)
    h = build_hierarchy(mesh_pos, cells, None, 2)
    excl = torch.from_numpy(near_pairs(h.edges[0], len(mesh_pos), 3))
    g = frame_graph(
        torch.zeros(len(mesh_pos), 3),
        torch.from_numpy(mesh_pos),
        torch.from_numpy(world),
        h,
        0.06,
        self_contact=True,
        exclude=excl,
    )
    default = frame_graph(
        torch.zeros(len(mesh_pos), 3), torch.from_numpy(mesh_pos), torch.from_numpy(world), h, 0.06, self_contact=True
    )  # excludes pairs within 3 mesh hops by default
    assert torch.equal(default.contact_edges, g.contact_edges)
    mesh = set(map(tuple, h.edges[0].T.tolist()))
    assert not mesh & set(map(tuple, g.contact_edges.T.tolist()))
    assert g.mesh_features.shape[1] == 2 + 1 + 3 + 1
    assert all(f.shape[1] == 7 for f in g.level_features)
    assert g.contact_edges.shape[1] > 0 and g.contact_features.shape[1] == 4
    none = frame_graph(
        torch.zeros(len(mesh_pos), 3), torch.from_numpy(mesh_pos), torch.from_numpy(world), h, 0.06
    )  # without self-contact a single object touches nothing
    assert none.contact_edges.shape == (2, 0) and none.contact_features.shape == (0, 4)


def test_cached_mesh_space_features_follow_the_mesh_positions():
    m = plate_and_ball(h=0.1, length=2.0, radius=0.5)
    h = build_hierarchy(m["mesh_pos"], m["cells"], m["node_type"], 2)
    n = len(m["mesh_pos"])
    u = torch.from_numpy(m["mesh_pos"])
    a = frame_graph(torch.zeros(n, 1), u, u, h, 0.1)
    torch.testing.assert_close(a.mesh_features, mesh_edge_features(u, u, torch.from_numpy(h.edges[0])))
    scaled = frame_graph(torch.zeros(n, 1), 2 * u, u, h, 0.1)  # other mesh positions: not stale
    torch.testing.assert_close(scaled.mesh_features[:, :3], 2 * a.mesh_features[:, :3])
    torch.testing.assert_close(scaled.level_features[1][:, :3], 2 * a.level_features[1][:, :3])
