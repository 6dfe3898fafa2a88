r"""Laplacian eigenvector positional encoding (Dwivedi & Bresson), for the HCMT+LPE ablation.

For each graph of a batch, with :math:`L = I - D^{-1/2} A D^{-1/2}` the symmetric normalized Laplacian of its
mesh edges, the encoding is the eigenvectors of the :math:`k` smallest eigenvalues after the first (``k = 8``),
zero-padded when the graph has fewer than ``k + 1`` nodes. Eigenvector signs are arbitrary, so training flips each
of the ``k`` signs at random (per graph, per forward pass); the encoding enters as ``z_i += P·pe_i`` (a learned
``Linear(k, d)``), as in Dwivedi & Bresson.

Eigenvectors depend only on the mesh connectivity, which is static along a trajectory: they are computed on the
CPU with SciPy (shift-invert ``eigsh``, dense ``eigh`` for small graphs) and cached per connectivity.
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import torch
from torch import Tensor, nn

from hcmt.errors import InputError

_DENSE_BELOW = 400  # nodes: dense eigh is faster than shift-invert Lanczos below this size


def laplacian_pe(edges: np.ndarray, num_nodes: int, k: int = 8) -> np.ndarray:
    """``[num_nodes, k]`` eigenvectors of the normalized Laplacian (eigenvalues 2..k+1), float64."""
    if k < 1:
        raise InputError(f"LPE dimension k must be positive, got {k}")
    pe = np.zeros((num_nodes, k))
    if num_nodes < 2:
        return pe
    adj = sp.coo_matrix((np.ones(edges.shape[1]), (edges[1], edges[0])), shape=(num_nodes, num_nodes)).tocsr()
    adj = ((adj + adj.T) > 0).astype(np.float64)
    deg = np.asarray(adj.sum(1)).ravel()
    d_inv_sqrt = np.where(deg > 0, 1.0 / np.sqrt(np.maximum(deg, 1e-30)), 0.0)
    lap = sp.eye(num_nodes) - sp.diags(d_inv_sqrt) @ adj @ sp.diags(d_inv_sqrt)
    m = min(k + 1, num_nodes)
    if num_nodes < _DENSE_BELOW or m >= num_nodes - 1:
        vals, vecs = np.linalg.eigh(lap.toarray())
    else:  # L is PSD, so L + 1e-3·I is invertible: shift-invert finds the smallest eigenvalues fast
        vals, vecs = spla.eigsh(lap.tocsc(), k=m, sigma=-1e-3, which="LM")
    order = np.argsort(vals)[1:m]
    pe[:, : len(order)] = vecs[:, order]
    return pe


class LaplacianPE(nn.Module):
    def __init__(self, hidden: int = 128, k: int = 8, cache_size: int = 256):
        super().__init__()
        self.k, self.cache_size = int(k), int(cache_size)
        self.proj = nn.Linear(self.k, hidden)
        self._cache: OrderedDict[bytes, np.ndarray] = OrderedDict()

    def _pe(self, edges: Tensor, num_nodes: int) -> np.ndarray:
        e = edges.detach().cpu().numpy()
        key = hashlib.blake2b(e.tobytes(), digest_size=16, key=str(num_nodes).encode()).digest()
        if key not in self._cache:
            self._cache[key] = laplacian_pe(e, num_nodes, self.k)
            if len(self._cache) > self.cache_size:
                self._cache.popitem(last=False)
        self._cache.move_to_end(key)
        return self._cache[key]

    def encoding(self, mesh_edges: Tensor, num_nodes: int, batch: Tensor | None = None) -> Tensor:
        """``[N, k]`` encoding of every node, per graph of the batch (graphs are contiguous node ranges)."""
        device = mesh_edges.device
        if batch is None or num_nodes == 0:
            counts = [num_nodes]
        else:
            counts = torch.bincount(batch, minlength=int(batch.max()) + 1).tolist()
        starts = np.concatenate([[0], np.cumsum(counts)])
        edges = mesh_edges.detach().cpu()
        graph_of_edge = np.searchsorted(starts, edges[1].numpy(), side="right") - 1
        parts = []
        for b, n in enumerate(counts):  # loop over graphs of a batch, not over nodes
            sub = edges[:, torch.from_numpy(graph_of_edge == b)] - int(starts[b])
            pe = torch.from_numpy(self._pe(sub, n)).float()
            if self.training:
                pe = pe * (torch.randint(0, 2, (1, self.k)) * 2 - 1)
            parts.append(pe)
        return torch.cat(parts).to(device)

    def forward(self, mesh_edges: Tensor, num_nodes: int, batch: Tensor | None = None) -> Tensor:
        """``P·pe``: ``[N, hidden]``, added to the encoded nodes."""
        return self.proj(self.encoding(mesh_edges, num_nodes, batch).to(self.proj.weight.dtype))
