"""The whole AR-CUBE: inverse and forward kinematics and the velocity model (model §5.5, 7.4).

Inputs broadcast over leading axes: ``params`` ``(..., 27)`` or the paper's ``(..., 23)`` (mm, deg;
see :mod:`arcube.model.design`), drill tips ``E`` ``(..., 3)`` in the patient frame R_w (mm), drill
axes ``e`` ``(..., 3)``, working modes ``mode`` ``(..., 4)`` = (eps_T_x, eps_T_y, eps_R_x, eps_R_y).
A typical batch is ``params[:, None, :]`` (designs) against ``E[None, :, :]`` (points).

The stages work in mechanism coordinates at the centre C = E + L e of the spherical stage
(model §13, :mod:`arcube.model.frames`); with the mounting rotation and L at 0, C = E in R_w - m.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.model.design import Geometry, unpack
from arcube.model.modes import ALL_MODES, DEFAULT_MODE, format_mode, parse_mode  # noqa: F401 (the working modes, used from here)
from arcube.model import frames
from arcube.model.poses import leg_coords
from arcube.model.stages import rts, tls, tms


class IKSolution(NamedTuple):
    """Everything the inverse kinematics computes at a pose; every field broadcast to ``(...)``.

    Joint angles are NaN where their stage has no solution; the ``*_arg`` fields say why:
    a stage is solvable iff every |arg| <= 1.
    """

    E_m: NDArray[np.float64]  # (..., 3) centre C of the spherical stage in R_m, mm (the drill tip when L = 0)
    e: NDArray[np.float64]  # (..., 3) drill axis in R_m
    rho: NDArray[np.float64]  # (..., 3) rad, TLS cranks
    sigma: NDArray[np.float64]  # (..., 2) rad, RTS inputs = TMS outputs
    delta: NDArray[np.float64]  # (..., 2) rad, TMS inputs
    tls_arg: NDArray[np.float64]  # (..., 3)
    rts_arg: NDArray[np.float64]  # (..., 2)
    tms_arg: NDArray[np.float64]  # (..., 2)
    u_beta: NDArray[np.float64]  # (..., 2, 3) intermediate RTS axes x_beta, y_beta
    terms: tms.TMSJacobianTerms  # F, G, D, E, H, each (..., 2)

    @property
    def reachable(self) -> NDArray[np.bool_]:
        """w_L of the paper (before the finiteness check and guards): Eq 1 and both Eq 3 solvable."""
        return (
            np.all(np.abs(self.tls_arg) <= 1.0, axis=-1)
            & np.all(np.abs(self.rts_arg) <= 1.0, axis=-1)
            & np.all(np.abs(self.tms_arg) <= 1.0, axis=-1)
        )

    @property
    def assembly(self) -> NDArray[np.float64]:
        """Assembly signs (sign H_x, sign H_y, sign det[x_beta, y_beta, e]) ``(..., 3)``, for the FK."""
        return np.concatenate([np.sign(self.terms.H), np.sign(rts.det_beta(self.e, self.u_beta))[..., None]], axis=-1)

    @property
    def working_mode(self) -> NDArray[np.float64]:
        """Working mode (sign F_x, sign F_y, -sign J_AS_x, -sign J_AS_y) ``(..., 4)`` of this solution."""
        j_as = rts.J_AS_diag(self.e, self.u_beta)
        return np.concatenate([np.sign(self.terms.F), -np.sign(j_as)], axis=-1)


def _tms_plane(E_m: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Leg coordinates (v, w) of the drill tip for legs x, y: each ``(..., 2)``."""
    lc = leg_coords(E_m)[..., :2, :]
    return lc[..., 1], lc[..., 2]


def inverse_kinematics(params: ArrayLike, E: ArrayLike, e: ArrayLike, mode: ArrayLike = DEFAULT_MODE) -> IKSolution:
    """Full IK: pose (E in R_w, e) -> (rho, sigma, delta), stage by stage in the paper's order.

    The pose goes to mechanism coordinates at C = E + L e (model §13); TLS (Eq 1) gives rho
    from the position; RTS (Eq 4) gives sigma from the direction; TMS (Eq 3) then finds delta
    that connects them.
    """
    g = unpack(params)
    mode_a = np.asarray(mode, dtype=float)
    eps_T, eps_R = mode_a[..., 0:2], mode_a[..., 2:4]
    E_m, e_a = frames.to_mechanism(g, E, e)
    rho, tls_arg = tls.ik(E_m, g.f, g.p, g.r)
    sigma, rts_arg = rts.ik(e_a, g.alpha, g.beta, g.o, eps_R)
    v, w = _tms_plane(E_m)
    rho_xy = rho[..., :2]
    delta, tms_arg = tms.ik(v, w, rho_xy, sigma, g.p[..., :2], g.d[..., :2], g.c, g.t, eps_T)
    terms = tms.jacobian_terms(v, w, rho_xy, delta, sigma, g.p[..., :2], g.d[..., :2], g.t)
    ub = rts.u_beta(sigma, g.alpha, g.o)
    shape = np.broadcast_shapes(E_m.shape[:-1], e_a.shape[:-1], rho.shape[:-1], delta.shape[:-1])
    return IKSolution(
        E_m=np.broadcast_to(E_m, shape + (3,)),
        e=np.broadcast_to(e_a, shape + (3,)),
        rho=np.broadcast_to(rho, shape + (3,)),
        sigma=np.broadcast_to(sigma, shape + (2,)),
        delta=delta,
        tls_arg=np.broadcast_to(tls_arg, shape + (3,)),
        rts_arg=np.broadcast_to(rts_arg, shape + (2,)),
        tms_arg=tms_arg,
        u_beta=np.broadcast_to(ub, shape + (2, 3)),
        terms=terms,
    )


class FKSolution(NamedTuple):
    """Pose from joints; NaN where the chosen assembly mode does not close."""

    E: NDArray[np.float64]  # (..., 3) drill tip in R_w, mm
    e: NDArray[np.float64]  # (..., 3) drill axis in R_w
    sigma: NDArray[np.float64]  # (..., 2) rad
    valid: NDArray[np.bool_]  # (...) both four-bars and the spherical five-bar assemble


def forward_kinematics(params: ArrayLike, rho: ArrayLike, delta: ArrayLike, assembly: ArrayLike) -> FKSolution:
    """Full FK (model §5.5): TLS FK -> E; TMS FK -> sigma; RTS FK -> e.

    ``assembly`` ``(..., 3)`` = (eps_H_x, eps_H_y, eps_P), e.g. :attr:`IKSolution.assembly`.
    """
    g = unpack(params)
    asm = np.asarray(assembly, dtype=float)
    rho_a = np.asarray(rho, dtype=float)
    E_m = tls.fk(rho_a, g.f, g.p, g.r)
    v, w = _tms_plane(E_m)
    sigma, tms_arg = tms.fk(v, w, rho_a[..., :2], delta, g.p[..., :2], g.d[..., :2], g.c, g.t, asm[..., 0:2])
    e_m, radicand = rts.fk(sigma, g.alpha, g.beta, g.o, asm[..., 2])
    valid = np.all(np.abs(tms_arg) <= 1.0, axis=-1) & (radicand >= 0.0)
    e = frames.directions_to_world(g, e_m)
    C = frames.points_to_world(g, E_m)
    L = np.asarray(g.L, dtype=float)[..., None]
    E = np.where(L == 0.0, C, C - L * e)
    return FKSolution(E=E, e=e, sigma=sigma, valid=valid)


class VelocityModel(NamedTuple):
    """A t = B q_dot (model §7.4, Eq 11 corrected); t = (v, omega), q = (rho_x, rho_y, rho_z, delta_x, delta_y)."""

    A: NDArray[np.float64]  # (..., 5, 6)
    B: NDArray[np.float64]  # (..., 5, 5)


def jacobians(sol: IKSolution, params: ArrayLike) -> dict[str, NDArray[np.float64]]:
    """The seven Jacobians of the velocity model as matrices: J_LV (3x3), J_AV, J_rho (2x3),
    J_sigma, J_delta, J_AS (2x2 diagonal), J_AP (2x3); each with leading axes ``(...)``."""
    g: Geometry = unpack(params)
    t = sol.terms
    return {
        "J_LV": _diag(tls.jacobian_LV_diag(sol.rho, g.p)),
        "J_AV": tms.J_AV(t),
        "J_sigma": _diag(t.H),
        "J_AS": _diag(rts.J_AS_diag(sol.e, sol.u_beta)),
        "J_AP": rts.J_AP(sol.e, sol.u_beta),
        "J_rho": tms.J_rho(t),
        "J_delta": _diag(t.F),
    }


def _diag(d: NDArray[np.float64]) -> NDArray[np.float64]:
    return d[..., :, None] * np.eye(d.shape[-1])


def velocity_model(sol: IKSolution, params: ArrayLike) -> VelocityModel:
    """Assemble A (5x6) and B (5x5): [I 0; J_AV  J_sigma J_AS^-1 J_AP] t = [J_LV 0; J_rho J_delta] q_dot."""
    J = jacobians(sol, params)
    lead = np.broadcast_shapes(J["J_AV"].shape[:-2], J["J_LV"].shape[:-2])
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.diagonal(J["J_sigma"], axis1=-2, axis2=-1) / np.diagonal(J["J_AS"], axis1=-2, axis2=-1)
    A = np.zeros(lead + (5, 6))
    A[..., 0:3, 0:3] = np.eye(3)
    A[..., 3:5, 0:3] = J["J_AV"]
    A[..., 3:5, 3:6] = ratio[..., :, None] * J["J_AP"]
    B = np.zeros(lead + (5, 5))
    B[..., 0:3, 0:3] = J["J_LV"]
    B[..., 3:5, 0:3] = J["J_rho"]
    B[..., 3:5, 3:5] = J["J_delta"]
    return VelocityModel(A=A, B=B)


def joint_rates(model: VelocityModel, v: ArrayLike, omega: ArrayLike) -> NDArray[np.float64]:
    """q_dot = B^-1 A t ``(..., 5)`` (rad/s) for the twist v ``(..., 3)`` mm/s, omega ``(..., 3)`` rad/s.

    Spin about e does not enter (J_AP e = 0). NaN where B is singular.
    """
    t = np.concatenate(np.broadcast_arrays(np.asarray(v, float), np.asarray(omega, float)), axis=-1)
    rhs = np.einsum("...ij,...j->...i", model.A, t)
    return _solve_or_nan(model.B, rhs)


def twist_from_joint_rates(model: VelocityModel, q_dot: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(v, omega) from joint rates: the twist with omega orthogonal to e solving A t = B q_dot.

    A has the spin about e as its null space, so the minimum-norm (pseudo-inverse) solution is
    the one with no spin. NaN where A has rank < 5 (the twist is not defined there).
    """
    rhs = np.einsum("...ij,...j->...i", model.B, np.asarray(q_dot, float))
    A = model.A
    finite = np.all(np.isfinite(A), axis=(-2, -1))
    A_safe = np.where(finite[..., None, None], A, 0.0)
    s = np.linalg.svd(A_safe, compute_uv=False)
    ok = finite & (s[..., -1] > 1e-12 * s[..., 0])
    t = np.einsum("...ij,...j->...i", np.linalg.pinv(A_safe), np.where(finite[..., None], rhs, 0.0))
    t = np.where(ok[..., None], t, np.nan)
    return t[..., 0:3], t[..., 3:6]


def _solve_or_nan(M: NDArray[np.float64], rhs: NDArray[np.float64]) -> NDArray[np.float64]:
    """Batched ``solve(M, rhs)`` that returns NaN rows where M is singular or not finite."""
    lead = np.broadcast_shapes(M.shape[:-2], rhs.shape[:-1])
    Mb = np.broadcast_to(M, lead + M.shape[-2:])
    rb = np.broadcast_to(rhs, lead + rhs.shape[-1:])
    finite = np.all(np.isfinite(Mb), axis=(-2, -1)) & np.all(np.isfinite(rb), axis=-1)
    det = np.where(finite, np.linalg.det(np.where(finite[..., None, None], Mb, np.eye(M.shape[-1]))), 0.0)
    ok = finite & (det != 0.0)
    safe = np.where(ok[..., None, None], Mb, np.eye(M.shape[-1]))
    x = np.linalg.solve(safe, np.where(ok[..., None], rb, 0.0)[..., None])[..., 0]
    return np.where(ok[..., None], x, np.nan)
