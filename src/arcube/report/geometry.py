"""Joint positions of the AR-CUBE at poses, for drawing (MODEL.md 3.1, 4.1, 5.1, 6).

Everything is computed from the inverse kinematics (:func:`arcube.mechanism.inverse_kinematics`),
arrays first: ``params`` ``(..., 23)`` (mm, deg), drill tips ``E`` ``(..., 3)`` in the patient
frame R_w (mm) and drill axes ``e`` ``(..., 3)`` broadcast together, e.g. designs
``params[:, None, :]`` against points ``E[None, :, :]``. The leading shape of the result is the
broadcast shape ``(...)``; no Python loop runs over designs or points.

All returned points are in R_w (mechanism coordinates + m). Where the IK has no solution the
affected points are NaN (a drawing then simply leaves them out).

Per-leg arrays have a legs axis before the coordinates: 3 legs (x, y, z) for the TLS points,
2 legs (x, y) for the four-bars and the spherical links.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.design import unpack
from arcube.mechanism import DEFAULT_MODE, IKSolution, inverse_kinematics
from arcube.poses import LEG_PERM

_I3 = np.eye(3)
U_HAT: NDArray[np.float64] = _I3[LEG_PERM[:, 0]]
"""(3 legs, 3): û of legs x, y, z in world axes (MODEL.md 1.2)."""
V_HAT: NDArray[np.float64] = _I3[LEG_PERM[:, 1]]
W_HAT: NDArray[np.float64] = _I3[LEG_PERM[:, 2]]

Z_ELBOW_SIGN = 1.0
"""Default elbow of the z dyad: +1 puts the elbow J on the ẑ × (Q_z − D_z) side of the line
D_z -> Q_z (to the left, seen from +z); -1 mirrors it. The dyad is passive and unchecked by the
paper, so this is only a drawing choice."""


class MechanismPoints(NamedTuple):
    """Joint positions in R_w (mm); leading shape ``(...)`` of the broadcast inputs."""

    O: NDArray[np.float64]  # (..., 3) origin O_m = m
    P: NDArray[np.float64]  # (..., 3, 3) proximal active pivots P_u = m - f_u û (legs x, y, z)
    D: NDArray[np.float64]  # (..., 3, 3) crank tips D_u (distal active joints)
    Q: NDArray[np.float64]  # (..., 3, 3) platform attachments Q_u = E + r û
    K: NDArray[np.float64]  # (..., 2, 3) four-bar input link tips K_u = D_u + d_u n(delta_u)
    T: NDArray[np.float64]  # (..., 2, 3) four-bar output link tips T_u = Q_u + t_u n(sigma_u)
    J_z: NDArray[np.float64]  # (..., 3) z-dyad elbow, NaN where the dyad does not close
    z_closes: NDArray[np.bool_]  # (...) the z dyad (d_z, c_z) spans |Q_z - D_z|
    B: NDArray[np.float64]  # (..., 2, 3) intermediate spherical joints E + r u_beta
    H: NDArray[np.float64]  # (..., 3) drill holder E + r e
    arc_alpha: NDArray[np.float64]  # (..., 2, S, 3) proximal links: great circle E + r û -> E + r u_beta
    arc_beta: NDArray[np.float64]  # (..., 2, S, 3) distal links: great circle E + r u_beta -> E + r e
    E: NDArray[np.float64]  # (..., 3) drill tip (centre of the sphere)
    drill_end: NDArray[np.float64]  # (..., 3) E + L e, the motor end of the drill
    reachable: NDArray[np.bool_]  # (...) Eq 1 and both Eq 3 solvable (IKSolution.reachable)
    r: NDArray[np.float64]  # (...) sphere radius, mm
    c_z: NDArray[np.float64]  # (...) second z-dyad link used for J_z, mm


def link_dir(phi: ArrayLike, v_hat: ArrayLike, w_hat: ArrayLike) -> NDArray[np.float64]:
    """In-plane link direction n(phi) = sin(phi) v̂ - cos(phi) ŵ (MODEL.md 4.1), ``(..., 3)``."""
    ph = np.asarray(phi, dtype=float)[..., None]
    return np.sin(ph) * np.asarray(v_hat, float) - np.cos(ph) * np.asarray(w_hat, float)


def great_circle(a: ArrayLike, b: ArrayLike, n_samples: int) -> NDArray[np.float64]:
    """Unit vectors sampled along the shorter great-circle arc from ``a`` to ``b`` (slerp).

    ``a``, ``b`` ``(..., 3)`` unit; returns ``(..., n_samples, 3)``, both ends included.
    Where a and b (nearly) coincide the arc degenerates to normalised linear interpolation,
    which is exact in that limit and avoids 0/0.
    """
    a_ = np.asarray(a, dtype=float)[..., None, :]
    b_ = np.asarray(b, dtype=float)[..., None, :]
    s = np.linspace(0.0, 1.0, n_samples)[:, None]
    cross = np.linalg.norm(np.cross(a_, b_), axis=-1, keepdims=True)
    omega = np.arctan2(cross, np.sum(a_ * b_, axis=-1, keepdims=True))  # angle in [0, pi], robust near 0
    small = np.sin(omega) < 1e-9
    with np.errstate(invalid="ignore", divide="ignore"):
        slerp = (np.sin((1.0 - s) * omega) * a_ + np.sin(s * omega) * b_) / np.sin(omega)
    lerp = (1.0 - s) * a_ + s * b_
    lerp = lerp / np.linalg.norm(lerp, axis=-1, keepdims=True)
    return np.where(small, lerp, slerp)


def dyad_elbow(D: ArrayLike, Q: ArrayLike, axis: ArrayLike, l1: ArrayLike, l2: ArrayLike, sign: float = Z_ELBOW_SIGN) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Elbow of a planar two-link RRR chain D -> J -> Q with |J - D| = l1, |Q - J| = l2.

    ``D``, ``Q`` ``(..., 3)`` lie in a plane normal to the unit ``axis`` ``(3,)``; ``l1``, ``l2``
    ``(...)`` mm. ``sign`` picks the elbow: +1 on the axis × (Q - D) side. Returns
    ``(J, closes)``: J ``(..., 3)`` NaN where |l1 - l2| <= |Q - D| <= l1 + l2 fails.
    """
    D_, Q_ = np.asarray(D, dtype=float), np.asarray(Q, dtype=float)
    l1_, l2_ = np.asarray(l1, dtype=float), np.asarray(l2, dtype=float)
    dq = Q_ - D_
    L = np.linalg.norm(dq, axis=-1)
    closes = (L <= l1_ + l2_) & (L >= np.abs(l1_ - l2_)) & (L > 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        along = (l1_ * l1_ - l2_ * l2_ + L * L) / (2.0 * L)  # distance from D to the foot of J on DQ
        height = np.sqrt(np.maximum(l1_ * l1_ - along * along, 0.0))
        e1 = dq / L[..., None]
    e2 = np.cross(np.asarray(axis, dtype=float), e1)
    J = D_ + along[..., None] * e1 + sign * height[..., None] * e2
    return np.where(closes[..., None], J, np.nan), closes


def mechanism_points(
    params: ArrayLike, E: ArrayLike, e: ArrayLike, mode: ArrayLike = DEFAULT_MODE, *,
    c_z: ArrayLike | None = None, z_elbow: float = Z_ELBOW_SIGN,
    drill_length: ArrayLike | None = None, arc_samples: int = 17, sol: IKSolution | None = None,
) -> MechanismPoints:  # fmt: skip
    """All joint positions of the mechanism at poses (E, e), from the IK.

    Parameters
    ----------
    params : ``(..., 23)`` designs (mm, deg).
    E, e : ``(..., 3)`` drill tips in R_w (mm) and unit drill axes.
    mode : ``(..., 4)`` working mode (eps_T_x, eps_T_y, eps_R_x, eps_R_y).
    c_z : second z-dyad link (mm), ``Options.c_z``; None means c_z = d_z (MODEL.md 6).
    z_elbow : elbow sign of the z dyad (see :data:`Z_ELBOW_SIGN`).
    drill_length : L (mm) of the drawn drill from the tip E toward the motor; default 2 r.
    arc_samples : S, points per spherical link arc (>= 2).
    sol : a precomputed IK solution of the same inputs (skips recomputing it).
    """
    g = unpack(params)
    if sol is None:
        with np.errstate(invalid="ignore", divide="ignore"):
            sol = inverse_kinematics(params, E, e, mode)
    lead = sol.rho.shape[:-1]
    m = np.broadcast_to(g.m, lead + (3,))
    r = np.broadcast_to(g.r, lead)
    E_m = sol.E_m
    # TLS (MODEL.md 3.1), in R_m: P_u = -f_u û, D_u = P_u + p_u (-sin rho û + cos rho ŵ), Q_u = E + r û.
    P = -g.f[..., :, None] * U_HAT
    P = np.broadcast_to(P, lead + (3, 3))
    rho = sol.rho[..., :, None]
    D = P + g.p[..., :, None] * (-np.sin(rho) * U_HAT + np.cos(rho) * W_HAT)
    Q = E_m[..., None, :] + r[..., None, None] * U_HAT
    # TMS four-bars of legs x, y (MODEL.md 4.1), in the plane u = u_E + r shared by D_u and Q_u.
    K = D[..., :2, :] + g.d[..., :2, None] * link_dir(sol.delta, V_HAT[:2], W_HAT[:2])
    T = Q[..., :2, :] + g.t[..., :, None] * link_dir(sol.sigma, V_HAT[:2], W_HAT[:2])
    # z dyad (MODEL.md 6): passive RRR from D_z to Q_z, axes along ẑ.
    d_z = g.d[..., 2]
    cz = np.broadcast_to(d_z if c_z is None else np.asarray(c_z, dtype=float), lead)
    J_z, z_closes = dyad_elbow(D[..., 2, :], Q[..., 2, :], U_HAT[2], np.broadcast_to(d_z, lead), cz, z_elbow)
    # RTS (MODEL.md 5.1): sphere of radius r centred at E; arcs û -> u_beta (alpha) -> e (beta).
    ub = sol.u_beta
    e_b = np.broadcast_to(sol.e[..., None, :], ub.shape)
    u_b = np.broadcast_to(U_HAT[:2], ub.shape)
    centre = E_m[..., None, None, :]
    rr = r[..., None, None, None]
    arc_alpha = centre + rr * great_circle(u_b, ub, arc_samples)
    arc_beta = centre + rr * great_circle(ub, e_b, arc_samples)
    B = E_m[..., None, :] + r[..., None, None] * ub
    H = E_m + r[..., None] * sol.e
    L = 2.0 * r if drill_length is None else np.broadcast_to(np.asarray(drill_length, dtype=float), lead)
    drill_end = E_m + L[..., None] * sol.e
    # Every point above is in R_m; shift to the patient frame R_w once, at the end.
    m1 = m[..., None, :]
    return MechanismPoints(
        O=m.copy(), P=P + m1, D=D + m1, Q=Q + m1, K=K + m1, T=T + m1, J_z=J_z + m,
        z_closes=z_closes, B=B + m1, H=H + m,
        arc_alpha=arc_alpha + m[..., None, None, :], arc_beta=arc_beta + m[..., None, None, :],
        E=E_m + m, drill_end=drill_end + m, reachable=np.asarray(sol.reachable), r=r.copy(), c_z=cz.copy(),
    )  # fmt: skip
