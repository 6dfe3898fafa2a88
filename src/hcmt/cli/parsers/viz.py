"""The arguments and first checks of ``hcmt plot``, ``export`` and ``demo``."""

from __future__ import annotations

import argparse

from hcmt.cli import CommandError, check_outputs
from hcmt.cli.parsers.common import (
    MAX_FPS,
    MAX_LEVELS,
    MAX_STEPS,
    MAX_STRIDE,
    check_folder,
    check_run,
    cores,
    cores_count,
    count,
    same_as,
    span,
)
from hcmt.config import MAX_TRAJECTORIES
from hcmt.errors import clip

PICTURES = ("contours", "animation", "errors", "training", "hierarchy", "attention")


# -- plot, export --------------------------------------------------------------------------------------------------
def frames_of(text: str | None) -> list[int] | None:
    if text is None:
        return None
    try:
        return [int(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise CommandError(
            f"--frames {clip(text)!r}: expected comma-separated frame numbers, e.g. 0,10,25,51"
        ) from None


def pictures_of(text: str | None) -> list[str]:
    if not text:
        return list(PICTURES)
    picked = [t.strip() for t in text.split(",") if t.strip()]
    unknown = [t for t in picked if t not in PICTURES]
    if unknown:
        raise CommandError(f"--only {clip(', '.join(unknown))}: expected some of {', '.join(PICTURES)}")
    return picked


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("runs", nargs="+", metavar="RUN", help="run folder(s) made by `hcmt train`")
    p.add_argument("--data", required=True, help="native dataset folder")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--split", default="test")
    p.add_argument("--device", help="where missing rollouts run: cpu, cuda, cuda:N (default: cuda when available)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def configure_plot(p: argparse.ArgumentParser) -> None:
    _common(p)
    p.add_argument("--trajectory", default="0", help="index or name of the trajectory to draw (default 0)")
    p.add_argument("--frames", help="frames of the contour figure, e.g. 0,10,25,51 (default: 4 spread evenly)")
    p.add_argument("--only", help=f"comma-separated subset of {','.join(PICTURES)} (default: all)")
    p.add_argument("--cmap", default="viridis", help="matplotlib colour map (default viridis)")
    p.add_argument(
        "--scale",
        default="frame",
        choices=["frame", "all"],
        help="contour colour scale: one per frame (row) or one for the whole figure",
    )
    p.add_argument(
        "--fps",
        type=count(1, MAX_FPS),
        default=10,
        metavar="N",
        help=f"animation frames per second, {span(1, MAX_FPS)} (default 10)",
    )
    p.add_argument(
        "--stride",
        type=count(1, MAX_STRIDE),
        metavar="N",
        help=f"animate every N-th frame, {span(1, MAX_STRIDE)} (default: at most 100 frames)",
    )
    p.add_argument(
        "--levels",
        type=count(1, MAX_LEVELS),
        metavar="N",
        help=f"hierarchy levels to draw when no run is an HCMT with a hierarchy, {span(1, MAX_LEVELS)}",
    )
    p.add_argument("--attention-frame", type=int, help="frame of the attention maps (default: the impact)")
    p.add_argument(
        "--limit",
        type=count(1, MAX_TRAJECTORIES),
        metavar="N",
        help=f"error curves: roll out only the first N trajectories where needed, {span(1, MAX_TRAJECTORIES)}",
    )


def check_plot(args) -> None:
    pictures_of(args.only)
    frames_of(args.frames)
    check_export(args)
    check_outputs({}, {"--out": args.out})


def configure_export(p: argparse.ArgumentParser) -> None:
    _common(p)
    p.add_argument(
        "--format",
        default="vtu",
        choices=["vtu", "xdmf"],
        help="vtu: one file per frame + a .pvd collection; xdmf: one .xdmf + .h5 per series",
    )
    p.add_argument("--trajectory", default="0", help="index or name of the trajectory, or 'all' (default 0)")
    p.add_argument(
        "--stride",
        type=count(1, MAX_STRIDE),
        default=1,
        metavar="N",
        help=f"export every N-th frame, {span(1, MAX_STRIDE)} (default 1: all)",
    )


def check_export(args) -> None:
    for run in args.runs:
        check_folder("RUN", run, "a run folder made by `hcmt train`")
    check_folder("--data", args.data, "a native dataset folder (meta.json + <split>.h5)")


# -- demo ----------------------------------------------------------------------------------------------------------
def configure_demo(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="demo_out", help="folder for pictures (and with --train the data and run)")
    p.add_argument("--model", default="pretrained:impact_plate_small", help="model for the design check")
    same_as(p, path="--model")
    p.add_argument("--device", help="cpu, cuda, cuda:N (default: cuda when available)")
    p.add_argument(
        "--train",
        action="store_true",
        help="train a model from scratch instead (generate, train, evaluate; several minutes)",
    )
    p.add_argument(
        "--steps",
        type=count(1, MAX_STEPS),
        metavar="N",
        help=f"--train: training steps, {span(1, MAX_STEPS)} (default: the demo config's)",
    )
    p.add_argument(
        "--train-trajectories",
        type=count(1, MAX_TRAJECTORIES),
        default=12,
        metavar="N",
        help=f"--train: training trajectories to generate, {span(1, MAX_TRAJECTORIES)} (default 12)",
    )
    p.add_argument(
        "--test",
        type=count(1, MAX_TRAJECTORIES),
        default=2,
        metavar="N",
        help=f"--train: test trajectories to generate, {span(1, MAX_TRAJECTORIES)} (default 2)",
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--workers",
        type=cores_count,
        default=min(2, cores()),
        metavar="N",
        help=f"--train: worker processes, 1 to this machine's cores ({cores()}; default {min(2, cores())})",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bars")


def check_demo(args) -> None:
    if args.steps is not None and not args.train:
        raise CommandError(
            "--steps sets the training length of `hcmt demo --train`; the default demo trains nothing "
            "(it uses the shipped model)"
        )
    if not args.train:
        check_run("--model", args.model)
