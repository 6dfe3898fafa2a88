"""Drawing a nodal field on a deformed mesh (matplotlib, no pyplot: nothing here needs a display).

2-D meshes (triangles in the plane, e.g. the Impact Plate cross-section) are drawn with
:class:`matplotlib.tri.Triangulation` and Gouraud-shaded ``tripcolor`` (the nodal values interpolated linearly over
each triangle, as a CST field is), at equal aspect: a 0.75 mm plate under a 3 mm ball must look like one.
3-D meshes (tetrahedra, or cloth triangles in 3-D) are drawn as their surface triangles in a 3-D axes, each face
coloured by the mean of its nodes' values.

The zoom window around the impact (:func:`impact_window`) is our choice, since the paper only marks one by hand
(Fig. 5's red box): centred on the closest pair of nodes of two different objects, as tall as four times the
thinnest object's thickness (the smaller side of its bounding box; 3 mm for a 0.75 mm plate) and 4/3 as wide, moved
inside the scene's bounding box. That shows the ball's tip and the plate beneath it with the through-thickness
stress visible at any plate thickness.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib
import numpy as np
from matplotlib import colors
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.tri import Triangulation
from mpl_toolkits.mplot3d.art3d import Poly3DCollection
from scipy.spatial import cKDTree

from hcmt.files import atomic_path

ZOOM_THICKNESSES = 4.0  # zoom window height, in thicknesses of the thinnest object
ZOOM_ASPECT = 4.0 / 3.0  # zoom window width / height


def new_figure(width: float, height: float) -> Figure:
    """A figure drawn by Agg (headless); ``constrained`` layout keeps titles and colour bars apart."""
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig: Figure, path: str | Path, dpi: int = 150) -> Path:
    """Write a figure atomically (a temporary file renamed onto ``path``): a full disk or an interrupt leaves no
    empty or half-written picture, and an error names ``path``."""
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format=path.suffix.lstrip(".") or "png")
    return path


def surface_triangles(cells: np.ndarray) -> np.ndarray:
    """Triangles to draw: the cells themselves, or the boundary faces (used by one tetrahedron) of a volume mesh."""
    cells = np.asarray(cells, np.int64)
    if cells.shape[1] == 3:
        return cells
    faces = np.concatenate([cells[:, [0, 1, 2]], cells[:, [0, 1, 3]], cells[:, [0, 2, 3]], cells[:, [1, 2, 3]]])
    _, inv, count = np.unique(np.sort(faces, axis=1), axis=0, return_inverse=True, return_counts=True)
    return faces[count[inv.ravel()] == 1]


def field_limits(values: list[np.ndarray]) -> tuple[float, float]:
    """Colour range of the reference values: [0, max] for a non-negative field (von Mises stress, a displacement
    norm), [min, max] otherwise; a constant field gets a range of one unit around its value."""
    v = np.concatenate([np.ravel(a) for a in values])
    v = v[np.isfinite(v)]
    if not len(v):
        return 0.0, 1.0
    lo, hi = float(v.min()), float(v.max())
    lo = 0.0 if lo >= 0 else lo
    if hi <= lo:
        return lo - 0.5, lo + 0.5
    return lo, hi


def extend_of(norm: colors.Normalize, values: list[np.ndarray]) -> str:
    """Colour-bar ``extend``: which ends other panels' values pass beyond the shared range."""
    v = np.concatenate([np.ravel(a) for a in values]) if values else np.zeros(0)
    v = v[np.isfinite(v)]
    low = bool(len(v) and v.min() < norm.vmin - 1e-9 * abs(norm.vmax - norm.vmin))
    high = bool(len(v) and v.max() > norm.vmax + 1e-9 * abs(norm.vmax - norm.vmin))
    return {(False, False): "neither", (True, False): "min", (False, True): "max", (True, True): "both"}[(low, high)]


def draw_field_2d(ax, pos: np.ndarray, cells: np.ndarray, values: np.ndarray, norm, cmap, *, edges: bool = False):
    """Gouraud-shaded nodal ``values`` [N] on the triangles ``cells`` at positions ``pos`` [N, 2]; returns the
    mappable. ``edges`` overlays the mesh (thin lines) so the node positions can be compared."""
    tri = Triangulation(pos[:, 0], pos[:, 1], surface_triangles(cells))
    artist = ax.tripcolor(tri, np.asarray(values, np.float64), shading="gouraud", norm=norm, cmap=cmap, rasterized=True)
    if edges:
        ax.triplot(tri, color="white", lw=0.3, alpha=0.55)
    ax.set_aspect("equal")
    return artist


def draw_field_3d(
    ax,
    pos: np.ndarray,
    cells: np.ndarray,
    values: np.ndarray,
    norm,
    cmap,
    *,
    limits: tuple[np.ndarray, np.ndarray] | None = None,
    length_unit: str | None = None,
):
    """Surface triangles of a 3-D mesh, each coloured by its nodes' mean value, at equal scale on every axis.
    ``limits`` (lo [3], hi [3]): the axes' box, shared by the panels to compare (default: ``pos``'s own)."""

    faces = surface_triangles(cells)
    face_values = np.asarray(values, np.float64)[faces].mean(1)
    poly = Poly3DCollection(pos[faces], facecolors=_cmap(cmap)(norm(face_values)), edgecolors="none")
    ax.add_collection3d(poly)
    lo, hi = limits if limits is not None else (pos.min(0), pos.max(0))
    span = np.maximum(hi - lo, 1e-3 * float((hi - lo).max() or 1.0))  # a flat mesh still gets a box
    ax.set_xlim(lo[0], lo[0] + span[0])
    ax.set_ylim(lo[1], lo[1] + span[1])
    ax.set_zlim(lo[2], lo[2] + span[2])
    ax.set_box_aspect(span)
    ax.tick_params(labelsize=5, pad=0)
    ax.locator_params(nbins=4)
    for axis, name in zip((ax.xaxis, ax.yaxis, ax.zaxis), "xyz"):
        axis.set_label_text(f"{name} [{length_unit}]" if length_unit else name, fontsize=6)
        axis.labelpad = -6
    return ScalarMappable(norm=norm, cmap=_cmap(cmap))


def box_3d(positions: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) corners enclosing every finite position of the given [N, 3] arrays."""
    p = np.concatenate([np.asarray(x).reshape(-1, 3) for x in positions])
    p = p[np.isfinite(p).all(1)]
    return p.min(0), p.max(0)


def _cmap(cmap):
    return matplotlib.colormaps[cmap] if isinstance(cmap, str) else cmap


def draw_edges(ax, pos: np.ndarray, edges: np.ndarray, **kw) -> LineCollection:
    """Graph edges ``[2, E]`` as line segments at positions ``pos`` [N, 2]."""
    seg = np.stack([pos[edges[0]], pos[edges[1]]], axis=1)
    lines = LineCollection(seg, **{"colors": "0.25", "linewidths": 0.4, **kw})
    ax.add_collection(lines)
    ax.set_aspect("equal")
    return lines


def scene_box(pos: np.ndarray, pad: float = 0.03) -> tuple[float, float, float, float]:
    """Bounding box ``(x0, x1, y0, y1)`` of 2-D positions, padded by ``pad`` of its larger side."""
    lo, hi = pos[:, :2].min(0), pos[:, :2].max(0)
    p = pad * float((hi - lo).max() or 1.0)
    return lo[0] - p, hi[0] + p, lo[1] - p, hi[1] + p


def closest_pair(pos: np.ndarray, object_id: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Positions of the closest pair of nodes of two different objects (None for a single object)."""
    ids = np.unique(object_id)
    if len(ids) < 2:
        return None
    best, pair = np.inf, None
    for o in ids:  # one KD-tree query per object (a scene has a handful), vectorized over its nodes
        mine, others = pos[object_id == o], pos[object_id != o]
        d, j = cKDTree(others).query(mine)
        k = int(np.argmin(d))
        if d[k] < best:
            best, pair = float(d[k]), (mine[k], others[j[k]])
    return pair


def closest_contact(pos: np.ndarray, object_id: np.ndarray) -> np.ndarray | None:
    """Midpoint of the closest pair of nodes of two different objects (None for a single object)."""
    pair = closest_pair(pos, object_id)
    return None if pair is None else 0.5 * (pair[0] + pair[1])


def impact_window(
    pos: np.ndarray, object_id: np.ndarray, reference: np.ndarray | None = None
) -> tuple[float, float, float, float] | None:
    """Zoom window ``(x0, x1, y0, y1)`` around the impact at 2-D positions ``pos`` (see the module docstring);
    thicknesses are measured on ``reference`` (the undeformed mesh; default ``pos``). None for a single object."""
    centre = closest_contact(pos, object_id)
    if centre is None:
        return None
    ref = pos if reference is None else reference
    ids = np.unique(object_id)
    lo = np.stack([ref[object_id == o].min(0) for o in ids])  # per object: a handful
    hi = np.stack([ref[object_id == o].max(0) for o in ids])
    extent = hi - lo
    thin = extent.min(1)
    thin = float(thin[thin > 0].min()) if (thin > 0).any() else float(extent.max())
    height = ZOOM_THICKNESSES * thin
    width = ZOOM_ASPECT * height
    x0, x1, y0, y1 = scene_box(pos, pad=0.0)
    x0, x1, y0, y1 = x0 - 0.05 * height, x1 + 0.05 * height, y0 - 0.05 * height, y1 + 0.05 * height  # a margin
    wx0 = float(np.clip(centre[0] - width / 2, x0, max(x0, x1 - width)))
    wy0 = float(np.clip(centre[1] - height / 2, y0, max(y0, y1 - height)))
    return wx0, wx0 + width, wy0, wy0 + height


def panel_size(box: tuple[float, float, float, float], width: float = 3.4) -> tuple[float, float]:
    """Inches of one equal-aspect panel showing ``box``: ``width`` wide, as tall as the box's aspect asks
    (between 0.9 and 4.5 inches, so a thin plate alone still gets a readable panel)."""
    dx, dy = box[1] - box[0], box[3] - box[2]
    return width, float(np.clip(width * dy / max(dx, 1e-12), 0.9, 4.5))
