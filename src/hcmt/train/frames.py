"""The frame pipeline: one place turns (trajectory, time, noise) into the model's input graph, its target and the
loss mask, for training, rollout and attention maps alike; and :class:`FrameDataset`, the training frames of a split
as a ``torch.utils.data.Dataset`` for ``DataLoader`` workers.

* :func:`input_graph`: the model input at positions ``x^t`` (Table 9 node inputs through the dataset's adapter,
  mesh and contact edges of that frame, the hierarchy);
* :func:`training_sample`: ``(graph, target, mask)`` of frame ``t`` with training noise (``train.noise_nodes``:
  NORMAL nodes, or every predicted node) and the target corrected by ``(1 - γ) · noise`` (GNS / MeshGraphNets);
* :func:`pushforward_sample`: the same frame whose input ``x^t`` is the model's own one-step prediction from the
  noised frame ``t − 1`` (no gradient), the target landing on the data's ``x^{t+1}`` (the pushforward trick,
  Brandstetter, Worrall & Welling, "Message Passing Neural PDE Solvers", ICLR 2022: training inputs drawn from the
  distribution of the model's own rollout states, against rollout drift);
* :class:`FrameDataset`: item ``i`` is training frame ``i`` (``frames[i] = (trajectory, t)``), with noise drawn
  from a generator seeded by ``(seed, i)``; the trainer instead asks for ``(i, step, rank, previous)`` keys
  (:class:`StepSampler`), which draw the noise exactly as the training loop always has (one generator per step,
  seeded by ``(seed, step, rank)``, the step's frames in order), so the number of workers never changes a result.
  The HDF5 file is opened lazily in each process (a dataset pickles without its trajectories).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from torch import Tensor
from torch.utils.data import Dataset, Sampler

from hcmt.graph.batch import Graph, PadSizes, collate, pad_graph, pad_rows
from hcmt.train.adapters import Adapter, integrate, node_features, noise_mask, output_mask, target
from hcmt.train.data import Trajectory, build_graph, load_split


def input_graph(traj: Trajectory, pos: Tensor, prev: Tensor, next_prescribed: Tensor, radius: float) -> Graph:
    """The model input for positions ``pos`` ``[N, d]`` (``prev``: ``x^{t-1}``; ``next_prescribed``: the data's
    ``x^{t+1}``, read only for prescribed nodes' velocity inputs)."""
    feats = node_features(traj.adapter, traj.static, pos, prev, next_prescribed)
    return build_graph(traj, pos, feats, radius)


def training_sample(traj: Trajectory, t: int, noise: Tensor, gamma: float, radius: float, drift: Tensor | None = None,
                    prev: Tensor | None = None) -> tuple[Graph, Tensor, Tensor]:
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
def pushforward_sample(model, traj: Trajectory, t: int, noise: Tensor, prev_noise: Tensor, gamma: float,
                       radius: float) -> tuple[Graph, Tensor, Tensor]:
    """:func:`training_sample` of frame ``t`` (``t − 1 >= history``) whose ``x^t`` is the model's prediction from
    frame ``t − 1`` with ``prev_noise``, plus ``noise``; ``x^{t−1}`` is that noised input (as in a rollout). The
    prediction carries no gradient; boundary-condition nodes take the data's values."""
    a, w = traj.adapter, traj.world_pos
    x, before = w[t - 1] + prev_noise, w[t - 1 - a.history]
    graph = input_graph(traj, x, before, w[t], radius)
    device = next(model.parameters()).device
    was_training = model.training
    model.eval()
    out = model.denormalize(model(graph.to(device), accumulate=False)).float().cpu()
    model.train(was_training)
    pred, _ = integrate(a, out, x, before, w[t], traj.static["node_type"])
    return training_sample(traj, t, noise, gamma, radius, drift=pred - w[t], prev=x)


def step_seed(seed: int, step: int, rank: int) -> int:
    """The seed of a training step's random draws (noise, and in the loop LPE sign flips)."""
    return int(np.random.SeedSequence([seed, step, rank]).generate_state(1)[0])


class FrameDataset(Dataset):
    """The training frames ``(trajectory, t)`` of one split, each turned into ``(graph, target, mask)``.

    ``data`` a native dataset folder; ``adapter`` the dataset's (:func:`hcmt.train.adapters.config_adapter`);
    ``levels``/``remesh`` the hierarchy the model needs; ``radius`` the contact radius γ; ``noise_std`` σ on the
    ``noise_nodes`` (``normal`` or ``predicted``) and ``gamma`` the target correction; ``seed`` for the noise.
    Works with ``DataLoader(num_workers=N)``. :meth:`pushforward_item` builds an item with the model's help (in
    the training process).
    """

    def __init__(self, data: str | Path, split: str, adapter: Adapter, levels: int, remesh: bool, radius: float,
                 noise_std: float = 0.0, gamma: float = 1.0, seed: int = 0, exclude: list[int] | None = None,
                 noise_nodes: str = "normal"):
        self.data, self.split, self.adapter = Path(data), split, adapter
        self.levels, self.remesh, self.radius = levels, remesh, float(radius)
        self.noise_std, self.gamma, self.seed, self.exclude = float(noise_std), float(gamma), int(seed), exclude
        self.noise_nodes = noise_nodes
        self._trajs: list[Trajectory] | None = None
        self.frames = np.asarray([(i, t) for i, tr in enumerate(self.trajectories)
                                  for t in range(adapter.history, tr.num_steps - 1)], np.int64).reshape(-1, 2)

    @property
    def trajectories(self) -> list[Trajectory]:
        if self._trajs is None:  # opened lazily: in each DataLoader worker on its first item
            self._trajs = load_split(self.data, self.split, self.adapter, self.levels, self.remesh,
                                     exclude=self.exclude)
        return self._trajs

    def __getstate__(self):
        state = dict(self.__dict__)
        state["_trajs"] = None  # workers read the file themselves
        return state

    def __len__(self) -> int:
        return len(self.frames)

    def num_nodes(self, i: int) -> int:
        return self.trajectories[int(self.frames[i][0])].num_nodes

    def __getitem__(self, key) -> tuple[Graph, Tensor, Tensor]:
        """``i`` (frame ``i``, noise seeded by ``(seed, i)``) or ``(i, step, rank, previous)`` (the trainer's key:
        noise drawn from the step's generator after the draws of the step's ``previous`` frames' node counts)."""
        tr, t, noise, _ = self._draw(key)
        return training_sample(tr, t, noise, self.gamma, self.radius)

    def pushforward_item(self, key, model, probability: float) -> tuple[Graph, Tensor, Tensor]:
        """Item ``key`` as :meth:`__getitem__` (the same noise), except that with ``probability`` (drawn from the
        item's generator after its noise) and where frame ``t − 1`` has its history, it is a
        :func:`pushforward_sample` from frame ``t − 1``."""
        tr, t, noise, gen = self._draw(key)
        u = float(torch.rand((), generator=gen))
        if u < probability and t - 1 >= self.adapter.history:
            return pushforward_sample(model, tr, t, noise, self._noise(tr, gen), self.gamma, self.radius)
        return training_sample(tr, t, noise, self.gamma, self.radius)

    def _noise(self, tr: Trajectory, gen: torch.Generator) -> Tensor:
        d = tr.world_pos.shape[-1]
        return (torch.randn((tr.num_nodes, d), generator=gen) * self.noise_std
                * noise_mask(self.adapter, tr.static["node_type"], d, self.noise_nodes))

    def _draw(self, key) -> tuple[Trajectory, int, Tensor, torch.Generator]:
        if isinstance(key, (int, np.integer)):
            i, gen, previous = int(key), torch.Generator().manual_seed(step_seed(self.seed, int(key), 0)), ()
        else:
            i, step, rank, previous = key
            gen = torch.Generator().manual_seed(step_seed(self.seed, step, rank))
        ti, t = (int(v) for v in self.frames[i])
        tr = self.trajectories[ti]
        d = tr.world_pos.shape[-1]
        for n in previous:  # replay the draws of the frames before this one in the step's batch
            torch.randn((n, d), generator=gen)
        return tr, t, self._noise(tr, gen), gen


def collate_samples(items: list[tuple[Graph, Tensor, Tensor]]) -> tuple[Graph, Tensor, Tensor]:
    """A step's samples as one batched graph with concatenated targets and masks."""
    graphs, targets, masks = zip(*items)
    return collate(list(graphs)), torch.cat(targets), torch.cat(masks)


def pad_sizes(dataset: FrameDataset, batch: int) -> PadSizes:
    """Static sizes that hold any training batch of ``batch`` frames of ``dataset`` (``train.compile``): the mesh
    and hierarchy of every trajectory are fixed (a frame's graph takes its mesh edges, pooling and level edges
    from the trajectory's hierarchy), so the largest trajectory bounds every level."""
    counts = []
    for tr in dataset.trajectories:
        h = tr.hierarchy
        counts.append((tr.num_nodes, int(h.edges[0].shape[1]),
                       [(len(h.pool[l]), int(h.edges[l + 1].shape[1])) for l in range(h.levels)]))
    return PadSizes.fit(counts, batch)


def collate_padded(items: list[tuple[Graph, Tensor, Tensor]], sizes: PadSizes) -> tuple[Graph, Tensor, Tensor]:
    """:func:`collate_samples`, then dummy rows up to ``sizes`` (:func:`hcmt.graph.batch.pad_graph`); the
    targets and the loss mask get zero rows, so the loss is the unpadded one."""
    graph, tgt, mask = collate_samples(items)
    padded = pad_graph(graph, sizes)
    return padded, pad_rows(tgt, padded.num_nodes)[0], pad_rows(mask, padded.num_nodes)[0]


class StepSampler(Sampler):
    """The keys of every training step from ``start`` to ``end``: a fresh permutation of the frames per epoch
    (seeded by ``(seed, epoch)``), each rank taking its share of the step's global batch of ``batch`` frames per
    rank. A pure function of (seed, step, rank), so a resumed run sees the same data as one that never stopped."""

    def __init__(self, dataset: FrameDataset, batch: int, seed: int, start: int, end: int, world: int = 1,
                 rank: int = 0):
        self.dataset, self.batch, self.seed, self.start, self.end = dataset, batch, seed, start, end
        self.world, self.rank = world, rank
        self.per_epoch = max(len(dataset) // (world * batch), 1)

    def __len__(self) -> int:
        return max(self.end - self.start, 0)

    def __iter__(self):
        for step in range(self.start, self.end):
            epoch, pos = divmod(step, self.per_epoch)
            perm = np.random.default_rng([self.seed, epoch]).permutation(len(self.dataset))
            first = (pos * self.world + self.rank) * self.batch
            picks = perm[first:first + self.batch]
            sizes = [self.dataset.num_nodes(i) for i in picks]
            yield [(int(i), step, self.rank, tuple(sizes[:k])) for k, i in enumerate(picks)]
