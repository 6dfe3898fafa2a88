"""Average a long run's kept checkpoints into one: a candidate for choose_checkpoint.py.

    python benchmarks/release/average_checkpoints.py RUN --steps 360000 380000 400000

The second long run's kept checkpoints, 20,000 steps apart at a learning rate of ~2e-4, differed by 8× in their
deflection error on the same test designs (docs/RESULTS.md, "The long run's checkpoints"): each is one point of a
noisy walk. Averaging the weights of the last few (stochastic weight averaging, Izmailov et al. 2018, applied after
the run) is the usual remedy. ``RUN/avg_<N1>_<N2>_..._.pt`` holds the mean of their parameters and the last one's
buffers (the normalizers' running statistics: they only accumulate, so the latest holds every step's), its step and
the averaged steps, no optimizer state (it is a model, not a point to resume from).
``choose_checkpoint.py`` judges it beside the kept steps; ``ship_model.py --checkpoint avg_...`` ships it.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import torch

from hcmt.data.runs import RunFolder, read_checkpoint
from hcmt.errors import InputError
from hcmt.models import from_checkpoint
from hcmt.training.runtime import save_atomic


def average(run: Path, steps: list[int]) -> Path:
    """Write the average of ``run``'s kept ``step_<N>.pt`` for ``steps`` (at least two); its path."""
    folder = RunFolder(run)
    if len(set(steps)) < 2:
        raise InputError(f"--steps: at least two different kept steps to average, got {steps}")
    states = []
    for n in sorted(set(steps)):
        path = folder.kept(n)
        if not path.is_file():
            raise InputError(f"{path}: no such checkpoint (kept every train.keep_every steps)")
        states.append(read_checkpoint(path))
    last = states[-1]
    if any(s["model_args"] != last["model_args"] for s in states):
        raise InputError(f"{run}: the checkpoints of --steps hold different models")
    model = from_checkpoint(last)
    buffers = {name for name, _ in model.named_buffers()}
    mean = {
        k: v if k in buffers else torch.stack([s["model"][k] for s in states]).mean(0) for k, v in last["model"].items()
    }
    model.load_state_dict(mean)
    out = run / f"avg_{'_'.join(str(n) for n in sorted(set(steps)))}.pt"
    save_atomic(
        {
            "model_args": last["model_args"],
            "model": model.state_dict(),
            "step": int(last["step"]),
            "best": float(last.get("best", float("inf"))),
            "averaged_steps": sorted(set(steps)),
        },
        out,
    )
    return out


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run", type=Path, help="the run folder (its kept step_<N>.pt)")
    p.add_argument("--steps", type=int, nargs="+", required=True, help="the kept steps to average")
    a = p.parse_args(argv)
    try:
        print(f"wrote {average(a.run, a.steps)}")
    except InputError as exc:
        print(f"average_checkpoints: {exc}", file=sys.stderr)
        raise SystemExit(2) from None


if __name__ == "__main__":
    main()
