"""The long run's checkpoints as points beyond the scaling study's budgets.

    python benchmarks/scaling/long_run.py SNAPSHOT --data DATA [--checkpoint best|step_N] [--label NAME]
        [--split SPLIT [SPLIT ...]] [--out benchmarks/results/scaling_long_run.json]

``SNAPSHOT``: a copy of the long run's folder (run.yaml, best.pt) taken while it trains (copy it: the run rewrites
best.pt). Its best.pt is judged on DATA's test split exactly as every point of :mod:`scaling.run`
(:func:`scaling.run.test_errors`) and kept in ``--out`` under its checkpoint step, so each later snapshot adds a
row (each row names its model: ``model``; a row without one is HCMT's). The long run is HCMT with the study's
recipe on all 480 designs (and MGN with the same recipe, data and schedule, labelled apart), but its learning rate
decays over its own 400,000 steps: a checkpoint at step N is not the study's N-step run (whose rate has fully
decayed by N), so its rows stand beside the study's fit, not in it (docs/RESULTS.md, section "Scaling with
budget and designs").
``--label`` names the run a row belongs to (a row is kept per label and step): the first long run was lost at step
~212,000 with its disk, and the second, trained again from step 0 with the same command, adds its own rows.
``--split`` judges other splits of DATA instead, their designs pooled (``test_thicker test_higher
test_thicker_higher``: the designs outside the training ranges that ``hcmt generate --variants`` writes), kept per
split (rows without one are the test split's).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
from common import RESULTS, write_json  # noqa: E402
from hcmt.inference.run import Run  # noqa: E402
from scaling.analysis import run_of  # noqa: E402
from scaling.run import test_errors  # noqa: E402


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("snapshot", type=Path, help="a copy of the long run's folder (run.yaml, best.pt)")
    p.add_argument("--data", type=Path, required=True)
    p.add_argument(
        "--checkpoint",
        default="best",
        help="best (the default: a snapshot's) or step_N, a checkpoint "
        "train.keep_every kept (immutable: the live run folder may be judged)",
    )
    p.add_argument("--label", default=None, help="the run's name in the table (default: the snapshot folder)")
    p.add_argument(
        "--split",
        nargs="+",
        default=["test"],
        help="the splits of DATA judged, pooled (default test; "
        "the outside-range splits of `hcmt generate --variants`: test_thicker test_higher "
        "test_thicker_higher)",
    )
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--out", type=Path, default=RESULTS / "scaling_long_run.json")
    a = p.parse_args(argv)
    torch.set_num_threads(a.threads)
    loaded = Run.load(a.snapshot, "cpu", a.checkpoint)
    cfg = loaded.config
    for split in a.split:
        if not (a.data / f"{split}.h5").is_file():
            sys.exit(f"long_run.py: --split {split}: {a.data / (split + '.h5')} does not exist")
    row = {
        **test_errors(loaded, a.data.resolve(), None, tuple(a.split)),
        "designs": loaded.meta["generator"]["counts"]["train"],
        "schedule_steps": cfg.train.steps,
        "lr": cfg.train.lr,
        "lr_final": cfg.train.lr_final,
        "snapshot": str(a.snapshot),
        "checkpoint": a.checkpoint,
        "run": a.label or a.snapshot.name,
        "model": loaded.info.model["name"],
    }
    if a.split != ["test"]:
        row["split"] = " + ".join(a.split)
    old = json.loads(a.out.read_text()) if a.out.is_file() else {"checkpoints": []}

    def key(r):
        return run_of(r), r["checkpoint_step"], r.get("split", "test")

    kept = [r for r in old["checkpoints"] if key(r) != key(row)]
    runs = list(dict.fromkeys(run_of(r) for r in kept + [row]))  # each run's rows together, in order of its first
    out = {
        "command": f"python benchmarks/scaling/long_run.py SNAPSHOT --data {a.data} --checkpoint step_N --label RUN",
        "checkpoints": sorted(
            kept + [row], key=lambda r: (runs.index(run_of(r)), r["checkpoint_step"], r.get("split", "test"))
        ),
    }
    print(json.dumps(row["errors"], indent=1))
    print(f"wrote {write_json(a.out, out)}")


if __name__ == "__main__":
    main()
