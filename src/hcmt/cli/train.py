"""``hcmt train / rollout / evaluate / compare``: printing only (their arguments and first checks:
:mod:`hcmt.cli.parsers`); the library functions live in :mod:`hcmt.training` and :mod:`hcmt.inference.evaluate`."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from hcmt.cli import CommandError, check_outputs
from hcmt.data.format import Split
from hcmt.data.runs import RunFolder, check_start
from hcmt.files import atomic_path, check_apart, undo_on_error
from hcmt.inference.evaluate import compare, evaluate, format_compare, format_metrics
from hcmt.inference.rollout_files import check_options, check_results_folder, run_rollouts
from hcmt.inference.run import Run, dataset_warnings
from hcmt.training import train


# -- train ---------------------------------------------------------------------------------------------------------
def main_train(args: argparse.Namespace) -> int:
    overrides = list(args.overrides) + ([f"train.steps={args.steps}"] if args.steps is not None else [])
    folder = RunFolder(args.out, must_exist=False)
    check_start(folder, args.resume, flags=True)
    if args.resume and folder.info is not None and not args.config:  # resume with the run's saved settings
        saved = folder.info
        ablation = args.ablation or saved["model"].get("ablation")  # run.yaml's model arguments: older runs too
        cfg, overrides = saved["config"], ([f"model.ablation={ablation}"] if ablation else []) + overrides
        data = args.data or saved["data"]
        model = args.model or saved["model"]["name"]
        seed = args.seed if args.seed is not None else saved.get("seed", 0)
    else:
        missing = [
            f"--{k}"
            for k in ("config", "data", "model")
            if getattr(args, k) is None and not (args.init and k != "data")
        ]
        if missing:
            raise CommandError(
                f"{', '.join(missing)} required (only `--resume --out RUN` of an existing run may leave "
                "them out, and --init its source's config and model)"
            )
        ablation = [f"model.ablation={args.ablation}"] if args.ablation else []  # --ablation: model.ablation
        cfg, data, model = args.config, args.data, args.model
        overrides = ablation + overrides
        seed = args.seed if args.seed is not None else 0
    check_apart({"--out": args.out}, {"--data": data, "--init": _folder(args.init)}, owned=("--out",))
    summary = train(
        cfg,
        data,
        model,
        args.out,
        overrides=overrides,
        seed=seed,
        resume=args.resume,
        device=args.device,
        progress=not args.no_progress,
        init=args.init,
        init_normalizers=args.init_normalizers,
    )
    print(json.dumps(summary, indent=2))
    return 0


def _folder(model: str | None) -> str | None:
    """A model given as a run folder (None for ``pretrained:NAME`` or none)."""
    return None if model is None or model.startswith("pretrained:") else model


# -- rollout -------------------------------------------------------------------------------------------------------
def _print_warnings(args, warnings: list[str]) -> None:
    for w in warnings:
        print(f"hcmt {args.command}: warning: {w}", file=sys.stderr)


def _load(args) -> Run:
    """The run of ``rollout`` / ``evaluate``, after every check that needs no model: the options, the dataset split
    (one line, before the model loads and before --out is made) and where the results go."""
    check_options(batch=args.batch, compile=args.compile)  # bad options: one line before the model loads
    Split(args.data, args.split).close()  # no meta.json, no such split: refused before anything is made
    if args.out is not None:  # a shipped model: its rollouts and metrics go to --out
        check_apart({"--out": args.out}, {"--data": args.data})
        check_results_folder(args.out, args.run)  # never over another model's results
        return Run.load(args.run, args.device, args.checkpoint).writing_to(args.out)
    check_apart({"RUN": args.run}, {"--data": args.data})  # its rollouts and metrics go to RUN
    return Run.load(args.run, args.device, args.checkpoint)


def main_rollout(args: argparse.Namespace) -> int:
    with undo_on_error(args.out):  # a refusal after --out was made leaves no empty folder
        run = _load(args)
        _print_warnings(args, dataset_warnings(run, args.data, args.split))
        path = run_rollouts(
            run,
            args.data,
            args.split,
            limit=args.limit,
            batch=args.batch,
            compile=args.compile,
            progress=not args.no_progress,
        )
    print(f"wrote {path}")
    return 0


# -- evaluate ------------------------------------------------------------------------------------------------------
def main_evaluate(args: argparse.Namespace) -> int:
    with undo_on_error(args.out):  # a refusal after --out was made leaves no empty folder
        run = _load(args)
        m = evaluate(
            run,
            args.data,
            args.split,
            limit=args.limit,
            batch=args.batch,
            compile=args.compile,
            progress=not args.no_progress,
        )
    _print_warnings(args, m.warnings)
    print(format_metrics(m))
    print(f"wrote {run.folder.metrics_path(args.split, args.data)}")
    return 0


# -- compare -------------------------------------------------------------------------------------------------------
def main_compare(args: argparse.Namespace) -> int:
    check_apart({"--json": args.json}, [("RUN", r) for r in args.runs])
    check_outputs({"--json": args.json})
    table = compare(args.runs, args.split)
    print(f"split {args.split}; runs grouped by model and dataset")
    print(format_compare(table))
    if args.json:
        with atomic_path(Path(args.json)) as tmp:
            tmp.write_text(json.dumps(table, indent=2))
    return 0
