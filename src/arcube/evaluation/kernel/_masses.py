"""The holding torque of model §18.2 at one point, from the kernel's stage terms and the forward Jacobian.

dV/dq = -(1/1000) sum_b m_b g^T J_b, J_b the Jacobian (mm/rad) of body b's centre of mass
(:mod:`arcube.evaluation.mass_bodies`, the NumPy reference, builds all 65 bodies' Jacobians). g is constant,
so the sum collapses by how the bodies move; in mechanism coordinates (G = R^T g), with the rates of
the centre J_C = diag(-p_u cos rho_u) (its only columns are the rho columns: the TLS of model §7.1)
and of the drill axis J_e (from ``_performance``'s J_e, turned by R^T), column j of g^T sum m J is

    W_j = M_C G.J_C,j + M_e G.J_e,j + sum_u s_u sigma_dot_u,j + [j = rho_u] c_D,u G.dD_u
          + [j = delta_u] c_K,u G.dK_u + (the z dyad),

* M_C: every mass that moves with the centre: the platform triangle, the output links, half the
  couplers (their T end), all 48 chords (a chord's midpoint is C + r (a v1 + b v2), a, b its ends'
  mean slerp coefficients), the drill motor, the z dyad's share at Q_z;
* M_e: the beta chords' share along e (r sum_k b_k mu) and the motor at C + (r + L_m / 2) e;
* sigma_dot_u = -(u_beta . J_e) / J_AS,u (differentiating Eq 4), with s_u = the share of u_beta's
  rate (û x u_beta: the alpha chords' b and the beta chords' a sums) and of T_u's (û x (T_u - Q_u):
  half the coupler, half the output link);
* dD_u = -p_u (cos rho_u û + sin rho_u ŵ) in the rho_u column only (half the crank, the input link and
  half the coupler through K_u, the delta actuator); dK_u = d_u (cos delta_u v̂ + sin delta_u ŵ) in the
  delta_u column only (half the input link and half the coupler);
* the z dyad where it closes: its elbow's rate solves (J - D).dJ = (J - D).dD_z, (J - Q).dJ = (J - Q).dC,
  ẑ.dJ = ẑ.dC, so G.dJ = y . rhs with M^T y = G (Cramer's rule; NaN where M is singular, as the
  reference); where it does not close both its rods lie on D_z -> Q_z.

Then |tau_i|max = |dV/dq_i - F_t e^T J_E,i / 1000| + F_l |P_perp J_E,i| / 1000 (N m), its maximum and the
first actuator that attains it. About 200 flops a point, against the reference's 65 bodies x 2 ends x 3 x 5.
"""

from __future__ import annotations

import math

from numba import njit

from arcube.evaluation.kernel._layout import G_ARC_A, G_ARC_B, G_ARC_CHORD, G_C, G_D, G_F, G_P, G_R, G_T, NAN
from arcube.evaluation.kernel._layout import (
    O_GRAVITY,
    O_LATERAL_FORCE,
    O_LINK_MASS,
    O_M_DELTA,
    O_M_MOTOR,
    O_MOTOR_LENGTH,
    O_THRUST,
)
from arcube.evaluation.kernel._layout import X_HOLDING_TORQUE_ACTUATOR, X_HOLDING_TORQUE_NM
from arcube.evaluation.kernel._scalar import rot, rot_t, z_link

_SQRT2 = math.sqrt(2.0)


@njit(cache=True, error_model="numpy")
def _dyad(g, cz, C0, C1, C2, pcr2, sr2, G0, G1, G2, dz1, dz2):
    """The z dyad's elbow where it closes: (closes, y0 (J - D).dD_z, h_x, h_y, h_z) with h = y1 (J - Q) + y2 ẑ,
    so that G.dJ = y0 (J - D).dD_z [rho_z column] + h . J_C (module doc); dD_z = (0, dz1, dz2), the rho_z
    column of D_z's rate; NaN where M is singular."""
    d2, p2, f2, r = g[G_D + 2], g[G_P + 2], g[G_F + 2], g[G_R]
    D1, D2 = pcr2, -f2 - p2 * sr2  # D_z = (0, p cos rho, -f - p sin rho)
    q0, q1, q2 = C0, C1 - D1, (C2 + r) - D2  # Q_z - D_z, Q_z = C + r ẑ
    Lz = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2)
    if not (Lz > 0.0 and abs(d2 - cz) <= Lz <= d2 + cz):
        return False, 0.0, 0.0, 0.0, 0.0
    along = (d2 * d2 - cz * cz + Lz * Lz) / (2.0 * Lz)
    height = math.sqrt(max(d2 * d2 - along * along, 0.0))
    u0, u1, u2 = q0 / Lz, q1 / Lz, q2 / Lz
    a0, a1, a2 = along * u0 - height * u1, along * u1 + height * u0, along * u2  # J - D (elbow sign +1)
    b0, b1, b2 = a0 - q0, a1 - q1, a2 - q2  # J - Q
    det = a0 * b1 - a1 * b0  # [J - D, J - Q, ẑ]
    if not (det != 0.0 and math.isfinite(det)):
        return True, NAN, NAN, NAN, NAN
    y0 = (G0 * b1 - G1 * b0) / det
    y1 = (a0 * G1 - a1 * G0) / det
    y2 = (G0 * (a1 * b2 - a2 * b1) + G1 * (a2 * b0 - a0 * b2) + G2 * (a0 * b1 - a1 * b0)) / det
    return True, y0 * (a1 * dz1 + a2 * dz2), y1 * b0, y1 * b1, y1 * b2 + y2


@njit(cache=True, error_model="numpy")
def _holding_torque(g, opt, tls, tms, rts, J, row):
    """Write the holding torque (N m) and its actuator to the extra row ``row`` of a point whose tip metrics
    ``_performance._tip_metrics`` just computed (``J`` (2, 3, 5): J_E, J_e in R_w). The point's stage values
    ``tls``, ``tms``, ``rts`` (:mod:`~arcube.evaluation.kernel._state`) in mechanism coordinates: the centre C,
    sines and cosines of rho, delta and sigma (p cos rho as ``pcr``), u_beta of legs x and y, J_AS, the drill axis e."""
    pcr0, pcr1, pcr2 = tls.pcr0, tls.pcr1, tls.pcr2
    sr0, sr1, sr2 = tls.sr0, tls.sr1, tls.sr2
    xb0, xb1, xb2, yb0, yb1, yb2 = rts.xb0, rts.xb1, rts.xb2, rts.yb0, rts.yb1, rts.yb2
    lam, md, mm, Lm = opt[O_LINK_MASS], opt[O_M_DELTA], opt[O_M_MOTOR], opt[O_MOTOR_LENGTH]
    G0, G1, G2 = rot_t(g, opt[O_GRAVITY], opt[O_GRAVITY + 1], opt[O_GRAVITY + 2])
    p0, p1, p2 = g[G_P], g[G_P + 1], g[G_P + 2]
    d0, d1, d2 = g[G_D], g[G_D + 1], g[G_D + 2]
    c0, c1, t0, t1, r = g[G_C], g[G_C + 1], g[G_T], g[G_T + 1], g[G_R]
    cz = z_link(g, opt)
    # one chord's mass (kg) of the links alpha_x, alpha_y, beta_x, beta_y, and the chords' slerp sums (no array temporaries)
    lr2 = 2.0 * r * lam
    mu0, mu1, mu2, mu3 = (
        lr2 * g[G_ARC_CHORD],
        lr2 * g[G_ARC_CHORD + 1],
        lr2 * g[G_ARC_CHORD + 2],
        lr2 * g[G_ARC_CHORD + 3],
    )
    closes, jd, h0, h1, h2 = _dyad(g, cz, tls.C0, tls.C1, tls.C2, pcr2, sr2, G0, G1, G2, -p2 * sr2, -pcr2)
    half_z = lam * cz / 2.0 if closes else lam * (d2 + cz) / 2.0  # the dyad's share at Q_z (moves with C) and at D_z
    M_C = (
        (((lam * (c0 + c1) / 2.0 + lam * (t0 + t1)) + 3.0 * lam * _SQRT2 * r) + 12.0 * (mu0 + mu1 + mu2 + mu3))
        + mm
        + half_z
    )
    M_e = r * (mu2 * g[G_ARC_B + 2] + mu3 * g[G_ARC_B + 3]) + mm * (r + Lm / 2.0)
    s_x = (G2 * xb1 - G1 * xb2) * r * (mu0 * g[G_ARC_B] + mu2 * g[G_ARC_A + 2]) + t0 * (
        rts.cs0 * G1 + rts.ss0 * G2
    ) * lam * (c0 + t0) / 2.0
    s_y = (G0 * yb2 - G2 * yb0) * r * (mu1 * g[G_ARC_B + 1] + mu3 * g[G_ARC_A + 3]) + t1 * (
        rts.cs1 * G2 + rts.ss1 * G0
    ) * lam * (c1 + t1) / 2.0
    kx, ky = -s_x / rts.jas0, -s_y / rts.jas1  # times u_beta . J_e: the sigma_dot terms
    elbow = lam * (d2 + cz) / 2.0 if closes else 0.0  # the elbow's rods (the rods' Q_z ends are in M_C)
    gD0 = (
        (lam * p0 / 2.0 + lam * d0 + lam * c0 / 2.0 + md) * -(pcr0 * G0 + p0 * sr0 * G2)
        - M_C * G0 * pcr0
        - elbow * h0 * pcr0
    )
    gD1 = (
        (lam * p1 / 2.0 + lam * d1 + lam * c1 / 2.0 + md) * -(pcr1 * G1 + p1 * sr1 * G0)
        - M_C * G1 * pcr1
        - elbow * h1 * pcr1
    )
    gD2 = (
        (lam * p2 / 2.0 + (lam * d2 / 2.0 if closes else half_z)) * -(p2 * sr2 * G1 + pcr2 * G2)
        - M_C * G2 * pcr2
        + elbow * (jd - h2 * pcr2)
    )
    gK3 = lam * (d0 + c0) / 2.0 * d0 * (tms.cd0 * G1 + tms.sd0 * G2)
    gK4 = lam * (d1 + c1) / 2.0 * d1 * (tms.cd1 * G2 + tms.sd1 * G0)
    e0, e1, e2 = rot(g, rts.em0, rts.em1, rts.em2)
    F_t, F_l = opt[O_THRUST], opt[O_LATERAL_FORCE]
    best = -1.0
    which = -1.0
    finite = True
    for j in range(5):
        w0, w1, w2 = rot_t(g, J[1, 0, j], J[1, 1, j], J[1, 2, j])  # J_e column j, mechanism axes
        W = (
            M_e * (G0 * w0 + G1 * w1 + G2 * w2)
            + kx * (xb0 * w0 + xb1 * w1 + xb2 * w2)
            + ky * (yb0 * w0 + yb1 * w1 + yb2 * w2)
        )
        W += gD0 if j == 0 else (gD1 if j == 1 else (gD2 if j == 2 else (gK3 if j == 3 else gK4)))
        a = e0 * J[0, 0, j] + e1 * J[0, 1, j] + e2 * J[0, 2, j]
        l0, l1, l2 = J[0, 0, j] - a * e0, J[0, 1, j] - a * e1, J[0, 2, j] - a * e2
        tau = abs(-W / 1000.0 - F_t * a / 1000.0) + F_l * math.sqrt(l0 * l0 + l1 * l1 + l2 * l2) / 1000.0
        if not math.isfinite(tau):
            finite = False
        elif tau > best:
            best = tau
            which = float(j)
    row[X_HOLDING_TORQUE_NM] = best if finite else NAN
    row[X_HOLDING_TORQUE_ACTUATOR] = which if finite else -1.0
