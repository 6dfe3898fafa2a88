"""The Impact Plate's design schema: the design parameters, solver settings, presets, families and materials, their
sampling (:func:`sample_design`) and parsing (``--design K=V``, ``--stack``): the plain values and checks that the
command's parsers need (``hcmt generate/simulate --help``, a refused ``--frames 0``) without the solver, the mesh or
scipy. :mod:`hcmt.sim.scene` assembles a design's scene (its docstring has the choices and units),
:mod:`hcmt.sim.driver` simulates it."""
from __future__ import annotations

import difflib
import numbers
from dataclasses import asdict, dataclass, fields

import numpy as np

from hcmt.errors import InputError, clip

#: the solver's formulations (:func:`hcmt.sim.solver.build_model`)
FORMULATIONS = ("axisymmetric", "plane_strain")


GRAVITY = 9.81e-3  # mm/ms^2
CONTACT_RADIUS = 0.4  # mm, the learned model's contact-edge radius (paper Table 7); the initial gap must be smaller
#: the largest Poisson ratio of a layer under the top one (an adhesive): near 0.5 linear triangles lock
MAX_LAYER_POISSON = 0.45
#: the soft backing's density (g/mm^3, a foam of 200 kg/m^3) and Poisson ratio
BACKING_DENSITY, BACKING_POISSON = 2e-4, 0.3
UNITS = {"length": "mm", "time": "ms", "mass": "g", "force": "N", "stress": "MPa", "energy": "mJ",
         "velocity": "mm/ms (= m/s)", "density": "g/mm^3", "modulus": "MPa"}


@dataclass(frozen=True)
class Design:
    """One Impact Plate design (the attributes stored with each trajectory)."""

    thickness: float = 0.75  # mm
    drop_height: float = 750.0  # mm
    plate_density: float = 2.5e-3  # g/mm^3
    plate_modulus: float = 70e3  # MPa
    plate_poisson: float = 0.22
    ball_radius: float = 3.5  # mm
    ball_density: float = 7.85e-3
    ball_modulus: float = 200e3
    ball_poisson: float = 0.3
    mesh_size: float = 0.125  # mm, plate element size (and ball element size)
    plate_half_length: float = 15.0  # mm, disk radius (axisymmetric) or half width (plane strain)
    gap: float = 0.02  # mm, initial ball-plate gap
    # panel families (docs/solver.md, "Panel families"): 0 means absent, so the fields above alone are the first
    # scene, one clamped layer struck by the ball. Layers 2-4 lie under the top one (thickness, plate_*), bonded.
    layer2_thickness: float = 0.0  # mm (0: no second layer)
    layer2_density: float = 1.4e-3  # g/mm^3 (defaults: the polymer film)
    layer2_modulus: float = 4e3  # MPa
    layer2_poisson: float = 0.38
    layer3_thickness: float = 0.0
    layer3_density: float = 1.4e-3
    layer3_modulus: float = 4e3
    layer3_poisson: float = 0.38
    layer4_thickness: float = 0.0
    layer4_density: float = 1.4e-3
    layer4_modulus: float = 4e3
    layer4_poisson: float = 0.38
    support_radius: float = 0.0  # mm, a simply supported ring under the panel at this radius, rim free (0: clamped)
    backing_thickness: float = 0.0  # mm, a bonded soft backing under the panel, its bottom fixed, rim free (0: none)
    backing_modulus: float = 10.0  # MPa (density BACKING_DENSITY, Poisson BACKING_POISSON)
    pen_tip_radius: float = 0.0  # mm, a pen's hemispherical tip (ball_* material) instead of the ball (0: the ball)
    pen_mass: float = 2.0  # g, the pen's rigid rod

    @property
    def impact_speed(self) -> float:
        """v0 = sqrt(2 g H) (mm/ms)."""
        return float(np.sqrt(2 * GRAVITY * self.drop_height))

    @property
    def layers(self) -> list[tuple[float, float, float, float]]:
        """The panel's bonded layers from the top face down: (thickness mm, density, modulus MPa, Poisson)."""
        out = [(self.thickness, self.plate_density, self.plate_modulus, self.plate_poisson)]
        for k in (2, 3, 4):
            t = getattr(self, f"layer{k}_thickness")
            if t > 0:
                out.append((t, *(getattr(self, f"layer{k}_{m}") for m in ("density", "modulus", "poisson"))))
        return out

    @property
    def total_thickness(self) -> float:
        return float(sum(layer[0] for layer in self.layers))

    @property
    def impactor(self) -> str:
        return "pen" if self.pen_tip_radius > 0 else "ball"

    @property
    def impactor_radius(self) -> float:
        return self.pen_tip_radius if self.pen_tip_radius > 0 else self.ball_radius

    @property
    def family(self) -> str:
        """The design's family (:data:`FAMILIES`): ``mono``, ``stack2`` .. ``stack4``, ``ring``, ``backing``,
        ``pen``, or their combination joined by ``+`` (``stack3+pen``)."""
        n = len(self.layers)
        parts = ([f"stack{n}"] if n > 1 else []) + (["ring"] if self.support_radius > 0 else []) + \
            (["backing"] if self.backing_thickness > 0 else []) + (["pen"] if self.pen_tip_radius > 0 else [])
        return "+".join(parts) or "mono"

    def validate(self) -> "Design":
        """Refuse impossible designs with a message naming the parameter and what was expected."""
        for name in ("thickness", "ball_radius", "mesh_size", "plate_half_length", "drop_height", "gap"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise InputError(f"must be > 0 (mm), got {v}", param=name)
        for name in ("layer2_thickness", "layer3_thickness", "layer4_thickness", "support_radius",
                     "backing_thickness", "pen_tip_radius"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise InputError(f"must be >= 0 mm (0: none), got {v}", param=name)
        check_material("plate", self.plate_density, self.plate_modulus, self.plate_poisson)
        check_material("ball", self.ball_density, self.ball_modulus, self.ball_poisson)
        for k in (2, 3, 4):
            if getattr(self, f"layer{k}_thickness") > 0:
                if k > 2 and not getattr(self, f"layer{k - 1}_thickness") > 0:
                    raise InputError(f"layer{k}_thickness is set but layer{k - 1}_thickness is 0: layers stack "
                                     "from the top without gaps")
                nu = getattr(self, f"layer{k}_poisson")
                if not 0 <= nu <= MAX_LAYER_POISSON:
                    raise InputError(f"layer{k}_poisson must be in [0, {MAX_LAYER_POISSON}] (near 0.5 the linear "
                                     f"triangles lock volumetrically), got {nu}")
                check_material(f"layer{k}", *(getattr(self, f"layer{k}_{m}") for m in ("density", "modulus",
                                                                                       "poisson")))
        if self.gap >= CONTACT_RADIUS:
            raise InputError(f"gap ({self.gap} mm) must be smaller than the contact radius {CONTACT_RADIUS} mm so the "
                             "first frame already sees the ball near the plate")
        if self.mesh_size > self.total_thickness:
            what = "thickness" if len(self.layers) == 1 else "the stack's total thickness"
            raise InputError(f"mesh_size ({self.mesh_size} mm) must not exceed {what} ({self.total_thickness:g} mm)")
        if self.pen_tip_radius > 0:
            if not self.mesh_size <= self.pen_tip_radius <= 10 * self.total_thickness:
                raise InputError(f"pen_tip_radius ({self.pen_tip_radius} mm) must lie between mesh_size "
                                 f"({self.mesh_size:g} mm) and 10 x the panel's thickness "
                                 f"({10 * self.total_thickness:g} mm)")
            if not (np.isfinite(self.pen_mass) and self.pen_mass > 0):
                raise InputError(f"must be > 0 g, got {self.pen_mass}", param="pen_mass")
        elif self.mesh_size > self.ball_radius / 3:
            raise InputError(f"mesh_size ({self.mesh_size} mm) must be at most ball_radius / 3 "
                             f"({self.ball_radius / 3:.3g} mm)")
        if self.plate_half_length <= self.impactor_radius:
            raise InputError(f"plate_half_length ({self.plate_half_length} mm) must exceed the "
                             f"{'pen_tip_radius' if self.pen_tip_radius > 0 else 'ball_radius'} "
                             f"({self.impactor_radius} mm)")
        if self.support_radius > 0 and not self.mesh_size <= self.support_radius <= self.plate_half_length - \
                self.mesh_size:
            raise InputError(f"support_radius ({self.support_radius} mm) must lie inside the plate: between mesh_size "
                             f"({self.mesh_size:g}) and plate_half_length - mesh_size "
                             f"({self.plate_half_length - self.mesh_size:g} mm)")
        if self.backing_thickness > 0:
            if self.support_radius > 0:
                raise InputError("support_radius and backing_thickness are both set: choose one support (a ring, "
                                 "or a backing)")
            check_material("backing", BACKING_DENSITY, self.backing_modulus, BACKING_POISSON)
        return self


@dataclass(frozen=True)
class Settings:
    """Solver and recording settings shared by a whole dataset (written to meta.json's ``generator``)."""

    formulation: str = "axisymmetric"
    frames: int = 52
    frame_dt: float = 0.002  # ms between recorded frames
    safety: float = 0.8  # Courant safety factor
    bulk_viscosity: float = 0.06  # linear bulk viscosity b1 (0 = off)
    penalty: float = 0.2  # contact penalty factor alpha, k = alpha m / dt^2
    gravity: float = GRAVITY
    peak_stress: bool = False  # also record stress_max: each node's largest von Mises since the previous frame

    def __post_init__(self) -> None:
        """Each field of its type, else one line naming it (``Settings(frames="8")``); a numpy number is taken as
        the Python one (a ``bool`` is no number, a float no whole number)."""
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "formulation":
                ok, expected = isinstance(v, str), "text"
            elif f.name == "peak_stress":
                ok, expected = isinstance(v, (bool, np.bool_)), "True or False"
                v = bool(v) if ok else v
            elif f.name == "frames":
                ok, expected = is_number(v, whole=True), "a whole number"
                v = int(v) if ok else v
            else:
                ok, expected = is_number(v), "a number"
                v = float(v) if ok else v
            if not ok:
                raise InputError(f"must be {expected}, got {clip(repr(v))} ({a_type(v)})", param=f.name)
            object.__setattr__(self, f.name, v)

    def validate(self) -> "Settings":
        for name, ok, expected in (("formulation", self.formulation in FORMULATIONS, f"one of {FORMULATIONS}"),
                                   ("frames", self.frames >= 2, ">= 2"), ("frame_dt", self.frame_dt > 0, "> 0 ms"),
                                   ("safety", 0 < self.safety <= 0.8, "in (0, 0.8]"),
                                   ("bulk_viscosity", self.bulk_viscosity >= 0, ">= 0"),
                                   ("penalty", 0 < self.penalty <= 0.5, "in (0, 0.5]")):
            if not ok:  # param: the command names its flag (--frames)
                raise InputError(f"must be {expected}, got {getattr(self, name)!r}", param=name)
        return self


#: Sampling ranges (uniform) per preset; parameters not listed keep their :class:`Design` default.
RANGES: dict[str, dict[str, tuple[float, float]]] = {
    "paper": dict(thickness=(0.5, 1.0), drop_height=(500.0, 1000.0), plate_density=(2.2e-3, 2.8e-3),
                  plate_modulus=(50e3, 90e3), plate_poisson=(0.20, 0.25), ball_radius=(3.0, 4.0),
                  ball_density=(7.75e-3, 8.0e-3), ball_modulus=(190e3, 210e3), mesh_size=(0.12, 0.135),
                  plate_half_length=(15.0, 15.0)),
    "small": dict(thickness=(0.5, 1.0), drop_height=(500.0, 1000.0), plate_density=(2.2e-3, 2.8e-3),
                  plate_modulus=(50e3, 90e3), plate_poisson=(0.20, 0.25), ball_radius=(3.5, 4.25),
                  ball_density=(7.75e-3, 8.0e-3), ball_modulus=(190e3, 210e3), mesh_size=(0.29, 0.32),
                  plate_half_length=(12.0, 12.0)),
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


#: the panel's layer materials (density g/mm^3, Young's modulus MPa, Poisson): soda-lime / aluminosilicate
#: cover glass, a polymer film (PET / polarizer, 2-6 GPa) and an optically clear adhesive (1-100 MPa; Poisson 0.45,
#: not the rubber's 0.49+: :data:`MAX_LAYER_POISSON`)
MATERIALS = {"glass": (2.5e-3, 70e3, 0.22), "film": (1.4e-3, 4e3, 0.38), "adhesive": (1.0e-3, 20.0, 0.45)}

_FILM = dict(density=(1.2e-3, 1.5e-3), modulus=(2e3, 6e3), poisson=(0.30, 0.40))
_ADHESIVE = dict(density=(0.9e-3, 1.1e-3), modulus=(20.0, 100.0), poisson=(0.40, 0.45))


def _layer(k: int, thickness: tuple[float, float], material: dict) -> dict:
    return {f"layer{k}_thickness": thickness, **{f"layer{k}_{m}": r for m, r in material.items()}}


#: Named design families: ranges replacing or adding to the preset's (:data:`RANGES`), so that a split can hold a
#: family out. ``mono`` is the first scene unchanged; the others vary the plate's outer radius too. A range of
#: ``support_radius`` is a fraction of the drawn ``plate_half_length`` (:data:`RELATIVE`).
FAMILIES: dict[str, dict[str, tuple[float, float]]] = {
    "mono": {},
    "stack2": dict(thickness=(0.4, 0.8), plate_half_length=(10.0, 14.0), **_layer(2, (0.1, 0.3), _FILM)),
    "stack3": dict(thickness=(0.4, 0.7), plate_half_length=(10.0, 14.0), **_layer(2, (0.05, 0.15), _ADHESIVE),
                   **_layer(3, (0.1, 0.3), _FILM)),
    "stack4": dict(thickness=(0.4, 0.7), plate_half_length=(10.0, 14.0), **_layer(2, (0.05, 0.15), _ADHESIVE),
                   **_layer(3, (0.1, 0.3), _FILM), **_layer(4, (0.05, 0.15), _ADHESIVE)),
    "ring": dict(plate_half_length=(10.0, 14.0), support_radius=(0.6, 0.9)),
    "backing": dict(plate_half_length=(10.0, 14.0), backing_thickness=(1.0, 2.0), backing_modulus=(5.0, 50.0)),
    "pen": dict(plate_half_length=(10.0, 14.0), pen_tip_radius=(0.5, 1.0), pen_mass=(1.0, 4.0)),
}
#: family ranges given as a fraction of another drawn parameter
RELATIVE = {"support_radius": "plate_half_length"}


def family_ranges(preset: str = "small", family: str = "mono", variant: str | None = None) -> dict:
    """The sampling ranges of a family: the preset's, the family's replacing or adding to them, a
    generalization variant's last (ranges of :data:`RELATIVE` parameters stay fractions)."""
    if preset not in RANGES:
        raise InputError(f"unknown preset {preset!r}; expected one of {sorted(RANGES)}")
    if family not in FAMILIES:
        raise InputError(f"unknown family {family!r}; expected one of {', '.join(FAMILIES)}")
    if variant is not None and variant not in VARIANTS:
        raise InputError(f"unknown variant {variant!r}; expected one of {sorted(VARIANTS)}")
    return {**RANGES[preset], **FAMILIES[family], **(VARIANTS[variant] if variant else {})}


def resolve_relative(values: dict[str, float]) -> dict[str, float]:
    """Drawn values with each :data:`RELATIVE` parameter (drawn as a fraction) turned into its length."""
    return {k: v * values[RELATIVE[k]] if k in RELATIVE else v for k, v in values.items()}


def check_material(name: str, density, modulus, poisson) -> None:
    """Refuse impossible materials with a message naming the parameter (``plate_density``: param=, so that the
    command names its flag) and the expected range."""
    for key, v, ok, expected in (
        ("density", density, lambda a: a > 0, "> 0 g/mm^3"),
        ("modulus", modulus, lambda a: a > 0, "> 0 MPa (Young's modulus)"),
        ("poisson", poisson, lambda a: (a > -1) & (a < 0.5), "in (-1, 0.5) (Poisson ratio)"),
    ):
        a = np.asarray(v, float)
        if not np.all(np.isfinite(a)) or not np.all(ok(a)):
            raise InputError(f"must be {expected}, got {clip(v)}", param=f"{name}_{key}")


def describe_family(family: str) -> str:
    """One line: what a family varies beyond the preset's ranges, with units (``--help``, ``hcmt models``)."""
    ranges = FAMILIES[family]
    if not ranges:
        return "the first scene, one clamped layer struck by the ball"
    return ", ".join(f"{k} {lo:g}-{hi:g}{' x plate_half_length' if k in RELATIVE else ' ' + DESIGN_UNITS[k]}"
                     for k, (lo, hi) in ranges.items())


def parse_stack(stack: str) -> dict[str, float]:
    """``glass:0.55,adhesive:0.05,film:0.2`` (top layer first; a layer ``MATERIAL:THICKNESS[:density=..]
    [:modulus=..][:poisson=..]``, MATERIAL one of :data:`MATERIALS`) -> the Design fields of a stack of 1-4
    bonded layers, or one line saying what does not parse."""
    items = [i.strip() for i in stack.split(",") if i.strip()]
    where = repr(clip(stack))  # param "stack": the command prints --stack
    if not items:
        raise InputError(f"{where}: expected 1-4 layers MATERIAL:THICKNESS separated by commas, e.g. "
                         "glass:0.55,adhesive:0.05,film:0.2", param="stack")
    if len(items) > 4:
        raise InputError(f"{where}: {len(items)} layers; a stack has 1-4 layers", param="stack")
    out = {}
    for k, item in enumerate(items, 1):
        parts = item.split(":")
        if len(parts) < 2 or parts[0] not in MATERIALS:
            raise InputError(f"{where}: layer {k} {clip(item)!r}: expected MATERIAL:THICKNESS with MATERIAL one of "
                             f"{', '.join(MATERIALS)}", param="stack")
        material = dict(zip(("density", "modulus", "poisson"), MATERIALS[parts[0]]))
        thickness = parse_number(parts[1], f"{where}: layer {k} thickness", "stack")
        if thickness <= 0:
            raise InputError(f"{where}: layer {k} thickness must be > 0 mm, got {clip(parts[1])}", param="stack")
        for extra in parts[2:]:
            key, sep, raw = extra.partition("=")
            if not sep or key not in material:
                raise InputError(f"{where}: layer {k} {clip(extra)!r}: expected density=, modulus= or poisson=",
                                 param="stack")
            material[key] = parse_number(raw, f"{where}: layer {k} {key}", "stack")
        if k == 1:
            out.update(thickness=thickness, plate_density=material["density"], plate_modulus=material["modulus"],
                       plate_poisson=material["poisson"])
        else:
            out.update({f"layer{k}_thickness": thickness, **{f"layer{k}_{m}": v for m, v in material.items()}})
    for k in range(len(items) + 1, 5):
        out[f"layer{k}_thickness"] = 0.0
    return out


def is_number(v, whole: bool = False) -> bool:
    """Whether ``v`` is a real number (a numpy one too; a ``bool`` is not), a whole one for ``whole``."""
    if isinstance(v, (bool, np.bool_)):
        return False
    return isinstance(v, numbers.Integral) if whole else isinstance(v, numbers.Real)


def a_type(v) -> str:
    """``a str``, ``an int``: how a refusal names the type it got."""
    name = type(v).__name__
    return f"{'an' if name[:1] in 'aeiou' else 'a'} {name}"


#: the units a value given in a design unit is most often typed in by mistake: (factor to the design unit, name)
SLIPS = {"mm": ((1e3, "m"), (1e-3, "µm")), "MPa": ((1e-6, "Pa"), (1e-3, "kPa"), (1e3, "GPa")),
         "g/mm^3": ((1e-6, "kg/m^3"), (1e-3, "g/cm^3")), "g": ((1e3, "kg"), (1e-3, "mg"))}
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
    likely = [f"{name}: {value * scale:.6g} {unit}" for scale, name in SLIPS.get(unit, ())
              if lo <= value * scale <= hi]
    return f"{how}; it looks like {' or '.join(likely)}?" if likely else f"{how}, a unit slip?"


#: a design estimated to take longer than this is refused unless forced (``hcmt simulate --force``)
MAX_ESTIMATED_SECONDS = 600.0


DESIGN_KEYS = tuple(f.name for f in fields(Design))
#: the first scene's parameters (thickness .. gap): every hcmt Impact Plate dataset has them; the families' came later
FIRST_SCENE_KEYS = DESIGN_KEYS.index("gap") + 1
#: the unit of each design parameter (meta.json's units: mm, g, MPa)
DESIGN_UNITS = {"thickness": "mm", "drop_height": "mm", "plate_density": "g/mm^3", "plate_modulus": "MPa",
                "plate_poisson": "-", "ball_radius": "mm", "ball_density": "g/mm^3", "ball_modulus": "MPa",
                "ball_poisson": "-", "mesh_size": "mm", "plate_half_length": "mm", "gap": "mm",
                **{f"layer{k}_{m}": u for k in (2, 3, 4) for m, u in (("thickness", "mm"), ("density", "g/mm^3"),
                                                                     ("modulus", "MPa"), ("poisson", "-"))},
                "support_radius": "mm", "backing_thickness": "mm", "backing_modulus": "MPa", "pen_tip_radius": "mm",
                "pen_mass": "g"}


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
            raise InputError(f"{where} {shown!r}: unknown parameter {clip(key)!r}; "
                             + (f"did you mean {close[0]}? " if close else "")
                             + "the parameters are `hcmt simulate --help`'s (`hcmt models` lists them)")
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


def parse_number(raw: str, what: str, param: str | None = None) -> float:
    """A finite number from text, or one line naming ``what`` (and ``param``, the parameter it came in)."""
    try:
        v = float(raw)
    except ValueError:
        raise InputError(f"{what} must be a number, got {clip(raw.strip())!r}", param=param) from None
    if not np.isfinite(v):
        raise InputError(f"{what} must be a finite number, got {clip(raw.strip())!r}", param=param)
    return v


def preset_design(preset: str, family: str = "mono") -> Design:
    """The nominal design of a preset and family: the middle of every sampling range (:func:`family_ranges`)."""
    return Design(**resolve_relative({k: 0.5 * (lo + hi) for k, (lo, hi) in family_ranges(preset, family).items()}))


def sample_design(rng: np.random.Generator, preset: str = "small", variant: str | None = None,
                  edge_fraction: float = 0.0, family: str = "mono") -> Design:
    """Draw one design: every parameter of the family's ranges (:func:`family_ranges`) uniform, in sorted order,
    a variant's ranges replacing the training ones. With ``edge_fraction`` > 0, that share of designs then has its
    thickness or its drop height redrawn inside :data:`EDGES` (draws after the uniform ones: a design with
    ``edge_fraction`` 0 is the same as before; a ``mono`` design the same as before families existed)."""
    ranges = family_ranges(preset, family, variant)
    names = sorted(ranges)
    u = rng.random(len(names))
    values = resolve_relative({k: float(ranges[k][0] + (ranges[k][1] - ranges[k][0]) * ui)
                               for k, ui in zip(names, u)})
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
