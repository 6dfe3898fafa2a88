"""The Impact Plate's sampling: each preset's ranges (:data:`RANGES`), the generalization variants
(:data:`VARIANTS`), the edge draws (:data:`EDGES`), a family's ranges (the preset's, then the family's, ``--range``'s
and a variant's, each replacing the one before: :func:`family_ranges`), the designs drawn from them
(:func:`sample_design`: each parameter uniform in its range, drawn in sorted order) and their middle
(:func:`preset_design`, :func:`middle_design`).

It stands apart from the design schema (:mod:`hcmt.sim.params`: what a design is, its checks and parsing) because
it is the one place that decides which designs a dataset holds: a change here changes every dataset drawn after it.
Light (numpy only): the command's parsers read :data:`RANGES` and :func:`describe_family` before torch loads."""

from __future__ import annotations

import numpy as np

from hcmt.errors import InputError, clip
from hcmt.sim.families import FAMILIES, RELATIVE
from hcmt.sim.params import DESIGN_KEYS, Design
from hcmt.sim.units import DESIGN_UNITS

#: Sampling ranges (uniform) per preset; parameters not listed keep their :class:`Design` default.
RANGES: dict[str, dict[str, tuple[float, float]]] = {
    "paper": dict(
        thickness=(0.5, 1.0),
        drop_height=(500.0, 1000.0),
        plate_density=(2.2e-3, 2.8e-3),
        plate_modulus=(50e3, 90e3),
        plate_poisson=(0.20, 0.25),
        ball_radius=(3.0, 4.0),
        ball_density=(7.75e-3, 8.0e-3),
        ball_modulus=(190e3, 210e3),
        mesh_size=(0.12, 0.135),
        plate_half_length=(15.0, 15.0),
    ),
    "small": dict(
        thickness=(0.5, 1.0),
        drop_height=(500.0, 1000.0),
        plate_density=(2.2e-3, 2.8e-3),
        plate_modulus=(50e3, 90e3),
        plate_poisson=(0.20, 0.25),
        ball_radius=(3.5, 4.25),
        ball_density=(7.75e-3, 8.0e-3),
        ball_modulus=(190e3, 210e3),
        mesh_size=(0.29, 0.32),
        plate_half_length=(12.0, 12.0),
    ),
}

#: Generalization splits (paper appendix): ranges replacing the training ones.
VARIANTS: dict[str, dict[str, tuple[float, float]]] = {
    "test_thicker": dict(thickness=(1.0, 1.2)),
    "test_higher": dict(drop_height=(1000.0, 1200.0)),
    "test_thicker_higher": dict(thickness=(1.0, 1.2), drop_height=(1000.0, 1200.0)),
}


#: ``edge_fraction``: the share of designs drawn at the edges of the ranges where learned models fail first,
#: half with a thin plate (the lowest fifth of the thickness range), half with a high drop (the top fifth)
EDGES = {"thickness": (0.0, 0.2), "drop_height": (0.8, 1.0)}


def family_ranges(
    preset: str = "small",
    family: str = "mono",
    variant: str | None = None,
    override: dict[str, tuple[float, float]] | None = None,
) -> dict:
    """The sampling ranges of a family: the preset's, the family's replacing or adding to them, ``override``'s
    (``generate --range``: a sampled parameter's range widened or narrowed), a generalization variant's last
    (ranges of :data:`RELATIVE` parameters stay fractions)."""
    if preset not in RANGES:
        raise InputError(f"unknown preset {preset!r}; expected one of {sorted(RANGES)}")
    if family not in FAMILIES:
        raise InputError(f"unknown family {family!r}; expected one of {', '.join(FAMILIES)}")
    if variant is not None and variant not in VARIANTS:
        raise InputError(f"unknown variant {variant!r}; expected one of {sorted(VARIANTS)}")
    ranges = {**RANGES[preset], **FAMILIES[family]}
    for name, span in (override or {}).items():
        if name not in ranges:
            raise InputError(
                f"{name} is not a sampled parameter of the {preset} preset's {family} family; those are "
                f"{', '.join(sorted(ranges))}",
                param="range",
            )
        ranges[name] = (float(span[0]), float(span[1]))
    return {**ranges, **(VARIANTS[variant] if variant else {})}


def checked_ranges(
    preset: str, families: tuple[str, ...], ranges: dict[str, tuple[float, float]] | None
) -> dict[str, tuple[float, float]]:
    """``generate_dataset``'s ``ranges`` checked: sampled parameters of every family, finite, low <= high, and
    the designs at every corner valid (each refusal one line naming ``range``)."""
    out: dict[str, tuple[float, float]] = {}
    for name, span in (ranges or {}).items():
        try:
            lo, hi = (float(v) for v in span)
        except (TypeError, ValueError):
            raise InputError(f"{name}: expected (low, high), got {clip(span)!r}", param="range") from None
        if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
            raise InputError(f"{name}={lo:g}:{hi:g}: expected finite bounds with low <= high", param="range")
        out[str(name)] = (lo, hi)
    for family in families:
        full = family_ranges(preset, family, override=out)
        for corner in (0, 1):
            values = {k: (v[corner] if k in out else 0.5 * (v[0] + v[1])) for k, v in full.items()}
            try:
                Design(**resolve_relative(values)).validate()
            except InputError as e:
                raise InputError(
                    f"{', '.join(f'{k}={lo:g}:{hi:g}' for k, (lo, hi) in out.items())} gives a "
                    f"design the solver refuses: {e}",
                    param="range",
                ) from None
    return out


def resolve_relative(values: dict[str, float]) -> dict[str, float]:
    """Drawn values with each :data:`RELATIVE` parameter (drawn as a fraction) turned into its length."""
    return {k: v * values[RELATIVE[k]] if k in RELATIVE else v for k, v in values.items()}


def describe_family(family: str) -> str:
    """One line: what a family varies beyond the preset's ranges, with units (``--help``, ``hcmt models``)."""
    ranges = FAMILIES[family]
    if not ranges:
        return "the first scene, one clamped layer struck by the ball"
    return ", ".join(
        f"{k} {lo:g}-{hi:g}{' x plate_half_length' if k in RELATIVE else ' ' + DESIGN_UNITS[k]}"
        for k, (lo, hi) in ranges.items()
    )


def preset_design(preset: str, family: str = "mono") -> Design:
    """The nominal design of a preset and family: the middle of every sampling range (:func:`family_ranges`)."""
    return Design(**resolve_relative({k: 0.5 * (lo + hi) for k, (lo, hi) in family_ranges(preset, family).items()}))


def sample_design(
    rng: np.random.Generator,
    preset: str = "small",
    variant: str | None = None,
    edge_fraction: float = 0.0,
    family: str = "mono",
    override: dict[str, tuple[float, float]] | None = None,
) -> Design:
    """Draw one design: every parameter of the family's ranges (:func:`family_ranges`) uniform, in sorted order,
    a variant's ranges replacing the training ones. With ``edge_fraction`` > 0, that share of designs then has its
    thickness or its drop height redrawn inside :data:`EDGES` (draws after the uniform ones: a design with
    ``edge_fraction`` 0 is the same as before; a ``mono`` design the same as before families existed;
    ``override``: :func:`family_ranges`'s, the same draws mapped onto the changed ranges)."""
    ranges = family_ranges(preset, family, variant, override)
    names = sorted(ranges)
    u = rng.random(len(names))
    values = resolve_relative({k: float(ranges[k][0] + (ranges[k][1] - ranges[k][0]) * ui) for k, ui in zip(names, u)})
    if edge_fraction > 0 and rng.random() < edge_fraction:
        key = sorted(EDGES)[int(rng.random() < 0.5)]
        (lo, hi), (a, b) = ranges[key], EDGES[key]
        values[key] = float(lo + (hi - lo) * (a + (b - a) * rng.random()))
    return Design(**values)


def middle_design(meta: dict | None, ranges: dict[str, tuple[float, float]] | None = None) -> Design:
    """The middle of a model's training ranges (``ranges``: min and max of each parameter over its training
    designs), every parameter they do not name at the middle of the training preset's ranges (``hcmt
    simulate``'s defaults for that preset; the preset of a dataset's meta.json, ``paper`` when it names none)."""
    preset = ((meta or {}).get("generator") or {}).get("preset", "paper")
    values = {k: 0.5 * (lo + hi) for k, (lo, hi) in RANGES.get(preset, RANGES["paper"]).items()}
    values.update({k: 0.5 * (float(lo) + float(hi)) for k, (lo, hi) in (ranges or {}).items() if k in DESIGN_KEYS})
    return Design(**values)
