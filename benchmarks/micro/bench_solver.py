"""Seconds per Impact Plate trajectory of the built-in explicit FEM solver, on one core.

    .venv/bin/python benchmarks/micro/bench_solver.py --preset paper --n 5

Simulates ``n`` designs drawn as the generator draws them (seed 0, split train), one after the other in this
process (single-threaded: the solver uses no thread pool; BLAS threads are set to 1), and prints per trajectory:
nodes, substeps, wall and CPU time, microseconds per substep; then the mean. On a shared machine the CPU time is
the better figure (wall time includes waiting for the core). Target: <= 5 s per paper-preset
trajectory (52 frames x 0.002 ms).
"""

from __future__ import annotations

import argparse
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # one core, set before numpy loads
    os.environ.setdefault(var, "1")

import numpy as np  # noqa: E402

from hcmt.sim.driver import simulate  # noqa: E402
from hcmt.sim.params import Settings  # noqa: E402
from hcmt.sim.sampling import sample_design  # noqa: E402
from hcmt.sim.writer import trajectory_rng  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--preset", default="paper", choices=["paper", "small"])
    p.add_argument("--n", type=int, default=5, help="trajectories to time")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args()
    times, cpu = [], []
    for i in range(args.n):
        design = sample_design(trajectory_rng(args.seed, "train", i), args.preset)
        info = simulate(design, Settings()).info
        times.append(info.wall_time)
        cpu.append(info.cpu_time)
        print(
            f"{args.preset} #{i}: {info.num_nodes} nodes, {info.num_cells} cells, {info.substeps} substeps, "
            f"{info.wall_time:.2f} s wall, {info.cpu_time:.2f} s CPU "
            f"({1e6 * info.wall_time / info.substeps:.0f} us/substep)",
            flush=True,
        )
    print(
        f"mean {np.mean(times):.2f} s wall ({np.mean(cpu):.2f} s CPU) per {args.preset} trajectory "
        f"(wall min {np.min(times):.2f}, max {np.max(times):.2f}; "
        f"{os.cpu_count()} cpus on the machine, load average {os.getloadavg()[0]:.1f})"
    )


if __name__ == "__main__":
    main()
