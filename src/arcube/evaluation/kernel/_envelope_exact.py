"""Exact pieces of the envelope clearance (model §19.5), compiled, scalars only: the signed distance to an
axis-aligned box, its exact least along a segment, the lowest point of a great-circle arc, and lower bounds of
the box distance along a segment and over a piece of an arc (``_envelope`` prunes with them).

The least along a segment (:func:`_seg_box`) differs from the reference's enumeration of candidates: the
segment is clipped to the box's slabs; where it meets the box, the least of the largest of three linear
functions over the clipped part is at an end of it, where a coordinate of p - c is 0, or where two of the
functions cross; where it misses the box, the squared distance g(t) is convex and C^1 with a piecewise linear
derivative, so the root of g' lies between the two breakpoints (where |p_i - c_i| = a_i) at which g' changes
sign and is found by linear interpolation. Both are exact in real arithmetic; the two engines agree to rounding.
Scalars only: an array passed to a compiled call costs reference counts.
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True, error_model="numpy")
def _box_sd(x, y, z, c0, c1, c2, h0, h1, h2):
    """Signed distance of (x, y, z) to the box |X - c| <= h, in the reference's order of operations."""
    q0 = abs(x - c0) - h0
    q1 = abs(y - c1) - h1
    q2 = abs(z - c2) - h2
    o0 = max(q0, 0.0)
    o1 = max(q1, 0.0)
    o2 = max(q2, 0.0)
    return math.sqrt(o0 * o0 + o1 * o1 + o2 * o2) + min(max(q0, max(q1, q2)), 0.0)


@njit(cache=True, error_model="numpy")
def _at(a, b, d, t):
    """a + t d from the nearer end (t = 0, 1 give a, b exactly), one coordinate."""
    return a + t * d if t <= 0.5 else b - (1.0 - t) * d


@njit(cache=True, error_model="numpy")
def _sd_at(a0, a1, a2, b0, b1, b2, t, c0, c1, c2, h0, h1, h2):
    d0 = b0 - a0
    d1 = b1 - a1
    d2 = b2 - a2
    return _box_sd(_at(a0, b0, d0, t), _at(a1, b1, d1, t), _at(a2, b2, d2, t), c0, c1, c2, h0, h1, h2)


@njit(cache=True, error_model="numpy")
def _slab(u, d, h, t0, t1):
    """Clip [t0, t1] to |u + t d| <= h; returns (t0, t1) (empty when t0 > t1)."""
    if d == 0.0:
        if abs(u) > h:
            return 1.0, 0.0
        return t0, t1
    ta = (-h - u) / d
    tb = (h - u) / d
    return max(t0, min(ta, tb)), min(t1, max(ta, tb))


@njit(cache=True, error_model="numpy")
def _gp(t, u0, u1, u2, d0, d1, d2, h0, h1, h2):
    """Half the derivative of the squared distance to the box along the segment, at t."""
    s = 0.0
    w = u0 + t * d0
    q = abs(w) - h0
    if q > 0.0:
        s += (q if w > 0.0 else -q) * d0
    w = u1 + t * d1
    q = abs(w) - h1
    if q > 0.0:
        s += (q if w > 0.0 else -q) * d1
    w = u2 + t * d2
    q = abs(w) - h2
    if q > 0.0:
        s += (q if w > 0.0 else -q) * d2
    return s


@njit(cache=True, error_model="numpy")
def _bracket(tb, u0, u1, u2, d0, d1, d2, h0, h1, h2, lo, glo, hi, ghi):
    """Narrow the bracket (lo, glo) .. (hi, ghi) of g' = 0 by the breakpoint tb; returns it (lo = hi at a root)."""
    if not (lo < tb < hi):
        return lo, glo, hi, ghi
    g = _gp(tb, u0, u1, u2, d0, d1, d2, h0, h1, h2)
    if g < 0.0:
        return tb, g, hi, ghi
    if g > 0.0:
        return lo, glo, tb, g
    return tb, 0.0, tb, 0.0


@njit(cache=True, error_model="numpy")
def _cand(best, a0, a1, a2, b0, b1, b2, t, t0, t1, c0, c1, c2, h0, h1, h2):
    """min(best, box distance at t) for t in [t0, t1] (else best)."""
    if t0 <= t <= t1:
        v = _sd_at(a0, a1, a2, b0, b1, b2, t, c0, c1, c2, h0, h1, h2)
        if v < best:
            return v
    return best


@njit(cache=True, error_model="numpy")
def _seg_box(a0, a1, a2, b0, b1, b2, c0, c1, c2, h0, h1, h2):
    """Exact least signed distance to the box |X - c| <= h along the segment a -> b (module doc), mm."""
    d0 = b0 - a0
    d1 = b1 - a1
    d2 = b2 - a2
    u0 = a0 - c0
    u1 = a1 - c1
    u2 = a2 - c2
    t0, t1 = _slab(u0, d0, h0, 0.0, 1.0)
    t0, t1 = _slab(u1, d1, h1, t0, t1)
    t0, t1 = _slab(u2, d2, h2, t0, t1)
    if t0 <= t1:  # the segment meets the box: least of max_i (|u_i + t d_i| - h_i) over [t0, t1]
        best = _sd_at(a0, a1, a2, b0, b1, b2, t0, c0, c1, c2, h0, h1, h2)
        best = _cand(best, a0, a1, a2, b0, b1, b2, t1, t0, t1, c0, c1, c2, h0, h1, h2)
        if d0 != 0.0:
            best = _cand(best, a0, a1, a2, b0, b1, b2, -u0 / d0, t0, t1, c0, c1, c2, h0, h1, h2)
        if d1 != 0.0:
            best = _cand(best, a0, a1, a2, b0, b1, b2, -u1 / d1, t0, t1, c0, c1, c2, h0, h1, h2)
        if d2 != 0.0:
            best = _cand(best, a0, a1, a2, b0, b1, b2, -u2 / d2, t0, t1, c0, c1, c2, h0, h1, h2)
        for pair in range(3):
            if pair == 0:
                ui, di, hi_, uj, dj, hj = u0, d0, h0, u1, d1, h1
            elif pair == 1:
                ui, di, hi_, uj, dj, hj = u0, d0, h0, u2, d2, h2
            else:
                ui, di, hi_, uj, dj, hj = u1, d1, h1, u2, d2, h2
            for si in (-1.0, 1.0):
                for sj in (-1.0, 1.0):
                    den = si * di - sj * dj
                    if den != 0.0:
                        t = ((sj * uj - hj) - (si * ui - hi_)) / den
                        best = _cand(best, a0, a1, a2, b0, b1, b2, t, t0, t1, c0, c1, c2, h0, h1, h2)
        return best
    # outside all along: the root of g' (continuous, nondecreasing, linear between breakpoints)
    glo = _gp(0.0, u0, u1, u2, d0, d1, d2, h0, h1, h2)
    if glo >= 0.0:
        return _box_sd(a0, a1, a2, c0, c1, c2, h0, h1, h2)
    ghi = _gp(1.0, u0, u1, u2, d0, d1, d2, h0, h1, h2)
    if ghi <= 0.0:
        return _box_sd(b0, b1, b2, c0, c1, c2, h0, h1, h2)
    lo = 0.0
    hi = 1.0
    for axis in range(3):
        if axis == 0:
            u, d, h = u0, d0, h0
        elif axis == 1:
            u, d, h = u1, d1, h1
        else:
            u, d, h = u2, d2, h2
        if d != 0.0:
            lo, glo, hi, ghi = _bracket((h - u) / d, u0, u1, u2, d0, d1, d2, h0, h1, h2, lo, glo, hi, ghi)
            lo, glo, hi, ghi = _bracket((-h - u) / d, u0, u1, u2, d0, d1, d2, h0, h1, h2, lo, glo, hi, ghi)
    t = lo if hi == lo else lo - glo * (hi - lo) / (ghi - glo)
    return _sd_at(a0, a1, a2, b0, b1, b2, min(max(t, 0.0), 1.0), c0, c1, c2, h0, h1, h2)


@njit(cache=True, error_model="numpy")
def _arc_lowest_z(a0, a1, a2, b0, b1, b2, cz, r):
    """The least z of the great-circle arc C + r (a -> b) (C_z = ``cz``): its ends, or where z is stationary."""
    dot = a0 * b0 + a1 * b1 + a2 * b2
    n0 = b0 - dot * a0
    n1 = b1 - dot * a1
    n2 = b2 - dot * a2
    nn = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    ends = min(cz + r * a2, cz + r * b2)
    if not nn > 1e-12:
        return ends
    nz = n2 / nn
    R = math.sqrt(a2 * a2 + nz * nz)
    # the stationary minimum phi* (cos, sin) = (-a_z, -n_z) / R lies on the arc [0, theta], theta <= pi,
    # iff sin phi* >= 0 and cos phi* >= cos theta = dot
    if R > 0.0 and -nz >= 0.0 and -a2 / R >= dot:
        return min(cz - r * R, ends)
    return ends


@njit(cache=True, error_model="numpy")
def _bound(p0, p1, p2, q0, q1, q2, c0, c1, c2, h0, h1, h2):
    """A lower bound of the box's signed distance along p -> q: the distance at its midpoint less half its length,
    or, larger, the gap between the segment's bounding box and the box when they are apart (then every point of the
    segment is outside the box, at least that far from it; where they overlap, a point may be inside)."""
    g0 = max(min(p0, q0) - (c0 + h0), (c0 - h0) - max(p0, q0), 0.0)
    g1 = max(min(p1, q1) - (c1 + h1), (c1 - h1) - max(p1, q1), 0.0)
    g2 = max(min(p2, q2) - (c2 + h2), (c2 - h2) - max(p2, q2), 0.0)
    e0 = q0 - p0
    e1 = q1 - p1
    e2 = q2 - p2
    mid = _box_sd(0.5 * (p0 + q0), 0.5 * (p1 + q1), 0.5 * (p2 + q2), c0, c1, c2, h0, h1, h2) - 0.5 * math.sqrt(
        e0 * e0 + e1 * e1 + e2 * e2
    )
    gap = g0 * g0 + g1 * g1 + g2 * g2
    return max(math.sqrt(gap), mid) if gap > 0.0 else mid


@njit(cache=True, error_model="numpy")
def _piece_ball(p0, p1, p2, q0, q1, q2, r, c0, c1, c2, h0, h1, h2):
    """A lower bound of the box distance over the piece of a circle of radius ``r`` (at most a half circle) between
    its points p and q, and over its chord: at the chord's midpoint, less sqrt(half chord^2 + sag^2)."""
    half = 0.5 * math.sqrt((q0 - p0) ** 2 + (q1 - p1) ** 2 + (q2 - p2) ** 2)
    sag = r - math.sqrt(max(r * r - half * half, 0.0))
    return _box_sd(0.5 * (p0 + q0), 0.5 * (p1 + q1), 0.5 * (p2 + q2), c0, c1, c2, h0, h1, h2) - math.sqrt(
        half * half + sag * sag
    )
