"""The memory of a process that builds training items, and how fast one builds them.

    python benchmarks/memory/run.py            # writes benchmarks/results/data_memory.json (about 5-10 min)

* RSS: a fresh process builds ``--items`` training items (``FrameDataset`` + ``StepSampler``, batch 1) in one
  ``DataLoader`` worker, on paper-size Impact Plate datasets of 4 and 40 trajectories, with the split read per item
  (the training path) and held in memory (``in_memory=True``, the ``load_split`` path training used before); the
  worker's peak RSS (``VmHWM``) and the training process's RSS after building the dataset are reported.
* Throughput: frames per second one process (one core, one torch thread) builds, collate included -- what one
  ``DataLoader`` worker delivers -- at paper size (Impact Plate, 6 levels) and at Deforming Plate size (1,271-ish
  tetrahedral nodes, 400 frames, 2 levels), with keys spread over the split (LRU misses) and from one trajectory
  (LRU hits); the workers needed to feed a 10 ms GPU step at batch 1 is ``ceil(10 ms / ms per frame)``.
* ``hcmt convert``: the peak RSS of converting official-layout (Deforming Plate TFRecord) files of 20 and 200
  trajectories.

The datasets are synthetic, written with ``hcmt.data.format.write_split`` (the solver takes about a minute per
paper trajectory): one paper-preset Impact Plate mesh (``hcmt.sim.scene``, its mesh size set for about 2,200 nodes)
with synthetic motion and stress over 52 frames, copied with small per-copy perturbations of the mesh and frames
(each copy its own hierarchy); a tetrahedral plate and obstacle for Deforming Plate.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch
from tfrecord.writer import TFRecordWriter

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
from common import write_json  # noqa: E402
from hcmt.data.format import NodeType, make_meta, write_meta, write_split  # noqa: E402
from hcmt.design.start import initial_frames  # noqa: E402
from hcmt.domains.adapters import get_adapter  # noqa: E402
from hcmt.sim.params import Settings  # noqa: E402
from hcmt.sim.sampling import sample_design  # noqa: E402
from hcmt.sim.scene import feature_spec  # noqa: E402
from hcmt.training.dataset import FrameDataset, StepSampler, collate_samples, step_loader  # noqa: E402

torch.set_num_threads(1)
PAPER_NODES = 2208  # the paper's Impact Plate mean node count (Table 6)
GPU_STEP_MS = 10.0


def proc_kb(pid: int | str = "self") -> dict[str, float]:
    """VmRSS and VmHWM (peak) of a process, in MB."""
    rows = dict(line.split(":", 1) for line in Path(f"/proc/{pid}/status").read_text().splitlines() if ":" in line)
    return {k: int(rows[k].split()[0]) / 1024 for k in ("VmRSS", "VmHWM")}


def paper_mesh(seed: int = 0) -> dict:
    """Static fields and frames 0-1 of a paper-preset design, its mesh size scaled to about 2,200 nodes."""
    design = sample_design(np.random.default_rng(seed), "paper")
    for _ in range(3):
        fields = initial_frames(design)["fields"]
        n = len(fields["mesh_pos"])
        if abs(n - PAPER_NODES) < 0.05 * PAPER_NODES:
            break
        design = replace(design, mesh_size=design.mesh_size * math.sqrt(n / PAPER_NODES))
    return fields


def impact_copy(base: dict, k: int, frames: int) -> dict:
    """Copy ``k``: the mesh moved by ~1e-4 mm (its own hierarchy), a falling ball and a bending plate, noise."""
    rng = np.random.default_rng(k)
    x0 = base["mesh_pos"] + rng.normal(0, 1e-4, base["mesh_pos"].shape).astype(np.float32)
    ball = base["node_type"][:, 0] == NodeType.OBSTACLE
    t = np.arange(frames, dtype=np.float32)[:, None]
    world = np.repeat(x0[None], frames, 0)
    world[:, ball, 1] -= 0.01 * t
    world[:, ~ball, 1] -= 1e-3 * t * np.cos(x0[~ball, 0])[None]
    world += rng.normal(0, 1e-5, world.shape).astype(np.float32)
    stress = np.abs(rng.normal(0, 1.0, (frames, len(x0), 1))).astype(np.float32)
    return {**base, "mesh_pos": x0, "world_pos": world, "stress": stress}


def impact_dataset(folder: Path, count: int, frames: int = 52) -> Path:
    """``count`` paper-size Impact Plate trajectories (:func:`impact_copy`) at ``folder`` (kept when present)."""
    if (folder / "meta.json").is_file():
        return folder
    base = {k: v for k, v in paper_mesh().items() if k not in ("world_pos", "stress")}
    meta = make_meta(
        feature_spec(Settings(frames=frames)),
        trajectory_length=frames,
        dimension=2,
        dt=0.002,
        generator={"preset": "paper", "synthetic": "benchmarks/memory/run.py"},
    )
    write_split(folder / "train.h5", meta, ((f"traj_{k:05d}", impact_copy(base, k, frames), {}) for k in range(count)))
    write_meta(folder, meta)
    return folder


def box_tets(nx: int, ny: int, nz: int, origin=(0.0, 0.0, 0.0), h: float = 0.01) -> tuple[np.ndarray, np.ndarray]:
    """A box of ``nx * ny * nz`` cubes of side ``h``, six tetrahedra each."""
    grid = np.stack(np.meshgrid(*(np.arange(k + 1) for k in (nx, ny, nz)), indexing="ij"), -1).reshape(-1, 3)
    pos = (grid * h + np.asarray(origin)).astype(np.float32)

    def nid(i, j, k):
        return (i * (ny + 1) + j) * (nz + 1) + k

    paths = [(0, 1, 3, 7), (0, 1, 5, 7), (0, 2, 3, 7), (0, 2, 6, 7), (0, 4, 5, 7), (0, 4, 6, 7)]
    tets = []
    for i, j, k in np.ndindex(nx, ny, nz):
        corner = [nid(i + (c >> 2 & 1), j + (c >> 1 & 1), k + (c & 1)) for c in range(8)]
        tets += [[corner[c] for c in path] for path in paths]
    return pos, np.asarray(tets, np.int32)


def deforming_fields(k: int, frames: int) -> dict:
    """A Deforming Plate-size trajectory: a 19 x 19 x 2 tetrahedral plate (HANDLE at x = 0) and a 3 x 3 x 3
    obstacle 5 mm above it moving down 0.1 mm a frame; 1,264 nodes."""
    plate, ptet = box_tets(19, 19, 2)
    obst, otet = box_tets(3, 3, 3, origin=(0.08, 0.08, 0.025))
    pos = np.concatenate([plate, obst])
    nt = np.zeros((len(pos), 1), np.int32)
    nt[len(plate) :] = NodeType.OBSTACLE
    nt[: len(plate)][plate[:, 0] == 0] = NodeType.HANDLE
    rng = np.random.default_rng(k)
    world = np.repeat(pos[None], frames, 0)
    world[:, len(plate) :, 2] -= 1e-4 * np.arange(frames, dtype=np.float32)[:, None]
    world += rng.normal(0, 1e-6, world.shape).astype(np.float32)
    return {
        "cells": np.concatenate([ptet, otet + len(plate)]),
        "node_type": nt,
        "mesh_pos": pos,
        "world_pos": world,
        "stress": np.abs(rng.normal(0, 1e3, (frames, len(pos), 1))).astype(np.float32),
    }


DEFORMING_FEATURES = {
    "cells": ("static", [-1, 4], "int32"),
    "node_type": ("static", [-1, 1], "int32"),
    "mesh_pos": ("static", [-1, 3], "float32"),
    "world_pos": ("dynamic", [-1, -1, 3], "float32"),
    "stress": ("dynamic", [-1, -1, 1], "float32"),
}


def deforming_dataset(folder: Path, count: int, frames: int = 400) -> Path:
    """``count`` Deforming Plate-size trajectories of ``frames`` frames at ``folder`` (kept when present)."""
    if (folder / "meta.json").is_file():
        return folder
    feats = {
        k: {"type": t, "shape": [frames, *s[1:]] if t == "dynamic" else s, "dtype": d}
        for k, (t, s, d) in DEFORMING_FEATURES.items()
    }
    meta = make_meta(feats, trajectory_length=frames, dimension=3, dt=None)
    write_split(folder / "train.h5", meta, ((f"traj_{k:05d}", deforming_fields(k, frames), {}) for k in range(count)))
    write_meta(folder, meta)
    return folder


def official_tfrecord(folder: Path, count: int, frames: int = 52) -> Path:
    """An official-layout (MeshGraphNets Deforming Plate) TFRecord folder of ``count`` trajectories."""
    if (folder / "train.tfrecord").is_file():
        return folder
    folder.mkdir(parents=True, exist_ok=True)
    feats = {
        k: {"type": t, "shape": [frames, *s[1:]] if t == "dynamic" else [1, *s], "dtype": d}
        for k, (t, s, d) in DEFORMING_FEATURES.items()
    }
    (folder / "meta.json").write_text(
        json.dumps(
            {
                "simulator": "comsol",
                "dt": 0.0,
                "trajectory_length": frames,
                "field_names": list(feats),
                "features": feats,
            }
        )
    )
    writer = TFRecordWriter(str(folder / "train.tfrecord"))
    for k in range(count):
        rec = deforming_fields(k, frames)
        writer.write({key: ([np.ascontiguousarray(v).tobytes()], "byte") for key, v in rec.items()})
    writer.close()
    return folder


# -- measurements ----------------------------------------------------------------------------------------------------
def child(spec: dict) -> dict:
    """In a fresh process: build the dataset, then ``items`` training items in one DataLoader worker; RSS of both."""
    adapter = get_adapter(spec["adapter"])
    ds = FrameDataset(
        spec["data"],
        "train",
        adapter,
        spec["levels"],
        True,
        spec["radius"],
        noise_std=0.003,
        seed=1,
        in_memory=spec["in_memory"],
    )
    main_after_build = proc_kb()["VmRSS"]
    it = step_loader(ds, StepSampler(ds, 1, seed=3, start=0, end=spec["items"]), workers=1)
    worker = it._workers[0].pid
    for _ in range(spec["items"] - 1):
        next(it)
    out = {"main_rss_after_build_mb": main_after_build, "worker": proc_kb(worker)}
    next(it)
    return out


def rss(data: Path, adapter: str, levels: int, radius: float, in_memory: bool, items: int) -> dict:
    spec = dict(data=str(data), adapter=adapter, levels=levels, radius=radius, in_memory=in_memory, items=items)
    r = subprocess.run(
        [sys.executable, __file__, "--child", json.dumps(spec)],
        capture_output=True,
        text=True,
        check=True,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    return json.loads(r.stdout.strip().splitlines()[-1])


def throughput(ds: FrameDataset, keys: list) -> dict:
    """ms per training frame (item and collate: a DataLoader worker's work at batch 1) over ``keys``, after one
    warm-up item."""
    collate_samples([ds[keys[0]]])
    times = []
    for key in keys:
        t0 = time.perf_counter()
        collate_samples([ds[key]])
        times.append(1e3 * (time.perf_counter() - t0))
    ms = float(np.median(times))
    return {
        "frames": len(times),
        "median_ms": ms,
        "mean_ms": float(np.mean(times)),
        "frames_per_s": 1e3 / ms,
        "workers_for_10ms_gpu_step": math.ceil(ms / GPU_STEP_MS),
    }


def feeding(data: Path, adapter: str, levels: int, radius: float, count: int) -> dict:
    """:func:`throughput` read per item with keys spread over the split and an LRU of one trajectory (a miss
    whenever the trajectory changes: the trainer's random order on a split of thousands), from one trajectory (LRU
    hits), and held in memory (the same spread keys)."""
    lazy = FrameDataset(data, "train", get_adapter(adapter), levels, True, radius, noise_std=0.003, seed=1, keep=1)
    spread = [int(i) for i in np.random.default_rng(0).permutation(len(lazy))[:count]]
    first = [i for i in range(len(lazy)) if lazy.frames[i][0] == 0][:count]
    out = {
        "nodes": int(lazy.source.nodes[0]),
        "frames_per_trajectory": int(lazy.source.steps[0]),
        "trajectories": len(lazy.source),
        "levels": levels,
        "read_per_item_lru_misses": throughput(lazy, spread),
        "read_per_item_lru_hits": throughput(lazy, first),
    }
    eager = FrameDataset(
        data, "train", get_adapter(adapter), levels, True, radius, noise_std=0.003, seed=1, in_memory=True
    )
    out["in_memory_spread"] = throughput(eager, spread)
    return out


def convert_rss(src: Path, out: Path) -> float:
    """Peak RSS (MB) of ``hcmt convert SRC OUT`` in a fresh process."""
    code = (
        "import resource, sys; from hcmt.cli import main; assert main(['convert', sys.argv[1], sys.argv[2]]) "
        "== 0; print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)"
    )
    r = subprocess.run([sys.executable, "-c", code, str(src), str(out)], capture_output=True, text=True, check=True)
    return float(r.stdout.strip().splitlines()[-1])


def memory(work: Path, counts: list[int], items: int) -> dict:
    """Worker and training-process RSS on paper-size Impact Plate datasets of each count, and on Deforming
    Plate-size ones of 2 and 6 trajectories, read per item and held in memory."""
    out = {}
    sets = [("impact_plate", f"impact_paper_{n}", n, impact_dataset, 6, 0.4) for n in counts]
    sets += [("deforming_plate", f"deforming_{n}", n, deforming_dataset, 2, 0.03) for n in (2, 6)]
    for adapter, name, n, make, levels, radius in sets:
        data = make(work / name, n)
        ds = FrameDataset(data, "train", get_adapter(adapter), levels, True, radius)
        for ti in range(len(ds.source)):  # hierarchies built once into the disk cache, as a first epoch would
            ds.source.static(ti)
        for in_memory in (True, False):
            key = f"{name} {'in memory' if in_memory else 'read per item'}"
            out[key] = rss(data, adapter, levels, radius, in_memory, items)
            print(key, json.dumps(out[key]), flush=True)
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--work", default=str(Path(__file__).resolve().parent.parent / "work" / "data_memory"))
    p.add_argument("--counts", type=int, nargs=2, default=[4, 40], help="Impact Plate trajectory counts")
    p.add_argument("--items", type=int, default=120, help="items each RSS process builds")
    p.add_argument("--convert", type=int, nargs=2, default=[20, 200], help="trajectories of the converted files")
    p.add_argument("--child")
    args = p.parse_args()
    if args.child:
        print(json.dumps(child(json.loads(args.child))))
        return
    work = Path(args.work)
    base = subprocess.run(
        [
            sys.executable,
            "-c",
            "import resource, hcmt.training.trainer; print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)",
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    results = {
        "command": "python benchmarks/memory/run.py " + " ".join(sys.argv[1:]),
        "python_with_hcmt_training_imported_mb": float(base.stdout.strip()),
        "rss": memory(work, args.counts, args.items),
    }
    results["throughput"] = {
        "impact_plate_paper": feeding(work / f"impact_paper_{args.counts[1]}", "impact_plate", 6, 0.4, 150),
        "deforming_plate_size": feeding(work / "deforming_6", "deforming_plate", 2, 0.03, 150),
    }
    print(json.dumps(results["throughput"], indent=1), flush=True)
    results["convert_peak_rss_mb"] = {}
    for n in args.convert:
        out = Path(tempfile.mkdtemp(dir=work)) / "native"
        results["convert_peak_rss_mb"][f"{n} trajectories"] = convert_rss(official_tfrecord(work / f"tf_{n}", n), out)
        print(n, results["convert_peak_rss_mb"], flush=True)
    print("wrote", write_json("data_memory.json", results))


if __name__ == "__main__":
    main()
