"""Flags spelled and defaulted alike across commands, so a flag learnt on one command works on the next."""

import argparse

from hcmt.cli import parsers
from hcmt.sim.sampling import preset_design


def parsed(name: str, argv: list[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser()
    getattr(parsers, f"configure_{name}")(p)
    return p.parse_args(argv)


def test_simulate_and_generate_default_to_the_same_preset():
    simulate = parsed("simulate", [])
    assert simulate.preset == parsed("generate", ["impact-plate", "out"]).preset == "small"
    design, _ = parsers.simulate_inputs(simulate)
    assert design == preset_design("small", "mono").validate()
