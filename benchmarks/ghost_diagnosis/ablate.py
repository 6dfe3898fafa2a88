"""Measured ablations of the stress that stays after the ball leaves, on the validation split.

    python benchmarks/ghost_diagnosis/ablate.py --data DATA --init RUN --work WORK [--steps 4000] [--arms a,b]
                                              [--json benchmarks/results/ghost_ablations.json]

Every arm continues the same trained run (``--init``: its weights, its recipe, its normalizers frozen) for
``--steps`` steps at a learning rate of 1e-4 decaying to 1e-5, changing one training option (:data:`ARMS`), then
:func:`run.diagnose` reads the validation split: the ghost difference (rollout, teacher-forced), the peak plate
stress and maximum deflection errors and how much a 1e-6 mm perturbation grows. Arm ``start`` is the run itself,
``control`` the same steps with nothing changed, ``control-seed1`` the same with another seed (the spread of the
protocol). Fine-tuning a strong run instead of training each arm from scratch keeps the arms at the budget where
the question matters (a run from scratch at this machine's budget is dominated by seed noise: docs/RESULTS.md,
"Scaling"), and it keeps the model's shape: options that change the inputs (``model.deformation``) or the target
(``data.stress_field``) are not arms here (their effect is in the recipe study, docs/RESULTS.md).

Resumable: a finished arm is read back from WORK, a stopped one resumes (``hcmt train --resume``).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
from common import RESULTS, write_json  # noqa: E402
from ghost_diagnosis.run import diagnose, medians  # noqa: E402
from hcmt.data.runs import RunFolder  # noqa: E402
from hcmt.inference.run import Run  # noqa: E402

#: arm -> (its --set overrides, its seed): one option changed against ``control``
ARMS = {
    "start": None,
    "control": ([], 0),
    "control-seed1": ([], 1),
    "no-pushforward": (["train.pushforward=0"], 0),
    "noise-x10": (["train.noise_std=0.003"], 0),
    "contact-free-x4": (["train.contact_free_weight=4"], 0),
}
#: every arm's schedule: a fine-tuning rate, frozen normalizers (--init's default), checkpoints to resume from
COMMON = [
    "train.lr=1e-4",
    "train.lr_final=1e-5",
    "train.valid_every=0",
    "train.pushforward_start=0",
    "train.checkpoint_every=500",
    "train.log_every=100",
]


def train_arm(name: str, init: str, data: Path, work: Path, steps: int, threads: int) -> Path:
    out = work / name
    sets, seed = ARMS[name]
    folder = RunFolder(out, must_exist=False)
    if folder.stats_path.is_file():  # finished (as scaling.run.trained reads it)
        return out
    if folder.latest.is_file():
        cmd = ["--resume", "--out", str(out), "--steps", str(steps)]
    else:
        cmd = [
            "--init",
            init,
            "--data",
            str(data),
            "--out",
            str(out),
            "--steps",
            str(steps),
            "--seed",
            str(seed),
            *[a for s in COMMON + sets for a in ("--set", s)],
        ]
    subprocess.run(
        [sys.executable, "-m", "hcmt", "train", *cmd, "--threads", str(threads), "--no-progress"], check=True
    )
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", type=Path, required=True)
    p.add_argument("--init", required=True, help="the trained run every arm continues")
    p.add_argument("--work", type=Path, required=True, help="the arms' run folders")
    p.add_argument("--steps", type=int, default=4000)
    p.add_argument("--arms", default=",".join(ARMS))
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--json", type=Path, default=RESULTS / "ghost_ablations.json")
    a = p.parse_args()
    arms = a.arms.split(",")
    unknown = [x for x in arms if x not in ARMS]
    if unknown:
        p.error(f"--arms: unknown {', '.join(unknown)}; expected some of {', '.join(ARMS)}")
    torch.set_num_threads(a.threads)
    out = json.loads(a.json.read_text()) if a.json.is_file() else {}
    out.update(
        command="python benchmarks/ghost_diagnosis/ablate.py " + " ".join(sys.argv[1:]),
        init=a.init,
        steps=a.steps,
        common=COMMON,
    )
    out.setdefault("arms", {})
    for name in arms:
        folder = a.init if ARMS[name] is None else train_arm(name, a.init, a.data, a.work, a.steps, a.threads)
        rows = diagnose(
            Run.load(str(folder), "cpu", which="checkpoint" if ARMS[name] else "best"), a.data, "valid", None
        )
        out["arms"][name] = {
            "sets": [] if ARMS[name] is None else ARMS[name][0],
            "seed": None if ARMS[name] is None else ARMS[name][1],
            **medians(rows),
            "rows": rows,
        }
        write_json(a.json, out)  # after every arm: a stopped study keeps what it measured
        print(name, {k: v for k, v in out["arms"][name].items() if k != "rows"}, flush=True)


if __name__ == "__main__":
    main()
