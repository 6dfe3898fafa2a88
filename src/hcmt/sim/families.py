"""The panel families: what each adds to the first scene (one clamped layer struck by the ball), as one small object
the design, the mesher's call, the scene and the cost estimate ask, instead of a branch on a design field in each.

A :class:`Feature` owns its design fields (after ``gap``: the first scene's fields come first) and says, of a
design: whether it is present (its ``switch`` field > 0: a dataset made before it existed stores no such field and
reads as the first scene), its part of the family's label, its fields' value rules (:meth:`~Feature.rules`, read
by the design's validation and the design check's first checks), its whole-design checks, the bonded layers it
adds to the panel (:meth:`~Feature.layers`) or under it (:meth:`~Feature.under`), its arguments to
:func:`hcmt.sim.mesh.impact_plate_mesh` (:meth:`~Feature.mesh`), its change to the nodes' static fields
(:meth:`~Feature.scene`) and its impactor's share of the cost estimate (:meth:`~Feature.cost`).
:data:`FEATURES` lists them in the order of a combined label (``stack3+pen``); :data:`FAMILIES`, the named
families a dataset is drawn from, is built from their ``families``. Adding one: docs/extending.md.

Light (numpy only): the command's parsers read :data:`FAMILIES` before torch loads.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from hcmt.errors import InputError
from hcmt.sim.rules import Rule, material_rules, positive, switch_rules
from hcmt.sim.units import DESIGN_UNITS

#: the largest Poisson ratio of a layer under the top one (an adhesive): near 0.5 linear triangles lock
MAX_LAYER_POISSON = 0.45
#: the soft backing's density (g/mm^3, a foam of 200 kg/m^3) and Poisson ratio
BACKING_DENSITY, BACKING_POISSON = 2e-4, 0.3

_FILM = dict(density=(1.2e-3, 1.5e-3), modulus=(2e3, 6e3), poisson=(0.30, 0.40))
_ADHESIVE = dict(density=(0.9e-3, 1.1e-3), modulus=(20.0, 100.0), poisson=(0.40, 0.45))
#: the plate's outer radius range of every family but ``mono``
_HALF_LENGTH = dict(plate_half_length=(10.0, 14.0))


def _layer(k: int, thickness: tuple[float, float], material: dict) -> dict:
    return {f"layer{k}_thickness": thickness, **{f"layer{k}_{m}": r for m, r in material.items()}}


class Feature:
    """One thing a panel family adds to the first scene. Subclasses set the class attributes and define every
    method marked *required* (tests/test_extending.py checks that each does, so none is silently the default)."""

    name = ""  # its part of Design.family
    switch = ""  # the design field whose value > 0 turns it on (0: absent, the first scene)
    switches: tuple[str, ...] = ()  # the fields where 0 means "none" (refused below 0)
    fields: tuple[str, ...] = ()  # every design field it owns
    families: dict[str, dict[str, tuple[float, float]]] = {}  # named families: ranges beyond the preset's
    impactor: str | None = None  # the impactor it puts in the ball's place

    def present(self, design) -> bool:
        return getattr(design, self.switch) > 0

    def label(self, design) -> str:
        return self.name

    def rules(self, values: Mapping[str, float]) -> list[Rule]:  # required
        """Its fields' value rules (:class:`hcmt.sim.rules.Rule`) that ``values`` (a design's, or the few a designs
        CSV's row gives) call for: each of its ``switches`` >= 0, and its other fields' where ``values`` turn it on.
        Every field has one (tests/test_extending.py); a rule that needs other fields goes in :meth:`check`."""
        raise NotImplementedError

    def given(self, values: Mapping[str, float]) -> bool:
        """Whether ``values`` turn it on (its ``switch`` > 0; unset: off)."""
        return values.get(self.switch, 0) > 0

    def check(self, design) -> None:  # required: refuse an impossible whole design (its values passed rules())
        raise NotImplementedError

    def layers(self, design) -> list[tuple[float, float, float, float]]:
        """The bonded panel layers it adds under the top one: (thickness mm, density, modulus MPa, Poisson)."""
        return []

    def under(self, design) -> list[tuple[float, float, float, float]]:
        """The bonded layers it adds under the panel (a support's), same tuple."""
        return []

    def mesh(self, design) -> dict:  # required: its keyword arguments of hcmt.sim.mesh.impact_plate_mesh
        raise NotImplementedError

    def scene(self, design, mesh: dict, density: np.ndarray, formulation: str) -> np.ndarray:  # required
        """The nodes' density [N] as the learned model sees it (the impactor's body may carry more mass)."""
        raise NotImplementedError

    def cost(self, design, h: float) -> tuple[float, float] | None:  # required
        """(element size, node count) of the impactor it brings, for the cost estimate; None: it changes the
        estimate only through :meth:`layers` and :meth:`under` (or not at all)."""
        raise NotImplementedError


class Stack(Feature):
    """Up to three bonded layers under the top one (``layer2_*`` .. ``layer4_*``), stacked without gaps."""

    name, switch = "stack", "layer2_thickness"
    switches = tuple(f"layer{k}_thickness" for k in (2, 3, 4))
    fields = tuple(f"layer{k}_{m}" for k in (2, 3, 4) for m in ("thickness", "density", "modulus", "poisson"))
    families = {
        "stack2": dict(thickness=(0.4, 0.8), **_HALF_LENGTH, **_layer(2, (0.1, 0.3), _FILM)),
        "stack3": dict(
            thickness=(0.4, 0.7), **_HALF_LENGTH, **_layer(2, (0.05, 0.15), _ADHESIVE), **_layer(3, (0.1, 0.3), _FILM)
        ),
        "stack4": dict(
            thickness=(0.4, 0.7),
            **_HALF_LENGTH,
            **_layer(2, (0.05, 0.15), _ADHESIVE),
            **_layer(3, (0.1, 0.3), _FILM),
            **_layer(4, (0.05, 0.15), _ADHESIVE),
        ),
    }

    def present(self, design) -> bool:
        return bool(self.layers(design))

    def label(self, design) -> str:
        return f"stack{1 + len(self.layers(design))}"

    def layers(self, design) -> list[tuple[float, float, float, float]]:
        out = []
        for k in (2, 3, 4):
            t = getattr(design, f"layer{k}_thickness")
            if t > 0:
                out.append((t, *(getattr(design, f"layer{k}_{m}") for m in ("density", "modulus", "poisson"))))
        return out

    def rules(self, values: Mapping[str, float]) -> list[Rule]:
        out = switch_rules(self.switches)
        for k in (2, 3, 4):
            if values.get(f"layer{k}_thickness", 0) > 0:
                out += material_rules(f"layer{k}", ("density", "modulus"))
                out.append(
                    Rule(
                        f"layer{k}_poisson",
                        lambda v: (v >= 0) & (v <= MAX_LAYER_POISSON),
                        f"in [0, {MAX_LAYER_POISSON}] (near 0.5 the linear triangles lock volumetrically)",
                        words="{param} must be {expected}, got {value}",  # no flag: --stack may have set it
                    )
                )
        return out

    def check(self, design) -> None:
        for k in (3, 4):
            if getattr(design, f"layer{k}_thickness") > 0 and not getattr(design, f"layer{k - 1}_thickness") > 0:
                raise InputError(
                    f"layer{k}_thickness is set but layer{k - 1}_thickness is 0: layers stack from the top without gaps"
                )

    def mesh(self, design) -> dict:
        return {}  # its layers reach the mesher with the panel's (Design.layers)

    def scene(self, design, mesh, density, formulation):
        return density  # its cells' materials come with the panel's (Design.layers)

    def cost(self, design, h):
        return None  # its rows count with the panel's (Design.layers)


class Ring(Feature):
    """A simply supported ring under the panel at ``support_radius``, the rim free."""

    name, switch, switches, fields = "ring", "support_radius", ("support_radius",), ("support_radius",)
    families = {"ring": dict(**_HALF_LENGTH, support_radius=(0.6, 0.9))}  # a fraction of plate_half_length

    def rules(self, values: Mapping[str, float]) -> list[Rule]:
        return switch_rules(self.switches)

    def check(self, design) -> None:
        r, h, L = design.support_radius, design.mesh_size, design.plate_half_length
        if not h <= r <= L - h:
            raise InputError(
                f"support_radius ({r} mm) must lie inside the plate: between mesh_size ({h:g}) and "
                f"plate_half_length - mesh_size ({L - h:g} mm)"
            )

    def mesh(self, design) -> dict:
        return {"support_radius": design.support_radius}

    def scene(self, design, mesh, density, formulation):
        return density

    def cost(self, design, h):
        return None  # the ring moves one grid line: the same mesh size


class Backing(Feature):
    """A bonded soft backing under the panel (``backing_thickness``, ``backing_modulus``), its bottom fixed, the
    rim free."""

    name, switch, switches = "backing", "backing_thickness", ("backing_thickness",)
    fields = ("backing_thickness", "backing_modulus")
    families = {"backing": dict(**_HALF_LENGTH, backing_thickness=(1.0, 2.0), backing_modulus=(5.0, 50.0))}

    def rules(self, values: Mapping[str, float]) -> list[Rule]:  # its density and Poisson ratio are fixed: BACKING_*
        return switch_rules(self.switches) + (material_rules("backing", ("modulus",)) if self.given(values) else [])

    def check(self, design) -> None:
        if design.support_radius > 0:
            raise InputError(
                "support_radius and backing_thickness are both set: choose one support (a ring, or a backing)"
            )

    def under(self, design) -> list[tuple[float, float, float, float]]:
        return [(design.backing_thickness, BACKING_DENSITY, design.backing_modulus, BACKING_POISSON)]

    def mesh(self, design) -> dict:
        return {"backing_thickness": design.backing_thickness}

    def scene(self, design, mesh, density, formulation):
        return density

    def cost(self, design, h):
        return None  # its rows count through under()


class Pen(Feature):
    """A pen in the ball's place: a hemispherical tip of ``pen_tip_radius`` (the ``ball_*`` material) held by a
    rigid rod of ``pen_mass``."""

    name, switch, switches, impactor = "pen", "pen_tip_radius", ("pen_tip_radius",), "pen"
    fields = ("pen_tip_radius", "pen_mass")
    families = {"pen": dict(**_HALF_LENGTH, pen_tip_radius=(0.5, 1.0), pen_mass=(1.0, 4.0))}

    def radius(self, design) -> float:
        return design.pen_tip_radius

    def rules(self, values: Mapping[str, float]) -> list[Rule]:
        mass = Rule("pen_mass", positive, f"> 0 {DESIGN_UNITS['pen_mass']}")
        return switch_rules(self.switches) + ([mass] if self.given(values) else [])

    def check(self, design) -> None:
        r, h, t = design.pen_tip_radius, design.mesh_size, design.total_thickness
        if not h <= r <= 10 * t:
            raise InputError(
                f"pen_tip_radius ({r} mm) must lie between mesh_size ({h:g} mm) and 10 x the panel's "
                f"thickness ({10 * t:g} mm)"
            )

    def mesh(self, design) -> dict:
        return {"impactor": "pen"}

    def scene(self, design, mesh, density, formulation):
        """The pen's nodes carry its effective density, its whole mass (tip and rod) over the tip's volume: a
        learned model sees the rod only through it."""
        cells = mesh["cells"]
        p = mesh["mesh_pos"][cells[mesh["cell_body"] == 1]]
        area = 0.5 * np.abs(
            (p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
            - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0])
        )
        weight = 2 * np.pi * p[:, :, 0].mean(1) if formulation == "axisymmetric" else 1.0  # revolved, or per mm
        volume = float(np.sum(weight * area))
        return np.where(mesh["body"] == 1, design.ball_density + design.pen_mass / volume, density)

    def cost(self, design, h):
        r = float(design.pen_tip_radius)
        hb = min(h, r / 3.0)  # a quarter disk at min(h, r / 3)
        return hb, np.pi * r * r / (4.0 * hb * hb) + 2.0 * r / hb + 1.0


STACK, RING, BACKING, PEN = Stack(), Ring(), Backing(), Pen()
#: every feature, in the order of a combined family label (``stack3+ring``, ``stack2+pen``)
FEATURES: tuple[Feature, ...] = (STACK, RING, BACKING, PEN)

#: Named design families: ranges replacing or adding to the preset's (:data:`hcmt.sim.sampling.RANGES`), so that a
#: split can hold a family out. ``mono`` is the first scene unchanged; the others vary the plate's outer radius too.
#: A range of ``support_radius`` is a fraction of the drawn ``plate_half_length`` (:data:`RELATIVE`).
FAMILIES: dict[str, dict[str, tuple[float, float]]] = {
    "mono": {},
    **{name: ranges for f in FEATURES for name, ranges in f.families.items()},
}
#: family ranges given as a fraction of another drawn parameter
RELATIVE = {"support_radius": "plate_half_length"}


def features(design) -> list[Feature]:
    """The features a design has, in :data:`FEATURES`' order (none: the first scene, ``mono``)."""
    return [f for f in FEATURES if f.present(design)]


def family_label(design) -> str:
    """``mono``, ``stack2`` .. ``stack4``, ``ring``, ``backing``, ``pen``, or their combination joined by ``+``."""
    return "+".join(f.label(design) for f in features(design)) or "mono"


def impactor_of(design) -> Feature | None:
    """The feature whose impactor replaces the ball, or None (the ball)."""
    return next((f for f in features(design) if f.impactor), None)
