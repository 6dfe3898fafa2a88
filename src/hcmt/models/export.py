"""A simulator's inference forward compiled ahead of time (``torch.export`` with symbolic sizes, then AOTInductor),
kept on disk, so that a process loads it in milliseconds instead of tracing and compiling it again (about 25 s for
the shipped model with a warm ``torch.compile`` cache, docs/RESULTS.md).

:func:`exported_forward` returns ``graph -> normalized output [N, out]`` (the model's ``forward(graph,
accumulate=False)`` in eval mode). The package is built once per model weights, torch version, CPU and thread count
(:func:`package_key`) into ``compile_cache_dir() / "aoti"`` (written to a temporary name, then renamed).

Symbolic sizes: ``torch.export`` specializes a size of 0 or 1, and a frame may have no contact edge (the ball far
from the plate), so every graph gets one dummy node and two dummy contact edges from it to itself before the call
(:func:`with_dummies`); messages along them reach only the dummy node, whose output row is dropped, so a real
node's output is what the model gives without them (tests/models/test_export.py).
"""

from __future__ import annotations

import hashlib
import logging
import os
import platform
import time
import warnings
from dataclasses import replace
from pathlib import Path

import torch
from torch import Tensor, nn

from hcmt.graph.batch import Graph

from .base import compile_cache_dir

logger = logging.getLogger(__name__)

#: the Graph fields an exported forward takes, in order (lists become tuples); masks are never passed (inference)
FIELDS = (
    "node_features",
    "mesh_edges",
    "mesh_features",
    "contact_edges",
    "contact_features",
    "pool",
    "level_edges",
    "level_features",
    "batch",
)


class _Forward(nn.Module):
    """``model(Graph(*fields), accumulate=False)`` with the graph's tensors as positional inputs (export takes
    tensors and tuples of them, not a dataclass)."""

    def __init__(self, model: nn.Module):
        super().__init__()
        self.model = model

    def forward(
        self,
        node_features,
        mesh_edges,
        mesh_features,
        contact_edges,
        contact_features,
        pool,
        level_edges,
        level_features,
        batch,
    ):
        return self.model(
            Graph(
                node_features,
                mesh_edges,
                mesh_features,
                contact_edges,
                contact_features,
                list(pool),
                list(level_edges),
                list(level_features),
                batch,
            ),
            accumulate=False,
        )


def with_dummies(graph: Graph) -> Graph:
    """``graph`` with one dummy node (zero features, its own batch index) and two dummy contact edges from it to
    itself: no size is 0 or 1, whatever the contact count. Its output row is the last one."""
    n = graph.num_nodes
    nf, cf = graph.node_features, graph.contact_features
    batch = graph.batch if graph.batch is not None else torch.zeros(n, dtype=torch.long, device=nf.device)
    return replace(
        graph,
        node_features=torch.cat([nf, nf.new_zeros(1, nf.shape[1])]),
        contact_edges=torch.cat([graph.contact_edges, graph.contact_edges.new_full((2, 2), n)], dim=1),
        contact_features=torch.cat([cf, cf.new_zeros(2, cf.shape[1])]),
        batch=torch.cat([batch, batch.new_full((1,), int(batch.max()) + 1 if n else 0)]),
    )


def _inputs(graph: Graph) -> tuple:
    return tuple(tuple(v) if isinstance(v, list) else v for v in (getattr(graph, f) for f in FIELDS))


def package_key(model: nn.Module) -> str:
    """What the compiled package depends on: the model's class and weights (buffers included: the normalizers),
    the torch version, the CPU and the thread count (Inductor writes its OpenMP loops for it), and the device the
    model is on (a CUDA package holds kernels for that GPU)."""
    device = next(model.parameters()).device
    gpu = torch.cuda.get_device_name(device) if device.type == "cuda" else ""
    h = hashlib.sha256()
    h.update(
        f"{type(model).__qualname__} {torch.__version__} {platform.machine()} {cpu_name()} "
        f"{torch.get_num_threads()} {device.type} {gpu}".encode()
    )
    for name, t in model.state_dict().items():
        h.update(name.encode())
        h.update(t.detach().cpu().contiguous().numpy().tobytes())
    return h.hexdigest()[:32]


def package_path(model: nn.Module) -> Path:
    """Where ``model``'s package is (or will be) on this machine: ``compile_cache_dir() / "aoti" / KEY.pt2``."""
    return compile_cache_dir() / "aoti" / f"{package_key(model)}.pt2"


def cpu_name() -> str:
    """The CPU's model name (/proc/cpuinfo), else what :mod:`platform` says."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


def build_package(model: nn.Module, example: Graph, path: Path) -> None:
    """Export ``model``'s forward with symbolic sizes from ``example`` and compile it into the package ``path``
    (written under a temporary name, then renamed), announced in one line first: it takes about a minute of one
    core, once per machine and model."""
    logger.warning(
        "hcmt: compiling %s's forward once for this machine (torch.export + AOTInductor, about a minute of one "
        "core), so that every later run loads it in milliseconds; it goes to %s",
        type(model).__name__,
        path,
    )
    start = time.perf_counter()
    model.eval()
    args = _inputs(with_dummies(example))
    auto = torch.export.Dim.AUTO

    def dims(x):
        if isinstance(x, tuple):
            return tuple(dims(y) for y in x)
        return {i: auto for i in range(x.dim())}

    with torch.no_grad():
        program = torch.export.export(_Forward(model), args, dynamic_shapes=dims(args), strict=True)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{os.getpid()}.{path.name}")  # AOTInductor wants the .pt2 suffix
    torch._inductor.aoti_compile_and_package(program, package_path=str(tmp))
    os.replace(tmp, path)
    logger.info("compiled %s's forward in %.0f s", type(model).__name__, time.perf_counter() - start)


def exported_forward(model: nn.Module, example: Graph):
    """``graph -> model(graph, accumulate=False)`` through an AOTInductor package of ``model`` (eval mode, no
    gradient), built from ``example`` (any graph of the model's kind: the sizes are symbolic) on the first call on
    this machine and loaded from the cache after."""
    import torch._inductor

    path = package_path(model)
    with warnings.catch_warnings():
        # torch's deprecation notices from inside export and packaging: about torch's internals, not the user's code
        warnings.simplefilter("ignore", FutureWarning)
        if not path.is_file():
            build_package(model, example, path)
        compiled = torch._inductor.aoti_load_package(str(path))

    def forward(graph: Graph) -> Tensor:
        return compiled(*_inputs(with_dummies(graph)))[: graph.num_nodes]

    return forward
