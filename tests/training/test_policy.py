"""``train.policy``: the training loop's conventions, hcmt's or the authors' code's, chosen by one key
(:mod:`hcmt.training.policy`); each of its fields a key that, set, wins over the policy."""

from dataclasses import replace

import pytest
import torch

from hcmt.config import load_config
from hcmt.training.dataset import collate_samples
from hcmt.training.policy import POLICIES, TrainingPolicy, policy_of
from hcmt.training.runtime import check_resume
from hcmt.training.schedule import keras_epsilon
from hcmt.training.trainer import Trainer
from layouts import write_impact_like

#: what the authors' code does otherwise than hcmt (configs/impact_plate_official.yaml, docs/architecture.md)
AUTHORS = {
    "normalizer_warmup": ("all", "nodes"),
    "mesh_edges_twice": (False, True),
    "loss_denominator": ("masked", "nodes"),
    "adam_epsilon": (1e-8, 1e-7),
    "adam_epsilon_hat": (False, True),
    "lr_decay_steps": (None, 1_000_000),
}


def test_the_two_policies_differ_in_the_documented_choices_only():
    hcmt, official = POLICIES["hcmt"], POLICIES["official"]
    assert hcmt == TrainingPolicy() == policy_of(load_config("impact_plate_cpu").train)
    assert official == policy_of(load_config("impact_plate_official").train)
    for key, (ours, theirs) in AUTHORS.items():
        assert (getattr(hcmt, key), getattr(official, key)) == (ours, theirs), key
    assert replace(hcmt, **{k: v[1] for k, v in AUTHORS.items()}) == official


def test_a_key_set_wins_over_its_policy_and_bad_values_are_refused():
    tc = load_config("impact_plate_official", ["train.loss_denominator=masked", "train.adam_epsilon=1e-6"]).train
    assert policy_of(tc) == replace(POLICIES["official"], loss_denominator="masked", adam_epsilon=1e-6)
    with pytest.raises(ValueError, match="train.policy: unknown value 'tf'; expected one of hcmt, official"):
        load_config("impact_plate_cpu", ["train.policy=tf"])
    with pytest.raises(ValueError, match="train.normalizer_warmup: unknown value 'some'"):
        load_config("impact_plate_cpu", ["train.normalizer_warmup=some"])


def test_a_run_yaml_spelling_the_keys_out_resumes_under_the_policy_and_a_change_is_refused(tmp_path):
    """Runs written before ``train.policy`` hold every key; they resume as the policy naming the same choices."""
    spelled = load_config(
        "impact_plate_official", [f"train.{k}={v[1]}" for k, v in AUTHORS.items()] + ["train.policy=hcmt"]
    )
    run = {"model": {"name": "hcmt"}, "seed": 0, "world_size": 1}
    check_resume(dict(run, config=spelled), dict(run, config=load_config("impact_plate_official")), tmp_path)
    with pytest.raises(ValueError, match=r"config\.train\.loss_denominator: 'nodes' \(run\) vs 'masked' \(now\)"):
        check_resume(dict(run, config=spelled), dict(run, config=load_config("impact_plate_cpu")), tmp_path)


def test_the_official_policys_step_against_hcmts(tmp_path, tiny_config):
    """One step on the same batch from the same parameters: the mesh normalizer counts level 0's edges twice, the
    loss is the masked error over N nodes, Adam's ε is Keras' ε̂ = 1e-7 in PyTorch's form, the decay is per step;
    during an official warm-up only the node normalizer counts."""
    data = write_impact_like(tmp_path / "data")

    def trainer(name, *extra):
        cfg = tiny_config("train.steps=4", "train.normalizer_steps=0", "train.lr_final=1e-5", *extra)
        return Trainer(cfg, data, "hcmt", tmp_path / name, seed=0, resume=False, device="cpu", progress=False)

    ours, theirs = trainer("hcmt"), trainer("official", "train.policy=official")
    graph, tgt, mask = batch = collate_samples([ours.frames[0]])
    assert graph.level_edges  # a hierarchy: mesh_edges_twice applies
    loss_ours, lr = ours.step(*batch)
    loss_theirs, lr_theirs = theirs.step(*batch)
    assert lr == lr_theirs == 1e-3  # step 0
    loss_twice, _ = trainer("twice", "train.mesh_edges_twice=true").step(*batch)  # the same statistics as theirs
    assert loss_twice != loss_ours
    assert loss_theirs == pytest.approx(loss_twice * float(mask.sum()) / graph.num_nodes, rel=1e-6)
    extra = float(theirs.model.mesh_normalizer.count - ours.model.mesh_normalizer.count)
    assert extra == graph.mesh_features.shape[0]
    assert ours.opt.param_groups[0]["eps"] == 1e-8
    assert theirs.opt.param_groups[0]["eps"] == pytest.approx(keras_epsilon(1e-7, 0.999, 1))
    assert ours.learning_rate(2) == pytest.approx(1e-3 * (1e-5 / 1e-3) ** 0.5)
    assert theirs.learning_rate(2) == pytest.approx(1e-3 * 0.1 ** (2 / 1e6))
    warm = trainer("warm", "train.policy=official", "train.normalizer_steps=2")
    before = {k: v.clone() for k, v in warm.model.state_dict().items() if "normalizer" not in k}
    warm.step(*batch)
    m = warm.model
    assert m.node_normalizer.count > 0 and m.mesh_normalizer.count == 0 and m.output_normalizer.count == 0
    for k, v in before.items():
        assert torch.equal(m.state_dict()[k], v), k  # no update while warming up
