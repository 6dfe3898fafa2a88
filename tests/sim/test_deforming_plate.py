"""The Deforming Plate scene and dataset: equilibrium at every step, every actuator shape and path, Newton's record,
and a generated file read by the same adapter as a file of the public layout."""

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from hcmt.data.convert import convert
from hcmt.data.format import NodeType, load_dataset, read_meta
from hcmt.domains.adapters import get_adapter
from hcmt.domains.trajectory import load_split
from hcmt.sim.deforming import simulate_plate, solve_plate
from hcmt.sim.deforming_data import generate_deforming_plate
from hcmt.sim.plate_params import PATHS, SHAPES, PlateDesign, PlateSettings

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from layouts import deforming_plate_tfrecord  # noqa: E402

SMALL = PlateSettings(frames=9, plate_nodes=240, layers=2, actuator_cells=2, rtol=1e-9)


@pytest.mark.parametrize("shape,path", list(zip(SHAPES, PATHS)))
def test_every_step_is_an_equilibrium(shape, path):
    """The clamped nodes' reaction equals the force on the actuator at every frame, to Newton's tolerance; the
    actuator presses (the plate's free end goes down, the force grows once in contact); Newton's iterations are
    recorded per step and few."""
    design = PlateDesign(shape=shape, path=path, slide=0.1, depth=2.0)
    r = solve_plate(design, SMALL)
    body = r["scene"].body
    tol = 10 * SMALL.rtol * np.abs(r["reaction"]).max() * np.sqrt(len(body.free))
    np.testing.assert_allclose(r["reaction"], r["actuator_force"], atol=max(tol, 1e-9))
    assert r["actuator_force"][-1, 2] > 0.01 * np.abs(r["actuator_force"]).max() > 0  # pushed up by the plate
    assert r["world"][-1, :, 2].min() < -design.thickness - 0.5  # the plate bends down
    assert r["iterations"].shape == (SMALL.frames - 1,) and r["iterations"].mean() <= 12  # 8 big steps
    print(
        f"{shape}/{path}: reaction - actuator force max {np.abs(r['reaction'] - r['actuator_force']).max():.2e} "
        f"N of {np.abs(r['actuator_force']).max():.3f} N; Newton iterations per step {r['iterations'].tolist()}"
    )


def test_trajectory_layout_node_types_and_stress():
    result = simulate_plate(PlateDesign(), SMALL)
    f, attrs = result["fields"], result["attrs"]
    n = len(f["mesh_pos"])
    assert f["mesh_pos"].shape == (n, 3) and f["cells"].shape[1] == 4 and f["node_type"].shape == (n, 1)
    assert f["world_pos"].shape == (SMALL.frames, n, 3) and f["stress"].shape == (SMALL.frames, n, 1)
    types = f["node_type"][:, 0]
    assert set(np.unique(types)) == {NodeType.NORMAL, NodeType.OBSTACLE, NodeType.HANDLE}
    handle, obstacle = types == NodeType.HANDLE, types == NodeType.OBSTACLE
    np.testing.assert_array_equal(
        f["world_pos"][:, handle], np.broadcast_to(f["mesh_pos"][handle], f["world_pos"][:, handle].shape)
    )
    moved = f["world_pos"][:, obstacle] - f["mesh_pos"][obstacle]
    np.testing.assert_allclose(moved, np.broadcast_to(moved[:, :1], moved.shape), atol=1e-5)  # rigid translation
    assert np.all(f["stress"][0] == 0) and f["stress"][-1].max() > 0 and np.all(f["stress"][:, obstacle] == 0)
    # SI fields, as the public dataset (the design is in mm and MPa)
    np.testing.assert_allclose(
        f["mesh_pos"][~obstacle].max(0),
        1e-3 * np.array([PlateDesign().plate_length, PlateDesign().plate_width, 0.0]),
        atol=1e-7,
    )
    assert PlateDesign().modulus * 1e6 > f["stress"].max() > 1e-3 * PlateDesign().modulus * 1e6  # in Pa
    assert len(json.loads(attrs["newton_iterations"])) == SMALL.frames - 1 and attrs["shape"] == "sphere"


def test_generated_and_public_layout_read_by_the_same_adapter(tmp_path):
    generate_deforming_plate(tmp_path / "gen", counts=dict(train=2, valid=1), seed=3, settings=SMALL, progress=False)
    deforming_plate_tfrecord(tmp_path / "src", steps=4)
    convert(tmp_path / "src", tmp_path / "public")
    gen_meta, pub_meta = read_meta(tmp_path / "gen"), read_meta(tmp_path / "public")
    assert gen_meta["dataset"] == "deforming_plate" and gen_meta["dimension"] == pub_meta["dimension"] == 3
    assert set(gen_meta["field_names"]) == set(pub_meta["field_names"])
    for name in gen_meta["field_names"]:
        g, p = gen_meta["features"][name], pub_meta["features"][name]
        assert (g["type"], g["dtype"], g["shape"][-1], len(g["shape"])) == (
            p["type"],
            p["dtype"],
            p["shape"][-1],
            len(p["shape"]),
        ), name
    adapter = get_adapter("deforming_plate")
    gen, pub = (load_split(tmp_path / d, "train", adapter, levels=1)[0] for d in ("gen", "public"))
    assert set(gen.static) == set(pub.static)
    for key in gen.static:
        assert gen.static[key].dtype == pub.static[key].dtype and gen.static[key].ndim == pub.static[key].ndim
    assert gen.world_pos.ndim == pub.world_pos.ndim == 3 and gen.world_pos.shape[2] == pub.world_pos.shape[2] == 3
    assert gen.stress.shape[2] == pub.stress.shape[2] == 1
    assert set(gen.static["node_type"].tolist()) == set(pub.static["node_type"].tolist())
    with load_dataset(tmp_path / "gen")["train"] as split:
        assert len(split) == 2 and split.attrs(0)["path"] in PATHS
        assert max(json.loads(split.attrs(0)["newton_iterations"])) == split.attrs(0)["newton_iterations_max"]


def test_generate_resumes_and_refuses_bad_input(tmp_path):
    out = tmp_path / "gen"
    first = generate_deforming_plate(out, counts=dict(train=1), seed=3, settings=SMALL, progress=False)
    again = generate_deforming_plate(out, counts=dict(train=2), seed=3, settings=SMALL, progress=False)
    assert first["simulated"] == 1 and again["simulated"] == 1 and again["skipped"] == 1
    with pytest.raises(ValueError, match="frames"):
        generate_deforming_plate(tmp_path / "x", counts=dict(train=1), settings=PlateSettings(frames=1))
    with pytest.raises(ValueError, match="estimated"):
        generate_deforming_plate(tmp_path / "y", counts=dict(train=1), settings=PlateSettings(plate_nodes=100_000))
    assert not (tmp_path / "y").exists()


@pytest.mark.parametrize(
    "extra,flag",
    [(["--variants"], "--variants"), (["--family", "stack2"], "--family"), (["--frames", "1"], "--frames")],
)
def test_command_refuses_impact_options_and_bad_frames(tmp_path, capsys, extra, flag):
    from hcmt.cli import main

    assert main(["generate", "deforming-plate", str(tmp_path / "d"), "--train", "1", *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and flag in err[0]
    assert not (tmp_path / "d").exists()


def test_a_design_that_does_not_converge_is_replaced_by_the_next_draw(monkeypatch):
    """The generator's job redraws from the trajectory's own stream when the solve fails (deterministic: the
    replacement is the stream's second design) and records how many it replaced; five failures are refused."""
    import hcmt.sim.deforming_data as dd
    from hcmt.sim.plate_params import sample_plate_design
    from hcmt.sim.quasistatic import NotConverged
    from hcmt.sim.writer import trajectory_rng

    seen = []

    def solve(design, settings, fail=1):
        seen.append(design)
        if len(seen) <= fail:
            raise NotConverged("stand-in")
        return {"fields": {"x": np.zeros(1)}, "attrs": {"shape": design.shape}}

    monkeypatch.setattr(dd, "simulate_plate", solve)
    fields, attrs = dd.deforming_trajectory({}, "", 0, "train", 14, {"frames": 3})
    rng = trajectory_rng(0, "train", 14)
    first, second = sample_plate_design(rng), sample_plate_design(rng)
    assert seen == [first, second] and first != second
    assert attrs == {"shape": second.shape, "redraws": 1}
    seen.clear()
    monkeypatch.setattr(dd, "simulate_plate", lambda d, s: solve(d, s, fail=99))
    with pytest.raises(NotConverged, match="none of 5 designs"):
        dd.deforming_trajectory({}, "", 0, "train", 14, {"frames": 3})
