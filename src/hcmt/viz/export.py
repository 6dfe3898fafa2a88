"""A rollout as a ParaView time series, through meshio: VTU files with a ``.pvd`` collection, or XDMF.

One series per source of a trajectory: ``<traj>_truth`` (the ground truth) and ``<traj>_<model>`` per run, so
ParaView shows them side by side. Point data of every frame:

* ``node_type`` (int32; MeshGraphNets enum + SYMMETRIC 7), ``displacement`` = ``x_t - x_0`` (3 components: ParaView's
  *Warp By Vector* wants vectors of three), ``position`` = ``x_t`` (3 components) and ``stress`` when the dataset
  has it;
* in a prediction's series also ``stress_true``, ``stress_error`` = predicted minus true stress,
  ``position_error`` = ``x_t^pred - x_t^true`` (3 components) and ``position_error_norm``.

2-D positions get a zero third coordinate. Time values are ``frame * dt`` (meta.json's ``dt``, in its time unit),
or the frame number when the dataset records no ``dt``.

* **VTU**: ``<series>/frame_00000.vtu ...`` with the mesh at its deformed position in each file, and
  ``<series>.pvd`` (a small XML collection file: open this one in ParaView).
* **XDMF**: ``<series>.xdmf`` + ``<series>.h5`` through :class:`meshio.xdmf.TimeSeriesWriter`, which stores the
  points once: they are the initial positions ``x_0``; apply *Warp By Vector* with ``displacement`` to see the
  deformed mesh (a limitation of the time-series writer, which has no moving points).
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from hcmt.errors import InputError, require
from hcmt.files import atomic_path
from hcmt.viz.rollouts import Case, Series

FORMATS = ("vtu", "xdmf")
_CELL_TYPES = {3: "triangle", 4: "tetra"}


def series_slug(case: Case, series: Series) -> str:
    """File stem of a series: ``traj_00000_truth``, ``traj_00000_hcmt``, ``traj_00000_mgn_run_b``."""
    name = "truth" if series is case.truth else series.label
    return f"{case.name}_" + re.sub(r"[^a-z0-9]+", "_", name.lower()).strip("_")


def pad3(x: np.ndarray) -> np.ndarray:
    """[N, d] -> [N, 3] with zero padding (ParaView's vectors have three components)."""
    x = np.asarray(x, np.float64)
    return np.concatenate([x, np.zeros((len(x), 3 - x.shape[1]))], axis=1) if x.shape[1] < 3 else x


def point_data(case: Case, series: Series, frame: int) -> dict[str, np.ndarray]:
    """The point data of one frame of one series (see the module docstring)."""
    pos = series.world_pos[frame]
    data = {
        "node_type": case.node_type.astype(np.int32),
        "position": pad3(pos),
        "displacement": pad3(pos - series.world_pos[0]),
    }
    if series.stress is not None:
        data["stress"] = np.asarray(series.stress[frame], np.float64).reshape(-1)
    if series is not case.truth:
        err = pad3(pos - case.truth.world_pos[frame])
        data["position_error"] = err
        data["position_error_norm"] = np.linalg.norm(err, axis=1)
        if series.stress is not None and case.truth.stress is not None:
            true = np.asarray(case.truth.stress[frame], np.float64).reshape(-1)
            data["stress_true"] = true
            data["stress_error"] = data["stress"] - true
    return data


def frame_times(case: Case, frames: list[int]) -> list[float]:
    dt = case.meta.get("dt")
    return [f * float(dt) if dt else float(f) for f in frames]


def write_pvd(path: Path, files: list[Path], times: list[float]) -> Path:
    """The ParaView collection file listing one VTU per time value (paths relative to the .pvd)."""
    root = ET.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
    coll = ET.SubElement(root, "Collection")
    for f, t in zip(files, times):
        ET.SubElement(
            coll, "DataSet", timestep=repr(float(t)), group="", part="0", file=f.relative_to(path.parent).as_posix()
        )
    ET.indent(root)
    with atomic_path(path) as tmp:
        tmp.write_bytes(b'<?xml version="1.0"?>\n' + ET.tostring(root) + b"\n")
    return path


def export_case(case: Case, out_dir: str | Path, fmt: str = "vtu", frames: list[int] | None = None) -> list[Path]:
    """Write every series of ``case`` as a time series; returns the files to open (``.pvd`` or ``.xdmf``)."""
    if fmt not in FORMATS:
        raise InputError(f"format must be one of {FORMATS}, got {fmt!r}")
    cell_type = _CELL_TYPES.get(case.cells.shape[1])
    if cell_type is None:
        raise InputError(f"cells with {case.cells.shape[1]} vertices; export handles triangles and tetrahedra")
    meshio = require("meshio", "viz")
    out_dir = Path(out_dir).resolve()
    out_dir.mkdir(parents=True, exist_ok=True)
    frames = list(range(case.num_frames)) if frames is None else [int(f) for f in frames]
    times = frame_times(case, frames)
    cells = [(cell_type, case.cells.astype(np.int64))]
    opened = []
    for series in case.series:
        slug = series_slug(case, series)
        if fmt == "vtu":
            folder = out_dir / slug
            folder.mkdir(exist_ok=True)
            files = []
            for f in frames:  # one file per frame
                path = folder / f"frame_{f:05d}.vtu"
                mesh = meshio.Mesh(pad3(series.world_pos[f]), cells, point_data=point_data(case, series, f))
                with atomic_path(path) as tmp:
                    meshio.write(tmp, mesh, file_format="vtu")
                files.append(path)
            opened.append(write_pvd(out_dir / f"{slug}.pvd", files, times))
        else:
            path = out_dir / f"{slug}.xdmf"
            cwd = os.getcwd()
            os.chdir(out_dir)  # meshio's TimeSeriesWriter puts its .h5 in the working folder, not beside the .xdmf
            try:
                with meshio.xdmf.TimeSeriesWriter(path.name) as writer:
                    writer.write_points_cells(pad3(series.world_pos[0]), cells)
                    for f, t in zip(frames, times):
                        writer.write_data(t, point_data=point_data(case, series, f))
            finally:
                os.chdir(cwd)
            opened.append(path)
    return opened
