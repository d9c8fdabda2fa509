"""Every hinge angle of the exported MuJoCo model (:mod:`arcube.export.mjcf`) at poses, from the IK.

The body tree, its hinges and their zero angles are documented in :mod:`arcube.export.mjcf`; this
module holds the names and the angles the exporter, its replay (:mod:`arcube.export.replay`) and the
tests share. Angles in rad, positions in the patient frame R_w (mm).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.model.modes import DEFAULT_MODE_TEXT
from arcube.coerce import mode_signs
from arcube.model import frames
from arcube.model.body import U_HAT, V_HAT, W_HAT, mechanism_points
from arcube.model.design import Design, unpack
from arcube.model.mechanism import inverse_kinematics

__all__ = ["ACTUATED", "JOINT_NAMES", "axes_world", "design_vector", "joint_values", "z_dyad_range"]

ACTUATED: tuple[str, ...] = ("rho_x", "rho_y", "rho_z", "delta_x", "delta_y")
"""The five actuated hinges (and their position actuators), in the order of model §7.4."""

JOINT_NAMES: tuple[str, ...] = (
    "rho_x",
    "kappa_x",
    "delta_x",
    "gamma_x",
    "rho_y",
    "kappa_y",
    "delta_y",
    "gamma_y",
    "rho_z",
    "kappa_z",
    "zdyad_D",
    "zdyad_J",
    "zdyad_Q",
    "sigma_x",
    "tau_x",
    "sigma_y",
    "tau_y",
)
"""Every hinge of the exported model, in the order of ``qpos`` (depth-first body tree)."""


def _wrap(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """Angles into (-pi, pi]."""
    return -np.remainder(np.pi - a, 2.0 * np.pi) + np.pi


def _dot(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.sum(a * b, axis=-1)


def design_vector(design: Design | ArrayLike) -> NDArray[np.float64]:
    """The ``(27,)`` vector (mm, deg) of a :class:`Design` or a ``(27,)`` / ``(23,)`` vector."""
    return Design.coerce(design).to_vector()


def axes_world(
    params: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(û, v̂, ŵ) of legs x, y, z in R_w, each ``(3 legs, 3)``, and R ``(3, 3)`` (one design)."""
    R = frames.mount_rotation(unpack(params))
    return U_HAT @ R.T, V_HAT @ R.T, W_HAT @ R.T, R


def joint_values(
    design: Design | ArrayLike,
    E: ArrayLike,
    e: ArrayLike,
    mode: str | ArrayLike = DEFAULT_MODE_TEXT,
    *,
    c_z: float | None = None,
) -> dict[str, NDArray[np.float64]]:
    """Every hinge angle of the exported model (rad) at poses (E, e) in R_w, from the IK; each ``(...)``.

    Keys are :data:`JOINT_NAMES`. Actuated hinges are the model's rho_u, delta_u; ``sigma_u`` is the
    model's sigma_u; ``kappa_u`` = rho_u (the knee that keeps the planar chain parallel); ``gamma_u``
    is the coupler's angle minus delta_u (about û); ``tau_u`` the dihedral angle at u_beta from the
    great circle toward û to the one toward e (about u_beta); ``zdyad_D`` the angle of J_z - D_z from
    x_m toward y_m, ``zdyad_J`` that of Q_z - J_z minus it, ``zdyad_Q`` minus the angle of Q_z - J_z.
    NaN where the IK (or the z dyad) has no solution. One design, poses broadcast.
    """
    params = design_vector(design)
    signs = mode_signs(mode)
    with np.errstate(invalid="ignore", divide="ignore"):
        sol = inverse_kinematics(params, E, e, signs)
        mp = mechanism_points(params, E, e, signs, c_z=c_z, sol=sol)
    U, V, W, R = axes_world(params)
    out: dict[str, NDArray[np.float64]] = {}
    for i, u in enumerate("xyz"):
        out[f"rho_{u}"] = sol.rho[..., i]
        out[f"kappa_{u}"] = sol.rho[..., i]
    ub_w = sol.u_beta @ R.T  # (..., 2, 3)
    for i, u in enumerate("xy"):
        out[f"delta_{u}"] = sol.delta[..., i]
        ct = mp.T[..., i, :] - mp.K[..., i, :]
        phi = np.arctan2(_dot(ct, V[i]), -_dot(ct, W[i]))
        out[f"gamma_{u}"] = _wrap(phi - sol.delta[..., i])
        out[f"sigma_{u}"] = sol.sigma[..., i]
        ub = ub_w[..., i, :]
        a = U[i] - _dot(U[i], ub)[..., None] * ub
        b = mp.e - _dot(mp.e, ub)[..., None] * ub
        out[f"tau_{u}"] = np.arctan2(_dot(np.cross(a, b), ub), _dot(a, b))
    xm, ym = R[:, 0], R[:, 1]
    dj = mp.J_z - mp.D[..., 2, :]
    jq = mp.Q[..., 2, :] - mp.J_z
    phi1 = np.arctan2(_dot(dj, ym), _dot(dj, xm))
    phi2 = np.arctan2(_dot(jq, ym), _dot(jq, xm))
    out["zdyad_D"] = phi1
    out["zdyad_J"] = _wrap(phi2 - phi1)
    out["zdyad_Q"] = _wrap(-phi2)
    return {name: np.asarray(out[name], dtype=float) for name in JOINT_NAMES}


def z_dyad_range(L_z: ArrayLike, d_z: float) -> tuple[float, float]:
    """The c_z range [lo, hi] (mm) that closes the z dyad at every span L_z = |Q_z - D_z| (model §6):
    the intersection of [|L_z - d_z|, L_z + d_z]; empty (lo > hi) when no c_z can."""
    L = np.asarray(L_z, dtype=float).reshape(-1)
    return float(np.max(np.abs(L - d_z))), float(np.min(L + d_z))
