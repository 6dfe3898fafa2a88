"""Package a trained run as a shipped model and write its model card's numbers.

    python benchmarks/ship_model.py RUN --data DATASET --name impact_plate_small [--designs 24] [--batch 8]
                                    [--command "how the run was trained"] [--data-command "how the data was made"]

1. writes ``src/hcmt/pretrained/NAME.pt`` (fp16 weights, config, training-data meta and design ranges, card);
2. evaluates the run on the test split with the paper's metrics (fp32 checkpoint);
3. ``--verify`` over the test split's designs (held out from training): the *shipped* fp16 model predicts each
   design from its parameters, the built-in solver simulates it again on this machine, errors and speedup;
4. writes benchmarks/results/model_NAME.json (docs/MODELS.md quotes it).
"""
from __future__ import annotations

import argparse
import json
import platform
import time
from dataclasses import fields
from pathlib import Path

import numpy as np
import torch
from common import write_json

from hcmt.data.format import Split
from hcmt.sim.scene import Design
from hcmt.train import predict as pr
from hcmt.train.run import evaluate
from hcmt.train.run import PRETRAINED_DIR, Run


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run", type=Path)
    p.add_argument("--data", type=Path, required=True)
    p.add_argument("--name", required=True)
    p.add_argument("--designs", type=int, default=24)
    p.add_argument("--batch", type=int, default=8)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--command", default="", help="the training command (recorded in the card)")
    p.add_argument("--data-command", default="", help="the data generation command (recorded in the card)")
    a = p.parse_args()
    torch.set_num_threads(a.threads)
    run = Run.load(a.run, "cpu")
    stats = json.loads((a.run / "train_stats.json").read_text())
    # training time from the log (median step time of every logged interval x its steps): a resumed run's
    # files do not tell when it started
    log = [json.loads(l) for l in (a.run / "log.jsonl").read_text().splitlines()]
    logged = [r for r in log if "ms_per_step" in r]
    wall = sum(r["ms_per_step"] / 1e3 * (r["step"] - p["step"]) for p, r in zip([{"step": 0}] + logged, logged))
    args = run.info["model"]
    card = {
        "summary": f"HCMT (hidden {args['hidden']}, λ {args['levels']}, L_C {args['L_C']}) trained "
                   f"{stats['steps']} steps on {run.meta['generator']['counts']['train']} generated "
                   f"`{run.meta['generator']['preset']}` Impact Plate trajectories",
        "steps": int(stats["steps"]), "device": stats.get("device"), "train_ms_per_step": stats["train_ms_per_step"],
        "train_wall_s_from_log": wall, "data_command": a.data_command, "train_command": a.command,
        "checkpoint": run.info["checkpoint"], "seed": run.info.get("seed"), "machine": platform.processor() or
        platform.machine(), "torch": str(torch.__version__),
    }
    path = run.save_pretrained(PRETRAINED_DIR / f"{a.name}.pt", card)
    print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB)")

    metrics = evaluate(a.run, a.data, "test")
    shipped = Run.load(f"pretrained:{a.name}", "cpu")
    keys = {f.name for f in fields(Design)}
    with Split(a.data, "test") as s:
        designs = [(s.names[i], Design(**{k: float(v) for k, v in s.attrs(i).items() if k in keys}))
                   for i in range(min(a.designs, len(s)))]
    settings = pr.settings_of(shipped.meta)
    t0 = time.perf_counter()
    preds = pr.predict(shipped, designs, batch=a.batch, progress=False)
    predict_wall = time.perf_counter() - t0
    truth = pr.solve(designs, settings)
    verified = pr.verify_designs(preds, truth)
    print(pr.format_table(preds, verified))
    single = pr.predict(shipped, designs[:1], batch=1, progress=False)[0]
    out = {"name": a.name, "file_mb": path.stat().st_size / 1e6, "card": card,
           "test_metrics": {k: metrics[k] for k in ("split", "trajectories", "position", "stress",
                                                    "inference_ms_per_step")},
           "verify": verified, "per_design": [{"name": p.name, **p.summary} for p in preds],
           "predict_wall_s_total": predict_wall, "batch": a.batch, "threads": a.threads,
           "single_design_wall_s": single.wall_s,
           "solver_wall_s_median": float(np.median([t.wall_s for t in truth])),
           "device": "cpu: " + (platform.processor() or platform.machine()),
           "command": "python benchmarks/ship_model.py " + " ".join(
               [str(a.run), "--data", str(a.data), "--name", a.name, "--designs", str(a.designs), "--batch",
                str(a.batch)])}
    print(f"wrote {write_json(f'model_{a.name}.json', out)}")


if __name__ == "__main__":
    main()
