"""Config files read as YAML 1.1 with YAML 1.2's floats (``lr: 1e-3`` is a number) and without duplicate keys
(refused, both lines named); a command-line value read as a number or YAML (:func:`parse_value`)."""

from __future__ import annotations

import copy
import re

import yaml

from hcmt.errors import InputError, clip


class _Loader(yaml.SafeLoader):
    """PyYAML's safe loader (YAML 1.1) with YAML 1.2's floats, ``1e-3``, ``1E-3`` and ``-.5`` (1.1 reads the first
    two as strings), and duplicate keys refused (1.1 keeps the last silently): :func:`load_yaml`."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+|\.[0-9][0-9_]*(?:[eE][-+]?[0-9]+)?)$"),
    list("-+0123456789."),
)


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
                raise InputError(
                    f"{where}: key {clip(dotted)} given twice, lines {lines[key.tag, name]} and "
                    f"{key.start_mark.line + 1}; keep one"
                )
            lines[key.tag, name] = key.start_mark.line + 1
        _no_twice(value, (*path, str(name)), where, seen)


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
        raise InputError(
            f"the value {clip(raw)!r} is not a YAML value ({getattr(exc, 'problem', None) or exc})"
        ) from None
