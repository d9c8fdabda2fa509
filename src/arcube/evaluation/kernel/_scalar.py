"""Scalar helpers of the kernel: the stage modules' closed forms for one value, NumPy's summation order,
and the mounting rotation of model §13.1 in its two summation orders (:func:`rot`, :func:`rot_t`)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from arcube.evaluation.kernel._layout import BIG as _BIG
from arcube.evaluation.kernel._layout import EXCESS_CAP as _CAP
from arcube.evaluation.kernel._layout import G_C_Z, G_D, G_FLAT, G_ROT, O_C_Z
from arcube.evaluation.kernel._layout import INF as _INF
from arcube.evaluation.kernel._layout import NAN as _NAN
from arcube.evaluation.kernel._layout import PI as _PI
from arcube.evaluation.kernel._layout import TWO_PI as _TWO_PI


@njit(cache=True, error_model="numpy")
def rot(g, x0, x1, x2):
    """R x, R the mounting rotation of the geometry row ``g`` (model §13.1): mechanism to patient
    axes. Each component is summed left to right, (R_i0 x0 + R_i1 x1) + R_i2 x2, as the body and the
    tip metrics always have; x itself where R = I exactly (``G_FLAT``)."""
    if g[G_FLAT] != 0.0:
        return x0, x1, x2
    R = g[G_ROT : G_ROT + 9]
    return (R[0] * x0 + R[1] * x1 + R[2] * x2, R[3] * x0 + R[4] * x1 + R[5] * x2, R[6] * x0 + R[7] * x1 + R[8] * x2)


@njit(cache=True, error_model="numpy")
def rot_t(g, a0, a1, a2):
    """R^T a (patient to mechanism axes, model §13.1), each component summed (p0 + p2) + p1: the order
    of NumPy's einsum in :func:`arcube.model.frames.to_mechanism` on the build the kernel was written
    against (einsum's order depends on the build: NumPy 2.4 sums left to right there, one ulp away at
    times, within the tests' tolerance). Kept, so that the kernel's results stay the same bits; a itself
    where R = I exactly (``G_FLAT``)."""
    if g[G_FLAT] != 0.0:
        return a0, a1, a2
    R = g[G_ROT : G_ROT + 9]
    return (
        (R[0] * a0 + R[6] * a2) + R[3] * a1,
        (R[1] * a0 + R[7] * a2) + R[4] * a1,
        (R[2] * a0 + R[8] * a2) + R[5] * a1,
    )


@njit(cache=True, error_model="numpy")
def cross(a0, a1, a2, b0, b1, b2):
    """a x b, each component a difference of two products as np.cross computes it."""
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


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
def _term(short, scale):
    """One guard term of model §16: np.minimum(short / scale, 1.0) (NaN propagates)."""
    x = short / scale
    if x > 1.0:
        return 1.0
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
        return 0.0 + _block_sum(a, np.int64(0), n)  # int64, not the constant 0: one specialization (see _driver)
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


@njit(cache=True, error_model="numpy")
def z_link(g, opt):
    """The z dyad's second link c_z (mm) of the geometry row ``g``: the design's own (model §19.1), else
    (NaN) the option's ``Guards.c_z``, else (NaN) d_z, as ``reference.design_c_z``."""
    cz = g[G_C_Z]
    if cz != cz:
        cz = opt[O_C_Z]
    if cz != cz:
        cz = g[G_D + 2]
    return cz
