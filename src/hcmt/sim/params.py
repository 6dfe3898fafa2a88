"""The Impact Plate's design schema: the design parameters, solver settings, families and materials, and their
parsing (``--design K=V``, ``--stack``): the plain values and checks that the command's parsers need (``hcmt
generate/simulate --help``, a refused ``--frames 0``) without the solver, the mesh or scipy.
:mod:`hcmt.sim.sampling` draws designs from the presets' ranges, :mod:`hcmt.sim.scene` assembles a design's scene
(its docstring has the choices and units), :mod:`hcmt.sim.driver` simulates it."""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields

import numpy as np

from hcmt.errors import InputError, clip
from hcmt.sim.families import (  # noqa: F401 (the schema's names, read from here)
    BACKING_DENSITY,
    BACKING_POISSON,
    FAMILIES,
    FEATURES,
    MAX_LAYER_POISSON,
    RELATIVE,
    family_label,
    features,
    impactor_of,
)
from hcmt.sim.rules import Rule, material_rules, refuse, size_rules
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
        """Refuse impossible designs with a message naming the parameter and what was expected: each value by its
        rule (:func:`value_rules`), then the whole design (mesh_size against the thickness and the ball, the plate
        against the impactor, each family's :meth:`~hcmt.sim.families.Feature.check`)."""
        values = vars(self)
        refuse(value_rules(values), values)
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


def value_rules(values: Mapping[str, float]) -> list[Rule]:
    """Each design value's validity rule (:class:`hcmt.sim.rules.Rule`) that ``values`` (a design's, or the few a
    designs CSV's row gives) call for, whatever the values they leave unset: the first scene's, then each panel
    family's (:meth:`hcmt.sim.families.Feature.rules`: its sizes, and its other fields' where ``values`` turn it
    on). :meth:`Design.validate` refuses by them before its whole-design checks; the design check's first checks
    (:func:`hcmt.design.basics.value_problem`) read them too, before torch loads."""
    contact = Rule(
        "gap",
        lambda v: v < CONTACT_RADIUS,
        f"smaller than the contact radius {CONTACT_RADIUS} {DESIGN_UNITS['gap']}",
        words="{param} ({value} {unit}) must be {expected} so the first frame already sees the ball near the plate",
    )
    return [
        *size_rules(("thickness", "drop_height", "ball_radius", "mesh_size", "plate_half_length", "gap")),
        contact,
        *material_rules("plate"),
        *material_rules("ball"),
        *(rule for f in FEATURES for rule in f.rules(values)),
    ]


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


def design_from_attrs(attrs: dict) -> Design:
    """The :class:`Design` of a trajectory's attributes; parameters a dataset made before they existed take their
    default (the first scene's: no layers under the top one, clamped, the ball)."""
    return Design(**{k: float(attrs[k]) for k in DESIGN_KEYS if k in attrs})
