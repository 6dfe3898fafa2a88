"""Compressible neo-Hookean linear tetrahedra, vectorized over elements, assembled into scipy sparse matrices.

Strain energy per reference volume ``W = mu/2 (I1 - 3) - mu ln J + lam/2 (ln J)^2`` (``I1 = tr FᵀF``,
``J = det F``), first Piola-Kirchhoff stress ``P = mu (F - F⁻ᵀ) + lam ln J F⁻ᵀ``, Cauchy ``sigma = P Fᵀ / J``. With
``G`` the reference shape-function gradients [4,3] of a tetrahedron of volume ``V`` and ``B = G F⁻¹``:

* nodal internal force ``f_ai = V P_iJ G_aJ``;
* tangent ``K_aibk = V [mu (G Gᵀ)_ab δ_ik + (mu - lam ln J) B_bi B_ak + lam B_ai B_bk]`` (exact: Newton converges
  quadratically).

Degrees of freedom are ``3 node + i``; a fixed one is held at its given value and left out of the system. The
sparsity pattern (the elements' 12x12 blocks and one 3x3 block per node, for contact) is built once; every
assembly is one ``bincount`` onto it (no loop over elements).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from hcmt.errors import InputError
from hcmt.sim.tet import gradients


def lame(modulus: float, poisson: float) -> tuple[float, float]:
    """(lambda, mu) of Young's modulus and Poisson's ratio."""
    if not modulus > 0 or not -1.0 < poisson < 0.5:
        raise InputError(f"needs modulus > 0 and -1 < poisson < 0.5, got {modulus}, {poisson}", param="poisson")
    return modulus * poisson / ((1 + poisson) * (1 - 2 * poisson)), modulus / (2 * (1 + poisson))


def von_mises(sigma: np.ndarray) -> np.ndarray:
    """von Mises stress of Cauchy stress tensors [..., 3, 3]."""
    dev = sigma - np.trace(sigma, axis1=-2, axis2=-1)[..., None, None] * np.eye(3) / 3
    return np.sqrt(1.5 * np.einsum("...ij,...ij->...", dev, dev))


def _cofactors(F: np.ndarray) -> np.ndarray:
    """Cofactor matrices [C,3,3] (``det F = F_0j cof_0j``, ``F⁻¹ = cofᵀ / det F``): numpy's batched inv and det
    are several times slower on 3x3 blocks."""
    r0, r1, r2 = F[:, 0], F[:, 1], F[:, 2]
    return np.stack([np.cross(r1, r2), np.cross(r2, r0), np.cross(r0, r1)], 1)


@dataclass
class Pattern:
    """The reduced (free x free) CSR pattern and where each element / node-block entry lands in it."""

    keep: np.ndarray  # entries (elements' 144 each, then nodes' 9 each) inside the free system
    slot: np.ndarray  # their CSR positions
    indptr: np.ndarray
    indices: np.ndarray
    size: int


def _pattern(tets: np.ndarray, num_nodes: int, free: np.ndarray) -> Pattern:
    edof = (3 * tets[:, :, None] + np.arange(3)).reshape(len(tets), 12)
    ndof = (3 * np.arange(num_nodes)[:, None] + np.arange(3)).reshape(num_nodes, 3)
    rows = np.concatenate([np.repeat(edof, 12, 1).ravel(), np.repeat(ndof, 3, 1).ravel()])
    cols = np.concatenate([np.tile(edof, 12).ravel(), np.tile(ndof, 3).ravel()])
    reduced = np.full(3 * num_nodes, -1, np.int64)
    reduced[free] = np.arange(len(free))
    r, c = reduced[rows], reduced[cols]
    keep = np.flatnonzero((r >= 0) & (c >= 0))
    keys, slot = np.unique(r[keep] * len(free) + c[keep], return_inverse=True)
    indptr = np.searchsorted(keys // len(free), np.arange(len(free) + 1))
    return Pattern(keep, slot.ravel(), indptr, (keys % len(free)).astype(np.int32), len(keys))


@dataclass
class NeoHookean:
    """A neo-Hookean body: reference nodes ``pos`` [N,3], tetrahedra [C,4], material, fixed degrees of freedom
    (indices ``3 node + i``)."""

    pos: np.ndarray
    tets: np.ndarray
    modulus: float
    poisson: float
    fixed: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    def __post_init__(self):
        self.pos = np.asarray(self.pos, float)
        self.tets = np.asarray(self.tets, np.int64)
        self.grads, self.volume = gradients(self.pos, self.tets)
        if np.any(self.volume <= 0):
            raise InputError("every tetrahedron needs a positive volume", param="tets")
        self.lam, self.mu = lame(self.modulus, self.poisson)
        mask = np.ones(3 * len(self.pos), bool)
        mask[np.asarray(self.fixed, np.int64)] = False
        self.free = np.flatnonzero(mask)
        self.pattern = _pattern(self.tets, len(self.pos), self.free)
        # nodal sums of the elements' [C,4,3] forces as one sparse product (N x 4C), no scatter loop
        self.scatter = sp.csr_matrix(
            (np.ones(self.tets.size), (self.tets.ravel(), np.arange(self.tets.size))),
            shape=(len(self.pos), self.tets.size),
        )

    def deformation(self, x: np.ndarray) -> np.ndarray:
        """Deformation gradients F [C,3,3] of the current positions ``x`` [N,3]."""
        return np.matmul(x[self.tets].transpose(0, 2, 1), self.grads)

    def _kinematics(self, x):
        """(F, J, F⁻¹, ln J); the last two None when an element is inverted."""
        F = self.deformation(x)
        cof = _cofactors(F)
        J = np.einsum("ci,ci->c", F[:, 0], cof[:, 0])
        if np.any(J <= 0) or not np.all(np.isfinite(J)):
            return F, J, None, None
        return F, J, cof.transpose(0, 2, 1) / J[:, None, None], np.log(J)

    def energy(self, x: np.ndarray) -> float:
        """Total strain energy; ``inf`` when an element is inverted."""
        F, J, _, lnJ = self._kinematics(x)
        if lnJ is None:
            return np.inf
        W = 0.5 * self.mu * (np.einsum("cij,cij->c", F, F) - 3) - self.mu * lnJ + 0.5 * self.lam * lnJ**2
        return float(self.volume @ W)

    def forces(self, x: np.ndarray, tangent: bool = False):
        """Internal nodal forces [N,3] (``None`` when an element is inverted) and, with ``tangent``, the element
        stiffness blocks [C,4,3,4,3]."""
        F, J, Finv, lnJ = self._kinematics(x)
        if lnJ is None:
            return (None, None) if tangent else None
        B = np.matmul(self.grads, Finv)  # [C,4,3]: B_ak = G_aJ F⁻¹_Jk
        V = self.volume[:, None, None]
        fe = V * (self.mu * np.matmul(self.grads, F.transpose(0, 2, 1)) + (self.lam * lnJ - self.mu)[:, None, None] * B)
        f = self.scatter @ fe.reshape(-1, 3)
        if not tangent:
            return f
        VB = B * V
        GG = self.mu * np.matmul(self.grads * V, self.grads.transpose(0, 2, 1))  # [C,4,4]
        K = (
            self.lam * VB[:, :, :, None, None] * B[:, None, None, :, :]
            + ((self.mu - self.lam * lnJ)[:, None, None] * VB)[:, :, None, None, :]
            * B.transpose(0, 2, 1)[:, None, :, :, None]
        )
        K += GG[:, :, None, :, None] * np.eye(3)[None, None, :, None, :]
        return f, K

    def assemble(self, K: np.ndarray, node_blocks: np.ndarray | None = None) -> sp.csr_matrix:
        """The free system's CSR matrix from element blocks [C,4,3,4,3] plus optional node blocks [N,3,3]."""
        blocks = np.zeros((len(self.pos), 3, 3)) if node_blocks is None else node_blocks
        values = np.concatenate([K.ravel(), blocks.ravel()])[self.pattern.keep]
        p = self.pattern
        data = np.bincount(p.slot, weights=values, minlength=p.size)
        return sp.csr_matrix((data, p.indices, p.indptr), shape=(len(self.free), len(self.free)))

    def cauchy(self, x: np.ndarray) -> np.ndarray:
        """Cauchy stress per element [C,3,3]."""
        F, J, Finv, lnJ = self._kinematics(x)
        FinvT = Finv.transpose(0, 2, 1)
        P = self.mu * (F - FinvT) + (self.lam * lnJ)[:, None, None] * FinvT
        return np.einsum("cij,ckj->cik", P, F) / J[:, None, None]

    def nodal_von_mises(self, x: np.ndarray) -> np.ndarray:
        """Element von Mises stresses volume-averaged onto the nodes [N]."""
        vm = von_mises(self.cauchy(x))
        num = np.bincount(self.tets.ravel(), weights=np.repeat(vm * self.volume, 4), minlength=len(self.pos))
        den = np.bincount(self.tets.ravel(), weights=np.repeat(self.volume, 4), minlength=len(self.pos))
        return np.divide(num, den, out=np.zeros_like(num), where=den > 0)
