"""The design check is as safe as training: strict --designs CSVs (with a fuzz test), results that carry
their warnings and model, rollouts and metrics keyed by dataset, options checked before the cache, cost refusal,
one-line interrupts, incomplete datasets, model cards with ranges, pictures, confidence notes."""

import csv
import io
import json
import random
import shutil

import numpy as np
import pytest

import hcmt.cli.design as cli_design
import hcmt.viz.contours as viz_contours
from conftest import IMPACT_DATA
from hcmt.cli import main as cli
from hcmt.design.check import Prediction, check_designs, cost_check, weak_reasons
from hcmt.design.inputs import confidence, read_designs_csv, region_of
from hcmt.design.reports import contour_picture
from hcmt.inference.run import Run
from hcmt.sim.params import DESIGN_KEYS, Design, Settings, parse_design
from hcmt.sim.sampling import middle_design
from hcmt.training import train
from hcmt.viz.contours import axis_names, shared_norm
from hcmt.viz.rollouts import load_case
from summaries import fake_summary

pytestmark = pytest.mark.slow  # trained runs and solver verification

FRAMES = IMPACT_DATA["frames"]


@pytest.fixture(scope="module")
def setup(tmp_path_factory, tiny_config, impact_data):
    root = tmp_path_factory.mktemp("safety")
    gen = [
        "generate",
        "impact-plate",
        "--preset",
        "small",
        "--train",
        "2",
        "--valid",
        "0",
        "--test",
        "1",
        "--no-progress",
    ]
    shutil.copytree(impact_data, root / "data")  # the test run's dataset (conftest), a copy this module may change
    assert cli([*gen[:2], str(root / "other"), *gen[2:], "--seed", "2", "--frames", str(FRAMES)]) == 0
    assert (
        cli([*gen[:2], str(root / "coarse_dt"), *gen[2:], "--seed", "1", "--frames", "4", "--frame-dt", "0.004"]) == 0
    )
    train(tiny_config("train.steps=2", "train.checkpoint_every=2"), root / "data", "mgn", root / "run", progress=False)
    return root


def _one_line_error(capsys, rc):
    err = [l for l in capsys.readouterr().err.strip().splitlines() if ": warning: " not in l]
    assert rc == 2 and len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


# -- 1. designs CSV --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "text,message",
    [
        ("name,thickness,drop_height\na,0.8,900\nb,0.8,\n", "line 3, column 3 (drop_height): missing value"),
        ("name,thickness,drop_height\na,0.8,900,5\n", "line 2: 4 values for 3 columns"),
        ("name,thickness\na,0.8\nb,-0.8\n", "line 3, column 2 (thickness) must be > 0"),
        ("name,thick\na,0.8\n", "line 1, column 2: unknown column 'thick'"),
        ("name,thickness\na,inf\n", "line 2, column 2 (thickness) must be a finite number"),
        ("name,thickness\na,thin\n", "line 2, column 2 (thickness) must be a number, got 'thin'"),
        (
            "name,thickness,thickness\na,0.7,0.8\n",
            "line 1, column 3: the column 'thickness' appears twice (columns 2 and 3)",
        ),
        ("name,thickness\n", "a header but no designs"),
    ],
)
def test_bad_designs_csv_is_refused_naming_file_line_and_column(setup, tmp_path, capsys, text, message):
    path = tmp_path / "d.csv"
    path.write_text(text)
    msg = _one_line_error(capsys, cli(["predict", str(setup / "run"), "--designs", str(path), "--no-progress"]))
    assert str(path) in msg and message in msg


def test_bom_crlf_and_blank_lines_are_read(setup):
    path = setup / "ok.csv"
    path.write_bytes("\ufeffname,thickness\r\n\r\na,0.7\r\n\r\nb,0.9\r\n".encode("utf-8"))
    designs = read_designs_csv(path, Design())
    assert [(n, d.thickness) for n, d in designs] == [("a", 0.7), ("b", 0.9)]


def test_fuzz_designs_csv(setup, tmp_path, capsys):
    """Random damage to a good CSV: every case exits 0 with the designs it holds, or 2 with one line."""
    rng = random.Random(0)
    run = Run.load(setup / "run", "cpu")
    good = [["name", "thickness", "drop_height"], ["a", "0.7", "800"], ["b", "0.9", "600"]]
    damages = ["delete", "extra", "word", "blank", "bom", "crlf", "nan", "empty"]
    for case in range(40):
        rows = [list(r) for r in good]
        for _ in range(rng.randint(1, 2)):
            kind, r = rng.choice(damages), rng.randrange(len(rows))
            if kind == "delete" and rows[r]:
                rows[r].pop(rng.randrange(len(rows[r])))
            elif kind == "extra":
                rows[r].append("1.0")
            elif kind == "word" and rows[r]:
                rows[r][rng.randrange(len(rows[r]))] = "abc"
            elif kind == "blank":
                rows.insert(r, [])
            elif kind == "nan" and rows[r]:
                rows[r][-1] = "nan"
            elif kind == "empty" and rows[r]:
                rows[r][-1] = ""
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\r\n" if rng.random() < 0.3 else "\n").writerows(rows)
        text = ("\ufeff" if rng.random() < 0.3 else "") + buf.getvalue()
        path = tmp_path / f"f{case}.csv"
        path.write_text(text, encoding="utf-8")
        try:
            designs = read_designs_csv(path, middle_design(run.meta))
        except ValueError as exc:
            assert "\n" not in str(exc) and str(path) in str(exc)
            continue
        # accepted: then it holds exactly the good rows' values (a damaged name is still a name)
        got = [(d.thickness, d.drop_height) for _, d in designs]
        assert got == [(0.7, 800.0), (0.9, 600.0)], (text, got)


# -- 2 / 9. results carry warnings and model; numeric CSV -------------------------------------------------------
def test_json_and_csv_carry_warnings_model_and_full_precision(setup, tmp_path):
    rc = cli(
        [
            "predict",
            str(setup / "run"),
            "--design",
            "thickness=5",
            "--design",
            "thickness=0.7",
            "--json",
            str(tmp_path / "o.json"),
            "--csv",
            str(tmp_path / "o.csv"),
            "--device",
            "cpu",
            "--no-progress",
        ]
    )
    assert rc == 0
    res = json.loads((tmp_path / "o.json").read_text())
    first, second = res["designs"]
    assert first["model"] == str(setup / "run")
    assert any("thickness = 5 is outside" in w for w in first["warnings"])
    assert not any(w.startswith("thickness = 5") for w in second["warnings"])
    with open(tmp_path / "o.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert float(rows[0]["peak_plate_stress_mpa"]) == first["peak_plate_stress_mpa"]  # every digit
    assert float(rows[0]["peak_plate_r_mm"]) == first["peak_plate_where_mm"][0]
    assert float(rows[0]["thickness"]) == 5.0 and "thickness = 5 is outside" in rows[0]["warnings"]
    assert "thickness = 5" not in rows[1]["warnings"]
    for k in ("max_deflection_mm", "wall_s", "peak_plate_when_ms"):
        float(rows[1][k])  # numbers, not display strings


# -- 3 / 4. evaluate: keyed by dataset, dt refused, options before the cache ------------------------------------
def test_evaluating_another_dataset_never_overwrites_the_runs_own(setup, capsys):
    run = setup / "run"
    assert cli(["evaluate", str(run), "--data", str(setup / "data"), "--split", "test", "--no-progress"]) == 0
    own = json.loads((run / "metrics_test.json").read_text())
    capsys.readouterr()
    assert cli(["evaluate", str(run), "--data", str(setup / "other"), "--split", "test", "--no-progress"]) == 0
    assert json.loads((run / "metrics_test.json").read_text()) == own
    other = json.loads((run / "metrics_test@other.json").read_text())
    assert other["data"].endswith("other") and (run / "rollout_test@other.h5").is_file()
    assert (run / "rollout_test.h5").is_file()
    table = capsys.readouterr()
    assert "metrics_test@other.json" in table.out


def test_a_dataset_of_another_frame_interval_is_refused_before_any_work(setup, capsys):
    run = setup / "run"
    for command in ("evaluate", "rollout"):
        msg = _one_line_error(capsys, cli([command, str(run), "--data", str(setup / "coarse_dt"), "--no-progress"]))
        assert "0.004" in msg and "0.002" in msg and "dt" in msg
    assert not (run / "rollout_test@coarse_dt.h5").exists()


def test_options_are_checked_before_the_cache(setup, capsys):
    run = setup / "run"
    assert cli(["evaluate", str(run), "--data", str(setup / "data"), "--no-progress"]) == 0  # cache now exists
    capsys.readouterr()
    msg = _one_line_error(capsys, cli(["evaluate", str(run), "--data", str(setup / "data"), "--device", "tpu"]))
    assert "--device 'tpu'" in msg
    msg = _one_line_error(capsys, cli(["evaluate", str(run), "--data", str(setup / "data"), "--batch", "0"]))
    assert "--batch" in msg


# -- 5. cost refusal -------------------------------------------------------------------------------------------
def test_predict_refuses_a_mesh_far_beyond_the_training_data(setup):
    run = Run.load(setup / "run", "cpu")
    fine = [("fine", parse_design(["mesh_size=0.02"], middle_design(run.meta)))]
    with pytest.raises(ValueError, match=r"fine: about .* nodes at mesh_size 0.02 .*exceeds 600 s.*--force"):
        cost_check(run, fine, Settings(frames=90), verify=False, force=False)
    cost_check(run, fine, Settings(frames=90), verify=False, force=True)  # forced: no refusal
    finer = [("finer", parse_design(["mesh_size=0.005"], middle_design(run.meta)))]
    with pytest.raises(ValueError, match=r"finer: the design's mesh would have .* nodes"):
        cost_check(run, finer, Settings(frames=90), verify=False, force=True)  # too large to build at all
    cost_check(run, [("ok", middle_design(run.meta))], Settings(frames=90), verify=True, force=False)


# -- 6. Ctrl-C -------------------------------------------------------------------------------------------------
def test_interrupt_says_what_happened(setup, capsys, monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt()

    monkeypatch.setattr(cli_design, "check_designs", interrupted)
    rc = cli(["predict", str(setup / "run"), "--design", "thickness=0.7", "--no-progress"])
    err = [l for l in capsys.readouterr().err.strip().splitlines() if ": warning: " not in l]
    assert rc == 130 and len(err) == 1 and err[0].startswith("hcmt predict: interrupted; nothing half-written")


# -- 7. incomplete dataset -------------------------------------------------------------------------------------
def test_info_on_an_interrupted_generate(setup, tmp_path, capsys):
    folder = tmp_path / "half"
    folder.mkdir()
    (folder / "meta.json").write_text((setup / "data" / "meta.json").read_text())
    (folder / ".parts").mkdir()
    msg = _one_line_error(capsys, cli(["info", str(folder)]))
    assert "incomplete dataset" in msg and "rerun the same `hcmt generate` command" in msg


# -- 8. models -------------------------------------------------------------------------------------------------
def test_models_lists_design_parameters_and_ranges(capsys):
    assert cli(["models", "--json"]) == 0
    cards = json.loads(capsys.readouterr().out)
    if not cards:
        pytest.skip("no shipped model")
    card = next(iter(cards.values()))
    assert set(card["design_parameters"]) == set(DESIGN_KEYS)
    lo, hi = card["design_parameters"]["thickness"]["training_range"]
    assert 0 < lo < hi and card["window"]["frames"] > 2
    assert cli(["models"]) == 0
    assert "thickness" in capsys.readouterr().out


# -- 10. --no-progress and help --------------------------------------------------------------------------------
@pytest.mark.parametrize("command", ["rollout", "evaluate", "plot", "export", "demo", "predict", "sweep"])
def test_no_progress_is_everywhere(command, capsys):
    with pytest.raises(SystemExit):
        cli([command, "--help"])
    out = capsys.readouterr().out
    assert "--no-progress" in out and "--threads" in out
    if command == "demo":
        assert "shipped HCMT model beside the solver" in out


# -- 12. pictures ----------------------------------------------------------------------------------------------
def test_pictures_name_r_and_stress_has_no_below_zero_arrow(setup):
    run = setup / "run"
    case = load_case([Run.load(run, "cpu")], setup / "data", "test", 0, progress=False)
    assert axis_names(case) == ("r", "y")  # the generator's axisymmetric scene
    case.predictions[0].stress = case.predictions[0].stress - 50.0  # a model predicting negative von Mises
    norm, extend = shared_norm(case, [FRAMES - 1], "stress")
    assert norm.vmin == 0 and extend in ("neither", "max")


def test_contour_pair_shows_both_peaks(setup, monkeypatch):
    seen = {}
    monkeypatch.setattr(viz_contours, "plot_contours", lambda case, out, frames: seen.setdefault("f", frames) or [out])
    run = Run.load(setup / "run", "cpu")
    check = check_designs(
        run, [("d", parse_design(["thickness=0.7"], middle_design(run.meta)))], verify=True, progress=False
    )
    p, t = check.preds[0], check.truth[0]
    contour_picture(p, t, run.meta, setup / "img", "MGN")
    want = sorted({max(p.summary.peak_plate_frame, 1), max(t.summary.peak_plate_frame, 1)})
    assert seen["f"] == want


# -- 13. confidence ----------------------------------------------------------------------------------------------
def test_confidence_regions_and_the_weak_note():
    ranges = {"thickness": (0.5, 1.0), "drop_height": (500.0, 1000.0)}
    assert region_of(Design(thickness=0.55, drop_height=700), ranges) == "thin"
    assert region_of(Design(thickness=0.8, drop_height=950), ranges) == "high"
    assert region_of(Design(thickness=0.55, drop_height=950), ranges) == "thin+high"
    assert region_of(Design(thickness=0.8, drop_height=700), ranges) == "inside"
    assert region_of(Design(thickness=2.0, drop_height=700), ranges) == "outside"

    class FakeRun:
        card = {
            "confidence": [
                {
                    "region": "thin",
                    "label": "thin plates",
                    "designs": 5,
                    "peak_plate_stress_error_pct_median": 18.0,
                    "peak_plate_stress_error_pct_worst": -40.0,
                },
                {
                    "region": "inside",
                    "label": "inside",
                    "designs": 20,
                    "peak_plate_stress_error_pct_median": 4.0,
                    "peak_plate_stress_error_pct_worst": 9.0,
                },
            ]
        }

    FakeRun.ranges = ranges
    thin = Prediction("t", Design(thickness=0.55, drop_height=700), *([np.zeros(1)] * 5), wall_s=1.0)
    inside = Prediction("i", Design(thickness=0.8, drop_height=700), *([np.zeros(1)] * 5), wall_s=1.0)
    for p in (thin, inside):
        p.summary = fake_summary(confidence=confidence(p.design, FakeRun))
    assert "median peak plate stress error of 18.0 %" in weak_reasons(thin)[0]
    assert weak_reasons(inside) == []
