r"""Edge-gated multi-head graph attention with a clipped score (paper eqs. 1–3, 5–6).

For a receiver :math:`i`, its senders :math:`j` over one edge set (one *branch*), head :math:`k` and block
:math:`\ell`:

.. math::
    a^{k}_{ij} = \operatorname{softmax}_j\big(\operatorname{clip}(Q^k\mathrm{LN}(z_i)\odot K^k\mathrm{LN}(z_j)
                 / \sqrt{d_k}, -c, c) + E^k\mathrm{LN}(e_{ij})\big),\qquad
    \bar z^k_i = \sum_j a^k_{ij} \odot W^k\mathrm{LN}(e_{ij}) \odot V^k\mathrm{LN}(z_j).

Choices where the paper is ambiguous (documented here once for CMT, HMT and the ablations):

* **One score per channel, not one per head.** The edge term :math:`E\,\mathrm{LN}(e_{ij})` with
  :math:`E\in\mathbb{R}^{d\times d}` is a vector, so the score it is added to is a vector; the authors' code
  (yuyudeep/hcmt, ``single_propagate_attention``) multiplies ``q * k`` element-wise and never sums over channels.
  The softmax therefore normalizes each (head, channel) over the receiver's incoming edges of the branch: the
  weights of every receiver sum to 1 per head, per channel and per branch.
* **The edge term is added after the clip, as the paper's eq. 1 writes it.** The authors' code instead multiplies
  the clipped query-key product by :math:`E\,e_{ij}`; hcmt follows the paper, the spec.
* **Scale** :math:`\sqrt{d_k}` with :math:`d_k = d/H` the head width (the authors' code and Dwivedi & Bresson);
  the paper writes :math:`\sqrt{d_z}`, a constant factor the learned Q, K absorb.
* **Softmax, not the authors' unnormalized** ``exp``: the paper's ``softmax_j`` asks for normalized
  weights. It is numerically stable: :func:`torch_geometric.utils.softmax` subtracts the per-receiver maximum (the
  clip bounds only the query-key part; the edge term is unbounded).
* The softmax weights :math:`a_{ij}` are what :func:`propagate` returns as attention weights; the gate
  :math:`W\,\mathrm{LN}(e_{ij})` multiplies them afterwards (eq. 1 writes it as part of :math:`a`).
* Q, K, V, E, W carry no bias (they are matrices in the paper and in the authors' code).
* Nodes with no incoming edge in a branch get exactly zero from that branch (an empty segment sums to zero); a
  branch with no edges at all (no contact) contributes zeros.

**Two modes** (``model.attention``), both with these projections:

* ``paper`` (default): the formula above, the paper's eq. 1, a per-receiver softmax.
* ``official``: the authors' code exactly (yuyudeep/hcmt ``core_model.py``,
  ``MultiHeadAttentionMesh.single_propagate_attention`` and ``MultiHeadAttentionCnt.propagate_attention``):

  .. math::
      w^k_{ij} = \exp\big(\operatorname{clip}(E^k\mathrm{LN}(e_{ij}) \odot Q^k\mathrm{LN}(z_i) \odot
                 K^k\mathrm{LN}(z_j) / \sqrt{d_k}, -c, c)\big),\qquad
      \bar z^k_i = \sum_j w^k_{ij} \odot W^k\mathrm{LN}(e_{ij}) \odot V^k\mathrm{LN}(z_j).

  No normalization: the edge term sits *inside* the clip, and a sum keeps how many neighbours (e.g. contact edges)
  contribute, which a softmax removes. Every weight lies in :math:`[e^{-c}, e^{c}]`.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass

from torch import Tensor, nn
from torch_geometric.utils import scatter, softmax

from hcmt.config import ATTENTION_MODES
from hcmt.errors import InputError

#: ``model.attention``'s modes, declared with the config's other choices (:mod:`hcmt.config.choices`)
MODES = ATTENTION_MODES


@dataclass
class AttentionMap:
    """One block's attention weights as data (PyG's ``(edge_index, alpha)`` convention): what
    :func:`recording` collects from a model's forward, what pictures draw without knowing the model.

    ``name``: the block and branch (``cmt0.mesh``, ``cmt0.contact``, ``hmt.down1``, ``gt3``); ``level``: the
    hierarchy level of its nodes (0: the mesh); ``edge_index`` ``[2, E]`` (row 0 sender j, row 1 receiver i) on
    that level's nodes; ``weights`` ``[E, H, d_k]`` (or ``[E, H]``), :math:`a^k_{ij}`; ``normalized``: whether the
    weights of a receiver sum to 1 (softmax; False for the authors' unnormalized ``official`` attention)."""

    name: str
    level: int
    edge_index: Tensor
    weights: Tensor
    normalized: bool = True
    stage: str = ""  # cmt | down | bottom | up (HMT's U) | gt
    block: int = 0  # the block's number within its stage (HMT: its level)
    branch: str = "mesh"  # the edges: mesh | contact | mesh+contact


class AttentionTap(nn.Module):
    """Where a block's attention weights pass (the identity): a forward hook (:func:`recording`, on the taps the
    model declares: :class:`TapSite`) reads them there, with their edges and branch, so ``forward`` returns outputs
    only."""

    def forward(self, weights: Tensor, edges: Tensor, branch: str, normalized: bool) -> Tensor:
        return weights


@dataclass(eq=False)
class TapSite:
    """Where a model's :class:`AttentionTap` sits, as the model declares it (:meth:`attention_taps` of
    :class:`~hcmt.models.base.Simulator`): the map's ``name`` (``{branch}`` is filled with the branch the block
    passes: ``cmt0.{branch}``), its ``stage``, ``block`` number and hierarchy ``level``."""

    tap: AttentionTap
    name: str
    stage: str
    block: int = 0
    level: int = 0


def declared_taps(model: nn.Module) -> list[TapSite]:
    """The model's declared taps, refusing a model with an :class:`AttentionTap` it does not declare (a model that
    adds a tap must say where it sits, or its maps would be unnamed)."""
    sites = list(model.attention_taps()) if hasattr(model, "attention_taps") else []
    declared = {id(s.tap) for s in sites}
    missing = [path for path, m in model.named_modules() if isinstance(m, AttentionTap) and id(m) not in declared]
    if missing:
        raise RuntimeError(
            f"{type(model).__name__} has attention taps it does not declare in attention_taps(): "
            f"{', '.join(missing[:4])}"
        )
    return sites


@contextlib.contextmanager
def recording(model: nn.Module):
    """While open, every forward of ``model`` appends one :class:`AttentionMap` per block and branch, in call order,
    to the list it yields (CMT: ``cmt{ℓ}.mesh`` / ``cmt{ℓ}.contact`` on level 0; HMT: ``hmt.down{l}`` /
    ``hmt.bottom{λ}`` / ``hmt.up{l}`` on level ``l``; GT: ``gt{ℓ}``); forward hooks on the taps the model declares
    (:func:`declared_taps`)."""
    maps, handles = [], []

    def hook_for(site: TapSite):
        def hook(tap, args, weights):
            edges, branch, normalized = args[1:]
            maps.append(
                AttentionMap(
                    site.name.format(branch=branch),
                    site.level,
                    edges,
                    weights,
                    normalized,
                    site.stage,
                    site.block,
                    branch,
                )
            )

        return hook

    for site in declared_taps(model):
        handles.append(site.tap.register_forward_hook(hook_for(site)))
    try:
        yield maps
    finally:
        for h in handles:
            h.remove()


def check_mode(mode: str) -> str:
    if mode not in MODES:
        raise InputError(f"model.attention: unknown value {mode!r}; expected one of {', '.join(MODES)}")
    return mode


def propagate(
    q: Tensor,
    k: Tensor,
    v: Tensor,
    edge_term: Tensor,
    gate: Tensor,
    edges: Tensor,
    clip: float,
    mode: str = "paper",
) -> tuple[Tensor, Tensor]:
    """One attention branch, vectorized over edges.

    q, k, v: ``[N, H, d_k]`` node projections; edge_term, gate: ``[E, H, d_k]`` (``E·LN(e)``, ``W·LN(e)``);
    edges: ``[2, E]`` with row 0 the sender j and row 1 the receiver i. Returns the aggregated ``[N, H, d_k]`` and
    the weights ``[E, H, d_k]``: softmax weights :math:`a_{ij}` (``paper``) or unnormalized
    :math:`w_{ij}` (``official``).
    """
    num_nodes, _, d_k = q.shape
    j, i = edges[0], edges[1]
    score = (q.index_select(0, i) * k.index_select(0, j)) / math.sqrt(d_k)
    if mode == "official":
        weights = (edge_term * score).clamp(-clip, clip).exp()
    else:
        weights = softmax(score.clamp(-clip, clip) + edge_term, i, num_nodes=num_nodes, dim=0)
    message = weights * gate * v.index_select(0, j)
    return scatter(message, i, dim=0, dim_size=num_nodes, reduce="sum"), weights


class EdgeGatedAttention(nn.Module):
    """The projections Q, K, V (of nodes) and E, W (of edges) of one block, shared by its branches.

    The paper uses the same symbols :math:`Q_z, K_z, V_z, E_z, W_z` in both CMT branches (eqs. 1–2), and the
    authors' code shares them; each edge type keeps its own pre-LayerNorm (in the block).
    """

    def __init__(self, hidden: int = 128, heads: int = 4, clip: float = 2.0, mode: str = "paper"):
        super().__init__()
        self.mode = check_mode(mode)
        if hidden % heads:
            raise InputError(f"hidden size {hidden} must be divisible by the number of heads {heads}")
        if not clip > 0:
            raise InputError(f"clip range c must be positive, got {clip}")
        self.hidden, self.heads, self.clip = hidden, heads, float(clip)
        self.qkv = nn.Linear(hidden, 3 * hidden, bias=False)  # Q, K, V fused: one matmul
        self.ew = nn.Linear(hidden, 2 * hidden, bias=False)  # E, W fused
        self.reset_parameters()

    def reset_parameters(self) -> None:
        for lin in (self.qkv, self.ew):
            nn.init.xavier_uniform_(lin.weight)

    def project_nodes(self, z_ln: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        q, k, v = self.qkv(z_ln).view(-1, 3, self.heads, self.hidden // self.heads).unbind(1)
        return q, k, v

    def forward(self, qkv: tuple[Tensor, Tensor, Tensor], e_ln: Tensor, edges: Tensor) -> tuple[Tensor, Tensor]:
        """One branch: returns ``([N, hidden], weights [E, H, d_k])``."""
        q, k, v = qkv
        edge_term, gate = self.ew(e_ln).view(-1, 2, self.heads, self.hidden // self.heads).unbind(1)
        out, weights = propagate(q, k, v, edge_term, gate, edges, self.clip, self.mode)
        return out.reshape(-1, self.hidden), weights

    def extra_repr(self) -> str:
        return f"hidden={self.hidden}, heads={self.heads}, clip={self.clip}, mode={self.mode}"
