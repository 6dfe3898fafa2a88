"""The arguments and first checks of ``hcmt convert``, ``info`` and ``hierarchy``: the commands on a dataset that
exists (a public one converted, a native one described or its hierarchy tabled). They stand apart from ``generate``
and ``simulate`` (:mod:`hcmt.cli.parsers.data`), which run the solver and share its settings; these take none."""

from __future__ import annotations

import argparse
from pathlib import Path

from hcmt.cli import CommandError
from hcmt.cli.parsers.common import MAX_LEVELS, check_folder, count, span
from hcmt.config import MAX_TRAJECTORIES


# -- convert, info, hierarchy --------------------------------------------------------------------------------------
def configure_convert(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("src", help="TFRecord dataset folder (meta.json + <split>.tfrecord) or GGNS pickle(s)")
    parser.add_argument("out", help="output folder for the native dataset (meta.json + <split>.h5)")


def check_convert(args) -> None:
    if not Path(args.src).exists():
        raise CommandError(
            f"SRC {args.src}: no such file or folder; expected a TFRecord dataset folder or GGNS pickle(s)"
        )


def configure_info(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dataset", help="native dataset folder (meta.json + <split>.h5)")
    parser.add_argument(
        "--all",
        action="store_true",
        help="list every design parameter on its own line, the "
        "constant ones too (default: the varying ones, the constants in one line)",
    )


def check_info(args) -> None:
    check_folder("DATASET", args.dataset, "a native dataset folder (meta.json + <split>.h5)")


def configure_hierarchy(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dataset", metavar="DATASET", help="native dataset folder (meta.json + <split>.h5)")
    parser.add_argument(
        "--levels",
        type=count(0, MAX_LEVELS),
        required=True,
        metavar="N",
        help=f"number of pooled levels lambda, {span(0, MAX_LEVELS)} (paper: 6 for Impact Plate, 2 "
        "Deforming Plate, 4 Sphere Simple, 1 Deformable Plate)",
    )
    parser.add_argument("--json", metavar="FILE", help="also write the table as JSON: one object per level 0..L")
    parser.add_argument("--split", default="train", help="split to read (default: train)")
    parser.add_argument(
        "--trajectories",
        type=count(0, MAX_TRAJECTORIES),
        default=0,
        metavar="N",
        help=f"use the first N trajectories, {span(0, MAX_TRAJECTORIES)} (default 0: all)",
    )
    parser.add_argument("--no-cache", action="store_true", help="do not read or write DATASET/.cache/hierarchy")


check_hierarchy = check_info
