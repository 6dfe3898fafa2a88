"""``hcmt generate impact-plate`` and ``hcmt simulate``: write a native Impact Plate dataset, or time one design.

Dataset writing is parallel and resumable:

* trajectory ``i`` of split ``s`` draws its design from ``SeedSequence([seed, code(s), i])``, so the output is
  identical whatever the worker count or order;
* each finished trajectory is written atomically to ``OUT/.parts/<split>/<i>.h5``; a rerun skips existing parts;
* when a split is complete its parts are assembled atomically into ``OUT/<split>.h5`` and then removed; an
  interruption at any point leaves either complete files or nothing (never a half-written file).
"""
from __future__ import annotations

import argparse
import multiprocessing as mp
import shutil
import signal
import sys
from dataclasses import asdict, fields
from pathlib import Path

import h5py
import numpy as np
from tqdm import tqdm

from hcmt.config import plural
from hcmt.data.errors import DatasetError
from hcmt.data.format import make_meta, read_meta, write_meta, write_split
from hcmt.sim.scene import (CONTACT_RADIUS, DESIGN_UNITS, FAMILIES, MATERIALS as _MATERIALS, MAX_ESTIMATED_SECONDS, RANGES, RELATIVE, UNITS,
                            VARIANTS, Design, Settings, describe_family, family_ranges, feature_spec, parse_stack, plan, sample_design,
                            simulate, validated_warnings)

#: Split names and their stable codes in the per-trajectory seed.
SPLITS = ("train", "valid", "test", "test_thicker", "test_higher", "test_thicker_higher")


def trajectory_rng(seed: int, split: str, index: int) -> np.random.Generator:
    """The generator of trajectory ``index`` of ``split``: independent of worker count and order."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), SPLITS.index(split), int(index)]))


def trajectory_name(index: int) -> str:
    return f"traj_{index:05d}"


def trajectory_family(meta: dict, index: int) -> str:
    """The family of trajectory ``index`` of a generated dataset: its families in turn (``i mod n``)."""
    families = (meta.get("generator") or {}).get("families") or ["mono"]
    return families[index % len(families)]


def dataset_meta(preset: str, seed: int, counts: dict[str, int], settings: Settings, edge_fraction: float = 0.0,
                 families: tuple[str, ...] = ("mono",)) -> dict:
    extra = {"edge_fraction": float(edge_fraction)} if edge_fraction else {}  # absent: datasets made before it
    if tuple(families) != ("mono",):  # absent: one family, the first scene (datasets made before families)
        extra.update(families=list(families),
                     family_ranges={f: {k: list(v) for k, v in FAMILIES[f].items()} for f in families})
    generator = dict(name="hcmt impact-plate", preset=preset, seed=int(seed), counts=dict(counts), **extra,
                     settings=asdict(settings), ranges={k: list(v) for k, v in RANGES[preset].items()},
                     variants={k: {p: list(r) for p, r in v.items()} for k, v in VARIANTS.items()},
                     contact_radius=CONTACT_RADIUS)
    return make_meta(feature_spec(settings), trajectory_length=settings.frames, dimension=2, dt=settings.frame_dt,
                     units=UNITS, generator=generator, dataset="impact_plate")


def _run_one(task: tuple) -> tuple[str, int, float]:
    """Worker: simulate one trajectory and write its part file atomically (spawn-safe, top level)."""
    out, meta, preset, seed, split, index, settings = task
    variant = split if split in VARIANTS else None
    edges = float(meta["generator"].get("edge_fraction", 0.0)) if split == "train" else 0.0
    design = sample_design(trajectory_rng(seed, split, index), preset, variant, edges,
                           family=trajectory_family(meta, index))
    result = simulate(design, Settings(**settings))
    part = Path(out) / ".parts" / split / f"{index:05d}.h5"
    part.parent.mkdir(parents=True, exist_ok=True)
    write_split(part, meta, [(trajectory_name(index), result["fields"], result["attrs"])])
    return split, index, result["info"]["wall_time"]


def _ignore_sigint() -> None:
    """Pool workers leave Ctrl-C to the parent, which stops the pool and says what was kept."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _split_complete(path: Path, count: int) -> bool:
    if not path.is_file():
        return False
    try:
        with h5py.File(path, "r") as f:
            return int(f.attrs.get("num_trajectories", -1)) == count and len(f.keys()) == count
    except OSError:
        return False


def _existing(path: Path) -> int:
    """Trajectories of a complete split file (0 when missing or unreadable)."""
    if not path.is_file():
        return 0
    try:
        with h5py.File(path, "r") as f:
            n = int(f.attrs.get("num_trajectories", -1))
            return n if n == len(f.keys()) else 0
    except OSError:
        return 0


def _assemble(out: Path, meta: dict, split: str, count: int) -> Path:
    """Write ``OUT/<split>.h5`` from its parts and, when the dataset grows, the trajectories already in the old
    split file (atomically), then remove the parts."""
    parts = out / ".parts" / split
    old = out / f"{split}.h5"
    have = _existing(old)

    def trajectories():
        for i in range(count):  # one trajectory in memory at a time
            src = parts / f"{i:05d}.h5"
            with h5py.File(src if src.is_file() or i >= have else old, "r") as f:
                g = f[trajectory_name(i)]
                yield trajectory_name(i), {k: g[k][()] for k in g.keys()}, dict(g.attrs)

    path = write_split(old, meta, trajectories())
    shutil.rmtree(parts, ignore_errors=True)
    return path


def _differences(old: dict, new: dict, prefix: str = "") -> str:
    """``seed 1 there, 2 asked; settings.frames 90 there, 52 asked``: what differs between two generator blocks."""
    out = []
    for k in sorted(set(old) | set(new)):
        a, b = old.get(k), new.get(k)
        if isinstance(a, dict) and isinstance(b, dict):
            inner = _differences(a, b, f"{prefix}{k}.")
            out += [inner] if inner else []
        elif a != b:
            out.append(f"{prefix}{k} {a} there, {b} asked")
    return "; ".join(out)


def generate_dataset(out, *, preset: str = "small", counts: dict[str, int], seed: int = 0, workers: int = 1,
                     settings: Settings = Settings(), progress: bool = True, edge_fraction: float = 0.0,
                     families: tuple[str, ...] = ("mono",)) -> dict:
    """Generate (or finish) an Impact Plate dataset in ``out``. ``counts`` maps split names (of :data:`SPLITS`) to
    trajectory counts; ``edge_fraction`` of the training designs are drawn at the ranges' edges (thin plates, high
    drops: :data:`hcmt.sim.scene.EDGES`); ``families`` (:data:`hcmt.sim.scene.FAMILIES`) take the trajectories of
    every split in turn, and meta.json's ``families`` lists each trajectory's. Returns ``{"simulated": n,
    "skipped": n, "splits": {split: path}}``."""
    families = tuple(families)
    if not families:
        raise ValueError(f"family: give at least one of {', '.join(FAMILIES)}")
    for f in families:
        if f not in FAMILIES:
            raise ValueError(f"family {f!r} does not exist; the families are {', '.join(FAMILIES)}")
    if len(set(families)) < len(families):
        raise ValueError(f"family: {', '.join(families)} names a family twice; name each once")
    if not 0.0 <= float(edge_fraction) <= 1.0:
        raise ValueError(f"--edge-fraction must be in [0, 1], got {edge_fraction}")
    if preset not in RANGES:
        raise ValueError(f"unknown preset {preset!r}; expected one of {sorted(RANGES)}")
    for split, n in counts.items():
        if split not in SPLITS:
            raise ValueError(f"unknown split {split!r}; expected one of {SPLITS}")
        if int(n) < 0:
            raise ValueError(f"--{split} must be >= 0 trajectories, got {n}")
    if int(workers) < 1:
        raise ValueError(f"--workers must be >= 1, got {workers}")
    settings.validate()
    counts = {k: int(v) for k, v in counts.items() if int(v) > 0}
    if not counts:
        raise ValueError("nothing to generate: every trajectory count (--train, --valid, --test) is 0")
    out = Path(out)
    meta = dataset_meta(preset, seed, counts, settings, edge_fraction, families)
    meta["families"] = {split: [trajectory_family(meta, i) for i in range(n)] for split, n in counts.items()}
    if (out / "meta.json").is_file():
        old = read_meta(out)
        old_gen, new_gen = dict(old.get("generator") or {}), dict(meta["generator"])
        old_counts, _ = old_gen.pop("counts", {}), new_gen.pop("counts")
        if old_gen != new_gen:
            raise DatasetError(f"holds a dataset generated with other settings ({_differences(old_gen, new_gen)}); "
                               "rerun with the dataset's own settings or choose another output folder",
                               file=out / "meta.json")
        fewer = {k: v for k, v in old_counts.items() if counts.get(k, 0) < v}
        if fewer:
            k, v = next(iter(fewer.items()))
            raise DatasetError(f"holds {v} {k} trajectories; asking for {counts.get(k, 0)} would drop some. A dataset "
                               "only grows (trajectory i of a split depends on seed, split and i alone): ask for at "
                               "least as many, or choose another output folder", file=out / "meta.json")
    out.mkdir(parents=True, exist_ok=True)
    write_meta(out, meta)

    todo, done_splits, skipped = [], {}, 0
    for split, n in counts.items():
        if _split_complete(out / f"{split}.h5", n):
            done_splits[split] = out / f"{split}.h5"
            shutil.rmtree(out / ".parts" / split, ignore_errors=True)
            skipped += n
            continue
        have = _existing(out / f"{split}.h5")  # a smaller complete split file: the dataset is growing
        for i in range(n):
            if i < have or (out / ".parts" / split / f"{i:05d}.h5").is_file():
                skipped += 1
            else:
                todo.append((str(out), meta, preset, int(seed), split, i, asdict(settings)))

    bar = tqdm(total=len(todo), desc=f"impact-plate {preset}", unit="traj", disable=not progress or not todo)
    if workers == 1 or len(todo) <= 1:
        for task in todo:
            _run_one(task)
            bar.update(1)
    else:
        with mp.get_context("spawn").Pool(min(int(workers), len(todo)), initializer=_ignore_sigint) as pool:
            for _ in pool.imap_unordered(_run_one, todo):
                bar.update(1)
    bar.close()
    for split, n in counts.items():
        if split not in done_splits:
            done_splits[split] = _assemble(out, meta, split, n)
    parts = out / ".parts"
    if parts.is_dir() and not any(parts.iterdir()):
        parts.rmdir()
    return dict(simulated=len(todo), skipped=skipped, splits=done_splits)


# ---------------------------------------------------------------------------------------------------- commands

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
    _settings_arguments(parser)


def main_generate(args) -> int:
    counts = dict(train=args.train, valid=args.valid, test=args.test)
    if args.variants:
        counts.update({v: args.variant_count for v in VARIANTS})
    total = sum(max(int(v), 0) for v in counts.values())
    families = parse_families(args.family)
    if total:
        cost = max((plan(preset_design(args.preset, f), _settings(args)) for f in families),
                   key=lambda c: c["estimated_s"])
        print(f"{plural(total, 'trajectory', 'trajectories')} of about {cost['num_nodes']} nodes and {cost['substeps']} substeps each: about "
              f"{cost['estimated_s']:.1f} s per trajectory on one core, {total * cost['estimated_s'] / 60:.1f} "
              f"core-minutes in all (finished trajectories are reused on a rerun)", flush=True)
    result = generate_dataset(args.out, preset=args.preset, counts=counts, seed=args.seed, workers=args.workers,
                              settings=_settings(args), progress=not args.no_progress,
                              edge_fraction=args.edge_fraction, families=families)
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


def preset_design(preset: str, family: str = "mono") -> Design:
    """The nominal design of a preset and family: the middle of every sampling range (:func:`family_ranges`)."""
    values = {k: 0.5 * (lo + hi) for k, (lo, hi) in family_ranges(preset, family).items()}
    for key, of in RELATIVE.items():
        if key in values:
            values[key] *= values[of]
    return Design(**values)


def parse_families(text: str) -> tuple[str, ...]:
    """``mono,stack2,ring`` -> the families, each checked against :data:`FAMILIES`."""
    names = tuple(t.strip() for t in text.split(",") if t.strip())
    for name in names or ("",):
        if name not in FAMILIES:
            raise ValueError(f"--family {text!r}: family {name!r} does not exist; the families are "
                             f"{', '.join(FAMILIES)}")
    return names


def configure_simulate(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--preset", choices=sorted(RANGES), default="paper",
                        help="defaults for unspecified parameters: the middle of the preset's ranges (default paper)")
    parser.add_argument("--family", default="mono",
                        help=f"defaults from this family's ranges instead: one of {', '.join(FAMILIES)} (default mono)")
    parser.add_argument("--stack", default=None, metavar="SPEC",
                        help="the panel's bonded layers from the top, MATERIAL:THICKNESS[:density=..][:modulus=..]"
                             f"[:poisson=..] separated by commas, 1-4 layers, MATERIAL one of {', '.join(_MATERIALS)}"
                             " (e.g. glass:0.55,adhesive:0.05,film:0.2); sets thickness, plate_* and layer2-4_*")
    for f in fields(Design):
        parser.add_argument("--" + f.name.replace("_", "-"), type=float, default=None,
                            help=_DESIGN_HELP.get(f.name) or f"{DESIGN_UNITS[f.name]}")
    parser.add_argument("--out", default=None, help="write the trajectory to FILE.h5 (meta.json beside it)")
    parser.add_argument("--force", action="store_true",
                        help=f"solve even when the estimated time exceeds {MAX_ESTIMATED_SECONDS:.0f} s")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    _settings_arguments(parser)


def main_simulate(args) -> int:
    given = {f.name: getattr(args, f.name) for f in fields(Design) if getattr(args, f.name) is not None}
    stack = parse_stack(args.stack) if args.stack is not None else {}
    both = sorted(set(stack) & set(given))
    if both:
        raise ValueError(f"--stack sets {', '.join(both)}; do not give --{both[0].replace('_', '-')} too")
    family = parse_families(args.family)
    if len(family) != 1:
        raise ValueError(f"--family {args.family!r}: name one family for one design")
    design = Design(**{**asdict(preset_design(args.preset, family[0])), **stack, **given}).validate()
    settings = _settings(args)
    if args.out is not None and Path(args.out).suffix != ".h5":
        raise ValueError(f"--out must name an .h5 file, got {args.out}")
    for w in validated_warnings(design):
        print(f"hcmt simulate: warning: {w}", file=sys.stderr)
    cost = plan(design, settings)
    print(f"{cost['num_nodes']} nodes, {cost['num_cells']} triangles, {cost['substeps']} substeps of "
          f"{cost['dt']:.3e} ms: estimated {cost['estimated_s']:.1f} s on one core", flush=True)
    if cost["estimated_s"] > MAX_ESTIMATED_SECONDS and not args.force:
        raise ValueError(f"estimated {cost['estimated_s']:.0f} s exceeds {MAX_ESTIMATED_SECONDS:.0f} s "
                         f"({cost['num_nodes']} nodes x {cost['substeps']} substeps; mesh_size {design.mesh_size} mm, "
                         f"plate_poisson {design.plate_poisson}); coarsen the mesh or pass --force")
    bar = tqdm(total=settings.frames, desc="simulate", unit="frame",
               disable=args.no_progress or cost["estimated_s"] < 5.0)
    result = simulate(design, settings, progress=lambda k: bar.update(1))
    bar.close()
    info, f = result["info"], result["fields"]
    print(f"simulated {settings.frames} frames ({(settings.frames - 1) * settings.frame_dt:.3f} ms) of "
          f"{info['num_nodes']} nodes / {info['num_cells']} triangles in {info['substeps']} substeps "
          f"(dt {info['dt']:.3e} ms): wall-clock {info['wall_time']:.2f} s "
          f"({1e3 * info['wall_time'] / (settings.frames - 1):.1f} ms per frame); "
          f"peak von Mises {float(f['stress'].max()):.1f} MPa")
    if args.out:
        path = Path(args.out)
        meta = dataset_meta(args.preset, 0, {path.stem: 1}, settings)
        write_split(path, meta, [(trajectory_name(0), f, result["attrs"])])
        if not (path.parent / "meta.json").exists():
            write_meta(path.parent, meta)
        print(f"wrote {path}")
    sys.stdout.flush()
    return 0
