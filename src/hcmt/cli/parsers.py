"""Every command's arguments (``configure_NAME(parser)``) and its first checks (``check_NAME(args)``): light, no
torch, scipy, scikit-learn or matplotlib, so that a mistake in the command line is one line in a fraction of a
second, before the command's module (:data:`hcmt.cli.COMMANDS`) loads them.

Counts: every count option has its bound in its help, and a value outside it is refused in one line (one rule for
all, no silent capping): ``--threads`` and ``--workers`` at most this machine's cores, trajectories per split
:data:`hcmt.config.MAX_TRAJECTORIES`, designs :data:`hcmt.config.MAX_DESIGNS`, a batch :data:`hcmt.config.MAX_BATCH`.
"""
from __future__ import annotations

import argparse
from dataclasses import asdict, fields
from pathlib import Path

from hcmt.cli import CommandError, check_outputs
from hcmt.config import (
    ABLATION_ALIASES,
    ABLATIONS,
    INFERENCE_COMPILE_MODES,
    INIT_NORMALIZERS,
    MAX_BATCH,
    MAX_DESIGNS,
    MAX_TRAJECTORIES,
    MODELS,
    available_pretrained,
    load_config,
    machine_cores,
)
from hcmt.design.basics import (
    DEFAULT_READOUT,
    DESIGN_BATCH,
    QUANTITIES,
    READOUTS,
    RESTARTS,
    check_values,
    check_yield,
    parse_vary,
    read_table,
)
from hcmt.errors import clip, require_installed
from hcmt.sim.params import (
    CONTACT_RADIUS,
    DESIGN_UNITS,
    FAMILIES,
    MATERIALS,
    MAX_ESTIMATED_SECONDS,
    RANGES,
    Design,
    Settings,
    describe_family,
    design_key,
    design_values,
    parse_stack,
    preset_design,
)

#: the largest count of a few options without a natural bound: training steps, frames a picture shows per second,
#: optimizer restarts, hierarchy levels, a picture's frame stride
MAX_STEPS, MAX_FPS, MAX_RESTARTS, MAX_LEVELS, MAX_STRIDE = 10**9, 100, 100, 64, 10_000
PICTURES = ("contours", "animation", "errors", "training", "hierarchy", "attention")


# -- counts --------------------------------------------------------------------------------------------------------
def count(lo: int, hi: int, what: str = ""):
    """An argparse type: a whole number from ``lo`` to ``hi`` (``what``: why that bound), else one line."""
    def parse(text: str) -> int:
        try:
            n = int(text)
        except ValueError:
            n = None
        if n is None or not lo <= n <= hi:
            raise argparse.ArgumentTypeError(f"expected a whole number from {lo} to {hi:,}{what}, got {clip(text)!r}")
        return n
    return parse


def cores_count(text: str) -> int:
    return count(1, machine_cores(), " (this machine's cores)")(text)


def threads_arg(text: str) -> int | str:
    return text if text == "auto" else count(1, machine_cores(), " (this machine's cores) or auto")(text)


def span(lo: int, hi: int) -> str:
    """How a count's help states its bound: ``1 to 1,024``."""
    return f"{lo} to {hi:,}"


# -- shared options ------------------------------------------------------------------------------------------------
class Once(argparse.Action):
    """An option given at most once: a second one is refused in one line (``why``: what to do) where argparse
    would keep the last silently."""

    def __init__(self, *args, why: str = "give it once", **kwargs):
        super().__init__(*args, **kwargs)
        self.why = why

    def __call__(self, parser, namespace, values, option_string=None):
        given = f"_{self.dest}_given"
        if getattr(namespace, given, False):
            parser.error(f"{option_string}: given twice ({clip(getattr(namespace, self.dest), 40)}, "
                         f"{clip(values, 40)}); {self.why}")
        setattr(namespace, given, True)
        setattr(namespace, self.dest, values)


def compile_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--compile", default="auto", choices=INFERENCE_COMPILE_MODES,
                   help="torch.compile the model: default compiles once for every mesh (symbolic sizes; about 25 s, "
                        "65 s the first time on a machine), reduce-overhead (CUDA graphs) and max-autotune on padded "
                        "graphs; aot exports the forward once per machine and model (about a minute), and later calls "
                        "load it instead of compiling (default where the export fails); auto (default): on the CPU aot "
                        "where this model's package is already built, or for at least 2,000 model steps in all (about "
                        "23 designs of the small preset); elsewhere default for at least 2,000 steps where a compiler "
                        "exists; else none")


def batch_arg(p: argparse.ArgumentParser, what: str, default: int | None, default_text: str) -> None:
    p.add_argument("--batch", type=count(1, MAX_BATCH), default=default, metavar="N",
                   help=f"{what} together, {span(1, MAX_BATCH)} (default {default_text})")


def verify_arg(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument("--verify", nargs="?", const="all", metavar="auto",
                   help=f"also run the built-in solver on every design and {what}; `--verify auto` (with "
                        "--yield-mpa) runs it only on the designs whose call is undecided, and their final call is "
                        "the solver's")


def surrogate_args(p: argparse.ArgumentParser) -> None:
    g = p.add_mutually_exclusive_group()
    g.add_argument("--surrogate", metavar="FILE.json", help="the response surface to report beside the model (made "
                   "by `hcmt surrogate fit`; default: the model's own, shipped with it or RUN/surrogate.json)")
    g.add_argument("--no-surrogate", action="store_true", help="no response surface: the mesh model alone")


def readout_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--readout", choices=READOUTS, default=DEFAULT_READOUT,
                   help="raw (default): the mesh model's answer is its own outputs (stress field and positions) in "
                        "every frame, whatever the response surface; contact: also report (as contact_*) the peak "
                        "from the frames the ball touches the plate, the window ending at the response surface's "
                        "bound of when the ball leaves, and a bending formula after it; element: also report (as "
                        "element_*) the solver's element law on the predicted positions. The calls and trends use "
                        "the chosen read-out; the JSON records it")


def model_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("model", nargs="?", help="run folder made by `hcmt train`, or pretrained:NAME (`hcmt models` "
                   "lists them)")
    same_as(p, path="MODEL")


def same_as(p: argparse.ArgumentParser, **flags: str) -> None:
    """Name library parameters that this command calls otherwise (``path="MODEL"``: ``Run.load``'s ``path`` is
    ``hcmt predict``'s MODEL), so that their errors name the flag (:func:`hcmt.cli.flag_of`)."""
    p.param_flags = {**getattr(p, "param_flags", {}), **flags}


def check_run(name: str, text: str) -> None:
    """A run folder (``NAME``: the argument's name) that exists, or ``pretrained:NAME`` of a shipped model: one line
    before the model loads."""
    if text.startswith("pretrained:"):
        if text.split(":", 1)[1] not in available_pretrained():
            raise CommandError(f"{name} {clip(text)}: no such shipped model; `hcmt models` lists them")
        return
    path = Path(text)
    if not (path / "run.yaml").is_file():
        hint = f"; the shipped model is pretrained:{text}" if text in available_pretrained() else ""
        what = "no such folder" if not path.exists() else "not a run folder (no run.yaml)"
        raise CommandError(f"{name} {text}: {what}; expected a folder made by `hcmt train --out RUN`, or "
                           f"pretrained:NAME{hint}")


def check_folder(name: str, text: str, what: str) -> None:
    if not Path(text).is_dir():
        raise CommandError(f"{name} {text}: no such folder; expected {what}")


def check_split(data: str, split: str) -> None:
    """A dataset folder's ``meta.json`` and ``<split>.h5`` exist (a cheap look before torch loads; the reader checks
    the contents)."""
    folder = Path(data)
    if not (folder / "meta.json").is_file():
        raise CommandError(f"--data {clip(data)}: no meta.json; expected a native dataset folder (meta.json + "
                           "<split>.h5)")
    if not (folder / f"{split}.h5").is_file():
        have = ", ".join(sorted(f.stem for f in folder.glob("*.h5"))) or "none"
        raise CommandError(f"--split {clip(split)}: {clip(data)} has no {clip(split)}.h5; splits there: {have}")


# -- generate, simulate ---------------------------------------------------------------------------------------------
def parse_families(text: str) -> tuple[str, ...]:
    """``mono,stack2,ring`` -> the families, each checked against :data:`FAMILIES`."""
    names = tuple(t.strip() for t in text.split(",") if t.strip())
    for name in names or ("",):
        if name not in FAMILIES:
            raise CommandError(f"--family {clip(text)!r}: family {clip(name)!r} does not exist; the families are "
                               f"{', '.join(FAMILIES)}")
    return names


def _settings_arguments(parser: argparse.ArgumentParser) -> None:
    d = Settings()
    g = parser.add_argument_group("solver")
    g.add_argument("--formulation", choices=["axisymmetric", "plane_strain"], default=d.formulation,
                   help="axisymmetric (sphere on a disk, default) or plane strain")
    g.add_argument("--frames", type=int, default=d.frames,
                   help=f"recorded frames, >= 2 (default {d.frames}; a model's window may be longer: `hcmt models` "
                        "shows it; a window too short cuts a thin plate's peak)")
    g.add_argument("--frame-dt", type=float, default=d.frame_dt, help=f"ms between frames (default {d.frame_dt})")
    g.add_argument("--bulk-viscosity", type=float, default=d.bulk_viscosity,
                   help=f"linear bulk viscosity b1, 0 = off (default {d.bulk_viscosity})")
    g.add_argument("--penalty", type=float, default=d.penalty, help=f"contact penalty factor (default {d.penalty})")
    g.add_argument("--peak-stress", action="store_true",
                   help="also record stress_max: each node's largest von Mises stress between two frames (a model "
                        "trains on it with --set data.stress_field=stress_max)")


def settings_of_args(args) -> Settings:
    """The solver settings of ``generate`` / ``simulate``, validated (a bad one names its flag: ``--frames``)."""
    return Settings(formulation=args.formulation, frames=args.frames, frame_dt=args.frame_dt,
                    bulk_viscosity=args.bulk_viscosity, penalty=args.penalty,
                    peak_stress=getattr(args, "peak_stress", False)).validate()


def configure_generate(parser: argparse.ArgumentParser) -> None:
    trajectories = count(0, MAX_TRAJECTORIES)
    parser.add_argument("dataset", choices=["impact-plate"], help="which dataset to generate")
    parser.add_argument("out", help="output dataset folder (created; an interrupted run resumes in place)")
    parser.add_argument("--preset", choices=sorted(RANGES), default="small",
                        help="paper: ~2,200 nodes as the paper; small: ~400-600 nodes for CPU training")
    for flag, what, default in (("--train", "training", 2000), ("--valid", "validation", 200),
                                ("--test", "test", 200)):
        parser.add_argument(flag, type=trajectories, default=default, metavar="N",
                            help=f"{what} trajectories, {span(0, MAX_TRAJECTORIES)} (default {default})")
    parser.add_argument("--variants", action="store_true",
                        help="also write test_thicker, test_higher, test_thicker_higher (generalization splits)")
    parser.add_argument("--variant-count", type=trajectories, default=50, metavar="N",
                        help=f"trajectories per variant split, {span(0, MAX_TRAJECTORIES)} (default 50)")
    parser.add_argument("--seed", type=int, default=0, help="dataset seed (default 0)")
    parser.add_argument("--edge-fraction", type=float, default=0.0,
                        help="share of training designs drawn at the ranges' edges where models fail first: thin "
                             "plates (lowest fifth of the thickness range) or high drops (top fifth); default 0")
    parser.add_argument("--workers", type=cores_count, default=1, metavar="N",
                        help=f"worker processes, 1 to this machine's cores ({machine_cores()}; default 1)")
    parser.add_argument("--family", default="mono", metavar="F[,F...]",
                        help="design families, taking each split's trajectories in turn: "
                             + "; ".join(f"{k}: {describe_family(k)}" for k in FAMILIES) + " (default mono)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--force", action="store_true",
                        help=f"generate even when a trajectory is estimated to take over {MAX_ESTIMATED_SECONDS:.0f} s")
    _settings_arguments(parser)


def check_generate(args) -> None:
    parse_families(args.family)
    settings_of_args(args)


_DESIGN_HELP = {"layer2_thickness": "mm, a bonded layer under the top one (0: none; default material the polymer film)",
                "support_radius": "mm, a simply supported ring under the panel, rim free (0: clamped rim)",
                "backing_thickness": "mm, a bonded soft backing under the panel, bottom fixed, rim free (0: none)",
                "backing_modulus": "MPa, the backing's Young's modulus",
                "pen_tip_radius": "mm, a pen's hemispherical tip instead of the ball (0: the ball)",
                "pen_mass": "g, the pen's rigid rod", "thickness": "plate thickness (mm)",
                "drop_height": "drop height H (mm), v0 = sqrt(2 g H)",
                "plate_density": "g/mm^3", "plate_modulus": "Young's modulus (MPa)", "plate_poisson": "",
                "ball_radius": "mm", "ball_density": "g/mm^3", "ball_modulus": "MPa", "ball_poisson": "",
                "mesh_size": "element size (mm)", "plate_half_length": "plate radius / half width (mm)",
                "gap": f"initial gap (mm), < contact radius {CONTACT_RADIUS}"}


def configure_simulate(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--preset", choices=sorted(RANGES), default="small",
                        help="defaults for unspecified parameters: the middle of the preset's sampling ranges "
                             "(default small, as `hcmt generate`). `hcmt predict` and `sweep` take the middle of "
                             "their model's training designs instead (`hcmt models` lists them; for the shipped "
                             "model, trained on small, within 0.1 %% of these) and its recorded window (--frames)")
    parser.add_argument("--family", default="mono",
                        help=f"defaults from this family's ranges instead: one of {', '.join(FAMILIES)} (default mono)")
    parser.add_argument("--stack", default=None, metavar="SPEC",
                        help="the panel's bonded layers from the top, MATERIAL:THICKNESS[:density=..][:modulus=..]"
                             f"[:poisson=..] separated by commas, 1-4 layers, MATERIAL one of {', '.join(MATERIALS)}"
                             " (e.g. glass:0.55,adhesive:0.05,film:0.2); sets thickness, plate_* and layer2-4_*")
    parser.add_argument("--design", nargs="+", default=[], metavar="KEY=VALUE",
                        help="the design, spelled as in predict and sweep, e.g. --design thickness=0.8 "
                             "drop_height=900 (unspecified parameters from --preset / --family); each parameter is "
                             "also its own flag below (--thickness 0.8)")
    for f in fields(Design):
        parser.add_argument("--" + f.name.replace("_", "-"), type=float, default=None,
                            help=_DESIGN_HELP.get(f.name) or f"{DESIGN_UNITS[f.name]}")
    parser.add_argument("--out", default=None, help="write the trajectory to FILE.h5 (meta.json beside it)")
    parser.add_argument("--force", action="store_true",
                        help=f"solve even when the estimated time exceeds {MAX_ESTIMATED_SECONDS:.0f} s")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    _settings_arguments(parser)


def simulate_inputs(args) -> tuple[Design, Settings]:
    """The design and settings of ``hcmt simulate``, validated; one line naming the flag at fault."""
    given = {f.name: getattr(args, f.name) for f in fields(Design) if getattr(args, f.name) is not None}
    listed = design_values(args.design)
    twice = sorted(set(listed) & set(given))
    if twice:
        raise CommandError(f"--design {twice[0]}=... and --{twice[0].replace('_', '-')}: the same parameter twice; "
                           "give it once")
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


# -- convert, info, hierarchy --------------------------------------------------------------------------------------
def configure_convert(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("src", help="TFRecord dataset folder (meta.json + <split>.tfrecord) or GGNS pickle(s)")
    parser.add_argument("out", help="output folder for the native dataset (meta.json + <split>.h5)")


def check_convert(args) -> None:
    if not Path(args.src).exists():
        raise CommandError(f"SRC {args.src}: no such file or folder; expected a TFRecord dataset folder or "
                           "GGNS pickle(s)")


def configure_info(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dataset", help="native dataset folder (meta.json + <split>.h5)")
    parser.add_argument("--all", action="store_true", help="list every design parameter on its own line, the "
                        "constant ones too (default: the varying ones, the constants in one line)")


def check_info(args) -> None:
    check_folder("DATASET", args.dataset, "a native dataset folder (meta.json + <split>.h5)")


def configure_hierarchy(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dataset", metavar="DATASET", help="native dataset folder (meta.json + <split>.h5)")
    parser.add_argument("--levels", type=count(0, MAX_LEVELS), required=True, metavar="N",
                        help=f"number of pooled levels lambda, {span(0, MAX_LEVELS)} (paper: 6 for Impact Plate, 2 "
                             "Deforming Plate, 4 Sphere Simple, 1 Deformable Plate)")
    parser.add_argument("--json", metavar="FILE", help="also write the table as JSON: one object per level 0..L")
    parser.add_argument("--split", default="train", help="split to read (default: train)")
    parser.add_argument("--trajectories", type=count(0, MAX_TRAJECTORIES), default=0, metavar="N",
                        help=f"use the first N trajectories, {span(0, MAX_TRAJECTORIES)} (default 0: all)")
    parser.add_argument("--no-cache", action="store_true", help="do not read or write DATASET/.cache/hierarchy")


check_hierarchy = check_info


# -- train, rollout, evaluate, compare -----------------------------------------------------------------------------
def configure_train(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", help="built-in config name (impact_plate, impact_plate_cpu, ...) or a YAML file")
    same_as(p, name_or_path="--config")
    p.add_argument("--data", help="native dataset folder")
    p.add_argument("--model", choices=MODELS)
    p.add_argument("--ablation", choices=ABLATIONS + ABLATION_ALIASES,
                   help="HCMT ablation (paper Tables 3, 10-12): --set model.ablation; the paper's HCMT without "
                        "remeshing, no-remesh, is a graph setting: --set data.remesh=false")
    p.add_argument("--steps", type=count(1, MAX_STEPS), metavar="N",
                   help=f"training steps, {span(1, MAX_STEPS)} (overrides train.steps)")
    p.add_argument("--seed", type=int, help="random seed (default 0)")
    p.add_argument("--out", required=True, help="run folder")
    p.add_argument("--resume", action="store_true", help="continue the run in --out from its last checkpoint; "
                   "`--resume --out RUN` alone uses the run's saved settings (--steps may extend it)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override any config key, e.g. --set train.lr=3e-4 --set model.levels=4")
    p.add_argument("--init", metavar="RUN|pretrained:NAME",
                   help="start from that model's weights (fine-tuning, e.g. a shipped model on your own solver's "
                        "data); the run takes its model settings (architecture, features), and its config and "
                        "model when --config / --model are left out")
    p.add_argument("--init-normalizers", choices=INIT_NORMALIZERS, default="keep",
                   help="with --init: keep its normalizer statistics, frozen (default), or re-accumulate them on "
                        "--data")
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
    p.add_argument("--out", metavar="DIR", help="for a shipped model (pretrained:NAME): the folder its rollouts and "
                   "metrics are written to (a run folder's go to RUN)")
    p.add_argument("--split", default="test")
    p.add_argument("--limit", type=count(1, MAX_TRAJECTORIES), metavar="N",
                   help=f"only the first N trajectories, {span(1, MAX_TRAJECTORIES)}")
    p.add_argument("--checkpoint", default="best", choices=["best", "checkpoint"])
    p.add_argument("--device", help="cpu, cuda, cuda:N (default: cuda when available)")
    batch_arg(p, "trajectories rolled out as one batched graph", 1, "1")
    compile_arg(p)
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def _check_run_args(args) -> None:
    check_run("RUN", args.run)
    check_folder("--data", args.data, "a native dataset folder (meta.json + <split>.h5)")
    shipped = args.run.startswith("pretrained:")
    if shipped and args.out is None:
        raise CommandError(f"RUN {clip(args.run)}: a shipped model has no run folder; give --out DIR for its "
                           "rollouts and metrics")
    if not shipped and args.out is not None:
        raise CommandError(f"--out {clip(args.out)}: for a shipped model (pretrained:NAME); a run folder's rollouts "
                           "and metrics go to RUN")
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


# -- predict, sweep, models ----------------------------------------------------------------------------------------
def configure_predict(p: argparse.ArgumentParser) -> None:
    model_arg(p)
    p.add_argument("--design", nargs="+", action="append", default=[], metavar="KEY=VALUE",
                   help="one design, e.g. --design thickness=0.8 drop_height=900 (repeat for more designs); "
                        "parameters as `hcmt simulate`'s, unspecified ones at the middle of the training ranges")
    p.add_argument("--designs", metavar="FILE.csv", help="designs from a CSV file: header of parameter names "
                   "(optional `name` column), one design per row; with --design too, the --design ones come first; "
                   f"{span(1, MAX_DESIGNS)} designs in all")
    p.add_argument("--device", help="cpu, cuda, cuda:N (default: cuda when available)")
    batch_arg(p, "designs rolled out", DESIGN_BATCH, f"{DESIGN_BATCH}, measured fastest on one CPU thread")
    compile_arg(p)
    p.add_argument("--yield-mpa", type=float, help="report the margin of the peak plate stress to this stress "
                   "(MPa, 1 to 100,000) and a pass / fail / undecided call per design from the trusted interval")
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
    return {"verify": verify, "yield_mpa": check_yield(args.yield_mpa), "readout": args.readout,
            "surrogate": False if args.no_surrogate else (args.surrogate or True)}


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
        raise CommandError(f"{len(args.design) + rows:,} designs (--design and --designs); expected at most "
                           f"{MAX_DESIGNS:,} in one call")


def configure_sweep(p: argparse.ArgumentParser) -> None:
    model_arg(p)
    p.add_argument("--vary", required=True, metavar="PARAM=LO:HI:N", action=Once, why="a sweep varies one parameter",
                   help="the parameter swept and its range, e.g. thickness=0.55:0.95:5 (N points, 2 to 256, ends "
                        "included)")
    p.add_argument("--design", nargs="+", default=[], metavar="KEY=VALUE",
                   help="the other parameters, e.g. --design drop_height=750 (default: the middle of the training "
                        "ranges)")
    verify_arg(p, "compare the trends")
    p.add_argument("--yield-mpa", type=float, help="report the smallest / largest parameter value that keeps the "
                   "peak plate stress below this stress (MPa, 1 to 100,000) from the final calls, for model and solver")
    surrogate_args(p)
    readout_arg(p)
    p.add_argument("--device", help="cpu, cuda, cuda:N (default: cuda when available)")
    batch_arg(p, "sweep points rolled out", DESIGN_BATCH,
              f"{DESIGN_BATCH}: one point at a time, measured fastest on one CPU thread; N of --vary: the whole sweep "
              "in one batch")
    compile_arg(p)
    p.add_argument("--force", action="store_true", help="run even designs estimated to take over 600 s")
    p.add_argument("--out", default="sweep_out", help="folder for the plot (default sweep_out)")
    p.add_argument("--json", help="write the points (as predict's JSON, each with its verify block) and the "
                   "analysis as JSON")
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
        raise CommandError(f"--vary {clip(args.vary)} and --design {clip(fixed[0])}: {param} is the swept "
                           "parameter; drop it from --design")
    check_values([args.design], vary=args.vary)  # every value, both ends of the range, before torch loads


def configure_models(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", action="store_true", help="print the model cards as JSON")


# -- surrogate -----------------------------------------------------------------------------------------------------
def configure_surrogate(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    f = sub.add_parser("fit", help="fit the response surface on a dataset's solver runs and write it as JSON",
                       description="Fit one Gaussian process per scalar answer (" + ", ".join(QUANTITIES) + ") on "
                       "the design parameters of an hcmt-generated Impact Plate dataset's split; written as JSON "
                       "(no pickle). Use it with `hcmt predict/sweep --surrogate FILE`, or save it as "
                       "RUN/surrogate.json to make it the run's own.")
    f.add_argument("data", help="an hcmt-generated Impact Plate dataset (`hcmt generate impact-plate`)")
    f.add_argument("--out", required=True, help="the surrogate file to write (JSON)")
    f.add_argument("--split", default="train", help="the split whose designs it is fitted on (default train)")
    f.add_argument("--limit", type=count(1, MAX_TRAJECTORIES), metavar="N",
                   help=f"fit on the first N trajectories only, {span(1, MAX_TRAJECTORIES)}")
    f.add_argument("--restarts", type=count(0, MAX_RESTARTS), default=RESTARTS, metavar="N",
                   help=f"optimizer restarts of the marginal likelihood, {span(0, MAX_RESTARTS)} (default {RESTARTS})")
    f.add_argument("--seed", type=int, default=0, help="seed of the optimizer restarts")
    f.add_argument("--stress-field", choices=("stress", "stress_max"), default="stress",
                   help="the stress the model learned (default stress; stress_max: `generate --peak-stress` data and "
                        "a model trained with --set data.stress_field=stress_max)")
    f.add_argument("--label", help="what the training designs are, recorded in the file (default: the dataset's "
                   "path and split)")


def check_surrogate(args) -> None:
    check_folder("DATA", args.data, "an hcmt-generated Impact Plate dataset (`hcmt generate impact-plate`)")


# -- plot, export --------------------------------------------------------------------------------------------------
def frames_of(text: str | None) -> list[int] | None:
    if text is None:
        return None
    try:
        return [int(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise CommandError(f"--frames {clip(text)!r}: expected comma-separated frame numbers, e.g. 0,10,25,51") \
            from None


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
    p.add_argument("--scale", default="frame", choices=["frame", "all"],
                   help="contour colour scale: one per frame (row) or one for the whole figure")
    p.add_argument("--fps", type=count(1, MAX_FPS), default=10, metavar="N",
                   help=f"animation frames per second, {span(1, MAX_FPS)} (default 10)")
    p.add_argument("--stride", type=count(1, MAX_STRIDE), metavar="N",
                   help=f"animate every N-th frame, {span(1, MAX_STRIDE)} (default: at most 100 frames)")
    p.add_argument("--levels", type=count(1, MAX_LEVELS), metavar="N",
                   help=f"hierarchy levels to draw when no run is an HCMT with a hierarchy, {span(1, MAX_LEVELS)}")
    p.add_argument("--attention-frame", type=int, help="frame of the attention maps (default: the impact)")
    p.add_argument("--limit", type=count(1, MAX_TRAJECTORIES), metavar="N",
                   help=f"error curves: roll out only the first N trajectories where needed, "
                        f"{span(1, MAX_TRAJECTORIES)}")


def check_plot(args) -> None:
    pictures_of(args.only)
    frames_of(args.frames)
    check_export(args)
    check_outputs({}, {"--out": args.out})


def configure_export(p: argparse.ArgumentParser) -> None:
    _common(p)
    p.add_argument("--format", default="vtu", choices=["vtu", "xdmf"],
                   help="vtu: one file per frame + a .pvd collection; xdmf: one .xdmf + .h5 per series")
    p.add_argument("--trajectory", default="0", help="index or name of the trajectory, or 'all' (default 0)")
    p.add_argument("--stride", type=count(1, MAX_STRIDE), default=1, metavar="N",
                   help=f"export every N-th frame, {span(1, MAX_STRIDE)} (default 1: all)")


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
    p.add_argument("--train", action="store_true", help="train a model from scratch instead (generate, train, "
                   "evaluate; several minutes)")
    p.add_argument("--steps", type=count(1, MAX_STEPS), metavar="N",
                   help=f"--train: training steps, {span(1, MAX_STEPS)} (default: the demo config's)")
    p.add_argument("--train-trajectories", type=count(1, MAX_TRAJECTORIES), default=12, metavar="N",
                   help=f"--train: training trajectories to generate, {span(1, MAX_TRAJECTORIES)} (default 12)")
    p.add_argument("--test", type=count(1, MAX_TRAJECTORIES), default=2, metavar="N",
                   help=f"--train: test trajectories to generate, {span(1, MAX_TRAJECTORIES)} (default 2)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--workers", type=cores_count, default=min(2, machine_cores()), metavar="N",
                   help=f"--train: worker processes, 1 to this machine's cores ({machine_cores()}; default "
                        f"{min(2, machine_cores())})")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")


def check_demo(args) -> None:
    if args.steps is not None and not args.train:
        raise CommandError("--steps sets the training length of `hcmt demo --train`; the default demo trains nothing "
                           "(it uses the shipped model)")
    if not args.train:
        check_run("--model", args.model)
