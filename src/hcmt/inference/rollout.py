"""Autoregressive rollout: from the first frame(s), the model's own predictions feed the next step; boundary
conditions are imposed and contact edges recomputed at every step.

Several trajectories roll out together (:func:`rollout_batch`): at each step their graphs are collated into one
disconnected graph and the model runs once, so a batch costs about one model call per step on a GPU. Every model is
node-local (a node's output depends on its own graph only; the normalizers do not accumulate in rollout), so a batch
gives what one-by-one rollouts give, up to float summation order (tests/training/test_train.py).

``compile`` (``--compile`` of ``hcmt rollout / evaluate / predict``) runs the model through ``torch.compile``.
``default`` compiles with symbolic sizes (:func:`hcmt.models.base.compile_simulator` with ``dynamic=True``): one
compiled graph serves every design and contact count, so a design check compiles once per machine (the persistent
cache) instead of once per mesh. ``reduce-overhead`` (CUDA graphs) and ``max-autotune`` need static shapes: the
graph is padded (:func:`hcmt.graph.batch.pad_graph`; the mesh and hierarchy of a batch never change along a rollout,
contact edges go to bucket sizes), so after the first steps every step replays a compiled graph. ``aot`` runs the
forward exported ahead of time (:mod:`hcmt.models.export`): built once per machine and model, then loaded in
milliseconds by every process; where the export or its compilation fails, ``aot`` falls back to ``default`` with a
warning. ``auto`` on the CPU is ``aot`` where the model's package is already built on this machine (any length) or
the rollouts are long enough to compile (:data:`hcmt.models.base.AUTO_COMPILE_ROLLOUT_STEPS`); elsewhere it is
:func:`hcmt.models.base.resolve_compile`'s choice.
"""
from __future__ import annotations

import logging
import time

import torch

from hcmt.domains.adapters import Adapter, integrate
from hcmt.domains.frames import input_graph
from hcmt.domains.trajectory import Trajectory
from hcmt.errors import InputError, RolloutError
from hcmt.graph.batch import PadSizes, collate, pad_graph
from hcmt.models.base import AUTO_COMPILE_ROLLOUT_STEPS, compile_simulator, resolve_compile
from hcmt.models.export import exported_forward, package_path

logger = logging.getLogger(__name__)


def rollout_compile(mode: str, model, steps: int) -> str:
    """The compile mode of rollouts that take ``steps`` model steps in all (``auto``:
    :func:`hcmt.models.base.resolve_compile` against :data:`hcmt.models.base.AUTO_COMPILE_ROLLOUT_STEPS`); a caller
    that rolls out in chunks resolves once, with its total, and hands the result to every chunk."""
    device = next(model.parameters()).device
    lpe = getattr(model, "lpe", None) is not None  # its eigenvectors are computed per graph, outside the compiler
    resolved = resolve_compile(mode, steps=steps, device=device, lpe=lpe, threshold=AUTO_COMPILE_ROLLOUT_STEPS)
    if mode == "auto" and device.type == "cpu" and not lpe and (resolved == "default" or package_path(model).is_file()):
        return "aot"  # built: loads in milliseconds; long: built once (about a minute), then every process loads it
    return resolved


def compiled(model, mode: str, dynamic: bool):
    """``model`` compiled (:func:`hcmt.models.base.compile_simulator`), once per model, mode and shape policy: the
    wrapper is kept on the model, so the chunks of a design check reuse its compiled graphs."""
    cache = model.__dict__.setdefault("_compiled_rollout", {})
    if (mode, dynamic) not in cache:
        cache[mode, dynamic] = compile_simulator(model, mode, dynamic=dynamic)
    return cache[mode, dynamic]


def exported(model, graph):
    """``model``'s forward ahead-of-time compiled (:func:`hcmt.models.export.exported_forward`, built from ``graph``
    once per machine, then loaded), kept on the model as :func:`compiled` keeps its wrapper."""
    cache = model.__dict__.setdefault("_compiled_rollout", {})
    if "aot" not in cache:
        try:
            forward = exported_forward(model, graph)
            cache["aot"] = lambda g, accumulate=False: forward(g)
        except Exception as exc:  # noqa: BLE001 -- export and AOTInductor raise many types; every one falls back
            logger.warning("--compile aot: the ahead-of-time export failed (%s: %s); torch.compile (default) instead",
                           type(exc).__name__, str(exc).splitlines()[0][:200] if str(exc) else "")
            cache["aot"] = compiled(model, "default", dynamic=True)
    return cache["aot"]


@torch.no_grad()
def rollout(model, adapter: Adapter, traj: Trajectory, radius: float, steps: int | None = None,
            compile: str = "none") -> dict:
    """Roll ``model`` out over ``traj``. Returns ``world_pos`` [T, N, d] and ``stress`` [T, N, 1] (or None) as
    tensors whose first ``adapter.history + 1`` frames are the data's, ``ms_per_step`` and ``start`` (the first
    predicted frame)."""
    return rollout_batch(model, adapter, [traj], radius, steps, compile=compile)[0]


@torch.no_grad()
def rollout_batch(model, adapter: Adapter, trajs: list[Trajectory], radius: float, steps: int | None = None,
                  progress=None, compile: str = "none") -> list[dict]:
    """Roll out several trajectories with the same number of frames together, one batched model call per step.

    Frames ``0 .. history`` of each trajectory start the rollout; later frames of ``traj.world_pos`` are read only
    where a boundary condition sets the position (clamped, symmetry and prescribed nodes), so a trajectory whose
    later frames hold just those values (:func:`hcmt.design.check.design_trajectory`) rolls out the same.
    ``progress(n)`` is called after every step. Returns one dict per trajectory, as :func:`rollout`;
    ``ms_per_step`` is the batch's time per step divided by the number of trajectories (compilation included)."""
    model.eval()
    net, pad = model, None
    device = next(model.parameters()).device  # graphs go where the model is; results come back to the CPU
    compile = rollout_compile(compile, model, len(trajs) * (len(trajs[0].world_pos) - 1 - adapter.history)
                              if trajs else 0)
    padded = compile not in ("none", "default", "aot")  # CUDA graphs and autotuning want static shapes
    if compile not in ("none", "aot"):  # aot: built from the first step's graph
        net = compiled(model, compile, dynamic=not padded)
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
        real = graph.num_nodes
        if padded:  # static sizes: the batch's mesh and hierarchy, contact edges in buckets
            pad = pad or PadSizes.of([graph])
            graph = pad_graph(graph, pad)
        elif compile == "aot":
            net = exported(model, graph)
        out = model.denormalize(net(graph.to(device), accumulate=False)[:real]).cpu()
        for b, (tr, o) in enumerate(zip(trajs, out.split(sizes))):
            x, prev = inputs[b]
            nxt, s = integrate(adapter, o, x, prev, tr.world_pos[t + 1], tr.static["node_type"])
            if not torch.isfinite(nxt).all() or (s is not None and not torch.isfinite(s).all()):
                raise RolloutError(f"trajectory {tr.name}: the predicted state became non-finite at step {t + 1} "
                                   f"(frame {t + 1} of {T}); the model diverged")
            pos[b].append(nxt)
            if stress[b] is not None:
                stress[b].append(s if s is not None else tr.stress[t + 1])
        elapsed += time.perf_counter() - start
        if progress is not None:
            progress(1)
    per_step = 1e3 * elapsed / max(T - 1 - h, 1) / len(trajs)
    return [{"world_pos": torch.stack(p), "stress": torch.stack(s) if s is not None else None,
             "ms_per_step": per_step, "start": h + 1} for p, s in zip(pos, stress)]
