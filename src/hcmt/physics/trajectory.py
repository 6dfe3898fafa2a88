"""Trajectories as tensors, with what never changes along them (mesh edges, objects, the hierarchy) built once,
and one frame turned into the model input :class:`~hcmt.graph.batch.Graph` by :func:`hcmt.graph.build.frame_graph`."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from hcmt.data.format import Split
from hcmt.errors import DatasetError
from hcmt.graph.batch import Graph
from hcmt.graph.build import frame_graph
from hcmt.graph.hierarchy import Hierarchy, cached_hierarchy, hierarchy_cache_dir
from hcmt.physics.adapters import Adapter, exclude_trajectories


@dataclass
class Trajectory:
    name: str
    static: dict[str, Tensor]  # node_type [N], mesh_pos [N, m], per-node fields ([N, 1])
    world_pos: Tensor  # [T, N, d]
    stress: Tensor | None  # [T, N, 1]
    hierarchy: Hierarchy  # level 0 (mesh edges, objects) and the pooled levels the model uses
    adapter: Adapter
    attrs: dict = field(default_factory=dict)

    @property
    def num_steps(self) -> int:
        return int(self.world_pos.shape[0])

    @property
    def num_nodes(self) -> int:
        return int(self.world_pos.shape[1])


def prepare_trajectory(fields: dict, name: str, adapter: Adapter, levels: int, remesh: bool = True,
                       cache_dir: str | Path | None = None, attrs: dict | None = None) -> Trajectory:
    """Tensors of one trajectory plus its ``levels``-level hierarchy (0: the mesh alone)."""
    node_type = np.asarray(fields["node_type"]).reshape(-1).astype(np.int64)
    n = node_type.shape[0]
    static = {"node_type": torch.from_numpy(node_type),
              "mesh_pos": torch.from_numpy(np.asarray(fields["mesh_pos"], np.float32))}
    for key in adapter.node_fields:
        static[key] = torch.from_numpy(np.asarray(fields[key], np.float32).reshape(n, -1))
    hierarchy = cached_hierarchy(np.asarray(fields["mesh_pos"]), np.asarray(fields["cells"]), node_type, levels,
                                 remesh=remesh, cache_dir=cache_dir)
    return Trajectory(
        name=name, static=static,
        world_pos=torch.from_numpy(np.asarray(fields["world_pos"], np.float32)),
        stress=(torch.from_numpy(np.asarray(fields[adapter.stress_field], np.float32))
                if adapter.stress_field in fields else None),
        hierarchy=hierarchy, adapter=adapter, attrs=dict(attrs or {}),
    )


def load_split(dataset: str | Path, split: str, adapter: Adapter, levels: int, remesh: bool = True,
               limit: int | None = None, exclude: list[int] | None = None) -> list[Trajectory]:
    """Every (or the first ``limit``) trajectory of a split, prepared. The hierarchy cache lives beside the data."""
    cache = hierarchy_cache_dir(dataset)
    with Split(dataset, split) as s:
        needed = ["mesh_pos", "cells", "node_type", "world_pos", *adapter.node_fields]
        needed += [adapter.stress_field] if adapter.stress_output else []
        missing = [f for f in needed if f not in s.meta["features"]]
        if missing:
            raise DatasetError(f"the {adapter.name} adapter (the config's `dataset`) needs fields {missing} that this "
                               f"dataset lacks; it has {s.meta['field_names']}", file=s.path, field=missing[0])
        if s.meta["trajectory_length"] and int(s.meta["trajectory_length"]) < adapter.history + 2:
            raise DatasetError(f"trajectories of {s.meta['trajectory_length']} frames are too short: training and "
                               f"rollout need at least {adapter.history + 2}", file=s.path)
        idx = exclude_trajectories(s.names, exclude)
        if limit is not None:
            idx = idx[:limit]
        if len(idx) == 0:
            raise DatasetError(f"split {split!r} holds no trajectory to use", file=s.path)
        return [prepare_trajectory(s[i], s.names[i], adapter, levels, remesh, cache, s.attrs(i)) for i in idx]


def build_graph(traj: Trajectory, pos: Tensor, node_feats: Tensor, radius: float) -> Graph:
    """The model input for one frame at world positions ``pos`` [N, d] (contact edges found anew)."""
    a = traj.adapter
    return frame_graph(node_feats, traj.static["mesh_pos"], pos.detach() if pos.requires_grad else pos,
                       traj.hierarchy, radius, a.self_contact, node_type=traj.static["node_type"],
                       type_pairs=a.contact_types, deformation=a.deformation)
