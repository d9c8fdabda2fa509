"""The body's clearance to the envelope of the whole patient (MODEL.md 19.5) at one point, compiled.

The same quantity as :func:`arcube.evaluation.envelope_clearance.envelope_clearance` (its doc gives the
definition, the tie rule and the arcs' chords), by a different exact minimisation along a segment
(:func:`_seg_box`): the segment is clipped to the box's slabs; where it meets the box, the least of the
largest of three linear functions over the clipped part is at an end of it, where a coordinate of
p - c is 0, or where two of the functions cross; where it misses the box, the squared distance g(t) is
convex and C^1 with a piecewise linear derivative, so the root of g' lies between the two breakpoints
(where |p_i - c_i| = a_i) at which g' changes sign and is found by linear interpolation. Both are exact
in real arithmetic; the two engines agree to rounding.

The search is pruned, never approximated: the table comes first (exact, a handful of comparisons), and
a segment is minimised against a box only when the box's distance at its midpoint, less its half
length, could beat the least value so far (a signed distance is 1-Lipschitz); an arc only when the ball
around its chord's midpoint that holds it could, then each of its chords likewise. A pair is skipped
only when its bound exceeds the least value by ``_SKIP_MM`` (> TIE_MM), so every value within TIE_MM of the
least is computed, and the first region, then the first primitive, among them is named, as in the reference. A skin mesh is searched as the
anatomy is (``_clearance._anatomy_clearance``), capped at the least value so far.
"""

from __future__ import annotations

import math

from numba import njit

from arcube.evaluation.envelope_clearance import ENVELOPE_ARC_CHORDS, TIE_MM
from arcube.evaluation.kernel._clearance import _anatomy_clearance

_SKIP_MM = 1e-6
"""A pair is skipped when its lower bound exceeds the least value so far by more than this (rounding)."""
N_CHORDS = ENVELOPE_ARC_CHORDS
_INF = math.inf
_NAN = math.nan


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
def _arc_lowest_z(a, b, cz, r):
    """The least z of the great-circle arc C + r (a -> b) (C_z = ``cz``): its ends, or where z is stationary."""
    dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    n0 = b[0] - dot * a[0]
    n1 = b[1] - dot * a[1]
    n2 = b[2] - dot * a[2]
    nn = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    ends = min(cz + r * a[2], cz + r * b[2])
    if not nn > 1e-12:
        return ends
    nz = n2 / nn
    R = math.sqrt(a[2] * a[2] + nz * nz)
    # the stationary minimum phi* (cos, sin) = (-a_z, -n_z) / R lies on the arc [0, theta], theta <= pi,
    # iff sin phi* >= 0 and cos phi* >= cos theta = dot
    if R > 0.0 and -nz >= 0.0 and -a[2] / R >= dot:
        return min(cz - r * R, ends)
    return ends


@njit(cache=True, error_model="numpy")
def _chords(arcs, arc_c, arc_r, j, out):
    """The vertices (N_CHORDS + 1, 3) of arc j's chord polyline into ``out``, as the reference's arc_chord_points."""
    a = arcs[j, 0]
    b = arcs[j, 1]
    dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    n0 = b[0] - dot * a[0]
    n1 = b[1] - dot * a[1]
    n2 = b[2] - dot * a[2]
    nn = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if nn > 1e-12:
        theta = math.atan2(nn, dot)
        n0 /= nn
        n1 /= nn
        n2 /= nn
    else:
        theta = 0.0
        n0 = n1 = n2 = 0.0
    for k in range(N_CHORDS + 1):
        if k == 0:
            w0, w1, w2 = a[0], a[1], a[2]
        elif k == N_CHORDS:
            w0, w1, w2 = b[0], b[1], b[2]
        else:
            phi = theta * (k / N_CHORDS)
            cs = math.cos(phi)
            sn = math.sin(phi)
            w0 = a[0] * cs + n0 * sn
            w1 = a[1] * cs + n1 * sn
            w2 = a[2] * cs + n2 * sn
        out[j, k, 0] = arc_c[0] + arc_r * w0
        out[j, k, 1] = arc_c[1] + arc_r * w1
        out[j, k, 2] = arc_c[2] + arc_r * w2


@njit(cache=True, error_model="numpy")
def _bound(p, q, c0, c1, c2, h0, h1, h2):
    """A lower bound of the box distance along p -> q: at the midpoint, less half the length."""
    m0 = 0.5 * (p[0] + q[0])
    m1 = 0.5 * (p[1] + q[1])
    m2 = 0.5 * (p[2] + q[2])
    e0 = q[0] - p[0]
    e1 = q[1] - p[1]
    e2 = q[2] - p[2]
    return _box_sd(m0, m1, m2, c0, c1, c2, h0, h1, h2) - 0.5 * math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)


@njit(cache=True, error_model="numpy")
def _seg_value(p, q, c0, c1, c2, h0, h1, h2):
    return _seg_box(p[0], p[1], p[2], q[0], q[1], q[2], c0, c1, c2, h0, h1, h2)


@njit(cache=True, error_model="numpy")
def _arc_ball(arcs, arc_c, arc_r, j, c0, c1, c2, h0, h1, h2):
    """A lower bound of the box distance along arc j: at its chord's midpoint, less the radius
    sqrt(half chord^2 + sag^2) of the ball about it that holds the arc (an arc of at most pi)."""
    a = arcs[j, 0]
    b = arcs[j, 1]
    m0 = arc_c[0] + arc_r * 0.5 * (a[0] + b[0])
    m1 = arc_c[1] + arc_r * 0.5 * (a[1] + b[1])
    m2 = arc_c[2] + arc_r * 0.5 * (a[2] + b[2])
    half = 0.5 * arc_r * math.sqrt((b[0] - a[0]) ** 2 + (b[1] - a[1]) ** 2 + (b[2] - a[2]) ** 2)
    sag = arc_r - math.sqrt(max(arc_r * arc_r - half * half, 0.0))
    return _box_sd(m0, m1, m2, c0, c1, c2, h0, h1, h2) - math.sqrt(half * half + sag * sag)


@njit(cache=True, error_model="numpy")
def _finite_body(lines, arcs, arc_c, arc_r):
    s = arc_r + arc_c[0] + arc_c[1] + arc_c[2]
    for k in range(lines.shape[0]):
        for end in range(2):
            s += lines[k, end, 0] + lines[k, end, 1] + lines[k, end, 2]
    for j in range(arcs.shape[0]):
        for end in range(2):
            s += arcs[j, end, 0] + arcs[j, end, 1] + arcs[j, end, 2]
    return math.isfinite(s)


@njit(cache=True, error_model="numpy")
def _envelope_clearance(lines, arc_c, arc_r, arcs, radius, n_lines, envelope, order, work, lower, chords, done, pv):
    """(clearance mm, primitive index, region index) of the body to the envelope; (NaN, -1, -1) for a body
    that is not finite.

    ``lines`` (n_lines, 2, 3), ``arcs`` (4, 2, 3), ``arc_c`` (3,), ``arc_r``: the body (``_body._body_world``);
    ``radius`` (27,) the primitives' radii; ``envelope`` = (boxes (B, 7), table_z (NaN: none), has_skin,
    then the 8 items of the skin's grids as ``_clearance._lookup`` takes them); ``order``, ``work``, ``lower``:
    the anatomy search's (for the skin); buffers ``chords`` (4, N_CHORDS + 1, 3), ``done`` (4,) bool and ``pv``
    (>= regions, 27): each region's value per primitive (+inf where pruned). The region named is the first whose
    least is within TIE_MM of the least over all, the primitive the first of that region within it (the reference's rule).
    """
    boxes, table_z, has_skin = envelope[0], envelope[1], envelope[2]
    if not _finite_body(lines, arcs, arc_c, arc_r):
        return _NAN, -1, -1
    n_box = boxes.shape[0]
    n_arcs = arcs.shape[0]
    n_prims = n_lines + n_arcs
    has_table = table_z == table_z
    n_reg = n_box + (1 if has_skin else 0) + (1 if has_table else 0)
    for r in range(n_reg):
        for k in range(n_prims):
            pv[r, k] = _INF
    best = _INF
    if has_table:  # exact and cheap: first, so that its value prunes the boxes
        tr = n_reg - 1
        for k in range(n_lines):
            pv[tr, k] = min(lines[k, 0, 2], lines[k, 1, 2]) - table_z - radius[k]
            best = min(best, pv[tr, k])
        for j in range(n_arcs):
            pv[tr, n_lines + j] = _arc_lowest_z(arcs[j, 0], arcs[j, 1], arc_c[2], arc_r) - table_z - radius[n_lines + j]
            best = min(best, pv[tr, n_lines + j])
    for j in range(n_arcs):
        done[j] = False
    for bi in range(n_box):
        c0, c1, c2 = boxes[bi, 0], boxes[bi, 1], boxes[bi, 2]
        h0, h1, h2 = boxes[bi, 3], boxes[bi, 4], boxes[bi, 5]
        rho = boxes[bi, 6]
        for k in range(n_lines):
            p = lines[k, 0]
            q = lines[k, 1]
            off = rho + radius[k]
            if _bound(p, q, c0, c1, c2, h0, h1, h2) - off >= best + _SKIP_MM:
                continue
            v = _seg_value(p, q, c0, c1, c2, h0, h1, h2) - off
            pv[bi, k] = v
            best = min(best, v)
        for j in range(n_arcs):
            off = rho + radius[n_lines + j]
            if _arc_ball(arcs, arc_c, arc_r, j, c0, c1, c2, h0, h1, h2) - off >= best + _SKIP_MM:
                continue
            if not done[j]:
                _chords(arcs, arc_c, arc_r, j, chords)
                done[j] = True
            for m in range(N_CHORDS):
                p = chords[j, m]
                q = chords[j, m + 1]
                if _bound(p, q, c0, c1, c2, h0, h1, h2) - off >= best + _SKIP_MM:
                    continue
                v = _seg_value(p, q, c0, c1, c2, h0, h1, h2) - off
                if v < pv[bi, n_lines + j]:
                    pv[bi, n_lines + j] = v
                best = min(best, v)
    if has_skin:
        for k in range(lower.shape[0]):
            lower[k] = -_INF
        skin_grids = (envelope[3], envelope[4], envelope[5], envelope[6], envelope[7], envelope[8], envelope[9], envelope[10])
        v, k = _anatomy_clearance(lines, arc_c, arc_r, arcs, radius, n_lines, skin_grids, order, work, best, lower, -_INF)
        if k >= 0:
            pv[n_box, k] = v
            best = min(best, v)
    if not best < _INF:
        return _NAN, -1, -1
    tie = best + TIE_MM
    for r in range(n_reg):
        for k in range(n_prims):
            if pv[r, k] <= tie:
                return best, k, r
    return _NAN, -1, -1
