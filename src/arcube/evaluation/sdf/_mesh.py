"""Exact signed distance to closed triangle meshes: a bounding-volume hierarchy (NumPy), the compiled
point-to-triangle search (``_tri_dist2``, ``_mesh_grid_unsigned``) and inside/outside per shell (``_Shells``)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numba import njit, prange


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
        a, b = current[0 : 2 * m : 2], current[1 : 2 * m : 2]
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
    return (
        order,
        np.ascontiguousarray(all_lo),
        np.ascontiguousarray(all_hi),
        np.concatenate(left),
        np.concatenate(right),
        np.concatenate(first),
        np.concatenate(count),
        int(current[0]),
    )


@njit(cache=True)
def _corner(s, t, u, v, qx, qy, qz, apx, apy, apz, ex, ey, ez):  # pragma: no cover - compiled
    """Ericson's tests of the regions of corner b and of edge ab, in :func:`_tri_dist2`'s order, with b and c
    swapped those of corner c and edge ac: (in one of them, squared distance, the barycentric area vc or vb).

    q = p - b, ap = p - a, e = b - a; s, t: (b - a).q and (c - a).q; u, v: (b - a).ap and (c - a).ap.
    """
    if s >= 0.0 and t <= s:
        return True, qx * qx + qy * qy + qz * qz, 0.0
    area = u * t - s * v
    if area <= 0.0 and u >= 0.0 and s <= 0.0:
        x = u / (u - s)
        rx, ry, rz = apx - x * ex, apy - x * ey, apz - x * ez
        return True, rx * rx + ry * ry + rz * rz, area
    return False, 0.0, area


@njit(cache=True)
def _tri_dist2(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):  # pragma: no cover - compiled
    """Squared distance from p to triangle abc (Ericson, Real-Time Collision Detection 5.1.5).

    Scalar arguments only: passing arrays into a function called from a parallel loop costs
    an atomic reference count per call, which the two threads then fight over.
    """
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1, d2 = abx * apx + aby * apy + abz * apz, acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return apx * apx + apy * apy + apz * apz
    bpx, bpy, bpz = px - bx, py - by, pz - bz
    d3, d4 = abx * bpx + aby * bpy + abz * bpz, acx * bpx + acy * bpy + acz * bpz
    hit, dist2, vc = _corner(d3, d4, d1, d2, bpx, bpy, bpz, apx, apy, apz, abx, aby, abz)
    if hit:
        return dist2
    cpx, cpy, cpz = px - cx, py - cy, pz - cz
    d5, d6 = abx * cpx + aby * cpy + abz * cpz, acx * cpx + acy * cpy + acz * cpz
    hit, dist2, vb = _corner(d6, d5, d2, d1, cpx, cpy, cpz, apx, apy, apz, acx, acy, acz)
    if hit:
        return dist2
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


# inlined (numba IR) where it is called: a call with arrays from the parallel loop would cost an atomic
# reference count per call (see _tri_dist2)
@njit(cache=True, inline="always")
def _tri_dist2_of(px, py, pz, tri, t):  # pragma: no cover - compiled
    """:func:`_tri_dist2` from p to triangle ``t`` of ``tri`` (n, 3, 3)."""
    return _tri_dist2(
        px,
        py,
        pz,
        tri[t, 0, 0],
        tri[t, 0, 1],
        tri[t, 0, 2],
        tri[t, 1, 0],
        tri[t, 1, 1],
        tri[t, 1, 2],
        tri[t, 2, 0],
        tri[t, 2, 1],
        tri[t, 2, 2],
    )


@njit(parallel=True, cache=True)
def _mesh_grid_unsigned(
    origin, spacing, nx, ny, nz, skip, tri, order, node_lo, node_hi, left, right, first, count, root, out
):  # pragma: no cover - compiled
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
                    best = _tri_dist2_of(px, py, pz, tri, last)
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
                            d2 = _tri_dist2_of(px, py, pz, tri, t)
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

    def on_grid(self, origin: np.ndarray, shape: tuple[int, int, int], spacing: float, tick: Any = None) -> np.ndarray:
        """Exact signed distance of the union at the nodes of a grid; ``tick()`` (if given) is called after each shell
        and after the nodes outside every shell.

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
            sl = tuple(
                slice(
                    int(np.searchsorted(axes[a], lo[a], side="left")),
                    int(np.searchsorted(axes[a], hi[a], side="right")),
                )
                for a in range(3)
            )
            sub_shape = tuple(s.stop - s.start for s in sl)
            if min(sub_shape) <= 0:
                if tick is not None:
                    tick()
                continue  # no node inside the shell's bounding box
            sub_origin = origin + spacing * np.array([s.start for s in sl], dtype=np.float64)
            d = np.empty(sub_shape)
            _mesh_grid_unsigned(
                sub_origin,
                float(spacing),
                sub_shape[0],
                sub_shape[1],
                sub_shape[2],
                np.zeros(sub_shape, dtype=bool),
                tri,
                *bvh,
                d,
            )
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
                    comp_in[labels.ravel()[flat_idx[len(band) :]]] = is_in[len(band) :]
                    ins |= comp_in[labels] & safe
            if ins.any():
                depth[sl] = np.where(ins, np.maximum(depth[sl], d), depth[sl])
                inside[sl] |= ins
            if tick is not None:
                tick()
        out = np.empty(shape)
        _mesh_grid_unsigned(origin, float(spacing), shape[0], shape[1], shape[2], inside, self.tri, *self.bvh, out)
        out[inside] = -depth[inside]
        if tick is not None:
            tick()
        return out
