"""MLP factory of MeshGraphNets (Pfaff et al.), used by every encoder, decoder and MGN update function.

``mlp(in, hidden, out, layers=2)`` is ``Linear-ReLU`` repeated ``layers`` times then a final ``Linear``
(DeepMind's ``widths = [hidden] * layers + [out]``, ``activate_final=False``), followed by a ``LayerNorm`` on the
output unless ``layer_norm=False`` (the decoder has none, paper "Decoder and Updater").
"""

from __future__ import annotations

from torch import nn

from hcmt.errors import InputError


def mlp(in_size: int, hidden: int, out_size: int, *, layers: int = 2, layer_norm: bool = True) -> nn.Sequential:
    if min(in_size, hidden, out_size) < 1 or layers < 0:
        raise InputError(f"mlp sizes must be positive, got in={in_size} hidden={hidden} out={out_size} layers={layers}")
    mods: list[nn.Module] = []
    width = in_size
    for _ in range(layers):
        mods += [nn.Linear(width, hidden), nn.ReLU()]
        width = hidden
    mods.append(nn.Linear(width, out_size))
    if layer_norm:
        mods.append(nn.LayerNorm(out_size))
    return nn.Sequential(*mods)


def ffn(size: int, bias: bool = True) -> nn.Sequential:
    """The Transformer FFN of HCMT (and of the GT baseline, paper appendix): three linear layers, two ReLUs.
    ``bias=False`` is the authors' code (``core_model.FFN``: ``snt.Linear(with_bias=False)``)."""

    def lin():
        return nn.Linear(size, size, bias=bias)

    return nn.Sequential(lin(), nn.ReLU(), lin(), nn.ReLU(), lin())
