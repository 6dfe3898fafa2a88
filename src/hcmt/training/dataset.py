"""The training frames of a split as a ``torch.utils.data.Dataset`` (:class:`FrameDataset`) for ``DataLoader``
workers, the step sampler and the collate functions.

item ``i`` is training frame ``i`` (``frames[i] = (trajectory, t)``), with noise drawn
  from a generator seeded by ``(seed, i)``; the trainer instead asks for ``(i, step, rank, previous)`` keys
  (:class:`StepSampler`), which draw the noise exactly as the training loop always has (one generator per step,
  seeded by ``(seed, step, rank)``, the step's frames in order), so the number of workers never changes a result.
  The split is read per item (the frames it needs, a few trajectories' static fields and hierarchies) from an HDF5
  file opened lazily in each process: a DataLoader worker or DDP rank holds the index, not the split, and reads
  only the trajectories of its own keys.
"""

from __future__ import annotations

import functools
import signal
from pathlib import Path

import numpy as np
import torch
from torch import Tensor
from torch.utils.data import Dataset, Sampler

from hcmt.domains.adapters import Adapter, noise_mask
from hcmt.domains.frames import pushforward_sample, step_seed, training_sample
from hcmt.domains.trajectory import SplitReader, Trajectory, load_split
from hcmt.graph.batch import Graph, PadSizes, collate, pad_graph, pad_rows
from hcmt.inference.quantities import CONTACT_TOL


class InMemorySplit:
    """A split held whole in memory (:func:`load_split`), with :class:`SplitReader`'s interface: the eager path
    (``FrameDataset(in_memory=True)``), for small data and to check the lazy path against. Loaded lazily in each
    process; pickles without its trajectories."""

    def __init__(
        self, dataset, split: str, adapter: Adapter, levels: int, remesh: bool, exclude: list[int] | None = None
    ):
        self.args = (dataset, split, adapter, levels, remesh)
        self.exclude, self._trajs = exclude, None
        self.steps = np.asarray([tr.num_steps for tr in self.trajectories], np.int64)
        self.nodes = np.asarray([tr.num_nodes for tr in self.trajectories], np.int64)

    @property
    def trajectories(self) -> list[Trajectory]:
        if self._trajs is None:  # opened lazily: in each DataLoader worker on its first item
            self._trajs = load_split(*self.args, exclude=self.exclude)
        return self._trajs

    def __getstate__(self):
        return {**self.__dict__, "_trajs": None}  # workers read the file themselves

    def __len__(self) -> int:
        return len(self.steps)

    def static(self, ti: int) -> Trajectory:
        return self.trajectories[ti]

    def window(self, ti: int, lo: int, hi: int) -> Trajectory:
        return self.trajectories[ti]

    def trajectory(self, ti: int) -> Trajectory:
        return self.trajectories[ti]

    def close(self) -> None:
        pass


class FrameDataset(Dataset):
    """The training frames ``(trajectory, t)`` of one split, each turned into ``(graph, target, mask)``.

    ``data`` a native dataset folder; ``adapter`` the dataset's (:func:`hcmt.domains.adapters.config_adapter`);
    ``levels``/``remesh`` the hierarchy the model needs; ``radius`` the contact radius γ; ``noise_std`` σ on the
    ``noise_nodes`` (``normal`` or ``predicted``) and ``gamma`` the target correction; ``seed`` for the noise;
    ``contact_free_weight`` scales the loss mask of an item where nothing touches (``train.``, :meth:`_weigh`).
    Works with ``DataLoader(num_workers=N)``. :meth:`pushforward_item` builds an item with the model's help (in
    the training process).

    The split is read per item (:class:`hcmt.domains.trajectory.SplitReader`: the index, a few trajectories'
    static fields and hierarchies, the frames ``x^{t-h-1} .. x^{t+1}`` an item needs), so a process's memory does
    not grow with the split; ``keep`` trajectories stay in its LRU. ``in_memory=True`` holds the whole split
    instead (:func:`load_split`); both give the same items bit for bit.
    """

    def __init__(
        self,
        data: str | Path,
        split: str,
        adapter: Adapter,
        levels: int,
        remesh: bool,
        radius: float,
        noise_std: float = 0.0,
        gamma: float = 1.0,
        seed: int = 0,
        exclude: list[int] | None = None,
        noise_nodes: str = "normal",
        in_memory: bool = False,
        keep: int = 4,
        contact_free_weight: float = 1.0,
    ):
        self.data, self.split, self.adapter = Path(data), split, adapter
        self.levels, self.remesh, self.radius = levels, remesh, float(radius)
        self.noise_std, self.gamma, self.seed, self.exclude = float(noise_std), float(gamma), int(seed), exclude
        self.noise_nodes, self.contact_free_weight = noise_nodes, float(contact_free_weight)
        self.source = (
            InMemorySplit(data, split, adapter, levels, remesh, exclude)
            if in_memory
            else SplitReader(data, split, adapter, levels, remesh, exclude, keep)
        )
        self.frames = np.asarray(
            [(i, t) for i, steps in enumerate(self.source.steps) for t in range(adapter.history, int(steps) - 1)],
            np.int64,
        ).reshape(-1, 2)

    def __len__(self) -> int:
        return len(self.frames)

    def num_nodes(self, i: int) -> int:
        return int(self.source.nodes[int(self.frames[i][0])])

    def trajectory(self, ti: int) -> Trajectory:
        """Trajectory ``ti`` of the split with all its frames (tests, tools; training reads per item)."""
        return self.source.trajectory(ti)

    def __getitem__(self, key) -> tuple[Graph, Tensor, Tensor]:
        """``i`` (frame ``i``, noise seeded by ``(seed, i)``) or ``(i, step, rank, previous)`` (the trainer's key:
        noise drawn from the step's generator after the draws of the step's ``previous`` frames' node counts)."""
        tr, t, noise, _ = self._draw(key, self.adapter.history)
        return self._weigh(training_sample(tr, t, noise, self.gamma, self.radius))

    def pushforward_item(self, key, model, probability: float, forward=None) -> tuple[Graph, Tensor, Tensor]:
        """Item ``key`` as :meth:`__getitem__` (the same noise), except that with ``probability`` (drawn from the
        item's generator after its noise) and where frame ``t − 1`` has its history, it is a
        :func:`pushforward_sample` from frame ``t − 1`` (through ``forward`` when given)."""
        tr, t, noise, gen = self._draw(key, self.adapter.history + 1)
        u = float(torch.rand((), generator=gen))
        if u < probability and t - 1 >= self.adapter.history:
            return self._weigh(
                pushforward_sample(model, tr, t, noise, self._noise(tr, gen), self.gamma, self.radius, forward)
            )
        return self._weigh(training_sample(tr, t, noise, self.gamma, self.radius))

    def _weigh(self, item: tuple[Graph, Tensor, Tensor]) -> tuple[Graph, Tensor, Tensor]:
        """The item with its loss mask times ``contact_free_weight`` when nothing touches in its input frame: no
        contact pair closer than :data:`hcmt.inference.quantities.CONTACT_TOL` (the read-outs' touch tolerance; a
        pair within the contact radius γ but farther apart is near, not touching). The trainer's loss divides by the
        mask's nonzero entries, so the weight is the frame's share of the loss."""
        graph, tgt, mask = item
        if self.contact_free_weight != 1.0 and not bool((graph.contact_features[:, -1] <= CONTACT_TOL).any()):
            mask = mask * self.contact_free_weight
        return graph, tgt, mask

    def _noise(self, tr: Trajectory, gen: torch.Generator) -> Tensor:
        d = tr.world_pos.shape[-1]
        return (
            torch.randn((tr.num_nodes, d), generator=gen)
            * self.noise_std
            * noise_mask(self.adapter, tr.static["node_type"], d, self.noise_nodes)
        )

    def _draw(self, key, back: int) -> tuple[Trajectory, int, Tensor, torch.Generator]:
        """The item's trajectory with frames ``t - back .. t + 1`` read, ``t``, its noise and generator."""
        if isinstance(key, (int, np.integer)):
            i, gen, previous = int(key), torch.Generator().manual_seed(step_seed(self.seed, int(key), 0)), ()
        else:
            i, step, rank, previous = key
            gen = torch.Generator().manual_seed(step_seed(self.seed, step, rank))
        ti, t = (int(v) for v in self.frames[i])
        tr = self.source.window(ti, t - back, t + 2)
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
    for ti in range(len(dataset.source)):
        tr = dataset.source.static(ti)
        h = tr.hierarchy
        counts.append(
            (
                tr.num_nodes,
                int(h.edges[0].shape[1]),
                [(len(h.pool[l]), int(h.edges[l + 1].shape[1])) for l in range(h.levels)],
            )
        )
    dataset.source.close()  # DataLoader workers open the file themselves
    return PadSizes.fit(counts, batch)


def collate_padded(items: list[tuple[Graph, Tensor, Tensor]], sizes: PadSizes) -> tuple[Graph, Tensor, Tensor]:
    """:func:`collate_samples`, then dummy rows up to ``sizes`` (:func:`hcmt.graph.batch.pad_graph`); the
    targets and the loss mask get zero rows, so the loss is the unpadded one."""
    graph, tgt, mask = collate_samples(items)
    padded = pad_graph(graph, sizes)
    return padded, pad_rows(tgt, padded.num_nodes)[0], pad_rows(mask, padded.num_nodes)[0]


def padded_forward(net, sizes: PadSizes):
    """``graph -> output`` of ``net`` (a model compiled for padded graphs) on ``graph`` padded to ``sizes`` and cut
    back to its real nodes: a pushforward's prediction in Inductor's inference graphs instead of eager (the shipped
    recipe on one loaded CPU thread: 87 ms per eager prediction with its graph (cProfile), 22-29 ms per compiled
    inference call (torch.profiler)); it agrees with the model on the plain graph within float32 rounding
    (tests/training/test_train.py)."""
    return lambda graph: net(pad_graph(graph, sizes), accumulate=False)[: graph.num_nodes]


class StepSampler(Sampler):
    """The keys of every training step from ``start`` to ``end``: a fresh permutation of the frames per epoch
    (seeded by ``(seed, epoch)``), each rank taking its share of the step's global batch of ``batch`` frames per
    rank. A pure function of (seed, step, rank), so a resumed run sees the same data as one that never stopped."""

    def __init__(
        self, dataset: FrameDataset, batch: int, seed: int, start: int, end: int, world: int = 1, rank: int = 0
    ):
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
            picks = perm[first : first + self.batch]
            sizes = [self.dataset.num_nodes(i) for i in picks]
            yield [(int(i), step, self.rank, tuple(sizes[:k])) for k, i in enumerate(picks)]


def step_loader(
    frames: FrameDataset, sampler: StepSampler, pad: PadSizes | None = None, workers: int = 0, pushforward=None
):
    """An iterator over the training steps' batches ``(graph, target, mask)``: built by ``DataLoader`` workers
    (``workers``; 0: in this process) in step order, padded to ``pad`` when given (``train.compile``). With
    ``pushforward`` (``key -> item``: the item needs the model) the batches are built in this process, each just
    before its step."""
    collate = collate_samples if pad is None else functools.partial(collate_padded, sizes=pad)
    if pushforward is not None:
        return (collate([pushforward(key) for key in keys]) for keys in sampler)
    return iter(
        torch.utils.data.DataLoader(
            frames,
            batch_sampler=sampler,
            collate_fn=collate,
            num_workers=workers,
            worker_init_fn=_ignore_sigint if workers else None,
        )
    )


def _ignore_sigint(worker_id: int) -> None:
    """DataLoader workers leave Ctrl-C to the training process, which finishes the step and saves."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
