"""Transmitting stage (TMS): the planar four-bars of legs x and y (model §4, 7.2).

In the plane u = u_E + r of leg u, with leg coordinates (v, w) and link directions
n(phi) = sin(phi) v - cos(phi) w:

* input pivot D_u = (0, p_u cos rho_u), input link tip K_u = D_u + d_u n(delta_u);
* output pivot Q_u = (v_E, w_E), output link tip T_u = Q_u + t_u n(sigma_u);
* coupler |T_u - K_u| = c_u (Eq 2).

Every function broadcasts over leading axes; the last axis holds the legs x, y. ``v`` and
``w`` are the leg coordinates of the drill tip E in R_m: leg x (v, w) = (y, z), leg y (v, w) = (z, x).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.model.stages import solve_harmonic


def ik(
    v: ArrayLike,
    w: ArrayLike,
    rho: ArrayLike,
    sigma: ArrayLike,
    p: ArrayLike,
    d: ArrayLike,
    c: ArrayLike,
    t: ArrayLike,
    eps_T: ArrayLike,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Eq 3: delta_u = atan2(B, A) + eps_T acos(C / sqrt(A^2 + B^2)), wrapped to [-pi, pi).

    Shapes ``(..., 2)``; lengths mm, angles rad, ``eps_T`` in {+1, -1} (= sign F_u).
    Returns ``(delta, arg)``; reachable iff |arg| <= 1 (NaN delta otherwise).
    """
    t_ = np.asarray(t, dtype=float)
    d_ = np.asarray(d, dtype=float)
    a = np.asarray(v, dtype=float) + t_ * np.sin(sigma)
    b = np.asarray(w, dtype=float) - t_ * np.cos(sigma) - np.asarray(p, dtype=float) * np.cos(rho)
    A = 2.0 * d_ * b
    B = -2.0 * d_ * a
    C = np.asarray(c, dtype=float) ** 2 - a * a - b * b - d_ * d_
    return solve_harmonic(A, B, C, eps_T)


def fk(
    v: ArrayLike,
    w: ArrayLike,
    rho: ArrayLike,
    delta: ArrayLike,
    p: ArrayLike,
    d: ArrayLike,
    c: ArrayLike,
    t: ArrayLike,
    eps_H: ArrayLike,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Output angle sigma_u given the input delta_u (model §4.4), assembly mode eps_H = sign H_u.

    Shapes ``(..., 2)``. Returns ``(sigma, arg)``; assembled iff |arg| <= 1.
    """
    d_ = np.asarray(d, dtype=float)
    t_ = np.asarray(t, dtype=float)
    k_v = d_ * np.sin(delta) - np.asarray(v, dtype=float)
    k_w = np.asarray(p, dtype=float) * np.cos(rho) - d_ * np.cos(delta) - np.asarray(w, dtype=float)
    C = (t_ * t_ + k_v * k_v + k_w * k_w - np.asarray(c, dtype=float) ** 2) / (2.0 * t_)
    return solve_harmonic(-k_w, k_v, C, eps_H)


class TMSJacobianTerms(NamedTuple):
    """Coefficients of ``F delta_dot + G rho_dot = D v_dot + E w_dot + H sigma_dot`` (½ dPhi, unnormalised).

    Each field ``(..., 2)`` for legs x, y. F, G, H in mm^2 (per rad); D, E in mm.
    """

    F: NDArray[np.float64]
    G: NDArray[np.float64]
    D: NDArray[np.float64]
    E: NDArray[np.float64]
    H: NDArray[np.float64]


def jacobian_terms(
    v: ArrayLike,
    w: ArrayLike,
    rho: ArrayLike,
    delta: ArrayLike,
    sigma: ArrayLike,
    p: ArrayLike,
    d: ArrayLike,
    t: ArrayLike,
) -> TMSJacobianTerms:
    """F, G, D, E, H of model §7.2 from the coupler vector T_u - K_u = (a_v, a_w)."""
    d_ = np.asarray(d, dtype=float)
    t_ = np.asarray(t, dtype=float)
    p_ = np.asarray(p, dtype=float)
    sd, cd = np.sin(delta), np.cos(delta)
    ss, cs = np.sin(sigma), np.cos(sigma)
    a_v = np.asarray(v, dtype=float) - d_ * sd + t_ * ss
    a_w = np.asarray(w, dtype=float) + d_ * cd - t_ * cs - p_ * np.cos(rho)
    return TMSJacobianTerms(
        F=d_ * (a_v * cd + a_w * sd),
        G=-p_ * a_w * np.sin(rho),
        D=a_v,
        E=a_w,
        H=t_ * (a_v * cs + a_w * ss),
    )


def constraint(
    v: ArrayLike,
    w: ArrayLike,
    rho: ArrayLike,
    delta: ArrayLike,
    sigma: ArrayLike,
    p: ArrayLike,
    d: ArrayLike,
    c: ArrayLike,
    t: ArrayLike,
) -> NDArray[np.float64]:
    """Phi_u of Eq 2 (mm^2), zero on the closed four-bar; ``(..., 2)``."""
    d_ = np.asarray(d, dtype=float)
    t_ = np.asarray(t, dtype=float)
    a_v = np.asarray(v, dtype=float) - d_ * np.sin(delta) + t_ * np.sin(sigma)
    a_w = (
        np.asarray(w, dtype=float) + d_ * np.cos(delta) - t_ * np.cos(sigma) - np.asarray(p, dtype=float) * np.cos(rho)
    )
    return a_v * a_v + a_w * a_w - np.asarray(c, dtype=float) ** 2


def J_AV(terms: TMSJacobianTerms) -> NDArray[np.float64]:
    """J_AV ``(..., 2, 3)`` (mm), columns x, y, z: [[0, D_x, E_x], [E_y, 0, D_y]]."""
    D, E = terms.D, terms.E
    zero = np.zeros_like(D[..., 0])
    return np.stack(
        [np.stack([zero, D[..., 0], E[..., 0]], axis=-1), np.stack([E[..., 1], zero, D[..., 1]], axis=-1)],
        axis=-2,
    )


def J_rho(terms: TMSJacobianTerms) -> NDArray[np.float64]:
    """J_rho ``(..., 2, 3)`` (mm^2): [[G_x, 0, 0], [0, G_y, 0]], acting on the 3-vector rho_dot."""
    G = terms.G
    out = np.zeros(G.shape[:-1] + (2, 3))
    out[..., 0, 0] = G[..., 0]
    out[..., 1, 1] = G[..., 1]
    return out
