"""The command surface: one registry, every documented subcommand listed with one line."""

import argparse
import subprocess
import sys

import pytest

import hcmt.cli.design
import hcmt.errors
from hcmt.cli import COMMANDS, THREADED, flag_of, main as cli
from hcmt.inference.rollout_files import check_options

DOCUMENTED = [
    "generate",
    "simulate",
    "convert",
    "info",
    "hierarchy",
    "train",
    "rollout",
    "evaluate",
    "compare",
    "predict",
    "sweep",
    "models",
    "surrogate",
    "plot",
    "export",
    "demo",
]


def test_every_registered_command_is_documented_here():
    assert sorted(DOCUMENTED) == sorted(COMMANDS)


def test_help_lists_every_subcommand_once():
    out = subprocess.run([sys.executable, "-m", "hcmt", "--help"], capture_output=True, text=True, check=True).stdout
    for name in DOCUMENTED:
        assert name in COMMANDS
        assert sum(line.split()[0] == name for line in out.splitlines() if line.strip()) == 1, name


def test_each_subcommand_help_parses(capsys):
    """In-process (each command module imports once), every command's --help, its options listed."""
    for name in DOCUMENTED:
        with pytest.raises(SystemExit) as stop:
            cli([name, "--help"])
        out = capsys.readouterr().out
        assert stop.value.code == 0, name
        assert "usage: hcmt " + name in out, name
        assert ("--threads" in out) == (name in THREADED), name


def test_unknown_command_fails():
    r = subprocess.run([sys.executable, "-m", "hcmt", "frobnicate"], capture_output=True, text=True)
    assert r.returncode != 0


# -- errors: a user's mistake is one line naming the flag, a bug keeps its traceback ---------------------------------
def test_a_library_parameter_error_names_the_flag_on_the_command_line(impact_data, capsys):
    with pytest.raises(hcmt.errors.InputError) as exc:
        check_options(batch=0, compile="none")
    assert str(exc.value) == "batch must be a whole number from 1 to 1,024, got 0" and exc.value.param == "batch"
    rc = cli(["simulate", "--frames", "0"])  # Settings.validate's frames, the API's word
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and err == ["hcmt simulate: error: --frames must be >= 2, got 0"]  # the flag


def test_an_unexpected_exception_is_a_bug_and_keeps_its_traceback(monkeypatch, capsys):
    def broken(args):
        raise ValueError("an internal invariant broke")  # a plain ValueError is no user error

    monkeypatch.setattr(hcmt.cli.design, "main_models", broken)
    with pytest.raises(ValueError, match="internal invariant"):
        cli(["models"])
    monkeypatch.setattr(
        hcmt.cli.design,
        "main_models",
        lambda args: (_ for _ in ()).throw(hcmt.cli.CommandError("--json: an empty path; name a file")),
    )
    assert cli(["models"]) == 2
    assert capsys.readouterr().err.strip() == "hcmt models: error: --json: an empty path; name a file"


def test_flag_of_maps_parameters_to_options_and_positionals():
    p = argparse.ArgumentParser()
    p.add_argument("data")
    p.add_argument("--yield-mpa", type=float)
    p.add_argument("-b", "--batch", type=int)
    assert flag_of(p, "yield_mpa") == "--yield-mpa" and flag_of(p, "batch") == "--batch"
    assert flag_of(p, "data") == "DATA" and flag_of(p, "nothing") is None and flag_of(None, "batch") is None
