"""Body clearances for one point (model §14.3): to the anatomy's distance grids, and between parts.

* ``_lookup``: the anatomy's signed distance at a point, exactly as
  :class:`arcube.evaluation.sdf.AnatomyDistance` computes it (trilinear in the fine grid inside
  its box, else in the coarse grid, plus the distance to the coarse box outside it);
* ``_anatomy_clearance``: a branch-and-bound search along every primitive's axis (segment, arc,
  point): an interval is dropped when its mid value minus its half-length times a Lipschitz bound
  of the interpolated field along it cannot beat the best value found so far by more than
  ``TOL_MM``, so the result is within ``TOL_MM`` of the interpolated field's minimum over the body,
  and within ``TOL_MM`` + eps of the true one (eps: the grid's interpolation error,
  :mod:`arcube.evaluation.sdf`). The bound is 1 (a distance is 1-Lipschitz) for long intervals;
  for short ones inside one grid, the largest grid differences over the blocks of ``BLOCK``^3
  cells the interval's box touches, summed with the interval direction's components (a trilinear
  field's partial derivatives are averages of its grid differences). A part running parallel to
  a face then needs a few lookups instead of one every ``TOL_MM``;
* the self clearance is in :mod:`arcube.evaluation.kernel._self`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from arcube.evaluation.kernel._self import line_move

TOL_MM = 0.1
"""How far above the interpolated field's minimum over the body the search may stop (mm)."""
_STACK = 96
BLOCK = 8
"""Cells per block edge of the gradient bounds."""
_LOCAL = 24.0
"""Intervals shorter than this (mm) get the local gradient bound."""


def block_gradients(values: np.ndarray, spacing: float) -> np.ndarray:
    """``(bx, by, bz, 3)``: per block of BLOCK^3 cells, the largest |difference| / spacing of the grid
    along x, y and z over the edges of its cells (bounds of the interpolated field's partials)."""
    v = np.asarray(values, dtype=np.float64)
    out = []
    for axis in range(3):
        d = np.abs(np.diff(v, axis=axis)) / spacing
        # each cell's 4 edges along ``axis``: max over the two nodes in each other direction
        for other in range(3):
            if other != axis:
                d = np.maximum(
                    np.take(d, range(0, d.shape[other] - 1), axis=other),
                    np.take(d, range(1, d.shape[other]), axis=other),
                )
        cells = d  # (nx - 1, ny - 1, nz - 1)
        pad = [(0, (-n) % BLOCK) for n in cells.shape]
        cells = np.pad(cells, pad, constant_values=0.0)
        b = [n // BLOCK for n in cells.shape]
        out.append(cells.reshape(b[0], BLOCK, b[1], BLOCK, b[2], BLOCK).max(axis=(1, 3, 5)))
    return np.ascontiguousarray(np.stack(out, axis=-1))


@njit(cache=True, error_model="numpy")
def _block_bound(o, h, v, gb, lo0, lo1, lo2, hi0, hi1, hi2, u0, u1, u2):
    """Bound of |d field / ds| along unit (u0, u1, u2) over the box [lo, hi] inside grid (o, h, v), or
    inf when the box leaves the grid; gb are its block_gradients."""
    nx, ny, nz = v.shape
    a0 = (lo0 - o[0]) / h
    a1 = (lo1 - o[1]) / h
    a2 = (lo2 - o[2]) / h
    b0 = (hi0 - o[0]) / h
    b1 = (hi1 - o[1]) / h
    b2 = (hi2 - o[2]) / h
    if a0 < 0.0 or a1 < 0.0 or a2 < 0.0 or b0 > nx - 1.0 or b1 > ny - 1.0 or b2 > nz - 1.0:
        return math.inf
    i0 = min(int(a0), nx - 2) // BLOCK
    i1 = min(int(b0), nx - 2) // BLOCK
    j0 = min(int(a1), ny - 2) // BLOCK
    j1 = min(int(b1), ny - 2) // BLOCK
    k0 = min(int(a2), nz - 2) // BLOCK
    k1 = min(int(b2), nz - 2) // BLOCK
    w0 = abs(u0)
    w1 = abs(u1)
    w2 = abs(u2)
    best = 0.0
    for i in range(i0, i1 + 1):
        for j in range(j0, j1 + 1):
            for k in range(k0, k1 + 1):
                s = w0 * gb[i, j, k, 0] + w1 * gb[i, j, k, 1] + w2 * gb[i, j, k, 2]
                if s > best:
                    best = s
    return best


@njit(cache=True, error_model="numpy")
def _grid(o, h, v, x, y, z):
    """Trilinear value of grid (origin o, spacing h, values v) at (x, y, z); outside the box, the
    value at the clamped point plus the distance to it."""
    nx, ny, nz = v.shape
    gx = (x - o[0]) / h
    gy = (y - o[1]) / h
    gz = (z - o[2]) / h
    cx = min(max(gx, 0.0), nx - 1.0)
    cy = min(max(gy, 0.0), ny - 1.0)
    cz = min(max(gz, 0.0), nz - 1.0)
    out = math.sqrt((gx - cx) ** 2 + (gy - cy) ** 2 + (gz - cz) ** 2) * h
    i = min(int(cx), nx - 2)
    j = min(int(cy), ny - 2)
    k = min(int(cz), nz - 2)
    fx = cx - i
    fy = cy - j
    fz = cz - k
    c00 = v[i, j, k] * (1.0 - fx) + v[i + 1, j, k] * fx
    c10 = v[i, j + 1, k] * (1.0 - fx) + v[i + 1, j + 1, k] * fx
    c01 = v[i, j, k + 1] * (1.0 - fx) + v[i + 1, j, k + 1] * fx
    c11 = v[i, j + 1, k + 1] * (1.0 - fx) + v[i + 1, j + 1, k + 1] * fx
    c0 = c00 * (1.0 - fy) + c10 * fy
    c1 = c01 * (1.0 - fy) + c11 * fy
    return c0 * (1.0 - fz) + c1 * fz + out


@njit(cache=True, error_model="numpy")
def _lookup(grids, x, y, z):
    """Signed distance to the anatomy at (x, y, z), mm: the fine grid inside its box, else the coarse grid.

    ``grids``: (fine_origin (3,), fine_spacing, fine_values (nx, ny, nz), coarse_origin, coarse_spacing,
    coarse_values, fine_gradients, coarse_gradients), mm; the gradients are :func:`block_gradients`.
    """
    fine_origin, fine_spacing, fine_values, coarse_origin, coarse_spacing, coarse_values, _, _ = grids
    nx, ny, nz = fine_values.shape
    gx = (x - fine_origin[0]) / fine_spacing
    gy = (y - fine_origin[1]) / fine_spacing
    gz = (z - fine_origin[2]) / fine_spacing
    if 0.0 <= gx <= nx - 1.0 and 0.0 <= gy <= ny - 1.0 and 0.0 <= gz <= nz - 1.0:
        return _grid(fine_origin, fine_spacing, fine_values, x, y, z)
    return _grid(coarse_origin, coarse_spacing, coarse_values, x, y, z)


@njit(cache=True, error_model="numpy")
def _curve_point(is_arc, a, b, c, r, nrm, s, out):
    """Point at parameter s of a segment a -> b (s in [0, 1]) or of an arc c + r (a cos s + nrm sin s)."""
    if is_arc:
        cs = math.cos(s)
        sn = math.sin(s)
        for q in range(3):
            out[q] = c[q] + r * (a[q] * cs + nrm[q] * sn)
    else:
        for q in range(3):
            out[q] = a[q] + s * (b[q] - a[q])


@njit(cache=True, error_model="numpy")
def _lipschitz(grids, p, q, sag, is_arc):
    """Lipschitz bound of the looked-up field along the piece from p to q (an arc piece: its chord
    grown by its sag, any direction)."""
    (
        fine_origin,
        fine_spacing,
        fine_values,
        coarse_origin,
        coarse_spacing,
        coarse_values,
        fine_gradients,
        coarse_gradients,
    ) = grids
    lo0 = min(p[0], q[0]) - sag
    lo1 = min(p[1], q[1]) - sag
    lo2 = min(p[2], q[2]) - sag
    hi0 = max(p[0], q[0]) + sag
    hi1 = max(p[1], q[1]) + sag
    hi2 = max(p[2], q[2]) + sag
    if is_arc:
        u0 = u1 = u2 = 1.0
    else:
        d0 = q[0] - p[0]
        d1 = q[1] - p[1]
        d2 = q[2] - p[2]
        n = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if n == 0.0:
            return 0.0
        u0 = d0 / n
        u1 = d1 / n
        u2 = d2 / n
    bound = _block_bound(
        fine_origin, fine_spacing, fine_values, fine_gradients, lo0, lo1, lo2, hi0, hi1, hi2, u0, u1, u2
    )
    if bound == math.inf:
        # outside the fine box entirely: the coarse grid's blocks; across its boundary: 1
        nx, ny, nz = fine_values.shape
        fhi0 = fine_origin[0] + fine_spacing * (nx - 1)
        fhi1 = fine_origin[1] + fine_spacing * (ny - 1)
        fhi2 = fine_origin[2] + fine_spacing * (nz - 1)
        apart = (
            hi0 < fine_origin[0]
            or lo0 > fhi0
            or hi1 < fine_origin[1]
            or lo1 > fhi1
            or hi2 < fine_origin[2]
            or lo2 > fhi2
        )
        if apart:
            bound = _block_bound(
                coarse_origin, coarse_spacing, coarse_values, coarse_gradients, lo0, lo1, lo2, hi0, hi1, hi2, u0, u1, u2
            )
    return min(bound, 1.0)


@njit(cache=True, error_model="numpy")
def _search(is_arc, a, b, c, r, nrm, total, scale, radius, grids, best, stack_lo, stack_hi, pt, p, q, enough):
    """Branch and bound over s in [0, total] (mm per unit of s: ``scale``); returns the best value and
    a lower bound of this primitive's minimum (the least of d - Lipschitz bound x half-length over the
    intervals it dropped; -inf when it stopped at a value <= ``enough``). ``pt``, ``p``, ``q``: (3,) work buffers."""
    floor = math.inf
    top = 0
    stack_lo[0] = 0.0
    stack_hi[0] = total
    while top >= 0:
        lo = stack_lo[top]
        hi = stack_hi[top]
        top -= 1
        mid = 0.5 * (lo + hi)
        _curve_point(is_arc, a, b, c, r, nrm, mid, pt)
        d = _lookup(grids, pt[0], pt[1], pt[2]) - radius
        if d < best:
            best = d
            if best <= enough:
                return best, -math.inf
        half = 0.5 * (hi - lo) * scale
        if d - half >= best - TOL_MM or half <= 0.5 * TOL_MM or top + 2 >= _STACK:
            floor = min(floor, d - half)
            continue
        if half <= _LOCAL:
            _curve_point(is_arc, a, b, c, r, nrm, lo, p)
            _curve_point(is_arc, a, b, c, r, nrm, hi, q)
            sag = r * (1.0 - math.cos(0.5 * (hi - lo))) if is_arc else 0.0
            bound = d - _lipschitz(grids, p, q, sag, is_arc) * half
            if bound >= best - TOL_MM:
                floor = min(floor, bound)
                continue
        top += 1
        stack_lo[top] = mid
        stack_hi[top] = hi
        top += 1
        stack_lo[top] = lo
        stack_hi[top] = mid
    return best, floor


@njit(cache=True, error_model="numpy")
def _anatomy_clearance(lines, arc_c, arc_r, arcs, radius, n_lines, grids, order, work, cap, lower, enough):
    """(clearance, primitive index) of the body primitives to the anatomy; ``order``: primitives to try first.

    ``cap``: a value the caller does not need beaten (inf for the exact minimum). Parts that cannot
    come within ``TOL_MM`` below it are pruned; when none does, returns (cap, -1).
    ``lower`` (27,): known lower bounds of each primitive's clearance (-inf: none); a primitive whose
    bound cannot beat the best so far is not searched; the others' entries are set to the bound their
    search proves (the caller carries them to the next point, less how far the primitive moved).
    ``enough``: a value below which the caller needs no more (a guard's shortfall past its grading scale,
    model §16; -inf: none): the search stops at the first body point found at or below it."""
    stack_lo = work[0]
    stack_hi = work[1]
    pt = work[2, :3]
    nrm = work[3, :3]
    pbuf = work[4, :3]
    qbuf = work[5, :3]
    best = cap
    best_k = -1
    for idx in range(order.shape[0]):
        k = order[idx]
        before = best
        if lower[k] >= best - TOL_MM:
            continue
        # the curve of _curve_point: the segment a -> b over s in [0, 1] (its length in mm per unit of s), or the
        # arc about arc_c over the angle s in [0, angle] (arc_r mm per radian)
        is_arc = k >= n_lines
        if not is_arc:
            a = lines[k, 0]
            b = lines[k, 1]
            centre, r, total = a, 0.0, 1.0
            scale = math.sqrt((b[0] - a[0]) ** 2 + (b[1] - a[1]) ** 2 + (b[2] - a[2]) ** 2)
        else:
            j = k - n_lines
            a = arcs[j, 0]
            b = arcs[j, 1]
            dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
            for q in range(3):
                nrm[q] = b[q] - dot * a[q]
            nn = math.sqrt(nrm[0] ** 2 + nrm[1] ** 2 + nrm[2] ** 2)
            if nn > 1e-12:
                for q in range(3):
                    nrm[q] /= nn
                angle = math.atan2(nn, dot)
            else:
                angle = 0.0
            centre, r, total, scale = arc_c, arc_r, angle, arc_r
        best, lower[k] = _search(
            is_arc,
            a,
            b,
            centre,
            r,
            nrm,
            total,
            scale,
            radius[k],
            grids,
            best,
            stack_lo,
            stack_hi,
            pt,
            pbuf,
            qbuf,
            enough,
        )
        if best < before:
            best_k = k
        if best <= enough:
            break
    return best, best_k


@njit(cache=True, error_model="numpy")
def _carry_bounds(lower, lines, prev, valid):
    """Lower bounds of the primitives' clearances at this point from those of the previous body
    ``prev``: a segment's points move by at most the larger move of its ends (the same parameter on
    both), a sphere by its centre's; the arcs' bounds are dropped (they are always searched). Without
    a previous body (``valid`` false) every bound is dropped. ``prev`` then takes this body.
    ``lines`` (n, 2, 3): the segments and points (the first n entries of ``lower``; the arcs' follow)."""
    n_lines = lines.shape[0]
    for j in range(n_lines):
        m = line_move(lines, prev, j)
        lower[j] = lower[j] - m if valid else -math.inf
    for j in range(n_lines, lower.shape[0]):
        lower[j] = -math.inf
