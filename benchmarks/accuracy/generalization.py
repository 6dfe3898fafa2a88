"""Paper Table 13 (generalization): the accuracy study's HCMT and MGN runs (trained on the normal split), evaluated
on the test, thicker, higher and thicker-and-higher splits. Resumable.

    python benchmarks/accuracy/generalization.py --work benchmarks/work [--steps 3000] [--seeds 0 1 2]

Writes benchmarks/results/generalization.json.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
from common import dataset, run_and_evaluate, write_json  # noqa: E402
from hcmt.inference.metrics import summarize_runs  # noqa: E402

SPLITS = ("test", "test_thicker", "test_higher", "test_thicker_higher")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--work", type=Path, default=Path("benchmarks/work"))
    p.add_argument("--steps", type=int, default=3000)
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    a = p.parse_args()
    data = dataset(a.work)
    out = {}
    for model in ("mgn", "hcmt"):
        per_split = {s: [] for s in SPLITS}
        for seed in a.seeds:
            res = run_and_evaluate(
                a.work, data, f"acc_{model}_s{seed}_{a.steps}", model, seed, [f"train.steps={a.steps}"], splits=SPLITS
            )
            if res is None:  # another process is training it
                continue
            for s in SPLITS:
                per_split[s].append(res[s])
        if per_split["test"]:
            out[model] = {s: summarize_runs(v) for s, v in per_split.items()}
            out[model]["seeds"] = len(per_split["test"])
    if len(out) < 2:
        return
    write_json("generalization.json", {"steps": a.steps, "seeds": a.seeds, "rows": out})
    print(f"{'split':<22}{'MGN pos':>12}{'MGN stress':>14}{'HCMT pos':>12}{'HCMT stress':>14}")
    for s in SPLITS:
        g, h = out["mgn"][s], out["hcmt"][s]
        print(
            f"{s:<22}{g['position']['rmse_all']['mean']:>12.4g}{g['stress']['rmse_all']['mean']:>14.4g}"
            f"{h['position']['rmse_all']['mean']:>12.4g}{h['stress']['rmse_all']['mean']:>14.4g}"
        )


if __name__ == "__main__":
    main()
