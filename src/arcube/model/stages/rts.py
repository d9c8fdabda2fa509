"""Rotational stage (RTS): the spherical five-bar centred at the drill tip E (model §5, 7.3).

Leg u (x or y) has its proximal axis along +u through E; its proximal link (arc alpha_u)
turns with lambda_u = sigma_u + o_u, giving the intermediate axis

    u_beta = cos(alpha_u) u + sin(alpha_u) (sin(lambda_u) v - cos(lambda_u) w),

and its distal link (arc beta_u) reaches the drill axis e: u_beta . e = cos(beta_u) (Eq 4).

Every function broadcasts over leading axes; per-leg arrays have last axis (x, y) and
vectors are world-frame ``(..., 3)`` (or ``(..., 2, 3)`` per leg).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.model.poses import leg_coords
from arcube.model.stages import solve_harmonic, wrap_angle

_TO_WORLD: NDArray[np.intp] = np.array([[0, 1, 2], [2, 0, 1]])
"""Row i: for leg i (x, y), the leg-coordinate index (u, v, w) that gives world x, y, z."""

_AXES: NDArray[np.float64] = np.eye(3)[:2]
"""Proximal axes x_alpha = +x, y_alpha = +y, ``(2, 3)``."""


def ik(
    e: ArrayLike, alpha: ArrayLike, beta: ArrayLike, o: ArrayLike, eps_R: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Input angles sigma_u reaching drill axis ``e`` (model §5.2), working mode eps_R = -sign J_AS,u.

    Parameters: ``e`` ``(..., 3)`` unit; ``alpha``, ``beta``, ``o``, ``eps_R`` ``(..., 2)`` (rad, signs).
    Returns ``(sigma, arg)`` ``(..., 2)``: sigma wrapped to [-pi, pi) (NaN where unreachable) and
    the argument C/sqrt(A^2 + B^2), reachable iff |arg| <= 1.
    """
    el = leg_coords(e)[..., :2, :]  # (..., 2, 3): (e_u, e_v, e_w) for legs x, y
    sa = np.sin(alpha)
    A = -sa * el[..., 2]
    B = sa * el[..., 1]
    C = np.cos(beta) - np.cos(alpha) * el[..., 0]
    lam, arg = solve_harmonic(A, B, C, eps_R)
    return wrap_angle(lam - np.asarray(o, dtype=float)), arg


def u_beta(sigma: ArrayLike, alpha: ArrayLike, o: ArrayLike) -> NDArray[np.float64]:
    """Intermediate axes x_beta, y_beta in world coordinates, ``(..., 2, 3)``."""
    lam = np.asarray(sigma, dtype=float) + np.asarray(o, dtype=float)
    sa = np.sin(alpha)
    local = np.stack([np.cos(alpha) + 0.0 * lam, sa * np.sin(lam), -sa * np.cos(lam)], axis=-1)
    return np.take_along_axis(local, np.broadcast_to(_TO_WORLD, local.shape), axis=-1)


def constraint(e: ArrayLike, sigma: ArrayLike, alpha: ArrayLike, beta: ArrayLike, o: ArrayLike) -> NDArray[np.float64]:
    """Gamma_u = u_beta . e - cos(beta_u) (Eq 4), zero when closed; ``(..., 2)``."""
    ub = u_beta(sigma, alpha, o)
    return np.einsum("...ij,...j->...i", ub, np.asarray(e, dtype=float)) - np.cos(beta)


def J_AS_diag(e: ArrayLike, ub: ArrayLike) -> NDArray[np.float64]:
    """Diagonal of J_AS: (u_alpha x u_beta) . e for legs x, y, ``(..., 2)``."""
    cross = np.cross(_AXES, np.asarray(ub, dtype=float))
    return np.einsum("...ij,...j->...i", cross, np.asarray(e, dtype=float))


def J_AP(e: ArrayLike, ub: ArrayLike) -> NDArray[np.float64]:
    """J_AP ``(..., 2, 3)``: rows (x_beta x e)^T and (y_beta x e)^T (rows are orthogonal to e)."""
    ea = np.asarray(e, dtype=float)[..., None, :]
    return np.cross(np.asarray(ub, dtype=float), ea)


def det_beta(e: ArrayLike, ub: ArrayLike) -> NDArray[np.float64]:
    """det[x_beta, y_beta, e] ``(...)``: zero at the RTS parallel (Type-2) singularity; its sign is eps_P."""
    ub_ = np.asarray(ub, dtype=float)
    return np.einsum("...j,...j->...", np.cross(ub_[..., 0, :], ub_[..., 1, :]), np.asarray(e, dtype=float))


def fk(
    sigma: ArrayLike, alpha: ArrayLike, beta: ArrayLike, o: ArrayLike, eps_P: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Drill axis e given the inputs sigma (model §5.4), assembly mode eps_P = sign det[x_b, y_b, e].

    Returns ``(e, radicand)``: ``e`` ``(..., 3)`` (NaN where it does not assemble) and the
    radicand (1 - a^2 - b^2 - 2abg)/(1 - g^2), which must be >= 0.
    """
    ub = u_beta(sigma, alpha, o)
    xb, yb = ub[..., 0, :], ub[..., 1, :]
    g = np.einsum("...j,...j->...", xb, yb)
    cb = np.cos(beta)
    cx, cy = cb[..., 0], cb[..., 1]
    one_g2 = 1.0 - g * g
    with np.errstate(divide="ignore", invalid="ignore"):
        a = (cx - g * cy) / one_g2
        b = (cy - g * cx) / one_g2
        radicand = (1.0 - a * a - b * b - 2.0 * a * b * g) / one_g2
    ok = (radicand >= 0.0) & (one_g2 > 0.0)
    h = np.asarray(eps_P, dtype=float) * np.sqrt(np.where(ok, radicand, np.nan))
    e = a[..., None] * xb + b[..., None] * yb + h[..., None] * np.cross(xb, yb)
    return e, np.where(one_g2 > 0.0, radicand, -np.inf)
