"""A trained model and everything needed to use it: :class:`Run`.

A run is either a run folder made by ``hcmt train`` (``run.yaml`` + ``best.pt`` / ``checkpoint.pt``) or a model
shipped inside the package (``pretrained:NAME``, files under ``hcmt/pretrained/``). Both give the same object:
the model (on the chosen device, in eval mode), the config it was trained with, its adapter and contact radius, the
hierarchy it needs and what its training data was (dataset meta.json: the generator's settings and the design
ranges), so rollouts, evaluation and design predictions need nothing else.

A shipped model is one file: ``{"model_args", "model" (state dict, fp16 where the run's tensor was float32),
"config", "meta" (the training data's meta.json), "ranges" (min/max of every design parameter over the training
trajectories), "card" (how it was made)}``; it loads with ``torch.load(weights_only=True)``, offline.
"""
from __future__ import annotations

import json
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np
import torch

from hcmt.data.format import atomic_path, ensure_space
from hcmt.train.metrics import SCALE, format_physics, impact_groups, impact_metrics, plate_mask, step_rmse, summarize_impact

PRETRAINED_DIR = Path(__file__).resolve().parent.parent / "pretrained"


def resolve_device(device: str | None = None) -> torch.device:
    """``None``: CUDA when available, else the CPU. An unknown device, or CUDA on a CPU-only torch, is refused with
    one line (``ValueError``)."""
    if device is None:
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    try:
        dev = torch.device(device)
    except (RuntimeError, ValueError):
        raise ValueError(f"--device {device!r}: not a device; expected cpu, cuda or cuda:N") from None
    if dev.type == "cuda":
        if not torch.cuda.is_available():
            raise ValueError(f"--device {device}: this torch has no usable CUDA device (torch {torch.__version__}); "
                             "use --device cpu")
        if dev.index is not None and dev.index >= torch.cuda.device_count():
            raise ValueError(f"--device {device}: only {torch.cuda.device_count()} CUDA device(s) here")
    elif dev.type != "cpu":
        raise ValueError(f"--device {device}: unsupported device type {dev.type!r}; expected cpu or cuda")
    return dev


def available_pretrained() -> dict[str, Path]:
    """Shipped models by name (``impact_plate_small``, ...)."""
    return {p.stem: p for p in sorted(PRETRAINED_DIR.glob("*.pt"))}


@dataclass
class Run:
    """A trained model with its config and training-data facts. Make one with :meth:`load`."""

    model: torch.nn.Module
    info: dict  # run.yaml: model (constructor arguments), config, data, seed; plus "checkpoint"
    source: str  # the run folder or ``pretrained:NAME``
    meta: dict | None = None  # the training data's meta.json (None when the dataset is gone)
    ranges: dict[str, tuple[float, float]] = field(default_factory=dict)  # design parameters of the training data
    card: dict = field(default_factory=dict)  # shipped models: how they were made

    # -- loading -------------------------------------------------------------------------------------------------
    @classmethod
    def load(cls, path: str | Path, device: str | None = None, which: str = "best") -> "Run":
        """A run folder, or ``pretrained:NAME`` (see :func:`available_pretrained`). ``device`` as
        :func:`resolve_device` (default: CUDA when available)."""
        dev = resolve_device(device)
        text = str(path)
        if text.startswith("pretrained:"):
            return cls._pretrained(text.split(":", 1)[1], dev)
        from hcmt.train.trainer import load_run

        model, info = load_run(path, which, device="cpu")
        meta, ranges = _data_facts(info.get("data"))
        return cls(model.to(dev), info, str(path), meta, ranges)

    @classmethod
    def _pretrained(cls, name: str, device: torch.device) -> "Run":
        from hcmt.train.trainer import make_model

        shipped = available_pretrained()
        if name not in shipped:
            raise ValueError(f"pretrained:{name}: no such shipped model; available: "
                             f"{', '.join(shipped) or 'none'} (`hcmt models` lists them)")
        pack = torch.load(shipped[name], map_location="cpu", weights_only=True)
        model = make_model(pack["model_args"])
        ref = model.state_dict()
        model.load_state_dict({k: v.to(ref[k].dtype) for k, v in pack["model"].items()})
        model.eval()
        info = {"model": pack["model_args"], "config": pack["config"], "data": None,
                "checkpoint": {"file": shipped[name].name, "step": int(pack["card"].get("steps", 0))}}
        ranges = {k: (float(v[0]), float(v[1])) for k, v in pack["ranges"].items()}
        return cls(model.to(device), info, f"pretrained:{name}", pack["meta"], ranges, pack["card"])

    # -- what the run is -------------------------------------------------------------------------------------------
    @property
    def config(self) -> dict:
        return self.info["config"]

    @property
    def device(self) -> torch.device:
        return next(self.model.parameters()).device

    @property
    def adapter(self):
        from hcmt.train.adapters import config_adapter

        return config_adapter(self.config)

    @property
    def radius(self) -> float:
        return float(self.config["train"]["contact_radius"])

    @property
    def hierarchy(self) -> tuple[int, bool]:
        """(levels, remesh) of the hierarchy the model needs."""
        from hcmt.train.trainer import uses_hierarchy

        return uses_hierarchy(self.info["model"])

    @property
    def label(self) -> str:
        from hcmt.viz.rollouts import DISPLAY_NAMES

        args = self.info["model"]
        return DISPLAY_NAMES.get(args["name"], args["name"].upper()) + (
            f" ({args['ablation']})" if args.get("ablation") else "")

    # -- using it ---------------------------------------------------------------------------------------------------
    def design(self, **params):
        """An Impact Plate :class:`~hcmt.sim.scene.Design`: ``params`` over the middle of the training preset's
        ranges (``hcmt simulate``'s defaults for that preset), validated."""
        from hcmt.train.predict import default_design, parse_design

        return parse_design([f"{k}={v}" for k, v in params.items()], default_design(self.meta), where="design")

    def rollout(self, data: str | Path, split: str = "test", limit: int | None = None, batch: int = 1,
                compile: str = "none") -> Path:
        """Roll out over a split of a dataset; returns ``RUN/rollout_<split>.h5`` (run folders only)."""
        return run_rollouts(self._folder(), data, split, limit, self.info["checkpoint"]["file"].removesuffix(".pt"),
                            str(self.device), batch, compile)

    def evaluate(self, data: str | Path, split: str = "test", limit: int | None = None, batch: int = 1,
                 compile: str = "none") -> dict:
        """The paper's RMSE metrics on a split (``RUN/metrics_<split>.json``); rolls out first when needed."""
        return evaluate(self._folder(), data, split, limit, self.info["checkpoint"]["file"].removesuffix(".pt"),
                        str(self.device), batch, compile)

    def _folder(self) -> Path:
        if self.source.startswith("pretrained:"):
            raise ValueError(f"{self.source}: a shipped model has no run folder to write rollouts to; use "
                             "hcmt.predict_designs for designs, or train a run")
        return Path(self.source)

    # -- packaging -------------------------------------------------------------------------------------------------
    def save_pretrained(self, path: str | Path, card: dict, half: bool = True) -> Path:
        """Write this run as one shipped-model file (fp16 weights with ``half``), atomically."""
        from hcmt.data.format import atomic_path

        if self.meta is None or not self.ranges:
            raise ValueError(f"{self.source}: its training dataset ({self.info.get('data')}) is needed to record "
                             "the design ranges; keep it next to the run")
        state = {k: (v.half() if half and v.dtype == torch.float32 else v).cpu()
                 for k, v in self.model.state_dict().items()}
        pack = {"model_args": self.info["model"], "model": state, "config": self.config, "meta": self.meta,
                "ranges": {k: [float(a), float(b)] for k, (a, b) in self.ranges.items()},
                "card": json.loads(json.dumps(card, default=str))}  # plain types: loads with weights_only=True
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(path) as tmp:
            torch.save(pack, tmp)
        return path


def _data_facts(data: str | None) -> tuple[dict | None, dict[str, tuple[float, float]]]:
    """(meta.json, min/max of each numeric design attribute over the training split) of a run's dataset, or
    (None, {}) when it is not there any more."""
    if not data or not (Path(data) / "meta.json").is_file():
        return None, {}
    from hcmt.data.format import Split, read_meta

    meta = read_meta(data)
    ranges: dict[str, list[float]] = {}
    if (Path(data) / "train.h5").is_file():
        with Split(data, "train", meta) as s:
            for i in range(len(s)):
                for k, v in s.attrs(i).items():
                    if isinstance(v, (int, float, np.number)) and not isinstance(v, bool):
                        ranges.setdefault(k, []).append(float(v))
    return json.loads(json.dumps(meta)), {k: (min(v), max(v)) for k, v in ranges.items()}


# -- rollout files, evaluation, comparison ------------------------------------------------------------------------
def _run_data(run) -> str | None:
    """The resolved training-data path recorded in ``RUN/run.yaml`` (None when not recorded)."""
    import yaml

    path = Path(run) / "run.yaml"
    return yaml.safe_load(path.read_text()).get("data") if path.is_file() else None


def data_key(run, data) -> str:
    """``""`` when ``data`` is the run's own training dataset (or not given), else ``"@<dataset folder name>"``:
    the suffix of the rollout and metrics files of another dataset, so evaluating one never overwrites the
    run's own."""
    if data is None:
        return ""
    own = _run_data(run)
    return "" if own is None or str(Path(data).resolve()) == str(Path(own).resolve()) else f"@{Path(data).name}"


def rollout_path(run: str | Path, split: str, data=None) -> Path:
    return Path(run) / f"rollout_{split}{data_key(run, data)}.h5"


def check_dataset(train_meta: dict | None, data, train_data=None, split: str | None = None) -> list[str]:
    """Whether ``data`` suits a model trained on ``train_meta`` (the training data's meta.json): a different frame
    interval ``dt`` is refused (``ValueError``: a model steps one training interval at a time); another generator
    preset, or node counts outside the training data's (when ``train_data`` and ``split`` are given) give one
    warning line each (returned)."""
    from hcmt.data.format import Split, read_meta

    if train_meta is None:
        return []
    meta = read_meta(data)
    a, b = train_meta.get("dt"), meta.get("dt")
    if a is not None and b is not None and not np.isclose(float(a), float(b), rtol=1e-6, atol=0):
        raise ValueError(f"{data}: frames {b} apart (dt), but the model was trained on frames {a} apart; a model "
                         f"steps one training interval at a time: use data recorded at dt {a}")
    out = []
    pa, pb = ((m.get("generator") or {}).get("preset") for m in (train_meta, meta))
    if pa and pb and pa != pb:
        out.append(f"{data} is a `{pb}` dataset; the model was trained on `{pa}` data: expect larger errors")
    if train_data is not None and split is not None and (Path(train_data) / "train.h5").is_file():
        with Split(train_data, "train") as s:
            trained = [s.num_nodes(i) for i in range(len(s))]
        with Split(data, split) as s:
            now = [s.num_nodes(i) for i in range(len(s))]
        if now and trained and (min(now) < 0.9 * min(trained) or max(now) > 1.1 * max(trained)):
            out.append(f"{data} {split}: {min(now)}-{max(now)} nodes per trajectory, the training data "
                       f"{min(trained)}-{max(trained)}: expect larger errors")
    return out


def dataset_warnings(run, data, split: str) -> list[str]:
    """:func:`check_dataset` of ``data`` against a run folder's training data (named in ``run.yaml``; nothing to
    compare when it is gone): raises for another ``dt``, returns the warning lines."""
    from hcmt.data.format import read_meta

    own = _run_data(run)
    meta = read_meta(own) if own and (Path(own) / "meta.json").is_file() else None
    return check_dataset(meta, data, own, split)


def run_rollouts(run, data, split, limit=None, checkpoint="best", device=None, batch: int = 1,
                 compile: str = "none", *, progress: bool = True) -> Path:
    """Roll a run's model out over a split; predictions go to ``RUN/rollout_<split>.h5`` (``rollout_<split>@<data
    name>.h5`` for a dataset other than the run's own), atomically. ``batch`` trajectories of equal length step
    together as one batched graph. The progress bar counts model steps over the whole split (with an ETA)."""
    from tqdm import tqdm

    from hcmt.train.data import load_split
    from hcmt.train.rollout import rollout_batch

    check_options(device, batch, compile)
    r = Run.load(run, device, checkpoint)
    check_dataset(r.meta, data)
    levels, remesh = r.hierarchy
    trajs = load_split(data, split, r.adapter, levels, remesh, limit=limit)
    path = rollout_path(run, split, data)
    h = r.adapter.history
    bar = tqdm(total=sum(max(tr.num_steps - 1 - h, 0) for tr in trajs), desc=f"rollout {split}", unit="step",
               dynamic_ncols=True, disable=not progress)
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        for key, value in rollout_key(data, split, r.info["checkpoint"]["file"],
                                      r.info["checkpoint"]["step"]).items():
            f.attrs[key] = value
        by_length: dict[int, list] = defaultdict(list)
        for tr in trajs:
            by_length[tr.num_steps].append(tr)
        for group in by_length.values():
            for first in range(0, len(group), batch):
                chunk = group[first:first + batch]
                results = rollout_batch(r.model, r.adapter, chunk, r.radius, compile=compile,
                                        progress=lambda n, k=len(chunk): bar.update(n * k))
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


def rollout_key(data, split, checkpoint_file, step) -> dict:
    """What a rollout file was made from: dataset, split and checkpoint (file and step)."""
    return {"data": str(Path(data).resolve()), "split": split, "checkpoint": checkpoint_file,
            "checkpoint_step": int(step)}


def check_options(device=None, batch: int = 1, compile: str = "none") -> None:
    """Refuse bad rollout options in one line before any cache is consulted or work done."""
    from hcmt.models.base import COMPILE_MODES

    resolve_device(device)
    if isinstance(batch, bool) or not isinstance(batch, int) or batch < 1:
        raise ValueError(f"--batch must be a whole number >= 1, got {batch}")
    if compile not in COMPILE_MODES:
        raise ValueError(f"--compile must be one of {', '.join(COMPILE_MODES)}, got {compile!r}")


def rollout_for(run, data, split: str, need: int | None = None, checkpoint: str = "best", device=None,
                batch: int = 1, compile: str = "none", *, progress: bool = True) -> Path:
    """The one rollout-cache rule, used by evaluation and every picture: ``RUN/rollout_<split>.h5`` is reused when
    it was made from this dataset, split and checkpoint (same step) and holds the first ``need`` trajectories of
    the split (all when ``need`` is None); otherwise it is rolled out again, never with fewer trajectories than the
    file had. A rollout file in a folder without checkpoints (predictions brought from elsewhere) is used as it is
    when it holds the trajectories asked for. Options are checked first, whatever the cache holds; the file of
    a dataset other than the run's own is ``rollout_<split>@<data name>.h5``."""
    from hcmt.data.format import Split

    check_options(device, batch, compile)
    path = rollout_path(run, split, data)
    ckpt = Path(run) / f"{checkpoint}.pt"
    ckpt = ckpt if ckpt.is_file() else Path(run) / "checkpoint.pt"
    with Split(data, split) as s:
        names = s.names
    want = len(names) if need is None else min(int(need), len(names))
    have = 0
    if path.is_file() and not ckpt.is_file():  # predictions without a checkpoint to check them against: use them
        with h5py.File(path, "r") as f:
            if set(names[:want]) <= set(f.keys()):
                return path
    if path.is_file() and ckpt.is_file():
        step = int(torch.load(ckpt, map_location="cpu", weights_only=True)["step"])
        with h5py.File(path, "r") as f:
            attrs = {k: (v.item() if hasattr(v, "item") else v) for k, v in f.attrs.items()}
            if all(attrs.get(k) == v for k, v in rollout_key(data, split, ckpt.name, step).items()):
                have = len(f.keys())
                if set(names[:want]) <= set(f.keys()):
                    return path
    limit = max(want, have)
    return run_rollouts(run, data, split, limit if limit < len(names) else None, checkpoint, device, batch, compile,
                        progress=progress)


def evaluate(run, data, split, limit=None, checkpoint="best", device=None, batch: int = 1,
             compile: str = "none", *, progress: bool = True) -> dict:
    """Paper metrics (and for Impact Plate the physics metrics) of a run on a split, written to
    ``RUN/metrics_<split>.json`` (``metrics_<split>@<data name>.json`` for a dataset other than the run's own);
    rolls out first (on ``device``, default CUDA when available) if the rollout file is missing or stale. A
    dataset of another frame interval is refused; other mismatches with the training data are recorded under
    ``warnings``."""
    from hcmt.data.format import Split, read_meta
    from hcmt.train.metrics import aggregate, rollout_rmse

    check_options(device, batch, compile)
    warnings = dataset_warnings(run, data, split)
    meta = read_meta(data)
    path = rollout_for(run, data, split, limit, checkpoint, device, batch, compile, progress=progress)
    per_traj, ms, physics, by_step = [], [], [], defaultdict(list)
    with h5py.File(path, "r") as f, Split(data, split) as s:
        index = {n: i for i, n in enumerate(s.names)}
        for name in s.names[:limit]:  # the first `limit` trajectories (all when None), however many the file holds
            truth = s[index[name]]
            g = f[name]
            start = int(g.attrs["start"])
            row = {"trajectory": name}
            row.update({f"position_{k}": v for k, v in rollout_rmse(g["world_pos"][()], truth["world_pos"], start).items()})
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
    units = meta.get("units") or {}
    metrics = {"split": split, "data": str(Path(data).resolve()), "trajectories": len(per_traj), "scale": SCALE,
               "units": {k: units[k] for k in ("length", "stress") if k in units}, "warnings": warnings}
    for q in ("position", "stress"):
        if f"{q}_rmse_all" in means:
            metrics[q] = {k: means[f"{q}_{k}"] for k in ("rmse_1", "rmse_50", "rmse_all")}
    metrics["inference_ms_per_step"] = float(np.median(ms))
    stats = Path(run) / "train_stats.json"
    metrics["train_ms_per_step"] = json.loads(stats.read_text()).get("train_ms_per_step") if stats.is_file() else None
    if physics:
        metrics["physics"] = summarize_impact(physics)
        metrics["error_by_step"] = {k: np.mean(v, 0).tolist() for k, v in by_step.items()}
        for row, phys in zip(per_traj, physics):
            row["physics"] = phys
    metrics["per_trajectory"] = per_traj
    with atomic_path(metrics_path(run, split, data)) as tmp:  # one file per split: never overwrites another split's
        tmp.write_text(json.dumps(metrics, indent=2))
    return metrics


def impact_physics(pos, stress, truth: dict, start: int) -> tuple[dict, dict]:
    """(:func:`hcmt.train.metrics.impact_metrics`, the position and stress error by step (×10³) of the ball, the
    contact zone and the far plate) of one Impact Plate rollout against its trajectory ``truth``."""
    plate = plate_mask(truth["cells"], truth["node_type"])
    groups = impact_groups(np.asarray(truth["world_pos"][0]), plate)
    steps = {}
    for q, pred, true in (("position", pos, truth["world_pos"]), ("stress", stress, truth["stress"])):
        for g, mask in groups.items():
            steps[f"{q}_{g}"] = (step_rmse(pred[:, mask], true[:, mask])[start:] * SCALE).tolist()
    return impact_metrics(pos, stress, truth["world_pos"], truth["stress"], plate, start), steps


def metrics_path(run, split: str, data=None) -> Path:
    return Path(run) / f"metrics_{split}{data_key(run, data)}.json"


def metric_unit(m: dict, quantity: str) -> str:
    """The unit of a quantity's RMSE as the dataset records it (``units.length`` / ``units.stress``)."""
    return (m.get("units") or {}).get("length" if quantity == "position" else quantity) or "data units"


def format_metrics(m: dict) -> str:
    """The RMSE table in the data's units (metrics.json keeps the paper's ×10³ values)."""
    lines = [f"split {m['split']}: {m['trajectories']} trajectories, RMSE over the rollout's steps 1, 1-50 and all",
             f"  {'':<18}{'rmse_1':>12}{'rmse_50':>12}{'rmse_all':>12}"]
    for q in ("position", "stress"):
        if q in m:
            name = f"{q} [{metric_unit(m, q)}]"
            lines.append(f"  {name:<18}" + "".join(f"{m[q][k] / SCALE:>12.4g}" for k in ("rmse_1", "rmse_50", "rmse_all")))
    lines.append(f"  inference {m['inference_ms_per_step']:.2f} ms/step"
                 + (f", training {m['train_ms_per_step']:.2f} ms/step" if m.get("train_ms_per_step") else ""))
    if "physics" in m:
        lines += format_physics(m["physics"])
    return "\n".join(lines)


def compare(runs: list[str], split: str = "test") -> dict:
    """{label: {quantity: {metric: {mean, std, n}}}} over seeds of one split. Runs are grouped by model (+ ablation)
    and by the dataset they were evaluated on: runs of different datasets are never averaged together (the label
    then names the dataset)."""
    import yaml

    from hcmt.train.metrics import summarize_runs

    groups: dict[tuple[str, str], list[dict]] = defaultdict(list)
    for run in runs:
        mpath = metrics_path(run, split)
        if not mpath.is_file():
            raise FileNotFoundError(f"{mpath}: run `hcmt evaluate {run} --data ... --split {split}` first")
        info = yaml.safe_load((Path(run) / "run.yaml").read_text())["model"]
        label = info["name"].upper() + (f" ({info['ablation']})" if info.get("ablation") else "")
        m = json.loads(mpath.read_text())
        groups[(label, m.get("data", "?"))].append(m)
    datasets = {d for _, d in groups}
    return {(label if len(datasets) == 1 else f"{label} [{Path(d).name}]"): summarize_runs(ms)
            for (label, d), ms in groups.items()}


def format_compare(table: dict) -> str:
    head = f"{'Model':<24}{'Position RMSE-all':>24}{'Stress RMSE-all':>24}{'Position RMSE-1':>20}  seeds"
    lines = ["RMSE x1e3 in the data's units (Impact Plate: position 1e-3 mm = µm, stress 1e-3 MPa = kPa), "
             "mean ± std over seeds (paper Table 2 layout)", head]
    for label, row in table.items():
        def cell(q, k, w):
            if q not in row:
                return f"{'-':>{w}}"
            return f"{row[q][k]['mean']:>{w - 10}.4g} ± {row[q][k]['std']:<7.3g}"
        n = row["inference_ms_per_step"]["n"]
        lines.append(f"{label:<24}{cell('position', 'rmse_all', 24)}{cell('stress', 'rmse_all', 24)}"
                     f"{cell('position', 'rmse_1', 20)}  {n}")
    return "\n".join(lines)
