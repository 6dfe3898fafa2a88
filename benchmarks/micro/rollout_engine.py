"""The rollout engine against the loop it replaced: seconds per design of the shipped model's design rollouts, one
at a time and batched, on one CPU thread.

    python benchmarks/micro/rollout_engine.py [--model pretrained:impact_plate_small] [--designs 8] [--batches 1 8]
        [--repeats 2] [--steps 0] [--threads 1] [--json rollout_engine_cpu.json]

The designs are drawn from the model's preset (seeded) and built as the design check builds them
(:func:`hcmt.design.prediction.design_trajectory`). ``old`` is :func:`old_rollout_batch`, a copy of the rollout loop
before the engine (kept here only, the reference of tests/inference/test_rollout_engine.py: each step built each
design's graph on the host with :func:`hcmt.domains.frames.input_graph`, collated them, ran the model and integrated
each design in a Python loop); ``new`` is :func:`hcmt.inference.rollout.rollout_batch` (the static graph merged
once, every step's graph built for the whole batch at once, the rollout on the model's device; on the CPU one
forward per block of at most ``CPU_BLOCK_NODES`` nodes). Both run eager (``compile="none"``).
Each repeat times, for every batch size, the old path then the new one on all the designs (the order alternates
between repeats, so both see the same load); the time per design is a whole pass's wall time (and CPU time, less
sensitive to other jobs on a shared machine) over the designs. Reported: the median per design of each path and
batch size, new ÷ old, the largest batch ÷ the smallest per path, and the largest difference between the two paths'
positions and stress. ``--steps N`` rolls out N model steps per design
(0: the whole recorded window).
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common, machine
from common import write_json  # noqa: E402
from hcmt.design.inputs import settings_of  # noqa: E402
from hcmt.design.prediction import design_trajectory  # noqa: E402
from hcmt.domains.adapters import integrate  # noqa: E402
from hcmt.domains.frames import input_graph  # noqa: E402
from hcmt.errors import InputError, RolloutError  # noqa: E402
from hcmt.graph.batch import collate  # noqa: E402
from hcmt.inference.rollout import rollout_batch  # noqa: E402
from hcmt.inference.run import Run  # noqa: E402
from hcmt.sim.sampling import sample_design  # noqa: E402
from machine import core_peak  # noqa: E402


@torch.no_grad()
def old_rollout_batch(model, adapter, trajs, radius: float, steps: int | None = None) -> list[dict]:
    """The rollout loop before the engine (eager only): per step, each trajectory's graph built on the host
    (:func:`input_graph`), collated, moved to the model's device; the output back on the host, each trajectory
    integrated and checked in a Python loop. The reference the engine must equal."""
    model.eval()
    device = next(model.parameters()).device
    lengths = {int(tr.world_pos.shape[0]) for tr in trajs}
    if len(lengths) != 1:
        raise InputError(f"trajectories of different lengths {sorted(lengths)} cannot roll out in one batch")
    (full,) = lengths
    h = adapter.history
    T = full if steps is None else min(full, steps + h + 1)
    pos = [[tr.world_pos[i] for i in range(h + 1)] for tr in trajs]
    stress = [[tr.stress[i] for i in range(h + 1)] if tr.stress is not None else None for tr in trajs]
    sizes = [tr.num_nodes for tr in trajs]
    elapsed = 0.0
    for t in range(h, T - 1):
        start = time.perf_counter()
        graphs, inputs = [], []
        for b, tr in enumerate(trajs):
            x, prev = pos[b][-1], pos[b][-2] if h else pos[b][-1]
            graphs.append(input_graph(tr, x, prev, tr.world_pos[t + 1], radius))
            inputs.append((x, prev))
        graph = collate(graphs)
        out = model.denormalize(model(graph.to(device), accumulate=False)).cpu()
        for b, (tr, o) in enumerate(zip(trajs, out.split(sizes))):
            x, prev = inputs[b]
            nxt, s = integrate(adapter, o, x, prev, tr.world_pos[t + 1], tr.static["node_type"])
            if not torch.isfinite(nxt).all() or (s is not None and not torch.isfinite(s).all()):
                raise RolloutError(
                    f"trajectory {tr.name}: the predicted state became non-finite at step {t + 1} "
                    f"(frame {t + 1} of {T}); the model diverged"
                )
            pos[b].append(nxt)
            if stress[b] is not None:
                stress[b].append(s if s is not None else tr.stress[t + 1])
        elapsed += time.perf_counter() - start
    per_step = 1e3 * elapsed / max(T - 1 - h, 1) / len(trajs)
    return [
        {
            "world_pos": torch.stack(p),
            "stress": torch.stack(s) if s is not None else None,
            "ms_per_step": per_step,
            "start": h + 1,
        }
        for p, s in zip(pos, stress)
    ]


def one_pass(fn, run, trajs: list, batch: int, steps: int | None) -> tuple[float, float, list[dict]]:
    """Wall and CPU seconds per design of rolling ``trajs`` out ``batch`` at a time with ``fn``, and the results."""
    t0, c0, results = time.perf_counter(), time.process_time(), []
    for first in range(0, len(trajs), batch):
        results += fn(run.model, run.adapter, trajs[first : first + batch], run.radius, steps)
    return (time.perf_counter() - t0) / len(trajs), (time.process_time() - c0) / len(trajs), results


def largest_difference(a: list[dict], b: list[dict]) -> dict:
    """The largest absolute difference of positions (mm) and stress (MPa) between two passes, and the scales."""
    pos = max(float((x["world_pos"] - y["world_pos"]).abs().max()) for x, y in zip(a, b))
    stress = max(float((x["stress"] - y["stress"]).abs().max()) for x, y in zip(a, b))
    return {
        "world_pos_abs": pos,
        "stress_abs": stress,
        "world_pos_scale": max(float(x["world_pos"].abs().max()) for x in a),
        "stress_scale": max(float(x["stress"].abs().max()) for x in a),
    }


def measure(run, trajs: list, batches: list[int], repeats: int, steps: int | None) -> tuple[dict, dict]:
    """Per batch size, each path's wall and CPU seconds per design in every repeat (old and new interleaved), and
    the largest difference between the paths."""
    paths = {"old": old_rollout_batch, "new": lambda m, a, t, r, s: rollout_batch(m, a, t, r, s)}
    times = {b: {"old": [], "new": [], "old_cpu": [], "new_cpu": []} for b in batches}
    diff: dict = {}
    for k in range(repeats):
        for b in batches:
            order = ("old", "new") if k % 2 == 0 else ("new", "old")
            got = {}
            for name in order:
                per, cpu, got[name] = one_pass(paths[name], run, trajs, b, steps)
                times[b][name].append(per)
                times[b][f"{name}_cpu"].append(cpu)
                print(f"repeat {k + 1} batch {b} {name}: {per:.3f} s per design ({cpu:.3f} s CPU)", flush=True)
            d = largest_difference(got["new"], got["old"])
            diff = {key: max(diff.get(key, 0.0), v) for key, v in d.items()}
    return times, diff


def summary(times: dict, batches: list[int]) -> dict:
    """Medians per batch size (wall and CPU seconds per design), new ÷ old, and the largest batch ÷ the smallest."""
    rows = {}
    for b in batches:
        med = {k: statistics.median(v) for k, v in times[b].items()}
        rows[str(b)] = {
            "old_s_per_design": med["old"],
            "new_s_per_design": med["new"],
            "new_over_old": med["new"] / med["old"],
            "old_cpu_s_per_design": med["old_cpu"],
            "new_cpu_s_per_design": med["new_cpu"],
            "new_over_old_cpu": med["new_cpu"] / med["old_cpu"],
            **{f"{k}_runs_s": v for k, v in times[b].items()},
        }
    lo, hi = str(min(batches)), str(max(batches))
    scaling = {
        f"{p}{c}": rows[hi][f"{p}{c}_s_per_design"] / rows[lo][f"{p}{c}_s_per_design"]
        for p in ("old", "new")
        for c in ("", "_cpu")
    }
    return {"batches": rows, f"batch_{hi}_over_batch_{lo}": scaling}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", default="pretrained:impact_plate_small")
    p.add_argument("--designs", type=int, default=8)
    p.add_argument("--batches", type=int, nargs="+", default=[1, 8])
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--steps", type=int, default=0, help="model steps per design (0: the whole recorded window)")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--seed", type=int, default=123)
    p.add_argument("--json", default="rollout_engine_cpu.json")
    a = p.parse_args()
    torch.set_num_threads(a.threads)
    run = Run.load(a.model, "cpu")
    settings, rng = settings_of(run.meta), np.random.default_rng(a.seed)
    trajs = [
        design_trajectory(run, f"d{i}", sample_design(rng, run.meta["generator"]["preset"]), settings)[0]
        for i in range(a.designs)
    ]
    steps = a.steps or None
    load = os.getloadavg()[0]
    times, diff = measure(run, trajs, a.batches, a.repeats, steps)
    out = {
        "model": a.model,
        "device": f"cpu: {core_peak()['cpu']} ({platform.machine()})",
        "threads": a.threads,
        "cpus": os.cpu_count(),
        "load_average_before": load,
        "load_average_after": os.getloadavg()[0],
        "torch": torch.__version__,
        "designs": a.designs,
        "repeats": a.repeats,
        "model_steps_per_design": (steps or settings.frames - 1 - run.adapter.history),
        "nodes_per_design": [tr.num_nodes for tr in trajs],
        **summary(times, a.batches),
        "largest_difference_new_old": diff,
        "command": "python benchmarks/micro/rollout_engine.py " + " ".join(sys.argv[1:]),
    }
    for b, row in out["batches"].items():
        print(
            f"batch {b}: old {row['old_s_per_design']:.3f} s, new {row['new_s_per_design']:.3f} s per design "
            f"(new/old {row['new_over_old']:.3f}); CPU old {row['old_cpu_s_per_design']:.3f} s, new "
            f"{row['new_cpu_s_per_design']:.3f} s (new/old {row['new_over_old_cpu']:.3f})"
        )
    print(f"largest batch / smallest, per design: {out[next(k for k in out if k.startswith('batch_'))]}")
    print(f"largest difference new - old: {diff}")
    print(f"wrote {write_json(a.json, out)}")


if __name__ == "__main__":
    main()
