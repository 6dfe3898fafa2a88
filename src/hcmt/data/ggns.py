"""Read the Deformable Plate data of Linkerhägner et al. (GGNS, "Grounding Graph Network Simulators").

Each split is a pickle holding a list of trajectories; a trajectory is a dict with (at least)

* ``nodes_grid`` [T, N, 2]: the plate's node positions (its rest shape is ``nodes_grid[0]``),
* ``triangles_grid`` [C, 3]: the plate's triangles,
* ``nodes_collider`` [T, M, 2] and ``triangles_collider`` [K, 3]: the collider (the pushing ball),
* ``poisson_ratio``: the plate material's Poisson ratio (a scalar),

plus fields hcmt does not use (``edge_index_grid``, ``pcd_points``, ...). Each is mapped onto the native layout:
plate nodes NORMAL, collider nodes OBSTACLE, ``mesh_pos`` the rest shape, ``world_pos`` [T, N+M, 2], per-node
``poisson_ratio`` [N+M, 1] (the paper's Table 9 input ν_i) and the scalar as a design-parameter attribute.
"""

from __future__ import annotations

import os
import pickle
from pathlib import Path

import numpy as np

from hcmt.data.format import NodeType
from hcmt.errors import DatasetError

REQUIRED = ("nodes_grid", "triangles_grid", "nodes_collider", "triangles_collider", "poisson_ratio")


#: the only globals a GGNS pickle may name: numpy's array, scalar and dtype reconstruction (numpy 1 and 2 spell its
#: core module differently), ``_codecs.encode`` (how protocol 2 stores bytes) and plain builtin containers. Any
#: other global (``os.system``, a class of some library) is refused before it is called: no code from a data file
#: runs.
SAFE_GLOBALS = {
    **{(m, n): None for m in ("numpy.core.multiarray", "numpy._core.multiarray") for n in ("_reconstruct", "scalar")},
    **{(m, "_frombuffer"): None for m in ("numpy.core.numeric", "numpy._core.numeric")},
    ("numpy", "ndarray"): None,
    ("numpy", "dtype"): None,
    ("_codecs", "encode"): None,
    **{("builtins", n): None for n in ("list", "dict", "tuple", "set", "frozenset", "bytearray", "complex", "slice")},
}


class _SafeUnpickler(pickle.Unpickler):
    """An unpickler that builds numpy arrays, numbers, strings and containers only (:data:`SAFE_GLOBALS`)."""

    def __init__(self, file, path: Path):
        super().__init__(file)
        self.path = path

    def find_class(self, module: str, name: str):
        if (module, name) in SAFE_GLOBALS or (module == "numpy.dtypes" and name.endswith("DType")):
            return super().find_class(module, name)
        raise DatasetError(
            f"refused: the pickle names the global {module[:60]}.{name[:60]}, not a numpy array or a "
            "plain container; hcmt runs no code from a data file (a GGNS pickle holds only arrays, "
            "numbers, strings, lists and dicts)",
            file=self.path,
        )


def load_ggns_pickle(path: str | os.PathLike) -> list[dict]:
    """The trajectories of a GGNS pickle, read with :class:`_SafeUnpickler`: no code the file names is run."""
    path = Path(path)
    try:
        with open(path, "rb") as f:
            data = _SafeUnpickler(f, path).load()
    except (pickle.UnpicklingError, EOFError, AttributeError, ValueError, TypeError, IndexError) as exc:
        if isinstance(exc, DatasetError):
            raise
        raise DatasetError(f"cannot be unpickled (truncated or not a GGNS pickle): {exc}", file=path) from None
    if isinstance(data, dict):
        data = [data]
    if not isinstance(data, (list, tuple)) or not all(isinstance(t, dict) for t in data):
        raise DatasetError("expected a list of trajectory dicts (GGNS Deformable Plate layout)", file=path)
    return list(data)


def _array(traj: dict, key: str, dtype, file, trajectory) -> np.ndarray:
    """``traj[key]`` as an array of ``dtype``; a ragged or non-numeric value names the file, trajectory and field."""
    try:
        return np.asarray(traj[key], dtype=dtype)
    except (ValueError, TypeError) as exc:
        raise DatasetError(
            f"not a numeric array ({str(exc).splitlines()[0][:80]})", file=file, trajectory=trajectory, field=key
        ) from None


def ggns_to_native(traj: dict, *, file=None, trajectory=None) -> tuple[dict, dict]:
    """Map one GGNS trajectory dict to native fields and design-parameter attributes."""
    for key in REQUIRED:
        if key not in traj:
            raise DatasetError(
                f"missing; a GGNS trajectory needs {list(REQUIRED)}", file=file, trajectory=trajectory, field=key
            )
    grid, collider = (_array(traj, k, np.float32, file, trajectory) for k in ("nodes_grid", "nodes_collider"))
    for name, arr in (("nodes_grid", grid), ("nodes_collider", collider)):
        if arr.ndim != 3 or arr.shape[-1] != 2:
            raise DatasetError(
                f"shape {list(arr.shape)}; expected [T, N, 2]", file=file, trajectory=trajectory, field=name
            )
    if grid.shape[0] != collider.shape[0]:
        raise DatasetError(
            f"{collider.shape[0]} steps but nodes_grid has {grid.shape[0]}",
            file=file,
            trajectory=trajectory,
            field="nodes_collider",
        )
    n = grid.shape[1]
    tri_grid, tri_coll = (_array(traj, k, np.int64, file, trajectory) for k in ("triangles_grid", "triangles_collider"))
    for name, tri, count in (("triangles_grid", tri_grid, n), ("triangles_collider", tri_coll, collider.shape[1])):
        if tri.ndim != 2 or tri.shape[1] != 3:
            raise DatasetError(
                f"shape {list(tri.shape)}; expected [C, 3]", file=file, trajectory=trajectory, field=name
            )
        if tri.size and (tri.min() < 0 or tri.max() >= count):
            raise DatasetError(
                f"index out of range [{tri.min()}, {tri.max()}] for {count} nodes",
                file=file,
                trajectory=trajectory,
                field=name,
            )
    nu = _array(traj, "poisson_ratio", np.float64, file, trajectory).reshape(-1)
    if nu.size == 0:
        raise DatasetError("empty; expected one number", file=file, trajectory=trajectory, field="poisson_ratio")
    nu = float(nu[0])
    world = np.concatenate([grid, collider], axis=1)
    total = world.shape[1]
    node_type = np.full((total, 1), int(NodeType.NORMAL), dtype=np.int32)
    node_type[n:] = int(NodeType.OBSTACLE)
    fields = {
        "mesh_pos": world[0].copy(),
        "cells": np.concatenate([tri_grid, tri_coll + n]).astype(np.int32),
        "node_type": node_type,
        "poisson_ratio": np.full((total, 1), nu, dtype=np.float32),
        "world_pos": world,
    }
    return fields, {"poisson_ratio": nu}


def ggns_features(num_steps: int) -> dict:
    return {
        "mesh_pos": {"type": "static", "shape": [-1, 2], "dtype": "float32"},
        "cells": {"type": "static", "shape": [-1, 3], "dtype": "int32"},
        "node_type": {"type": "static", "shape": [-1, 1], "dtype": "int32"},
        "poisson_ratio": {"type": "static", "shape": [-1, 1], "dtype": "float32"},
        "world_pos": {"type": "dynamic", "shape": [num_steps, -1, 2], "dtype": "float32"},
    }
