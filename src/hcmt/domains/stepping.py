"""A batch of trajectories set up once for a rollout on the model's device, and each step's input built from it
for all of them at once.

:func:`frame_batch` merges what never changes along the rollout (:func:`hcmt.graph.build.merge_static`: mesh edges
and their mesh-space features, the hierarchy, objects, node types; the adapter's static node fields) and the data's
positions of every frame (the history frames and the positions boundary conditions prescribe), on one device.
:func:`batch_input` is :func:`hcmt.domains.frames.input_graph` of every trajectory, collated, from their
concatenated positions ``[N, d]``: node features and integration are node-local, so they run on concatenated
tensors as they are.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor

from hcmt.domains.adapters import Adapter, node_features
from hcmt.domains.trajectory import FrameWindow, Trajectory
from hcmt.errors import InputError
from hcmt.graph.batch import Graph
from hcmt.graph.build import MergedStatic, merge_static, merged_graph


@dataclass
class FrameBatch:
    """Trajectories rolled out together, merged on one device (:func:`frame_batch`)."""

    adapter: Adapter  # the trajectories' own: node inputs and contact rules (:func:`batch_input`)
    names: list[str]
    sizes: list[int]  # nodes of each trajectory
    static: dict[str, Tensor]  # node_type, mesh_pos and the adapter's node fields, concatenated
    graph: MergedStatic
    world_pos: Tensor  # [T, N, d] the data's positions of the frames rolled out
    stress: Tensor | None  # [T, N, 1] the data's stress (zeros for a trajectory without), None if none has it
    has_stress: list[bool]  # which trajectories have a stress field

    @property
    def batch(self) -> Tensor:
        """``[N]`` the trajectory of every node."""
        return self.graph.batch


def frames_of(field: Tensor | FrameWindow, count: int) -> Tensor:
    """Frames ``0 .. count - 1`` of a ``[T, ...]`` field as one tensor."""
    if isinstance(field, FrameWindow):
        return torch.stack([field[i] for i in range(count)])
    return field[:count]


def frame_batch(trajs: list[Trajectory], frames: int, device) -> FrameBatch:
    """``trajs`` (one adapter, one hierarchy depth) merged on ``device`` for a rollout over their first ``frames``
    frames."""
    adapters = {tr.adapter for tr in trajs}
    if len(adapters) != 1:
        raise InputError("trajectories of different dataset adapters cannot roll out in one batch")
    (adapter,) = adapters
    keys = ["node_type", "mesh_pos", *adapter.node_fields]
    static = {k: torch.cat([tr.static[k] for tr in trajs]).to(device) for k in keys}
    world = torch.cat([frames_of(tr.world_pos, frames) for tr in trajs], dim=1).to(device)
    graph = merge_static(
        [tr.hierarchy for tr in trajs],
        [tr.static["mesh_pos"] for tr in trajs],
        [tr.static["node_type"] for tr in trajs],
        device,
        world.dtype,
        adapter.self_contact,
    )
    has = [tr.stress is not None for tr in trajs]
    stress = None
    if any(has):
        parts = [
            frames_of(tr.stress, frames)
            if tr.stress is not None
            else torch.zeros((frames, tr.num_nodes, 1), dtype=world.dtype)
            for tr in trajs
        ]
        stress = torch.cat(parts, dim=1).to(device)
    return FrameBatch(
        adapter, [tr.name for tr in trajs], [tr.num_nodes for tr in trajs], static, graph, world, stress, has
    )


def batch_input(fb: FrameBatch, pos: Tensor, prev: Tensor, next_prescribed: Tensor, radius: float) -> Graph:
    """The model input of every trajectory at positions ``pos`` ``[N, d]`` (``prev``: ``x^{t-1}``;
    ``next_prescribed``: the data's ``x^{t+1}``), collated: :func:`hcmt.domains.frames.input_graph` of each."""
    a = fb.adapter
    feats = node_features(a, fb.static, pos, prev, next_prescribed)
    return merged_graph(
        fb.graph, feats, pos, radius, a.self_contact, type_pairs=a.contact_types, deformation=a.deformation
    )
