"""The model input: one graph (or several, batched) as plain tensors.

Conventions shared by every model and every graph builder:

* edges are ``[2, E]`` int64 with row 0 the **sender** ``j`` and row 1 the **receiver** ``i``
  (PyTorch Geometric's ``source_to_target``); mesh edges are present in both directions;
* features are **raw** (unnormalized): the models own their input normalizers;
* the hierarchy (paper, "Pooling Method") is given level by level: ``pool[l]`` holds, for level ``l+1``,
  the indices into level ``l``'s nodes of the nodes that level ``l+1`` keeps; ``level_edges[l]`` and
  ``level_features[l]`` are level ``l+1``'s (remeshed) mesh edges, in level ``l+1``'s own node numbering,
  and their raw features (same layout as ``mesh_features``). Level 0 is the mesh itself;
* a **padded** graph (:func:`pad_graph`, for compiled steps with static shapes) appends dummy rows at the end of
  every node and edge tensor of every level: dummy edges join the first dummy node of their level to itself,
  dummy nodes pool to the first dummy node of the level below, so no real node ever receives anything from
  padding; ``node_mask``, ``mesh_mask``, ``contact_mask`` and ``level_masks`` (1 real, 0 dummy) keep the dummy rows
  out of the normalizers' statistics and the loss.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace

import torch
from torch import Tensor

from hcmt.errors import InputError


@dataclass
class Graph:
    node_features: Tensor  # [N, F_node]
    mesh_edges: Tensor  # [2, E]
    mesh_features: Tensor  # [E, F_mesh]
    contact_edges: Tensor  # [2, C]
    contact_features: Tensor  # [C, F_contact]
    pool: list[Tensor] = field(default_factory=list)  # λ tensors, [N_{l+1}]
    level_edges: list[Tensor] = field(default_factory=list)  # λ tensors, [2, E_{l+1}]
    level_features: list[Tensor] = field(default_factory=list)  # λ tensors, [E_{l+1}, F_mesh]
    batch: Tensor | None = None  # [N] graph index of each node, None for a single graph
    # padded graphs only (pad_graph): 1.0 for real rows, 0.0 for dummy rows; None means every row is real
    node_mask: Tensor | None = None  # [N]
    mesh_mask: Tensor | None = None  # [E]
    contact_mask: Tensor | None = None  # [C]
    level_masks: list[Tensor] = field(default_factory=list)  # λ tensors, [E_{l+1}]

    @property
    def num_nodes(self) -> int:
        return int(self.node_features.shape[0])

    @property
    def num_levels(self) -> int:
        return len(self.pool)

    def to(self, device) -> "Graph":
        def move(v):
            if isinstance(v, Tensor):
                return v.to(device)
            if isinstance(v, list):
                return [t.to(device) for t in v]
            return v

        return replace(self, **{f.name: move(getattr(self, f.name)) for f in fields(self)})


def collate(graphs: list[Graph]) -> Graph:
    """Batch graphs into one disconnected graph: node indices of each graph are offset by the nodes before
    it, at every level. All graphs must have the same number of levels."""
    if len(graphs) == 1:
        g = graphs[0]
        return replace(g, batch=torch.zeros(g.num_nodes, dtype=torch.long, device=g.node_features.device))
    levels = {g.num_levels for g in graphs}
    if len(levels) != 1:
        raise InputError(f"cannot batch graphs with different hierarchy depths {sorted(levels)}")
    (num_levels,) = levels
    # node counts per graph per level: level 0 then each pooled level
    counts = [[g.num_nodes] + [int(p.shape[0]) for p in g.pool] for g in graphs]
    offsets = torch.tensor(counts).cumsum(0) - torch.tensor(counts)  # [B, λ+1]

    def cat_edges(getter, level):
        return torch.cat([getter(g) + int(offsets[b, level]) for b, g in enumerate(graphs)], dim=1)

    return Graph(
        node_features=torch.cat([g.node_features for g in graphs]),
        mesh_edges=cat_edges(lambda g: g.mesh_edges, 0),
        mesh_features=torch.cat([g.mesh_features for g in graphs]),
        contact_edges=cat_edges(lambda g: g.contact_edges, 0),
        contact_features=torch.cat([g.contact_features for g in graphs]),
        pool=[torch.cat([g.pool[l] + int(offsets[b, l]) for b, g in enumerate(graphs)]) for l in range(num_levels)],
        level_edges=[cat_edges(lambda g, l=l: g.level_edges[l], l + 1) for l in range(num_levels)],
        level_features=[torch.cat([g.level_features[l] for g in graphs]) for l in range(num_levels)],
        batch=torch.cat([torch.full((g.num_nodes,), b, dtype=torch.long) for b, g in enumerate(graphs)]),
    )


def bucket(n: int, smallest: int = 64) -> int:
    """The padded size of ``n`` rows: the smallest ``m·2^k >= n`` with ``m`` in 4..7 (at most 25 % dummy rows,
    four sizes per octave, so a compiled step sees few shapes), at least ``smallest``."""
    if n <= smallest:
        return smallest
    k = max(int(math.log2(n)) - 2, 0)
    while True:
        for m in (4, 5, 6, 7):
            if m << k >= n:
                return m << k
        k += 1


@dataclass(frozen=True)
class PadSizes:
    """Static sizes a padded graph is brought to: nodes and mesh edges of level 0, ``levels[l] = (nodes, edges)``
    of level ``l+1``; contact edges, which change every frame, go to :func:`bucket` sizes."""

    nodes: int
    mesh: int
    levels: tuple[tuple[int, int], ...] = ()

    @staticmethod
    def of(graphs: list[Graph], batch: int = 1) -> "PadSizes":
        """Sizes that hold a batch of ``batch`` of the largest of ``graphs``."""
        return PadSizes.fit(
            [
                (
                    g.num_nodes,
                    int(g.mesh_edges.shape[1]),
                    [(int(p.shape[0]), int(e.shape[1])) for p, e in zip(g.pool, g.level_edges)],
                )
                for g in graphs
            ],
            batch,
        )

    @staticmethod
    def fit(counts: list[tuple[int, int, list[tuple[int, int]]]], batch: int = 1) -> "PadSizes":
        """Sizes that hold a batch of ``batch`` of the largest of several graphs given by their counts ``(nodes,
        mesh edges, [(level nodes, level edges), ...])`` (each size its own maximum), with one dummy node per level
        to spare, rounded up to :func:`bucket` sizes so that batches of other meshes (other designs, the last
        smaller batch of a rollout) mostly land on shapes already compiled."""

        def most(values):
            return bucket(batch * max(values) + 1)

        levels = tuple(
            (most([c[2][l][0] for c in counts]), most([c[2][l][1] for c in counts]))
            for l in range(min(len(c[2]) for c in counts))
        )
        return PadSizes(most([c[0] for c in counts]), most([c[1] for c in counts]), levels)


def pad_rows(x: Tensor, size: int, what: str = "rows") -> tuple[Tensor, Tensor]:
    """``x`` ``[R, ...]`` with zero rows appended up to ``size``, and its mask ``[size]`` (1 real, 0 dummy)."""
    extra = size - x.shape[0]
    if extra < 0:
        raise InputError(f"{what}: {x.shape[0]} rows exceed the padded size {size}")
    mask = torch.cat([x.new_ones(x.shape[0]), x.new_zeros(extra)])
    return torch.cat([x, x.new_zeros((extra, *x.shape[1:]))]), mask


def pad_graph(g: Graph, sizes: PadSizes) -> Graph:
    """``g`` with dummy rows appended to every node and edge tensor up to ``sizes`` (contact edges to
    ``bucket(C)``), and the masks that mark them. A real node's output and every gradient are unchanged
    (tests/graph/test_padding.py): dummy edges only ever reach dummy nodes."""
    if g.node_mask is not None:
        raise InputError("graph is padded already")
    counts = [g.num_nodes] + [int(p.shape[0]) for p in g.pool]
    if len(sizes.levels) < g.num_levels:
        raise InputError(f"pad sizes cover {len(sizes.levels)} levels, the graph has {g.num_levels}")
    targets = [sizes.nodes] + [n for n, _ in sizes.levels[: g.num_levels]]
    for level, (n, t) in enumerate(zip(counts, targets)):
        if n >= t:
            raise InputError(f"level {level}: {n} nodes do not fit the padded size {t} (one dummy node needed)")

    def edges(e: Tensor, size: int, dummy: int, what: str) -> Tensor:
        if size < e.shape[1]:
            raise InputError(f"{what}: {e.shape[1]} edges exceed the padded size {size}")
        return torch.cat([e, e.new_full((2, size - e.shape[1]), dummy)], dim=1)

    node_features, node_mask = pad_rows(g.node_features, sizes.nodes, "nodes")
    mesh_features, mesh_mask = pad_rows(g.mesh_features, sizes.mesh, "mesh edges")
    c = bucket(g.contact_edges.shape[1])
    contact_features, contact_mask = pad_rows(g.contact_features, c, "contact edges")
    pool, level_edges, level_features, level_masks = [], [], [], []
    for l in range(g.num_levels):
        n_up, (n_pad, e_pad) = counts[l], sizes.levels[l]
        pool.append(torch.cat([g.pool[l], g.pool[l].new_full((n_pad - counts[l + 1],), n_up)]))
        level_edges.append(edges(g.level_edges[l], e_pad, counts[l + 1], f"level {l + 1} edges"))
        f, m = pad_rows(g.level_features[l], e_pad, f"level {l + 1} edges")
        level_features.append(f)
        level_masks.append(m)
    batch = (
        None
        if g.batch is None
        else torch.cat(
            [g.batch, g.batch.new_full((sizes.nodes - g.num_nodes,), int(g.batch.max()) + 1 if g.num_nodes else 0)]
        )
    )
    return Graph(
        node_features,
        edges(g.mesh_edges, sizes.mesh, g.num_nodes, "mesh edges"),
        mesh_features,
        edges(g.contact_edges, c, g.num_nodes, "contact edges"),
        contact_features,
        pool,
        level_edges,
        level_features,
        batch,
        node_mask,
        mesh_mask,
        contact_mask,
        level_masks,
    )
