"""The Impact Plate's design schema: the design parameters, solver settings, presets, families and materials, their
sampling (:func:`sample_design`) and parsing (``--design K=V``, ``--stack``): the plain values and checks that the
command's parsers need (``hcmt generate/simulate --help``, a refused ``--frames 0``) without the solver, the mesh or
scipy. :mod:`hcmt.sim.scene` assembles a design's scene (its docstring has the choices and units),
:mod:`hcmt.sim.driver` simulates it."""

from __future__ import annotations

import difflib
from dataclasses import asdict, dataclass, fields

import numpy as np

from hcmt.errors import InputError, clip
from hcmt.sim.families import (  # noqa: F401 (the schema's names, read from here)
    BACKING_DENSITY,
    BACKING_POISSON,
    FAMILIES,
    FEATURES,
    MATERIALS,
    MAX_LAYER_POISSON,
    RELATIVE,
    check_material,
    family_label,
    features,
    impactor_of,
    parse_stack,
)
from hcmt.sim.settings import FORMULATIONS, GRAVITY, Settings  # noqa: F401 (read from here too)
from hcmt.sim.units import DESIGN_UNITS, PARAMETERS  # noqa: F401 (each parameter's unit and help, declared there)
from hcmt.sim.values import a_type, is_number, parse_number  # noqa: F401 (read from here too)

CONTACT_RADIUS = 0.4  # mm, the learned model's contact-edge radius (paper Table 7); the initial gap must be smaller
UNITS = {
    "length": "mm",
    "time": "ms",
    "mass": "g",
    "force": "N",
    "stress": "MPa",
    "energy": "mJ",
    "velocity": "mm/ms (= m/s)",
    "density": "g/mm^3",
    "modulus": "MPa",
}


@dataclass(frozen=True)
class Design:
    """One Impact Plate design (the attributes stored with each trajectory). Each parameter's unit and meaning:
    :data:`hcmt.sim.units.PARAMETERS`, their one declaration."""

    thickness: float = 0.75
    drop_height: float = 750.0
    plate_density: float = 2.5e-3
    plate_modulus: float = 70e3
    plate_poisson: float = 0.22
    ball_radius: float = 3.5
    ball_density: float = 7.85e-3
    ball_modulus: float = 200e3
    ball_poisson: float = 0.3
    mesh_size: float = 0.125  # the plate's element size (and the ball's)
    plate_half_length: float = 15.0  # disk radius (axisymmetric) or half width (plane strain)
    gap: float = 0.02  # the initial ball-plate gap
    # panel families (docs/solver.md, "Panel families"; each field's owner in hcmt.sim.families.FEATURES): 0 means
    # absent, so the fields above alone are the first scene, one clamped layer struck by the ball. Layers 2-4 lie
    # under the top one (thickness, plate_*), bonded.
    layer2_thickness: float = 0.0  # 0: no second layer
    layer2_density: float = 1.4e-3  # the defaults: the polymer film
    layer2_modulus: float = 4e3
    layer2_poisson: float = 0.38
    layer3_thickness: float = 0.0
    layer3_density: float = 1.4e-3
    layer3_modulus: float = 4e3
    layer3_poisson: float = 0.38
    layer4_thickness: float = 0.0
    layer4_density: float = 1.4e-3
    layer4_modulus: float = 4e3
    layer4_poisson: float = 0.38
    support_radius: float = 0.0  # a simply supported ring under the panel at this radius, rim free (0: clamped)
    backing_thickness: float = 0.0  # a bonded soft backing under the panel, its bottom fixed, rim free (0: none)
    backing_modulus: float = 10.0  # density BACKING_DENSITY, Poisson BACKING_POISSON
    pen_tip_radius: float = 0.0  # a pen's hemispherical tip (ball_* material) instead of the ball (0: the ball)
    pen_mass: float = 2.0  # the pen's rigid rod

    @property
    def impact_speed(self) -> float:
        """v0 = sqrt(2 g H) (mm/ms)."""
        return float(np.sqrt(2 * GRAVITY * self.drop_height))

    @property
    def layers(self) -> list[tuple[float, float, float, float]]:
        """The panel's bonded layers from the top face down: (thickness mm, density, modulus MPa, Poisson)."""
        return [
            (self.thickness, self.plate_density, self.plate_modulus, self.plate_poisson),
            *(layer for f in features(self) for layer in f.layers(self)),
        ]

    @property
    def total_thickness(self) -> float:
        return float(sum(layer[0] for layer in self.layers))

    @property
    def impactor(self) -> str:
        """``ball``, or the impactor a feature puts in its place (``pen``)."""
        f = impactor_of(self)
        return f.impactor if f else "ball"

    @property
    def impactor_radius(self) -> float:
        f = impactor_of(self)
        return f.radius(self) if f else self.ball_radius

    @property
    def family(self) -> str:
        """The design's family (:data:`FAMILIES`): ``mono``, ``stack2`` .. ``stack4``, ``ring``, ``backing``,
        ``pen``, or their combination joined by ``+`` (``stack3+pen``; :func:`hcmt.sim.families.family_label`)."""
        return family_label(self)

    def validate(self) -> "Design":
        """Refuse impossible designs with a message naming the parameter and what was expected."""
        for name in ("thickness", "ball_radius", "mesh_size", "plate_half_length", "drop_height", "gap"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise InputError(f"must be > 0 (mm), got {v}", param=name)
        for name in (name for f in FEATURES for name in f.switches):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise InputError(f"must be >= 0 mm (0: none), got {v}", param=name)
        check_material("plate", self.plate_density, self.plate_modulus, self.plate_poisson)
        check_material("ball", self.ball_density, self.ball_modulus, self.ball_poisson)
        if self.gap >= CONTACT_RADIUS:
            raise InputError(
                f"gap ({self.gap} mm) must be smaller than the contact radius {CONTACT_RADIUS} mm so the "
                "first frame already sees the ball near the plate"
            )
        if self.mesh_size > self.total_thickness:
            what = "thickness" if len(self.layers) == 1 else "the stack's total thickness"
            raise InputError(f"mesh_size ({self.mesh_size} mm) must not exceed {what} ({self.total_thickness:g} mm)")
        if impactor_of(self) is None and self.mesh_size > self.ball_radius / 3:
            raise InputError(
                f"mesh_size ({self.mesh_size} mm) must be at most ball_radius / 3 ({self.ball_radius / 3:.3g} mm)"
            )
        if self.plate_half_length <= self.impactor_radius:
            raise InputError(
                f"plate_half_length ({self.plate_half_length} mm) must exceed the "
                f"{'ball_radius' if impactor_of(self) is None else impactor_of(self).switch} "
                f"({self.impactor_radius} mm)"
            )
        for f in features(self):  # each family's own checks (hcmt.sim.families)
            f.check(self)
        return self


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


#: the units a value given in a design unit is most often typed in by mistake: (factor to the design unit, name)
SLIPS = {
    "mm": ((1e3, "m"), (1e-3, "µm")),
    "MPa": ((1e-6, "Pa"), (1e-3, "kPa"), (1e3, "GPa")),
    "g/mm^3": ((1e-6, "kg/m^3"), (1e-3, "g/cm^3")),
    "g": ((1e3, "kg"), (1e-3, "mg")),
}
#: a value this many times beyond the nearest end of its expected span is an order-of-magnitude slip, not a design
SLIP_FACTOR = 10.0


def _times(r: float) -> str:
    return f"{r:.2g}x" if r < 10 else f"{r:,.0f}x" if r < 1e6 else f"{r:.1e}x"


def unit_slip(value: float, unit: str, lo: float, hi: float, factor: float = SLIP_FACTOR) -> str | None:
    """How far ``value`` (in ``unit``) lies beyond ``lo`` .. ``hi`` when it is more than ``factor`` times beyond
    it, and the unit it looks typed in if read in one (:data:`SLIPS`) it lands inside: ``"7.5e+08 is 7,500x above
    it; it looks like Pa: 750 MPa?"``; None when it is inside or near."""
    if not (np.isfinite(value) and lo > 0 and hi > 0):
        return None
    if value > hi * factor:
        how = f"{value:.6g} is {_times(value / hi)} above it"
    elif value < lo / factor:
        how = f"{value:.6g} is {_times(lo / value)} below it" if value > 0 else f"{value:.6g} is not above 0"
    else:
        return None
    likely = [f"{name}: {value * scale:.6g} {unit}" for scale, name in SLIPS.get(unit, ()) if lo <= value * scale <= hi]
    return f"{how}; it looks like {' or '.join(likely)}?" if likely else f"{how}, a unit slip?"


#: a design estimated to take longer than this is refused unless forced (``hcmt simulate --force``)
MAX_ESTIMATED_SECONDS = 600.0


DESIGN_KEYS = tuple(f.name for f in fields(Design))
#: the first scene's parameters (thickness .. gap): every hcmt Impact Plate dataset has them; the families' came later
FIRST_SCENE_KEYS = DESIGN_KEYS.index("gap") + 1


def design_values(items: list[str], where: str = "--design") -> dict[str, float]:
    """``["thickness=0.8", "drop_height=900"]`` -> ``{"thickness": 0.8, ...}``: names as ``hcmt simulate``'s
    options, with ``_`` or ``-``, each once; values finite numbers; else one line naming ``where``."""
    values = {}
    for item in items:
        key, sep, raw = item.partition("=")
        key, shown = design_key(key), clip(item)
        if not sep:
            raise InputError(f"{where} {shown!r}: expected KEY=VALUE, e.g. thickness=0.8")
        if key not in DESIGN_KEYS:
            close = difflib.get_close_matches(key, DESIGN_KEYS, n=1)
            raise InputError(
                f"{where} {shown!r}: unknown parameter {clip(key)!r}; "
                + (f"did you mean {close[0]}? " if close else "")
                + "the parameters are `hcmt simulate --help`'s (`hcmt models` lists them)"
            )
        if key in values:
            raise InputError(f"{where} {shown!r}: {key} is given twice in one design; give it once")
        values[key] = parse_number(raw, f"{where} {shown!r}: {key}")
    return values


def parse_design(items: list[str], defaults: Design, where: str = "--design") -> Design:
    """``["thickness=0.8", "drop_height=900"]`` -> a validated :class:`Design` (other parameters from
    ``defaults``; :func:`design_values`)."""
    values = design_values(items, where)
    try:
        return Design(**{**asdict(defaults), **values}).validate()
    except ValueError as exc:
        raise InputError(f"{where} {exc}") from None


def design_key(text: str) -> str:
    """``--plate-modulus`` / ``plate-modulus`` / ``plate_modulus=...`` -> ``plate_modulus``: a parameter's name as
    written in ``--design``, ``--vary`` or a CSV header."""
    return text.partition("=")[0].strip().lstrip("-").replace("-", "_")


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


def design_from_attrs(attrs: dict) -> Design:
    """The :class:`Design` of a trajectory's attributes; parameters a dataset made before they existed take their
    default (the first scene's: no layers under the top one, clamped, the ball)."""
    return Design(**{k: float(attrs[k]) for k in DESIGN_KEYS if k in attrs})


def middle_design(meta: dict | None, ranges: dict[str, tuple[float, float]] | None = None) -> Design:
    """The middle of a model's training ranges (``ranges``: min and max of each parameter over its training
    designs), every parameter they do not name at the middle of the training preset's ranges (``hcmt
    simulate``'s defaults for that preset; the preset of a dataset's meta.json, ``paper`` when it names none)."""
    preset = ((meta or {}).get("generator") or {}).get("preset", "paper")
    values = {k: 0.5 * (lo + hi) for k, (lo, hi) in RANGES.get(preset, RANGES["paper"]).items()}
    values.update({k: 0.5 * (float(lo) + float(hi)) for k, (lo, hi) in (ranges or {}).items() if k in DESIGN_KEYS})
    return Design(**values)
