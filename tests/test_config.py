import pytest

from hcmt.train.config import builtin_configs, load_config

TABLE8 = {  # dataset: (L_C, L_H, lambda, noise std, gamma, steps)
    "impact_plate": (2, 13, 6, 0.003, 0.4, 2_000_000),
    "deforming_plate": (10, 5, 2, 0.003, 0.03, 10_000_000),
    "sphere_simple": (6, 9, 4, 0.001, 0.05, 10_000_000),
    "deformable_plate": (12, 3, 1, 0.001, 0.08, 675_000),
}


@pytest.mark.parametrize("name", TABLE8)
def test_paper_configs_hold_table8(name):
    c = load_config(name)
    m, t = c["model"], c["train"]
    L_H = 2 * m["levels"] + 1  # derived, as the paper's L_H = 2λ + 1
    assert (m["L_C"], L_H, m["levels"], t["noise_std"], t["contact_radius"], t["steps"]) == TABLE8[name]
    assert m["L_C"] + L_H == 15 and "L_H" not in m
    assert (t["lr"], t["lr_final"], t["batch_size"], m["hidden"], m["heads"]) == (1e-4, 1e-6, 1, 128, 4)
    assert f"{name}_cpu" in builtin_configs()


def test_base_and_overrides(tmp_path):
    c = load_config("impact_plate_cpu", ["train.lr=3e-4", "model.levels=3", "new.key=[1, 2]"])
    assert c["train"]["lr"] == 3e-4 and c["model"]["levels"] == 3 and c["new"]["key"] == [1, 2]
    assert c["train"]["noise_std"] == 0.003  # inherited from impact_plate
    f = tmp_path / "mine.yaml"
    f.write_text("base: impact_plate\ntrain:\n  steps: 7\n")
    assert load_config(str(f))["train"]["steps"] == 7
    with pytest.raises(FileNotFoundError, match="built-in"):
        load_config("nope")
    with pytest.raises(ValueError, match="section.key=value"):
        load_config("impact_plate", ["oops"])


@pytest.mark.parametrize("name", TABLE8)
def test_model_defaults_adapters_and_configs_agree(name):
    """Table 8 and Table 9 live in three places (configs, model defaults, dataset adapters): they must agree."""
    from hcmt.models import dataset_spec
    from hcmt.train.adapters import get_adapter

    spec, adapter, cfg = dataset_spec(name), get_adapter(name), load_config(name)
    assert adapter.node_in(spec["dim"]) == spec["node_in"]
    assert adapter.out(spec["dim"]) == spec["out"]
    assert adapter.order == spec["integration"]
    m, t = cfg["model"], cfg["train"]
    assert (m["L_C"], 2 * m["levels"] + 1, m["levels"]) == (spec["L_C"], spec["L_H"], spec["levels"])
    assert (t["noise_std"], t["contact_radius"], t["steps"]) == (spec["noise_std"], spec["radius"], spec["training_steps"])
