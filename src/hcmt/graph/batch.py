"""The model input: one graph (or several, batched) as plain tensors.

Conventions shared by every model and every graph builder:

* edges are ``[2, E]`` int64 with row 0 the **sender** ``j`` and row 1 the **receiver** ``i``
  (PyTorch Geometric's ``source_to_target``); mesh edges are present in both directions;
* features are **raw** (unnormalized): the models own their input normalizers;
* the hierarchy (paper, "Pooling Method") is given level by level: ``pool[l]`` holds, for level ``l+1``,
  the indices into level ``l``'s nodes of the nodes that level ``l+1`` keeps; ``level_edges[l]`` and
  ``level_features[l]`` are level ``l+1``'s (remeshed) mesh edges, in level ``l+1``'s own node numbering,
  and their raw features (same layout as ``mesh_features``). Level 0 is the mesh itself.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

import torch
from torch import Tensor


@dataclass
class Graph:
    node_features: Tensor  # [N, F_node]
    mesh_edges: Tensor  # [2, E]
    mesh_features: Tensor  # [E, F_mesh]
    contact_edges: Tensor  # [2, C]
    contact_features: Tensor  # [C, F_contact]
    pool: list[Tensor] = field(default_factory=list)  # λ tensors, [N_{l+1}]
    level_edges: list[Tensor] = field(default_factory=list)  # λ tensors, [2, E_{l+1}]
    level_features: list[Tensor] = field(default_factory=list)  # λ tensors, [E_{l+1}, F_mesh]
    batch: Tensor | None = None  # [N] graph index of each node, None for a single graph

    @property
    def num_nodes(self) -> int:
        return int(self.node_features.shape[0])

    @property
    def num_levels(self) -> int:
        return len(self.pool)

    def to(self, device) -> "Graph":
        def move(v):
            if isinstance(v, Tensor):
                return v.to(device)
            if isinstance(v, list):
                return [t.to(device) for t in v]
            return v

        return replace(self, **{f.name: move(getattr(self, f.name)) for f in fields(self)})


def collate(graphs: list[Graph]) -> Graph:
    """Batch graphs into one disconnected graph: node indices of each graph are offset by the nodes before
    it, at every level. All graphs must have the same number of levels."""
    if len(graphs) == 1:
        g = graphs[0]
        return replace(g, batch=torch.zeros(g.num_nodes, dtype=torch.long, device=g.node_features.device))
    levels = {g.num_levels for g in graphs}
    if len(levels) != 1:
        raise ValueError(f"cannot batch graphs with different hierarchy depths {sorted(levels)}")
    (num_levels,) = levels
    # node counts per graph per level: level 0 then each pooled level
    counts = [[g.num_nodes] + [int(p.shape[0]) for p in g.pool] for g in graphs]
    offsets = torch.tensor(counts).cumsum(0) - torch.tensor(counts)  # [B, λ+1]

    def cat_edges(getter, level):
        return torch.cat([getter(g) + int(offsets[b, level]) for b, g in enumerate(graphs)], dim=1)

    return Graph(
        node_features=torch.cat([g.node_features for g in graphs]),
        mesh_edges=cat_edges(lambda g: g.mesh_edges, 0),
        mesh_features=torch.cat([g.mesh_features for g in graphs]),
        contact_edges=cat_edges(lambda g: g.contact_edges, 0),
        contact_features=torch.cat([g.contact_features for g in graphs]),
        pool=[
            torch.cat([g.pool[l] + int(offsets[b, l]) for b, g in enumerate(graphs)]) for l in range(num_levels)
        ],
        level_edges=[cat_edges(lambda g, l=l: g.level_edges[l], l + 1) for l in range(num_levels)],
        level_features=[torch.cat([g.level_features[l] for g in graphs]) for l in range(num_levels)],
        batch=torch.cat([torch.full((g.num_nodes,), b, dtype=torch.long) for b, g in enumerate(graphs)]),
    )
