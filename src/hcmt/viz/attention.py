r"""Attention maps of a trained model as sparse-matrix images (paper Fig. 6 and 15-18).

The model runs once on the graph of one ground-truth frame (teacher forcing: the data's :math:`x^t` and
:math:`x^{t-1}`, as in training) and returns every block's softmax weights :math:`a^k_{ij}` (``[E, H, d_k]``: one
weight per head and channel, :mod:`hcmt.models.attention`). A map is the matrix
:math:`A_{ij} = \operatorname{mean}_{k,c}\, a^{k,c}_{ij}` with the receiver :math:`i` as the row and the sender
:math:`j` as the column. Averaging over heads and channels is our choice (the paper does not say how its maps
reduce the heads); it keeps the softmax's property that every row with an incoming edge sums to 1, so a row of the
image is how one node spreads its attention.

HCMT with ``attention="official"`` (the authors' unnormalized :math:`w_{ij} = \exp(\mathrm{clip}(\cdot))`) has no
such weights: for display, each head and channel of :math:`w` is divided by its sum over the receiver's incoming
edges of the branch, :math:`w_{ij} / \sum_{j'} w_{ij'}`, so the figure is comparable; the title says so.

Nodes are ordered object by object (their order within an object kept), so each object is a diagonal block and the
contact attention lies in the off-diagonal blocks; block boundaries are drawn and labelled (the Impact Plate: the
plate, object 0, top left; the ball bottom right, as the paper's Fig. 15 describes). HCMT gives, per CMT block,
``cmt{n}.contact`` and ``cmt{n}.mesh`` on level 0, and per HMT block ``hmt.down{l}`` / ``hmt.bottom{λ}`` /
``hmt.up{l}`` on level ``l``; the figure shows the first CMT block's two branches and the down-going HMT block of
every level (the bottom block for level λ), like Fig. 15. The Graph Transformer baseline gives ``gt{n}`` over mesh
and contact edges together.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import torch
from matplotlib import colors

from hcmt.data.format import NodeType, Split
from hcmt.domains.frames import input_graph
from hcmt.domains.trajectory import prepare_trajectory
from hcmt.errors import InputError
from hcmt.graph.hierarchy import hierarchy_cache_dir
from hcmt.inference.run import Run
from hcmt.models import REGISTRY
from hcmt.models.attention import AttentionMap, recording
from hcmt.viz.meshplot import closest_pair, new_figure, save_figure
from hcmt.viz.rollouts import trajectory_index


@dataclass
class AttentionMaps:
    """The maps of one frame: ``matrices[name]`` a CSR ``[N_l, N_l]`` (row receiver, column sender) of the block
    ``blocks[name]`` (an :class:`~hcmt.models.attention.AttentionMap` without its tensors: level, stage, block,
    branch); ``object_id[l]`` the object of every level-``l`` node."""

    matrices: dict[str, sp.csr_matrix]
    blocks: dict[str, AttentionMap]
    object_id: list[np.ndarray]
    trajectory: str = ""
    frame: int = 0
    model: str = ""
    node_type: list[np.ndarray] = field(default_factory=list)
    normalized_for_display: bool = False  # official attention: w_ij / sum_j w_ij per receiver, not softmax weights


def attention_matrix(weights, edges, num_nodes: int) -> sp.csr_matrix:
    """Weights ``[E, ...]`` of edges ``[2, E]`` (row 0 sender j, row 1 receiver i) -> CSR ``A[i, j]``, the mean
    over every axis after the first (heads, channels)."""
    w = np.asarray(weights.detach().cpu().numpy() if hasattr(weights, "detach") else weights, np.float64)
    e = np.asarray(edges.detach().cpu().numpy() if hasattr(edges, "detach") else edges, np.int64)
    if w.shape[0] != e.shape[1]:
        raise InputError(f"{w.shape[0]} weights for {e.shape[1]} edges")
    w = w.reshape(len(w), -1).mean(1)
    return sp.coo_matrix((w, (e[1], e[0])), shape=(num_nodes, num_nodes)).tocsr()


def maps_from_model(model, graph) -> dict:
    """Run ``model`` on ``graph`` recording its attention: ``{"matrices": {name: CSR}, "blocks": {name:
    AttentionMap without weights}, "normalized_for_display"}`` from the model's
    :class:`~hcmt.models.attention.AttentionMap` list (each names its level and carries its edges)."""
    device = next(model.parameters()).device
    with torch.no_grad(), recording(model) as attention:
        model(graph.to(device), accumulate=False)
    sizes = [graph.num_nodes] + [len(p) for p in graph.pool]
    matrices, blocks, rescaled = {}, {}, False
    for m in attention:
        w, edges = m.weights.cpu(), m.edge_index.cpu()
        if not m.normalized:  # unnormalized weights: divide by the receiver's sum (per head, channel) for display
            receiver = edges[1]
            total = torch.zeros((sizes[m.level], *w.shape[1:]), dtype=w.dtype).index_add_(0, receiver, w)
            w = w / total.index_select(0, receiver)
            rescaled = True
        matrices[m.name] = attention_matrix(w, edges, sizes[m.level])
        blocks[m.name] = replace(m, weights=None, edge_index=None)
    return {"matrices": matrices, "blocks": blocks, "normalized_for_display": rescaled}


def default_frame(world_pos: np.ndarray, object_id: np.ndarray, history: int) -> int:
    """The ground-truth frame where two objects come closest (the impact), kept where a graph can be built."""
    gaps = []
    for f in range(len(world_pos)):  # one KD-tree query per frame
        pair = closest_pair(world_pos[f], object_id)
        gaps.append(0.0 if pair is None else float(np.linalg.norm(pair[0] - pair[1])))
    return int(np.clip(np.argmin(gaps), history, len(world_pos) - 2))


def frame_attention(
    run: Run, data: str | Path, split: str = "test", trajectory: int | str = 0, frame: int | None = None
) -> AttentionMaps:
    """Attention maps of a run's model on one ground-truth frame (default: the impact, :func:`default_frame`)."""
    if not REGISTRY[run.info.model["name"]].has_attention:
        raise InputError(
            f"{run.label} has no attention to show (MeshGraphNets is not a Transformer); use an HCMT or GT run"
        )
    adapter = run.adapter
    levels, remesh = run.hierarchy_spec
    with Split(data, split) as s:
        index = trajectory_index(s.names, trajectory)
        traj = prepare_trajectory(
            s[index], s.names[index], adapter, levels, remesh, hierarchy_cache_dir(data), s.attrs(index)
        )
    world = traj.world_pos
    obj = np.asarray(traj.hierarchy.object_id)
    h = adapter.history
    T = traj.num_steps
    if frame is None:
        frame = default_frame(world.numpy(), obj, h)
    if not h <= frame <= T - 2:
        raise InputError(
            f"frame {frame} out of range: a graph needs frames {h}..{T - 2} of trajectory {traj.name} "
            f"(the previous frame as input, the next one for prescribed nodes)"
        )
    graph = input_graph(traj, world[frame], world[frame - h], world[frame + 1], run.radius)
    level_nodes = [np.asarray(v) for v in traj.hierarchy.nodes[1:]]
    maps = maps_from_model(run.model, graph)
    nt = traj.static["node_type"].numpy()
    return AttentionMaps(
        maps["matrices"],
        maps["blocks"],
        [obj] + [obj[v] for v in level_nodes],
        traj.name,
        int(frame),
        run.label,
        [nt] + [nt[v] for v in level_nodes],
        maps["normalized_for_display"],
    )


def object_order(object_id: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(permutation putting the nodes object by object, boundaries between the blocks in the new order)."""
    order = np.argsort(object_id, kind="stable")
    counts = np.bincount(object_id)
    return order, np.cumsum(counts[counts > 0])[:-1]


def default_panels(maps: AttentionMaps) -> list[tuple[str, str]]:
    """(block name, panel title) of the figure: the first CMT block's branches and each level's first HMT block
    (Fig. 15), or the first and last GT layers."""
    blocks = list(maps.blocks.values())
    first_cmt = [b for b in blocks if b.stage == "cmt" and b.block == 0]
    first_cmt.sort(key=lambda b: 0 if b.branch == "contact" else 1)
    panels = [(b.name, f"{b.branch.capitalize()} of CMT (block 0)") for b in first_cmt]
    hmt = [b for b in blocks if b.stage in ("down", "bottom", "up")]
    for level in sorted({b.level for b in hmt}):
        first = next(b for b in hmt if b.level == level)
        panels.append((first.name, f"Level {level} of HMT ({first.stage} block)"))
    gts = [b for b in blocks if b.stage == "gt"]
    for b in (gts[:1] + gts[-1:]) if len(gts) > 1 else gts:
        panels.append((b.name, f"GT layer {b.block} (mesh and contact)"))
    return panels


def object_ticks(
    maps: AttentionMaps, level: int, order: np.ndarray, bounds: np.ndarray
) -> tuple[list[float], list[str]]:
    """One tick per object block of a level's map, labelled with the object and its most common node type."""
    n = len(order)
    starts = np.concatenate([[0], bounds])
    ends = np.concatenate([bounds, [n]])
    ticks, labels = [], []
    for o, (a, b) in enumerate(zip(starts, ends)):  # one tick per object block
        ticks.append((a + b - 1) / 2)
        types = maps.node_type[level][order[a:b]] if maps.node_type else None
        common = int(np.bincount(types).argmax()) if types is not None and len(types) else None
        labels.append(f"obj {o}" + (f"\n{NodeType(common).name}" if common in NodeType._value2member_map_ else ""))
    return ticks, labels


def attention_figure(maps: AttentionMaps, panels: list[tuple[str, str]] | None = None, columns: int = 3):
    """The maps as sparse-matrix images, one panel per block, one logarithmic colour scale for all (the weights of
    a row sum to 1; a log scale shows the spread of small weights and the few large ones alike)."""
    panels = panels or default_panels(maps)
    if not panels:
        raise InputError("no attention blocks to draw")
    cols = min(columns, len(panels))
    rows = int(np.ceil(len(panels) / cols))
    fig = new_figure(3.3 * cols + 1.0, 3.8 * rows + 0.6)
    fig.get_layout_engine().set(h_pad=0.12, hspace=0.06)  # room between a panel's title and the x label above
    values = np.concatenate([maps.matrices[n].data for n, _ in panels])
    positive = values[values > 0]
    lo = float(max(positive.min(), 1e-4)) if len(positive) else 1e-3
    norm = colors.LogNorm(vmin=min(lo, 0.5), vmax=1.0)
    mappable = None
    for k, (name, title) in enumerate(panels):
        ax = fig.add_subplot(rows, cols, k + 1)
        level = maps.blocks[name].level
        obj = maps.object_id[level]
        n = len(obj)
        order, bounds = object_order(obj)
        rank = np.empty(n, np.int64)
        rank[order] = np.arange(n)
        coo = maps.matrices[name].tocoo()
        size = float(np.clip((200.0 / max(n, 1)) ** 2, 1.0, 25.0))  # about one node's width, at least a point
        if maps.blocks[name].branch == "contact":
            size = max(size, 6.0)  # contact edges are few: make them visible
        mappable = ax.scatter(
            rank[coo.col], rank[coo.row], c=coo.data, s=size, marker="s", linewidths=0, norm=norm, cmap="viridis"
        )
        for b in bounds:
            ax.axhline(b - 0.5, color="red", lw=0.6)
            ax.axvline(b - 0.5, color="red", lw=0.6)
        ax.set_xlim(-0.5, n - 0.5)
        ax.set_ylim(n - 0.5, -0.5)
        ax.set_aspect("equal")
        ticks, labels = object_ticks(maps, level, order, bounds)
        ax.set_xticks(ticks, labels, fontsize=6)
        ax.set_yticks(ticks, labels, fontsize=6, rotation=90, va="center")
        ax.set_xlabel(f"sender j ({n} nodes)", fontsize=7)
        ax.set_ylabel("receiver i", fontsize=7)
        ax.set_title(f"{title}\n{coo.nnz} edges", fontsize=8)
    cbar = fig.colorbar(mappable, ax=fig.axes, aspect=40)
    if maps.normalized_for_display:
        cbar.set_label(
            "$w_{ij} / \\sum_j w_{ij}$ (official attention, normalized for display)\n(mean over heads and channels)",
            fontsize=8,
        )
    else:
        cbar.set_label("attention weight $a_{ij}$\n(mean over heads and channels)", fontsize=8)
    fig.suptitle(
        f"Attention maps of {maps.model}, trajectory {maps.trajectory}, frame {maps.frame} "
        "\nrow i: how receiver i spreads its attention over its senders j (each row sums to 1); "
        "red lines: object blocks",
        fontsize=9,
    )
    return fig


def plot_attention(maps: AttentionMaps, path: str | Path, dpi: int = 150) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    save_figure(attention_figure(maps), path, dpi=dpi)
    return path
