"""Learned design check against the built-in solver on the same designs and machine (the GPU
goals' rollout rows): one design at a time and a batched sweep.

    python benchmarks/micro/design_speed.py [--model pretrained:impact_plate_small] [--designs 64] [--batches 1 64]
                                      [--device cpu|cuda] [--threads 1] [--json design_speed_cpu.json]

Designs are drawn from the model's training preset (seeded); for each batch size (and compile mode) the design
check (:func:`hcmt.design.check.check_designs` with ``verify=True``) predicts them ``batch`` at a time (wall time
per design = batch wall time / designs) and the solver simulates each chunk's designs right after it, so the model
and the solver alternate per chunk under the same load (one chunk: the batch, then the solver; each row's
``speedup_measured`` says which); the solver thus runs once per design and configuration, as ``hcmt simulate`` runs
it (between-frame peaks recorded only for a model that learned ``stress_max``: ``speedup_measured``'s ``solver``).
Reports medians and the ratio solver ÷ prediction, and names the device.
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
from hcmt.design.check import check_designs  # noqa: E402
from hcmt.inference.run import Run  # noqa: E402
from hcmt.sim.sampling import sample_design  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", default="pretrained:impact_plate_small")
    p.add_argument("--designs", type=int, default=64)
    p.add_argument("--batches", type=int, nargs="+", default=[1, 64])
    p.add_argument("--device", default=None)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--seed", type=int, default=123)
    p.add_argument("--json", default="design_speed_cpu.json")
    p.add_argument(
        "--compile",
        nargs="+",
        default=["none"],
        help="inference modes to time (none, default, reduce-overhead): each batch size is timed in each mode",
    )
    a = p.parse_args()
    torch.set_num_threads(a.threads)
    run = Run.load(a.model, a.device)
    preset = run.meta["generator"]["preset"]
    rng = np.random.default_rng(a.seed)
    designs = [(f"d{i}", sample_design(rng, preset)) for i in range(a.designs)]
    t0 = time.perf_counter()
    rows, solver = {}, []
    for batch, mode in ((b, m) for m in a.compile for b in a.batches):
        check = check_designs(run, designs, batch=batch, verify=True, compile=mode, progress=False, surrogate=False)
        mine = np.array([t.wall_s for t in check.truth])
        solver += list(mine)
        per = check.wall_s / len(designs)
        key = str(batch) if mode == "none" else f"{batch} compile={mode}"
        verified, measured = check.verified, check.verified.speedup_measured
        rows[key] = {
            "wall_s": check.wall_s,
            "per_design_s": per,
            "speedup_median_solver": float(np.median(mine) / per),
            "peak_stress_error_pct_median": verified.peak_plate_stress_error_pct.median,
            "solver_s_median": float(np.median(mine)),
            "speedup_measured": measured.to_json(),
        }
        print(
            f"batch {key}: {per:.3f} s per design ({check.wall_s:.1f} s for {len(designs)}, compilation included); "
            f"solver median {np.median(mine):.3f} s: speedup {rows[key]['speedup_median_solver']:.2f}x "
            f"({measured.how})",
            flush=True,
        )
    solver = np.array(solver)
    dev = str(run.device)
    name = (
        torch.cuda.get_device_name(run.device)
        if run.device.type == "cuda"
        else (platform.processor() or platform.machine())
    )
    out = {
        "model": a.model,
        "device": f"{dev}: {name}",
        "threads": a.threads,
        "designs": a.designs,
        "solver_s_median": float(np.median(solver)),
        "solver_s_total": float(solver.sum()),
        "solver_runs": len(solver),
        "batches": rows,
        "wall_total_s": time.perf_counter() - t0,
        "command": f"python benchmarks/micro/design_speed.py --model {a.model} --designs {a.designs} --batches "
        + " ".join(map(str, a.batches))
        + f" --threads {a.threads} --compile "
        + " ".join(a.compile),
    }
    print(f"wrote {write_json(a.json, out)}")


if __name__ == "__main__":
    main()
