"""Bad input, round 3: a long value echoed in full, slow refusals before the heavy imports,
unbounded counts, messages without the flag, SIGTERM's exit status, an API looser than the command and notes that
ask for a solver run the command does not do. Each case: one line of at most 300 characters naming the flag or
file and what was expected, exit 2, nothing written; the API raises InputError with the parameter's name."""

import argparse
import json
import os
import resource
import signal
import subprocess
import sys
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import pytest

import hcmt
import hcmt.cli.design
from hcmt.cli import COMMANDS, GUARD, LINE, build_parser, main as cli, one_line
from hcmt.config import MAX_TRAJECTORIES, PRETRAINED_DIR, load_config
from hcmt.data.convert import convert
from hcmt.design.check import weak_reasons
from hcmt.design.inputs import read_designs_csv
from hcmt.design.summary import CallInterval, Confidence
from hcmt.design.surrogate import Surrogate, SurrogateError
from hcmt.errors import InputError
from hcmt.sim.generate import generate_dataset
from hcmt.sim.params import Design, Settings, parse_design
from summaries import fake_summary, fake_verify

ROOT = Path(__file__).resolve().parents[2]
HEAVY = ("torch", "scipy", "sklearn", "matplotlib")
LONG = "n" * 5000


def refused(capsys, argv: list[str]) -> str:
    """The one line of a refused command (exit 2, argparse's refusals too)."""
    rc = cli(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "Traceback" not in err[0], err
    assert len(err[0]) <= GUARD, len(err[0])
    return err[0]


# -- 7. a long value is echoed shortened ---------------------------------------------------------------------------
def test_a_5000_character_design_name_is_echoed_shortened(tmp_path):
    path = tmp_path / "long.csv"
    path.write_text(f"name,thickness\n{LONG},0.8\n")
    with pytest.raises(InputError) as exc:
        read_designs_csv(path, Design())
    msg = str(exc.value)
    assert len(msg) < 300 and "n" * 59 + "…" in msg and "n" * 61 not in msg
    assert "5,000 characters long; expected at most 200" in msg and "line 2" in msg


@pytest.mark.parametrize("item", [LONG + "=1", "thickness=" + LONG, LONG])
def test_a_5000_character_design_item_is_echoed_shortened(item):
    with pytest.raises(InputError) as exc:
        parse_design([item], Design())
    assert len(str(exc.value)) < 300 and "…" in str(exc.value)


def test_no_error_line_is_longer_than_the_guard(monkeypatch, capsys):
    def long_error(args):
        raise InputError("x" * 5000 + " " + "word " * 500 + "expected the end to stay", param="json")

    monkeypatch.setattr(hcmt.cli.design, "main_models", long_error)
    line = refused(capsys, ["models", "--json"])
    assert line.startswith("hcmt models: error: --json xxx") and line.endswith("expected the end to stay")
    assert len(line) == GUARD and one_line("short") == "short" and len(one_line("word " * 200, "; tail")) == GUARD
    path = "/" + "/".join(["folder"] * 30) + "/data.json:"
    assert one_line(f"{path} damaged").endswith("der/folder/data.json: damaged")  # a long path keeps its file


# -- 8. refused before the heavy imports, in one line --------------------------------------------------------------
def cases(tmp: Path) -> list[tuple[list[str], str]]:
    (tmp / "empty.csv").write_text("")
    (tmp / "dup.csv").write_text("thickness,drop_height,thickness\n0.8,700,0.9\n")
    (tmp / "long.csv").write_text(f"name,thickness\n{LONG},0.8\n")
    model = "pretrained:impact_plate_small"
    out = str(tmp / "gen")
    return [
        (["predict", model, "--threads", "0"], "argument --threads: expected a whole number from 1 to"),
        (["predict", model, "--designs", str(tmp / "empty.csv")], "empty.csv: no designs"),
        (
            ["predict", model, "--designs", str(tmp / "dup.csv")],
            "the column 'thickness' appears twice (columns 1 and 3)",
        ),
        (["predict", model, "--designs", str(tmp / "missing.csv")], "missing.csv: no such designs file"),
        (["predict", model, "--designs", str(tmp / "long.csv")], "'" + "n" * 59 + "…' is 5,000 characters long"),
        (["predict", model, "--design", LONG + "=1"], "unknown parameter '" + "n" * 59 + "…'"),
        (["predict", str(tmp / "nothere"), "--design", "thickness=0.7"], "MODEL " + str(tmp / "nothere")),
        (["predict", model, "--design", "thickness=0.7", "--batch", "100000"], "argument --batch: expected"),
        (["sweep", model, "--vary", "thickness=0.5:1:1000"], "--vary 'thickness=0.5:1:1000': N must be between"),
        (["predict", model, "--design", "thickness=0.7", "--readout", "peak"], "argument --readout: invalid choice"),
        (["sweep", model, "--vary", "thickness=0.5:1:3", "--readout", "learned"], "argument --readout: invalid"),
        (["generate", "impact-plate", out, "--workers", "100000"], "argument --workers: expected a whole number"),
        (["generate", "impact-plate", out, "--train", str(MAX_TRAJECTORIES + 1)], "argument --train: expected"),
        (["generate", "impact-plate", out, "--family", "nosuch"], "--family 'nosuch'"),
        (["simulate", "--frames", "0"], "--frames must be >= 2, got 0"),
        (["simulate", "--plate-density", "-1"], "--plate-density must be > 0"),
        (["train", "--config", "impact_plate_cpu", "--set", "train.lrr=1", "--out", out], "--set 'train.lrr=1'"),
        (["train", "--config", "nosuch", "--out", out], "--config 'nosuch': neither a file nor"),
        (["demo", "--workers", "100000"], "argument --workers: expected"),
    ]


def test_argument_errors_come_before_the_heavy_imports(tmp_path):
    """In a fresh interpreter: every case one line naming its flag or file, exit 2, a pointer to --help for
    argparse's, no torch / scipy / sklearn / matplotlib loaded, nothing written, in little CPU time."""
    script = (
        "import json, sys, resource\nfrom hcmt.cli import main\nout = []\n"
        f"for argv, _ in {cases(tmp_path)!r}:\n"
        "    out.append(main(argv))\n"
        f"print(json.dumps([out, [m for m in {HEAVY!r} if m in sys.modules]]))\n"
    )
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    r = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
        env={**os.environ, "PYTHONPATH": str(ROOT / "src")},
    )
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    codes, heavy = json.loads(r.stdout)
    lines = r.stderr.strip().splitlines()
    assert heavy == [] and codes == [2] * len(codes) and len(lines) == len(codes), r.stderr
    for (argv, message), line in zip(cases(tmp_path), lines):
        assert line.startswith(f"hcmt {argv[0]}: error: ") and message in line and len(line) <= LINE, (argv, line)
        if "argument --" in message:
            assert line.endswith(f"; see 'hcmt {argv[0]} --help'"), line
    assert not (tmp_path / "gen").exists()
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    assert cpu < 1.5, cpu  # all of them together, interpreter included: less than one torch import


@pytest.mark.slow  # a fresh interpreter, timed
def test_a_bad_flag_is_refused_in_under_a_second_and_a_half_of_cpu():
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    r = subprocess.run(
        [sys.executable, "-m", "hcmt", "predict", "pretrained:impact_plate_small", "--threads", "0"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
    )
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "usage:" not in r.stderr, r.stderr
    assert (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime) < 1.5


def test_building_any_command_parser_loads_no_heavy_module():
    script = (
        "import sys\nfrom hcmt.cli import build_parser\n"
        f"for name in {sorted(COMMANDS)!r}:\n    sys.argv = ['hcmt', name]\n    build_parser()\n"
        f"print([m for m in {HEAVY!r} if m in sys.modules])\n"
    )
    r = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
        env={**os.environ, "PYTHONPATH": str(ROOT / "src")},
    )
    assert r.returncode == 0 and r.stdout.strip() == "[]", r.stderr


# -- 9. one rule for every count, the flag named, SIGTERM 143 -------------------------------------------------------
def command_parsers(monkeypatch) -> list[tuple[str, argparse.ArgumentParser]]:
    out = []
    for name in COMMANDS:
        monkeypatch.setattr(sys, "argv", ["hcmt", name])
        p = build_parser().command_parser
        subs = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]
        out += [(name, q) for s in subs for q in s.choices.values()] + [(name, p)]
    return out


#: int options that are no count: a seed, a frame index, simulate's --frames (Settings.validate names it)
NOT_COUNTS = {"--seed", "--attention-frame", "--frames"}


def test_every_count_option_has_its_bound_in_its_help_and_is_refused_above_it(monkeypatch):
    seen = 0
    for name, p in command_parsers(monkeypatch):
        for a in p._actions:
            flag = max(a.option_strings, key=len) if a.option_strings else a.dest
            if a.type is int:
                assert flag in NOT_COUNTS, f"{name} {flag}: a bare int; give it a bound (hcmt.cli.parsers.count)"
            elif a.type is not None and getattr(a.type, "__qualname__", "").startswith(
                ("count", "cores_count", "threads_arg")
            ):
                seen += 1
                assert " to " in (a.help or ""), f"{name} {flag}: the help states no bound: {a.help}"
                with pytest.raises(argparse.ArgumentTypeError, match="expected a whole number from"):
                    a.type(str(10**12))
    assert seen >= 25


def test_sigterm_exits_143_and_sigint_130(monkeypatch, capsys):
    handler = signal.getsignal(signal.SIGTERM)
    before = signal.signal(signal.SIGINT, signal.SIG_IGN)  # a caller that ignores Ctrl-C: the command still stops
    try:
        for signum, code in ((signal.SIGTERM, 143), (signal.SIGINT, 130)):
            monkeypatch.setattr(hcmt.cli.design, "main_models", lambda args, s=signum: os.kill(os.getpid(), s))
            assert cli(["models"]) == code
            err = capsys.readouterr().err
            assert "interrupted" in err and "Traceback" not in err
        assert signal.getsignal(signal.SIGTERM) == handler  # both restored
        assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, before)


# -- 10. the Python API refuses what the command refuses ----------------------------------------------------------
@pytest.fixture(scope="module")
def shipped():
    return hcmt.load_pretrained("impact_plate_small", "cpu")


def test_run_load_of_a_missing_folder_or_model_is_an_input_error(tmp_path):
    for path in (tmp_path / "missing", tmp_path, "pretrained:nosuch"):
        with pytest.raises(InputError) as exc:
            hcmt.Run.load(path)
        assert exc.value.param == "path", exc.value


@pytest.mark.parametrize(
    "designs,message",
    [
        (["a"], "item 0: expected a (name, Design) pair"),
        ([], "expected a list of 1 to"),
        ("thickness=0.7", "expected a list of 1 to"),
        ([("../x", Design())], "would be a path outside its own folder"),
        ([("a", Design()), ("a", Design())], "already names item 0"),
        ([("a", Design(thickness=-1))], "item 0 ('a'): thickness must be > 0"),
        ([(LONG, Design())], "5,000 characters long"),
    ],
)
def test_predict_designs_refuses_bad_designs_naming_the_parameter(shipped, designs, message):
    with pytest.raises(InputError) as exc:
        hcmt.predict_designs(shipped, designs, progress=False)
    assert exc.value.param == "designs" and message in str(exc.value) and len(str(exc.value)) < 300


def test_predict_designs_refuses_a_batch_out_of_bounds(shipped):
    for batch in (0, 10**6, 2.5):
        with pytest.raises(InputError) as exc:
            hcmt.predict_designs(shipped, [("a", Design())], batch=batch, progress=False)
        assert exc.value.param == "batch"


@pytest.mark.parametrize(
    "override,message",
    [
        ("train.lrr=1", "train.lrr: unknown key; did you mean train.lr?"),
        ("train.lr=[1", "the value '[1' is not a YAML value"),
        ("nokey", "expected section.key=value"),
        ("train.lr=-1", "train.lr must be"),
    ],
)
def test_load_config_errors_name_the_override_not_the_cli(override, message):
    with pytest.raises(InputError) as exc:
        load_config("impact_plate_cpu", [override])
    assert exc.value.param == "overrides" and message in str(exc.value) and "--set" not in str(exc.value)


def test_a_surrogate_of_impossible_designs_is_refused():
    doc = json.loads((PRETRAINED_DIR / "impact_plate_small.surrogate.json").read_text())
    Surrogate.from_dict(doc)  # the shipped one loads
    doc["designs"] = [[1e308] * len(row) for row in doc["designs"]]
    with pytest.raises(SurrogateError, match="training design 1 is no design hcmt builds"):
        Surrogate.from_dict(doc)


def test_settings_and_generate_name_their_parameter(tmp_path):
    with pytest.raises(InputError) as exc:
        Settings(frames=0).validate()
    assert exc.value.param == "frames" and str(exc.value) == "frames must be >= 2, got 0"
    for kwargs, param in ((dict(workers=10**5), "workers"), (dict(counts={"train": MAX_TRAJECTORIES + 1}), "counts")):
        with pytest.raises(InputError) as exc:
            generate_dataset(tmp_path / "d", **{"counts": {"train": 1}, **kwargs}, progress=False)
        assert exc.value.param == param
    assert not (tmp_path / "d").exists()


# -- 11. notes that ask for a solver run that does not come --------------------------------------------------------
def note_of(call: str | None, verified: bool = False) -> str:
    summary = fake_summary(
        confidence=Confidence("outside", "outside the training ranges", 0),
        peak_plate_stress_mpa=500.0,
        verify=fake_verify() if verified else None,
    )
    if call is not None:
        summary = replace(
            summary,
            call=call,
            call_interval_mpa=CallInterval(200.0, 800.0 if call != "pass" else 600.0, "model", "raw"),
        )
    return " ".join(weak_reasons(SimpleNamespace(name="p", summary=summary)))


def test_a_decided_call_is_not_told_to_verify():
    assert "verify" not in note_of("pass") and "the pass call already allows for it" in note_of("pass")
    assert "200-600 MPa lies below the yield stress" in note_of("pass")
    assert "lies above the yield stress" in note_of("fail")
    assert "verify with the solver (--verify)" in note_of("undecided") and "verify with" in note_of(None)
    assert "verify" not in note_of("undecided", verified=True)


def test_convert_of_a_missing_source_is_an_input_error(tmp_path):
    with pytest.raises(InputError) as exc:
        convert(tmp_path / "missing", tmp_path / "out")
    assert exc.value.param == "src" and "no such file or folder" in str(exc.value)
    assert not (tmp_path / "out").exists()
