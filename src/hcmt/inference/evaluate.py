"""Evaluation and comparison of trained runs (the paper's metrics and the physics an engineer reads).

Every function takes a :class:`hcmt.inference.run.Run` (checkpoint and device chosen when it was loaded) and
keyword-only options. The rollouts measured are the run's rollout files (:mod:`hcmt.inference.rollout_files`: one
cache rule, :func:`~hcmt.inference.rollout_files.rollout_for`, decides when a run's rollout file is reused).
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from pathlib import Path

import h5py
import numpy as np

from hcmt.config import plural
from hcmt.data.format import Split, read_meta
from hcmt.data.runs import RunFolder
from hcmt.errors import InputError, RolloutError
from hcmt.files import atomic_path, read_json
from hcmt.inference.metrics import (
    SCALE,
    EvalMetrics,
    Rmse,
    TrajectoryMetrics,
    aggregate,
    rmse_units,
    rollout_rmse,
    step_rmse,
    summarize_runs,
)
from hcmt.inference.physics import ImpactMetrics, format_physics, impact_metrics, summarize_impact
from hcmt.inference.quantities import impact_groups, plate_mask
from hcmt.inference.rollout import rollout
from hcmt.inference.rollout_files import check_options, results_folder, rollout_for
from hcmt.inference.run import Run, dataset_warnings, model_label


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
    rows: list[TrajectoryMetrics] = []
    ms: list[float] = []
    by_step: dict[str, list[list[float]]] = defaultdict(list)
    with h5py.File(path, "r") as f, Split(data, split) as s:
        index = {n: i for i, n in enumerate(s.names)}
        for name in s.names[:limit]:  # the first `limit` trajectories (all when None), however many the file holds
            truth = s[index[name]]
            if run.adapter.stress_field in truth:  # the field the model learned (data.stress_field)
                truth["stress"] = truth[run.adapter.stress_field]
            g = f[name]
            row, steps = _trajectory_metrics(name, g, truth, meta.get("dataset") == "impact_plate")
            ms.append(float(g.attrs["ms_per_step"]))
            for key, curve in steps.items():
                by_step[key].append(curve)
            rows.append(row)
    physics = [r.physics for r in rows if r.physics is not None]
    units = meta.get("units") or {}

    def mean(quantity: str) -> Rmse | None:  # over trajectories; None unless every trajectory has that RMSE
        each = [getattr(row, quantity) for row in rows]
        return None if any(r is None for r in each) else Rmse(**aggregate([r.to_json() for r in each]))

    metrics = EvalMetrics(
        split=split,
        data=str(Path(data).resolve()),
        trajectories=len(rows),
        scale=SCALE,
        rmse_units=rmse_units(units),  # every RMSE (and error_by_step) is ×scale: in these units
        units={k: units[k] for k in ("length", "stress") if k in units},
        warnings=warnings,
        position=mean("position"),
        stress=mean("stress"),
        inference_ms_per_step=float(np.median(ms)),
        train_ms_per_step=(folder.train_stats() or {}).get("train_ms_per_step"),
        physics=summarize_impact(physics) if physics else None,
        error_by_step={k: np.mean(v, 0).tolist() for k, v in by_step.items()} if physics else None,
        per_trajectory=rows,
    )
    with atomic_path(folder.metrics_path(split, data)) as tmp:  # one file per split: never overwrites another's
        tmp.write_text(json.dumps(metrics.to_json(), indent=2))
    return metrics


def _trajectory_metrics(
    name: str, g: h5py.Group, truth: dict, impact: bool
) -> tuple[TrajectoryMetrics, dict[str, list[float]]]:
    """One rollout's (``g``) metrics against its trajectory ``truth``, and (``impact``) its error by step."""
    start = int(g.attrs["start"])
    position = Rmse(**rollout_rmse(g["world_pos"][()], truth["world_pos"], start))
    stress: Rmse | None = None
    phys: ImpactMetrics | None = None
    steps: dict[str, list[float]] = {}
    if "stress" in g and "stress" in truth:
        stress = Rmse(**rollout_rmse(g["stress"][()], truth["stress"], start))
    if impact and stress is not None:
        phys, steps = impact_physics(g["world_pos"][()], g["stress"][()], truth, start)
    return TrajectoryMetrics(trajectory=name, position=position, stress=stress, physics=phys), steps


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
    """(:func:`hcmt.inference.physics.impact_metrics`, the position and stress error by step (×10³) of the ball, the
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
