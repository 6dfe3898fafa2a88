"""``hcmt demo``: the quickstart (the shipped model's design check beside the solver; ``--train``: the whole
pipeline from nothing).

Default: the trained HCMT model shipped with hcmt (``pretrained:impact_plate_small``) predicts three new Impact Plate
designs (thickness and drop height not in its training data) from their parameters alone, then the built-in FEM
solver simulates the same designs and the two are compared: peak plate stress, its location, the deflection, the
position RMSE and the speedup, plus a stress-contour picture at the peak.

``--train``: the whole pipeline from nothing instead: generate a small dataset with the solver, train HCMT on the
CPU, roll it out on the test trajectories and evaluate it. Run again, it reuses the dataset and the trained model
(``--steps N`` beyond what the run has done trains the missing steps).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from hcmt.config import load_config
from hcmt.data.runs import RunFolder
from hcmt.design.basics import DESIGN_BATCH
from hcmt.design.check import check_designs
from hcmt.design.inputs import settings_of
from hcmt.design.reports import contour_picture, format_table
from hcmt.errors import missing_extra
from hcmt.inference.evaluate import evaluate, format_metrics
from hcmt.inference.run import Run
from hcmt.sim.generate import generate_dataset
from hcmt.sim.params import parse_design
from hcmt.sim.sampling import middle_design
from hcmt.training import train

#: three designs inside the shipped model's training ranges, chosen by hand (not sampled from its data)
DEMO_DESIGNS = [
    {"thickness": 0.6, "drop_height": 600.0},
    {"thickness": 0.8, "drop_height": 850.0},
    {"thickness": 0.95, "drop_height": 950.0},
]


def main(args: argparse.Namespace) -> int:
    return train_demo(args) if args.train else design_demo(args)


def design_demo(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    run = Run.load(args.model, args.device)
    card = run.card
    print(f"[1/3] {run.label} model {run.source}: {card.get('summary', 'trained run')}")
    defaults = middle_design(run.meta, run.ranges)
    designs = [
        (f"design_{i + 1}", parse_design([f"{k}={v}" for k, v in d.items()], defaults))
        for i, d in enumerate(DEMO_DESIGNS)
    ]
    settings = settings_of(run.meta)
    print(
        f"[2/3] predicting {len(designs)} new designs on {run.device} (thickness mm, drop height mm: "
        + ", ".join(f"{d.thickness:g}/{d.drop_height:g}" for _, d in designs)
        + ")"
    )
    print(
        f"[3/3] simulating the same designs with the built-in FEM solver ({settings.frames} frames of "
        f"{settings.frame_dt} ms each)"
    )
    # predict's default batch (one design on a CPU): the model and the solver alternate per design, so the speedup's
    # two wall times see the same load
    check = check_designs(run, designs, batch=DESIGN_BATCH, verify=True, progress=not args.no_progress)
    preds, truth, verified = check.preds, check.truth, check.verified
    for note in check.notes:
        print(f"note: {note}")
    print(
        "\nvon Mises stresses in MPa, lengths in mm; 'err' columns compare the model with the solver"
        + (
            "; 'surrogate' is the response surface (a Gaussian process) fitted on the model's own training designs"
            if check.surrogate
            else ""
        )
    )
    print(format_table(preds, verified))
    missing = missing_extra("viz", "matplotlib")
    if missing is None:
        picture = contour_picture(preds[1], truth[1], run.meta, Path(args.out), run.label)
        print(f"\ncontours at the peak frame, solver beside prediction: {picture}")
    else:
        print(f"\nno contour picture: {missing}")
    print(
        "your own designs:  hcmt predict pretrained:impact_plate_small --design thickness=0.8 drop_height=700 --verify"
    )
    print(
        "a sweep:           hcmt sweep pretrained:impact_plate_small --vary thickness=0.55:0.95:9 --design "
        "drop_height=600 --yield-mpa 750 --verify auto"
    )
    print("where the model is weak: `hcmt models` (measured error by region) and docs/MODELS.md")
    print(f"took {time.perf_counter() - t0:.0f} s")
    return 0


def train_demo(args: argparse.Namespace) -> int:
    out = Path(args.out)
    data, run = out / "impact_plate_small", out / "run_hcmt"
    t0 = time.perf_counter()
    if not (data / "test.h5").is_file() or (data / ".parts").exists():  # the generator resumes where it stopped
        print(f"[1/3] generating the small Impact Plate dataset in {data}")
        generate_dataset(
            data,
            preset="small",
            counts=dict(train=args.train_trajectories, valid=1, test=args.test),
            seed=args.seed,
            workers=args.workers,
            progress=not args.no_progress,
        )
    else:
        print(f"[1/3] reusing the dataset in {data}")
    cfg = load_config("demo", [f"train.steps={args.steps}"] if args.steps else [])
    want = cfg.train.steps
    folder = RunFolder(run, must_exist=False)
    done = folder.steps_done()
    if done >= want and folder.stats_path.is_file():
        print(f"[2/3] reusing the trained model in {run} ({done} steps; --steps N with N > {done} trains more)")
    elif folder.latest.is_file():
        print(f"[2/3] training HCMT {want - done} more steps on the CPU (to {want}) -> {run}")
        train(cfg, data, "hcmt", run, seed=args.seed, resume=True, device="cpu", progress=not args.no_progress)
    else:
        print(f"[2/3] training HCMT afresh for {want} steps on the CPU -> {run}")
        train(cfg, data, "hcmt", run, seed=args.seed, device="cpu", progress=not args.no_progress)
    print("[3/3] rolling out and evaluating on the test split")
    metrics = evaluate(Run.load(run, "cpu"), data, "test", progress=not args.no_progress)
    print(format_metrics(metrics))
    print(f"\ndataset   {data}   (hcmt info {data})")
    print(f"run       {run}   (checkpoints, log.jsonl, tb/)")
    print(f"rollout   {run / 'rollout_test.h5'}")
    print(f"metrics   {run / 'metrics_test.json'}")
    print(f"took {time.perf_counter() - t0:.0f} s")
    return 0
