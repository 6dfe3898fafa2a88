"""The Impact Plate generator: constraints and initial speed in the written data, determinism across worker
counts, resuming after an interruption, variant ranges, and refusal of impossible input."""

from __future__ import annotations

import shutil
from collections import namedtuple

import numpy as np
import pytest

import hcmt.sim.generate as gen
import hcmt.sim.writer as writer
from hcmt.cli import main
from hcmt.data.format import NodeType, list_splits, open_split
from hcmt.errors import DatasetError
from hcmt.inference.evaluate import evaluate
from hcmt.inference.run import Run
from hcmt.sim.cost import plan
from hcmt.sim.driver import simulate
from hcmt.sim.params import GRAVITY, Design, Settings
from hcmt.sim.sampling import RANGES, sample_design
from hcmt.sim.scene import design_mesh
from hcmt.training import train

SHORT = Settings(frames=6)  # impact begins at t = gap / v0 >= 0.0045 ms, i.e. within frames 2-3


def read_all(path, split):
    s = open_split(path, split)
    return [(s[i], s.attrs(i)) for i in range(len(s))]


def test_generated_data_obeys_constraints_and_initial_speed(tmp_path):
    gen.generate_dataset(tmp_path, preset="small", counts=dict(train=2), seed=3, settings=SHORT, progress=False)
    for fields, attrs in read_all(tmp_path, "train"):
        nt, pos, wp = fields["node_type"][:, 0], fields["mesh_pos"], fields["world_pos"]
        sym, handle, ball = nt == NodeType.SYMMETRIC, nt == NodeType.HANDLE, nt == NodeType.OBSTACLE
        assert sym.any() and handle.any() and ball.any()
        assert np.all(wp[:, sym, 0] == 0.0)  # x fixed on the symmetry line, every frame, exactly
        assert np.all(wp[:, handle] == pos[handle])  # clamped
        assert np.all(wp[0] == pos)
        # ball in free fall before contact: displacement over one frame = v0 dt + g dt^2 / 2
        dt = SHORT.frame_dt
        dy = wp[1, ball, 1] - wp[0, ball, 1]
        v0 = np.sqrt(2 * GRAVITY * attrs["drop_height"])
        np.testing.assert_allclose(-dy, v0 * dt + 0.5 * GRAVITY * dt**2, rtol=2e-3)
        assert 0.5 <= attrs["thickness"] <= 1.0 and 500 <= attrs["drop_height"] <= 1000
        # the plate is hit: stress grows from zero
        assert fields["stress"][0].max() < 1e-3 and fields["stress"][-1].max() > 10.0
        assert np.all(fields["density"][ball, 0] == np.float32(attrs["ball_density"]))
        assert np.all(fields["modulus"][~ball & ~sym, 0] == np.float32(attrs["plate_modulus"]))


def test_same_seed_same_output_whatever_the_worker_count(tmp_path):
    counts = dict(train=2, valid=1)
    gen.generate_dataset(
        tmp_path / "one", preset="small", counts=counts, seed=7, workers=1, settings=SHORT, progress=False
    )
    gen.generate_dataset(
        tmp_path / "two", preset="small", counts=counts, seed=7, workers=2, settings=SHORT, progress=False
    )
    for split in counts:
        a, b = read_all(tmp_path / "one", split), read_all(tmp_path / "two", split)
        assert len(a) == len(b) == counts[split]
        for (fa, aa), (fb, ab) in zip(a, b):
            assert aa == ab
            for k in fa:
                np.testing.assert_array_equal(fa[k], fb[k])
    # a different seed gives different designs
    other = sample_design(writer.trajectory_rng(8, "train", 0), "small")
    assert other != sample_design(writer.trajectory_rng(7, "train", 0), "small")


def test_resume_after_interruption(tmp_path, monkeypatch):
    out = tmp_path / "ds"
    real = writer._run_one
    calls = []

    def crash_on_third(task):
        if len(calls) == 2:
            raise KeyboardInterrupt
        calls.append(task[5])
        return real(task)

    monkeypatch.setattr(writer, "_run_one", crash_on_third)
    with pytest.raises(KeyboardInterrupt):
        gen.generate_dataset(out, preset="small", counts=dict(train=3), seed=1, settings=SHORT, progress=False)
    assert not (out / "train.h5").exists()  # no split file until it is complete
    assert sorted(p.name for p in (out / ".parts" / "train").iterdir()) == ["00000.h5", "00001.h5"]
    monkeypatch.setattr(writer, "_run_one", real)
    result = gen.generate_dataset(out, preset="small", counts=dict(train=3), seed=1, settings=SHORT, progress=False)
    assert result["simulated"] == 1 and result["skipped"] == 2
    assert not (out / ".parts").exists()
    assert list_splits(out) == ["train"] and not list(out.glob("*.tmp")) and not list(out.glob(".*.tmp"))
    # identical to an uninterrupted run
    gen.generate_dataset(tmp_path / "ref", preset="small", counts=dict(train=3), seed=1, settings=SHORT, progress=False)
    for (fa, aa), (fb, ab) in zip(read_all(out, "train"), read_all(tmp_path / "ref", "train")):
        assert aa == ab
        np.testing.assert_array_equal(fa["world_pos"], fb["world_pos"])
    # a finished dataset is not redone; other settings in the same folder are refused
    assert (
        gen.generate_dataset(out, preset="small", counts=dict(train=3), seed=1, settings=SHORT, progress=False)[
            "simulated"
        ]
        == 0
    )
    with pytest.raises(DatasetError, match="other settings"):
        gen.generate_dataset(out, preset="small", counts=dict(train=3), seed=2, settings=SHORT, progress=False)


def test_growing_a_dataset_adds_only_the_missing_trajectories(tmp_path):
    grown, fresh = tmp_path / "grown", tmp_path / "fresh"
    gen.generate_dataset(grown, preset="small", counts=dict(train=2, test=1), seed=4, settings=SHORT, progress=False)
    before = read_all(grown, "train")
    result = gen.generate_dataset(
        grown, preset="small", counts=dict(train=3, test=1), seed=4, settings=SHORT, progress=False
    )
    assert result["simulated"] == 1 and result["skipped"] == 3
    gen.generate_dataset(fresh, preset="small", counts=dict(train=3, test=1), seed=4, settings=SHORT, progress=False)
    after, ref = read_all(grown, "train"), read_all(fresh, "train")
    assert len(after) == 3
    for (fa, aa), (fb, ab) in zip(after, ref):  # identical to a fresh generation with the larger counts
        assert aa == ab
        np.testing.assert_array_equal(fa["world_pos"], fb["world_pos"])
    for (fa, _), (fb, _) in zip(before, after):  # existing trajectories unchanged
        np.testing.assert_array_equal(fa["stress"], fb["stress"])
    with pytest.raises(DatasetError, match="would drop"):
        gen.generate_dataset(
            grown, preset="small", counts=dict(train=2, test=1), seed=4, settings=SHORT, progress=False
        )
    with pytest.raises(ValueError, match="nothing to generate"):
        gen.generate_dataset(
            tmp_path / "none",
            preset="small",
            counts=dict(train=0, valid=0, test=0),
            seed=4,
            settings=SHORT,
            progress=False,
        )
    assert not (tmp_path / "none").exists()


@pytest.mark.parametrize(
    "variant, thick, high",
    [("test_thicker", True, False), ("test_higher", False, True), ("test_thicker_higher", True, True)],
)
def test_variant_ranges(variant, thick, high):
    rng = np.random.default_rng(0)
    designs = [sample_design(rng, "paper", variant) for _ in range(200)]
    t = np.array([d.thickness for d in designs])
    h = np.array([d.drop_height for d in designs])
    assert np.all((t >= 1.0) & (t <= 1.2)) if thick else np.all((t >= 0.5) & (t <= 1.0))
    assert np.all((h >= 1000) & (h <= 1200)) if high else np.all((h >= 500) & (h <= 1000))


def test_cli_generate_writes_all_splits_with_variants(tmp_path, capsys):
    out = tmp_path / "cli"
    code = main(
        [
            "generate",
            "impact-plate",
            str(out),
            "--preset",
            "small",
            "--train",
            "1",
            "--valid",
            "1",
            "--test",
            "1",
            "--variants",
            "--variant-count",
            "1",
            "--seed",
            "0",
            "--workers",
            "2",
            "--frames",
            "3",
            "--no-progress",
        ]
    )
    assert code == 0
    assert list_splits(out) == ["train", "valid", "test", "test_higher", "test_thicker", "test_thicker_higher"]
    assert 1.0 <= open_split(out, "test_thicker").attrs(0)["thickness"] <= 1.2


@pytest.mark.parametrize(
    "change, word",
    [
        (dict(thickness=0.0), "thickness"),
        (dict(thickness=-1.0), "thickness"),
        (dict(ball_radius=0.0), "ball_radius"),
        (dict(plate_modulus=-5.0), "modulus"),
        (dict(ball_modulus=0.0), "modulus"),
        (dict(plate_poisson=0.5), "Poisson"),
        (dict(ball_poisson=-1.2), "Poisson"),
        (dict(gap=0.4), "contact radius"),
        (dict(gap=0.0), "gap"),
        (dict(plate_density=0.0), "density"),
        (dict(drop_height=0.0), "drop_height"),
        (dict(mesh_size=2.0), "mesh_size"),
    ],
)
def test_impossible_designs_are_refused_before_work(change, word, monkeypatch):
    monkeypatch.setattr("hcmt.sim.driver.design_mesh", lambda d: pytest.fail("work started"))
    with pytest.raises(ValueError, match=word):
        simulate(Design(**{**vars(Design()), **change}))


def test_cli_simulate_refuses_bad_gap_and_times_a_design(tmp_path, capsys):
    assert main(["simulate", "--gap", "0.5"]) == 2
    assert "contact radius" in capsys.readouterr().err
    assert main(["generate", "impact-plate", str(tmp_path / "x"), "--workers", "0"]) == 2  # out of its bounds
    assert "argument --workers: expected a whole number from 1" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()
    out = tmp_path / "one.h5"
    assert main(["simulate", "--preset", "small", "--thickness", "0.6", "--frames", "3", "--out", str(out)]) == 0
    assert "wall-clock" in capsys.readouterr().out
    assert open_split(tmp_path, "one").attrs(0)["thickness"] == pytest.approx(0.6)


def test_preset_node_counts():
    """paper ~2,200 nodes (Table 6: 2,208) on average, small 400-600; at least 4 layers through the plate."""
    for preset, (lo, hi) in dict(paper=(1900, 2500), small=(400, 600)).items():
        rng = np.random.default_rng(1)
        meshes = [design_mesh(sample_design(rng, preset)) for _ in range(20)]
        n = np.array([len(m["mesh_pos"]) for m in meshes])
        assert lo <= n.mean() <= hi, (preset, n.mean())
        for m in meshes:
            plate_axis = m["mesh_pos"][(m["body"] == 0) & (m["mesh_pos"][:, 0] == 0)]
            assert len(plate_axis) >= 5
    assert RANGES["paper"]["thickness"] == (0.5, 1.0)


def test_simulate_states_its_cost_and_refuses_an_absurd_one(capsys):
    assert main(["simulate", "--mesh-size", "0.02", "--no-progress"]) == 2
    captured = capsys.readouterr()
    assert "substeps" in captured.out and "estimated" in captured.out
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and "exceeds 600 s" in err[0] and "--force" in err[0]


def test_inverted_element_stops_the_solve_naming_the_frame(capsys):
    assert main(["simulate", "--preset", "small", "--plate-modulus", "0.001", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0].startswith(
        "hcmt simulate: warning: plate_modulus = 0.001 is outside the range the solver is validated for (1000 .. 1e+06"
    )
    assert len(err) == 2 and "solve stopped at frame" in err[1] and "inverted" in err[1]


def test_far_outside_the_validated_range_warns(capsys):
    assert main(["simulate", "--preset", "small", "--drop-height", "1e7", "--frames", "3", "--no-progress"]) == 0
    err = capsys.readouterr().err
    assert "impact_speed = 442.9" in err and "validated for (0 .. 10" in err


def test_disk_full_is_one_line_and_a_rerun_resumes(tmp_path, monkeypatch, capsys):
    real = shutil.disk_usage
    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda p: usage(1 << 30, 1 << 30, 1000))  # 1 kB free
    out = tmp_path / "ds"
    assert (
        main(
            [
                "generate",
                "impact-plate",
                str(out),
                "--train",
                "1",
                "--valid",
                "0",
                "--test",
                "0",
                "--frames",
                "3",
                "--no-progress",
            ]
        )
        == 2
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "No space left on device" in err[0] and str(out) in err[0]
    assert not list(out.rglob("*.h5")) and not list(out.rglob("*.tmp"))  # nothing half-written
    monkeypatch.setattr(shutil, "disk_usage", real)
    assert (
        main(
            [
                "generate",
                "impact-plate",
                str(out),
                "--train",
                "1",
                "--valid",
                "0",
                "--test",
                "0",
                "--frames",
                "3",
                "--no-progress",
            ]
        )
        == 0
    )
    assert list_splits(out) == ["train"]


def test_interrupted_generate_is_one_line_and_keeps_finished_work(tmp_path, monkeypatch, capsys):
    real = writer._run_one
    calls = []

    def stop_on_second(task):
        if calls:
            raise KeyboardInterrupt
        calls.append(task)
        return real(task)

    monkeypatch.setattr(writer, "_run_one", stop_on_second)
    out = tmp_path / "ds"
    args = [
        "generate",
        "impact-plate",
        str(out),
        "--train",
        "2",
        "--valid",
        "0",
        "--test",
        "0",
        "--frames",
        "3",
        "--no-progress",
    ]
    assert main(args) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "finished trajectories are kept" in err[0] and "hcmt generate" in err[0]
    assert [p.name for p in (out / ".parts" / "train").glob("*.h5")] == ["00000.h5"]


def test_peak_stress_is_the_largest_stress_between_frames():
    """stress_max at a coarse interval equals the maximum over the substeps of a run that records every substep
    (same substep: the coarse frame holds n substeps, the fine run one), and is never below the frame's stress."""
    d = Design(thickness=0.6, drop_height=900.0, mesh_size=0.6, plate_half_length=8.0, ball_radius=3.0)
    coarse = Settings(frames=6, frame_dt=0.008, peak_stress=True)
    n = plan(d, coarse)["substeps"] // (coarse.frames - 1)  # substeps per coarse frame
    fine = simulate(d, Settings(frames=(coarse.frames - 1) * n + 1, frame_dt=coarse.frame_dt / n))
    assert fine.info.substeps == (coarse.frames - 1) * n  # one substep per fine frame
    r = simulate(d, coarse)
    got, stress = r.fields["stress_max"][..., 0], r.fields["stress"][..., 0]
    want = fine.fields["stress"][..., 0]
    np.testing.assert_allclose(stress, want[::n], rtol=1e-5, atol=1e-4)  # the same trajectory
    for k in range(1, coarse.frames):
        np.testing.assert_allclose(got[k], want[(k - 1) * n + 1 : k * n + 1].max(0), rtol=1e-5, atol=1e-4)
    assert (got >= stress - 1e-4).all() and got.max() > stress.max()  # a coarse frame steps over the true peak


def test_peak_stress_recording_changes_no_frame():
    """The between-frame peak recording (``Settings.peak_stress``: the solver one substep at a time) changes no
    recorded frame: positions and frame stress are those of the solve without it, bit for bit; so the design check's
    solver records it only for a model that learned ``stress_max``, and otherwise runs as ``hcmt simulate`` does."""
    d = Design(thickness=0.6, drop_height=900.0, mesh_size=0.6, plate_half_length=8.0, ball_radius=3.0)
    plain, recorded = (simulate(d, Settings(frames=6, frame_dt=0.008, peak_stress=p)) for p in (False, True))
    assert "stress_max" in recorded.fields and "stress_max" not in plain.fields
    assert plain.fields["stress"][-1].max() > 1.0  # in contact: the comparison below is not vacuous
    assert recorded.info.substeps == plain.info.substeps
    for k in ("world_pos", "stress"):
        np.testing.assert_array_equal(recorded.fields[k], plain.fields[k])


def test_generate_peak_stress_writes_the_field_and_a_model_trains_on_it(tmp_path, tiny_config):
    out = tmp_path / "ip"
    assert (
        main(
            [
                "generate",
                "impact-plate",
                str(out),
                "--preset",
                "small",
                "--train",
                "1",
                "--valid",
                "1",
                "--test",
                "1",
                "--frames",
                "5",
                "--frame-dt",
                "0.004",
                "--peak-stress",
                "--no-progress",
            ]
        )
        == 0
    )
    with open_split(out, "test") as s:
        t = s[0]
        assert t["stress_max"].shape == t["stress"].shape and (t["stress_max"] >= t["stress"] - 1e-4).all()
    cfg = tiny_config("train.steps=2", "data.stress_field=stress_max")
    train(cfg, out, "mgn", tmp_path / "run", progress=False)
    run = Run.load(tmp_path / "run", "cpu")
    assert run.adapter.stress_field == "stress_max"
    m = evaluate(run, out, "test", progress=False)
    assert np.isfinite(m.stress.rmse_all)
    with pytest.raises(ValueError, match="data.stress_field: unknown value 'peak'"):
        tiny_config("data.stress_field=peak")
