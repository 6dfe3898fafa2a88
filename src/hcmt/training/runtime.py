"""The training run's plumbing: processes (torchrun / DDP), Ctrl-C, the run folder's lock and checkpoints,
rank-zero logging, TensorBoard scalars, step times, and the exact-resume check.

Several processes: under ``torchrun`` (``WORLD_SIZE`` set by it) training uses DistributedDataParallel with gloo on
CPU and NCCL on GPU; each rank takes its share of the shared permutation. DDP broadcasts buffers from rank 0 at
every forward, so the normalizers' statistics are rank 0's (a sample of the data, like any running statistic) and
every rank normalizes its inputs alike; a non-finite loss on any rank stops all of them (:func:`stop_together`).
Validation rollouts run on rank 0 while the others wait in the next all-reduce (keep them shorter than the backend's
timeout)."""

from __future__ import annotations

import contextlib
import io
import json
import logging
import math
import os
import signal
import threading
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch
import torch.distributed as dist
import yaml

from hcmt.errors import InputError
from hcmt.files import atomic_path, take_lock
from hcmt.models import architecture
from hcmt.training.policy import policy_of


def check_resume(saved: dict, run: dict, out: Path) -> None:
    """An exact continuation needs the settings the run started with; only ``train.steps`` may grow (the
    learning-rate schedule then stretches to the new length)."""

    def strip(r):
        policy = asdict(policy_of(r["config"].train))  # the loop's conventions, named by the policy or key by key
        r = dict(r, config=r["config"].to_dict(), model=architecture(r["model"]))  # older runs saved more
        r = yaml.safe_load(yaml.safe_dump(r))  # both read through Config
        r["config"]["train"].pop("steps", None)
        r["config"]["train"].pop("policy", None)
        r["config"]["train"].update(policy)
        return r

    a, b = strip(saved), strip(run)
    changed = []
    for k in ("model", "config", "seed", "world_size"):
        changed += _differences(a.get(k, b[k]), b[k], k)
    if changed:
        raise InputError(
            f"{out}: resuming with other settings than the run was started with: {'; '.join(changed)} "
            f"(see {out / 'run.yaml'}); `hcmt train --resume --out {out}` alone resumes with the saved "
            "settings"
        )


def _differences(a, b, key: str) -> list[str]:
    """``key.sub: saved -> now`` for every leaf that differs."""
    if isinstance(a, dict) and isinstance(b, dict):
        return [d for k in sorted(set(a) | set(b)) for d in _differences(a.get(k), b.get(k), f"{key}.{k}")]
    return [] if a == b else [f"{key}: {a!r} (run) vs {b!r} (now)"]


class TrainingInterrupted(KeyboardInterrupt):
    """Training stopped on Ctrl-C / SIGTERM after saving a checkpoint; the message says where."""


class InterruptFlag:
    """SIGINT and SIGTERM set ``self.set`` instead of raising mid-step (a half-done optimizer step must never be
    saved); the loop checks it after each step. Installed only in the main thread; ``restore`` puts the previous
    handlers back."""

    def __init__(self):
        self.set, self._old = False, {}
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old[sig] = signal.signal(sig, self._handle)

    def _handle(self, signum, frame):
        self.set = True

    def restore(self) -> None:
        for sig, handler in self._old.items():
            signal.signal(sig, handler)
        self._old = {}


def rewrite_log(path: Path, records: list[dict]) -> None:
    """``log.jsonl`` holding ``records`` only (a resumed run drops what was logged after its checkpoint)."""
    with atomic_path(path) as tmp:
        tmp.write_text("".join(json.dumps(r) + "\n" for r in records))


def save_atomic(obj, path: Path) -> None:
    """torch.save through memory, then a plain write: a full disk raises ``OSError`` naming the path."""
    buffer = io.BytesIO()
    torch.save(obj, buffer)
    with atomic_path(path) as tmp:
        tmp.write_bytes(buffer.getbuffer())


def distributed() -> tuple[int, int]:
    """(rank, world size). Under torchrun: NCCL with one GPU per process; more processes than GPUs is refused with
    one line (NCCL cannot put two ranks on one GPU); without CUDA, gloo on the CPU."""
    if "WORLD_SIZE" in os.environ and int(os.environ["WORLD_SIZE"]) > 1:  # launched by torchrun
        world = int(os.environ["WORLD_SIZE"])
        gpus = torch.cuda.device_count() if torch.cuda.is_available() else 0
        if gpus and world > gpus:
            raise InputError(
                f"{world} training processes but {gpus} GPU(s): NCCL needs one GPU per process; use "
                f"torchrun --nproc_per_node={gpus}, or run on the CPU (CUDA_VISIBLE_DEVICES= gives gloo)"
            )
        if not dist.is_initialized():
            dist.init_process_group("nccl" if gpus else "gloo")
        return dist.get_rank(), dist.get_world_size()
    return 0, 1


def lock_run(out: Path) -> Path:
    """``RUN/.lock`` holding our pid (:func:`hcmt.files.take_lock`); a second writer is refused."""
    lock = out / ".lock"
    holder = take_lock(lock)
    if holder is not None:
        raise InputError(
            f"{out} is being written by another training process (pid {holder}, {lock}); wait for "
            "it or choose another run folder"
        )
    return lock


def rank_zero_logging(rank: int, log_file: Path) -> logging.Handler | None:
    """Rank 0 logs INFO messages of ``hcmt.*`` to ``RUN/train.log`` (the terminal keeps its progress bar and
    warnings); other ranks log warnings only. Returns the handler to remove at the end."""
    root = logging.getLogger("hcmt")
    if rank != 0:
        root.setLevel(logging.WARNING)
        return None
    root.setLevel(logging.INFO)
    handler = logging.FileHandler(log_file)
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(message)s"))
    root.addHandler(handler)
    return handler


def stop_together(world: int, device: torch.device, loss: float, interrupted: bool) -> tuple[bool, bool]:
    """(finite, stop) agreed by every rank, or the others would hang in the next all-reduce."""
    if world == 1:
        return math.isfinite(loss), interrupted
    flag = torch.tensor([0.0 if math.isfinite(loss) else 1.0, float(interrupted)], device=device)
    dist.all_reduce(flag)
    return flag[0].item() == 0, flag[1].item() > 0


def deterministic_kernels() -> None:
    """``train.deterministic``: deterministic CUDA kernels and cuBLAS workspace (the cuBLAS setting is read when
    its handle is created: in a process that used CUDA before, export ``CUBLAS_WORKSPACE_CONFIG=:4096:8`` before
    starting it); :func:`deterministic_scope` restores the settings after the run."""
    os.environ.setdefault("CUBLAS_WORKSPACE_CONFIG", ":4096:8")
    torch.use_deterministic_algorithms(True)
    torch.backends.cudnn.benchmark = False


@contextlib.contextmanager
def deterministic_scope():
    """Restore torch's deterministic-algorithm and cuDNN settings on exit (``train.deterministic`` is per run)."""
    saved = (
        torch.are_deterministic_algorithms_enabled(),
        torch.is_deterministic_algorithms_warn_only_enabled(),
        torch.backends.cudnn.benchmark,
    )
    try:
        yield
    finally:
        torch.use_deterministic_algorithms(saved[0], warn_only=saved[1])
        torch.backends.cudnn.benchmark = saved[2]


class _NoScalars:
    """Stands in for TensorBoard's ``SummaryWriter`` when tensorboard is not installed: writes nothing (the
    scalars are in log.jsonl all the same)."""

    def add_scalar(self, *args, **kwargs) -> None:
        pass

    def close(self) -> None:
        pass


_no_tensorboard_said = False  # the info line that no TensorBoard scalars are written: once per process


def summary_writer(folder: Path, purge_step: int | None):
    """TensorBoard's ``SummaryWriter`` on ``folder`` (``tb/``), or :class:`_NoScalars` without the ``tensorboard``
    extra (``pip install 'hcmt[tensorboard]'``)."""
    try:
        from torch.utils.tensorboard import SummaryWriter
    except ImportError:
        return _NoScalars()
    return SummaryWriter(str(folder), purge_step=purge_step)


def say_no_tensorboard(writer) -> None:
    """Log once per process that ``writer`` is :class:`_NoScalars`."""
    if isinstance(writer, _NoScalars):
        _say_no_tensorboard()


def _say_no_tensorboard() -> None:
    global _no_tensorboard_said
    if not _no_tensorboard_said:
        _no_tensorboard_said = True
        logging.getLogger("hcmt.train").info(
            "no TensorBoard scalars: tensorboard is not installed (pip install 'hcmt[tensorboard]'); log.jsonl has them"
        )


def step_times(times: list[tuple[float, float]]) -> dict:
    """Median wall time and CPU time (this process, all its threads: robust to other load on one thread) per step,
    in ms, of ``(wall s, cpu s)`` pairs."""
    wall, cpu = (1e3 * float(np.median([t[k] for t in times])) if times else None for k in (0, 1))
    return {"ms_per_step": wall, "cpu_ms_per_step": cpu}


def run_summary(steps: int, loss: float, times: list, best: float, world: int, device: torch.device) -> dict:
    """The training summary (``train_stats.json``, what :func:`hcmt.training.train` returns): steps done, the last
    loss, step times (:func:`step_times`), the best validation position RMSE-all (None before any), processes and
    device."""
    return {
        "steps": steps,
        "final_loss": loss,
        **{f"train_{k}": v for k, v in step_times(times).items()},
        "best_valid_position_rmse_all": best if math.isfinite(best) else None,
        "world_size": world,
        "device": str(device),
    }
