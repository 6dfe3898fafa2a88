"""Choose the checkpoint of a long run to ship on the validation split's engineering errors.

    python benchmarks/release/choose_checkpoint.py RUN --data DATA [--split valid] [--limit N] [--json OUT]
        [--cache DIR]

``best.pt`` follows only the validation position RMSE-all (the trainer's rule), and on the first long run a
checkpoint with the best position error had twice another's deflection error. So every checkpoint the run kept
(``best``, each ``step_<N>.pt`` of ``train.keep_every`` and each average of them, ``avg_<N>_<M>....pt`` of
average_checkpoints.py) is rolled out on ``--split`` (the validation split: the
test split stays for the model card) and judged as the scaling study judges a point
(:func:`scaling.run.test_errors`: medians over trajectories of |peak plate stress error| %, |max deflection error| %
and the ghost difference). The choice is the checkpoint whose worst ratio to the model goals (peak 3 %, deflection
4 %, ghost 0.05) is lowest. ``--json`` keeps every row and the choice; ``ship_model.py RUN --checkpoint NAME`` ships it.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common, scaling
from common import write_json  # noqa: E402
from hcmt.data.runs import RunFolder  # noqa: E402
from hcmt.files import atomic_path  # noqa: E402
from hcmt.inference.run import Run  # noqa: E402
from report_common import MODEL_GOALS as GOALS  # noqa: E402
from scaling.run import test_errors  # noqa: E402


def kept(folder: RunFolder) -> list[str]:
    """The run's checkpoints worth choosing among: ``best``, every kept ``step_<N>`` by step, then every average of
    kept steps (``avg_<N>_<M>...``, average_checkpoints.py) by its last step."""

    def named(prefix):
        found = [p.stem for p in folder.path.glob(f"{prefix}_*.pt") if re.fullmatch(rf"{prefix}(_\d+)+", p.stem)]
        return sorted(found, key=lambda n: [int(x) for x in n.split("_")[1:]][::-1])

    return (["best"] if folder.best.is_file() else []) + named("step") + named("avg")


def score(errors: dict) -> float:
    """The worst ratio of a checkpoint's median errors to their goals (below 1: every goal met)."""
    return max(errors[k] / goal for k, goal in GOALS.items())


def judged(run: Path, which: str, data: Path, split: str, limit: int | None, cache: Path | None) -> dict:
    """One checkpoint's row; kept steps and averages never change, so with ``cache`` their rows are kept there
    (``best.pt`` moves while the run trains: always judged afresh)."""
    path = None if cache is None or which == "best" else cache / f"{which}.{split}.{limit or 'all'}.json"
    if path is not None and path.is_file():
        return json.loads(path.read_text())
    row = {"checkpoint": which, **test_errors(Run.load(run, "cpu", which), data, limit, split)}
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(path) as tmp:
            tmp.write_text(json.dumps(row, indent=1))
    return row


def choose(run: Path, data: Path, split: str = "valid", limit: int | None = None, cache: Path | None = None) -> dict:
    folder = RunFolder(run)
    rows = []
    for which in kept(folder):
        row = judged(run, which, data, split, limit, cache)
        row["score"] = score(row["errors"])
        rows.append(row)
        e = row["errors"]
        print(
            f"{which:>12s} (step {row['checkpoint_step']}): peak {e['peak_error_pct']:.1f} %, deflection "
            f"{e['deflection_error_pct']:.1f} %, ghost {e['ghost_difference']:.3f}, position "
            f"{e['position_rmse_all']:.4g}: score {row['score']:.2f}",
            flush=True,
        )
    if not rows:
        raise SystemExit(f"{run}: no best.pt or step_<N>.pt to choose among")
    best = min(rows, key=lambda r: r["score"])
    return {
        "run": str(run),
        "data": str(data),
        "split": split,
        "goals": GOALS,
        "rows": rows,
        "chosen": best["checkpoint"],
        "chosen_step": best["checkpoint_step"],
    }


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run", type=Path, help="the run folder (it may still be training: kept checkpoints do not change)")
    p.add_argument("--data", type=Path, required=True)
    p.add_argument("--split", default="valid")
    p.add_argument("--limit", type=int, default=None, help="only the first N trajectories of the split")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--json", type=Path, default=None)
    p.add_argument(
        "--cache",
        type=Path,
        default=None,
        help="a folder keeping each kept step's and average's row "
        "(immutable checkpoints: a later choice judges only the new ones)",
    )
    a = p.parse_args(argv)
    torch.set_num_threads(a.threads)
    out = choose(a.run, a.data.resolve(), a.split, a.limit, a.cache)
    out["command"] = "python benchmarks/release/choose_checkpoint.py " + " ".join(
        argv if argv is not None else sys.argv[1:]
    )
    print(f"chosen: {out['chosen']} (step {out['chosen_step']})")
    if a.json:
        print(f"wrote {write_json(a.json, out)}")


if __name__ == "__main__":
    main()
