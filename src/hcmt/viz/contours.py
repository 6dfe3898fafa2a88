"""Stress contours on the deformed mesh, ground truth beside the predictions (paper Fig. 5 and 11-14).

Rows are frames, columns are the ground truth and each run's rollout. The panels of a row share **one** colour
scale and colour bar, set by the ground truth at that frame (from 0 for a non-negative field such as von Mises
stress), so ground truth and predictions are compared colour for colour; predictions beyond that range saturate
and the colour bar's end arrows say so. One scale per row rather than per figure (``scale="frame"``, our choice):
the impact's peak stress is many times the stress a few frames later, and one scale for all frames leaves the later
rows a single dark colour; ``scale="all"`` gives every row the same scale (each row still has its colour bar).
The colour bar carries the unit from meta.json (``units.stress``). A dataset without stress (Sphere Simple,
Deformable Plate) is drawn with the displacement magnitude ``||x_t - x_0||`` instead.

Two pictures for a 2-D scene: the whole scene, with the zoom window marked by a red box (as the paper's Fig. 5), and
the zoom window itself (:func:`hcmt.viz.meshplot.impact_window`) with the mesh edges drawn, so the node positions
of prediction and ground truth can be compared where the ball meets the plate.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib import colors
from matplotlib.patches import Rectangle

from hcmt.errors import InputError
from hcmt.inference.metrics import step_rmse
from hcmt.viz.meshplot import (
    box_3d,
    draw_field_2d,
    draw_field_3d,
    extend_of,
    field_limits,
    impact_window,
    new_figure,
    panel_size,
    save_figure,
    scene_box,
)
from hcmt.viz.rollouts import Case, Series, quantity_label

STRESS_NAME = "von Mises stress"


def field_name(case: Case) -> str:
    """``stress`` when the dataset has it, else ``displacement`` (the magnitude from frame 0)."""
    return "stress" if case.has_stress else "displacement"


def field_values(series: Series, frame: int, field: str) -> np.ndarray:
    """Nodal values [N] of ``field`` at ``frame``: the stress, or the displacement magnitude from frame 0."""
    if field == "stress":
        if series.stress is None:
            raise InputError(f"{series.label} has no stress; draw field='displacement' instead")
        return np.asarray(series.stress[frame]).reshape(-1)
    if field == "displacement":
        return np.linalg.norm(series.world_pos[frame] - series.world_pos[0], axis=-1)
    raise InputError(f"unknown field {field!r}; expected 'stress' or 'displacement'")


def field_label(case: Case, field: str) -> str:
    if field == "stress":
        return quantity_label(STRESS_NAME, case.unit("stress"))
    return quantity_label("displacement magnitude", case.unit("length"))


def default_frames(case: Case, count: int = 4) -> list[int]:
    """``count`` frames spread evenly over the rollout, the last frame included and the initial one left out."""
    last = case.num_frames - 1
    frames = np.unique(np.round(np.linspace(0, last, count + 1)).astype(int))[1:]
    return frames.tolist() or [last]


def check_frames(case: Case, frames: list[int]) -> list[int]:
    out = []
    for f in frames:
        f = int(f)
        if not -case.num_frames <= f < case.num_frames:
            raise InputError(f"frame {f} out of range; trajectory {case.name} has frames 0..{case.num_frames - 1}")
        out.append(f % case.num_frames)
    return out


def shared_norm(case: Case, frames: list[int], field: str) -> tuple[colors.Normalize, str]:
    """One colour scale for every panel (from the ground truth) and the colour bar's ``extend``."""
    lo, hi = field_limits([field_values(case.truth, f, field) for f in frames])
    norm = colors.Normalize(lo, hi)
    preds = [field_values(s, f, field) for s in case.predictions for f in frames]
    if lo >= 0:  # a non-negative quantity (von Mises, a norm): a model's values below 0 get no "below 0" arrow
        preds = [np.maximum(p, 0.0) for p in preds]
    return norm, extend_of(norm, preds)


def axis_names(case: Case) -> tuple[str, str]:
    """``("r", "y")`` for an axisymmetric scene (the Impact Plate generator's default; the tables say r), else
    ``("x", "y")``."""
    settings = ((case.meta or {}).get("generator") or {}).get("settings") or {}
    return ("r" if settings.get("formulation") == "axisymmetric" else "x"), "y"


def view_box(case: Case, frames: list[int]) -> tuple[float, float, float, float]:
    """Axes limits of the full view: every series at the frames shown, but at most half the ground truth's
    size beyond it on each side (a diverged prediction leaves the picture rather than shrinking the rest)."""
    truth = scene_box(np.concatenate([case.truth.world_pos[f] for f in frames]))
    allpos = np.concatenate([s.world_pos[f] for s in case.series for f in frames])
    allpos = allpos[np.isfinite(allpos).all(1)]
    every = scene_box(allpos)
    wx, wy = truth[1] - truth[0], truth[3] - truth[2]
    return (
        max(every[0], truth[0] - wx / 2),
        min(every[1], truth[1] + wx / 2),
        max(every[2], truth[2] - wy / 2),
        min(every[3], truth[3] + wy / 2),
    )


def frame_rmse(series: Series, truth: Series, frame: int, field: str) -> float:
    """RMSE over nodes of ``field`` at ``frame`` (the paper's per-step error, in physical units)."""
    if field == "displacement":
        a, b = series.world_pos[frame], truth.world_pos[frame]
    else:
        a, b = field_values(series, frame, field), field_values(truth, frame, field)
        a, b = np.reshape(a, (len(a), -1)), np.reshape(b, (len(b), -1))
    return float(step_rmse(a[None], b[None])[0])


SCALES = ("frame", "all")


def panel_title(case: Case, s, f: int, field: str) -> str:
    """A series' label, and for a prediction its RMSE against the ground truth at frame ``f``."""
    if s is case.truth:
        return s.label
    unit = case.unit("stress" if field == "stress" else "length")
    what = "stress" if field == "stress" else "position"
    return s.label + f"\n{what} RMSE {frame_rmse(s, case.truth, f, field):.3g}" + (f" {unit}" if unit else "")


def draw_panel_2d(ax, case: Case, s, f: int, field: str, norm, cmap: str, zoom: bool, window, first: bool):
    """One 2-D contour panel of ``contour_figure``: the field on the deformed mesh inside ``window``; in the whole
    view the ground truth's first panel marks the zoomed window in red. Returns the mappable."""
    mappable = draw_field_2d(ax, s.world_pos[f], case.cells, field_values(s, f, field), norm, cmap, edges=zoom)
    x0, x1, y0, y1 = window
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    if not zoom and first and len(case.predictions):
        zw = impact_window(case.truth.world_pos[f], case.object_id, case.truth.world_pos[0])
        if zw is not None:
            ax.add_patch(Rectangle((zw[0], zw[2]), zw[1] - zw[0], zw[3] - zw[2], fill=False, ec="red", lw=1.0))
    length = case.unit("length")
    ax.tick_params(labelsize=7)
    ax.set_xlabel(quantity_label(axis_names(case)[0], length), fontsize=8)
    if first:
        ax.set_ylabel(quantity_label(axis_names(case)[1], length), fontsize=8)
    else:
        ax.tick_params(labelleft=False)
    return mappable


def draw_panel_3d(ax, case: Case, s, f: int, field: str, norm, cmap: str, limits):
    """One 3-D contour panel of ``contour_figure``: the field on the deformed mesh in ``limits``; the mappable."""
    return draw_field_3d(
        ax,
        s.world_pos[f],
        case.cells,
        field_values(s, f, field),
        norm,
        cmap,
        limits=limits,
        length_unit=case.unit("length"),
    )


def row_windows(case: Case, frames: list[int], zoom: bool) -> list:
    """Axes limits of each row of ``contour_figure``: the frame's impact window (``zoom``, 2-D), else the full view."""
    if zoom:
        if case.dim == 3:
            raise InputError("the zoomed view is for 2-D scenes; this dataset is 3-D")
        windows = [impact_window(case.truth.world_pos[f], case.object_id, case.truth.world_pos[0]) for f in frames]
        if any(w is None for w in windows):
            raise InputError(f"trajectory {case.name} has a single object: there is no impact to zoom on")
        return windows
    return [view_box(case, frames)] * len(frames)


def contour_figure(
    case: Case,
    frames: list[int] | None = None,
    *,
    field: str | None = None,
    zoom: bool = False,
    cmap: str = "viridis",
    scale: str = "frame",
    panel_width: float = 3.2,
):
    """The contour grid (rows: frames, columns: ground truth then predictions). ``zoom`` draws the impact window
    of each frame (2-D only) instead of the whole scene; ``scale`` is ``frame`` (one colour scale per row) or
    ``all`` (one for the figure). Returns the figure."""
    frames = check_frames(case, frames if frames is not None else default_frames(case))
    field = field or field_name(case)
    if scale not in SCALES:
        raise InputError(f"scale must be one of {SCALES}, got {scale!r}")
    norms = (
        [shared_norm(case, [f], field) for f in frames]
        if scale == "frame"
        else [shared_norm(case, frames, field)] * len(frames)
    )
    series = case.series
    rows, cols = len(frames), len(series)
    three_d = case.dim == 3
    windows = row_windows(case, frames, zoom)
    w, h = panel_size(windows[0], panel_width) if not three_d else (panel_width, panel_width * 0.8)
    fig = new_figure(w * cols + 1.2, (h + 0.9) * rows + 0.4)  # + row title, panel titles, x label
    limits3d = box_3d([case.truth.world_pos[f] for f in frames]) if three_d else None  # shared by every panel
    for r, (f, sub) in enumerate(zip(frames, np.atleast_1d(fig.subfigures(rows, 1)))):  # one row per frame
        norm, extend = norms[r]
        sub.suptitle(case.time_label(f), fontsize=9, fontweight="bold")
        row_axes = []
        for c, s in enumerate(series):
            if three_d:
                ax = sub.add_subplot(1, cols, c + 1, projection="3d")
                mappable = draw_panel_3d(ax, case, s, f, field, norm, cmap, limits3d)
            else:
                ax = sub.add_subplot(1, cols, c + 1)
                mappable = draw_panel_2d(ax, case, s, f, field, norm, cmap, zoom, windows[r], first=c == 0)
            ax.set_title(panel_title(case, s, f, field), fontsize=9)
            row_axes.append(ax)
        cbar = sub.colorbar(mappable, ax=row_axes, extend=extend, aspect=15)
        cbar.set_label(field_label(case, field), fontsize=8)
        cbar.ax.tick_params(labelsize=7)
    what = "impact zoom, mesh edges in white" if zoom else "whole scene"
    if not zoom and not three_d and len(case.predictions):
        what += "; red box: the zoomed view"
    name = "von Mises stress" if field == "stress" else "Displacement magnitude"
    fig.suptitle(f"{name} on the deformed mesh, trajectory {case.name} ({what})", fontsize=10)
    return fig


def plot_contours(
    case: Case,
    out_dir: str | Path,
    frames: list[int] | None = None,
    *,
    cmap: str = "viridis",
    scale: str = "frame",
    dpi: int = 150,
) -> list[Path]:
    """Write ``<field>_contours.png`` (whole scene) and, for a 2-D scene of several objects,
    ``<field>_contours_zoom.png`` (the impact window). Returns the paths written."""
    out_dir = Path(out_dir)
    field = field_name(case)
    paths = []
    zooms = [False] + ([True] if case.dim == 2 and len(np.unique(case.object_id)) > 1 else [])
    for zoom in zooms:
        fig = contour_figure(case, frames, field=field, zoom=zoom, cmap=cmap, scale=scale)
        path = out_dir / f"{field}_contours{'_zoom' if zoom else ''}.png"
        save_figure(fig, path, dpi=dpi)
        paths.append(path)
    return paths
