"""The headline: HCMT (paper and official attention), MGN and GT on the `paper` preset at CPU scale, with the
training noise σ chosen per model on the validation split. Resumable (finished runs are skipped).

    python benchmarks/parity/run.py --work benchmarks/work [--steps 800] [--sigmas 3e-4 1e-3 3e-3] [--seeds 0 1 2]

Phase 1 (sweep): every model, seed 0, each σ; evaluated on valid and test. σ per model = the lowest validation
position RMSE-all (the test split is never looked at to choose). Phase 2: the remaining seeds at the chosen σ.
Writes benchmarks/results/noise_sweep.json and benchmarks/results/parity_paper.json (mean ± std over seeds,
HCMT ÷ MGN, per-group and per-step errors on the test split).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
from common import RESULTS, dataset, run_and_evaluate, write_json  # noqa: E402
from hcmt.inference.metrics import mean_std, summarize_runs  # noqa: E402

PAPER = dict(preset="paper", train=32, valid=4, test=6, seed=2024, variants=0)
CONFIG = "impact_plate_paper_cpu"
# study label -> (model, config overrides)
VARIANTS = {
    "hcmt": ("hcmt", []),
    "hcmt-official": ("hcmt", ["model.attention=official"]),
    "mgn": ("mgn", []),
    "gt": ("gt", []),
}


def sigma_tag(s: float) -> str:
    return f"{s:.0e}".replace("-0", "-")


def run_name(label, seed, sigma, steps) -> str:
    return f"par_{label}_s{seed}_n{sigma_tag(sigma)}_{steps}"


TABLE_ONLY = False  # --table-only: collect finished runs, train nothing


def one(work, data, label, seed, sigma, steps, splits):
    model, overrides = VARIANTS[label]
    name = run_name(label, seed, sigma, steps)
    if TABLE_ONLY and not all((work / "runs" / name / f"metrics_{s}.json").is_file() for s in splits):
        return name, None
    res = run_and_evaluate(
        work,
        data,
        name,
        model,
        seed,
        [f"train.steps={steps}", f"train.noise_std={sigma}", *overrides],
        splits=splits,
        config=CONFIG,
        details=True,
    )
    return name, res


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--work", type=Path, default=Path("benchmarks/work"))
    p.add_argument("--steps", type=int, default=800)
    p.add_argument("--sigmas", type=float, nargs="+", default=[3e-4, 1e-3, 3e-3])
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    p.add_argument("--models", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    p.add_argument("--phase", choices=["sweep", "seeds", "all"], default="all")
    p.add_argument("--table-only", action="store_true", help="write the tables from the finished runs; train nothing")
    a = p.parse_args()
    global TABLE_ONLY
    TABLE_ONLY = a.table_only
    data = a.work / f"impact_plate_{PAPER['preset']}_{PAPER['train']}" if a.table_only else dataset(a.work, PAPER)
    for label in a.models:  # phase 1: the σ sweep, seed 0
        for sigma in a.sigmas:
            print(f"sweep {label} σ={sigma}", flush=True)
            one(a.work, data, label, a.seeds[0], sigma, a.steps, ("valid",))  # choosing needs valid only
    # the sweep's table from the runs on disk: several processes may share the work (run locks)
    sweep = {}
    for label in a.models:
        for sigma in a.sigmas:
            run = a.work / "runs" / run_name(label, a.seeds[0], sigma, a.steps)
            if (run / "metrics_valid.json").is_file():
                m = {
                    s: json.loads((run / f"metrics_{s}.json").read_text())
                    for s in ("valid", "test")
                    if (run / f"metrics_{s}.json").is_file()
                }
                sweep.setdefault(label, {})[str(sigma)] = {
                    "run": run.name,
                    "seed": a.seeds[0],
                    "steps": a.steps,
                    **{s: {q: m[s][q] for q in ("position", "stress")} for s in m},
                }
    write_json("noise_sweep.json", sweep)
    if a.phase == "sweep":
        return
    table = {"config": CONFIG, "dataset": PAPER, "steps": a.steps, "models": {}}
    chosen = {}
    for label in a.models:
        tried = sweep.get(label, {})
        if len(tried) < len(a.sigmas):  # another process is still sweeping this model: choose once it is done
            print(f"{label}: σ sweep incomplete ({len(tried)} of {len(a.sigmas)}), seeds skipped here", flush=True)
            continue
        chosen[label] = float(min(tried, key=lambda s: tried[s]["valid"]["position"]["rmse_all"]))
    done: dict[str, list] = {label: [] for label in chosen}
    for seed in a.seeds:  # seed by seed, so an interrupted study has every model at the same number of seeds
        for label, sigma in chosen.items():
            print(f"{label} seed {seed} σ={sigma}", flush=True)
            name, res = one(a.work, data, label, seed, sigma, a.steps, ("test",))
            if res is not None:
                done[label].append((seed, name, res["test"]))
    for label, runs in done.items():
        if not runs:
            continue
        row = summarize_runs([r for _, _, r in runs])
        row.update(noise_std=chosen[label], seeds=[s for s, _, _ in runs], runs=[n for _, n, _ in runs])
        details = [json.loads((a.work / "runs" / n / "details_test.json").read_text()) for _, n, _ in runs]
        row["groups"] = {
            g: {q: mean_std(d["groups"][g][q] for d in details) for q in details[0]["groups"][g]}
            for g in details[0]["groups"]
        }
        row["position_error_by_step"] = np.mean([d["position_by_step"] for d in details], 0).tolist()
        row["stress_error_by_step"] = np.mean([d["stress_by_step"] for d in details], 0).tolist()
        table["models"][label] = row
    write_json("parity_paper.json", table)
    m = table["models"]
    for label in ("hcmt", "hcmt-official", "gt"):
        if label in m and "mgn" in m:
            r = {q: m[label][q]["rmse_all"]["mean"] / m["mgn"][q]["rmse_all"]["mean"] for q in ("position", "stress")}
            print(f"{label} / mgn: position {r['position']:.2f}, stress {r['stress']:.2f} (paper: 0.51, 0.41)")
    print(f"wrote {RESULTS / 'parity_paper.json'}")


if __name__ == "__main__":
    main()
