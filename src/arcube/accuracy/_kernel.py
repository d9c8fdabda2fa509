"""Compiled first-order budget (Numba): :func:`first_order_numba` == :func:`arcube.accuracy.first_order.first_order`.

Long module: the compiled twin of :mod:`arcube.accuracy.first_order` reads top to bottom as it does, one step per function.

Per point, in one pass: the IK of model §3-5 (at the centre C, mechanism frame), the derivatives of
the FK with respect to the 27 parameters and 5 joints (the implicit differentiation of
:mod:`arcube.model.sensitivity`, written out for one point), the source columns G_E, G_e, and the
worst cases, RMS and shares of model §20.3 (the zonogon's farthest vertex by an angle sort).
Points run one after the other: 300 take ~7 ms, and a serial kernel compiles in a third less time
than a ``prange`` one and loads from the cache without starting a thread pool.

Functions an evaluation kernel can call per point (item "robust design" of issue 31), all ``njit``:

* :func:`point_jacobians` (geometry row, the IK's C_m, e_m and sines/cosines as an :class:`IKPoint` -> G ``(2, 3, n)``);
* :func:`point_budget` (G, e, T, sigma -> worst lateral, worst axis, worst axial, RMS lateral, shares);
* :func:`lateral_errors` (both, from the IK's values one by one: -> (lateral_error_wc, lateral_error_rms), mm).

Their inputs are plain arrays made in Python once per design: :func:`geometry_rows` (the design's
dimensions, rotation, mounting axes) and, from :class:`~arcube.accuracy.settings.ToleranceSettings`,
the tolerances T and sigmas ``(n,)`` with the column map :func:`source_map`. Nothing here reads a
module constant of another module (only this file's own), so Numba's on-disk cache, keyed by this
file, cannot go stale.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from arcube.accuracy.first_order import FirstOrder
from arcube.accuracy.sources import IS_ANGLE, JOINT_COLUMN, PARAM_COLUMN
from arcube.model import frames
from arcube.model.design import PARAM_NAMES, full_params, unpack
from arcube.model.sensitivity import mount_axes

# The geometry row: m(3) f(3) p(3) d_x d_y c(2) t(2) r o(2) alpha(2) beta(2) (rad) R(9, row-major) omega(9: rows rx, ry, rz) L
_M, _F, _P, _D, _C, _T, _R, _O, _AL, _BE, _ROT, _OM, _L = 0, 3, 6, 9, 11, 13, 15, 16, 18, 20, 22, 31, 40
N_GEO = 41
N_COLS = 32  # the 27 parameters (PARAM_NAMES order), then the 5 joints
_PARAM_ORDER = tuple(
    "m_x m_y m_z f_x f_y f_z p_x p_y p_z d_x d_y d_z c_x c_y t_x t_y r o_x o_y"
    " alpha_x alpha_y beta_x beta_y mount_rx mount_ry mount_rz L".split()
)
# the column numbers below are written for this order
assert PARAM_NAMES == _PARAM_ORDER, "arcube.accuracy._kernel: the design parameter order changed"


class IKPoint(NamedTuple):
    """The IK's values at one point that :func:`point_jacobians` reads (as :func:`_ik_point` returns them), in the
    mechanism frame. A namedtuple: Numba passes it as one struct and compiles ``ik.sr0`` to a read of its field."""

    Cm0: float  # the centre C_m (mm)
    Cm1: float
    Cm2: float
    em0: float  # the drill axis e_m
    em1: float
    em2: float
    sr0: float  # sin, cos of rho_x, then of rho_y and rho_z
    cr0: float
    sr1: float
    cr1: float
    sr2: float
    cr2: float
    sd0: float  # sin, cos of delta_x, then of delta_y
    cd0: float
    sd1: float
    cd1: float
    ss0: float  # sin, cos of sigma_x, then of sigma_y
    cs0: float
    ss1: float
    cs1: float


def geometry_rows(params: ArrayLike) -> NDArray[np.float64]:
    """Geometry rows ``(..., N_GEO)`` of designs ``(..., 27)`` (mm, deg): what :func:`point_jacobians` reads."""
    g = unpack(full_params(params))
    parts = [
        g.m,
        g.f,
        g.p,
        g.d[..., :2],
        g.c,
        g.t,
        g.r[..., None],
        g.o,
        g.alpha,
        g.beta,
        frames.mount_rotation(g).reshape(g.r.shape + (9,)),
        mount_axes(g).reshape(g.r.shape + (9,)),
        g.L[..., None],
    ]
    return np.ascontiguousarray(np.concatenate(parts, axis=-1), dtype=np.float64)


def source_map(
    param_column: ArrayLike, joint_column: ArrayLike, is_angle: ArrayLike
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """(column ``(n,)`` into the 32 derivative columns, scale ``(n,)``: pi/180 for a source in degrees, else 1)."""
    pc, jc = np.asarray(param_column), np.asarray(joint_column)
    col = np.where(pc >= 0, pc, 27 + jc).astype(np.int64)
    return col, np.where(np.asarray(is_angle), np.pi / 180.0, 1.0)


@njit(cache=True, error_model="numpy")
def _to_world(geo, a0, a1, a2):
    R = geo[_ROT : _ROT + 9]
    return R[0] * a0 + R[1] * a1 + R[2] * a2, R[3] * a0 + R[4] * a1 + R[5] * a2, R[6] * a0 + R[7] * a1 + R[8] * a2


@njit(cache=True, error_model="numpy")
def _columns(geo, ctx, seeds, cols):
    """Columns of (dE, de) in R_w from each variable's seeds ``(32, 11)``: dC_m (3), the direct part of ½ dPhi_u (2),
    dlambda_u, dalpha_u, dbeta_u (2 each) (:mod:`arcube.model.sensitivity`); ``ctx`` holds the point's constants."""
    av0, aw0, av1, aw1, H0, H1 = ctx[0], ctx[1], ctx[2], ctx[3], ctx[4], ctx[5]
    L = geo[_L]
    for k in range(seeds.shape[0]):
        dC0, dC1, dC2, phi0, phi1 = seeds[k, 0], seeds[k, 1], seeds[k, 2], seeds[k, 3], seeds[k, 4]
        dsx = -(av0 * dC1 + aw0 * dC2 + phi0) / H0  # leg x: (v, w) = (y, z)
        dsy = -(av1 * dC2 + aw1 * dC0 + phi1) / H1  # leg y: (v, w) = (z, x)
        rx = -ctx[6] * (dsx + seeds[k, 5]) - ctx[8] * seeds[k, 7] - ctx[10] * seeds[k, 9]
        ry = -ctx[7] * (dsy + seeds[k, 6]) - ctx[9] * seeds[k, 8] - ctx[11] * seeds[k, 10]
        e0 = ctx[12] * rx + ctx[15] * ry
        e1 = ctx[13] * rx + ctx[16] * ry
        e2 = ctx[14] * rx + ctx[17] * ry
        w0, w1, w2 = _to_world(geo, e0, e1, e2)
        c0, c1, c2 = _to_world(geo, dC0, dC1, dC2)
        cols[0, 0, k] = c0 - L * w0
        cols[0, 1, k] = c1 - L * w1
        cols[0, 2, k] = c2 - L * w2
        cols[1, 0, k] = w0
        cols[1, 1, k] = w1
        cols[1, 2, k] = w2


@njit(cache=True, error_model="numpy")
def point_jacobians(geo, ik, col, scale, ctx, cols, G):
    """G_E = G[0], G_e = G[1] ``(3, n)`` in R_w per source unit, at a point the IK solved: ``ik`` its
    :class:`IKPoint` (the centre C_m and axis e_m in the mechanism frame, sin/cos of rho (3), delta (2) and sigma (2)).
    ``col``, ``scale`` from :func:`source_map`; ``ctx`` ``(18,)`` and ``cols`` ``(2, 3, 32)`` are work buffers.
    Returns False where the derivatives do not exist (H_u = 0 or det[x_b, y_b, e] = 0: a singularity), G then NaN."""
    em0, em1, em2 = ik.em0, ik.em1, ik.em2
    p, d, c, t = geo[_P : _P + 3], geo[_D : _D + 2], geo[_C : _C + 2], geo[_T : _T + 2]
    # TMS coupler terms (model §7.2): a_v = D, a_w = E
    av0 = ik.Cm1 - d[0] * ik.sd0 + t[0] * ik.ss0
    aw0 = ik.Cm2 + d[0] * ik.cd0 - t[0] * ik.cs0 - p[0] * ik.cr0
    av1 = ik.Cm2 - d[1] * ik.sd1 + t[1] * ik.ss1
    aw1 = ik.Cm0 + d[1] * ik.cd1 - t[1] * ik.cs1 - p[1] * ik.cr1
    H0 = t[0] * (av0 * ik.cs0 + aw0 * ik.ss0)
    H1 = t[1] * (av1 * ik.cs1 + aw1 * ik.ss1)
    F0 = d[0] * (av0 * ik.cd0 + aw0 * ik.sd0)
    F1 = d[1] * (av1 * ik.cd1 + aw1 * ik.sd1)
    G0 = -p[0] * aw0 * ik.sr0
    G1 = -p[1] * aw1 * ik.sr1
    # RTS: lambda = sigma + o; u_beta in mechanism axes (leg y's local (u, v, w) is world (y, z, x))
    so0, co0, so1, co1 = math.sin(geo[_O]), math.cos(geo[_O]), math.sin(geo[_O + 1]), math.cos(geo[_O + 1])
    sl0, cl0 = ik.ss0 * co0 + ik.cs0 * so0, ik.cs0 * co0 - ik.ss0 * so0
    sl1, cl1 = ik.ss1 * co1 + ik.cs1 * so1, ik.cs1 * co1 - ik.ss1 * so1
    sa0, ca0, sa1, ca1 = math.sin(geo[_AL]), math.cos(geo[_AL]), math.sin(geo[_AL + 1]), math.cos(geo[_AL + 1])
    xb0, xb1, xb2 = ca0, sa0 * sl0, -sa0 * cl0
    yb0, yb1, yb2 = -sa1 * cl1, ca1, sa1 * sl1
    det = (xb1 * yb2 - xb2 * yb1) * em0 + (xb2 * yb0 - xb0 * yb2) * em1 + (xb0 * yb1 - xb1 * yb0) * em2
    ok = H0 != 0.0 and H1 != 0.0 and det != 0.0
    ctx[0], ctx[1], ctx[2], ctx[3], ctx[4], ctx[5] = av0, aw0, av1, aw1, H0, H1
    ctx[6] = sa0 * (cl0 * em1 + sl0 * em2)  # du_beta/dlambda . e, leg x (e_u, e_v, e_w) = (e0, e1, e2)
    ctx[7] = sa1 * (cl1 * em2 + sl1 * em0)  # leg y: (e1, e2, e0)
    ctx[8] = -sa0 * em0 + ca0 * (sl0 * em1 - cl0 * em2)  # du_beta/dalpha . e
    ctx[9] = -sa1 * em1 + ca1 * (sl1 * em2 - cl1 * em0)
    ctx[10], ctx[11] = math.sin(geo[_BE]), math.sin(geo[_BE + 1])
    ctx[12] = (yb1 * em2 - yb2 * em1) / det  # P_x = (y_b x e) / det
    ctx[13] = (yb2 * em0 - yb0 * em2) / det
    ctx[14] = (yb0 * em1 - yb1 * em0) / det
    ctx[15] = (em1 * xb2 - em2 * xb1) / det  # P_y = (e x x_b) / det
    ctx[16] = (em2 * xb0 - em0 * xb2) / det
    ctx[17] = (em0 * xb1 - em1 * xb0) / det
    seeds = np.zeros((N_COLS, 11))  # rows: the 27 parameters, then the 5 joints; the frame's rows stay 0 here
    seeds[3, 0] = seeds[4, 1] = seeds[5, 2] = -1.0  # f_u (d_z, row 11, does not move the tool: all 0)
    seeds[6, 0], seeds[6, 3] = -ik.sr0, -aw0 * ik.cr0  # p_x: the crank tip's u and w
    seeds[7, 1], seeds[7, 4] = -ik.sr1, -aw1 * ik.cr1  # p_y
    seeds[8, 2] = -ik.sr2  # p_z
    seeds[9, 3] = -av0 * ik.sd0 + aw0 * ik.cd0  # d_x
    seeds[10, 4] = -av1 * ik.sd1 + aw1 * ik.cd1  # d_y
    seeds[12, 3], seeds[13, 4] = -c[0], -c[1]  # c_u
    seeds[14, 3] = av0 * ik.ss0 - aw0 * ik.cs0  # t_x
    seeds[15, 4] = av1 * ik.ss1 - aw1 * ik.cs1  # t_y
    seeds[16, 0] = seeds[16, 1] = seeds[16, 2] = -1.0  # r
    seeds[17, 5], seeds[18, 6] = 1.0, 1.0  # o_u: lambda_u
    seeds[19, 7], seeds[20, 8] = 1.0, 1.0  # alpha_u
    seeds[21, 9], seeds[22, 10] = 1.0, 1.0  # beta_u
    seeds[27, 0], seeds[27, 3] = -p[0] * ik.cr0, -G0  # rho_x
    seeds[28, 1], seeds[28, 4] = -p[1] * ik.cr1, -G1  # rho_y
    seeds[29, 2] = -p[2] * ik.cr2  # rho_z
    seeds[30, 3], seeds[31, 4] = -F0, -F1  # delta_u
    _columns(geo, ctx, seeds, cols)
    # the frame: m, the mounting angles (a rotation about omega_k through m) and L act on (E, e) in R_w
    e0, e1, e2 = _to_world(geo, em0, em1, em2)
    C0, C1, C2 = _to_world(geo, ik.Cm0, ik.Cm1, ik.Cm2)
    L = geo[_L]
    r0, r1, r2 = C0 - L * e0, C1 - L * e1, C2 - L * e2  # E - m
    for k in range(3):
        for i in range(3):
            cols[0, i, k] = 1.0 if i == k else 0.0
            cols[1, i, k] = 0.0
        w0, w1, w2 = geo[_OM + 3 * k], geo[_OM + 3 * k + 1], geo[_OM + 3 * k + 2]
        cols[0, 0, 23 + k] = w1 * r2 - w2 * r1
        cols[0, 1, 23 + k] = w2 * r0 - w0 * r2
        cols[0, 2, 23 + k] = w0 * r1 - w1 * r0
        cols[1, 0, 23 + k] = w1 * e2 - w2 * e1
        cols[1, 1, 23 + k] = w2 * e0 - w0 * e2
        cols[1, 2, 23 + k] = w0 * e1 - w1 * e0
    cols[0, 0, 26], cols[0, 1, 26], cols[0, 2, 26] = -e0, -e1, -e2  # L
    cols[1, 0, 26] = cols[1, 1, 26] = cols[1, 2, 26] = 0.0
    for j in range(col.shape[0]):
        s = scale[j] if ok else math.nan
        for a in range(2):
            for i in range(3):
                G[a, i, j] = cols[a, i, col[j]] * s
    return ok


@njit(cache=True, error_model="numpy")
def _zonogon(hx, hy, ang):
    """max over s in [-1, 1]^n of |sum s_i h_i| (h_i = (hx_i, hy_i)): generators turned into the upper half-plane,
    sorted by angle, vertices by cumulative sums (as :func:`arcube.accuracy.first_order.zonogon_radius`).
    Overwrites hx, hy and ang ``(n,)``."""
    sx = sy = 0.0
    for i in range(hx.shape[0]):
        x, y = hx[i], hy[i]
        if y < 0.0 or (y == 0.0 and x < 0.0):
            x, y = -x, -y
        hx[i], hy[i] = x, y
        ang[i] = math.atan2(y, x)
        sx += x
        sy += y
    vx, vy = -sx, -sy
    best = vx * vx + vy * vy
    for k in np.argsort(ang):
        vx += 2.0 * hx[k]
        vy += 2.0 * hy[k]
        best = max(best, vx * vx + vy * vy)
    return math.sqrt(best)


@njit(cache=True, error_model="numpy")
def point_budget(G, e0, e1, e2, T, sig, hx, hy, ang, share):
    """model §20.3 at one point from G ``(2, 3, n)`` (per source unit), the unit axis e in R_w, the tolerances T
    and sigmas ``(n,)``: returns (worst lateral mm, worst axis deg, worst axial mm, RMS lateral mm) and writes
    each source's share of the lateral variance to ``share`` ``(n,)``. hx, hy, ang ``(n,)``: work buffers."""
    n = T.shape[0]
    # the plane perpendicular to e: as arcube.evaluation.performance.spin_free_basis
    h0, h1 = (0.0, 1.0) if abs(e0) > 0.9 else (1.0, 0.0)
    dot = h0 * e0 + h1 * e1
    a0, a1, a2 = h0 - dot * e0, h1 - dot * e1, -dot * e2
    na = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    a0, a1, a2 = a0 / na, a1 / na, a2 / na
    b0, b1, b2 = e1 * a2 - e2 * a1, e2 * a0 - e0 * a2, e0 * a1 - e1 * a0
    axial = total = 0.0
    for i in range(n):
        gx = a0 * G[0, 0, i] + a1 * G[0, 1, i] + a2 * G[0, 2, i]
        gy = b0 * G[0, 0, i] + b1 * G[0, 1, i] + b2 * G[0, 2, i]
        var = sig[i] * sig[i] * (gx * gx + gy * gy)
        share[i] = var
        total += var
        hx[i], hy[i] = T[i] * gx, T[i] * gy
        axial += T[i] * abs(e0 * G[0, 0, i] + e1 * G[0, 1, i] + e2 * G[0, 2, i])
    lateral = _zonogon(hx, hy, ang)
    for i in range(n):
        hx[i] = T[i] * (a0 * G[1, 0, i] + a1 * G[1, 1, i] + a2 * G[1, 2, i])
        hy[i] = T[i] * (b0 * G[1, 0, i] + b1 * G[1, 1, i] + b2 * G[1, 2, i])
        share[i] = share[i] / total if total > 0.0 else 0.0
    axis = math.degrees(_zonogon(hx, hy, ang))
    return lateral, axis, axial, math.sqrt(total)


@njit(cache=True, error_model="numpy")
def _harmonic(A, B, C, eps):
    """sin, cos of x = atan2(B, A) + eps acos(C / hypot(A, B)) (Eq 3's form), and whether |C / R| <= 1."""
    R = math.hypot(A, B)
    if not R > 0.0 or not abs(C / R) <= 1.0:
        return math.nan, math.nan, False
    x = math.atan2(B, A) + eps * math.acos(C / R)
    return math.sin(x), math.cos(x), True


@njit(cache=True, error_model="numpy")
def _ik_point(geo, mode, E0, E1, E2, e0, e1, e2):
    """IK of model §3-5 at the pose (E, e) in R_w, mechanism frame at the centre C = E + L e:
    (ok, :class:`IKPoint`)."""
    L = geo[_L]
    R = geo[_ROT : _ROT + 9]
    a0, a1, a2 = E0 + L * e0 - geo[_M], E1 + L * e1 - geo[_M + 1], E2 + L * e2 - geo[_M + 2]
    C0, C1, C2 = R[0] * a0 + R[3] * a1 + R[6] * a2, R[1] * a0 + R[4] * a1 + R[7] * a2, R[2] * a0 + R[5] * a1 + R[8] * a2
    m0, m1, m2 = R[0] * e0 + R[3] * e1 + R[6] * e2, R[1] * e0 + R[4] * e1 + R[7] * e2, R[2] * e0 + R[5] * e1 + R[8] * e2
    r = geo[_R]
    g0 = (C0 + geo[_F] + r) / geo[_P]
    g1 = (C1 + geo[_F + 1] + r) / geo[_P + 1]
    g2 = (C2 + geo[_F + 2] + r) / geo[_P + 2]
    ok = abs(g0) <= 1.0 and abs(g1) <= 1.0 and abs(g2) <= 1.0
    cr0, cr1, cr2 = (
        math.sqrt((1.0 - g0) * (1.0 + g0)),
        math.sqrt((1.0 - g1) * (1.0 + g1)),
        math.sqrt((1.0 - g2) * (1.0 + g2)),
    )
    sa0, sa1 = math.sin(geo[_AL]), math.sin(geo[_AL + 1])
    ca0, ca1 = math.cos(geo[_AL]), math.cos(geo[_AL + 1])
    sl0, cl0, ok0 = _harmonic(
        -sa0 * m2, sa0 * m1, math.cos(geo[_BE]) - ca0 * m0, mode[2]
    )  # leg x (e_u, e_v, e_w) = (e0, e1, e2)
    sl1, cl1, ok1 = _harmonic(-sa1 * m0, sa1 * m2, math.cos(geo[_BE + 1]) - ca1 * m1, mode[3])  # leg y: (e1, e2, e0)
    so0, co0, so1, co1 = math.sin(geo[_O]), math.cos(geo[_O]), math.sin(geo[_O + 1]), math.cos(geo[_O + 1])
    ss0, cs0 = sl0 * co0 - cl0 * so0, cl0 * co0 + sl0 * so0  # sigma = lambda - o
    ss1, cs1 = sl1 * co1 - cl1 * so1, cl1 * co1 + sl1 * so1
    d0, d1, t0, t1, p0, p1 = geo[_D], geo[_D + 1], geo[_T], geo[_T + 1], geo[_P], geo[_P + 1]
    a, b = C1 + t0 * ss0, C2 - t0 * cs0 - p0 * cr0  # leg x: (v, w) = (y, z)
    sd0, cd0, ok2 = _harmonic(2.0 * d0 * b, -2.0 * d0 * a, geo[_C] ** 2 - a * a - b * b - d0 * d0, mode[0])
    a, b = C2 + t1 * ss1, C0 - t1 * cs1 - p1 * cr1  # leg y: (v, w) = (z, x)
    sd1, cd1, ok3 = _harmonic(2.0 * d1 * b, -2.0 * d1 * a, geo[_C + 1] ** 2 - a * a - b * b - d1 * d1, mode[1])
    ok = ok and ok0 and ok1 and ok2 and ok3
    return ok, IKPoint(C0, C1, C2, m0, m1, m2, -g0, cr0, -g1, cr1, -g2, cr2, sd0, cd0, sd1, cd1, ss0, cs0, ss1, cs1)


@njit(cache=True, error_model="numpy")
def lateral_errors(
    geo,
    T,
    sig,
    col,
    scale,
    Cm0,
    Cm1,
    Cm2,
    em0,
    em1,
    em2,
    sr0,
    cr0,
    sr1,
    cr1,
    sr2,
    cr2,
    sd0,
    cd0,
    sd1,
    cd1,
    ss0,
    cs0,
    ss1,
    cs1,
    ctx,
    cols,
    G,
    hx,
    hy,
    ang,
    share,
):
    """(lateral_error_wc, lateral_error_rms) in mm at a point an IK solved (the fields of an :class:`IKPoint`, one
    argument each), under tolerances T and sigmas ``(n,)``: what an evaluation kernel needs for the objectives and
    limits ``lateral_error_wc`` and ``lateral_error_rms``. NaN at a singular point. The rest are work buffers:
    ctx (18,), cols (2, 3, 32), G (2, 3, n), hx, hy, ang, share (n,)."""
    ik = IKPoint(Cm0, Cm1, Cm2, em0, em1, em2, sr0, cr0, sr1, cr1, sr2, cr2, sd0, cd0, sd1, cd1, ss0, cs0, ss1, cs1)
    if not point_jacobians(geo, ik, col, scale, ctx, cols, G):
        return math.nan, math.nan
    e0, e1, e2 = _to_world(geo, em0, em1, em2)
    lateral, _, _, rms = point_budget(G, e0, e1, e2, T, sig, hx, hy, ang, share)
    return lateral, rms


@njit(cache=True, error_model="numpy")
def _first_order_points(geo, mode, E, e, T, sig, col, scale, valid, out, share, G):
    """Every point of one design: ``valid`` (P,), ``out`` (P, 4) = worst lateral, worst axis, worst axial, RMS
    lateral; ``share`` (P, n); ``G`` (P, 2, 3, n). NaN where the point is not reached."""
    n = T.shape[0]
    ctx = np.empty(18)
    cols = np.empty((2, 3, N_COLS))
    hx, hy, ang = np.empty(n), np.empty(n), np.empty(n)
    for k in range(E.shape[0]):
        ne = math.sqrt(e[k, 0] ** 2 + e[k, 1] ** 2 + e[k, 2] ** 2)
        e0, e1, e2 = e[k, 0] / ne, e[k, 1] / ne, e[k, 2] / ne
        ok, ik = _ik_point(geo, mode, E[k, 0], E[k, 1], E[k, 2], e0, e1, e2)
        if ok:
            ok = point_jacobians(geo, ik, col, scale, ctx, cols, G[k])
            ok = ok and np.all(np.isfinite(G[k]))
        valid[k] = ok
        if ok:
            lat, axis, axial, rms = point_budget(G[k], e0, e1, e2, T, sig, hx, hy, ang, share[k])
            out[k, 0], out[k, 1], out[k, 2], out[k, 3] = lat, axis, axial, rms
        else:
            out[k, :] = math.nan
            share[k, :] = math.nan
            G[k] = math.nan


def first_order_numba(
    params: ArrayLike, E: ArrayLike, e: ArrayLike, mode: ArrayLike, T: ArrayLike, sigma: ArrayLike
) -> FirstOrder:
    """:func:`arcube.accuracy.first_order.first_order` for one design ``(27,)`` (or 23) at P points ``(P, 3)``, compiled.

    ``mode`` ``(4,)``; ``T``, ``sigma`` ``(n,)`` per source of :data:`arcube.accuracy.sources.SOURCE_NAMES` (mm, deg).
    """
    geo = geometry_rows(np.asarray(params, dtype=float).reshape(-1))
    # writable C-order copies: Numba compiles a function anew for a read-only array (a broadcast view, a constant)
    E_a = np.array(np.asarray(E, dtype=float).reshape(-1, 3), order="C")
    e_a = np.array(np.broadcast_to(np.asarray(e, dtype=float), E_a.shape), order="C")
    T_a = np.array(T, dtype=np.float64, order="C")
    s_a = np.array(sigma, dtype=np.float64, order="C")
    col, scale = source_map(PARAM_COLUMN, JOINT_COLUMN, IS_ANGLE)
    P, n = E_a.shape[0], T_a.shape[0]
    valid = np.empty(P, dtype=np.bool_)
    out = np.empty((P, 4))
    share = np.empty((P, n))
    G = np.empty((P, 2, 3, n))
    mode = np.array(mode, dtype=np.float64)  # as E_a (the working mode is often a module constant)
    _first_order_points(geo, mode, E_a, e_a, T_a, s_a, col, scale, valid, out, share, G)
    return FirstOrder(
        lateral_wc_mm=out[:, 0],
        axis_wc_deg=out[:, 1],
        axial_wc_mm=out[:, 2],
        lateral_rms_mm=out[:, 3],
        share=share,
        G_E=G[:, 0],
        G_e=G[:, 1],
        valid=valid,
    )
