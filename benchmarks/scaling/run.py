"""The scaling study: HCMT and MGN on the `small` preset, error against the training budget and
against the number of training designs, judged on held-out designs.

    python benchmarks/scaling/run.py --data DATA --work WORK [--budgets 1000 3000 10000 30000] \
        [--designs 60 120 480] [--designs-budget 10000] [--seeds 0 1] [--multi-seed 2] [--models hcmt mgn] \
        [--threads 1] [--compile none] [--eval N] [--out benchmarks/results/scaling.json] [--restore JSON]

The points: every budget with the largest design count (the budget axis), every smaller design count at
``--designs-budget`` steps (the design axis); the ``--multi-seed`` cheapest budgets get every seed of ``--seeds``,
the other points the first. A design count N trains on the first N trajectories of DATA's train split (the others
left out by ``data.exclude_trajectories``). Every run uses the shipped model's recipe (docs/MODELS.md) with its
``train.steps`` the budget, ``train.pushforward_start`` scaled with it (2,000 of 36,000) and validation thinned.

Per point, on the first ``--eval`` test designs (all by default): position and stress RMSE-all as
:func:`hcmt.inference.evaluate` computes them (×10³, the paper's metric), and from the same rollouts the median over
trajectories of |peak plate stress error| %, |max deflection error| % and the ghost difference |model ghost ratio −
solver ghost ratio| (:mod:`hcmt.inference.quantities`).

Resumable: each (model, budget, designs, seed) is a run folder WORK/runs/NAME; a finished run (train_stats.json)
is not trained again, an interrupted one resumes from its checkpoint, and each evaluation is kept as
RUN/scaling_eval.json; ``--restore JSON`` takes the points an earlier results file of the same study judged as
finished (a lost work folder). Several processes may share WORK (a run another process holds is skipped). ``--out`` is
rewritten after every finished point, so a partial study still reports (benchmarks/report.py, section "Scaling
with budget and designs"; ``python benchmarks/scaling/report.py OUT`` prints that section alone).
"""

from __future__ import annotations

import argparse
import json
import platform
import shutil
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common, report_common
from common import RESULTS, claim, portable  # noqa: E402
from hcmt.config import COMPILE_MODES, load_config  # noqa: E402
from hcmt.data.format import Split  # noqa: E402
from hcmt.data.runs import RunFolder  # noqa: E402
from hcmt.files import atomic_path  # noqa: E402
from hcmt.inference.evaluate import evaluate  # noqa: E402
from hcmt.inference.run import Run  # noqa: E402
from hcmt.training import train  # noqa: E402
from hcmt.training.runtime import TrainingInterrupted  # noqa: E402

#: the shipped model's recipe (docs/MODELS.md); pushforward_start, validation and checkpoints are set per budget
RECIPE = [
    "model.attention=official",
    "train.noise_std=0.0003",
    "model.target=acceleration",
    "train.noise_nodes=predicted",
    "train.pushforward=0.5",
    "model.deformation=true",
]
SHIPPED = (2000, 36000)  # the shipped model's pushforward_start and steps
NORMALIZER_STEPS = 200  # impact_plate_cpu's; a fifth of the budget below 1,000 steps
VALIDATIONS = 8  # validations per run (best.pt: the lowest validation position RMSE-all, as the shipped model)
EVAL_FILE = "scaling_eval.json"


def plan(budgets, designs, designs_budget, seeds, multi_seed, models) -> list[dict]:
    """The points, cheapest first: (model, budget, designs, seed)."""
    full, cheap = max(designs), sorted(budgets)[:multi_seed]
    pts = {(b, full, s) for b in budgets for s in (seeds if b in cheap else seeds[:1])}
    pts |= {(designs_budget, n, s) for n in designs for s in (seeds if designs_budget in cheap else seeds[:1])}
    return [{"model": m, "budget": b, "designs": n, "seed": s} for b, n, s in sorted(pts) for m in models]


def name(p: dict) -> str:
    return f"{p['model']}_b{p['budget']}_d{p['designs']}_s{p['seed']}"


def overrides(
    budget: int, designs: int, total: int, valid_trajectories: int, compile_mode: str, extra: list[str]
) -> list[str]:
    """The run's config overrides: the recipe scaled to ``budget`` steps, the first ``designs`` of ``total``
    training trajectories."""
    out = RECIPE + [
        f"train.steps={budget}",
        f"train.pushforward_start={round(budget * SHIPPED[0] / SHIPPED[1])}",
        f"train.normalizer_steps={min(NORMALIZER_STEPS, max(1, budget // 5))}",
        f"train.valid_every={max(1, budget // VALIDATIONS)}",
        f"train.valid_trajectories={valid_trajectories}",
        f"train.checkpoint_every={max(1, min(500, budget // 4))}",
        f"train.compile={compile_mode}",
    ]
    if designs < total:
        out.append(f"data.exclude_trajectories=[{','.join(map(str, range(designs, total)))}]")
    return out + list(extra)


def trained(run: Path, data: Path, p: dict, cfg_name: str, ovr: list[str]) -> None:
    """Train the run, resuming its checkpoint, unless train_stats.json says it is finished."""
    folder = RunFolder(run, must_exist=False)
    if folder.stats_path.is_file():
        return
    if run.exists() and not folder.latest.is_file():
        shutil.rmtree(run)  # a start that left no checkpoint
    resume = folder.latest.is_file()
    t0 = time.perf_counter()
    print(f"  {'resuming' if resume else 'training'} {run.name}", flush=True)
    train(load_config(cfg_name, ovr), data, p["model"], run, seed=p["seed"], resume=resume, progress=False)
    print(f"  trained {run.name} in {time.perf_counter() - t0:.0f} s", flush=True)


def judged(run: Path, data: Path, limit: int | None) -> dict:
    """The point's errors on the test split (evaluate's metrics_test.json, plus the engineering errors)."""
    loaded = Run.load(run, "cpu")
    stats = RunFolder(run).train_stats()
    return {
        **test_errors(loaded, data, limit),
        "steps": stats["steps"],
        "train_ms_per_step": stats["train_ms_per_step"],
    }


def test_errors(loaded: Run, data: Path, limit: int | None, split: str | tuple[str, ...] = "test") -> dict:
    """A loaded run's errors on the first ``limit`` designs of ``split`` (all: None; several splits: their designs
    pooled): the paper's RMSE-all and, from the same rollouts, the medians over trajectories of the engineering
    errors; its rollout files are not kept."""
    splits = (split,) if isinstance(split, str) else tuple(split)
    ms = [evaluate(loaded, data, s, limit=limit, progress=False) for s in splits]
    rows = [r.physics for m in ms for r in m.per_trajectory]
    counts = [m.trajectories for m in ms]
    peak = np.abs([r.peak_plate_stress_error_pct for r in rows])
    defl = np.abs([r.max_deflection_error_pct for r in rows])
    ghost = np.abs([r.model_ghost_ratio - r.solver_ghost_ratio for r in rows])
    for s in splits:
        loaded.folder.rollout_path(s, data).unlink(missing_ok=True)

    def pooled(values):  # each split's mean over its trajectories, pooled by their counts
        return float(np.average(values, weights=counts))

    return {
        "trajectories": sum(counts),
        "checkpoint_step": loaded.checkpoint_step,
        "errors": {
            "position_rmse_all": pooled([m.position.rmse_all for m in ms]),
            "stress_rmse_all": pooled([m.stress.rmse_all for m in ms]),
            "peak_error_pct": float(np.median(peak)),
            "deflection_error_pct": float(np.median(defl)),
            "ghost_difference": float(np.median(ghost)),
        },
        "worst": {
            "peak_error_pct": float(peak.max()),
            "deflection_error_pct": float(defl.max()),
            "ghost_difference": float(ghost.max()),
        },
        "solver_ghost_ratio": float(np.median([r.solver_ghost_ratio for r in rows])),
        "rebound_agreement": pooled([m.physics.rebound_agreement for m in ms]),
    }


def point(work: Path, data: Path, p: dict, cfg_name: str, ovr: list[str], limit: int | None) -> dict | None:
    """One point, trained and judged once (kept in RUN/scaling_eval.json); None while another process has it."""
    run = work / "runs" / name(p)
    cached = run / EVAL_FILE
    if cached.is_file():
        return json.loads(cached.read_text())
    if not claim(run):
        print(f"  {run.name} is held by another process: skipped here", flush=True)
        return None
    try:
        trained(run, data, p, cfg_name, ovr)
        row = {**p, **judged(run, data, limit)}
        with atomic_path(cached) as tmp:
            tmp.write_text(json.dumps(row, indent=1))
        return row
    finally:
        (run.parent / f"{run.name}.lock").unlink(missing_ok=True)


#: the header keys that make two studies' points comparable (restore)
SAME_STUDY = ("recipe", "config", "extra_overrides", "compile")


def restore(work: Path, earlier: Path, header: dict, points: list[dict]) -> int:
    """Write WORK's missing RUN/scaling_eval.json of the planned points judged in ``earlier`` (a results file of
    this study, e.g. the committed benchmarks/results/scaling.json), so a study whose work folder was lost trains
    only what it never finished; the number restored. Refused when the study's settings differ."""
    old = json.loads(earlier.read_text())
    differ = [k for k in SAME_STUDY if old.get(k) != header[k]]
    if differ:
        raise SystemExit(
            f"--restore {earlier}: another study ({', '.join(f'{k} {old.get(k)!r}' for k in differ)}; "
            f"this one: {', '.join(repr(header[k]) for k in differ)})"
        )
    wanted, n = {name(q) for q in points}, 0
    for row in old["points"]:
        cached = work / "runs" / name(row) / EVAL_FILE
        if name(row) in wanted and not cached.is_file():
            cached.parent.mkdir(parents=True, exist_ok=True)
            with atomic_path(cached) as tmp:
                tmp.write_text(json.dumps({**row, "restored_from": str(earlier)}, indent=1))
            n += 1
    return n


def finished(work: Path, points: list[dict]) -> list[dict]:
    """The planned points judged so far (by any process sharing WORK)."""
    files = (work / "runs" / name(q) / EVAL_FILE for q in points)
    return [json.loads(f.read_text()) for f in files if f.is_file()]


def write(out: Path, header: dict, points: list[dict], planned: int) -> None:
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(out) as tmp:
        tmp.write_text(
            json.dumps(portable({**header, "planned": planned, "done": len(points), "points": points}), indent=1)
        )


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", type=Path, required=True, help="a `small`-preset dataset with train, valid, test")
    p.add_argument("--work", type=Path, required=True, help="run folders go to WORK/runs (outside the repository)")
    p.add_argument("--budgets", nargs="+", type=int, default=[1000, 3000, 10000, 30000], help="training steps")
    p.add_argument("--designs", nargs="+", type=int, default=[60, 120, 480], help="training design counts")
    p.add_argument("--designs-budget", type=int, default=10000, help="the budget of the design axis")
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1])
    p.add_argument("--multi-seed", type=int, default=2, help="this many cheapest budgets get every seed")
    p.add_argument("--models", nargs="+", default=["hcmt", "mgn"])
    p.add_argument("--config", default="impact_plate_cpu")
    p.add_argument("--valid-trajectories", type=int, default=4)
    p.add_argument("--eval", type=int, default=None, help="test designs judged (default: all)")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--compile", default="none", choices=COMPILE_MODES, help="train.compile")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="another config override")
    p.add_argument("--out", type=Path, default=RESULTS / "scaling.json")
    p.add_argument(
        "--restore",
        type=Path,
        metavar="JSON",
        help="points judged in this earlier results file of the "
        "same study count as finished (a lost work folder; the data regenerated by the same command)",
    )
    a = p.parse_args(argv)
    torch.set_num_threads(a.threads)
    data = a.data.resolve()
    with Split(data, "train") as s:
        total = len(s)
    with Split(data, "valid") as s:
        valid = min(a.valid_trajectories, len(s))
    if max(a.designs) > total:
        raise SystemExit(f"{data}: {total} training designs, --designs asks for {max(a.designs)}")
    points = plan(a.budgets, a.designs, a.designs_budget, a.seeds, a.multi_seed, a.models)
    header = {
        "command": "python benchmarks/scaling/run.py " + " ".join(argv if argv is not None else sys.argv[1:]),
        "data": str(data),
        "train_designs_in_data": total,
        "device": f"cpu ({platform.processor() or platform.machine()}), {a.threads} thread(s)",
        "recipe": RECIPE,
        "config": a.config,
        "extra_overrides": a.set,
        "compile": a.compile,
        "budgets": sorted(a.budgets),
        "designs": sorted(a.designs),
        "designs_budget": a.designs_budget,
        "seeds": a.seeds,
        "multi_seed": a.multi_seed,
        "models": a.models,
    }
    if a.restore:
        print(f"restored {restore(a.work, a.restore, header, points)} judged points from {a.restore}", flush=True)
    print(
        f"scaling study: {len(points)} points, {sum(q['budget'] for q in points):,} training steps in all", flush=True
    )
    for q in points:
        ovr = overrides(q["budget"], q["designs"], total, valid, a.compile, a.set)
        try:
            row = point(a.work, data, q, a.config, ovr, a.eval)
        except (TrainingInterrupted, KeyboardInterrupt) as exc:
            write(a.out, header, finished(a.work, points), len(points))
            raise SystemExit(
                f"{exc or 'interrupted'}; {a.out} holds the finished points: run the same command again to resume"
            ) from None
        if row is None:
            continue
        done = finished(a.work, points)  # this process's points and those other processes finished
        e = row["errors"]
        print(
            f"  {name(q)}: position {e['position_rmse_all']:.4g}, stress {e['stress_rmse_all']:.4g}, peak "
            f"{e['peak_error_pct']:.1f} %, deflection {e['deflection_error_pct']:.1f} %, ghost "
            f"{e['ghost_difference']:.3f} ({len(done)}/{len(points)} points done)",
            flush=True,
        )
        write(a.out, header, done, len(points))
    write(a.out, header, finished(a.work, points), len(points))
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
