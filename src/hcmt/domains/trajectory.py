"""Trajectories as tensors, with what never changes along them (mesh edges, objects, the hierarchy) built once,
and one frame turned into the model input :class:`~hcmt.graph.batch.Graph` by :func:`hcmt.graph.build.frame_graph`.

:func:`load_split` holds a whole split in memory (validation, rollouts). :class:`SplitReader` is the training path:
it holds the split's index (names, frame and node counts, from the file's shapes), the static fields and hierarchy
of a few trajectories (an LRU; hierarchies memoized on disk) and reads the frames an item needs per item
(:class:`FrameWindow`), so a process's memory does not grow with the split.
"""

from __future__ import annotations

import os
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from hcmt.data.format import Split
from hcmt.domains.adapters import Adapter, exclude_trajectories
from hcmt.errors import DatasetError
from hcmt.graph.batch import Graph
from hcmt.graph.build import frame_graph
from hcmt.graph.hierarchy import Hierarchy, cached_hierarchy, hierarchy_cache_dir


class FrameWindow:
    """Frames ``lo .. lo + len(data) - 1`` of a ``[T, ...]`` field, indexed by absolute frame (``w[t]``) as the
    whole field would be; ``shape`` is the whole field's. A frame outside the window is an ``IndexError``."""

    def __init__(self, data: Tensor, lo: int, total: int):
        self.data, self.lo, self.total = data, int(lo), int(total)

    @property
    def shape(self) -> torch.Size:
        return torch.Size((self.total, *self.data.shape[1:]))

    def __getitem__(self, t: int) -> Tensor:
        k = int(t) - self.lo
        if not 0 <= k < len(self.data):
            raise IndexError(f"frame {t} is outside the frames read, {self.lo}..{self.lo + len(self.data) - 1}")
        return self.data[k]


@dataclass
class Trajectory:
    name: str
    static: dict[str, Tensor]  # node_type [N], mesh_pos [N, m], per-node fields ([N, 1])
    world_pos: Tensor | FrameWindow  # [T, N, d] (a FrameWindow: the frames one training item reads)
    stress: Tensor | FrameWindow | None  # [T, N, 1]
    hierarchy: Hierarchy  # level 0 (mesh edges, objects) and the pooled levels the model uses
    adapter: Adapter
    attrs: dict = field(default_factory=dict)

    @property
    def num_steps(self) -> int:
        return int(self.world_pos.shape[0])

    @property
    def num_nodes(self) -> int:
        return int(self.world_pos.shape[1])


def prepare_static(
    fields: dict,
    adapter: Adapter,
    levels: int,
    remesh: bool = True,
    cache_dir: str | Path | None = None,
    memory: bool = True,
) -> tuple[dict[str, Tensor], Hierarchy]:
    """The static tensors of one trajectory (node_type, mesh_pos, the adapter's node fields) and its
    ``levels``-level hierarchy (:func:`cached_hierarchy`; ``memory=False`` leaves it out of the in-process memo)."""
    node_type = np.asarray(fields["node_type"]).reshape(-1).astype(np.int64)
    n = node_type.shape[0]
    static = {
        "node_type": torch.from_numpy(node_type),
        "mesh_pos": torch.from_numpy(np.asarray(fields["mesh_pos"], np.float32)),
    }
    for key in adapter.node_fields:
        static[key] = torch.from_numpy(np.asarray(fields[key], np.float32).reshape(n, -1))
    hierarchy = cached_hierarchy(
        np.asarray(fields["mesh_pos"]),
        np.asarray(fields["cells"]),
        node_type,
        levels,
        remesh=remesh,
        cache_dir=cache_dir,
        memory=memory,
    )
    return static, hierarchy


def prepare_trajectory(
    fields: dict,
    name: str,
    adapter: Adapter,
    levels: int,
    remesh: bool = True,
    cache_dir: str | Path | None = None,
    attrs: dict | None = None,
) -> Trajectory:
    """Tensors of one trajectory plus its ``levels``-level hierarchy (0: the mesh alone)."""
    static, hierarchy = prepare_static(fields, adapter, levels, remesh, cache_dir)
    return Trajectory(
        name=name,
        static=static,
        world_pos=torch.from_numpy(np.asarray(fields["world_pos"], np.float32)),
        stress=(
            torch.from_numpy(np.asarray(fields[adapter.stress_field], np.float32))
            if adapter.stress_field in fields
            else None
        ),
        hierarchy=hierarchy,
        adapter=adapter,
        attrs=dict(attrs or {}),
    )


def check_split(s: Split, adapter: Adapter) -> None:
    """Refuse a split that lacks the adapter's fields or whose trajectories are too short to train on."""
    needed = ["mesh_pos", "cells", "node_type", "world_pos", *adapter.node_fields]
    needed += [adapter.stress_field] if adapter.stress_output else []
    missing = [f for f in needed if f not in s.meta["features"]]
    if missing:
        raise DatasetError(
            f"the {adapter.name} adapter (the config's `dataset`) needs fields {missing} that this "
            f"dataset lacks; it has {s.meta['field_names']}",
            file=s.path,
            field=missing[0],
        )
    if s.meta["trajectory_length"] and int(s.meta["trajectory_length"]) < adapter.history + 2:
        raise DatasetError(
            f"trajectories of {s.meta['trajectory_length']} frames are too short: training and "
            f"rollout need at least {adapter.history + 2}",
            file=s.path,
        )


def split_indices(s: Split, exclude: list[int] | None, limit: int | None = None) -> np.ndarray:
    """The file indices of the trajectories to use (``exclude`` left out, the first ``limit``); none is an error."""
    idx = exclude_trajectories(s.names, exclude)
    if limit is not None:
        idx = idx[:limit]
    if len(idx) == 0:
        raise DatasetError(f"split {s.split!r} holds no trajectory to use", file=s.path)
    return idx


def load_split(
    dataset: str | Path,
    split: str,
    adapter: Adapter,
    levels: int,
    remesh: bool = True,
    limit: int | None = None,
    exclude: list[int] | None = None,
) -> list[Trajectory]:
    """Every (or the first ``limit``) trajectory of a split, prepared. The hierarchy cache lives beside the data."""
    cache = hierarchy_cache_dir(dataset)
    with Split(dataset, split) as s:
        check_split(s, adapter)
        idx = split_indices(s, exclude, limit)
        return [prepare_trajectory(s[i], s.names[i], adapter, levels, remesh, cache, s.attrs(i)) for i in idx]


class SplitReader:
    """One split's trajectories read per item, for training: memory that does not grow with the split.

    Holds the index (``names``, ``steps`` and ``nodes`` per trajectory, from the file's shapes: no array read at
    construction), the static tensors and hierarchy of the ``keep`` trajectories used last (hierarchies memoized on
    disk in ``DATASET/.cache/hierarchy``), and reads the frames an item needs per item (an HDF5 hyperslab). The
    file is opened lazily in each process (a ``DataLoader`` worker, a DDP rank) and never pickled.
    """

    def __init__(
        self,
        dataset: str | Path,
        split: str,
        adapter: Adapter,
        levels: int,
        remesh: bool = True,
        exclude: list[int] | None = None,
        keep: int = 4,
    ):
        self.dataset, self.split, self.adapter = Path(dataset), split, adapter
        self.levels, self.remesh, self.keep = levels, remesh, max(int(keep), 1)
        with Split(dataset, split) as s:
            check_split(s, adapter)
            self.index = split_indices(s, exclude)
            layouts = [s.layout(int(i)) for i in self.index]
            self.names = [s.names[int(i)] for i in self.index]
            self.stress_field = adapter.stress_field if adapter.stress_field in s.meta["features"] else None
        self.steps = np.asarray([lay["world_pos"][0] for lay in layouts], np.int64)
        self.nodes = np.asarray([lay["world_pos"][1] for lay in layouts], np.int64)
        self._split, self._pid, self._static = None, None, OrderedDict()

    def __len__(self) -> int:
        return len(self.names)

    def __getstate__(self):
        state = dict(self.__dict__)
        state.update(_split=None, _pid=None, _static=OrderedDict())  # each process opens the file itself
        return state

    def _file(self) -> Split:
        if self._pid != os.getpid():  # first use in this process (a forked worker drops its parent's handle)
            self._split, self._pid, self._static = Split(self.dataset, self.split), os.getpid(), OrderedDict()
        return self._split

    def static(self, ti: int) -> Trajectory:
        """Trajectory ``ti`` without frames (``world_pos``/``stress`` empty windows): its static tensors and
        hierarchy, from the LRU or read."""
        if ti in self._static:
            self._static.move_to_end(ti)
            return self._static[ti]
        s = self._file()
        i = int(self.index[ti])
        fields = s.read(i, ["mesh_pos", "cells", "node_type", *self.adapter.node_fields], num_nodes=int(self.nodes[ti]))
        static, hierarchy = prepare_static(
            fields, self.adapter, self.levels, self.remesh, hierarchy_cache_dir(self.dataset), memory=False
        )
        empty = FrameWindow(torch.zeros((0, int(self.nodes[ti]), 0)), 0, int(self.steps[ti]))
        # no attributes: training reads none, and 30 HDF5 attributes cost more than the item (trajectory() reads them)
        tr = Trajectory(self.names[ti], static, empty, empty if self.stress_field else None, hierarchy, self.adapter)
        self._static[ti] = tr
        if len(self._static) > self.keep:
            self._static.popitem(last=False)
        return tr

    def window(self, ti: int, lo: int, hi: int) -> Trajectory:
        """Trajectory ``ti`` with frames ``lo .. hi - 1`` of ``world_pos`` and the stress field read."""
        base = self.static(ti)
        lo, hi = max(int(lo), 0), min(int(hi), int(self.steps[ti]))
        names = ["world_pos"] + ([self.stress_field] if self.stress_field else [])
        got = self._file().read(int(self.index[ti]), names, slice(lo, hi))
        frames = {
            k: FrameWindow(torch.from_numpy(np.asarray(v, np.float32)), lo, int(self.steps[ti])) for k, v in got.items()
        }
        return Trajectory(
            base.name,
            base.static,
            frames["world_pos"],
            frames.get(self.stress_field),
            base.hierarchy,
            self.adapter,
            base.attrs,
        )

    def close(self) -> None:
        """Close this process's file handle and drop the LRU (the next read opens the file again)."""
        if self._split is not None and self._pid == os.getpid():
            self._split.close()
        self._split, self._pid, self._static = None, None, OrderedDict()

    def trajectory(self, ti: int) -> Trajectory:
        """Trajectory ``ti`` with all its frames (as :func:`load_split` gives it)."""
        tr = self.window(ti, 0, int(self.steps[ti]))
        return Trajectory(
            tr.name,
            tr.static,
            tr.world_pos.data,
            tr.stress.data if tr.stress is not None else None,
            tr.hierarchy,
            self.adapter,
            self._file().attrs(int(self.index[ti])),
        )


def build_graph(traj: Trajectory, pos: Tensor, node_feats: Tensor, radius: float) -> Graph:
    """The model input for one frame at world positions ``pos`` [N, d] (contact edges found anew)."""
    a = traj.adapter
    return frame_graph(
        node_feats,
        traj.static["mesh_pos"],
        pos.detach() if pos.requires_grad else pos,
        traj.hierarchy,
        radius,
        a.self_contact,
        node_type=traj.static["node_type"],
        type_pairs=a.contact_types,
        deformation=a.deformation,
    )
