"""The arguments and first checks of ``hcmt train``, ``rollout``, ``evaluate`` and ``compare``."""

from __future__ import annotations

import argparse

from hcmt.cli import CommandError, check_outputs
from hcmt.cli.parsers.common import (
    MAX_STEPS,
    batch_arg,
    check_folder,
    check_run,
    check_split,
    compile_arg,
    count,
    same_as,
    span,
)
from hcmt.config import ABLATION_ALIASES, ABLATIONS, INIT_NORMALIZERS, MAX_TRAJECTORIES, MODELS, load_config
from hcmt.errors import clip


# -- train, rollout, evaluate, compare -----------------------------------------------------------------------------
def configure_train(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", help="built-in config name (impact_plate, impact_plate_cpu, ...) or a YAML file")
    same_as(p, name_or_path="--config")
    p.add_argument("--data", help="native dataset folder")
    p.add_argument("--model", choices=MODELS)
    p.add_argument(
        "--ablation",
        choices=ABLATIONS + ABLATION_ALIASES,
        help="HCMT ablation (paper Tables 3, 10-12): --set model.ablation; the paper's HCMT without "
        "remeshing, no-remesh, is a graph setting: --set data.remesh=false",
    )
    p.add_argument(
        "--steps",
        type=count(1, MAX_STEPS),
        metavar="N",
        help=f"training steps, {span(1, MAX_STEPS)} (overrides train.steps)",
    )
    p.add_argument("--seed", type=int, help="random seed (default 0)")
    p.add_argument("--out", required=True, help="run folder")
    p.add_argument(
        "--resume",
        action="store_true",
        help="continue the run in --out from its last checkpoint; "
        "`--resume --out RUN` alone uses the run's saved settings (--steps may extend it)",
    )
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override any config key, e.g. --set train.lr=3e-4 --set model.levels=4",
    )
    p.add_argument(
        "--init",
        metavar="RUN|pretrained:NAME",
        help="start from that model's weights (fine-tuning, e.g. a shipped model on your own solver's "
        "data); the run takes its model settings (architecture, features), and its config and "
        "model when --config / --model are left out",
    )
    p.add_argument(
        "--init-normalizers",
        choices=INIT_NORMALIZERS,
        default="keep",
        help="with --init: keep its normalizer statistics, frozen (default), or re-accumulate them on --data",
    )
    p.add_argument("--device", help="cpu, cuda, cuda:1 (default: cuda if available)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def check_train(args) -> None:
    if args.config is not None:  # its file and every --set, one line before torch loads (main_train reads it again)
        load_config(args.config, list(args.overrides))
    if args.data is not None:
        check_folder("--data", args.data, "a native dataset folder (meta.json + <split>.h5)")
    if args.init is not None:
        check_run("--init", args.init)


def _run_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("run", help="run folder made by `hcmt train`, or pretrained:NAME (a shipped model, with --out)")
    same_as(p, path="RUN")
    p.add_argument("--data", required=True, help="native dataset folder")
    p.add_argument(
        "--out",
        metavar="DIR",
        help="for a shipped model (pretrained:NAME): the folder its rollouts and "
        "metrics are written to (a run folder's go to RUN)",
    )
    p.add_argument("--split", default="test")
    p.add_argument(
        "--limit",
        type=count(1, MAX_TRAJECTORIES),
        metavar="N",
        help=f"only the first N trajectories, {span(1, MAX_TRAJECTORIES)}",
    )
    p.add_argument("--checkpoint", default="best", choices=["best", "checkpoint"])
    p.add_argument("--device", help="cpu, cuda, cuda:N (default: cuda when available)")
    batch_arg(
        p,
        "trajectories rolled out together (one batched graph per step; on the CPU in blocks of at most 1,536 nodes)",
        1,
        "1",
    )
    compile_arg(p)
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def _check_run_args(args) -> None:
    check_run("RUN", args.run)
    check_folder("--data", args.data, "a native dataset folder (meta.json + <split>.h5)")
    shipped = args.run.startswith("pretrained:")
    if shipped and args.out is None:
        raise CommandError(
            f"RUN {clip(args.run)}: a shipped model has no run folder; give --out DIR for its rollouts and metrics"
        )
    if not shipped and args.out is not None:
        raise CommandError(
            f"--out {clip(args.out)}: for a shipped model (pretrained:NAME); a run folder's rollouts "
            "and metrics go to RUN"
        )
    check_split(args.data, args.split)
    if args.out is not None:
        check_outputs({}, {"--out": args.out})


configure_rollout = configure_evaluate = _run_args
check_rollout = check_evaluate = _check_run_args


def configure_compare(p: argparse.ArgumentParser) -> None:
    p.add_argument("runs", nargs="+", help="run folders holding metrics_<split>.json (from `hcmt evaluate`)")
    p.add_argument("--split", default="test", help="which split's metrics to compare (default test)")
    p.add_argument("--json", help="also write the table as JSON")


def check_compare(args) -> None:
    for run in args.runs:
        check_folder("RUNS", run, "run folders holding metrics_<split>.json (from `hcmt evaluate`)")
