"""Explicit-dynamics FEM on linear triangles (CST): the numerical solver behind the Impact Plate generator.

Governing equation (paper Table 1, flexible dynamic): ``M x'' + D x' + T(x) = f(t)``, integrated with the central
difference scheme (:class:`hcmt.sim.explicit.CentralDifference`) and a lumped (diagonal) mass ``M``.

Constitutive law: total-Lagrangian St Venant-Kirchhoff per element,

    F = I + grad u = sum_a x_a (grad N_a)^T,   E = (F^T F - I) / 2,   S = lambda tr(E) I + 2 mu E,
    P = F S,   f_a = W P grad N_a      (W: element weight; internal force of node a),

which is exactly objective: a rigid rotation gives E = 0 and no force (a small-strain K u would not).

Two formulations (``formulation``):

* ``"axisymmetric"`` (default): x is the radius r, y the axis z. The hoop stretch ``F_tt = r / R`` is evaluated at the
  element centroid (``R`` reference, ``r`` current centroid radius); ``W = 2 pi R_c A`` so masses, forces (N) and
  energies (mJ) are those of the full revolved 3-D body (a half disk becomes a whole sphere).
* ``"plane_strain"``: ``F_zz = 1`` (so ``S_zz = lambda tr E``), ``W = A`` (per mm of depth).

Units: mm, ms, g, hence N, MPa, mJ, and speeds in mm/ms = m/s.

Hot path: ``F`` for all elements is one sparse product ``D @ x`` with a precomputed gradient operator ``D`` [3C, N]
(rows: dN/dX, dN/dY, centroid average); the nodal forces are ``D^T @ Q`` with ``Q`` the weighted stresses. No loop
over elements.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from hcmt.errors import InputError
from hcmt.sim.params import FORMULATIONS
from hcmt.sim.rules import check_material


@dataclass
class FEModel:
    """Precomputed operators of a triangle mesh (reference configuration ``X``)."""

    X: np.ndarray  # [N,2] reference positions
    cells: np.ndarray  # [C,3]
    formulation: str
    D: sp.csc_matrix  # [3C, N] gradient + centroid operator ([2C, N] in plane strain: no hoop rows)
    DT: sp.csc_matrix  # its transpose
    W: np.ndarray  # [C] element weight (volume, or area per unit depth)
    Rc: np.ndarray  # [C] reference centroid radius (axisymmetric) else ones
    lam: np.ndarray  # [C] Lame lambda (MPa)
    mu: np.ndarray  # [C] shear modulus (MPa)
    rho: np.ndarray  # [C] density (g/mm^3)
    wave_speed: np.ndarray  # [C] dilatational wave speed sqrt((lambda + 2 mu) / rho)
    altitude: np.ndarray  # [C] smallest altitude of each triangle (mm)
    mass: np.ndarray  # [N] lumped nodal mass (g)
    nodal_average: sp.csr_matrix  # [N, C] element -> node average (area weighted)
    bulk_viscosity: float = 0.0  # linear bulk viscosity coefficient b1

    def __post_init__(self):
        self.lamW = self.lam * self.W  # weighted constants of the hot path
        self.mu2W = 2 * self.mu * self.W
        self.etaW = self.bulk_viscosity * self.rho * self.wave_speed * self.altitude * self.W

    @property
    def num_nodes(self) -> int:
        return len(self.X)

    @property
    def num_cells(self) -> int:
        return len(self.cells)


def lame(modulus, poisson):
    """(lambda, mu) of Young's modulus E and Poisson ratio nu: lambda = E nu / ((1+nu)(1-2nu)), mu = E / (2(1+nu))."""
    modulus, poisson = np.asarray(modulus, float), np.asarray(poisson, float)
    return modulus * poisson / ((1 + poisson) * (1 - 2 * poisson)), modulus / (2 * (1 + poisson))


def build_model(
    X: np.ndarray,
    cells: np.ndarray,
    density,
    modulus,
    poisson,
    *,
    formulation: str = "axisymmetric",
    bulk_viscosity: float = 0.0,
) -> FEModel:
    """Precompute the CST operators of a mesh. ``density``, ``modulus`` (MPa), ``poisson`` are per cell or scalars."""
    if formulation not in FORMULATIONS:
        raise InputError(f"formulation must be one of {FORMULATIONS}, got {formulation!r}")
    if bulk_viscosity < 0:
        raise InputError(f"bulk_viscosity must be >= 0, got {bulk_viscosity}")
    X = np.asarray(X, float)
    cells = np.asarray(cells, np.int64)
    C, N = len(cells), len(X)
    rho, E, nu = (np.broadcast_to(np.asarray(v, float), (C,)).copy() for v in (density, modulus, poisson))
    check_material("element", rho, E, nu)
    p = X[cells]  # [C,3,2]
    A, dNdX, dNdY, altitude = _triangle_geometry(p)
    Rc = p[:, :, 0].mean(1)
    if formulation == "axisymmetric":
        if np.any(X[:, 0] < -1e-9):
            raise InputError("axisymmetric meshes need x = r >= 0 for every node")
        W = 2 * np.pi * Rc * A
    else:
        Rc = np.ones(C)
        W = A.copy()
    D = _gradient_operator(cells, dNdX, dNdY, N, formulation)
    lam, mu = lame(E, nu)
    c = np.sqrt((lam + 2 * mu) / rho)
    mass = np.bincount(cells.ravel(), weights=np.repeat(rho * W / 3.0, 3), minlength=N)
    avg = sp.csr_matrix((np.repeat(A, 3), (cells.ravel(), np.repeat(np.arange(C), 3))), shape=(N, C))
    deg = np.asarray(avg.sum(1)).ravel()
    avg = sp.diags(1.0 / np.where(deg > 0, deg, 1.0)) @ avg
    return FEModel(
        X=X,
        cells=cells,
        formulation=formulation,
        D=D.tocsc(),
        DT=D.T,  # CSC: faster multivector products
        W=W,
        Rc=Rc,
        lam=lam,
        mu=mu,
        rho=rho,
        wave_speed=c,
        altitude=altitude,
        mass=mass,
        nodal_average=avg.tocsr(),
        bulk_viscosity=float(bulk_viscosity),
    )


def _triangle_geometry(p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(area [C], dN/dX [C,3], dN/dY [C,3], smallest altitude [C]) of triangles ``p`` [C,3,2], counter-clockwise."""
    # grad N_a = perp(x_c - x_b) / (2A) for the cyclic triple (a, b, c)
    nxt, prv = p[:, [1, 2, 0]], p[:, [2, 0, 1]]
    A = 0.5 * (
        (p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0])
    )
    if np.any(A <= 0):
        bad = np.flatnonzero(A <= 0)[:5]
        raise InputError(f"cells must be counter-clockwise with positive area; cells {bad.tolist()} are not")
    dNdX = (nxt[..., 1] - prv[..., 1]) / (2 * A[:, None])  # [C,3]
    dNdY = (prv[..., 0] - nxt[..., 0]) / (2 * A[:, None])
    edge = np.linalg.norm(nxt - p, axis=2)  # edge a -> a+1, opposite vertex a+2
    return A, dNdX, dNdY, (2 * A[:, None] / edge).min(1)


def _gradient_operator(
    cells: np.ndarray, dNdX: np.ndarray, dNdY: np.ndarray, N: int, formulation: str
) -> sp.csr_matrix:
    """The operator ``D`` [3C, N] (dN/dX, dN/dY and centroid-average rows; no hoop rows in plane strain)."""
    C = len(cells)
    blocks = 3 if formulation == "axisymmetric" else 2  # the centroid-average rows only carry the hoop stretch
    rows = np.concatenate([np.repeat(np.arange(C), 3) + k * C for k in range(blocks)])
    cols = np.tile(cells.ravel(), blocks)
    vals = np.concatenate([dNdX.ravel(), dNdY.ravel(), np.full(3 * C, 1.0 / 3.0)][:blocks])
    return sp.csr_matrix((vals, (rows, cols)), shape=(blocks * C, N))


def stable_time_step(model: FEModel, safety: float = 0.8) -> float:
    """Courant step ``dt = safety * min_e h_e / c_e`` (h_e smallest altitude, c_e dilatational wave speed), reduced
    by the bulk-viscosity factor ``sqrt(1 + b1^2) - b1``. ``safety`` must lie in (0, 0.8]."""
    if not 0 < safety <= 0.8:
        raise InputError(f"time-step safety factor must be in (0, 0.8], got {safety}")
    b1 = model.bulk_viscosity
    return float(safety * np.min(model.altitude / model.wave_speed) * (np.sqrt(1 + b1 * b1) - b1))


def deformation(model: FEModel, x: np.ndarray):
    """Deformation gradient components ``(F11, F12, F21, F22, F33)`` per element (F_iJ = dx_i/dX_J)."""
    C = model.num_cells
    G = model.D @ x  # [3C,2] ([2C,2] plane strain)
    F11, F21 = G[:C, 0], G[:C, 1]
    F12, F22 = G[C : 2 * C, 0], G[C : 2 * C, 1]
    F33 = G[2 * C :, 0] / model.Rc if model.formulation == "axisymmetric" else np.ones(C)
    return F11, F12, F21, F22, F33


def green_lagrange(F11, F12, F21, F22, F33):
    """E = (F^T F - I)/2 as (E11, E22, E12, E33)."""
    return (
        0.5 * (F11 * F11 + F21 * F21 - 1),
        0.5 * (F12 * F12 + F22 * F22 - 1),
        0.5 * (F11 * F12 + F21 * F22),
        0.5 * (F33 * F33 - 1),
    )


def internal_force(model: FEModel, x: np.ndarray, v: np.ndarray | None = None) -> np.ndarray:
    """Nodal internal (resisting) forces ``f_a = sum_e W P grad N_a`` (+ hoop term ``W P_tt / (3 R_c)`` on u_r)
    [N,2]. With ``v`` and a bulk viscosity ``b1 > 0`` adds the linear bulk-viscosity stress
    ``q = b1 rho c h tr(eps_dot)`` (h: smallest altitude; applied in compression and expansion alike, with the
    reference gradients, so it is a pure dissipation ``W q tr(eps_dot) >= 0``).

    This is the hot path: one sparse product for F (and the velocity gradient), elementwise SVK algebra, one sparse
    product back to the nodes; the algebra is written out rather than calling :func:`deformation` to save
    temporaries."""
    C = model.num_cells
    visc = v is not None and model.bulk_viscosity > 0
    G = model.D @ (np.concatenate((x, v), axis=1) if visc else x)
    F11, F21, F12, F22 = G[:C, 0], G[:C, 1], G[C : 2 * C, 0], G[C : 2 * C, 1]
    axi = model.formulation == "axisymmetric"
    E11 = 0.5 * (F11 * F11 + F21 * F21 - 1.0)
    E22 = 0.5 * (F12 * F12 + F22 * F22 - 1.0)
    tr = E11 + E22
    if axi:
        F33 = G[2 * C :, 0] / model.Rc
        E33 = 0.5 * (F33 * F33 - 1.0)
        tr += E33
    lt = model.lamW * tr  # weighted stresses W S
    S11 = lt + model.mu2W * E11
    S22 = lt + model.mu2W * E22
    S12 = model.mu2W * (F11 * F12 + F21 * F22) * 0.5
    q = 0.0
    if visc:
        rate = G[:C, 2] + G[C : 2 * C, 3]
        if axi:
            rate += G[2 * C :, 2] / model.Rc
        q = model.etaW * rate
    Q = np.empty((len(G), 2))
    Q[:C, 0] = F11 * S11 + F12 * S12 + q
    Q[:C, 1] = F21 * S11 + F22 * S12
    Q[C : 2 * C, 0] = F11 * S12 + F12 * S22
    Q[C : 2 * C, 1] = F21 * S12 + F22 * S22 + q
    if axi:
        Q[2 * C :, 0] = (F33 * (lt + model.mu2W * E33) + q) / model.Rc
        Q[2 * C :, 1] = 0.0
    return model.DT @ Q


def strain_energy(model: FEModel, x: np.ndarray) -> float:
    """Total SVK strain energy ``sum_e W (lambda/2 tr(E)^2 + mu E:E)`` (mJ)."""
    E11, E22, E12, E33 = green_lagrange(*deformation(model, x))
    tr = E11 + E22 + E33
    psi = 0.5 * model.lam * tr**2 + model.mu * (E11**2 + E22**2 + 2 * E12**2 + E33**2)
    return float(np.dot(model.W, psi))


def cauchy_stress(model: FEModel, x: np.ndarray):
    """Element Cauchy stress ``sigma = F S F^T / J`` as (s11, s22, s12, s33); s33 is the hoop (axisymmetric) or
    out-of-plane (plane strain, ``lambda tr E`` for F33 = 1) component."""
    F11, F12, F21, F22, F33 = deformation(model, x)
    E11, E22, E12, E33 = green_lagrange(F11, F12, F21, F22, F33)
    lt = model.lam * (E11 + E22 + E33)
    m2 = 2 * model.mu
    S11, S22, S12, S33 = lt + m2 * E11, lt + m2 * E22, m2 * E12, lt + m2 * E33
    J = (F11 * F22 - F12 * F21) * F33
    P11, P12 = F11 * S11 + F12 * S12, F11 * S12 + F12 * S22
    P21, P22 = F21 * S11 + F22 * S12, F21 * S12 + F22 * S22
    return ((P11 * F11 + P12 * F12) / J, (P21 * F21 + P22 * F22) / J, (P11 * F21 + P12 * F22) / J, S33 * F33 * F33 / J)


def von_mises(s11, s22, s12, s33):
    """sigma_vm = sqrt(((s11-s22)^2 + (s22-s33)^2 + (s33-s11)^2)/2 + 3 s12^2), the out-of-plane component included."""
    return np.sqrt(0.5 * ((s11 - s22) ** 2 + (s22 - s33) ** 2 + (s33 - s11) ** 2) + 3 * s12**2)


def nodal_von_mises(model: FEModel, x: np.ndarray) -> np.ndarray:
    """Element von Mises stress averaged (area weighted) to the nodes [N]; every element belongs to one body, so
    the average never mixes the ball and the plate."""
    return model.nodal_average @ von_mises(*cauchy_stress(model, x))


def linear_stiffness(model: FEModel) -> sp.csr_matrix:
    """Small-strain stiffness ``K = B^T diag(W C) B`` [2N, 2N] (dofs interleaved x0, y0, x1, ...): the tangent of
    :func:`internal_force` at the reference configuration, for static solves and stable-step checks.
    ``B`` maps u to (eps11, eps22, gamma12, eps33) per element; eps33 = u_r / R_c in the axisymmetric case, 0 else."""
    C, N = model.num_cells, model.num_nodes
    D = model.D.tocsr()
    Dx, Dy = D[:C], D[C : 2 * C]
    zero = sp.csr_matrix((C, N))
    hoop = sp.diags(1.0 / model.Rc) @ D[2 * C :] if model.formulation == "axisymmetric" else zero
    B = sp.bmat([[Dx, zero], [zero, Dy], [Dy, Dx], [hoop, zero]]).tocsr()  # columns: all ux, then all uy
    lam, mu = model.lam * model.W, model.mu * model.W
    a = lam + 2 * mu
    blocks = [[a, lam, None, lam], [lam, a, None, lam], [None, None, mu, None], [lam, lam, None, a]]
    Cmat = sp.bmat([[sp.diags(b) if b is not None else None for b in row] for row in blocks], format="csr")
    K = (B.T @ Cmat @ B).tocsr()
    perm = np.arange(2 * N).reshape(2, N).T.ravel()  # to interleaved dofs
    return K[perm][:, perm].tocsr()
