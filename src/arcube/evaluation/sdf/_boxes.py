"""Exact signed distance to a union of boxes: the NumPy formula and the compiled grid fill (``_boxes_grid``)."""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

import numpy as np
from numba import njit, prange


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
    ext = np.einsum("bij,bj->bi", np.abs(rots), halves)  # half-size of each box's axis-aligned bounds
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


# inlined (numba IR) where it is called: a call with arrays from the parallel loop would cost an atomic
# reference count per call, which the threads fight over
@njit(cache=True, inline="always")
def _box_sd_of(x, y, z, centres, rots, halves, b):  # pragma: no cover
    """:func:`_box_sd` of the point (x, y, z) to box ``b`` of the arrays of :func:`_box_arrays`."""
    return _box_sd(
        x - centres[b, 0],
        y - centres[b, 1],
        z - centres[b, 2],
        rots[b, 0, 0],
        rots[b, 0, 1],
        rots[b, 0, 2],
        rots[b, 1, 0],
        rots[b, 1, 1],
        rots[b, 1, 2],
        rots[b, 2, 0],
        rots[b, 2, 1],
        rots[b, 2, 2],
        halves[b, 0],
        halves[b, 1],
        halves[b, 2],
    )


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
                best = _box_sd_of(x, y, z, centres, rots, halves, last)
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
                    d = _box_sd_of(x, y, z, centres, rots, halves, b)
                    if d < best:
                        best = d
                        arg = b
                out[i, j, k] = best
                last = arg


def _boxes_on_grid(
    origin: np.ndarray, shape: tuple[int, int, int], spacing: float, arrays: tuple[np.ndarray, np.ndarray, np.ndarray]
) -> np.ndarray:
    centres, halves, rots = arrays
    out = np.empty(shape, dtype=np.float64)
    ext = np.ascontiguousarray(np.einsum("bij,bj->bi", np.abs(rots), halves))
    _boxes_grid(
        origin,
        float(spacing),
        shape[0],
        shape[1],
        shape[2],
        centres,
        halves,
        rots,
        ext,
        np.ascontiguousarray(halves.min(axis=1)),
        out,
    )
    return out
