"""The one graph every contestant times: hcmt's paper-size Impact Plate frame, written to an .npz.

    PYTHONPATH=src python benchmarks/peers/export_graph.py OUT.npz

The ``paper`` preset mesh of :mod:`hcmt.sim.mesh`, its 6-level hierarchy (bi-stride + Delaunay), the world
position a small random displacement of the mesh position (σ = 0.01) and the contact edges of radius 0.4 there.
Node inputs (hcmt's layout): one-hot node type (9), velocity (2), density, modulus, random normal. The file holds
hcmt's graph tensors (level 0 mesh / contact edges and features, ``pool_l``, ``level_edges_l``,
``level_features_l``) and the raw frame the TensorFlow side needs (positions, node type, velocity, density,
modulus)."""

from __future__ import annotations

import sys

import numpy as np
import torch

from hcmt.domains.spec import dataset_spec
from hcmt.graph.build import frame_graph
from hcmt.graph.hierarchy import build_hierarchy
from hcmt.sim.mesh import preset_mesh


def export(path: str, seed: int = 0) -> dict:
    spec = dataset_spec("impact_plate")
    rng = np.random.default_rng(seed)
    mesh = preset_mesh("paper")
    hierarchy = build_hierarchy(mesh["mesh_pos"], mesh["cells"], mesh["node_type"], levels=spec["levels"])
    mesh_pos = mesh["mesh_pos"].astype(np.float32)
    world_pos = (mesh_pos + rng.normal(scale=0.01, size=mesh_pos.shape)).astype(np.float32)
    extra = rng.normal(size=(len(mesh_pos), 4)).astype(np.float32)  # velocity (2), density, modulus
    one_hot = np.eye(9, dtype=np.float32)[mesh["node_type"]]
    g = frame_graph(
        torch.from_numpy(np.concatenate([one_hot, extra], 1)),
        torch.from_numpy(mesh_pos),
        torch.from_numpy(world_pos),
        hierarchy,
        spec["radius"],
    )
    arrays = dict(
        node_features=g.node_features,
        mesh_edges=g.mesh_edges,
        mesh_features=g.mesh_features,
        contact_edges=g.contact_edges,
        contact_features=g.contact_features,
    )
    for level, (p, e, f) in enumerate(zip(g.pool, g.level_edges, g.level_features)):
        arrays.update({f"pool_{level}": p, f"level_edges_{level}": e, f"level_features_{level}": f})
    arrays = {k: v.numpy() for k, v in arrays.items()}
    arrays.update(
        mesh_pos=mesh_pos,
        world_pos=world_pos,
        node_type=mesh["node_type"].astype(np.int32),
        cells=mesh["cells"].astype(np.int32),
        velocity=extra[:, :2],
        density=extra[:, 2:3],
        modulus=extra[:, 3:4],
        out_dim=np.int64(spec["out"]),
    )
    np.savez(path, **arrays)
    return {
        "nodes": len(mesh_pos),
        "mesh_edges": int(g.mesh_edges.shape[1]),
        "contact_edges": int(g.contact_edges.shape[1]),
        "level_nodes": [len(p) for p in g.pool],
    }


if __name__ == "__main__":
    print(export(sys.argv[1]))
