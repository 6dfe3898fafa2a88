"""Configs by name or path: built-in ones by name (``src/hcmt/configs/NAME.yaml``, also reachable as ``configs/``),
or a file path. A config may name a ``base`` config whose values it overrides: a built-in config's name, or a path
read from the folder of the file naming it; a chain that returns to a file is refused. Also the shipped models'
folder and the check that a config's data is of its dataset."""

from __future__ import annotations

import os
from pathlib import Path

import yaml

from hcmt.config.schema import Config, apply_overrides, check_schema
from hcmt.config.yamlread import load_yaml, merge
from hcmt.errors import InputError, clip

CONFIG_DIR = Path(__file__).resolve().parent.parent / "configs"
#: the models shipped inside the package (``pretrained:NAME``)
PRETRAINED_DIR = Path(__file__).resolve().parent.parent / "pretrained"


def builtin_configs() -> list[str]:
    return sorted(p.stem for p in CONFIG_DIR.glob("*.yaml"))


def available_pretrained() -> dict[str, Path]:
    """Shipped models by name (``impact_plate_small``, ...)."""
    return {p.stem: p for p in sorted(PRETRAINED_DIR.glob("*.pt"))}


def _locate(name_or_path, within: Path | None) -> Path:
    """The file a config name or path means: a path (a ``base``'s from the folder of the config naming it,
    ``within``), else a built-in config's name."""
    if not isinstance(name_or_path, (str, os.PathLike)) or not str(name_or_path).strip():
        if within is not None:
            raise InputError(
                f"config {within}: base: got {clip(repr(name_or_path))}; expected a built-in config's "
                "name or a YAML path (from this file's folder)"
            )
        raise InputError(
            f"expected a built-in config's name or a YAML path, got {clip(repr(name_or_path))}", param="name_or_path"
        )
    path = Path(name_or_path)
    if within is not None and not path.is_absolute():
        path = within.parent / path
    if path.is_file():
        return path
    if str(name_or_path) in builtin_configs():
        return CONFIG_DIR / f"{name_or_path}.yaml"
    where = f" (the base of {within}, looked for in {within.parent})" if within else ""
    raise InputError(
        f"{clip(str(name_or_path))!r}{where}: neither a file nor a built-in config ({', '.join(builtin_configs())})",
        param=None if within else "name_or_path",
    )


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
        raise InputError(f"config {path}: nested too deeply for a config (its sections hold keys, one level)") from None
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
    return (
        f"config {loop[0]}: its base chain is a loop, {names}; each file names the next as its `base`: remove "
        "or change one of them"
    )


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


def load_config(name_or_path: str | os.PathLike, overrides: list[str] | str | None = None) -> "Config":
    """A config by name or path, its ``base`` chain merged, then ``section.key=value`` overrides
    (:func:`apply_overrides`), as a complete :class:`Config`; every key and value checked against the schema (one
    line naming the file or the override, the key, what was expected; a bad override is an :class:`InputError`
    of the parameter ``overrides``, which ``hcmt train`` words as its ``--set``). A ``base`` path is read from the
    folder of the file naming it; one string of overrides is one item (``"train.steps=20"``)."""
    return Config.from_dict(apply_overrides(_read(name_or_path), overrides), str(name_or_path))


def as_config(config, overrides: list[str] | None = None) -> Config:
    """A :class:`Config` from a Config, a config mapping, a built-in config name or a YAML path, with
    ``section.key=value`` overrides."""
    if isinstance(config, Config):
        return config.with_overrides(overrides)
    if isinstance(config, dict):
        return Config.from_dict(apply_overrides(config, overrides))
    if not isinstance(config, (str, os.PathLike)):
        raise InputError(
            f"expected a Config, a config mapping, a built-in config's name or a YAML path, got {clip(repr(config))}",
            param="config",
        )
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
    raise InputError(
        f"{source}: dataset {dataset}{where}, but {Path(data) / 'meta.json'} holds dataset "
        f"{clip(str(theirs))}; expected data of dataset {dataset}"
        + (f", or a config of dataset {theirs}{hint}" if source.startswith("config") else "")
    )
