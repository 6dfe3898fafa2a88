"""Shared plumbing of the paper-table benchmarks: dataset generation, resumable runs, result files.

Every script is resumable: a finished run (``metrics_<split>.json`` present) is skipped, an interrupted one resumes
from its last checkpoint, and the dataset is generated once (the generator itself skips finished trajectories).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import time
from pathlib import Path

import h5py
import numpy as np
import torch

from hcmt.config import load_config
from hcmt.data.format import Split
from hcmt.data.runs import RunFolder
from hcmt.files import atomic_path, take_lock
from hcmt.inference.evaluate import evaluate
from hcmt.inference.metrics import plate_mask, rollout_details as details
from hcmt.inference.run import Run
from hcmt.sim.generate import generate_dataset
from hcmt.sim.params import Settings
from hcmt.sim.sampling import VARIANTS
from hcmt.training import train

# Benchmarks run two scripts side by side on the 2-core machine: one intra-op thread each avoids oversubscription.
torch.set_num_threads(1)

ROOT = Path(__file__).resolve().parent
RESULTS = ROOT / "results"
CHECKOUT = ROOT.parent
#: the work folder that commands in docs/RESULTS.md name as ``$HCMT_WORK`` (data sets, run folders, scratch results):
#: the environment variable ``HCMT_WORK``, else ``benchmarks/work`` inside the checkout (ignored by git)
WORK = Path(os.environ.get("HCMT_WORK") or ROOT / "work").resolve()

# The accuracy study's scale (stated in docs/RESULTS.md): `small` preset, CPU budget per run.
DATASET = dict(preset="small", train=40, valid=4, test=10, seed=2024, variants=20)


def dataset(work: Path, spec: dict = DATASET) -> Path:
    """The benchmark's dataset under ``work``, generated (or finished: the generator skips what exists) by
    :func:`hcmt.sim.generate.generate_dataset`."""
    data = work / (
        f"impact_plate_{spec['preset']}_{spec['train']}"
        + (f"_{spec['frames']}" if spec.get("frames") else "")
        + (f"_dt{spec['frame_dt']:g}" if spec.get("frame_dt") else "")
    )
    counts = {"train": spec["train"], "valid": spec["valid"], "test": spec["test"]}
    if spec.get("variants"):
        counts.update({v: spec["variants"] for v in VARIANTS})
    default = Settings()
    settings = Settings(frames=spec.get("frames") or default.frames, frame_dt=spec.get("frame_dt") or default.frame_dt)
    generate_dataset(
        data, preset=spec["preset"], counts=counts, seed=spec["seed"], workers=2, settings=settings, progress=False
    )
    return data


def run_and_evaluate(
    work: Path,
    data: Path,
    name: str,
    model: str,
    seed: int,
    overrides: list[str],
    splits=("test",),
    ablation: str | None = None,
    config: str = "impact_plate_cpu",
    details: bool = False,
    keep_rollouts: bool = False,
) -> dict:
    """Train (or resume, or skip) one run, then evaluate it on each split; returns {split: metrics}."""
    run = work / "runs" / name
    folder = RunFolder(run, must_exist=False)
    out = {}
    done = all(folder.metrics_path(s).is_file() for s in splits)
    if not done and not claim(run):
        print(f"  {name} is being trained by another process: skipped here", flush=True)
        return None
    if not done:
        try:
            _train_and_evaluate(run, data, model, seed, overrides, splits, ablation, config, details, keep_rollouts)
        finally:
            (run.parent / f"{run.name}.lock").unlink(missing_ok=True)  # ours: claimed above
    for s in splits:
        out[s] = json.loads(folder.metrics_path(s).read_text())
    stats = RunFolder(run).train_stats()
    for s in splits:
        out[s]["train_ms_per_step"] = stats["train_ms_per_step"]
        out[s]["steps"] = stats["steps"]
    return out


def _train_and_evaluate(
    run, data, model, seed, overrides, splits, ablation, config, details=False, keep_rollouts=False
) -> None:
    """Train the run unless trained (resuming a checkpoint), then write ``metrics_<split>.json`` per split."""
    cfg = load_config(config, overrides)
    folder = RunFolder(run, must_exist=False)
    if not folder.stats_path.is_file():
        if run.exists() and not folder.latest.is_file():
            shutil.rmtree(run)
        t0 = time.perf_counter()
        train(cfg, data, model, run, ablation=ablation, seed=seed, resume=folder.latest.is_file(), progress=False)
        print(f"  trained {run.name} in {time.perf_counter() - t0:.0f} s", flush=True)
    for s in splits:
        if folder.metrics_path(s).is_file():  # evaluated before (e.g. the sweep's validation split)
            continue
        evaluate(Run.load(run, "cpu"), data, s, progress=False)  # writes RUN/metrics_<split>.json
        if details:
            with atomic_path(run / f"details_{s}.json") as tmp:
                tmp.write_text(json.dumps(rollout_details(run, data, s), indent=2))
        if not keep_rollouts:
            folder.rollout_path(s).unlink(missing_ok=True)


def rollout_details(run: Path, data: Path, split: str) -> dict:
    """Error by node group (plate: the body holding the clamped HANDLE nodes; ball: the other body) and by
    rollout step, averaged over the split's trajectories, from the run's rollout file."""
    rows = []
    with h5py.File(RunFolder(run).rollout_path(split), "r") as f, Split(data, split) as s:
        index = {n: i for i, n in enumerate(s.names)}
        for name in f.keys():
            truth = s[index[name]]
            plate = plate_mask(truth["cells"], truth["node_type"])
            groups = {"plate": plate, "ball": ~plate}
            start = int(f[name].attrs["start"])
            pos = details(f[name]["world_pos"][()], truth["world_pos"], start, groups)
            st = details(f[name]["stress"][()], truth["stress"], start, groups)
            rows.append((pos, st))
    return {
        "groups": {
            g: {
                "position": float(np.mean([p["groups"][g] for p, _ in rows])),
                "stress": float(np.mean([t["groups"][g] for _, t in rows])),
            }
            for g in ("plate", "ball")
        },
        "position_by_step": np.mean([p["by_step"] for p, _ in rows], 0).tolist(),
        "stress_by_step": np.mean([t["by_step"] for _, t in rows], 0).tolist(),
    }


def claim(run: Path) -> bool:
    """Let several benchmark processes share the work: the first to create ``RUN.lock`` (holding its pid) owns
    the run; a lock whose process is gone is taken over."""
    return take_lock(run.parent / f"{run.name}.lock") in (None, os.getpid())


def portable(obj):
    """``obj`` (a path, a command line, or a result's dicts and lists of them) as a fresh clone reads it: every
    absolute path inside the work folder :data:`WORK` written as ``$HCMT_WORK/...``, inside the checkout relative
    to its root, so a result file records no folder of the machine that wrote it. Other values are returned as
    they are."""
    if isinstance(obj, dict):
        return {k: portable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [portable(v) for v in obj]
    if isinstance(obj, Path):
        obj = str(obj)
    if not isinstance(obj, str):
        return obj
    # the work folder first: by default it lies inside the checkout
    for root, name in ((WORK, "$HCMT_WORK"), (CHECKOUT, ".")):
        obj = re.sub(re.escape(str(root)) + r"(/|(?![\w.-]))", lambda m: name + m.group(1), obj)
    return re.sub(r"(?<![\w$.])\./(?=[\w$])", "", obj)  # ./benchmarks/x -> benchmarks/x


def write_json(name: str, obj) -> Path:
    """Write ``benchmarks/results/NAME`` (its paths :func:`portable`)."""
    RESULTS.mkdir(parents=True, exist_ok=True)
    path = RESULTS / name
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(portable(obj), indent=2))
    return path


def fmt(ms: dict) -> str:
    return f"{ms['mean']:.4g} ± {ms['std']:.2g}"
