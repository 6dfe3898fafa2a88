"""Each Impact Plate design parameter's unit and meaning, declared once: ``hcmt simulate``'s options
(``--thickness``), ``hcmt models``, the designs CSV's and ``--design``'s messages, the sweep's axis, the response
surface's file (``units``) and docs/cli.md read them here. Light (no numpy): the command's parsers read it before
torch loads."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Parameter:
    """One design parameter's ``unit`` (``-``: a ratio) and ``help``, the text of its option, where ``{unit}``
    stands for the unit (and ``{contact_radius}`` for :data:`hcmt.sim.params.CONTACT_RADIUS`)."""

    unit: str
    help: str = "{unit}"

    def describe(self, **values) -> str:
        """The help text, its unit (and ``values``) filled in."""
        return self.help.format(unit=self.unit, **values)


def _layer(k: int) -> dict[str, Parameter]:
    """A bonded layer under the top one: its thickness (0: none) and material."""
    thickness = (
        "{unit}, a bonded layer under the top one (0: none; default material the polymer film)" if k == 2 else "{unit}"
    )
    return {
        f"layer{k}_thickness": Parameter("mm", thickness),
        f"layer{k}_density": Parameter("g/mm^3"),
        f"layer{k}_modulus": Parameter("MPa"),
        f"layer{k}_poisson": Parameter("-"),
    }


#: every design parameter, in :class:`hcmt.sim.params.Design`'s order (tests/sim/test_design_parameters.py)
PARAMETERS: dict[str, Parameter] = {
    "thickness": Parameter("mm", "plate thickness ({unit})"),
    "drop_height": Parameter("mm", "drop height H ({unit}), v0 = sqrt(2 g H)"),
    "plate_density": Parameter("g/mm^3"),
    "plate_modulus": Parameter("MPa", "Young's modulus ({unit})"),
    "plate_poisson": Parameter("-"),
    "ball_radius": Parameter("mm"),
    "ball_density": Parameter("g/mm^3"),
    "ball_modulus": Parameter("MPa"),
    "ball_poisson": Parameter("-"),
    "mesh_size": Parameter("mm", "element size ({unit})"),
    "plate_half_length": Parameter("mm", "plate radius / half width ({unit})"),
    "gap": Parameter("mm", "initial gap ({unit}), < contact radius {contact_radius}"),
    **_layer(2),
    **_layer(3),
    **_layer(4),
    "support_radius": Parameter("mm", "{unit}, a simply supported ring under the panel, rim free (0: clamped rim)"),
    "backing_thickness": Parameter(
        "mm", "{unit}, a bonded soft backing under the panel, bottom fixed, rim free (0: none)"
    ),
    "backing_modulus": Parameter("MPa", "{unit}, the backing's Young's modulus"),
    "pen_tip_radius": Parameter("mm", "{unit}, a pen's hemispherical tip instead of the ball (0: the ball)"),
    "pen_mass": Parameter("g", "{unit}, the pen's rigid rod"),
}
#: the unit of each design parameter (meta.json's units: mm, g, MPa)
DESIGN_UNITS = {k: p.unit for k, p in PARAMETERS.items()}
