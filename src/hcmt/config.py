"""YAML configs: built-in ones by name (``src/hcmt/configs/NAME.yaml``, also reachable as ``configs/``), or a
file path. A config may name a ``base`` config whose values it overrides: a built-in config's name, or a path read
from the folder of the file naming it; a chain that returns to a file is refused. Files are read as YAML 1.1 with
YAML 1.2's floats (``lr: 1e-3`` is a number) and without duplicate keys (refused, both lines named). Any key can be
overridden from the command line as ``section.key=value`` (the value is parsed as YAML: ``train.lr=3e-4``,
``model.levels=4``)."""
from __future__ import annotations

import copy
import difflib
import os
import re
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Optional, get_args, get_origin, get_type_hints

import yaml

from hcmt.errors import InputError, clip

#: the package version (``hcmt --version``, ``hcmt.__version__``)
VERSION = "0.1.0"
CONFIG_DIR = Path(__file__).resolve().parent / "configs"
#: the models shipped inside the package (``pretrained:NAME``)
PRETRAINED_DIR = Path(__file__).resolve().parent / "pretrained"
#: the datasets hcmt knows (a config's ``dataset``; each has an adapter in :mod:`hcmt.domains.adapters`)
DATASET_NAMES = ("impact_plate", "deforming_plate", "sphere_simple", "deformable_plate")
#: ``torch.compile`` modes (``train.compile``, ``--compile``); ``none`` is eager, ``auto`` compiles a long run where
#: a compiler exists (:func:`hcmt.models.base.resolve_compile`); the rest are ``torch.compile``'s own modes
COMPILE_MODES = ("none", "auto", "default", "reduce-overhead", "max-autotune")
TORCH_COMPILE_MODES = COMPILE_MODES[2:]
#: inference's modes (``--compile`` of ``hcmt rollout / evaluate / predict / sweep``) add ``aot``: the forward exported
#: ahead of time with symbolic sizes and compiled once per machine (:mod:`hcmt.models.export`), loaded in milliseconds
INFERENCE_COMPILE_MODES = (*COMPILE_MODES, "aot")
#: the models (:data:`hcmt.models.REGISTRY`, in this order) and HCMT's ablations (paper Tables 3, 10-12)
MODELS = ("hcmt", "mgn", "gt")
ABLATIONS = ("late-contact", "only-cmt", "only-hmt", "lpe", "single-branch")
#: the paper's remeshing ablation ("HCMT without remeshing", appendix "Additional Ablation Study") changes the graph,
#: not the model: it is ``data.remesh: false``. Its old spelling, ``model.ablation: no-remesh`` (configs, ``--set``,
#: ``hcmt train --ablation no-remesh``, the ``model`` of run.yaml files and checkpoints written before), still reads,
#: as an alias: :class:`Config` and :func:`current_model_args` translate it where a config or model arguments are read
NO_REMESH = "no-remesh"
ABLATION_ALIASES = (NO_REMESH,)
#: ``init_normalizers``: a fine-tuned run keeps its source's normalizer statistics, frozen (the few runs of a new
#: family make poor statistics), or zeroes them and accumulates them afresh on its own data
INIT_NORMALIZERS = ("keep", "reaccumulate")
#: the bounds of the counts every command and API function takes (one rule: above the bound, refused in one line):
#: trajectories of one split, designs of one design check or sweep, trajectories or designs in one batch
MAX_TRAJECTORIES, MAX_DESIGNS, MAX_BATCH = 100_000, 10_000, 1024


def builtin_configs() -> list[str]:
    return sorted(p.stem for p in CONFIG_DIR.glob("*.yaml"))


class _Loader(yaml.SafeLoader):
    """PyYAML's safe loader (YAML 1.1) with YAML 1.2's floats, ``1e-3``, ``1E-3`` and ``-.5`` (1.1 reads the first
    two as strings), and duplicate keys refused (1.1 keeps the last silently): :func:`load_yaml`."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+|\.[0-9][0-9_]*(?:[eE][-+]?[0-9]+)?)$"),
    list("-+0123456789."))


def load_yaml(text: str, where: str):
    """``text`` read as YAML (:class:`_Loader`); a key given twice in one mapping is refused in one line naming
    ``where`` (``config FILE``), the key (``train.steps``) and both lines."""
    loader = _Loader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        _no_twice(node, (), where, set())
        return loader.construct_document(node)
    finally:
        loader.dispose()


def _no_twice(node, path: tuple, where: str, seen: set) -> None:
    if id(node) in seen:  # an alias: checked where its anchor stands
        return
    seen.add(id(node))
    if isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            _no_twice(item, (*path, f"[{i}]"), where, seen)
    if not isinstance(node, yaml.MappingNode):
        return
    lines: dict = {}
    for key, value in node.value:
        name = key.value if isinstance(key, yaml.ScalarNode) else None
        if name is not None and key.tag != "tag:yaml.org,2002:merge":
            if (key.tag, name) in lines:
                dotted = ".".join((*path, str(name))).replace(".[", "[")
                raise InputError(f"{where}: key {clip(dotted)} given twice, lines {lines[key.tag, name]} and "
                                 f"{key.start_mark.line + 1}; keep one")
            lines[key.tag, name] = key.start_mark.line + 1
        _no_twice(value, (*path, str(name)), where, seen)


def _locate(name_or_path, within: Path | None) -> Path:
    """The file a config name or path means: a path (a ``base``'s from the folder of the config naming it,
    ``within``), else a built-in config's name."""
    if not isinstance(name_or_path, (str, os.PathLike)) or not str(name_or_path).strip():
        if within is not None:
            raise InputError(f"config {within}: base: got {clip(repr(name_or_path))}; expected a built-in config's "
                             "name or a YAML path (from this file's folder)")
        raise InputError(f"expected a built-in config's name or a YAML path, got {clip(repr(name_or_path))}",
                         param="name_or_path")
    path = Path(name_or_path)
    if within is not None and not path.is_absolute():
        path = within.parent / path
    if path.is_file():
        return path
    if str(name_or_path) in builtin_configs():
        return CONFIG_DIR / f"{name_or_path}.yaml"
    where = f" (the base of {within}, looked for in {within.parent})" if within else ""
    raise InputError(f"{clip(str(name_or_path))!r}{where}: neither a file nor a built-in config "
                     f"({', '.join(builtin_configs())})", param=None if within else "name_or_path")


def _read(name_or_path, within: Path | None = None, chain: tuple = ()) -> dict:
    """A config file's keys, its ``base`` chain merged (``within``: the file naming ``name_or_path`` as its base;
    ``chain``: the files read so far on the way, (resolved, as shown), whose return is a loop, refused)."""
    path = _locate(name_or_path, within)
    key = path.resolve()
    if any(key == k for k, _ in chain):
        raise InputError(_loop([*chain, (key, path)]))
    chain = (*chain, (key, path))
    try:
        data = load_yaml(path.read_text(encoding="utf-8"), f"config {path}") or {}
    except UnicodeDecodeError:
        raise InputError(f"config {path}: not a text file (not UTF-8)") from None
    except RecursionError:  # YAML's reader recurses per level
        raise InputError(f"config {path}: nested too deeply for a config (its sections hold keys, one level)") \
            from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        raise InputError(f"config {path}:{where}: not valid YAML ({getattr(exc, 'problem', None) or exc})") from None
    if not isinstance(data, dict):
        raise InputError(f"config {path}: expected a mapping at top level")
    base = data.pop("base", None)
    check_schema(data, str(path))
    return merge(_read(base, path, chain), data) if base is not None else data


def _loop(chain: list) -> str:
    """The message of a ``base`` chain that returns to a file read before: the files of the loop, each after the
    first named from the first's folder where it lies there."""
    start = next(i for i, (k, _) in enumerate(chain) if k == chain[-1][0])
    loop = [p for _, p in chain[start:]]
    home = loop[0].resolve().parent

    def short(p: Path) -> str:
        return str(p.resolve().relative_to(home)) if p.resolve().is_relative_to(home) else str(p)

    names = " -> ".join([str(loop[0]), *(short(p) for p in loop[1:])])
    return (f"config {loop[0]}: its base chain is a loop, {names}; each file names the next as its `base`: remove "
            "or change one of them")


def set_in(name_or_path, key: str) -> str | None:
    """The config of ``name_or_path``'s ``base`` chain whose file sets the top-level ``key`` (a built-in one by its
    name), or None: for messages, on a chain :func:`load_config` has read already."""
    path = _locate(name_or_path, None)
    while True:
        data = load_yaml(path.read_text(encoding="utf-8"), f"config {path}") or {}
        if key in data:
            return path.stem if path.parent == CONFIG_DIR else str(path)
        if data.get("base") is None:
            return None
        path = _locate(data["base"], path)


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
    try:
        return load_yaml(raw, f"the value {clip(raw)!r}")
    except yaml.YAMLError as exc:
        raise InputError(f"the value {clip(raw)!r} is not a YAML value ({getattr(exc, 'problem', None) or exc})") \
            from None


def load_config(name_or_path: str | os.PathLike, overrides: list[str] | str | None = None) -> "Config":
    """A config by name or path, its ``base`` chain merged, then ``section.key=value`` overrides
    (:func:`apply_overrides`), as a complete :class:`Config`; every key and value checked against the schema (one
    line naming the file or the override, the key, what was expected; a bad override is an :class:`InputError`
    of the parameter ``overrides``, which ``hcmt train`` words as its ``--set``). A ``base`` path is read from the
    folder of the file naming it; one string of overrides is one item (``"train.steps=20"``)."""
    return Config.from_dict(apply_overrides(_read(name_or_path), overrides), str(name_or_path))


def apply_overrides(cfg: dict, overrides: list[str] | None) -> dict:
    """``cfg`` (a copy) with ``section.key=value`` items applied, each checked against the schema first (the one
    path of every override, ``hcmt train --set`` for a new run and for ``--resume``)."""
    cfg = copy.deepcopy(cfg)
    for item in override_list(overrides):
        try:
            key, sep, raw = str(item).partition("=")
            if not sep or not key:
                raise InputError("expected section.key=value")
            *parents, leaf = key.split(".")
            value = parse_value(raw)
            check_schema(_nest(parents + [leaf], value), None)
        except InputError as exc:  # param: `hcmt train` prints its flag, --set
            raise InputError(f"{clip(item)!r}: {exc.detail}", param="overrides") from None
        node = cfg
        for p in parents:
            node = node.setdefault(p, {})
        node[leaf] = value
    return cfg


def override_list(overrides) -> list:
    """``overrides`` as a list: None is none, and one string is one item (``"train.steps=20"``; never its
    characters); a list or tuple as it is; anything else refused in one line."""
    if overrides is None:
        return []
    if isinstance(overrides, str):
        return [overrides]
    if isinstance(overrides, (list, tuple)):
        return list(overrides)
    raise InputError(f"expected a list of section.key=value strings, got {type(overrides).__name__} "
                     f"{clip(repr(overrides))}", param="overrides")


def _nest(keys: list[str], value):
    return {keys[0]: _nest(keys[1:], value)} if len(keys) > 1 else {keys[0]: value}


# -- the schema: one frozen dataclass per section, its fields' defaults the defaults --------------------------------
# Kept hand-written (stdlib dataclasses): pydantic adds 185 ms and OmegaConf 272 ms to the import of the parsers
# before torch loads (python -X importtime, this machine, 2026-12-03), for the same ~150 lines of checks and messages.
def _field(default, *allowed, required: bool = False, minimum=None, maximum=None, above=None, says=None):
    """A schema field: ``allowed`` values, ``required`` to train, and bounds (``minimum <= v <= maximum``,
    ``v > above``) that :func:`check_schema` enforces; ``says``: how its message names the bounds."""
    return field(default=default, metadata={"allowed": allowed, "required": required, "minimum": minimum,
                                            "maximum": maximum, "above": above, "says": says})


@dataclass(frozen=True)
class ModelConfig:
    """``model:`` (paper Table 8 depths; ``hidden`` is the latent width)."""

    hidden: int = _field(128, minimum=1)
    heads: int = _field(4, minimum=1)
    L_C: int = _field(2, minimum=0)  # contact-mesh transformer blocks
    levels: int = _field(0, minimum=0)  # λ, the hierarchy's levels (HCMT); its L_H = 2λ + 1 blocks are derived
    clip: float = 2.0  # attention logit clip
    blocks: int = _field(15, minimum=1)  # message-passing blocks of MGN and GT
    ffn_bias: bool = True
    attention: str = _field("paper", "paper", "official")
    target: Optional[str] = _field(None, "velocity", "acceleration")  # None: the dataset's Table 9 output
    deformation: bool = False  # hcmt's edge deformation features x_ij − u_ij and stretch
    # HCMT's ablations (paper Tables 3, 10-12; --ablation); no-remesh is read as data.remesh=false (NO_REMESH)
    ablation: Optional[str] = _field(None, *ABLATIONS, *ABLATION_ALIASES)


@dataclass(frozen=True)
class TrainConfig:
    """``train:`` (Table 8's schedule and noise; hcmt's speed and formulation options)."""

    steps: Optional[int] = _field(None, required=True, minimum=1)
    lr: Optional[float] = _field(None, required=True, above=0)
    contact_radius: Optional[float] = _field(None, required=True)  # the contact search radius (Table 8's γ)
    batch_size: int = _field(1, minimum=1)
    lr_final: Optional[float] = None  # None: constant ``lr``
    lr_decay_rate: float = 0.1  # with lr_decay_steps
    noise_std: float = _field(0.0, minimum=0)
    noise_gamma: Optional[float] = None  # None: 1.0 for a velocity target, 0.1 for acceleration
    noise_nodes: str = _field("normal", "normal", "predicted")
    pushforward: float = _field(0.0, minimum=0, maximum=1, says="a probability in [0, 1]")
    pushforward_start: int = 0
    # the loss weight of a frame where nothing touches (no contact pair within quantities.CONTACT_TOL: the impactor
    # after it has left, where stress that stays lives); 1: the plain mean over frames. Measured: docs/RESULTS.md,
    # "The stress that stays: measured ablations"
    contact_free_weight: float = _field(1.0, minimum=0)
    normalizer_steps: int = _field(0, minimum=0)
    # the loop's conventions: hcmt's or the authors' code's (hcmt.training.policy); each key below, left null, is
    # the policy's value
    policy: str = _field("hcmt", "hcmt", "official")
    normalizer_warmup: Optional[str] = _field(None, "all", "nodes")
    mesh_edges_twice: Optional[bool] = None
    loss_denominator: Optional[str] = _field(None, "masked", "nodes")
    adam_epsilon: Optional[float] = _field(None, above=0)
    adam_epsilon_hat: Optional[bool] = None
    lr_decay_steps: Optional[int] = _field(None, minimum=1)  # lr·rate^(step/this), no floor; hcmt: lr->lr_final
    log_every: int = _field(100, minimum=1)
    checkpoint_every: int = _field(1000, minimum=1)
    # also keep the checkpoint of every keep_every-th step as step_<N>.pt (0: none), so that a long run's checkpoint
    # can be chosen afterwards on more than best.pt's position RMSE (peak, deflection, ghost)
    keep_every: int = _field(0, minimum=0)
    valid_every: int = _field(0, minimum=0)
    valid_trajectories: int = _field(2, minimum=0)
    contact_pairs: str = _field("all", "all", "official")
    workers: int = _field(0, minimum=0)
    checkpoint_blocks: bool = False
    precision: str = _field("fp32", "fp32", "bf16")
    compile: str = _field("auto", *COMPILE_MODES)
    deterministic: bool = False


@dataclass(frozen=True)
class DataConfig:
    """``data:``."""

    exclude_trajectories: Optional[tuple] = None  # trajectory indices of the train split to leave out
    stress_field: str = _field("stress", "stress", "stress_max")  # stress_max: `generate --peak-stress`
    # hold the training split in memory instead of reading each item's frames from the file: a step of the shipped
    # recipe took 145 against 160 ms of CPU on the `small` preset; memory grows with the split (docs/RESULTS.md)
    in_memory: bool = False
    # the coarse levels' edges of HCMT's hierarchy: Delaunay remeshing of the pooled nodes (the paper), or, false,
    # the kept nodes two hops apart on the finer level (BSMS; the paper's "HCMT without remeshing" ablation, appendix
    # "Additional Ablation Study"); hcmt.graph.hierarchy.build_hierarchy. Old spelling: model.ablation=no-remesh
    remesh: bool = True


SECTIONS = {"model": ModelConfig, "train": TrainConfig, "data": DataConfig}
_KIND = {int: "a whole number", float: "a number", bool: "true or false", str: "a string",
         tuple: "a list of trajectory indices"}
_CAST = {"a whole number": int, "a number": float, "a list of trajectory indices": tuple}


@dataclass(frozen=True)
class Spec:
    """What one config key must be: its kind, allowed values, whether null is allowed and its bounds."""

    kind: str
    allowed: tuple
    nullable: bool
    required: bool
    minimum: float | None
    maximum: float | None
    above: float | None
    says: str | None


def _spec(cls) -> dict[str, Spec]:
    hints = get_type_hints(cls)
    out = {}
    for f in fields(cls):
        t = hints[f.name]
        args = [a for a in get_args(t) if a is not type(None)]
        base = args[0] if args else t
        out[f.name] = Spec(_KIND[get_origin(base) or base], tuple(f.metadata.get("allowed", ())),
                           type(None) in get_args(t),
                           *(f.metadata.get(k) for k in ("required", "minimum", "maximum", "above", "says")))
    return out


#: every key a config may hold: section -> key -> :class:`Spec`
SCHEMA: dict[str, dict[str, Spec]] = {name: _spec(cls) for name, cls in SECTIONS.items()}
TOP = {"dataset": ("a string", DATASET_NAMES)}


@dataclass(frozen=True)
class Config:
    """A complete, checked config: ``dataset`` and one frozen section each (``cfg.train.lr``). Every key holds a
    value of its declared type (a YAML ``1`` for a number is ``1.0``); what a file leaves out is the section's
    default. Made by :func:`load_config` or :meth:`from_dict`; ``run.yaml`` holds :meth:`to_dict`."""

    dataset: Optional[str] = None
    model: ModelConfig = field(default_factory=ModelConfig)
    train: TrainConfig = field(default_factory=TrainConfig)
    data: DataConfig = field(default_factory=DataConfig)

    @classmethod
    def from_dict(cls, cfg: dict, source: str = "config") -> "Config":
        """The one completion of a config mapping (a file's, ``run.yaml``'s, the API's): checked against the
        schema (one line naming ``source``, the key and what was expected), defaults filled, values cast."""
        if isinstance(cfg, Config):
            return cfg
        if not isinstance(cfg, dict):
            raise InputError(f"config {source}: expected a mapping of sections, got {type(cfg).__name__}")
        cfg = _without_derived(cfg)
        check_schema(cfg, source)
        return cls(dataset=cfg.get("dataset"),
                   **{name: cls_(**(cfg.get(name) or {})) for name, cls_ in SECTIONS.items()})

    def __post_init__(self):
        """However the Config was made (:meth:`from_dict`, or by hand from the section classes), every value is
        checked against the schema and cast to its declared type."""
        plain = self.to_dict()
        check_schema(plain, "Config")
        if plain["model"]["ablation"] == NO_REMESH:  # the old spelling of data.remesh=false (NO_REMESH): read once
            plain["model"]["ablation"], plain["data"]["remesh"] = None, False
        for name, cls_ in SECTIONS.items():
            object.__setattr__(self, name, cls_(**{
                k: v if v is None or SCHEMA[name][k].kind not in _CAST else _CAST[SCHEMA[name][k].kind](v)
                for k, v in plain[name].items()}))

    def to_dict(self) -> dict:
        """Plain types (lists, not tuples) for YAML and ``torch.load(weights_only=True)``."""
        out = asdict(self)
        ex = out["data"].get("exclude_trajectories")
        if ex is not None:
            out["data"]["exclude_trajectories"] = list(ex)
        return out

    def with_overrides(self, overrides: list[str] | None) -> "Config":
        """This config with ``section.key=value`` items applied (:func:`apply_overrides`)."""
        return Config.from_dict(apply_overrides(self.to_dict(), overrides)) if overrides else self

    def for_training(self) -> "Config":
        """This config, refused in one line when a key training needs (``Spec.required``, ``dataset``) is unset."""
        if self.dataset is None:
            raise InputError("config: `dataset` (the adapter: impact_plate, deforming_plate, ...) is missing")
        for name, specs in SCHEMA.items():
            for key, spec in specs.items():
                if spec.required and getattr(getattr(self, name), key) is None:
                    raise InputError(f"config: {name}.{key} is missing (see configs/impact_plate.yaml for a "
                                     "complete config)")
        return self


def current_model_args(args: dict) -> dict:
    """A model's constructor arguments (run.yaml's ``model``, a checkpoint's ``model_args``) as hcmt reads them now:
    the old ``no-remesh`` ablation, which never changed the model, dropped (the run's config, read through
    :class:`Config`, holds it as ``data.remesh: false``)."""
    return dict(args, ablation=None) if args.get("ablation") == NO_REMESH else args


def as_config(config, overrides: list[str] | None = None) -> Config:
    """A :class:`Config` from a Config, a config mapping, a built-in config name or a YAML path, with
    ``section.key=value`` overrides."""
    if isinstance(config, Config):
        return config.with_overrides(overrides)
    if isinstance(config, dict):
        return Config.from_dict(apply_overrides(config, overrides))
    if not isinstance(config, (str, os.PathLike)):
        raise InputError(f"expected a Config, a config mapping, a built-in config's name or a YAML path, got "
                         f"{clip(repr(config))}", param="config")
    return load_config(config, overrides)


def check_same_dataset(dataset: str | None, meta: dict, data, source: str, origin: str | None = None) -> None:
    """Refuse ``data`` of another dataset than ``dataset`` (a config's or a trained run's): meta.json's own
    ``dataset`` (``hcmt generate`` writes it; a dataset that names none, converted, is not checked), in one line
    naming ``source`` (``config FILE``, ``run RUN``; ``origin``: what set it, ``its base NAME`` (:func:`set_in`), ``an
    override``), both datasets and the configs of the data's one."""
    theirs = meta.get("dataset") if isinstance(meta, dict) else None
    if dataset is None or theirs is None or theirs == dataset:
        return
    fits = [n for n in builtin_configs() if n.startswith(str(theirs))]
    hint = f" (built-in: {', '.join(fits[:3])})" if source.startswith("config") and fits else ""
    where = f" (set by {origin})" if origin else ""
    raise InputError(f"{source}: dataset {dataset}{where}, but {Path(data) / 'meta.json'} holds dataset "
                     f"{clip(str(theirs))}; expected data of dataset {dataset}"
                     + (f", or a config of dataset {theirs}{hint}" if source.startswith("config") else ""))


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
    return isinstance(value, (list, tuple)) and all(isinstance(v, int) and not isinstance(v, bool) for v in value)


def _bounds(spec: Spec, value) -> str | None:
    """What ``value`` breaks of ``spec``'s bounds, as ``a whole number >= 1``, or None."""
    for bound, op, holds in (("minimum", ">=", lambda b: value >= b), ("above", ">", lambda b: value > b),
                             ("maximum", "<=", lambda b: value <= b)):
        b = getattr(spec, bound)
        if b is not None and not holds(b):
            return spec.says or f"{spec.kind} {op} {b:g}"
    return None


def _unknown(key: str, known: list[str], source: str):
    close = difflib.get_close_matches(key, known, n=1, cutoff=0.6)
    hint = f"; did you mean {close[0]}?" if close else f"; known: {clip(', '.join(known), 120)}"
    return InputError(f"{_head(source)}{clip(key)}: unknown key{hint}")


def _head(source: str | None) -> str:
    """How a schema message starts: ``config FILE: `` (None: the caller names the source itself)."""
    return f"config {source}: " if source is not None else ""


def _without_derived(cfg: dict) -> dict:
    """``cfg`` without the ``model.L_H`` that run.yaml files written before it was derived hold (null or
    2·levels + 1); any other value stays, for :func:`check_schema` to refuse."""
    model = cfg.get("model")
    if not isinstance(model, dict) or "L_H" not in model:
        return cfg
    levels = model.get("levels", ModelConfig.levels)
    if model["L_H"] is None or (isinstance(levels, int) and model["L_H"] == 2 * levels + 1):
        return dict(cfg, model={k: v for k, v in model.items() if k != "L_H"})
    return cfg


def check_schema(cfg: dict, source: str | None = "config") -> None:
    """Refuse unknown keys (with the closest known one), values of the wrong type, values outside a fixed set and
    values outside a key's bounds."""
    sections = list(SCHEMA)
    for top, value in cfg.items():
        if top in TOP:
            kind, allowed = TOP[top]
            if value is None:  # not set yet (Config.for_training refuses it)
                continue
            if not _ok(kind, value) or (allowed and value not in allowed):
                raise InputError(f"{_head(source)}{top}: got {clip(repr(value))}; expected one of {', '.join(allowed)}")
            continue
        if top == "base":
            continue
        if top not in SCHEMA:
            raise _unknown(top, sections + list(TOP), source)
        if not isinstance(value, dict):
            raise InputError(f"{_head(source)}{top}: expected a section of keys, got {clip(repr(value))}")
        for key, v in value.items():
            if top == "model" and key == "L_H":
                raise InputError(f"{_head(source)}model.L_H: derived, L_H = 2·model.levels + 1 (paper §3.2), not a "
                                 "setting; set model.levels")
            if key not in SCHEMA[top]:
                raise _unknown(f"{top}.{key}", [f"{top}.{k}" for k in SCHEMA[top]]
                               + [f"{s}.{k}" for s in SCHEMA for k in SCHEMA[s] if s != top], source)
            spec = SCHEMA[top][key]
            if v is None and spec.nullable:
                continue
            if not _ok(spec.kind, v):
                raise InputError(f"{_head(source)}{top}.{key}: got {clip(repr(v))}; expected {spec.kind}")
            if spec.allowed and v not in spec.allowed:
                raise InputError(f"{_head(source)}{top}.{key}: unknown value {clip(repr(v))}; expected one of "
                                 f"{', '.join(spec.allowed)}")
            broken = _bounds(spec, v) if isinstance(v, (int, float)) else None
            if broken:
                raise InputError(f"{_head(source)}{top}.{key} must be {broken}, got {clip(repr(v))}")


def plural(n: int, word: str, many: str | None = None) -> str:
    """``1 trajectory``, ``2 trajectories``: a count with its noun (``many``: the plural when not ``word + s``)."""
    return f"{n} {word if n == 1 else (many or word + 's')}"


def machine_cores() -> int:
    """The CPU cores this process may run on: the bound of ``--threads`` and ``--workers``."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


#: the torch thread counts hcmt set in this process: ``chosen``, a command's ``--threads`` (:func:`set_threads`);
#: ``auto``, the Python API's default (:func:`default_threads`)
_THREADS: dict[str, int] = {}


def auto_threads() -> int:
    """The CPU cores not already busy: cores minus the 1-minute load average (at least 1). On a machine whose other
    cores run another job this is 1 thread, never the oversubscribed default that made a design take 10x longer
    (docs/RESULTS.md, "Threads")."""
    cores = machine_cores()
    try:
        busy = os.getloadavg()[0]
    except OSError:  # no load average on this platform
        busy = 0.0
    return max(1, min(cores, int(cores - busy + 0.5)))


def set_threads(threads: int | str) -> int:
    """Apply ``--threads`` (1 to the machine's cores, or ``auto``: refused above by its parser) to torch's intra-op
    pool; returns the number set. The API keeps it (:func:`default_threads`)."""
    import torch  # heavy: loaded only by what computes (this module stays light: `hcmt --help` stays fast)

    n = auto_threads() if threads == "auto" else int(threads)
    torch.set_num_threads(n)
    _THREADS["chosen"] = n
    return n


def default_threads() -> int:
    """The Python API's torch threads (``hcmt.train``, ``hcmt.evaluate``, ``hcmt.predict_designs``): the command's
    default, :func:`auto_threads`, applied to torch unless the caller chose a count: ``OMP_NUM_THREADS`` or
    ``MKL_NUM_THREADS`` set, a command's ``--threads`` (:func:`set_threads`), or ``torch.set_num_threads`` called
    with a count other than torch's own start value (:func:`_torch_start_counts`). Chosen once per process, as a
    command chooses at its start (two calls of one script compute alike). Returns the count in use."""
    import torch  # loaded already by the API that calls this

    now = torch.get_num_threads()
    if now in (_THREADS.get("chosen"), _THREADS.get("auto")) or any(
            os.environ.get(v) for v in ("OMP_NUM_THREADS", "MKL_NUM_THREADS")):
        return now  # a command's --threads, this default chosen before, or the environment's
    if now not in _torch_start_counts():
        return now  # the caller's torch.set_num_threads
    n = auto_threads()
    if n != now:
        torch.set_num_threads(n)
    _THREADS["auto"] = n
    return n


def _torch_start_counts() -> set[int]:
    """The thread counts torch may start with here: OpenMP's, the CPUs this process may run on; MKL's and torch's
    own pool's, their physical cores (read on Linux; elsewhere the CPUs only: a count not recognized is kept)."""
    cpus = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else range(os.cpu_count() or 1)
    cores = set()
    for cpu in cpus:
        top = Path(f"/sys/devices/system/cpu/cpu{cpu}/topology")
        try:
            cores.add(((top / "physical_package_id").read_text().strip(), (top / "core_id").read_text().strip()))
        except OSError:
            cores.add(("", str(cpu)))  # no topology: counted as a core of its own
    return {len(cpus), len(cores), os.cpu_count() or 1}


def available_pretrained() -> dict[str, Path]:
    """Shipped models by name (``impact_plate_small``, ...)."""
    return {p.stem: p for p in sorted(PRETRAINED_DIR.glob("*.pt"))}
