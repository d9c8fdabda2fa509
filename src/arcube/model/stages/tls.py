"""Translational stage (TLS): three cranks on the negative axes of R_m (model §3).

Leg u has its proximal active pivot at P_u = -f_u u, a crank p_u whose tip D_u is at
P_u + p_u (-sin rho_u u + cos rho_u w), and a planar distal chain with axes along u that
ends at Q_u = E + r u. Hence -f_u - p_u sin rho_u = u_E + r: each crank sets one coordinate.

All arrays broadcast over leading axes; the last axis holds the legs x, y, z.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def ik_argument(E_m: ArrayLike, f: ArrayLike, p: ArrayLike, r: ArrayLike) -> NDArray[np.float64]:
    """Argument (u + f_u + r)/p_u of Eq 1, ``(..., 3)``; the leg is reachable iff |arg| <= 1."""
    r_ = np.asarray(r, dtype=float)[..., None]
    return (np.asarray(E_m, dtype=float) + np.asarray(f, dtype=float) + r_) / np.asarray(p, dtype=float)


def ik(E_m: ArrayLike, f: ArrayLike, p: ArrayLike, r: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Eq 1: rho_u = -asin((u + f_u + r)/p_u), principal branch (cos rho >= 0).

    Parameters: ``E_m`` drill tip in mechanism coordinates ``(..., 3)`` mm; ``f``, ``p``
    ``(..., 3)`` mm; ``r`` ``(...)`` mm.
    Returns ``(rho, arg)``: ``rho`` ``(..., 3)`` rad (NaN where unreachable) and the Eq 1
    argument ``arg`` (reachable iff |arg| <= 1).
    """
    arg = ik_argument(E_m, f, p, r)
    ok = np.abs(arg) <= 1.0
    rho = -np.arcsin(np.where(ok, arg, np.nan))
    return rho, arg


def fk(rho: ArrayLike, f: ArrayLike, p: ArrayLike, r: ArrayLike) -> NDArray[np.float64]:
    """Drill tip in mechanism coordinates: u = -f_u - r - p_u sin rho_u, ``(..., 3)`` mm."""
    r_ = np.asarray(r, dtype=float)[..., None]
    return -np.asarray(f, dtype=float) - r_ - np.asarray(p, dtype=float) * np.sin(np.asarray(rho, dtype=float))


def crank_tip_w(rho: ArrayLike, p: ArrayLike) -> NDArray[np.float64]:
    """w leg coordinate p_u cos rho_u of the crank tip D_u (its v coordinate is 0), ``(..., 3)`` mm."""
    return np.asarray(p, dtype=float) * np.cos(np.asarray(rho, dtype=float))


def jacobian_LV_diag(rho: ArrayLike, p: ArrayLike) -> NDArray[np.float64]:
    """Diagonal of J_LV = diag(-p_u cos rho_u) (mm/rad), ``(..., 3)``: v = J_LV rho_dot (Eq 5, exact sign)."""
    return -np.asarray(p, dtype=float) * np.cos(np.asarray(rho, dtype=float))
