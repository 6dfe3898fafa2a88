"""Rollout files, evaluation and comparison of trained runs (the paper's metrics and the physics an engineer reads).

Every function takes a :class:`hcmt.inference.run.Run` (checkpoint and device chosen when it was loaded) and
keyword-only options. One cache rule (:func:`rollout_for`) decides when a run's rollout file is reused.
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from pathlib import Path

import h5py
import numpy as np
from tqdm import tqdm

from hcmt.config import INFERENCE_COMPILE_MODES, MAX_BATCH, plural
from hcmt.data.format import Split, read_meta
from hcmt.data.runs import RunFolder, available_pretrained
from hcmt.domains.trajectory import load_split
from hcmt.errors import InputError, RolloutError, clip
from hcmt.files import atomic_path, ensure_space, read_json
from hcmt.inference.metrics import (
    SCALE,
    EvalMetrics,
    ImpactMetrics,
    Rmse,
    aggregate,
    format_physics,
    impact_metrics,
    rmse_units,
    rollout_rmse,
    step_rmse,
    summarize_impact,
    summarize_runs,
)
from hcmt.inference.quantities import impact_groups, plate_mask
from hcmt.inference.rollout import rollout, rollout_batch, rollout_compile
from hcmt.inference.run import Run, check_dataset, dataset_warnings, model_label


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


def evaluate(
    run: Run,
    data,
    split: str = "test",
    *,
    limit: int | None = None,
    batch: int = 1,
    compile: str = "auto",
    progress: bool = True,
) -> EvalMetrics:
    """Paper metrics (and for Impact Plate the physics metrics) of a run on a split, written to
    ``RUN/metrics_<split>.json`` (``metrics_<split>@<data name>.json`` for a dataset other than the run's own);
    rolls out first if the rollout file is missing or stale. A dataset of another frame interval is refused;
    other mismatches with the training data are recorded under ``warnings``."""
    check_options(batch=batch, compile=compile)
    folder = results_folder(run)
    warnings = dataset_warnings(run, data, split)
    meta = read_meta(data)
    path = rollout_for(run, data, split, need=limit, batch=batch, compile=compile, progress=progress)
    per_traj, ms, physics, by_step = [], [], [], defaultdict(list)
    with h5py.File(path, "r") as f, Split(data, split) as s:
        index = {n: i for i, n in enumerate(s.names)}
        for name in s.names[:limit]:  # the first `limit` trajectories (all when None), however many the file holds
            truth = s[index[name]]
            if run.adapter.stress_field in truth:  # the field the model learned (data.stress_field)
                truth["stress"] = truth[run.adapter.stress_field]
            g = f[name]
            start = int(g.attrs["start"])
            row = {"trajectory": name}
            position = rollout_rmse(g["world_pos"][()], truth["world_pos"], start)
            row.update({f"position_{k}": v for k, v in position.items()})
            if "stress" in g and "stress" in truth:
                row.update({f"stress_{k}": v for k, v in rollout_rmse(g["stress"][()], truth["stress"], start).items()})
            per_traj.append(row)
            ms.append(float(g.attrs["ms_per_step"]))
            if meta.get("dataset") == "impact_plate" and "stress" in g and "stress" in truth:
                phys, steps = impact_physics(g["world_pos"][()], g["stress"][()], truth, start)
                physics.append(phys)
                for key, curve in steps.items():
                    by_step[key].append(curve)
    means = aggregate([{k: v for k, v in r.items() if k != "trajectory"} for r in per_traj])
    for row, phys in zip(per_traj, physics):
        row["physics"] = phys.to_json()
    units = meta.get("units") or {}
    rmse = {
        q: Rmse(*(means[f"{q}_{k}"] for k in ("rmse_1", "rmse_50", "rmse_all")))
        for q in ("position", "stress")
        if f"{q}_rmse_all" in means
    }
    metrics = EvalMetrics(
        split=split,
        data=str(Path(data).resolve()),
        trajectories=len(per_traj),
        scale=SCALE,
        rmse_units=rmse_units(units),  # every RMSE (and error_by_step) is ×scale: in these units
        units={k: units[k] for k in ("length", "stress") if k in units},
        warnings=warnings,
        position=rmse.get("position"),
        stress=rmse.get("stress"),
        inference_ms_per_step=float(np.median(ms)),
        train_ms_per_step=(folder.train_stats() or {}).get("train_ms_per_step"),
        physics=summarize_impact(physics) if physics else None,
        error_by_step={k: np.mean(v, 0).tolist() for k, v in by_step.items()} if physics else None,
        per_trajectory=per_traj,
    )
    with atomic_path(folder.metrics_path(split, data)) as tmp:  # one file per split: never overwrites another's
        tmp.write_text(json.dumps(metrics.to_json(), indent=2))
    return metrics


def validation_rmse(model, adapter, trajs, radius: float) -> dict:
    """Mean RMSE-all of validation rollouts (training's best.pt criterion); a diverging rollout counts as infinite
    error (early training)."""
    pos, stress = [], []
    for tr in trajs:
        try:
            r = rollout(model, adapter, tr, radius)
        except RolloutError:
            pos.append(math.inf)
            stress.append(math.inf)
            continue
        pos.append(rollout_rmse(r["world_pos"].numpy(), tr.world_pos.numpy(), r["start"])["rmse_all"])
        if r["stress"] is not None:
            stress.append(rollout_rmse(r["stress"].numpy(), tr.stress.numpy(), r["start"])["rmse_all"])
    out = {"valid/position_rmse_all": float(np.mean(pos))}
    if stress:
        out["valid/stress_rmse_all"] = float(np.mean(stress))
    return out


def impact_physics(pos, stress, truth: dict, start: int) -> tuple[ImpactMetrics, dict]:
    """(:func:`hcmt.inference.metrics.impact_metrics`, the position and stress error by step (×10³) of the ball, the
    contact zone and the far plate) of one Impact Plate rollout against its trajectory ``truth``."""
    plate = plate_mask(truth["cells"], truth["node_type"])
    groups = impact_groups(np.asarray(truth["world_pos"][0]), plate)
    steps = {}
    for q, pred, true in (("position", pos, truth["world_pos"]), ("stress", stress, truth["stress"])):
        for g, mask in groups.items():
            steps[f"{q}_{g}"] = (step_rmse(pred[:, mask], true[:, mask])[start:] * SCALE).tolist()
    return impact_metrics(pos, stress, truth["world_pos"], truth["stress"], plate, start), steps


def format_metrics(m: EvalMetrics) -> str:
    """The RMSE table at the scale metrics_<split>.json stores it (the paper's ×10³, in :func:`rmse_units`)."""
    units = rmse_units(m.units or {})
    lines = [
        f"split {m.split}: {plural(m.trajectories, 'trajectory', 'trajectories')}, "
        f"RMSE ×{SCALE:g} over the rollout's steps 1, 1-50 and all (as metrics_{m.split}.json stores it)",
        f"  {'':<20}{'rmse_1':>12}{'rmse_50':>12}{'rmse_all':>12}",
    ]
    for q, r in (("position", m.position), ("stress", m.stress)):
        if r is not None:
            name = f"{q} [{units[q]}]"
            lines.append(f"  {name:<20}" + "".join(f"{v:>12.4g}" for v in (r.rmse_1, r.rmse_50, r.rmse_all)))
    lines.append(
        f"  inference {m.inference_ms_per_step:.2f} ms/step"
        + (f", training {m.train_ms_per_step:.2f} ms/step" if m.train_ms_per_step else "")
    )
    if m.physics is not None:
        lines += format_physics(m.physics)
    return "\n".join(lines)


def compare(runs: list[str | Path | RunFolder | Run], split: str = "test") -> dict:
    """{label: {quantity: {metric: {mean, std, n}}}} over seeds of one split. Runs are grouped by model (+ ablation)
    and by the dataset they were evaluated on: runs of different datasets are never averaged together (the label
    then names the dataset)."""
    groups: dict[tuple[str, str], list[dict]] = defaultdict(list)
    for run in runs:
        folder = run.require_folder() if isinstance(run, Run) else run if isinstance(run, RunFolder) else RunFolder(run)
        mpath = folder.metrics_path(split)
        if not mpath.is_file():
            raise FileNotFoundError(f"{mpath}: run `hcmt evaluate {folder.path} --data ... --split {split}` first")
        m = read_json(mpath, f"`hcmt evaluate {folder.path} --split {split}`")
        if folder.info is None:  # a shipped model's results folder (Run.writing_to) has no run.yaml
            raise InputError(
                f"{folder.path}: no run.yaml (a shipped model's results, or a damaged run folder); "
                "hcmt compare takes run folders made by `hcmt train`"
            )
        groups[(model_label(folder.info["model"], folder.info.get("config")), m.get("data", "?"))].append(m)
    datasets = {d for _, d in groups}
    return {
        (label if len(datasets) == 1 else f"{label} [{Path(d).name}]"): summarize_runs(ms)
        for (label, d), ms in groups.items()
    }


def format_compare(table: dict) -> str:
    head = f"{'Model':<24}{'Position RMSE-all':>24}{'Stress RMSE-all':>24}{'Position RMSE-1':>20}  seeds"
    lines = [
        "RMSE x1e3 in the data's units (Impact Plate: position 1e-3 mm = µm, stress 1e-3 MPa = kPa), "
        "mean ± std over seeds (paper Table 2 layout)",
        head,
    ]
    for label, row in table.items():

        def cell(q, k, w):
            if q not in row:
                return f"{'-':>{w}}"
            return f"{row[q][k]['mean']:>{w - 10}.4g} ± {row[q][k]['std']:<7.3g}"

        n = row["inference_ms_per_step"]["n"]
        lines.append(
            f"{label:<24}{cell('position', 'rmse_all', 24)}{cell('stress', 'rmse_all', 24)}"
            f"{cell('position', 'rmse_1', 20)}  {n}"
        )
    return "\n".join(lines)
