"""Trajectories as tensors, with what never changes along them (mesh edges, objects, the hierarchy) built once,
and one frame turned into the model input :class:`~hcmt.graph.batch.Graph`."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from hcmt.data.format import Split
from hcmt.graph.batch import Graph
from hcmt.graph.contact import contact_edges, near_pairs, object_ids
from hcmt.graph.edges import cells_to_edges, contact_edge_features, mesh_edge_features
from hcmt.graph.hierarchy import cached_hierarchy
from hcmt.train.adapters import Adapter, exclude_trajectories

SELF_CONTACT_HOPS = 2  # self-contact ignores node pairs this close on the mesh (cloth)


@dataclass
class Trajectory:
    name: str
    static: dict[str, Tensor]  # node_type [N], mesh_pos [N, m], cells, per-node fields ([N, 1])
    world_pos: Tensor  # [T, N, d]
    stress: Tensor | None  # [T, N, 1]
    mesh_edges: Tensor  # [2, E]
    object_id: Tensor  # [N]
    adapter: Adapter
    pool: list[Tensor] = field(default_factory=list)  # λ × [N_{l+1}] into level l
    level_edges: list[Tensor] = field(default_factory=list)  # λ × [2, E_{l+1}]
    level_nodes: list[Tensor] = field(default_factory=list)  # λ × [N_{l+1}] level-0 index of each level node
    self_exclude: np.ndarray | None = None  # pair keys self-contact skips
    attrs: dict = field(default_factory=dict)

    @property
    def num_steps(self) -> int:
        return int(self.world_pos.shape[0])

    @property
    def num_nodes(self) -> int:
        return int(self.world_pos.shape[1])


def prepare_trajectory(fields: dict, name: str, adapter: Adapter, levels: int, remesh: bool = True,
                       cache_dir: str | Path | None = None, attrs: dict | None = None) -> Trajectory:
    """Tensors of one trajectory plus its mesh edges, objects and ``levels``-level hierarchy."""
    node_type = np.asarray(fields["node_type"]).reshape(-1).astype(np.int64)
    cells = np.asarray(fields["cells"]).astype(np.int64)
    n = node_type.shape[0]
    edges = cells_to_edges(cells, n)
    static = {"node_type": torch.from_numpy(node_type),
              "mesh_pos": torch.from_numpy(np.asarray(fields["mesh_pos"], np.float32))}
    for key in adapter.node_fields:
        static[key] = torch.from_numpy(np.asarray(fields[key], np.float32).reshape(n, -1))
    traj = Trajectory(
        name=name, static=static,
        world_pos=torch.from_numpy(np.asarray(fields["world_pos"], np.float32)),
        stress=torch.from_numpy(np.asarray(fields["stress"], np.float32)) if "stress" in fields else None,
        mesh_edges=torch.from_numpy(edges), object_id=torch.from_numpy(object_ids(cells, n)), adapter=adapter,
        attrs=dict(attrs or {}),
    )
    if adapter.self_contact:
        traj.self_exclude = near_pairs(edges, n, SELF_CONTACT_HOPS)
    if levels > 0:
        h = cached_hierarchy(np.asarray(fields["mesh_pos"]), cells, node_type, levels, remesh=remesh,
                             cache_dir=cache_dir)
        traj.pool = [torch.from_numpy(np.asarray(p, np.int64)) for p in h.pool]
        traj.level_edges = [torch.from_numpy(np.asarray(e, np.int64)) for e in h.edges[1:]]
        traj.level_nodes = [torch.from_numpy(np.asarray(v, np.int64)) for v in h.nodes[1:]]
    return traj


def load_split(dataset: str | Path, split: str, adapter: Adapter, levels: int, remesh: bool = True,
               limit: int | None = None, exclude: list[int] | None = None) -> list[Trajectory]:
    """Every (or the first ``limit``) trajectory of a split, prepared. The hierarchy cache lives beside the data."""
    cache = Path(dataset) / ".cache" / "hierarchy"
    with Split(dataset, split) as s:
        idx = exclude_trajectories(s.names, exclude)
        if limit is not None:
            idx = idx[:limit]
        return [prepare_trajectory(s[i], s.names[i], adapter, levels, remesh, cache, s.attrs(i)) for i in idx]


def build_graph(traj: Trajectory, pos: Tensor, node_feats: Tensor, radius: float) -> Graph:
    """The model input for one frame at world positions ``pos`` [N, d] (contact edges found anew)."""
    a = traj.adapter
    mesh_pos = traj.static["mesh_pos"]
    contact = contact_edges(pos.detach(), traj.object_id, radius, node_type=traj.static["node_type"],
                            type_pairs=a.contact_types, self_contact=a.self_contact, exclude=traj.self_exclude)
    contact = torch.as_tensor(contact, dtype=torch.long, device=pos.device)
    return Graph(
        node_features=node_feats,
        mesh_edges=traj.mesh_edges,
        mesh_features=mesh_edge_features(mesh_pos, pos, traj.mesh_edges),
        contact_edges=contact,
        contact_features=contact_edge_features(pos, contact),
        pool=traj.pool,
        level_edges=traj.level_edges,
        level_features=[mesh_edge_features(mesh_pos[v], pos[v], e) for v, e in zip(traj.level_nodes, traj.level_edges)],
    )
