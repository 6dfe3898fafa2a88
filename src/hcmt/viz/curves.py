"""Charts: rollout error per step for one or more runs, and training curves from ``RUN/log.jsonl``.

The per-step error is the paper's (:func:`hcmt.inference.metrics.step_rmse`): at step ``t``,
``e_t = sqrt(mean_i ||pred_t,i - true_t,i||^2)`` over the nodes, drawn in physical units (the tables' x10^3
scaling is for printing numbers, not for axes), averaged over the trajectories every run has rolled out, with the
band between the best and the worst trajectory when there are several. Steps before a run's first predicted frame
are the data's and are not drawn.
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np

from hcmt.data.format import Split, read_meta
from hcmt.data.runs import RunFolder
from hcmt.errors import InputError
from hcmt.inference.metrics import SCALE, step_rmse
from hcmt.inference.rollout_files import rollout_file
from hcmt.inference.run import Run
from hcmt.viz.meshplot import new_figure, save_figure
from hcmt.viz.rollouts import quantity_label, unique_labels

QUANTITIES = ("position", "stress")


def rollout_errors(
    runs: list[Run | RunFolder],
    data: str | Path,
    split: str = "test",
    labels: list[str] | None = None,
    limit: int | None = None,
    *,
    progress: bool = True,
) -> dict[str, dict]:
    """Per-step RMSE of every run: ``{label: {"position": [n, T], "stress": [n, T] (if any), "start": int,
    "trajectories": names}}`` over the trajectories all runs have rolled out (rolling out the first ``limit``, or
    all, where a run has no rollout file yet)."""
    labels = labels or unique_labels(runs)
    paths = [rollout_file(run, data, split, need=limit, progress=progress) for run in runs]
    names = None
    for path in paths:
        with h5py.File(path, "r") as f:
            names = set(f.keys()) if names is None else names & set(f.keys())
    meta = read_meta(data)
    out = {}
    with Split(data, split, meta) as s:
        names = [n for n in s.names if n in names]
        if not names:
            raise InputError(
                f"the runs' rollout files ({', '.join(map(str, paths))}) share no trajectory of split "
                f"{split!r}; roll them out on the same data"
            )
        truths = {n: s[s.names.index(n)] for n in names}
    for label, path in zip(labels, paths):
        errors = {q: [] for q in QUANTITIES}
        start = 1
        with h5py.File(path, "r") as f:
            for n in names:
                g, truth = f[n], truths[n]
                start = int(g.attrs.get("start", 1))
                errors["position"].append(step_rmse(g["world_pos"][()], truth["world_pos"]))
                if "stress" in g and "stress" in truth:
                    errors["stress"].append(step_rmse(g["stress"][()], truth["stress"]))
        out[label] = {q: np.stack(v) for q, v in errors.items() if v}
        out[label].update(start=start, trajectories=names)
    return out


def plot_error_curves(
    errors: dict[str, dict], meta: dict, path: str | Path, *, log: bool | None = None, dpi: int = 150
) -> Path:
    """One chart per quantity (position, stress), one line per run (mean over trajectories, min-max band).
    ``log`` y-axis: default when the errors span more than two decades."""
    quantities = [q for q in QUANTITIES if any(q in e for e in errors.values())]
    fig = new_figure(4.6 * len(quantities), 3.6)
    units = meta.get("units") or {}
    dt = meta.get("dt")
    for k, q in enumerate(quantities):
        ax = fig.add_subplot(1, len(quantities), k + 1)
        spans = []
        for label, e in errors.items():
            if q not in e:
                continue
            values = e[q][:, e["start"] :]
            steps = np.arange(e["start"], e["start"] + values.shape[1])
            mean = values.mean(0)
            (line,) = ax.plot(steps, mean, label=label, lw=1.5)
            if len(values) > 1:
                ax.fill_between(steps, values.min(0), values.max(0), color=line.get_color(), alpha=0.2, lw=0)
            spans.append(values[values > 0])
        allv = np.concatenate(spans) if spans else np.zeros(0)
        use_log = log if log is not None else bool(len(allv) and allv.max() > 100 * allv.min())
        if use_log:
            ax.set_yscale("log")
        else:
            ax.set_ylim(bottom=0)
        unit = units.get("length" if q == "position" else "stress")
        ax.set_ylabel(quantity_label(f"{q} RMSE", unit))
        ax.set_xlabel("rollout step (frame)")
        if dt:
            sec = ax.secondary_xaxis("top", functions=(lambda s, dt=float(dt): s * dt, lambda t, dt=float(dt): t / dt))
            sec.set_xlabel(quantity_label("time", units.get("time")), fontsize=8)
            sec.tick_params(labelsize=7)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    n = len(next(iter(errors.values()))["trajectories"])
    fig.suptitle(
        f"Rollout error per step, mean over {n} trajector{'y' if n == 1 else 'ies'}"
        + (" (band: best to worst)" if n > 1 else ""),
        fontsize=10,
    )
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, path, dpi=dpi)
    return path


def read_log(run: str | Path) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """``RUN/log.jsonl`` as (training columns, validation columns), each ``{key: array}`` with ``step``.
    Lines written by an interrupted run that was resumed may repeat steps: the last line of a step wins."""
    folder = RunFolder(run, must_exist=False)
    if not folder.log.is_file():
        raise FileNotFoundError(f"{folder.log}: no training log (written by `hcmt train`)")
    train, valid = {}, {}
    for rec in folder.log_records():
        (train if "loss" in rec else valid)[rec["step"]] = rec

    def columns(recs):
        steps = sorted(recs)
        keys = sorted({k for r in recs.values() for k in r})
        return {k: np.array([recs[s].get(k, np.nan) for s in steps], np.float64) for k in keys}

    return columns(train), columns(valid)


def running_mean(y: np.ndarray, window: int) -> np.ndarray:
    """Mean of the last ``window`` values at every point (fewer at the start)."""
    c = np.cumsum(np.insert(np.asarray(y, np.float64), 0, 0.0))
    n = np.arange(1, len(y) + 1)
    lo = np.maximum(n - window, 0)
    return (c[n] - c[lo]) / (n - lo)


def plot_training_curves(
    runs: list[Run | RunFolder], meta: dict, path: str | Path, labels: list[str] | None = None, dpi: int = 150
) -> Path:
    """Training loss, learning rate and the validation rollout RMSE-all (position, and stress when logged) against
    the step, one line per run. The validation metrics are logged x10^3 (the paper's tables) and drawn in physical
    units."""
    labels = labels or unique_labels(runs)
    logs = [read_log((r.require_folder() if isinstance(r, Run) else r).path) for r in runs]
    has_stress = any("valid/stress_rmse_all" in v for _, v in logs)
    panels = ["loss", "lr", "valid/position_rmse_all"] + (["valid/stress_rmse_all"] if has_stress else [])
    units = meta.get("units") or {}
    titles = {
        "loss": ("training loss", "one-step MSE, normalized"),
        "lr": ("learning rate", "learning rate"),
        "valid/position_rmse_all": ("validation rollout", quantity_label("position RMSE-all", units.get("length"))),
        "valid/stress_rmse_all": ("validation rollout", quantity_label("stress RMSE-all", units.get("stress"))),
    }
    fig = new_figure(8.4, 6.4)
    for k, key in enumerate(panels):
        ax = fig.add_subplot(2, 2, k + 1)
        spans = []
        for label, (train, valid) in zip(labels, logs):
            cols = train if key in ("loss", "lr") else valid
            if key not in cols:
                ax.plot([], [], label=f"{label} (not logged)")
                continue
            y = cols[key] / (1.0 if key in ("loss", "lr") else SCALE)
            if key == "loss" and len(y) >= 30:  # noisy: the raw values faint, a running mean over 5% on top
                (line,) = ax.plot(cols["step"], y, lw=0.6, alpha=0.35)
                ax.plot(
                    cols["step"],
                    running_mean(y, max(3, len(y) // 20)),
                    color=line.get_color(),
                    lw=1.4,
                    label=f"{label} (running mean)",
                )
            else:
                ax.plot(cols["step"], y, label=label, lw=1.2, marker="o" if len(y) < 15 else None, ms=3)
            spans.append(y[np.isfinite(y) & (y > 0)])
        allv = np.concatenate(spans) if spans else np.zeros(0)
        if len(allv) and allv.max() > 30 * allv.min():  # a log axis only where the values span decades
            ax.set_yscale("log")
        ax.set_xlabel("training step")
        ax.set_title(titles[key][0], fontsize=9)
        ax.set_ylabel(titles[key][1], fontsize=8)
        ax.grid(True, which="both", alpha=0.25)
        ax.legend(fontsize=7)
    fig.suptitle("Training curves", fontsize=10)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, path, dpi=dpi)
    return path
