import argparse
import dataclasses

import pytest
import torch
import yaml

from graph_meshes import plate_and_ball
from hcmt.cli.parsers import configure_train
from hcmt.config import Config, builtin_configs, load_config
from hcmt.data.runs import PRETRAINED_DIR, RunFolder
from hcmt.domains.spec import dataset_spec, model_args
from hcmt.errors import InputError
from hcmt.graph.hierarchy import build_hierarchy
from hcmt.graph.remesh import two_hop_edges
from hcmt.inference.run import Run
from hcmt.models import uses_hierarchy

TABLE8 = {  # dataset: (L_C, L_H, lambda, noise std, gamma, steps)
    "impact_plate": (2, 13, 6, 0.003, 0.4, 2_000_000),
    "deforming_plate": (10, 5, 2, 0.003, 0.03, 10_000_000),
    "sphere_simple": (6, 9, 4, 0.001, 0.05, 10_000_000),
    "deformable_plate": (12, 3, 1, 0.001, 0.08, 675_000),
}


@pytest.mark.parametrize("name", TABLE8)
def test_paper_configs_hold_table8(name):
    c = load_config(name)
    m, t = c.model, c.train
    L_H = 2 * m.levels + 1  # derived, as the paper's L_H = 2λ + 1
    assert (m.L_C, L_H, m.levels, t.noise_std, t.contact_radius, t.steps) == TABLE8[name]
    assert m.L_C + L_H == 15 and not hasattr(m, "L_H")  # not a setting: derived from λ
    assert (t.lr, t.lr_final, t.batch_size, m.hidden, m.heads) == (1e-4, 1e-6, 1, 128, 4)
    assert f"{name}_cpu" in builtin_configs()


def test_base_and_overrides(tmp_path):
    c = load_config("impact_plate_cpu", ["train.lr=3e-4", "model.levels=3", "data.exclude_trajectories=[1, 2]"])
    assert c.train.lr == 3e-4 and c.model.levels == 3 and c.data.exclude_trajectories == (1, 2)
    assert c.train.noise_std == 0.003  # inherited from impact_plate
    f = tmp_path / "mine.yaml"
    f.write_text("base: impact_plate\ntrain:\n  steps: 7\n")
    assert load_config(str(f)).train.steps == 7
    with pytest.raises(InputError, match="built-in") as exc:
        load_config("nope")
    assert exc.value.param == "name_or_path"  # `hcmt train` words it as --config
    with pytest.raises(ValueError, match="section.key=value"):
        load_config("impact_plate", ["oops"])


# Table 9 by hand: (node_in, mesh_in, contact_in, out, integration order)
TABLE9 = {
    "impact_plate": (9 + 2 + 1 + 1, 2 + 1 + 2 + 1, 3, 3, 1),
    "deforming_plate": (9 + 3, 3 + 1 + 3 + 1, 4, 4, 1),
    "sphere_simple": (9 + 3, 2 + 1 + 3 + 1, 4, 3, 2),
    "deformable_plate": (9 + 1, 2 + 1 + 2 + 1, 3, 2, 1),
}


@pytest.mark.parametrize("name", TABLE8)
def test_dataset_spec_holds_tables_8_and_9(name):
    """One source per dataset: Table 8 from its config, Table 9 from its adapter; both against the paper."""
    spec = dataset_spec(name)
    assert (spec["node_in"], spec["mesh_in"], spec["contact_in"], spec["out"], spec["integration"]) == TABLE9[name]
    assert (
        spec["L_C"],
        spec["L_H"],
        spec["levels"],
        spec["noise_std"],
        spec["radius"],
        spec["training_steps"],
    ) == TABLE8[name]


@pytest.mark.parametrize(
    "overrides,yaml_text,message",
    [
        (["train.lrr=1"], None, "overrides 'train.lrr=1': train.lrr: unknown key; did you mean train.lr?"),
        (["train.lr=fast"], None, "train.lr: got 'fast'; expected a number"),
        (["train.steps=20.5"], None, "train.steps: got 20.5; expected a whole number"),
        (
            ["model.attention=softmax"],
            None,
            "model.attention: unknown value 'softmax'; expected one of paper, official",
        ),
        ([], "base: impact_plate\ntrian:\n  steps: 3\n", "trian: unknown key; did you mean train?"),
        ([], "base: impact_plate\ntrain:\n  steps: [3\n", "line 4, column 1: not valid YAML"),
        ([], "base: impact_plate\nmodel:\n  hiden: 64\n", "model.hiden: unknown key; did you mean model.hidden?"),
    ],
)
def test_schema_refuses_unknown_keys_and_wrong_types(tmp_path, overrides, yaml_text, message):
    name = "impact_plate"
    if yaml_text is not None:
        name = str(tmp_path / "mine.yaml")
        (tmp_path / "mine.yaml").write_text(yaml_text)
    with pytest.raises(ValueError) as exc:
        load_config(name, overrides)
    assert message in str(exc.value)
    if yaml_text is not None:
        assert "mine.yaml" in str(exc.value)


def test_every_builtin_config_passes_the_schema():
    for name in builtin_configs():
        load_config(name)


def test_a_config_is_frozen_complete_and_typed():
    c = Config.from_dict(
        {
            "dataset": "impact_plate",
            "train": {"lr": 1, "steps": 10.0, "contact_radius": 2},
            "data": {"exclude_trajectories": [3]},
        }
    )
    assert c.train.lr == 1.0 and isinstance(c.train.lr, float)  # a YAML 1 for a number is a float
    assert c.train.steps == 10 and isinstance(c.train.steps, int)  # a whole float for a count is an int
    assert c.train.noise_std == 0.0 and c.model.hidden == 128  # what the mapping left out: the defaults
    with pytest.raises(dataclasses.FrozenInstanceError):
        c.train.lr = 2.0
    assert Config.from_dict(c.to_dict()) == c and c.to_dict()["data"]["exclude_trajectories"] == [3]
    assert c.with_overrides(["train.lr=3e-4"]).train.lr == 3e-4 and c.train.lr == 1.0  # a new object


@pytest.mark.parametrize(
    "overrides,message",
    [
        (["train.steps=0"], "train.steps must be a whole number >= 1, got 0"),
        (["train.lr=0"], "train.lr must be a number > 0, got 0"),
        (["train.batch_size=-2"], "train.batch_size must be a whole number >= 1, got -2"),
        (["train.pushforward=1.5"], "train.pushforward must be a probability in [0, 1], got 1.5"),
    ],
)
def test_the_schema_holds_the_bounds(overrides, message):
    with pytest.raises(ValueError) as exc:
        load_config("impact_plate_cpu", overrides)
    assert str(exc.value) == f"overrides {overrides[0]!r}: {message}" and exc.value.param == "overrides"


def test_training_needs_the_required_keys():
    with pytest.raises(ValueError, match="train.lr is missing"):
        Config.from_dict({"dataset": "impact_plate", "train": {"steps": 3, "contact_radius": 1.0}}).for_training()
    with pytest.raises(ValueError, match="`dataset`"):
        Config.from_dict({"train": {"steps": 3, "lr": 1e-3, "contact_radius": 1.0}}).for_training()
    assert load_config("impact_plate").for_training().train.steps == 2_000_000


def test_run_yaml_is_read_back_as_a_config(tmp_path):
    cfg = load_config("impact_plate_cpu", ["data.exclude_trajectories=[1]"])
    RunFolder(tmp_path, must_exist=False).write_info({"model": {"name": "mgn"}, "config": cfg})
    plain = yaml.safe_load((tmp_path / "run.yaml").read_text())  # plain YAML: no Python tags
    assert plain["config"]["data"]["exclude_trajectories"] == [1] and plain["config"]["train"]["lr"] == cfg.train.lr
    back = RunFolder(tmp_path).info["config"]
    assert isinstance(back, Config) and back == cfg
    (tmp_path / "run.yaml").write_text("model: {name: mgn}\nconfig: {train: {lr: fast}}\n")
    with pytest.raises(ValueError, match="run.yaml: its settings do not load .*train.lr: got 'fast'"):
        RunFolder(tmp_path)


def test_L_H_is_derived_and_cannot_be_set(tmp_path):
    """L_H = 2λ + 1 (paper §3.2) is no setting: a config or --set naming it is refused in one line; a run.yaml of
    an older run holding it (null, or 2·levels + 1) still reads, any other value is refused."""
    for source in (
        lambda: load_config("impact_plate_cpu", ["model.L_H=9"]),
        lambda: Config.from_dict({"dataset": "impact_plate", "model": {"levels": 4, "L_H": 7}}),
    ):
        with pytest.raises(InputError, match=r"model\.L_H: derived, L_H = 2·model\.levels \+ 1 .*set model\.levels"):
            source()
    path = tmp_path / "old.yaml"
    path.write_text("base: impact_plate_cpu\nmodel:\n  L_H: 9\n")
    with pytest.raises(InputError, match="not a setting"):
        load_config(str(path))
    for old in (None, 9):
        assert Config.from_dict({"model": {"levels": 4, "L_H": old}}).model.levels == 4


def test_ablation_is_a_model_setting():
    assert load_config("impact_plate_cpu", ["model.ablation=only-hmt"]).model.ablation == "only-hmt"
    assert load_config("impact_plate_cpu").model.ablation is None
    with pytest.raises(InputError, match="model.ablation: unknown value 'bogus'; expected one of late-contact"):
        load_config("impact_plate_cpu", ["model.ablation=bogus"])


def test_the_shipped_models_recipe_is_the_named_config_impact_plate_shipped():
    from hcmt.inference.run import Run

    shipped = Run.load("pretrained:impact_plate_small", "cpu").config
    assert load_config("impact_plate_shipped").to_dict() == shipped.to_dict()


def test_no_remesh_is_the_graph_setting_data_remesh_and_the_old_spelling_still_reads(tmp_path):
    """The paper's "HCMT without remeshing" is ``data.remesh: false``: the hierarchy's coarse edges join the kept
    nodes two hops apart (BSMS). Its old spelling, ``model.ablation: no-remesh`` (``--set``, ``--ablation``, an
    older run.yaml and checkpoint), reads as it, and an older run still builds the 2-hop hierarchy."""
    new = load_config("impact_plate_cpu", ["data.remesh=false"])
    assert (new.model.ablation, new.data.remesh) == (None, False) and load_config("impact_plate_cpu").data.remesh
    assert load_config("impact_plate_cpu", ["model.ablation=no-remesh"]) == new
    assert dataclasses.replace(new, model=dataclasses.replace(new.model, ablation="no-remesh")) == new
    assert "no-remesh" not in yaml.safe_dump(new.to_dict())
    meta = {"dimension": 3, "features": {"mesh_pos": {"shape": [1, 3]}}}
    assert model_args(new, "hcmt", meta)["levels"] == 4  # HCMT takes it; a model without a hierarchy refuses it
    with pytest.raises(InputError, match="data.remesh false: .* model mgn has no hierarchy"):
        model_args(new, "mgn", meta)
    # an older run: run.yaml and checkpoint with the ablation in the model arguments and the config
    pack = torch.load(PRETRAINED_DIR / "impact_plate_small.pt", weights_only=True)
    args = dict(pack["model_args"], ablation="no-remesh")
    config = dict(pack["config"], model=dict(pack["config"]["model"], ablation="no-remesh"))
    (tmp_path / "run.yaml").write_text(yaml.safe_dump({"model": args, "config": config, "data": None, "seed": 0}))
    torch.save({"model_args": args, "model": pack["model"], "step": 7}, tmp_path / "best.pt")
    run = Run.load(tmp_path, "cpu")
    assert run.info.model["ablation"] is None and run.config.data.remesh is False and run.config.model.ablation is None
    assert run.hierarchy_spec == (4, False) and run.label == "HCMT (no-remesh)" and run.info.checkpoint.step == 7
    assert uses_hierarchy(run.info.model, new.data.remesh) == uses_hierarchy(run.info.model, False) == (4, False)
    m = plate_and_ball(h=0.25)
    h = build_hierarchy(m["mesh_pos"], m["cells"], m["node_type"], 2, *run.hierarchy_spec[1:])
    assert not h.remesh
    for level in (1, 2):  # every coarse level's edges: the finer level's kept nodes two hops apart
        two_hop = two_hop_edges(h.edges[level - 1], h.num_nodes(level - 1), h.pool[level - 1])
        assert set(map(tuple, h.edges[level].T.tolist())) == set(map(tuple, two_hop.T.tolist()))
    parser = argparse.ArgumentParser()
    configure_train(parser)
    assert parser.parse_args(["--out", "x", "--ablation", "no-remesh"]).ablation == "no-remesh"  # an alias still
