"""Signed distance to the anatomy on grids, for the clearance of MODEL.md section 14.3.

The anatomy is a union of closed solids (meshes of :mod:`arcube.io.meshes`, or the boxes of
:mod:`arcube.patients.anatomy`). Its signed distance at a point p is the minimum over the
solids of each solid's own signed distance:

    sd(p) = min_s sd_s(p),   sd_s(p) = +dist(p, ∂s) outside s, −dist(p, ∂s) inside s.

Outside every solid this is exactly the Euclidean distance to the union. Inside, it is minus
the depth into the *deepest* solid containing p, which is never deeper than the true depth
into the union (where solids overlap, the union can be deeper): it is negative exactly
inside the union, and exact wherever one solid alone is what p is in, e.g. everywhere
outside the overlaps of the default anatomy's boxes.

Grids. :class:`DistanceGrid` stores node values ``values[i, j, k] = sd(origin + spacing ·
(i, j, k))`` (float64, C-contiguous) and reads them by trilinear interpolation inside its box
of nodes; outside that box it returns ``|p − q| + value(q)`` with q the point clamped into the
box. :class:`AnatomyDistance` holds two grids: a fine one (default spacing 1 mm) over the
anatomy's bounding box plus a 30 mm margin, and a coarse one (6 mm) over the bounding box plus
400 mm; a lookup uses the fine grid where p lies in the fine grid's box, else the coarse one.
Node values are exact (up to float64 rounding), whichever way the grid was built; both grids
put their nodes on multiples of their spacing, so fine and coarse nodes coincide where the
coarse spacing is a multiple of the fine one.

Accuracy. sd is 1-Lipschitz, so trilinear interpolation of exact node values is within
(√3/2)·h of the truth anywhere (h = spacing; the weighted mean distance to the cell's corners
is at most half the cell diagonal). That bound is reached only at creases of sd; for the
creases that polyhedral anatomy produces it is much smaller:

* a flat face, or a smooth surface of radius R ≫ h: error ≤ about 3h²/(8R) (0.01 mm for
  h = 1 mm, R = 40 mm); exact (0) next to a flat face, where sd is linear;
* a medial ridge (two surfaces facing each other, e.g. the middle of a gap between two
  solids, or the middle of a box's inside) crossing a cell: ≤ h/2, reached when the ridge
  plane is perpendicular to a grid axis and halfway between two nodes;
* a convex corner (three faces at right angles, e.g. a box vertex) inside a cell: ≤ 0.50·h
  when the box is grid-aligned, and ≤ 0.532·h for boxes rotated arbitrarily (numerical
  maximisation over rotation, vertex position and evaluation point; found at points within
  ~0.1·h of the vertex); the interpolated value is then too large.

So with the default 1 mm fine spacing the error is ≤ 0.5 mm everywhere except within about
0.1 mm of a convex corner of a rotated solid, where it can reach 0.53 mm; a fine spacing of
0.94 mm or less makes 0.5 mm a strict bound. In the coarse region (≥ 30 mm from the anatomy's
bounding box) there are no faces or corners, only ridges and smooth distance, so the error
there is ≤ h/2 = 3 mm for the default coarse spacing (see tests/test_sdf.py for the measured
values). Beyond the coarse box, ``|p − q| + value(q)`` is an upper bound of the distance; the
anatomy sits ≥ 400 mm inside that box, so its excess is a few % of |p − q| at most.

Long module: numba-compiled signed-distance kernels (boxes, triangle BVH, grids) with their accuracy analysis in the docstring.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit, prange

__all__ = ["AnatomyDistance", "DistanceGrid", "box_signed_distance", "grid_for_bounds"]


# --------------------------------------------------------------------------- grids

@dataclass(frozen=True)
class DistanceGrid:
    """Signed distance sampled on a regular grid (patient frame, mm).

    Attributes:
        origin: (3,) float64, position of node (0, 0, 0).
        spacing: node spacing, mm.
        values: (nx, ny, nz) float64, C-contiguous, values[i, j, k] = signed distance at
            ``origin + spacing * (i, j, k)``; every n >= 2.
    """

    origin: np.ndarray
    spacing: float
    values: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "origin", np.ascontiguousarray(self.origin, dtype=np.float64).reshape(3))
        object.__setattr__(self, "spacing", float(self.spacing))
        object.__setattr__(self, "values", np.ascontiguousarray(self.values, dtype=np.float64))
        if self.values.ndim != 3 or min(self.values.shape) < 2 or not self.spacing > 0:
            raise ValueError("DistanceGrid needs values of shape (nx, ny, nz), every n >= 2, and spacing > 0")

    @property
    def shape(self) -> tuple[int, int, int]:
        return self.values.shape  # type: ignore[return-value]

    @property
    def lo(self) -> np.ndarray:
        """Lower corner of the box of nodes."""
        return self.origin.copy()

    @property
    def hi(self) -> np.ndarray:
        """Upper corner of the box of nodes (the last node)."""
        return self.origin + self.spacing * (np.array(self.values.shape, dtype=np.float64) - 1.0)

    def contains(self, points: Any) -> np.ndarray:
        """(...,) bool: points inside the (closed) box of nodes."""
        p = np.asarray(points, dtype=np.float64)
        return np.all((p >= self.lo) & (p <= self.hi), axis=-1)

    def __call__(self, points: Any) -> np.ndarray:
        """Signed distance at ``points`` (..., 3) -> (...): trilinear inside, |p - q| + value(q) outside."""
        p = np.asarray(points, dtype=np.float64)
        if p.shape[-1:] != (3,):
            raise ValueError("points must have shape (..., 3)")
        flat = p.reshape(-1, 3)
        q = np.clip(flat, self.lo, self.hi)
        t = (q - self.origin) / self.spacing
        n = np.array(self.values.shape)
        i0 = np.clip(np.floor(t).astype(np.int64), 0, n - 2)
        f = t - i0
        v = self.values
        out = np.zeros(len(flat))
        for dx in (0, 1):
            wx = f[:, 0] if dx else 1.0 - f[:, 0]
            for dy in (0, 1):
                wy = f[:, 1] if dy else 1.0 - f[:, 1]
                for dz in (0, 1):
                    wz = f[:, 2] if dz else 1.0 - f[:, 2]
                    out += wx * wy * wz * v[i0[:, 0] + dx, i0[:, 1] + dy, i0[:, 2] + dz]
        out += np.linalg.norm(flat - q, axis=1)
        return out.reshape(p.shape[:-1])

    def nodes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The node coordinates along x, y and z (1-D arrays)."""
        return tuple(self.origin[a] + self.spacing * np.arange(self.values.shape[a]) for a in range(3))  # type: ignore[return-value]


def grid_for_bounds(lo: Sequence[float], hi: Sequence[float], spacing: float,
                    margin: float) -> tuple[np.ndarray, tuple[int, int, int]]:
    """Origin and shape of the grid of the given spacing that covers [lo − margin, hi + margin].

    Nodes sit on multiples of ``spacing``: origin = floor((lo − margin) / spacing) · spacing.
    """
    if not spacing > 0 or not margin >= 0:
        raise ValueError("spacing must be > 0 and margin >= 0")
    lo_a = np.asarray(lo, dtype=np.float64) - margin
    hi_a = np.asarray(hi, dtype=np.float64) + margin
    origin = np.floor(lo_a / spacing + 1e-9) * spacing
    n = np.ceil((hi_a - origin) / spacing - 1e-9).astype(np.int64) + 1
    n = np.maximum(n, 2)
    return origin, (int(n[0]), int(n[1]), int(n[2]))


# --------------------------------------------------------------------------- boxes, exact

def box_signed_distance(points: Any, centre: Any, half_extents: Any, rotation: Any) -> np.ndarray:
    """Exact signed distance (..., 3) -> (...) to the box ``centre + rotation @ u``, |u_i| <= half_extents[i]."""
    p = np.asarray(points, dtype=np.float64)
    local = (p - np.asarray(centre, dtype=np.float64)) @ np.asarray(rotation, dtype=np.float64)
    q = np.abs(local) - np.asarray(half_extents, dtype=np.float64)
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
    inside = np.minimum(q.max(axis=-1), 0.0)
    return outside + inside


def _box_arrays(boxes: Iterable[Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    centres, halves, rots = [], [], []
    for b in boxes:
        c, h, r = (np.asarray(a, dtype=np.float64) for a in tuple(b)[:3])
        if c.shape != (3,) or h.shape != (3,) or r.shape != (3, 3) or np.any(h < 0):
            raise ValueError("a box is (centre (3,), half_extents (3,) >= 0, rotation (3, 3))")
        if not np.allclose(r.T @ r, np.eye(3), atol=1e-9) or np.linalg.det(r) < 0:
            raise ValueError("a box rotation must be a rotation matrix")
        centres.append(c)
        halves.append(h)
        rots.append(r)
    if not centres:
        raise ValueError("no boxes")
    return np.array(centres), np.array(halves), np.ascontiguousarray(np.array(rots))


def _boxes_bounds(centres: np.ndarray, halves: np.ndarray, rots: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    ext = np.einsum("bij,bj->bi", np.abs(rots), halves)   # half-size of each box's axis-aligned bounds
    return (centres - ext).min(axis=0), (centres + ext).max(axis=0)


@njit(cache=True)
def _box_sd(dx, dy, dz, r00, r01, r02, r10, r11, r12, r20, r21, r22, hx, hy, hz):  # pragma: no cover
    """Exact signed distance of the offset d = p - centre to a box (rotation r, half-extents h); scalars only."""
    qx = abs(r00 * dx + r10 * dy + r20 * dz) - hx
    qy = abs(r01 * dx + r11 * dy + r21 * dz) - hy
    qz = abs(r02 * dx + r12 * dy + r22 * dz) - hz
    ox = max(qx, 0.0)
    oy = max(qy, 0.0)
    oz = max(qz, 0.0)
    return math.sqrt(ox * ox + oy * oy + oz * oz) + min(max(qx, max(qy, qz)), 0.0)


@njit(parallel=True, cache=True)
def _boxes_grid(origin, spacing, nx, ny, nz, centres, halves, rots, ext, min_half, out):  # pragma: no cover
    """min over boxes of the exact box distance at every node.

    The previous node's nearest box is tried first; another box b is skipped when a lower
    bound proves it cannot be smaller: outside, the distance to b's axis-aligned bounds
    (``ext``: their half-sizes); inside some box, b must contain p and reach deeper than
    ``min_half[b]`` allows.
    """
    nb = centres.shape[0]
    for i in prange(nx):
        x = origin[0] + spacing * i
        for j in range(ny):
            y = origin[1] + spacing * j
            last = 0
            for k in range(nz):
                z = origin[2] + spacing * k
                best = _box_sd(x - centres[last, 0], y - centres[last, 1], z - centres[last, 2],
                               rots[last, 0, 0], rots[last, 0, 1], rots[last, 0, 2],
                               rots[last, 1, 0], rots[last, 1, 1], rots[last, 1, 2],
                               rots[last, 2, 0], rots[last, 2, 1], rots[last, 2, 2],
                               halves[last, 0], halves[last, 1], halves[last, 2])
                arg = last
                for b in range(nb):
                    if b == last:
                        continue
                    ddx = max(abs(x - centres[b, 0]) - ext[b, 0], 0.0)
                    ddy = max(abs(y - centres[b, 1]) - ext[b, 1], 0.0)
                    ddz = max(abs(z - centres[b, 2]) - ext[b, 2], 0.0)
                    lb2 = ddx * ddx + ddy * ddy + ddz * ddz
                    if best >= 0.0:
                        if lb2 >= best * best:
                            continue
                    elif lb2 > 0.0 or -min_half[b] >= best:
                        continue
                    d = _box_sd(x - centres[b, 0], y - centres[b, 1], z - centres[b, 2],
                                rots[b, 0, 0], rots[b, 0, 1], rots[b, 0, 2],
                                rots[b, 1, 0], rots[b, 1, 1], rots[b, 1, 2],
                                rots[b, 2, 0], rots[b, 2, 1], rots[b, 2, 2],
                                halves[b, 0], halves[b, 1], halves[b, 2])
                    if d < best:
                        best = d
                        arg = b
                out[i, j, k] = best
                last = arg


def _boxes_on_grid(origin: np.ndarray, shape: tuple[int, int, int], spacing: float,
                   arrays: tuple[np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
    centres, halves, rots = arrays
    out = np.empty(shape, dtype=np.float64)
    ext = np.ascontiguousarray(np.einsum("bij,bj->bi", np.abs(rots), halves))
    _boxes_grid(origin, float(spacing), shape[0], shape[1], shape[2], centres, halves, rots, ext,
                np.ascontiguousarray(halves.min(axis=1)), out)
    return out


# --------------------------------------------------------------------------- meshes, exact

def _spread_bits(v: np.ndarray) -> np.ndarray:
    """10-bit integers -> every third bit (for Morton codes)."""
    v = v.astype(np.int64) & 0x3FF
    v = (v | (v << 16)) & 0x030000FF
    v = (v | (v << 8)) & 0x0300F00F
    v = (v | (v << 4)) & 0x030C30C3
    return (v | (v << 2)) & 0x09249249


def _bvh(tri: np.ndarray) -> tuple[Any, ...]:
    """Bounding-volume hierarchy over triangles (F, 3, 3), built with numpy.

    Triangles are sorted along a Morton curve of their centroids and grouped into leaves
    (1 triangle for small meshes, 4 above 256); adjacent nodes are then paired level by level.

    Returns:
        (order, node_lo, node_hi, left, right, first, count, root): leaf ``n`` holds the
        triangles ``order[first[n]:first[n] + count[n]]``; internal nodes have count 0.
    """
    n = len(tri)
    leaf = 1 if n <= 256 else 4
    lo_t, hi_t, cen = tri.min(axis=1), tri.max(axis=1), tri.mean(axis=1)
    c0 = cen.min(axis=0)
    span = np.maximum(cen.max(axis=0) - c0, 1e-300)
    q = np.clip(((cen - c0) / span * 1023.0).astype(np.int64), 0, 1023)
    code = (_spread_bits(q[:, 0]) << 2) | (_spread_bits(q[:, 1]) << 1) | _spread_bits(q[:, 2])
    order = np.argsort(code, kind="stable").astype(np.int64)
    starts = np.arange(0, n, leaf, dtype=np.int64)
    counts = np.diff(np.append(starts, n)).astype(np.int64)
    lo = [np.minimum.reduceat(lo_t[order], starts, axis=0)]
    hi = [np.maximum.reduceat(hi_t[order], starts, axis=0)]
    left = [np.full(len(starts), -1, dtype=np.int64)]
    right = [np.full(len(starts), -1, dtype=np.int64)]
    first, count = [starts], [counts]
    all_lo, all_hi = lo[0], hi[0]
    current = np.arange(len(starts), dtype=np.int64)
    next_id = len(starts)
    while len(current) > 1:
        m = len(current) // 2
        a, b = current[0:2 * m:2], current[1:2 * m:2]
        lo.append(np.minimum(all_lo[a], all_lo[b]))
        hi.append(np.maximum(all_hi[a], all_hi[b]))
        all_lo, all_hi = np.concatenate([all_lo, lo[-1]]), np.concatenate([all_hi, hi[-1]])
        left.append(a)
        right.append(b)
        first.append(np.zeros(m, dtype=np.int64))
        count.append(np.zeros(m, dtype=np.int64))
        ids = np.arange(next_id, next_id + m, dtype=np.int64)
        next_id += m
        current = np.append(ids, current[-1]) if len(current) % 2 else ids
    return (order, np.ascontiguousarray(all_lo), np.ascontiguousarray(all_hi), np.concatenate(left),
            np.concatenate(right), np.concatenate(first), np.concatenate(count), int(current[0]))


@njit(cache=True)
def _tri_dist2(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):  # pragma: no cover - compiled
    """Squared distance from p to triangle abc (Ericson, Real-Time Collision Detection 5.1.5).

    Scalar arguments only: passing arrays into a function called from a parallel loop costs
    an atomic reference count per call, which the two threads then fight over.
    """
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return apx * apx + apy * apy + apz * apz
    bpx, bpy, bpz = px - bx, py - by, pz - bz
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return bpx * bpx + bpy * bpy + bpz * bpz
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        qx, qy, qz = apx - v * abx, apy - v * aby, apz - v * abz
        return qx * qx + qy * qy + qz * qz
    cpx, cpy, cpz = px - cx, py - cy, pz - cz
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return cpx * cpx + cpy * cpy + cpz * cpz
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        qx, qy, qz = apx - w * acx, apy - w * acy, apz - w * acz
        return qx * qx + qy * qy + qz * qz
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        qx, qy, qz = bpx - w * (cx - bx), bpy - w * (cy - by), bpz - w * (cz - bz)
        return qx * qx + qy * qy + qz * qz
    denom = 1.0 / (va + vb + vc)
    v = vb * denom
    w = vc * denom
    qx = apx - v * abx - w * acx
    qy = apy - v * aby - w * acy
    qz = apz - v * abz - w * acz
    return qx * qx + qy * qy + qz * qz


@njit(parallel=True, cache=True)
def _mesh_grid_unsigned(origin, spacing, nx, ny, nz, skip, tri, order, node_lo, node_hi, left, right,
                        first, count, root, out):  # pragma: no cover - compiled
    """Exact distance from every grid node (not ``skip``) to the nearest triangle (BVH, warm start)."""
    for i in prange(nx):
        stack = np.empty(128, dtype=np.int64)
        px = origin[0] + spacing * i
        for j in range(ny):
            py = origin[1] + spacing * j
            last = -1
            for k in range(nz):
                if skip[i, j, k]:
                    continue
                pz = origin[2] + spacing * k
                best = np.inf
                best_t = -1
                if last >= 0:  # the previous node's nearest triangle: a tight first bound
                    best = _tri_dist2(px, py, pz, tri[last, 0, 0], tri[last, 0, 1], tri[last, 0, 2],
                                      tri[last, 1, 0], tri[last, 1, 1], tri[last, 1, 2],
                                      tri[last, 2, 0], tri[last, 2, 1], tri[last, 2, 2])
                    best_t = last
                stack[0] = root
                sp = 1
                while sp > 0:
                    sp -= 1
                    nd = stack[sp]
                    ddx = max(node_lo[nd, 0] - px, 0.0, px - node_hi[nd, 0])
                    ddy = max(node_lo[nd, 1] - py, 0.0, py - node_hi[nd, 1])
                    ddz = max(node_lo[nd, 2] - pz, 0.0, pz - node_hi[nd, 2])
                    if ddx * ddx + ddy * ddy + ddz * ddz >= best:
                        continue
                    if count[nd] > 0:
                        for m in range(first[nd], first[nd] + count[nd]):
                            t = order[m]
                            d2 = _tri_dist2(px, py, pz, tri[t, 0, 0], tri[t, 0, 1], tri[t, 0, 2],
                                            tri[t, 1, 0], tri[t, 1, 1], tri[t, 1, 2],
                                            tri[t, 2, 0], tri[t, 2, 1], tri[t, 2, 2])
                            if d2 < best:
                                best = d2
                                best_t = t
                    else:
                        a, b = left[nd], right[nd]
                        # visit the nearer child first: push it last
                        ax_ = 0.5 * (node_lo[a, 0] + node_hi[a, 0]) - px
                        ay_ = 0.5 * (node_lo[a, 1] + node_hi[a, 1]) - py
                        az_ = 0.5 * (node_lo[a, 2] + node_hi[a, 2]) - pz
                        bx_ = 0.5 * (node_lo[b, 0] + node_hi[b, 0]) - px
                        by_ = 0.5 * (node_lo[b, 1] + node_hi[b, 1]) - py
                        bz_ = 0.5 * (node_lo[b, 2] + node_hi[b, 2]) - pz
                        ca = ax_ * ax_ + ay_ * ay_ + az_ * az_
                        cb = bx_ * bx_ + by_ * by_ + bz_ * bz_
                        if ca < cb:
                            stack[sp] = b
                            stack[sp + 1] = a
                        else:
                            stack[sp] = a
                            stack[sp + 1] = b
                        sp += 2
                out[i, j, k] = math.sqrt(best)
                last = best_t


class _Shells:
    """The solids of a list of closed meshes: one per connected shell; BVHs over their triangles."""

    def __init__(self, meshes: Sequence[Any]) -> None:
        from arcube.io.meshes import split_shells

        # per shell: vertices, faces, triangles (F, 3, 3), bounds lo, hi, BVH
        self.shells: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, tuple]] = []
        for mesh in meshes:
            for shell in split_shells(mesh):
                v = np.ascontiguousarray(shell.vertices, dtype=np.float64)
                f = np.ascontiguousarray(shell.faces, dtype=np.int64)
                tri = np.ascontiguousarray(v[f])
                self.shells.append((v, f, tri, v.min(axis=0), v.max(axis=0), _bvh(tri)))
        if not self.shells:
            raise ValueError("no triangles in the meshes")
        self.tri = np.ascontiguousarray(np.concatenate([s[2] for s in self.shells]))
        self.lo = np.min([s[3] for s in self.shells], axis=0)
        self.hi = np.max([s[4] for s in self.shells], axis=0)
        self.bvh = _bvh(self.tri)

    def on_grid(self, origin: np.ndarray, shape: tuple[int, int, int], spacing: float) -> np.ndarray:
        """Exact signed distance of the union at the nodes of a grid.

        Per shell, at the nodes of its bounding box: the exact distance d_s to the shell
        (BVH). Two neighbouring nodes both farther than h/2 from the shell cannot have its
        surface between them (any point of the segment is within h/2 of one end), so inside/
        outside is constant on each 6-connected component of {d_s > h/2}: libigl's fast winding
        number is asked once per component and at every node with d_s <= h/2.
        """
        import igl
        from scipy import ndimage

        axes = [origin[a] + spacing * np.arange(shape[a]) for a in range(3)]
        depth = np.zeros(shape)
        inside = np.zeros(shape, dtype=bool)
        for v, f, tri, lo, hi, bvh in self.shells:
            sl = tuple(slice(int(np.searchsorted(axes[a], lo[a], side="left")),
                             int(np.searchsorted(axes[a], hi[a], side="right"))) for a in range(3))
            sub_shape = tuple(s.stop - s.start for s in sl)
            if min(sub_shape) <= 0:
                continue  # no node inside the shell's bounding box
            sub_origin = origin + spacing * np.array([s.start for s in sl], dtype=np.float64)
            d = np.empty(sub_shape)
            _mesh_grid_unsigned(sub_origin, float(spacing), sub_shape[0], sub_shape[1], sub_shape[2],
                                np.zeros(sub_shape, dtype=bool), tri, *bvh, d)
            safe = d > 0.5 * spacing * (1.0 + 1e-9)
            labels, n_comp = ndimage.label(safe)
            ins = np.zeros(sub_shape, dtype=bool)
            band = np.flatnonzero(~safe)
            query = [band]
            if n_comp:
                _, first = np.unique(labels.ravel(), return_index=True)
                query.append(first[1:] if labels.ravel()[first[0]] == 0 else first)
            flat_idx = np.concatenate(query)
            if len(flat_idx):
                ijk = np.column_stack(np.unravel_index(flat_idx, sub_shape)).astype(np.float64)
                w = igl.fast_winding_number(v, f, np.ascontiguousarray(sub_origin + spacing * ijk))
                is_in = w > 0.5
                ins.ravel()[band] = is_in[: len(band)]
                if n_comp:
                    comp_in = np.zeros(n_comp + 1, dtype=bool)
                    comp_in[labels.ravel()[flat_idx[len(band):]]] = is_in[len(band):]
                    ins |= comp_in[labels] & safe
            if ins.any():
                depth[sl] = np.where(ins, np.maximum(depth[sl], d), depth[sl])
                inside[sl] |= ins
        out = np.empty(shape)
        _mesh_grid_unsigned(origin, float(spacing), shape[0], shape[1], shape[2], inside, self.tri, *self.bvh, out)
        out[inside] = -depth[inside]
        return out


# --------------------------------------------------------------------------- the two-level lookup

@dataclass(frozen=True)
class AnatomyDistance:
    """Signed distance to the anatomy: a fine grid near it, a coarse one around it.

    Attributes:
        fine: grid over the anatomy's bounding box + ``fine_margin`` (default 1 mm spacing, 30 mm).
        coarse: grid over the bounding box + ``coarse_margin`` (default 6 mm spacing, 400 mm).
        bounds: (lo, hi), each (3,), the anatomy's axis-aligned bounding box (patient frame, mm).
    """

    fine: DistanceGrid
    coarse: DistanceGrid
    bounds: tuple[np.ndarray, np.ndarray]

    def __call__(self, points: Any) -> np.ndarray:
        """Signed distance (..., 3) -> (...): the fine grid where p is in its box, else the coarse one."""
        p = np.asarray(points, dtype=np.float64)
        if p.shape[-1:] != (3,):
            raise ValueError("points must have shape (..., 3)")
        flat = p.reshape(-1, 3)
        in_fine = self.fine.contains(flat)
        out = np.empty(len(flat))
        if in_fine.any():
            out[in_fine] = self.fine(flat[in_fine])
        if (~in_fine).any():
            out[~in_fine] = self.coarse(flat[~in_fine])
        return out.reshape(p.shape[:-1])

    @property
    def nbytes(self) -> int:
        """Memory held by the two grids' values, bytes."""
        return int(self.fine.values.nbytes + self.coarse.values.nbytes)

    @classmethod
    def from_meshes(cls, meshes: Sequence[Any], fine_spacing: float = 1.0, fine_margin: float = 30.0,
                    coarse_spacing: float = 6.0, coarse_margin: float = 400.0) -> AnatomyDistance:
        """Grids of the union of closed meshes (each connected shell is one solid).

        Node values are exact: the distance to each shell at the nodes of its bounding box and
        the distance of every node outside all shells to the nearest triangle, both by an
        exact search in a bounding-volume hierarchy (compiled); inside/outside of each shell by
        libigl's fast winding number near its surface and once per connected region away from
        it (see ``_Shells.on_grid``).
        """
        if not isinstance(meshes, (list, tuple)):
            meshes = [meshes]
        shells = _Shells(meshes)
        return cls._build(shells.lo, shells.hi, shells.on_grid, fine_spacing, fine_margin,
                          coarse_spacing, coarse_margin)

    @classmethod
    def from_boxes(cls, boxes: Iterable[Any], fine_spacing: float = 1.0, fine_margin: float = 30.0,
                   coarse_spacing: float = 6.0, coarse_margin: float = 400.0) -> AnatomyDistance:
        """Grids of a union of boxes, each ``(centre, half_extents, rotation)``, by the exact box formula."""
        arrays = _box_arrays(boxes)
        lo, hi = _boxes_bounds(*arrays)
        return cls._build(lo, hi, lambda o, s, h: _boxes_on_grid(o, s, h, arrays), fine_spacing, fine_margin,
                          coarse_spacing, coarse_margin)

    @classmethod
    def _build(cls, lo: np.ndarray, hi: np.ndarray, fill: Any, fine_spacing: float, fine_margin: float,
               coarse_spacing: float, coarse_margin: float) -> AnatomyDistance:
        grids = []
        for spacing, margin in ((fine_spacing, fine_margin), (coarse_spacing, coarse_margin)):
            origin, shape = grid_for_bounds(lo, hi, spacing, margin)
            grids.append(DistanceGrid(origin, spacing, fill(origin, shape, float(spacing))))
        return cls(grids[0], grids[1], (np.asarray(lo, dtype=np.float64).copy(), np.asarray(hi, dtype=np.float64).copy()))
