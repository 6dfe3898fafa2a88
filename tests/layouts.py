"""Small files in the official layouts of the public datasets, with real (if tiny) geometry, for tests."""

from __future__ import annotations

import json
import pickle

import numpy as np
from tfrecord.writer import TFRecordWriter

from hcmt.data.format import NodeType, make_meta, write_meta, write_split


def write_tf_dataset(folder, meta, split_records):
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "meta.json").write_text(json.dumps(meta))
    for split, records in split_records.items():
        w = TFRecordWriter(str(folder / f"{split}.tfrecord"))
        for rec in records:
            w.write({k: ([np.ascontiguousarray(v).tobytes()], "byte") for k, v in rec.items()})
        w.close()


def grid_triangles(nx, ny, x0=0.0, y0=0.0, dx=1.0, dy=1.0):
    """Structured triangle mesh of (nx+1) x (ny+1) nodes: positions [N,2], triangles [C,3] (counter-clockwise)."""
    xs, ys = np.meshgrid(x0 + dx * np.arange(nx + 1), y0 + dy * np.arange(ny + 1), indexing="xy")
    pos = np.stack([xs.ravel(), ys.ravel()], 1)
    i = np.arange(nx)[None, :] + (nx + 1) * np.arange(ny)[:, None]
    a, b, c, d = i, i + 1, i + nx + 1, i + nx + 2
    tris = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    return pos, tris


def box_tetrahedra(nx, ny, nz, origin=(0, 0, 0), h=1.0):
    """Structured tetrahedral box: each hexahedron split into 6 tetrahedra (Kuhn)."""
    g = np.stack(np.meshgrid(*(np.arange(n + 1) for n in (nx, ny, nz)), indexing="ij"), -1).reshape(-1, 3)
    pos = g * h + np.asarray(origin, float)

    def idx(x, y, z):
        return (x * (ny + 1) + y) * (nz + 1) + z

    cx, cy, cz = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
    cx, cy, cz = cx.ravel(), cy.ravel(), cz.ravel()
    v = [idx(cx + (k >> 0 & 1), cy + (k >> 1 & 1), cz + (k >> 2 & 1)) for k in range(8)]
    paths = [(1, 3), (1, 5), (2, 3), (2, 6), (4, 5), (4, 6)]
    tets = np.concatenate([np.stack([v[0], v[a], v[b], v[7]], 1) for a, b in paths])
    return pos, tets


def impact_like(n_traj=2, steps=6, seed=0):
    """Native Impact-Plate-like trajectories: a clamped plate and a ball-ish block moving down onto it."""
    rng = np.random.default_rng(seed)
    plate, ptri = grid_triangles(10, 2, dx=0.5, dy=0.25)
    ball, btri = grid_triangles(3, 3, dx=0.25, dy=0.25, y0=0.6)
    pos = np.concatenate([plate, ball]).astype(np.float32)
    cells = np.concatenate([ptri, btri + len(plate)]).astype(np.int32)
    n = len(pos)
    nt = np.zeros((n, 1), np.int32)
    nt[len(plate) :] = NodeType.OBSTACLE
    nt[np.isclose(pos[:, 0], 0)] = NodeType.SYMMETRIC
    nt[: len(plate)][np.isclose(plate[:, 0], 5.0)] = NodeType.HANDLE
    trajs = []
    for k in range(n_traj):
        world = np.repeat(pos[None], steps, 0).copy()
        v = 0.05 + 0.02 * k
        world[:, len(plate) :, 1] -= v * np.arange(steps)[:, None]
        bend = 0.01 * np.maximum(np.arange(steps) - 2, 0)[:, None] * np.cos(plate[:, 0] / 10 * np.pi / 2)[None]
        world[:, : len(plate), 1] -= bend
        stress = np.abs(rng.normal(size=(steps, n, 1))).astype(np.float32) * 10
        fields = {
            "mesh_pos": pos,
            "cells": cells,
            "node_type": nt,
            "world_pos": world.astype(np.float32),
            "stress": stress,
            "density": np.full((n, 1), 2.5e-3, np.float32),
            "modulus": np.full((n, 1), 7e4 + 1e3 * k, np.float32),
        }
        trajs.append(fields)
    return trajs


def write_impact_like(folder, n_train=2, n_valid=1, n_test=1, steps=6):
    feats = {
        "mesh_pos": {"type": "static", "shape": [-1, 2], "dtype": "float32"},
        "cells": {"type": "static", "shape": [-1, 3], "dtype": "int32"},
        "node_type": {"type": "static", "shape": [-1, 1], "dtype": "int32"},
        "density": {"type": "static", "shape": [-1, 1], "dtype": "float32"},
        "modulus": {"type": "static", "shape": [-1, 1], "dtype": "float32"},
        "world_pos": {"type": "dynamic", "shape": [steps, -1, 2], "dtype": "float32"},
        "stress": {"type": "dynamic", "shape": [steps, -1, 1], "dtype": "float32"},
    }
    meta = make_meta(feats, trajectory_length=steps, dimension=2, dt=0.002, units={"length": "mm"})
    folder.mkdir(parents=True, exist_ok=True)
    for split, count, seed in (("train", n_train, 0), ("valid", n_valid, 1), ("test", n_test, 2)):
        trajs = impact_like(count, steps, seed)
        write_split(
            folder / f"{split}.h5", meta, ((f"traj_{i:05d}", t, {"thickness": 0.5}) for i, t in enumerate(trajs))
        )
    write_meta(folder, meta)
    return folder


def deforming_plate_tfrecord(folder, steps=4, n=2):
    """deforming_plate layout: a tetrahedral plate (HANDLE at one end) pushed by a tetrahedral obstacle."""
    plate, ptet = box_tetrahedra(6, 2, 1, h=0.1)
    obst, otet = box_tetrahedra(1, 1, 1, origin=(0.25, 0.05, 0.11), h=0.05)
    pos = np.concatenate([plate, obst]).astype(np.float32)
    cells = np.concatenate([ptet, otet + len(plate)]).astype(np.int32)
    nt = np.zeros(len(pos), np.int32)
    nt[len(plate) :] = NodeType.OBSTACLE
    nt[: len(plate)][np.isclose(plate[:, 0], 0)] = NodeType.HANDLE
    meta = {
        "simulator": "comsol",
        "dt": 0.0,
        "collision_radius": 0.03,
        "trajectory_length": steps,
        "field_names": ["cells", "node_type", "mesh_pos", "world_pos", "stress"],
        "features": {
            "cells": {"type": "static", "shape": [1, -1, 4], "dtype": "int32"},
            "node_type": {"type": "static", "shape": [1, -1, 1], "dtype": "int32"},
            "mesh_pos": {"type": "static", "shape": [1, -1, 3], "dtype": "float32"},
            "world_pos": {"type": "dynamic", "shape": [steps, -1, 3], "dtype": "float32"},
            "stress": {"type": "dynamic", "shape": [steps, -1, 1], "dtype": "float32"},
        },
    }
    recs = []
    for k in range(n):
        world = np.repeat(pos[None], steps, 0).copy()
        world[:, len(plate) :, 2] -= 0.005 * (k + 1) * np.arange(steps)[:, None]
        recs.append(
            {
                "cells": cells[None],
                "node_type": nt.reshape(1, -1, 1),
                "mesh_pos": pos[None],
                "world_pos": world.astype(np.float32),
                "stress": np.random.rand(steps, len(pos), 1).astype(np.float32),
            }
        )
    write_tf_dataset(folder, meta, {"train": recs, "valid": recs[:1], "test": recs[:1]})


def sphere_simple_tfrecord(folder, steps=4, n=2):
    """sphere_simple layout: a cloth (2-D mesh space, 3-D world) with two HANDLE corners, falling."""
    cloth, tri = grid_triangles(5, 5, dx=0.1, dy=0.1)
    nt = np.zeros(len(cloth), np.int32)
    nt[[0, 5]] = NodeType.HANDLE
    meta = {
        "simulator": "arcsim",
        "dt": 0.01,
        "collision_radius": 0.05,
        "trajectory_length": steps,
        "field_names": ["cells", "mesh_pos", "node_type", "world_pos"],
        "features": {
            "cells": {"type": "static", "shape": [1, -1, 3], "dtype": "int32"},
            "mesh_pos": {"type": "static", "shape": [1, -1, 2], "dtype": "float32"},
            "node_type": {"type": "static", "shape": [1, -1, 1], "dtype": "int32"},
            "world_pos": {"type": "dynamic", "shape": [steps, -1, 3], "dtype": "float32"},
        },
    }
    recs = []
    for k in range(n):
        w0 = np.concatenate([cloth, np.zeros((len(cloth), 1))], 1)
        world = np.repeat(w0[None], steps, 0)
        drop = 0.01 * (k + 1) * np.arange(steps)[:, None] ** 2 * (nt == 0)[None]
        world[:, :, 2] -= drop
        recs.append(
            {
                "cells": tri.astype(np.int32)[None],
                "mesh_pos": cloth.astype(np.float32)[None],
                "node_type": nt.reshape(1, -1, 1),
                "world_pos": world.astype(np.float32),
            }
        )
    write_tf_dataset(folder, meta, {"train": recs, "valid": recs[:1], "test": recs[:1]})


def ggns_pickles(folder, steps=4, n=2):
    """Deformable Plate (GGNS) layout: a triangle plate pushed by a triangle collider."""
    folder.mkdir(parents=True, exist_ok=True)
    plate, ptri = grid_triangles(6, 3, dx=0.1, dy=0.1)
    coll, ctri = grid_triangles(1, 1, dx=0.1, dy=0.1, x0=0.25, y0=0.32)
    trajs = []
    for k in range(n):
        grid = np.repeat(plate[None], steps, 0).copy()
        grid[:, :, 1] -= 0.002 * np.arange(steps)[:, None] * np.exp(-((plate[:, 0] - 0.3) ** 2) / 0.02)[None]
        collider = np.repeat(coll[None], steps, 0).copy()
        collider[:, :, 1] -= 0.003 * np.arange(steps)[:, None]
        trajs.append(
            {
                "nodes_grid": grid,
                "edge_index_grid": np.zeros((2, 0), int),
                "triangles_grid": ptri,
                "nodes_collider": collider,
                "triangles_collider": ctri,
                "poisson_ratio": 0.3 + 0.1 * k,
                "pcd_points": np.zeros((3, 2)),
            }
        )
    for split in ("train", "valid", "test"):
        with open(folder / f"{split}.pkl", "wb") as f:
            pickle.dump(trajs, f)
