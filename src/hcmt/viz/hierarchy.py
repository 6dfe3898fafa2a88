"""Pictures of the HCMT mesh hierarchy: the level-wise meshes (paper Fig. 4) and each level before and after
Delaunay remeshing (Fig. 10).

Every level is drawn at the mesh positions of its nodes (``mesh_pos[hierarchy.nodes[l]]``), its edges coloured by
object in the order of their lowest node (the Impact Plate: the plate green, the ball light blue, as the paper's
Fig. 3).
*Before remeshing* at level ``l`` is the graph the pooled nodes of level ``l`` would have without remeshing: the
nodes of level ``l-1`` kept by pooling, joined when at most two hops apart in level ``l-1`` (the BSMS edges,
:func:`hcmt.graph.remesh.two_hop_edges`); *after* is the hierarchy's Delaunay level. The same nodes, so the
picture isolates what remeshing changes. Each panel's title gives the node count, the ratio ``|V_l|/|V_0|`` and the
mean scaled Jacobian of the level's cells (before remeshing: the triangles of the 2-hop graph,
:func:`hcmt.graph.remesh.clique_cells`), the measure of the paper's Table 7.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.lines import Line2D
from mpl_toolkits.mplot3d.art3d import Line3DCollection

from hcmt.data.format import NodeType
from hcmt.errors import InputError
from hcmt.graph.hierarchy import Hierarchy
from hcmt.graph.quality import quality_summary
from hcmt.graph.remesh import clique_cells, two_hop_edges
from hcmt.viz.meshplot import draw_edges, impact_window, new_figure, panel_size, save_figure, scene_box
from hcmt.viz.rollouts import quantity_label

OBJECT_COLOURS = ("#2ca02c", "#1f9bd7", "#d62728", "#9467bd", "#8c564b", "#e377c2")  # object 0, 1, ...


def object_colours(object_id: np.ndarray) -> np.ndarray:
    """Colour of every node's object, by object number (the Impact Plate's plate, numbered first, is green)."""
    return np.asarray(OBJECT_COLOURS, dtype=object)[np.asarray(object_id) % len(OBJECT_COLOURS)]


def object_legend(fig, object_id: np.ndarray, node_type: np.ndarray | None) -> None:
    """Legend naming each object by its most common node type (``NORMAL`` plate, ``OBSTACLE`` ball)."""

    handles = []
    for o in np.unique(object_id)[: len(OBJECT_COLOURS)]:  # a handful of objects
        label = f"object {o}"
        if node_type is not None:
            types = np.asarray(node_type).reshape(-1)[object_id == o]
            common = int(np.bincount(types).argmax())
            label += f" ({NodeType(common).name if common in NodeType._value2member_map_ else common} nodes)"
        handles.append(Line2D([], [], color=OBJECT_COLOURS[o % len(OBJECT_COLOURS)], label=label))
    fig.legend(handles=handles, fontsize=7, loc="outside lower center", ncols=len(handles), frameon=False)


def _draw_level(
    ax, pos: np.ndarray, edges: np.ndarray, colours: np.ndarray, box, *, marked: bool = False, lw: float = 0.5
) -> None:
    edges = edges[:, edges[0] < edges[1]]  # each undirected edge once
    if pos.shape[1] == 3:
        seg = np.stack([pos[edges[0]], pos[edges[1]]], axis=1)
        ax.add_collection3d(Line3DCollection(seg, colors=list(colours[edges[0]]), linewidths=lw))
        ax.scatter(*pos.T, s=2, c=list(colours), depthshade=False)
        lo, hi = pos.min(0), pos.max(0)
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_zlim(lo[2], hi[2])
        ax.set_box_aspect(np.maximum(hi - lo, 1e-3 * (hi - lo).max()))
        return
    draw_edges(ax, pos, edges, colors=list(colours[edges[0]]), linewidths=lw)
    inside = ((pos[:, 0] >= box[0]) & (pos[:, 0] <= box[1]) & (pos[:, 1] >= box[2]) & (pos[:, 1] <= box[3])).sum()
    size = float(np.clip(2000.0 / max(int(inside), 1), 0.3, 9.0))  # dots shrink as the visible nodes crowd
    ax.scatter(
        pos[:, 0],
        pos[:, 1],
        s=size if marked else min(size, 1.5),
        c="black" if marked else list(colours),
        zorder=3,
        linewidths=0,
    )
    ax.set_xlim(box[0], box[1])
    ax.set_ylim(box[2], box[3])
    ax.set_aspect("equal")
    ax.tick_params(labelsize=6)


def _axes(fig, rows, cols, k, three_d):
    return fig.add_subplot(rows, cols, k, **({"projection": "3d"} if three_d else {}))


def _view(mesh_pos: np.ndarray, hierarchy: Hierarchy, zoom: bool):
    """(level-0 positions, whether 3-D, the drawing window: the impact zoom or the whole 2-D scene)."""
    pos0 = np.asarray(mesh_pos, np.float64)
    three_d = pos0.shape[1] == 3
    if zoom and three_d:
        raise InputError("the zoomed view is for 2-D meshes")
    box = impact_window(pos0, hierarchy.object_id) if zoom else (None if three_d else scene_box(pos0))
    if box is None and not three_d:
        raise InputError("a single object: there is no impact to zoom on")
    return pos0, three_d, box


def level_figure(
    mesh_pos: np.ndarray,
    hierarchy: Hierarchy,
    *,
    levels: list[int] | None = None,
    zoom: bool = False,
    length_unit: str | None = None,
    node_type: np.ndarray | None = None,
    columns: int = 4,
):
    """The level-wise meshes (Fig. 4): one panel per level (default all, ``0..λ``); ``zoom`` shows the impact
    window (2-D). Returns the figure."""
    levels = list(range(hierarchy.levels + 1)) if levels is None else [int(l) for l in levels]
    for l in levels:
        if not 0 <= l <= hierarchy.levels:
            raise InputError(f"level {l} out of range; the hierarchy has levels 0..{hierarchy.levels}")
    pos0, three_d, box = _view(mesh_pos, hierarchy, zoom)
    colours = object_colours(hierarchy.object_id)
    cols = min(columns, len(levels))
    rows = int(np.ceil(len(levels) / cols))
    w, h = panel_size(box, 3.2) if not three_d else (3.2, 2.8)
    fig = new_figure(w * cols + 0.4, h * rows + 0.5)
    n0 = hierarchy.num_nodes(0)
    for k, l in enumerate(levels):
        ax = _axes(fig, rows, cols, k + 1, three_d)
        nodes = hierarchy.nodes[l]
        _draw_level(ax, pos0[nodes], hierarchy.edges[l], colours[nodes], box, lw=0.6 if zoom else 0.4)
        q = quality_summary(pos0[nodes], hierarchy.cells[l]) if len(hierarchy.cells[l]) else None
        sj = f", scaled Jacobian {q['jacobian']:.2f}" if q and q["cells"] else ""
        ax.set_title(f"Level {l}: {len(nodes)} nodes\n$|V_{{{l}}}|/|V_0|$ = {len(nodes) / n0:.2f}{sj}", fontsize=8)
        if k == 0:
            object_legend(fig, hierarchy.object_id, node_type)
        if not three_d:
            ax.set_xlabel(quantity_label("x", length_unit), fontsize=7)
            ax.set_ylabel(quantity_label("y", length_unit), fontsize=7)
    how = "Delaunay remeshing" if hierarchy.remesh else "2-hop edges, no remeshing"
    fig.suptitle(
        f"Mesh hierarchy, level by level ({how}; {'impact zoom' if zoom else 'whole scene'})\n"
        "scaled Jacobian: mean over the level's cells, 1 for equilateral triangles",
        fontsize=9,
    )
    return fig


def remeshing_figure(
    mesh_pos: np.ndarray,
    hierarchy: Hierarchy,
    *,
    zoom: bool = False,
    length_unit: str | None = None,
    node_type: np.ndarray | None = None,
):
    """Each level ``1..λ`` before (2-hop edges of the pooled nodes) and after Delaunay remeshing (Fig. 10); the
    pooled nodes are the black dots. Needs a hierarchy built with ``remesh=True``."""
    if not hierarchy.remesh:
        raise InputError("this hierarchy was built without remeshing; build it with remesh=True to compare")
    if hierarchy.levels < 1:
        raise InputError("the hierarchy has no pooled level (levels=0): nothing was remeshed")
    pos0, three_d, box = _view(mesh_pos, hierarchy, zoom)
    colours = object_colours(hierarchy.object_id)
    k_cell = hierarchy.cells[0].shape[1]
    rows = hierarchy.levels
    w, h = panel_size(box, 3.4) if not three_d else (3.4, 2.8)
    fig = new_figure(2 * w + 0.4, h * rows + 0.5)
    for l in range(1, rows + 1):
        nodes = hierarchy.nodes[l]
        n_fine = hierarchy.num_nodes(l - 1)
        before = two_hop_edges(hierarchy.edges[l - 1], n_fine, hierarchy.pool[l - 1])
        graphs = (
            ("before", before, clique_cells(before, len(nodes), k_cell)),
            ("after", hierarchy.edges[l], hierarchy.cells[l]),
        )
        for c, (when, edges, cells) in enumerate(graphs):
            ax = _axes(fig, rows, 2, 2 * (l - 1) + c + 1, three_d)
            _draw_level(ax, pos0[nodes], edges, colours[nodes], box, marked=True, lw=0.6)
            q = quality_summary(pos0[nodes], cells)
            sj = f"scaled Jacobian {q['jacobian']:.2f}" if q["cells"] else "no cells"
            ax.set_title(f"Level {l} {when} remeshing\n{edges.shape[1] // 2} edges, {sj}", fontsize=8)
            if l == 1 and c == 0:
                object_legend(fig, hierarchy.object_id, node_type)
            if not three_d:
                ax.set_xlabel(quantity_label("x", length_unit), fontsize=7)
                ax.set_ylabel(quantity_label("y", length_unit), fontsize=7)
    fig.suptitle(
        "Pooled levels before (2-hop edges) and after Delaunay remeshing"
        + (" (impact zoom)" if zoom else "")
        + "\nblack dots: the pooled nodes; scaled Jacobian: mean over "
        "the cells, 1 for equilateral triangles",
        fontsize=9,
    )
    return fig


def plot_hierarchy(
    mesh_pos: np.ndarray,
    hierarchy: Hierarchy,
    out_dir: str | Path,
    *,
    length_unit: str | None = None,
    node_type: np.ndarray | None = None,
    dpi: int = 150,
) -> list[Path]:
    """Write ``hierarchy_levels.png`` and ``hierarchy_remeshing.png`` (whole scene) and, for a 2-D scene of several
    objects, their ``_zoom`` versions. Returns the paths written."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    pos = np.asarray(mesh_pos)
    zooms = [False] + ([True] if pos.shape[1] == 2 and len(np.unique(hierarchy.object_id)) > 1 else [])
    paths = []
    for zoom in zooms:
        suffix = "_zoom" if zoom else ""
        kw = dict(zoom=zoom, length_unit=length_unit, node_type=node_type)
        figures = [("levels", level_figure(pos, hierarchy, **kw))]
        if hierarchy.remesh and hierarchy.levels:
            figures.append(("remeshing", remeshing_figure(pos, hierarchy, **kw)))
        for name, fig in figures:
            path = out_dir / f"hierarchy_{name}{suffix}.png"
            save_figure(fig, path, dpi=dpi)
            paths.append(path)
    return paths
