"""YAML configs: built-in ones by name (``src/hcmt/configs/NAME.yaml``, also reachable as ``configs/``), or a
file path. A config may name a ``base`` config whose values it overrides. Any key can be overridden from the
command line as ``section.key=value`` (the value is parsed as YAML: ``train.lr=3e-4``, ``model.levels=4``)."""
from __future__ import annotations

import copy
from pathlib import Path

import yaml

from hcmt.models.base import COMPILE_MODES

CONFIG_DIR = Path(__file__).resolve().parent.parent / "configs"


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
    """A config by name or path, its ``base`` chain merged, then ``section.key=value`` overrides; every key and
    value checked against :data:`SCHEMA` (one line naming the file or ``--set``, the key, what was expected)."""
    cfg = _read(name_or_path)
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
    for section in ("model", "train", "data"):
        cfg.setdefault(section, {})
    return cfg


def _nest(keys: list[str], value):
    return {keys[0]: _nest(keys[1:], value)} if len(keys) > 1 else {keys[0]: value}


_INT, _FLOAT, _BOOL, _STR = "a whole number", "a number", "true or false", "a string"
#: every key a config may hold: (what it must be, allowed values or None)
SCHEMA: dict[str, dict[str, tuple]] = {
    "model": {"hidden": (_INT, None), "heads": (_INT, None), "L_C": (_INT, None), "levels": (_INT, None),
              "L_H": (_INT, None), "clip": (_FLOAT, None), "blocks": (_INT, None), "ffn_bias": (_BOOL, None),
              "attention": (_STR, ("paper", "official")), "target": (_STR, ("velocity", "acceleration")),
              "deformation": (_BOOL, None)},
    "train": {"steps": (_INT, None), "batch_size": (_INT, None), "lr": (_FLOAT, None), "lr_final": (_FLOAT, None),
              "lr_decay_steps": (_INT, None), "lr_decay_rate": (_FLOAT, None), "noise_std": (_FLOAT, None),
              "noise_gamma": (_FLOAT, None), "contact_radius": (_FLOAT, None), "normalizer_steps": (_INT, None),
              "log_every": (_INT, None), "checkpoint_every": (_INT, None), "valid_every": (_INT, None),
              "valid_trajectories": (_INT, None), "contact_pairs": (_STR, ("all", "official")),
              "workers": (_INT, None), "checkpoint_blocks": (_BOOL, None), "precision": (_STR, ("fp32", "bf16")),
              "compile": (_STR, COMPILE_MODES),
              "deterministic": (_BOOL, None), "noise_nodes": (_STR, ("normal", "predicted")),
              "pushforward": (_FLOAT, None), "pushforward_start": (_INT, None),
              "normalizer_warmup": (_STR, ("all", "nodes")), "mesh_edges_twice": (_BOOL, None),
              "loss_denominator": (_STR, ("masked", "nodes")), "adam_epsilon": (_FLOAT, None),
              "adam_epsilon_hat": (_BOOL, None)},
    "data": {"exclude_trajectories": ("a list of trajectory indices", None)},
}
TOP = {"dataset": (_STR, ("impact_plate", "deforming_plate", "sphere_simple", "deformable_plate"))}


def _ok(kind: str, value) -> bool:
    if kind == _INT:
        return (isinstance(value, int) and not isinstance(value, bool)) or (
            isinstance(value, float) and value.is_integer())
    if kind == _FLOAT:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if kind == _BOOL:
        return isinstance(value, bool)
    if kind == _STR:
        return isinstance(value, str)
    return isinstance(value, list) and all(isinstance(v, int) and not isinstance(v, bool) for v in value)


def _unknown(key: str, known: list[str], source: str):
    import difflib

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
            kind, allowed = SCHEMA[top][key]
            if v is None and key in ("L_H", "lr_decay_steps", "noise_gamma", "target"):
                continue
            if not _ok(kind, v):
                raise ValueError(f"config {source}: {top}.{key}: got {v!r}; expected {kind}")
            if allowed and v not in allowed:
                raise ValueError(f"config {source}: {top}.{key}: unknown value {v!r}; expected one of "
                                 f"{', '.join(allowed)}")
            if key == "pushforward" and not 0 <= v <= 1:
                raise ValueError(f"config {source}: train.pushforward: got {v!r}; expected a probability in [0, 1]")
