"""The design check of two checkouts and the solver side by side: seconds per design on the
shipped model's `small` preset, one CPU thread.

    python benchmarks/micro/design_ab.py --old OLD_TREE --new NEW_TREE [--designs 48] [--rounds 2] [--threads 1]
        [--json benchmarks/results/design_ab_cpu.json]

Every round runs three fresh processes (the same interpreter, each checkout's own ``src`` on ``PYTHONPATH``, one
thread): the old checkout's design check, the new one's, and the solver (the new checkout's
:func:`hcmt.sim.driver.simulate`) on the same ``--designs`` designs (drawn once from the shipped model's preset,
seeded), in an order that alternates between rounds, so the three see the same load. A design check is
``check_designs(run, designs)`` with the checkout's defaults (what a user of ``hcmt predict --designs`` gets: the
old batch of 8 and eager model; the new one's ``DESIGN_BATCH`` and ``compile="auto"``); its time per design is the
call's wall time over the designs, compilation included, and ``steady_s`` the median per design after the first chunk
(compilation excluded). The solver's time per design is each simulation's wall time, the solver run as ``hcmt
simulate`` runs it (the training data's settings, its between-frame peak recording off unless the model learned
``stress_max``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
from pathlib import Path

WORKER = r"""
import dataclasses, json, sys, time
import numpy as np, torch
torch.set_num_threads(1)
from hcmt.inference.run import Run
from hcmt.design.check import check_designs
try:
    from hcmt.sim.params import Design
except ImportError:  # checkouts before hcmt.sim.params
    from hcmt.sim.scene import Design
job = json.loads(sys.argv[1])
names = {f.name for f in dataclasses.fields(Design)}
designs = [(f"d{i}", Design(**{k: v for k, v in d.items() if k in names})) for i, d in enumerate(job["designs"])]
run = Run.load(job["model"], "cpu")
if job["side"] == "solver":
    from hcmt.design.inputs import settings_of
    from hcmt.sim.driver import simulate
    # as a user runs it (hcmt simulate): the between-frame peaks recorded only where a stress_max model reads them
    settings = dataclasses.replace(settings_of(run.meta), peak_stress=run.adapter.stress_field == "stress_max")
    per = []
    for _, d in designs:
        t0 = time.perf_counter(); simulate(d, settings); per.append(time.perf_counter() - t0)
    wall, recorded = sum(per), {}
else:
    try:  # the checkout's defaults, as a user gets them
        from hcmt.design.basics import DESIGN_BATCH as batch
    except Exception:  # older checkouts: batches of 8
        batch = 8
    try:
        from hcmt.design.inputs import settings_of
        from hcmt.inference.rollout import rollout_compile
        steps = len(designs) * (settings_of(run.meta).frames - 1 - run.adapter.history)
        mode = rollout_compile("auto", run.model, steps)  # what compile="auto" resolves to
    except Exception:  # older checkouts: eager
        mode = "none"
    if mode == "aot":  # its package built on this machine before the run, or built inside the timed call
        from hcmt.models.export import package_path
        mode = "aot" if package_path(run.model).is_file() else "aot, built in the call"
    t0 = time.perf_counter()
    check = check_designs(run, designs, progress=False)
    wall = time.perf_counter() - t0
    per, recorded = [p.wall_s for p in check.preds], {"batch": batch, "compile": mode}
print(json.dumps({"wall_s": wall, "per_design": per, **recorded}))
"""


def one_side(tree: Path, side: str, model: str, designs: list[dict], threads: int) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree / "src"), OMP_NUM_THREADS=str(threads), MKL_NUM_THREADS=str(threads))
    job = json.dumps({"side": side, "model": model, "designs": designs})
    out = subprocess.run([sys.executable, "-c", WORKER, job], env=env, check=True, capture_output=True, text=True)
    r = json.loads(out.stdout.strip().splitlines()[-1])
    per = r["per_design"]
    chunk = next((i for i, x in enumerate(per) if x != per[0]), len(per))  # the first chunk's designs
    steady = per[chunk:] if side != "solver" else per
    return {
        "side": side,
        **{k: r[k] for k in ("batch", "compile") if k in r},
        "per_design_s": r["wall_s"] / len(per),
        "median_s": statistics.median(per),
        "steady_s": statistics.median(steady) if steady else None,
        "wall_s": r["wall_s"],
        "load_1min": os.getloadavg()[0],
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--old", type=Path, required=True, help="checkout of the old commit (a git worktree)")
    p.add_argument("--new", type=Path, required=True, help="checkout of the new commit")
    p.add_argument("--model", default="pretrained:impact_plate_small")
    p.add_argument("--designs", type=int, default=48)
    p.add_argument("--rounds", type=int, default=2)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--seed", type=int, default=123)
    p.add_argument(
        "--json", type=Path, default=Path(__file__).resolve().parent.parent / "results" / "design_ab_cpu.json"
    )
    a = p.parse_args()
    sys.path.insert(0, str(a.new.resolve() / "src"))
    import dataclasses

    import numpy as np

    from hcmt.inference.run import Run
    from hcmt.sim.sampling import sample_design

    preset = Run.load(a.model, "cpu").meta["generator"]["preset"]
    rng = np.random.default_rng(a.seed)
    designs = [dataclasses.asdict(sample_design(rng, preset)) for _ in range(a.designs)]
    trees = {"old": a.old.resolve(), "new": a.new.resolve(), "solver": a.new.resolve()}
    commits = {
        k: subprocess.run(
            ["git", "-C", str(t), "rev-parse", "--short", "HEAD"], capture_output=True, text=True
        ).stdout.strip()
        for k, t in trees.items()
        if k != "solver"
    }
    rows = []
    for rnd in range(a.rounds):
        order = ("old", "new", "solver") if rnd % 2 == 0 else ("solver", "new", "old")
        for side in order:
            rows.append({"round": rnd, **one_side(trees[side], side, a.model, designs, a.threads)})
            print(json.dumps(rows[-1]), flush=True)
    med = {
        side: {k: statistics.median(r[k] for r in rows if r["side"] == side) for k in ("per_design_s", "steady_s")}
        for side in trees
    }
    summary = {
        "old_s_per_design": med["old"]["per_design_s"],
        "new_s_per_design": med["new"]["per_design_s"],
        "solver_s_per_design": med["solver"]["per_design_s"],
        "new_over_old": med["old"]["per_design_s"] / med["new"]["per_design_s"],
        "new_over_solver": med["solver"]["per_design_s"] / med["new"]["per_design_s"],
        "old_over_solver": med["solver"]["per_design_s"] / med["old"]["per_design_s"],
        "steady_new_s": med["new"]["steady_s"],
        "steady_old_s": med["old"]["steady_s"],
        "steady_new_over_old": med["old"]["steady_s"] / med["new"]["steady_s"],
        "steady_new_over_solver": med["solver"]["per_design_s"] / med["new"]["steady_s"],
    }
    print(" ".join(f"{k} {v:.3f}" for k, v in summary.items()))
    a.json.parent.mkdir(parents=True, exist_ok=True)
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
    from common import portable  # noqa: E402  (the work folder as $HCMT_WORK, the checkout as relative)

    a.json.write_text(
        json.dumps(
            portable(
                {
                    "commits": commits,
                    "device": platform.processor() or platform.machine(),
                    "threads": a.threads,
                    "designs": a.designs,
                    "rounds": a.rounds,
                    "model": a.model,
                    "command": "python benchmarks/micro/design_ab.py " + " ".join(sys.argv[1:]),
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
