"""Training throughput of two checkouts side by side: samples per second on the ``small`` preset.

    python benchmarks/micro/train_speed.py --old OLD_TREE --new NEW_TREE [--also NAME=TREE] --data DATA [--threads 1 2]
        [--recipes cpu ship] [--steps 150] [--rounds 2] [--json benchmarks/results/train_speed.json]

For every round, thread count and recipe, ``hcmt train`` runs ``--steps`` steps in each checkout (its own
``src`` on ``PYTHONPATH``, a fresh process, the same interpreter), old and new alternating so that both see the
same load. The figure is the trainer's own median wall time of a step (loading the batch, forward, loss, backward,
Adam), read from the run's ``train_stats.json``; samples per second is the batch size over it (the new checkout
also records its CPU time per step, which another job's load moves less). Recipes:

* ``cpu``: the defaults of ``impact_plate_cpu`` (HCMT, paper attention, velocity target, no pushforward);
* ``ship``: the shipped model's recipe (docs/MODELS.md: official attention, acceleration target, deformation
  features, noise on predicted nodes, pushforward 0.5).

Either checkout's defaults apply: what is compared is what a user gets from each without extra flags. The first
steps of a compiled run (compilation) are outside the median as long as ``--steps`` is several times their number.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from hcmt.models.export import cpu_name

RECIPES = {
    "cpu": [],
    "ship": [
        "model.attention=official",
        "train.noise_std=0.0003",
        "model.target=acceleration",
        "train.noise_nodes=predicted",
        "train.pushforward=0.5",
        "train.pushforward_start=0",
        "model.deformation=true",
    ],
}


def one_run(tree: Path, data: Path, recipe: str, threads: int, steps: int, work: Path, extra=()) -> dict:
    out = work / f"run_{tree.name}_{recipe}_{threads}"
    shutil.rmtree(out, ignore_errors=True)
    sets = [
        f"--set={s}"
        for s in RECIPES[recipe]
        + [
            "train.valid_every=0",
            "train.normalizer_steps=10",
            "train.checkpoint_every=100000",
            "train.log_every=10",
            *extra,
        ]
    ]
    env = dict(os.environ, PYTHONPATH=str(tree / "src"), OMP_NUM_THREADS=str(threads))
    cmd = [
        sys.executable,
        "-c",
        "import sys; from hcmt.cli import main; sys.argv[0] = 'hcmt'; sys.exit(main())",
        "train",
        "--config",
        "impact_plate_cpu",
        "--data",
        str(data),
        "--model",
        "hcmt",
        "--out",
        str(out),
        "--steps",
        str(steps),
        "--threads",
        str(threads),
        "--no-progress",
        *sets,
    ]
    t0 = time.perf_counter()
    subprocess.run(cmd, env=env, check=True, capture_output=True, text=True)
    wall, load = time.perf_counter() - t0, os.getloadavg()[0]  # other processes' share of the cores, as it ended
    stats = json.loads((out / "train_stats.json").read_text())
    run = (out / "run.yaml").read_text()
    batch = 1 if "batch_size" not in run else int(run.split("batch_size:")[1].split()[0])
    ms = float(stats["train_ms_per_step"])
    cpu = stats.get("train_cpu_ms_per_step")  # absent at commits before it was recorded
    shutil.rmtree(out, ignore_errors=True)
    return {
        "ms_per_step": ms,
        "cpu_ms_per_step": cpu,
        "samples_per_s": 1e3 * batch / ms,
        "wall_s": wall,
        "batch": batch,
        "load_1min": load,
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--old", type=Path, required=True, help="checkout of the old commit (a git worktree)")
    p.add_argument("--new", type=Path, required=True, help="checkout of the new commit")
    p.add_argument("--data", type=Path, required=True, help="a `small` preset dataset with a train split")
    p.add_argument(
        "--also",
        action="append",
        default=[],
        metavar="NAME=TREE",
        help="a further checkout timed in the same rounds with --new-set (e.g. the main branch before the "
        "change: new against it says what the change itself buys)",
    )
    p.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    p.add_argument("--recipes", nargs="+", default=list(RECIPES), choices=list(RECIPES))
    p.add_argument("--steps", type=int, default=150)
    p.add_argument("--rounds", type=int, default=2)
    p.add_argument(
        "--new-set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a setting for the new checkout only, e.g. train.compile=default: what `auto` (the default) "
        "chooses for a run of 5,000 steps or more, which a short timed run would not trigger",
    )
    results = Path(__file__).resolve().parent.parent / "results"
    p.add_argument("--json", type=Path, default=results / "train_speed.json")
    a = p.parse_args()
    trees = {
        "old": a.old.resolve(),
        "new": a.new.resolve(),
        **{n: Path(t).resolve() for n, t in (x.split("=", 1) for x in a.also)},
    }
    commits = {
        k: subprocess.run(
            ["git", "-C", str(t), "rev-parse", "--short", "HEAD"], capture_output=True, text=True
        ).stdout.strip()
        for k, t in trees.items()
    }
    rows = []
    with tempfile.TemporaryDirectory(prefix="train_speed_") as tmp:
        for rnd in range(a.rounds):
            for threads in a.threads:
                for recipe in a.recipes:
                    order = list(trees) if rnd % 2 == 0 else list(trees)[::-1]  # alternate who goes first
                    for side in order:
                        r = one_run(
                            trees[side], a.data, recipe, threads, a.steps, Path(tmp), a.new_set if side != "old" else ()
                        )
                        rows.append({"round": rnd, "threads": threads, "recipe": recipe, "side": side, **r})
                        print(json.dumps(rows[-1]), flush=True)
    summary = []
    for threads in a.threads:
        for recipe in a.recipes:
            med = {
                side: statistics.median(
                    r["samples_per_s"]
                    for r in rows
                    if r["threads"] == threads and r["recipe"] == recipe and r["side"] == side
                )
                for side in trees
            }
            summary.append(
                {
                    "threads": threads,
                    "recipe": recipe,
                    "old_samples_per_s": med["old"],
                    "new_samples_per_s": med["new"],
                    "ratio": med["new"] / med["old"],
                    **{f"{n}_samples_per_s": med[n] for n in trees if n not in ("old", "new")},
                    **{f"new_over_{n}": med["new"] / med[n] for n in trees if n not in ("old", "new")},
                }
            )
            also = "".join(
                f", {n} {med[n]:.2f} (new ÷ {n} {med['new'] / med[n]:.2f}x)" for n in trees if n not in ("old", "new")
            )
            print(
                f"{recipe:5s} {threads} thread(s): old {med['old']:.2f} samples/s, new {med['new']:.2f}, "
                f"ratio {med['new'] / med['old']:.2f}x{also}"
            )
    a.json.parent.mkdir(parents=True, exist_ok=True)
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
    from common import portable  # noqa: E402  (the work folder as $HCMT_WORK, the checkout as relative)

    a.json.write_text(
        json.dumps(
            portable(
                {
                    "commits": commits,
                    "device": platform.processor() or platform.machine(),
                    "cpu": cpu_name(),
                    "steps": a.steps,
                    "rounds": a.rounds,
                    "new_set": a.new_set,
                    "command": "python " + " ".join(sys.argv),
                    "data": str(a.data),
                    "summary": summary,
                    "rows": rows,
                }
            ),
            indent=1,
        )
        + "\n"
    )
    print(f"wrote {a.json}")


if __name__ == "__main__":
    main()
