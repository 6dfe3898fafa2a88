"""The command surface: one registry, every documented subcommand listed with one line."""
import subprocess
import sys

from hcmt.cli import COMMANDS

DOCUMENTED = ["generate", "simulate", "convert", "info", "hierarchy", "train", "rollout", "evaluate", "compare",
              "plot", "export", "demo"]


def test_help_lists_every_subcommand_once():
    out = subprocess.run([sys.executable, "-m", "hcmt", "--help"], capture_output=True, text=True, check=True).stdout
    for name in DOCUMENTED:
        assert name in COMMANDS
        assert sum(line.split()[0] == name for line in out.splitlines() if line.strip()) == 1, name


def test_each_subcommand_help_parses():
    for name in DOCUMENTED:
        r = subprocess.run([sys.executable, "-m", "hcmt", name, "--help"], capture_output=True, text=True)
        assert r.returncode == 0, (name, r.stderr[-2000:])
        assert "usage: hcmt " + name in r.stdout


def test_unknown_command_fails():
    r = subprocess.run([sys.executable, "-m", "hcmt", "frobnicate"], capture_output=True, text=True)
    assert r.returncode != 0
