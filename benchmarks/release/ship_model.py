"""Package a trained run as a shipped model and write its model card's numbers.

    python benchmarks/release/ship_model.py RUN --data DATASET --name impact_plate_small [--designs 24] [--batch 8]
                                    [--checkpoint best|checkpoint|step_N|avg_N_M]
                                    [--command "how the run was trained"] [--data-command "how the data was made"]

1. writes ``src/hcmt/pretrained/NAME.pt`` (fp16 weights, config, training-data meta and design ranges, card);
2. evaluates the run on the test split with the paper's metrics (fp32 checkpoint);
3. verifies ``--designs`` held-out designs of a fresh seed (``--design-seed``): the model card's measured error
   by region (``confidence``), then the *shipped* fp16 model against the solver (errors, physics, speedup), and
   a thickness and a drop-height sweep with ``--verify`` (trend signs, the minimum-thickness call);
4. writes benchmarks/results/model_NAME.json (docs/MODELS.md quotes it);
5. writes ``src/hcmt/pretrained/NAME.surrogate.json``: the response surface of its training designs.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
from common import write_json  # noqa: E402
from hcmt.data.runs import PRETRAINED_DIR  # noqa: E402
from hcmt.design import sweep as sw  # noqa: E402
from hcmt.design.check import check_designs, predict  # noqa: E402
from hcmt.design.inputs import region_of  # noqa: E402
from hcmt.design.reports import format_table  # noqa: E402
from hcmt.design.surrogate import Surrogate  # noqa: E402
from hcmt.inference.evaluate import evaluate  # noqa: E402
from hcmt.inference.run import Run  # noqa: E402
from hcmt.sim.params import parse_design  # noqa: E402
from hcmt.sim.sampling import middle_design, sample_design  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run", type=Path)
    p.add_argument("--data", type=Path, required=True)
    p.add_argument("--name", required=True)
    p.add_argument("--designs", type=int, default=30, help="held-out designs of a fresh seed to verify")
    p.add_argument("--design-seed", type=int, default=90210, help="seed of the verification designs")
    p.add_argument("--yield-mpa", type=float, default=703.0, help="limit of the sweeps' minimum-thickness call")
    p.add_argument("--batch", type=int, default=8)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument(
        "--checkpoint",
        default="best",
        help="best, checkpoint (the latest), step_N (kept by "
        "train.keep_every) or avg_N_M... (average_checkpoints.py); choose_checkpoint.py chooses on the "
        "validation split",
    )
    p.add_argument("--command", default="", help="the training command (recorded in the card)")
    p.add_argument("--data-command", default="", help="the data generation command (recorded in the card)")
    a = p.parse_args()
    torch.set_num_threads(a.threads)
    run = Run.load(a.run, "cpu", a.checkpoint)
    stats = json.loads((a.run / "train_stats.json").read_text())
    # training time from the log (median step time of every logged interval x its steps): a resumed run's
    # files do not tell when it started
    log = [json.loads(l) for l in (a.run / "log.jsonl").read_text().splitlines()]
    logged = [r for r in log if "ms_per_step" in r]
    wall = sum(r["ms_per_step"] / 1e3 * (r["step"] - p["step"]) for p, r in zip([{"step": 0}] + logged, logged))
    args = run.info.model
    card = {
        "summary": f"HCMT (hidden {args['hidden']}, λ {args['levels']}, L_C {args['L_C']}) trained "
        f"{stats['steps']} steps (shipped: {a.checkpoint}, the checkpoint of step {run.checkpoint_step}) on "
        f"{run.meta['generator']['counts']['train']} generated "
        f"`{run.meta['generator']['preset']}` Impact Plate trajectories of "
        f"{run.meta['generator']['settings']['frames']} frames",
        "recipe": {
            k: getattr(run.config.model if k in ("target", "deformation", "attention") else run.config.train, k)
            for k in (
                "target",
                "deformation",
                "attention",
                "noise_std",
                "noise_nodes",
                "pushforward",
                "pushforward_start",
            )
        },
        "frame_dt_ms": run.meta.get("dt"),
        "training_designs": run.meta["generator"]["counts"]["train"],
        "steps": int(stats["steps"]),
        "device": stats.get("device"),
        "train_ms_per_step": stats["train_ms_per_step"],
        "train_wall_s_from_log": wall,
        "data_command": a.data_command,
        "train_command": a.command,
        "checkpoint": asdict(run.info.checkpoint),
        "seed": run.info.seed,
        "machine": platform.processor() or platform.machine(),
        "torch": str(torch.__version__),
    }
    metrics = evaluate(run, a.data, "test", progress=False)
    # held-out designs of a fresh seed (uniform inside the training ranges; no study or training used the seed)
    rng = np.random.default_rng(a.design_seed)
    designs = [(f"fresh_{i:02d}", sample_design(rng, run.meta["generator"]["preset"])) for i in range(a.designs)]
    preliminary = Run.load(a.run, "cpu", a.checkpoint)
    check = check_designs(preliminary, designs, batch=a.batch, verify=True, progress=False)
    print(format_table(check.preds, check.verified))
    regions = {}
    for p in check.preds:
        regions.setdefault(region_of(p.design, preliminary.ranges), []).append(p.summary.verify)
    labels = {
        "inside": "inside the ranges' edges",
        "thin": "thin plates (lowest fifth of thickness)",
        "high": "high drops (top fifth of drop height)",
        "thin+high": "thin plates dropped from high",
    }
    card["confidence"] = [
        {
            "region": k,
            "label": labels.get(k, k),
            "designs": len(rows),
            "peak_plate_stress_error_pct_median": float(np.median([abs(r.peak_plate_stress_error_pct) for r in rows])),
            "peak_plate_stress_error_pct_worst": float(max((r.peak_plate_stress_error_pct for r in rows), key=abs)),
            "max_deflection_error_pct_median": float(np.median([abs(r.max_deflection_error_pct) for r in rows])),
            "rebound_agreement": float(np.mean([r.rebound_agrees for r in rows])),
        }
        for k, rows in sorted(regions.items())
    ]
    card["verify_designs"] = {"seed": a.design_seed, "count": a.designs}
    path = run.save_pretrained(PRETRAINED_DIR / f"{a.name}.pt", card)
    print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB)")
    # every shipped model carries the response surface of its own training designs (hcmt.design.surrogate)
    surrogate = Surrogate.fit_dataset(a.data)
    surrogate.source = f"the training designs of pretrained:{a.name} ({a.data_command or a.data})"
    print(f"wrote {surrogate.save(PRETRAINED_DIR / f'{a.name}.surrogate.json')}")
    shipped = Run.load(f"pretrained:{a.name}", "cpu")
    check = check_designs(shipped, designs, batch=a.batch, verify=True, progress=False)  # the fp16 file itself
    print(format_table(check.preds, check.verified))
    sweeps = {}
    for vary, fixed in (("thickness=0.5:1.0:6", ["drop_height=750"]), ("drop_height=520:990:6", ["thickness=0.75"])):
        param, lo, hi, n = sw.parse_vary(vary)
        base = parse_design(fixed, middle_design(shipped.meta))
        sc, analysis = sw.sweep(shipped, param, lo, hi, n, base, verify=True, yield_mpa=a.yield_mpa, progress=False)
        print(sw.format_analysis(analysis))
        sweeps[vary] = {
            "design": fixed,
            **analysis,
            "model_peak": [q.summary.peak_plate_stress_mpa for q in sc.preds],
            "solver_peak": [t.summary.peak_plate_stress_mpa for t in sc.truth],
            "model_deflection": [q.summary.max_deflection_mm for q in sc.preds],
            "solver_deflection": [t.summary.max_deflection_mm for t in sc.truth],
        }
    single = predict(shipped, designs[:1], batch=1, progress=False)[0]
    out = {
        "name": a.name,
        "file_mb": path.stat().st_size / 1e6,
        "card": card,
        "test_metrics": {
            k: metrics.to_json()[k]
            for k in ("split", "trajectories", "position", "stress", "inference_ms_per_step", "physics")
        },
        "verify": None if check.verified is None else check.verified.to_json(),
        "per_design": [{"name": q.name, **q.summary.to_json()} for q in check.preds],
        "sweeps": sweeps,
        "predict_wall_s_total": check.wall_s,
        "batch": a.batch,
        "threads": a.threads,
        "single_design_wall_s": single.wall_s,
        "solver_wall_s_median": float(np.median([t.wall_s for t in check.truth])),
        "device": "cpu: " + (platform.processor() or platform.machine()),
        "command": "python benchmarks/release/ship_model.py "
        + " ".join(
            [
                str(a.run),
                "--data",
                str(a.data),
                "--name",
                a.name,
                "--designs",
                str(a.designs),
                "--batch",
                str(a.batch),
                "--design-seed",
                str(a.design_seed),
            ]
        ),
    }
    print(f"wrote {write_json(f'model_{a.name}.json', out)}")


if __name__ == "__main__":
    main()
