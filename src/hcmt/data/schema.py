"""The schema of hcmt's native dataset format: what ``meta.json`` says and what a trajectory must be to match it.

``meta.json`` follows the MeshGraphNets convention: ``field_names`` and, per field in ``features``, ``type``
(``static`` | ``dynamic``), ``dtype`` and ``shape`` with -1 for a node or cell count. Static fields are stored once,
without a time axis (``mesh_pos`` [N,d], ``cells`` [C,3|4], ``node_type`` [N,1]); dynamic fields carry one
(``world_pos`` [T,N,d], ``stress`` [T,N,1]). Trajectories may differ in node count.

No file is read or written here: the checks are shared by reading and writing (:mod:`hcmt.data.format`, which
re-exports every name of this module), so one definition of a valid dataset serves both.
"""

from __future__ import annotations

import enum
import os
from typing import Mapping

import numpy as np

from hcmt.errors import DatasetError

FORMAT_NAME = "hcmt-dataset"
FORMAT_VERSION = 1


class NodeType(enum.IntEnum):
    """MeshGraphNets' node-type enum plus SYMMETRIC as in the official HCMT Impact Plate data."""

    NORMAL = 0
    OBSTACLE = 1
    AIRFOIL = 2
    HANDLE = 3
    INFLOW = 4
    OUTFLOW = 5
    WALL_BOUNDARY = 6
    SYMMETRIC = 7


NODE_TYPE_SIZE = 9  # one-hot width, as in the official code (enum SIZE = 9)

_DTYPES = {"float32", "float64", "int32", "int64", "uint8", "int8", "int16", "uint16", "bool"}


def make_meta(
    features: Mapping[str, Mapping],
    trajectory_length: int,
    dimension: int,
    dt: float | None = None,
    units: Mapping[str, str] | None = None,
    generator: Mapping | None = None,
    **extra,
) -> dict:
    """Build a ``meta.json`` dictionary and check that it is well formed.

    ``features`` maps a field name to ``{"type": "static"|"dynamic", "shape": [...], "dtype": "float32"}``.
    """
    meta = {
        "format": FORMAT_NAME,
        "version": FORMAT_VERSION,
        "field_names": list(features),
        "features": {
            k: {"type": v["type"], "shape": list(v["shape"]), "dtype": str(v["dtype"])} for k, v in features.items()
        },
        "trajectory_length": int(trajectory_length),
        "dimension": int(dimension),
        "dt": dt,
        "units": dict(units or {}),
        "node_types": {t.name: int(t) for t in NodeType},
        "node_type_size": NODE_TYPE_SIZE,
        "generator": dict(generator or {}),
        **extra,
    }
    check_meta(meta, "meta.json")
    return meta


def check_meta(meta: Mapping, where: str | os.PathLike) -> None:
    """Refuse a schema that cannot describe a trajectory."""
    for key in ("field_names", "features", "trajectory_length"):
        if key not in meta:
            raise DatasetError(
                f"missing key {key!r}; a dataset's meta.json needs field_names, features and trajectory_length",
                file=where,
            )
    for name in meta["field_names"]:
        spec = meta["features"].get(name)
        if spec is None:
            raise DatasetError("listed in field_names but has no entry in features", file=where, field=name)
        if spec.get("type") not in ("static", "dynamic", "static_varlen", "dynamic_varlen"):
            raise DatasetError(f"type {spec.get('type')!r}; expected static or dynamic", file=where, field=name)
        if str(spec.get("dtype")) not in _DTYPES:
            raise DatasetError(
                f"dtype {spec.get('dtype')!r}; expected one of {sorted(_DTYPES)}", file=where, field=name
            )
    if "dt" not in meta:
        raise DatasetError(
            "missing key 'dt' (time between frames; null when the source does not record it)", file=where
        )
    dt = meta["dt"]
    if dt is not None and (not isinstance(dt, (int, float)) or isinstance(dt, bool) or not np.isfinite(dt) or dt < 0):
        raise DatasetError(f"dt {dt!r}: expected a non-negative number (or null when unknown)", file=where)


def validate_trajectory(meta: Mapping, fields: Mapping[str, np.ndarray], *, file=None, trajectory=None) -> dict:
    """Check one trajectory against ``meta``; return its fields as arrays of the declared dtypes.

    Checks: every declared field present and no undeclared one; rank, fixed dimensions and -1 dimensions
    consistent (node count shared by all per-node fields, time axis equal to ``trajectory_length``); dtype
    kind (float vs integer); finite values; cell indices within the node count; node types within the enum.
    """
    arrays = {name: np.asarray(value) for name, value in fields.items()}
    check_layout(meta, {k: (v.shape, v.dtype) for k, v in arrays.items()}, file=file, trajectory=trajectory)
    return check_values(meta, {name: arrays[name] for name in meta["field_names"]}, file=file, trajectory=trajectory)


def check_layout(meta: Mapping, shapes: Mapping[str, tuple], *, file=None, trajectory=None) -> int | None:
    """The checks of :func:`validate_trajectory` that need no values, on ``{field: (shape, dtype)}`` (an HDF5
    file's dataset shapes, read without reading the arrays); returns the node count."""
    specs = meta["features"]
    missing = [k for k in meta["field_names"] if k not in shapes]
    if missing:
        raise DatasetError(
            f"missing; meta.json declares {meta['field_names']}", file=file, trajectory=trajectory, field=missing[0]
        )
    extra = [k for k in shapes if k not in specs]
    if extra:
        raise DatasetError(
            f"unexpected field; meta.json declares only {meta['field_names']}",
            file=file,
            trajectory=trajectory,
            field=extra[0],
        )
    num_nodes = None
    for name in meta["field_names"]:
        where = dict(file=file, trajectory=trajectory, field=name)
        spec, (got, dtype) = specs[name], shapes[name]
        got, shape, want = tuple(got), list(spec["shape"]), np.dtype(spec["dtype"])
        if spec["type"] == "dynamic" and shape and shape[0] in (-1, None) and int(meta["trajectory_length"]) > 0:
            shape[0] = int(meta["trajectory_length"])  # a time axis declared -1 still has trajectory_length frames
        if len(got) != len(shape):
            raise DatasetError(f"shape {list(got)} has rank {len(got)}; meta.json declares shape {shape}", **where)
        for axis, (g, exp) in enumerate(zip(got, shape)):
            if exp != -1 and g != exp:
                raise DatasetError(f"shape {list(got)} disagrees with meta.json shape {shape} at axis {axis}", **where)
        if np.dtype(dtype).kind != want.kind and not (np.dtype(dtype).kind in "iu" and want.kind in "iu"):
            raise DatasetError(f"dtype {np.dtype(dtype)} disagrees with meta.json dtype {want}", **where)
        if name != "cells":  # every other field is per node: its node axis must agree with mesh_pos's
            n = got[1] if spec["type"] == "dynamic" else got[0]
            if num_nodes is not None and n != num_nodes:
                raise DatasetError(f"has {n} nodes but other per-node fields have {num_nodes}", **where)
            num_nodes = n
    return num_nodes


def check_values(
    meta: Mapping, arrays: Mapping[str, np.ndarray], *, file=None, trajectory=None, num_nodes: int | None = None
) -> dict:
    """The value checks of :func:`validate_trajectory` on some fields of a trajectory whose layout passed
    :func:`check_layout` (a dynamic field may be a few frames of it): finite values, cell indices within the node
    count, node types within the enum; returns them as arrays of the declared dtypes."""
    out = {}
    for name, value in arrays.items():
        if value.dtype.kind == "f" and not np.isfinite(value).all():
            bad = np.argwhere(~np.isfinite(value))[0].tolist()
            raise DatasetError(
                f"non-finite value (NaN or Inf) at index {bad}", file=file, trajectory=trajectory, field=name
            )
        spec = meta["features"][name]
        if num_nodes is None and name != "cells" and value.ndim:
            num_nodes = value.shape[1] if spec["type"] == "dynamic" else value.shape[0]
        out[name] = value.astype(np.dtype(spec["dtype"]), copy=False)
    cells = out.get("cells")
    if cells is not None and num_nodes is not None and cells.size and (cells.min() < 0 or cells.max() >= num_nodes):
        raise DatasetError(
            f"cell index out of range [{int(cells.min())}, {int(cells.max())}]; the trajectory has {num_nodes} nodes",
            file=file,
            trajectory=trajectory,
            field="cells",
        )
    if "node_type" in out:
        unknown = np.setdiff1d(np.unique(out["node_type"]), [int(t) for t in NodeType])
        if unknown.size:
            raise DatasetError(
                f"unknown node type(s) {unknown.tolist()}; expected {[f'{t.name}={int(t)}' for t in NodeType]}",
                file=file,
                trajectory=trajectory,
                field="node_type",
            )
    return out
