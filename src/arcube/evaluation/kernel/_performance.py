"""Physical performance at the drill tip for one point (model §15), from the kernel's stage terms.

The velocity model A t = B q̇ (7.4) is solved in closed form instead of by a 5x5 solve: its first
three rows give v_C = J_LV ρ̇; the last two give diag(H/J_AS) J_AP ω = M q̇ with
M = [J_rho - J_AV J_LV | J_delta]; the spin-free ω then follows from the dual basis of the rows
q_u = u_beta x e of J_AP inside the plane ⊥ e:

    P_x = (q_y x e) / det,  P_y = (e x q_x) / det,  det = (q_x x q_y) . e = det[x_b, y_b, e],
    J_ω = P_x (J_AS,x / H_x) M_x + P_y (J_AS,y / H_y) M_y.

:mod:`arcube.evaluation.performance` (the NumPy reference, a generic 5x5 solve with an explicit
basis b1, b2) is the oracle: the tests hold the two equal.
"""

from __future__ import annotations

import math

from numba import njit

from arcube.evaluation.kernel._layout import G_L, METRIC_COLUMNS, NAN, O_ENCODER, O_LATERAL_FORCE, O_STIFFNESS, O_THRUST
from arcube.evaluation.kernel._layout import X_AXIAL_ERROR_MM, X_AXIS_ERROR_DEG, X_DEFLECTION_MM, X_LATERAL_ERROR_MM
from arcube.evaluation.kernel._layout import (
    X_HOLDING_TORQUE_ACTUATOR,
    X_HOLDING_TORQUE_NM,
    X_TIP_ERROR_MM,
    X_TORQUE_ACTUATOR,
    X_TORQUE_NM,
)
from arcube.evaluation.kernel._scalar import cross, rot


@njit(cache=True, error_model="numpy")
def _no_metrics(row):
    """The metrics of an unreachable point in an extra row: NaN, and actuators -1."""
    for j in range(METRIC_COLUMNS.shape[0]):
        row[METRIC_COLUMNS[j]] = NAN
    row[X_TORQUE_ACTUATOR] = -1.0
    row[X_HOLDING_TORQUE_ACTUATOR] = -1.0


@njit(cache=True, error_model="numpy")
def _box_maxima(J, eps, e0, e1, e2):
    """max over sign vectors s of |J_E diag(eps) s|, of its part ⊥ e, and of |J_e diag(eps) s|
    (``J`` (2, 3, 5)). s and -s give the same norms, so s_0 = +1 and the 16 others are visited in
    Gray-code order: one sign flips per step, an O(1) update of both sums."""
    a0 = a1 = a2 = b0 = b1 = b2 = 0.0
    for i in range(5):
        a0 += eps[i] * J[0, 0, i]
        a1 += eps[i] * J[0, 1, i]
        a2 += eps[i] * J[0, 2, i]
        b0 += eps[i] * J[1, 0, i]
        b1 += eps[i] * J[1, 1, i]
        b2 += eps[i] * J[1, 2, i]
    tip = lat = axis = 0.0
    for g in range(16):
        if g > 0:
            i = 1
            while not (g >> (i - 1)) & 1:  # the lowest set bit of g names the column that flips
                i += 1
            gray = g ^ (g >> 1)  # bit i - 1 set: column i now has sign -1
            w = -2.0 * eps[i] if (gray >> (i - 1)) & 1 else 2.0 * eps[i]
            a0 += w * J[0, 0, i]
            a1 += w * J[0, 1, i]
            a2 += w * J[0, 2, i]
            b0 += w * J[1, 0, i]
            b1 += w * J[1, 1, i]
            b2 += w * J[1, 2, i]
        n = a0 * a0 + a1 * a1 + a2 * a2
        d = a0 * e0 + a1 * e1 + a2 * e2
        m = b0 * b0 + b1 * b1 + b2 * b2
        if n > tip:
            tip = n
        if n - d * d > lat:
            lat = n - d * d
        if m > axis:
            axis = m
    return math.sqrt(tip), math.sqrt(lat), math.sqrt(axis)


@njit(cache=True, error_model="numpy")
def _tip_metrics(g, tls, tms, rts, opt, J, row):
    """Write the metrics of one point to its extra row ``row`` (the ``X_*`` columns of the PointResults
    fields tip_error_mm .. deflection_mm; the holding torque's NaN and -1, which ``_masses`` overwrites
    when it is on), from the point's stage values ``tls``, ``tms``, ``rts`` (:mod:`~arcube.evaluation.kernel._state`)
    with the loads of the option vector ``opt``: encoder (rad), thrust, lateral force (N),
    stiffness (N·mm/rad); ``J``: (2, 3, 5) work buffer, filled with (J_E, J_e) in R_w."""
    em0, em1, em2 = rts.em0, rts.em1, rts.em2
    xb0, xb1, xb2, yb0, yb1, yb2 = rts.xb0, rts.xb1, rts.xb2, rts.yb0, rts.yb1, rts.yb2
    pcr0, pcr1, pcr2 = tls.pcr0, tls.pcr1, tls.pcr2
    # J_AP rows q = u_beta x e (mechanism axes)
    qx0, qx1, qx2 = cross(xb0, xb1, xb2, em0, em1, em2)
    qy0, qy1, qy2 = cross(yb0, yb1, yb2, em0, em1, em2)
    det = (qx1 * qy2 - qx2 * qy1) * em0 + (qx2 * qy0 - qx0 * qy2) * em1 + (qx0 * qy1 - qx1 * qy0) * em2
    px0 = (qy1 * em2 - qy2 * em1) / det
    px1 = (qy2 * em0 - qy0 * em2) / det
    px2 = (qy0 * em1 - qy1 * em0) / det
    py0 = (em1 * qx2 - em2 * qx1) / det
    py1 = (em2 * qx0 - em0 * qx2) / det
    py2 = (em0 * qx1 - em1 * qx0) / det
    rx = rts.jas0 / tms.H0
    ry = rts.jas1 / tms.H1
    # rows M_x, M_y of M = [J_rho - J_AV J_LV | J_delta], J_LV = diag(-p cos rho)
    mx = (rx * tms.G0, rx * tms.D0 * pcr1, rx * tms.E0 * pcr2, rx * tms.F0, 0.0)
    my = (ry * tms.E1 * pcr0, ry * tms.G1, ry * tms.D1 * pcr2, 0.0, ry * tms.F1)
    lv = (-pcr0, -pcr1, -pcr2)
    L = g[G_L]
    e0, e1, e2 = rot(g, em0, em1, em2)
    for i in range(5):
        # column i of J_C and J_ω (mechanism axes), then to R_w
        c0 = lv[0] if i == 0 else 0.0
        c1 = lv[1] if i == 1 else 0.0
        c2 = lv[2] if i == 2 else 0.0
        w0 = px0 * mx[i] + py0 * my[i]
        w1 = px1 * mx[i] + py1 * my[i]
        w2 = px2 * mx[i] + py2 * my[i]
        c0, c1, c2 = rot(g, c0, c1, c2)
        w0, w1, w2 = rot(g, w0, w1, w2)
        x0 = e1 * w2 - e2 * w1  # e x ω-column
        x1 = e2 * w0 - e0 * w2
        x2 = e0 * w1 - e1 * w0
        J[0, 0, i] = c0 + L * x0
        J[0, 1, i] = c1 + L * x1
        J[0, 2, i] = c2 + L * x2
        J[1, 0, i] = -x0
        J[1, 1, i] = -x1
        J[1, 2, i] = -x2
    eps = opt[O_ENCODER : O_ENCODER + 5]
    F_t = opt[O_THRUST]
    F_l = opt[O_LATERAL_FORCE]
    k = opt[O_STIFFNESS : O_STIFFNESS + 5]
    tip, lat, axis = _box_maxima(J, eps, e0, e1, e2)
    row[X_TIP_ERROR_MM] = tip
    row[X_LATERAL_ERROR_MM] = lat
    row[X_AXIS_ERROR_DEG] = math.degrees(axis)
    axial = 0.0
    torque = -1.0
    which = -1.0
    p0 = p1 = p2 = 0.0  # P_perp C_E e
    s00 = s11 = s22 = s01 = s02 = s12 = 0.0  # P_perp C_E P_perp
    for i in range(5):
        a = e0 * J[0, 0, i] + e1 * J[0, 1, i] + e2 * J[0, 2, i]
        l0 = J[0, 0, i] - a * e0
        l1 = J[0, 1, i] - a * e1
        l2 = J[0, 2, i] - a * e2
        axial += eps[i] * abs(a)
        tau = (F_t * abs(a) + F_l * math.sqrt(l0 * l0 + l1 * l1 + l2 * l2)) / 1000.0
        if tau > torque:
            torque = tau
            which = float(i)
        c = 1.0 / k[i]
        p0 += l0 * a * c
        p1 += l1 * a * c
        p2 += l2 * a * c
        s00 += l0 * l0 * c
        s11 += l1 * l1 * c
        s22 += l2 * l2 * c
        s01 += l0 * l1 * c
        s02 += l0 * l2 * c
        s12 += l1 * l2 * c
    # eigenvalues of the PSD S with e in its null space: 0, and the roots of x^2 - tr x + m2
    tr = s00 + s11 + s22
    m2 = (s00 * s11 - s01 * s01) + (s00 * s22 - s02 * s02) + (s11 * s22 - s12 * s12)
    half = 0.5 * tr
    lam = half + math.sqrt(max(half * half - m2, 0.0))
    row[X_AXIAL_ERROR_MM] = axial
    torque = torque if torque == torque and torque >= 0.0 else math.nan
    row[X_TORQUE_NM] = torque
    row[X_TORQUE_ACTUATOR] = which if torque == torque else -1.0
    row[X_DEFLECTION_MM] = F_t * math.sqrt(p0 * p0 + p1 * p1 + p2 * p2) + F_l * lam
    row[X_HOLDING_TORQUE_NM] = NAN
    row[X_HOLDING_TORQUE_ACTUATOR] = -1.0
