"""Readers for the published datasets, on small files written in the exact official layouts."""

import pickle

import numpy as np
import pytest

from hcmt.cli import main as cli
from hcmt.data.format import NodeType, open_split, read_meta
from hcmt.data.tfrecord import iter_tfrecord
from hcmt.errors import DatasetError
from layouts import sphere_simple_tfrecord, write_tf_dataset


def deforming_plate(folder, steps=3, trajectories=2):
    """deforming_plate layout: tetrahedra, 3-D, static with a leading 1, stress dynamic."""
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
    rng = np.random.default_rng(0)
    records = []
    for t in range(trajectories):
        n = 8 + t
        pos = rng.random((1, n, 3)).astype(np.float32)
        records.append(
            {
                "cells": np.array([[[0, 1, 2, 3], [4, 5, 6, 7]]], np.int32),
                "node_type": np.where(np.arange(n) < 4, 1, 0).astype(np.int32).reshape(1, n, 1),
                "mesh_pos": pos,
                "world_pos": np.repeat(pos, steps, 0) + 0.01 * rng.random((steps, n, 3)).astype(np.float32),
                "stress": rng.random((steps, n, 1)).astype(np.float32),
            }
        )
    write_tf_dataset(folder, meta, {"train": records, "valid": records[:1]})
    return meta, records


def test_deforming_plate_tfrecord_reads_and_converts(tmp_path, capsys):
    meta, records = deforming_plate(tmp_path / "src")
    got = list(iter_tfrecord(tmp_path / "src", "train"))
    assert len(got) == 2
    assert got[1]["mesh_pos"].shape == (9, 3) and got[1]["cells"].shape == (2, 4)
    np.testing.assert_array_equal(got[1]["world_pos"], records[1]["world_pos"])
    assert cli(["convert", str(tmp_path / "src"), str(tmp_path / "out")]) == 0
    assert "split train: 2 trajectories" in capsys.readouterr().out
    native = read_meta(tmp_path / "out")
    assert native["features"]["cells"]["shape"] == [-1, 4] and native["dimension"] == 3
    assert native["collision_radius"] == 0.03
    with open_split(tmp_path / "out", "train") as s:
        np.testing.assert_array_equal(s[0]["stress"], records[0]["stress"])
        np.testing.assert_array_equal(s[1]["node_type"], records[1]["node_type"][0])


def test_sphere_simple_cloth_layout_2d_mesh_space_3d_world(tmp_path):
    sphere_simple_tfrecord(tmp_path / "src", steps=4)
    assert cli(["convert", str(tmp_path / "src"), str(tmp_path / "out")]) == 0
    with open_split(tmp_path / "out", "test") as s:
        t = s[0]
    assert t["mesh_pos"].shape == (36, 2) and t["world_pos"].shape == (4, 36, 3)
    assert read_meta(tmp_path / "out")["dimension"] == 3


def test_hcmt_impact_plate_static_varlen_row_splits(tmp_path):
    """The official HCMT Impact Plate layout: a static_varlen field cut by its length_<name> row splits."""
    steps, n = 3, 6
    meta = {
        "trajectory_length": steps,
        "field_names": ["mesh_pos", "cells", "node_type", "world_pos", "stress", "m_ids", "length_m_ids"],
        "features": {
            "mesh_pos": {"type": "static", "shape": [1, -1, 2], "dtype": "float32"},
            "cells": {"type": "static", "shape": [1, -1, 3], "dtype": "int32"},
            "node_type": {"type": "static", "shape": [1, -1, 1], "dtype": "int32"},
            "world_pos": {"type": "dynamic", "shape": [steps, -1, 2], "dtype": "float32"},
            "stress": {"type": "dynamic", "shape": [steps, -1, 1], "dtype": "float32"},
            "m_ids": {"type": "static_varlen", "shape": [-1], "dtype": "int32"},
        },
    }
    rec = {
        "mesh_pos": np.random.rand(1, n, 2).astype(np.float32),
        "cells": np.array([[[0, 1, 2], [3, 4, 5]]], np.int32),
        "node_type": np.array([7, 0, 0, 7, 1, 1], np.int32).reshape(1, n, 1),
        "world_pos": np.random.rand(steps, n, 2).astype(np.float32),
        "stress": np.random.rand(steps, n, 1).astype(np.float32),
        "m_ids": np.array([0, 2, 4, 0, 2], np.int32),
        "length_m_ids": np.array([0, 3, 5], np.int32),
    }
    write_tf_dataset(tmp_path / "src", meta, {"train": [rec]})
    (traj,) = iter_tfrecord(tmp_path / "src", "train")
    assert [r.tolist() for r in traj["m_ids"]] == [[0, 2, 4], [0, 2]]
    assert traj["node_type"].shape == (n, 1)
    assert cli(["convert", str(tmp_path / "src"), str(tmp_path / "out")]) == 0
    native = read_meta(tmp_path / "out")
    assert "m_ids" not in native["features"] and native["generator"]["skipped_fields"] == ["m_ids"]


def test_truncated_tfrecord_named_and_no_output_left(tmp_path, capsys):
    deforming_plate(tmp_path / "src")
    path = tmp_path / "src" / "train.tfrecord"
    data = path.read_bytes()
    path.write_bytes(data[:-100])
    with pytest.raises(DatasetError, match=r"train.tfrecord, trajectory 1: truncated"):
        list(iter_tfrecord(tmp_path / "src", "train"))
    assert cli(["convert", str(tmp_path / "src"), str(tmp_path / "out")]) == 2
    assert "train.tfrecord" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_corrupted_tfrecord_checksum(tmp_path):
    deforming_plate(tmp_path / "src")
    path = tmp_path / "src" / "train.tfrecord"
    data = bytearray(path.read_bytes())
    data[40] ^= 0xFF
    path.write_bytes(bytes(data))
    with pytest.raises(DatasetError, match="checksum"):
        list(iter_tfrecord(tmp_path / "src", "train"))


@pytest.mark.parametrize("case", ["shape", "dtype", "missing", "nan"])
def test_tfrecord_disagreeing_with_meta_is_refused(tmp_path, capsys, case):
    meta, records = deforming_plate(tmp_path / "src", trajectories=1)
    rec = dict(records[0])
    field = {"shape": "world_pos", "dtype": "cells", "missing": "stress", "nan": "stress"}[case]
    if case == "shape":
        rec["world_pos"] = rec["world_pos"][:, :, :2]  # 2-D positions against a 3-D schema
    elif case == "dtype":
        rec["cells"] = rec["cells"].astype(np.int16)  # 2-byte values against int32
        rec["cells"] = np.concatenate([rec["cells"], rec["cells"][:, :1]], 1)
    elif case == "missing":
        rec.pop("stress")
    else:
        rec["stress"] = rec["stress"].copy()
        rec["stress"][0, 0, 0] = np.nan
    write_tf_dataset(tmp_path / "src", meta, {"train": [rec]})
    assert cli(["convert", str(tmp_path / "src"), str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "train" in err and "trajectory" in err and f"field {field}" in err
    assert not (tmp_path / "out").exists()


def ggns_trajectory(steps=5, nu=0.3):
    grid = np.random.rand(steps, 4, 2).astype(np.float32)
    coll = np.random.rand(steps, 3, 2).astype(np.float32)
    return {
        "nodes_grid": grid,
        "edge_index_grid": np.array([[0, 1], [1, 0]]),
        "triangles_grid": np.array([[0, 1, 2], [1, 2, 3]]),
        "nodes_collider": coll,
        "triangles_collider": np.array([[0, 1, 2]]),
        "poisson_ratio": nu,
        "pcd_points": np.random.rand(10, 2),
    }


def test_ggns_deformable_plate_pickle(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    trajs = [ggns_trajectory(nu=0.2), ggns_trajectory(nu=0.45)]
    with open(src / "train.pkl", "wb") as f:
        pickle.dump(trajs, f)
    assert cli(["convert", str(src), str(tmp_path / "out")]) == 0
    with open_split(tmp_path / "out", "train") as s:
        t = s[1]
        assert s.attrs(1)["poisson_ratio"] == pytest.approx(0.45)
    np.testing.assert_array_equal(t["mesh_pos"][:4], trajs[1]["nodes_grid"][0])  # rest shape = first frame
    np.testing.assert_array_equal(t["world_pos"][:, 4:], trajs[1]["nodes_collider"])
    assert t["cells"].tolist() == [[0, 1, 2], [1, 2, 3], [4, 5, 6]]
    assert t["node_type"][:, 0].tolist() == [NodeType.NORMAL] * 4 + [NodeType.OBSTACLE] * 3
    np.testing.assert_allclose(t["poisson_ratio"], 0.45)


def test_ggns_bad_pickle(tmp_path, capsys):
    src = tmp_path / "train.pkl"
    bad = ggns_trajectory()
    bad.pop("triangles_collider")
    src.write_bytes(pickle.dumps([ggns_trajectory(), bad]))
    assert cli(["convert", str(src), str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "train.pkl" in err and "trajectory 1" in err and "field triangles_collider" in err
    src.write_bytes(pickle.dumps([ggns_trajectory()])[:-20])
    assert cli(["convert", str(src), str(tmp_path / "out2")]) == 2
    assert "unpickled" in capsys.readouterr().err


@pytest.mark.parametrize(
    "field,value",
    [
        ("nodes_grid", [[[0.0, 0.0]], [[0.0, 0.0], [1.0, 1.0]]]),
        ("poisson_ratio", "abc"),
        ("triangles_grid", [[0, 1, "x"]]),
    ],
)
def test_ggns_ragged_or_non_numeric_arrays_name_the_field(tmp_path, capsys, field, value):
    bad = ggns_trajectory()
    bad[field] = np.array(value, dtype=object) if field == "nodes_grid" else value
    (tmp_path / "train.pkl").write_bytes(pickle.dumps([bad]))
    assert cli(["convert", str(tmp_path / "train.pkl"), str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "trajectory 0" in err[0] and f"field {field}" in err[0] and "numeric" in err[0], err
