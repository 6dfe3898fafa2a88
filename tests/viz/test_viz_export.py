"""ParaView export: the files meshio and ParaView read, holding exactly the rollout's arrays."""

import xml.etree.ElementTree as ET

import h5py
import meshio
import numpy as np
import pytest

from hcmt.cli import main as cli
from hcmt.data.runs import RunFolder
from hcmt.errors import DatasetError
from hcmt.viz.export import export_case
from hcmt.viz.rollouts import Case, Series, load_case
from layouts import box_tetrahedra
from viz_runs import SHIFT, STRESS_OFFSET, fake_run, impact_dataset

pytestmark = pytest.mark.slow  # trained runs rolled out


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    root = tmp_path_factory.mktemp("export")
    data = impact_dataset(root / "data", n_test=2)
    run = fake_run(root / "run_mgn", data)
    return data, run


def read_pvd(path):
    sets = ET.parse(path).getroot().find("Collection").findall("DataSet")
    return [(float(d.get("timestep")), path.parent / d.get("file")) for d in sets]


def test_vtu_series_holds_the_rollout(setup, tmp_path):
    data, run = setup
    case = load_case([RunFolder(run)], data, "test", 0)
    opened = export_case(case, tmp_path, "vtu")
    assert [p.name for p in opened] == ["traj_00000_truth.pvd", "traj_00000_mgn.pvd"]
    pred, truth = case.predictions[0], case.truth
    dt = case.meta["dt"]
    for pvd, series in zip(opened, (truth, pred)):
        entries = read_pvd(pvd)
        assert len(entries) == case.num_frames
        assert np.allclose([t for t, _ in entries], dt * np.arange(case.num_frames))
        for f, (_, path) in enumerate(entries):
            m = meshio.read(path)
            assert np.array_equal(m.points[:, :2], series.world_pos[f]) and not m.points[:, 2].any()
            assert np.array_equal(m.cells_dict["triangle"], case.cells)
            pd = m.point_data
            assert np.array_equal(pd["node_type"], case.node_type)
            assert np.array_equal(pd["stress"], series.stress[f, :, 0])
            assert np.allclose(pd["displacement"][:, :2], series.world_pos[f] - series.world_pos[0])
            if series is pred:
                assert np.array_equal(pd["stress_true"], truth.stress[f, :, 0])
                assert np.allclose(pd["stress_error"], STRESS_OFFSET if f >= pred.start else 0.0, atol=1e-5)
                want = SHIFT if f >= pred.start else np.zeros(2)
                assert np.allclose(pd["position_error"][:, :2], want, atol=1e-6)
                assert np.allclose(pd["position_error_norm"], np.linalg.norm(want), atol=1e-6)
            else:
                assert "stress_error" not in pd


def test_xdmf_series_reads_back(setup, tmp_path):
    data, run = setup
    case = load_case([RunFolder(run)], data, "test", 0)
    paths = export_case(case, tmp_path, "xdmf", frames=[0, 3, 5])
    assert (tmp_path / "traj_00000_mgn.h5").is_file()  # beside the .xdmf, wherever the working folder is
    pred = case.predictions[0]
    with meshio.xdmf.TimeSeriesReader(paths[1]) as reader:
        points, cells = reader.read_points_cells()
        assert np.array_equal(points[:, :2], pred.world_pos[0])  # the writer stores the points once
        assert np.array_equal(cells[0].data, case.cells)
        assert reader.num_steps == 3
        for k, f in enumerate([0, 3, 5]):
            t, pd, _ = reader.read_data(k)
            assert t == pytest.approx(f * case.meta["dt"])
            assert np.array_equal(pd["position"][:, :2], pred.world_pos[f])
            assert np.array_equal(pd["stress"], pred.stress[f, :, 0])
            assert np.allclose(points[:, :2] + pd["displacement"][:, :2], pred.world_pos[f], atol=1e-6)


def test_export_command_all_trajectories_with_stride(setup, tmp_path):
    data, run = setup
    assert (
        cli(
            [
                "export",
                str(run),
                "--data",
                str(data),
                "--format",
                "vtu",
                "--out",
                str(tmp_path),
                "--trajectory",
                "all",
                "--stride",
                "2",
            ]
        )
        == 0
    )
    pvds = sorted(p.name for p in tmp_path.glob("*.pvd"))
    assert pvds == ["traj_00000_mgn.pvd", "traj_00000_truth.pvd", "traj_00001_mgn.pvd", "traj_00001_truth.pvd"]
    frames = [p.name for _, p in read_pvd(tmp_path / "traj_00001_mgn.pvd")]
    assert frames == ["frame_00000.vtu", "frame_00002.vtu", "frame_00004.vtu"]


def test_export_tetrahedra(tmp_path):
    pos, tets = box_tetrahedra(2, 1, 1, h=0.5)
    world = np.stack([pos, pos + [0, 0, -0.1], pos + [0, 0, -0.2]]).astype(np.float32)
    stress = np.random.default_rng(0).random((3, len(pos), 1)).astype(np.float32)
    case = Case(
        "traj_00000",
        pos,
        tets,
        np.zeros(len(pos), np.int64),
        Series("Ground truth", world, stress),
        [Series("HCMT", world + 0.01, stress * 2, start=1)],
        meta={"dt": None},
    )
    paths = export_case(case, tmp_path, "vtu")
    t, last = read_pvd(paths[1])[-1]
    assert t == 2.0  # no dt: time is the frame number
    m = meshio.read(last)
    assert np.array_equal(m.cells_dict["tetra"], tets)
    assert np.allclose(m.points, world[2] + 0.01)
    assert np.allclose(m.point_data["stress_error"], stress[2, :, 0])


def test_rollout_of_another_dataset_is_refused(setup, tmp_path):
    data, _ = setup
    run = fake_run(tmp_path / "run", data)
    with h5py.File(run / "rollout_test.h5", "a") as f:
        del f["traj_00000/world_pos"]
        f["traj_00000/world_pos"] = np.zeros((6, 7, 2), np.float32)
    with pytest.raises(DatasetError, match="another dataset"):
        load_case([RunFolder(run)], data, "test", 0)
    assert cli(["export", str(run), "--data", str(data), "--out", str(tmp_path / "x"), "--trajectory", "9"]) == 2
