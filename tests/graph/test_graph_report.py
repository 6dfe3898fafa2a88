"""`hcmt hierarchy DATASET --levels L --json FILE` on a small native dataset."""

import json

import numpy as np

from graph_meshes import plate_and_ball
from hcmt.cli import main
from hcmt.data.format import make_meta, write_meta, write_split
from hcmt.graph.hierarchy import build_hierarchy
from hcmt.graph.report import KEYS, level_quality


def make_dataset(path, sizes=(0.1, 0.12)):
    meta = make_meta(
        {
            "mesh_pos": {"type": "static", "shape": [-1, 2], "dtype": "float32"},
            "cells": {"type": "static", "shape": [-1, 3], "dtype": "int32"},
            "node_type": {"type": "static", "shape": [-1, 1], "dtype": "int32"},
            "world_pos": {"type": "dynamic", "shape": [2, -1, 2], "dtype": "float32"},
        },
        trajectory_length=2,
        dimension=2,
        dt=1.0,
    )
    write_meta(path, meta)
    meshes = [plate_and_ball(h=h, length=3.0, radius=0.8) for h in sizes]
    trajs = [
        (
            f"traj_{i:05d}",
            {
                "mesh_pos": m["mesh_pos"].astype(np.float32),
                "cells": m["cells"].astype(np.int32),
                "node_type": m["node_type"][:, None].astype(np.int32),
                "world_pos": np.stack([m["mesh_pos"]] * 2).astype(np.float32),
            },
            {},
        )
        for i, m in enumerate(meshes)
    ]
    write_split(path / "train.h5", meta, trajs)
    return meshes


def test_hierarchy_command_writes_the_table_as_json(tmp_path, capsys):
    meshes = make_dataset(tmp_path / "ds")
    out = tmp_path / "q.json"
    assert main(["hierarchy", str(tmp_path / "ds"), "--levels", "3", "--json", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "jacobian" in printed and "1..3" in printed
    rows = json.loads(out.read_text())
    assert [r["level"] for r in rows] == [0, 1, 2, 3]
    assert all(set(r) == set(KEYS) for r in rows)
    # the averages are those of the two trajectories' own hierarchies
    per = [
        level_quality(
            build_hierarchy(m["mesh_pos"].astype(np.float32), m["cells"], m["node_type"], 3),
            m["mesh_pos"].astype(np.float32),
        )
        for m in meshes
    ]
    for level in range(4):
        assert rows[level]["nodes"] == np.mean([p[level]["nodes"] for p in per])
        assert np.isclose(rows[level]["jacobian_after"], np.mean([p[level]["jacobian_after"] for p in per]))
    assert rows[0]["jacobian_before"] == rows[0]["jacobian_after"]  # level 0 is not remeshed
    assert np.mean([r["jacobian_after"] for r in rows[1:]]) > np.mean([r["jacobian_before"] for r in rows[1:]])
    assert all(a["nodes"] > b["nodes"] for a, b in zip(rows, rows[1:]))
    # the hierarchies were cached beside the dataset
    assert len(list((tmp_path / "ds" / ".cache" / "hierarchy").glob("*.npy"))) == 2


def test_hierarchy_command_reports_bad_input(tmp_path, capsys):
    make_dataset(tmp_path / "ds", sizes=(0.1,))
    assert main(["hierarchy", str(tmp_path / "ds"), "--levels", "-1"]) == 2  # out of its bounds: argparse's line
    assert "argument --levels: expected a whole number from 0 to 64" in capsys.readouterr().err
    assert main(["hierarchy", str(tmp_path / "missing"), "--levels", "2"]) == 2
    capsys.readouterr()
    assert main(["hierarchy", str(tmp_path / "ds"), "--levels", "40"]) == 2  # more levels than the mesh has
    err = capsys.readouterr().err
    assert "traj_00000" in err and "more than this mesh can be pooled" in err
