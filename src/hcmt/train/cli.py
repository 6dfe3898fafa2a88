"""``hcmt train / rollout / evaluate / compare / predict / models``."""
from __future__ import annotations

import argparse
import json
import time
from collections import defaultdict
from pathlib import Path

import h5py
import numpy as np
import torch

from hcmt.data.format import atomic_path, ensure_space
from hcmt.models import ABLATIONS, MODELS
from hcmt.train.config import load_config
from hcmt.train.metrics import SCALE


# -- train ---------------------------------------------------------------------------------------------------------
def configure_train(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", help="built-in config name (impact_plate, impact_plate_cpu, ...) or a YAML file")
    p.add_argument("--data", help="native dataset folder")
    p.add_argument("--model", choices=MODELS)
    p.add_argument("--ablation", choices=ABLATIONS, help="HCMT ablation (paper Tables 3, 10-12)")
    p.add_argument("--steps", type=int, help="training steps (overrides train.steps)")
    p.add_argument("--seed", type=int, help="random seed (default 0)")
    p.add_argument("--out", required=True, help="run folder")
    p.add_argument("--resume", action="store_true", help="continue the run in --out from its last checkpoint; "
                   "`--resume --out RUN` alone uses the run's saved settings (--steps may extend it)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override any config key, e.g. --set train.lr=3e-4 --set model.levels=4")
    p.add_argument("--device", help="cpu, cuda, cuda:1 (default: cuda if available)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def main_train(args: argparse.Namespace) -> int:
    import yaml

    from hcmt.train.config import check_schema, parse_value
    from hcmt.train.trainer import train

    overrides = list(args.set) + ([f"train.steps={args.steps}"] if args.steps is not None else [])
    saved_path = Path(args.out) / "run.yaml"
    if args.resume and saved_path.is_file() and not args.config:  # resume with the run's saved settings
        saved = yaml.safe_load(saved_path.read_text())
        cfg = saved["config"]
        for item in overrides:
            key, _, raw = item.partition("=")
            *parents, leaf = key.split(".")
            node = cfg
            for part in parents:
                node = node.setdefault(part, {})
            node[leaf] = parse_value(raw)
        check_schema(cfg, f"{saved_path} with --set")
        data = args.data or saved["data"]
        model = args.model or saved["model"]["name"]
        ablation = args.ablation if args.ablation is not None else saved["model"].get("ablation")
        seed = args.seed if args.seed is not None else saved.get("seed", 0)
    else:
        missing = [f"--{k}" for k in ("config", "data", "model") if getattr(args, k) is None]
        if missing:
            raise ValueError(f"{', '.join(missing)} required (only `--resume --out RUN` of an existing run may leave "
                             "them out)")
        cfg, data, model, ablation = load_config(args.config, overrides), args.data, args.model, args.ablation
        seed = args.seed if args.seed is not None else 0
    summary = train(cfg, data, model, args.out, ablation=ablation, seed=seed,
                    resume=args.resume, device=args.device, progress=not args.no_progress)
    print(json.dumps(summary, indent=2))
    return 0


# -- rollout -------------------------------------------------------------------------------------------------------
def _run_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("run", help="run folder made by `hcmt train`")
    p.add_argument("--data", required=True, help="native dataset folder")
    p.add_argument("--split", default="test")
    p.add_argument("--limit", type=int, help="only the first N trajectories")
    p.add_argument("--checkpoint", default="best", choices=["best", "checkpoint"])
    p.add_argument("--device", help="cpu, cuda, cuda:N (default: cuda when available)")
    p.add_argument("--batch", type=int, default=1, help="trajectories rolled out together as one batched graph")


configure_rollout = _run_args


def rollout_path(run: str | Path, split: str) -> Path:
    return Path(run) / f"rollout_{split}.h5"


def run_rollouts(run, data, split, limit=None, checkpoint="best", device=None, batch: int = 1) -> Path:
    """Roll a run's model out over a split; predictions go to ``RUN/rollout_<split>.h5`` (atomically). ``batch``
    trajectories of equal length step together as one batched graph. The progress bar counts model steps over the
    whole split (with an ETA)."""
    from tqdm import tqdm

    from hcmt.train.data import load_split
    from hcmt.train.rollout import rollout_batch
    from hcmt.train.run import Run

    r = Run.load(run, device, checkpoint)
    levels, remesh = r.hierarchy
    trajs = load_split(data, split, r.adapter, levels, remesh, limit=limit)
    path = rollout_path(run, split)
    h = r.adapter.history
    bar = tqdm(total=sum(max(tr.num_steps - 1 - h, 0) for tr in trajs), desc=f"rollout {split}", unit="step",
               dynamic_ncols=True)
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        for key, value in rollout_key(data, split, limit, r.info["checkpoint"]["file"],
                                      r.info["checkpoint"]["step"]).items():
            f.attrs[key] = value
        if batch < 1:
            raise ValueError(f"--batch must be >= 1, got {batch}")
        by_length: dict[int, list] = defaultdict(list)
        for tr in trajs:
            by_length[tr.num_steps].append(tr)
        for group in by_length.values():
            for first in range(0, len(group), batch):
                chunk = group[first:first + batch]
                results = rollout_batch(r.model, r.adapter, chunk, r.radius,
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


def rollout_key(data, split, limit, checkpoint_file, step) -> dict:
    """What a rollout file was made from; :func:`evaluate` redoes the rollout when any of it changed."""
    return {"data": str(Path(data).resolve()), "split": split, "limit": -1 if limit is None else int(limit),
            "checkpoint": checkpoint_file, "checkpoint_step": int(step)}


def _rollout_is_current(path: Path, run, data, split, limit, checkpoint) -> bool:
    if not path.is_file():
        return False
    ckpt = Path(run) / f"{checkpoint}.pt"
    ckpt = ckpt if ckpt.is_file() else Path(run) / "checkpoint.pt"
    if not ckpt.is_file():
        return False
    step = int(torch.load(ckpt, map_location="cpu", weights_only=True)["step"])
    want = rollout_key(data, split, limit, ckpt.name, step)
    with h5py.File(path, "r") as f:
        have = {k: (v.item() if hasattr(v, "item") else v) for k, v in f.attrs.items()}
    return all(have.get(k) == v for k, v in want.items())


def main_rollout(args: argparse.Namespace) -> int:
    path = run_rollouts(args.run, args.data, args.split, args.limit, args.checkpoint, args.device, args.batch)
    print(f"wrote {path}")
    return 0


# -- evaluate ------------------------------------------------------------------------------------------------------
configure_evaluate = _run_args


def evaluate(run, data, split, limit=None, checkpoint="best", device=None, batch: int = 1) -> dict:
    """Paper metrics of a run on a split; rolls out first (on ``device``, default CUDA when available) if
    ``RUN/rollout_<split>.h5`` is missing or stale."""
    from hcmt.data.format import Split
    from hcmt.train.metrics import aggregate, rollout_rmse

    path = rollout_path(run, split)
    if not _rollout_is_current(path, run, data, split, limit, checkpoint):
        run_rollouts(run, data, split, limit, checkpoint, device, batch)
    per_traj, ms = [], []
    with h5py.File(path, "r") as f, Split(data, split) as s:
        index = {n: i for i, n in enumerate(s.names)}
        for name in f.keys():
            truth = s[index[name]]
            g = f[name]
            start = int(g.attrs["start"])
            row = {"trajectory": name}
            row.update({f"position_{k}": v for k, v in rollout_rmse(g["world_pos"][()], truth["world_pos"], start).items()})
            if "stress" in g and "stress" in truth:
                row.update({f"stress_{k}": v for k, v in rollout_rmse(g["stress"][()], truth["stress"], start).items()})
            per_traj.append(row)
            ms.append(float(g.attrs["ms_per_step"]))
    means = aggregate([{k: v for k, v in r.items() if k != "trajectory"} for r in per_traj])
    from hcmt.data.format import read_meta

    units = read_meta(data).get("units") or {}
    metrics = {"split": split, "data": str(Path(data).resolve()), "trajectories": len(per_traj), "scale": SCALE,
               "units": {k: units[k] for k in ("length", "stress") if k in units}}
    for q in ("position", "stress"):
        if f"{q}_rmse_all" in means:
            metrics[q] = {k: means[f"{q}_{k}"] for k in ("rmse_1", "rmse_50", "rmse_all")}
    metrics["inference_ms_per_step"] = float(np.median(ms))
    stats = Path(run) / "train_stats.json"
    metrics["train_ms_per_step"] = json.loads(stats.read_text()).get("train_ms_per_step") if stats.is_file() else None
    metrics["per_trajectory"] = per_traj
    with atomic_path(metrics_path(run, split)) as tmp:  # one file per split: never overwrites another split's
        tmp.write_text(json.dumps(metrics, indent=2))
    return metrics


def metrics_path(run, split: str) -> Path:
    return Path(run) / f"metrics_{split}.json"


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
    return "\n".join(lines)


def main_evaluate(args: argparse.Namespace) -> int:
    m = evaluate(args.run, args.data, args.split, args.limit, args.checkpoint, args.device, args.batch)
    print(format_metrics(m))
    print(f"wrote {metrics_path(args.run, args.split)}")
    return 0


# -- compare -------------------------------------------------------------------------------------------------------
def configure_compare(p: argparse.ArgumentParser) -> None:
    p.add_argument("runs", nargs="+", help="run folders holding metrics_<split>.json (from `hcmt evaluate`)")
    p.add_argument("--split", default="test", help="which split's metrics to compare (default test)")
    p.add_argument("--json", help="also write the table as JSON")


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


def main_compare(args: argparse.Namespace) -> int:
    table = compare(args.runs, args.split)
    print(f"split {args.split}; runs grouped by model and dataset")
    print(format_compare(table))
    if args.json:
        with atomic_path(Path(args.json)) as tmp:
            tmp.write_text(json.dumps(table, indent=2))
    return 0


# -- predict / models ----------------------------------------------------------------------------------------------
def configure_predict(p: argparse.ArgumentParser) -> None:
    p.add_argument("model", help="run folder made by `hcmt train`, or pretrained:NAME (`hcmt models` lists them)")
    p.add_argument("--design", nargs="+", action="append", default=[], metavar="KEY=VALUE",
                   help="one design, e.g. --design thickness=0.8 drop_height=900 (repeat for more designs); "
                        "parameters as `hcmt simulate`'s, unspecified ones at the middle of the training ranges")
    p.add_argument("--designs", metavar="FILE.csv", help="designs from a CSV file: header of parameter names "
                   "(optional `name` column), one design per row")
    p.add_argument("--device", help="cpu, cuda, cuda:N (default: cuda when available)")
    p.add_argument("--batch", type=int, default=8, help="designs rolled out together (default 8)")
    p.add_argument("--yield-mpa", type=float, help="report the margin of the peak plate stress to this stress (MPa)")
    p.add_argument("--verify", action="store_true", help="also run the built-in solver and report the errors and "
                   "the speedup")
    p.add_argument("--images", action="store_true", help="stress-contour PNG at each design's peak frame")
    p.add_argument("--out", default="predict_out", help="folder for --images (default predict_out)")
    p.add_argument("--json", help="write the results as JSON")
    p.add_argument("--csv", help="write the table as CSV")
    p.add_argument("--no-progress", action="store_true")


def main_predict(args: argparse.Namespace) -> int:
    import sys

    from hcmt.train import predict as pr
    from hcmt.train.run import Run

    if not args.design and not args.designs:
        raise ValueError("give designs with --design KEY=VALUE ... or --designs FILE.csv")
    run = Run.load(args.model, args.device)
    if run.config.get("dataset") != "impact_plate":
        raise ValueError(f"{args.model}: predict is for Impact Plate models; this one was trained on "
                         f"{run.config.get('dataset')!r}")
    defaults = pr.default_design(run.meta)
    designs = [(f"design_{i + 1}", pr.parse_design(items, defaults)) for i, items in enumerate(args.design)]
    if args.designs:
        designs += pr.read_designs_csv(args.designs, defaults)
    settings = pr.settings_of(run.meta)
    for name, d in designs:
        for w in pr.range_warnings(d, run.ranges):
            print(f"hcmt predict: warning: {name}: {w}", file=sys.stderr)
    t0 = time.perf_counter()
    preds = pr.predict(run, designs, batch=args.batch, progress=not args.no_progress)
    wall = time.perf_counter() - t0
    pr.add_margin(preds, args.yield_mpa)
    truth = verified = None
    if args.verify:
        truth = pr.solve(designs, settings)
        verified = pr.verify(preds, truth)
    print(f"{run.label} ({run.source}) on {run.device}: {len(preds)} design(s), {settings.frames} frames of "
          f"{settings.frame_dt} ms, {wall:.2f} s in all; stresses are von Mises [MPa], lengths [mm]")
    print(pr.format_table(preds, verified))
    if args.images:
        for i, p in enumerate(preds):
            path = pr.contour_picture(p, truth[i] if truth else None, run.meta, args.out, run.label)
            print(f"contours {p.name}: {path}")
    if args.csv:
        print(f"wrote {pr.write_csv(preds, args.csv)}")
    if args.json:
        with atomic_path(Path(args.json)) as tmp:
            tmp.write_text(json.dumps(pr.to_json(preds, verified, run.source, str(run.device)), indent=2))
        print(f"wrote {args.json}")
    return 0


def configure_models(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", action="store_true", help="print the model cards as JSON")


def main_models(args: argparse.Namespace) -> int:
    from hcmt.train.run import Run, available_pretrained

    shipped = available_pretrained()
    if not shipped:
        print("no shipped models in this installation")
        return 0
    cards = {}
    for name, path in shipped.items():
        run = Run.load(f"pretrained:{name}", "cpu")
        cards[name] = {"file": str(path), "size_mb": path.stat().st_size / 1e6, **run.card}
    if args.json:
        print(json.dumps(cards, indent=2))
        return 0
    for name, c in cards.items():
        print(f"pretrained:{name}  {c.get('summary', '')}  ({c['size_mb']:.1f} MB; docs/MODELS.md)")
    return 0
