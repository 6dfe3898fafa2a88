"""Hand-made design-check records for tests that need a few fields only: :func:`fake_summary` (a
:class:`hcmt.design.summary.Summary` whose trajectory quantities are zeros), :func:`fake_metrics` and
:func:`fake_verify` likewise; and :func:`type_errors`, each field of a result whose value is not its declared type."""

from __future__ import annotations

import dataclasses
import types
import typing
from dataclasses import MISSING, fields

from hcmt.design.summary import Summary, VerifyRow
from hcmt.inference.physics import ImpactMetrics

_ZERO = {
    "float": 0.0,
    "int": 0,
    "bool": False,
    "list[float]": [0.0, 0.0],
    "list[float] | None": None,
    "list[int] | None": None,
}


def _zeros(cls, given: dict):
    """``cls`` holding ``given``; every other field without a default a zero of its declared type."""
    base = {
        f.name: _ZERO[f.type]
        for f in fields(cls)
        if f.default is MISSING and f.default_factory is MISSING and f.name not in given
    }
    return cls(**base, **given)


def fake_summary(**given) -> Summary:
    """A summary holding ``given``, every other trajectory quantity zero (the stress history: two zeros)."""
    return _zeros(Summary, given)


def fake_metrics(**given) -> ImpactMetrics:
    """Impact metrics holding ``given``, every other field zero (False for the rebound flags)."""
    return _zeros(ImpactMetrics, given)


def fake_verify(**given) -> VerifyRow:
    """A verify row holding ``given``, every other field zero."""
    return _zeros(VerifyRow, given)


def type_errors(obj, where: str = "") -> list[str]:
    """Every field of a dataclass ``obj`` (and of the dataclasses it holds) whose value does not match its declared
    type: ``float`` is a Python float (not an int, not a numpy scalar), ``int`` an int and not a bool, containers
    checked element by element, ``X | None`` holding a value as ``X`` (a nested record's own fields named)."""
    hints = typing.get_type_hints(type(obj))
    out = []
    for f in dataclasses.fields(obj):
        out += _mismatch(getattr(obj, f.name), hints[f.name], f"{where}{type(obj).__name__}.{f.name}")
    return out


def _mismatch(value, hint, where: str) -> list[str]:
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        others = [a for a in args if a is not type(None)]
        if value is not None and len(others) == 1:  # X | None holding a value: X's own errors, nested ones named
            return _mismatch(value, others[0], where)
        tried = [_mismatch(value, a, where) for a in args]
        return [] if any(not t for t in tried) else [f"{where}: {value!r:.60} is not {hint}"]
    if hint is type(None):
        return [] if value is None else [f"{where}: {value!r:.60} is not None"]
    if origin is list:
        if type(value) is not list:
            return [f"{where}: {type(value).__name__} is not a list"]
        return [e for v in value for e in _mismatch(v, args[0], where + "[]")]
    if origin is tuple:
        if type(value) is not tuple or len(value) != len(args):
            return [f"{where}: {value!r:.60} is not a tuple of {len(args)}"]
        return [e for v, a in zip(value, args) for e in _mismatch(v, a, where + "[]")]
    if origin is dict:
        if type(value) is not dict:
            return [f"{where}: {type(value).__name__} is not a dict"]
        return [e for k, v in value.items() for e in _mismatch(k, args[0], where) + _mismatch(v, args[1], where)]
    if dataclasses.is_dataclass(hint):
        return type_errors(value, where + ".") if isinstance(value, hint) else [f"{where}: not a {hint.__name__}"]
    if hint in (int, float, bool, str, dict, list):
        return [] if type(value) is hint else [f"{where}: {type(value).__name__} {value!r:.60} is not {hint.__name__}"]
    if isinstance(hint, type):  # e.g. np.ndarray
        return [] if isinstance(value, hint) else [f"{where}: {type(value).__name__} is not {hint.__name__}"]
    raise AssertionError(f"{where}: no check for {hint}")
