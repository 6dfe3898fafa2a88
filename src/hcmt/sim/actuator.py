"""The Deforming Plate's rigid actuators: a sphere, a cylinder (axis along y) and a box, each with its exact signed
distance (for the contact, :class:`hcmt.sim.quasistatic.Contact`) and a tetrahedral mesh whose nodes are the
dataset's OBSTACLE nodes; and the paths they follow."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hcmt.sim.plate_params import PATHS, SHAPES
from hcmt.sim.tet import ball_tets, block_tets, cylinder_tets

#: the box's half height and edge rounding, as fractions of its half edge (the actuator's size)
BOX_HEIGHT, BOX_ROUND = 0.6, 0.25


@dataclass(frozen=True)
class Sphere:
    center: np.ndarray
    radius: float

    def distance(self, p):
        v = p - self.center
        r = np.maximum(np.linalg.norm(v, axis=1), 1e-12)
        n = v / r[:, None]
        return r - self.radius, n, (np.eye(3) - np.einsum("ni,nj->nij", n, n)) / r[:, None, None]

    def mesh(self, n: int):
        return ball_tets(self.center, self.radius, n)


@dataclass(frozen=True)
class Cylinder:
    """Infinite along y (its mesh is longer than the plate is wide, so the two agree where the plate is)."""

    center: np.ndarray
    radius: float
    length: float

    def distance(self, p):
        v = (p - self.center) * np.array([1.0, 0.0, 1.0])
        r = np.maximum(np.linalg.norm(v, axis=1), 1e-12)
        n = v / r[:, None]
        axis = np.diag([1.0, 0.0, 1.0])
        return r - self.radius, n, (axis - np.einsum("ni,nj->nij", n, n)) / r[:, None, None]

    def mesh(self, n: int):
        return cylinder_tets(self.center, self.radius, self.length, n)


@dataclass(frozen=True)
class Box:
    """A box with edges and corners rounded by ``round`` (its signed distance is then smooth outside the inner box
    and near the surface): half edges ``half``."""

    center: np.ndarray
    half: np.ndarray
    round: float

    def distance(self, p):
        rel = p - self.center
        q = np.abs(rel) - (self.half - self.round)
        v = np.maximum(q, 0.0)
        out = np.linalg.norm(v, axis=1)
        inner = out <= 1e-12  # inside the inner box: the nearest face's normal
        rows, axis = np.arange(len(p)), np.argmax(q, axis=1)
        n = np.where(inner[:, None], 0.0, np.sign(rel) * v / np.maximum(out, 1e-12)[:, None])
        n[rows[inner], axis[inner]] = np.sign(rel[rows[inner], axis[inner]])
        proj = np.einsum("ni,ij->nij", (v > 0).astype(float), np.eye(3))
        dn = (proj - np.einsum("ni,nj->nij", n, n)) / np.maximum(out, 1e-12)[:, None, None]
        d = np.where(inner, q.max(1), out) - self.round
        return d, n, np.where(inner[:, None, None], 0.0, dn)

    def mesh(self, n: int):
        return block_tets(self.center, self.half, n)


def make_shape(shape: str, center, size: float, span: float):
    """A shape of characteristic ``size`` (radius, half edge) at ``center``; ``span``: the cylinder's length."""
    center = np.asarray(center, float)
    if shape == "sphere":
        return Sphere(center, size)
    if shape == "cylinder":
        return Cylinder(center, size, span)
    if shape == "box":
        return Box(center, np.array([size, size, BOX_HEIGHT * size]), BOX_ROUND * size)
    raise ValueError(f"unknown actuator shape {shape!r}; expected one of {SHAPES}")


def moved(shape, offset):
    """The shape translated by ``offset`` [3]."""
    return type(shape)(**{**shape.__dict__, "center": shape.center + np.asarray(offset, float)})


def path_offsets(path: str, s: np.ndarray, depth: float, slide: float) -> np.ndarray:
    """Offsets [len(s),3] of the actuator at load parameters ``s`` in [0, 1]: ``press`` straight down by
    ``depth``; ``oblique`` down by ``depth`` while moving ``slide`` along x; ``press_slide`` down in the first
    half, then along x by ``slide``."""
    s = np.asarray(s, float)
    zero = np.zeros_like(s)
    if path == "press":
        return np.stack([zero, zero, -depth * s], 1)
    if path == "oblique":
        return np.stack([slide * s, zero, -depth * s], 1)
    if path == "press_slide":
        down, along = np.minimum(2 * s, 1.0), np.maximum(2 * s - 1, 0.0)
        return np.stack([slide * along, zero, -depth * down], 1)
    raise ValueError(f"unknown actuator path {path!r}; expected one of {PATHS}")
