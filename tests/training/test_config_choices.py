"""Each config choice list is declared once, in :mod:`hcmt.config.choices`, and the module that acts on the values
reads it or is keyed by exactly its values: a value added to one and not the other fails here."""

from __future__ import annotations

import hcmt.config as config
from hcmt.config import SCHEMA, TOP, choices
from hcmt.domains import adapters
from hcmt.models import REGISTRY, attention, hcmt as hcmt_model
from hcmt.training import policy


def test_every_allowed_list_of_the_schema_is_a_named_choice_list():
    named = {v: k for k, v in vars(choices).items() if k.isupper() and isinstance(v, tuple)}
    named[choices.ABLATIONS + choices.ABLATION_ALIASES] = "ABLATIONS + ABLATION_ALIASES"
    loose = [
        f"{section}.{key}"
        for section, specs in SCHEMA.items()
        for key, spec in specs.items()
        if spec.allowed and spec.allowed not in named
    ]
    assert loose == [], f"allowed values written in the schema, not in hcmt.config.choices: {loose}"
    assert TOP["dataset"][1] is choices.DATASET_NAMES


def test_the_owners_read_the_one_list_or_are_keyed_by_it():
    assert attention.MODES is config.ATTENTION_MODES  # one list: the modes attention computes
    assert adapters.NOISE_NODES is config.NOISE_NODES
    assert hcmt_model.ABLATIONS is config.ABLATIONS
    assert tuple(adapters.ADAPTERS) == config.DATASET_NAMES
    assert tuple(adapters.TARGETS) == tuple(adapters.DEFAULT_GAMMA) == config.TARGET_NAMES
    assert tuple(adapters.CONTACT_PAIRS) == config.CONTACT_PAIR_NAMES
    assert tuple(policy.POLICIES) == config.POLICY_NAMES
    assert tuple(REGISTRY) == config.MODELS


def test_the_schema_allows_exactly_the_owners_values():
    model, train = SCHEMA["model"], SCHEMA["train"]
    assert model["attention"].allowed == attention.MODES
    assert model["target"].allowed == tuple(adapters.TARGETS)
    assert train["noise_nodes"].allowed == adapters.NOISE_NODES
    assert train["policy"].allowed == tuple(policy.POLICIES)
    assert train["contact_pairs"].allowed == tuple(adapters.CONTACT_PAIRS)
    assert TOP["dataset"][1] == tuple(adapters.ADAPTERS)
