"""The panel's named layer materials (:data:`MATERIALS`) and ``--stack``: a panel written as its layers, top first,
``MATERIAL:THICKNESS[:density=..][:modulus=..][:poisson=..]``, read into the :class:`~hcmt.sim.params.Design`
fields of a stack of 1-4 bonded layers (:func:`parse_stack`).

It stands apart from the families (:mod:`hcmt.sim.families`: what each feature adds to a design) because it is text
read into a design, not a feature: it writes the ``stack`` feature's fields, which
:meth:`~hcmt.sim.params.Design.validate` checks. Light (numpy only): the command's parsers read :data:`MATERIALS`
before torch loads."""

from __future__ import annotations

from hcmt.errors import InputError, clip
from hcmt.sim.values import parse_number

#: the panel's layer materials (density g/mm^3, Young's modulus MPa, Poisson): soda-lime / aluminosilicate
#: cover glass, a polymer film (PET / polarizer, 2-6 GPa) and an optically clear adhesive (1-100 MPa; Poisson 0.45,
#: not the rubber's 0.49+: :data:`hcmt.sim.families.MAX_LAYER_POISSON`)
MATERIALS = {"glass": (2.5e-3, 70e3, 0.22), "film": (1.4e-3, 4e3, 0.38), "adhesive": (1.0e-3, 20.0, 0.45)}


def parse_stack(stack: str) -> dict[str, float]:
    """``glass:0.55,adhesive:0.05,film:0.2`` (top layer first; a layer ``MATERIAL:THICKNESS[:density=..]
    [:modulus=..][:poisson=..]``, MATERIAL one of :data:`MATERIALS`) -> the Design fields of a stack of 1-4
    bonded layers, or one line saying what does not parse."""
    items = [i.strip() for i in stack.split(",") if i.strip()]
    where = repr(clip(stack))  # param "stack": the command prints --stack
    if not items:
        raise InputError(
            f"{where}: expected 1-4 layers MATERIAL:THICKNESS separated by commas, e.g. "
            "glass:0.55,adhesive:0.05,film:0.2",
            param="stack",
        )
    if len(items) > 4:
        raise InputError(f"{where}: {len(items)} layers; a stack has 1-4 layers", param="stack")
    out = {}
    for k, item in enumerate(items, 1):
        parts = item.split(":")
        if len(parts) < 2 or parts[0] not in MATERIALS:
            raise InputError(
                f"{where}: layer {k} {clip(item)!r}: expected MATERIAL:THICKNESS with MATERIAL one of "
                f"{', '.join(MATERIALS)}",
                param="stack",
            )
        material = dict(zip(("density", "modulus", "poisson"), MATERIALS[parts[0]]))
        thickness = parse_number(parts[1], f"{where}: layer {k} thickness", "stack")
        if thickness <= 0:
            raise InputError(f"{where}: layer {k} thickness must be > 0 mm, got {clip(parts[1])}", param="stack")
        for extra in parts[2:]:
            key, sep, raw = extra.partition("=")
            if not sep or key not in material:
                raise InputError(
                    f"{where}: layer {k} {clip(extra)!r}: expected density=, modulus= or poisson=", param="stack"
                )
            material[key] = parse_number(raw, f"{where}: layer {k} {key}", "stack")
        if k == 1:
            out.update(
                thickness=thickness,
                plate_density=material["density"],
                plate_modulus=material["modulus"],
                plate_poisson=material["poisson"],
            )
        else:
            out.update({f"layer{k}_thickness": thickness, **{f"layer{k}_{m}": v for m, v in material.items()}})
    for k in range(len(items) + 1, 5):
        out[f"layer{k}_thickness"] = 0.0
    return out
