"""An animation of a rollout beside the ground truth (a GIF, written with Pillow).

Columns are the ground truth and each run; a 2-D scene of several objects gets a second row with the impact zoom
(:func:`hcmt.viz.meshplot.impact_window`, following the ground truth frame by frame). The colour scale is fixed
for the whole animation (a scale that changes between frames would make colours meaningless): from 0 (or the
minimum) to the ground truth's 99th percentile over all frames and nodes (``percentile``). The percentile rather
than the maximum is our choice: the impact's peak lasts a few frames at a few nodes and would leave the rest of
the animation one dark colour; values beyond it saturate, and the colour bar's arrow says so.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib import colors
from matplotlib.cm import ScalarMappable
from PIL import Image

from hcmt.errors import InputError
from hcmt.files import atomic_path
from hcmt.viz.contours import field_label, field_name, field_values, view_box
from hcmt.viz.meshplot import (
    box_3d,
    closest_pair,
    draw_field_2d,
    draw_field_3d,
    extend_of,
    impact_window,
    new_figure,
    panel_size,
)
from hcmt.viz.rollouts import Case, quantity_label


def animation_frames(num_frames: int, stride: int | None = None, max_frames: int = 100) -> list[int]:
    """Frames drawn: every ``stride``-th (default: the stride that keeps at most ``max_frames``), and the last."""
    if stride is None:  # the last frame is added below, so at most max_frames - 1 strides fit
        stride = 1 if num_frames <= max_frames else int(np.ceil((num_frames - 1) / (max_frames - 1)))
    if stride < 1:
        raise InputError(f"stride must be >= 1, got {stride}")
    frames = list(range(0, num_frames, stride))
    if frames[-1] != num_frames - 1:
        frames.append(num_frames - 1)
    return frames


def animation_norm(case: Case, field: str, percentile: float = 99.0) -> tuple[colors.Normalize, str]:
    """The fixed colour scale: [0 or min, ``percentile`` of the ground truth over every frame]."""
    if not 0 < percentile <= 100:
        raise InputError(f"percentile must be in (0, 100], got {percentile}")
    truth = np.stack([field_values(case.truth, f, field) for f in range(case.num_frames)])
    truth = truth[np.isfinite(truth)]
    lo = 0.0 if truth.min() >= 0 else float(truth.min())
    hi = float(np.percentile(truth, percentile))
    if hi <= lo:
        hi = float(truth.max()) if truth.max() > lo else lo + 1.0
    norm = colors.Normalize(lo, hi)
    every = [field_values(s, f, field) for s in case.series for f in range(case.num_frames)]
    return norm, extend_of(norm, every)


def closest_frame(case: Case) -> int:
    """The ground-truth frame where two objects come closest (the impact)."""
    obj = case.object_id
    gaps = [np.linalg.norm(np.subtract(*closest_pair(case.truth.world_pos[f], obj))) for f in range(case.num_frames)]
    return int(np.argmin(gaps))


def animation_axes(case: Case, field: str, norm, extend: str, percentile: float, cmap: str):
    """The animation's figure: one column per series, the whole view on top and (2-D, several objects) the impact
    zoom below, one colour bar; returns (fig, axes [row][col], title, box, window)."""
    three_d = case.dim == 3
    obj = case.object_id
    zoom = not three_d and len(np.unique(obj)) > 1
    box = view_box(case, list(range(case.num_frames)))
    window = impact_window(case.truth.world_pos[closest_frame(case)], obj, case.truth.world_pos[0]) if zoom else None
    cols, rows = len(case.series), 1 + zoom
    w, h = panel_size(box, 3.0) if not three_d else (3.0, 2.6)
    zh = panel_size(window, 3.0)[1] if zoom else 0.0
    fig = new_figure(w * cols + 1.0, h + zh + 0.7)
    kw = {"projection": "3d"} if three_d else {}
    axes = [[fig.add_subplot(rows, cols, r * cols + c + 1, **kw) for c in range(cols)] for r in range(rows)]
    cbar = fig.colorbar(
        ScalarMappable(norm=norm, cmap=cmap), ax=[a for row in axes for a in row], extend=extend, aspect=25
    )
    label = field_label(case, field)
    if norm.vmin == 0:
        label += f"\n(scale: 0 to the ground truth's {percentile:g}th percentile)"
    cbar.set_label(label, fontsize=8)
    length = case.unit("length")
    for r in range(rows):
        for c, s in enumerate(case.series):
            ax = axes[r][c]
            if r == 0:
                ax.set_title(s.label, fontsize=9)
            if three_d:
                continue
            x0, x1, y0, y1 = box if r == 0 else window
            ax.set_xlim(x0, x1)
            ax.set_ylim(y0, y1)
            ax.set_aspect("equal")
            ax.tick_params(labelsize=6)
            if c == 0:
                ax.set_ylabel(("impact zoom\n" if r else "") + quantity_label("y", length), fontsize=7)
            if r == rows - 1:
                ax.set_xlabel(quantity_label("x", length), fontsize=7)
    return fig, axes, fig.suptitle(" ", fontsize=10), box, window


def render_frames(fig, axes, title, frames: list[int], draw, three_d: bool, dpi: int) -> list:
    """One RGB image per animation frame: 3-D redrawn in full, 2-D by blitting (the static parts rendered once,
    then only ``draw(f)``'s artists and the title)."""
    canvas = fig.canvas
    images = []
    if three_d:  # 3-D axes redraw their whole scene anyway: draw every frame in full
        for f in frames:
            for row in axes:
                for ax in row:
                    for coll in list(ax.collections):
                        coll.remove()
            draw(f)
            canvas.draw()
            images.append(Image.fromarray(np.asarray(canvas.buffer_rgba())).convert("RGB"))
        return images
    title.set_animated(True)
    fig.set_dpi(dpi)
    canvas.draw()  # lay out and render the static parts once
    fig.set_layout_engine("none")
    background = canvas.copy_from_bbox(fig.bbox)
    for f in frames:  # one rendered image per animation frame
        canvas.restore_region(background)
        artists = draw(f)
        for ax, a in artists:
            ax.draw_artist(a)
        fig.draw_artist(title)
        images.append(Image.fromarray(np.asarray(canvas.buffer_rgba())).convert("RGB"))
        for _, a in artists:
            a.remove()
    return images


def animate(
    case: Case,
    path: str | Path,
    *,
    fps: int = 10,
    stride: int | None = None,
    cmap: str = "viridis",
    percentile: float = 99.0,
    dpi: int = 100,
) -> Path:
    """Write the animation to ``path`` (``.gif``); returns it. One animation frame per drawn rollout frame
    (:func:`animation_frames`). The zoom row shows one window for the whole animation (the impact window at the
    frame of closest approach), so the view does not jump; everything but the meshes and the title is drawn once
    (blitting, :func:`render_frames`), which makes a frame about ten times cheaper than redrawing the figure."""
    path = Path(path)
    if path.suffix.lower() != ".gif":
        raise InputError(f"{path}: expected a .gif file name (animations are written with Pillow)")
    if fps <= 0:
        raise InputError(f"fps must be > 0, got {fps}")
    path.parent.mkdir(parents=True, exist_ok=True)
    field = field_name(case)
    norm, extend = animation_norm(case, field, percentile)
    three_d = case.dim == 3
    fig, axes, title, box, window = animation_axes(case, field, norm, extend, percentile, cmap)
    limits3d = box_3d(list(case.truth.world_pos)) if three_d else None  # one box for every panel and frame
    length = case.unit("length")
    last = case.num_frames - 1
    starts = min(s.start for s in case.predictions) if case.predictions else 0

    def draw(f: int) -> list:
        artists = []
        for r, row in enumerate(axes):
            for ax, s in zip(row, case.series):
                before = set(ax.get_children())
                values = field_values(s, f, field)
                if three_d:
                    draw_field_3d(
                        ax, s.world_pos[f], case.cells, values, norm, cmap, limits=limits3d, length_unit=length
                    )
                else:
                    draw_field_2d(ax, s.world_pos[f], case.cells, values, norm, cmap, edges=r == 1)
                    ax.set_xlim(*(box if r == 0 else window)[:2])
                    ax.set_ylim(*(box if r == 0 else window)[2:])
                artists += [(ax, a) for a in ax.get_children() if a not in before]
        note = " (input frame: predictions = data)" if f < starts else ""
        title.set_text(f"Trajectory {case.name}: {case.time_label(f, last)}{note}")
        return artists

    images = render_frames(fig, axes, title, animation_frames(case.num_frames, stride), draw, three_d, dpi)
    with atomic_path(path) as tmp:
        images[0].save(
            tmp, format="GIF", save_all=True, append_images=images[1:], duration=int(round(1000 / fps)), loop=0
        )
    return path
