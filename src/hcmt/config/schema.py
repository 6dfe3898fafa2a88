"""The config's checks and its complete form: every key's :class:`Spec` read from the section classes
(:mod:`hcmt.config.sections`), :func:`check_schema` (unknown keys with the closest known one, types, allowed values,
bounds, each refused in one line), ``section.key=value`` overrides (:func:`apply_overrides`) and :class:`Config`,
the frozen, complete config (``L_H = 2λ + 1`` derived, never set)."""

from __future__ import annotations

import copy
import difflib
from dataclasses import asdict, dataclass, field, fields
from typing import Optional, get_args, get_origin, get_type_hints

from hcmt.config.choices import DATASET_NAMES, NO_REMESH
from hcmt.config.sections import SECTIONS, DataConfig, ModelConfig, TrainConfig
from hcmt.config.yamlread import parse_value
from hcmt.errors import InputError, clip

_KIND = {
    int: "a whole number",
    float: "a number",
    bool: "true or false",
    str: "a string",
    tuple: "a list of trajectory indices",
}
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
        m = f.metadata  # sections._field's; a field declared without it has none: required False, no bounds
        out[f.name] = Spec(
            _KIND[get_origin(base) or base],
            tuple(m.get("allowed", ())),
            type(None) in get_args(t),
            bool(m.get("required", False)),
            m.get("minimum"),
            m.get("maximum"),
            m.get("above"),
            m.get("says"),
        )
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
        return cls(
            dataset=cfg.get("dataset"), **{name: cls_(**(cfg.get(name) or {})) for name, cls_ in SECTIONS.items()}
        )

    def __post_init__(self):
        """However the Config was made (:meth:`from_dict`, or by hand from the section classes), every value is
        checked against the schema and cast to its declared type."""
        plain = self.to_dict()
        check_schema(plain, "Config")
        if plain["model"]["ablation"] == NO_REMESH:  # the old spelling of data.remesh=false (NO_REMESH): read once
            plain["model"]["ablation"], plain["data"]["remesh"] = None, False
        for name, cls_ in SECTIONS.items():
            object.__setattr__(
                self,
                name,
                cls_(
                    **{
                        k: v if v is None or SCHEMA[name][k].kind not in _CAST else _CAST[SCHEMA[name][k].kind](v)
                        for k, v in plain[name].items()
                    }
                ),
            )

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
                    raise InputError(
                        f"config: {name}.{key} is missing (see configs/impact_plate.yaml for a complete config)"
                    )
        return self


def current_model_args(args: dict) -> dict:
    """A model's constructor arguments (run.yaml's ``model``, a checkpoint's ``model_args``) as hcmt reads them now:
    the old ``no-remesh`` ablation, which never changed the model, dropped (the run's config, read through
    :class:`Config`, holds it as ``data.remesh: false``)."""
    return dict(args, ablation=None) if args.get("ablation") == NO_REMESH else args


def apply_overrides(cfg: dict, overrides: list[str] | str | None) -> dict:
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
    raise InputError(
        f"expected a list of section.key=value strings, got {type(overrides).__name__} {clip(repr(overrides))}",
        param="overrides",
    )


def _nest(keys: list[str], value):
    return {keys[0]: _nest(keys[1:], value)} if len(keys) > 1 else {keys[0]: value}


def _ok(kind: str, value) -> bool:
    if kind == "a whole number":
        return (isinstance(value, int) and not isinstance(value, bool)) or (
            isinstance(value, float) and value.is_integer()
        )
    if kind == "a number":
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if kind == "true or false":
        return isinstance(value, bool)
    if kind == "a string":
        return isinstance(value, str)
    return isinstance(value, (list, tuple)) and all(isinstance(v, int) and not isinstance(v, bool) for v in value)


def _bounds(spec: Spec, value) -> str | None:
    """What ``value`` breaks of ``spec``'s bounds, as ``a whole number >= 1``, or None."""
    for bound, op, holds in (
        ("minimum", ">=", lambda b: value >= b),
        ("above", ">", lambda b: value > b),
        ("maximum", "<=", lambda b: value <= b),
    ):
        b = getattr(spec, bound)
        if b is not None and not holds(b):
            return spec.says or f"{spec.kind} {op} {b:g}"
    return None


def _unknown(key: str, known: list[str], source: str | None) -> InputError:
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
                raise InputError(
                    f"{_head(source)}model.L_H: derived, L_H = 2·model.levels + 1 (paper §3.2), not a "
                    "setting; set model.levels"
                )
            if key not in SCHEMA[top]:
                raise _unknown(
                    f"{top}.{key}",
                    [f"{top}.{k}" for k in SCHEMA[top]] + [f"{s}.{k}" for s in SCHEMA for k in SCHEMA[s] if s != top],
                    source,
                )
            spec = SCHEMA[top][key]
            if v is None and spec.nullable:
                continue
            if not _ok(spec.kind, v):
                raise InputError(f"{_head(source)}{top}.{key}: got {clip(repr(v))}; expected {spec.kind}")
            if spec.allowed and v not in spec.allowed:
                raise InputError(
                    f"{_head(source)}{top}.{key}: unknown value {clip(repr(v))}; expected one of "
                    f"{', '.join(spec.allowed)}"
                )
            broken = _bounds(spec, v) if isinstance(v, (int, float)) else None
            if broken:
                raise InputError(f"{_head(source)}{top}.{key} must be {broken}, got {clip(repr(v))}")
