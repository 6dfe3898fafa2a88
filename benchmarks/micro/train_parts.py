"""Where a training step's time goes: the trainer's compiled CPU step taken apart.

    python benchmarks/micro/train_parts.py --data DATA [--threads 1 2] [--recipes cpu ship] [--steps 60] [--warm 40]
        [--rounds 1] [--json train_parts_cpu.json]

For each thread count and recipe (those of benchmarks/micro/train_speed.py), a fresh process builds the trainer as
``hcmt train`` does (config ``impact_plate_cpu``, ``train.compile=default``: what a run of 5,000 steps or more
gets), runs ``--warm`` steps (compilation) and times ``--steps`` steps twice: once with plain clocks (means), split
into the batch (``next`` of the trainer's loader: reading, graph building, and in the shipped recipe the pushforward
item's forward), the forward with the loss, the backward and Adam; once under ``torch.profiler`` (with the FLOPs of
the matrix products and Inductor's kernels recorded), which sums the self time of the matrix products
(``aten::mm``/``addmm``/``bmm``, with their GFLOP/s) and of Inductor's fused kernels, means per step. The matrix
products' GFLOP/s against the core's fp32 peak (:func:`machine.core_peak`, recorded as the peers' benchmark records
it) say how much of the step is already at the hardware's limit; the plain step less the two is what runs outside
both (Python, the compiled wrapper, autograd, Adam, the batch). With ``--rounds R`` every row runs R times, each in
a fresh process, the rows interleaved, and each number is the median over its rounds.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from train_speed import RECIPES  # noqa: E402

MATMUL = ("aten::mm", "aten::addmm", "aten::bmm")
TRAIN_SETS = (
    "train.valid_every=0",
    "train.normalizer_steps=10",
    "train.checkpoint_every=100000",
    "train.log_every=10",
    "train.compile=default",
)


def trainer(data: Path, recipe: str, steps: int, out: Path):
    from hcmt.config import load_config
    from hcmt.training.trainer import Trainer

    cfg = load_config("impact_plate_cpu", [*RECIPES[recipe], *TRAIN_SETS, f"train.steps={steps}"])
    return Trainer(cfg, data, "hcmt", out, seed=0, resume=False, device="cpu", progress=False)


def timed_steps(tr, loader, steps: int) -> dict:
    """Per-part wall times (ms, means over ``steps``: a throughput; the shipped recipe's steps are two kinds, with and
    without a pushforward item) of :meth:`Trainer.step`, unchanged: marks taken as it enters its ``_update`` (after
    the forward and loss) and around Adam's step (after the backward)."""
    parts = {k: [] for k in ("batch", "forward_loss", "backward", "adam", "step")}
    update, adam = tr._update, tr.opt.step
    marks: list[float] = []

    def marked_update(loss, lr):
        marks.append(time.perf_counter())
        update(loss, lr)

    def marked_adam(*args, **kwargs):
        marks.append(time.perf_counter())
        out = adam(*args, **kwargs)
        marks.append(time.perf_counter())
        return out

    tr._update, tr.opt.step = marked_update, marked_adam
    try:
        for _ in range(steps):
            marks.clear()
            t0 = time.perf_counter()
            batch = next(loader)
            t1 = time.perf_counter()
            tr.step(*batch)
            t2 = time.perf_counter()
            for k, v in zip(parts, (t1 - t0, marks[0] - t1, marks[1] - marks[0], marks[2] - marks[1], t2 - t0)):
                parts[k].append(v)
    finally:
        del tr._update, tr.opt.step  # the class's methods again
    return {k: 1e3 * statistics.fmean(v) for k, v in parts.items()}


def profiled_steps(tr, loader, steps: int) -> dict:
    """Per step (means over ``steps`` under the profiler): the self time of the matrix products and their GFLOP/s,
    the self time of Inductor's kernels, and the profiled step's total."""
    import torch._inductor.config as inductor
    from torch.profiler import ProfilerActivity, profile

    assert inductor.cpp.enable_kernel_profile  # set before compiling (main): the kernels appear as events
    with profile(activities=[ProfilerActivity.CPU], with_flops=True) as prof:
        for _ in range(steps):
            tr.step(*next(loader))
    events = prof.key_averages()
    mm = [e for e in events if e.key in MATMUL]
    kernels = [e for e in events if "cpp_fused" in e.key]
    mm_us = sum(e.self_cpu_time_total for e in mm)
    flops = sum(e.flops for e in mm)
    return {
        "profiled_step_ms": sum(e.self_cpu_time_total for e in events) / 1e3 / steps,
        "matmul_ms": mm_us / 1e3 / steps,
        "matmul_calls": sum(e.count for e in mm) / steps,
        "matmul_gflop": flops / 1e9 / steps,
        "matmul_gflops": flops / 1e3 / mm_us if mm_us else None,
        "inductor_kernels_ms": sum(e.self_cpu_time_total for e in kernels) / 1e3 / steps,
        "inductor_kernel_calls": sum(e.count for e in kernels) / steps,
    }


def one(data: Path, recipe: str, threads: int, steps: int, warm: int) -> dict:
    import torch
    import torch._inductor.config as inductor

    inductor.cpp.enable_kernel_profile = True
    torch.set_num_threads(threads)
    with tempfile.TemporaryDirectory(prefix="train_parts_") as tmp:
        tr = trainer(data, recipe, warm + 2 * steps, Path(tmp) / "run")
        loader = tr._loader(warm + 2 * steps)
        tr.model.train()
        t0 = time.perf_counter()
        for _ in range(warm):
            tr.step(*next(loader))
        row = {
            "warm_s": time.perf_counter() - t0,
            **timed_steps(tr, loader, steps),
            **profiled_steps(tr, loader, steps),
        }
    return {"recipe": recipe, "threads": threads, "steps": steps, "warm": warm, **row}


def median_row(rounds: list[dict]) -> dict:
    """One row from its rounds: each number the median over the rounds (the rounds' steps: ``rounds``)."""
    first = rounds[0]
    row = {k: statistics.median(r[k] for r in rounds) if isinstance(v, float) else v for k, v in first.items()}
    return {**row, "rounds": len(rounds), "step_by_round": [r["step"] for r in rounds]}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", type=Path, required=True, help="a `small` preset dataset with a train split")
    p.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    p.add_argument("--recipes", nargs="+", default=list(RECIPES), choices=list(RECIPES))
    p.add_argument("--steps", type=int, default=60)
    p.add_argument("--warm", type=int, default=40)
    p.add_argument("--rounds", type=int, default=1, help="fresh processes per row, interleaved; each field's median")
    p.add_argument("--json", default="train_parts_cpu.json", help="a name in benchmarks/results or a path")
    p.add_argument("--one", nargs=2, metavar=("RECIPE", "THREADS"), help=argparse.SUPPRESS)  # the child process
    a = p.parse_args()
    if a.one:
        print(json.dumps(one(a.data.resolve(), a.one[0], int(a.one[1]), a.steps, a.warm)))
        return
    from common import write_json  # benchmarks/common.py (the parent folder)
    from hcmt.models.export import cpu_name
    from machine import core_peak

    runs: dict = {}
    for _ in range(a.rounds):  # rounds interleaved: a load change on the shared machine falls on every row alike
        for threads in a.threads:
            for recipe in a.recipes:
                env = dict(os.environ, OMP_NUM_THREADS=str(threads))
                out = subprocess.run(
                    [
                        sys.executable,
                        __file__,
                        "--data",
                        str(a.data),
                        "--steps",
                        str(a.steps),
                        "--warm",
                        str(a.warm),
                        "--one",
                        recipe,
                        str(threads),
                    ],
                    env=env,
                    check=True,
                    capture_output=True,
                    text=True,
                ).stdout
                got = {**json.loads(out.strip().splitlines()[-1]), "load_1min": os.getloadavg()[0]}
                runs.setdefault((threads, recipe), []).append(got)
                print(json.dumps(got), flush=True)
    rows = [median_row(r) for r in runs.values()]
    commit = subprocess.run(
        ["git", "-C", str(Path(__file__).parent), "rev-parse", "--short", "HEAD"], capture_output=True, text=True
    ).stdout.strip()
    path = write_json(
        a.json,
        {
            "command": "python benchmarks/micro/train_parts.py " + " ".join(sys.argv[1:]),
            "commit": commit,
            "cpu": cpu_name(),
            "device": platform.processor() or platform.machine(),
            "core_peak": core_peak(),
            "data": str(a.data),
            "rows": rows,
        },
    )
    print(f"wrote {path}")


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
    main()
