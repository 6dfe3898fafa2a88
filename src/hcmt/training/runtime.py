"""The training run's plumbing: processes (torchrun / DDP), Ctrl-C, the run folder's lock and checkpoints,
rank-zero logging, and the exact-resume check."""
from __future__ import annotations

import contextlib
import io
import logging
import math
import os
import signal
import threading
from pathlib import Path

import torch
import torch.distributed as dist
import yaml

from hcmt.domains.adapters import own_args
from hcmt.errors import InputError
from hcmt.files import atomic_path, take_lock


def check_resume(saved: dict, run: dict, out: Path) -> None:
    """An exact continuation needs the settings the run started with; only ``train.steps`` may grow (the
    learning-rate schedule then stretches to the new length)."""
    def strip(r):
        # both read through Config; the model's arguments less those it does not take (runs saved before
        # hcmt.domains.adapters.MODEL_KEYS kept every model's)
        r = yaml.safe_load(yaml.safe_dump(dict(r, config=r["config"].to_dict(), model=own_args(r["model"]))))
        r["config"]["train"].pop("steps", None)
        return r

    a, b = strip(saved), strip(run)
    changed = []
    for k in ("model", "config", "seed", "world_size"):
        changed += _differences(a.get(k, b[k]), b[k], k)
    if changed:
        raise InputError(f"{out}: resuming with other settings than the run was started with: {'; '.join(changed)} "
                         f"(see {out / 'run.yaml'}); `hcmt train --resume --out {out}` alone resumes with the saved "
                         "settings")


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
            raise InputError(f"{world} training processes but {gpus} GPU(s): NCCL needs one GPU per process; use "
                             f"torchrun --nproc_per_node={gpus}, or run on the CPU (CUDA_VISIBLE_DEVICES= gives gloo)")
        if not dist.is_initialized():
            dist.init_process_group("nccl" if gpus else "gloo")
        return dist.get_rank(), dist.get_world_size()
    return 0, 1


def lock_run(out: Path) -> Path:
    """``RUN/.lock`` holding our pid (:func:`hcmt.data.format.take_lock`); a second writer is refused."""
    lock = out / ".lock"
    holder = take_lock(lock)
    if holder is not None:
        raise InputError(f"{out} is being written by another training process (pid {holder}, {lock}); wait for "
                         "it or choose another run folder")
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


@contextlib.contextmanager
def deterministic_scope():
    """Restore torch's deterministic-algorithm and cuDNN settings on exit (``train.deterministic`` is per run)."""
    saved = (torch.are_deterministic_algorithms_enabled(), torch.is_deterministic_algorithms_warn_only_enabled(),
             torch.backends.cudnn.benchmark)
    try:
        yield
    finally:
        torch.use_deterministic_algorithms(saved[0], warn_only=saved[1])
        torch.backends.cudnn.benchmark = saved[2]
