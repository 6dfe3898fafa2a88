r"""The updater (paper "Decoder and Updater"): integrate the decoded, un-normalized output into positions.

* first order (velocity outputs; Impact Plate, Deforming Plate, Deformable Plate):
  :math:`\hat x^{t+1}_i = x^t_i + \hat{\dot x}^t_i`, the velocity being the per-step displacement
  :math:`x^{t+1} - x^t` (the same units as the input velocity :math:`x^t - x^{t-1}`, paper Table 9);
* second order (acceleration outputs; Sphere Simple, as MeshGraphNets' cloth):
  :math:`\hat x^{t+1}_i = 2x^t_i - x^{t-1}_i + \hat{\ddot x}^t_i`.

The kinematic quantity is the first ``dim`` channels of the output; further channels (stress) are returned as
they are.
"""

from __future__ import annotations

from torch import Tensor

from hcmt.errors import InputError


def update_positions(
    output: Tensor, position: Tensor, previous_position: Tensor | None = None, *, order: int = 1
) -> tuple[Tensor, Tensor]:
    """``(next_position [N, dim], remaining output channels [N, out - dim])`` from an un-normalized output."""
    dim = position.shape[-1]
    if output.shape[-1] < dim or output.shape[:-1] != position.shape[:-1]:
        raise InputError(
            f"output {tuple(output.shape)} must start with {dim} kinematic channels for positions "
            f"{tuple(position.shape)}"
        )
    kin, rest = output[..., :dim], output[..., dim:]
    if order == 1:
        return position + kin, rest
    if order == 2:
        if previous_position is None:
            raise InputError("second-order integration needs previous_position (x^{t-1})")
        return 2 * position - previous_position + kin, rest
    raise InputError(f"integration order must be 1 (velocity) or 2 (acceleration), got {order}")
