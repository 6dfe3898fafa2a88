"""The 3-D Deforming Plate scene (the public MeshGraphNets ``deforming_plate`` layout, generated): a plate of
compressible neo-Hookean tetrahedra clamped along ``x = 0`` (HANDLE) and pressed quasi-statically by a rigid
actuator (OBSTACLE: a sphere, a cylinder or a box, moving along a drawn path). Units mm, N, MPa.

Each frame is an equilibrium (:func:`hcmt.sim.quasistatic.advance`); ``stress`` is the nodal von Mises stress of
the plate (volume-averaged from its elements; 0 on the actuator). Design parameters, their units and ranges are
declared once, in :data:`hcmt.sim.plate_params.RANGES`.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass

import numpy as np

from hcmt.data.format import NodeType
from hcmt.sim.actuator import BOX_HEIGHT, make_shape, moved, path_offsets
from hcmt.sim.hyper import NeoHookean
from hcmt.sim.plate_params import GAP, TO_METRES, TO_PASCALS, PlateDesign, PlateSettings
from hcmt.sim.quasistatic import Contact, Newton, advance
from hcmt.sim.tet import box_tets, surface_nodes


def plate_grid(design: PlateDesign, settings: PlateSettings):
    """The plate's grid lines (xs, ys, zs): about ``plate_nodes`` nodes, square-ish in plane."""
    per_layer = settings.plate_nodes / (settings.layers + 1)
    nx = max(1, round(np.sqrt(per_layer * design.plate_length / design.plate_width)) - 1)
    ny = max(1, round(per_layer / (nx + 1)) - 1)
    return (
        np.linspace(0, design.plate_length, nx + 1),
        np.linspace(0, design.plate_width, ny + 1),
        np.linspace(-design.thickness, 0, settings.layers + 1),
    )


@dataclass
class PlateScene:
    body: NeoHookean
    shape: object  # the actuator at rest (hcmt.sim.actuator)
    contact_nodes: np.ndarray
    k: float
    delta: float
    actuator_pos: np.ndarray
    actuator_tets: np.ndarray
    handle: np.ndarray  # clamped plate nodes
    spacing: float


def build_scene(design: PlateDesign, settings: PlateSettings = PlateSettings()) -> PlateScene:
    design.validate()
    settings.validate()
    xs, ys, zs = plate_grid(design, settings)
    pos, tets = box_tets(xs, ys, zs)
    handle = np.flatnonzero(pos[:, 0] == 0.0)
    body = NeoHookean(pos, tets, design.modulus, design.poisson, fixed=(3 * handle[:, None] + np.arange(3)).ravel())
    size = design.actuator_size
    lift = size if design.shape != "box" else BOX_HEIGHT * size  # the actuator's bottom GAP x t above the plate
    center = (
        design.actuator_x * design.plate_length,
        design.actuator_y * design.plate_width,
        lift + GAP * design.thickness,
    )
    shape = make_shape(design.shape, center, size, 1.2 * design.plate_width)
    apos, atets = shape.mesh(settings.actuator_cells)
    h = float(np.mean([xs[1] - xs[0], ys[1] - ys[0]]))
    return PlateScene(
        body,
        shape,
        surface_nodes(tets),
        settings.penalty * design.modulus * h,
        settings.reach * h,
        apos,
        atets,
        handle,
        h,
    )


def actuator_offsets(design: PlateDesign, frames: int) -> np.ndarray:
    """The actuator's offset at each frame [T,3]: it touches after the first frames' gap, then presses."""
    travel = (design.depth + GAP) * design.thickness
    return path_offsets(design.path, np.linspace(0.0, 1.0, frames), travel, design.slide * design.plate_length)


def _step_load(scene: PlateScene, settings: PlateSettings, start: np.ndarray, end: np.ndarray):
    """The load of one step for :func:`hcmt.sim.quasistatic.advance`: at ``s``, the actuator at
    ``start + s (end - start)`` (the clamp holds its own values)."""

    def load(s: float, x: np.ndarray) -> list[Contact]:
        shape = moved(scene.shape, start + s * (end - start))
        return [Contact(shape, scene.contact_nodes, scene.k, scene.delta, settings.curved)]

    return load


def solve_plate(design: PlateDesign, settings: PlateSettings = PlateSettings(), progress=None) -> dict:
    """Every frame's equilibrium: positions [T,N,3] of the plate, nodal von Mises [T,N], Newton iterations and
    substeps per step [T-1], residual histories, support reaction and actuator force [T,3]."""
    scene = build_scene(design, settings)
    body, offsets = scene.body, actuator_offsets(design, settings.frames)
    newton = Newton(rtol=settings.rtol)
    x = body.pos.copy()
    T = settings.frames
    world, vm = np.zeros((T, len(x), 3)), np.zeros((T, len(x)))
    world[0] = x
    its, subs, histories = np.zeros(T - 1, np.int32), np.zeros(T - 1, np.int32), []
    reaction, force = np.zeros((T, 3)), np.zeros((T, 3))
    for t in range(1, T):
        contact = _step_load(scene, settings, offsets[t - 1], offsets[t])
        x, log = advance(body, x, contact, newton, predictor=world[t - 1] - world[max(t - 2, 0)])
        its[t - 1], subs[t - 1] = log.iterations, log.substeps
        histories.append(log.residuals)
        world[t], vm[t] = x, body.nodal_von_mises(x)
        reaction[t] = body.forces(x)[scene.handle].sum(0)
        force[t] = contact(1.0, x)[0].force_on_obstacle(x)
        if progress is not None:
            progress(t)
    return dict(
        scene=scene,
        world=world,
        von_mises=vm,
        iterations=its,
        substeps=subs,
        residuals=histories,
        reaction=reaction,
        actuator_force=force,
        offsets=offsets,
    )


def simulate_plate(design: PlateDesign, settings: PlateSettings = PlateSettings(), progress=None) -> dict:
    """One trajectory in the dataset's layout: ``fields`` (mesh_pos, cells, node_type, world_pos in m, stress in Pa),
    ``attrs`` (the design; Newton's iterations and substeps per step and the actuator's force [T,3] in N, as JSON
    lists) and ``info`` (wall time)."""
    start = time.perf_counter()
    r = solve_plate(design, settings, progress)
    scene = r["scene"]
    n_plate, apos = len(scene.body.pos), scene.actuator_pos
    mesh_pos = np.concatenate([scene.body.pos, apos])
    node_type = np.zeros((len(mesh_pos), 1), np.int32)
    node_type[scene.handle] = NodeType.HANDLE
    node_type[n_plate:] = NodeType.OBSTACLE
    actuator = apos[None] + r["offsets"][:, None, :]
    fields = {
        "mesh_pos": (mesh_pos * TO_METRES).astype(np.float32),
        "cells": np.concatenate([scene.body.tets, scene.actuator_tets + n_plate]).astype(np.int32),
        "node_type": node_type,
        "world_pos": (np.concatenate([r["world"], actuator], 1) * TO_METRES).astype(np.float32),
        "stress": (
            np.concatenate([r["von_mises"], np.zeros((settings.frames, len(apos)))], 1)[..., None] * TO_PASCALS
        ).astype(np.float32),
    }
    # per-step records as JSON text: the dataset's attributes are scalars (hcmt.data.format.Split.attrs)
    attrs = {
        **asdict(design),
        "newton_iterations": json.dumps(r["iterations"].tolist()),
        "substeps": json.dumps(r["substeps"].tolist()),
        "actuator_force": json.dumps(np.round(r["actuator_force"], 9).tolist()),
        "newton_iterations_max": int(r["iterations"].max(initial=0)),
    }
    wall = time.perf_counter() - start
    return dict(
        fields=fields,
        attrs=attrs,
        info=dict(wall_time=wall, num_nodes=len(mesh_pos), iterations=int(r["iterations"].sum())),
    )


def feature_spec(frames: int) -> dict:
    """meta.json's features: the public deforming_plate fields (static fields without their leading 1)."""
    return {
        "mesh_pos": {"type": "static", "shape": [-1, 3], "dtype": "float32"},
        "cells": {"type": "static", "shape": [-1, 4], "dtype": "int32"},
        "node_type": {"type": "static", "shape": [-1, 1], "dtype": "int32"},
        "world_pos": {"type": "dynamic", "shape": [frames, -1, 3], "dtype": "float32"},
        "stress": {"type": "dynamic", "shape": [frames, -1, 1], "dtype": "float32"},
    }
