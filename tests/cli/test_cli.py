"""The command surface: one registry, every documented subcommand listed with one line."""
import subprocess
import sys

import pytest

from hcmt.cli import COMMANDS, THREADED
from hcmt.cli import main as cli

DOCUMENTED = ["generate", "simulate", "convert", "info", "hierarchy", "train", "rollout", "evaluate", "compare",
              "predict", "sweep", "models", "surrogate", "plot", "export", "demo"]


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
