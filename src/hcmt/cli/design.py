"""``hcmt predict / sweep / models``: printing only (their arguments and first checks: :mod:`hcmt.cli.parsers`); the
library functions live in :mod:`hcmt.design.check` and :mod:`hcmt.design.sweep`."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from hcmt.cli import CommandError
from hcmt.cli.parsers import check_options
from hcmt.config import plural
from hcmt.data.runs import PRETRAINED_DIR, available_pretrained
from hcmt.design import sweep as sw
from hcmt.design.basics import parse_vary
from hcmt.design.check import check_designs
from hcmt.design.inputs import range_warnings, read_designs_csv, settings_of
from hcmt.design.model_interval import Calibration, interval_path
from hcmt.design.reports import contour_picture, format_calls, format_table, to_json, write_csv
from hcmt.design.surrogate_use import run_surrogate_path
from hcmt.errors import missing_extra
from hcmt.files import atomic_path, check_apart, undo_on_error
from hcmt.inference.run import Run
from hcmt.sim.cost import duration, solver_seconds
from hcmt.sim.params import DESIGN_KEYS, DESIGN_UNITS, FAMILIES, parse_design
from hcmt.sim.sampling import describe_family, middle_design


def readout_words(readout: str) -> str:
    """The header's words for the read-out used."""
    return "raw (the model's own outputs)" if readout == "raw" else f"{readout} (as {readout}_*, beside the raw)"


def print_notes(command: str, check) -> None:
    for note in check.notes:
        print(f"hcmt {command}: note: {note}", file=sys.stderr)


# -- predict / models ----------------------------------------------------------------------------------------------
def main_predict(args: argparse.Namespace) -> int:
    options = check_options(args)  # check_predict has refused bad options before the model loads
    run = _design_run(args)
    check_apart(
        {"--json": args.json, "--csv": args.csv, "--out": args.out if args.images else None},
        {**read_paths(args, run), "--designs": args.designs},
    )
    defaults = middle_design(run.meta, run.ranges)
    designs = [(f"design_{i + 1}", parse_design(items, defaults)) for i, items in enumerate(args.design)]
    if args.designs:
        designs += read_designs_csv(
            args.designs, defaults, first=len(designs) + 1, taken={n: "--design" for n, _ in designs}
        )
    for name, d in designs:
        for w in range_warnings(d, run.ranges):
            print(f"hcmt predict: warning: {name}: {w}", file=sys.stderr)
    seconds = solver_seconds([d for _, d in designs], settings_of(run.meta)) if options["verify"] else None
    if seconds is not None:  # the solver's total before it starts: 10,000 designs are hours
        n, every = len(designs), options["verify"] is True
        print(
            f"--verify: the solver runs on {'each' if every else 'the undecided ones'} of the {n:,} "
            f"design{'s' if n != 1 else ''} after the model: {'' if every else 'up to '}{duration(seconds)} on one "
            f"core by its estimate (about {seconds / n:.1f} s a design, on the high side for small meshes)",
            flush=True,
        )
    check = check_designs(
        run, designs, batch=args.batch, compile=args.compile, progress=not args.no_progress, force=args.force, **options
    )
    print_notes("predict", check)
    preds, truth = check.preds, check.truth
    print(
        f"{run.label} ({run.source}) on {run.device}: {plural(len(preds), 'design')}, "
        f"{check.settings.frames} frames of "
        f"{check.settings.frame_dt} ms, {check.wall_s:.2f} s in all; stresses are von Mises [MPa], lengths [mm]; "
        f"read-out: {readout_words(check.readout)}"
        + (f"; response surface: {check.surrogate}" if check.surrogate else "")
    )
    print(format_table(preds, check.verified))
    if args.yield_mpa is not None:
        print(format_calls(preds, args.yield_mpa))
    with undo_on_error(args.out if args.images else None, args.csv, args.json):  # all outputs or none
        if args.images:
            for i, p in enumerate(preds):
                path = contour_picture(p, truth[i] if truth else None, run.meta, args.out, run.label)
                print(f"contours {p.name}: {path}")
        if args.csv:
            print(f"wrote {write_csv(preds, args.csv)}")
        if args.json:
            with atomic_path(Path(args.json)) as tmp:
                tmp.write_text(json.dumps(to_json(preds, check.verified, run.source, str(run.device), check), indent=2))
            print(f"wrote {args.json}")
    return 0


def read_paths(args, run) -> dict[str, str | Path | None]:
    """What predict and sweep read, for :func:`hcmt.files.check_apart`: the model (its run folder, or the shipped
    models' folder), the model's training data and the --surrogate file."""
    folder = run.folder
    return {
        "MODEL": folder.path if folder is not None else PRETRAINED_DIR,
        "the model's training data": folder.train_data if folder is not None else None,
        "--surrogate": args.surrogate,
    }


def _design_run(args):
    """The Impact Plate model of ``predict`` / ``sweep``."""
    run = Run.load(args.model, args.device)
    if run.config.dataset != "impact_plate":
        raise CommandError(
            f"{args.model}: predict is for Impact Plate models; this one was trained on {run.config.dataset!r}"
        )
    if run.meta is None and run.folder is not None:
        raise CommandError(
            f"{args.model}: its training data ({run.info.data}) is gone and the run holds no "
            f"{run.folder.data_facts_path.name} (by `hcmt train`) with the generator's settings, design "
            "ranges and keys that predict needs; restore the dataset, or retrain"
        )
    return run


# -- sweep ---------------------------------------------------------------------------------------------------------
def main_sweep(args: argparse.Namespace) -> int:
    param, lo, hi, n = parse_vary(args.vary)
    options = check_options(args)  # check_sweep has refused bad options before the model loads
    run = _design_run(args)
    check_apart({"--json": args.json, "--csv": args.csv, "--out": args.out}, read_paths(args, run))
    base = parse_design(args.design, middle_design(run.meta, run.ranges))
    designs = sw.sweep_designs(base, param, lo, hi, n)
    for w in sorted({w for _, d in designs for w in range_warnings(d, run.ranges)}):  # each distinct one once
        print(f"hcmt sweep: warning: {w}", file=sys.stderr)
    check, analysis = sw.sweep(
        run,
        param,
        lo,
        hi,
        n,
        base,
        batch=args.batch,
        progress=not args.no_progress,
        compile=args.compile,
        force=args.force,
        **options,
    )
    print_notes("sweep", check)
    print(
        f"{run.label} ({run.source}) on {run.device}: {param} from {lo:g} to {hi:g} in {n} points, "
        f"{check.wall_s:.2f} s in all; stresses are von Mises [MPa], lengths [mm]; "
        f"read-out: {readout_words(check.readout)}"
        + (f"; response surface: {check.surrogate}" if check.surrogate else "")
    )
    print(format_table(check.preds, check.verified))
    if args.yield_mpa is not None:
        print(format_calls(check.preds, args.yield_mpa, param, lambda p: f"{getattr(p.design, param):.6g}"))
    print(sw.format_analysis(analysis))
    with undo_on_error(args.out, args.csv, args.json):  # all outputs or none
        missing = missing_extra("viz", "matplotlib")
        print(
            f"plot: {sw.plot_sweep(check, analysis, args.out, run.label)}" if missing is None else f"no plot: {missing}"
        )
        if args.csv:
            print(f"wrote {write_csv(check.preds, args.csv)}")
        if args.json:
            with atomic_path(Path(args.json)) as tmp:
                tmp.write_text(json.dumps(sw.sweep_json(check, analysis, run.source, str(run.device)), indent=2))
            print(f"wrote {args.json}")
    return 0


def trained_families(meta: dict | None) -> dict[str, int]:
    """The design families of a model's training split and their counts (``mono`` for data made before them)."""
    listed = ((meta or {}).get("families") or {}).get("train")
    if listed is None:
        listed = ["mono"] * int((((meta or {}).get("generator") or {}).get("counts") or {}).get("train", 0))
    return {k: listed.count(k) for k in dict.fromkeys(listed)}


def model_card(name: str, path: Path) -> dict:
    """The card ``hcmt models`` prints (or writes as JSON) of the shipped model ``name``, its file ``path``."""
    run = Run.load(f"pretrained:{name}", "cpu")
    defaults = middle_design(run.meta, run.ranges)
    settings = settings_of(run.meta)
    surrogate = run_surrogate_path(run)
    return {
        "file": str(path),
        "size_mb": path.stat().st_size / 1e6,
        **run.card,
        "window": {"frames": settings.frames, "frame_dt_ms": settings.frame_dt},
        "surrogate": str(surrogate) if surrogate is not None and surrogate.is_file() else None,
        "families": trained_families(run.meta),
        "model_interval": interval_card(run),
        "design_parameters": {
            k: {
                "training_range": list(run.ranges[k]) if k in run.ranges else None,
                "default": getattr(defaults, k),
                "unit": DESIGN_UNITS[k],
            }
            for k in DESIGN_KEYS
        },
    }


def main_models(args: argparse.Namespace) -> int:
    shipped = available_pretrained()
    if not shipped:
        print("no shipped models in this installation")
        return 0
    cards = {name: model_card(name, path) for name, path in shipped.items()}
    if args.json:
        print(json.dumps(cards, indent=2))
        return 0
    for name, c in cards.items():
        print(f"pretrained:{name}  {c.get('summary', '')}  ({c['size_mb']:.1f} MB; docs/MODELS.md)")
        w = c["window"]
        print(
            f"  window: {w['frames']} frames of {w['frame_dt_ms']} ms; design parameters (a --designs CSV's "
            "columns; unset ones take the default):"
        )
        for k, d in c["design_parameters"].items():
            rng = d["training_range"]
            trained = (
                "not varied in training" if rng is None or rng[0] == rng[1] else f"trained {rng[0]:.6g} .. {rng[1]:.6g}"
            )
            print(f"    {k:<18} {d['unit']:<7} default {d['default']:<10.6g} {trained}")
        print(
            "  trained on the families "
            + ", ".join(f"{k} ({n})" for k, n in c["families"].items())
            + f"; the generator's families (hcmt generate --family): {', '.join(FAMILIES)}; a design of another "
            "family is outside its training and warned as such"
        )
        print(f"  response surface beside it: {c['surrogate'] or 'none'}")
        print("  " + interval_lines(c["model_interval"]))
        if c.get("confidence"):
            print(
                "  measured error by region (docs/MODELS.md): "
                + "; ".join(
                    f"{r['label']}: peak plate stress median {r['peak_plate_stress_error_pct_median']:.1f} %"
                    for r in c["confidence"]
                )
            )
    print('panel families (hcmt generate --family; docs/solver.md, "Panel families", has the validated ranges):')
    for k in FAMILIES:
        print(f"  {k:<8} {describe_family(k)}")
    return 0


def interval_card(run) -> dict | None:
    """The model's own calibrated interval as ``hcmt models`` reports it: the cells, their held-out designs and
    the coverage measured on designs of other seeds (the calibration file's ``measured`` block), or None."""
    path = interval_path(run)
    if path is None or not path.is_file():
        return None
    cal = Calibration.load(path)
    return {
        "file": str(path),
        "level": cal.level,
        "cells": {k: c.designs for k, c in cal.cells.items()},
        "measured": cal.measured,
    }


def interval_lines(card: dict | None) -> str:
    """The model's own interval in a few lines: each calibrated cell, its held-out designs, and where measured the
    coverage of the peak plate stress, the deflection and the whole history with the peak's median width."""
    if card is None:
        return "the mesh model's own interval: none calibrated (outside the ranges its calls stay undecided)"
    measured = (card.get("measured") or {}).get("by_cell", {})
    lines = [
        f"the mesh model's own {100 * card['level']:.0f} % interval, by cell (held-out designs it was "
        "calibrated on; coverage of the solver measured on designs of other seeds: peak, deflection, whole "
        "history; the peak interval's median width):"
    ]
    for cell, n in card["cells"].items():
        m = measured.get(cell)
        got = (
            "not measured"
            if not m
            else (
                f"covers {100 * m['peak_plate_stress_mpa']:.0f} / {100 * m['max_deflection_mm']:.0f} / "
                f"{100 * m['plate_stress_history_mpa']:.0f} % of {m['designs']}, width "
                f"{100 * m['median_rel_width_peak']:.0f} %"
            )
        )
        lines.append(f"    {cell:<28} {n:>3} designs; {got}")
    lines.append("    any other cell outside the ranges: no interval, the call stays undecided")
    return "\n".join(lines)
