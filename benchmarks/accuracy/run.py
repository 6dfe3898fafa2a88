"""Paper Table 2 on hcmt's own data: HCMT, MGN and GT with the same budget, several seeds, on a generated
Impact Plate dataset (scale in benchmarks/common.py: DATASET). Resumable.

    python benchmarks/accuracy/run.py --work benchmarks/work [--steps 3000] [--seeds 0 1 2]

Writes benchmarks/results/accuracy.json as {model: {"position": {"rmse_1": {"mean", "std"}, "rmse_all": ...},
"stress": {...}, "train_ms_per_step": ..., "inference_ms_per_step": ...}} and prints the table.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
from common import dataset, fmt, run_and_evaluate, write_json  # noqa: E402
from hcmt.inference.metrics import summarize_runs  # noqa: E402
from hcmt.models import MODELS  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--work", type=Path, default=Path("benchmarks/work"))
    p.add_argument("--steps", type=int, default=3000)
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    p.add_argument("--set", action="append", default=[], help="extra config overrides for every run")
    p.add_argument("--models", nargs="+", default=list(MODELS), choices=MODELS)
    p.add_argument("--json", default="accuracy.json", help="result file name under benchmarks/results/")
    a = p.parse_args()
    data = dataset(a.work)
    table = {}
    for model in a.models:
        ms = []
        for seed in a.seeds:
            print(f"{model} seed {seed}", flush=True)
            res = run_and_evaluate(
                a.work, data, f"acc_{model}_s{seed}_{a.steps}", model, seed, [f"train.steps={a.steps}", *a.set]
            )
            if res is not None:  # None: another process is training it
                ms.append((seed, res["test"]))
        if not ms:
            continue
        table[model] = summarize_runs([m for _, m in ms])
        table[model]["seeds"] = [s for s, _ in ms]
        table[model]["steps"] = a.steps
    path = write_json(a.json, table)
    if not table:
        return
    print(
        f"\n{'model':<6}{'pos RMSE-1':>18}{'pos RMSE-all':>20}{'stress RMSE-1':>20}{'stress RMSE-all':>22}"
        f"{'train ms':>12}"
    )
    for m, r in table.items():
        print(
            f"{m:<6}{fmt(r['position']['rmse_1']):>18}{fmt(r['position']['rmse_all']):>20}"
            f"{fmt(r['stress']['rmse_1']):>20}{fmt(r['stress']['rmse_all']):>22}"
            f"{r['train_ms_per_step']['mean']:>12.1f}"
        )
    if "hcmt" not in table or "mgn" not in table:
        return
    h, g = table["hcmt"], table["mgn"]
    print(
        f"HCMT/MGN position RMSE-all {h['position']['rmse_all']['mean'] / g['position']['rmse_all']['mean']:.2f}, "
        f"stress RMSE-all {h['stress']['rmse_all']['mean'] / g['stress']['rmse_all']['mean']:.2f} "
        "(paper: 0.51 and 0.41)"
    )
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
