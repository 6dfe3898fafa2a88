"""One frame of a trajectory -> the model input :class:`~hcmt.graph.batch.Graph` (paper, "Encoder": ``G_0 = (V_0,
E_0, C)`` and the pooled levels ``G_1 .. G_lambda`` of the HMT layer).

Static parts (mesh edges, hierarchy, objects) are built once per trajectory; per frame only the world-space edge
features and the contact edges are computed. Features follow :mod:`hcmt.graph.edges` (relative vectors are
sender minus receiver). A coarse level's edge features use the positions of its nodes, found through the
level-0 index of each level node (``hierarchy.nodes``): ``m_ij`` at level ``l`` is built from
``mesh_pos[nodes[l]]`` and ``world_pos[nodes[l]]``. The mesh-space half of the coarse levels' features is static
and computed once per hierarchy (recomputed if other mesh positions are passed).

Rollouts of a batch of designs merge the static parts once (:func:`merge_static`: every level's indices offset by the
designs before, objects kept apart, a ``batch`` vector), and :func:`merged_graph` builds each step's graph of all the
designs at once from their concatenated positions, on their device: the graph :func:`~hcmt.graph.batch.collate`
makes of the designs' :func:`frame_graph` graphs (tests/inference/test_rollout_engine.py).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable

import numpy as np
import torch
from torch import Tensor

from hcmt.errors import InputError
from hcmt.graph.batch import Graph
from hcmt.graph.contact import contact_edges, near_pairs
from hcmt.graph.edges import contact_edge_features, relative
from hcmt.graph.hierarchy import Hierarchy


def hierarchy_tensors(hierarchy: Hierarchy, device) -> dict:
    """``pool``, ``edges``, ``nodes`` (and ``edges_level0``: each level's edges in level-0 numbers) of a hierarchy
    as int64 tensors on ``device``, cached on the hierarchy."""
    key = str(torch.device(device))
    cached = hierarchy._tensors.get(key)
    if cached is None:
        cached = {
            name: [torch.as_tensor(a, dtype=torch.long).to(device) for a in getattr(hierarchy, name)]
            for name in ("pool", "edges", "nodes")
        }
        cached["object_id"] = torch.as_tensor(hierarchy.object_id, dtype=torch.long).to(device)
        # every level's edges in level-0 node numbers: features gather level-0 positions directly
        cached["edges_level0"] = [
            torch.as_tensor(n[e], dtype=torch.long).to(device) for n, e in zip(hierarchy.nodes, hierarchy.edges)
        ]
        hierarchy._tensors[key] = cached
    return cached


def frame_graph(
    node_features: Tensor,
    mesh_pos: Tensor,
    world_pos: Tensor,
    hierarchy: Hierarchy,
    radius: float,
    self_contact: bool = False,
    *,
    node_type: Tensor | None = None,
    type_pairs: Iterable[tuple[int, int]] | None = None,
    self_contact_hops: int = 3,
    exclude: Tensor | None = None,
    contact_method: str = "auto",
    deformation: bool = False,
) -> Graph:
    """The graph of one frame: the hierarchy's mesh edges and objects, contact edges found at ``world_pos``.

    ``node_features`` ``[N, F]`` (raw), ``mesh_pos`` ``[N, d_mesh]``, ``world_pos`` ``[N, d_world]``;
    ``radius`` the contact radius gamma. Contact rules (``type_pairs``; ``self_contact``, which
    excludes the pairs within ``self_contact_hops`` hops of the hierarchy's mesh edges unless ``exclude`` keys
    are given) as in :func:`hcmt.graph.contact.contact_edges`. All tensors end up on ``world_pos``'s device.
    ``deformation`` appends :func:`deformation_features` to every level's edge features (``model.deformation``).
    """
    device = world_pos.device
    h = hierarchy_tensors(hierarchy, device)
    mesh_pos = mesh_pos.to(device=device, dtype=world_pos.dtype)
    mesh_edges, object_id = h["edges"][0], h["object_id"]
    if self_contact and exclude is None:
        key = f"near_{self_contact_hops}"
        if key not in h:  # static: computed once per hierarchy and device
            h[key] = torch.from_numpy(near_pairs(hierarchy.edges[0], hierarchy.num_nodes(0), self_contact_hops)).to(
                device
            )
        exclude = h[key]
    contacts = contact_edges(
        world_pos,
        object_id,
        radius,
        node_type=node_type,
        type_pairs=type_pairs,
        self_contact=self_contact,
        exclude=exclude,
        method=contact_method,
    )
    mesh_part = _mesh_space_features(h, mesh_pos)
    world_part = [relative(world_pos, e) for e in h["edges_level0"][1:]]
    mesh_features = _edge_features(mesh_part[0], relative(world_pos, mesh_edges), deformation)
    return Graph(
        node_features=node_features.to(device),
        mesh_edges=mesh_edges,
        mesh_features=mesh_features,
        contact_edges=contacts,
        contact_features=contact_edge_features(world_pos, contacts),
        pool=list(h["pool"]),
        level_edges=list(h["edges"][1:]),
        level_features=[_edge_features(u, x, deformation) for u, x in zip(mesh_part[1:], world_part)],
    )


def deformation_features(mesh_part: Tensor, world_part: Tensor) -> Tensor:
    """``[x_ij − u_ij, |x_ij| − |u_ij|]`` ``[E, d + 1]`` from ``[u_ij, |u_ij|]`` and ``[x_ij, |x_ij|]``: the edge's
    deformation and its stretch, zero at rest. hcmt's option ``model.deformation`` (not in the paper): in ``x_ij``
    and ``u_ij`` alone a plate's bending strain (1e-4 of an edge's length) is a difference of two inputs each
    normalized to O(1), which the encoder must learn to resolve; given explicitly, the normalizer scales it to O(1)
    so the restoring force of a deflected plate can be read directly."""
    if mesh_part.shape[-1] != world_part.shape[-1]:
        raise InputError("model.deformation needs mesh and world spaces of one dimension (not cloth)")
    return world_part - mesh_part


def _edge_features(mesh_part: Tensor, world_part: Tensor, deformation: bool) -> Tensor:
    parts = [mesh_part, world_part] + ([deformation_features(mesh_part, world_part)] if deformation else [])
    return torch.cat(parts, dim=-1)


def _mesh_space_features(h: dict, mesh_pos: Tensor) -> list[Tensor]:
    """``[u_ij, |u_ij|]`` of every level (0..lambda); static, so cached with the mesh positions they came from."""
    cached = h.get("mesh_part")
    if cached is None or cached[0].dtype != mesh_pos.dtype or not torch.equal(cached[0], mesh_pos):
        cached = (mesh_pos, [relative(mesh_pos, e) for e in h["edges_level0"]])
        h["mesh_part"] = cached
    return cached[1]


@dataclass
class MergedStatic:
    """What never changes along a rollout of a batch of designs, merged as :func:`~hcmt.graph.batch.collate` merges
    their graphs (level-``l`` indices offset by the level-``l`` nodes of the designs before), on one device."""

    sizes: list[int]  # level-0 nodes of each design
    batch: Tensor  # [N] the design of every node
    object_id: Tensor  # [N] objects, numbered apart across designs
    node_type: Tensor  # [N]
    mesh_edges: Tensor  # [2, E]
    pool: list[Tensor]  # λ tensors: per level, the kept nodes' indices into the level below
    level_edges: list[Tensor]  # λ tensors: level l+1's edges in its own numbering
    edges_level0: list[Tensor]  # λ+1 tensors: every level's edges in level-0 numbers (level 0: the mesh edges)
    mesh_part: list[Tensor]  # λ+1 tensors: [u_ij, |u_ij|] of every level's edges
    exclude: Tensor | None  # self-contact: the pair keys a * N + b close on the mesh (sorted), else None

    def counts(self) -> tuple[int, int, list[tuple[int, int]]]:
        """``(nodes, mesh edges, [(level nodes, level edges), ...])`` of the merged graph, as
        :meth:`hcmt.graph.batch.PadSizes.fit` takes them."""
        return (
            sum(self.sizes),
            int(self.mesh_edges.shape[1]),
            [(int(p.shape[0]), int(e.shape[1])) for p, e in zip(self.pool, self.level_edges)],
        )


def merge_static(
    hierarchies: list[Hierarchy],
    mesh_pos: list[Tensor],
    node_type: list[Tensor],
    device,
    dtype: torch.dtype = torch.float32,
    self_contact: bool = False,
    self_contact_hops: int = 3,
) -> MergedStatic:
    """The static graph of several designs (their hierarchies, mesh positions ``[N_b, d_mesh]`` and node types),
    merged once on ``device``; mesh-space features in ``dtype`` (the world positions')."""
    levels = {h.levels for h in hierarchies}
    if len(levels) != 1:
        raise InputError(f"cannot batch graphs with different hierarchy depths {sorted(levels)}")
    counts = np.array([[h.num_nodes(l) for l in range(h.levels + 1)] for h in hierarchies], np.int64)
    offsets = np.cumsum(counts, 0) - counts  # [B, λ+1]
    total = int(counts[:, 0].sum())

    def cat(arrays) -> Tensor:
        return torch.from_numpy(np.concatenate([np.asarray(a, np.int64) for a in arrays], -1)).to(device)

    objects = np.cumsum([0] + [int(h.object_id.max()) + 1 if len(h.object_id) else 0 for h in hierarchies])
    (lam,) = levels
    edges0 = [cat([h.nodes[l][h.edges[l]] + offsets[b, 0] for b, h in enumerate(hierarchies)]) for l in range(lam + 1)]
    pos = torch.cat([m.to(dtype) for m in mesh_pos]).to(device)
    exclude = None
    if self_contact:  # each design's near pairs, keyed in the merged numbering
        keys = []
        for b, h in enumerate(hierarchies):
            n, o = h.num_nodes(0), int(offsets[b, 0])
            k = near_pairs(h.edges[0], n, self_contact_hops)
            keys.append((k // n + o) * total + k % n + o)
        exclude = cat(keys)
    return MergedStatic(
        sizes=counts[:, 0].tolist(),
        batch=cat([np.full(int(c), b) for b, c in enumerate(counts[:, 0])]),
        object_id=cat([h.object_id + objects[b] for b, h in enumerate(hierarchies)]),
        node_type=torch.cat([t.reshape(-1).long() for t in node_type]).to(device),
        mesh_edges=edges0[0],
        pool=[cat([h.pool[l] + offsets[b, l] for b, h in enumerate(hierarchies)]) for l in range(lam)],
        level_edges=[cat([h.edges[l + 1] + offsets[b, l + 1] for b, h in enumerate(hierarchies)]) for l in range(lam)],
        edges_level0=edges0,
        mesh_part=[relative(pos, e) for e in edges0],
        exclude=exclude,
    )


def merged_graph(
    static: MergedStatic,
    node_features: Tensor,
    world_pos: Tensor,
    radius: float,
    self_contact: bool = False,
    *,
    type_pairs: Iterable[tuple[int, int]] | None = None,
    contact_method: str = "auto",
    deformation: bool = False,
) -> Graph:
    """The graph of every design of ``static`` at their concatenated world positions ``[N, d]`` (node features
    ``[N, F]``): :func:`frame_graph` of each design, collated, in one pass on ``world_pos``'s device. Contact edges
    never join two designs (``batch``)."""
    several = len(static.sizes) > 1
    contacts = contact_edges(
        world_pos,
        static.object_id,
        radius,
        node_type=static.node_type,
        type_pairs=type_pairs,
        self_contact=self_contact,
        exclude=static.exclude,
        method=contact_method,
        batch=static.batch if several else None,
    )
    world = [relative(world_pos, e) for e in static.edges_level0]
    features = [_edge_features(u, x, deformation) for u, x in zip(static.mesh_part, world)]
    return Graph(
        node_features=node_features,
        mesh_edges=static.mesh_edges,
        mesh_features=features[0],
        contact_edges=contacts,
        contact_features=contact_edge_features(world_pos, contacts),
        pool=list(static.pool),
        level_edges=list(static.level_edges),
        level_features=features[1:],
        batch=static.batch,
    )
