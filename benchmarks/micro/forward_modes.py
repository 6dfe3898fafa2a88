"""One rollout step of the shipped model in every inference mode this CPU offers: where the
design check's time goes and what each option buys.

    python benchmarks/micro/forward_modes.py [--model pretrained:impact_plate_small] [--threads 1] [--repeats 30]
        [--modes eager compiled-static compiled-dynamic frozen frozen-bf16 bf16] [--json forward_modes_cpu.json]

The graph is a design of the model's preset (seeded) at its first rollout step; every mode's median forward time
(ms), its output's relative difference from the eager fp32 forward (``‖y − y_eager‖ / ‖y_eager‖``), the matmul
FLOPs of one forward (torch.utils.flop_counter) and the achieved GFLOP/s. Modes: ``eager``; ``compiled-static``
(Inductor on the padded graph, static shapes: what training on CUDA uses); ``compiled-dynamic`` (symbolic sizes: what
rollouts use); ``frozen`` (Inductor's ``freezing``: weights as constants, prepacked); ``frozen-bf16`` and ``bf16``
(autocast to bfloat16: matmuls on AMX where the CPU has it; not exact); ``aot`` (torch.export with symbolic
sizes and AOTInductor, :mod:`hcmt.models.export`: built once per machine, then loaded). Compilation times are reported
separately.
"""

from __future__ import annotations

import argparse
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import torch
from torch.utils.flop_counter import FlopCounterMode

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
from common import write_json  # noqa: E402
from hcmt.design.inputs import settings_of  # noqa: E402
from hcmt.design.prediction import design_trajectory  # noqa: E402
from hcmt.domains.frames import input_graph  # noqa: E402
from hcmt.graph.batch import PadSizes, collate, pad_graph  # noqa: E402
from hcmt.inference.run import Run  # noqa: E402
from hcmt.models.base import compile_simulator  # noqa: E402
from hcmt.models.export import exported_forward  # noqa: E402
from hcmt.sim.sampling import sample_design  # noqa: E402

MODES = ("eager", "compiled-static", "compiled-dynamic", "frozen", "frozen-bf16", "bf16", "aot")


def timed(fn, graph, repeats: int) -> float:
    with torch.no_grad():
        for _ in range(3):
            fn(graph)
        ts = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            fn(graph)
            ts.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(ts)


def forward_of(model, mode: str, graph):
    """(callable on a graph, whether it takes the padded graph)."""
    import torch._inductor.config as inductor

    if mode == "aot":  # built from (or loaded from the cache for) this graph's kind: sizes symbolic
        return exported_forward(model, graph), False

    inductor.freezing = mode.startswith("frozen")
    if mode in ("eager", "bf16"):
        net = model
    else:
        torch._dynamo.reset()
        net = compile_simulator(model, "default", dynamic=mode == "compiled-dynamic")
    bf16 = mode.endswith("bf16")

    def fn(graph):
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16):
            return net(graph, accumulate=False).float()

    return fn, mode not in ("eager", "bf16", "compiled-dynamic")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", default="pretrained:impact_plate_small")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--repeats", type=int, default=30)
    p.add_argument("--seed", type=int, default=5)
    p.add_argument("--modes", nargs="+", default=list(MODES), choices=MODES)
    p.add_argument("--json", default="forward_modes_cpu.json")
    a = p.parse_args()
    torch.set_num_threads(a.threads)
    run = Run.load(a.model, "cpu")
    model = run.model.eval()
    design = sample_design(np.random.default_rng(a.seed), run.meta["generator"]["preset"])
    tr, _ = design_trajectory(run, "d", design, settings_of(run.meta))
    graph = input_graph(tr, tr.world_pos[1], tr.world_pos[0], tr.world_pos[2], run.radius)
    padded = pad_graph(collate([graph]), PadSizes.of([graph]))
    with torch.no_grad(), FlopCounterMode(display=False) as fc:
        ref = model(graph, accumulate=False)
    flops = fc.get_total_flops()
    rows = {}
    for mode in a.modes:
        fn, pads = forward_of(model, mode, graph)
        x = padded if pads else graph
        t0 = time.perf_counter()
        with torch.no_grad():
            out = fn(x)[: graph.num_nodes]
        first = time.perf_counter() - t0
        ms = timed(fn, x, a.repeats)
        rows[mode] = {
            "ms": ms,
            "first_call_s": first,
            "gflop_per_s": flops / ms / 1e6,
            "rel_diff": float((out - ref).norm() / ref.norm()),
        }
        print(
            f"{mode:17s} {ms:7.2f} ms  {flops / ms / 1e6:5.1f} GFLOP/s  first call {first:6.1f} s  "
            f"rel diff {rows[mode]['rel_diff']:.1e}",
            flush=True,
        )
    out = {
        "model": a.model,
        "device": f"cpu: {platform.processor() or platform.machine()}",
        "threads": a.threads,
        "nodes": graph.num_nodes,
        "mesh_edges": int(graph.mesh_edges.shape[1]),
        "contact_edges": int(graph.contact_edges.shape[1]),
        "padded_nodes": padded.num_nodes,
        "gflop_per_forward": flops / 1e9,
        "modes": rows,
        "command": "python benchmarks/micro/forward_modes.py " + " ".join(sys.argv[1:]),
    }
    print(f"wrote {write_json(a.json, out)}")


if __name__ == "__main__":
    main()
