"""A run folder on disk: :class:`RunFolder` (the one owner of its file names), its ``run.yaml`` and checkpoints,
the rule of when a folder may start or resume a run, and where the shipped models live.

Below both training (which writes a run folder) and inference (which reads one), so that neither goes through the
other to reach its files.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import torch
import yaml

from hcmt.config import (  # noqa: F401 (PRETRAINED_DIR: re-exported)
    PRETRAINED_DIR,
    Config,
    available_pretrained,
    current_model_args,
)
from hcmt.data.format import Split, read_meta
from hcmt.errors import InputError
from hcmt.files import atomic_path, read_json

#: checkpoint names that mean one file: missing, they are an error, never the run's latest
NAMED_CHECKPOINTS = ("step_", "avg_")


class RunFolder:
    """A run folder made by ``hcmt train``: the one owner of its file names, ``run.yaml`` parsed once.

    ``run.yaml`` holds the model's constructor arguments (``model``), the config (``config``), the training data
    (``data``), ``seed`` and ``world_size``; the checkpoints are ``checkpoint.pt`` (latest), ``best.pt`` and
    ``step_<N>.pt`` (kept every ``train.keep_every`` steps);
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
            raise InputError(f"{self.path / 'run.yaml'}: not a run folder (made by `hcmt train --out RUN`){hint}")

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
        """``best.pt``, ``checkpoint.pt``, a kept ``step_<N>.pt`` or an average of kept steps ``avg_<N>_<M>....pt``
        (benchmarks/release/average_checkpoints.py); the latest checkpoint when ``best`` is missing (a kept step or
        an average is never replaced by another)."""
        path = self.path / f"{which}.pt"
        return path if path.is_file() or which.startswith(NAMED_CHECKPOINTS) else self.latest

    @property
    def log(self) -> Path:
        return self.path / "log.jsonl"

    @property
    def best(self) -> Path:
        return self.path / "best.pt"

    @property
    def latest(self) -> Path:
        return self.path / "checkpoint.pt"

    def kept(self, step: int) -> Path:
        """The checkpoint kept at ``step`` (``train.keep_every``): ``step_<step>.pt``."""
        return self.path / f"step_{step}.pt"

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
        return read_json(self.stats_path, "`hcmt train`") if self.stats_path.is_file() else None

    def log_records(self) -> list[dict]:
        """``log.jsonl``'s records in order (each with an integer ``step``); a damaged line is one line naming the
        file and the line."""
        out = []
        for number, line in enumerate(self.log.read_text(encoding="utf-8", errors="replace").splitlines(), 1):
            if not line.strip():
                continue
            try:
                rec = json.loads(line)
                rec["step"] = int(rec["step"])
            except (ValueError, TypeError, KeyError) as exc:
                raise InputError(
                    f"{self.log}, line {number}: not a log record ({exc.__class__.__name__}: "
                    f"{line[:60]!r}); it is written by `hcmt train`"
                ) from None
            out.append(rec)
        return out

    def write_stats(self, summary: dict) -> None:
        """``train_stats.json`` (standard JSON: non-finite numbers become null), atomically."""
        with atomic_path(self.stats_path) as tmp:
            tmp.write_text(
                json.dumps(
                    {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in summary.items()},
                    indent=2,
                )
            )

    def write_info(self, info: dict) -> None:
        """``run.yaml`` (its :class:`hcmt.config.Config` as plain YAML, :meth:`~hcmt.config.Config.to_dict`),
        atomically."""
        with atomic_path(self.run_yaml) as tmp:
            tmp.write_text(yaml.safe_dump(dict(info, config=info["config"].to_dict()), sort_keys=False))
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
                tmp.write_text(json.dumps({"meta": meta, "ranges": {k: list(v) for k, v in ranges.items()}}, indent=1))

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
                raise InputError(
                    f"{self.data_facts_path}: damaged ({exc.__class__.__name__}); it is written by "
                    "`hcmt train` from the training data's meta.json"
                ) from None
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


def beside_model(run, name: str) -> Path | None:
    """A file that belongs to a model (``name``: ``surrogate.json``, ``interval.json``): ``hcmt/pretrained/
    MODEL.NAME`` beside a shipped model, ``RUN/NAME`` in a run folder, None for a model with neither."""
    if str(run.source).startswith("pretrained:"):
        return PRETRAINED_DIR / f"{run.source.split(':', 1)[1]}.{name}"
    folder = getattr(run, "folder", None)
    return folder.path / name if folder is not None else None


def read_run_yaml(path: Path) -> dict:
    """``run.yaml`` as a dict with its ``model`` and, when it has one, its ``config`` read back through
    :meth:`hcmt.config.Config.from_dict` (completed and checked); one line naming the file when it is not."""
    try:
        info = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise InputError(
            f"{path}: not readable YAML ({str(exc).splitlines()[0]}); it is written by `hcmt train` "
            "(restore it, or train the run again)"
        ) from None
    if (
        not isinstance(info, dict)
        or not isinstance(info.get("model"), dict)
        or ("config" in info and not isinstance(info["config"], dict))
    ):
        what = (
            "empty"
            if not info
            else "no model section (the model's constructor arguments)"
            if not isinstance(info, dict) or not isinstance(info.get("model"), dict)
            else "a config that is no mapping"
        )
        raise InputError(f"{path}: {what}; run.yaml is written by `hcmt train` (restore it, or train the run again)")
    info["model"] = current_model_args(info["model"])  # an old no-remesh run: its config says data.remesh false
    if "config" in info:
        try:
            info["config"] = Config.from_dict(info["config"], str(path))
        except (TypeError, ValueError) as exc:
            raise InputError(
                f"{path}: its settings do not load ({str(exc).splitlines()[0][:200]}); restore it or "
                "train the run again"
            ) from None
    return info


def read_checkpoint(path: Path, device="cpu", earlier: Path | None = None) -> dict:
    """A checkpoint (``torch.load(weights_only=True)``) as a dict; a truncated, empty or foreign file is one line
    naming it and what can be done: copy the run's other checkpoint (``earlier``) over it when that one is readable,
    else train the run again."""
    try:
        state = torch.load(path, map_location=device, weights_only=True)
        if not isinstance(state, dict) or "model" not in state:
            raise InputError(f"{path}: not an hcmt checkpoint (no model weights){_other_checkpoint(path, earlier)}")
    except (FileNotFoundError, InputError):
        raise
    except Exception as exc:  # torch raises RuntimeError, EOFError, UnpicklingError, ...: all mean "damaged"
        raise InputError(
            f"{path}: not a readable checkpoint (truncated or corrupt: {exc.__class__.__name__})"
            f"{_other_checkpoint(path, earlier)}"
        ) from None
    if isinstance(state.get("model_args"), dict):  # an old no-remesh checkpoint: the model is HCMT's own
        state["model_args"] = current_model_args(state["model_args"])
    return state


def _other_checkpoint(path: Path, earlier: Path | None) -> str:
    """The advice of a damaged checkpoint: the run's other one, only when it can be read."""
    if earlier is None or not earlier.is_file() or earlier == path:
        return "; restore it, or train the run again"
    try:
        state = torch.load(earlier, map_location="cpu", weights_only=True)
        usable = isinstance(state, dict) and "model" in state
    except Exception:  # damaged as well
        usable = False
    if usable:
        return f"; the run's {earlier.name} is readable (copy it over {path.name} to go on from it)"
    return f"; {earlier.name} is damaged too: restore them, or train the run again"


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


def check_start(folder: RunFolder, resume: bool, *, flags: bool = False) -> None:
    """The one rule of a run folder's start: ``resume`` needs a readable run with a checkpoint, a new run needs a
    folder that holds none. One line each, in the command line's words with ``flags`` (``--resume``, ``--out``),
    else in the Python API's (``resume=True``, ``overwrite=True``)."""
    if resume and folder.damaged:
        raise InputError(folder.damaged)
    if resume and folder.info is not None and "config" not in folder.info:
        raise InputError(
            f"{folder.run_yaml}: no config section, so the run cannot be resumed; it is written by "
            "`hcmt train` (restore it, or train the run again)"
        )
    if resume and not folder.latest.is_file():
        raise FileNotFoundError(
            f"{folder.latest}: nothing to resume; start without {'--resume' if flags else 'resume=True'}"
        )
    if not resume and folder.holds_run():
        raise InputError(
            f"{folder.path} already holds a run; pass --resume to continue it or choose another --out"
            if flags
            else f"hcmt.train: {folder.path} already holds a run; pass resume=True to continue "
            "it, overwrite=True to delete it and start afresh, or another out folder"
        )
