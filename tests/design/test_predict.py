"""Design check (`hcmt predict`): initial state without a solver, batched prediction, verify, range warnings,
refused designs, shipped models."""

import json
import shutil
from dataclasses import replace

import numpy as np
import pytest
import torch

import hcmt
from conftest import IMPACT_DATA
from hcmt.cli import main as cli
from hcmt.data.runs import available_pretrained
from hcmt.design import prediction, verification
from hcmt.design.check import Prediction, check_designs, design_trajectory, predict, summarize
from hcmt.design.inputs import settings_of
from hcmt.design.reports import format_table, to_json
from hcmt.design.start import initial_frames, start_frames
from hcmt.design.verification import SOLVER_AS_SIMULATE, SOLVER_RECORDING
from hcmt.inference.metrics import plate_mask
from hcmt.inference.rollout import rollout
from hcmt.inference.run import Run
from hcmt.sim.driver import simulate
from hcmt.sim.params import Design, Settings, parse_design
from hcmt.sim.sampling import middle_design, sample_design
from hcmt.training import train
from summaries import type_errors

pytestmark = pytest.mark.slow  # trained runs and solver verification

FRAMES = IMPACT_DATA["frames"]


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory, tiny_config, impact_data):
    """A 3-step HCMT run on the test run's generated `small` trajectories (conftest; real generator meta and design
    attrs)."""
    root = tmp_path_factory.mktemp("predict")
    shutil.copytree(impact_data, root / "data")
    train(tiny_config("train.steps=3", "train.checkpoint_every=3"), root / "data", "hcmt", root / "run", progress=False)
    return root / "run"


def test_initial_frames_match_the_solver():
    design, settings = Design(thickness=0.7, mesh_size=0.3, ball_radius=3.6, plate_half_length=12.0), Settings(frames=2)
    start, solved = initial_frames(design, settings)["fields"], simulate(design, settings).fields
    for key in ("mesh_pos", "cells", "node_type", "density", "modulus"):
        np.testing.assert_array_equal(start[key], solved[key])
    moved = np.abs(solved["world_pos"][1] - solved["world_pos"][0]).max()
    assert moved > 5e-3  # the ball falls v0 dt ~ 7.7e-3 mm in a frame: the comparison below is not vacuous
    np.testing.assert_allclose(start["world_pos"], solved["world_pos"], rtol=0, atol=1e-6)
    assert solved["stress"][:2].max() < 1e-2 and (start["stress"] == 0).all()


def test_ball_crossing_the_gap_in_one_frame_is_refused():
    with pytest.raises(ValueError, match="drop_height.*gap"):
        initial_frames(Design(drop_height=5e5, mesh_size=0.3, ball_radius=3.6, plate_half_length=12.0))


def test_batch_equals_one_by_one(tiny_run):
    run = Run.load(tiny_run, "cpu")
    designs = [
        (f"d{i}", parse_design([f"thickness={t}", f"drop_height={h}"], middle_design(run.meta)))
        for i, (t, h) in enumerate([(0.6, 600), (0.9, 950), (0.75, 700)])
    ]
    together = predict(run, designs, batch=3, progress=False)
    alone = predict(run, designs, batch=1, progress=False)
    assert together[0].world_pos.shape[0] == FRAMES
    for a, b in zip(together, alone):
        np.testing.assert_allclose(a.world_pos, b.world_pos, rtol=0, atol=1e-5)
        np.testing.assert_allclose(a.stress, b.stress, rtol=1e-4, atol=1e-3)
    assert not np.allclose(together[0].world_pos, together[1].world_pos)  # different designs, different results


def test_summary_reads_peaks_off_the_trajectory():
    """Peaks, where, when and deflection on a hand-made two-body trajectory."""
    cells = np.array([[0, 1, 2], [3, 4, 5]])
    node_type = np.array([3, 0, 0, 1, 1, 1])  # plate: nodes 0-2 (clamped node 0), ball: 3-5
    mesh = np.array([[1.0, 0], [0, 0], [0, -1], [0, 1], [1, 1], [0, 2]])
    T = 4
    world = np.repeat(mesh[None], T, 0).copy()
    world[2, 2, 1] -= 0.3  # plate node 2 deflects 0.3 mm at frame 2
    stress = np.zeros((T, 6, 1))
    stress[3, 1, 0], stress[1, 4, 0] = 250.0, 90.0
    p = Prediction("x", Design(), world, stress, mesh, cells, node_type, wall_s=1.0)
    s = summarize(p, frame_dt=0.002)
    assert s.peak_plate_stress_mpa == 250.0 and s.peak_plate_where_mm == [0.0, 0.0]
    assert s.peak_plate_when_ms == pytest.approx(0.006) and s.peak_plate_frame == 3
    assert s.peak_ball_stress_mpa == 90.0 and s.peak_ball_when_ms == pytest.approx(0.002)
    assert s.max_deflection_mm == pytest.approx(0.3)


def test_cli_designs_csv_json_and_range_warning(tiny_run, tmp_path, capsys):
    csv_file = tmp_path / "designs.csv"
    csv_file.write_text("name,thickness,drop_height\nthin,0.55,800\nthick,1.4,800\n")
    out = tmp_path / "res.json"
    rc = cli(
        [
            "predict",
            str(tiny_run),
            "--design",
            "thickness=0.7",
            "--designs",
            str(csv_file),
            "--json",
            str(out),
            "--csv",
            str(tmp_path / "t.csv"),
            "--yield-mpa",
            "300",
            "--device",
            "cpu",
            "--no-progress",
        ]
    )
    captured = capsys.readouterr()
    assert rc == 0
    assert "warning: thick: thickness = 1.4 is outside the model's training data" in captured.err
    assert "design_1" in captured.out and "thin" in captured.out and "margin MPa" in captured.out
    res = json.loads(out.read_text())
    assert [d["name"] for d in res["designs"]] == ["design_1", "thin", "thick"]
    keys = {
        "peak_plate_stress_mpa",
        "peak_plate_where_mm",
        "peak_plate_when_ms",
        "peak_ball_stress_mpa",
        "peak_ball_where_mm",
        "peak_ball_when_ms",
        "max_deflection_mm",
        "yield_margin_mpa",
        "wall_s",
        "design",
    }
    assert keys <= set(res["designs"][0])
    d = res["designs"][0]
    assert d["yield_margin_mpa"] == pytest.approx(300 - d["peak_plate_stress_mpa"])
    assert res["designs"][1]["design"]["thickness"] == 0.55 and res["units"]["stress"] == "MPa"
    assert (tmp_path / "t.csv").read_text().count("\n") == 4


@pytest.mark.parametrize(
    "args,message",
    [
        (["--design", "thickness=-1"], "thickness must be > 0"),
        (["--design", "thicknes=0.5"], "unknown parameter 'thicknes'"),
        (["--design", "thickness=thin"], "thickness must be a number"),
        (["--device", "tpu", "--design", "thickness=0.5"], "--device 'tpu'"),
        ([], "give designs"),
    ],
)
def test_impossible_designs_are_refused(tiny_run, capsys, args, message):
    assert cli(["predict", str(tiny_run), *args, "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0] and "Traceback" not in err[0]


def test_verify_compares_with_the_solver(tiny_run, tmp_path, capsys):
    out = tmp_path / "v.json"
    assert (
        cli(
            [
                "predict",
                str(tiny_run),
                "--design",
                "thickness=0.8",
                "--verify",
                "--images",
                "--out",
                str(tmp_path / "img"),
                "--json",
                str(out),
                "--device",
                "cpu",
                "--no-progress",
            ]
        )
        == 0
    )
    res = json.loads(out.read_text())
    v = res["designs"][0]["verify"]
    solved = simulate(Design(**res["designs"][0]["design"]), Settings(frames=FRAMES)).fields
    plate = plate_mask(solved["cells"], solved["node_type"])
    assert v["solver_peak_plate_stress_mpa"] == pytest.approx(float(solved["stress"][:, plate].max()), rel=1e-6)
    pred = res["designs"][0]["peak_plate_stress_mpa"]
    assert v["peak_plate_stress_error_pct"] == pytest.approx(
        100 * (pred - v["solver_peak_plate_stress_mpa"]) / v["solver_peak_plate_stress_mpa"]
    )
    assert v["speedup"] > 0 and res["verify"]["designs"] == 1
    assert (tmp_path / "img" / "design_1" / "stress_contours_zoom.png").is_file()
    assert "against the solver" in capsys.readouterr().out


@pytest.mark.parametrize("verify", [True, "auto"])
def test_model_and_solver_alternate_per_chunk_and_the_note_says_so(tiny_run, monkeypatch, verify):
    """The speedup's two wall times are measured under the same load: each chunk of `batch` designs is predicted,
    then solved (all of it, or its undecided designs for "auto") before the next chunk; the note and the JSON say
    how."""
    run = Run.load(tiny_run, "cpu")
    designs = [(f"d{i}", replace(middle_design(run.meta), thickness=t)) for i, t in enumerate((0.6, 0.7, 0.8, 0.9))]
    order = []
    real_rollout, real_simulate = prediction.rollout_batch, verification.simulate

    def rollout_batch(model, adapter, trajectories, *args, **kwargs):
        order.append(("model", [tr.name for tr in trajectories]))
        return real_rollout(model, adapter, trajectories, *args, **kwargs)

    def simulate_(design, settings):
        order.append(("solver", [n for n, d in designs if d == design]))
        return real_simulate(design, settings)

    monkeypatch.setattr(prediction, "rollout_batch", rollout_batch)
    monkeypatch.setattr(verification, "simulate", simulate_)
    # "auto" solves the undecided designs only: a yield stress at the model's own answer leaves them all undecided
    yield_mpa = float(np.median([p.summary.peak_plate_stress_mpa for p in predict(run, designs, progress=False)]))
    order.clear()
    check = check_designs(run, designs, batch=2, verify=verify, yield_mpa=yield_mpa, progress=False, surrogate=False)
    assert [p.summary.call for p in check.preds] == ["undecided"] * 4
    assert order == [
        ("model", ["d0", "d1"]),
        ("solver", ["d0"]),
        ("solver", ["d1"]),
        ("model", ["d2", "d3"]),
        ("solver", ["d2"]),
        ("solver", ["d3"]),
    ]
    assert check.verified is not None and check.verified.speedup_measured is not None
    assert type_errors(check.verified) == []
    measured = check.verified.speedup_measured
    assert measured.interleaved and measured.batch == 2 and measured.chunks == 2
    assert measured.threads == torch.get_num_threads() and measured.device == "cpu"
    assert (
        "model and solver alternating per chunk of 2 designs (2 chunks" in check.verified.note
        and measured.how in check.verified.note
    )
    assert f"{torch.get_num_threads()} torch thread" in measured.how
    # the tiny model learned the frame stress: the solver ran as `hcmt simulate` runs it, and the words say so
    assert measured.solver == SOLVER_AS_SIMULATE and measured.solver in measured.how
    got = to_json(check.preds, check.verified, run.source, "cpu", check)["verify"]["speedup_measured"]
    assert got == measured.to_json() and list(got) == [
        "how",
        "interleaved",
        "batch",
        "chunks",
        "device",
        "threads",
        "solver",
    ]
    assert "speedup = solver ÷ model wall time per design, model and solver alternating" in format_table(
        check.preds, check.verified
    )
    # one chunk holding every design cannot alternate, and says so
    one = check_designs(run, designs[:2], batch=2, verify=True, progress=False, surrogate=False)
    assert one.verified is not None and one.verified.speedup_measured is not None
    assert not one.verified.speedup_measured.interleaved
    assert "not alternating: the model's one batch of 2 designs, then the solver" in one.verified.note


@pytest.mark.parametrize("field_", ["stress", "stress_max"])
def test_the_verify_solver_records_between_frame_peaks_only_when_the_comparison_reads_them(
    tiny_run, monkeypatch, field_
):
    """Training data made with --peak-stress (as the shipped model's was): a model that learned the frame stress is
    compared with the solver as `hcmt simulate` runs it (no between-frame peak recording: the speedup divides by the
    solver a user runs), a stress_max model with the recording it reads; the speedup's words say which."""
    run = Run.load(tiny_run, "cpu")
    run.meta = {**run.meta, "generator": {**run.meta["generator"]}}
    run.meta["generator"]["settings"] = {**run.meta["generator"]["settings"], "peak_stress": True}
    run.adapter = replace(run.adapter, stress_field=field_)
    seen, real_simulate = [], verification.simulate

    def simulate_(design, settings):
        seen.append(settings)
        return real_simulate(design, settings)

    monkeypatch.setattr(verification, "simulate", simulate_)
    check = check_designs(run, [("d", middle_design(run.meta))], verify=True, progress=False, surrogate=False)
    recording = field_ == "stress_max"
    assert settings_of(run.meta).peak_stress and seen == [replace(settings_of(run.meta), peak_stress=recording)]
    assert check.verified is not None and check.verified.speedup_measured is not None
    measured = check.verified.speedup_measured
    assert (
        measured.solver == (SOLVER_RECORDING if recording else SOLVER_AS_SIMULATE) and measured.solver in measured.how
    )
    assert ("the solver with between-frame peak recording, which the comparison reads" in measured.how) == recording
    assert measured.how in format_table(check.preds, check.verified) and measured.how in check.verified.note
    assert to_json(check.preds, check.verified, run.source, "cpu", check)["verify"]["speedup_measured"]["solver"] == (
        measured.solver
    )


@pytest.mark.parametrize("name", sorted(available_pretrained()) or ["<none shipped>"])
def test_every_shipped_model_loads_and_predicts(name):
    if name == "<none shipped>":
        pytest.fail("no model ships in src/hcmt/pretrained/")
    run = hcmt.load_pretrained(name, device="cpu")
    assert name.startswith(run.config.dataset) and run.ranges and run.card.get("steps")
    settings = settings_of(run.meta)
    tr, _ = design_trajectory(run, "d", middle_design(run.meta), settings)
    r = rollout(run.model, run.adapter, tr, run.radius, steps=1)
    assert r["world_pos"].shape[0] == 3 and torch.isfinite(r["world_pos"]).all()
    assert tr.world_pos.shape[0] == settings.frames


def test_demo_predicts_three_designs_beside_the_solver(tmp_path, capsys):
    assert cli(["demo", "--out", str(tmp_path / "demo"), "--device", "cpu"]) == 0
    captured = capsys.readouterr()
    out = captured.out
    assert "surrogate MPa [95 %]" in out and out.count("design_") >= 3 and "against the solver over 3 designs" in out
    assert "speedup" in out and "solver" in captured.err  # the solver's progress bar
    assert (tmp_path / "demo" / "design_2" / "stress_contours_zoom.png").is_file()
    assert cli(["demo", "--steps", "0"]) == 2  # --steps belongs to --train
    assert cli(["demo", "--train", "--steps", "0", "--out", str(tmp_path / "t")]) == 2
    assert not (tmp_path / "t").exists()


def test_start_frames_solve_the_first_frame_only_when_the_ball_reaches_the_plate_within_it():
    """At 0.008 ms a 4 mm/ms ball crosses the 0.02 mm gap within the first frame: the learned rollout then starts
    from the solver's frame 1 (one frame of a solve); at 0.002 ms from initial_frames, no solver run."""
    design = Design(drop_height=820.0, mesh_size=0.6, ball_radius=3.0, plate_half_length=8.0)
    coarse = Settings(frames=3, frame_dt=0.008)
    with pytest.raises(ValueError, match="gap"):
        initial_frames(design, coarse)
    s = start_frames(design, coarse)
    solved = simulate(design, coarse).fields
    assert s["info"]["solver_frames"] == 1 and s["fields"]["world_pos"].shape[0] == 2
    np.testing.assert_array_equal(s["fields"]["world_pos"], solved["world_pos"][:2])
    fine = start_frames(design, Settings(frames=3, frame_dt=0.002))
    assert fine["info"]["solver_frames"] == 0
    np.testing.assert_array_equal(
        fine["fields"]["world_pos"], initial_frames(design, Settings(frames=3, frame_dt=0.002))["fields"]["world_pos"]
    )


def test_auto_compile_counts_every_design_of_the_check(tiny_run, monkeypatch):
    """``compile="auto"`` (the design check's default) is resolved once, for all the designs' model steps together
    (:data:`hcmt.models.base.AUTO_COMPILE_ROLLOUT_STEPS`), and every chunk gets that mode: a check of many designs
    compiles even though each chunk alone is short (on the CPU: the ahead-of-time compiled forward, no package built
    here)."""
    from hcmt.models import base

    class Stop(Exception):
        pass

    seen = []

    def spy(*args, compile, **kw):
        seen.append(compile)
        raise Stop

    monkeypatch.setattr(base.shutil, "which", lambda name: f"/usr/bin/{name}")
    monkeypatch.setattr(prediction, "rollout_batch", spy)
    monkeypatch.setenv("TORCHINDUCTOR_CACHE_DIR", str(tiny_run.parent / "empty-cache"))
    run = Run.load(tiny_run, "cpu")
    per_design = settings_of(run.meta).frames - 1 - run.adapter.history
    enough = -(-base.AUTO_COMPILE_ROLLOUT_STEPS // per_design)
    rng = np.random.default_rng(0)
    pick = run.meta["generator"]["preset"]
    designs = [(f"d{i}", sample_design(rng, pick)) for i in range(enough)]
    for count, mode in ((enough, "aot"), (enough - 1, "none")):
        with pytest.raises(Stop):
            predict(run, designs[:count], batch=1, progress=False)
        assert seen[-1] == mode, count
