"""The optimizer's schedule: the paper's learning-rate decay and the authors' Keras Adam ε."""

from __future__ import annotations

import math


def learning_rate(
    step: int, steps: int, lr: float, lr_final: float, decay_steps: int | None = None, decay_rate: float = 0.1
) -> float:
    """Exponential decay from ``lr`` at step 0 to ``lr_final`` at the last step (paper: 1e-4 -> 1e-6).

    With ``decay_steps`` (``train.lr_decay_steps``) the decay is by step instead, without floor:
    ``lr * decay_rate ** (step / decay_steps)``, the authors' code (run_model.py:
    ``exponential_decay(1e-4, step, decay_steps=1e6, decay_rate=0.1)``); the run's length then does not matter."""
    if decay_steps:
        return lr * decay_rate ** (step / decay_steps)
    return lr * (lr_final / lr) ** min(step / max(steps, 1), 1.0)


def keras_epsilon(epsilon_hat: float, beta2: float, t: int) -> float:
    """PyTorch Adam's ε that reproduces TF/Keras Adam's ``epsilon`` ε̂ at optimizer step ``t`` (1-based).

    Keras updates ``θ −= lr·sqrt(1−β₂ᵗ)/(1−β₁ᵗ) · m / (sqrt(v) + ε̂)``, PyTorch ``θ −= lr · m̂ / (sqrt(v̂) + ε)``
    with ``m̂ = m/(1−β₁ᵗ)``, ``v̂ = v/(1−β₂ᵗ)``: equal for ``ε = ε̂ / sqrt(1 − β₂ᵗ)``."""
    return epsilon_hat / math.sqrt(1.0 - beta2**t)
