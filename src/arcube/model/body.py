"""The robot's body: joint positions at poses and the named parts of model §14.1.

Everything is computed from the inverse kinematics (:func:`arcube.model.mechanism.inverse_kinematics`),
arrays first: ``params`` ``(..., 27)`` (or the paper's ``(..., 23)``; mm, deg), drill tips ``E``
``(..., 3)`` in the patient frame R_w (mm) and drill axes ``e`` ``(..., 3)`` broadcast together,
e.g. designs ``params[:, None, :]`` against points ``E[None, :, :]``. The leading shape of the
result is the broadcast shape ``(...)``; no Python loop runs over designs or points.

All returned points are in R_w (mechanism coordinates mapped by the mounting rotation and m,
model §13). Where the IK has no solution the affected points are NaN.

Per-leg arrays have a legs axis before the coordinates: 3 legs (x, y, z) for the TLS points,
2 legs (x, y) for the four-bars and the spherical links.

:func:`body_parts` turns the joints into the parts of model §14.1 (segments, great-circle arcs
and points, each with a radius), shared by the clearance code, the 3D report and the exports.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.errors import InputError
from arcube.io.inputs import short_repr
from arcube.model import frames
from arcube.model.design import unpack
from arcube.model.mechanism import DEFAULT_MODE, IKSolution, inverse_kinematics
from arcube.model.poses import LEG_PERM

_I3 = np.eye(3)
U_HAT: NDArray[np.float64] = _I3[LEG_PERM[:, 0]]
"""(3 legs, 3): û of legs x, y, z in world axes (model §1.2)."""
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
    B: NDArray[np.float64]  # (..., 2, 3) intermediate spherical joints C + r u_beta
    H: NDArray[np.float64]  # (..., 3) drill holder H = C + r e (model §13.2)
    arc_alpha: NDArray[np.float64]  # (..., 2, S, 3) proximal links: great circle C + r û -> C + r u_beta
    arc_beta: NDArray[np.float64]  # (..., 2, S, 3) distal links: great circle C + r u_beta -> C + r e
    E: NDArray[np.float64]  # (..., 3) drill tip
    C: NDArray[np.float64]  # (..., 3) centre of the spherical stage C = E + L e (= E when L = 0)
    e: NDArray[np.float64]  # (..., 3) drill axis in R_w
    drill_end: NDArray[np.float64]  # (..., 3) H + L_m e, the motor end of the drill motor
    reachable: NDArray[np.bool_]  # (...) Eq 1 and both Eq 3 solvable (IKSolution.reachable)
    r: NDArray[np.float64]  # (...) sphere radius, mm
    c_z: NDArray[np.float64]  # (...) second z-dyad link used for J_z, mm


def link_dir(phi: ArrayLike, v_hat: ArrayLike, w_hat: ArrayLike) -> NDArray[np.float64]:
    """In-plane link direction n(phi) = sin(phi) v̂ - cos(phi) ŵ (model §4.1), ``(..., 3)``."""
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


def dyad_elbow(
    D: ArrayLike, Q: ArrayLike, axis: ArrayLike, l1: ArrayLike, l2: ArrayLike, sign: float = Z_ELBOW_SIGN
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
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
    params: ArrayLike,
    E: ArrayLike,
    e: ArrayLike,
    mode: ArrayLike = DEFAULT_MODE,
    *,
    c_z: ArrayLike | None = None,
    z_elbow: float = Z_ELBOW_SIGN,
    motor_length: ArrayLike | None = None,
    arc_samples: int = 17,
    sol: IKSolution | None = None,
) -> MechanismPoints:
    """All joint positions of the mechanism at poses (E, e), from the IK.

    Parameters
    ----------
    params : ``(..., 27)`` (or ``(..., 23)``) designs (mm, deg).
    E, e : ``(..., 3)`` drill tips in R_w (mm) and unit drill axes.
    mode : ``(..., 4)`` working mode (eps_T_x, eps_T_y, eps_R_x, eps_R_y).
    c_z : second z-dyad link (mm), ``Options.c_z``; None means c_z = d_z (model §6).
    z_elbow : elbow sign of the z dyad (see :data:`Z_ELBOW_SIGN`).
    motor_length : L_m (mm) of the drill motor beyond the holder H (model §14.1); default 120.
    arc_samples : S, points per spherical link arc (>= 2).
    sol : a precomputed IK solution of the same inputs (skips recomputing it).
    """
    g = unpack(params)
    if sol is None:
        with np.errstate(invalid="ignore", divide="ignore"):
            sol = inverse_kinematics(params, E, e, mode)
    lead = sol.rho.shape[:-1]
    r = np.broadcast_to(g.r, lead)
    C_m = sol.E_m  # the stages work at the centre C, in R_m
    # TLS (model §3.1), in R_m: P_u = -f_u û, D_u = P_u + p_u (-sin rho û + cos rho ŵ), Q_u = C + r û.
    P = -g.f[..., :, None] * U_HAT
    P = np.broadcast_to(P, lead + (3, 3))
    rho = sol.rho[..., :, None]
    D = P + g.p[..., :, None] * (-np.sin(rho) * U_HAT + np.cos(rho) * W_HAT)
    Q = C_m[..., None, :] + r[..., None, None] * U_HAT
    # TMS four-bars of legs x, y (model §4.1), in the plane u = u_C + r shared by D_u and Q_u.
    K = D[..., :2, :] + g.d[..., :2, None] * link_dir(sol.delta, V_HAT[:2], W_HAT[:2])
    T = Q[..., :2, :] + g.t[..., :, None] * link_dir(sol.sigma, V_HAT[:2], W_HAT[:2])
    # z dyad (model §6): passive RRR from D_z to Q_z, axes along ẑ_m.
    d_z = g.d[..., 2]
    cz = np.broadcast_to(d_z if c_z is None else np.asarray(c_z, dtype=float), lead)
    J_z, z_closes = dyad_elbow(D[..., 2, :], Q[..., 2, :], U_HAT[2], np.broadcast_to(d_z, lead), cz, z_elbow)
    # RTS (model §5.1): sphere of radius r centred at C; arcs û -> u_beta (alpha) -> e (beta).
    ub = sol.u_beta
    e_b = np.broadcast_to(sol.e[..., None, :], ub.shape)
    u_b = np.broadcast_to(U_HAT[:2], ub.shape)
    centre = C_m[..., None, None, :]
    rr = r[..., None, None, None]
    arc_alpha = centre + rr * great_circle(u_b, ub, arc_samples)
    arc_beta = centre + rr * great_circle(ub, e_b, arc_samples)
    B = C_m[..., None, :] + r[..., None, None] * ub
    H = C_m + r[..., None] * sol.e
    Lm = np.broadcast_to(np.asarray(120.0 if motor_length is None else motor_length, dtype=float), lead)
    drill_end = H + Lm[..., None] * sol.e
    L = np.broadcast_to(g.L, lead)
    E_m = C_m - L[..., None] * sol.e
    # Every point above is in R_m; map to the patient frame R_w once, at the end (model §13.1).
    world = lambda X: frames.points_to_world(g, X)  # noqa: E731
    O = np.broadcast_to(g.m, lead + (3,)).copy()
    E_w = np.where(L[..., None] == 0.0, world(C_m), world(E_m))
    return MechanismPoints(
        O=O,
        P=world(P),
        D=world(D),
        Q=world(Q),
        K=world(K),
        T=world(T),
        J_z=world(J_z),
        z_closes=z_closes,
        B=world(B),
        H=world(H),
        arc_alpha=world(arc_alpha),
        arc_beta=world(arc_beta),
        E=E_w,
        C=world(C_m),
        e=frames.directions_to_world(g, sol.e),
        drill_end=world(drill_end),
        reachable=np.asarray(sol.reachable),
        r=r.copy(),
        c_z=cz.copy(),
    )


# ----------------------------------------------------------------------------- model §14.1: parts

FOUR_BAR_PARTS: tuple[str, ...] = ("input_x", "input_y", "coupler_x", "coupler_y", "output_x", "output_y")
"""The links of the TMS four-bars x and y (model §4): a part each, and a moving body each (model §18.1)."""
PART_NAMES: tuple[str, ...] = (
    "frame_x",
    "frame_y",
    "frame_z",
    "actuator_P_x",
    "actuator_P_y",
    "actuator_P_z",
    "crank_x",
    "crank_y",
    "crank_z",
    "actuator_D_x",
    "actuator_D_y",
    *FOUR_BAR_PARTS,
    "zdyad",
    "platform",
    "spherical_alpha_x",
    "spherical_alpha_y",
    "spherical_beta_x",
    "spherical_beta_y",
    "drill_motor",
)
"""The named parts of the robot's body (model §14.1); the tool E -> H is exempt and not a part."""
_PART = {name: i for i, name in enumerate(PART_NAMES)}


def _finite(value: float) -> bool:
    try:
        return math.isfinite(value)
    except OverflowError:  # an int beyond the float range
        return False


@dataclass(frozen=True)
class BodyRadii:
    """Radii of the body parts (model §14.1), mm: links, actuators (spheres at P_u, D_u), drill motor."""

    link: float = 8.0
    actuator: float = 25.0
    motor: float = 20.0
    motor_length: float = 120.0

    def __post_init__(self) -> None:
        for name in ("link", "actuator", "motor", "motor_length"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and _finite(value) and value > 0.0):
                raise InputError.of(f"BodyRadii.{name}", f"must be a finite number of mm > 0, got {short_repr(value)}")


# Primitive tables: (part, joint points it touches, leg, stage). Joints: O, P_u, D_u, K_u, T_u, Q_u, J_z, B_u, H.
_SEGMENTS: tuple[tuple[str, frozenset[str], str, str], ...] = (
    *((f"frame_{u}", frozenset({"O", f"P_{u}"}), u, "TLS") for u in "xyz"),
    *((f"crank_{u}", frozenset({f"P_{u}", f"D_{u}"}), u, "TLS") for u in "xyz"),
    *((f"input_{u}", frozenset({f"D_{u}", f"K_{u}"}), u, "TMS") for u in "xy"),
    *((f"coupler_{u}", frozenset({f"K_{u}", f"T_{u}"}), u, "TMS") for u in "xy"),
    *((f"output_{u}", frozenset({f"Q_{u}", f"T_{u}"}), u, "TMS") for u in "xy"),
    ("zdyad", frozenset({"D_z", "J_z", "Q_z"}), "z", "TMS"),
    ("zdyad", frozenset({"D_z", "J_z", "Q_z"}), "z", "TMS"),
    *(("platform", frozenset({"Q_x", "Q_y", "Q_z"}), "platform", "platform") for _ in range(3)),
    ("drill_motor", frozenset({"H"}), "tool", "tool"),
)
_SPHERES: tuple[tuple[str, frozenset[str], str, str], ...] = (
    *((f"actuator_P_{u}", frozenset({f"P_{u}"}), u, "TLS") for u in "xyz"),
    *((f"actuator_D_{u}", frozenset({f"D_{u}"}), u, "TMS") for u in "xy"),
)
_ARCS: tuple[tuple[str, frozenset[str], str, str], ...] = (
    *((f"spherical_alpha_{u}", frozenset({f"Q_{u}", f"B_{u}"}), u, "RTS") for u in "xy"),
    *((f"spherical_beta_{u}", frozenset({f"B_{u}", "H"}), u, "RTS") for u in "xy"),
)
PRIMITIVES: tuple[tuple[str, frozenset[str], str, str], ...] = _SEGMENTS + _SPHERES + _ARCS
"""Every primitive in order: 18 segments, 5 spheres, 4 arcs; (part name, joints, leg, stage)."""
N_SEGMENTS, N_SPHERES, N_ARCS = len(_SEGMENTS), len(_SPHERES), len(_ARCS)


def _self_pairs() -> NDArray[np.intp]:
    """Primitive pairs checked by the self clearance (model §14.3): parts of different legs or
    stages that share no joint point; the spherical arcs are not checked against each other."""
    pairs = []
    for i, (_, ji, li, si) in enumerate(PRIMITIVES):
        for j in range(i + 1, len(PRIMITIVES)):
            _, jj, lj, sj = PRIMITIVES[j]
            if (li, si) == (lj, sj) or ji & jj or (si == sj == "RTS"):
                continue
            pairs.append((i, j))
    return np.array(pairs, dtype=np.intp)


SELF_PAIRS: NDArray[np.intp] = _self_pairs()
"""``(n_pairs, 2)`` indices into :data:`PRIMITIVES` of the pairs the self clearance measures."""


class BodyParts(NamedTuple):
    """The body as primitives in R_w (mm), leading shape ``(...)``; NaN where the IK has no solution."""

    segments: NDArray[np.float64]
    """``(..., 18, 2, 3)`` the segments' end points (frame, links, z dyad, drill motor), in :data:`PRIMITIVES` order."""
    spheres: NDArray[np.float64]
    """``(..., 5, 3)`` the actuators' centres."""
    arc_centre: NDArray[np.float64]
    """``(..., 3)`` the centre C of the spherical stage's arcs."""
    arc_radius: NDArray[np.float64]
    """``(...)`` their radius r."""
    arc_ends: NDArray[np.float64]
    """``(..., 4, 2, 3)`` unit start and end directions of the great-circle arcs."""
    radius: NDArray[np.float64]
    """``(27,)`` each primitive's radius, in :data:`PRIMITIVES` order."""


def body_parts(mp: MechanismPoints, radii: BodyRadii = BodyRadii()) -> BodyParts:
    """The parts of model §14.1 from joint positions (``mechanism_points``, whose ``drill_end`` must be
    H + L_m e with L_m = ``radii.motor_length``)."""
    P, D, Q, K, T = mp.P, mp.D, mp.Q, mp.K, mp.T
    O = np.broadcast_to(mp.O[..., None, :], P.shape)
    closes = mp.z_closes[..., None]
    z_mid = np.where(closes, mp.J_z, Q[..., 2, :])  # open dyad: D_z -> Q_z, then a point segment at Q_z
    segs = [
        *(np.stack([O[..., u, :], P[..., u, :]], axis=-2) for u in range(3)),
        *(np.stack([P[..., u, :], D[..., u, :]], axis=-2) for u in range(3)),
        *(np.stack([D[..., u, :], K[..., u, :]], axis=-2) for u in range(2)),
        *(np.stack([K[..., u, :], T[..., u, :]], axis=-2) for u in range(2)),
        *(np.stack([Q[..., u, :], T[..., u, :]], axis=-2) for u in range(2)),
        np.stack([D[..., 2, :], z_mid], axis=-2),
        np.stack([z_mid, Q[..., 2, :]], axis=-2),
        np.stack([Q[..., 0, :], Q[..., 1, :]], axis=-2),
        np.stack([Q[..., 1, :], Q[..., 2, :]], axis=-2),
        np.stack([Q[..., 2, :], Q[..., 0, :]], axis=-2),
        np.stack([mp.H, mp.drill_end], axis=-2),
    ]
    spheres = np.concatenate([P, D[..., :2, :]], axis=-2)
    r = mp.r[..., None, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        u_dir = (Q[..., :2, :] - mp.C[..., None, :]) / r
        b_dir = (mp.B - mp.C[..., None, :]) / r
    e_dir = np.broadcast_to(mp.e[..., None, :], b_dir.shape)
    arcs = np.stack(
        [np.stack([u_dir, b_dir], axis=-2), np.stack([b_dir, e_dir], axis=-2)], axis=-4
    )  # (..., 2 kinds, 2 legs, 2, 3)
    arcs = arcs.reshape(arcs.shape[:-4] + (4, 2, 3))
    return BodyParts(
        segments=np.stack(segs, axis=-3),
        spheres=spheres,
        arc_centre=mp.C,
        arc_radius=mp.r,
        arc_ends=arcs,
        radius=primitive_radii(radii),
    )


def primitive_radii(radii: BodyRadii = BodyRadii()) -> NDArray[np.float64]:
    """``(27,)`` radius of each primitive in :data:`PRIMITIVES` order, mm."""
    rad = [radii.link] * (N_SEGMENTS - 1) + [radii.motor] + [radii.actuator] * N_SPHERES + [radii.link] * N_ARCS
    return np.array(rad, dtype=float)


PRIMITIVE_PART: NDArray[np.intp] = np.array([_PART[p[0]] for p in PRIMITIVES], dtype=np.intp)
"""``(27,)``: index into :data:`PART_NAMES` of each primitive."""
