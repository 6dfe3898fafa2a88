"""Online feature normalizer, as MeshGraphNets' ``normalization.Normalizer``.

Running statistics over every row seen while accumulating: ``mean = Σx / n``,
``std = max(sqrt(Σx²/n − mean²), ε)``; accumulation stops after ``max_accumulations`` calls. The statistics are
buffers, so they are saved in the model's ``state_dict`` and move with ``.to(device)``. Sums are kept in float64
(float32 sums of 10⁶ batches lose the variance to cancellation). Before anything was accumulated the normalizer is
the identity (mean 0, std 1) rather than MGN's division by ε, so an untrained model in eval mode stays finite.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from hcmt.errors import InputError


class Normalizer(nn.Module):
    def __init__(self, size: int, *, max_accumulations: int = 10**6, std_epsilon: float = 1e-8):
        super().__init__()
        if size < 1:
            raise InputError(f"Normalizer size must be positive, got {size}")
        self.size, self.max_accumulations, self.std_epsilon = size, int(max_accumulations), float(std_epsilon)
        self.register_buffer("count", torch.zeros((), dtype=torch.float64))
        self.register_buffer("num_accumulations", torch.zeros((), dtype=torch.float64))
        self.register_buffer("sum", torch.zeros(size, dtype=torch.float64))
        self.register_buffer("sum_squared", torch.zeros(size, dtype=torch.float64))

    @torch.no_grad()
    def reset(self) -> None:
        """Forget the statistics: the state of a new normalizer (a fine-tuning run that re-accumulates them)."""
        for b in self.buffers():
            b.zero_()

    def _check(self, x: Tensor) -> None:
        if x.dim() != 2 or x.shape[1] != self.size:
            raise InputError(f"Normalizer expects features [rows, {self.size}], got shape {tuple(x.shape)}")

    @torch.no_grad()
    def accumulate(self, x: Tensor, mask: Tensor | None = None) -> None:
        """Add the rows of ``x`` to the statistics (no-op once ``max_accumulations`` is reached or x is empty).

        ``mask`` ``[rows]`` (1 real, 0 dummy; padded graphs) adds only the real rows (a mask of zeros counts as
        empty). One branch-free path for both: no Python test of a tensor's value, so a CUDA step does not wait for
        the device here and a compiled step does not break its graph."""
        self._check(x)
        x64 = x.detach().to(torch.float64)
        if mask is None:
            rows = torch.tensor(float(x.shape[0]), dtype=torch.float64, device=x.device)
        else:
            real = mask.to(torch.float64)
            x64, rows = x64 * real[:, None], real.sum()
        on = (self.num_accumulations < self.max_accumulations) & (rows > 0)
        zero = x64.new_zeros(())
        self.count += torch.where(on, rows, zero)
        self.sum += torch.where(on, x64.sum(0), zero)
        self.sum_squared += torch.where(on, (x64 * x64).sum(0), zero)
        self.num_accumulations += on.to(torch.float64)

    def mean(self) -> Tensor:
        return (self.sum / self.count.clamp(min=1.0)).float()

    def std(self) -> Tensor:
        n = self.count.clamp(min=1.0)
        var = (self.sum_squared / n - (self.sum / n) ** 2).clamp(min=0.0)
        std = var.sqrt().clamp(min=self.std_epsilon)
        return torch.where(self.count > 0, std, torch.ones_like(std)).float()

    def forward(self, x: Tensor, accumulate: bool = False, mask: Tensor | None = None) -> Tensor:
        """Normalize ``x`` (after adding its rows, or its ``mask``ed rows, to the statistics when ``accumulate``)."""
        if accumulate:
            self.accumulate(x, mask)
        else:
            self._check(x)
        return (x - self.mean().to(x.dtype)) / self.std().to(x.dtype)

    def inverse(self, x: Tensor) -> Tensor:
        """Un-normalize: ``x · std + mean``."""
        self._check(x)
        return x * self.std().to(x.dtype) + self.mean().to(x.dtype)

    def extra_repr(self) -> str:
        return f"size={self.size}, max_accumulations={self.max_accumulations}, std_epsilon={self.std_epsilon}"
