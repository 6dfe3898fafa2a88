"""The arguments and first checks of ``hcmt predict``, ``sweep``, ``models`` and ``surrogate``."""

from __future__ import annotations

import argparse
from pathlib import Path

from hcmt.cli import CommandError, check_outputs
from hcmt.cli.parsers.common import (
    MAX_RESTARTS,
    Once,
    batch_arg,
    check_folder,
    check_run,
    compile_arg,
    count,
    model_arg,
    readout_arg,
    span,
    surrogate_args,
    verify_arg,
)
from hcmt.config import MAX_DESIGNS, MAX_TRAJECTORIES, STRESS_FIELDS
from hcmt.design.basics import DESIGN_BATCH, QUANTITIES, RESTARTS, check_values, check_yield, parse_vary, read_table
from hcmt.errors import clip, require_installed
from hcmt.sim.params import design_key, design_values


# -- predict, sweep, models ----------------------------------------------------------------------------------------
def configure_predict(p: argparse.ArgumentParser) -> None:
    model_arg(p)
    p.add_argument(
        "--design",
        nargs="+",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="one design, e.g. --design thickness=0.8 drop_height=900 (repeat for more designs); "
        "parameters as `hcmt simulate`'s, unspecified ones at the middle of the training ranges",
    )
    p.add_argument(
        "--designs",
        metavar="FILE.csv",
        help="designs from a CSV file: header of parameter names "
        "(optional `name` column), one design per row; with --design too, the --design ones come first; "
        f"{span(1, MAX_DESIGNS)} designs in all",
    )
    p.add_argument("--device", help="cpu, cuda, cuda:N (default: cuda when available)")
    batch_arg(p, "designs rolled out", DESIGN_BATCH, f"{DESIGN_BATCH}, measured fastest on one CPU thread")
    compile_arg(p)
    p.add_argument(
        "--yield-mpa",
        type=float,
        help="report the margin of the peak plate stress to this stress "
        "(MPa, 1 to 100,000) and a pass / fail / undecided call per design from the trusted interval",
    )
    verify_arg(p, "report the errors and the speedup")
    surrogate_args(p)
    readout_arg(p)
    p.add_argument("--images", action="store_true", help="stress-contour PNG at each design's peak frame")
    p.add_argument("--out", default="predict_out", help="folder for --images (default predict_out)")
    p.add_argument("--force", action="store_true", help="run even designs estimated to take over 600 s")
    p.add_argument("--json", help="write the results as JSON")
    p.add_argument("--csv", help="write the table as CSV")
    p.add_argument("--no-progress", action="store_true")


def take_model(args, design_lists: list[list[str]]) -> None:
    """Accept the model after the options (``--design ... MODEL``, ``--verify MODEL``): argparse gives it to the
    option before it. Also checks ``--verify``'s value (nothing, or ``auto``) and that the model exists."""
    if args.verify not in (None, "all", "auto"):
        if args.model is not None:
            raise CommandError(f"--verify {clip(args.verify)!r}: expected nothing (every design) or auto")
        args.model, args.verify = args.verify, "all"
    if args.model is None and design_lists and design_lists[-1]:
        last = design_lists[-1][-1]
        if "=" not in last or last.startswith("pretrained:") or Path(last).exists():
            args.model = design_lists[-1].pop()
    if args.model is None:
        raise CommandError("give the model: a run folder made by `hcmt train`, or pretrained:NAME (`hcmt models`)")
    design_lists[:] = [items for items in design_lists if items]
    check_run("MODEL", args.model)


def check_options(args) -> dict:
    """The design-check options shared by predict and sweep: ``--yield-mpa`` a plausible yield stress in MPa (a
    unit slip, Pa for MPa, refused here: :func:`hcmt.design.basics.check_yield`)."""
    verify = {"all": True, "auto": "auto", None: False}[args.verify]
    if verify == "auto" and args.yield_mpa is None:
        raise CommandError("--verify auto runs the solver on the designs whose call is undecided: give --yield-mpa Y")
    return {
        "verify": verify,
        "yield_mpa": check_yield(args.yield_mpa),
        "readout": args.readout,
        "surrogate": False if args.no_surrogate else (args.surrogate or True),
        "interval": False if args.no_model_interval else (args.model_interval or True),
    }


def check_predict(args) -> None:
    take_model(args, args.design)
    if not args.design and not args.designs:
        raise CommandError("give designs with --design KEY=VALUE ... or --designs FILE.csv")
    for items in args.design:
        design_values(items)
    check_options(args)
    check_outputs({"--json": args.json, "--csv": args.csv}, {"--out": args.out} if args.images else {})
    if args.images:
        require_installed("viz", "matplotlib")  # before the model runs: --images needs the pictures' extra
    check_values(args.design, args.designs)  # every value and the file's rows, one line before torch loads
    rows = len(read_table(Path(args.designs))[2]) if args.designs else 0
    if len(args.design) + rows > MAX_DESIGNS:
        raise CommandError(
            f"{len(args.design) + rows:,} designs (--design and --designs); expected at most "
            f"{MAX_DESIGNS:,} in one call"
        )


def configure_sweep(p: argparse.ArgumentParser) -> None:
    model_arg(p)
    p.add_argument(
        "--vary",
        required=True,
        metavar="PARAM=LO:HI:N",
        action=Once,
        why="a sweep varies one parameter",
        help="the parameter swept and its range, e.g. thickness=0.55:0.95:5 (N points, 2 to 256, ends included)",
    )
    p.add_argument(
        "--design",
        nargs="+",
        default=[],
        metavar="KEY=VALUE",
        help="the other parameters, e.g. --design drop_height=750 (default: the middle of the training ranges)",
    )
    verify_arg(p, "compare the trends")
    p.add_argument(
        "--yield-mpa",
        type=float,
        help="report the smallest / largest parameter value that keeps the "
        "peak plate stress below this stress (MPa, 1 to 100,000) from the final calls, for model and solver",
    )
    surrogate_args(p)
    readout_arg(p)
    p.add_argument("--device", help="cpu, cuda, cuda:N (default: cuda when available)")
    batch_arg(
        p,
        "sweep points rolled out",
        DESIGN_BATCH,
        f"{DESIGN_BATCH}: one point at a time, measured fastest on one CPU thread; N of --vary: the whole sweep "
        "in one batch",
    )
    compile_arg(p)
    p.add_argument("--force", action="store_true", help="run even designs estimated to take over 600 s")
    p.add_argument("--out", default="sweep_out", help="folder for the plot (default sweep_out)")
    p.add_argument(
        "--json", help="write the points (as predict's JSON, each with its verify block) and the analysis as JSON"
    )
    p.add_argument("--csv", help="write the points as CSV")
    p.add_argument("--no-progress", action="store_true")


def check_sweep(args) -> None:
    param = parse_vary(args.vary)[0]
    take_model(args, [args.design])
    design_values(args.design)
    check_options(args)
    check_outputs({"--json": args.json, "--csv": args.csv}, {"--out": args.out})
    fixed = [item for item in args.design if design_key(item) == param]
    if fixed:
        raise CommandError(
            f"--vary {clip(args.vary)} and --design {clip(fixed[0])}: {param} is the swept "
            "parameter; drop it from --design"
        )
    check_values([args.design], vary=args.vary)  # every value, both ends of the range, before torch loads


def configure_models(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", action="store_true", help="print the model cards as JSON")


# -- surrogate -----------------------------------------------------------------------------------------------------
def configure_surrogate(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    f = sub.add_parser(
        "fit",
        help="fit the response surface on a dataset's solver runs and write it as JSON",
        description="Fit one Gaussian process per scalar answer (" + ", ".join(QUANTITIES) + ") on "
        "the design parameters of an hcmt-generated Impact Plate dataset's split; written as JSON "
        "(no pickle). Use it with `hcmt predict/sweep --surrogate FILE`, or save it as "
        "RUN/surrogate.json to make it the run's own.",
    )
    f.add_argument("data", help="an hcmt-generated Impact Plate dataset (`hcmt generate impact-plate`)")
    f.add_argument("--out", required=True, help="the surrogate file to write (JSON)")
    f.add_argument("--split", default="train", help="the split whose designs it is fitted on (default train)")
    f.add_argument(
        "--limit",
        type=count(1, MAX_TRAJECTORIES),
        metavar="N",
        help=f"fit on the first N trajectories only, {span(1, MAX_TRAJECTORIES)}",
    )
    f.add_argument(
        "--restarts",
        type=count(0, MAX_RESTARTS),
        default=RESTARTS,
        metavar="N",
        help=f"optimizer restarts of the marginal likelihood, {span(0, MAX_RESTARTS)} (default {RESTARTS})",
    )
    f.add_argument("--seed", type=int, default=0, help="seed of the optimizer restarts")
    f.add_argument(
        "--stress-field",
        choices=STRESS_FIELDS,
        default="stress",
        help="the stress the model learned (default stress; stress_max: `generate --peak-stress` data and "
        "a model trained with --set data.stress_field=stress_max)",
    )
    f.add_argument(
        "--label", help="what the training designs are, recorded in the file (default: the dataset's path and split)"
    )


def check_surrogate(args) -> None:
    check_folder("DATA", args.data, "an hcmt-generated Impact Plate dataset (`hcmt generate impact-plate`)")
