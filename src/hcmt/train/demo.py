"""``hcmt demo``: the quickstart. Generates a small Impact Plate dataset with the built-in FEM solver, trains HCMT
for a few minutes on the CPU, rolls it out on the test trajectories, evaluates it against the ground truth and
prints the metrics and where everything went. Run again, it reuses the dataset and resumes training."""
from __future__ import annotations

import argparse
import time
from pathlib import Path


def configure(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="demo_out", help="folder for the dataset and the run (default: demo_out)")
    p.add_argument("--steps", type=int, help="training steps (default: the demo config's)")
    p.add_argument("--train", type=int, default=12, help="training trajectories to generate")
    p.add_argument("--test", type=int, default=2, help="test trajectories to generate")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--workers", type=int, default=2)


def main(args: argparse.Namespace) -> int:
    from hcmt.cli import main as hcmt
    from hcmt.train.cli import evaluate, format_metrics
    from hcmt.train.config import load_config
    from hcmt.train.trainer import train

    out = Path(args.out)
    data, run = out / "impact_plate_small", out / "run_hcmt"
    t0 = time.perf_counter()
    if not (data / "test.h5").is_file() or (data / ".parts").exists():  # the generator resumes where it stopped
        print(f"[1/3] generating the small Impact Plate dataset in {data}")
        rc = hcmt(["generate", "impact-plate", str(data), "--preset", "small", "--train", str(args.train),
                   "--valid", "1", "--test", str(args.test), "--seed", str(args.seed), "--workers", str(args.workers)])
        if rc:
            return rc
    else:
        print(f"[1/3] reusing the dataset in {data}")
    cfg = load_config("demo", [f"train.steps={args.steps}"] if args.steps else [])
    done = (run / "train_stats.json").is_file() and not args.steps
    print(f"[2/3] training HCMT for {cfg['train']['steps']} steps on the CPU -> {run}")
    if not done:
        train(cfg, data, "hcmt", run, seed=args.seed, resume=(run / "checkpoint.pt").is_file(), device="cpu")
    print("[3/3] rolling out and evaluating on the test split")
    metrics = evaluate(run, data, "test")
    print(format_metrics(metrics))
    print(f"\ndataset   {data}   (hcmt info {data})")
    print(f"run       {run}   (checkpoints, log.jsonl, tb/)")
    print(f"rollout   {run / 'rollout_test.h5'}")
    print(f"metrics   {run / 'metrics.json'}")
    print(f"took {time.perf_counter() - t0:.0f} s")
    return 0
