r"""Graph Transformer baseline with edge features (Dwivedi & Bresson 2021; paper appendix "Baseline Details").

MGN's encoders and decoder; ``blocks`` (15) GT layers, ``heads`` (4), hidden 128, no positional encoding, over
mesh and contact edges **together** (one edge set: the two encoded sets concatenated). One layer, as in the
reference ``GraphTransformerLayer`` with edge features (residual, then LayerNorm; BatchNorm is unusable at batch
size 1), with the paper's changes (HCMT's three-layer FFN; clip range [−2, 2]):

.. math::
    \hat w_{ij} = \frac{Q h_i \odot K h_j}{\sqrt{d_k}} \odot E e_{ij},\qquad
    w^k_{ij} = \operatorname{softmax}_j\big(\operatorname{clip}(\textstyle\sum_{c\in k}\hat w_{ij,c}, -2, 2)\big),

    h_i \leftarrow \mathrm{LN}(h_i + O_h \Vert_k \textstyle\sum_j w^k_{ij} V^k h_j),\quad
    e_{ij} \leftarrow \mathrm{LN}(e_{ij} + O_e \hat w_{ij}),\quad
    x \leftarrow \mathrm{LN}(x + \mathrm{FFN}(x)) \text{ for } x = h, e.

Unlike HCMT, the score is one scalar per head (summed over the head's channels) and the edge features are
updated, as in Dwivedi & Bresson.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor, nn
from torch_geometric.utils import scatter, softmax

from hcmt.errors import InputError
from hcmt.graph.batch import Graph

from .attention import AttentionTap, TapSite
from .base import Simulator
from .mlp import ffn
from .registry import register


class GTLayer(nn.Module):
    def __init__(self, hidden: int = 128, heads: int = 4, clip: float = 2.0, *, update_edges: bool = True):
        super().__init__()
        if hidden % heads:
            raise InputError(f"hidden size {hidden} must be divisible by the number of heads {heads}")
        if not clip > 0:
            raise InputError(f"clip range must be positive, got {clip}")
        self.heads, self.d_k, self.clip = heads, hidden // heads, float(clip)
        self.qkv = nn.Linear(hidden, 3 * hidden, bias=False)
        self.E = nn.Linear(hidden, hidden, bias=False)
        self.O_h, self.norm1_h, self.norm2_h, self.ffn_h = (
            nn.Linear(hidden, hidden),
            nn.LayerNorm(hidden),
            nn.LayerNorm(hidden),
            ffn(hidden),
        )
        self.update_edges = update_edges
        self.tap = AttentionTap()  # the weights, for hcmt.models.attention.recording
        if update_edges:  # the last layer's edge update would feed nothing: it has none (no dead parameters)
            self.O_e, self.norm1_e, self.norm2_e, self.ffn_e = (
                nn.Linear(hidden, hidden),
                nn.LayerNorm(hidden),
                nn.LayerNorm(hidden),
                ffn(hidden),
            )

    def forward(self, h: Tensor, e: Tensor, edges: Tensor) -> tuple[Tensor, Tensor]:
        n, hidden = h.shape
        j, i = edges[0], edges[1]
        q, k, v = self.qkv(h).view(n, 3, self.heads, self.d_k).unbind(1)
        w_hat = q.index_select(0, i) * k.index_select(0, j) / math.sqrt(self.d_k)
        w_hat = w_hat * self.E(e).view(-1, self.heads, self.d_k)  # [E, H, d_k]
        weights = self.tap(
            softmax(w_hat.sum(-1).clamp(-self.clip, self.clip), i, num_nodes=n, dim=0), edges, "mesh+contact", True
        )  # [E, H]
        agg = scatter(weights.unsqueeze(-1) * v.index_select(0, j), i, dim=0, dim_size=n, reduce="sum")
        h = self.norm1_h(h + self.O_h(agg.reshape(n, hidden)))
        h = self.norm2_h(h + self.ffn_h(h))
        if self.update_edges:
            e = self.norm1_e(e + self.O_e(w_hat.reshape(-1, hidden)))
            e = self.norm2_e(e + self.ffn_e(e))
        return h, e


@register(
    "gt",
    "GT (Graph Transformer)",
    has_attention=True,  # the label: not "ground truth"
    settings=("hidden", "blocks", "heads", "clip"),
)
class GT(Simulator):
    r"""Graph Transformer (Dwivedi & Bresson 2021), the paper's attention baseline: encode, ``blocks`` layers of
    clipped edge-gated attention over mesh and contact edges together (one softmax per receiver), edges updated
    in every layer but the last, decode.

    Args:
        node_in, mesh_in, contact_in, out: feature and output widths, as :class:`~hcmt.models.hcmt.HCMT`.
        blocks: Transformer layers (15, the depth of the paper's HCMT).
        heads: attention heads (4).
        hidden: latent width (128).
        clip: the clip range of the attention logits.

    Shapes: ``graph.node_features [N, node_in]``, ``graph.mesh_features [E, mesh_in]`` with ``mesh_edges [2, E]``,
    ``graph.contact_features [C, contact_in]`` with ``contact_edges [2, C]``; ``forward`` returns the normalized
    output ``[N, out]``, ``denormalize`` the physical one. Save with :func:`hcmt.models.checkpoint_state`, load with
    :func:`hcmt.models.from_checkpoint` (the constructor arguments travel with the weights).
    """

    def __init__(
        self,
        node_in: int,
        mesh_in: int,
        contact_in: int,
        out: int,
        *,
        blocks: int = 15,
        heads: int = 4,
        hidden: int = 128,
        clip: float = 2.0,
    ):
        super().__init__(node_in, mesh_in, contact_in, out, hidden=hidden)
        if blocks < 1:
            raise InputError(f"GT needs at least one layer, got {blocks}")
        self.layers = nn.ModuleList(GTLayer(hidden, heads, clip, update_edges=n < blocks - 1) for n in range(blocks))

    def attention_taps(self) -> list[TapSite]:
        """Layer ℓ's map ``gt{ℓ}`` on level 0, over mesh and contact edges together."""
        return [TapSite(layer.tap, f"gt{n}", "gt", n, 0) for n, layer in enumerate(self.layers)]

    def forward(self, graph: Graph, accumulate: bool | None = None) -> Tensor:
        """Normalized output ``[N, out]`` (:func:`~hcmt.models.attention.recording` collects one
        :class:`~hcmt.models.attention.AttentionMap` per layer, over mesh and contact edges together)."""
        self.check_graph(graph)
        acc = self._accumulating(accumulate)
        h = self.encode_nodes(graph, acc)
        e = torch.cat([self.encode_mesh(*self.mesh_inputs(graph), accumulate=acc), self.encode_contact(graph, acc)])
        edges = torch.cat([graph.mesh_edges, graph.contact_edges], dim=1)
        for layer in self.layers:
            h, e = self.run_block(layer, h, e, edges)
        return self.decoder(h)
