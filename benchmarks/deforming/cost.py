"""Seconds per Deforming Plate trajectory on one core (docs/solver.md, "Deforming Plate: cost").

    OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/deforming/cost.py [--n 3] [--frames 400] [--seed 0]

Simulates the first ``n`` training designs of ``hcmt generate deforming-plate --seed S`` (the generator's own
draws) and reports each one's wall and CPU seconds, nodes, Newton iterations and substeps. Writes
benchmarks/results/deforming_cost.json. Cost: about n x 30 s.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")  # one core: set before numpy loads BLAS

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
from common import write_json  # noqa: E402
from hcmt.sim.deforming import simulate_plate  # noqa: E402
from hcmt.sim.plate_params import PlateSettings, sample_plate_design  # noqa: E402
from hcmt.sim.writer import trajectory_rng  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=3)
    p.add_argument("--frames", type=int, default=400)
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args()
    rows = []
    for i in range(a.n):
        design = sample_plate_design(trajectory_rng(a.seed, "train", i))
        wall, cpu = time.perf_counter(), time.process_time()
        r = simulate_plate(design, PlateSettings(frames=a.frames))
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        its = json.loads(r["attrs"]["newton_iterations"])
        rows.append(
            {
                "index": i,
                "shape": design.shape,
                "path": design.path,
                "nodes": r["info"]["num_nodes"],
                "wall_s": round(wall, 2),
                "cpu_s": round(cpu, 2),
                "newton_iterations": sum(its),
                "iterations_per_step": round(sum(its) / len(its), 3),
                "max_iterations": max(its),
                "max_substeps": max(json.loads(r["attrs"]["substeps"])),
            }
        )
        print(rows[-1], flush=True)
    cpu = [r["cpu_s"] for r in rows]
    summary = {
        "frames": a.frames,
        "seed": a.seed,
        "mean_cpu_s": round(sum(cpu) / len(cpu), 2),
        "load_average": os.getloadavg()[0],
        "rows": rows,
        "command": "OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/deforming/cost.py "
        f"--n {a.n} --frames {a.frames} --seed {a.seed}",
    }
    print(f"mean CPU seconds per trajectory: {summary['mean_cpu_s']}")
    write_json("deforming_cost.json", summary)


if __name__ == "__main__":
    main()
