"""Learned design check against the built-in solver on the same designs and machine (issue "Fast on a GPU", the
rollout rows): one design at a time and a batched sweep.

    python benchmarks/micro/design_speed.py [--model pretrained:impact_plate_small] [--designs 64] [--batches 1 64]
                                      [--device cpu|cuda] [--threads 1] [--json design_speed_cpu.json]

Designs are drawn from the model's training preset (seeded); the solver simulates each one (its wall time per
design); the model predicts them with each batch size (wall time per design = batch wall time / designs). Reports
medians and the ratio solver ÷ prediction, and names the device.
"""
from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
from common import write_json  # noqa: E402
from hcmt.design.check import predict, solve  # noqa: E402
from hcmt.design.inputs import settings_of  # noqa: E402
from hcmt.inference.run import Run  # noqa: E402
from hcmt.sim.params import sample_design  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", default="pretrained:impact_plate_small")
    p.add_argument("--designs", type=int, default=64)
    p.add_argument("--batches", type=int, nargs="+", default=[1, 64])
    p.add_argument("--device", default=None)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--seed", type=int, default=123)
    p.add_argument("--json", default="design_speed_cpu.json")
    p.add_argument("--compile", nargs="+", default=["none"], help="inference modes to time (none, default, "
                   "reduce-overhead): each batch size is timed in each mode")
    a = p.parse_args()
    torch.set_num_threads(a.threads)
    run = Run.load(a.model, a.device)
    preset = run.meta["generator"]["preset"]
    rng = np.random.default_rng(a.seed)
    designs = [(f"d{i}", sample_design(rng, preset)) for i in range(a.designs)]
    settings = settings_of(run.meta)
    t0 = time.perf_counter()
    truth = solve(designs, settings)
    solver = np.array([t.wall_s for t in truth])
    rows = {}
    for batch, mode in ((b, m) for m in a.compile for b in a.batches):
        t1 = time.perf_counter()
        preds = predict(run, designs, batch=batch, progress=False, compile=mode)
        wall = time.perf_counter() - t1
        per = wall / len(designs)
        key = str(batch) if mode == "none" else f"{batch} compile={mode}"
        rows[key] = {"wall_s": wall, "per_design_s": per, "speedup_median_solver": float(np.median(solver) / per),
                            "peak_stress_error_pct_median": float(np.median(np.abs(
                                [100 * (q.summary["peak_plate_stress_mpa"] - t.summary["peak_plate_stress_mpa"])
                                 / t.summary["peak_plate_stress_mpa"] for q, t in zip(preds, truth)])))}
        print(f"batch {key}: {per:.3f} s per design ({wall:.1f} s for {len(designs)}, compilation included); solver "
              f"median {np.median(solver):.3f} s: speedup {rows[key]['speedup_median_solver']:.2f}x", flush=True)
    dev = str(run.device)
    name = torch.cuda.get_device_name(run.device) if run.device.type == "cuda" else (platform.processor() or
                                                                                        platform.machine())
    out = {"model": a.model, "device": f"{dev}: {name}", "threads": a.threads, "designs": a.designs,
           "solver_s_median": float(np.median(solver)), "solver_s_total": float(solver.sum()), "batches": rows,
           "wall_total_s": time.perf_counter() - t0,
           "command": f"python benchmarks/micro/design_speed.py --model {a.model} --designs {a.designs} --batches "
                      + " ".join(map(str, a.batches)) + f" --threads {a.threads} --compile " + " ".join(a.compile)}
    print(f"wrote {write_json(a.json, out)}")


if __name__ == "__main__":
    main()
