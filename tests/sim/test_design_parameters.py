"""Each design parameter's unit and help are declared once (:data:`hcmt.sim.units.PARAMETERS`): ``hcmt
simulate``'s options, the unit the designs CSV's messages and the response surface's file use, and the first
checks' messages all read that declaration."""

from __future__ import annotations

import argparse
import ast
from pathlib import Path

from hcmt.cli.parsers import configure_simulate
from hcmt.design.basics import value_problem
from hcmt.sim import params
from hcmt.sim.units import DESIGN_UNITS, PARAMETERS

SRC = Path(__file__).resolve().parents[2] / "src" / "hcmt"


def test_every_design_parameter_is_declared_once_in_order():
    assert tuple(PARAMETERS) == params.DESIGN_KEYS
    assert params.DESIGN_UNITS is DESIGN_UNITS  # read from the declaration, not a copy kept beside it
    assert DESIGN_UNITS == {k: p.unit for k, p in PARAMETERS.items()}


def test_the_command_help_is_the_declaration():
    parser = argparse.ArgumentParser()
    configure_simulate(parser)
    helps = {a.dest: a.help for a in parser._actions}
    for name, parameter in PARAMETERS.items():
        assert helps[name] == parameter.describe(contact_radius=params.CONTACT_RADIUS), name
        assert parameter.unit in helps[name], name


def test_the_first_checks_name_the_declared_unit(monkeypatch):
    monkeypatch.setitem(DESIGN_UNITS, "thickness", "furlong")
    monkeypatch.setitem(DESIGN_UNITS, "plate_density", "stone/in^3")
    assert value_problem({"thickness": -1.0}) == ("thickness", "must be > 0 (furlong), got -1")
    assert value_problem({"plate_density": 0.0}) == ("plate_density", "must be > 0 stone/in^3, got 0")


def test_no_other_module_keeps_a_table_of_parameter_units_or_helps():
    """A dict literal with three or more design parameters' names as keys outside hcmt.sim.units would be a second
    declaration (the CLI's help table and the old unit table were)."""
    keys = set(params.DESIGN_KEYS)
    found = []
    for path in SRC.rglob("*.py"):
        if path.name == "units.py" and path.parent.name == "sim":
            continue
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Dict):
                names = {k.value for k in node.keys if isinstance(k, ast.Constant) and isinstance(k.value, str)}
                strings = [v for v in node.values if isinstance(v, ast.Constant) and isinstance(v.value, str)]
                if len(names & keys) >= 3 and len(strings) >= 3:
                    found.append(f"{path.relative_to(SRC)}:{node.lineno}")
    assert found == []
