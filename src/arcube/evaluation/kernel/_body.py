"""The body of one design at one point (model §14.1), as primitives in the patient frame.

Fills ``lines`` (23, 2, 3): the 18 segments then the 5 actuator points (zero-length segments), in
the order of :data:`arcube.model.body.PRIMITIVES`, and ``arcs`` (4, 2, 3): unit start and end
directions of the spherical links about the centre ``arc_c`` (3,), from the joint values of the
per-point pass (mechanism coordinates, model §3-6), mapped by the mounting rotation and m.
"""

from __future__ import annotations

import math

from numba import njit

from arcube.evaluation.kernel._layout import G_D, G_F, G_M, G_P, G_R, G_T
from arcube.evaluation.kernel._scalar import rot

# _put, _dir and _seg are inlined where they are called (numba IR): their integer indices are constants, and a call
# with constants compiles a specialization for each value (46 of _put alone), a fifth of the kernel's compile time.


@njit(cache=True, error_model="numpy", inline="always")
def _put(g, out, i, j, x0, x1, x2):
    """out[i, j] = m + R x: a point from mechanism to patient coordinates (model §13.1)."""
    y0, y1, y2 = rot(g, x0, x1, x2)
    out[i, j, 0] = y0 + g[G_M]
    out[i, j, 1] = y1 + g[G_M + 1]
    out[i, j, 2] = y2 + g[G_M + 2]


@njit(cache=True, error_model="numpy", inline="always")
def _dir(g, out, i, j, x0, x1, x2):
    """out[i, j] = R x: a direction from mechanism to patient axes."""
    y0, y1, y2 = rot(g, x0, x1, x2)
    out[i, j, 0] = y0
    out[i, j, 1] = y1
    out[i, j, 2] = y2


@njit(cache=True, error_model="numpy", inline="always")
def _seg(g, lines, i, a0, a1, a2, b0, b1, b2):
    _put(g, lines, i, 0, a0, a1, a2)
    _put(g, lines, i, 1, b0, b1, b2)


@njit(cache=True, error_model="numpy")
def _body_world(g, c_z, motor_length, tls, tms, rts, lines, arcs, arc_c):
    """Fill ``lines``, ``arcs``, ``arc_c`` (see the module doc) from the point's stage values ``tls``, ``tms``,
    ``rts`` (:mod:`~arcube.evaluation.kernel._state`: the centre C, the axis e, the joint angles' sines and cosines,
    u_beta of legs x and y, in R_m); returns the arcs' radius r."""
    C0, C1, C2 = tls.C0, tls.C1, tls.C2
    e0, e1, e2 = rts.em0, rts.em1, rts.em2
    f0, f1, f2 = g[G_F], g[G_F + 1], g[G_F + 2]
    p0, p1, p2 = g[G_P], g[G_P + 1], g[G_P + 2]
    d0, d1, d2 = g[G_D], g[G_D + 1], g[G_D + 2]
    t0, t1 = g[G_T], g[G_T + 1]
    r = g[G_R]
    cz = c_z
    # TLS: P_u = -f_u u, D_u = P_u + p_u (-sin rho u + cos rho w); Q_u = C + r u
    Dx0, Dx1, Dx2 = -f0 - p0 * tls.sr0, 0.0, p0 * tls.cr0
    Dy0, Dy1, Dy2 = p1 * tls.cr1, -f1 - p1 * tls.sr1, 0.0
    Dz0, Dz1, Dz2 = 0.0, p2 * tls.cr2, -f2 - p2 * tls.sr2
    Qx0, Qx1, Qx2 = C0 + r, C1, C2
    Qy0, Qy1, Qy2 = C0, C1 + r, C2
    Qz0, Qz1, Qz2 = C0, C1, C2 + r
    # TMS: K = D + d n(delta), T = Q + t n(sigma), n(phi) = sin phi v - cos phi w
    Kx0, Kx1, Kx2 = Dx0, Dx1 + d0 * tms.sd0, Dx2 - d0 * tms.cd0
    Ky0, Ky1, Ky2 = Dy0 - d1 * tms.cd1, Dy1, Dy2 + d1 * tms.sd1
    Tx0, Tx1, Tx2 = Qx0, Qx1 + t0 * rts.ss0, Qx2 - t0 * rts.cs0
    Ty0, Ty1, Ty2 = Qy0 - t1 * rts.cs1, Qy1, Qy2 + t1 * rts.ss1
    # z dyad elbow (model §6 and 14.1: on the z_m x (Q_z - D_z) side); open: D_z -> Q_z
    q0 = Qz0 - Dz0
    q1 = Qz1 - Dz1
    q2 = Qz2 - Dz2
    Lz = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2)
    if Lz > 0.0 and abs(d2 - cz) <= Lz <= d2 + cz:
        along = (d2 * d2 - cz * cz + Lz * Lz) / (2.0 * Lz)
        height = math.sqrt(max(d2 * d2 - along * along, 0.0))
        u0 = q0 / Lz
        u1 = q1 / Lz
        u2 = q2 / Lz
        J0 = Dz0 + along * u0 - height * u1
        J1 = Dz1 + along * u1 + height * u0
        J2 = Dz2 + along * u2
    else:
        J0, J1, J2 = Qz0, Qz1, Qz2
    # RTS: B_u = C + r u_beta, H = C + r e, motor end H + L_m e
    H0, H1, H2 = C0 + r * e0, C1 + r * e1, C2 + r * e2
    M0, M1, M2 = H0 + motor_length * e0, H1 + motor_length * e1, H2 + motor_length * e2
    _seg(g, lines, 0, 0.0, 0.0, 0.0, -f0, 0.0, 0.0)
    _seg(g, lines, 1, 0.0, 0.0, 0.0, 0.0, -f1, 0.0)
    _seg(g, lines, 2, 0.0, 0.0, 0.0, 0.0, 0.0, -f2)
    _seg(g, lines, 3, -f0, 0.0, 0.0, Dx0, Dx1, Dx2)
    _seg(g, lines, 4, 0.0, -f1, 0.0, Dy0, Dy1, Dy2)
    _seg(g, lines, 5, 0.0, 0.0, -f2, Dz0, Dz1, Dz2)
    _seg(g, lines, 6, Dx0, Dx1, Dx2, Kx0, Kx1, Kx2)
    _seg(g, lines, 7, Dy0, Dy1, Dy2, Ky0, Ky1, Ky2)
    _seg(g, lines, 8, Kx0, Kx1, Kx2, Tx0, Tx1, Tx2)
    _seg(g, lines, 9, Ky0, Ky1, Ky2, Ty0, Ty1, Ty2)
    _seg(g, lines, 10, Qx0, Qx1, Qx2, Tx0, Tx1, Tx2)
    _seg(g, lines, 11, Qy0, Qy1, Qy2, Ty0, Ty1, Ty2)
    _seg(g, lines, 12, Dz0, Dz1, Dz2, J0, J1, J2)
    _seg(g, lines, 13, J0, J1, J2, Qz0, Qz1, Qz2)
    _seg(g, lines, 14, Qx0, Qx1, Qx2, Qy0, Qy1, Qy2)
    _seg(g, lines, 15, Qy0, Qy1, Qy2, Qz0, Qz1, Qz2)
    _seg(g, lines, 16, Qz0, Qz1, Qz2, Qx0, Qx1, Qx2)
    _seg(g, lines, 17, H0, H1, H2, M0, M1, M2)
    _seg(g, lines, 18, -f0, 0.0, 0.0, -f0, 0.0, 0.0)
    _seg(g, lines, 19, 0.0, -f1, 0.0, 0.0, -f1, 0.0)
    _seg(g, lines, 20, 0.0, 0.0, -f2, 0.0, 0.0, -f2)
    _seg(g, lines, 21, Dx0, Dx1, Dx2, Dx0, Dx1, Dx2)
    _seg(g, lines, 22, Dy0, Dy1, Dy2, Dy0, Dy1, Dy2)
    # arcs: alpha_x, alpha_y (u -> u_beta), beta_x, beta_y (u_beta -> e), unit directions in R_w
    _dir(g, arcs, 0, 0, 1.0, 0.0, 0.0)
    _dir(g, arcs, 0, 1, rts.xb0, rts.xb1, rts.xb2)
    _dir(g, arcs, 1, 0, 0.0, 1.0, 0.0)
    _dir(g, arcs, 1, 1, rts.yb0, rts.yb1, rts.yb2)
    _dir(g, arcs, 2, 0, rts.xb0, rts.xb1, rts.xb2)
    _dir(g, arcs, 2, 1, e0, e1, e2)
    _dir(g, arcs, 3, 0, rts.yb0, rts.yb1, rts.yb2)
    _dir(g, arcs, 3, 1, e0, e1, e2)
    c0, c1, c2 = rot(g, C0, C1, C2)
    arc_c[0] = c0 + g[G_M]
    arc_c[1] = c1 + g[G_M + 1]
    arc_c[2] = c2 + g[G_M + 2]
    return r
