"""Bad input, round 4: unit slips and far-out designs never end in a decided call, and the Python API refuses
arguments of the wrong type in one line naming the parameter.

(a) a yield stress typed in Pa, kPa or GPa for MPa (or scaled by 1e-6 .. 1e6) is refused naming ``--yield-mpa``,
    its unit and its span, before the model loads; one that slips through the span, and a design value off by
    orders of magnitude (metres for mm), never gets a ``pass``;
(b) a design outside the model's training ranges (each parameter and combinations, up to ten times its range) gets
    no ``pass`` / ``fail`` from the model or the response surface: its call is ``undecided`` and ``--verify auto``
    gives it to the solver, whose call is the final one;
(c) the API's arguments: a model given as text or None, a yield stress as text or a bool, a numpy integer batch,
    ``Settings(frames="8")``, ``settings=dict(...)``."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import asdict, replace
from types import SimpleNamespace

import numpy as np
import pytest

import hcmt
import hcmt.cli.design
import hcmt.design.check as check_module
from hcmt.cli import main as cli
from hcmt.design.calls import add_calls, final_calls
from hcmt.design.check import check_designs, check_options, predict_designs, solve_chunk
from hcmt.design.inputs import design_for, range_warnings, region_of, with_family_defaults
from hcmt.design.prediction import check_design_list
from hcmt.design.summary import Confidence, SurrogateAnswer
from hcmt.design.sweep import analyse, sweep
from hcmt.errors import InputError
from hcmt.sim.params import DESIGN_KEYS, DESIGN_UNITS, Design, Settings, design_values
from hcmt.sim.sampling import RANGES, preset_design
from refusals import refused
from summaries import fake_summary

MODEL = "pretrained:impact_plate_small"
#: the shipped model's training preset: the ranges of the stand-in checks (the shipped run's own are a little inside)
TRAINED = with_family_defaults(dict(RANGES["small"]))
SCALES = (1e-6, 1e-3, 1e3, 1e6)


@pytest.fixture
def no_model(monkeypatch):
    """The command's own work (which loads torch and the model) is never reached: a refusal came first."""

    def reached(args):
        raise AssertionError("the command ran: its options were not refused before the model loads")

    monkeypatch.setattr(hcmt.cli.design, "main_predict", reached)
    monkeypatch.setattr(hcmt.cli.design, "main_sweep", reached)


@pytest.fixture(scope="module")
def shipped():
    return hcmt.load_pretrained("impact_plate_small", "cpu")


def stand_in(design: Design, peak: float, surrogate: tuple[float, float, float] | None = None) -> SimpleNamespace:
    """A prediction as the calls read it: the design, the mesh model's peak and the surrogate's (mean, lo, hi)."""
    answers = {"peak_plate_stress_mpa": SurrogateAnswer(*map(float, surrogate))} if surrogate else None
    summary = fake_summary(peak_plate_stress_mpa=float(peak), max_deflection_mm=0.2, surrogate=answers)
    return SimpleNamespace(name="p", design=design, summary=summary)


# -- (a) unit slips ------------------------------------------------------------------------------------------------
def slipped_yields(rng: np.random.Generator) -> list[tuple[float, str | None]]:
    """(typed value, the unit it was typed in when a plain confusion): plausible yield stresses (150 to 5,000 MPa)
    typed in Pa, kPa or GPa, and scaled by each of :data:`SCALES`."""
    out = []
    for y in rng.uniform(150, 5000, 4):
        out += [(y * 1e6, "Pa"), (y * 1e3, "kPa"), (y / 1e3, "GPa")]
        out += [(y * s, None) for s in SCALES]
    return out


def test_a_yield_stress_in_the_wrong_unit_is_refused_before_the_model_loads(capsys, no_model):
    from hcmt.design.basics import YIELD_SPAN_MPA

    lo, hi = YIELD_SPAN_MPA
    for command in (["predict", MODEL, "--design", "thickness=0.7"], ["sweep", MODEL, "--vary", "thickness=0.6:0.9:3"]):
        for typed, unit in slipped_yields(np.random.default_rng(41)):
            if lo <= typed <= hi:  # a scale that lands inside the span: the call below never passes it
                continue
            line = refused(capsys, [*command, "--yield-mpa", str(float(typed))])
            assert line.startswith(f"hcmt {command[0]}: error: --yield-mpa ") and " MPa " in line, line
            assert f"from {lo:g} to {hi:,.0f}" in line, line
            if unit is not None:  # the likely value in MPa, in the unit it was typed in
                assert f"{unit}: {typed * {'Pa': 1e-6, 'kPa': 1e-3, 'GPa': 1e3}[unit]:.6g} MPa" in line, line


def test_the_issues_pa_for_mpa_is_refused_with_the_likely_value(capsys, no_model):
    line = refused(capsys, ["predict", MODEL, "--design", "thickness=0.55", "drop_height=950", "--yield-mpa", "7.5e8"])
    assert "--yield-mpa" in line and "MPa" in line and "it looks like Pa: 750 MPa?" in line


@pytest.mark.slow  # a fresh interpreter
def test_a_slipped_yield_is_refused_before_torch_loads():
    script = (
        "import json, sys\nfrom hcmt.cli import main\n"
        f"rc = main(['predict', {MODEL!r}, '--design', 'thickness=0.7', '--yield-mpa', '7.5e8'])\n"
        "print(json.dumps([rc, [m for m in ('torch', 'scipy', 'sklearn') if m in sys.modules]]))\n"
    )
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert json.loads(r.stdout.splitlines()[-1]) == [2, []], r.stdout[-300:]  # refused, nothing heavy loaded
    assert "--yield-mpa" in r.stderr and len(r.stderr.splitlines()) == 1


def test_the_api_refuses_a_slipped_yield_naming_it(shipped):
    from hcmt.design.basics import YIELD_SPAN_MPA

    lo, hi = YIELD_SPAN_MPA
    designs = [("a", design_for(shipped, thickness=0.7))]
    base = preset_design("small")
    for typed, _ in slipped_yields(np.random.default_rng(42)):
        if lo <= typed <= hi:
            continue
        for run_it in (
            lambda: predict_designs(shipped, designs, yield_mpa=typed, progress=False),
            lambda: sweep(shipped, "thickness", 0.6, 0.9, 3, base, yield_mpa=typed, progress=False),
        ):
            with pytest.raises(InputError) as exc:
                run_it()
            assert exc.value.param == "yield_mpa" and "MPa" in str(exc.value) and len(str(exc.value)) < 300


def test_a_slipped_yield_inside_the_span_never_passes():
    """A yield stress scaled down into the span (1,500 MPa typed as 1.5) is far below any peak: never a pass."""
    rng = np.random.default_rng(43)
    from hcmt.design.basics import YIELD_SPAN_MPA

    for typed, _ in slipped_yields(rng):
        if not YIELD_SPAN_MPA[0] <= typed <= YIELD_SPAN_MPA[1] or typed > 150:
            continue
        peak = rng.uniform(300, 1500)
        p = stand_in(preset_design("small"), peak, (peak, 0.9 * peak, 1.1 * peak))
        add_calls([p], check_options([("a", p.design)], False, typed, 1, "raw"))
        assert p.summary.call != "pass", (typed, peak)


def slipped_designs() -> list[tuple[str, float]]:
    """(parameter, value): each length, modulus, density and the drop height of the preset's middle design scaled
    by each of :data:`SCALES` (metres or µm for mm, Pa or GPa for MPa, ...)."""
    base = asdict(preset_design("small"))
    keys = [k for k in RANGES["small"] if DESIGN_UNITS[k] != "-" and RANGES["small"][k][0] != RANGES["small"][k][1]]
    return [(k, base[k] * s) for k in keys for s in SCALES]


def test_a_design_value_off_by_orders_of_magnitude_is_refused_or_warned_with_its_unit_and_never_passes():
    """Through the command's parse (``--design K=V``) and the check's calls: a slipped value is refused (an
    impossible design), or warned in one line naming its unit, and its call is undecided even where the trusted
    interval lies far below the yield stress."""
    base = preset_design("small")
    accepted = 0
    for key, value in slipped_designs():
        try:
            design = replace(base, **design_values([f"{key}={value!r}"])).validate()
        except InputError:
            continue  # refused: thickness 0.0008 mm is thinner than the mesh
        accepted += 1
        warning = [w for w in range_warnings(design, TRAINED) if w.startswith(f"{key} = ")]
        assert len(warning) == 1 and DESIGN_UNITS[key] in warning[0] and len(warning[0]) < 300, (key, value)
        assert "looks like" in warning[0] or "unit slip" in warning[0], warning[0]
        p = stand_in(design, 500.0, (500.0, 450.0, 550.0))
        add_calls([p], 5000.0, ranges=TRAINED)  # the interval says pass; the design is far outside
        assert p.summary.call == "undecided" and p.summary.call_interval_mpa.trusted is False, (key, value)
    assert accepted >= 10


@pytest.mark.slow  # the shipped model on a few designs through the command
def test_the_command_never_passes_a_slipped_design_value(tmp_path, capsys):
    out = tmp_path / "p.json"
    for item in ("drop_height=0.7", "drop_height=700000", "thickness=0.0008", "plate_modulus=70"):
        rc = cli(
            [
                "predict",
                MODEL,
                "--design",
                "thickness=0.6",
                item,
                "--yield-mpa",
                "5000",
                "--json",
                str(out),
                "--no-progress",
                "--device",
                "cpu",
            ]
        )
        err = capsys.readouterr().err.strip().splitlines()
        if rc == 2:
            assert len(err) == 1 and not out.exists(), err
            continue
        key = item.split("=")[0]
        assert rc == 0 and any(f"{key} = " in line and DESIGN_UNITS[key] in line for line in err), err
        (d,) = json.loads(out.read_text())["designs"]
        assert d["call"] == d["final_call"] == "undecided", d["call"]
        out.unlink()


# -- (b) far-out designs -------------------------------------------------------------------------------------------
def far_out(rng: np.random.Generator, n: int) -> list[Design]:
    """``n`` valid designs with 1 to 3 of the preset's varied parameters outside the training ranges, each up to ten
    times its range beyond the nearer end (the others drawn inside)."""
    ranges = {k: r for k, r in RANGES["small"].items() if r[0] != r[1]}
    keys, out = sorted(ranges), []
    while len(out) < n:
        values = {k: lo + (hi - lo) * rng.random() for k, (lo, hi) in ranges.items()}
        for k in rng.choice(keys, size=rng.integers(1, 4), replace=False):
            lo, hi = ranges[k]
            beyond = (hi - lo) * rng.uniform(0.05, 10.0)
            values[k] = hi + beyond if rng.random() < 0.5 or lo - beyond <= 0 else lo - beyond
        try:
            out.append(replace(preset_design("small"), **values).validate())
        except InputError:
            continue  # an impossible design (a mesh coarser than the plate, a Poisson ratio past 0.5)
    return out


def test_a_far_out_design_is_never_decided_without_the_solver(monkeypatch):
    """Whatever the intervals say (all below the yield stress, all above, straddling), a design outside the
    training ranges is undecided; ``verify="auto"`` sends it to the solver and the final call is the solver's."""
    rng = np.random.default_rng(44)
    designs = far_out(rng, 36)
    assert all(region_of(d, TRAINED) == "outside" for d in designs)
    preds = []
    for d in designs:
        peak = rng.uniform(100, 3000)
        lo, hi = sorted(rng.uniform(0.5, 1.5, 2) * peak)
        preds.append(stand_in(d, peak, (0.5 * (lo + hi), lo, hi) if rng.random() < 0.8 else None))
    for y in (1.0, float(rng.uniform(200, 2000)), 1e5):  # below every interval, among them, above every one
        add_calls(preds, y, ranges=TRAINED)
        assert {p.summary.call for p in preds} == {"undecided"}, y
        final_calls(preds, None, y)
        assert {p.summary.final_call for p in preds} == {"undecided"}
    solved, y = [], 1000.0
    monkeypatch.setattr(
        check_module,
        "solve",
        lambda items, *a, **k: (
            solved.extend(n for n, _ in items)
            or [SimpleNamespace(summary=fake_summary(peak_plate_stress_mpa=2.0 * y)) for _ in items]
        ),
    )  # the solver: all fail
    add_calls(preds, y, ranges=TRAINED)
    named = [SimpleNamespace(name=f"d{i}", design=p.design, summary=p.summary) for i, p in enumerate(preds)]
    truth = solve_chunk(named, "auto", Settings(), "stress", SimpleNamespace(total=0, refresh=lambda: None))
    assert solved == [p.name for p in named]
    final_calls(named, truth, y)
    assert {p.summary.final_call for p in named} == {"fail"}  # the solver's, 2 y > y


def test_a_summary_that_records_an_outside_region_is_undecided_too():
    """Without the run's ranges the calls read the region the check recorded (``confidence``)."""
    for call_yield in (1.0, 1e5):
        p = stand_in(Design(), 500.0, (500.0, 450.0, 550.0))
        p.summary = replace(p.summary, confidence=Confidence("outside", "outside the training ranges", 0))
        add_calls([p], call_yield)
        assert p.summary.call == "undecided"


def test_inside_designs_keep_their_decided_calls():
    """The rule takes nothing from designs inside the ranges: the call there is the interval's."""
    rng = np.random.default_rng(45)
    ranges = {k: r for k, r in RANGES["small"].items() if r[0] != r[1]}
    for _ in range(12):
        d = replace(preset_design("small"), **{k: lo + (hi - lo) * rng.random() for k, (lo, hi) in ranges.items()})
        p = stand_in(d, 500.0, (500.0, 450.0, 550.0))
        add_calls([p], 1000.0, ranges=TRAINED)
        assert p.summary.call == "pass" and p.summary.call_interval_mpa.trusted


def test_a_sweep_never_passes_a_point_outside_the_ranges():
    """The sweep's final limit (the thinnest plate that passes) reads the final calls: points beyond the training
    thickness are undecided, never the limit, however low their interval."""
    lo, hi = RANGES["small"]["thickness"]
    values = np.linspace(lo, hi + 3 * (hi - lo), 8)
    preds = [
        stand_in(replace(preset_design("small"), thickness=float(t)), 400.0, (400.0, 380.0, 420.0)) for t in values
    ]
    add_calls(preds, 1000.0, ranges=TRAINED)
    final_calls(preds, None, 1000.0)
    check = SimpleNamespace(preds=preds, truth=None, readout="raw", solver_runs=0)
    limit = analyse(check, "thickness", 1000.0)["limit"]
    final = limit["final"]
    assert final["passing"] and max(final["passing"]) <= hi * (1 + 1e-6)
    assert final["undecided"] == [float(t) for t in values if t > hi * (1 + 1e-6)]
    # the "model alone" line passes no outside point either, though every peak there is below the yield stress
    assert limit["model"]["passing"] == [float(t) for t in values if t <= hi * (1 + 1e-6)]


@pytest.mark.slow  # the shipped model and the solver on two designs
def test_verify_auto_gives_far_out_designs_to_the_solver(shipped):
    designs = [
        ("high", design_for(shipped, thickness=0.4, drop_height=5000)),
        ("thin", design_for(shipped, thickness=0.5, drop_height=2000)),
    ]
    check = check_designs(shipped, designs, verify="auto", yield_mpa=1700, progress=False)
    for p, t in zip(check.preds, check.truth):
        assert p.summary.call == "undecided" and t is not None and p.summary.verified is True
        assert p.summary.final_call == ("pass" if t.summary.peak_plate_stress_mpa < 1700 else "fail")


# -- (c) the API's argument types ----------------------------------------------------------------------------------
def api_cases(shipped, tmp_path):
    one = [("a", Design())]
    return [
        (lambda: predict_designs("pretrained:impact_plate_small", one, progress=False), "run"),
        (lambda: predict_designs(None, one, progress=False), "run"),
        (lambda: hcmt.predict_designs(MODEL, one, progress=False), "run"),
        (lambda: design_for(MODEL, thickness=0.7), "run"),
        (lambda: hcmt.design_for(None, thickness=0.7), "run"),
        (lambda: hcmt.design_for(shipped, thickness="0.7"), "thickness"),
        (lambda: hcmt.load_pretrained(None), "name"),
        (lambda: hcmt.load_pretrained(3), "name"),
        (lambda: predict_designs(shipped, one, yield_mpa="750", progress=False), "yield_mpa"),
        (lambda: predict_designs(shipped, one, yield_mpa=True, progress=False), "yield_mpa"),
        (lambda: predict_designs(shipped, one, batch=True, progress=False), "batch"),
        (lambda: hcmt.Settings(frames="8"), "frames"),
        (lambda: hcmt.Settings(frames=True), "frames"),
        (lambda: hcmt.Settings(frames=8.5), "frames"),
        (lambda: hcmt.Settings(frame_dt="0.002"), "frame_dt"),
        (lambda: hcmt.Settings(peak_stress="yes"), "peak_stress"),
        (lambda: hcmt.Settings(formulation=None), "formulation"),
        (
            lambda: hcmt.generate_dataset(tmp_path / "d", counts={"train": 1}, settings=dict(frames=8), progress=False),
            "settings",
        ),
    ]


def test_api_arguments_of_the_wrong_type_are_refused_naming_them(shipped, tmp_path):
    for i, (call, param) in enumerate(api_cases(shipped, tmp_path)):
        with pytest.raises(InputError) as exc:
            call()
        msg = str(exc.value)
        assert exc.value.param == param and len(msg) < 300 and ("expected" in msg or "must be" in msg), (i, msg)
    assert not (tmp_path / "d").exists()


def test_numpy_numbers_are_numbers():
    design = [("a", Design())]
    check_design_list(design, np.int64(2))
    assert check_options(design, "auto", np.float64(750.0), np.int32(1), "raw") == 750.0
    s = Settings(frames=np.int64(8), frame_dt=np.float32(0.004), peak_stress=np.bool_(True))
    assert s.frames == 8 and type(s.frames) is int and type(s.frame_dt) is float and s.peak_stress is True
    assert s.validate() is s
    with pytest.raises(InputError) as exc:
        check_options(design, "auto", np.bool_(True), 1, "raw")
    assert exc.value.param == "yield_mpa"


@pytest.mark.slow  # one rollout of the shipped model
def test_a_numpy_batch_and_yield_run(shipped):
    (p,) = predict_designs(
        shipped,
        [("a", design_for(shipped, thickness=np.float64(0.7)))],
        batch=np.int64(1),
        yield_mpa=np.float32(5000),
        progress=False,
    )
    assert p.summary.call in ("pass", "undecided") and set(DESIGN_KEYS) == set(asdict(p.design))
