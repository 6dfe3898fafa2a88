r"""MeshGraphNets baseline (Pfaff et al. 2021; paper appendix "Baseline Details"), with contact edges.

Encode-process-decode with ``blocks`` (15) message-passing blocks, hidden 128, DeepMind's scheme: each edge set
has its own edge MLP and is summed **separately** into the node update,

.. math::
    e'_{ij} = e_{ij} + f_{mesh}([e_{ij}, z_j, z_i]),\quad s'_{iq} = s_{iq} + f_{contact}([s_{iq}, z_q, z_i]),\quad
    z'_i = z_i + f_{node}([z_i, \textstyle\sum_j e'_{ij}, \sum_q s'_{iq}]),

where the sums take the *updated* messages (before the edge residual, as DeepMind's ``_update_edge_features``
output is aggregated and the residual added afterwards). Every f is :func:`~hcmt.models.mlp.mlp` (two hidden
layers, LayerNorm). Aggregation is a scatter-sum over receivers (row 1 of the edges).
"""

from __future__ import annotations

import torch
from torch import Tensor, nn
from torch_geometric.utils import scatter

from hcmt.errors import InputError
from hcmt.graph.batch import Graph

from .base import Simulator
from .mlp import mlp
from .registry import register


class MGNBlock(nn.Module):
    def __init__(self, hidden: int = 128):
        super().__init__()
        self.mesh_edge = mlp(3 * hidden, hidden, hidden)
        self.contact_edge = mlp(3 * hidden, hidden, hidden)
        self.node = mlp(3 * hidden, hidden, hidden)

    @staticmethod
    def _edge_update(f: nn.Sequential, e: Tensor, z: Tensor, edges: Tensor) -> Tensor:
        """``f([e_ij, z_j, z_i])`` with f's first layer split by its input blocks,
        :math:`W[e, z_j, z_i] + b = W_e e + (W_s z)_j + (W_r z)_i + b`: the node terms once per node, then gathered
        per edge, instead of a ``[E, 3d]`` concatenation through ``[3d, d]`` (PhysicsNeMo's "concat trick"; the
        same parameters, equal up to float rounding: tests/models/test_models_parts.py)."""
        first, *rest = f
        w_e, w_s, w_r = first.weight.split(e.shape[-1], dim=1)
        h = (
            nn.functional.linear(e, w_e, first.bias)
            + nn.functional.linear(z, w_s).index_select(0, edges[0])
            + nn.functional.linear(z, w_r).index_select(0, edges[1])
        )
        for layer in rest:
            h = layer(h)
        return h

    def forward(self, z: Tensor, e: Tensor, mesh_edges: Tensor, s: Tensor, contact_edges: Tensor):
        n = z.shape[0]
        de = self._edge_update(self.mesh_edge, e, z, mesh_edges)
        ds = self._edge_update(self.contact_edge, s, z, contact_edges)
        agg_mesh = scatter(de, mesh_edges[1], dim=0, dim_size=n, reduce="sum")
        agg_contact = scatter(ds, contact_edges[1], dim=0, dim_size=n, reduce="sum")
        z = z + self.node(torch.cat([z, agg_mesh, agg_contact], dim=-1))
        return z, e + de, s + ds


@register("mgn", "MGN", settings=("hidden", "blocks"))
class MGN(Simulator):
    r"""MeshGraphNets (Pfaff et al. 2021), the paper's baseline: encode, ``blocks`` message-passing blocks that
    update mesh edges, contact edges and nodes (:math:`e'_{ij} = f(e_{ij}, v_i, v_j)`,
    :math:`v'_i = g(v_i, \sum_j e'_{ij}, \sum_q s'_{iq})`, residual), decode.

    Args:
        node_in, mesh_in, contact_in, out: feature and output widths, as :class:`~hcmt.models.hcmt.HCMT`.
        blocks: message-passing blocks (MeshGraphNets: 15).
        hidden: latent width (128).

    Shapes: ``graph.node_features [N, node_in]``, ``graph.mesh_features [E, mesh_in]`` with ``mesh_edges [2, E]``,
    ``graph.contact_features [C, contact_in]`` with ``contact_edges [2, C]``; ``forward`` returns the normalized
    output ``[N, out]``, ``denormalize`` the physical one. Save with :func:`hcmt.models.checkpoint_state`, load with
    :func:`hcmt.models.from_checkpoint` (the constructor arguments travel with the weights).
    """

    def __init__(self, node_in: int, mesh_in: int, contact_in: int, out: int, *, blocks: int = 15, hidden: int = 128):
        super().__init__(node_in, mesh_in, contact_in, out, hidden=hidden)
        if blocks < 1:
            raise InputError(f"MGN needs at least one message-passing block, got {blocks}")
        self.blocks = nn.ModuleList(MGNBlock(hidden) for _ in range(blocks))

    def forward(self, graph: Graph, accumulate: bool | None = None) -> Tensor:
        """Normalized output ``[N, out]``; the hierarchy fields of ``graph`` are ignored."""
        self.check_graph(graph)
        acc = self._accumulating(accumulate)
        z = self.encode_nodes(graph, acc)
        e = self.encode_mesh(*self.mesh_inputs(graph), accumulate=acc)
        s = self.encode_contact(graph, acc)
        for block in self.blocks:
            z, e, s = self.run_block(block, z, e, graph.mesh_edges, s, graph.contact_edges)
        return self.decoder(z)
