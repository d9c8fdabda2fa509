"""Condition numbers of the seven Jacobians and the local index eta_L (model §8.1, Eq 13).

kappa(J) = sigma_max / sigma_min with 2-norm singular values, +inf where the rank is short.
Closed forms only (no SVD on the hot path):

* diagonal matrices: max|d_i| / min|d_i|;
* 2 x n matrices: with F = ||M||_F^2 and g = sqrt(det(M M^T)),
  kappa = (F + sqrt(F^2 - 4 g^2)) / (2 g).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.model.design import unpack
from arcube.model.mechanism import IKSolution
from arcube.model.stages import rts, tls

JACOBIAN_NAMES: tuple[str, ...] = ("J_LV", "J_AV", "J_sigma", "J_AS", "J_AP", "J_rho", "J_delta")
"""Order of the last axis of :func:`condition_numbers` (the order of Eq 13)."""


def kappa_diag(d: ArrayLike) -> NDArray[np.float64]:
    """kappa of diag(d) over the last axis ``(..., k)`` -> ``(...)``; +inf where some d_i = 0."""
    a = np.abs(np.asarray(d, dtype=float))
    lo = np.min(a, axis=-1)
    hi = np.max(a, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(lo > 0.0, hi / lo, np.where(np.isnan(lo), np.nan, np.inf))


def kappa_from_invariants(F: ArrayLike, g: ArrayLike) -> NDArray[np.float64]:
    """kappa of a rank-2 2 x n matrix from F = ||M||_F^2 and g = sqrt(det(M M^T)) >= 0."""
    F_ = np.asarray(F, dtype=float)
    g_ = np.abs(np.asarray(g, dtype=float))
    # F^2 - 4g^2 = (s1^2 - s2^2)^2 >= 0 in exact arithmetic; clip rounding below zero.
    root = np.sqrt(np.maximum(F_ * F_ - 4.0 * g_ * g_, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        k = (F_ + root) / (2.0 * g_)
    return np.where(g_ > 0.0, np.maximum(k, 1.0), np.where(np.isnan(g_), np.nan, np.inf))


def kappa_2xn(M: ArrayLike) -> NDArray[np.float64]:
    """kappa of 2 x n matrices ``(..., 2, n)`` by Cauchy-Binet (g^2 = sum of squared 2x2 minors)."""
    Ma = np.asarray(M, dtype=float)
    F = np.sum(Ma * Ma, axis=(-2, -1))
    n = Ma.shape[-1]
    # Sum of squared 2x2 minors: accurate to ~eps * kappa, unlike |r0|^2 |r1|^2 - (r0.r1)^2.
    g2 = sum(
        (Ma[..., 0, i] * Ma[..., 1, j] - Ma[..., 0, j] * Ma[..., 1, i]) ** 2 for i in range(n) for j in range(i + 1, n)
    )
    return kappa_from_invariants(F, np.sqrt(g2))


def condition_numbers(sol: IKSolution, params: ArrayLike) -> NDArray[np.float64]:
    """The seven condition numbers ``(..., 7)`` in :data:`JACOBIAN_NAMES` order.

    NaN where the IK has no solution (the joint angles are NaN there), +inf at a singularity.
    """
    g = unpack(params)
    T = sol.terms
    Dx, Dy, Ex, Ey = T.D[..., 0], T.D[..., 1], T.E[..., 0], T.E[..., 1]
    # J_AV = [[0, D_x, E_x], [E_y, 0, D_y]]: the three 2x2 minors are -D_x E_y, -E_x E_y, D_x D_y.
    F_av = Dx * Dx + Ex * Ex + Ey * Ey + Dy * Dy
    g_av = np.sqrt((Dx * Ey) ** 2 + (Ex * Ey) ** 2 + (Dx * Dy) ** 2)
    # J_AP rows (u_beta x e): g = |(x_b x e) x (y_b x e)| = |det[x_b, y_b, e]| since |e| = 1.
    J_ap = rts.J_AP(sol.e, sol.u_beta)
    F_ap = np.sum(J_ap * J_ap, axis=(-2, -1))
    g_ap = np.abs(rts.det_beta(sol.e, sol.u_beta))
    kappas = [
        kappa_diag(tls.jacobian_LV_diag(sol.rho, g.p)),
        kappa_from_invariants(F_av, g_av),
        kappa_diag(T.H),
        kappa_diag(rts.J_AS_diag(sol.e, sol.u_beta)),
        kappa_from_invariants(F_ap, g_ap),
        kappa_diag(T.G),
        kappa_diag(T.F),
    ]
    return np.stack(np.broadcast_arrays(*kappas), axis=-1)
