"""The arguments and first checks of ``hcmt generate`` and ``simulate``, the two commands that run the solver."""

from __future__ import annotations

import argparse
from dataclasses import asdict, fields
from pathlib import Path

from hcmt.cli import CommandError
from hcmt.cli.parsers.common import cores, cores_count, count, span
from hcmt.config import MAX_TRAJECTORIES
from hcmt.errors import clip
from hcmt.sim.materials import MATERIALS, parse_stack
from hcmt.sim.params import (
    CONTACT_RADIUS,
    FAMILIES,
    FORMULATIONS,
    MAX_ESTIMATED_SECONDS,
    PARAMETERS,
    Design,
    Settings,
    design_values,
)
from hcmt.sim.plate_params import PlateSettings
from hcmt.sim.sampling import RANGES, checked_ranges, describe_family, preset_design


# -- generate, simulate ---------------------------------------------------------------------------------------------
def parse_families(text: str) -> tuple[str, ...]:
    """``mono,stack2,ring`` -> the families, each checked against :data:`FAMILIES`."""
    names = tuple(t.strip() for t in text.split(",") if t.strip())
    for name in names or ("",):
        if name not in FAMILIES:
            raise CommandError(
                f"--family {clip(text)!r}: family {clip(name)!r} does not exist; the families are {', '.join(FAMILIES)}"
            )
    return names


def parameter_range(text: str) -> tuple[str, float, float]:
    """``--range NAME=LO:HI`` parsed (argparse turns the ValueError into one line naming the flag)."""
    name, eq, span = text.partition("=")
    lo, colon, hi = span.partition(":")
    try:
        bounds = float(lo), float(hi)
    except ValueError:
        bounds = ()
    if not (eq and colon and name.strip() and bounds):
        raise argparse.ArgumentTypeError(f"expected NAME=LO:HI such as thickness=0.5:1.25, got {clip(text)!r}")
    return name.strip(), *bounds


def range_overrides(args) -> dict[str, tuple[float, float]]:
    """``--range`` as ``generate_dataset``'s ``ranges`` (a name given twice refused)."""
    out: dict[str, tuple[float, float]] = {}
    for name, lo, hi in args.range:
        if name in out:
            raise CommandError(f"--range {name} is given twice; give each parameter once")
        out[name] = (lo, hi)
    return out


def _settings_arguments(parser: argparse.ArgumentParser, generate: bool = False) -> None:
    d = Settings()
    g = parser.add_argument_group("solver")
    g.add_argument(
        "--formulation",
        choices=FORMULATIONS,
        default=d.formulation,
        help="axisymmetric (sphere on a disk, default) or plane strain",
    )
    plate = f"; deforming-plate: {PlateSettings().frames}" if generate else ""
    g.add_argument(
        "--frames",
        type=int,
        default=None if generate else d.frames,
        help=f"recorded frames, >= 2 (default {d.frames}{plate}; a model's window may be longer: `hcmt "
        "models` shows it; a window too short cuts a thin plate's peak)",
    )
    g.add_argument("--frame-dt", type=float, default=d.frame_dt, help=f"ms between frames (default {d.frame_dt})")
    g.add_argument(
        "--bulk-viscosity",
        type=float,
        default=d.bulk_viscosity,
        help=f"linear bulk viscosity b1, 0 = off (default {d.bulk_viscosity})",
    )
    g.add_argument("--penalty", type=float, default=d.penalty, help=f"contact penalty factor (default {d.penalty})")
    g.add_argument(
        "--peak-stress",
        action="store_true",
        help="also record stress_max: each node's largest von Mises stress between two frames (a model "
        "trains on it with --set data.stress_field=stress_max)",
    )


def settings_of_args(args) -> Settings:
    """The solver settings of ``generate`` / ``simulate``, validated (a bad one names its flag: ``--frames``)."""
    frames = Settings().frames if args.frames is None else args.frames  # None: generate's per-dataset default
    return Settings(
        formulation=args.formulation,
        frames=frames,
        frame_dt=args.frame_dt,
        bulk_viscosity=args.bulk_viscosity,
        penalty=args.penalty,
        peak_stress=getattr(args, "peak_stress", False),
    ).validate()


def _split_arguments(parser: argparse.ArgumentParser) -> None:
    """``generate``'s trajectories per split: --train, --valid, --test, --variants and --variant-count."""
    trajectories = count(0, MAX_TRAJECTORIES)
    for flag, what, default in (("--train", "training", 2000), ("--valid", "validation", 200), ("--test", "test", 200)):
        parser.add_argument(
            flag,
            type=trajectories,
            default=default,
            metavar="N",
            help=f"{what} trajectories, {span(0, MAX_TRAJECTORIES)} (default {default})",
        )
    parser.add_argument(
        "--variants",
        action="store_true",
        help="also write test_thicker, test_higher, test_thicker_higher (generalization splits)",
    )
    parser.add_argument(
        "--variant-count",
        type=trajectories,
        default=50,
        metavar="N",
        help=f"trajectories per variant split, {span(0, MAX_TRAJECTORIES)} (default 50)",
    )


def configure_generate(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "dataset",
        choices=["impact-plate", "deforming-plate"],
        help="which dataset to generate: impact-plate (2-D explicit dynamics) or deforming-plate (3-D "
        "quasi-static, the MeshGraphNets layout; takes --train/--valid/--test, --seed, --workers, "
        "--frames, --force, --no-progress; the other options are impact-plate's)",
    )
    parser.add_argument("out", help="output dataset folder (created; an interrupted run resumes in place)")
    parser.add_argument(
        "--preset",
        choices=sorted(RANGES),
        default="small",
        help="paper: ~2,200 nodes as the paper; small: ~400-600 nodes for CPU training",
    )
    _split_arguments(parser)
    parser.add_argument("--seed", type=int, default=0, help="dataset seed (default 0)")
    parser.add_argument(
        "--edge-fraction",
        type=float,
        default=0.0,
        help="share of training designs drawn at the ranges' edges where models fail first: thin "
        "plates (lowest fifth of the thickness range) or high drops (top fifth); default 0",
    )
    parser.add_argument(
        "--range",
        type=parameter_range,
        action="append",
        default=[],
        metavar="NAME=LO:HI",
        help="replace a sampled parameter's range in every split (repeatable; e.g. --range "
        "thickness=0.5:1.25 --range drop_height=500:1250); a variant split keeps its own range "
        "of the parameters it sets; meta.json records it as range_overrides",
    )
    parser.add_argument(
        "--workers",
        type=cores_count,
        default=1,
        metavar="N",
        help=f"worker processes, 1 to this machine's cores ({cores()}; default 1)",
    )
    parser.add_argument(
        "--family",
        default="mono",
        metavar="F[,F...]",
        help="design families, taking each split's trajectories in turn: "
        + "; ".join(f"{k}: {describe_family(k)}" for k in FAMILIES)
        + " (default mono)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument(
        "--force",
        action="store_true",
        help=f"generate even when a trajectory is estimated to take over {MAX_ESTIMATED_SECONDS:.0f} s",
    )
    _settings_arguments(parser, generate=True)


#: impact-plate's options that deforming-plate refuses when set (flag, argument, default)
_IMPACT_ONLY = (
    ("--preset", "preset", "small"),
    ("--variants", "variants", False),
    ("--family", "family", "mono"),
    ("--edge-fraction", "edge_fraction", 0.0),
    ("--formulation", "formulation", Settings().formulation),
    ("--frame-dt", "frame_dt", Settings().frame_dt),
    ("--penalty", "penalty", Settings().penalty),
    ("--bulk-viscosity", "bulk_viscosity", Settings().bulk_viscosity),
    ("--peak-stress", "peak_stress", False),
    ("--range", "range", []),
)


def plate_settings_of_args(args) -> PlateSettings:
    """deforming-plate's settings (a bad one names its flag: ``--frames``)."""
    settings = PlateSettings(**({} if args.frames is None else {"frames": args.frames}))
    settings.validate()
    return settings


def check_generate(args) -> None:
    if args.dataset == "deforming-plate":
        for flag, name, default in _IMPACT_ONLY:
            if getattr(args, name) != default:
                raise CommandError(
                    f"{flag} is an impact-plate option; deforming-plate takes --train, --valid, "
                    "--test, --seed, --workers, --frames, --force and --no-progress"
                )
        plate_settings_of_args(args)
        return
    families = parse_families(args.family)
    settings_of_args(args)
    checked_ranges(args.preset, families, range_overrides(args))


def configure_simulate(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--preset",
        choices=sorted(RANGES),
        default="small",
        help="defaults for unspecified parameters: the middle of the preset's sampling ranges "
        "(default small, as `hcmt generate`). `hcmt predict` and `sweep` take the middle of "
        "their model's training designs instead (`hcmt models` lists them; for the shipped "
        "model, trained on small, within 0.1 %% of these) and its recorded window (--frames)",
    )
    parser.add_argument(
        "--family",
        default="mono",
        help=f"defaults from this family's ranges instead: one of {', '.join(FAMILIES)} (default mono)",
    )
    parser.add_argument(
        "--stack",
        default=None,
        metavar="SPEC",
        help="the panel's bonded layers from the top, MATERIAL:THICKNESS[:density=..][:modulus=..]"
        f"[:poisson=..] separated by commas, 1-4 layers, MATERIAL one of {', '.join(MATERIALS)}"
        " (e.g. glass:0.55,adhesive:0.05,film:0.2); sets thickness, plate_* and layer2-4_*",
    )
    parser.add_argument(
        "--design",
        nargs="+",
        default=[],
        metavar="KEY=VALUE",
        help="the design, spelled as in predict and sweep, e.g. --design thickness=0.8 "
        "drop_height=900 (unspecified parameters from --preset / --family); each parameter is "
        "also its own flag below (--thickness 0.8)",
    )
    for name, parameter in PARAMETERS.items():  # each parameter's unit and help: hcmt.sim.units
        parser.add_argument(
            "--" + name.replace("_", "-"),
            type=float,
            default=None,
            help=parameter.describe(contact_radius=CONTACT_RADIUS),
        )
    parser.add_argument("--out", default=None, help="write the trajectory to FILE.h5 (meta.json beside it)")
    parser.add_argument(
        "--force", action="store_true", help=f"solve even when the estimated time exceeds {MAX_ESTIMATED_SECONDS:.0f} s"
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    _settings_arguments(parser)


def simulate_inputs(args) -> tuple[Design, Settings]:
    """The design and settings of ``hcmt simulate``, validated; one line naming the flag at fault."""
    given = {f.name: getattr(args, f.name) for f in fields(Design) if getattr(args, f.name) is not None}
    listed = design_values(args.design)
    twice = sorted(set(listed) & set(given))
    if twice:
        raise CommandError(
            f"--design {twice[0]}=... and --{twice[0].replace('_', '-')}: the same parameter twice; give it once"
        )
    given.update(listed)
    stack = parse_stack(args.stack) if args.stack is not None else {}
    both = sorted(set(stack) & set(given))
    if both:
        raise CommandError(f"--stack sets {', '.join(both)}; do not give --{both[0].replace('_', '-')} too")
    family = parse_families(args.family)
    if len(family) != 1:
        raise CommandError(f"--family {clip(args.family)!r}: name one family for one design")
    design = Design(**{**asdict(preset_design(args.preset, family[0])), **stack, **given}).validate()
    settings = settings_of_args(args)
    if args.out is not None and Path(args.out).suffix != ".h5":
        raise CommandError(f"--out must name an .h5 file, got {clip(args.out)}")
    return design, settings


check_simulate = simulate_inputs
