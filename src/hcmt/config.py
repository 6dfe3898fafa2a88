"""YAML configs: built-in ones by name (``src/hcmt/configs/NAME.yaml``, also reachable as ``configs/``), or a
file path. A config may name a ``base`` config whose values it overrides. Any key can be overridden from the
command line as ``section.key=value`` (the value is parsed as YAML: ``train.lr=3e-4``, ``model.levels=4``)."""
from __future__ import annotations

import copy
import difflib
from dataclasses import asdict, dataclass, field, fields
from typing import Optional, get_args, get_origin, get_type_hints
from pathlib import Path

import yaml


#: the package version (``hcmt --version``, ``hcmt.__version__``)
VERSION = "0.1.0"
CONFIG_DIR = Path(__file__).resolve().parent / "configs"
#: the datasets hcmt knows (a config's ``dataset``; each has an adapter in :mod:`hcmt.physics.adapters`)
DATASET_NAMES = ("impact_plate", "deforming_plate", "sphere_simple", "deformable_plate")
#: ``torch.compile`` modes (``train.compile``, ``--compile``); ``none`` is eager
COMPILE_MODES = ("none", "default", "reduce-overhead", "max-autotune")


def builtin_configs() -> list[str]:
    return sorted(p.stem for p in CONFIG_DIR.glob("*.yaml"))


def _read(name_or_path: str) -> dict:
    path = Path(name_or_path)
    if not path.is_file():
        path = CONFIG_DIR / f"{name_or_path}.yaml"
    if not path.is_file():
        raise FileNotFoundError(f"config {name_or_path!r}: neither a file nor a built-in config "
                                f"(built-in: {', '.join(builtin_configs())})")
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        raise ValueError(f"config {path}:{where}: not valid YAML ({getattr(exc, 'problem', None) or exc})") from None
    if not isinstance(data, dict):
        raise ValueError(f"config {path}: expected a mapping at top level")
    base = data.pop("base", None)
    check_schema(data, str(path))
    return merge(_read(base), data) if base else data


def merge(base: dict, over: dict) -> dict:
    out = copy.deepcopy(base)
    for k, v in over.items():
        out[k] = merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else copy.deepcopy(v)
    return out


def parse_value(raw: str):
    """A command-line value: a number if it reads as one (YAML 1.1 takes ``3e-4`` for a string), else YAML."""
    for kind in (int, float):
        try:
            return kind(raw)
        except ValueError:
            pass
    return yaml.safe_load(raw)


def load_config(name_or_path: str, overrides: list[str] | None = None) -> dict:
    """A config by name or path, its ``base`` chain merged, then ``section.key=value`` overrides
    (:func:`apply_overrides`), completed with the schema's defaults (:func:`complete_config`); every key and value
    checked against the schema (one line naming the file or ``--set``, the key, what was expected)."""
    return complete_config(apply_overrides(_read(name_or_path), overrides))


def apply_overrides(cfg: dict, overrides: list[str] | None) -> dict:
    """``cfg`` (a copy) with ``section.key=value`` items applied, each checked against the schema first (the one
    path of ``--set``, for a new run and for ``--resume``)."""
    cfg = copy.deepcopy(cfg)
    for item in overrides or []:
        key, sep, raw = item.partition("=")
        if not sep or not key:
            raise ValueError(f"--set {item!r}: expected section.key=value")
        *parents, leaf = key.split(".")
        check_schema(_nest(parents + [leaf], parse_value(raw)), f"--set {item}")
        node = cfg
        for p in parents:
            node = node.setdefault(p, {})
        node[leaf] = parse_value(raw)
    return cfg


def _nest(keys: list[str], value):
    return {keys[0]: _nest(keys[1:], value)} if len(keys) > 1 else {keys[0]: value}


# -- the schema: one dataclass per section, its fields' defaults the defaults ---------------------------------------
def _choice(default, *allowed):
    return field(default=default, metadata={"allowed": allowed})


@dataclass
class ModelConfig:
    """``model:`` (paper Table 8 depths; ``hidden`` is the latent width)."""

    hidden: int = 128
    heads: int = 4
    L_C: int = 2  # contact-mesh transformer blocks
    levels: int = 0  # λ, the hierarchy's levels (HCMT)
    L_H: Optional[int] = None  # 2λ + 1 when given
    clip: float = 2.0  # attention logit clip
    blocks: int = 15  # message-passing blocks of MGN and GT
    ffn_bias: bool = True
    attention: str = _choice("paper", "paper", "official")
    target: Optional[str] = _choice(None, "velocity", "acceleration")  # None: the dataset's Table 9 output
    deformation: bool = False  # hcmt's edge deformation features x_ij − u_ij and stretch


@dataclass
class TrainConfig:
    """``train:`` (Table 8's schedule and noise; hcmt's speed and formulation options)."""

    steps: Optional[int] = None  # required (check_train_config)
    lr: Optional[float] = None  # required
    contact_radius: Optional[float] = None  # required: the contact search radius (Table 8's γ)
    batch_size: int = 1
    lr_final: Optional[float] = None  # None: constant ``lr``
    lr_decay_steps: Optional[int] = None  # None: decay over ``steps``
    lr_decay_rate: float = 0.1
    noise_std: float = 0.0
    noise_gamma: Optional[float] = None  # None: 1.0 for a velocity target, 0.1 for acceleration
    noise_nodes: str = _choice("normal", "normal", "predicted")
    pushforward: float = 0.0  # probability in [0, 1]
    pushforward_start: int = 0
    normalizer_steps: int = 0
    normalizer_warmup: str = _choice("all", "all", "nodes")
    mesh_edges_twice: bool = False
    loss_denominator: str = _choice("masked", "masked", "nodes")
    adam_epsilon: Optional[float] = None  # None: 1e-8 (PyTorch's), 1e-7 with adam_epsilon_hat (Keras')
    adam_epsilon_hat: bool = False
    log_every: int = 100
    checkpoint_every: int = 1000
    valid_every: int = 0
    valid_trajectories: int = 2
    contact_pairs: str = _choice("all", "all", "official")
    workers: int = 0
    checkpoint_blocks: bool = False
    precision: str = _choice("fp32", "fp32", "bf16")
    compile: str = _choice("none", *COMPILE_MODES)
    deterministic: bool = False


@dataclass
class DataConfig:
    """``data:``."""

    exclude_trajectories: Optional[list] = None  # trajectory indices of the train split to leave out
    stress_field: str = _choice("stress", "stress", "stress_max")  # stress_max: `generate --peak-stress`


SECTIONS = {"model": ModelConfig, "train": TrainConfig, "data": DataConfig}
_KIND = {int: "a whole number", float: "a number", bool: "true or false", str: "a string",
         list: "a list of trajectory indices"}


def _spec(cls) -> dict[str, tuple[str, tuple | None, bool]]:
    """key -> (what it must be, allowed values or None, may be null) of a section dataclass."""
    hints = get_type_hints(cls)
    out = {}
    for f in fields(cls):
        t = hints[f.name]
        args = [a for a in get_args(t) if a is not type(None)]
        base = args[0] if args else t
        out[f.name] = (_KIND[get_origin(base) or base], f.metadata.get("allowed") or None, type(None) in get_args(t))
    return out


#: every key a config may hold: section -> key -> (what it must be, allowed values or None, may be null)
SCHEMA: dict[str, dict[str, tuple]] = {name: _spec(cls) for name, cls in SECTIONS.items()}
TOP = {"dataset": ("a string", DATASET_NAMES)}


def complete_config(cfg: dict) -> dict:
    """``cfg`` (a copy) with every section key present: the dataclass defaults fill what the file left out, so
    code reads ``cfg["train"]["noise_std"]`` without a default of its own. Checked against the schema."""
    check_schema(cfg)
    out = copy.deepcopy(cfg)
    for name, cls in SECTIONS.items():
        out[name] = asdict(cls(**(cfg.get(name) or {})))
    return out


def _ok(kind: str, value) -> bool:
    if kind == "a whole number":
        return (isinstance(value, int) and not isinstance(value, bool)) or (
            isinstance(value, float) and value.is_integer())
    if kind == "a number":
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if kind == "true or false":
        return isinstance(value, bool)
    if kind == "a string":
        return isinstance(value, str)
    return isinstance(value, list) and all(isinstance(v, int) and not isinstance(v, bool) for v in value)


def _unknown(key: str, known: list[str], source: str):
    close = difflib.get_close_matches(key, known, n=1, cutoff=0.6)
    hint = f"; did you mean {close[0]}?" if close else f"; known: {', '.join(known)}"
    return ValueError(f"config {source}: {key}: unknown key{hint}")


def check_schema(cfg: dict, source: str = "config") -> None:
    """Refuse unknown keys (with the closest known one), values of the wrong type and values outside a fixed set."""
    sections = list(SCHEMA)
    for top, value in cfg.items():
        if top in TOP:
            kind, allowed = TOP[top]
            if not _ok(kind, value) or (allowed and value not in allowed):
                raise ValueError(f"config {source}: {top}: got {value!r}; expected one of {', '.join(allowed)}")
            continue
        if top == "base":
            continue
        if top not in SCHEMA:
            raise _unknown(top, sections + list(TOP), source)
        if not isinstance(value, dict):
            raise ValueError(f"config {source}: {top}: expected a section of keys, got {value!r}")
        for key, v in value.items():
            if key not in SCHEMA[top]:
                raise _unknown(f"{top}.{key}", [f"{top}.{k}" for k in SCHEMA[top]]
                               + [f"{s}.{k}" for s in SCHEMA for k in SCHEMA[s] if s != top], source)
            kind, allowed, nullable = SCHEMA[top][key]
            if v is None and nullable:
                continue
            if not _ok(kind, v):
                raise ValueError(f"config {source}: {top}.{key}: got {v!r}; expected {kind}")
            if allowed and v not in allowed:
                raise ValueError(f"config {source}: {top}.{key}: unknown value {v!r}; expected one of "
                                 f"{', '.join(allowed)}")
            if key == "pushforward" and not 0 <= v <= 1:
                raise ValueError(f"config {source}: train.pushforward: got {v!r}; expected a probability in [0, 1]")


def check_train_config(cfg: dict) -> None:
    """What training needs beyond the schema: a dataset, steps, a learning rate and a contact radius."""
    tc = cfg["train"]
    for key in ("steps", "lr", "contact_radius"):
        if tc.get(key) is None:
            raise ValueError(f"config: train.{key} is missing (see configs/impact_plate.yaml for a complete config)")
    if "dataset" not in cfg:
        raise ValueError("config: `dataset` (the adapter: impact_plate, deforming_plate, ...) is missing")
    steps = tc["steps"]
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
        raise ValueError(f"train.steps must be a whole number >= 1, got {steps!r}")
    batch_size = tc["batch_size"]
    if isinstance(batch_size, bool) or not isinstance(batch_size, int) or batch_size < 1:
        raise ValueError(f"train.batch_size must be a whole number >= 1, got {batch_size!r}")
    if not isinstance(tc["lr"], (int, float)) or not tc["lr"] > 0:
        raise ValueError(f"train.lr must be a number > 0, got {tc['lr']!r}")


def plural(n: int, word: str, many: str | None = None) -> str:
    """``1 trajectory``, ``2 trajectories``: a count with its noun (``many``: the plural when not ``word + s``)."""
    return f"{n} {word if n == 1 else (many or word + 's')}"
