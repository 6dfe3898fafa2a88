"""Numbers as the design schema reads them (:mod:`hcmt.sim.params`, :mod:`hcmt.sim.families`): whether a value is
a real or whole number, how a refusal names a type, a finite number from text. Light: numpy only."""

from __future__ import annotations

import numbers

import numpy as np

from hcmt.errors import InputError, clip


def is_number(v, whole: bool = False) -> bool:
    """Whether ``v`` is a real number (a numpy one too; a ``bool`` is not), a whole one for ``whole``."""
    if isinstance(v, (bool, np.bool_)):
        return False
    return isinstance(v, numbers.Integral) if whole else isinstance(v, numbers.Real)


def a_type(v) -> str:
    """``a str``, ``an int``: how a refusal names the type it got."""
    name = type(v).__name__
    return f"{'an' if name[:1] in 'aeiou' else 'a'} {name}"


def parse_number(raw: str, what: str, param: str | None = None) -> float:
    """A finite number from text, or one line naming ``what`` (and ``param``, the parameter it came in)."""
    try:
        v = float(raw)
    except ValueError:
        raise InputError(f"{what} must be a number, got {clip(raw.strip())!r}", param=param) from None
    if not np.isfinite(v):
        raise InputError(f"{what} must be a finite number, got {clip(raw.strip())!r}", param=param)
    return v
