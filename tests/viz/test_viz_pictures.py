"""Pictures: what they show is checked (scales, units, frames, errors, edges, attention rows), not just that a file
appears."""

import json

import numpy as np
import pytest
from PIL import Image

from hcmt.cli import main as cli
from hcmt.data.format import read_meta
from hcmt.data.runs import RunFolder
from hcmt.graph.contact import object_ids
from hcmt.graph.hierarchy import build_hierarchy
from hcmt.inference.run import Run
from hcmt.training import train
from hcmt.viz.animation import animate, animation_frames
from hcmt.viz.attention import attention_matrix, frame_attention, object_order, plot_attention
from hcmt.viz.contours import contour_figure
from hcmt.viz.curves import plot_error_curves, plot_training_curves, read_log, rollout_errors
from hcmt.viz.hierarchy import level_figure, remeshing_figure
from hcmt.viz.meshplot import impact_window
from hcmt.viz.rollouts import Case, Series, load_case
from layouts import box_tetrahedra, impact_like
from viz_runs import SHIFT, STRESS_OFFSET, fake_run, impact_dataset

pytestmark = pytest.mark.slow  # trained runs rolled out


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    return impact_dataset(tmp_path_factory.mktemp("viz") / "data")


@pytest.fixture(scope="module")
def hcmt_run(data, tmp_path_factory, tiny_config):
    run = tmp_path_factory.mktemp("runs") / "hcmt"
    cfg = tiny_config(
        "model.blocks=2",
        "train.log_every=1",
        "train.checkpoint_every=2",
        "train.valid_every=2",
        "train.valid_trajectories=1",
        "train.contact_radius=0.3",
        "train.steps=2",
    )
    train(cfg, data, "hcmt", run, seed=0, progress=False)
    return run


def panels(fig):
    return [a for a in fig.axes if a.collections and a.get_label() != "<colorbar>"]


def colourbars(fig):
    return [a for a in fig.axes if a.get_label() == "<colorbar>"]


def pixels(path):
    return np.asarray(Image.open(path).convert("RGB"), np.int16)


def assert_nontrivial(path, min_colours=20):
    img = pixels(path)
    assert img.shape[0] > 200 and img.shape[1] > 200
    assert len(np.unique(img.reshape(-1, 3), axis=0)) >= min_colours  # drawn, not a blank canvas
    return img


# -- zoom window -----------------------------------------------------------------------------------------------------
def test_impact_window_is_four_thicknesses_tall_around_the_closest_pair():
    fields = impact_like(1, 2)[0]
    pos, obj = fields["mesh_pos"].astype(np.float64), object_ids(fields["cells"], len(fields["mesh_pos"]))
    x0, x1, y0, y1 = impact_window(pos, obj)
    assert y1 - y0 == pytest.approx(4 * 0.5)  # the plate (0.5 thick) is the thinnest object
    assert x1 - x0 == pytest.approx(4 / 3 * 2.0)
    # the gap between the ball (bottom at y = 0.6) and the plate (top at y = 0.5) is inside the window
    assert y0 < 0.5 and y1 > 0.6 and x0 <= 0.0 + 1e-9
    single = obj == obj[0]
    assert impact_window(pos[single], obj[single]) is None


# -- contours --------------------------------------------------------------------------------------------------------
def _panel_mean(fig, ax):
    img = np.asarray(fig.canvas.buffer_rgba())[..., :3].astype(float)
    bb = ax.get_window_extent()
    h = img.shape[0]
    return img[int(h - bb.y1) + 2 : int(h - bb.y0) - 2, int(bb.x0) + 2 : int(bb.x1) - 2].mean((0, 1))


def test_contours_share_one_scale_per_row_with_units(data, tmp_path):
    run = fake_run(tmp_path / "run", data, stress_offset=0.0, shift=np.zeros(2, np.float32))
    case = load_case([RunFolder(run)], data)
    fig = contour_figure(case, [2, 5])
    fig.canvas.draw()
    axes = panels(fig)
    assert len(axes) == 4 and all(a.get_aspect() == 1.0 for a in axes)
    for row, f in enumerate([2, 5]):
        a, b = axes[2 * row], axes[2 * row + 1]
        na, nb = a.collections[0].norm, b.collections[0].norm
        assert (na.vmin, na.vmax) == (nb.vmin, nb.vmax) == (0.0, pytest.approx(case.truth.stress[f].max()))
        assert np.allclose(a.collections[0].get_array(), case.truth.stress[f, :, 0])
    assert [c.get_ylabel() for c in colourbars(fig)] == ["von Mises stress [MPa]", "von Mises stress [MPa]"]
    assert axes[-1].get_xlabel() == "x [mm]" and axes[0].get_ylabel() == "y [mm]"
    assert [sf._suptitle.get_text() for sf in fig.subfigs] == ["frame 2, t = 0.004 ms", "frame 5, t = 0.01 ms"]
    fig = contour_figure(case, [5], zoom=True)  # (the whole-scene view marks the zoom window on the truth only)
    fig.canvas.draw()
    a, b = panels(fig)
    assert np.allclose(_panel_mean(fig, a), _panel_mean(fig, b), atol=1.0)  # an exact prediction looks the same

    # a prediction with ten times the stress: the shared scale saturates it and the colour bar says so
    case.predictions[0] = Series("MGN", case.truth.world_pos, case.truth.stress * 10, 2)
    fig = contour_figure(case, [5], scale="all", zoom=True)
    fig.canvas.draw()
    a, b = panels(fig)
    assert not np.allclose(_panel_mean(fig, a), _panel_mean(fig, b), atol=5.0)
    (cbar,) = colourbars(fig)
    assert cbar.get_ylabel() == "von Mises stress [MPa]" and "RMSE" in b.get_title()
    assert cbar._colorbar.extend == "max"


def test_contours_without_units_or_stress_say_so(tmp_path):
    data = impact_dataset(tmp_path / "data", units=False)
    case = load_case([], data)
    fig = contour_figure(case, [3])
    assert [a.get_ylabel() for a in colourbars(fig)] == ["von Mises stress (unit not in meta.json)"]
    case.truth.stress = None
    fig = contour_figure(case, [3], zoom=True)
    assert [a.get_ylabel() for a in colourbars(fig)] == ["displacement magnitude (unit not in meta.json)"]
    with pytest.raises(ValueError, match="frame 9 out of range"):
        contour_figure(case, [9])


def test_contours_of_a_3d_mesh(tmp_path):
    pos, tets = box_tetrahedra(3, 2, 1, h=0.5)
    world = np.stack([pos, pos * [1, 1, 0.9]])
    stress = np.stack([np.zeros((len(pos), 1)), pos[:, :1]])
    case = Case(
        "t",
        pos,
        tets,
        np.zeros(len(pos), np.int64),
        Series("Ground truth", world, stress),
        [Series("HCMT", world, stress, 1)],
        meta={},
    )
    fig = contour_figure(case, [1])
    fig.savefig(tmp_path / "c.png", dpi=100)
    assert_nontrivial(tmp_path / "c.png")
    with pytest.raises(ValueError, match="2-D"):
        contour_figure(case, [1], zoom=True)


# -- animation -------------------------------------------------------------------------------------------------------
def test_animation_has_one_image_per_drawn_frame(data, tmp_path):
    case = load_case([RunFolder(fake_run(tmp_path / "run", data))], data)
    assert animation_frames(6) == [0, 1, 2, 3, 4, 5] and animation_frames(6, 4) == [0, 4, 5]
    long = animation_frames(1000)
    assert len(long) <= 100 and long[-1] == 999 and len(set(np.diff(long[:-1]))) == 1
    for stride, count in ((None, 6), (2, 4)):
        path = animate(case, tmp_path / f"a{count}.gif", stride=stride)
        im = Image.open(path)
        assert im.n_frames == count
        im.seek(0)
        first = np.asarray(im.convert("RGB"), np.int16)
        im.seek(count - 1)
        last = np.asarray(im.convert("RGB"), np.int16)
        assert first.shape[0] > 200 and np.abs(first - last).sum() > 0  # the meshes moved, the title changed
    with pytest.raises(ValueError, match=".gif"):
        animate(case, tmp_path / "a.avi")


# -- curves ----------------------------------------------------------------------------------------------------------
def test_error_curves_show_the_known_errors(data, tmp_path):
    runs = [fake_run(tmp_path / "a", data), fake_run(tmp_path / "b", data, model="hcmt", shift=2 * SHIFT)]
    errors = rollout_errors([RunFolder(r) for r in runs], data)
    assert list(errors) == ["MGN", "HCMT"]
    for label, factor in (("MGN", 1), ("HCMT", 2)):
        e = errors[label]
        assert e["start"] == 2 and e["trajectories"] == ["traj_00000"]
        assert np.allclose(e["position"][0, :2], 0) and np.allclose(e["position"][0, 2:], factor * 0.05, atol=1e-6)
        assert np.allclose(e["stress"][0, 2:], STRESS_OFFSET, atol=1e-5)
    path = plot_error_curves(errors, read_meta(data), tmp_path / "err.png")
    assert_nontrivial(path)


def test_training_curves_read_the_log(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    lines = [{"step": s, "loss": 1.0 / s, "lr": 1e-3, "ms_per_step": 5.0} for s in (1, 2, 3)]
    lines += [
        {"step": 2, "loss": 0.25, "lr": 1e-3, "ms_per_step": 5.0},  # resumed: step 2 logged again
        {"step": 3, "valid/position_rmse_all": 40.0, "valid/stress_rmse_all": 9e3},
    ]
    (run / "log.jsonl").write_text("\n".join(json.dumps(l) for l in lines) + "\n")
    (run / "run.yaml").write_text("model: {name: hcmt}\n")
    train_cols, valid = read_log(run)
    assert train_cols["step"].tolist() == [1, 2, 3] and train_cols["loss"].tolist() == [1.0, 0.25, 1 / 3]
    assert valid["valid/position_rmse_all"].tolist() == [40.0]
    fig_path = plot_training_curves([RunFolder(run)], {"units": {"length": "mm", "stress": "MPa"}}, tmp_path / "t.png")
    assert_nontrivial(fig_path)
    (run / "log.jsonl").write_text("{not json\n")
    with pytest.raises(ValueError, match="line 1"):
        read_log(run)


# -- hierarchy -------------------------------------------------------------------------------------------------------
def test_hierarchy_pictures_draw_every_level_and_the_two_hop_graph():
    fields = impact_like(1, 2)[0]
    pos = fields["mesh_pos"].astype(np.float64)
    h = build_hierarchy(pos, fields["cells"], fields["node_type"], 2)
    fig = level_figure(pos, h)
    axes = [a for a in fig.axes if a.collections]
    assert len(axes) == 3
    for l, ax in enumerate(axes):
        assert len(ax.collections[0].get_segments()) == h.edges[l].shape[1] // 2  # each edge once
        assert f"{h.num_nodes(l)} nodes" in ax.get_title()
    fig = remeshing_figure(pos, h)
    axes = [a for a in fig.axes if a.collections]
    assert len(axes) == 4
    for l in (1, 2):
        before, after = axes[2 * (l - 1)], axes[2 * (l - 1) + 1]
        # before: kept nodes of level l-1 at most two hops apart there (dense matrix powers, independently)
        n = h.num_nodes(l - 1)
        a = np.zeros((n, n), bool)
        a[h.edges[l - 1][0], h.edges[l - 1][1]] = True
        reach = (a | (a.astype(int) @ a.astype(int) > 0))[np.ix_(h.pool[l - 1], h.pool[l - 1])]
        np.fill_diagonal(reach, False)
        assert len(before.collections[0].get_segments()) == int(reach.sum()) // 2
        assert len(after.collections[0].get_segments()) == h.edges[l].shape[1] // 2
        assert "scaled Jacobian" in after.get_title()
    with pytest.raises(ValueError, match="no pooled level"):
        remeshing_figure(pos, build_hierarchy(pos, fields["cells"], fields["node_type"], 0))


# -- attention -------------------------------------------------------------------------------------------------------
def test_attention_matrix_rows_are_receivers():
    w = np.array([[0.2, 0.4], [1.0, 1.0], [0.3, 0.3]])  # [E, H]
    edges = np.array([[0, 1, 2], [1, 2, 1]])  # senders, receivers
    a = attention_matrix(w, edges, 3).toarray()
    assert a[1, 0] == pytest.approx(0.3) and a[2, 1] == 1.0 and a[1, 2] == pytest.approx(0.3) and a.sum() == 1.6
    order, bounds = object_order(np.array([1, 0, 1, 0, 2]))
    assert order.tolist() == [1, 3, 0, 2, 4] and bounds.tolist() == [2, 4]


def test_attention_maps_of_a_trained_hcmt(data, hcmt_run, tmp_path):
    maps = frame_attention(Run.load(hcmt_run, "cpu"), data, "test", 0, frame=3)
    assert {"cmt0.mesh", "cmt0.contact", "hmt.down0", "hmt.bottom1", "hmt.up0"} <= set(maps.matrices)
    n0 = len(maps.object_id[0])
    for name, m in maps.matrices.items():
        level = maps.blocks[name].level
        assert m.shape == (len(maps.object_id[level]),) * 2
        rows = np.asarray(m.sum(1)).ravel()
        has = np.diff(m.indptr) > 0
        assert np.allclose(rows[has], 1.0, atol=1e-5), name  # a softmax over each receiver's senders
    contact = maps.matrices["cmt0.contact"].tocoo()
    obj = maps.object_id[0]
    assert contact.nnz > 0 and (obj[contact.row] != obj[contact.col]).all()  # contact joins different objects
    assert maps.matrices["hmt.down0"].nnz == maps.matrices["cmt0.mesh"].nnz and n0 == 49
    path = plot_attention(maps, tmp_path / "att.png")
    assert_nontrivial(path)
    with pytest.raises(ValueError, match="frame 5 out of range"):
        frame_attention(Run.load(hcmt_run, "cpu"), data, "test", 0, frame=5)


# -- the command -----------------------------------------------------------------------------------------------------
def test_plot_command_writes_every_picture(data, hcmt_run, tmp_path, capsys):
    other = fake_run(tmp_path / "mgn", data)
    out = tmp_path / "pics"
    assert not (hcmt_run / "rollout_test.h5").exists()
    assert cli(["plot", str(hcmt_run), str(other), "--data", str(data), "--out", str(out), "--frames", "2,5"]) == 0
    assert (hcmt_run / "rollout_test.h5").is_file()  # rolled out on demand
    names = {
        "stress_contours.png",
        "stress_contours_zoom.png",
        "rollout.gif",
        "rollout_error.png",
        "training_curves.png",
        "hierarchy_levels.png",
        "hierarchy_levels_zoom.png",
        "hierarchy_remeshing.png",
        "hierarchy_remeshing_zoom.png",
        "attention_hcmt.png",
    }
    assert {p.name for p in out.iterdir()} == names
    for name in names - {"rollout.gif"}:
        assert_nontrivial(out / name)
    assert "MGN" in capsys.readouterr().out  # the MGN run has no attention: said, not failed
    assert cli(["plot", str(other), "--data", str(data), "--out", str(out), "--frames", "2,x"]) == 2
    assert "--frames" in capsys.readouterr().err
    assert cli(["plot", str(other), "--data", str(data), "--out", str(out), "--only", "pictures"]) == 2
    assert cli(["plot", str(other), "--data", str(data), "--out", str(out), "--trajectory", "7"]) == 2
    assert "out of range" in capsys.readouterr().err
