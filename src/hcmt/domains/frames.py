"""The frame pipeline: one place turns (trajectory, time, noise) into the model's input graph, its target and the
loss mask, for training, rollout and attention maps alike.

* :func:`input_graph`: the model input at positions ``x^t`` (Table 9 node inputs through the dataset's adapter,
  mesh and contact edges of that frame, the hierarchy);
* :func:`training_sample`: ``(graph, target, mask)`` of frame ``t`` with training noise (``train.noise_nodes``:
  NORMAL nodes, or every predicted node) and the target corrected by ``(1 - γ) · noise`` (GNS / MeshGraphNets);
* :func:`pushforward_sample`: the same frame whose input ``x^t`` is the model's own one-step prediction from the
  noised frame ``t − 1`` (no gradient), the target landing on the data's ``x^{t+1}`` (the pushforward trick,
  Brandstetter, Worrall & Welling, "Message Passing Neural PDE Solvers", ICLR 2022: training inputs drawn from the
  distribution of the model's own rollout states, against rollout drift);

The training frames of a split as a ``Dataset`` are :class:`hcmt.training.dataset.FrameDataset`.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import Tensor

from hcmt.domains.adapters import integrate, node_features, output_mask, target
from hcmt.domains.trajectory import Trajectory, build_graph
from hcmt.graph.batch import Graph


def input_graph(traj: Trajectory, pos: Tensor, prev: Tensor, next_prescribed: Tensor, radius: float) -> Graph:
    """The model input for positions ``pos`` ``[N, d]`` (``prev``: ``x^{t-1}``; ``next_prescribed``: the data's
    ``x^{t+1}``, read only for prescribed nodes' velocity inputs)."""
    feats = node_features(traj.adapter, traj.static, pos, prev, next_prescribed)
    return build_graph(traj, pos, feats, radius)


def training_sample(
    traj: Trajectory,
    t: int,
    noise: Tensor,
    gamma: float,
    radius: float,
    drift: Tensor | None = None,
    prev: Tensor | None = None,
) -> tuple[Graph, Tensor, Tensor]:
    """``(graph, target [N, out], loss mask [N, out])`` of frame ``t`` with ``noise`` ``[N, d]`` added to ``x^t``.

    ``drift`` (pushforward) is a further offset of ``x^t`` that the target corrects entirely, ``prev`` replaces the
    data's ``x^{t−1}``."""
    a = traj.adapter
    w = traj.world_pos
    pos, nxt = w[t] + noise, w[t + 1]
    prev = w[t - a.history] if prev is None else prev
    if drift is not None:
        pos = pos + drift
    graph = input_graph(traj, pos, prev, nxt, radius)
    stress = traj.stress[t + 1] if traj.stress is not None else None
    tgt = target(a, pos, prev, nxt + (1.0 - gamma) * noise, stress)
    return graph, tgt, output_mask(a, traj.static["node_type"], pos.shape[1])


@torch.no_grad()
def pushforward_sample(
    model, traj: Trajectory, t: int, noise: Tensor, prev_noise: Tensor, gamma: float, radius: float, forward=None
) -> tuple[Graph, Tensor, Tensor]:
    """:func:`training_sample` of frame ``t`` (``t − 1 >= history``) whose ``x^t`` is the model's prediction from
    frame ``t − 1`` with ``prev_noise``, plus ``noise``; ``x^{t−1}`` is that noised input (as in a rollout). The
    prediction carries no gradient; boundary-condition nodes take the data's values. ``forward`` (``graph ->``
    the model's normalized output, e.g. a compiled model on padded graphs) replaces ``model(graph)``."""
    a, w = traj.adapter, traj.world_pos
    x, before = w[t - 1] + prev_noise, w[t - 1 - a.history]
    graph = input_graph(traj, x, before, w[t], radius)
    device = next(model.parameters()).device
    was_training = model.training
    model.eval()
    raw = forward(graph.to(device)) if forward is not None else model(graph.to(device), accumulate=False)
    out = model.denormalize(raw).float().cpu()
    model.train(was_training)
    pred, _ = integrate(a, out, x, before, w[t], traj.static["node_type"])
    return training_sample(traj, t, noise, gamma, radius, drift=pred - w[t], prev=x)


def step_seed(seed: int, step: int, rank: int) -> int:
    """The seed of a training step's random draws (noise, and in the loop LPE sign flips)."""
    return int(np.random.SeedSequence([seed, step, rank]).generate_state(1)[0])
