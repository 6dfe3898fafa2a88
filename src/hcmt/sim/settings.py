"""The solver and recording settings a whole dataset shares (:class:`Settings`, meta.json's ``generator``), the
formulations and gravity: part of the design schema (:mod:`hcmt.sim.params` reads them from here). Light."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from hcmt.errors import InputError, clip
from hcmt.sim.values import a_type, is_number

#: the solver's formulations (:func:`hcmt.sim.solver.build_model`)
FORMULATIONS = ("axisymmetric", "plane_strain")


GRAVITY = 9.81e-3  # mm/ms^2


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
        for name, ok, expected in (
            ("formulation", self.formulation in FORMULATIONS, f"one of {FORMULATIONS}"),
            ("frames", self.frames >= 2, ">= 2"),
            ("frame_dt", self.frame_dt > 0, "> 0 ms"),
            ("safety", 0 < self.safety <= 0.8, "in (0, 0.8]"),
            ("bulk_viscosity", self.bulk_viscosity >= 0, ">= 0"),
            ("penalty", 0 < self.penalty <= 0.5, "in (0, 0.5]"),
        ):
            if not ok:  # param: the command names its flag (--frames)
                raise InputError(f"must be {expected}, got {getattr(self, name)!r}", param=name)
        return self
