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
import math
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np
import torch
import yaml

from hcmt.config import complete_config
from hcmt.data.format import Split, atomic_path, read_meta
from hcmt.models import REGISTRY, from_checkpoint, resolve_device, uses_hierarchy
from hcmt.physics.adapters import config_adapter
from hcmt.sim.scene import Design, middle_design, parse_design

PRETRAINED_DIR = Path(__file__).resolve().parent.parent / "pretrained"


def available_pretrained() -> dict[str, Path]:
    """Shipped models by name (``impact_plate_small``, ...)."""
    return {p.stem: p for p in sorted(PRETRAINED_DIR.glob("*.pt"))}


class RunFolder:
    """A run folder made by ``hcmt train``: the one owner of its file names, ``run.yaml`` parsed once.

    ``run.yaml`` holds the model's constructor arguments (``model``), the config (``config``), the training data
    (``data``), ``seed`` and ``world_size``; the checkpoints are ``checkpoint.pt`` (latest) and ``best.pt``;
    rollouts and metrics of a split are ``rollout_<split>[@<data>].h5`` and ``metrics_<split>[@<data>].json``."""

    def __init__(self, path: str | Path, *, must_exist: bool = True):
        self.path = Path(path)
        self.info: dict | None = None
        self.damaged: str | None = None  # why run.yaml could not be read (a folder that may be written anew)
        if (self.path / "run.yaml").is_file():
            try:
                self.info = read_run_yaml(self.path / "run.yaml")
            except ValueError as exc:
                if must_exist:
                    raise
                self.damaged = str(exc)
        elif must_exist:
            hint = f"; the shipped model is pretrained:{self.path}" if str(self.path) in available_pretrained() else ""
            raise FileNotFoundError(f"{self.path / 'run.yaml'}: not a run folder (made by `hcmt train --out RUN`)"
                                    f"{hint}")

    def __repr__(self) -> str:
        return f"RunFolder({str(self.path)!r})"

    @property
    def source(self) -> str:
        return str(self.path)

    # -- files the training loop writes
    @property
    def run_yaml(self) -> Path:
        return self.path / "run.yaml"

    def checkpoint(self, which: str = "best") -> Path:
        """``best.pt`` or ``checkpoint.pt``; the latest checkpoint when ``which`` is missing."""
        path = self.path / f"{which}.pt"
        return path if path.is_file() else self.latest

    @property
    def log(self) -> Path:
        return self.path / "log.jsonl"

    @property
    def best(self) -> Path:
        return self.path / "best.pt"

    @property
    def latest(self) -> Path:
        return self.path / "checkpoint.pt"

    @property
    def tensorboard(self) -> Path:
        return self.path / "tb"

    @property
    def text_log(self) -> Path:
        return self.path / "train.log"

    def steps_done(self) -> int:
        """The step of the latest checkpoint (0 when there is none)."""
        if not self.latest.is_file():
            return 0
        return int(read_checkpoint(self.latest, "cpu", earlier=self.best)["step"])

    def holds_run(self) -> bool:
        """Whether the folder holds a run (its settings or a checkpoint)."""
        return self.run_yaml.is_file() or self.latest.is_file()

    @property
    def stats_path(self) -> Path:
        return self.path / "train_stats.json"

    def train_stats(self) -> dict | None:
        return json.loads(self.stats_path.read_text()) if self.stats_path.is_file() else None

    def write_stats(self, summary: dict) -> None:
        """``train_stats.json`` (standard JSON: non-finite numbers become null), atomically."""
        with atomic_path(self.stats_path) as tmp:
            tmp.write_text(json.dumps({k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                                       for k, v in summary.items()}, indent=2))

    def write_info(self, info: dict) -> None:
        with atomic_path(self.run_yaml) as tmp:
            tmp.write_text(yaml.safe_dump(info, sort_keys=False))
        self.info = info

    @property
    def data_facts_path(self) -> Path:
        return self.path / "data.json"

    def write_data_facts(self, data) -> None:
        """``data.json``: the training data's meta.json and design ranges, so the run needs no dataset to predict
        designs (the generator's settings, the ranges and the design keys travel with it)."""
        meta, ranges = _data_facts(data)
        if meta is not None:
            with atomic_path(self.data_facts_path) as tmp:
                tmp.write_text(json.dumps({"meta": meta, "ranges": {k: list(v) for k, v in ranges.items()}},
                                          indent=1))

    def data_facts(self) -> tuple[dict | None, dict[str, tuple[float, float]]]:
        """(meta.json, design ranges) of the training data: from the dataset while it is there, else from the
        run's ``data.json``."""
        meta, ranges = _data_facts(self.train_data)
        if meta is None and self.data_facts_path.is_file():
            try:
                facts = json.loads(self.data_facts_path.read_text())
                meta = facts["meta"]
                ranges = {k: (float(v[0]), float(v[1])) for k, v in facts["ranges"].items()}
                generator = meta.get("generator") if isinstance(meta, dict) else None
                if not isinstance(generator, dict) or not isinstance(generator.get("settings", {}), dict):
                    raise TypeError("no generator block")
            except (ValueError, KeyError, TypeError, IndexError, AttributeError, OverflowError) as exc:
                raise ValueError(f"{self.data_facts_path}: damaged ({exc.__class__.__name__}); it is written by "
                                 "`hcmt train` from the training data's meta.json") from None
        return meta, ranges

    # -- files of its use
    @property
    def train_data(self) -> str | None:
        """The resolved training-data path recorded in ``run.yaml``."""
        return (self.info or {}).get("data")

    def data_key(self, data) -> str:
        """``""`` when ``data`` is the run's own training dataset (or not given), else ``"@<dataset folder
        name>"``: the suffix of the rollout and metrics files of another dataset, so evaluating one never
        overwrites the run's own."""
        own = self.train_data
        if data is None or own is None or str(Path(data).resolve()) == str(Path(own).resolve()):
            return ""
        return f"@{Path(data).name}"

    def rollout_path(self, split: str, data=None) -> Path:
        return self.path / f"rollout_{split}{self.data_key(data)}.h5"

    def metrics_path(self, split: str, data=None) -> Path:
        return self.path / f"metrics_{split}{self.data_key(data)}.json"

    @property
    def label(self) -> str:
        return model_label(self.info["model"])


def read_run_yaml(path: Path) -> dict:
    """``run.yaml`` as a dict with its ``model`` (and ``config`` when the run has a checkpoint: :func:`load_run`
    checks it); one line naming the file when it is not."""
    try:
        info = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: not readable YAML ({str(exc).splitlines()[0]}); it is written by `hcmt train` "
                         "(restore it, or train the run again)") from None
    if not isinstance(info, dict) or not isinstance(info.get("model"), dict) or (
            "config" in info and not isinstance(info["config"], dict)):
        what = "empty" if not info else "no model section (the model's constructor arguments)" \
            if not isinstance(info, dict) or not isinstance(info.get("model"), dict) else "a config that is no mapping"
        raise ValueError(f"{path}: {what}; run.yaml is written by `hcmt train` (restore it, or train the run again)")
    return info


def read_checkpoint(path: Path, device="cpu", earlier: Path | None = None) -> dict:
    """A checkpoint (``torch.load(weights_only=True)``) as a dict; a truncated, empty or foreign file is one line
    naming it, and the other checkpoint of the run when there is one."""
    other = f"; another checkpoint of the run exists: {earlier} (copy it over {path.name} to go on from it)" \
        if earlier is not None and earlier.is_file() and earlier != path else ""
    try:
        state = torch.load(path, map_location=device, weights_only=True)
    except FileNotFoundError:
        raise
    except Exception as exc:  # torch raises RuntimeError, EOFError, UnpicklingError, ...: all mean "damaged"
        raise ValueError(f"{path}: not a readable checkpoint (truncated or corrupt: {exc.__class__.__name__}){other}") \
            from None
    if not isinstance(state, dict) or "model" not in state:
        raise ValueError(f"{path}: not an hcmt checkpoint (no model weights){other}")
    return state


def model_label(args: dict) -> str:
    """The display label of a model from its constructor arguments (:data:`hcmt.models.REGISTRY`), with its
    ablation."""
    info = REGISTRY.get(args.get("name"))
    label = info.label if info else str(args.get("name")).upper()
    return label + (f" ({args['ablation']})" if args.get("ablation") else "")


def load_run(run: str | Path | RunFolder, which: str = "best", device: str = "cpu"):
    """(model, run dict) of a run folder; ``which`` is ``best`` or ``checkpoint``. The run dict is ``run.yaml``
    (its config completed with the schema's defaults) plus ``checkpoint: {file, step}``."""
    folder = run if isinstance(run, RunFolder) else RunFolder(run)
    path = folder.checkpoint(which)
    if not path.is_file():
        raise FileNotFoundError(f"{folder.path}: no checkpoint yet (best.pt / checkpoint.pt)")
    state = read_checkpoint(path, device, earlier=folder.latest if path == folder.best else folder.best)
    try:
        model = from_checkpoint(state)
    except (KeyError, TypeError, RuntimeError, ValueError) as exc:
        raise ValueError(f"{path}: the checkpoint does not hold the model run.yaml describes ({exc.__class__.__name__}:"
                         f" {str(exc).splitlines()[0][:200]})") from None
    try:  # a hand-edited or damaged run.yaml: its settings must still make the run's adapter and graph
        info = dict(folder.info, config=complete_config(folder.info["config"]))
        config_adapter(info["config"])
        float(info["config"]["train"]["contact_radius"])
        uses_hierarchy(info["model"])
        info["checkpoint"] = {"file": path.name, "step": int(state["step"])}
    except (TypeError, ValueError, KeyError, AttributeError) as exc:
        raise ValueError(f"{folder.run_yaml}: its settings do not load ({exc.__class__.__name__}: "
                         f"{str(exc).splitlines()[0][:160] if str(exc) else '-'}); restore it or train the run again") \
            from None
    return model, info


@dataclass
class Run:
    """A trained model with its config and training-data facts: the handle that rollout, evaluation, pictures and
    the design check take. Make one with :meth:`load`."""

    model: torch.nn.Module
    info: dict  # run.yaml: model (constructor arguments), config, data, seed; plus "checkpoint"
    source: str  # the run folder or ``pretrained:NAME``
    meta: dict | None = None  # the training data's meta.json (None when the dataset is gone)
    ranges: dict[str, tuple[float, float]] = field(default_factory=dict)  # design parameters of the training data
    card: dict = field(default_factory=dict)  # shipped models: how they were made
    folder: RunFolder | None = None  # None for a shipped model

    # -- loading -------------------------------------------------------------------------------------------------
    @classmethod
    def load(cls, path: str | Path, device: str | None = None, which: str = "best") -> "Run":
        """A run folder, or ``pretrained:NAME`` (see :func:`available_pretrained`). ``device`` as
        :func:`hcmt.models.resolve_device` (default: CUDA when available); ``which``: ``best`` or ``checkpoint``
        (the latest)."""
        if isinstance(path, Run):
            return path
        dev = resolve_device(device)
        if not isinstance(path, RunFolder) and str(path).startswith("pretrained:"):
            return cls._pretrained(str(path).split(":", 1)[1], dev)
        folder = path if isinstance(path, RunFolder) else RunFolder(path)  # run.yaml parsed once
        model, info = load_run(folder, which, device="cpu")
        meta, ranges = folder.data_facts()
        return cls(model.to(dev), info, folder.source, meta, ranges, folder=folder)

    @classmethod
    def _pretrained(cls, name: str, device: torch.device) -> "Run":
        shipped = available_pretrained()
        if name not in shipped:
            raise ValueError(f"pretrained:{name}: no such shipped model; available: "
                             f"{', '.join(shipped) or 'none'} (`hcmt models` lists them)")
        pack = read_checkpoint(shipped[name])
        try:
            model = from_checkpoint(pack)
        except (KeyError, TypeError, RuntimeError, ValueError) as exc:
            raise ValueError(f"{shipped[name]}: a damaged shipped model ({exc.__class__.__name__}); reinstall hcmt") \
                from None
        info = {"model": pack["model_args"], "config": complete_config(pack["config"]), "data": None,
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

    @cached_property
    def adapter(self):
        return config_adapter(self.config)  # once per run: it validates and completes the config

    @property
    def radius(self) -> float:
        return float(self.config["train"]["contact_radius"])

    @property
    def hierarchy_spec(self) -> tuple[int, bool]:
        """(levels, remesh) of the mesh hierarchy the model needs (0 levels: none)."""
        return uses_hierarchy(self.info["model"])

    @property
    def label(self) -> str:
        return model_label(self.info["model"])

    @property
    def checkpoint_step(self) -> int:
        return int(self.info["checkpoint"]["step"])

    def require_folder(self) -> RunFolder:
        """The run folder (rollouts and metrics are written there); a shipped model has none."""
        if self.folder is None:
            raise ValueError(f"{self.source}: a shipped model has no run folder to write rollouts to; use "
                             "hcmt.predict_designs for designs, or train a run")
        return self.folder

    # -- using it ---------------------------------------------------------------------------------------------------
    def design(self, **params) -> Design:
        """An Impact Plate :class:`~hcmt.sim.scene.Design`: ``params`` over the middle of the model's training
        ranges (:func:`hcmt.sim.scene.middle_design`), validated."""
        return parse_design([f"{k}={v}" for k, v in params.items()], middle_design(self.meta, self.ranges),
                            where="design")

    # -- packaging -------------------------------------------------------------------------------------------------
    def save_pretrained(self, path: str | Path, card: dict, half: bool = True) -> Path:
        """Write this run as one shipped-model file (fp16 weights with ``half``), atomically."""
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
    meta = read_meta(data)
    ranges: dict[str, list[float]] = {}
    if (Path(data) / "train.h5").is_file():
        with Split(data, "train", meta) as s:
            for i in range(len(s)):
                for k, v in s.attrs(i).items():
                    if isinstance(v, (int, float, np.number)) and not isinstance(v, bool):
                        ranges.setdefault(k, []).append(float(v))
    return json.loads(json.dumps(meta)), {k: (min(v), max(v)) for k, v in ranges.items()}


def check_dataset(train_meta: dict | None, data, train_data=None, split: str | None = None) -> list[str]:
    """Whether ``data`` suits a model trained on ``train_meta`` (the training data's meta.json): a different frame
    interval ``dt`` is refused (``ValueError``: a model steps one training interval at a time); another generator
    preset, or node counts outside the training data's (when ``train_data`` and ``split`` are given) give one
    warning line each (returned)."""
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


def dataset_warnings(run: Run, data, split: str) -> list[str]:
    """:func:`check_dataset` of ``data`` against the run's training data (nothing to compare when it is gone):
    raises for another ``dt``, returns the warning lines."""
    own = run.info.get("data")
    return check_dataset(run.meta, data, own if own and Path(own).is_dir() else None, split)
