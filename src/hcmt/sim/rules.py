"""Each design value's validity rule, declared once as a :class:`Rule` (``thickness`` > 0, a layer's Poisson ratio
in [0, MAX_LAYER_POISSON], the gap smaller than the contact radius): the first scene's in
:func:`hcmt.sim.params.value_rules`, each panel family's beside its fields (:meth:`hcmt.sim.families.Feature.rules`).
:meth:`hcmt.sim.params.Design.validate` refuses a design by them (:func:`refuse`) before its whole-design checks,
and the design check's first checks of a ``--designs`` file, ``--design`` and ``--vary``
(:func:`hcmt.design.basics.value_problem`) read the same rules before torch loads. Light: numpy only."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from typing import Any, NamedTuple

import numpy as np

from hcmt.errors import InputError, clip
from hcmt.sim.units import DESIGN_UNITS


class Rule(NamedTuple):
    """``param`` must be ``expected`` (the words after "must be"), which ``ok`` tests of a finite value (a number,
    or a numpy array of them, elementwise). Refused as ``must be EXPECTED, got VALUE`` naming the parameter
    (``param=``: the command prints its flag), or in ``words`` where given: the refusal's own words, naming the
    parameter itself and no flag (``{param}``, ``{value}``, ``{unit}`` and ``{expected}`` filled in)."""

    param: str
    ok: Callable[[Any], Any]
    expected: str
    words: str = ""

    def holds(self, value) -> bool:
        """Whether ``value`` is finite (every element of an array) and passes ``ok``."""
        if isinstance(value, (int, float)):  # a design's number (numpy's float64 too): without numpy, faster
            return math.isfinite(value) and bool(self.ok(value))
        a = np.asarray(value, float)
        return bool(np.all(np.isfinite(a)) and np.all(self.ok(a)))

    def refusal(self, value) -> InputError:
        """The one-line refusal of ``value``."""
        if self.words:
            unit = DESIGN_UNITS.get(self.param, "")
            return InputError(self.words.format(param=self.param, value=clip(value), unit=unit, expected=self.expected))
        return InputError(f"must be {self.expected}, got {clip(value)}", param=self.param)


def positive(v):
    return v > 0


def size_rules(names: Iterable[str]) -> list[Rule]:
    """Each of ``names`` a size > 0 (``must be > 0 (mm)``)."""
    return [Rule(k, positive, f"> 0 ({DESIGN_UNITS[k]})") for k in names]


def switch_rules(names: Iterable[str]) -> list[Rule]:
    """Each of ``names`` a size where 0 means none (a panel family's switch): >= 0."""
    return [Rule(k, lambda v: v >= 0, f">= 0 {DESIGN_UNITS[k]} (0: none)") for k in names]


def material_rules(name: str, keys: tuple[str, ...] = ("density", "modulus", "poisson")) -> list[Rule]:
    """The rules of the material ``name``'s ``keys`` (``plate``: ``plate_density`` > 0, ``plate_modulus`` > 0,
    ``plate_poisson`` in (-1, 0.5)); a material that is no design parameter (the solver's elements) in the plate's
    units."""
    rules = [
        Rule(f"{name}_density", positive, f"> 0 {_unit(name, 'density')}"),
        Rule(f"{name}_modulus", positive, f"> 0 {_unit(name, 'modulus')} (Young's modulus)"),
        Rule(f"{name}_poisson", lambda a: (a > -1) & (a < 0.5), "in (-1, 0.5) (Poisson ratio)"),
    ]
    return [rule for rule in rules if rule.param.rpartition("_")[2] in keys]


def _unit(name: str, key: str) -> str:
    return DESIGN_UNITS.get(f"{name}_{key}", DESIGN_UNITS[f"plate_{key}"])


def refuse(rules: Iterable[Rule], values: Mapping[str, Any]) -> None:
    """Raise the refusal (:class:`~hcmt.errors.InputError`) of the first of ``rules`` that its value in ``values``
    breaks."""
    for rule in rules:
        if not rule.holds(values[rule.param]):
            raise rule.refusal(values[rule.param])


def check_material(name: str, density, modulus, poisson) -> None:
    """Refuse impossible materials (numbers, or arrays of them) with a message naming the parameter
    (``plate_density``: param=, so that the command names its flag) and the expected range."""
    refuse(material_rules(name), {f"{name}_density": density, f"{name}_modulus": modulus, f"{name}_poisson": poisson})
