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

import numpy as np
from scipy.spatial import cKDTree

from hcmt.errors import InputError


def boundary_edges(cells: np.ndarray) -> np.ndarray:
    """Edges used by exactly one triangle, oriented as in their (counter-clockwise) cell, so the body lies on the
    left of ``a -> b`` and the outward normal is ``(t_y, -t_x) / |t|``."""
    e = np.concatenate([cells[:, [0, 1]], cells[:, [1, 2]], cells[:, [2, 0]]])
    key = np.sort(e, axis=1)
    _, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return e[cnt[inv.ravel()] == 1]


class PenaltyContact:
    """Two-pass node-to-segment penalty contact between body 0 and body 1 (``body`` [N] in {0, 1})."""

    def __init__(
        self,
        X: np.ndarray,
        cells: np.ndarray,
        body: np.ndarray,
        mass: np.ndarray,
        dt: float,
        *,
        alpha: float = 0.2,
        exclude_axis: bool = True,
        k_nearest: int = 4,
    ):
        if not 0 < alpha <= 0.5:
            raise InputError(f"penalty factor alpha must be in (0, 0.5] to stay inside the stable step, got {alpha}")
        self.mass, self.dt, self.alpha, self.K = mass, dt, alpha, k_nearest
        edges = boundary_edges(cells)
        if exclude_axis:  # segments on the symmetry line x = 0 are not surfaces
            edges = edges[~((np.abs(X[edges[:, 0], 0]) < 1e-9) & (np.abs(X[edges[:, 1], 0]) < 1e-9))]
        eb = body[edges[:, 0]]
        if np.any(eb != body[edges[:, 1]]):
            raise InputError("a boundary edge joins the two bodies; contact needs two separate bodies")
        bnodes = np.unique(boundary_edges(cells))
        # pass 0: plate nodes on ball segments; pass 1: ball nodes on plate segments
        self.passes = [(bnodes[body[bnodes] == s], edges[eb == 1 - s]) for s in (0, 1)]
        lengths = np.linalg.norm(X[edges[:, 1]] - X[edges[:, 0]], axis=1)
        self.min_segment = float(lengths.min())
        self.search = 2.0 * float(lengths.max())
        self.countdown = 0
        self.s = self.seg = self.k = None

    def refresh(self, x: np.ndarray, v: np.ndarray) -> None:
        """Recompute the candidate pairs of both passes (one stacked set of arrays) and the number of substeps
        they stay valid."""
        slaves, cands = [], []
        for sl, segs in self.passes:
            mid = 0.5 * (x[segs[:, 0]] + x[segs[:, 1]])
            k = min(self.K, len(mid))
            d, idx = cKDTree(mid).query(x[sl], k=k)
            d, idx = d.reshape(len(sl), k), idx.reshape(len(sl), k)
            near = d[:, 0] < self.search
            if k < self.K:  # pad with the nearest segment (a duplicate candidate changes nothing)
                idx = np.concatenate([idx, np.repeat(idx[:, :1], self.K - k, 1)], 1)
            slaves.append(sl[near])
            cands.append(segs[idx[near]])
        self.s = np.concatenate(slaves)
        self.seg = np.concatenate(cands).reshape(-1, self.K, 2)
        m = self.mass
        self.k = self.alpha * np.minimum(m[self.s][:, None], np.minimum(m[self.seg[..., 0]], m[self.seg[..., 1]]))
        self.k /= self.dt**2
        self.gather = np.concatenate([self.s, self.seg[..., 0].ravel(), self.seg[..., 1].ravel()])
        vmax = float(np.sqrt((v**2).sum(1).max())) if len(v) else 0.0
        self.countdown = max(1, int(0.25 * self.min_segment / (2 * vmax * self.dt + 1e-300)))

    def _pairs(self, x: np.ndarray):
        """Active contacts: for every candidate slave the valid segment of least penetration."""
        S, K = self.seg.shape[:2]
        p = x[self.gather]  # one gather: slaves, then segment starts, then segment ends
        xs, xa, xb = p[:S, None], p[S : S + S * K].reshape(S, K, 2), p[S + S * K :].reshape(S, K, 2)
        t, r = xb - xa, xs - xa
        tx, ty, rx, ry = t[..., 0], t[..., 1], r[..., 0], r[..., 1]
        L2 = tx * tx + ty * ty
        L = np.sqrt(L2)
        xi = (rx * tx + ry * ty) / L2
        g = (rx * ty - ry * tx) / L  # (x_s - x_a) . n, n = (t_y, -t_x) / L
        ok = (xi >= 0) & (xi <= 1) & (g < 0) & (g > -0.5 * L)
        j = np.argmax(np.where(ok, g, -np.inf), axis=1)
        rows = np.arange(S)
        hit = ok[rows, j]
        rows, j = rows[hit], j[hit]
        n = np.stack([ty[rows, j], -tx[rows, j]], -1) / L[rows, j, None]
        return self.s[rows], self.seg[rows, j], xi[rows, j], n, g[rows, j], self.k[rows, j]

    def force(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Contact forces [N,2] at positions ``x`` (refreshing candidates when due)."""
        if self.countdown <= 0:
            self.refresh(x, v)
        self.countdown -= 1
        N = len(x)
        s, seg, xi, n, g, k = self._pairs(x)
        if len(s) == 0:
            return np.zeros((N, 2))
        pn = (-k * g)[:, None] * n
        idx = np.concatenate([s, seg[:, 0], seg[:, 1]])
        w = np.concatenate([pn, -pn * (1 - xi)[:, None], -pn * xi[:, None]])
        return np.stack(
            [np.bincount(idx, weights=w[:, 0], minlength=N), np.bincount(idx, weights=w[:, 1], minlength=N)], 1
        )

    def energy(self, x: np.ndarray) -> float:
        """Penalty energy ``sum k g^2 / 2`` over both passes (mJ)."""
        if self.s is None:
            return 0.0
        _, _, _, _, g, k = self._pairs(x)
        return float(0.5 * np.dot(k, g * g))

    def contact_force_on(self, x: np.ndarray, nodes_mask: np.ndarray) -> np.ndarray:
        """Resultant contact force [2] on the nodes selected by ``nodes_mask`` (e.g. the ball)."""
        if self.s is None:
            return np.zeros(2)
        countdown = self.countdown
        self.countdown = 1  # no refresh from a diagnostic call
        f = self.force(x, np.zeros_like(x))
        self.countdown = countdown
        return f[nodes_mask].sum(0)
