"""How far below the true stress peak does a dataset's RECORDED peak fall at each frame interval?

A dataset records frames every ``frame_dt`` ms (0.002, 0.004, 0.008 in the frame-interval study) while the solver
takes ``n`` substeps per 0.002 ms frame, so a coarse interval samples the impact's short stress peak coarsely. For
every design of a split (default: the test split of the study's 0.002 ms dataset), one solver run records EVERY
substep: ``Settings(frames=88 n + 1, frame_dt=0.002 / n)`` with ``n`` the substeps the dataset's solve took per
0.002 ms frame, so the substep is the dataset's own and frames ``k n``, ``k 2n``, ``k 4n`` are exactly the
0.002 / 0.004 / 0.008 ms grids of the 0.176 ms window.

* true peak: max over every substep and the body's nodes of the nodal von Mises stress (MPa), and its time;
* recorded peak at each interval: the same max over that interval's grid only; shortfall = (true - recorded) / true;
* the same for the ball (body 1) as for the plate (body 0);
* ``phases``: the shortfall of a grid shifted by every possible offset (not only the one starting at t = 0), its
  mean and worst over the offsets: what the interval costs independently of where the peak happens to fall;
* agreement: the fine run's 0.002 ms grid against the dataset's recorded stress for that design (peak and every
  value), and, where the study's 0.004 / 0.008 ms datasets lie beside it (``--compare``), their recorded plate
  peak against the fine run's grid at their interval (their solve chose its own substep, so expect small
  differences there).

    PYTHONPATH=src python benchmarks/interval/peak_sampling.py [--data DIR] [--split test] [--limit N]
        # writes benchmarks/results/peak_sampling.json
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # one thread (set before numpy loads)
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import re  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from dataclasses import asdict, fields  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from hcmt.data.format import open_split, read_meta  # noqa: E402
from hcmt.sim.cost import plan  # noqa: E402
from hcmt.sim.driver import simulate  # noqa: E402
from hcmt.sim.params import Design, Settings  # noqa: E402
from hcmt.sim.scene import design_mesh  # noqa: E402

#: the 0.002 ms dataset of the frame-interval study (interval/run.py --work $HCMT_WORK/interval)
DATA = os.path.join(os.environ.get("HCMT_WORK") or "benchmarks/work", "interval", "impact_plate_small_40_89_dt0.002")
OUT = Path(__file__).resolve().parent.parent / "results" / "peak_sampling.json"
BASE_DT = 0.002  # ms, the finest recorded interval
FACTORS = {0.002: 1, 0.004: 2, 0.008: 4}  # interval (ms) -> multiple of BASE_DT
BODIES = {"plate": 0, "ball": 1}
DESIGN_KEYS = {f.name for f in fields(Design)}


def _portable(obj):
    """``obj`` with the work folder as ``$HCMT_WORK`` and the checkout as relative paths (benchmarks/common.py;
    imported here, when the result is written, as common loads the training stack)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
    from common import portable

    return portable(obj)


def write_json(path: Path, obj) -> None:
    """Write atomically: a temporary file beside ``path``, then ``os.replace``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as f:
            json.dump(obj, f, indent=1)
            f.write("\n")
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def shortfall(true: float, recorded: float) -> float:
    """(true - recorded) / true in %."""
    return float(100.0 * (true - recorded) / true)


def sibling_datasets(data: Path) -> list[Path]:
    """The study's datasets at the coarser intervals beside ``data`` (``..._40_45_dt0.004``, ``..._40_23_dt0.008``)."""
    m = re.fullmatch(r"(.*)_(\d+)_dt([0-9.]+)", data.name)
    if not m:
        return []
    out = []
    for dt, k in FACTORS.items():
        if k > 1:
            p = data.parent / f"{m.group(1)}_{88 // k + 1}_dt{dt:g}"
            if (p / "meta.json").is_file():
                out.append(p)
    return out


def body_curves(stress: np.ndarray, body: np.ndarray) -> dict[str, np.ndarray]:
    """Per body, the max over its nodes at every recorded frame [T]."""
    return {name: stress[:, body == b].max(1) for name, b in BODIES.items()}


def one_design(design: Design, settings: Settings, recorded: dict, compare: dict[float, dict]) -> dict:
    """Fine solve of one design; recorded vs true peaks per body and interval; the agreement checks."""
    frames0 = settings.frames  # the dataset's 0.002 ms frames (89)
    window = frames0 - 1
    per_frame = plan(design, settings)["substeps"] // window  # n: the dataset's substeps per 0.002 ms frame
    fine = Settings(**{**asdict(settings), "frames": window * per_frame + 1, "frame_dt": settings.frame_dt / per_frame})
    assert plan(design, fine)["substeps"] == window * per_frame, "the fine run must take one substep per frame"
    mesh = design_mesh(design)
    result = simulate(design, fine)
    f, info = result.fields, result.info
    if not np.array_equal(f["mesh_pos"], recorded["mesh_pos"]):
        raise RuntimeError("the design's mesh differs from the dataset's: not the same design")
    stress = f["stress"][..., 0]  # [T_fine, N]
    t = np.arange(len(stress)) * fine.frame_dt
    curves = body_curves(stress, mesh["body"])
    row = {
        "substeps_per_frame": per_frame,
        "substep_dt_ms": info.dt,
        "num_nodes": info.num_nodes,
        "wall_s": round(info.wall_time, 2),
    }
    for name, c in curves.items():
        k = int(c.argmax())
        r = {"true_peak_mpa": float(c[k]), "true_peak_time_ms": float(t[k]), "true_peak_substep": k, "intervals": {}}
        for dt, m in FACTORS.items():
            step = m * per_frame  # substeps between recorded frames at this interval
            grid = c[::step]
            j = int(grid.argmax())
            # every offset of the grid: the frames o, o + step, ... inside the window
            phase = np.array([shortfall(c[k], c[o::step].max()) for o in range(step)])
            r["intervals"][f"{dt:g}"] = {
                "recorded_peak_mpa": float(grid[j]),
                "recorded_peak_time_ms": float(t[j * step]),
                "shortfall_pct": shortfall(c[k], grid[j]),
                "phases": {"mean_shortfall_pct": float(phase.mean()), "worst_shortfall_pct": float(phase.max())},
            }
        row[name] = r

    # the fine run's 0.002 ms grid against the dataset's own recorded stress (same substep: should agree closely)
    mine = stress[::per_frame]
    theirs = recorded["stress"][..., 0]
    ref = body_curves(theirs, mesh["body"])
    grid = body_curves(mine, mesh["body"])
    row["agreement_0.002"] = {
        **{
            f"{name}_peak_diff_pct": float(100 * abs(grid[name].max() - ref[name].max()) / ref[name].max())
            for name in BODIES
        },
        "max_abs_stress_diff_mpa": float(np.abs(mine - theirs).max()),
        "max_abs_position_diff_mm": float(np.abs(f["world_pos"][::per_frame] - recorded["world_pos"]).max()),
    }
    # the study's coarser datasets: their solve has its own substep (ceil(frame_dt / stable dt) per frame)
    for dt, other in compare.items():
        m = FACTORS[dt]
        other_curve = body_curves(other["stress"][..., 0], mesh["body"])
        row[f"agreement_{dt:g}"] = {
            "substeps_per_frame": other["substeps_per_frame"],
            **{f"{name}_recorded_peak_mpa": float(other_curve[name].max()) for name in BODIES},
            **{
                f"{name}_peak_diff_pct": float(
                    100 * abs(curves[name][:: m * per_frame].max() - other_curve[name].max()) / other_curve[name].max()
                )
                for name in BODIES
            },
        }
    return row


def summarise(rows: list[dict]) -> dict:
    out = {}
    for name in BODIES:
        out[name] = {}
        for dt in FACTORS:
            s = np.array([r[name]["intervals"][f"{dt:g}"]["shortfall_pct"] for r in rows])
            pm = np.array([r[name]["intervals"][f"{dt:g}"]["phases"]["mean_shortfall_pct"] for r in rows])
            pw = np.array([r[name]["intervals"][f"{dt:g}"]["phases"]["worst_shortfall_pct"] for r in rows])
            out[name][f"{dt:g}"] = {
                "median_shortfall_pct": float(np.median(s)),
                "worst_shortfall_pct": float(s.max()),
                "mean_shortfall_pct": float(s.mean()),
                "phases_mean_shortfall_pct": float(pm.mean()),
                "phases_worst_shortfall_pct": float(pw.max()),
            }
    agree = {}
    for key in sorted({k for r in rows for k in r if k.startswith("agreement_")}):
        have = [r[key] for r in rows if key in r]
        agree[key] = {
            k: float(max(h[k] for h in have))
            for k in have[0]
            if k.endswith(("_pct", "_mpa", "_mm")) and not k.endswith("recorded_peak_mpa")
        }
    out["agreement_max"] = agree
    n = [r["substeps_per_frame"] for r in rows]
    out["substeps_per_frame"] = {"min": int(min(n)), "median": float(np.median(n)), "max": int(max(n))}
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--data", default=DATA, help=f"dataset folder recorded at 0.002 ms (default {DATA})")
    p.add_argument("--split", default="test", help="split whose designs are solved (default test)")
    p.add_argument("--limit", type=int, default=None, help="only the first N designs")
    p.add_argument(
        "--compare",
        nargs="*",
        default=None,
        help="datasets of the same designs at coarser intervals to check (default: the study's "
        "..._dt0.004 / ..._dt0.008 folders beside --data, where present)",
    )
    p.add_argument("--out", default=str(OUT), help=f"result JSON (default {OUT})")
    args = p.parse_args(argv)

    start = time.perf_counter()
    data = Path(args.data)
    meta = read_meta(data)
    gen = meta["generator"]
    settings = Settings(**gen["settings"]).validate()
    if abs(settings.frame_dt - BASE_DT) > 1e-12 or settings.frames != 89:
        raise SystemExit(
            f"--data must be recorded at {BASE_DT} ms over 89 frames, got {settings.frame_dt} ms x {settings.frames}"
        )
    split = open_split(data, args.split)
    count = len(split) if args.limit is None else min(args.limit, len(split))
    others = {}
    for path in sibling_datasets(data) if args.compare is None else [Path(c) for c in args.compare]:
        m = read_meta(path)
        others[float(m["dt"])] = (path, Settings(**m["generator"]["settings"]), open_split(path, args.split))

    rows = []
    for i in range(count):
        attrs = split.attrs(i)
        design = Design(**{k: v for k, v in attrs.items() if k in DESIGN_KEYS})
        compare = {}
        for dt, (path, st, sp) in others.items():
            if sp.names[i] != split.names[i] or any(sp.attrs(i)[k] != attrs[k] for k in DESIGN_KEYS):
                raise SystemExit(f"{path}: trajectory {i} is not the same design as in {data}")
            compare[dt] = {
                "stress": sp[i]["stress"],
                "substeps_per_frame": plan(design, st)["substeps"] // (st.frames - 1),
            }
        row = {
            "trajectory": split.names[i],
            "design": asdict(design),
            **one_design(design, settings, split[i], compare),
        }
        rows.append(row)
        pl, ba = row["plate"], row["ball"]
        print(
            f"{row['trajectory']}: n={row['substeps_per_frame']:3d}  plate true {pl['true_peak_mpa']:7.1f} MPa at "
            f"{pl['true_peak_time_ms']:.4f} ms, shortfall "
            + " / ".join(f"{pl['intervals'][k]['shortfall_pct']:.2f}" for k in ("0.002", "0.004", "0.008"))
            + f" %; ball true {ba['true_peak_mpa']:7.1f} MPa, shortfall "
            + " / ".join(f"{ba['intervals'][k]['shortfall_pct']:.2f}" for k in ("0.002", "0.004", "0.008"))
            + f" %; agreement {row['agreement_0.002']['plate_peak_diff_pct']:.2e} %  ({row['wall_s']} s)",
            flush=True,
        )
    summary = summarise(rows)
    result = {
        "command": "PYTHONPATH=src python benchmarks/interval/peak_sampling.py"
        + (f" --data {args.data}" if args.data != DATA else "")
        + (f" --split {args.split}" if args.split != "test" else "")
        + (f" --limit {args.limit}" if args.limit is not None else ""),
        "data": str(data),
        "split": args.split,
        "designs": count,
        "window_ms": (settings.frames - 1) * BASE_DT,
        "settings": asdict(settings),
        "intervals_ms": list(FACTORS),
        "compared": {f"{dt:g}": str(v[0]) for dt, v in others.items()},
        "summary": summary,
        "rows": rows,
        "wall_s": round(time.perf_counter() - start, 1),
    }
    write_json(Path(args.out), _portable(result))
    print(json.dumps(summary, indent=1))
    print(f"wrote {args.out} in {result['wall_s']} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
