"""Train-step and inference time of HCMT, MeshGraphNets and Graph Transformer on a paper-size Impact Plate graph.

    .venv/bin/python benchmarks/micro/bench_models.py [--steps 10] [--threads N] [--device cpu|cuda|all] [--json FILE]

The graph: the ``paper`` preset mesh of :mod:`hcmt.sim.mesh` (about 2,200 nodes), its 6-level hierarchy
(bi-stride + Delaunay) and the contact edges of radius 0.4 (Table 8) at a slightly perturbed position. Models use
the paper's Impact Plate settings (hidden 128; HCMT L_C = 2, λ = 6, L_H = 13; MGN and GT 15 blocks, GT 4 heads).
A train step is forward + MSE loss on normalized targets + backward + Adam step; inference is a no-grad forward in
eval mode. Models are timed in interleaved rounds (one step of each per round) so that load drift on a shared
machine hits them alike; the median over rounds is reported. The paper measured 51.12 ms (HCMT) and 51.56 ms (MGN)
per training step on its GPU (appendix, Table 10).

``--compile``: also the trainer's compiled step (``train.compile``): the graph padded to static sizes
(:func:`hcmt.graph.batch.pad_graph`), normalizers accumulated eagerly, then ``torch.compile`` (mode
``reduce-overhead``, i.e. CUDA graphs, on CUDA; inductor's default on the CPU) of forward + backward, Adam fused on
CUDA. The compile time (first calls) is reported apart. ``--batches 1 8 32``: training throughput, paper-size
samples per second, for batches of that many copies of the graph (HCMT and MGN; eager, and compiled with
``--compile``).
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np
import torch

from hcmt.domains.spec import build_for_dataset, dataset_spec
from hcmt.graph.batch import PadSizes, collate, pad_graph, pad_rows
from hcmt.graph.build import frame_graph
from hcmt.graph.hierarchy import build_hierarchy
from hcmt.models.base import compile_simulator
from hcmt.sim.mesh import preset_mesh


def impact_plate_graph(seed: int = 0):
    spec = dataset_spec("impact_plate")
    rng = np.random.default_rng(seed)
    mesh = preset_mesh("paper")
    hierarchy = build_hierarchy(mesh["mesh_pos"], mesh["cells"], mesh["node_type"], levels=spec["levels"])
    mesh_pos = torch.from_numpy(mesh["mesh_pos"]).float()
    world_pos = mesh_pos + torch.from_numpy(rng.normal(scale=0.01, size=mesh_pos.shape)).float()
    one_hot = torch.nn.functional.one_hot(torch.from_numpy(mesh["node_type"]), 9).float()
    feats = torch.cat([one_hot, torch.from_numpy(rng.normal(size=(len(mesh_pos), 4))).float()], 1)
    return frame_graph(feats, mesh_pos, world_pos, hierarchy, spec["radius"])


def _sync(device):
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def _step_fn(model, graph, target, opt, compiled, mask, dynamic: bool = False):
    """The trainer's step: eager (accumulating forward) or compiled (eager accumulation, compiled forward; with
    ``dynamic`` symbolic sizes on the graph as it is, the trainer's CPU path, else static shapes)."""
    net = model
    if compiled:
        net = compile_simulator(model, "reduce-overhead" if graph.node_features.is_cuda else "default", dynamic=dynamic)

    def step():
        model.train()
        if compiled:
            model.accumulate(graph, target)
            out, tgt = net(graph, accumulate=False), model.normalize_target(target, accumulate=False)
        else:
            out, tgt = model(graph, accumulate=True), model.normalize_target(target, accumulate=True)
        loss = ((out - tgt).square() * mask).sum() / mask.sum()
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()

    def infer():
        model.eval()
        with torch.no_grad():
            net(graph, accumulate=False)

    return step, infer


def bench_modes(device: torch.device, steps: int, batches: list[int], compile_: bool, warmup: int = 3) -> dict:
    """Eager vs compiled train step and inference (batch 1), and throughput per batch size, HCMT and MGN."""
    base = impact_plate_graph()
    out_dim = dataset_spec("impact_plate")["out"]
    modes = ["eager", "compiled"] if compile_ else ["eager"]
    rows = []
    for name in ("hcmt", "mgn"):
        for batch in batches:
            g = collate([base] * batch)
            target = torch.randn(g.num_nodes, out_dim)
            for mode in modes:
                torch.manual_seed(0)
                model = build_for_dataset(name, "impact_plate").to(device)
                opt = torch.optim.Adam(model.parameters(), lr=1e-4, fused=device.type == "cuda")
                graph, tgt = g, target
                if mode == "compiled":
                    graph = pad_graph(g, PadSizes.of([g]))
                    tgt = pad_rows(target, graph.num_nodes)[0]
                graph, tgt = graph.to(device), tgt.to(device)
                mask = (graph.node_mask if graph.node_mask is not None else torch.ones(graph.num_nodes, device=device))[
                    :, None
                ]  # the loss over real rows only
                step, infer = _step_fn(model, graph, tgt, opt, mode == "compiled", mask)
                row = {"model": name, "mode": mode, "batch": batch, "nodes": g.num_nodes}
                for kind, fn in (("train", step), ("inference", infer)):
                    if kind == "inference" and batch != 1:
                        continue
                    _sync(device)
                    t0 = time.perf_counter()
                    for _ in range(warmup):
                        fn()
                    _sync(device)
                    row[f"{kind}_warmup_s"] = time.perf_counter() - t0  # includes compilation when compiled
                    times = []
                    for _ in range(steps):
                        _sync(device)
                        t0 = time.perf_counter()
                        fn()
                        _sync(device)
                        times.append(1000 * (time.perf_counter() - t0))
                    row[f"{kind}_ms"] = statistics.median(times)
                row["samples_per_s"] = 1000 * batch / row["train_ms"]
                rows.append(row)
                print(
                    f"{name:5} {mode:8} batch {batch:3}: train {row['train_ms']:9.1f} ms "
                    f"({row['samples_per_s']:7.2f} samples/s)"
                    + (f", inference {row['inference_ms']:8.1f} ms" if "inference_ms" in row else "")
                    + f", warm-up {row['train_warmup_s']:.1f} s",
                    flush=True,
                )
    return {
        "device": str(device) if device.type == "cpu" else torch.cuda.get_device_name(device),
        "threads": torch.get_num_threads(),
        "nodes": base.num_nodes,
        "steps": steps,
        "rows": rows,
    }


def bench(device: torch.device, steps: int, warmup: int = 3) -> dict:
    graph = impact_plate_graph().to(device)
    target = torch.randn(graph.num_nodes, dataset_spec("impact_plate")["out"], device=device)
    models = {name: build_for_dataset(name, "impact_plate").to(device) for name in ("hcmt", "mgn", "gt")}
    opts = {name: torch.optim.Adam(m.parameters(), lr=1e-4) for name, m in models.items()}
    times = {name: {"train": [], "inference": []} for name in models}

    def train_step(name):
        m = models[name].train()
        loss = (m(graph) - m.normalize_target(target)).square().mean()
        opts[name].zero_grad(set_to_none=True)
        loss.backward()
        opts[name].step()

    def infer(name):
        m = models[name].eval()
        with torch.no_grad():
            m(graph)

    for kind, fn in (("train", train_step), ("inference", infer)):
        for r in range(warmup + steps):
            for name in models:
                _sync(device)
                t0 = time.perf_counter()
                fn(name)
                _sync(device)
                if r >= warmup:
                    times[name][kind].append(1000 * (time.perf_counter() - t0))
    result = {
        "device": str(device) if device.type == "cpu" else torch.cuda.get_device_name(device),
        "threads": torch.get_num_threads(),
        "nodes": graph.num_nodes,
        "mesh_edges": int(graph.mesh_edges.shape[1]),
        "contact_edges": int(graph.contact_edges.shape[1]),
        "level_nodes": [len(p) for p in graph.pool],
        "models": {},
    }
    for name, m in models.items():
        result["models"][name] = {
            "parameters": sum(p.numel() for p in m.parameters()),
            "train_ms": statistics.median(times[name]["train"]),
            "inference_ms": statistics.median(times[name]["inference"]),
        }
    mods = result["models"]
    result["hcmt_over_mgn_train"] = mods["hcmt"]["train_ms"] / mods["mgn"]["train_ms"]
    result["hcmt_over_mgn_inference"] = mods["hcmt"]["inference_ms"] / mods["mgn"]["inference_ms"]
    return result


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=10, help="timed rounds per model (median reported)")
    p.add_argument("--threads", type=int, default=None, help="torch CPU threads (default: torch's)")
    p.add_argument("--device", choices=("cpu", "cuda", "all"), default="all")
    p.add_argument("--json", default=None, help="also write the results to this JSON file")
    p.add_argument("--compile", action="store_true", help="eager vs compiled step (HCMT, MGN)")
    p.add_argument("--batches", type=int, nargs="+", help="training throughput at these batch sizes (HCMT, MGN)")
    args = p.parse_args(argv)
    if args.threads:
        torch.set_num_threads(args.threads)
    devices = [torch.device("cpu")] if args.device in ("cpu", "all") else []
    if args.device in ("cuda", "all") and torch.cuda.is_available():
        devices.append(torch.device("cuda"))
    elif args.device == "cuda":
        p.error("no CUDA device available")
    results = []
    if args.compile or args.batches:
        for device in devices:
            results.append(bench_modes(device, args.steps, args.batches or [1], args.compile))
        if args.json:
            with open(args.json, "w") as f:
                json.dump(results, f, indent=2)
        return 0
    for device in devices:
        torch.manual_seed(0)
        r = bench(device, args.steps)
        results.append(r)
        print(
            f"\n{r['device']} ({r['threads']} threads): {r['nodes']} nodes, {r['mesh_edges']} mesh edges, "
            f"{r['contact_edges']} contact edges, levels {r['level_nodes']}"
        )
        print(f"{'model':6} {'parameters':>11} {'train ms':>9} {'infer ms':>9}")
        for name, m in r["models"].items():
            print(f"{name:6} {m['parameters']:>11,} {m['train_ms']:>9.1f} {m['inference_ms']:>9.1f}")
        print(f"HCMT / MGN: train {r['hcmt_over_mgn_train']:.2f}, inference {r['hcmt_over_mgn_inference']:.2f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
