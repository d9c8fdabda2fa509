"""First-order derivatives of the closed-form forward kinematics (model §5.5 with 13.1-13.2), analytic.

The drill tip E and axis e of :func:`arcube.model.mechanism.forward_kinematics`, in the patient frame
R_w, differentiated with respect to the 27 design parameters and the five joint angles, by implicit
differentiation of the constraints the FK solves, stage after stage:

* TLS (Eq 1, 3.3): C_u = -f_u - r - p_u sin rho_u (mechanism coordinates of the centre C);
* TMS (Eq 2): Phi_u(v, w, rho_u, delta_u, sigma_u; p_u, d_u, c_u, t_u) = 0, so with the Jacobian
  terms of model §7.2 (½ dPhi = D dv + E dw - F ddelta - G drho + H dsigma + direct parameter terms),
  dsigma_u = -(D dv + E dw - F ddelta - G drho + ½ dPhi/dp ...) / H;
* RTS (Eq 4): Gamma_u = u_beta . e - cos beta_u = 0 and e . e = 1, so
  [x_b; y_b; e] de = (-(du_beta) . e - sin beta_u dbeta_u)_u, 0), solved with the rows
  P_x = (y_b x e) / det, P_y = (e x x_b) / det, det = det[x_b, y_b, e];
* frames (13.1-13.2): e = R e_m, E = m + R C_m - L e; a mounting angle turns both about an axis
  omega_k through m (rz: z, ry: R_z y, rx: R_z R_y x), so dE = omega_k x (E - m), de = omega_k x e.

Shapes: inputs broadcast over leading axes ``(...)`` (designs x points), like the FK. Results
(:class:`FKDerivatives`): ``dE_dp``, ``de_dp`` ``(..., 3, 27)`` with columns in
:data:`arcube.model.design.PARAM_NAMES` order, ``dE_dq``, ``de_dq`` ``(..., 3, 5)`` with columns
(rho_x, rho_y, rho_z, delta_x, delta_y).

Units, per column: E in mm and e dimensionless, per **mm** for the lengths, m and L, and per
**radian** for every angle (o, alpha, beta, the three mounting angles, and the joints), although
design arrays hold angles in degrees: multiply an angle column by pi/180 for "per degree".
The joint columns are J_E (mm/rad) and J_e (1/rad) of model §15.1. The column of d_z is 0: the
z leg's dyad does not move the tool.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.model import frames
from arcube.model.design import INDEX, N_PARAMS, Geometry, unpack
from arcube.model.mechanism import DEFAULT_MODE, inverse_kinematics
from arcube.model.poses import leg_coords
from arcube.model.stages import rts, tls, tms

N_JOINTS = 5
_N = N_PARAMS + N_JOINTS  # every column: the 27 parameters, then the 5 joints
_Q = N_PARAMS  # index of the first joint column


class FKDerivatives(NamedTuple):
    """The pose and its first-order derivatives; every field broadcast to the leading shape ``(...)``.

    NaN where the FK does not assemble (``valid`` false) or sits on a singularity (H_u = 0 or
    det[x_b, y_b, e] = 0).
    """

    E: NDArray[np.float64]  # (..., 3) drill tip in R_w, mm
    e: NDArray[np.float64]  # (..., 3) unit drill axis in R_w
    dE_dp: NDArray[np.float64]  # (..., 3, 27) mm per mm (lengths, m, L) or mm per rad (angles)
    de_dp: NDArray[np.float64]  # (..., 3, 27) per mm or per rad
    dE_dq: NDArray[np.float64]  # (..., 3, 5) mm/rad: J_E of model §15.1
    de_dq: NDArray[np.float64]  # (..., 3, 5) 1/rad: J_e of model §15.1
    valid: NDArray[np.bool_]  # (...) the pose exists (FK assembles, or the IK reaches it)


def mount_axes(g: Geometry) -> NDArray[np.float64]:
    """Rotation axes omega_k ``(..., 3, 3)`` in R_w of the mounting angles (rows: rx, ry, rz), per rad:
    dR/d(angle_k) = [omega_k]x R for R = R_z R_y R_x (model §13.1)."""
    a = np.asarray(g.mount, dtype=float)
    cy, sy, cz, sz = np.cos(a[..., 1]), np.sin(a[..., 1]), np.cos(a[..., 2]), np.sin(a[..., 2])
    zero, one = np.zeros_like(cy), np.ones_like(cy)
    w_rx = np.stack([cz * cy, sz * cy, -sy], axis=-1)  # R_z R_y x
    w_ry = np.stack([-sz, cz, zero], axis=-1)  # R_z y
    w_rz = np.stack([zero, zero, one], axis=-1)
    return np.stack([w_rx, w_ry, w_rz], axis=-2)


def _derivatives(
    g: Geometry,
    C_m: NDArray[np.float64],
    e_m: NDArray[np.float64],
    rho: NDArray[np.float64],
    delta: NDArray[np.float64],
    sigma: NDArray[np.float64],
    valid: NDArray[np.bool_],
) -> FKDerivatives:
    """The derivatives at a closed configuration: C_m, e_m ``(..., 3)`` (mechanism frame), rho ``(..., 3)``,
    delta, sigma ``(..., 2)`` (rad), all consistent (the FK's or the IK's)."""
    lead = np.broadcast_shapes(
        C_m.shape[:-1], e_m.shape[:-1], rho.shape[:-1], delta.shape[:-1], sigma.shape[:-1], np.shape(g.r)
    )
    sr, cr = np.sin(rho), np.cos(rho)
    sd, cd = np.sin(delta), np.cos(delta)
    ss, cs = np.sin(sigma), np.cos(sigma)
    lc = leg_coords(C_m)[..., :2, :]
    v, w = lc[..., 1], lc[..., 2]  # (..., 2): leg x (y, z), leg y (z, x)
    p2, d2, t2, c2 = g.p[..., :2], g.d[..., :2], g.t, g.c
    a_v = v - d2 * sd + t2 * ss  # D of model §7.2
    a_w = w + d2 * cd - t2 * cs - p2 * cr[..., :2]  # E
    F = d2 * (a_v * cd + a_w * sd)
    G = -p2 * a_w * sr[..., :2]
    H = t2 * (a_v * cs + a_w * ss)

    # seeds: for every column j, dC_m (3), the direct part of ½ dPhi_u (2), dlambda_u, dalpha_u, dbeta_u (2 each)
    dC = np.zeros(lead + (3, _N))
    phi = np.zeros(lead + (2, _N))
    seed_lam = np.zeros((2, _N))
    seed_alpha = np.zeros((2, _N))
    seed_beta = np.zeros((2, _N))
    for u in range(3):
        dC[..., u, INDEX[f"f_{'xyz'[u]}"]] = -1.0
        dC[..., u, INDEX[f"p_{'xyz'[u]}"]] = -sr[..., u]
        dC[..., u, _Q + u] = -g.p[..., u] * cr[..., u]
    dC[..., :, INDEX["r"]] = -1.0
    for u, leg in enumerate("xy"):
        phi[..., u, INDEX[f"p_{leg}"]] = -a_w[..., u] * cr[..., u]
        phi[..., u, INDEX[f"d_{leg}"]] = -a_v[..., u] * sd[..., u] + a_w[..., u] * cd[..., u]
        phi[..., u, INDEX[f"c_{leg}"]] = -c2[..., u]
        phi[..., u, INDEX[f"t_{leg}"]] = a_v[..., u] * ss[..., u] - a_w[..., u] * cs[..., u]
        phi[..., u, _Q + u] = -G[..., u]
        phi[..., u, _Q + 3 + u] = -F[..., u]
        seed_lam[u, INDEX[f"o_{leg}"]] = 1.0
        seed_alpha[u, INDEX[f"alpha_{leg}"]] = 1.0
        seed_beta[u, INDEX[f"beta_{leg}"]] = 1.0

    # TMS: ½ dPhi_u = D dv + E dw + phi + H dsigma = 0; leg x (v, w) = (y, z), leg y (v, w) = (z, x)
    dv = np.stack([dC[..., 1, :], dC[..., 2, :]], axis=-2)
    dw = np.stack([dC[..., 2, :], dC[..., 0, :]], axis=-2)
    with np.errstate(divide="ignore", invalid="ignore"):
        dsigma = -(a_v[..., None] * dv + a_w[..., None] * dw + phi) / H[..., None]

    # RTS: u_beta . de = -(du_beta/dlambda . e) dlambda - (du_beta/dalpha . e) dalpha - sin(beta) dbeta
    lam = sigma + g.o
    sl, cl = np.sin(lam), np.cos(lam)
    sa, ca = np.sin(g.alpha), np.cos(g.alpha)
    el = leg_coords(e_m)[..., :2, :]  # (e_u, e_v, e_w) of legs x, y
    ub_lam_e = sa * (cl * el[..., 1] + sl * el[..., 2])  # du_beta/dlambda = sin(a) (cos(l) v + sin(l) w)
    ub_alpha_e = -sa * el[..., 0] + ca * (sl * el[..., 1] - cl * el[..., 2])
    dlam = dsigma + seed_lam
    rhs = -ub_lam_e[..., None] * dlam - ub_alpha_e[..., None] * seed_alpha - np.sin(g.beta)[..., None] * seed_beta
    ub = rts.u_beta(sigma, g.alpha, g.o)
    xb, yb = ub[..., 0, :], ub[..., 1, :]
    det = rts.det_beta(e_m, ub)
    with np.errstate(divide="ignore", invalid="ignore"):
        P_x = np.cross(yb, e_m) / det[..., None]
        P_y = np.cross(e_m, xb) / det[..., None]
    de_m = P_x[..., :, None] * rhs[..., 0:1, :] + P_y[..., :, None] * rhs[..., 1:2, :]

    # to the patient frame: E = m + R C_m - L R e_m, e = R e_m
    R = frames.mount_rotation(g)
    e_w = np.einsum("...ij,...j->...i", R, e_m)
    C_w = np.einsum("...ij,...j->...i", R, C_m) + g.m
    L = np.asarray(g.L, dtype=float)
    E_w = C_w - L[..., None] * e_w
    de = R @ de_m
    dE = R @ dC - L[..., None, None] * de
    for k in range(3):
        dE[..., k, INDEX[f"m_{'xyz'[k]}"]] = 1.0
    omega = mount_axes(g)
    for k, name in enumerate(("mount_rx", "mount_ry", "mount_rz")):
        dE[..., :, INDEX[name]] = np.cross(omega[..., k, :], E_w - g.m)
        de[..., :, INDEX[name]] = np.cross(omega[..., k, :], e_w)
    dE[..., :, INDEX["L"]] = -e_w
    de[..., :, INDEX["L"]] = 0.0

    ok = np.asarray(valid) & np.all(np.isfinite(dE), axis=(-2, -1)) & np.all(np.isfinite(de), axis=(-2, -1))
    dE = np.where(ok[..., None, None], dE, np.nan)
    de = np.where(ok[..., None, None], de, np.nan)
    return FKDerivatives(
        E=np.broadcast_to(E_w, lead + (3,)),
        e=np.broadcast_to(e_w, lead + (3,)),
        dE_dp=dE[..., :_Q],
        de_dp=de[..., :_Q],
        dE_dq=dE[..., _Q:],
        de_dq=de[..., _Q:],
        valid=np.broadcast_to(ok, lead),
    )


def fk_derivatives(params: ArrayLike, rho: ArrayLike, delta: ArrayLike, assembly: ArrayLike) -> FKDerivatives:
    """Derivatives of :func:`arcube.model.mechanism.forward_kinematics` at joints (rho, delta) in an assembly mode.

    Args:
        params: designs ``(..., 27)`` or ``(..., 23)`` (mm, deg).
        rho: crank angles ``(..., 3)`` rad; delta: four-bar inputs ``(..., 2)`` rad.
        assembly: ``(..., 3)`` = (eps_H_x, eps_H_y, eps_P), e.g. :attr:`IKSolution.assembly`.

    Returns:
        :class:`FKDerivatives` (units in the module doc: per mm, or per rad for every angle).
    """
    g = unpack(params)
    asm = np.asarray(assembly, dtype=float)
    rho_a = np.asarray(rho, dtype=float)
    delta_a = np.asarray(delta, dtype=float)
    C_m = tls.fk(rho_a, g.f, g.p, g.r)
    lc = leg_coords(C_m)[..., :2, :]
    sigma, tms_arg = tms.fk(
        lc[..., 1], lc[..., 2], rho_a[..., :2], delta_a, g.p[..., :2], g.d[..., :2], g.c, g.t, asm[..., 0:2]
    )
    e_m, radicand = rts.fk(sigma, g.alpha, g.beta, g.o, asm[..., 2])
    valid = np.all(np.abs(tms_arg) <= 1.0, axis=-1) & (radicand >= 0.0)
    return _derivatives(g, C_m, e_m, rho_a, delta_a, sigma, valid)


def pose_derivatives(params: ArrayLike, E: ArrayLike, e: ArrayLike, mode: ArrayLike = DEFAULT_MODE) -> FKDerivatives:
    """Derivatives of the FK at the joints the IK gives for the pose (E, e) in working mode ``mode``,
    in the assembly mode of that IK solution: what :func:`fk_derivatives` gives at
    ``(sol.rho, sol.delta, sol.assembly)``, computed from the IK's own stage values (no FK pass).

    ``E``, ``e`` ``(..., 3)`` in R_w; ``mode`` ``(..., 4)``; ``valid`` is the IK's reachability.
    """
    sol = inverse_kinematics(params, E, e, mode)
    return _derivatives(unpack(params), sol.E_m, sol.e, sol.rho, sol.delta, sol.sigma, sol.reachable)
