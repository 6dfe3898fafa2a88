"""The training engine's speed options agree with the reference step: the fused Adam the trainer uses
(one kernel for every parameter, on the CPU too) ends a short run within float32 rounding of PyTorch's per-tensor
Adam, the reference implementation."""

import pytest
import torch

import hcmt.training.trainer as trainer_module
from hcmt.training import train
from layouts import write_impact_like

pytestmark = pytest.mark.slow  # trains real (tiny) runs

EXTRA = [
    "model.blocks=2",
    "train.log_every=1",
    "train.checkpoint_every=100",
    "train.valid_every=0",
    "train.contact_radius=0.3",
    "train.steps=6",
    "train.noise_std=0.01",
    "train.normalizer_steps=1",
]


@pytest.fixture(scope="module")
def impact(tmp_path_factory):
    return write_impact_like(tmp_path_factory.mktemp("impact") / "data")


def final_parameters(run) -> dict:
    return torch.load(run / "checkpoint.pt", weights_only=False)["model"]


@pytest.mark.parametrize("model", ["hcmt", "mgn"])
def test_fused_adam_agrees_with_the_per_tensor_reference(impact, tmp_path, tiny_config, monkeypatch, model):
    cfg = tiny_config(*EXTRA)
    asked, adam = [], torch.optim.Adam

    def spy(reference: bool):
        def make(params, **kw):
            asked.append(dict(kw))
            if reference:  # the per-tensor loop, whatever the trainer asks for
                kw.update(fused=None, foreach=False)
            return adam(params, **kw)

        return make

    monkeypatch.setattr(trainer_module.torch.optim, "Adam", spy(False))
    train(cfg, impact, model, tmp_path / "fused", seed=2, progress=False, device="cpu")
    monkeypatch.setattr(trainer_module.torch.optim, "Adam", spy(True))
    train(cfg, impact, model, tmp_path / "reference", seed=2, progress=False, device="cpu")
    assert [kw.get("fused") for kw in asked] == [True, True]  # the trainer's choice, on the CPU
    a, b = final_parameters(tmp_path / "fused"), final_parameters(tmp_path / "reference")
    for k, v in a.items():
        if v.is_floating_point():
            # stated tolerance: 5 optimizer steps of lr 1e-3, float32 rounding (the kernels round differently)
            assert torch.allclose(v, b[k], rtol=1e-5, atol=1e-6), (k, (v - b[k]).abs().max())
