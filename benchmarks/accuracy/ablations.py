"""Paper Tables 3 and 10-12 (ablations) and Fig. 8 (sensitivity to the number of levels λ) on the accuracy
study's data. Resumable.

    python benchmarks/accuracy/ablations.py --work benchmarks/work [--steps 3000] [--seed 0]

Writes benchmarks/results/ablations.json and benchmarks/results/levels.json.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
from common import dataset, run_and_evaluate, write_json  # noqa: E402

ABLATIONS = [None, "late-contact", "only-hmt", "only-cmt", "lpe", "single-branch", "no-remesh"]
#: rows that change the graph, not the model: their overrides (the paper's "HCMT without remeshing" is data.remesh;
#: the row keeps its name, and its run folder, which older code trained as model.ablation=no-remesh, resumes)
GRAPH_ABLATIONS = {"no-remesh": ["data.remesh=false"]}
CLIPS = [1.0, 3.0]
LEVELS = [1, 2, 3, 4]


def row(res: dict | None) -> dict | None:
    if res is None:  # another process is training it
        return None
    m = res["test"]
    return {q: {k: m[q][k] for k in ("rmse_1", "rmse_all")} for q in ("position", "stress")}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--work", type=Path, default=Path("benchmarks/work"))
    p.add_argument("--steps", type=int, default=3000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--part", choices=["ablations", "levels", "all"], default="all")
    a = p.parse_args()
    data = dataset(a.work)
    base = [f"train.steps={a.steps}"]
    abl, lev = {}, {}
    for name in ABLATIONS if a.part != "levels" else []:
        label = name or "hcmt"
        print(label, flush=True)
        run = f"acc_hcmt_s{a.seed}_{a.steps}" if name is None else f"abl_{label}_s{a.seed}_{a.steps}"
        model_ablation = None if name in GRAPH_ABLATIONS else name
        abl[label] = row(
            run_and_evaluate(
                a.work, data, run, "hcmt", a.seed, base + GRAPH_ABLATIONS.get(name, []), ablation=model_ablation
            )
        )
    for c in CLIPS if a.part != "levels" else []:
        print(f"clip {c}", flush=True)
        abl[f"clip-{c:g}"] = row(
            run_and_evaluate(
                a.work, data, f"abl_clip{c:g}_s{a.seed}_{a.steps}", "hcmt", a.seed, base + [f"model.clip={c}"]
            )
        )
    abl = {k: v for k, v in abl.items() if v is not None}
    lev = {k: v for k, v in lev.items() if v is not None}
    if abl:
        write_json("ablations.json", {"seed": a.seed, "steps": a.steps, "rows": abl})
    for lam in LEVELS if a.part != "ablations" else []:
        print(f"levels {lam}", flush=True)
        # λ = 4 is the accuracy study's HCMT configuration (impact_plate_cpu): reuse that run
        name = f"acc_hcmt_s{a.seed}_{a.steps}" if lam == 4 else f"lev{lam}_s{a.seed}_{a.steps}"
        lev[lam] = row(run_and_evaluate(a.work, data, name, "hcmt", a.seed, base + [f"model.levels={lam}"]))
    lev = {k: v for k, v in lev.items() if v is not None}
    if lev:
        write_json("levels.json", {"seed": a.seed, "steps": a.steps, "L_C": 2, "rows": lev})
    for k, v in abl.items():
        print(f"{k:<16} position {v['position']['rmse_all']:10.4g}  stress {v['stress']['rmse_all']:10.4g}")
    for k, v in lev.items():
        print(f"levels {k:<9} position {v['position']['rmse_all']:10.4g}  stress {v['stress']['rmse_all']:10.4g}")


if __name__ == "__main__":
    main()
