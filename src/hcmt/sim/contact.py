"""Frictionless two-pass node-to-segment penalty contact between two bodies of a triangle mesh.

For a slave node ``s`` and a master boundary segment ``(a, b)`` with outward unit normal ``n`` (the master body on
the left of ``a -> b``), the gap is ``g = (x_s - x_a) . n`` and the projection ``xi = (x_s - x_a).(x_b - x_a)/|b-a|^2``.
A slave with ``g < 0`` and ``0 <= xi <= 1`` gets the penalty force ``p n`` (``p = -k g``) and the segment nodes get
``-p n (1 - xi)`` and ``-p n xi``: the exact gradient of the potential ``k g^2 / 2`` (the gradient of a point-line
distance with respect to the line's end points is ``-(1 - xi) n``, ``-xi n``), so contact conserves energy.
Two passes: ball nodes against plate segments, then plate nodes against ball segments.

Stiffness: ``k = alpha * min(m_s, m_a, m_b) / dt^2`` per slave-segment pair; a spring of that stiffness between the
lightest nodes has ``omega dt = sqrt(2 alpha)`` at most, so ``alpha`` of about 0.1-0.3 stays inside the stable step
(too stiff diverges). Masses carry the axisymmetric ``2 pi r`` weight, so the penalty scales like the ring area.

Candidates: each slave keeps its ``K`` nearest master segments (by midpoint, from a ``cKDTree``), refreshed every
``n`` substeps with ``n`` chosen so that no node can move more than a quarter of the shortest segment in between
(so the nearest segment cannot be missed).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree


def boundary_edges(cells: np.ndarray) -> np.ndarray:
    """Edges used by exactly one triangle, oriented as in their (counter-clockwise) cell, so the body lies on the
    left of ``a -> b`` and the outward normal is ``(t_y, -t_x) / |t|``."""
    e = np.concatenate([cells[:, [0, 1]], cells[:, [1, 2]], cells[:, [2, 0]]])
    key = np.sort(e, axis=1)
    _, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return e[cnt[inv.ravel()] == 1]


@dataclass
class ContactPass:
    slaves: np.ndarray  # [S] slave node ids (all boundary nodes of the slave body)
    segments: np.ndarray  # [M,2] master boundary segments
    # refreshed candidates
    active: np.ndarray | None = None  # [s] indices into slaves of the slaves near the master body
    cand: np.ndarray | None = None  # [s,K] segment indices


class PenaltyContact:
    """Two-pass node-to-segment penalty contact between body 0 and body 1 (``body`` [N] in {0, 1})."""

    def __init__(self, X: np.ndarray, cells: np.ndarray, body: np.ndarray, mass: np.ndarray, dt: float, *,
                 alpha: float = 0.2, exclude_axis: bool = True, k_nearest: int = 4):
        if not 0 < alpha <= 0.5:
            raise ValueError(f"penalty factor alpha must be in (0, 0.5] to stay inside the stable step, got {alpha}")
        self.mass, self.dt, self.alpha, self.K = mass, dt, alpha, k_nearest
        edges = boundary_edges(cells)
        if exclude_axis:  # segments on the symmetry line x = 0 are not surfaces
            edges = edges[~((np.abs(X[edges[:, 0], 0]) < 1e-9) & (np.abs(X[edges[:, 1], 0]) < 1e-9))]
        eb = body[edges[:, 0]]
        if np.any(eb != body[edges[:, 1]]):
            raise ValueError("a boundary edge joins the two bodies; contact needs two separate bodies")
        bnodes = np.unique(boundary_edges(cells))
        self.passes = [ContactPass(slaves=bnodes[body[bnodes] == s], segments=edges[eb == 1 - s]) for s in (0, 1)]
        lengths = np.linalg.norm(X[edges[:, 1]] - X[edges[:, 0]], axis=1)
        self.min_segment = float(lengths.min())
        self.search = 2.0 * float(lengths.max())
        self.countdown = 0

    def refresh(self, x: np.ndarray, v: np.ndarray) -> None:
        """Recompute candidate pairs and the number of substeps they stay valid."""
        for ps in self.passes:
            mid = 0.5 * (x[ps.segments[:, 0]] + x[ps.segments[:, 1]])
            k = min(self.K, len(mid))
            d, idx = cKDTree(mid).query(x[ps.slaves], k=k)
            d, idx = d.reshape(len(ps.slaves), k), idx.reshape(len(ps.slaves), k)
            near = d[:, 0] < self.search
            ps.active, ps.cand = np.flatnonzero(near), idx[near]
            seg = ps.segments[ps.cand]  # [s,K,2]
            m = self.mass
            ps.k = self.alpha * np.minimum(m[ps.slaves[ps.active]][:, None], np.minimum(m[seg[..., 0]], m[seg[..., 1]]))
            ps.k /= self.dt**2
        vmax = float(np.sqrt((v**2).sum(1).max())) if len(v) else 0.0
        self.countdown = max(1, int(0.25 * self.min_segment / (2 * vmax * self.dt + 1e-300)))

    def _pairs(self, ps: ContactPass, x: np.ndarray):
        s = ps.slaves[ps.active]
        seg = ps.segments[ps.cand]
        xs = x[s][:, None, :]
        xa, xb = x[seg[..., 0]], x[seg[..., 1]]
        t = xb - xa
        L2 = (t * t).sum(-1)
        L = np.sqrt(L2)
        r = xs - xa
        xi = (r * t).sum(-1) / L2
        n = np.stack([t[..., 1], -t[..., 0]], -1) / L[..., None]
        g = (r * n).sum(-1)
        ok = (xi >= 0) & (xi <= 1) & (g < 0) & (g > -0.5 * L)
        score = np.where(ok, g, -np.inf)
        j = np.argmax(score, axis=1)
        rows = np.arange(len(s))
        hit = ok[rows, j]
        rows, j = rows[hit], j[hit]
        return s[rows], seg[rows, j], xi[rows, j], n[rows, j], g[rows, j], ps.k[rows, j]

    def force(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Contact forces [N,2] at positions ``x`` (refreshing candidates when due)."""
        if self.countdown <= 0:
            self.refresh(x, v)
        self.countdown -= 1
        N = len(x)
        f = np.zeros((N, 2))
        for ps in self.passes:
            s, seg, xi, n, g, k = self._pairs(ps, x)
            if len(s) == 0:
                continue
            pn = (-k * g)[:, None] * n
            idx = np.concatenate([s, seg[:, 0], seg[:, 1]])
            w = np.concatenate([pn, -pn * (1 - xi)[:, None], -pn * xi[:, None]])
            f[:, 0] += np.bincount(idx, weights=w[:, 0], minlength=N)
            f[:, 1] += np.bincount(idx, weights=w[:, 1], minlength=N)
        return f

    def energy(self, x: np.ndarray) -> float:
        """Penalty energy ``sum k g^2 / 2`` over both passes (mJ)."""
        total = 0.0
        for ps in self.passes:
            if ps.active is None:
                continue
            _, _, _, _, g, k = self._pairs(ps, x)
            total += float(0.5 * np.dot(k, g * g))
        return total

    def contact_force_on(self, x: np.ndarray, nodes_mask: np.ndarray) -> np.ndarray:
        """Resultant contact force [2] on the nodes selected by ``nodes_mask`` (e.g. the ball)."""
        f = np.zeros((len(x), 2))
        for ps in self.passes:
            if ps.active is None:
                continue
            s, seg, xi, n, g, k = self._pairs(ps, x)
            pn = (-k * g)[:, None] * n
            np.add.at(f, s, pn)  # diagnostics only, not in the time loop
            np.add.at(f, seg[:, 0], -pn * (1 - xi)[:, None])
            np.add.at(f, seg[:, 1], -pn * xi[:, None])
        return f[nodes_mask].sum(0)
