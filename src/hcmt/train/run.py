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
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

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
                "ranges": {k: [float(a), float(b)] for k, (a, b) in self.ranges.items()}, "card": card}
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

