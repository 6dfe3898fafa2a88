"""Speed: learned rollout against the solver on the same trajectories, and how a training step's
time and peak memory grow with node count.

    python benchmarks/speed/run.py rollout --n 3 [--run RUN]    # paper preset: solver s/trajectory vs HCMT/MGN rollout
    python benchmarks/speed/run.py scaling [--sizes 1000 2000 4000 8000 16000 32000 64000] [--models hcmt mgn]
                                       [--checkpoint-blocks] [--device cpu|cuda] [--json speed_scaling.json]

``rollout``: simulates ``n`` paper-preset designs with the generator's solver (timed), then rolls HCMT and MGN out
over the same trajectories (timed per step: graph building, contact search and the model, no I/O). With ``--run``
the models come from trained runs (``RUN_HCMT RUN_MGN``); otherwise freshly initialized ones with the paper's
Impact Plate sizes (the time per step does not depend on the weights while the state stays finite).

``scaling``: Impact Plate meshes refined to each target node count (``sim.mesh.impact_plate_mesh`` with a smaller
element size), one training step (forward + loss + backward + Adam) of HCMT and MGN at paper sizes, median of
``--reps``; each (model, size) in a fresh process so that its peak resident memory (``ru_maxrss``) is its own.
Fits time ∝ N^k by least squares in log-log.

Writes benchmarks/results/speed_rollout.json and benchmarks/results/speed_scaling.json.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
from common import write_json  # noqa: E402
from hcmt.domains.adapters import get_adapter  # noqa: E402
from hcmt.domains.spec import build_for_dataset  # noqa: E402
from hcmt.domains.trajectory import prepare_trajectory  # noqa: E402
from hcmt.graph.build import frame_graph  # noqa: E402
from hcmt.graph.hierarchy import build_hierarchy  # noqa: E402
from hcmt.inference.rollout import rollout  # noqa: E402
from hcmt.inference.run import load_run  # noqa: E402
from hcmt.sim.driver import simulate  # noqa: E402
from hcmt.sim.mesh import impact_plate_mesh  # noqa: E402
from hcmt.sim.params import Settings  # noqa: E402
from hcmt.sim.sampling import sample_design  # noqa: E402
from hcmt.sim.writer import trajectory_rng  # noqa: E402


def _rollout(args) -> None:

    adapter = get_adapter("impact_plate")
    models = {}
    if args.run:
        for run in args.run:
            m, info = load_run(run)
            levels = int(info.model.get("levels", 0)) if info.model["name"] == "hcmt" else 0
            models[info.model["name"]] = (m, levels)
    else:
        torch.manual_seed(0)
        models = {
            "hcmt": (build_for_dataset("hcmt", "impact_plate"), 6),
            "mgn": (build_for_dataset("mgn", "impact_plate"), 0),
        }
    rows = []
    for i in range(args.n):
        design = sample_design(trajectory_rng(args.seed, "test", i), "paper")
        t0 = time.perf_counter()
        sim = simulate(design, Settings())
        solver_s = time.perf_counter() - t0
        fields = sim.fields
        steps = fields["world_pos"].shape[0] - 1
        row = {
            "nodes": int(fields["mesh_pos"].shape[0]),
            "frames": steps + 1,
            "solver_s": solver_s,
            "solver_ms_per_frame": 1e3 * solver_s / steps,
        }
        for name, (model, levels) in models.items():
            traj = prepare_trajectory(fields, f"design{i}", adapter, levels)
            try:
                r = rollout(model, adapter, traj, 0.4)
                row[f"{name}_ms_per_step"] = r["ms_per_step"]
            except RuntimeError as exc:  # an untrained model may diverge: report it rather than a time
                row[f"{name}_ms_per_step"] = None
                row[f"{name}_error"] = str(exc)
        rows.append(row)
        print(json.dumps(row), flush=True)
    summary = {"trajectories": rows, "threads": torch.get_num_threads(), "trained_runs": args.run or None}
    summary["solver_ms_per_frame"] = statistics.median(r["solver_ms_per_frame"] for r in rows)
    for name in models:
        vals = [r[f"{name}_ms_per_step"] for r in rows if r.get(f"{name}_ms_per_step")]
        if vals:
            summary[f"{name}_ms_per_step"] = statistics.median(vals)
            summary[f"{name}_speedup_vs_solver"] = summary["solver_ms_per_frame"] / summary[f"{name}_ms_per_step"]
    path = write_json("speed_rollout.json", summary)
    print(json.dumps({k: v for k, v in summary.items() if k != "trajectories"}, indent=2))
    print(f"wrote {path}")


def mesh_with_nodes(target: int) -> dict:
    """An Impact Plate mesh refined until it has about ``target`` nodes (element size ∝ 1/sqrt(N))."""
    h = 0.125 * np.sqrt(2150 / target)
    for _ in range(6):
        mesh = impact_plate_mesh(0.75, 3.5, h)
        n = len(mesh["mesh_pos"])
        if abs(n - target) / target < 0.1:
            break
        h *= np.sqrt(n / target)
    return mesh


MEMORY_CAP_GB = 12  # per measurement process: a size that needs more fails cleanly instead of meeting the OOM killer


def _one(model_name: str, target: int, reps: int, checkpoint_blocks: bool = False, device: str = "cpu") -> dict:
    """One (model, size) measurement; run in its own process. ``checkpoint_blocks``: activation checkpointing per
    block (``train.checkpoint_blocks``). On CUDA the peak is the allocator's (``max_memory_allocated``)."""
    dev = torch.device(device)
    if dev.type == "cpu":  # CUDA reserves address space far beyond its use: cap the CPU runs only
        cap = MEMORY_CAP_GB << 30
        resource.setrlimit(resource.RLIMIT_AS, (cap, cap))

    mesh = mesh_with_nodes(target)
    n = len(mesh["mesh_pos"])
    levels = 6 if model_name == "hcmt" else 0
    t0 = time.perf_counter()
    h = build_hierarchy(mesh["mesh_pos"], mesh["cells"], mesh["node_type"], levels)
    hierarchy_ms = 1e3 * (time.perf_counter() - t0)
    rng = np.random.default_rng(0)
    mesh_pos = torch.from_numpy(mesh["mesh_pos"]).float()
    world = mesh_pos + torch.from_numpy(rng.normal(scale=0.005, size=mesh_pos.shape)).float()
    feats = torch.cat(
        [
            torch.nn.functional.one_hot(torch.from_numpy(mesh["node_type"]), 9).float(),
            torch.from_numpy(rng.normal(size=(n, 4))).float(),
        ],
        1,
    )
    torch.manual_seed(0)
    model = build_for_dataset(model_name, "impact_plate").to(dev)
    model.checkpoint_blocks = checkpoint_blocks
    opt = torch.optim.Adam(model.parameters(), 1e-4, fused=dev.type == "cuda")
    target_out = torch.randn(n, 3, device=dev)
    times = []
    for i in range(reps + 1):
        t0 = time.perf_counter()
        g = frame_graph(feats, mesh_pos, world, h, 0.4).to(dev)
        loss = ((model(g, accumulate=True) - model.normalize_target(target_out, accumulate=True)) ** 2).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
        if dev.type == "cuda":
            torch.cuda.synchronize(dev)
        if i:  # the first step warms up allocators
            times.append(1e3 * (time.perf_counter() - t0))
    peak = (
        torch.cuda.max_memory_allocated(dev) / 2**20
        if dev.type == "cuda"
        else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    )
    return {
        "model": model_name,
        "nodes": n,
        "edges": int(g.mesh_edges.shape[1]),
        "train_ms": statistics.median(times),
        "hierarchy_ms": hierarchy_ms,
        "peak_mb": peak,
        "peak_kb_per_node": peak * 1024 / n,
        "checkpoint_blocks": checkpoint_blocks,
        "device": device if dev.type == "cpu" else torch.cuda.get_device_name(dev),
    }


def _scaling(args) -> None:
    """Resumable: rows already in speed_scaling.json are kept, the file is rewritten after every new row."""
    from common import RESULTS

    old = RESULTS / args.json
    rows = json.loads(old.read_text())["rows"] if old.is_file() else []
    ckpt = bool(args.checkpoint_blocks)
    for size in args.sizes:
        for model in args.models:
            if any(
                r["model"] == model
                and r.get("target_nodes", r.get("nodes")) == size
                and r.get("checkpoint_blocks", False) == ckpt
                and r.get("device", "cpu") in (args.device, None)
                for r in rows
            ):
                continue
            out = subprocess.run(
                [sys.executable, __file__, "one", model, str(size), "--reps", str(args.reps), "--device", args.device]
                + (["--checkpoint-blocks"] if ckpt else []),
                capture_output=True,
                text=True,
                env={**os.environ, "PYTHONUNBUFFERED": "1"},
            )
            if out.returncode:
                err = out.stderr.strip().splitlines()[-1] if out.stderr.strip() else f"exit {out.returncode}"
                rows.append(
                    {
                        "model": model,
                        "target_nodes": size,
                        "failed": err[-300:],
                        "checkpoint_blocks": ckpt,
                        "device": args.device,
                    }
                )
                print(json.dumps(rows[-1]), flush=True)
                write_json(args.json, {"rows": rows, "exponent": {}, "threads": torch.get_num_threads()})
                continue
            rows.append({"target_nodes": size, **json.loads(out.stdout.strip().splitlines()[-1])})
            print(json.dumps(rows[-1]), flush=True)
            write_json(args.json, {"rows": rows, "exponent": {}, "threads": torch.get_num_threads()})
    fits = {}
    for model in ("hcmt", "mgn"):
        r = [
            x
            for x in rows
            if x["model"] == model
            and "train_ms" in x
            and not x.get("checkpoint_blocks")
            and x.get("device", "cpu") in (args.device, None)
        ]
        if len(r) >= 2:
            k, _ = np.polyfit(np.log([x["nodes"] for x in r]), np.log([x["train_ms"] for x in r]), 1)
            fits[model] = float(k)
    path = write_json(args.json, {"rows": rows, "exponent": fits, "threads": torch.get_num_threads()})
    print(f"time ∝ N^k: {fits}\nwrote {path}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="what", required=True)
    r = sub.add_parser("rollout")
    r.add_argument("--n", type=int, default=3)
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--run", nargs="+", help="trained run folders (HCMT and/or MGN)")
    s = sub.add_parser("scaling")
    s.add_argument("--sizes", type=int, nargs="+", default=[1000, 2000, 4000, 8000, 16000, 32000, 64000])
    s.add_argument("--reps", type=int, default=3)
    s.add_argument("--models", nargs="+", default=["hcmt", "mgn"])
    s.add_argument("--checkpoint-blocks", action="store_true", help="activation checkpointing per block")
    s.add_argument("--device", default="cpu")
    s.add_argument("--json", default="speed_scaling.json", help="under benchmarks/results (resumed if present)")
    o = sub.add_parser("one")
    o.add_argument("model")
    o.add_argument("size", type=int)
    o.add_argument("--reps", type=int, default=3)
    o.add_argument("--checkpoint-blocks", action="store_true")
    o.add_argument("--device", default="cpu")
    a = p.parse_args()
    if a.what == "rollout":
        _rollout(a)
    elif a.what == "scaling":
        _scaling(a)
    else:
        print(json.dumps(_one(a.model, a.size, a.reps, a.checkpoint_blocks, a.device)))


if __name__ == "__main__":
    main()
