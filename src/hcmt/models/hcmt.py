r"""Hierarchical Contact Mesh Transformer (paper §3.2): encoder → CMT → HMT → decoder (→ updater).

* **CMT layer**: :math:`L_C` two-branch :class:`~hcmt.models.block.TransformerBlock`\ s on level 0, one branch over
  mesh edges :math:`E_0`, one over contact edges :math:`C` (eqs. 1–4).
* **HMT layer**: a U over the mesh hierarchy with :math:`\lambda` levels, one mesh-attention block per level on the
  way down (levels :math:`0..\lambda-1`), one at the bottom (level :math:`\lambda`) and one per level on the way up
  (levels :math:`\lambda-1..0`), so :math:`L_H = 2\lambda + 1` (eqs. 5–7; the authors' code). Contact edges are
  not used ("contact-then-propagate").

  - *Pooling* gathers the kept nodes: :math:`h^{l+1} = h^{l}[\mathrm{pool}_l]`.
  - *Unpooling* **replaces** the kept rows of level :math:`l`'s saved (post-down-block) features by the coarse
    features: ``saved.index_copy(0, pool[l], h)`` (the authors' ``tensor_scatter_nd_update``). Replacing, not
    adding, because the coarse features were obtained from those same saved rows by residual blocks
    (:math:`h_{coarse} = h_{saved}[\mathrm{pool}] + \Delta`), so replacing adds exactly the update :math:`\Delta`;
    adding would count :math:`h_{saved}` twice at kept nodes only.
  - Edge features: every level's raw edge features go through the one mesh normalizer and encoder (in one call);
    going up, a level reuses the same encoded edge features it used going down (paper: "the (ℓ−1)-th edge feature
    uses the (L_H−ℓ)-th edge feature after reaching the final level λ").

* **Decoder and updater**: the decoder (no LayerNorm) gives the normalized output; ``denormalize`` then
  :func:`hcmt.domains.updater.update_positions` (first order, :math:`\hat x^{t+1} = x^t + \hat{\dot x}^t`) give
  positions.

* **Ablations** (``ablation=``): ``late-contact`` (HMT, then CMT), ``only-cmt`` (:math:`L_C + L_H` CMT blocks, so the
  depth :math:`L = 15` of the paper is kept; no hierarchy), ``only-hmt`` (HMT alone, :math:`L_H` blocks, contact
  edges unused), ``lpe`` (+ Laplacian eigenvector PE, :mod:`hcmt.models.lpe`), ``single-branch`` (CMT blocks put
  mesh and contact edges in one softmax). The paper's remeshing ablation leaves the model unchanged: it is a graph
  setting, ``data.remesh: false`` (the coarse edges without Delaunay; :func:`hcmt.models.uses_hierarchy`). The clip
  range ``c`` is the ``clip`` setting.

* **The authors' variant** (``attention="official"``, ``ffn_bias=False``): their unnormalized attention sum and
  bias-free FFNs (:mod:`hcmt.models.attention`), in every CMT and HMT block and every ablation; config
  ``impact_plate_official``.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from hcmt.config import ABLATIONS, NO_REMESH, ModelConfig as _M  # the schema's defaults are the defaults
from hcmt.errors import DatasetError, InputError
from hcmt.graph.batch import Graph
from hcmt.graph.hierarchy import pool as pool_nodes, unpool

from .attention import TapSite, check_mode
from .base import Simulator
from .block import TransformerBlock
from .lpe import LaplacianPE
from .registry import register


class HMT(nn.Module):
    """The hierarchical mesh Transformer layer: ``2λ + 1`` one-branch blocks over the levels' mesh edges."""

    def __init__(
        self,
        levels: int,
        hidden: int = 128,
        heads: int = 4,
        clip: float = 2.0,
        *,
        attention: str = "paper",
        ffn_bias: bool = True,
    ):
        super().__init__()
        if levels < 0:
            raise InputError(f"number of levels λ must be >= 0, got {levels}")
        self.levels = levels

        def make():
            return TransformerBlock(hidden, heads, clip, edge_types=1, attention=attention, ffn_bias=ffn_bias)

        self.down = nn.ModuleList(make() for _ in range(levels))
        self.bottom = make()
        self.up = nn.ModuleList(make() for _ in range(levels))

    def forward(
        self, h: Tensor, latents: list[Tensor], edges: list[Tensor], pool: list[Tensor], run_block=None
    ) -> Tensor:
        """latents/edges: level 0..λ encoded mesh-edge features and edges; pool: λ kept-index tensors."""
        saved = []
        call = run_block or (lambda block, *args: block(*args))  # the model's (maybe checkpointed) block call

        def run(block, h, level):
            return call(block, h, [(latents[level], edges[level])])

        for level, block in enumerate(self.down):
            h = run(block, h, level)
            saved.append(h)
            h = pool_nodes(h, pool[level])
        h = run(self.bottom, h, self.levels)
        for level in reversed(range(self.levels)):
            h = unpool(h, saved[level], pool[level])
            h = run(self.up[level], h, level)
        return h


@register(
    "hcmt",
    "HCMT",
    needs_hierarchy=True,
    has_attention=True,
    extra=("lpe_k",),
    settings=("ablation", "levels", "L_C", "hidden", "heads", "clip", "attention", "ffn_bias"),
)
class HCMT(Simulator):
    r"""The Hierarchical Contact Mesh Transformer (paper §3.2, module docstring): encode, :math:`L_C` CMT blocks over
    level-0 mesh and contact edges (eqs. 1–4), an HMT U over :math:`\lambda` pooled levels,
    :math:`L_H = 2\lambda + 1` blocks (eqs. 5–7), decode.

    Args:
        node_in, mesh_in, contact_in, out: the widths of the raw node, mesh-edge and contact-edge features and
            of the output (paper Table 9; :class:`~hcmt.models.base.Simulator` lists them).
        L_C: contact-mesh Transformer blocks (paper Table 8: 2).
        levels: λ, the pooled levels of the hierarchy (Table 8: 4-6; 0 = no HMT).
        hidden: latent width :math:`d` (Table 8: 128).
        heads: attention heads (Table 8: 4).
        clip: the clip range :math:`c` of the attention logits (eq. 1).
        ablation: None or one of :data:`ABLATIONS` (paper Tables 3, 10-12).
        lpe_k: Laplacian eigenvectors of the ``lpe`` ablation.
        attention: ``paper`` (eq. 1, a per-receiver softmax) or ``official`` (the authors' unnormalized sum).
        ffn_bias: biases in the blocks' feed-forward networks (the authors' code: False).

    Shapes: ``graph.node_features [N, node_in]``, ``graph.mesh_features [E, mesh_in]`` with ``mesh_edges [2, E]``,
    ``graph.contact_features [C, contact_in]`` with ``contact_edges [2, C]``; ``forward`` returns the normalized
    output ``[N, out]`` (hierarchy: ``graph.pool``, ``graph.level_edges``, ``graph.level_features``),
    ``denormalize`` the physical one. Save with :func:`hcmt.models.checkpoint_state`, load with
    :func:`hcmt.models.from_checkpoint` (the constructor arguments travel with the weights).
    """

    def __init__(
        self,
        node_in: int,
        mesh_in: int,
        contact_in: int,
        out: int,
        *,
        L_C: int = _M.L_C,
        levels: int = _M.levels,
        hidden: int = _M.hidden,
        heads: int = _M.heads,
        clip: float = _M.clip,
        ablation: str | None = None,
        lpe_k: int = 8,
        attention: str = _M.attention,
        ffn_bias: bool = _M.ffn_bias,
    ):
        super().__init__(node_in, mesh_in, contact_in, out, hidden=hidden)
        if ablation in ("", "none"):
            ablation = None
        if ablation is not None and ablation not in ABLATIONS:
            raise InputError(
                f"unknown ablation {ablation!r}; expected one of {', '.join(ABLATIONS)} or None"
                + (
                    "; no remeshing is a graph setting: data.remesh=false (hcmt.models.uses_hierarchy)"
                    if ablation == NO_REMESH
                    else ""
                )
            )
        if L_C < 0 or levels < 0:
            raise InputError(f"L_C and λ must be >= 0, got L_C={L_C}, levels={levels}")
        self.ablation, self.L_C, self.levels, self.clip = ablation, L_C, levels, float(clip)
        self.attention_mode, self.ffn_bias = check_mode(attention), bool(ffn_bias)
        self.L_H = 2 * levels + 1
        cmt_blocks = {"only-cmt": L_C + self.L_H, "only-hmt": 0}.get(ablation, L_C)
        self.cmt = nn.ModuleList(
            TransformerBlock(
                hidden,
                heads,
                clip,
                edge_types=2,
                merge_branches=ablation == "single-branch",
                attention=attention,
                ffn_bias=ffn_bias,
            )
            for _ in range(cmt_blocks)
        )
        self.hmt = (
            None if ablation == "only-cmt" else HMT(levels, hidden, heads, clip, attention=attention, ffn_bias=ffn_bias)
        )
        self.lpe = LaplacianPE(hidden, lpe_k) if ablation == "lpe" else None
        if not self.cmt:  # only-hmt never sees contact edges: no unused parameters
            self.contact_encoder = None

    def attention_taps(self) -> list[TapSite]:
        """CMT block ℓ's branches ``cmt{ℓ}.mesh`` / ``cmt{ℓ}.contact`` on level 0; HMT's ``hmt.down{l}`` and
        ``hmt.up{l}`` on level ``l``, ``hmt.bottom{λ}`` on level λ."""
        sites = [TapSite(b.tap, f"cmt{n}.{{branch}}", "cmt", n, 0) for n, b in enumerate(self.cmt)]
        if self.hmt is not None:
            lam = self.levels
            sites += [
                TapSite(b.tap, f"hmt.{stage}{n}", stage, n, n)
                for stage in ("down", "up")
                for n, b in enumerate(getattr(self.hmt, stage))
            ]
            sites.append(TapSite(self.hmt.bottom.tap, f"hmt.bottom{lam}", "bottom", lam, lam))
        return sites

    @property
    def uses_hierarchy(self) -> bool:
        return self.hmt is not None and self.levels > 0

    def _levels(self, graph: Graph):
        if not self.uses_hierarchy:
            return [], [], []
        if graph.num_levels < self.levels:
            raise DatasetError(
                f"graph has {graph.num_levels} pooled levels, the model needs λ={self.levels}", field="pool"
            )
        pool, edges, feats = (
            graph.pool[: self.levels],
            graph.level_edges[: self.levels],
            graph.level_features[: self.levels],
        )
        for l, f in enumerate(feats):
            if f.dim() != 2 or f.shape[1] != self.mesh_in or f.shape[0] != edges[l].shape[1]:
                raise DatasetError(
                    f"level {l + 1}: expected [{edges[l].shape[1]}, {self.mesh_in}], got {tuple(f.shape)}",
                    field="level_features",
                )
        return pool, edges, feats

    def mesh_inputs(self, graph: Graph) -> tuple[Tensor, Tensor | None]:
        """Level 0's and every pooled level's raw mesh-edge features, in one tensor, and their mask."""
        level_feats = self._levels(graph)[2]
        mask = None if graph.mesh_mask is None else torch.cat([graph.mesh_mask, *graph.level_masks[: len(level_feats)]])
        return torch.cat([graph.mesh_features, *level_feats]), mask

    def forward(self, graph: Graph, accumulate: bool | None = None) -> Tensor:
        """Normalized output ``[N, out]``; :func:`~hcmt.models.attention.recording` collects the attention maps
        (:class:`~hcmt.models.attention.AttentionMap`), one per block and branch."""
        self.check_graph(graph)
        acc = self._accumulating(accumulate)
        pool, level_edges, level_feats = self._levels(graph)
        z = self.encode_nodes(graph, acc)
        if self.lpe is not None:
            z = z + self.lpe(graph.mesh_edges, graph.num_nodes, graph.batch)
        # one normalizer/encoder call for the mesh edges of every level (ε_mesh is shared across levels)
        sizes = [graph.mesh_features.shape[0]] + [f.shape[0] for f in level_feats]
        latents = list(self.encode_mesh(*self.mesh_inputs(graph), accumulate=acc).split(sizes))
        edges = [graph.mesh_edges, *level_edges]
        contact = self.encode_contact(graph, acc) if len(self.cmt) else None

        def cmt(z):
            for block in self.cmt:
                z = self.run_block(block, z, [(latents[0], graph.mesh_edges), (contact, graph.contact_edges)])
            return z

        def hmt(z):
            return z if self.hmt is None else self.hmt(z, latents, edges, pool, self.run_block)

        z = cmt(hmt(z)) if self.ablation == "late-contact" else hmt(cmt(z))
        return self.decoder(z)
