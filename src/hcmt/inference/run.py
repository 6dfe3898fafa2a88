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
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path

import numpy as np
import torch

from hcmt.config import NO_REMESH, Config, check_same_dataset, default_threads
from hcmt.data.format import Split, read_meta
from hcmt.data.runs import NAMED_CHECKPOINTS, RunFolder, available_pretrained, read_checkpoint
from hcmt.domains.adapters import config_adapter
from hcmt.errors import InputError, clip
from hcmt.files import atomic_path
from hcmt.models import REGISTRY, from_checkpoint, resolve_device, uses_hierarchy


def model_label(args: dict, config: Config | None = None) -> str:
    """The display label of a model from its constructor arguments (:data:`hcmt.models.REGISTRY`), with its
    ablation, and ``no-remesh`` where its ``config`` builds the hierarchy without remeshing (``data.remesh``)."""
    info = REGISTRY.get(args["name"]) if "name" in args else None
    label = info.label if info else str(args.get("name")).upper()
    remesh = config is None or config.data.remesh or not uses_hierarchy(args, False)[0]
    return label + (f" ({args['ablation']})" if args.get("ablation") else "") + ("" if remesh else f" ({NO_REMESH})")


@dataclass(frozen=True)
class CheckpointInfo:
    """The checkpoint a :class:`Run` was loaded from: its file name and training step."""

    file: str
    step: int


@dataclass(frozen=True)
class RunInfo:
    """What a trained model is: ``run.yaml``'s record (a shipped model's pack) and the checkpoint loaded.

    ``model`` is the model's constructor arguments (:func:`hcmt.models.make_model`), ``config`` the run's
    :class:`hcmt.config.Config`, ``data`` the resolved training-data path (None for a shipped model), ``seed``,
    ``world_size`` (processes) and ``init`` (``{from, normalizers, step}`` of a fine-tuned run) as ``run.yaml``
    holds them (None when it does not)."""

    model: dict
    config: Config
    data: str | None
    checkpoint: CheckpointInfo
    seed: int | None = None
    world_size: int | None = None
    init: dict | None = None

    @classmethod
    def from_record(cls, record: dict, checkpoint: CheckpointInfo) -> "RunInfo":
        """From ``run.yaml``'s record (:attr:`hcmt.data.runs.RunFolder.info`); a KeyError when it has no model or
        config."""
        return cls(
            model=record["model"],
            config=record["config"],
            data=record.get("data"),
            checkpoint=checkpoint,
            seed=record.get("seed"),
            world_size=record.get("world_size"),
            init=record.get("init"),
        )


def load_run(run: str | Path | RunFolder, which: str = "best", device: str = "cpu") -> tuple[torch.nn.Module, RunInfo]:
    """(model, :class:`RunInfo`) of a run folder; ``which`` is ``best``, ``checkpoint``, ``step_<N>`` (a checkpoint
    kept by ``train.keep_every``) or ``avg_<N>_<M>...`` (their average, benchmarks/release/average_checkpoints.py)."""
    folder = run if isinstance(run, RunFolder) else RunFolder(run)
    path = folder.checkpoint(which)
    if not path.is_file():
        raise InputError(
            f"{path}: no such checkpoint"
            if which.startswith(NAMED_CHECKPOINTS)
            else f"{folder.path}: no checkpoint yet (best.pt / checkpoint.pt)"
        )
    state = read_checkpoint(path, device, earlier=folder.latest if path == folder.best else folder.best)
    try:
        model = from_checkpoint(state)
    except (KeyError, TypeError, RuntimeError, ValueError) as exc:
        raise InputError(
            f"{path}: the checkpoint does not hold the model run.yaml describes ({exc.__class__.__name__}:"
            f" {str(exc).splitlines()[0][:200]})"
        ) from None
    if folder.info is None:  # a RunFolder(must_exist=False) whose run.yaml is missing or damaged
        raise InputError(folder.damaged or f"{folder.run_yaml}: missing; restore it or train the run again")
    try:  # a hand-edited or damaged run.yaml: its settings must still make the run's adapter and graph
        info = RunInfo.from_record(folder.info, CheckpointInfo(path.name, int(state["step"])))
        config_adapter(info.config.for_training())  # a KeyError when run.yaml has no config
        uses_hierarchy(info.model, info.config.data.remesh)
    except (TypeError, ValueError, KeyError, AttributeError) as exc:
        raise InputError(
            f"{folder.run_yaml}: its settings do not load ({exc.__class__.__name__}: "
            f"{str(exc).splitlines()[0][:160] if str(exc) else '-'}); restore it or train the run again"
        ) from None
    return model, info


@dataclass
class Run:
    """A trained model with its config and training-data facts: the handle that rollout, evaluation, pictures and
    the design check take. Make one with :meth:`load`."""

    model: torch.nn.Module
    info: RunInfo  # run.yaml's record (model arguments, config, data, seed) and the checkpoint loaded
    source: str  # the run folder or ``pretrained:NAME``
    meta: dict | None = None  # the training data's meta.json (None when the dataset is gone)
    ranges: dict[str, tuple[float, float]] = field(default_factory=dict)  # design parameters of the training data
    card: dict = field(default_factory=dict)  # shipped models: how they were made
    folder: RunFolder | None = None  # None for a shipped model

    # -- loading -------------------------------------------------------------------------------------------------
    @classmethod
    def load(cls, path: str | Path, device: str | None = None, which: str = "best") -> "Run":
        """A run folder, or ``pretrained:NAME`` (see :func:`available_pretrained`). ``device`` as
        :func:`hcmt.models.resolve_device` (default: CUDA when available); ``which``: ``best``, ``checkpoint``
        (the latest) or ``step_<N>`` (kept by ``train.keep_every``)."""
        if isinstance(path, Run):
            return path
        default_threads()  # the Python API's threads as the command's --threads auto (kept if the caller chose)
        dev = resolve_device(device)
        if not isinstance(path, RunFolder) and str(path).startswith("pretrained:"):
            return cls._pretrained(str(path).split(":", 1)[1], dev)
        if not isinstance(path, RunFolder) and not (Path(path) / "run.yaml").is_file():
            raise InputError(
                f"{clip(path)!r}: "
                + ("no such folder" if not Path(path).exists() else "no run.yaml")
                + "; expected a run folder made by `hcmt train`, or pretrained:NAME "
                "(hcmt.available_pretrained())",
                param="path",
            )
        folder = path if isinstance(path, RunFolder) else RunFolder(path)  # run.yaml parsed once
        model, info = load_run(folder, which, device="cpu")
        meta, ranges = folder.data_facts()
        return cls(model.to(dev), info, folder.source, meta, ranges, folder=folder)

    @classmethod
    def _pretrained(cls, name: str, device: torch.device) -> "Run":
        shipped = available_pretrained()
        if name not in shipped:
            raise InputError(
                f"'pretrained:{clip(name)}': no such shipped model; available: "
                f"{', '.join(shipped) or 'none'} (`hcmt models` lists them)",
                param="path",
            )
        pack = read_checkpoint(shipped[name])
        try:
            model = from_checkpoint(pack)
        except (KeyError, TypeError, RuntimeError, ValueError) as exc:
            raise InputError(
                f"{shipped[name]}: a damaged shipped model ({exc.__class__.__name__}); reinstall hcmt"
            ) from None
        card = pack["card"]  # the step of the weights shipped (a kept checkpoint), else the schedule's (older packs)
        step = int(card.get("checkpoint", {}).get("step", card.get("steps", 0)))
        info = RunInfo(
            model=pack["model_args"],
            config=Config.from_dict(pack["config"], str(shipped[name])),
            data=None,
            checkpoint=CheckpointInfo(shipped[name].name, step),
        )
        ranges = {k: (float(v[0]), float(v[1])) for k, v in pack["ranges"].items()}
        return cls(model.to(device), info, f"pretrained:{name}", pack["meta"], ranges, pack["card"])

    # -- what the run is -------------------------------------------------------------------------------------------
    @property
    def config(self) -> Config:
        return self.info.config

    @property
    def device(self) -> torch.device:
        return next(self.model.parameters()).device

    @cached_property
    def adapter(self):
        return config_adapter(self.config)  # once per run

    @property
    def radius(self) -> float:
        radius = self.config.train.contact_radius
        if radius is None:  # Run.load's configs are complete for training; a Run made by hand may not be
            raise InputError(
                f"{self.source}: its config has no train.contact_radius (the contact search radius "
                "its model was trained with)"
            )
        return radius

    @property
    def hierarchy_spec(self) -> tuple[int, bool]:
        """(levels, remesh) of the mesh hierarchy the model needs (0 levels: none)."""
        return uses_hierarchy(self.info.model, self.config.data.remesh)

    @property
    def label(self) -> str:
        return model_label(self.info.model, self.config)

    @property
    def checkpoint_step(self) -> int:
        return self.info.checkpoint.step

    def require_folder(self) -> RunFolder:
        """The run folder (rollouts and metrics are written there); a shipped model has none unless given one
        (:meth:`writing_to`)."""
        if self.folder is None:
            raise InputError(
                f"{self.source}: a shipped model has no run folder to write rollouts to; give it one "
                "(run.writing_to(DIR); hcmt evaluate --out DIR), or use hcmt.predict_designs for designs"
            )
        return self.folder

    def writing_to(self, path: str | Path) -> "Run":
        """This shipped model with ``path`` as the folder its rollouts and metrics are written to
        (``rollout_<split>.h5``, ``metrics_<split>.json``; made when missing): ``hcmt evaluate pretrained:NAME
        --out DIR``."""
        if self.folder is not None:
            raise InputError(f"{self.source}: a run folder writes its rollouts and metrics to itself", param="path")
        Path(path).mkdir(parents=True, exist_ok=True)
        return replace(self, folder=RunFolder(path, must_exist=False))

    # -- packaging -------------------------------------------------------------------------------------------------
    def save_pretrained(self, path: str | Path, card: dict, half: bool = True) -> Path:
        """Write this run as one shipped-model file (fp16 weights with ``half``), atomically."""
        if self.meta is None or not self.ranges:
            raise InputError(
                f"{self.source}: its training dataset ({self.info.data}) is needed to record "
                "the design ranges; keep it next to the run"
            )
        state = {
            k: (v.half() if half and v.dtype == torch.float32 else v).cpu() for k, v in self.model.state_dict().items()
        }
        pack = {
            "model_args": self.info.model,
            "model": state,
            "config": self.config.to_dict(),
            "meta": self.meta,
            "ranges": {k: [float(a), float(b)] for k, (a, b) in self.ranges.items()},
            "card": json.loads(json.dumps(card, default=str)),
        }  # plain types: loads with weights_only=True
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(path) as tmp:
            torch.save(pack, tmp)
        return path


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
        raise InputError(
            f"{data}: frames {b} apart (dt), but the model was trained on frames {a} apart; a model "
            f"steps one training interval at a time: use data recorded at dt {a}"
        )
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
            out.append(
                f"{data} {split}: {min(now)}-{max(now)} nodes per trajectory, the training data "
                f"{min(trained)}-{max(trained)}: expect larger errors"
            )
    return out


def dataset_warnings(run: Run, data, split: str) -> list[str]:
    """:func:`check_dataset` of ``data`` against the run's training data (nothing to compare when it is gone):
    raises for another ``dt``, returns the warning lines."""
    check_same_dataset(run.config.dataset, read_meta(data), data, f"run {clip(str(run.source))}")
    own = run.info.data
    return check_dataset(run.meta, data, own if own and Path(own).is_dir() else None, split)
