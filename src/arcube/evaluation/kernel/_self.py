"""Self clearance for one point (model §14.3): the pairs of :data:`arcube.model.body.SELF_PAIRS`,
segments and points by the closest-point formula (Ericson 5.1.9), arcs as the same chord polylines as
:mod:`arcube.evaluation.clearance`. Straight pairs carry a lower bound from point to point (less both
parts' moves), so a pair that stays far apart is not measured again while the guard only decides."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, error_model="numpy")
def _segment_distance(p1, q1, p2, q2):
    """clearance.segment_distance for one pair (Ericson 5.1.9)."""
    d10 = q1[0] - p1[0]
    d11 = q1[1] - p1[1]
    d12 = q1[2] - p1[2]
    d20 = q2[0] - p2[0]
    d21 = q2[1] - p2[1]
    d22 = q2[2] - p2[2]
    r0 = p1[0] - p2[0]
    r1 = p1[1] - p2[1]
    r2 = p1[2] - p2[2]
    a = d10 * d10 + d11 * d11 + d12 * d12
    e = d20 * d20 + d21 * d21 + d22 * d22
    f = d20 * r0 + d21 * r1 + d22 * r2
    c = d10 * r0 + d11 * r1 + d12 * r2
    b = d10 * d20 + d11 * d21 + d12 * d22
    tiny = 1e-12
    if a <= tiny:
        s = 0.0
        t = 0.0 if e <= tiny else min(max(f / e, 0.0), 1.0)
    elif e <= tiny:
        t = 0.0
        s = min(max(-c / a, 0.0), 1.0)
    else:
        denom = a * e - b * b
        s = min(max((b * f - c * e) / denom, 0.0), 1.0) if denom > 0.0 else 0.0
        t = (b * s + f) / e
        if t < 0.0:
            t = 0.0
            s = min(max(-c / a, 0.0), 1.0)
        elif t > 1.0:
            t = 1.0
            s = min(max((b - c) / a, 0.0), 1.0)
    x0 = p1[0] + d10 * s - (p2[0] + d20 * t)
    x1 = p1[1] + d11 * s - (p2[1] + d21 * t)
    x2 = p1[2] + d12 * s - (p2[2] + d22 * t)
    return math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)


@njit(cache=True, error_model="numpy")
def _chords(arc_c, arc_r, arcs, n, out, j):
    """Chord points of arc ``j`` into ``out[j]`` (n + 1, 3), as body.great_circle samples it (slerp)."""
    a = arcs[j, 0]
    b = arcs[j, 1]
    cx = a[1] * b[2] - a[2] * b[1]
    cy = a[2] * b[0] - a[0] * b[2]
    cz = a[0] * b[1] - a[1] * b[0]
    omega = math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), a[0] * b[0] + a[1] * b[1] + a[2] * b[2])
    so = math.sin(omega)
    for i in range(n + 1):
        s = i / n
        if so < 1e-9:
            p0 = (1.0 - s) * a[0] + s * b[0]
            p1 = (1.0 - s) * a[1] + s * b[1]
            p2 = (1.0 - s) * a[2] + s * b[2]
            nn = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
            p0 /= nn
            p1 /= nn
            p2 /= nn
        else:
            wa = math.sin((1.0 - s) * omega) / so
            wb = math.sin(s * omega) / so
            p0 = wa * a[0] + wb * b[0]
            p1 = wa * a[1] + wb * b[1]
            p2 = wa * a[2] + wb * b[2]
        out[j, i, 0] = arc_c[0] + arc_r * p0
        out[j, i, 1] = arc_c[1] + arc_r * p1
        out[j, i, 2] = arc_c[2] + arc_r * p2


@njit(cache=True, error_model="numpy")
def line_move(lines, prev, j):
    """How far straight primitive ``j`` of ``lines`` (n, 2, 3) moved since ``prev`` (same shape), mm: the larger
    move of its ends (every point of a segment moves by at most that). ``prev[j]`` then takes ``lines[j]``."""
    m = 0.0
    for end in range(2):
        dx = lines[j, end, 0] - prev[j, end, 0]
        dy = lines[j, end, 1] - prev[j, end, 1]
        dz = lines[j, end, 2] - prev[j, end, 2]
        m = max(m, math.sqrt(dx * dx + dy * dy + dz * dz))
        for q in range(3):
            prev[j, end, q] = lines[j, end, q]
    return m


@njit(cache=True, error_model="numpy")
def self_moves(lines, prev, valid, move):
    """How far each straight primitive moved since the previous body ``prev`` (:func:`line_move`), into
    ``move`` (n_lines,); +inf without a previous body (``valid`` false). ``prev`` then takes this body."""
    for j in range(lines.shape[0]):
        m = line_move(lines, prev, j)
        move[j] = m if valid else math.inf


@njit(cache=True, error_model="numpy")
def _self_clearance(lines, arc_c, arc_r, arcs, radius, n_lines, pairs, chords, cap, enough, lower, move):
    """Smallest distance between the primitive pairs, minus both radii (arcs as chord polylines).

    ``cap``: a value the caller does not need beaten (inf for the exact minimum; the guard's limit
    when only its decision and shortfall matter): pairs that cannot come below it are skipped.
    ``enough``: stop at the first pair at or below it (-inf: never).
    ``lower`` (n_pairs,): proven lower bounds of the straight pairs' clearances at the previous point
    (-inf: none), ``move`` (n_lines,): how far each straight primitive moved since (:func:`self_moves`);
    a pair whose bound less both moves cannot beat the best so far is skipped, and ``lower`` takes
    this point's bounds (a distance changes by at most the two parts' moves)."""
    n = chords.shape[1] - 1
    have = np.zeros(arcs.shape[0], dtype=np.bool_)  # chords computed only for arcs a pair gets close to
    best = cap
    for q in range(pairs.shape[0]):
        i = pairs[q, 0]
        j = pairs[q, 1]
        rad = radius[i] + radius[j]
        if j < n_lines:
            bound = lower[q] - move[i] - move[j]
            if bound >= best:
                lower[q] = bound
                continue
            d = _segment_distance(lines[i, 0], lines[i, 1], lines[j, 0], lines[j, 1])
            lower[q] = d - rad
        else:
            # an arc lies within arc_r of its centre: skip it when the segment is farther than that
            lo = _segment_distance(lines[i, 0], lines[i, 1], arc_c, arc_c) - arc_r
            if lo - rad >= best:
                continue
            a = j - n_lines
            if not have[a]:
                _chords(arc_c, arc_r, arcs, n, chords, a)
                have[a] = True
            # the chord polyline lies within its sag of the chord between the arc's ends
            ax = chords[a, 0, 0] - arc_c[0]
            ay = chords[a, 0, 1] - arc_c[1]
            az = chords[a, 0, 2] - arc_c[2]
            bx = chords[a, n, 0] - arc_c[0]
            by = chords[a, n, 1] - arc_c[1]
            bz = chords[a, n, 2] - arc_c[2]
            half = 0.5 * math.atan2(
                math.sqrt((ay * bz - az * by) ** 2 + (az * bx - ax * bz) ** 2 + (ax * by - ay * bx) ** 2),
                ax * bx + ay * by + az * bz,
            )
            sag = arc_r * (1.0 - math.cos(half))
            if _segment_distance(lines[i, 0], lines[i, 1], chords[a, 0], chords[a, n]) - sag - rad >= best:
                continue
            d = math.inf
            for m in range(n):
                dm = _segment_distance(lines[i, 0], lines[i, 1], chords[a, m], chords[a, m + 1])
                if dm < d:
                    d = dm
        if d - rad < best:
            best = d - rad
            if best <= enough:
                for r in range(q + 1, pairs.shape[0]):
                    lower[r] = -math.inf  # not looked at here: no bound to carry
                break
    return best
