"""The Impact Plate scene: a design (:mod:`hcmt.sim.params`) assembled into its mesh, cell materials, boundary
conditions, finite-element model and the native-format static fields; the solve is :mod:`hcmt.sim.driver`.

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

import numpy as np

from hcmt.sim.families import features
from hcmt.sim.mesh import HANDLE, SYMMETRIC, WALL_BOUNDARY, impact_plate_mesh
from hcmt.sim.params import Design, Settings
from hcmt.sim.solver import build_model


def design_mesh(design: Design) -> dict[str, np.ndarray]:
    """The design's mesh: the first scene's lengths, the panel's layers, and each family feature's own arguments
    of :func:`~hcmt.sim.mesh.impact_plate_mesh` (:meth:`hcmt.sim.families.Feature.mesh`: a ring's radius, a
    backing's thickness, the pen)."""
    extra = {k: v for f in features(design) for k, v in f.mesh(design).items()}
    return impact_plate_mesh(
        design.thickness,
        design.impactor_radius,
        design.mesh_size,
        plate_half_length=design.plate_half_length,
        gap=design.gap,
        layers=[layer[0] for layer in design.layers],
        **extra,
    )


def cell_materials(design: Design, mesh: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(density, modulus, Poisson) per cell [C] from the mesh's ``cell_layer``: the panel's layers, the backing
    (last), the impactor (-1: the ball_* material)."""
    under = [layer for f in features(design) for layer in f.under(design)]  # a backing's (Feature.under)
    table = np.array(
        [layer[1:] for layer in [*design.layers, *under]]
        + [(design.ball_density, design.ball_modulus, design.ball_poisson)]
    )
    m = table[mesh["cell_layer"]]  # -1 picks the impactor's row
    return m[:, 0], m[:, 1], m[:, 2]


def fem_model(design: Design, settings: Settings, mesh: dict):
    """The finite-element model of a design's mesh (:func:`hcmt.sim.solver.build_model`, its cells' materials
    from :func:`cell_materials`)."""
    return build_model(
        mesh["mesh_pos"],
        mesh["cells"],
        *cell_materials(design, mesh),
        formulation=settings.formulation,
        bulk_viscosity=settings.bulk_viscosity,
    )


def fixed_dofs(node_type: np.ndarray) -> np.ndarray:
    """[N, 2] bool: the degrees of freedom a boundary condition holds: SYMMETRIC x (the axis), HANDLE x and y
    (clamped), WALL_BOUNDARY y (a roller: the simply supported ring)."""
    fixed = np.zeros((len(node_type), 2), dtype=bool)
    fixed[node_type == SYMMETRIC, 0] = True
    fixed[node_type == HANDLE] = True
    fixed[node_type == WALL_BOUNDARY, 1] = True
    return fixed


def static_fields(design: Design, mesh: dict, formulation: str = "axisymmetric") -> dict[str, np.ndarray]:
    """The native-format static fields of a design's mesh: mesh_pos, cells, node_type, density, modulus.

    A node's density and modulus are those of the softest cell it belongs to, so that a soft layer one element
    thick is seen at both its faces. A family feature may change the density then (:meth:`Feature.scene
    <hcmt.sim.families.Feature.scene>`: the pen's nodes carry the whole pen's mass over the tip's volume)."""
    rho_c, E_c, _ = cell_materials(design, mesh)
    cells = mesh["cells"]
    rank = np.lexsort((rho_c, E_c))  # cells from softest to stiffest
    order = np.empty(len(rank), np.int64)
    order[rank] = np.arange(len(rank))
    node_rank = np.full(len(mesh["mesh_pos"]), len(rank), np.int64)
    np.minimum.at(node_rank, cells.ravel(), np.repeat(order, 3))
    softest = rank[node_rank]
    density, modulus = rho_c[softest], E_c[softest]
    for f in features(design):
        density = f.scene(design, mesh, density, formulation)
    return dict(
        mesh_pos=mesh["mesh_pos"].astype(np.float32),
        cells=cells.astype(np.int32),
        node_type=mesh["node_type"].astype(np.int32)[:, None],
        density=density.astype(np.float32)[:, None],
        modulus=modulus.astype(np.float32)[:, None],
    )


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
        **(
            {"stress_max": {"type": "dynamic", "shape": [T, -1, 1], "dtype": "float32"}} if settings.peak_stress else {}
        ),
    }
