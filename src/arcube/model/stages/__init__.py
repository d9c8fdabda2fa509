"""The three stages of the AR-CUBE and the z-leg dyad, each a module of array functions.

* :mod:`arcube.model.stages.tls`: translational stage (cranks, Eq 1, J_LV);
* :mod:`arcube.model.stages.tms`: transmitting four-bars of legs x and y (Eq 2-3, J_rho, J_delta, J_AV, J_sigma);
* :mod:`arcube.model.stages.rts`: spherical five-bar (Eq 4, J_AS, J_AP);
* :mod:`arcube.model.stages.zleg`: closure of the z leg's passive planar dyad (model §6).

Conventions shared by all: lengths in mm, angles in rad, leading axes broadcast (designs,
points), per-leg values stacked on the last axis (x, y[, z]).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def solve_harmonic(
    A: ArrayLike, B: ArrayLike, C: ArrayLike, eps: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Solve ``A cos x + B sin x = C`` on branch ``eps`` (+1/-1): x = atan2(B, A) + eps acos(C/R).

    Returns ``(x, arg)`` with ``arg = C / R`` (R = sqrt(A^2 + B^2)); a solution exists iff
    |arg| <= 1. ``x`` is wrapped to [-pi, pi) and is NaN where there is no solution.
    """
    A_, B_, C_ = (np.asarray(v, dtype=float) for v in (A, B, C))
    R = np.hypot(A_, B_)
    with np.errstate(divide="ignore", invalid="ignore"):
        # R = 0: no direction solves it (unreachable, +inf); NaN inputs (an upstream stage
        # failed) leave the argument undefined (NaN), so it never counts as an excess.
        arg = np.where(R > 0.0, C_ / R, np.where(R == 0.0, np.inf, np.nan))
    ok = np.abs(arg) <= 1.0
    x = np.arctan2(B_, A_) + np.asarray(eps, dtype=float) * np.arccos(np.where(ok, arg, np.nan))
    return wrap_angle(x), arg


def wrap_angle(x: ArrayLike) -> NDArray[np.float64]:
    """Wrap angles (rad) to [-pi, pi)."""
    return (np.asarray(x, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi
