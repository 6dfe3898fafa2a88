"""Bad input, round 4 (a new user's trial), the parse step: value errors of a ``--designs`` CSV and a ``--vary``
range refused before torch loads, a second ``--vary``, an unknown option pointing to its command's --help; and what
``hcmt simulate`` and ``hcmt predict --verify`` now say: a ball that never reached the plate, a window that may cut
the peak, the solver's total before a long verification starts."""

import importlib
import json
import os
import resource
import subprocess
import sys
import time
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import pytest

import hcmt.cli.design
from hcmt.cli import LINE, build_parser, main as cli
from hcmt.design.basics import check_values, value_problem
from hcmt.errors import InputError
from hcmt.sim.cost import fall, plan, solver_seconds, window_warnings
from hcmt.sim.params import DESIGN_KEYS, Settings, parse_design, value_rules
from hcmt.sim.sampling import preset_design
from refusals import refused

ROOT = Path(__file__).resolve().parents[2]
HEAVY = ("torch", "scipy", "sklearn", "matplotlib")
MODEL = "pretrained:impact_plate_small"


@pytest.fixture
def no_command_module(monkeypatch):
    """The command's own module (hcmt.cli.design: torch, the model) may not load: a refusal comes before it."""
    real = importlib.import_module

    def guarded(name, *args, **kwargs):
        assert name not in ("hcmt.cli.design", "hcmt.cli.data"), f"{name} loaded before the refusal"
        return real(name, *args, **kwargs)

    monkeypatch.setattr(importlib, "import_module", guarded)


#: (file text, what the one line says): every value error of a designs CSV
CSV_CASES = [
    ("thickness,drop_height\nnan,700\n", "line 2, column 1 (thickness) must be a finite number, got 'nan'"),
    ("thickness,drop_height\n0.8,inf\n", "line 2, column 2 (drop_height) must be a finite number, got 'inf'"),
    ("thickness,drop_height\n0.8mm,700\n", "line 2, column 1 (thickness) must be a number, got '0.8mm'"),
    ('thickness,drop_height\n"0,8",700\n', "line 2, column 1 (thickness) must be a number, got '0,8'"),
    ("thickness,drop_height\n0.8,700\n-0.8,700\n", "line 3, column 1 (thickness) must be > 0 (mm), got -0.8"),
    ("name,drop_height,gap\na,700,0.5\n", "line 2, column 3 (gap) must be smaller than the contact radius 0.4 mm"),
    ("thickness,plate_poisson\n0.8,0.5\n", "line 2, column 2 (plate_poisson) must be in (-1, 0.5)"),
    ("thickness,drop_height\n0.8\n", "line 2: 1 values for 2 columns (thickness, drop_height)"),
    ("thickness,drop_height\n0.8,700,3\n", "line 2: 3 values for 2 columns"),
    ("thickness,drop_height\n0.8, \n", "line 2, column 2 (drop_height): missing value"),
    ("thickness,drop_height\n", "a header but no designs"),
    ("name,thickness\na,0.6\nb,0.7\na,0.8\n", "line 4, column 1 (name): 'a' already names line 2"),
]


def cli_cases(tmp: Path) -> list[tuple[list[str], str]]:
    out = []
    for i, (text, message) in enumerate(CSV_CASES):
        (tmp / f"d{i}.csv").write_text(text)
        out.append(
            (
                ["predict", MODEL, "--designs", str(tmp / f"d{i}.csv"), "--json", str(tmp / "o.json")],
                f"d{i}.csv {message}" if "line" in message else message,
            )
        )
    return out + [
        (
            ["sweep", MODEL, "--vary", "thickness=-0.5:0.9:3", "--design", "drop_height=700", "--out", str(tmp / "sw")],
            "--vary 'thickness=-0.5:0.9:3': the point thickness=-0.5 is impossible: thickness must be > 0 (mm)",
        ),
        (
            ["sweep", MODEL, "--vary", "gap=0.01:0.5:3", "--out", str(tmp / "sw")],
            "the point gap=0.5 is impossible: gap must be smaller than the contact radius 0.4 mm",
        ),
        (
            ["sweep", MODEL, "--vary", "thickness=0.5:0.9:3", "--design", "ball_modulus=-2", "--out", str(tmp / "sw")],
            "--design 'ball_modulus=-2': ball_modulus must be > 0 MPa",
        ),
        (
            ["predict", MODEL, "--design", "thickness=0.8", "drop_height=-700"],
            "--design 'drop_height=-700': drop_height must be > 0 (mm), got -700",
        ),
    ]


# -- 1. every value of --designs and --vary refused in the parse step ------------------------------------------------
def test_value_errors_are_refused_before_the_command_loads(tmp_path, capsys, no_command_module):
    for argv, message in cli_cases(tmp_path):
        line = refused(capsys, argv)
        assert line.startswith(f"hcmt {argv[0]}: error: ") and message in line, (argv, line)
    assert not (tmp_path / "o.json").exists() and not (tmp_path / "sw").exists()


@pytest.mark.slow  # a fresh interpreter, timed
def test_value_errors_come_before_the_heavy_imports_in_little_time(tmp_path):
    """In a fresh interpreter: no torch / scipy / sklearn / matplotlib loaded when the refusals are printed, all of
    them in less CPU than one torch import, and in little wall time (slack for a busy machine: a torch import
    took 3-24 s there)."""
    cases = cli_cases(tmp_path)
    script = (
        "import json, sys\nfrom hcmt.cli import main\nout = []\n"
        f"for argv, _ in {cases!r}:\n    out.append(main(argv))\n"
        f"print(json.dumps([out, [m for m in {HEAVY!r} if m in sys.modules]]))\n"
    )
    before, t0 = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
    r = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
        env={**os.environ, "PYTHONPATH": str(ROOT / "src")},
    )
    wall, after = time.perf_counter() - t0, resource.getrusage(resource.RUSAGE_CHILDREN)
    codes, heavy = json.loads(r.stdout)
    lines = r.stderr.strip().splitlines()
    assert heavy == [] and codes == [2] * len(cases) and len(lines) == len(cases), r.stderr
    for (argv, message), line in zip(cases, lines):
        assert message in line and len(line) <= LINE, (argv, line)
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    assert cpu < 1.5 and wall < 6.0, (cpu, wall)  # the interpreter and all 16 refusals


#: every panel family's sizes set (the ring's left 0: one support), so that each family's rules apply
ALL_ON = dict(
    layer2_thickness=0.1, layer3_thickness=0.1, layer4_thickness=0.1, backing_thickness=1.5, pen_tip_radius=0.8
)
#: a value that each design parameter's rules refuse
BAD = dict(
    thickness=0,
    drop_height=-1,
    plate_density=0,
    plate_modulus=-5,
    plate_poisson=0.5,
    ball_radius=-3,
    ball_density=-1,
    ball_modulus=0,
    ball_poisson=-1,
    mesh_size=0,
    plate_half_length=-1,
    gap=0.4,
    layer2_thickness=-0.1,
    layer2_density=0,
    layer2_modulus=-1,
    layer2_poisson=0.47,
    layer3_thickness=-0.1,
    layer3_density=-1,
    layer3_modulus=0,
    layer3_poisson=-0.1,
    layer4_thickness=-1,
    layer4_density=0,
    layer4_modulus=-2,
    layer4_poisson=0.5,
    support_radius=-1,
    backing_thickness=-2,
    backing_modulus=0,
    pen_tip_radius=-1,
    pen_mass=-2,
)


def test_a_designs_file_and_design_refuse_the_same_values_in_the_same_words(tmp_path):
    """A ``--designs`` file's first checks (value_problem, before torch) and ``--design`` (Design.validate) read the
    same rules (hcmt.sim.params.value_rules): a value that breaks one is refused by both, naming the same parameter
    with the same "must be ..." words; a good design passes both (no false refusal)."""
    base = preset_design("small")
    assert value_problem(asdict(base)) is None and value_problem(ALL_ON) is None
    assert parse_design([f"{k}={x}" for k, x in ALL_ON.items()], base).family == "stack4+backing+pen"
    assert {rule.param for rule in value_rules({**asdict(base), **ALL_ON})} == set(BAD) == set(DESIGN_KEYS)
    for key, v in BAD.items():
        values = {**ALL_ON, key: v}
        (tmp_path / "d.csv").write_text(f"{','.join(values)}\n{','.join(map(str, values.values()))}\n")
        with pytest.raises(InputError) as from_file:
            check_values([], tmp_path / "d.csv")
        with pytest.raises(InputError) as from_flag:
            parse_design([f"{k}={x}" for k, x in values.items()], base)
        words = str(from_file.value).split(f" ({key}) must be ", 1)[1].rsplit(", got ", 1)[0]
        assert str(from_flag.value).startswith(f"--design {key} "), (key, from_flag.value)
        assert f"must be {words}" in str(from_flag.value), (key, from_file.value, from_flag.value)
        assert value_problem(values)[0] == key
    # a layer's, the backing's or the pen's material only where the same values set that layer, backing or pen
    assert value_problem({"layer2_density": -1}) is None
    assert value_problem({"layer2_thickness": 0.1, "layer2_poisson": 0.47})[0] == "layer2_poisson"
    assert value_problem({"backing_thickness": 1, "backing_modulus": 0})[0] == "backing_modulus"
    assert value_problem({"pen_tip_radius": 1, "pen_mass": -2})[0] == "pen_mass"


def test_check_values_counts_the_files_designs(tmp_path):
    path = tmp_path / "ok.csv"
    path.write_text("name,thickness,drop_height\na,0.6,700\n\nb,0.9,800\n")
    assert check_values([["thickness=0.7"]], path) == 2 and check_values([], None) == 0
    assert check_values([["drop_height=700"]], vary="thickness=0.5:0.9:3") == 0


# -- 2. a second --vary ------------------------------------------------------------------------------------------------
def test_a_second_vary_is_refused_not_dropped(capsys, no_command_module):
    line = refused(capsys, ["sweep", MODEL, "--vary", "thickness=0.5:0.9:3", "--vary", "drop_height=500:900:3"])
    assert line.startswith(
        "hcmt sweep: error: --vary: given twice (thickness=0.5:0.9:3, drop_height=500:900:3); "
        "a sweep varies one parameter"
    ), line


# -- 6. an unknown option points to its command's --help ----------------------------------------------------------
@pytest.mark.parametrize(
    "argv, command",
    [
        (["predict", MODEL, "--bogus", "1"], "hcmt predict"),
        (["sweep", MODEL, "--vary", "thickness=0.5:0.9:3", "--bogus"], "hcmt sweep"),
        (["surrogate", "fit", "data", "--out", "s.json", "--bogus"], "hcmt surrogate fit"),
        (["--bogus"], "hcmt"),
    ],
)
def test_an_unknown_option_points_to_its_commands_help(capsys, argv, command, no_command_module):
    line = refused(capsys, argv)
    assert line.startswith(f"{command}: error: unrecognized arguments: --bogus"), line
    assert line.endswith(f"; see '{command} --help'"), line


# -- 3, 4. simulate says what its window missed ----------------------------------------------------------------------
def warnings_of(capsys, argv: list[str]) -> list[str]:
    assert cli(argv) == 0
    return [line for line in capsys.readouterr().err.splitlines() if line.startswith("hcmt simulate: warning: ")]


def test_simulate_says_the_ball_never_reached_the_plate(capsys):
    lines = warnings_of(
        capsys, ["simulate", "--design", "drop_height=0.7", "--frames", "20", "--no-progress", "--threads", "1"]
    )
    touch = [w for w in lines if "did not touch the plate" in w]
    assert len(touch) == 1 and len(touch[0]) <= LINE, lines
    assert "(20 frames x 0.002 ms = 0.038 ms)" in touch[0] and "drop_height 0.7 mm" in touch[0]
    assert "(mm: 0.7 m is 700)" in touch[0] and "--frames" in touch[0] and "raise drop_height" in touch[0]
    assert not any("peak plate stress" in w for w in lines)  # not also "the window may cut the peak"


def test_fall_agrees_with_the_solver_on_when_the_ball_arrives():
    d = replace(preset_design("small"), drop_height=0.7)
    f = fall(d, Settings())
    assert f["fallen_mm"] < d.gap < fall(d, Settings(frames=f["touch_frame"] + 1))["fallen_mm"] + 1e-12
    assert fall(replace(d, drop_height=f["touch_height_mm"] * 1.01), Settings())["fallen_mm"] > d.gap


def test_simulate_warns_when_the_window_may_cut_the_peak(capsys):
    """A 0.5 mm plate dropped on from 500 mm peaks in the last of 52 frames (760 MPa; 809 MPa at frame 59 of 90):
    one line saying so and how to record more; a design that peaks early gets none."""
    lines = warnings_of(
        capsys, ["simulate", "--design", "thickness=0.5", "drop_height=500", "--no-progress", "--threads", "1"]
    )
    cut = [w for w in lines if "the window may cut the peak" in w]
    assert len(cut) == 1 and len(cut[0]) <= LINE and "--frames 90" in cut[0] and "ending at frame 51" in cut[0]


def test_window_warnings_rule():
    d, s = preset_design("small"), Settings(frames=52)
    touching = np.full(52, -0.01)
    rise = np.linspace(0, 1, 52)
    early = np.concatenate([np.linspace(0, 1, 30), np.linspace(1, 0.2, 22)])
    late = np.concatenate([np.linspace(0, 1, 50), [0.9, 0.8]])  # peak at frame 49: in the last three
    high_end = np.concatenate([np.linspace(0, 1, 40), np.full(12, 0.97)])  # the last frame still 97 %
    assert window_warnings(d, s, early, touching) == []
    for history in (rise, late, high_end):
        assert len(window_warnings(d, s, history, touching)) == 1
    assert "did not touch" in window_warnings(d, s, np.zeros(52), np.full(52, 0.01))[0]


# -- 5. predict --verify states the solver's total before it starts ------------------------------------------------
class Stop(Exception):
    pass


@pytest.mark.parametrize("verify", [["--verify"], ["--verify", "auto", "--yield-mpa", "600"]])
def test_predict_verify_states_the_solvers_total_up_front(tmp_path, capsys, monkeypatch, verify):
    rows = "\n".join(f"{0.5 + 0.5 * i / 2999:.5f},{500 + 500 * (i % 97) / 96:.1f}" for i in range(3_000))
    (tmp_path / "many.csv").write_text("thickness,drop_height\n" + rows + "\n")

    def started(*args, **kwargs):
        raise Stop

    monkeypatch.setattr(hcmt.cli.design, "check_designs", started)
    with pytest.raises(Stop):
        cli(["predict", MODEL, "--designs", str(tmp_path / "many.csv"), *verify, "--no-progress", "--threads", "1"])
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 1 and "of the 3,000 designs" in out[0] and " h on one core" in out[0], out
    assert ("each of" in out[0]) == (len(verify) == 1) and ("up to" in out[0]) == (len(verify) > 1)
    hours = float(out[0].split(" h on one core")[0].split()[-1])
    assert 2 < hours < 12  # 3,000 designs at 2.4-14 s each by the solver's estimate


def test_solver_seconds_is_plans_estimate_summed():
    base = preset_design("small")
    designs = [replace(base, thickness=t) for t in (0.5, 0.7, 0.9)]
    s = Settings(frames=90)
    assert solver_seconds(designs, s) == pytest.approx(sum(plan(d, s)["estimated_s"] for d in designs))
    assert solver_seconds([], s) == 0.0


# -- 4. which middle simulate fills from, said in its help ---------------------------------------------------------
def test_simulate_help_says_which_middle_it_fills_from(monkeypatch):
    monkeypatch.setattr(sys, "argv", ["hcmt", "simulate"])
    p = build_parser().command_parser
    helps = {a.dest: a.help for a in p._actions}
    assert "preset's sampling ranges" in helps["preset"] and "model's training designs" in helps["preset"]
    assert "`hcmt models`" in helps["frames"] and "peak" in helps["frames"]
