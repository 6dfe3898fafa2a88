"""Autoregressive rollout: from the first frame(s), the model's own predictions feed the next step; boundary
conditions are imposed and contact edges recomputed at every step."""
from __future__ import annotations

import time

import torch

from hcmt.train.adapters import Adapter, integrate, node_features
from hcmt.train.data import Trajectory, build_graph


class RolloutError(RuntimeError):
    """The predicted state became non-finite."""


@torch.no_grad()
def rollout(model, adapter: Adapter, traj: Trajectory, radius: float, steps: int | None = None) -> dict:
    """Roll ``model`` out over ``traj``. Returns ``world_pos`` [T, N, d] and ``stress`` [T, N, 1] (or None) as
    tensors whose first ``adapter.history + 1`` frames are the data's, and ``ms_per_step``."""
    model.eval()
    device = next(model.parameters()).device  # graphs go where the model is; results come back to the CPU
    world = traj.world_pos
    T = world.shape[0] if steps is None else min(world.shape[0], steps + adapter.history + 1)
    h = adapter.history
    pos_list = [world[i] for i in range(h + 1)]
    stress_list = [traj.stress[i] for i in range(h + 1)] if traj.stress is not None else None
    elapsed = 0.0
    for t in range(h, T - 1):
        start = time.perf_counter()
        pos, prev = pos_list[-1], pos_list[-2] if h else pos_list[-1]
        feats = node_features(adapter, traj.static, pos, prev, world[t + 1])
        graph = build_graph(traj, pos, feats, radius).to(device)
        out = model.denormalize(model(graph, accumulate=False)).cpu()
        nxt, stress = integrate(adapter, out, pos, prev, world[t + 1], traj.static["node_type"])
        elapsed += time.perf_counter() - start
        if not torch.isfinite(nxt).all() or (stress is not None and not torch.isfinite(stress).all()):
            raise RolloutError(f"trajectory {traj.name}: the predicted state became non-finite at step {t + 1} "
                               f"(frame {t + 1} of {T}); the model diverged")
        pos_list.append(nxt)
        if stress_list is not None:
            stress_list.append(stress if stress is not None else traj.stress[t + 1])
    steps_done = max(T - 1 - h, 1)
    return {
        "world_pos": torch.stack(pos_list),
        "stress": torch.stack(stress_list) if stress_list is not None else None,
        "ms_per_step": 1e3 * elapsed / steps_done,
        "start": h + 1,
    }
