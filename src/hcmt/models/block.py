r"""The Transformer block of CMT and HMT (paper eqs. 1–4 and 5–7), pre-LayerNorm.

.. math::
    u_i = z_i + O\,\bar z_i,\qquad z_i^{\ell+1} = u_i + \mathrm{FFN}(\mathrm{LN}(u_i)),

with :math:`\bar z_i` the concatenation of the branches' multi-head outputs (eq. 3). Edge features are not
updated (paper: "the edge network remains unaltered").

* A CMT block has two branches (mesh edges, contact edges); an HMT block one (the level's mesh edges); the
  single-branch ablation puts mesh and contact edges into one softmax (each edge type still has its own LN).
* **O maps the concatenation back to d**: the paper gives :math:`O\in\mathbb{R}^{2d\times 2d}`, which cannot be
  added to :math:`z_i\in\mathbb{R}^d`; the authors' code uses ``Linear(d)`` on the ``2d`` concatenation, so here
  :math:`O\in\mathbb{R}^{d\times bd}` for :math:`b` branches, without bias.
* ``attention`` picks the weights (:mod:`hcmt.models.attention`: ``paper`` softmax or the authors' ``official``
  unnormalized sum); ``ffn_bias=False`` drops the FFN's biases as the authors' code does.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from hcmt.errors import InputError

from .attention import AttentionTap, EdgeGatedAttention
from .mlp import ffn


class TransformerBlock(nn.Module):
    def __init__(
        self,
        hidden: int = 128,
        heads: int = 4,
        clip: float = 2.0,
        *,
        edge_types: int = 1,
        merge_branches: bool = False,
        attention: str = "paper",
        ffn_bias: bool = True,
    ):
        super().__init__()
        if edge_types < 1:
            raise InputError(f"a block needs at least one edge type, got {edge_types}")
        self.edge_types, self.merge_branches = edge_types, bool(merge_branches)
        branches = 1 if merge_branches else edge_types
        self.norm_node = nn.LayerNorm(hidden)
        self.norm_edges = nn.ModuleList(nn.LayerNorm(hidden) for _ in range(edge_types))
        self.attention = EdgeGatedAttention(hidden, heads, clip, attention)
        self.tap = AttentionTap()  # the weights, for hcmt.models.attention.recording
        self.branches = ("mesh+contact",) if merge_branches and edge_types > 1 else ("mesh", "contact")[:edge_types]
        self.O = nn.Linear(branches * hidden, hidden, bias=False)
        self.norm_ffn = nn.LayerNorm(hidden)
        self.ffn = ffn(hidden, bias=ffn_bias)

    def forward(self, z: Tensor, edge_sets: list[tuple[Tensor, Tensor]]) -> Tensor:
        """z: ``[N, d]``; edge_sets: one ``(latents [E_b, d], edges [2, E_b])`` per edge type. Returns
        ``z^{ℓ+1}``; each branch's attention weights pass :attr:`tap` (:func:`~hcmt.models.attention.recording`)."""
        if len(edge_sets) != self.edge_types:
            raise InputError(f"block built for {self.edge_types} edge types, got {len(edge_sets)}")
        qkv = self.attention.project_nodes(self.norm_node(z))
        normed = [(norm(e), edges) for norm, (e, edges) in zip(self.norm_edges, edge_sets)]
        if self.merge_branches and len(normed) > 1:
            normed = [(torch.cat([e for e, _ in normed]), torch.cat([ed for _, ed in normed], dim=1))]
        outs, weights = zip(*(self.attention(qkv, e, edges) for e, edges in normed))
        for w, (_, edges), branch in zip(weights, normed, self.branches):
            self.tap(w, edges, branch, self.attention.mode == "paper")
        u = z + self.O(torch.cat(outs, dim=-1))
        return u + self.ffn(self.norm_ffn(u))
