"""``hcmt plot`` and ``hcmt export``.

``hcmt plot RUN [RUN ...] --data DATASET --out DIR`` writes, for one trajectory of a split (rolled out first where a
run has no rollout of it yet):

* ``stress_contours.png`` / ``stress_contours_zoom.png``: ground truth beside every run at a few frames
  (``displacement_contours*.png`` for a dataset without stress);
* ``rollout.gif``: the rollouts beside the ground truth;
* ``rollout_error.png``: position and stress RMSE per step of every run;
* ``training_curves.png``: loss, learning rate and validation RMSE of every run with a ``log.jsonl``;
* ``hierarchy_levels*.png`` / ``hierarchy_remeshing*.png``: the mesh hierarchy of the first HCMT run (or
  ``--levels``);
* ``attention_<model>.png``: the attention maps of every HCMT or GT run.

``hcmt export RUN [RUN ...] --data DATASET --format vtu|xdmf --out DIR`` writes the ground truth and every run's
rollout as ParaView time series (:mod:`hcmt.viz.export`).
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

from hcmt.cli import CommandError, check_outputs
from hcmt.cli.parsers import frames_of, pictures_of
from hcmt.data.format import Split, read_meta
from hcmt.data.runs import RunFolder
from hcmt.files import check_apart
from hcmt.graph.hierarchy import cached_hierarchy, hierarchy_cache_dir
from hcmt.inference.rollout_files import rollout_file
from hcmt.inference.run import Run
from hcmt.models import REGISTRY, uses_hierarchy
from hcmt.viz.animation import animate
from hcmt.viz.attention import frame_attention, plot_attention
from hcmt.viz.contours import plot_contours
from hcmt.viz.curves import plot_error_curves, plot_training_curves, rollout_errors
from hcmt.viz.export import export_case
from hcmt.viz.hierarchy import plot_hierarchy
from hcmt.viz.rollouts import load_case, unique_labels


def read_paths(args) -> list[tuple[str, str]]:
    """What plot and export read (:func:`hcmt.files.check_apart`): --data and every RUN."""
    return [("--data", args.data), *(("RUN", r) for r in args.runs)]


def _slug(label: str) -> str:
    return re.sub(r"[^a-z0-9]+", "_", label.lower()).strip("_")


def _load_runs(args) -> list[Run | RunFolder]:
    """Every run folder loaded once (model on ``--device``): the handle the pictures take; a folder without a
    checkpoint (predictions brought from elsewhere) as a bare :class:`RunFolder` whose rollout files are used."""
    out = []
    for r in args.runs:
        folder = RunFolder(r)
        out.append(Run.load(folder, args.device) if folder.checkpoint().is_file() else folder)
    return out


def _plot_hierarchy(args, runs, case, out: Path, notes: list[str]) -> list[Path]:
    """The level-wise meshes of ``--levels`` or of the first run that uses a hierarchy (else a note)."""
    levels, remesh = args.levels, True
    if levels is None:
        for run in runs:
            if isinstance(run, Run):
                lv, rm = run.hierarchy_spec
            else:  # a run folder without a checkpoint yet: its run.yaml
                cfg = run.info.get("config")
                lv, rm = uses_hierarchy(run.info["model"], cfg is None or cfg.data.remesh)
            if lv:
                levels, remesh = lv, rm
                break
    if not levels:
        notes.append("hierarchy: no run uses a mesh hierarchy; pass --levels N to draw one")
        return []
    h = cached_hierarchy(
        case.mesh_pos, case.cells, case.node_type, levels, remesh, cache_dir=hierarchy_cache_dir(args.data)
    )
    return plot_hierarchy(case.mesh_pos, h, out, length_unit=case.unit("length"), node_type=case.node_type)


def _plot_attention(args, runs, labels: list[str], out: Path, notes: list[str]) -> list[Path]:
    """One attention map per Transformer run with a checkpoint (a note for each other one)."""
    written = []
    for run, label in zip(runs, labels):
        if not isinstance(run, Run):
            notes.append(f"attention: {label} ({run.source}) has no checkpoint; skipped")
            continue
        if not REGISTRY[run.info.model["name"]].has_attention:
            notes.append(f"attention: {label} ({run.source}) is not a Transformer; skipped")
            continue
        maps = frame_attention(run, args.data, args.split, args.trajectory, args.attention_frame)
        maps.model = label
        written.append(plot_attention(maps, out / f"attention_{_slug(label)}.png"))
    return written


def main_plot(args: argparse.Namespace) -> int:
    only = pictures_of(args.only)
    frames = frames_of(args.frames)
    import matplotlib  # here, not above: hcmt.viz's import checked it first (one line naming the viz extra)

    if args.cmap not in matplotlib.colormaps:
        raise CommandError(f"--cmap {args.cmap!r}: not a matplotlib colour map (e.g. viridis, magma, jet)")
    check_outputs({}, {"--out": args.out})
    check_apart({"--out": args.out}, read_paths(args))
    out = Path(args.out)
    runs = _load_runs(args)
    labels = unique_labels(runs)
    written, notes = [], []
    case = None
    if {"contours", "animation", "hierarchy"} & set(only):
        case = load_case(runs, args.data, args.split, args.trajectory, labels, progress=not args.no_progress)
    if "contours" in only:
        written += plot_contours(case, out, frames, cmap=args.cmap, scale=args.scale)
    if "animation" in only:
        written.append(animate(case, out / "rollout.gif", fps=args.fps, stride=args.stride, cmap=args.cmap))
    if "errors" in only:
        errors = rollout_errors(runs, args.data, args.split, labels, limit=args.limit, progress=not args.no_progress)
        written.append(plot_error_curves(errors, read_meta(args.data), out / "rollout_error.png"))
    if "training" in only:
        folders = [r.folder if isinstance(r, Run) else r for r in runs]
        logged = [(f, lab) for f, lab in zip(folders, labels) if f is not None and f.log.is_file()]
        if logged:
            written.append(
                plot_training_curves(
                    [r for r, _ in logged],
                    read_meta(args.data),
                    out / "training_curves.png",
                    [lab for _, lab in logged],
                )
            )
        else:
            notes.append("training curves: no run has a log.jsonl")
    if "hierarchy" in only:
        written += _plot_hierarchy(args, runs, case, out, notes)
    if "attention" in only:
        written += _plot_attention(args, runs, labels, out, notes)
    for path in written:
        print(f"wrote {path}")
    for note in notes:
        print(f"note: {note}")
    return 0


# -- export --------------------------------------------------------------------------------------------------------
def main_export(args: argparse.Namespace) -> int:
    check_apart({"--out": args.out}, read_paths(args))
    with Split(args.data, args.split) as s:
        names = list(s.names)
    runs = _load_runs(args)
    if args.trajectory == "all":
        for run in runs:  # roll the whole split out once rather than trajectory by trajectory
            rollout_file(run, args.data, args.split, progress=not args.no_progress)
        picks = names
    else:
        picks = [args.trajectory]
    labels = unique_labels(runs)
    for t in picks:
        case = load_case(runs, args.data, args.split, t, labels, progress=not args.no_progress)
        frames = list(range(0, case.num_frames, args.stride))
        for path in export_case(case, args.out, args.format, frames):
            print(f"wrote {path}")
    if args.format == "xdmf":
        print("note: XDMF stores the initial positions; apply Warp By Vector with 'displacement' in ParaView")
    return 0
