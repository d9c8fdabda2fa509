"""Compiled evaluation kernel (Numba): :func:`evaluate_task_numba` == :func:`arcube.evaluation.evaluate_task`.

One fused pass per (design, point): TLS IK (Eq 1), RTS IK (MODEL.md 5.2), TMS IK (4.2), the
seven condition numbers by the closed forms of 8.1, the local guards of 8.2 and the graded
excess of 12.2. A design's points then get the global ``single_assembly_mode`` guard and the
summaries (w_G, eta_G, violation, dexterity statistics). Designs run in parallel (``prange``,
Numba's default thread count); when there are fewer than two designs per thread, the points
are split into chunks instead. With ``want_points=False`` no designs x points array exists.

Agreement with the NumPy reference. The code repeats the reference's operations in its order
(sums left to right, ``einsum``'s (p0 + p2) + p1, NumPy's pairwise summation over points, the
Python/NumPy float modulo of the angle wrap, the same NaN/inf conventions), with two kinds of
shortcut in the default (fast) path, each exact in real arithmetic:

* TLS: cos(rho) = sqrt((1 - arg)(1 + arg)) and sin(rho) = -arg instead of cos/sin(-asin(arg));
* TMS: R = sqrt(A^2 + B^2) instead of hypot(A, B); cos(delta), sin(delta) from the angle sum
  delta = atan2(B, A) + eps acos(arg), i.e. ((A arg - eps B s) / R, (B arg + eps A s) / R)
  with s = sqrt(1 - arg^2); the delta output is atan2(sin delta, cos delta), mapped to [-pi, pi).

That saves ~15 libm calls per point (the RTS, which depends on the drill direction only, is
computed once per run of equal directions, i.e. once per trajectory). The results then differ
from the reference by rounding only: ~1e-13 relative at ordinary points, growing like
eps * kappa and eps / (1 - arg^2) near a singularity or a TMS limit, which is also how much the
reference itself moves between NumPy builds (AVX-512 NumPy uses SVML for arcsin, arccos and
arctan2, one ulp away from libm). ``exact=True`` evaluates every trigonometric function as the
reference does: bit for bit equal to a NumPy that uses libm (e.g. ``NPY_DISABLE_CPU_FEATURES=
"X86_V4 AVX512_ICL"``), ~2x slower.
"""

from __future__ import annotations

import math
import time

import numpy as np
from numba import get_num_threads, njit, prange
from numpy.typing import ArrayLike

from arcube.design import N_PARAMS
from arcube.evaluation import _EXCESS_CAP, FAILURES, Options, PointResults, TaskResults
from arcube.evaluation import evaluate_task as _evaluate_task_numpy
from arcube.mechanism import DEFAULT_MODE

__all__ = ["evaluate_task_numba", "warm_up"]

_PI = math.pi
_TWO_PI = 2.0 * math.pi
_CAP = float(_EXCESS_CAP)
_BIG = float(np.finfo(np.float64).max)
_INF = math.inf
_NAN = math.nan

_CODE_SINGULAR = FAILURES.index("singular/J_LV") + 1  # 8 .. 14 in JACOBIAN_NAMES order
_CODE_Z_DYAD = FAILURES.index("guard/z_dyad") + 1
_CODE_RHO = FAILURES.index("guard/rho_max") + 1
_CODE_TRANS = FAILURES.index("guard/transmission") + 1
_CODE_KAPPA = FAILURES.index("guard/kappa_max") + 1
_CODE_SAM = FAILURES.index("guard/single_assembly_mode") + 1
assert FAILURES[:7] == ("TLS/x", "TLS/y", "TLS/z", "RTS/x", "RTS/y", "TMS/x", "TMS/y")

# Layout of the per-design geometry rows built by _geometry (mm, rad, trig of the angles).
_G_M, _G_F, _G_P, _G_D, _G_C, _G_T, _G_R, _G_O = 0, 3, 6, 9, 12, 14, 16, 17
_G_SA, _G_CA, _G_CB, _G_SB = 19, 21, 23, 25
_N_GEO = 27

# Layout of the option vector built by _option_vector.
_O_ZDYAD, _O_CZ, _O_RHO_ON, _O_RHO, _O_TR_ON, _O_TR, _O_KM_ON, _O_KM, _O_SAM, _O_EXACT = range(10)

# Layout of the per-design summary rows.
_S_NBAD, _S_RF, _S_ETAG, _S_VIOL, _S_DMIN, _S_DMEAN, _S_DMAX = range(7)
_N_SUMM = 7

_CHUNK = 64
"""Points per tile when a few designs are split over threads."""


# --------------------------------------------------------------------------- scalar helpers


@njit(cache=True, error_model="numpy")
def _wrap(x):
    """(x + pi) % (2 pi) - pi with Python/NumPy modulo semantics (result in [-pi, pi))."""
    return (x + _PI) % _TWO_PI - _PI


@njit(cache=True, error_model="numpy")
def _arg(C, R):
    """C/R where R > 0; +inf where R = 0 (no direction solves it); NaN where R is NaN (an
    upstream stage failed: the argument is undefined and never counts as an excess)."""
    if R > 0.0:
        return C / R
    if R == 0.0:
        return _INF
    return _NAN


@njit(cache=True, error_model="numpy")
def _harmonic(A, B, C, eps):
    """stages.solve_harmonic for scalars: (x wrapped, arg = C/R); x NaN where |arg| > 1."""
    R = math.hypot(A, B)
    arg = _arg(C, R)
    if abs(arg) <= 1.0:
        x = _wrap(math.atan2(B, A) + eps * math.acos(arg))
    else:
        x = _NAN
    return x, arg


@njit(cache=True, error_model="numpy")
def _kdiag2(a, b):
    """indices.kappa_diag for two entries: NaN if any is NaN, +inf if the smaller is 0."""
    a = abs(a)
    b = abs(b)
    if a != a or b != b:
        return _NAN
    lo = a if a < b else b
    hi = a if a > b else b
    if lo > 0.0:
        return hi / lo
    return _INF


@njit(cache=True, error_model="numpy")
def _kdiag3(a, b, c):
    a = abs(a)
    b = abs(b)
    c = abs(c)
    if a != a or b != b or c != c:
        return _NAN
    lo = min(a, b, c)
    hi = max(a, b, c)
    if lo > 0.0:
        return hi / lo
    return _INF


@njit(cache=True, error_model="numpy")
def _kinv(F, g):
    """indices.kappa_from_invariants for scalars."""
    g = abs(g)
    t = F * F - 4.0 * g * g
    if t != t:
        root = _NAN
    else:
        root = math.sqrt(t if t >= 0.0 else 0.0)
    k = (F + root) / (2.0 * g)
    if g > 0.0:
        if k >= 1.0 or k != k:
            return k
        return 1.0
    if g != g:
        return _NAN
    return _INF


@njit(cache=True, error_model="numpy")
def _clip_excess(a):
    """One term of evaluation._excess: min(max(|a| - 1, 0), cap), NaN -> 0."""
    x = abs(a) - 1.0
    if x != x:
        return 0.0
    if x < 0.0:
        return 0.0
    if x > _CAP:
        return _CAP
    return x


@njit(cache=True, error_model="numpy")
def _nan_to_num(x):
    if x != x:
        return 0.0
    if x == _INF:
        return _BIG
    if x == -_INF:
        return -_BIG
    return x


@njit(cache=True, error_model="numpy")
def _pos(x):
    """np.maximum(x, 0.0) (NaN propagates)."""
    if x >= 0.0 or x != x:
        return x
    return 0.0


@njit(cache=True, error_model="numpy")
def _block_sum(a, lo, n):
    """NumPy's pairwise_sum for n <= 128 (8 accumulators, then the tail)."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r0 = a[lo]
    r1 = a[lo + 1]
    r2 = a[lo + 2]
    r3 = a[lo + 3]
    r4 = a[lo + 4]
    r5 = a[lo + 5]
    r6 = a[lo + 6]
    r7 = a[lo + 7]
    i = 8
    lim = n - n % 8
    while i < lim:
        j = lo + i
        r0 += a[j]
        r1 += a[j + 1]
        r2 += a[j + 2]
        r3 += a[j + 3]
        r4 += a[j + 4]
        r5 += a[j + 5]
        r6 += a[j + 6]
        r7 += a[j + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@njit(cache=True, error_model="numpy")
def _pairwise_sum(a):
    """0.0 + NumPy's pairwise_sum of a 1-D float array, i.e. ``np.sum(a)`` bit for bit.

    NumPy recurses: n <= 128 is a block, else split at n2 = n//2 - (n//2) % 8. Done here with
    an explicit stack (post-order), so no recursion in compiled code.
    """
    n = a.shape[0]
    if n <= 128:
        return 0.0 + _block_sum(a, 0, n)
    # frames: lo, n, state (0 = new, 1 = left done), partial (left result)
    los = np.empty(64, np.int64)
    ns = np.empty(64, np.int64)
    states = np.zeros(64, np.int64)
    partial = np.zeros(64)
    top = 0
    los[0] = 0
    ns[0] = n
    states[0] = 0
    ret = 0.0
    have_ret = False
    while top >= 0:
        lo = los[top]
        nn = ns[top]
        if have_ret:
            # a child just returned `ret`
            if states[top] == 0:
                partial[top] = ret
                states[top] = 1
                have_ret = False
                n2 = nn // 2
                n2 -= n2 % 8
                top += 1
                los[top] = lo + n2
                ns[top] = nn - n2
                states[top] = 0
                continue
            ret = partial[top] + ret
            top -= 1
            continue
        if nn <= 128:
            ret = _block_sum(a, lo, nn)
            have_ret = True
            top -= 1
            continue
        n2 = nn // 2
        n2 -= n2 % 8
        top += 1
        los[top] = lo
        ns[top] = n2
        states[top] = 0
    return 0.0 + ret


# --------------------------------------------------------------------------- the kernel


@njit(cache=True, error_model="numpy")
def _tms_leg(v, w, pcr, sr, ss, cs, p, d, c, t, eps, want_delta, exact):
    """TMS IK (Eq 3) and the Jacobian terms of one leg; pcr = p cos(rho), sr = sin(rho).

    Returns delta, arg, F, G, D (= a_v), E (= a_w), H, as stages.tms.ik / jacobian_terms.
    Fast path: cos(delta) and sin(delta) from the angle sum delta = phi + eps psi with
    cos(phi) = A/R, sin(phi) = B/R, cos(psi) = arg, sin(psi) = sqrt(1 - arg^2) (no libm call;
    eps must be +-1); delta itself = atan2(sin, cos) only when ``want_delta`` (else NaN).
    ``exact``: hypot, atan2 + eps acos wrapped, sin and cos, as the reference.
    """
    a = v + t * ss
    b = (w - t * cs) - pcr
    A = (2.0 * d) * b
    B = (-2.0 * d) * a
    C = ((c * c - a * a) - b * b) - d * d
    R = math.hypot(A, B) if exact else math.sqrt(A * A + B * B)
    arg = _arg(C, R)
    if not abs(arg) <= 1.0:
        return _NAN, arg, _NAN, _NAN, _NAN, _NAN, _NAN
    if exact:
        delta = _wrap(math.atan2(B, A) + eps * math.acos(arg))
        sd = math.sin(delta)
        cd = math.cos(delta)
    else:
        es = eps * math.sqrt((1.0 - arg) * (1.0 + arg))
        cd = (A * arg - B * es) / R
        sd = (B * arg + A * es) / R
        if want_delta:
            # atan2 gives (-pi, pi]; the reference wraps to [-pi, pi)
            delta = math.atan2(sd, cd)
            if delta == _PI:
                delta = -_PI
        else:
            delta = _NAN
    av = (v - d * sd) + t * ss
    aw = ((w + d * cd) - t * cs) - pcr
    F = d * (av * cd + aw * sd)
    G = ((-p) * aw) * sr
    H = t * (av * cs + aw * ss)
    return delta, arg, F, G, av, aw, H


@njit(cache=True, error_model="numpy")
def _tls_leg(u, f, r, p, want_rho, exact):
    """TLS IK (Eq 1) of one leg: (arg, rho, cos rho, sin rho), NaN angles where |arg| > 1.

    Fast path: cos(rho) = sqrt((1 - arg)(1 + arg)), sin(rho) = -arg (rho = -asin(arg)), no libm
    call; rho itself only if ``want_rho``. At |arg| = 1 exactly, cos(asin(arg)) as the reference
    evaluates it (6e-17, not 0: the reference does not call that point singular).
    ``exact``: cos and sin of rho, as the reference.
    """
    arg = ((u + f) + r) / p
    if not abs(arg) <= 1.0:
        return arg, _NAN, _NAN, _NAN
    if exact:
        rho = -math.asin(arg)
        return arg, rho, math.cos(rho), math.sin(rho)
    rho = -math.asin(arg) if want_rho else _NAN
    if abs(arg) == 1.0:
        return arg, rho, math.cos(math.asin(arg)), -arg
    return arg, rho, math.sqrt((1.0 - arg) * (1.0 + arg)), -arg


@njit(cache=True, error_model="numpy")
def _design_points(i, k0, k1, geo, modes, E, e, same_e, opt, full,
                   fail, eta, exc, code, kappa_o, rho_o, delta_o, sigma_o):  # fmt: skip
    """Points k0..k1-1 of design i: writes failure (before the global guard), eta_raw, excess,
    assembly code into the rows fail/eta/exc/code, and the detailed fields when ``full``."""
    g = geo[i]
    m0, m1, m2 = g[_G_M], g[_G_M + 1], g[_G_M + 2]
    f0, f1, f2 = g[_G_F], g[_G_F + 1], g[_G_F + 2]
    p0, p1, p2 = g[_G_P], g[_G_P + 1], g[_G_P + 2]
    d0, d1, d2 = g[_G_D], g[_G_D + 1], g[_G_D + 2]
    c0, c1 = g[_G_C], g[_G_C + 1]
    t0, t1 = g[_G_T], g[_G_T + 1]
    r = g[_G_R]
    o0, o1 = g[_G_O], g[_G_O + 1]
    sa0, sa1 = g[_G_SA], g[_G_SA + 1]
    ca0, ca1 = g[_G_CA], g[_G_CA + 1]
    cb0, cb1 = g[_G_CB], g[_G_CB + 1]
    sb0, sb1 = g[_G_SB], g[_G_SB + 1]
    epsT0, epsT1, epsR0, epsR1 = modes[i, 0], modes[i, 1], modes[i, 2], modes[i, 3]

    z_dyad = opt[_O_ZDYAD] != 0.0
    cz = opt[_O_CZ]
    if cz != cz:
        cz = d2
    rho_on = opt[_O_RHO_ON] != 0.0
    rho_th = opt[_O_RHO]
    tr_on = opt[_O_TR_ON] != 0.0
    s0 = opt[_O_TR]
    km_on = opt[_O_KM_ON] != 0.0
    km = opt[_O_KM]
    exact = opt[_O_EXACT] != 0.0
    need_rho = full or rho_on
    # per-design constants of the guards
    reach_z = d2 + cz
    gap_z = abs(d2 - cz)
    nF0 = d0 * c0
    nF1 = d1 * c1
    nH0 = t0 * c0
    nH1 = t1 * c1
    nAS0 = sa0 * sb0
    nAS1 = sa1 * sb1
    nAP = sb0 * sb1

    # RTS cache (depends on the direction only)
    have = False
    sig0 = sig1 = rarg0 = rarg1 = 0.0
    ss0 = cs0 = ss1 = cs1 = 0.0
    jas0 = jas1 = det = kAS = kAP = 0.0

    for k in range(k0, k1):
        if not (have and same_e[k]):
            have = True
            e0, e1, e2 = e[k, 0], e[k, 1], e[k, 2]
            # leg x: (e_u, e_v, e_w) = (e0, e1, e2)
            lam, rarg0 = _harmonic((-sa0) * e2, sa0 * e1, cb0 - ca0 * e0, epsR0)
            sig0 = _wrap(lam - o0)
            lam2 = sig0 + o0
            xb0 = ca0 + 0.0 * lam2
            xb1 = sa0 * math.sin(lam2)
            xb2 = (-sa0) * math.cos(lam2)
            # leg y: (e_u, e_v, e_w) = (e1, e2, e0); local (u, v, w) -> world (y, z, x)
            lam, rarg1 = _harmonic((-sa1) * e0, sa1 * e2, cb1 - ca1 * e1, epsR1)
            sig1 = _wrap(lam - o1)
            lam2 = sig1 + o1
            yb1 = ca1 + 0.0 * lam2
            yb2 = sa1 * math.sin(lam2)
            yb0 = (-sa1) * math.cos(lam2)
            if sig0 == sig0:
                ss0 = math.sin(sig0)
                cs0 = math.cos(sig0)
            else:
                ss0 = cs0 = _NAN
            if sig1 == sig1:
                ss1 = math.sin(sig1)
                cs1 = math.cos(sig1)
            else:
                ss1 = cs1 = _NAN
            # J_AS = (u_alpha x u_beta) . e, as np.cross + einsum
            jas0 = ((0.0 * xb2 - 0.0 * xb1) * e0 + (xb1 - 0.0 * xb0) * e2) + (0.0 * xb0 - xb2) * e1
            jas1 = ((yb2 - 0.0 * yb1) * e0 + (0.0 * yb1 - yb0) * e2) + (0.0 * yb0 - 0.0 * yb2) * e1
            # J_AP rows u_beta x e
            q0 = xb1 * e2 - xb2 * e1
            q1 = xb2 * e0 - xb0 * e2
            q2 = xb0 * e1 - xb1 * e0
            q3 = yb1 * e2 - yb2 * e1
            q4 = yb2 * e0 - yb0 * e2
            q5 = yb0 * e1 - yb1 * e0
            F_ap = ((((q0 * q0 + q1 * q1) + q2 * q2) + q3 * q3) + q4 * q4) + q5 * q5
            # det[x_b, y_b, e] = (x_b x y_b) . e; NumPy's einsum sums 3 products as (p0 + p2) + p1
            det = ((xb1 * yb2 - xb2 * yb1) * e0 + (xb0 * yb1 - xb1 * yb0) * e2) + (xb2 * yb0 - xb0 * yb2) * e1
            kAS = _kdiag2(jas0, jas1)
            kAP = _kinv(F_ap, abs(det))

        # TLS (Eq 1)
        Em0 = E[k, 0] - m0
        Em1 = E[k, 1] - m1
        Em2 = E[k, 2] - m2
        ta0, rho0, cr0, sr0 = _tls_leg(Em0, f0, r, p0, need_rho, exact)
        ta1, rho1, cr1, sr1 = _tls_leg(Em1, f1, r, p1, need_rho, exact)
        ta2, rho2, cr2, sr2 = _tls_leg(Em2, f2, r, p2, need_rho, exact)
        pcr0 = p0 * cr0
        pcr1 = p1 * cr1
        pcr2 = p2 * cr2

        # TMS (Eq 3): leg x (v, w) = (y, z), leg y (v, w) = (z, x)
        del0, marg0, F0, G0, D0, E0, H0 = _tms_leg(Em1, Em2, pcr0, sr0, ss0, cs0, p0, d0, c0, t0, epsT0, full, exact)
        del1, marg1, F1, G1, D1, E1, H1 = _tms_leg(Em2, Em0, pcr1, sr1, ss1, cs1, p1, d1, c1, t1, epsT1, full, exact)

        # stage failures, in FAILURES order
        fc = 0
        if abs(ta0) > 1.0:
            fc = 1
        elif abs(ta1) > 1.0:
            fc = 2
        elif abs(ta2) > 1.0:
            fc = 3
        elif abs(rarg0) > 1.0:
            fc = 4
        elif abs(rarg1) > 1.0:
            fc = 5
        elif not (abs(marg0) <= 1.0):
            fc = 6
        elif not (abs(marg1) <= 1.0):
            fc = 7
        stages_ok = fc == 0

        ex = ((0.0 + _clip_excess(ta0)) + _clip_excess(ta1)) + _clip_excess(ta2)
        ex = ex + ((0.0 + _clip_excess(rarg0)) + _clip_excess(rarg1))
        ex = ex + ((0.0 + _clip_excess(marg0)) + _clip_excess(marg1))

        eta_raw = _INF
        if stages_ok:
            k_lv = _kdiag3(pcr0, pcr1, pcr2)  # |-p cos rho|
            F_av = ((D0 * D0 + E0 * E0) + E1 * E1) + D1 * D1
            g_av = math.sqrt(((D0 * E1) * (D0 * E1) + (E0 * E1) * (E0 * E1)) + (D0 * D1) * (D0 * D1))
            k_av = _kinv(F_av, g_av)
            k_sg = _kdiag2(H0, H1)
            k_rh = _kdiag2(G0, G1)
            k_dl = _kdiag2(F0, F1)
            # eta_raw = max over kappa with NaN -> inf; singular = first non-finite kappa
            eta_raw = 0.0
            sing = 0
            for j in range(7):
                if j == 0:
                    kj = k_lv
                elif j == 1:
                    kj = k_av
                elif j == 2:
                    kj = k_sg
                elif j == 3:
                    kj = kAS
                elif j == 4:
                    kj = kAP
                elif j == 5:
                    kj = k_rh
                else:
                    kj = k_dl
                if full:
                    kappa_o[i, k, j] = kj
                if not math.isfinite(kj):
                    if sing == 0:
                        sing = _CODE_SINGULAR + j
                    if kj != kj:
                        kj = _INF
                if kj > eta_raw:
                    eta_raw = kj
            fc = sing
            # local guards, in FAILURES order; their shortfalls add to the excess
            if z_dyad:
                L = math.hypot(Em0, Em1 - pcr2)
                short = (_pos(L - reach_z) + _pos(gap_z - L)) / reach_z
                if short > 0.0 and fc == 0:
                    fc = _CODE_Z_DYAD
                ex = ex + _nan_to_num(short)
            if rho_on:
                short = ((0.0 + _pos(abs(rho0) - rho_th)) + _pos(abs(rho1) - rho_th)) + _pos(abs(rho2) - rho_th)
                if short > 0.0 and fc == 0:
                    fc = _CODE_RHO
                ex = ex + _nan_to_num(short)
            if tr_on:
                short = 0.0 + _pos(s0 - abs(F0 / nF0))
                short += _pos(s0 - abs(F1 / nF1))
                short += _pos(s0 - abs(H0 / nH0))
                short += _pos(s0 - abs(H1 / nH1))
                short += _pos(s0 - abs(jas0 / nAS0))
                short += _pos(s0 - abs(jas1 / nAS1))
                short += _pos(s0 - abs(det / nAP))
                if short > 0.0 and fc == 0:
                    fc = _CODE_TRANS
                ex = ex + _nan_to_num(short)
            if km_on:
                short = _pos(eta_raw - km) / km
                if short > _CAP:
                    short = _CAP
                if eta_raw > km and fc == 0:
                    fc = _CODE_KAPPA
                ex = ex + _nan_to_num(short)
        elif full:
            for j in range(7):
                kappa_o[i, k, j] = _NAN

        fail[k] = fc
        eta[k] = eta_raw
        exc[k] = ex
        code[k] = (4 if H0 > 0.0 else 0) + (2 if H1 > 0.0 else 0) + (1 if det > 0.0 else 0)
        if full:
            rho_o[i, k, 0] = rho0
            rho_o[i, k, 1] = rho1
            rho_o[i, k, 2] = rho2
            delta_o[i, k, 0] = del0
            delta_o[i, k, 1] = del1
            sigma_o[i, k, 0] = sig0
            sigma_o[i, k, 1] = sig1


@njit(cache=True, error_model="numpy")
def _finalize(sam, fail, eta, exc, code, dex, summ):
    """Global guard, then eta_L, dexterity and the summaries of one design (rows of length P)."""
    n = fail.shape[0]
    if sam:
        counts = np.zeros(8, np.int64)
        for k in range(n):
            if fail[k] == 0:
                counts[code[k]] += 1
        ref = 0
        for c in range(1, 8):
            if counts[c] > counts[ref]:
                ref = c
        for k in range(n):
            if fail[k] == 0 and code[k] != ref:
                fail[k] = _CODE_SAM
    n_bad = 0
    dmin = _INF
    dmax = -_INF
    for k in range(n):
        if fail[k] == 0:
            dk = 100.0 / eta[k]
        else:
            n_bad += 1
            eta[k] = _INF
            dk = 0.0
        dex[k] = dk
        if dk < dmin:
            dmin = dk
        if dk > dmax:
            dmax = dk
    frac_bad = n_bad / n
    summ[_S_NBAD] = n_bad
    summ[_S_RF] = 1.0 - frac_bad
    if n_bad == 0:
        summ[_S_ETAG] = _pairwise_sum(eta) / n
        summ[_S_VIOL] = 0.0
    else:
        summ[_S_ETAG] = _INF
        summ[_S_VIOL] = frac_bad + _pairwise_sum(exc)
    summ[_S_DMIN] = dmin
    summ[_S_DMEAN] = _pairwise_sum(dex) / n
    summ[_S_DMAX] = dmax


@njit(cache=True, parallel=True, error_model="numpy")
def _kernel(geo, modes, E, e, same_e, opt, full, split, chunk,
            fail_o, eta_o, exc_o, dex_o, code_o, kappa_o, rho_o, delta_o, sigma_o, summ):  # fmt: skip
    """All designs x all points. With ``split`` (or ``full``), the per-point rows live in the
    (D, P) arrays; otherwise each design works in rows of its own (no D x P temporaries)."""
    n_des = geo.shape[0]
    n_pts = E.shape[0]
    sam = opt[_O_SAM] != 0.0
    if split:
        n_chunk = (n_pts + chunk - 1) // chunk
        for tile in prange(n_des * n_chunk):
            i = tile // n_chunk
            k0 = (tile % n_chunk) * chunk
            k1 = min(n_pts, k0 + chunk)
            _design_points(i, k0, k1, geo, modes, E, e, same_e, opt, full,
                           fail_o[i], eta_o[i], exc_o[i], code_o[i], kappa_o, rho_o, delta_o, sigma_o)  # fmt: skip
        for i in prange(n_des):
            _finalize(sam, fail_o[i], eta_o[i], exc_o[i], code_o[i], dex_o[i], summ[i])
    elif full:
        for i in prange(n_des):
            _design_points(i, 0, n_pts, geo, modes, E, e, same_e, opt, full,
                           fail_o[i], eta_o[i], exc_o[i], code_o[i], kappa_o, rho_o, delta_o, sigma_o)  # fmt: skip
            _finalize(sam, fail_o[i], eta_o[i], exc_o[i], code_o[i], dex_o[i], summ[i])
    else:
        for i in prange(n_des):
            fail = np.empty(n_pts, np.int16)
            eta = np.empty(n_pts)
            exc = np.empty(n_pts)
            code = np.empty(n_pts, np.int8)
            dex = np.empty(n_pts)
            _design_points(i, 0, n_pts, geo, modes, E, e, same_e, opt, full,
                           fail, eta, exc, code, kappa_o, rho_o, delta_o, sigma_o)  # fmt: skip
            _finalize(sam, fail, eta, exc, code, dex, summ[i])


# --------------------------------------------------------------------------- Python side


def _owned(a: np.ndarray) -> np.ndarray:
    """C-contiguous, writeable float64 (one compiled signature: Numba types read-only arrays apart)."""
    c = np.ascontiguousarray(a, dtype=np.float64)
    return c if c.flags.writeable else c.copy()


def _geometry(params: np.ndarray) -> np.ndarray:
    """Per-design rows (D, 27): lengths, offsets in rad and the trig of alpha, beta, computed
    with the same NumPy operations as arcube.design.unpack and the stage modules."""
    x = params
    o = np.deg2rad(x[:, 17:19])
    alpha = np.deg2rad(x[:, 19:21])
    beta = np.deg2rad(x[:, 21:23])
    geo = np.empty((x.shape[0], _N_GEO))
    geo[:, 0:17] = x[:, 0:17]
    geo[:, _G_O : _G_O + 2] = o
    geo[:, _G_SA : _G_SA + 2] = np.sin(alpha)
    geo[:, _G_CA : _G_CA + 2] = np.cos(alpha)
    geo[:, _G_CB : _G_CB + 2] = np.cos(beta)
    geo[:, _G_SB : _G_SB + 2] = np.sin(beta)
    return geo


def _option_vector(options: Options, exact: bool = False) -> np.ndarray:
    """The guards as numbers, thresholds computed as evaluation._guard_checks computes them."""
    opt = np.zeros(10)
    opt[_O_ZDYAD] = float(options.z_dyad)
    opt[_O_CZ] = np.nan if options.c_z is None else float(options.c_z)
    if options.rho_max_deg is not None:
        opt[_O_RHO_ON] = 1.0
        opt[_O_RHO] = np.deg2rad(options.rho_max_deg)
    if options.min_transmission_deg is not None:
        opt[_O_TR_ON] = 1.0
        opt[_O_TR] = np.sin(np.deg2rad(options.min_transmission_deg))
    if options.kappa_max is not None:
        opt[_O_KM_ON] = 1.0
        opt[_O_KM] = float(options.kappa_max)
    opt[_O_SAM] = float(options.single_assembly_mode)
    opt[_O_EXACT] = float(exact)
    return opt


def evaluate_task_numba(
    params: ArrayLike, E: ArrayLike, e: ArrayLike, mode: ArrayLike = DEFAULT_MODE,
    options: Options = Options(), want_points: bool = True, *, exact: bool = False,
) -> TaskResults:  # fmt: skip
    """Same results as :func:`arcube.evaluation.evaluate_task`, compiled (see the module doc).

    ``params`` ``(..., 23)`` mm/deg; ``E``, ``e`` ``(P, 3)``; ``mode`` broadcasting as ``(..., 4)``;
    results ``(batch..., P)`` per point and ``(batch...)`` per design, batch being the broadcast
    of ``params[..., :]`` and ``mode[..., :]``'s leading axes.
    With ``want_points=False`` the result's ``points`` is None (only the summaries are computed,
    with no designs x points arrays); the summaries are identical either way.
    ``exact=True`` evaluates every trigonometric function as the reference does (slower).
    E or e not 2-D, no points or no designs: handed to the NumPy reference.
    """
    p = np.asarray(params, dtype=float)
    m = np.asarray(mode, dtype=float)
    E_a = np.asarray(E, dtype=float)
    e_a = np.asarray(e, dtype=float)
    if p.ndim < 1 or p.shape[-1] != N_PARAMS:
        raise ValueError(f"design array must have last axis {N_PARAMS}, got shape {p.shape}")
    if m.ndim < 1 or m.shape[-1] != 4:
        raise ValueError(f"mode must have last axis 4, got shape {m.shape}")
    if E_a.ndim != 2 or e_a.ndim != 2 or E_a.shape[-1] != 3 or e_a.shape[-1] != 3:
        return _evaluate_task_numpy(p, E_a, e_a, m, options)
    E_b, e_b = np.broadcast_arrays(E_a, e_a)
    batch = np.broadcast_shapes(p.shape[:-1], m.shape[:-1])
    n_des = math.prod(batch)
    n_pts = E_b.shape[0]
    if n_pts == 0 or n_des == 0:
        return _evaluate_task_numpy(p, E_a, e_a, m, options)

    pf = _owned(np.broadcast_to(p, batch + (N_PARAMS,)).reshape(n_des, N_PARAMS))
    mf = _owned(np.broadcast_to(m, batch + (4,)).reshape(n_des, 4))
    Ec = _owned(E_b)
    ec = _owned(e_b)
    same_e = np.zeros(n_pts, dtype=np.bool_)
    bits = ec.view(np.int64)  # bitwise: -0.0 and 0.0 may take different RTS branches
    same_e[1:] = np.all(bits[1:] == bits[:-1], axis=-1)
    geo = _geometry(pf)
    # the fast path's angle-sum identities hold for signs only; other values (meaningless,
    # but accepted by the reference) take the reference's formulas
    exact = exact or not bool(np.all(np.abs(mf) == 1.0))
    opt = _option_vector(options, exact)

    n_threads = get_num_threads()
    split = n_des < 2 * n_threads and n_pts >= 2 * _CHUNK
    full = bool(want_points)
    rows = full or split
    shp = (n_des, n_pts) if rows else (1, 1)
    fail = np.empty(shp, np.int16)
    eta = np.empty(shp)
    exc = np.empty(shp)
    dex = np.empty(shp)
    code = np.empty(shp, np.int8)
    if full:
        kappa = np.empty((n_des, n_pts, 7))
        rho = np.empty((n_des, n_pts, 3))
        delta = np.empty((n_des, n_pts, 2))
        sigma = np.empty((n_des, n_pts, 2))
    else:
        kappa = np.empty((1, 1, 7))
        rho = np.empty((1, 1, 3))
        delta = np.empty((1, 1, 2))
        sigma = np.empty((1, 1, 2))
    summ = np.empty((n_des, _N_SUMM))
    _kernel(geo, mf, Ec, ec, same_e, opt, full, split, _CHUNK,
            fail, eta, exc, dex, code, kappa, rho, delta, sigma, summ)  # fmt: skip

    n_bad = summ[:, _S_NBAD].astype(np.int64)
    out_shape = batch + (n_pts,)
    points = None
    if full:
        points = PointResults(
            reachable=(fail == 0).reshape(out_shape),
            failure=fail.reshape(out_shape),
            kappa=kappa.reshape(out_shape + (7,)),
            eta_L=eta.reshape(out_shape),
            dexterity_pct=dex.reshape(out_shape),
            excess=exc.reshape(out_shape),
            rho=rho.reshape(out_shape + (3,)),
            delta=delta.reshape(out_shape + (2,)),
            sigma=sigma.reshape(out_shape + (2,)),
        )

    def summary(col: int) -> np.ndarray:
        return summ[:, col].reshape(batch)

    return TaskResults(
        points=points,  # type: ignore[arg-type]
        w_G=(n_bad == 0).reshape(batch),
        reachable_fraction=summary(_S_RF),
        eta_G=summary(_S_ETAG),
        violation=summary(_S_VIOL),
        dexterity_min=summary(_S_DMIN),
        dexterity_mean=summary(_S_DMEAN),
        dexterity_max=summary(_S_DMAX),
    )


def warm_up() -> float:
    """Compile (or load from the on-disk cache) the kernel on a tiny input; returns the seconds it took."""
    t0 = time.perf_counter()
    from arcube.design import PAPER_TABLE2, PARAM_NAMES

    x = np.array([PAPER_TABLE2[n] for n in PARAM_NAMES])
    E = np.array([[-50.0, 10.0, 0.0], [-40.0, 20.0, 5.0]])
    e = np.array([[0.0, 0.0, 1.0], [0.0, 0.6, 0.8]])
    evaluate_task_numba(np.stack([x, x]), E, e, DEFAULT_MODE, Options(), want_points=True)
    evaluate_task_numba(x, E, e, DEFAULT_MODE, Options(), want_points=False)
    return time.perf_counter() - t0
