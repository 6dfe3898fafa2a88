"""The training recipe study on the `small` preset (90-frame window), HCMT with the
recommended attention (official, σ 3e-4 mm), equal steps, 3 seeds: today's formulation (velocity target, noise on
NORMAL nodes) against each option of the formulation, alone and combined. Resumable; several processes may share
the work (run locks).

    python benchmarks/recipe/run.py --work $HCMT_WORK/study [--steps 3000] [--seeds 0 1 2]        # train + evaluate
    python benchmarks/recipe/run.py --work $HCMT_WORK/study --table-only                          # the tables

Every run is evaluated on the validation and the test split (``metrics_<split>.json``, physics metrics included);
the recipe is chosen on the validation split (:func:`choose`), never the test split. Writes
benchmarks/results/recipe_small.json.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from scipy.stats import rankdata

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
from common import dataset, run_and_evaluate, write_json  # noqa: E402
from hcmt.inference.evaluate import evaluate  # noqa: E402
from hcmt.inference.metrics import mean_std  # noqa: E402
from hcmt.inference.run import Run  # noqa: E402

# 40 / 4 / 12 designs of the `small` preset over a 90-frame window (0.178 ms: the whole impact of every design of
# the ranges, docs/RESULTS.md "Window"); another seed than any other study's
DATA = dict(preset="small", train=40, valid=4, test=12, seed=2026, variants=0, frames=90)
CONFIG = "impact_plate_cpu"
BASE = ["model.attention=official", "train.noise_std=0.0003"]
# label -> overrides: the formulation options of `model.target`, `train.noise_nodes`, `train.pushforward`
RECIPES = {
    "vel-normal": [],  # today's: the paper's Table 9 target, the authors' NORMAL-only noise
    "acc-normal": ["model.target=acceleration"],
    "vel-predicted": ["train.noise_nodes=predicted"],
    "acc-predicted": ["model.target=acceleration", "train.noise_nodes=predicted"],
    "vel-normal-pf": ["train.pushforward=0.5", "train.pushforward_start=1000"],
    "acc-predicted-pf": [
        "model.target=acceleration",
        "train.noise_nodes=predicted",
        "train.pushforward=0.5",
        "train.pushforward_start=1000",
    ],
    # hcmt's edge deformation features (model.deformation), aimed at the plate's missing restoring force
    "vel-normal-def": ["model.deformation=true"],
    "acc-predicted-def": ["model.target=acceleration", "train.noise_nodes=predicted", "model.deformation=true"],
    "acc-predicted-pf-def": [
        "model.target=acceleration",
        "train.noise_nodes=predicted",
        "train.pushforward=0.5",
        "train.pushforward_start=1000",
        "model.deformation=true",
    ],
}
SPLITS = ("valid", "test")


def run_name(label: str, seed: int, steps: int) -> str:
    return f"rec_{label}_s{seed}_{steps}"


def train_all(work: Path, data: Path, steps: int, seeds: list[int], labels: list[str]) -> None:
    for seed in seeds:  # seed by seed: an interrupted study has every recipe at the same number of seeds
        for label in labels:
            print(f"{label} seed {seed}", flush=True)
            run_and_evaluate(
                work,
                data,
                run_name(label, seed, steps),
                "hcmt",
                seed,
                [f"train.steps={steps}", *BASE, *RECIPES[label]],
                splits=SPLITS,
                config=CONFIG,
                keep_rollouts=True,
            )


#: validation criteria of :func:`choose`: (key path in a run's summary, larger is better)
CRITERIA = (
    ("rebound_agreement", True),
    ("peak_plate_stress_error_pct", False),
    ("max_deflection_error_pct", False),
    ("position_rmse_all", False),
)


def run_summary(run: Path, data: Path, split: str) -> dict:
    """The run's metrics on a split with the physics metrics (recomputed from the kept rollout when the metrics
    file predates them)."""
    m = json.loads((run / f"metrics_{split}.json").read_text())
    if "physics" not in m:
        m = evaluate(Run.load(run, "cpu"), data, split, progress=False).to_json()  # as the file holds it
    p = m["physics"]
    out = {
        "position_rmse_all": m["position"]["rmse_all"],
        "stress_rmse_all": m["stress"]["rmse_all"],
        "rebound_agreement": p["rebound_agreement"],
        "model_rebounds": p["model_rebounds"],
        "solver_rebounds": p["solver_rebounds"],
        "far_deflection_error_um": p["far_deflection_error_um"]["median"],
        "train_ms_per_step": json.loads((run / "train_stats.json").read_text())["train_ms_per_step"],
        "inference_ms_per_step": m["inference_ms_per_step"],
        "error_by_step": m["error_by_step"],
    }
    for key in (
        "peak_plate_stress_error_pct",
        "peak_ball_stress_error_pct",
        "peak_plate_frame_error",
        "max_deflection_error_pct",
    ):
        out[key] = p[key]["median_abs"]
        out[f"{key}_signed"] = p[key]["median"]
        out[f"{key}_worst"] = p[key]["worst"]
    return out


def choose(valid: dict[str, dict]) -> tuple[str, dict]:
    """The recipe with the lowest sum of ranks over :data:`CRITERIA` (means over seeds, validation split); tied
    values share their average rank (scipy.stats.rankdata)."""
    labels = list(valid)
    ranks = np.zeros(len(labels))
    for key, larger in CRITERIA:
        v = np.array([valid[lab][key]["mean"] for lab in labels])
        ranks += rankdata(-v if larger else v)
    sums = {lab: float(r) for lab, r in zip(labels, ranks)}
    return min(sums, key=sums.get), sums


def table(work: Path, steps: int, seeds: list[int], labels: list[str]) -> Path:
    data = work / f"impact_plate_{DATA['preset']}_{DATA['train']}_{DATA['frames']}"
    rows: dict[str, dict] = {}
    for label in labels:
        runs = [work / "runs" / run_name(label, s, steps) for s in seeds]
        runs = [r for r in runs if all((r / f"metrics_{sp}.json").is_file() for sp in SPLITS)]
        if not runs:
            continue
        rows[label] = {"overrides": RECIPES[label], "seeds": len(runs), "runs": [r.name for r in runs]}
        for split in SPLITS:
            per_run = [run_summary(r, data, split) for r in runs]
            row = {k: mean_std(p[k] for p in per_run) for k in per_run[0] if k != "error_by_step"}
            row["error_by_step"] = {
                k: np.mean([p["error_by_step"][k] for p in per_run], 0).tolist() for k in per_run[0]["error_by_step"]
            }
            rows[label][split] = row
    full = [lab for lab in rows if rows[lab]["seeds"] == max(r["seeds"] for r in rows.values())]
    chosen, ranks = choose({lab: rows[lab]["valid"] for lab in full}) if full else (None, {})
    return write_json(
        "recipe_small.json",
        {
            "dataset": DATA,
            "config": CONFIG,
            "base": BASE,
            "steps": steps,
            "criteria": [k for k, _ in CRITERIA],
            "rank_sums": ranks,
            "chosen": chosen,
            "recipes": rows,
        },
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--work", type=Path, default=Path("benchmarks/work"))
    p.add_argument("--steps", type=int, default=3000)
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    p.add_argument("--recipes", nargs="+", default=list(RECIPES), choices=list(RECIPES))
    p.add_argument("--table-only", action="store_true", help="write the tables from the finished runs; train nothing")
    a = p.parse_args()
    data = a.work / f"impact_plate_{DATA['preset']}_{DATA['train']}_{DATA['frames']}"
    if not a.table_only:
        data = dataset(a.work, DATA)
        train_all(a.work, data, a.steps, a.seeds, a.recipes)
    print(f"wrote {table(a.work, a.steps, a.seeds, a.recipes)}")


if __name__ == "__main__":
    main()
