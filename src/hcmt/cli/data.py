"""``hcmt generate / simulate / convert / info / hierarchy``: the data commands, argument parsing and printing only;
the library functions live in :mod:`hcmt.sim.generate`, :mod:`hcmt.sim.scene`, :mod:`hcmt.data.convert`,
:mod:`hcmt.data.info` and :mod:`hcmt.graph.report`."""
from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import asdict, fields
from pathlib import Path

from tqdm import tqdm

from hcmt.cli import CommandError
from hcmt.config import plural
from hcmt.data.convert import convert
from hcmt.data.format import write_meta, write_split
from hcmt.data.info import summarize
from hcmt.files import atomic_path, check_apart
from hcmt.graph.report import dataset_quality, format_table
from hcmt.inference import quantities
from hcmt.sim.generate import dataset_meta, generate_dataset, generation_cost, preset_design, trajectory_name
from hcmt.sim.scene import (CONTACT_RADIUS, DESIGN_UNITS, FAMILIES, MATERIALS, MAX_ESTIMATED_SECONDS, RANGES,
                            VARIANTS, Design, Settings, check_cost, describe_family, parse_stack, plan, simulate,
                            validated_warnings)


# -- generate, simulate ---------------------------------------------------------------------------------------------
def parse_families(text: str) -> tuple[str, ...]:
    """``mono,stack2,ring`` -> the families, each checked against :data:`FAMILIES`."""
    names = tuple(t.strip() for t in text.split(",") if t.strip())
    for name in names or ("",):
        if name not in FAMILIES:
            raise CommandError(f"--family {text!r}: family {name!r} does not exist; the families are "
                               f"{', '.join(FAMILIES)}")
    return names






def _settings_arguments(parser: argparse.ArgumentParser) -> None:
    d = Settings()
    g = parser.add_argument_group("solver")
    g.add_argument("--formulation", choices=["axisymmetric", "plane_strain"], default=d.formulation,
                   help="axisymmetric (sphere on a disk, default) or plane strain")
    g.add_argument("--frames", type=int, default=d.frames, help=f"recorded frames (default {d.frames})")
    g.add_argument("--frame-dt", type=float, default=d.frame_dt, help=f"ms between frames (default {d.frame_dt})")
    g.add_argument("--bulk-viscosity", type=float, default=d.bulk_viscosity,
                   help=f"linear bulk viscosity b1, 0 = off (default {d.bulk_viscosity})")
    g.add_argument("--penalty", type=float, default=d.penalty, help=f"contact penalty factor (default {d.penalty})")
    g.add_argument("--peak-stress", action="store_true",
                   help="also record stress_max: each node's largest von Mises stress between two frames (a model "
                        "trains on it with --set data.stress_field=stress_max)")


def _settings(args) -> Settings:
    return Settings(formulation=args.formulation, frames=args.frames, frame_dt=args.frame_dt,
                    bulk_viscosity=args.bulk_viscosity, penalty=args.penalty,
                    peak_stress=getattr(args, "peak_stress", False)).validate()


def configure_generate(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dataset", choices=["impact-plate"], help="which dataset to generate")
    parser.add_argument("out", help="output dataset folder (created; an interrupted run resumes in place)")
    parser.add_argument("--preset", choices=sorted(RANGES), default="small",
                        help="paper: ~2,200 nodes as the paper; small: ~400-600 nodes for CPU training")
    parser.add_argument("--train", type=int, default=2000, help="training trajectories (default 2000)")
    parser.add_argument("--valid", type=int, default=200, help="validation trajectories (default 200)")
    parser.add_argument("--test", type=int, default=200, help="test trajectories (default 200)")
    parser.add_argument("--variants", action="store_true",
                        help="also write test_thicker, test_higher, test_thicker_higher (generalization splits)")
    parser.add_argument("--variant-count", type=int, default=50, help="trajectories per variant split (default 50)")
    parser.add_argument("--seed", type=int, default=0, help="dataset seed (default 0)")
    parser.add_argument("--edge-fraction", type=float, default=0.0,
                        help="share of training designs drawn at the ranges' edges where models fail first: thin "
                             "plates (lowest fifth of the thickness range) or high drops (top fifth); default 0")
    parser.add_argument("--workers", type=int, default=1, help="worker processes (default 1)")
    parser.add_argument("--family", default="mono", metavar="F[,F...]",
                        help="design families, taking each split's trajectories in turn: "
                             + "; ".join(f"{k}: {describe_family(k)}" for k in FAMILIES) + " (default mono)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--force", action="store_true",
                        help=f"generate even when a trajectory is estimated to take over {MAX_ESTIMATED_SECONDS:.0f} s")
    _settings_arguments(parser)


def main_generate(args) -> int:
    counts = dict(train=args.train, valid=args.valid, test=args.test)
    if args.variants:
        counts.update({v: args.variant_count for v in VARIANTS})
    total = sum(max(int(v), 0) for v in counts.values())
    families = parse_families(args.family)
    if total:
        _, cost = generation_cost(args.preset, families, _settings(args))
        print(f"{plural(total, 'trajectory', 'trajectories')} of about {cost['num_nodes']} nodes and {cost['substeps']} substeps each: about "
              f"{cost['estimated_s']:.1f} s per trajectory on one core, {total * cost['estimated_s'] / 60:.1f} "
              f"core-minutes in all (finished trajectories are reused on a rerun)", flush=True)
    result = generate_dataset(args.out, preset=args.preset, counts=counts, seed=args.seed, workers=args.workers,
                              settings=_settings(args), progress=not args.no_progress,
                              edge_fraction=args.edge_fraction, families=families, force=args.force)
    print(f"{args.out}: simulated {plural(result['simulated'], 'trajectory', 'trajectories')}, reused "
          f"{result['skipped']}; splits: "
          + ", ".join(f"{k} ({counts[k]})" for k in result["splits"]))
    return 0


_DESIGN_HELP = {"layer2_thickness": "mm, a bonded layer under the top one (0: none; default material the polymer film)",
                "support_radius": "mm, a simply supported ring under the panel, rim free (0: clamped rim)",
                "backing_thickness": "mm, a bonded soft backing under the panel, bottom fixed, rim free (0: none)",
                "backing_modulus": "MPa, the backing's Young's modulus",
                "pen_tip_radius": "mm, a pen's hemispherical tip instead of the ball (0: the ball)",
                "pen_mass": "g, the pen's rigid rod","thickness": "plate thickness (mm)", "drop_height": "drop height H (mm), v0 = sqrt(2 g H)",
                "plate_density": "g/mm^3", "plate_modulus": "Young's modulus (MPa)", "plate_poisson": "",
                "ball_radius": "mm", "ball_density": "g/mm^3", "ball_modulus": "MPa", "ball_poisson": "",
                "mesh_size": "element size (mm)", "plate_half_length": "plate radius / half width (mm)",
                "gap": f"initial gap (mm), < contact radius {CONTACT_RADIUS}"}


def configure_simulate(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--preset", choices=sorted(RANGES), default="paper",
                        help="defaults for unspecified parameters: the middle of the preset's ranges (default paper)")
    parser.add_argument("--family", default="mono",
                        help=f"defaults from this family's ranges instead: one of {', '.join(FAMILIES)} (default mono)")
    parser.add_argument("--stack", default=None, metavar="SPEC",
                        help="the panel's bonded layers from the top, MATERIAL:THICKNESS[:density=..][:modulus=..]"
                             f"[:poisson=..] separated by commas, 1-4 layers, MATERIAL one of {', '.join(MATERIALS)}"
                             " (e.g. glass:0.55,adhesive:0.05,film:0.2); sets thickness, plate_* and layer2-4_*")
    for f in fields(Design):
        parser.add_argument("--" + f.name.replace("_", "-"), type=float, default=None,
                            help=_DESIGN_HELP.get(f.name) or f"{DESIGN_UNITS[f.name]}")
    parser.add_argument("--out", default=None, help="write the trajectory to FILE.h5 (meta.json beside it)")
    parser.add_argument("--force", action="store_true",
                        help=f"solve even when the estimated time exceeds {MAX_ESTIMATED_SECONDS:.0f} s")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    _settings_arguments(parser)


def peak_line(f: dict, frame_dt: float) -> str:
    """The simulated design's peak von Mises stress, plate and ball apart (:mod:`hcmt.inference.quantities`)."""
    plate = quantities.plate_mask(f["cells"], f["node_type"])
    parts = []
    for body, mask in (("plate", plate), ("ball", ~plate)):
        value, t, node = quantities.peak(f["stress"], mask)
        r, y = f["world_pos"][t, node]
        parts.append(f"peak {body} stress {value:.1f} MPa at r,y = {r:.2f},{y:.2f} mm, {t * frame_dt:.3f} ms")
    deflection = quantities.max_deflection(f["world_pos"], f["mesh_pos"], plate)
    return "; ".join(parts) + f"; max plate deflection {deflection:.4f} mm"


def main_simulate(args) -> int:
    given = {f.name: getattr(args, f.name) for f in fields(Design) if getattr(args, f.name) is not None}
    stack = parse_stack(args.stack) if args.stack is not None else {}
    both = sorted(set(stack) & set(given))
    if both:
        raise CommandError(f"--stack sets {', '.join(both)}; do not give --{both[0].replace('_', '-')} too")
    family = parse_families(args.family)
    if len(family) != 1:
        raise CommandError(f"--family {args.family!r}: name one family for one design")
    design = Design(**{**asdict(preset_design(args.preset, family[0])), **stack, **given}).validate()
    settings = _settings(args)
    if args.out is not None and Path(args.out).suffix != ".h5":
        raise CommandError(f"--out must name an .h5 file, got {args.out}")
    for w in validated_warnings(design):
        print(f"hcmt simulate: warning: {w}", file=sys.stderr)
    cost = plan(design, settings)
    print(f"{cost['num_nodes']} nodes, {cost['num_cells']} triangles, {cost['substeps']} substeps of "
          f"{cost['dt']:.3e} ms: estimated {cost['estimated_s']:.1f} s on one core", flush=True)
    check_cost(cost["estimated_s"], cost["num_nodes"], design, args.force, what=f" ({cost['substeps']} substeps)")
    bar = tqdm(total=settings.frames, desc="simulate", unit="frame",
               disable=args.no_progress or cost["estimated_s"] < 5.0)
    result = simulate(design, settings, progress=lambda k: bar.update(1))
    bar.close()
    info, f = result["info"], result["fields"]
    print(f"simulated {settings.frames} frames ({(settings.frames - 1) * settings.frame_dt:.3f} ms) of "
          f"{info['num_nodes']} nodes / {info['num_cells']} triangles in {info['substeps']} substeps "
          f"(dt {info['dt']:.3e} ms): wall-clock {info['wall_time']:.2f} s "
          f"({1e3 * info['wall_time'] / (settings.frames - 1):.1f} ms per frame)")
    print(peak_line(f, settings.frame_dt))
    if args.out:
        path = Path(args.out)
        meta = dataset_meta(args.preset, 0, {path.stem: 1}, settings)
        write_split(path, meta, [(trajectory_name(0), f, result["attrs"])])
        if not (path.parent / "meta.json").exists():
            write_meta(path.parent, meta)
        print(f"wrote {path}")
    sys.stdout.flush()
    return 0



# -- convert, info, hierarchy --------------------------------------------------------------------------------------
def configure_convert(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("src", help="TFRecord dataset folder (meta.json + <split>.tfrecord) or GGNS pickle(s)")
    parser.add_argument("out", help="output folder for the native dataset (meta.json + <split>.h5)")

def main_convert(args: argparse.Namespace) -> int:
    check_apart({"OUT": args.out}, {"SRC": args.src}, owned=("OUT",))
    meta = convert(args.src, args.out)
    print(f"converted {args.src} -> {args.out}")
    print(summarize(args.out))
    return 0 if meta else 1



def configure_info(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dataset", help="native dataset folder (meta.json + <split>.h5)")

def main_info(args: argparse.Namespace) -> int:
    print(summarize(args.dataset))
    return 0



def configure_hierarchy(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dataset", metavar="DATASET", help="native dataset folder (meta.json + <split>.h5)")
    parser.add_argument("--levels", type=int, required=True, help="number of pooled levels lambda (paper: 6 for "
                        "Impact Plate, 2 Deforming Plate, 4 Sphere Simple, 1 Deformable Plate)")
    parser.add_argument("--json", metavar="FILE", help="also write the table as JSON: one object per level 0..L")
    parser.add_argument("--split", default="train", help="split to read (default: train)")
    parser.add_argument("--trajectories", type=int, default=0, metavar="N",
                        help="use the first N trajectories (default 0: all)")
    parser.add_argument("--no-cache", action="store_true", help="do not read or write DATASET/.cache/hierarchy")



def main_hierarchy(args: argparse.Namespace) -> int:
    check_apart({"--json": args.json}, {"DATASET": args.dataset})
    count, rows = dataset_quality(args.dataset, args.split, args.levels, trajectories=args.trajectories,
                                  cache=not args.no_cache)
    print(f"{args.dataset} [{args.split}]: {plural(count, 'trajectory', 'trajectories')}, {args.levels} levels")
    print(format_table(rows))
    if args.json:
        clean = [{k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in r.items()} for r in rows]
        with atomic_path(Path(args.json)) as tmp:
            tmp.write_text(json.dumps(clean, indent=2) + "\n")
    return 0
