"""The native dataset format: round trip, atomic writes, and every bad input it refuses (a missing, damaged or
inconsistent file)."""

import json

import h5py
import numpy as np
import pytest

from hcmt.cli import main as cli
from hcmt.data.format import NodeType, make_meta, open_split, read_meta, write_meta, write_split
from hcmt.errors import DatasetError

T = 4


def features():
    return {
        "mesh_pos": {"type": "static", "shape": [-1, 2], "dtype": "float32"},
        "cells": {"type": "static", "shape": [-1, 3], "dtype": "int32"},
        "node_type": {"type": "static", "shape": [-1, 1], "dtype": "int32"},
        "world_pos": {"type": "dynamic", "shape": [T, -1, 2], "dtype": "float32"},
        "stress": {"type": "dynamic", "shape": [T, -1, 1], "dtype": "float32"},
    }


def trajectory(n=6, seed=0):
    rng = np.random.default_rng(seed)
    pos = rng.random((n, 2)).astype(np.float32)
    cells = np.stack([np.arange(n - 2), np.arange(1, n - 1), np.arange(2, n)], 1).astype(np.int32)
    node_type = np.zeros((n, 1), np.int32)
    node_type[0] = NodeType.HANDLE
    node_type[-1] = NodeType.SYMMETRIC
    world = pos[None] + rng.normal(size=(T, n, 2)).astype(np.float32) * 0.01
    return {
        "mesh_pos": pos,
        "cells": cells,
        "node_type": node_type,
        "world_pos": world,
        "stress": rng.random((T, n, 1)).astype(np.float32),
    }


@pytest.fixture
def meta():
    return make_meta(features(), trajectory_length=T, dimension=2, dt=0.002, units={"length": "mm", "time": "ms"})


def test_round_trip_keeps_fields_attrs_and_varying_node_counts(tmp_path, meta):
    trajs = [trajectory(6, 0), trajectory(9, 1)]
    write_meta(tmp_path, meta)
    write_split(
        tmp_path / "train.h5", meta, [(f"traj_{i:05d}", t, {"thickness": 0.5 + i}) for i, t in enumerate(trajs)]
    )
    assert read_meta(tmp_path)["node_types"]["SYMMETRIC"] == 7
    with open_split(tmp_path, "train") as split:
        assert len(split) == 2
        for i, t in enumerate(trajs):
            got = split[i]
            for k, v in t.items():
                np.testing.assert_array_equal(got[k], v)
                assert got[k].dtype == v.dtype
            assert split.attrs(i) == {"thickness": 0.5 + i}
    # static fields carry no time axis in the file
    with h5py.File(tmp_path / "train.h5") as f:
        assert f["traj_00001/mesh_pos"].shape == (9, 2)
        assert f["traj_00001/world_pos"].shape == (T, 9, 2)


@pytest.mark.parametrize(
    "mutate, field, words",
    [
        (lambda t: t.pop("stress"), "stress", "missing"),
        (lambda t: t.__setitem__("velocity", t["world_pos"]), "velocity", "unexpected"),
        (lambda t: t.__setitem__("world_pos", t["world_pos"][:2]), "world_pos", "shape"),
        (lambda t: t.__setitem__("mesh_pos", t["mesh_pos"][:, :1]), "mesh_pos", "shape"),
        (lambda t: t.__setitem__("cells", t["cells"].astype(np.float32)), "cells", "dtype"),
        (lambda t: t["stress"].__setitem__((1, 2, 0), np.nan), "stress", "non-finite"),
        (lambda t: t["world_pos"].__setitem__((0, 0, 0), np.inf), "world_pos", "non-finite"),
        (lambda t: t["cells"].__setitem__((0, 0), 99), "cells", "out of range"),
        (lambda t: t["node_type"].__setitem__((2, 0), 12), "node_type", "unknown node type"),
        (lambda t: t.__setitem__("stress", t["stress"][:, :-1]), "stress", "nodes"),
    ],
)
def test_bad_trajectory_is_refused_naming_file_trajectory_field_and_leaves_no_file(
    tmp_path, meta, mutate, field, words
):
    good, bad = trajectory(6, 0), trajectory(6, 1)
    mutate(bad)
    path = tmp_path / "train.h5"
    with pytest.raises(DatasetError) as err:
        write_split(path, meta, [("traj_00000", good, {}), ("traj_00001", bad, {})])
    msg = str(err.value)
    assert str(path) in msg and "traj_00001" in msg and f"field {field}" in msg and words in msg
    assert list(tmp_path.iterdir()) == []  # no half-written file, no temp file


def test_interrupted_write_leaves_previous_file_intact(tmp_path, meta):
    path = tmp_path / "train.h5"
    write_split(path, meta, [("traj_00000", trajectory(), {})])
    before = path.read_bytes()

    def boom():
        yield "traj_00000", trajectory(), {}
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_split(path, meta, boom())
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["train.h5"]


def test_truncated_hdf5_gives_clear_error_and_cli_exit_code(tmp_path, meta, capsys):
    write_meta(tmp_path, meta)
    path = write_split(tmp_path / "train.h5", meta, [("traj_00000", trajectory(200), {})])
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(DatasetError, match="train.h5"):
        s = open_split(tmp_path, "train")
        s[0]
    assert cli(["info", str(tmp_path)]) == 2
    assert "train.h5" in capsys.readouterr().err


@pytest.mark.parametrize("dt,message", [(None, "missing key 'dt'"), ("fast", "dt 'fast'"), (-1.0, "dt -1.0")])
def test_meta_without_a_valid_dt_is_refused(tmp_path, meta, capsys, dt, message):
    meta = dict(meta)
    if dt is None:
        meta.pop("dt", None)
    else:
        meta["dt"] = dt
    (tmp_path / "meta.json").write_text(json.dumps(meta))
    assert cli(["info", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0] and "meta.json" in err[0]


def test_bad_meta_is_refused(tmp_path):
    (tmp_path / "meta.json").write_text(json.dumps({"field_names": ["a"], "features": {}, "trajectory_length": 1}))
    with pytest.raises(DatasetError, match="field a"):
        read_meta(tmp_path)
    with pytest.raises(DatasetError, match="meta.json"):
        read_meta(tmp_path / "nowhere")


def test_info_reports_counts_nodes_types_and_parameter_ranges(tmp_path, meta, capsys):
    write_meta(tmp_path, meta)
    write_split(
        tmp_path / "train.h5",
        meta,
        [(f"traj_{i:05d}", trajectory(6 + 3 * i, i), {"drop_height": 500.0 + 100 * i}) for i in range(3)],
    )
    write_split(tmp_path / "test_thicker.h5", meta, [("traj_00000", trajectory(7), {})])
    assert cli(["info", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "split train: 3 trajectories, nodes min/mean/max 6/9.0/12" in out
    assert "split test_thicker: 1 trajectories" in out
    assert "drop_height" in out and "500 .. 700" in out
    assert "HANDLE 3" in out and "SYMMETRIC 3" in out and "NORMAL 21" in out


def test_info_lists_the_varying_parameters_and_the_constants_in_one_line(tmp_path, meta, capsys):
    write_meta(tmp_path, meta)
    write_split(
        tmp_path / "train.h5",
        meta,
        [
            (f"traj_{i:05d}", trajectory(6, i), {"drop_height": 500.0 + 100 * i, "ball_radius": 2.5, "gap": 0.1})
            for i in range(2)
        ],
    )
    assert cli(["info", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "drop_height" in out and "500 .. 600" in out
    assert "    constant (2): ball_radius=2.5, gap=0.1" in out and "2.5 .. 2.5" not in out
    assert cli(["info", str(tmp_path), "--all"]) == 0
    out = capsys.readouterr().out
    assert "2.5 .. 2.5" in out and "constant (" not in out


def test_time_axis_declared_minus_one_still_checked_and_any_per_node_field(tmp_path):
    feats = features()
    feats["world_pos"]["shape"] = [-1, -1, 2]
    feats["poisson_ratio"] = {"type": "static", "shape": [-1, 1], "dtype": "float32"}
    meta = make_meta(feats, trajectory_length=T, dimension=2)
    t = trajectory()
    t["poisson_ratio"] = np.full((6, 1), 0.3, np.float32)
    write_split(tmp_path / "ok.h5", meta, [("traj_00000", t, {})])
    short = dict(t, world_pos=t["world_pos"][:2])
    with pytest.raises(DatasetError, match="field world_pos.*shape"):
        write_split(tmp_path / "a.h5", meta, [("traj_00000", short, {})])
    wrong = dict(t, poisson_ratio=np.full((7, 1), 0.3, np.float32))
    with pytest.raises(DatasetError, match="field poisson_ratio.*7 nodes"):
        write_split(tmp_path / "b.h5", meta, [("traj_00000", wrong, {})])


def _edit(path, key, fn):
    with h5py.File(path, "r+") as f:
        value = fn(f[key][()])
        del f[key]
        f[key] = value


@pytest.mark.parametrize(
    "corrupt,message",
    [
        (
            lambda p: _edit(
                p, "traj_00000/world_pos", lambda v: np.where(np.arange(v.size).reshape(v.shape) == 3, np.nan, v)
            ),
            "field world_pos",
        ),
        (lambda p: _edit(p, "traj_00000/cells", lambda v: v + 100), "cell index out of range"),
        (lambda p: _edit(p, "traj_00000/node_type", lambda v: np.full_like(v, 42)), "unknown node type(s) [42]"),
        (lambda p: _edit(p, "traj_00000/stress", lambda v: v[..., :0]), "field stress"),
    ],
)
def test_info_validates_as_training_does(tmp_path, meta, capsys, corrupt, message):
    write_meta(tmp_path, meta)
    path = write_split(tmp_path / "train.h5", meta, [("traj_00000", trajectory(), {})])
    corrupt(path)
    assert cli(["info", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0] and "traj_00000" in err[0] and "Traceback" not in err[0]


def test_dynamic_fields_are_chunked_by_frame_and_read_per_frame(tmp_path, meta):
    """Training reads a few frames per item: new files chunk dynamic fields one frame each; Split.layout gives the
    shapes without reading and Split.read a frame range equal to the whole field's slice, also from a file whose
    chunks span several frames (files written before the per-frame chunks)."""
    traj = trajectory(n=3000)
    write_split(tmp_path / "train.h5", meta, [("traj_00000", traj, {})])
    with h5py.File(tmp_path / "train.h5", "r") as f:
        assert f["traj_00000/world_pos"].chunks == (1, 3000, 2) and f["traj_00000/stress"].chunks == (1, 3000, 1)
        assert f["traj_00000/mesh_pos"].chunks != (1, 2)
    old = tmp_path / "old"
    old.mkdir()
    with h5py.File(old / "train.h5", "w") as f:  # h5py's own chunks, several frames each
        for k, v in traj.items():
            f.create_dataset(
                f"traj_00000/{k}",
                data=v,
                compression="gzip",
                chunks=(T, 100, 1)[: v.ndim] if k in ("world_pos", "stress") else None,
            )
    write_meta(old, meta)
    write_meta(tmp_path, meta)
    for folder in (tmp_path, old):
        s = open_split(folder, "train")
        assert s.layout(0) == {k: v.shape for k, v in traj.items()}
        got = s.read(0, ["world_pos", "stress", "cells"], slice(1, 3), num_nodes=3000)
        assert np.array_equal(got["world_pos"], traj["world_pos"][1:3]) and np.array_equal(got["cells"], traj["cells"])
        assert np.array_equal(got["stress"], traj["stress"][1:3])


def test_a_frame_read_alone_is_still_checked(tmp_path, meta):
    """Split.read checks the values it reads as Split[i] does: a NaN in a frame, a cell index out of range, one
    line naming the file, trajectory and field; Split.layout checks the shapes."""
    traj = trajectory()
    write_split(tmp_path / "train.h5", meta, [("traj_00000", traj, {})])
    write_meta(tmp_path, meta)
    with h5py.File(tmp_path / "train.h5", "r+") as f:
        f["traj_00000/world_pos"][2, 1, 0] = np.nan
        f["traj_00000/cells"][0, 0] = 99
    s = open_split(tmp_path, "train")
    assert s.read(0, ["world_pos"], slice(0, 2))["world_pos"].shape == (2, 6, 2)
    with pytest.raises(DatasetError, match=r"train\.h5, trajectory traj_00000, field world_pos: non-finite"):
        s.read(0, ["world_pos"], slice(1, 3))
    with pytest.raises(DatasetError, match=r"field cells: cell index out of range \[1, 99\]; the trajectory has 6"):
        s.read(0, ["cells"], num_nodes=6)
    s.close()
    with h5py.File(tmp_path / "train.h5", "r+") as f:
        del f["traj_00000/stress"]
        f["traj_00000/stress"] = np.zeros((T, 5, 1), np.float32)
    with pytest.raises(DatasetError, match=r"field stress: has 5 nodes but other per-node fields have 6"):
        open_split(tmp_path, "train").layout(0)
