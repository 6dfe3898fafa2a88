"""hcmt's contestant: MGN or HCMT (``official`` attention, no FFN bias: the authors' variant), eager or compiled.

    PYTHONPATH=src python benchmarks/peers/worker_hcmt.py GRAPH.npz {mgn|hcmt} {eager|compiled}

A train step is the trainer's: forward with normalizer accumulation, MSE over real nodes on normalized targets,
backward, Adam (lr 1e-4). Compiled: as the trainer compiles on the CPU, the graph as it is (no padding) with
symbolic sizes, the normalizers accumulated eagerly, the forward ``torch.compile``\\ d
(:func:`hcmt.models.base.compile_simulator` with ``dynamic=True``, inductor's default; its cache persists in
``~/.cache/hcmt/inductor``). Inference: a no-grad forward in eval mode.
The FLOPs of one eager train step and one inference are counted with ``torch.utils.flop_counter`` (matmuls only)."""

from __future__ import annotations

import sys
from pathlib import Path

from protocol import one_thread, serve, warm_up

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: micro.bench_models

one_thread()

import numpy as np  # noqa: E402
import torch  # noqa: E402
from torch.utils.flop_counter import FlopCounterMode  # noqa: E402

from hcmt.domains.spec import build_for_dataset  # noqa: E402
from hcmt.graph.batch import Graph  # noqa: E402
from micro.bench_models import _step_fn as train_and_infer  # noqa: E402


def load_graph(path: str) -> tuple[Graph, int]:
    d = np.load(path)
    t = {k: torch.from_numpy(v) for k, v in d.items() if k != "out_dim"}
    levels = sum(k.startswith("pool_") for k in d)
    g = Graph(
        t["node_features"],
        t["mesh_edges"],
        t["mesh_features"],
        t["contact_edges"],
        t["contact_features"],
        [t[f"pool_{i}"] for i in range(levels)],
        [t[f"level_edges_{i}"] for i in range(levels)],
        [t[f"level_features_{i}"] for i in range(levels)],
    )
    return g, int(d["out_dim"])


def contestant(path: str, name: str, mode: str):
    torch.set_num_threads(1)
    torch.manual_seed(0)
    graph, out = load_graph(path)
    target = torch.randn(graph.num_nodes, out)
    extra = dict(attention="official", ffn_bias=False) if name == "hcmt" else {}
    model = build_for_dataset(name, "impact_plate", **extra)
    opt = torch.optim.Adam(model.parameters(), lr=1e-4)
    mask = torch.ones(graph.num_nodes, 1)
    train, infer = train_and_infer(model, graph, target, opt, mode == "compiled", mask, dynamic=True)  # the trainer's

    info = {
        "framework": f"hcmt (torch {torch.__version__})",
        "model": name,
        "mode": mode,
        "parameters": sum(p.numel() for p in model.parameters()),
        "nodes": int(mask.sum()),
    }
    # the warm-up includes compiling (or loading it from the cache); FLOPs counted eagerly only
    warm_up(info, train, infer, (lambda: FlopCounterMode(display=False)) if mode == "eager" else None)
    return train, infer, info


if __name__ == "__main__":
    serve(*contestant(*sys.argv[1:4]))
