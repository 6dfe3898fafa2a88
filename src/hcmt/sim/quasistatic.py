"""Quasi-static equilibrium of a neo-Hookean body pressed by rigid analytic obstacles: Newton's method on the
total potential energy (strain energy + frictionless penalty contact), a backtracking line search on that
energy, and load substepping (the step halved) when Newton does not converge.

Contact: a surface node ``a`` at signed distance ``d_a`` from an obstacle (:class:`Obstacle`: its signed distance,
outward normal and the normal's gradient) stores the C² penalty ``φ(d) = k (δ − d)³ / (6δ)`` for ``0 < d < δ`` and
``k (δ²/6 − δ d/2 + d²/2)`` for ``d ≤ 0`` (``k d²/2`` shifted: the force ``−φ'(d) n`` rises smoothly from 0 at the
distance ``δ``, so Newton sees the contact stiffness ``φ''(d) = k (δ − d)/δ`` before the node touches and the active
set does not flip between iterations; ``δ → 0``: the plain penalty). Its stiffness is ``φ'' n nᵀ + φ' ∇n``; the
second term (the curvature of a sphere or cylinder, negative: ``φ' < 0``) enters the tangent with ``curved`` (the
exact tangent, as the generator and the Hertz test use it); it can make the tangent indefinite at a deep
penetration, where :func:`solve_spd` falls back from Cholesky to LU. The obstacle is pushed by ``Σ φ'(d_a) n_a``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Protocol

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from hcmt.sim.hyper import NeoHookean


class Obstacle(Protocol):
    def distance(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(signed distance [n], outward unit normal [n,3], normal gradient [n,3,3]) at points [n,3]."""


class NotConverged(RuntimeError):
    """Newton's method did not reach the tolerance even with the step cut to its smallest substep."""


@dataclass
class Contact:
    """Penalty contact between the body's ``nodes`` and an obstacle: stiffness ``k`` (force per length), reach
    ``delta`` (length)."""

    obstacle: Obstacle
    nodes: np.ndarray
    k: float
    delta: float = 0.0
    curved: bool = False  # include the curvature term in the stiffness

    def evaluate(self, x: np.ndarray):
        """(energy, gradient [n,3], stiffness [n,3,3], active mask [n]) at the nodes' positions."""
        d, n, dn = self.obstacle.distance(x[self.nodes])
        k, h = self.k, self.delta
        inside, near = d <= 0, (d > 0) & (d < h)
        e = np.where(inside, k * (h * h / 6 - h * d / 2 + d * d / 2), 0.0)
        de = np.where(inside, k * (d - h / 2), 0.0)
        dde = np.where(inside, k, 0.0)
        if h > 0:
            g = np.where(near, h - d, 0.0)
            e, de, dde = e + k * g**3 / (6 * h), de - k * g * g / (2 * h), dde + k * g / h
        curvature = de[:, None, None] * dn
        hess = dde[:, None, None] * np.einsum("ni,nj->nij", n, n) + np.where(self.curved, curvature, 0.0)
        return float(e.sum()), de[:, None] * n, hess, inside | near

    def force_on_obstacle(self, x: np.ndarray) -> np.ndarray:
        return self.evaluate(x)[1].sum(0)


@dataclass
class NodalForce:
    """Dead loads ``force`` [n,3] on ``nodes`` (potential ``-f·x``), evaluated like a :class:`Contact`."""

    nodes: np.ndarray
    force: np.ndarray

    def evaluate(self, x: np.ndarray):
        f = np.broadcast_to(np.asarray(self.force, float), (len(self.nodes), 3))
        return -float(np.sum(f * x[self.nodes])), -f, np.zeros((len(self.nodes), 3, 3)), np.ones(len(self.nodes), bool)


@dataclass
class Newton:
    """Settings: relative force tolerance, iteration limit, line-search cuts, substep depth."""

    rtol: float = 1e-8
    max_iter: int = 20
    cuts: int = 10
    depth: int = 6


@dataclass
class StepLog:
    """One solved load step: iterations and the residual norm before each iteration."""

    iterations: int = 0
    residuals: list = field(default_factory=list)
    substeps: int = 1


def _system(body: NeoHookean, x: np.ndarray, contacts: list[Contact], tangent: bool = True):
    """(residual on the free dofs, free tangent or None, full internal force) at ``x``."""
    out = body.forces(x, tangent=tangent)
    f, K = out if tangent else (out, None)
    if f is None:
        return None, None, None
    g = f.copy()
    blocks = np.zeros((len(x), 3, 3)) if tangent else None
    for c in contacts:
        _, cg, ch, _ = c.evaluate(x)
        np.add.at(g, c.nodes, cg)
        if tangent:
            np.add.at(blocks, c.nodes, ch)
    r = g.ravel()[body.free]
    return r, (body.assemble(K, blocks) if tangent else None), f


def potential(body: NeoHookean, x: np.ndarray, contacts: list[Contact]) -> float:
    return body.energy(x) + sum(c.evaluate(x)[0] for c in contacts)


def _line_search(body, x, dx, r, contacts, cuts):
    """The largest ``x + a dx`` (a = 1, 1/2, ...) that lowers the energy by Armijo's rule or, where the energy's
    round-off hides the decrease near the solution, lowers the residual's norm."""
    e0, slope, r0 = potential(body, x, contacts), float(r @ dx), float(np.linalg.norm(r))
    step = np.zeros(3 * len(x))
    alpha = 1.0
    for _ in range(cuts):
        step[body.free] = alpha * dx
        trial = x + step.reshape(-1, 3)
        e = potential(body, trial, contacts)
        if np.isfinite(e) and e <= e0 + 1e-4 * alpha * slope:
            return trial
        if (
            np.isfinite(e)
            and (rt := _system(body, trial, contacts, tangent=False)[0]) is not None
            and np.linalg.norm(rt) < (1 - 1e-4 * alpha) * r0
        ):
            return trial
        alpha *= 0.5
    return None


def solve_spd(K: sp.csr_matrix, b: np.ndarray) -> np.ndarray:
    """``K⁻¹ b`` for a symmetric tangent: LAPACK's banded Cholesky where the band is narrow (the structured
    meshes' natural order; scipy has no sparse Cholesky, and this is about twice as fast as SuperLU there), else
    SuperLU with a symmetric ordering (also the fallback when K is not positive definite)."""
    coo = K.tocoo()
    up = coo.row <= coo.col
    band = int((coo.col - coo.row)[up].max(initial=0))
    if band < K.shape[0] // 8:
        ab = np.zeros((band + 1, K.shape[0]))
        ab[band + coo.row[up] - coo.col[up], coo.col[up]] = coo.data[up]
        try:
            return la.cho_solve_banded(
                (la.cholesky_banded(ab, overwrite_ab=True, check_finite=False), False), b, check_finite=False
            )
        except la.LinAlgError:
            pass
    return spla.splu(K.tocsc(), permc_spec="MMD_AT_PLUS_A").solve(b)


def newton(body: NeoHookean, x: np.ndarray, contacts: list[Contact], settings: Newton = Newton()):
    """Equilibrium from the start ``x`` (fixed dofs keep their values): (x, StepLog); raises
    :class:`NotConverged`."""
    log = StepLog()
    scale = body.mu * float(np.mean(body.volume)) ** (2 / 3)  # the force of a unit strain on one element's face
    for it in range(settings.max_iter + 1):
        r, _, f = _system(body, x, contacts, tangent=False)  # the tangent only when another iteration follows
        if r is None:
            raise NotConverged("an element inverted")
        norm = float(np.linalg.norm(r))
        log.residuals.append(norm)
        if norm <= settings.rtol * max(float(np.linalg.norm(f)), scale):
            log.iterations = it
            return x, log
        if it == settings.max_iter:
            break
        dx = solve_spd(_system(body, x, contacts)[1], -r)
        x = _line_search(body, x, dx, r, contacts, settings.cuts)
        if x is None:
            break
    raise NotConverged(f"residual {norm:.3g} after {it} iterations")


def advance(
    body: NeoHookean,
    x: np.ndarray,
    load: Callable[[float, np.ndarray], list[Contact]],
    settings: Newton = Newton(),
    predictor: np.ndarray | None = None,
):
    """Solve the load step ``s: 0 -> 1`` from the equilibrium ``x``: ``load(s, x)`` applies the load at ``s`` (sets
    prescribed values in ``x``, returns the contacts). Newton starts from ``x + s predictor`` (the previous step's
    increment: quasi-static paths are smooth) where that is admissible. On failure the step is halved, recursively,
    down to ``2^-depth``. Returns (x, StepLog summed over the substeps)."""
    total = StepLog(substeps=0)

    def solve(x, s0, s1, depth):
        try:
            y = x.copy()
            if predictor is not None:
                guess = x + (s1 - s0) * predictor
                y = guess if np.isfinite(body.energy(guess)) else y
            y, log = newton(body, y, load(s1, y), settings)
        except NotConverged:
            if depth >= settings.depth:
                raise
            mid = 0.5 * (s0 + s1)
            return solve(solve(x, s0, mid, depth + 1), mid, s1, depth + 1)
        total.iterations += log.iterations
        total.residuals += log.residuals
        total.substeps += 1
        return y

    return solve(np.array(x, float), 0.0, 1.0, 0), total
