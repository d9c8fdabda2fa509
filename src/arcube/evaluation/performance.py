"""Physical performance at the drill tip (model §15): the NumPy reference.

* :func:`forward_jacobian`: the drill tip's Jacobians J_E (mm/rad) and J_e (1/rad), ``(..., 3, 5)``,
  in the patient frame R_w (model §15.1), built from the velocity model of model §7.4;
* :func:`tip_metrics`: accuracy (15.2), loads (15.3) and stiffness (15.4) from them.

Joint order (columns of the Jacobians): :data:`ACTUATOR_NAMES` = (rho_x, rho_y, rho_z, delta_x,
delta_y). Units: lengths mm, joint angles rad inside (degrees for the encoder resolution and the
reported axis error), forces N, torques N·m, actuator stiffness N·m/rad, deflections mm.

Every function broadcasts over leading axes, e.g. ``params[:, None, :]`` (designs) against
``E[None, :, :]`` (points).
"""

from __future__ import annotations

import itertools
import math
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.errors import InputError
from arcube.io.inputs import short_repr
from arcube.model import frames
from arcube.model.design import unpack
from arcube.model.mechanism import DEFAULT_MODE, IKSolution, inverse_kinematics, velocity_model
from arcube.options import Loads

ACTUATOR_NAMES: tuple[str, ...] = ("rho_x", "rho_y", "rho_z", "delta_x", "delta_y")
"""The five actuated joints, in the order of the Jacobians' columns and of ``torque_actuator``."""

_SIGNS: NDArray[np.float64] = np.array([(1.0, *s) for s in itertools.product((1.0, -1.0), repeat=4)])
"""16 of the 32 sign vectors of model §15.2, ``(16, 5)``: |M s| = |M (-s)|, so these give the same maximum."""

"""A' counts as singular where its 2-norm condition number exceeds 1/eps (or it is not finite)."""


def _cross_cols(a: NDArray[np.float64], M: NDArray[np.float64]) -> NDArray[np.float64]:
    """[a]x M: a ``(..., 3)`` crossed with every column of M ``(..., 3, k)`` -> ``(..., 3, k)``."""
    return np.swapaxes(np.cross(a[..., None, :], np.swapaxes(M, -1, -2)), -1, -2)


def spin_free_basis(e: ArrayLike) -> NDArray[np.float64]:
    """An orthonormal pair [b1 b2] ``(..., 3, 2)`` orthogonal to the unit axes ``e`` ``(..., 3)``.

    b1 is the component orthogonal to e of x̂ (of ŷ where |e_x| > 0.9), normalised; b2 = e x b1.
    NaN where e is NaN.
    """
    ea = np.asarray(e, dtype=float)
    ea = ea / np.linalg.norm(ea, axis=-1, keepdims=True)
    helper = np.where(np.abs(ea[..., :1]) > 0.9, np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0]))
    b1 = helper - np.sum(helper * ea, axis=-1, keepdims=True) * ea
    b1 = b1 / np.linalg.norm(b1, axis=-1, keepdims=True)
    b2 = np.cross(ea, b1)
    return np.stack([b1, b2], axis=-1)


def forward_jacobian(
    params: ArrayLike,
    E: ArrayLike,
    e: ArrayLike,
    mode: ArrayLike = DEFAULT_MODE,
    basis: ArrayLike | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Forward Jacobians of the drill tip (model §15.1), in the patient frame R_w.

    Args:
        params: designs ``(..., 27)`` or ``(..., 23)`` (mm, deg).
        E: drill tips ``(..., 3)`` in R_w (mm).
        e: unit drill axes ``(..., 3)`` in R_w (from the tip toward the motor).
        mode: working modes ``(..., 4)``.
        basis: optional orthonormal pair [b1 b2] ``(..., 3, 2)`` orthogonal to e, in R_w, that spans
            the spin-free angular velocities; default :func:`spin_free_basis`. The result does not
            depend on it (up to rounding).

    Returns:
        (J_E, J_e), each ``(..., 3, 5)``: Ė = J_E q̇ (mm/rad) and ė = J_e q̇ (1/rad), columns in
        :data:`ACTUATOR_NAMES` order. NaN where the IK has no solution or A' is singular.

    The velocity model A t = B q̇ (model §7.4) lives in mechanism coordinates at the centre C of
    the spherical stage: A' = A blockdiag(I3, [b1 b2]), J' = A'^-1 B, J_C = J'[0:3],
    J_ω = [b1 b2] J'[3:5]. Rotated to R_w by the mounting rotation R (model §13.1), then, since
    E = C - L e and ė = ω x e: J_E = J_C + L [e]x J_ω, J_e = -[e]x J_ω.
    """
    return jacobians_of_solution(inverse_kinematics(params, E, e, mode), params, basis)


def jacobians_of_solution(
    sol: IKSolution, params: ArrayLike, basis: ArrayLike | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(J_E, J_e) of :func:`forward_jacobian` from an IK solution already at hand (same shapes)."""
    g = unpack(params)
    model = velocity_model(sol, params)
    e_m = sol.e / np.linalg.norm(sol.e, axis=-1, keepdims=True)
    if basis is None:
        b_m = spin_free_basis(e_m)
    else:  # world -> mechanism: R^T b, column by column
        b_m = np.einsum("...ji,...jk->...ik", frames.mount_rotation(g), np.asarray(basis, dtype=float))
    A, B = model.A, model.B
    lead = np.broadcast_shapes(A.shape[:-2], B.shape[:-2], b_m.shape[:-2])
    A_rot = np.broadcast_to(A[..., :, 3:6] @ b_m, lead + (5, 2))
    A_p = np.concatenate([np.broadcast_to(A[..., :, 0:3], lead + (5, 3)), A_rot], axis=-1)
    B_b = np.broadcast_to(B, lead + (5, 5))
    finite = np.all(np.isfinite(A_p), axis=(-2, -1)) & np.all(np.isfinite(B_b), axis=(-2, -1))
    eye = np.eye(5)
    A_safe = np.where(finite[..., None, None], A_p, eye)
    # an LU factorization, not an SVD: exact singularity is all that matters here, since a point
    # where A' is near-singular has eta_L = inf and is unreachable anyway (model §15.1)
    ok = finite & np.asarray(sol.reachable) & (np.abs(np.linalg.det(A_safe)) > 0.0)
    A_safe = np.where(ok[..., None, None], A_safe, eye)
    J_p = np.linalg.solve(A_safe, np.where(ok[..., None, None], B_b, 0.0))
    J_p = np.where(ok[..., None, None], J_p, np.nan)
    J_C_m = J_p[..., 0:3, :]
    J_w_m = np.broadcast_to(b_m, lead + (3, 2)) @ J_p[..., 3:5, :]

    R = frames.mount_rotation(g)
    flat = frames.is_unrotated(g)[..., None, None]
    J_C = np.where(flat, J_C_m, R @ J_C_m)
    J_w = np.where(flat, J_w_m, R @ J_w_m)
    e_w = np.where(flat[..., 0], e_m, np.einsum("...ij,...j->...i", R, e_m))
    e_x_Jw = _cross_cols(e_w, J_w)
    L = np.asarray(g.L, dtype=float)[..., None, None]
    J_E = np.where(L == 0.0, J_C, J_C + L * e_x_Jw)
    return J_E, -e_x_Jw


class TipMetrics(NamedTuple):
    """Per-point physical performance at the drill tip (model §15.2-15.4); each field ``(...)``
    unless noted, NaN (and -1 for ``torque_actuator``) where the Jacobian is NaN."""

    tip_error_mm: NDArray[np.float64]  # max_s |J_E diag(eps) s|
    lateral_error_mm: NDArray[np.float64]  # max_s |P_perp J_E diag(eps) s|
    axial_error_mm: NDArray[np.float64]  # sum_i eps_i |e^T J_E,i|
    axis_error_deg: NDArray[np.float64]  # max_s |J_e diag(eps) s|, in degrees
    torque_Nm: NDArray[np.float64]  # max_i |tau_i|max
    torque_actuator: NDArray[np.int64]  # index into ACTUATOR_NAMES of the max, -1 where NaN
    torque_per_actuator_Nm: NDArray[np.float64]  # (..., 5) |tau_i|max = F_t |e^T J_E,i| + F_l |P_perp J_E,i|
    deflection_mm: NDArray[np.float64]  # F_t |P_perp C_E e| + F_l lambda_max(P_perp C_E P_perp)


def check_per_actuator(value: ArrayLike, param: str, unit: str) -> NDArray[np.float64]:
    """A scalar or 5 finite numbers > 0 as a ``(5,)`` array; else InputError naming ``param``."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise InputError.of(
            param, f"must be one or five finite numbers of {unit} > 0, got {short_repr(value)}"
        ) from None
    if a.shape not in ((), (5,)) or not np.all(np.isfinite(a)) or not np.all(a > 0.0):
        shown = a.tolist() if a.size <= 5 else f"an array of shape {a.shape}"
        raise InputError.of(param, f"must be one or five finite numbers of {unit} > 0, got {shown}")
    return np.broadcast_to(a, (5,)).astype(float)


def check_force(value: ArrayLike, param: str) -> float:
    """A finite scalar force >= 0 (N); else InputError naming ``param``."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise InputError.of(param, f"must be a finite number of N >= 0, got {short_repr(value)}") from None
    if a.shape != () or not math.isfinite(float(a)) or float(a) < 0.0:
        raise InputError.of(param, f"must be a finite number of N >= 0, got {a.tolist()}")
    return float(a)


def _max_quadratic(M: NDArray[np.float64]) -> NDArray[np.float64]:
    """max over sign vectors s of |M s| for M ``(..., 3, 5)`` -> ``(...)``, via the Gram matrix."""
    G = np.swapaxes(M, -1, -2) @ M
    q = np.sum(_SIGNS.T * (G @ _SIGNS.T), axis=-2)  # s_k^T G s_k for each sign vector k
    return np.sqrt(np.maximum(np.max(q, axis=-1), 0.0))


def tip_metrics(
    J_E: ArrayLike,
    J_e: ArrayLike,
    e: ArrayLike,
    encoder_deg: ArrayLike = 0.01,
    thrust_N: float = 30.0,
    lateral_N: float = 10.0,
    stiffness_Nm_per_rad: ArrayLike = 1e4,
) -> TipMetrics:
    """Accuracy, loads and stiffness at the drill tip (model §15.2-15.4).

    Args:
        J_E: tip Jacobians ``(..., 3, 5)`` (mm/rad), from :func:`forward_jacobian`.
        J_e: axis Jacobians ``(..., 3, 5)`` (1/rad).
        e: unit drill axes ``(..., 3)`` in the same frame as the Jacobians.
        encoder_deg: actuator position error bound ε (deg), one for all or ``(5,)``; > 0.
        thrust_N: thrust F_t along +e (N), >= 0.
        lateral_N: bound F_l of the lateral force across e (N), >= 0.
        stiffness_Nm_per_rad: actuator stiffness k (N·m/rad), one for all or ``(5,)``; > 0.

    Returns:
        :class:`TipMetrics`. The 15.2 maxima are exact (all sign vectors of the box's vertices).
        Torques: J_E is in mm/rad, so τ = -J_Eᵀ f is in N·mm, reported in N·m (/1000). Compliance:
        K is converted to N·mm/rad (x1000), so C_E = J_E K⁻¹ J_Eᵀ is in mm/N.

    Raises:
        InputError: a parameter is not finite, out of range or of the wrong shape (one line that
            names it as the keyword of this function, e.g. ``thrust_N``).
    """
    eps = np.deg2rad(check_per_actuator(encoder_deg, "encoder_deg", "deg"))
    k = check_per_actuator(stiffness_Nm_per_rad, "stiffness_Nm_per_rad", "N·m/rad") * 1000.0  # N·mm/rad
    F_t, F_l = check_force(thrust_N, "thrust_N"), check_force(lateral_N, "lateral_N")
    JE, Je = np.asarray(J_E, dtype=float), np.asarray(J_e, dtype=float)
    if JE.shape[-2:] != (3, 5) or Je.shape[-2:] != (3, 5):
        raise ValueError(f"J_E and J_e must have shape (..., 3, 5), got {JE.shape} and {Je.shape}")
    ea = np.asarray(e, dtype=float)
    ea = ea / np.linalg.norm(ea, axis=-1, keepdims=True)
    lead = np.broadcast_shapes(JE.shape[:-2], Je.shape[:-2], ea.shape[:-1])
    JE, Je = np.broadcast_to(JE, lead + (3, 5)), np.broadcast_to(Je, lead + (3, 5))
    ea = np.broadcast_to(ea, lead + (3,))

    # 15.2 accuracy
    axial_cols = np.einsum("...i,...ij->...j", ea, JE)  # e^T J_E,i (mm/rad), (..., 5)
    lateral_J = JE - ea[..., :, None] * axial_cols[..., None, :]  # P_perp J_E
    tip = _max_quadratic(JE * eps)
    lateral = _max_quadratic(lateral_J * eps)
    axial = np.sum(eps * np.abs(axial_cols), axis=-1)
    axis = np.rad2deg(_max_quadratic(Je * eps))

    # 15.3 loads (N·mm -> N·m)
    per = (F_t * np.abs(axial_cols) + F_l * np.linalg.norm(lateral_J, axis=-2)) / 1000.0
    bad = np.any(np.isnan(per), axis=-1)
    torque = np.where(bad, np.nan, np.max(np.where(bad[..., None], 0.0, per), axis=-1))
    actuator = np.where(bad, -1, np.argmax(np.where(bad[..., None], 0.0, per), axis=-1)).astype(np.int64)

    # 15.4 stiffness: C_E = W W^T with W = J_E K^-1/2 (mm / sqrt(N·mm/rad)·rad -> C_E in mm/N)
    W = JE / np.sqrt(k)
    b = spin_free_basis(ea)
    Wl = np.swapaxes(b, -1, -2) @ W  # [b1 b2]^T W, (..., 2, 5)
    push = np.einsum("...ij,...j->...i", Wl, np.einsum("...ij,...i->...j", W, ea))  # [b1 b2]^T C_E e, (..., 2)
    M = Wl @ np.swapaxes(Wl, -1, -2)  # lateral 2x2 block of C_E
    half_tr = 0.5 * (M[..., 0, 0] + M[..., 1, 1])
    lam = half_tr + np.hypot(0.5 * (M[..., 0, 0] - M[..., 1, 1]), M[..., 0, 1])
    deflection = F_t * np.linalg.norm(push, axis=-1) + F_l * lam

    nan = np.any(np.isnan(JE), axis=(-2, -1)) | np.any(np.isnan(Je), axis=(-2, -1))

    def masked(a: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.where(nan, np.nan, a)

    return TipMetrics(
        tip_error_mm=masked(tip),
        lateral_error_mm=masked(lateral),
        axial_error_mm=masked(axial),
        axis_error_deg=masked(axis),
        torque_Nm=masked(torque),
        torque_actuator=np.where(nan, -1, actuator).astype(np.int64),
        torque_per_actuator_Nm=np.where(nan[..., None], np.nan, per),
        deflection_mm=masked(deflection),
    )


PERFORMANCE_FIELDS: tuple[str, ...] = (
    "tip_error_mm",
    "lateral_error_mm",
    "axial_error_mm",
    "axis_error_deg",
    "torque_Nm",
    "deflection_mm",
)
"""The per-point metrics of model §15.2-15.4 that have a per-design maximum (15.5)."""
MAXIMUM_FIELDS: tuple[str, ...] = (*PERFORMANCE_FIELDS, "holding_torque_Nm")
"""Every per-point metric with a per-design maximum over the reachable points (``<name>_max``): those of
model §15 and the holding torque of 18.2 (:mod:`arcube.evaluation.masses`, with ``Outputs.holding_torque``)."""


def metrics_of_solution(
    sol: IKSolution,
    params: ArrayLike,
    loads: Loads | None = None,
    jacobians: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
) -> TipMetrics:
    """:func:`tip_metrics` at the points of an IK solution (shapes as ``sol``), in the patient frame, under ``loads``
    (:class:`~arcube.options.Loads`, its defaults when None). ``jacobians``: (J_E, J_e) of ``sol`` when already
    computed (:func:`jacobians_of_solution`)."""
    if loads is not None and not isinstance(loads, Loads):
        raise InputError.of("loads", f"must be an arcube.options.Loads (Options.loads), got {short_repr(loads)}")
    J_E, J_e = jacobians_of_solution(sol, params) if jacobians is None else jacobians
    e_w = frames.directions_to_world(unpack(params), sol.e)
    ld = Loads() if loads is None else loads
    return tip_metrics(J_E, J_e, e_w, ld.encoder_deg, ld.thrust_N, ld.lateral_force_N, ld.actuator_stiffness)
