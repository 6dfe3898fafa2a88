"""``hcmt generate / simulate / convert / info / hierarchy``: the data commands, printing only (their arguments and
first checks: :mod:`hcmt.cli.parsers`); the library functions live in :mod:`hcmt.sim.generate`,
:mod:`hcmt.sim.driver`, :mod:`hcmt.sim.cost`, :mod:`hcmt.data.convert`, :mod:`hcmt.data.info`
and :mod:`hcmt.graph.report`."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from tqdm import tqdm

from hcmt.cli import CommandError, check_outputs
from hcmt.cli.parsers import parse_families, plate_settings_of_args, range_overrides, settings_of_args, simulate_inputs
from hcmt.config import plural
from hcmt.data.convert import convert
from hcmt.data.format import read_meta, write_meta, write_split
from hcmt.data.info import summarize
from hcmt.errors import clip
from hcmt.files import atomic_path, check_apart, undo_on_error
from hcmt.graph.report import dataset_quality, format_table
from hcmt.inference import quantities
from hcmt.sim.cost import check_cost, plan, validated_warnings, window_warnings
from hcmt.sim.deforming_data import estimate_seconds, generate_deforming_plate
from hcmt.sim.driver import simulate
from hcmt.sim.generate import dataset_meta, generate_dataset, generation_cost
from hcmt.sim.sampling import VARIANTS
from hcmt.sim.writer import trajectory_name


# -- generate, simulate ---------------------------------------------------------------------------------------------
def main_generate(args) -> int:
    counts = dict(train=args.train, valid=args.valid, test=args.test)
    if args.dataset == "deforming-plate":
        return _generate_deforming(args, counts)
    if args.variants:
        counts.update({v: args.variant_count for v in VARIANTS})
    total = sum(max(int(v), 0) for v in counts.values())
    families = parse_families(args.family)
    if total:
        _, cost = generation_cost(args.preset, families, settings_of_args(args))
        print(
            f"{plural(total, 'trajectory', 'trajectories')} of about {cost['num_nodes']} nodes and "
            f"{cost['substeps']} substeps each: about "
            f"{cost['estimated_s']:.1f} s per trajectory on one core, {total * cost['estimated_s'] / 60:.1f} "
            f"core-minutes in all (finished trajectories are reused on a rerun)",
            flush=True,
        )
    result = generate_dataset(
        args.out,
        preset=args.preset,
        counts=counts,
        seed=args.seed,
        workers=args.workers,
        settings=settings_of_args(args),
        progress=not args.no_progress,
        edge_fraction=args.edge_fraction,
        families=families,
        force=args.force,
        ranges=range_overrides(args),
    )
    print(
        f"{args.out}: simulated {plural(result['simulated'], 'trajectory', 'trajectories')}, reused "
        f"{result['skipped']}; splits: " + ", ".join(f"{k} ({counts[k]})" for k in result["splits"])
    )
    return 0


def _generate_deforming(args, counts: dict[str, int]) -> int:
    settings = plate_settings_of_args(args)
    total = sum(max(int(v), 0) for v in counts.values())
    if total:
        each = estimate_seconds(settings)
        print(
            f"{plural(total, 'trajectory', 'trajectories')} of about {settings.plate_nodes} plate nodes and "
            f"{settings.frames - 1} quasi-static steps each: about {each:.0f} s per trajectory on one core, "
            f"{total * each / 60:.1f} core-minutes in all (finished trajectories are reused on a rerun)",
            flush=True,
        )
    result = generate_deforming_plate(
        args.out,
        counts=counts,
        seed=args.seed,
        workers=args.workers,
        settings=settings,
        progress=not args.no_progress,
        force=args.force,
    )
    print(
        f"{args.out}: simulated {plural(result['simulated'], 'trajectory', 'trajectories')}, reused "
        f"{result['skipped']}; splits: " + ", ".join(f"{k} ({counts[k]})" for k in result["splits"])
    )
    return 0


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


def simulate_target(out: str | None, preset: str, settings) -> dict | None:
    """Where ``hcmt simulate --out FILE.h5`` writes, checked before the solver runs: the dataset meta of the file,
    with ``write`` True when meta.json is to be written beside it. The file is a one-split dataset (FILE.h5 and
    meta.json in its folder: what ``hcmt info`` and ``load_dataset`` read), so its folder must be new, empty, or a
    dataset whose meta.json agrees with this trajectory (that meta.json is kept); a meta.json of other data (other
    frames, frame interval, fields) or a folder of other files (the working directory) is refused in one line."""
    if out is None:
        return None
    check_outputs({"--out": out})
    path = Path(out)
    meta = dataset_meta(preset, 0, {path.stem: 1}, settings)
    folder = path.parent
    if (folder / "meta.json").is_file():
        differs = _meta_differences(read_meta(folder), meta)
        if differs:
            raise CommandError(
                f"--out {out}: {folder / 'meta.json'} describes other data ({differs}); write the "
                "trajectory into a new folder, or one whose meta.json matches it"
            )
        return dict(meta=meta, write=False)
    if folder.is_dir() and any(not p.name.startswith(".") for p in folder.iterdir()):
        raise CommandError(
            f"--out {out}: {folder} holds other files and no meta.json; the trajectory is written as "
            f"a one-split dataset (FILE.h5 + meta.json): name a file in a new or empty folder, e.g. "
            f"--out {path.stem}/{path.name}"
        )
    return dict(meta=meta, write=True)


def _meta_differences(old: dict, new: dict) -> str:
    """``trajectory_length 52 there, 10 here``: what makes a trajectory of ``new`` unreadable beside ``old``'s."""
    keys = ("trajectory_length", "dimension", "dt")
    out = [f"{k} {old.get(k)} there, {new.get(k)} here" for k in keys if old.get(k) != new.get(k)]
    fields = sorted(set(old.get("features") or {}) ^ set(new["features"])) or [
        k for k in new["features"] if old["features"][k] != new["features"][k]
    ]
    if not out and fields:
        out.append(f"fields {', '.join(fields)} differ")
    old_settings = (old.get("generator") or {}).get("settings")
    if not out and old_settings is not None and old_settings != new["generator"]["settings"]:
        out.append("the solver settings differ")
    return clip("; ".join(out), 160)


def main_simulate(args) -> int:
    design, settings = simulate_inputs(args)
    target = simulate_target(args.out, args.preset, settings)
    for w in validated_warnings(design):
        print(f"hcmt simulate: warning: {w}", file=sys.stderr)
    cost = plan(design, settings)
    print(
        f"{cost['num_nodes']} nodes, {cost['num_cells']} triangles, {cost['substeps']} substeps of "
        f"{cost['dt']:.3e} ms: estimated {cost['estimated_s']:.1f} s on one core",
        flush=True,
    )
    check_cost(cost["estimated_s"], cost["num_nodes"], design, args.force, what=f" ({cost['substeps']} substeps)")
    bar = tqdm(
        total=settings.frames, desc="simulate", unit="frame", disable=args.no_progress or cost["estimated_s"] < 5.0
    )
    result = simulate(design, settings, progress=lambda k: bar.update(1))
    bar.close()
    info, f = result.info, result.fields
    print(
        f"simulated {settings.frames} frames ({(settings.frames - 1) * settings.frame_dt:.3f} ms) of "
        f"{info.num_nodes} nodes / {info.num_cells} triangles in {info.substeps} substeps "
        f"(dt {info.dt:.3e} ms): wall-clock {info.wall_time:.2f} s "
        f"({1e3 * info.wall_time / (settings.frames - 1):.1f} ms per frame)"
    )
    print(peak_line(f, settings.frame_dt))
    plate = quantities.plate_mask(f["cells"], f["node_type"])  # the ball never came, or the window cut the peak
    for w in window_warnings(
        design,
        settings,
        quantities.body_history(f["stress"], plate),
        quantities.contact_gap(f["world_pos"], f["mesh_pos"], plate),
    ):
        print(f"hcmt simulate: warning: {w}", file=sys.stderr)
    if target is not None:
        path = Path(args.out)
        with undo_on_error(path.parent if target["write"] else None):
            write_split(path, target["meta"], [(trajectory_name(0), f, result.attrs)])
            if target["write"]:
                write_meta(path.parent, target["meta"])
        print(f"wrote {path}" + (f" and {path.parent / 'meta.json'}" if target["write"] else ""))
    sys.stdout.flush()
    return 0


# -- convert, info, hierarchy --------------------------------------------------------------------------------------
def main_convert(args: argparse.Namespace) -> int:
    check_apart({"OUT": args.out}, {"SRC": args.src}, owned=("OUT",))
    meta = convert(args.src, args.out)
    print(f"converted {args.src} -> {args.out}")
    print(summarize(args.out))
    return 0 if meta else 1


def main_info(args: argparse.Namespace) -> int:
    print(summarize(args.dataset, args.all))
    return 0


def main_hierarchy(args: argparse.Namespace) -> int:
    check_apart({"--json": args.json}, {"DATASET": args.dataset})
    check_outputs({"--json": args.json})
    count, rows = dataset_quality(
        args.dataset, args.split, args.levels, trajectories=args.trajectories, cache=not args.no_cache
    )
    print(f"{args.dataset} [{args.split}]: {plural(count, 'trajectory', 'trajectories')}, {args.levels} levels")
    print(format_table(rows))
    if args.json:
        clean = [{k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in r.items()} for r in rows]
        with atomic_path(Path(args.json)) as tmp:
            tmp.write_text(json.dumps(clean, indent=2) + "\n")
    return 0
