"""Any generator's dataset writing (:func:`write_dataset`: the Impact Plate's and the Deforming Plate's), parallel,
resumable and locked:

* trajectory ``i`` of split ``s`` draws its design from ``SeedSequence([seed, code(s), i])``
  (:func:`trajectory_rng`), so the output is identical whatever the worker count or order;
* each finished trajectory is written atomically to ``OUT/.parts/<split>/<i>.h5``; a rerun skips existing parts;
* when a split is complete its parts are assembled atomically into ``OUT/<split>.h5`` and then removed; an
  interruption at any point leaves either complete files or nothing (never a half-written file);
* one generate at a time writes a folder: it holds ``OUT/.generate.lock`` (``flock``, released when it ends or is
  killed); a second one is refused naming the first one's pid, and a reader of the unfinished dataset is told that a
  generate is writing it (else, that an interrupted one can be rerun).

It stands apart from the generators (:mod:`hcmt.sim.generate`, :mod:`hcmt.sim.deforming_data`) because it knows no
problem: a job is a top-level ``trajectory(meta, preset, seed, split, index, settings) -> (fields, attrs)``
function, and how its files are written, resumed and grown is the same for every dataset.
"""

from __future__ import annotations

import multiprocessing as mp
import shutil
import signal
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

import h5py
import numpy as np
from tqdm import tqdm

from hcmt.config import MAX_TRAJECTORIES, machine_cores
from hcmt.data.format import GENERATE_LOCK, read_meta, write_meta, write_split
from hcmt.errors import DatasetError, InputError
from hcmt.files import folder_lock

#: Split names and their stable codes in the per-trajectory seed.
SPLITS = ("train", "valid", "test", "test_thicker", "test_higher", "test_thicker_higher")


def trajectory_rng(seed: int, split: str, index: int) -> np.random.Generator:
    """The generator of trajectory ``index`` of ``split``: independent of worker count and order."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), SPLITS.index(split), int(index)]))


def trajectory_name(index: int) -> str:
    return f"traj_{index:05d}"


def _run_one(task: tuple) -> tuple[str, int]:
    """Worker: simulate one trajectory with the task's top-level ``trajectory`` function (``(meta, preset, seed,
    split, index, settings) -> (fields, attrs)``) and write its part file atomically (spawn-safe, top level)."""
    out, meta, preset, seed, split, index, settings, trajectory = task
    fields, attrs = trajectory(meta, preset, seed, split, index, settings)
    part = Path(out) / ".parts" / split / f"{index:05d}.h5"
    part.parent.mkdir(parents=True, exist_ok=True)
    write_split(part, meta, [(trajectory_name(index), fields, attrs)])
    return split, index


def _ignore_sigint() -> None:
    """Pool workers leave Ctrl-C to the parent, which stops the pool and says what was kept."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _split_complete(path: Path, count: int) -> bool:
    if not path.is_file():
        return False
    try:
        with h5py.File(path, "r") as f:
            return int(f.attrs.get("num_trajectories", -1)) == count and len(f.keys()) == count
    except OSError:
        return False


def _existing(path: Path) -> int:
    """Trajectories of a complete split file (0 when missing or unreadable)."""
    if not path.is_file():
        return 0
    try:
        with h5py.File(path, "r") as f:
            n = int(f.attrs.get("num_trajectories", -1))
            return n if n == len(f.keys()) else 0
    except OSError:
        return 0


def _assemble(out: Path, meta: dict, split: str, count: int) -> Path:
    """Write ``OUT/<split>.h5`` from its parts and, when the dataset grows, the trajectories already in the old
    split file (atomically), then remove the parts."""
    parts = out / ".parts" / split
    old = out / f"{split}.h5"
    have = _existing(old)

    def trajectories():
        for i in range(count):  # one trajectory in memory at a time
            src = parts / f"{i:05d}.h5"
            with h5py.File(src if src.is_file() or i >= have else old, "r") as f:
                g = f[trajectory_name(i)]
                yield trajectory_name(i), {k: g[k][()] for k in g.keys()}, dict(g.attrs)

    path = write_split(old, meta, trajectories())
    shutil.rmtree(parts, ignore_errors=True)
    return path


def _differences(old: dict, new: dict, prefix: str = "") -> str:
    """``seed 1 there, 2 asked; settings.frames 90 there, 52 asked``: what differs between two generator blocks."""
    out = []
    for k in sorted(set(old) | set(new)):
        a, b = old.get(k), new.get(k)
        if isinstance(a, dict) and isinstance(b, dict):
            inner = _differences(a, b, f"{prefix}{k}.")
            out += [inner] if inner else []
        elif a != b:
            out.append(f"{prefix}{k} {a} there, {b} asked")
    return "; ".join(out)


def write_dataset(out, meta: dict, counts: dict[str, int], job: tuple, workers: int, progress: bool, desc: str) -> dict:
    """Write (or finish) the dataset ``meta`` describes in ``out``, one part file per trajectory: ``job`` is
    ``(preset, seed, settings dict, trajectory function)`` (:func:`_run_one`). Any problem's generator: resumable,
    parallel, locked, grown only with the same generator settings."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: is a file; name a folder for the dataset", param="out")
    if (out / "meta.json").is_file():
        _check_growth(out, read_meta(out), meta, counts)
    with _locked(out):
        if (out / "meta.json").is_file():  # again under the lock: a generate that just ended may have grown it
            _check_growth(out, read_meta(out), meta, counts)
        write_meta(out, meta)
        todo, done_splits, skipped = _tasks(out, meta, counts, job)
        _run_all(todo, workers, progress, desc)
        for split, n in counts.items():
            if split not in done_splits:
                done_splits[split] = _assemble(out, meta, split, n)
        parts = out / ".parts"
        if parts.is_dir() and not any(parts.iterdir()):
            parts.rmdir()
    return dict(simulated=len(todo), skipped=skipped, splits=done_splits)


@contextmanager
def _locked(out: Path) -> Iterator[None]:
    """Hold the dataset folder's generate lock (:data:`hcmt.data.format.GENERATE_LOCK`, made with the folder when
    missing): a second generate on it is refused in one line naming the first one's pid. When the block fails
    before meta.json is written (a refusal), the folders this call made are removed again: nothing is left."""
    made = [p for p in (out, *out.parents) if not p.exists()]
    out.mkdir(parents=True, exist_ok=True)

    def busy(pid: int) -> InputError:
        return InputError(f"{out}: a generate is writing it (pid {pid}); wait for it or stop it")

    try:
        with folder_lock(out / GENERATE_LOCK, busy):
            yield
    except BaseException:
        for p in made:  # innermost first; each only when empty (an interrupted generate keeps its .parts)
            if p.is_dir() and not any(p.iterdir()):
                p.rmdir()
        raise


def checked_counts(counts: dict[str, int], workers: int, splits: tuple[str, ...] = SPLITS) -> dict[str, int]:
    """The positive trajectory counts, after refusing an unknown split, a count out of bounds, a worker count
    beyond the machine's cores, or nothing to do (each in one line naming its parameter)."""
    for split, n in counts.items():
        if split not in splits:
            raise InputError(f"unknown split {split!r}; expected one of {splits}")
        if not 0 <= int(n) <= MAX_TRAJECTORIES:
            raise InputError(f"{split}: expected 0 to {MAX_TRAJECTORIES:,} trajectories, got {n}", param="counts")
    if not 1 <= int(workers) <= machine_cores():
        raise InputError(f"must be 1 to this machine's {machine_cores()} cores, got {workers}", param="workers")
    counts = {k: int(v) for k, v in counts.items() if int(v) > 0}
    if not counts:
        raise InputError("nothing to generate: every trajectory count (train, valid, test) is 0")
    return counts


def _check_growth(out: Path, old: dict, meta: dict, counts: dict[str, int]) -> None:
    """Refuse to write into a dataset generated with other settings, or to shrink one of its splits."""
    old_gen, new_gen = dict(old.get("generator") or {}), dict(meta["generator"])
    old_counts, _ = old_gen.pop("counts", {}), new_gen.pop("counts")
    if old_gen != new_gen:
        raise DatasetError(
            f"holds a dataset generated with other settings ({_differences(old_gen, new_gen)}); "
            "rerun with the dataset's own settings or choose another output folder",
            file=out / "meta.json",
        )
    fewer = {k: v for k, v in old_counts.items() if counts.get(k, 0) < v}
    if fewer:
        k, v = next(iter(fewer.items()))
        raise DatasetError(
            f"holds {v} {k} trajectories; asking for {counts.get(k, 0)} would drop some. A dataset "
            "only grows (trajectory i of a split depends on seed, split and i alone): ask for at "
            "least as many, or choose another output folder",
            file=out / "meta.json",
        )


def _tasks(out: Path, meta: dict, counts: dict[str, int], job: tuple) -> tuple[list[tuple], dict[str, Path], int]:
    """(the trajectories still to simulate, as :func:`_run_one` tasks; the splits already complete; how many
    trajectories are done). A complete split's leftover parts are removed."""
    todo, done_splits, skipped = [], {}, 0
    for split, n in counts.items():
        if _split_complete(out / f"{split}.h5", n):
            done_splits[split] = out / f"{split}.h5"
            shutil.rmtree(out / ".parts" / split, ignore_errors=True)
            skipped += n
            continue
        have = _existing(out / f"{split}.h5")  # a smaller complete split file: the dataset is growing
        for i in range(n):
            if i < have or (out / ".parts" / split / f"{i:05d}.h5").is_file():
                skipped += 1
            else:
                preset, seed, settings, trajectory = job
                todo.append((str(out), meta, preset, seed, split, i, settings, trajectory))
    return todo, done_splits, skipped


def _run_all(todo: list[tuple], workers: int, progress: bool, desc: str) -> None:
    """Run the tasks, in this process or a pool of ``workers`` spawned ones (Ctrl-C reaches this process only)."""
    bar = tqdm(total=len(todo), desc=desc, unit="traj", disable=not progress or not todo)
    if workers == 1 or len(todo) <= 1:
        for task in todo:
            _run_one(task)
            bar.update(1)
    else:
        with mp.get_context("spawn").Pool(min(int(workers), len(todo)), initializer=_ignore_sigint) as pool:
            for _ in pool.imap_unordered(_run_one, todo):
                bar.update(1)
    bar.close()
