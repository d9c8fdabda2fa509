"""The body's clearance to the envelope of the whole patient (model §19.5) at one point, compiled.

The same quantity as :func:`arcube.evaluation.envelope_clearance.envelope_clearance` (its doc gives the
definition, the tie rule and the arcs' chords), each pair minimised exactly by ``_envelope_exact``.

The search is pruned, never approximated. Each (box, primitive) pair keeps a lower bound from point to point:
its value at the previous point less how far the primitive moved since (a signed distance is 1-Lipschitz;
``_carry``). At a point the table comes first (exact, a handful of comparisons), then the pair that bound at
the previous point (a good first least), then every other pair, skipped when its carried bound (with none
carried: a geometric bound, ``_bound`` for a line, the ball about its chord that holds an arc) cannot come
within reach of the least so far; else a line is minimised exactly and an arc's chord polyline searched
piece by piece (balls about the pieces' chords) and chord by chord. A pair is skipped only when its bound exceeds the least
value so far by ``_SKIP_MM`` (> TIE_MM), so every value within TIE_MM of the least is computed, and the first
region, then the first primitive, among them is named, as in the reference. A skin mesh is searched as the
anatomy is (``_clearance._anatomy_clearance``), capped at the least value so far. The pairs are searched in one
loop whose helpers take scalars only: an array passed to a compiled call costs reference counts (atomic, shared by
the threads), about 40 ns per pair when the pair's check was a helper, more than the check.
"""

from __future__ import annotations

import math

from numba import njit

from arcube.evaluation.envelope_clearance import ENVELOPE_ARC_CHORDS, TIE_MM
from arcube.evaluation.kernel._clearance import _anatomy_clearance
from arcube.evaluation.kernel._envelope_exact import _arc_lowest_z, _bound, _piece_ball, _seg_box
from arcube.model.body import N_ARCS, N_SEGMENTS, N_SPHERES

_SKIP_MM = 1e-6
"""A pair is skipped when its lower bound exceeds the least value so far by more than this (rounding)."""
N_CHORDS = ENVELOPE_ARC_CHORDS
N_LINES = N_SEGMENTS + N_SPHERES
N_PRIMS = N_LINES + N_ARCS
_GROUP = 4
"""Chords per piece of an arc bounded as one (N_CHORDS is a multiple of it)."""
assert N_CHORDS % _GROUP == 0
_INF = math.inf
_NAN = math.nan


@njit(cache=True, error_model="numpy", inline="always")
def _layout(n_box):
    """Offsets into the state vector of one design's envelope search (``_envelope_regions``): rows of N_PRIMS values
    per region row (n_box boxes, a skin, a table): carried lower bounds, then this point's values; the previous body
    (lines, arcs' a, b and n, their centre); the previous binding (row, primitive); the chord vertices and their flags."""
    rows = n_box + 2
    lower = 0
    values = lower + rows * N_PRIMS
    prev_lines = values + rows * N_PRIMS
    prev_arcs = prev_lines + N_LINES * 6
    prev_centre = prev_arcs + N_ARCS * 9
    prev_bind = prev_centre + 3
    chords = prev_bind + 2
    done = chords + N_ARCS * (N_CHORDS + 1) * 3
    return lower, values, prev_lines, prev_arcs, prev_centre, prev_bind, chords, done, done + N_ARCS


@njit(cache=True, error_model="numpy")
def state_size(n_box):
    """Length of the state vector of ``_envelope_regions`` for an envelope of ``n_box`` rounded boxes."""
    return _layout(n_box)[-1]


@njit(cache=True, error_model="numpy", inline="always")
def _arc_normal(a0, a1, a2, b0, b1, b2):
    """(unit in-plane normal n of the arc a -> b (0 for a zero arc), |b - (a.b) a|, a.b)."""
    dot = a0 * b0 + a1 * b1 + a2 * b2
    n0 = b0 - dot * a0
    n1 = b1 - dot * a1
    n2 = b2 - dot * a2
    nn = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if nn > 1e-12:
        return n0 / nn, n1 / nn, n2 / nn, nn, dot
    return 0.0, 0.0, 0.0, nn, dot


@njit(cache=True, error_model="numpy", inline="always")
def _chords(arcs, arc_c, arc_r, j, st, at):
    """Arc j's chord polyline vertices (N_CHORDS + 1, 3) into st[at:], as the reference's arc_chord_points: the ends
    exactly C + r a and C + r b, between them C + r (a cos(k theta / N) + n sin(k theta / N)), the cosines and sines
    by the angle-addition recurrence (one libm call per arc; a few ulps from the reference's direct values)."""
    a0, a1, a2 = arcs[j, 0, 0], arcs[j, 0, 1], arcs[j, 0, 2]
    b0, b1, b2 = arcs[j, 1, 0], arcs[j, 1, 1], arcs[j, 1, 2]
    n0, n1, n2, nn, dot = _arc_normal(a0, a1, a2, b0, b1, b2)
    theta = math.atan2(nn, dot) if nn > 1e-12 else 0.0
    step = theta / N_CHORDS
    cd = math.cos(step)
    sd = math.sin(step)
    cs = 1.0
    sn = 0.0
    for k in range(N_CHORDS + 1):
        if k == 0:
            w0, w1, w2 = a0, a1, a2
        elif k == N_CHORDS:
            w0, w1, w2 = b0, b1, b2
        else:
            cs, sn = cs * cd - sn * sd, sn * cd + cs * sd
            w0 = a0 * cs + n0 * sn
            w1 = a1 * cs + n1 * sn
            w2 = a2 * cs + n2 * sn
        st[at + 3 * k] = arc_c[0] + arc_r * w0
        st[at + 3 * k + 1] = arc_c[1] + arc_r * w1
        st[at + 3 * k + 2] = arc_c[2] + arc_r * w2


_ARC_MOVE = math.sqrt((1.0 + 0.5 * math.pi) ** 2 + (0.5 * math.pi) ** 2 + 1.0)
"""(1 + pi/2) |da| + pi/2 |db| + |dn| <= _ARC_MOVE sqrt(|da|^2 + |db|^2 + |dn|^2) (Cauchy-Schwarz): one root per arc."""


@njit(cache=True, error_model="numpy", inline="always")
def _carry(lines, arc_c, arc_r, arcs, st, n_box, carry):
    """Lower bounds of this point's values from the previous point's, less how far the primitives moved (a signed
    distance is 1-Lipschitz): a segment's points move at most as far as its farther-moving end; a vertex of an arc's
    chord polyline, C + r (a cos phi + n sin phi) with phi = k theta / N, at most
    |dC| + r (|da| + |dn| + |dtheta|), |dtheta| <= pi/2 (|da| + |db|), over the four arcs at most the largest of these
    (one bound for the arcs: square roots are what this costs). Without a previous body
    (``carry`` false) every bound is -inf. Then the body is kept as the previous one. False when the body is not
    finite (nothing kept)."""
    lo, _, prev_lines, prev_arcs, prev_centre, _, _, done, _ = _layout(n_box)
    rows = n_box + 2
    fin = arc_r + (arc_c[0] + arc_c[1] + arc_c[2])
    values = _layout(n_box)[1]  # the line movements wait in this point's value row 0 until they are used
    for k in range(N_LINES):
        m2 = 0.0
        for end in range(2):
            at = prev_lines + 6 * k + 3 * end
            x0, x1, x2 = lines[k, end, 0], lines[k, end, 1], lines[k, end, 2]
            fin += (x0 + x1) + x2
            d0 = x0 - st[at]
            d1 = x1 - st[at + 1]
            d2 = x2 - st[at + 2]
            m2 = max(m2, d0 * d0 + d1 * d1 + d2 * d2)
            st[at], st[at + 1], st[at + 2] = x0, x1, x2
        st[values + k] = m2
    a2max = 0.0
    for j in range(N_ARCS):
        at = prev_arcs + 9 * j
        a0, a1, a2 = arcs[j, 0, 0], arcs[j, 0, 1], arcs[j, 0, 2]
        b0, b1, b2 = arcs[j, 1, 0], arcs[j, 1, 1], arcs[j, 1, 2]
        fin += ((a0 + a1) + a2) + ((b0 + b1) + b2)
        n0, n1, n2, _, _ = _arc_normal(a0, a1, a2, b0, b1, b2)
        q = (a0 - st[at]) ** 2 + (a1 - st[at + 1]) ** 2 + (a2 - st[at + 2]) ** 2
        q += (b0 - st[at + 3]) ** 2 + (b1 - st[at + 4]) ** 2 + (b2 - st[at + 5]) ** 2
        q += (n0 - st[at + 6]) ** 2 + (n1 - st[at + 7]) ** 2 + (n2 - st[at + 8]) ** 2
        a2max = max(a2max, q)
        st[at], st[at + 1], st[at + 2], st[at + 3], st[at + 4], st[at + 5] = a0, a1, a2, b0, b1, b2
        st[at + 6], st[at + 7], st[at + 8] = n0, n1, n2
        st[done + j] = 0.0
    if not math.isfinite(fin):
        return False
    d0 = arc_c[0] - st[prev_centre]
    d1 = arc_c[1] - st[prev_centre + 1]
    d2 = arc_c[2] - st[prev_centre + 2]
    st[prev_centre], st[prev_centre + 1], st[prev_centre + 2] = arc_c[0], arc_c[1], arc_c[2]
    if not carry:
        for i in range(lo, lo + rows * N_PRIMS):
            st[i] = -_INF
        return True
    for k in range(N_LINES):
        st[values + k] = math.sqrt(st[values + k])
    m_arc = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) + arc_r * _ARC_MOVE * math.sqrt(a2max)
    for r in range(rows):
        at = lo + r * N_PRIMS
        for k in range(N_LINES):
            st[at + k] -= st[values + k]
        for j in range(N_ARCS):
            st[at + N_LINES + j] -= m_arc
    return True


@njit(cache=True, error_model="numpy")
def _envelope_regions(lines, arc_c, arc_r, arcs, radius, boxes, table_z, has_skin, carry, st):
    """This point's values of the body against the envelope's boxes and table into the state ``st`` (``_layout``);
    returns the least, or NaN when the body is not finite (then nothing is carried to the next point).

    ``lines`` (N_LINES, 2, 3), ``arcs`` (N_ARCS, 2, 3), ``arc_c`` (3,), ``arc_r``: the body (``_body._body_world``);
    ``radius`` (N_PRIMS,) the primitives' radii, mm; ``boxes`` (B, 7); ``table_z`` (NaN: none); ``has_skin``: a skin
    region comes after the boxes (``_envelope_skin``); ``carry``: the previous call was this design's previous body.

    The table first (exact; an arc's lowest point only when its carried bound does not rule it out), then the pair
    (box, primitive) that bound at the previous point (a good first least), then every box against every primitive:
    skipped when its carried bound cannot come within _SKIP_MM of the least, or, with no bound carried, its geometric
    bound (a line: ``_bound``; an arc: the ball about its chord that holds it); else a line is minimised exactly and
    an arc's chord polyline is searched in pieces of _GROUP chords (balls about the pieces' chords), then chord by
    chord. Each pair then carries its value (an arc: the least of its chords and of the bounds of the pieces and
    chords skipped) to the next point. One loop, no helper taking arrays: each array passed costs reference counts."""
    n_box = boxes.shape[0]
    lo, vals, _, _, _, prev_bind, chords, done, _ = _layout(n_box)
    if not _carry(lines, arc_c, arc_r, arcs, st, n_box, carry):
        return _NAN
    for i in range(vals, vals + (n_box + 2) * N_PRIMS):  # (after _carry: it uses row 0 for the lines' movements)
        st[i] = _INF
    best = _INF
    if not math.isnan(table_z):
        tr = n_box + (1 if has_skin else 0)
        for k in range(N_LINES):
            v = min(lines[k, 0, 2], lines[k, 1, 2]) - table_z - radius[k]
            st[vals + tr * N_PRIMS + k] = v
            best = min(best, v)
        for j in range(N_ARCS):  # the lowest point of an arc costs roots: its carried bound first
            at = tr * N_PRIMS + N_LINES + j
            if st[lo + at] >= best + _SKIP_MM:
                continue
            low = _arc_lowest_z(
                arcs[j, 0, 0],
                arcs[j, 0, 1],
                arcs[j, 0, 2],
                arcs[j, 1, 0],
                arcs[j, 1, 1],
                arcs[j, 1, 2],
                arc_c[2],
                arc_r,
            )
            v = low - table_z - radius[N_LINES + j]
            st[vals + at] = v
            st[lo + at] = v
            best = min(best, v)
    first = int(st[prev_bind] * N_PRIMS + st[prev_bind + 1]) if carry and st[prev_bind] < n_box else -1
    for idx in range(-1, n_box * N_PRIMS):
        if idx < 0:
            if first < 0:
                continue
            pair = first
        elif idx == first:
            continue
        else:
            pair = idx
        bi = pair // N_PRIMS
        k = pair - bi * N_PRIMS
        lower = st[lo + pair]
        if lower >= best + _SKIP_MM:
            continue
        c0, c1, c2 = boxes[bi, 0], boxes[bi, 1], boxes[bi, 2]
        h0, h1, h2 = boxes[bi, 3], boxes[bi, 4], boxes[bi, 5]
        off = boxes[bi, 6] + radius[k]
        if k < N_LINES:
            p0, p1, p2 = lines[k, 0, 0], lines[k, 0, 1], lines[k, 0, 2]
            q0, q1, q2 = lines[k, 1, 0], lines[k, 1, 1], lines[k, 1, 2]
            if lower == -_INF:
                b = _bound(p0, p1, p2, q0, q1, q2, c0, c1, c2, h0, h1, h2) - off
                if b >= best + _SKIP_MM:
                    st[lo + pair] = b
                    continue
            v = _seg_box(p0, p1, p2, q0, q1, q2, c0, c1, c2, h0, h1, h2) - off
            st[vals + pair] = v
            st[lo + pair] = v
            best = min(best, v)
            continue
        j = k - N_LINES
        r = arc_r
        if lower == -_INF:
            b = (
                _piece_ball(
                    arc_c[0] + r * arcs[j, 0, 0],
                    arc_c[1] + r * arcs[j, 0, 1],
                    arc_c[2] + r * arcs[j, 0, 2],
                    arc_c[0] + r * arcs[j, 1, 0],
                    arc_c[1] + r * arcs[j, 1, 1],
                    arc_c[2] + r * arcs[j, 1, 2],
                    r,
                    c0,
                    c1,
                    c2,
                    h0,
                    h1,
                    h2,
                )
                - off
            )
            if b >= best + _SKIP_MM:
                st[lo + pair] = b
                continue
        ch = chords + j * (N_CHORDS + 1) * 3
        if st[done + j] == 0.0:
            _chords(arcs, arc_c, arc_r, j, st, ch)
            st[done + j] = 1.0
        least = _INF  # of the chords minimised
        floor = _INF  # of the bounds of the pieces and chords skipped
        for g in range(0, N_CHORDS, _GROUP):
            u = ch + 3 * g
            w = ch + 3 * (g + _GROUP)
            gb = _piece_ball(st[u], st[u + 1], st[u + 2], st[w], st[w + 1], st[w + 2], r, c0, c1, c2, h0, h1, h2) - off
            if gb >= best + _SKIP_MM:
                floor = min(floor, gb)
                continue
            for m in range(g, g + _GROUP):
                u = ch + 3 * m
                p0, p1, p2, q0, q1, q2 = st[u], st[u + 1], st[u + 2], st[u + 3], st[u + 4], st[u + 5]
                cb = _bound(p0, p1, p2, q0, q1, q2, c0, c1, c2, h0, h1, h2) - off
                if cb >= best + _SKIP_MM:
                    floor = min(floor, cb)
                    continue
                v = _seg_box(p0, p1, p2, q0, q1, q2, c0, c1, c2, h0, h1, h2) - off
                least = min(least, v)
                best = min(best, v)
        st[vals + pair] = least
        st[lo + pair] = min(least, floor)
    return best


@njit(cache=True, error_model="numpy")
def _envelope_skin(lines, arc_c, arc_r, arcs, radius, envelope, order, work, lower, st, best):
    """The skin region (a mesh, searched on its grids as the anatomy, ``_clearance._anatomy_clearance``) capped at the
    least so far ``best``: its value goes into the state's skin row; returns the new least."""
    n_box = envelope[0].shape[0]
    _, vals, _, _, _, _, _, _, _ = _layout(n_box)
    for k in range(lower.shape[0]):
        lower[k] = -_INF
    grids = (envelope[3], envelope[4], envelope[5], envelope[6], envelope[7], envelope[8], envelope[9], envelope[10])
    v, k = _anatomy_clearance(lines, arc_c, arc_r, arcs, radius, N_LINES, grids, order, work, best, lower, -_INF)
    if k >= 0:
        st[vals + n_box * N_PRIMS + k] = v
        return min(best, v)
    return best


@njit(cache=True, error_model="numpy")
def _envelope_pick(st, n_box, n_regions, best):
    """(clearance, primitive, region): the least ``best`` and the first region row, then the first primitive in it,
    whose value is within TIE_MM of it (the reference's rule); (NaN, -1, -1) when there is none. Remembers the pair
    for the next point (``_envelope_regions`` minimises it first)."""
    _, vals, _, _, _, prev_bind, _, _, _ = _layout(n_box)
    st[prev_bind] = n_box + 2.0  # none
    if not best < _INF:
        return _NAN, -1, -1
    tie = best + TIE_MM
    for r in range(n_regions):
        for k in range(N_PRIMS):
            if st[vals + r * N_PRIMS + k] <= tie:
                st[prev_bind] = r
                st[prev_bind + 1] = k
                return best, k, r
    return _NAN, -1, -1
