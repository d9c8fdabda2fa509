"""Poses, drill directions and leg frames (model §1).

A pose is the drill tip E (mm) and the unit drill axis e, which points from the tip back
toward the motor. Angles (psi, theta) are in radians here; user-facing code converts.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

LEG_PERM: NDArray[np.intp] = np.array([[0, 1, 2], [1, 2, 0], [2, 0, 1]])
"""Row i lists the world axes (u, v, w) of leg i (x, y, z): cyclic, so every triad is right-handed."""

LEG_NAMES: tuple[str, str, str] = ("x", "y", "z")


def leg_coords(a: ArrayLike) -> NDArray[np.float64]:
    """Leg coordinates of vectors ``a`` ``(..., 3)``: returns ``(..., 3 legs, 3)`` as (a_u, a_v, a_w)."""
    return np.asarray(a, dtype=float)[..., LEG_PERM]


def e_from_angles(psi: ArrayLike, theta: ArrayLike) -> NDArray[np.float64]:
    """Drill axis e = R_x(psi) R_y(theta) z, shape ``(..., 3)``; angles in rad."""
    psi_a, theta_a = np.broadcast_arrays(np.asarray(psi, float), np.asarray(theta, float))
    ct = np.cos(theta_a)
    return np.stack([np.sin(theta_a), -np.sin(psi_a) * ct, np.cos(psi_a) * ct], axis=-1)


def angles_from_e(e: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(psi, theta) in rad of unit vectors ``e`` ``(..., 3)``, on the chart |theta| < 90 deg."""
    ea = np.asarray(e, dtype=float)
    theta = np.arcsin(np.clip(ea[..., 0], -1.0, 1.0))
    psi = np.arctan2(-ea[..., 1], ea[..., 2])
    return psi, theta


def omega_from_angle_rates(psi: ArrayLike, psi_dot: ArrayLike, theta_dot: ArrayLike) -> NDArray[np.float64]:
    """Angular velocity of the frame R_x(psi) R_y(theta): psi_dot x + theta_dot (cos psi y + sin psi z)."""
    psi_a = np.asarray(psi, float)
    pd, td = np.asarray(psi_dot, float), np.asarray(theta_dot, float)
    zero = np.zeros(np.broadcast_shapes(psi_a.shape, pd.shape, td.shape))
    return np.stack([pd + zero, td * np.cos(psi_a) + zero, td * np.sin(psi_a) + zero], axis=-1)


def sample_trajectories(
    entry: ArrayLike, target: ArrayLike, n_points: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Sample trajectories at ``n_points`` equally spaced points, both ends included (model §1.4).

    Parameters
    ----------
    entry, target : ``(..., 3)`` mm, patient frame.
    n_points : N >= 2.

    Returns
    -------
    E : ``(..., N, 3)`` drill-tip positions, from entry (k = 0) to target (k = N-1).
    e : ``(..., 3)`` unit drill axis (entry - target)/|entry - target|, constant along each trajectory.
    """
    if n_points < 2:
        raise ValueError(f"a trajectory needs at least 2 points, got {n_points}")
    p_in = np.asarray(entry, dtype=float)
    p_tg = np.asarray(target, dtype=float)
    s = np.arange(n_points) / (n_points - 1)
    E = p_in[..., None, :] + s[:, None] * (p_tg - p_in)[..., None, :]
    axis = p_in - p_tg
    length = np.linalg.norm(axis, axis=-1, keepdims=True)
    if np.any(length == 0.0):
        raise ValueError("entry == target: a trajectory needs two distinct points")
    return E, axis / length
