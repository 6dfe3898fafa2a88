"""Autoregressive rollout: from the first frame(s), the model's own predictions feed the next step; boundary
conditions are imposed and contact edges recomputed at every step.

Several trajectories roll out together (:func:`rollout_batch`) as one disconnected graph, and the whole rollout lives
on the model's device: the batch's static graph (mesh edges and their mesh-space features, the hierarchy, objects,
node types) and the data's positions of every frame are merged there once (:func:`hcmt.domains.stepping.frame_batch`);
each step builds the node features, contact edges and world-space edge features of every trajectory at once from
their concatenated positions (:func:`hcmt.domains.stepping.batch_input`: the collated graph of the trajectories'
:func:`hcmt.domains.frames.input_graph`), runs the model once and integrates with the boundary conditions, with no
loop over trajectories; predicted frames stay on the device and come back once per batch. On the CPU a batch steps
in blocks of whole trajectories of bounded size (:data:`CPU_BLOCK_NODES`), one forward per block: there a larger
graph costs more per node. Every model is node-local (a node's output depends on its own graph only; the
normalizers do not accumulate in rollout), so a batch gives what one-by-one rollouts give, up to float summation
order (tests/training/test_train.py, tests/inference/test_rollout_engine.py). Contact search: the KD-tree on the CPU,
the dense search for GPU tensors (:func:`hcmt.graph.contact.contact_edges`; a pair within float32 rounding of the
radius may fall either way there).

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
from torch import Tensor

from hcmt.domains.adapters import Adapter, integrate
from hcmt.domains.stepping import FrameBatch, batch_input, frame_batch
from hcmt.domains.trajectory import Trajectory
from hcmt.errors import InputError, RolloutError
from hcmt.graph.batch import Graph, PadSizes, pad_graph
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
            logger.warning(
                "--compile aot: the ahead-of-time export failed (%s: %s); torch.compile (default) instead",
                type(exc).__name__,
                str(exc).splitlines()[0][:200] if str(exc) else "",
            )
            cache["aot"] = compiled(model, "default", dynamic=True)
    return cache["aot"]


#: On the CPU a batch steps in blocks of whole trajectories of at most this many nodes in all (at the shipped model's
#: width, 128; scaled by 128 / ``model.hidden``), one forward per block. Measured per design, the shipped model's
#: forward on one thread (a shared 2-core AMD EPYC) cost about the same for 1 to 3 designs in one graph (up to about
#: 1,500 nodes) and about 40 % more for 4 or 8 (its gathers and out-of-place elementwise ops grow superlinearly), so
#: one graph of a larger CPU batch costs more per design (benchmarks/micro/rollout_engine.py: batch 8 against 1).
#: On a GPU the whole batch is one block.
CPU_BLOCK_NODES = 1536


class Forward:
    """``graph -> the model's physical output [N, out]`` in a rollout's compile mode: the model itself, compiled
    (:func:`compiled`), on padded graphs (``pad``: sizes that hold every block's graph; the mesh and hierarchy of a
    batch never change along a rollout, contact edges go to buckets) or ahead of time (:func:`exported`, built from
    the first step's graph)."""

    def __init__(self, model, mode: str, pad: PadSizes):
        self.model, self.mode, self.net, self.pad = model, mode, model, pad
        self.padded = mode not in ("none", "default", "aot")  # CUDA graphs and autotuning want static shapes
        if mode not in ("none", "aot"):
            self.net = compiled(model, mode, dynamic=not self.padded)

    def __call__(self, graph: Graph) -> Tensor:
        real = graph.num_nodes
        if self.padded:
            graph = pad_graph(graph, self.pad)
        elif self.mode == "aot":
            self.net = exported(self.model, graph)
        return self.model.denormalize(self.net(graph, accumulate=False)[:real])


def blocks(trajs: list[Trajectory], model, device: torch.device) -> list[list[Trajectory]]:
    """The batch in the blocks that step as one graph each: the whole batch on a GPU; on the CPU consecutive
    trajectories of at most :data:`CPU_BLOCK_NODES` nodes in all (scaled by the model's width), at least one each."""
    if device.type != "cpu":
        return [trajs]
    budget = max(CPU_BLOCK_NODES * 128 // max(int(getattr(model, "hidden", 128)), 1), 1)
    out: list[list[Trajectory]] = []
    for tr in trajs:
        if out and sum(t.num_nodes for t in out[-1]) + tr.num_nodes <= budget:
            out[-1].append(tr)
        else:
            out.append([tr])
    return out


class Block:
    """One block of a batch in a rollout: its merged trajectories (:func:`hcmt.domains.stepping.frame_batch`) and
    its predicted frames, on the model's device (frames ``0 .. history`` the data's, later ones overwritten)."""

    def __init__(self, trajs: list[Trajectory], frames: int, device):
        self.fb = frame_batch(trajs, frames, device)
        self.pos = self.fb.world_pos.clone()
        self.stress = self.fb.stress.clone() if self.fb.stress is not None else None  # no stress output: the data's

    def step(self, forward: Forward, adapter: Adapter, t: int, radius: float) -> None:
        """Frame ``t + 1`` of every trajectory of the block from frame ``t`` (and ``t - 1``)."""
        fb, pos, h = self.fb, self.pos, adapter.history
        x, prev = pos[t], pos[t - 1] if h else pos[t]
        out = forward(batch_input(fb, x, prev, fb.world_pos[t + 1], radius))
        nxt, s = integrate(adapter, out, x, prev, fb.world_pos[t + 1], fb.static["node_type"])
        check_finite(fb, nxt, s, t, pos.shape[0])
        pos[t + 1] = nxt
        if self.stress is not None and s is not None:
            self.stress[t + 1] = s

    def results(self) -> list[tuple[Tensor, Tensor | None]]:
        """Each trajectory's ``(world_pos [T, N, d], stress [T, N, 1] or None)`` on the CPU: one copy per block."""
        fb, pos = self.fb, self.pos.cpu()
        stress = self.stress.cpu().split(fb.sizes, dim=1) if self.stress is not None else [None] * len(fb.sizes)
        return [
            (p.contiguous(), s.contiguous() if s is not None and has else None)
            for p, s, has in zip(pos.split(fb.sizes, dim=1), stress, fb.has_stress)
        ]


def check_finite(fb: FrameBatch, nxt: Tensor, stress: Tensor | None, t: int, frames: int) -> None:
    """One test of the whole block's next state; on failure the first trajectory (in batch order) that diverged is
    named."""
    ok = torch.isfinite(nxt).all(1)
    if stress is not None:
        ok &= torch.isfinite(stress).all(1)
    if not bool(ok.all()):
        name = fb.names[int(fb.batch[~ok].min())]
        raise RolloutError(
            f"trajectory {name}: the predicted state became non-finite at step {t + 1} "
            f"(frame {t + 1} of {frames}); the model diverged"
        )


@torch.no_grad()
def rollout(
    model, adapter: Adapter, traj: Trajectory, radius: float, steps: int | None = None, compile: str = "none"
) -> dict:
    """Roll ``model`` out over ``traj``. Returns ``world_pos`` [T, N, d] and ``stress`` [T, N, 1] (or None) as
    tensors whose first ``adapter.history + 1`` frames are the data's, ``ms_per_step`` and ``start`` (the first
    predicted frame)."""
    return rollout_batch(model, adapter, [traj], radius, steps, compile=compile)[0]


def rollout_frames(trajs: list[Trajectory], adapter: Adapter, steps: int | None) -> int:
    """The number of frames a batch rolls out (its trajectories' common length, or ``steps`` model steps)."""
    lengths = {int(tr.world_pos.shape[0]) for tr in trajs}
    if len(lengths) != 1:
        raise InputError(f"trajectories of different lengths {sorted(lengths)} cannot roll out in one batch")
    (full,) = lengths
    return full if steps is None else min(full, steps + adapter.history + 1)


@torch.no_grad()
def rollout_batch(
    model,
    adapter: Adapter,
    trajs: list[Trajectory],
    radius: float,
    steps: int | None = None,
    progress=None,
    compile: str = "none",
) -> list[dict]:
    """Roll out several trajectories with the same number of frames together, one batched model call per step
    (on the CPU one per block of :data:`CPU_BLOCK_NODES` nodes), on the model's device.

    Frames ``0 .. history`` of each trajectory start the rollout; later frames of ``traj.world_pos`` are read only
    where a boundary condition sets the position (clamped, symmetry and prescribed nodes), so a trajectory whose
    later frames hold just those values (:func:`hcmt.design.check.design_trajectory`) rolls out the same.
    ``progress(n)`` is called after every step. Returns one dict per trajectory, as :func:`rollout` (tensors on the
    CPU); ``ms_per_step`` is the batch's time per step divided by the number of trajectories (compilation, the
    batch's setup and the copy back included)."""
    model.eval()
    device = next(model.parameters()).device
    compile = rollout_compile(compile, model, len(trajs) * (trajs[0].num_steps - 1 - adapter.history) if trajs else 0)
    h, T = adapter.history, rollout_frames(trajs, adapter, steps)
    elapsed, start = 0.0, time.perf_counter()  # the progress callback's time left out
    parts = [Block(b, T, device) for b in blocks(trajs, model, device)]
    forward = Forward(model, compile, PadSizes.fit([p.fb.graph.counts() for p in parts]))
    for t in range(h, T - 1):
        for part in parts:
            part.step(forward, adapter, t, radius)
        if progress is not None:
            elapsed += time.perf_counter() - start
            progress(1)
            start = time.perf_counter()
    results = [r for part in parts for r in part.results()]
    elapsed += time.perf_counter() - start
    per_step = 1e3 * elapsed / max(T - 1 - h, 1) / len(trajs)
    return [{"world_pos": p, "stress": s, "ms_per_step": per_step, "start": h + 1} for p, s in results]
