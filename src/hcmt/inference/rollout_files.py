"""Rollout files: a run's predictions over a split rolled out once into ``RUN/rollout_<split>.h5``, keyed by dataset,
split and checkpoint, and reused by one cache rule (:func:`rollout_for`); the folder they go to refused when it
holds another model's results.

It stands alone from :mod:`hcmt.inference.evaluate` because evaluation is one of its readers: every picture and
``hcmt rollout`` read the same files without measuring anything.
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import h5py
from tqdm import tqdm

from hcmt.config import INFERENCE_COMPILE_MODES, MAX_BATCH
from hcmt.data.format import Split
from hcmt.data.runs import RunFolder, available_pretrained
from hcmt.domains.trajectory import load_split
from hcmt.errors import InputError, clip
from hcmt.files import atomic_path, ensure_space
from hcmt.inference.rollout import rollout_batch, rollout_compile
from hcmt.inference.run import Run, check_dataset


def check_options(*, batch: int = 1, compile: str = "none") -> None:
    """Refuse bad rollout options in one line before any cache is consulted or work done."""
    if isinstance(batch, bool) or not isinstance(batch, int) or not 1 <= batch <= MAX_BATCH:
        raise InputError(f"must be a whole number from 1 to {MAX_BATCH:,}, got {clip(batch)}", param="batch")
    if compile not in INFERENCE_COMPILE_MODES:
        raise InputError(f"must be one of {', '.join(INFERENCE_COMPILE_MODES)}, got {compile!r}", param="compile")


def check_results_folder(path, source: str) -> None:
    """Refuse (one line, ``param="out"``) a folder that a shipped model (``source`` ``pretrained:NAME``) is to write
    its rollouts and metrics to when it holds another model's: a run folder (``run.yaml`` or a checkpoint: its own
    ``metrics_<split>.json`` would be replaced by the shipped model's, and ``hcmt compare`` would show them as the
    run's), or rollouts made by another checkpoint. A run folder writing to itself is not checked."""
    if not str(source).startswith("pretrained:") or path is None or not Path(path).is_dir():
        return
    folder = RunFolder(path, must_exist=False)
    if folder.holds_run() or folder.damaged:
        held = folder.run_yaml.name if folder.run_yaml.is_file() else folder.latest.name
        raise InputError(
            f"{path}: a run folder of another model ({held}); {clip(source)}'s rollouts and metrics "
            "would replace its own: choose another folder",
            param="out",
        )
    shipped = available_pretrained().get(str(source).split(":", 1)[1])
    for p in sorted(folder.path.glob("rollout_*.h5")):
        try:
            with h5py.File(p, "r") as f:
                made_by = f.attrs.get("checkpoint")
        except OSError:
            continue  # a damaged rollout file is rolled out again (rollout_for)
        made_by = made_by.decode() if isinstance(made_by, bytes) else made_by
        if made_by is not None and shipped is not None and str(made_by) != Path(shipped).name:
            raise InputError(
                f"{path}: holds {p.name} of another model ({clip(str(made_by))}); {clip(source)}'s "
                "rollouts and metrics would replace it: choose another folder",
                param="out",
            )


def results_folder(run: Run) -> RunFolder:
    """The folder a run's rollouts and metrics go to (:meth:`Run.require_folder`), checked by
    :func:`check_results_folder`."""
    folder = run.require_folder()
    check_results_folder(folder.path, run.source)
    return folder


def rollout_key(data, split: str, run: Run) -> dict:
    """What a rollout file was made from: dataset, split and checkpoint (file and step)."""
    return {
        "data": str(Path(data).resolve()),
        "split": split,
        "checkpoint": run.info.checkpoint.file,
        "checkpoint_step": run.checkpoint_step,
    }


def run_rollouts(
    run: Run,
    data,
    split: str,
    *,
    limit: int | None = None,
    batch: int = 1,
    compile: str = "auto",
    progress: bool = True,
) -> Path:
    """Roll the run's model out over a split; predictions go to ``RUN/rollout_<split>.h5`` (``rollout_<split>@<data
    name>.h5`` for a dataset other than the run's own), atomically. ``batch`` trajectories of equal length step
    together as one batched graph. The progress bar counts model steps over the whole split (with an ETA)."""
    check_options(batch=batch, compile=compile)
    folder = results_folder(run)
    check_dataset(run.meta, data)
    levels, remesh = run.hierarchy_spec
    trajs = load_split(data, split, run.adapter, levels, remesh, limit=limit)
    path = folder.rollout_path(split, data)
    h = run.adapter.history
    total = sum(max(tr.num_steps - 1 - h, 0) for tr in trajs)
    compile = rollout_compile(compile, run.model, total)  # auto: once, for the whole split
    bar = tqdm(total=total, desc=f"rollout {split}", unit="step", dynamic_ncols=True, disable=not progress)
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        for key, value in rollout_key(data, split, run).items():
            f.attrs[key] = value
        by_length: dict[int, list] = defaultdict(list)
        for tr in trajs:
            by_length[tr.num_steps].append(tr)
        for group in by_length.values():
            for first in range(0, len(group), batch):
                chunk = group[first : first + batch]
                results = rollout_batch(
                    run.model,
                    run.adapter,
                    chunk,
                    run.radius,
                    compile=compile,
                    progress=lambda n, k=len(chunk): bar.update(n * k),
                )
                for tr, res in zip(chunk, results):
                    ensure_space(path, res["world_pos"].numel() * 4 * 2)
                    g = f.create_group(tr.name)
                    g["world_pos"] = res["world_pos"].numpy()
                    if res["stress"] is not None:
                        g["stress"] = res["stress"].numpy()
                    g.attrs["ms_per_step"] = res["ms_per_step"]
                    g.attrs["start"] = res["start"]
    bar.close()
    return path


def rollout_for(
    run: Run, data, split: str, *, need: int | None = None, batch: int = 1, compile: str = "auto", progress: bool = True
) -> Path:
    """The one rollout-cache rule, used by evaluation and every picture: ``RUN/rollout_<split>.h5`` is reused when
    it was made from this dataset, split and checkpoint (same step) and holds the first ``need`` trajectories of
    the split (all when ``need`` is None); otherwise it is rolled out again, never with fewer trajectories than the
    file had. Options are checked first, whatever the cache holds; the file of a dataset other than the run's own
    is ``rollout_<split>@<data name>.h5``."""
    check_options(batch=batch, compile=compile)
    path = results_folder(run).rollout_path(split, data)
    with Split(data, split) as s:
        names = s.names
    want = len(names) if need is None else min(int(need), len(names))
    have = 0
    if path.is_file():
        with h5py.File(path, "r") as f:
            attrs = {k: (v.item() if hasattr(v, "item") else v) for k, v in f.attrs.items()}
            if all(attrs.get(k) == v for k, v in rollout_key(data, split, run).items()):
                have = len(f.keys())
                if set(names[:want]) <= set(f.keys()):
                    return path
    limit = max(want, have)
    return run_rollouts(
        run, data, split, limit=limit if limit < len(names) else None, batch=batch, compile=compile, progress=progress
    )


def rollout_file(run: Run | RunFolder, data, split: str, *, need: int | None = None, progress: bool = True) -> Path:
    """The rollout file the pictures read: a :class:`Run`'s by :func:`rollout_for` (rolled out when missing or
    stale); a bare :class:`RunFolder` (predictions brought from elsewhere, no checkpoint) has its file used as it
    is, and must hold the first ``need`` trajectories (all when None)."""
    if isinstance(run, Run):
        return rollout_for(run, data, split, need=need, progress=progress)
    path = run.rollout_path(split, data)
    with Split(data, split) as s:
        names = s.names[:need]
    held = set()
    if path.is_file():
        with h5py.File(path, "r") as f:
            held = set(f.keys())
    if not set(names) <= held:
        raise FileNotFoundError(
            f"{path}: holds {len(held & set(names))} of the {len(names)} trajectories asked for, "
            f"and {run.path} has no checkpoint to roll them out"
        )
    return path
