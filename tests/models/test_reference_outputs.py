"""The safety net of refactors: every model's output and one training step's gradients equal the stored reference
(tests/reference_outputs.py) to float64 round-off."""

import pytest
import torch

import reference_outputs as ref


@pytest.mark.parametrize("label", sorted(ref.MODELS))
def test_outputs_and_gradients_equal_the_stored_reference(label):
    stored = torch.load(ref.PATH, weights_only=True)[label]
    now = ref.compute(label)
    assert set(now) == set(stored), "parameters were added, removed or renamed"
    assert now["output"].abs().max() > 1e-3 and len(now) > 10  # a real output and real gradients
    for key, value in stored.items():
        torch.testing.assert_close(now[key], value, rtol=1e-10, atol=1e-12, msg=f"{label}: {key}")
