"""Shared test settings: the one tiny training config.

TINY is what every tiny training run in the tests has in common: a 1-level, 1-contact-block HCMT of width 16
with 2 heads, one normalizer warm-up step, no validation, lr 1e-3. A test file that needs something else (more
steps, MGN/GT blocks, a checkpoint or validation period, another width) appends it as extra overrides; the last
``section.key=value`` for a key wins, so the extras override TINY. Test files build configs with the
``tiny_config`` fixture; ``--set`` command lines take the list itself (``from conftest import TINY``).
"""

import pytest

from hcmt.cli import main as cli
from hcmt.config import load_config

TINY = [
    "model.levels=1",
    "model.L_C=1",
    "model.hidden=16",
    "model.heads=2",
    "train.normalizer_steps=1",
    "train.valid_every=0",
    "train.lr=1e-3",
]


def tiny(*extra: str, base: str = "impact_plate_cpu") -> dict:
    """``load_config(base, TINY + extra)``."""
    return load_config(base, TINY + list(extra))


@pytest.fixture(scope="session")
def tiny_config():
    """:func:`tiny`: ``tiny_config("train.steps=2")`` is the Impact Plate CPU config with TINY and one more
    override; ``base=`` names another config. Session-scoped, so module-scoped fixtures can use it."""
    return tiny


#: the one generated dataset of the test run (:func:`impact_data`): 12 training designs (enough for a response
#: surface on 9 varied parameters + 2), one validation and one test trajectory of 8 frames, the `small` preset
IMPACT_DATA = dict(train=12, valid=1, test=1, frames=8, seed=11)


@pytest.fixture(scope="session")
def impact_data(tmp_path_factory):
    """A dataset made by `hcmt generate impact-plate` once per test run (:data:`IMPACT_DATA`), shared by every
    module that needs real generator data (its meta.json, design attributes and solver trajectories)."""
    out = tmp_path_factory.mktemp("impact_data") / "data"
    spec = IMPACT_DATA
    assert (
        cli(
            [
                "generate",
                "impact-plate",
                str(out),
                "--preset",
                "small",
                "--train",
                str(spec["train"]),
                "--valid",
                str(spec["valid"]),
                "--test",
                str(spec["test"]),
                "--seed",
                str(spec["seed"]),
                "--frames",
                str(spec["frames"]),
                "--no-progress",
            ]
        )
        == 0
    )
    return out
