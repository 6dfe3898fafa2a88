"""What the pictures show: one trajectory's ground truth beside the rollouts of one or more runs.

A run's predictions live in ``RUN/rollout_<split>.h5`` (one group per trajectory, written by
:func:`hcmt.inference.rollout_files.run_rollouts`); when that file is missing, or lacks the trajectory asked for, it is
rolled out first. Every series is checked against the dataset (node count, dimension, frame count) so a rollout of
another dataset is refused rather than drawn on the wrong mesh.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from hcmt.data.format import Split, read_meta
from hcmt.data.runs import RunFolder
from hcmt.errors import DatasetError, InputError
from hcmt.graph.contact import object_ids
from hcmt.inference.rollout_files import rollout_file
from hcmt.inference.run import Run, model_label


@dataclass
class Series:
    """One source of a trajectory: the ground truth or a run's rollout."""

    label: str  # "Ground truth", "HCMT", "MGN (run_b)"
    world_pos: np.ndarray  # [T, N, d]
    stress: np.ndarray | None  # [T, N, 1]
    start: int = 0  # first predicted frame (frames before it are the data's)
    run: Path | None = None


@dataclass
class Case:
    """One trajectory of a split: its mesh, the ground truth and the predictions."""

    name: str
    mesh_pos: np.ndarray  # [N, m]
    cells: np.ndarray  # [C, 3|4]
    node_type: np.ndarray  # [N]
    truth: Series
    predictions: list[Series] = field(default_factory=list)
    meta: dict = field(default_factory=dict)
    fields: dict = field(default_factory=dict)  # the trajectory's other per-node fields (density, ...)

    @property
    def num_frames(self) -> int:
        return int(self.truth.world_pos.shape[0])

    @property
    def dim(self) -> int:
        return int(self.truth.world_pos.shape[-1])

    @property
    def object_id(self) -> np.ndarray:
        return object_ids(self.cells, len(self.node_type))

    @property
    def series(self) -> list[Series]:
        return [self.truth, *self.predictions]

    @property
    def has_stress(self) -> bool:
        return self.truth.stress is not None

    def unit(self, quantity: str) -> str | None:
        """The unit meta.json records for ``quantity`` (``length``, ``time``, ``stress``), or None."""
        return (self.meta.get("units") or {}).get(quantity)

    def time_label(self, frame: int, last: int | None = None) -> str:
        """``frame 25`` (``frame 25 of 51`` with ``last``) plus its time when meta.json records ``dt``:
        ``frame 25, t = 0.1 ms``."""
        text = f"frame {frame}" + (f" of {last}" if last is not None else "")
        dt = self.meta.get("dt")
        if not dt:
            return text
        unit = self.unit("time")
        return f"{text}, t = {frame * float(dt):.3g}" + (f" {unit}" if unit else "")


def quantity_label(name: str, unit: str | None) -> str:
    """Axis or colour-bar label with its unit: ``von Mises stress [MPa]``; says so when the unit is unknown."""
    return f"{name} [{unit}]" if unit else f"{name} (unit not in meta.json)"


def unique_labels(runs: list[Run | RunFolder]) -> list[str]:
    """Run labels, with the run folder's name added where two runs would otherwise share one."""
    labels = [r.label if isinstance(r, Run) else model_label(r.info["model"], r.info.get("config")) for r in runs]
    return [f"{lab} ({Path(r.source).name})" if labels.count(lab) > 1 else lab for lab, r in zip(labels, runs)]


def trajectory_index(names: list[str], trajectory: int | str) -> int:
    """Position of a trajectory given by index (``0``, ``-1``) or by name (``traj_00003``)."""
    if isinstance(trajectory, str) and not trajectory.removeprefix("-").isdigit():
        if trajectory not in names:
            raise InputError(
                f"trajectory {trajectory!r} is not in the split; it has {names[:5]}"
                + (" ..." if len(names) > 5 else "")
            )
        return names.index(trajectory)
    i = int(trajectory)
    if not -len(names) <= i < len(names):
        raise InputError(f"trajectory index {i} out of range; the split has {len(names)} trajectories")
    return i % len(names)


def read_series(path: Path, name: str, label: str, truth: Series, run: Path | None = None) -> Series:
    with h5py.File(path, "r") as f:
        if name not in f:
            raise DatasetError(f"no trajectory {name!r}; it holds {sorted(f.keys())[:5]}", file=path)
        g = f[name]
        pos = g["world_pos"][()]
        stress = g["stress"][()] if "stress" in g else None
        start = int(g.attrs.get("start", 1))
    if pos.shape != truth.world_pos.shape:
        raise DatasetError(
            f"world_pos shape {list(pos.shape)} differs from the dataset's "
            f"{list(truth.world_pos.shape)}; was it rolled out on another dataset?",
            file=path,
            trajectory=name,
            field="world_pos",
        )
    if stress is not None and truth.stress is not None and stress.shape != truth.stress.shape:
        raise DatasetError(
            f"stress shape {list(stress.shape)} differs from the dataset's {list(truth.stress.shape)}",
            file=path,
            trajectory=name,
            field="stress",
        )
    return Series(label, pos, stress, start, run)


def load_case(
    runs: list[Run | RunFolder],
    data: str | Path,
    split: str = "test",
    trajectory: int | str = 0,
    labels: list[str] | None = None,
    *,
    progress: bool = True,
) -> Case:
    """The ground truth of one trajectory and every run's rollout of it (rolled out when missing, by the one cache
    rule :func:`hcmt.inference.rollout_files.rollout_for`; a bare :class:`RunFolder`'s file as it is)."""
    meta = read_meta(data)
    with Split(data, split, meta) as s:
        index = trajectory_index(s.names, trajectory)
        name = s.names[index]
        fields = s[index]
    truth = Series("Ground truth", fields["world_pos"], fields.get("stress"))
    case = Case(
        name=name,
        mesh_pos=fields["mesh_pos"],
        cells=fields["cells"].astype(np.int64),
        node_type=fields["node_type"].reshape(-1).astype(np.int64),
        truth=truth,
        meta=meta,
        fields={k: v for k, v in fields.items() if k not in ("world_pos", "stress", "mesh_pos", "cells")},
    )
    labels = labels or (unique_labels(runs) if runs else [])
    for run, label in zip(runs, labels):
        path = rollout_file(run, data, split, need=index + 1, progress=progress)
        case.predictions.append(read_series(path, name, label, truth, Path(run.source)))
    return case
