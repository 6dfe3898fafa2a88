"""The Deforming Plate's design schema (light: numpy only, for the command's parsers): design parameters with
their units and ranges (declared once, :data:`RANGES`), solver settings, sampling. The scene is
:mod:`hcmt.sim.deforming`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hcmt.errors import InputError

SHAPES = ("sphere", "cylinder", "box")
PATHS = ("press", "oblique", "press_slide")

#: the solver's units (the design parameters, the trajectories' attributes) are mm, N, MPa; the dataset's fields are
#: SI, as the public deforming_plate (its configs' contact radius 0.03 and noise 0.003 are metres)
UNITS = {"length": "m", "stress": "Pa", "design": "mm, N, MPa (the trajectories' attributes)"}
TO_METRES, TO_PASCALS = 1e-3, 1e6
#: the actuator starts GAP x thickness above the plate
GAP = 0.05

#: design parameter: (low, high, unit); "x plate_length" etc. are fractions of that parameter
RANGES: dict[str, tuple[float, float, str]] = {
    "plate_length": (80.0, 120.0, "mm"),
    "plate_width": (40.0, 70.0, "mm"),
    "thickness": (3.0, 8.0, "mm"),
    "modulus": (5.0, 50.0, "MPa"),
    "poisson": (0.25, 0.45, "-"),
    "actuator_size": (6.0, 14.0, "mm"),  # radius (sphere, cylinder) or half edge (box)
    "actuator_x": (0.45, 0.9, "x plate_length"),
    "actuator_y": (0.3, 0.7, "x plate_width"),
    "depth": (1.0, 4.0, "x thickness"),  # travel down after touching
    "slide": (-0.15, 0.15, "x plate_length"),  # travel along x (paths oblique, press_slide)
}


@dataclass(frozen=True)
class PlateDesign:
    """One Deforming Plate trajectory's design (its attributes in the dataset)."""

    plate_length: float = 100.0
    plate_width: float = 55.0
    thickness: float = 5.0
    modulus: float = 20.0
    poisson: float = 0.35
    actuator_size: float = 10.0
    actuator_x: float = 0.7
    actuator_y: float = 0.5
    depth: float = 2.5
    slide: float = 0.0
    shape: str = "sphere"
    path: str = "press"

    def validate(self) -> None:
        for k, (lo, hi, _) in RANGES.items():
            v = getattr(self, k)
            if not np.isfinite(v) or (
                k in ("plate_length", "plate_width", "thickness", "modulus", "actuator_size") and v <= 0
            ):
                raise InputError(f"must be positive and finite, got {v}", param=k)
        if self.shape not in SHAPES or self.path not in PATHS:
            raise InputError(
                f"shape must be one of {SHAPES} and path one of {PATHS}, got {self.shape}, {self.path}", param="shape"
            )


@dataclass(frozen=True)
class PlateSettings:
    """Solver settings: frames (load steps + 1), plate nodes aimed at, element layers through the thickness,
    actuator mesh cells per edge, contact penalty factor (``k = penalty E h``, ``h`` the in-plane spacing) and reach
    (``delta = reach h``: :class:`hcmt.sim.quasistatic.Contact`), Newton's relative tolerance."""

    frames: int = 400
    plate_nodes: int = 1100
    layers: int = 3
    actuator_cells: int = 4
    penalty: float = 5.0
    reach: float = 0.05
    rtol: float = 1e-6
    curved: bool = True

    def validate(self) -> None:
        if self.frames < 2:
            raise InputError(f"must be >= 2, got {self.frames}", param="frames")
        if not 8 <= self.plate_nodes <= 200_000 or self.layers < 1 or self.actuator_cells < 1:
            raise InputError(
                f"plate_nodes 8 to 200,000, layers and actuator_cells >= 1, got {self.plate_nodes}, "
                f"{self.layers}, {self.actuator_cells}",
                param="plate_nodes",
            )


def sample_plate_design(rng: np.random.Generator) -> PlateDesign:
    values = {k: float(rng.uniform(lo, hi)) for k, (lo, hi, _) in RANGES.items()}
    return PlateDesign(**values, shape=str(rng.choice(SHAPES)), path=str(rng.choice(PATHS)))
