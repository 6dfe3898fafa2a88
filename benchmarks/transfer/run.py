"""The transfer benchmark: a mesh model trained on some panel families, on a family it has not seen, against the
response surface an engineer would fit on the new family's runs.

    python benchmarks/transfer/run.py --work WORK --train-data DATA --new stack3=DATA3 --new pen=DATAP \
        [--models hcmt mgn] [--seeds 0 1] [--steps 8000] [--ft-steps 1500] [--ft-lr LR] [--shots 5 20] [--eval 8] \
        [--base NAME=RUN] [--json transfer.json]

``--base NAME=RUN`` (a run folder or ``pretrained:NAME``, e.g. the shipped model) is the base model instead of
training one per model and seed (``--models`` and ``--steps`` are then unused; ``--seeds`` seed the fine-tunings);
``--ft-lr`` is the fine-tuning's learning rate (decaying to a tenth of it; default: the config's 1e-3 to 1e-5).

The data (docs/RESULTS.md, "Panel families" has the commands): ``--train-data`` mixes the training families
(``hcmt generate impact-plate --family mono,stack2,ring``); each ``--new NAME=DATA`` is one family never trained
on, its ``train`` split the pool of runs a fine-tuning (and a response surface) may use, its ``test`` split the
designs everything is judged on. Per model and seed:

1. ``base``: trained from scratch on the training families; judged on their held-out ``test`` designs;
2. ``zero-shot``: the base model on each new family;
3. ``few-shot``: the base model fine-tuned (``hcmt train --init``, normalizers kept) on the first 5 / 20 runs of
   the new family;
4. ``surrogate``: the Gaussian-process response surface (:mod:`hcmt.design.surrogate`) fitted on the training
   families' runs (zero-shot: it cannot take a parameter its training designs held fixed, and says so) and on the
   same 5 / 20 runs of the new family.

Quantities per judged design: peak plate stress and max deflection (signed % error; median and worst of |error|),
the critical location (distance between the nodes at rest where the model's and the solver's peak plate stress
occur, mm), the stress field's RMSE-all (mesh models), rebound agreement, the solver runs each approach needed and
its seconds per design (the solver timed on the same designs, same machine, one thread).

Resumable: every run trains or resumes through :func:`hcmt.train`, every evaluation and surrogate row is a file
under WORK/rows/; several processes may share WORK (a row being made by another process is skipped). The summary
goes to benchmarks/results/transfer.json (``--report`` only summarizes what exists).
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
from common import claim, write_json  # noqa: E402
from hcmt.config import load_config  # noqa: E402
from hcmt.data.format import Split, read_meta, write_meta, write_split  # noqa: E402
from hcmt.data.runs import RunFolder  # noqa: E402
from hcmt.design.surrogate import Surrogate, dataset_answers  # noqa: E402
from hcmt.files import atomic_path  # noqa: E402
from hcmt.inference.evaluate import evaluate  # noqa: E402
from hcmt.inference.quantities import peak, plate_mask  # noqa: E402
from hcmt.inference.run import Run  # noqa: E402
from hcmt.sim.driver import simulate  # noqa: E402
from hcmt.sim.params import Settings, design_from_attrs  # noqa: E402
from hcmt.training import train  # noqa: E402

#: the shipped model's recipe (docs/MODELS.md), validation thinned for the CPU budget
RECIPE = [
    "model.attention=official",
    "train.noise_std=0.0003",
    "model.target=acceleration",
    "train.noise_nodes=predicted",
    "train.pushforward=0.5",
    "train.pushforward_start=2000",
    "model.deformation=true",
    "train.valid_every=2000",
    "train.valid_trajectories=3",
    "train.checkpoint_every=500",
]
FINE_TUNE = ["train.valid_every=500", "train.valid_trajectories=2", "train.pushforward_start=0"]


def subset(data: Path, n: int, out: Path) -> Path:
    """A dataset of the first ``n`` training runs of ``data`` (its valid split kept), written once."""
    if (out / "train.h5").is_file():
        return out
    out.mkdir(parents=True, exist_ok=True)
    meta = read_meta(data)
    with Split(data, "train", meta) as s:
        if len(s) < n:
            raise SystemExit(f"{data}: {len(s)} training runs, {n} asked")
        write_split(out / "train.h5", meta, ((s.names[i], s[i], s.attrs(i)) for i in range(n)))
    if (data / "valid.h5").is_file():
        with Split(data, "valid", meta) as s:
            write_split(out / "valid.h5", meta, ((s.names[i], s[i], s.attrs(i)) for i in range(len(s))))
    write_meta(out, meta)
    return out


def trained(
    work: Path,
    name: str,
    data: Path,
    model: str,
    seed: int,
    steps: int,
    init: Path | str | None = None,
    lr: float | None = None,
) -> Path:
    """Train (or resume, or reuse) one run folder; ``lr``: a fine-tuning's learning rate (to a tenth of it)."""
    run = work / "runs" / name
    if (run / "train_stats.json").is_file():
        return run
    overrides = RECIPE + (FINE_TUNE if init else []) + [f"train.steps={steps}"]
    overrides += [f"train.lr={lr}", f"train.lr_final={lr / 10}"] if lr is not None else []
    resume = RunFolder(run, must_exist=False).latest.is_file()
    t0 = time.perf_counter()
    train(
        load_config("impact_plate_cpu", overrides),
        data,
        model,
        run,
        seed=seed,
        resume=resume,
        progress=False,
        init=None if resume or init is None else str(init),
        init_normalizers="keep",
    )
    print(f"  trained {name} ({steps} steps) in {time.perf_counter() - t0:.0f} s", flush=True)
    return run


def critical_distance(rollout: Path, data: Path, split: str, limit: int) -> dict[str, float]:
    """Per trajectory: the distance (mm, at rest) between the model's and the solver's peak plate stress node."""
    out = {}
    with h5py.File(rollout, "r") as f, Split(data, split) as s:
        for i, name in enumerate(s.names[:limit]):
            t = s[i]
            plate = plate_mask(t["cells"], t["node_type"])
            start = int(f[name].attrs["start"])
            a = peak(f[name]["stress"][start:], plate)[2]
            b = peak(t["stress"][start:], plate)[2]
            out[name] = float(np.linalg.norm(t["mesh_pos"][a] - t["mesh_pos"][b]))
    return out


def judged(run: Path | str, data: Path, limit: int, out: Path | None = None) -> dict:
    """One mesh-model row: evaluate's physics per trajectory plus the critical location (a shipped model's
    rollouts go to ``out``)."""
    loaded = Run.load(run, "cpu")
    if str(run).startswith("pretrained:"):
        loaded = loaded.writing_to(out)
    m = evaluate(loaded, data, "test", limit=limit, progress=False)
    crit = critical_distance(loaded.folder.rollout_path("test", data), data, "test", limit)
    meta = read_meta(data)
    families = (meta.get("families") or {}).get("test") or ["mono"] * m.trajectories
    rows = []
    for i, r in enumerate(m.per_trajectory):
        p = r.physics
        rows.append(
            {
                "trajectory": r.trajectory,
                "family": families[i],
                "peak_error_pct": p.peak_plate_stress_error_pct,
                "deflection_error_pct": p.max_deflection_error_pct,
                "critical_mm": crit[r.trajectory],
                "rebound_agrees": bool(p.rebound_agrees),
                "stress_rmse_all": None if r.stress is None else r.stress.rmse_all,
                "position_rmse_all": r.position.rmse_all,
            }
        )
    steps = int(meta["trajectory_length"]) - 2
    return {
        "rows": rows,
        "s_per_design": m.inference_ms_per_step * steps / 1e3,
        "checkpoint_step": loaded.checkpoint_step,
    }


def surrogate_row(fit_data: Path, n: int | None, data: Path, limit: int) -> dict:
    """A response-surface row: fitted on the first ``n`` training runs of ``fit_data``, judged on ``data``'s
    test designs; a design with a parameter the fit held fixed is not predicted (``cannot_take``)."""
    designs, answers = dataset_answers(fit_data, "train", limit=n)
    t0 = time.perf_counter()
    gp = Surrogate.fit(designs, answers, source=str(fit_data), strict=False)
    fit_s = time.perf_counter() - t0
    tests, truth = dataset_answers(data, "test", limit=limit)
    meta = read_meta(data)
    families = (meta.get("families") or {}).get("test") or ["mono"] * len(tests)
    rows, cannot = [], {}
    t0 = time.perf_counter()
    preds = gp.predict(tests)
    predict_s = (time.perf_counter() - t0) / max(len(tests), 1)
    for i, (d, p) in enumerate(zip(tests, preds)):
        missing = gp.cannot_take(d)
        if missing:
            cannot.update({k: d.__getattribute__(k) for k in missing})
            continue
        rows.append(
            {
                "trajectory": i,
                "family": families[i],
                "peak_error_pct": 100 * (p["peak_plate_stress_mpa"].mean / truth["peak_plate_stress_mpa"][i] - 1),
                "deflection_error_pct": 100 * (p["max_deflection_mm"].mean / truth["max_deflection_mm"][i] - 1),
                "covers_peak": p["peak_plate_stress_mpa"].covers(truth["peak_plate_stress_mpa"][i]),
            }
        )
    return {
        "rows": rows,
        "s_per_design": predict_s,
        "fit_s": fit_s,
        "fitted_on": len(designs),
        "parameters": len(gp.parameters),
        "underdetermined": bool(gp.underdetermined),
        "cannot_take": sorted(cannot),
    }


def solver_seconds(data: Path, count: int = 2) -> float:
    """Median wall seconds of the solver on the first ``count`` test designs of ``data`` (this machine), run as
    ``hcmt simulate`` runs it: the data's settings without the between-frame peak recording (``--peak-stress``), which
    the models here (trained on the frame stress) are not compared with."""
    meta = read_meta(data)
    settings = Settings(**{**meta["generator"]["settings"], "peak_stress": False})
    times = []
    with Split(data, "test", meta) as s:
        for i in range(min(count, len(s))):
            times.append(simulate(design_from_attrs(s.attrs(i)), settings).info.wall_time)
    return float(np.median(times))


def row_file(work: Path, key: str, make) -> dict | None:
    """The row ``key``, made once (``make()``) and kept in WORK/rows/KEY.json; None while another process has it."""
    path = work / "rows" / f"{key}.json"
    if path.is_file():
        return json.loads(path.read_text())
    path.parent.mkdir(parents=True, exist_ok=True)
    if not claim(path.with_suffix("")):
        print(f"  {key}: another process makes it", flush=True)
        return None
    try:
        row = make()
        with atomic_path(path) as tmp:
            tmp.write_text(json.dumps(row, indent=1))
        return row
    finally:
        path.with_suffix(".lock").unlink(missing_ok=True)


def errors(rows: list[dict], key: str) -> dict:
    v = np.asarray([r[key] for r in rows], float)
    if not len(v):
        return {"median_abs": None, "worst": None}
    return {"median_abs": float(np.median(np.abs(v))), "worst": float(v[np.argmax(np.abs(v))])}


def summarize(row: dict) -> dict:
    rows = row["rows"]
    out = {
        "designs": len(rows),
        "peak": errors(rows, "peak_error_pct"),
        "deflection": errors(rows, "deflection_error_pct"),
        "s_per_design": row["s_per_design"],
    }
    if rows and "critical_mm" in rows[0]:
        c = np.asarray([r["critical_mm"] for r in rows])
        out["critical_mm"] = {"median": float(np.median(c)), "worst": float(c.max())}
        out["stress_rmse_all"] = float(np.mean([r["stress_rmse_all"] for r in rows]))
        out["rebound_agreement"] = float(np.mean([r["rebound_agrees"] for r in rows]))
    for k in ("fitted_on", "parameters", "underdetermined", "cannot_take", "checkpoint_step"):
        if k in row:
            out[k] = row[k]
    if rows and "covers_peak" in rows[0]:
        out["covers_peak"] = int(sum(r["covers_peak"] for r in rows))
    return out


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--work", type=Path, required=True)
    p.add_argument("--train-data", type=Path, required=True)
    p.add_argument("--new", action="append", default=[], metavar="NAME=DATA", help="a family never trained on")
    p.add_argument("--models", nargs="+", default=["hcmt", "mgn"])
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1])
    p.add_argument("--steps", type=int, default=8000)
    p.add_argument("--ft-steps", type=int, default=1500)
    p.add_argument("--shots", nargs="+", type=int, default=[5, 20])
    p.add_argument(
        "--eval",
        type=int,
        default=8,
        help="test designs judged per new family (all of the training families' test split)",
    )
    p.add_argument("--ft-lr", type=float, default=None, help="the fine-tuning's learning rate (to a tenth of it)")
    p.add_argument(
        "--base",
        metavar="NAME=RUN",
        help="this model is the base (a run folder or pretrained:NAME) instead of one trained per model and seed",
    )
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--json", default="transfer.json", help="the summary (a name in benchmarks/results or a path)")
    p.add_argument("--report", action="store_true", help="only summarize the rows that exist")
    a = p.parse_args(argv)
    torch.set_num_threads(a.threads)
    work, base_data = a.work, a.train_data.resolve()
    new = {k: Path(v).resolve() for k, v in (item.split("=", 1) for item in a.new)}
    held_out = len(Split(base_data, "test"))
    rows: dict[str, dict | None] = {}
    if not a.report:
        for fam, data in new.items():
            rows[f"solver_{fam}"] = row_file(work, f"solver_{fam}", lambda d=data: {"s": solver_seconds(d)})
        rows["solver_base"] = row_file(work, "solver_base", lambda: {"s": solver_seconds(base_data)})
        rows["gp_base"] = row_file(work, "gp_base", lambda: surrogate_row(base_data, None, base_data, held_out))
        for fam, data in new.items():
            rows[f"gp_{fam}_zero"] = row_file(
                work, f"gp_{fam}_zero", lambda d=data: surrogate_row(base_data, None, d, a.eval)
            )
            for n in a.shots:
                rows[f"gp_{fam}_{n}"] = row_file(
                    work, f"gp_{fam}_{n}", lambda d=data, n=n: surrogate_row(d, n, d, a.eval)
                )
        given = a.base.split("=", 1) if a.base else None
        for seed in a.seeds:
            for model in [None] if given else a.models:
                if given:  # the given model: its rows once, its fine-tunings per seed
                    base, run = f"{given[0]}_s{seed}", given[1]
                    model = Run.load(run, "cpu").info.model["name"]
                    out = work / "pretrained" / given[0]
                    rows[f"{given[0]}_base"] = row_file(
                        work, f"{given[0]}_base", lambda: judged(run, base_data, held_out, out)
                    )
                else:
                    base, out = f"{model}_s{seed}", None
                    if not claim(work / "runs" / base) and not (work / "runs" / base / "train_stats.json").is_file():
                        print(f"  {base}: another process trains it", flush=True)
                        continue
                    try:
                        run = trained(work, base, base_data, model, seed, a.steps)
                    finally:
                        (work / "runs" / f"{base}.lock").unlink(missing_ok=True)
                    rows[f"{base}_base"] = row_file(work, f"{base}_base", lambda r=run: judged(r, base_data, held_out))
                zero = given[0] if given else base
                for fam, data in new.items():
                    rows[f"{zero}_{fam}_zero"] = row_file(
                        work, f"{zero}_{fam}_zero", lambda r=run, d=data, o=out: judged(r, d, a.eval, o)
                    )
                    for n in a.shots:
                        name = f"{base}_{fam}{n}"
                        data_n = subset(data, n, work / "subsets" / f"{fam}_{n}")
                        ft = trained(work, name, data_n, model, seed, a.ft_steps, init=run, lr=a.ft_lr)
                        rows[f"{base}_{fam}_{n}"] = row_file(
                            work, f"{base}_{fam}_{n}", lambda r=ft, d=data: judged(r, d, a.eval)
                        )
    found = {f.stem: json.loads(f.read_text()) for f in sorted((work / "rows").glob("*.json"))}
    summary = {k: (v if k.startswith("solver") else summarize(v)) for k, v in found.items()}
    write_json(
        a.json,
        {
            "command": "python benchmarks/transfer/run.py "
            + " ".join(
                [
                    f"--work {work}",
                    f"--train-data {a.train_data}",
                    *(f"--new {x}" for x in a.new),
                    *([f"--base {a.base}"] if a.base else [f"--models {' '.join(a.models)}", f"--steps {a.steps}"]),
                    f"--seeds {' '.join(map(str, a.seeds))}",
                    f"--ft-steps {a.ft_steps}",
                    *([f"--ft-lr {a.ft_lr}"] if a.ft_lr is not None else []),
                    f"--shots {' '.join(map(str, a.shots))}",
                    f"--eval {a.eval}",
                ]
            ),
            "base": a.base,
            "ft_lr": a.ft_lr,
            "device": f"cpu ({platform.processor() or platform.machine()}), {a.threads} thread per process, two "
            "processes (one per seed) side by side on the 2-core machine",
            "train_families": sorted(set((read_meta(base_data).get("families") or {}).get("train") or ["mono"])),
            "new_families": {k: str(v) for k, v in new.items()},
            "rows": summary,
        },
    )
    print(json.dumps({k: v for k, v in summary.items()}, indent=1)[:4000])


if __name__ == "__main__":
    main()
