"""One leg of the TLS (Eq 1) and of the TMS (Eq 3) for one point, as the stage modules compute them."""

from __future__ import annotations

import math

from numba import njit

from arcube.evaluation.kernel._layout import NAN as _NAN
from arcube.evaluation.kernel._layout import PI as _PI
from arcube.evaluation.kernel._scalar import _arg, _wrap


@njit(cache=True, error_model="numpy")
def _tms_leg(v, w, pcr, sr, ss, cs, p, d, c, t, eps, want_delta, exact):
    """TMS IK (Eq 3) and the Jacobian terms of one leg; pcr = p cos(rho), sr = sin(rho).

    Returns delta, arg, F, G, D (= a_v), E (= a_w), H, as stages.tms.ik / jacobian_terms, and cos, sin of delta.
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
        return _NAN, arg, _NAN, _NAN, _NAN, _NAN, _NAN, _NAN, _NAN
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
    return delta, arg, F, G, av, aw, H, cd, sd


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
