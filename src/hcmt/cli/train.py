"""``hcmt train / rollout / evaluate / compare``: argument parsing and printing only; the library functions live in
:mod:`hcmt.training` and :mod:`hcmt.inference.evaluate`."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from hcmt.cli import CommandError
from hcmt.config import COMPILE_MODES, load_config
from hcmt.files import atomic_path, check_apart
from hcmt.inference.evaluate import check_options, compare, evaluate, format_compare, format_metrics, run_rollouts
from hcmt.inference.run import Run, dataset_warnings
from hcmt.data.runs import RunFolder, check_start
from hcmt.models import ABLATIONS, MODELS
from hcmt.training import train
from hcmt.training.trainer import INIT_NORMALIZERS


# -- train ---------------------------------------------------------------------------------------------------------
def configure_train(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", help="built-in config name (impact_plate, impact_plate_cpu, ...) or a YAML file")
    p.add_argument("--data", help="native dataset folder")
    p.add_argument("--model", choices=MODELS)
    p.add_argument("--ablation", choices=ABLATIONS, help="HCMT ablation (paper Tables 3, 10-12)")
    p.add_argument("--steps", type=int, help="training steps (overrides train.steps)")
    p.add_argument("--seed", type=int, help="random seed (default 0)")
    p.add_argument("--out", required=True, help="run folder")
    p.add_argument("--resume", action="store_true", help="continue the run in --out from its last checkpoint; "
                   "`--resume --out RUN` alone uses the run's saved settings (--steps may extend it)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override any config key, e.g. --set train.lr=3e-4 --set model.levels=4")
    p.add_argument("--init", metavar="RUN|pretrained:NAME",
                   help="start from that model's weights (fine-tuning, e.g. a shipped model on your own solver's "
                        "data); its architecture and feature widths must be this run's")
    p.add_argument("--init-normalizers", choices=INIT_NORMALIZERS, default="keep",
                   help="with --init: keep its normalizer statistics, frozen (default), or re-accumulate them on "
                        "--data")
    p.add_argument("--device", help="cpu, cuda, cuda:1 (default: cuda if available)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def main_train(args: argparse.Namespace) -> int:
    overrides = list(args.set) + ([f"train.steps={args.steps}"] if args.steps is not None else [])
    folder = RunFolder(args.out, must_exist=False)
    check_start(folder, args.resume, flags=True)
    if args.resume and folder.info is not None and not args.config:  # resume with the run's saved settings
        saved = folder.info
        cfg = saved["config"].with_overrides(overrides)  # the one --set path
        data = args.data or saved["data"]
        model = args.model or saved["model"]["name"]
        ablation = args.ablation if args.ablation is not None else saved["model"].get("ablation")
        seed = args.seed if args.seed is not None else saved.get("seed", 0)
    else:
        missing = [f"--{k}" for k in ("config", "data", "model") if getattr(args, k) is None]
        if missing:
            raise CommandError(f"{', '.join(missing)} required (only `--resume --out RUN` of an existing run may leave "
                               "them out)")
        cfg, data, model, ablation = load_config(args.config, overrides), args.data, args.model, args.ablation
        seed = args.seed if args.seed is not None else 0
    check_apart({"--out": args.out}, {"--data": data, "--init": _folder(args.init)}, owned=("--out",))
    summary = train(cfg, data, model, args.out, ablation=ablation, seed=seed,
                    resume=args.resume, device=args.device, progress=not args.no_progress, init=args.init,
                    init_normalizers=args.init_normalizers)
    print(json.dumps(summary, indent=2))
    return 0


def _folder(model: str | None) -> str | None:
    """A model given as a run folder (None for ``pretrained:NAME`` or none)."""
    return None if model is None or model.startswith("pretrained:") else model


# -- rollout -------------------------------------------------------------------------------------------------------
def _run_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("run", help="run folder made by `hcmt train`")
    p.add_argument("--data", required=True, help="native dataset folder")
    p.add_argument("--split", default="test")
    p.add_argument("--limit", type=int, help="only the first N trajectories")
    p.add_argument("--checkpoint", default="best", choices=["best", "checkpoint"])
    p.add_argument("--device", help="cpu, cuda, cuda:N (default: cuda when available)")
    p.add_argument("--batch", type=int, default=1, help="trajectories rolled out together as one batched graph")
    compile_arg(p)
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def _print_warnings(args, warnings: list[str]) -> None:
    for w in warnings:
        print(f"hcmt {args.command}: warning: {w}", file=sys.stderr)


def compile_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--compile", default="none", choices=COMPILE_MODES,
                   help="torch.compile the model on padded graphs (reduce-overhead: CUDA graphs); the first step of "
                        "each new shape compiles (minutes for a paper-size HCMT on one CPU thread), later ones replay "
                        "(default none)")


configure_rollout = _run_args


def _load(args) -> Run:
    check_options(batch=args.batch, compile=args.compile)  # bad options: one line before the model loads
    if args.limit is not None and args.limit < 1:
        raise CommandError(f"--limit must be >= 1 (the first N trajectories), got {args.limit}")
    check_apart({"RUN": args.run}, {"--data": args.data})  # its rollouts and metrics go to RUN
    return Run.load(args.run, args.device, args.checkpoint)


def main_rollout(args: argparse.Namespace) -> int:
    run = _load(args)
    _print_warnings(args, dataset_warnings(run, args.data, args.split))
    path = run_rollouts(run, args.data, args.split, limit=args.limit, batch=args.batch, compile=args.compile,
                        progress=not args.no_progress)
    print(f"wrote {path}")
    return 0


# -- evaluate ------------------------------------------------------------------------------------------------------
configure_evaluate = _run_args


def main_evaluate(args: argparse.Namespace) -> int:
    run = _load(args)
    m = evaluate(run, args.data, args.split, limit=args.limit, batch=args.batch, compile=args.compile,
                 progress=not args.no_progress)
    _print_warnings(args, m["warnings"])
    print(format_metrics(m))
    print(f"wrote {run.folder.metrics_path(args.split, args.data)}")
    return 0


# -- compare -------------------------------------------------------------------------------------------------------
def configure_compare(p: argparse.ArgumentParser) -> None:
    p.add_argument("runs", nargs="+", help="run folders holding metrics_<split>.json (from `hcmt evaluate`)")
    p.add_argument("--split", default="test", help="which split's metrics to compare (default test)")
    p.add_argument("--json", help="also write the table as JSON")


def main_compare(args: argparse.Namespace) -> int:
    check_apart({"--json": args.json}, [("RUN", r) for r in args.runs])
    table = compare(args.runs, args.split)
    print(f"split {args.split}; runs grouped by model and dataset")
    print(format_compare(table))
    if args.json:
        with atomic_path(Path(args.json)) as tmp:
            tmp.write_text(json.dumps(table, indent=2))
    return 0
