"""hcmt's native dataset format on disk: a folder with ``meta.json`` and one HDF5 file per split, read and written.

Layout::

    DATASET/
      meta.json          # MeshGraphNets-style schema + dimension, units, node types, generator settings
      train.h5           # one group per trajectory: traj_00000, traj_00001, ...
      valid.h5
      test.h5            # any other split name works too: test_thicker.h5, ...

What ``meta.json`` holds and the checks of a trajectory against it are :mod:`hcmt.data.schema` (its names are
re-exported here: ``from hcmt.data.format import NodeType, make_meta`` works as before). A trajectory's design
parameters are attributes of its group.

Every file is written atomically (a temp file in the same folder, then ``os.replace``), so an interrupted write
never leaves a file that looks complete. Split files carry checksums (HDF5 ``libver="latest"`` object headers and
a Fletcher-32 checksum per dataset chunk): a corrupted byte makes reading fail with one clear line instead of
yielding different data (tests/cli/test_fuzz.py).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Iterable, Mapping

import h5py
import numpy as np

from hcmt.data.schema import (
    _DTYPES as _DTYPES,
    FORMAT_NAME as FORMAT_NAME,
    FORMAT_VERSION as FORMAT_VERSION,
    NODE_TYPE_SIZE as NODE_TYPE_SIZE,
    NodeType as NodeType,
    check_layout as check_layout,
    check_meta as check_meta,
    check_values as check_values,
    make_meta as make_meta,
    validate_trajectory as validate_trajectory,
)
from hcmt.errors import DatasetError
from hcmt.files import atomic_path, ensure_space, lock_holder


def write_meta(dataset_dir: str | os.PathLike, meta: Mapping) -> Path:
    """Write ``meta.json`` atomically."""
    path = Path(dataset_dir) / "meta.json"
    check_meta(meta, path)
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(meta, indent=2, sort_keys=False) + "\n")
    return path


def read_meta(dataset_dir: str | os.PathLike) -> dict:
    path = Path(dataset_dir) / "meta.json"
    if not path.is_file():
        raise DatasetError(
            "not found; a dataset is a folder with meta.json and <split>.h5 files "
            "(make one with `hcmt generate` or `hcmt convert`)",
            file=path,
        )
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DatasetError(f"is not valid JSON ({exc.__class__.__name__}: {str(exc)[:80]})", file=path) from None
    check_meta(meta, path)
    return meta


#: the lock ``hcmt generate`` holds in the dataset folder it writes (:func:`hcmt.files.folder_lock`)
GENERATE_LOCK = ".generate.lock"


def generating(dataset_dir: str | os.PathLike) -> int | None:
    """The pid of the ``hcmt generate`` writing ``dataset_dir`` now, or None when none is."""
    return lock_holder(Path(dataset_dir) / GENERATE_LOCK)


def incomplete(dataset_dir: str | os.PathLike) -> str:
    """What a dataset folder with meta.json but no split file is, and what to do: wait for the ``hcmt generate``
    writing it, or rerun the one that was interrupted."""
    pid = generating(dataset_dir)
    if pid is not None:
        return (
            f"a `hcmt generate` is writing it (pid {pid}): meta.json but no split files yet; wait for it to "
            "finish, or stop it"
        )
    parts = " (an interrupted `hcmt generate` left .parts/)" if (Path(dataset_dir) / ".parts").is_dir() else ""
    return (
        f"incomplete dataset: meta.json but no split files{parts}; rerun the same `hcmt generate` command to finish it"
    )


def list_splits(dataset_dir: str | os.PathLike) -> list[str]:
    """Split names present in a dataset folder, train/valid/test first."""
    names = sorted(p.stem for p in Path(dataset_dir).glob("*.h5"))
    order = {"train": 0, "valid": 1, "test": 2}
    return sorted(names, key=lambda n: (order.get(n, 3), n))


def write_split(
    path: str | os.PathLike,
    meta: Mapping,
    trajectories: Iterable[tuple[str, Mapping[str, np.ndarray], Mapping]],
    compression: str | None = "gzip",
) -> Path:
    """Write one split file atomically; every trajectory is validated against ``meta`` first.

    ``trajectories`` yields ``(name, fields, attrs)``; ``attrs`` (design parameters) become group attributes.
    Nothing is left at ``path`` if any trajectory is refused.
    """
    path = Path(path)
    with atomic_path(path) as tmp:
        # libver="latest": checksummed object headers (attributes, group structure); fletcher32: a checksum per
        # dataset chunk. A corrupted byte then fails to read instead of passing as different, plausible data.
        with h5py.File(tmp, "w", libver="latest") as f:
            f.attrs["format"] = FORMAT_NAME
            f.attrs["version"] = FORMAT_VERSION
            count = 0
            for name, fields, attrs in trajectories:
                arrays = validate_trajectory(meta, fields, file=path, trajectory=name)
                ensure_space(path, sum(v.nbytes for v in arrays.values()))
                g = f.create_group(name)
                for key, value in arrays.items():
                    big = value.size > 4096
                    g.create_dataset(
                        key,
                        data=value,
                        compression=compression if big else None,
                        shuffle=bool(compression and big),
                        fletcher32=value.size > 0,
                        chunks=frame_chunks(meta, key, value.shape),
                    )
                for key, value in (attrs or {}).items():
                    g.attrs[key] = value
                count += 1
            f.attrs["num_trajectories"] = count
    return path


def frame_chunks(meta: Mapping, name: str, shape: tuple) -> tuple | None:
    """HDF5 chunks of one frame for a dynamic field (training reads a few frames of a trajectory per item: only
    their chunks are read and decompressed); None (h5py's choice) for static fields. Files written before this
    read the same, a frame at a time from larger chunks."""
    if meta["features"][name]["type"] != "dynamic" or len(shape) < 2 or 0 in shape:
        return None
    return (1, *shape[1:])


class Split:
    """Read-only access to one split of a native dataset.

    ``split[i]`` returns the trajectory's fields as a dict of numpy arrays, validated against meta.json;
    ``split.attrs(i)`` its design parameters; ``split.names`` the trajectory group names in file order.
    """

    def __init__(self, dataset_dir: str | os.PathLike, split: str, meta: Mapping | None = None):
        self.dataset_dir = Path(dataset_dir)
        self.meta = dict(meta) if meta is not None else read_meta(dataset_dir)
        self.path = self.dataset_dir / f"{split}.h5"
        self.split = split
        if not self.path.is_file():
            available = list_splits(self.dataset_dir)
            if not available:
                raise DatasetError(incomplete(self.dataset_dir), file=self.dataset_dir)
            pid = generating(self.dataset_dir)
            busy = "" if pid is None else f"; a `hcmt generate` is writing this dataset (pid {pid}): wait for it"
            raise DatasetError(f"split {split!r} not found; available: {available}{busy}", file=self.path)
        try:
            self._file = h5py.File(self.path, "r")
            self.names = sorted(self._file.keys())
        except (OSError, KeyError, RuntimeError, ValueError) as exc:
            raise DatasetError(f"cannot be read as HDF5 (truncated or corrupt?): {exc}", file=self.path) from None

    def __len__(self) -> int:
        return len(self.names)

    def __getitem__(self, i: int) -> dict[str, np.ndarray]:
        name = self.names[i]
        try:
            group = self._file[name]
            fields = {k: group[k][()] for k in group.keys()}
        except (OSError, KeyError, RuntimeError) as exc:
            raise DatasetError(
                f"cannot be read (truncated or corrupt file?): {exc}", file=self.path, trajectory=name
            ) from None
        return validate_trajectory(self.meta, fields, file=self.path, trajectory=name)

    def __iter__(self):
        return (self[i] for i in range(len(self)))

    def layout(self, i: int) -> dict[str, tuple[int, ...]]:
        """The shapes of trajectory ``i``'s fields from the file's metadata, no array read; checked against
        meta.json as :func:`validate_trajectory` checks them (rank, dimensions, dtype kind, node count)."""
        name = self.names[i]
        try:
            group = self._file[name]
            shapes = {k: (group[k].shape, group[k].dtype) for k in group.keys()}
        except (OSError, KeyError, RuntimeError) as exc:
            raise DatasetError(
                f"cannot be read (truncated or corrupt file?): {exc}", file=self.path, trajectory=name
            ) from None
        check_layout(self.meta, shapes, file=self.path, trajectory=name)
        return {k: tuple(shape) for k, (shape, _) in shapes.items()}

    def read(
        self, i: int, fields: Iterable[str], frames: slice | None = None, num_nodes: int | None = None
    ) -> dict[str, np.ndarray]:
        """Some fields of trajectory ``i``, value-checked (:func:`check_values`; ``num_nodes`` from
        :meth:`layout` for the cell indices' range), dynamic ones only at ``frames`` (an HDF5 hyperslab: only
        those frames' chunks are read)."""
        name, out = self.names[i], {}
        for key in fields:
            dynamic = self.meta["features"][key]["type"] == "dynamic"
            try:
                data = self._file[name][key]
                out[key] = data[frames] if dynamic and frames is not None else data[()]
            except (OSError, KeyError, RuntimeError, ValueError) as exc:
                raise DatasetError(
                    f"cannot be read (truncated or corrupt file?): {exc}", file=self.path, trajectory=name, field=key
                ) from None
        return check_values(self.meta, out, file=self.path, trajectory=name, num_nodes=num_nodes)

    def attrs(self, i: int) -> dict:
        try:
            items = self._file[self.names[i]].attrs.items()
            return {k: (v.item() if hasattr(v, "item") else v) for k, v in items}
        except (OSError, KeyError, RuntimeError) as exc:
            raise DatasetError(
                f"attributes cannot be read (corrupt file?): {exc}", file=self.path, trajectory=self.names[i]
            ) from None

    def num_nodes(self, i: int) -> int:
        try:
            return int(self._file[self.names[i]]["mesh_pos"].shape[0])
        except (OSError, KeyError, RuntimeError) as exc:
            raise DatasetError(
                f"cannot be read (corrupt file?): {exc}", file=self.path, trajectory=self.names[i], field="mesh_pos"
            ) from None

    def close(self) -> None:
        self._file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class NativeDataset:
    """A native dataset folder: ``meta`` (meta.json), ``splits`` (names), ``ds["train"]`` a :class:`Split` (items are
    validated trajectories: ``ds["train"][0]["world_pos"]`` ``[T, N, d]``)."""

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        self.meta = read_meta(self.path)
        self.splits = list_splits(self.path)

    def __getitem__(self, split: str) -> Split:
        return Split(self.path, split, self.meta)

    def __repr__(self) -> str:
        return f"NativeDataset({str(self.path)!r}, splits={self.splits})"


def load_dataset(path: str | os.PathLike) -> NativeDataset:
    """Open a native dataset folder (meta.json checked; splits read on access)."""
    return NativeDataset(path)


def open_split(dataset_dir: str | os.PathLike, split: str) -> Split:
    return Split(dataset_dir, split)
