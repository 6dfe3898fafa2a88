"""The Impact Plate scene: design parameters, their sampling and validation, and one simulated trajectory.

A deformable steel ball drops on the centre of a clamped glass panel (paper appendix "Impact Plate"; ANSYS explicit
dynamics there, :mod:`hcmt.sim.solver` here). Half model, symmetry line ``x = 0``. The ball starts ``gap`` above
the plate with the free-fall speed ``v0 = sqrt(2 g H)`` from the drop height ``H`` (the fall itself is not
simulated), so the impact happens inside the recorded window (52 frames x 0.002 ms = 0.104 ms).

Units (written to meta.json): mm, ms, g, hence N, MPa, mJ and mm/ms (= m/s).

Choices where the paper is silent (it lists "plate properties, thickness, density, modulus, drop height, mesh size"):
thickness U(0.5, 1.0) mm and drop height U(500, 1000) mm as its generalization study implies; plate density
U(2.2, 2.8)e-3 g/mm^3 and modulus U(50, 90) GPa (glass is 2.4-2.5e-3 and 60-80 GPa, widened); Poisson 0.20-0.25;
a steel ball (7.75-8.0e-3 g/mm^3, 190-210 GPa, nu 0.3) of radius 3-4 mm; the plate a disk of radius 15 mm
(``paper``) or 12 mm (``small``) clamped at its rim; mesh size drawn per preset so the node count matches
(about 2,200 for ``paper`` as in the paper's Table 6, 400-600 for ``small``).
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass, fields, replace

import numpy as np

from hcmt.errors import InputError
from hcmt.sim.contact import PenaltyContact
from hcmt.sim.mesh import HANDLE, SYMMETRIC, WALL_BOUNDARY, impact_plate_mesh
from hcmt.sim.solver import FORMULATIONS, CentralDifference, build_model, check_material, deformation, \
    nodal_von_mises, stable_time_step

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
                raise InputError(f"{name} must be > 0 (mm), got {v}")
        for name in ("layer2_thickness", "layer3_thickness", "layer4_thickness", "support_radius",
                     "backing_thickness", "pen_tip_radius"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise InputError(f"{name} must be >= 0 mm (0: none), got {v}")
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
                raise InputError(f"pen_mass must be > 0 g, got {self.pen_mass}")
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

    def validate(self) -> "Settings":
        if self.formulation not in FORMULATIONS:
            raise InputError(f"formulation must be one of {FORMULATIONS}, got {self.formulation!r}")
        if self.frames < 2:
            raise InputError(f"frames must be >= 2, got {self.frames}")
        if not self.frame_dt > 0:
            raise InputError(f"frame_dt must be > 0 ms, got {self.frame_dt}")
        if not 0 < self.safety <= 0.8:
            raise InputError(f"safety must be in (0, 0.8], got {self.safety}")
        if self.bulk_viscosity < 0:
            raise InputError(f"bulk_viscosity must be >= 0, got {self.bulk_viscosity}")
        if not 0 < self.penalty <= 0.5:
            raise InputError(f"penalty must be in (0, 0.5], got {self.penalty}")
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


def describe_family(family: str) -> str:
    """One line: what a family varies beyond the preset's ranges, with units (``--help``, ``hcmt models``)."""
    ranges = FAMILIES[family]
    if not ranges:
        return "the first scene, one clamped layer struck by the ball"
    return ", ".join(f"{k} {lo:g}-{hi:g}{' x plate_half_length' if k in RELATIVE else ' ' + DESIGN_UNITS[k]}"
                     for k, (lo, hi) in ranges.items())


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


def parse_stack(text: str) -> dict[str, float]:
    """``glass:0.55,adhesive:0.05,film:0.2`` (top layer first; a layer ``MATERIAL:THICKNESS[:density=..]
    [:modulus=..][:poisson=..]``, MATERIAL one of :data:`MATERIALS`) -> the Design fields of a stack of 1-4
    bonded layers, or one line saying what does not parse."""
    items = [i.strip() for i in text.split(",") if i.strip()]
    where = f"--stack {text!r}"
    if not items:
        raise InputError(f"{where}: expected 1-4 layers MATERIAL:THICKNESS separated by commas, e.g. "
                         "glass:0.55,adhesive:0.05,film:0.2")
    if len(items) > 4:
        raise InputError(f"{where}: {len(items)} layers; a stack has 1-4 layers")
    out = {}
    for k, item in enumerate(items, 1):
        parts = item.split(":")
        if len(parts) < 2 or parts[0] not in MATERIALS:
            raise InputError(f"{where}: layer {k} {item!r}: expected MATERIAL:THICKNESS with MATERIAL one of "
                             f"{', '.join(MATERIALS)}")
        material = dict(zip(("density", "modulus", "poisson"), MATERIALS[parts[0]]))
        thickness = parse_number(parts[1], f"{where}: layer {k} thickness")
        if thickness <= 0:
            raise InputError(f"{where}: layer {k} thickness must be > 0 mm, got {parts[1]}")
        for extra in parts[2:]:
            key, sep, raw = extra.partition("=")
            if not sep or key not in material:
                raise InputError(f"{where}: layer {k} {extra!r}: expected density=, modulus= or poisson=")
            material[key] = parse_number(raw, f"{where}: layer {k} {key}")
        if k == 1:
            out.update(thickness=thickness, plate_density=material["density"], plate_modulus=material["modulus"],
                       plate_poisson=material["poisson"])
        else:
            out.update({f"layer{k}_thickness": thickness, **{f"layer{k}_{m}": v for m, v in material.items()}})
    for k in range(len(items) + 1, 5):
        out[f"layer{k}_thickness"] = 0.0
    return out


def design_mesh(design: Design) -> dict[str, np.ndarray]:
    return impact_plate_mesh(design.thickness, design.impactor_radius, design.mesh_size,
                             plate_half_length=design.plate_half_length, gap=design.gap,
                             layers=[layer[0] for layer in design.layers], support_radius=design.support_radius,
                             backing_thickness=design.backing_thickness, impactor=design.impactor)


def cell_materials(design: Design, mesh: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(density, modulus, Poisson) per cell [C] from the mesh's ``cell_layer``: the panel's layers, the backing
    (last), the impactor (-1: the ball_* material)."""
    table = np.array([layer[1:] for layer in design.layers]
                     + ([(BACKING_DENSITY, design.backing_modulus, BACKING_POISSON)] if design.backing_thickness > 0
                        else [])
                     + [(design.ball_density, design.ball_modulus, design.ball_poisson)])
    m = table[mesh["cell_layer"]]  # -1 picks the impactor's row
    return m[:, 0], m[:, 1], m[:, 2]


#: cost model of the solver (docs/solver.md, "Speed"): per substep a fixed ~0.4 ms of Python and sparse-product
#: overhead plus ~3e-7 s per node, on one core of the development machine (a 34,768-node design measured 15 ms per
#: substep with the other core busy: 582 s where 1e-7 s per node had estimated 150 s; small meshes stay
#: overhead-bound, so their estimate stays conservative)
SECONDS_PER_SUBSTEP, SECONDS_PER_NODE_SUBSTEP = 4e-4, 3e-7
#: a design estimated to take longer than this is refused unless forced (``hcmt simulate --force``)
MAX_ESTIMATED_SECONDS = 600.0
#: the ranges the solver is validated for (docs/solver.md): outside them, results are not trusted
VALIDATED = {"impact_speed": (0.0, 10.0), "plate_modulus": (1e3, 1e6), "ball_modulus": (1e3, 1e6),
             "plate_poisson": (0.0, 0.45), "ball_poisson": (0.0, 0.45), "plate_density": (5e-4, 2e-2),
             "ball_density": (5e-4, 2e-2)}


class SolverError(InputError):
    """The solve cannot go on (an element inverted): the design is outside what the solver handles."""


def validated_warnings(design: Design) -> list[str]:
    """One line per parameter outside the range the solver is validated for."""
    out = []
    for key, (lo, hi) in VALIDATED.items():
        v = getattr(design, key)
        if not lo <= v <= hi:
            unit = " mm/ms (= m/s)" if key == "impact_speed" else ""
            out.append(f"{key} = {v:.6g}{unit} is outside the range the solver is validated for ({lo:g} .. {hi:g}; "
                       "docs/solver.md): do not trust the result")
    return out


def _model(design: Design, settings: Settings, mesh: dict):
    return build_model(mesh["mesh_pos"], mesh["cells"], *cell_materials(design, mesh),
                       formulation=settings.formulation, bulk_viscosity=settings.bulk_viscosity)


#: the largest mesh any command builds (nodes, from :func:`estimate`): the solver holds every frame (12 bytes per
#: node and frame) and a learned model's step about 160 kB per node (docs/RESULTS.md), so beyond this a design
#: exhausts memory before it could finish
MAX_NODES = 200_000


def estimate(design: Design, settings: Settings = Settings()) -> dict:
    """The cost of a design from its numbers alone, before any array is built: nodes (the plate's structured grid
    ``(L/h + 1)(max(4, t/h) + 1)`` plus the ball's half disk ``π r² / (2 h²) + 2 r / h + 1``), substeps (frames ×
    frame interval ÷ the Courant step ``safety h_min / c``, ``h_min`` = half the plate's layer height or element
    size, ``c`` the faster material's dilatational wave speed) and seconds (:data:`SECONDS_PER_SUBSTEP`,
    :data:`SECONDS_PER_NODE_SUBSTEP`). Floats throughout: a 1e308 mm plate is an infinite estimate, not an
    overflow."""
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        h, L, r = (float(v) for v in (design.mesh_size, design.plate_half_length, design.impactor_radius))
        layers = [(float(t), rho, E, nu) for t, rho, E, nu in design.layers]
        if design.backing_thickness > 0:
            layers.append((float(design.backing_thickness), BACKING_DENSITY, design.backing_modulus,
                           BACKING_POISSON))
        rows = [max(1.0, t / h) for t, *_ in layers]
        rows[0] += max(0.0, 4.0 - sum(rows[:len(design.layers)]))  # at least 4 rows through the panel
        if design.pen_tip_radius > 0:  # quarter disk at min(h, r / 3)
            hb = min(h, r / 3.0)
            impactor = np.pi * r * r / (4.0 * hb * hb) + 2.0 * r / hb + 1.0
        else:
            hb = h
            impactor = np.pi * r * r / (2.0 * h * h) + 2.0 * r / h + 1.0
        nodes = (L / h + 1.0) * (sum(rows) + 1.0) + impactor
        speeds = [np.sqrt(E * (1 - nu) / (rho * (1 + nu) * (1 - 2 * nu))) for _, rho, E, nu in layers]
        ball = np.sqrt(design.ball_modulus * (1 - design.ball_poisson) / (
            design.ball_density * (1 + design.ball_poisson) * (1 - 2 * design.ball_poisson)))
        b1 = settings.bulk_viscosity
        # the Courant step of the fastest element: its half height over its material's wave speed
        h_over_c = min([0.5 * min(h, t / n) / c for (t, *_), n, c in zip(layers, rows, speeds)] + [0.5 * hb / ball])
        dt = settings.safety * h_over_c * (np.sqrt(1 + b1 * b1) - b1)
        substeps = (settings.frames - 1) * np.ceil(settings.frame_dt / dt)
        seconds = substeps * (SECONDS_PER_SUBSTEP + SECONDS_PER_NODE_SUBSTEP * nodes)
    return {"num_nodes": float(nodes), "substeps": float(substeps), "estimated_s": float(seconds)}


def check_size(design: Design, settings: Settings = Settings(), where: str = "") -> dict:
    """:func:`estimate`, refusing (one line with the estimate) a design whose mesh would exceed
    :data:`MAX_NODES` nodes; returns the estimate."""
    e = estimate(design, settings)
    if not e["num_nodes"] <= MAX_NODES:
        n = f"{e['num_nodes']:.3g}" if np.isfinite(e["num_nodes"]) else "an unbounded number of"
        raise InputError(f"{where}the design's mesh would have {n} nodes (plate {design.plate_half_length:g} x "
                         f"{design.thickness:g} mm, ball radius {design.ball_radius:g} mm at mesh_size "
                         f"{design.mesh_size:g} mm), more than the {MAX_NODES:,} any command builds; coarsen the "
                         "mesh or shrink the design")
    return e


def check_cost(seconds: float, nodes: float, design: Design, force: bool = False, where: str = "",
               what: str = "") -> None:
    """The one cost rule of simulate, generate, predict and sweep: refuse, unless ``force``, a plan estimated at
    over :data:`MAX_ESTIMATED_SECONDS` (one line: the estimate, ``what`` it covers, the mesh, how to go on)."""
    if seconds > MAX_ESTIMATED_SECONDS and not force:
        raise InputError(f"{where}about {nodes:.0f} nodes at mesh_size {design.mesh_size:g} mm: estimated "
                         f"{seconds:.0f} s{what} exceeds {MAX_ESTIMATED_SECONDS:.0f} s; coarsen the mesh, record fewer "
                         "frames or force it (force=True, --force)")


def plan(design: Design, settings: Settings = Settings()) -> dict:
    """What a solve will cost before running it: nodes, cells, substeps, time step and estimated seconds. The
    mesh is built only after :func:`check_size` has refused a design too large to build."""
    design.validate()
    settings.validate()
    check_size(design, settings)
    mesh = design_mesh(design)
    per_frame = int(np.ceil(settings.frame_dt / stable_time_step(_model(design, settings, mesh), settings.safety)))
    n, substeps = len(mesh["mesh_pos"]), per_frame * (settings.frames - 1)
    return {"num_nodes": n, "num_cells": len(mesh["cells"]), "substeps": substeps,
            "dt": settings.frame_dt / per_frame,
            "estimated_s": substeps * (SECONDS_PER_SUBSTEP + SECONDS_PER_NODE_SUBSTEP * n)}


def solver(design: Design, settings: Settings = Settings()) -> tuple[CentralDifference, dict, int]:
    """The solver of a design, started: (the integrator at t = 0 with the impactor at ``v0``, the mesh
    (:func:`design_mesh`), substeps per frame). Boundary conditions :func:`fixed_dofs`, the pen's rod
    ``rigid``, penalty contact between the plate and the impactor."""
    mesh = design_mesh(design)
    X, cells, body = mesh["mesh_pos"], mesh["cells"], mesh["body"]
    model = _model(design, settings, mesh)
    substeps = int(np.ceil(settings.frame_dt / stable_time_step(model, settings.safety)))
    dt = settings.frame_dt / substeps  # frames land exactly on substeps
    contact = PenaltyContact(X, cells, body, model.mass, dt, alpha=settings.penalty)
    sim = CentralDifference(model, fixed_dofs(mesh["node_type"]), dt, contact=contact, gravity=settings.gravity,
                            rigid=(mesh["rigid"], design.pen_mass))
    v0 = np.zeros_like(X)
    v0[body == 1, 1] = -design.impact_speed
    sim.start(X, v0)
    return sim, mesh, substeps


def simulate(design: Design, settings: Settings = Settings(), *, progress=None) -> dict:
    """Simulate one design. Returns ``fields`` (the native-format arrays: mesh_pos, cells, node_type, density,
    modulus static; world_pos [T,N,2], stress [T,N,1] dynamic; float32/int32), ``attrs`` (the design parameters,
    its impact speed and the formulation) and ``info`` (wall and CPU time, substeps, time step, final energies).

    Frame k is the state at t = k * frame_dt; frame 0 the initial one. ``stress`` is the nodal von Mises stress
    (MPa): element Cauchy stress, the out-of-plane (hoop) component included, area-averaged to the nodes of its
    own body. With ``settings.peak_stress`` also ``stress_max`` [T,N,1]: each node's largest von Mises stress over
    the solver's substeps since the previous frame (frame 0: its own), the peak a coarse frame interval would
    otherwise step over (docs/RESULTS.md, "Frame interval")."""
    design.validate()
    settings.validate()
    check_size(design, settings)
    start, cpu_start = time.perf_counter(), time.process_time()
    sim, mesh, substeps = solver(design, settings)
    model, X, cells, dt = sim.model, mesh["mesh_pos"], mesh["cells"], sim.dt
    T, N = settings.frames, len(X)
    world_pos = np.empty((T, N, 2), np.float32)
    stress = np.empty((T, N, 1), np.float32)
    peak = np.empty((T, N, 1), np.float32) if settings.peak_stress else None
    for k in range(T):
        if k and peak is None:
            sim.step(substeps)
        elif k:  # one substep at a time: the largest stress between two frames (Settings.peak_stress)
            running = np.zeros(N)
            for _ in range(substeps):
                sim.step(1)
                np.maximum(running, nodal_von_mises(model, sim.x), out=running)
            peak[k, :, 0] = running
        world_pos[k] = sim.x
        F11, F12, F21, F22, F33 = deformation(model, sim.x)
        inverted = np.flatnonzero((F11 * F22 - F12 * F21) * F33 <= 0)
        if len(inverted) or not np.isfinite(sim.x).all():
            what = f"element {int(inverted[0])} inverted" if len(inverted) else "positions became non-finite"
            raise SolverError(f"solve stopped at frame {k} (t = {k * settings.frame_dt:.4g} ms): {what}; the design "
                              "is outside what the explicit solver handles (see the validated ranges in "
                              "docs/solver.md)")
        stress[k, :, 0] = nodal_von_mises(model, sim.x)
        if peak is not None and k == 0:
            peak[0] = stress[0]
        if progress is not None:
            progress(k)
    fields_ = dict(_static_fields(design, mesh, settings.formulation), world_pos=world_pos, stress=stress)
    if peak is not None:
        fields_["stress_max"] = peak
    attrs = {**asdict(design), "impact_speed": design.impact_speed, "formulation": settings.formulation,
             "family": design.family}
    info = dict(wall_time=time.perf_counter() - start, cpu_time=time.process_time() - cpu_start, substeps=substeps * (T - 1), dt=dt, num_nodes=N,
                num_cells=len(cells), energy=sim.energies())
    return dict(fields=fields_, attrs=attrs, info=info)


def fixed_dofs(node_type: np.ndarray) -> np.ndarray:
    """[N, 2] bool: the degrees of freedom a boundary condition holds: SYMMETRIC x (the axis), HANDLE x and y
    (clamped), WALL_BOUNDARY y (a roller: the simply supported ring)."""
    fixed = np.zeros((len(node_type), 2), dtype=bool)
    fixed[node_type == SYMMETRIC, 0] = True
    fixed[node_type == HANDLE] = True
    fixed[node_type == WALL_BOUNDARY, 1] = True
    return fixed


def _static_fields(design: Design, mesh: dict, formulation: str = "axisymmetric") -> dict[str, np.ndarray]:
    """The native-format static fields of a design's mesh: mesh_pos, cells, node_type, density, modulus.

    A node's density and modulus are those of the softest cell it belongs to, so that a soft layer one element
    thick is seen at both its faces. The pen's nodes carry the pen's effective density, its whole mass (tip and
    rod) over the tip's volume: a learned model sees the rod only through it."""
    rho_c, E_c, _ = cell_materials(design, mesh)
    cells = mesh["cells"]
    rank = np.lexsort((rho_c, E_c))  # cells from softest to stiffest
    order = np.empty(len(rank), np.int64)
    order[rank] = np.arange(len(rank))
    node_rank = np.full(len(mesh["mesh_pos"]), len(rank), np.int64)
    np.minimum.at(node_rank, cells.ravel(), np.repeat(order, 3))
    softest = rank[node_rank]
    density, modulus = rho_c[softest], E_c[softest]
    if design.pen_tip_radius > 0:
        tip = mesh["cell_body"] == 1
        p = mesh["mesh_pos"][cells[tip]]
        area = 0.5 * np.abs((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                            - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0]))
        weight = 2 * np.pi * p[:, :, 0].mean(1) if formulation == "axisymmetric" else 1.0  # revolved, or per mm
        volume = float(np.sum(weight * area))
        density = np.where(mesh["body"] == 1, design.ball_density + design.pen_mass / volume, density)
    return dict(
        mesh_pos=mesh["mesh_pos"].astype(np.float32), cells=cells.astype(np.int32),
        node_type=mesh["node_type"].astype(np.int32)[:, None],
        density=density.astype(np.float32)[:, None], modulus=modulus.astype(np.float32)[:, None])


def initial_frames(design: Design, settings: Settings = Settings()) -> dict:
    """The first two frames of a design without a solver run: what a learned model needs to start a rollout.

    Frame 0 is the mesh at rest with the ball ``gap`` above the plate; frame 1 is one ``frame_dt`` later in free
    flight, ``x^1 = x^0 - (v0 dt + g dt^2 / 2) e_y`` for the ball and ``- g dt^2 / 2`` for the plate's unclamped
    nodes (the ball cannot reach the plate in one frame: ``v0 dt < gap`` is checked). The solver's frame 1 agrees
    to float32 precision (tests/test_predict.py). Stress is zero in both frames. Returns ``fields`` (static fields,
    ``world_pos [2, N, 2]``, ``stress [2, N, 1]``) and ``attrs``, as :func:`simulate`."""
    design.validate()
    settings.validate()
    check_size(design, settings)
    dt, g = settings.frame_dt, settings.gravity
    fall = first_frame_fall(design, settings)
    if fall >= design.gap:
        raise InputError(f"drop_height {design.drop_height} mm: the ball ({design.impact_speed:.3g} mm/ms) would "
                         f"cross the {design.gap} mm gap within the first frame ({dt} ms); lower drop_height or "
                         "raise gap")
    mesh = design_mesh(design)
    x0 = mesh["mesh_pos"].astype(np.float64)
    x1 = x0.copy()
    ball = mesh["body"] == 1
    x1[ball, 1] -= fall
    x1[~ball & ~fixed_dofs(mesh["node_type"])[:, 1], 1] -= 0.5 * g * dt * dt
    fields_ = dict(_static_fields(design, mesh, settings.formulation), world_pos=np.stack([x0, x1]).astype(np.float32),
                   stress=np.zeros((2, len(x0), 1), np.float32))
    attrs = {**asdict(design), "impact_speed": design.impact_speed, "formulation": settings.formulation,
             "family": design.family}
    return dict(fields=fields_, attrs=attrs)


def first_frame_fall(design: Design, settings: Settings) -> float:
    """How far the ball falls in the first frame, ``v0 dt + g dt^2 / 2`` (mm)."""
    dt = settings.frame_dt
    return design.impact_speed * dt + 0.5 * settings.gravity * dt * dt


def start_frames(design: Design, settings: Settings = Settings()) -> dict:
    """Frames 0 and 1 of a design, what a learned rollout starts from: :func:`initial_frames` (no solver run) when
    the ball cannot reach the plate within the first frame, else the solver's own first frame (a coarse interval:
    at 0.008 ms a ball at 4 mm/ms crosses the 0.02 mm gap within it; the cost is one frame of a solve, in
    ``info``). Returns ``fields``, ``attrs`` and ``info`` ({"solver_frames": 0 or 1, "wall_time"})."""
    if first_frame_fall(design.validate(), settings.validate()) < design.gap:
        return {**initial_frames(design, settings), "info": {"solver_frames": 0, "wall_time": 0.0}}
    r = simulate(design, replace(settings, frames=2))
    f = dict(r["fields"])
    f.pop("stress_max", None)
    return {"fields": f, "attrs": r["attrs"], "info": {"solver_frames": 1, "wall_time": r["info"]["wall_time"]}}


def feature_spec(settings: Settings = Settings()) -> dict:
    """meta.json ``features`` of an Impact Plate dataset."""
    T = settings.frames
    return {
        "mesh_pos": {"type": "static", "shape": [-1, 2], "dtype": "float32"},
        "cells": {"type": "static", "shape": [-1, 3], "dtype": "int32"},
        "node_type": {"type": "static", "shape": [-1, 1], "dtype": "int32"},
        "density": {"type": "static", "shape": [-1, 1], "dtype": "float32"},
        "modulus": {"type": "static", "shape": [-1, 1], "dtype": "float32"},
        "world_pos": {"type": "dynamic", "shape": [T, -1, 2], "dtype": "float32"},
        "stress": {"type": "dynamic", "shape": [T, -1, 1], "dtype": "float32"},
        **({"stress_max": {"type": "dynamic", "shape": [T, -1, 1], "dtype": "float32"}} if settings.peak_stress
           else {}),
    }


__all__ = ["Design", "Settings", "RANGES", "VARIANTS", "FAMILIES", "MATERIALS", "UNITS", "GRAVITY",
           "CONTACT_RADIUS", "sample_design", "family_ranges", "parse_stack", "design_from_attrs", "simulate", "initial_frames", "start_frames", "feature_spec", "design_mesh"]


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


def parse_design(items: list[str], defaults: Design, where: str = "--design") -> Design:
    """``["thickness=0.8", "drop_height=900"]`` -> a validated :class:`Design` (other parameters from
    ``defaults``). Names as ``hcmt simulate``'s options, with ``_`` or ``-``; values finite numbers."""
    values = {}
    for item in items:
        key, sep, raw = item.partition("=")
        key = design_key(key)
        if not sep:
            raise InputError(f"{where} {item!r}: expected KEY=VALUE, e.g. thickness=0.8")
        if key not in DESIGN_KEYS:
            raise InputError(f"{where} {item!r}: unknown parameter {key!r}; expected one of {', '.join(DESIGN_KEYS)}")
        if key in values:
            raise InputError(f"{where} {item!r}: {key} is given twice in one design; give it once")
        values[key] = parse_number(raw, f"{where} {item!r}: {key}")
    try:
        return Design(**{**asdict(defaults), **values}).validate()
    except ValueError as exc:
        raise InputError(f"{where} {exc}") from None


def design_key(text: str) -> str:
    """``--plate-modulus`` / ``plate-modulus`` / ``plate_modulus=...`` -> ``plate_modulus``: a parameter's name as
    written in ``--design``, ``--vary`` or a CSV header."""
    return text.partition("=")[0].strip().lstrip("-").replace("-", "_")


def parse_number(raw: str, what: str) -> float:
    """A finite number from text, or one line naming ``what``."""
    try:
        v = float(raw)
    except ValueError:
        raise InputError(f"{what} must be a number, got {raw.strip()!r}") from None
    if not np.isfinite(v):
        raise InputError(f"{what} must be a finite number, got {raw.strip()!r}")
    return v
