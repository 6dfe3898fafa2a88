"""The long run's kept checkpoints on the judge's sweeps: do the trends' size and the limit calls
of the model alone improve with the training budget?

    python benchmarks/scaling/long_run_sweeps.py RUN --checkpoints step_120000 step_200000 ... \
        [--judge benchmarks/results/model_judge.json] [--out benchmarks/results/scaling_long_run_sweeps.json]

The sweeps' designs are the judge's (``surrogate.run.design_sets``: the data's middle design, thickness 0.5-1.0 mm
at four drop heights, drop height 520-990 mm at 0.75 mm). The solver's peaks, each sweep's yield stress and the
solver's trends are read from the judge's result file, which solved them, so only the model rolls out here (fp32
weights of RUN's kept checkpoints; the judge's shipped file is fp16). Per checkpoint: the passes of the model alone
that the solver fails, and the trends that agree with the solver's, counted by the judge's own functions
(``surrogate.run.unsafe_passes``, ``hcmt.design.sweep.trends_agree``). A checkpoint already in ``--out`` is kept,
not rolled out again.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common, surrogate
from common import RESULTS, write_json  # noqa: E402
from hcmt.design.check import check_designs  # noqa: E402
from hcmt.design.sweep import trends_agree  # noqa: E402
from hcmt.inference.run import Run  # noqa: E402
from surrogate.run import SWEEPS, TREND_QUANTITIES, design_sets, unsafe_passes  # noqa: E402


def judged(model: dict[str, dict[str, list[float]]], judge: dict) -> dict:
    """The judge's sweep counts for one model's answers. ``model[group][quantity]``: its value per sweep point
    (groups ``sweep_<h>`` and ``sweep_height``, quantities :data:`TREND_QUANTITIES`); ``judge``: model_judge.json."""
    unsafe = {}
    for (h, _), (key, s) in zip(SWEEPS, judge["sweeps"].items()):
        unsafe[key] = unsafe_passes(model[f"sweep_{h:g}"]["peak_plate_stress_mpa"], s["solver_peaks"], s["yield_mpa"])
    trends = {}
    for name, per_q in judge["trends"].items():
        trends[name] = {}
        for q in TREND_QUANTITIES:
            v, solver = model[name][q][-1] / model[name][q][0] - 1, per_q[q]["solver"]
            trends[name][q] = {"hcmt": v, "solver": solver, "agrees": trends_agree(v, solver)}
    return {
        "unsafe": sum(unsafe.values()),
        "unsafe_by_sweep": unsafe,
        "points": sum(len(s["solver_peaks"]) for s in judge["sweeps"].values()),
        "trends_agree": sum(t["agrees"] for per_q in trends.values() for t in per_q.values()),
        "trends_of": sum(len(per_q) for per_q in trends.values()),
        "trends": trends,
    }


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run", type=Path, help="the long run's folder (its kept step_N.pt)")
    p.add_argument("--checkpoints", nargs="+", required=True, help="step_N names kept by train.keep_every")
    p.add_argument("--judge", type=Path, default=RESULTS / "model_judge.json")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--out", type=Path, default=RESULTS / "scaling_long_run_sweeps.json")
    a = p.parse_args(argv)
    if not a.judge.is_file():
        sys.exit(f"long_run_sweeps.py: --judge {a.judge}: no such file (benchmarks/surrogate/run.py --json writes it)")
    judge = json.loads(a.judge.read_text())
    torch.set_num_threads(a.threads)
    old = json.loads(a.out.read_text()) if a.out.is_file() else {"rows": []}
    rows = {r["checkpoint"]: r for r in old["rows"]}
    for which in a.checkpoints:
        if which in rows:
            continue
        run = Run.load(a.run, "cpu", which)
        sets = design_sets(run)
        model = {}
        for name in dict.fromkeys([f"sweep_{h:g}" for h, _ in SWEEPS] + ["sweep_height"]):
            check = check_designs(run, sets[name], batch=len(sets[name]), surrogate=False, progress=False)
            model[name] = {q: [getattr(pr.summary, q) for pr in check.preds] for q in TREND_QUANTITIES}
        rows[which] = {
            "checkpoint": which,
            "checkpoint_step": run.checkpoint_step,
            **judged(model, judge),
            "model_peaks": {k: v["peak_plate_stress_mpa"] for k, v in model.items()},
        }
        r = rows[which]
        if r["checkpoint_step"] == judge.get("checkpoint_step"):  # the judge's own model: its peaks, fp16 vs fp32
            theirs = {f"sweep_{h:g}": s["model_peaks"] for (h, _), s in zip(SWEEPS, judge["sweeps"].values())}
            r["judge_peak_max_rel_diff"] = max(
                abs(m / t - 1) for k, v in theirs.items() for m, t in zip(r["model_peaks"][k], v)
            )
        print(
            f"{which}: unsafe {r['unsafe']} of {r['points']}, trends {r['trends_agree']} of {r['trends_of']}",
            flush=True,
        )
        out = {
            "command": "python benchmarks/scaling/long_run_sweeps.py RUN --checkpoints step_N ...",
            "run": str(a.run),
            "judge": {k: judge.get(k) for k in ("command", "model", "checkpoint_step")},
            "rows": sorted(rows.values(), key=lambda r: r["checkpoint_step"]),
        }
        print(f"wrote {write_json(a.out, out)}")


if __name__ == "__main__":
    main()
