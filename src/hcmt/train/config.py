"""YAML configs: built-in ones by name (``src/hcmt/configs/NAME.yaml``, also reachable as ``configs/``), or a
file path. A config may name a ``base`` config whose values it overrides. Any key can be overridden from the
command line as ``section.key=value`` (the value is parsed as YAML: ``train.lr=3e-4``, ``model.levels=4``)."""
from __future__ import annotations

import copy
from pathlib import Path

import yaml

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
    data = yaml.safe_load(path.read_text()) or {}
    if not isinstance(data, dict):
        raise ValueError(f"config {path}: expected a mapping at top level")
    base = data.pop("base", None)
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
    cfg = _read(name_or_path)
    for item in overrides or []:
        key, sep, raw = item.partition("=")
        if not sep or not key:
            raise ValueError(f"override {item!r}: expected section.key=value")
        node = cfg
        *parents, leaf = key.split(".")
        for p in parents:
            node = node.setdefault(p, {})
            if not isinstance(node, dict):
                raise ValueError(f"override {item!r}: {p} is not a section")
        node[leaf] = parse_value(raw)
    for section in ("model", "train", "data"):
        cfg.setdefault(section, {})
    check_choices(cfg, name_or_path)
    return cfg


def check_choices(cfg: dict, source: str = "config") -> None:
    """Keys with a fixed set of values are checked before any data is read: one line naming key, value, choices."""
    from hcmt.models.attention import MODES
    from hcmt.train.adapters import CONTACT_PAIRS

    for section, key, allowed in (("model", "attention", MODES), ("train", "contact_pairs", tuple(CONTACT_PAIRS))):
        value = cfg.get(section, {}).get(key)
        if value is not None and value not in allowed:
            raise ValueError(f"config {source}: {section}.{key}: unknown value {value!r}; expected one of "
                             f"{', '.join(allowed)}")
