"""One frame of a trajectory -> the model input :class:`~hcmt.graph.batch.Graph` (paper, "Encoder": ``G_0 = (V_0,
E_0, C)`` and the pooled levels ``G_1 .. G_lambda`` of the HMT layer).

Static parts (mesh edges, hierarchy, objects) are built once per trajectory; per frame only the world-space edge
features and the contact edges are computed. Features follow :mod:`hcmt.graph.edges` (relative vectors are
sender minus receiver). A coarse level's edge features use the positions of its nodes, found through the
level-0 index of each level node (``hierarchy.nodes``): ``m_ij`` at level ``l`` is built from
``mesh_pos[nodes[l]]`` and ``world_pos[nodes[l]]``. The mesh-space half of the coarse levels' features is static
and computed once per hierarchy (recomputed if other mesh positions are passed).
"""
from __future__ import annotations

from typing import Iterable

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
        cached = {name: [torch.as_tensor(a, dtype=torch.long).to(device) for a in getattr(hierarchy, name)]
                  for name in ("pool", "edges", "nodes")}
        cached["object_id"] = torch.as_tensor(hierarchy.object_id, dtype=torch.long).to(device)
        # every level's edges in level-0 node numbers: features gather level-0 positions directly
        cached["edges_level0"] = [torch.as_tensor(n[e], dtype=torch.long).to(device)
                                  for n, e in zip(hierarchy.nodes, hierarchy.edges)]
        hierarchy._tensors[key] = cached
    return cached


def frame_graph(node_features: Tensor, mesh_pos: Tensor, world_pos: Tensor, hierarchy: Hierarchy, radius: float,
                self_contact: bool = False, *, node_type: Tensor | None = None,
                type_pairs: Iterable[tuple[int, int]] | None = None, self_contact_hops: int = 3,
                exclude: Tensor | None = None, contact_method: str = "auto", deformation: bool = False) -> Graph:
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
            h[key] = torch.from_numpy(near_pairs(hierarchy.edges[0], hierarchy.num_nodes(0),
                                                 self_contact_hops)).to(device)
        exclude = h[key]
    contacts = contact_edges(world_pos, object_id, radius, node_type=node_type, type_pairs=type_pairs,
                             self_contact=self_contact, exclude=exclude, method=contact_method)
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
