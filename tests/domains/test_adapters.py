"""The adapters are built with keywords, and the config becomes only the chosen model's
constructor arguments (an MGN run gets no HCMT depth)."""

from pathlib import Path

import pytest

from hcmt.config import load_config
from hcmt.domains.adapters import ADAPTERS, Adapter, exclude_trajectories
from hcmt.domains.spec import model_args
from hcmt.errors import InputError
from hcmt.models import REGISTRY, architecture, make_model
from hcmt.training.runtime import check_resume

META = {"dimension": 2, "features": {"mesh_pos": {"shape": [-1, 2]}}}
TINY = ["model.levels=1", "model.L_C=1", "model.hidden=16", "model.heads=2", "model.blocks=2"]
WIDTHS = {"name", "node_in", "mesh_in", "contact_in", "out", "hidden"}


def test_adapters_are_built_with_keywords_only():
    with pytest.raises(TypeError):
        Adapter("impact_plate", 2, 2, (), True, False, True, 1, (), False, None)
    assert all(name == a.name for name, a in ADAPTERS.items())
    assert ADAPTERS["impact_plate"].node_in(2) == 9 + 2 + 2 and ADAPTERS["sphere_simple"].order == 2


@pytest.mark.parametrize("model", ["hcmt", "mgn", "gt"])
def test_model_args_hold_only_the_chosen_models_arguments(model):
    cfg = load_config("impact_plate", TINY)
    args = model_args(cfg, model, META)
    assert set(args) == WIDTHS | set(REGISTRY[model].settings)
    make_model(args)  # every key is one the model's constructor takes


def test_an_mgn_run_gets_no_hcmt_depths_and_no_ablation():
    args = model_args(load_config("impact_plate", TINY), "mgn", META)
    assert not {"levels", "L_C", "L_H", "heads", "clip", "attention", "ffn_bias", "ablation"} & set(args)
    with pytest.raises(InputError, match="an ablation of HCMT"):
        model_args(load_config("impact_plate", TINY + ["model.ablation=only-cmt"]), "gt", META)


def test_runs_saved_with_every_models_keys_still_resume():
    """A run.yaml written before each model saved only its own settings held an MGN's levels and an HCMT's
    blocks: architecture drops them, so
    resuming it compares equal."""
    cfg = load_config("impact_plate", TINY)
    for model in ("hcmt", "mgn"):
        now = model_args(cfg, model, META)
        old = {
            **now,
            "ablation": None,
            "levels": 1,
            "L_C": 1,
            "L_H": None,
            "heads": 2,
            "clip": 2.0,
            "blocks": 2,
            "attention": "paper",
            "ffn_bias": True,
        }
        assert architecture(old) == now
        run = {"model": now, "config": cfg, "seed": 0, "world_size": 1}
        check_resume({**run, "model": old}, run, Path("run"))
        with pytest.raises(InputError, match="hidden"):
            check_resume({**run, "model": {**old, "hidden": 32}}, run, Path("run"))


def test_an_exclusion_beyond_the_split_names_the_public_data_and_the_override():
    """The deforming_plate configs leave out the public data's trajectories 173 and 233: on a smaller dataset (hcmt's
    own generated one) the refusal says so and how to clear it; in range, those indices are dropped."""
    with pytest.raises(InputError, match=r"\[173, 233\]: out of range for a split of 80 .*exclude_trajectories=\[\]"):
        exclude_trajectories([f"t{i}" for i in range(80)], [173, 233])
    assert list(exclude_trajectories([f"t{i}" for i in range(5)], [1, 3])) == [0, 2, 4]
