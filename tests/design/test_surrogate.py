"""The response surface (hcmt.design.surrogate), the design check's read-outs (hcmt.design.readout) and the limit
calls: a GP that recovers a known law, JSON storage without pickle, refused files, answers side by side, calls that
pass only below the trusted interval, ``--verify auto``, no ghost peak."""

import json
import shutil
from dataclasses import replace

import numpy as np
import pytest
from sklearn.gaussian_process import GaussianProcessRegressor

import hcmt.design.check as check_module
from conftest import IMPACT_DATA
from hcmt.cli import main as cli
from hcmt.design import readout as ro
from hcmt.design.check import MODEL_BAND, call_of, check_designs, predict_designs, trusted_interval
from hcmt.design.inputs import design_for
from hcmt.design.reports import finite
from hcmt.design.summary import SurrogateAnswer
from hcmt.design.surrogate import Surrogate, SurrogateError
from hcmt.design.surrogate_use import for_run
from hcmt.inference.run import Run
from hcmt.sim.driver import simulate
from hcmt.sim.params import DESIGN_KEYS, FIRST_SCENE_KEYS, Design, Settings
from hcmt.sim.sampling import sample_design
from hcmt.training import train
from summaries import fake_summary

pytestmark = pytest.mark.slow  # trained runs, fitted response surfaces, solver verification

FRAMES = IMPACT_DATA["frames"]


def law(d: Design) -> dict:
    """A known power law in the design parameters (exact in log space) for the three stresses / deflection."""
    return {
        "peak_plate_stress_mpa": 700 * (d.thickness / 0.75) ** -0.6 * (d.drop_height / 750) ** 0.45,
        "peak_ball_stress_mpa": 800 * (d.ball_radius / 3.9) ** 0.3 * (d.drop_height / 750) ** 0.5,
        "max_deflection_mm": 0.15 * (d.thickness / 0.75) ** -1.2 * (d.plate_modulus / 7e4) ** -0.5,
        "peak_plate_t95_ms": 0.05 * (d.thickness / 0.75) ** 0.8,
    }


def fitted(n: int = 40, seed: int = 0, noise: float = 0.0) -> tuple[Surrogate, list[Design]]:
    rng = np.random.default_rng(seed)
    designs = [sample_design(rng, "small") for _ in range(n)]
    answers = {
        q: [v * (1 + noise * rng.standard_normal()) for v in (law(d)[q] for d in designs)] for q in law(designs[0])
    }
    return Surrogate.fit(designs, answers, restarts=1), designs


def test_the_gp_recovers_a_known_law_and_its_interval_covers_it():
    s, train_designs = fitted(80, noise=0.005)  # with 40 the ML fit is over-confident (19 / 30 covered)
    assert s.parameters and "thickness" in s.parameters and "ball_poisson" in s.fixed  # held fixed: not an input
    rng = np.random.default_rng(1)
    held = [sample_design(rng, "small") for _ in range(30)]
    out = s.predict(held)
    for q in ("peak_plate_stress_mpa", "max_deflection_mm"):
        err = [abs(o[q].mean / law(d)[q] - 1) for o, d in zip(out, held)]
        covered = sum(o[q].lo <= law(d)[q] <= o[q].hi for o, d in zip(out, held))
        assert np.median(err) < 0.01 and max(err) < 0.05, q
        assert covered >= 27, q  # a 95 % interval covers at least 90 % of 30
        assert all(o[q].lo < o[q].mean < o[q].hi for o in out)
    # far outside the training designs the band widens
    far = s.predict(
        [Design(thickness=1.2, drop_height=1200.0, mesh_size=0.3, plate_half_length=12.0, ball_radius=3.9)]
    )[0]["peak_plate_stress_mpa"]
    inside = out[0]["peak_plate_stress_mpa"]
    assert (far.hi - far.lo) / far.mean > (inside.hi - inside.lo) / inside.mean


def test_stored_as_json_and_loaded_without_an_optimizer_run(tmp_path, monkeypatch):
    s, designs = fitted(20)
    path = s.save(tmp_path / "s.json")
    doc = json.loads(path.read_text())  # plain JSON: no pickle anywhere
    assert doc["format"] == "hcmt-surrogate" and len(doc["designs"]) == 20
    assert set(doc["kernels"]["peak_plate_stress_mpa"]) == {"constant", "length_scales", "noise"}
    assert doc["input_transform"]["kind"] == "log-standardize" and "peak_plate_stress_mpa" in doc["output_transform"]

    def no_optimizer(*args, **kwargs):
        raise AssertionError("the optimizer ran on load")

    monkeypatch.setattr(GaussianProcessRegressor, "_constrained_optimization", no_optimizer)
    loaded = Surrogate.load(path)
    probe = designs[:3] + [Design(thickness=0.9, drop_height=640.0, mesh_size=0.3, plate_half_length=12.0)]
    for a, b in zip(s.predict(probe), loaded.predict(probe)):
        for q in a:
            assert b[q].mean == pytest.approx(a[q].mean, rel=1e-9) and b[q].hi == pytest.approx(a[q].hi, rel=1e-9)


def _damaged(tmp_path, kind: str):
    s, _ = fitted(14)
    path = s.save(tmp_path / "s.json")
    doc = json.loads(path.read_text())
    if kind == "missing":
        path.unlink()
    elif kind == "empty":
        path.write_text("")
    elif kind == "truncated":
        path.write_text(path.read_text()[: len(path.read_text()) // 2])
    elif kind == "binary":
        path.write_bytes(bytes(range(256)) * 4)
    elif kind == "not a surrogate":
        path.write_text(json.dumps({"hello": 1}))
    elif kind == "too few designs":
        doc["designs"] = doc["designs"][:5]
        for q in doc["answers"]:
            doc["answers"][q] = doc["answers"][q][:5]
        path.write_text(json.dumps(doc))
    elif kind == "bad kernel":
        doc["kernels"]["max_deflection_mm"]["length_scales"] = [-1.0]
        path.write_text(json.dumps(doc))
    elif kind == "a list":
        path.write_text("[1, 2, 3]")
    elif kind == "missing key":
        del doc["kernels"]
        path.write_text(json.dumps(doc))
    return path


KINDS = [
    "missing",
    "empty",
    "truncated",
    "binary",
    "not a surrogate",
    "too few designs",
    "bad kernel",
    "a list",
    "missing key",
]


@pytest.mark.parametrize("kind", KINDS)
def test_a_damaged_surrogate_file_is_refused_naming_it(tmp_path, kind):
    path = _damaged(tmp_path, kind)
    with pytest.raises(SurrogateError) as info:
        Surrogate.load(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)
    if kind == "too few designs":
        assert "parameters + 2" in str(info.value)


def test_fuzz_surrogate_files(tmp_path):
    """Random byte flips, truncations and deleted keys of a valid file: it loads or raises SurrogateError."""
    s, _ = fitted(14)
    good = s.save(tmp_path / "good.json").read_bytes()
    rng = np.random.default_rng(0)
    path, cases = tmp_path / "f.json", 0
    doc = json.loads(good)
    for i in range(150):
        kind = i % 3
        if kind == 0:
            b = bytearray(good)
            for j in rng.integers(0, len(b), size=rng.integers(1, 6)):
                b[j] = int(rng.integers(0, 256))
            path.write_bytes(bytes(b))
        elif kind == 1:
            path.write_bytes(good[: int(rng.integers(0, len(good)))])
        else:
            d = json.loads(good)
            keys = sorted(d)
            key = keys[int(rng.integers(0, len(keys)))]
            d[key] = [None, "x", -1.0, {}, [[1.0]]][int(rng.integers(0, 5))]
            path.write_text(json.dumps(d))
        try:
            Surrogate.load(path)
        except SurrogateError as exc:
            assert str(path) in str(exc)
        cases += 1
    assert cases == 150 and doc["format"] == "hcmt-surrogate"


# -- read-outs -----------------------------------------------------------------------------------------------------
def two_body(T: int = 12):
    """A hand-made plate (2 cells, clamped rim node) and ball on the axis; the ball touches during frames 2-5,
    then leaves; the learned stress keeps a 'ghost' larger than the contact peak after it has gone."""
    mesh = np.array(
        [
            [0.0, 0.0],
            [2.0, 0.0],
            [0.0, -0.5],
            [2.0, -0.5],  # plate: top axis node 0, rim 1 and 3
            [0.0, 0.02],
            [0.5, 0.5],
            [0.0, 1.0],
        ]
    )  # ball: lowest axis node 4
    cells = np.array([[0, 2, 3], [0, 3, 1], [4, 5, 6]])
    node_type = np.array([0, 3, 0, 3, 1, 1, 1])
    x = np.repeat(mesh[None], T, 0).copy()
    dip = np.array([0, 0, 0.02, 0.05, 0.06, 0.04, 0.02, 0.0, 0.0, 0.0, 0.0, 0.0])[:T]
    x[:, [0, 2], 1] -= dip[:, None]  # the plate's centre deflects
    x[:, 4:, 1] -= dip[:, None] + 0.02  # the ball rides on it while touching
    x[6:, 4:, 1] += np.arange(1, T - 5)[:, None] * 0.2  # ... and flies off from frame 6
    stress = np.zeros((T, 7, 1))
    stress[2:6, 0, 0] = [200.0, 400.0, 500.0, 300.0]
    stress[8:, 2, 0] = 650.0  # ghost: after the ball has gone
    modulus = np.array([7e4] * 4 + [2e5] * 3)
    return {
        "world_pos": x,
        "stress": stress,
        "mesh_pos": mesh,
        "cells": cells,
        "node_type": node_type,
        "modulus": modulus,
    }


def test_a_bound_on_when_the_ball_leaves_ends_the_window_of_a_lingering_learned_ball():
    """A learned ball that lingers on the plate (frames 2-11) with a late hump (650 MPa at frame 8): the window
    ends at the bound the check passes, so the hump is no peak when the bound lies before it."""
    f = two_body()
    f["world_pos"][6:, 4:, 1] = f["world_pos"][5, 4:, 1]  # the ball stays on the plate
    f["stress"][8, 0, 0] = 650.0
    lingering = ro.summarize_fields(f, 0.002, "contact")
    assert lingering.derived.peak_plate_stress_mpa == 650.0  # its own window holds the hump
    early = ro.summarize_fields(f, 0.002, "contact", contact_end_ms=6 * 0.002)
    late = ro.summarize_fields(f, 0.002, "contact", contact_end_ms=9 * 0.002)
    assert early.derived.peak_plate_stress_mpa == 500.0 and early.derived.peak_plate_frame == 4
    assert late.derived.peak_plate_stress_mpa == 650.0
    assert early.peak_plate_stress_mpa == late.peak_plate_stress_mpa == 650.0  # the model's own: unbounded
    assert ro.CONTACT_END_BOUND in ("lo", "mean", "hi")


def test_the_check_ends_the_window_at_the_surrogates_chosen_bound(monkeypatch):
    """With the contact read-out, check_designs hands it the surrogate's CONTACT_END_BOUND (lower 95 % bound) of
    contact_end_ms; with the default (the model's own outputs) no bound at all."""
    run = Run.load("pretrained:impact_plate_small", "cpu")
    designs = [("a", design_for(run)), ("b", design_for(run, thickness=0.95))]
    seen = {}

    class Stop(Exception):
        pass

    def spy(run_, designs_, **kw):
        seen.update(kw)
        raise Stop

    monkeypatch.setattr(check_module, "predict_chunks", spy)
    with pytest.raises(Stop):
        check_designs(run, designs, progress=False)
    assert seen["contact_end_ms"] is None and seen["readout"] == "raw"
    with pytest.raises(Stop):
        check_designs(run, designs, progress=False, readout="contact")
    intervals = check_module.for_run(run, True)[0].predict([d for _, d in designs])
    assert ro.CONTACT_END_BOUND == "lo"
    assert seen["contact_end_ms"] == [iv["contact_end_ms"].lo for iv in intervals]
    assert all(iv["contact_end_ms"].lo < iv["contact_end_ms"].hi for iv in intervals)


def test_t95_is_the_first_frame_of_a_plateau():
    f = two_body()
    f["stress"][2:6, 0, 0] = [480.0, 499.0, 500.0, 490.0]  # a plateau: 480 >= 0.95 * 500
    s = ro.summarize_fields(f, 0.002, "contact")
    assert s.derived.peak_plate_frame == 4 and s.derived.peak_plate_t95_frame == 2
    assert s.derived.peak_plate_t95_ms == pytest.approx(0.004)


def test_the_solvers_peak_lies_in_its_contact_window():
    design = Design(thickness=0.9, drop_height=900.0, mesh_size=0.3, ball_radius=3.6, plate_half_length=12.0)
    f = simulate(design, Settings(frames=80)).fields
    plate = ro.plate_mask(f["cells"], f["node_type"])
    gap = ro.contact_gap(f["world_pos"], f["mesh_pos"], plate)
    s = ro.summarize_fields(f, 0.002)
    assert gap[0] == pytest.approx(design.gap, abs=1e-6) and gap.min() < 0  # penalty contact penetrates
    window = ro.contact_window(gap)
    assert window[s.peak_plate_frame] and not window[-1]  # a thick plate: the ball has left by frame 79
    assert ro.history_correlation(f["stress"][..., 0], f["stress"][..., 0], s.peak_plate_node) == pytest.approx(1)


# -- calls ---------------------------------------------------------------------------------------------------------
def test_calls_pass_only_below_and_fail_only_above_the_trusted_interval():
    assert call_of(600, 690, 700) == "pass" and call_of(710, 800, 700) == "fail"
    assert call_of(650, 750, 700) == "undecided" and call_of(700, 720, 700) == "undecided"
    summary = fake_summary(
        peak_plate_stress_mpa=760.0, surrogate={"peak_plate_stress_mpa": SurrogateAnswer(680.0, 660.0, 700.0)}
    )
    assert trusted_interval(summary, "surrogate")[:2] == (660, 700)
    assert trusted_interval(summary, "union")[:2] == (660, 760)  # widened to hold the mesh model
    lo, hi, what = trusted_interval(fake_summary(peak_plate_stress_mpa=500.0), "union")  # no surrogate
    assert what == "model" and lo == pytest.approx(500 * (1 - MODEL_BAND)) and hi > 500
    with pytest.raises(ValueError, match="trust"):
        trusted_interval(summary, "best")


@pytest.fixture(scope="module")
def family(tmp_path_factory, tiny_config, impact_data):
    """The test run's 12 generated `small` training trajectories (conftest; enough for 9 varied parameters + 2), a
    tiny HCMT run on them and its surrogate saved as RUN/surrogate.json by the command."""
    root = tmp_path_factory.mktemp("surrogate")
    shutil.copytree(impact_data, root / "data")
    train(tiny_config("train.steps=2", "train.checkpoint_every=2"), root / "data", "hcmt", root / "run", progress=False)
    return root


def test_fit_command_writes_the_runs_surrogate_and_predict_reports_both(family, tmp_path, capsys):
    run, data = family / "run", family / "data"
    assert cli(["predict", str(run), "--design", "thickness=0.7", "--no-progress"]) == 0
    assert "has no response surface" in capsys.readouterr().err  # said in one line when there is none
    assert cli(["surrogate", "fit", str(data), "--out", str(run / "surrogate.json"), "--restarts", "0"]) == 0
    assert "9 parameters" in capsys.readouterr().out
    out = tmp_path / "p.json"
    assert (
        cli(
            [
                "predict",
                str(run),
                "--design",
                "thickness=0.7",
                "--design",
                "thickness=0.9",
                "--yield-mpa",
                "300",
                "--json",
                str(out),
                "--csv",
                str(tmp_path / "p.csv"),
                "--no-progress",
            ]
        )
        == 0
    )
    printed = capsys.readouterr().out
    assert "surrogate MPa [95 %]" in printed and "limit calls for a yield stress of 300 MPa" in printed
    res = json.loads(out.read_text())
    d = res["designs"][0]
    block = d["surrogate"]
    for q in ("peak_plate_stress_mpa", "max_deflection_mm", "peak_ball_stress_mpa"):
        assert block[q]["lo"] < block[q]["mean"] < block[q]["hi"]
    iv = block["peak_plate_stress_mpa"]
    assert d["disagreement"] == (not iv["lo"] <= d["peak_plate_stress_mpa"] <= iv["hi"])
    assert len(d["plate_stress_history_mpa"]) == FRAMES and d["call"] in ("pass", "fail", "undecided")
    assert d["final_call"] == d["call"] and d["verified"] is False and res["surrogate"]
    lo, hi = d["call_interval_mpa"]["lo"], d["call_interval_mpa"]["hi"]
    assert lo <= min(iv["lo"], d["peak_plate_stress_mpa"]) + 1e-9 and hi >= d["peak_plate_stress_mpa"] - 1e-9
    head = (tmp_path / "p.csv").read_text().splitlines()[0].split(",")
    assert {
        "surrogate_peak_plate_stress_mpa_mean",
        "surrogate_peak_plate_stress_mpa_lo",
        "call",
        "final_call",
        "disagreement",
    } <= set(head) and "plate_stress_history_mpa" not in head
    # the same surrogate by file, then none
    assert (
        cli(
            [
                "predict",
                str(run),
                "--design",
                "thickness=0.7",
                "--surrogate",
                str(run / "surrogate.json"),
                "--json",
                str(out),
                "--no-progress",
            ]
        )
        == 0
    )
    assert "surrogate" in json.loads(out.read_text())["designs"][0]
    assert (
        cli(["predict", str(run), "--design", "thickness=0.7", "--no-surrogate", "--json", str(out), "--no-progress"])
        == 0
    )
    assert "surrogate" not in json.loads(out.read_text())["designs"][0]
    # the Python API runs the same check
    (p,) = predict_designs(Run.load(run, "cpu"), [("x", Design(**d["design"]))], progress=False)
    assert p.summary.surrogate["peak_plate_stress_mpa"].mean == pytest.approx(iv["mean"], rel=1e-9)


def test_verify_auto_runs_the_solver_on_the_undecided_designs_only(family, tmp_path, capsys):
    run = Run.load(family / "run", "cpu")
    lo_t, hi_t = run.ranges["thickness"]  # inside the training ranges: a design outside them gets no decided call
    designs = [(f"d{i}", design_for(run, thickness=lo_t + u * (hi_t - lo_t))) for i, u in enumerate((0.2, 0.8))]
    probe = check_designs(run, designs, progress=False)
    lo, hi = (min(trusted_interval(p.summary)[k] for p in probe.preds) for k in (0, 1))
    never = check_designs(run, designs, verify="auto", yield_mpa=hi * 2, progress=False)
    assert never.solver_runs == 0 and all(p.summary.final_call == "pass" for p in never.preds)
    assert all(p.summary.verified is False for p in never.preds)
    first = probe.preds[0].summary
    y = 0.5 * sum(trusted_interval(first)[:2])  # inside design 0's trusted interval: undecided
    auto = check_designs(run, designs, verify="auto", yield_mpa=y, progress=False)
    a = auto.preds[0].summary
    assert a.call == "undecided" and a.verified is True and auto.truth[0] is not None
    assert a.final_call == ("pass" if a.verify.solver_peak_plate_stress_mpa < y else "fail")
    assert auto.solver_runs == sum(p.summary.call == "undecided" for p in auto.preds)
    assert a.solver_plate_stress_history_mpa is not None
    # refused without a yield stress, in one line
    assert cli(["predict", str(family / "run"), "--design", "thickness=0.7", "--verify", "auto", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--yield-mpa" in err[0]


def test_sweep_reports_the_final_minimum_and_the_solver_runs(family, tmp_path, capsys):
    out = tmp_path / "s.json"
    assert (
        cli(
            [
                "sweep",
                str(family / "run"),
                "--vary",
                "thickness=0.6:0.9:3",
                "--yield-mpa",
                "400",
                "--verify",
                "auto",
                "--out",
                str(tmp_path / "plot"),
                "--json",
                str(out),
                "--no-progress",
            ]
        )
        == 0
    )
    printed = capsys.readouterr().out
    assert "final calls" in printed and "limit calls for a yield stress of 400 MPa" in printed
    res = json.loads(out.read_text())
    final = res["sweep"]["limit"]["final"]
    assert final["solver_runs"] == res["solver_runs"] == sum(d["verified"] for d in res["designs"])
    assert final["calls"] == [d["final_call"] for d in res["designs"]]
    # ball_poisson was held fixed in training: a sweep over it says the trend is not learned
    assert (
        cli(
            [
                "sweep",
                str(family / "run"),
                "--vary",
                "ball_poisson=0.2:0.4:2",
                "--out",
                str(tmp_path / "plot"),
                "--no-surrogate",
                "--no-progress",
            ]
        )
        == 0
    )
    assert "held ball_poisson fixed" in capsys.readouterr().out


def test_a_surrogate_of_other_parameters_is_refused(family, tmp_path, capsys):
    s, _ = fitted(14)
    doc = s.to_dict()
    doc["parameters"] = doc["parameters"][:-1]
    doc["designs"] = [row[:-1] for row in doc["designs"]]
    for k in doc["kernels"].values():
        k["length_scales"] = k["length_scales"][:-1]
    (tmp_path / "other.json").write_text(json.dumps(doc))
    assert (
        cli(
            [
                "predict",
                str(family / "run"),
                "--design",
                "thickness=0.7",
                "--surrogate",
                str(tmp_path / "other.json"),
                "--no-progress",
            ]
        )
        == 2
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "other.json" in err[0] and "surrogate takes" in err[0]
    for kind in ("truncated", "not a surrogate"):
        path = _damaged(tmp_path, kind)
        assert (
            cli(
                ["predict", str(family / "run"), "--design", "thickness=0.7", "--surrogate", str(path), "--no-progress"]
            )
            == 2
        )
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and str(path) in err[0] and "Traceback" not in err[0]


def test_the_shipped_model_carries_its_surrogate():
    run = Run.load("pretrained:impact_plate_small", "cpu")
    s, note, ends_window = for_run(run)
    assert note is None and ends_window and len(s) == run.meta["generator"]["counts"]["train"]  # its training runs
    assert s.ranges()["thickness"] == pytest.approx(run.ranges["thickness"])
    (a,) = s.predict([design_for(run, thickness=0.6, drop_height=600)])
    assert 500 < a["peak_plate_stress_mpa"].mean < 1200 and a["max_deflection_mm"].lo > 0


@pytest.mark.parametrize("damage", ["huge constant", "huge integer", "nested", "no parameters"])
def test_numbers_no_float_holds_are_refused_too(tmp_path, damage):
    s, _ = fitted(14)
    path = s.save(tmp_path / "s.json")
    text = path.read_text()
    doc = json.loads(text)
    if damage == "huge constant":
        doc["kernels"]["peak_plate_stress_mpa"]["constant"] = 1e300
        path.write_text(json.dumps(doc))
    elif damage == "huge integer":
        doc["designs"][0][0] = 10**400  # valid JSON, no float holds it
        path.write_text(json.dumps(doc))
    elif damage == "nested":
        path.write_text("[" * 100000)
    else:
        doc["parameters"], doc["designs"] = [], [[] for _ in doc["designs"]]
        for k in doc["kernels"].values():
            k["length_scales"] = []
        path.write_text(json.dumps(doc))
    with pytest.raises(SurrogateError) as info:
        Surrogate.load(path)
    assert str(path) in str(info.value)


def test_json_output_is_standard_json():
    assert finite({"a": float("nan"), "b": [1.0, float("inf")], "c": "x"}) == {"a": None, "b": [1.0, None], "c": "x"}


def test_zero_valued_family_parameters_enter_linearly_and_other_families_are_not_taken(tmp_path):
    """A mix of mono and ring designs: support_radius is 0 for half of them, so it enters linearly (log(0) would
    be -inf) and the fit is finite; a law that jumps with the ring is learned; a pen design (pen_tip_radius held
    at 0 over the training designs) is named by cannot_take, and the JSON round trip keeps the linear inputs."""
    rng = np.random.default_rng(4)
    designs = [sample_design(rng, "small", family=("mono", "ring")[i % 2]) for i in range(60)]

    def ring_law(d):
        return {q: v * (1.5 if d.support_radius > 0 else 1.0) for q, v in law(d).items()}

    answers = {q: [ring_law(d)[q] for d in designs] for q in law(designs[0])}
    s = Surrogate.fit(designs, answers, restarts=1)
    assert "support_radius" in s.linear and "thickness" not in s.linear
    held = [sample_design(rng, "small", family=f) for f in ("mono", "ring") * 5]
    err = [
        abs(o["peak_plate_stress_mpa"].mean / ring_law(d)["peak_plate_stress_mpa"] - 1)
        for o, d in zip(s.predict(held), held)
    ]
    assert np.median(err) < 0.05
    pen = sample_design(rng, "small", family="pen")
    assert set(s.cannot_take(pen)) == {"pen_tip_radius", "pen_mass"}
    assert s.cannot_take(held[1]) == []
    back = Surrogate.load(s.save(tmp_path / "s.json"))
    assert back.linear == s.linear
    np.testing.assert_allclose(
        back.predict(held)[3]["peak_plate_stress_mpa"].mean, s.predict(held)[3]["peak_plate_stress_mpa"].mean, rtol=1e-9
    )


def test_a_surrogate_of_the_first_scene_cannot_take_family_parameters():
    """The shipped surrogate was fitted before the families: their parameters count as held at the default."""
    s, designs = fitted(20)
    first = {k: v for k, v in s.fixed.items() if k in DESIGN_KEYS[:FIRST_SCENE_KEYS]}
    old = Surrogate(s.parameters, first, s.X, s.Y, s.kernels)  # as a surrogate stored before the families
    for sur in (s, old):
        assert sur.cannot_take(replace(designs[0], pen_tip_radius=0.8)) == ["pen_tip_radius"]
        assert sur.cannot_take(replace(designs[0], layer2_thickness=0.1)) == ["layer2_thickness"]
        assert sur.cannot_take(designs[1]) == []


def test_few_designs_fit_only_when_not_strict():
    rng = np.random.default_rng(2)
    designs = [sample_design(rng, "small") for _ in range(5)]
    answers = {q: [law(d)[q] for d in designs] for q in law(designs[0])}
    with pytest.raises(ValueError, match="at least parameters \\+ 2"):
        Surrogate.fit(designs, answers)
    s = Surrogate.fit(designs, answers, strict=False, restarts=0)
    assert s.underdetermined and np.isfinite(s.predict(designs[:1])[0]["peak_plate_stress_mpa"].mean)
