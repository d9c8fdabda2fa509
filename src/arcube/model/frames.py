"""Mounting rotation and tool offset (model §13): the patient frame R_w <-> the mechanism frame R_m.

The axes of R_m are the columns of R = R_z(rz) R_y(ry) R_x(rx) (rotations about the fixed axes
of R_w: first x, then y, then z); its origin is m. A point X_w has mechanism coordinates
X_m = R^T (X_w - m), a direction d_w has d_m = R^T d_w. The stages are evaluated at the centre
C = E + L e of the spherical stage, not at the drill tip E (model §13.2).

With the four additions at 0 nothing is rotated or offset, and the results are those of the
paper's model bit for bit: where R = I or L = 0 the arrays pass through unchanged (``np.where``),
because multiplying by an identity would turn a -0.0 into +0.0 and move a branch cut.

Every function broadcasts over leading axes (designs, points).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.model.design import Geometry


def rotation_matrix(angles: ArrayLike) -> NDArray[np.float64]:
    """R = R_z(rz) R_y(ry) R_x(rx) ``(..., 3, 3)`` from ``angles`` ``(..., 3)`` = (rx, ry, rz) in rad."""
    a = np.asarray(angles, dtype=float)
    cx, cy, cz = np.cos(a[..., 0]), np.cos(a[..., 1]), np.cos(a[..., 2])
    sx, sy, sz = np.sin(a[..., 0]), np.sin(a[..., 1]), np.sin(a[..., 2])
    rows = [
        [cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx],
        [sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx],
        [-sy, cy * sx, cy * cx],
    ]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def is_unrotated(g: Geometry) -> NDArray[np.bool_]:
    """``(...)``: True where the three mounting angles are exactly 0 (R = I, the paper)."""
    return np.all(g.mount == 0.0, axis=-1)


def mount_rotation(g: Geometry) -> NDArray[np.float64]:
    """R ``(..., 3, 3)`` of each design: its columns are x_m, y_m, z_m in R_w."""
    return rotation_matrix(g.mount)


def _to_m(R: NDArray[np.float64], flat: NDArray[np.bool_], a: NDArray[np.float64]) -> NDArray[np.float64]:
    """R^T a where the design is rotated, a itself where R = I."""
    rotated = np.einsum("...ji,...j->...i", R, a)
    return np.where(flat[..., None], a, rotated)


def _to_w(R: NDArray[np.float64], flat: NDArray[np.bool_], a: NDArray[np.float64]) -> NDArray[np.float64]:
    """R a where the design is rotated, a itself where R = I."""
    rotated = np.einsum("...ij,...j->...i", R, a)
    return np.where(flat[..., None], a, rotated)


def centre(g: Geometry, E: ArrayLike, e: ArrayLike) -> NDArray[np.float64]:
    """The centre of the spherical stage C = E + L e in R_w ``(..., 3)`` mm (C = E exactly where L = 0)."""
    E_a, e_a = np.asarray(E, dtype=float), np.asarray(e, dtype=float)
    L = np.asarray(g.L, dtype=float)[..., None]
    return np.where(L == 0.0, E_a, E_a + L * e_a)


def to_mechanism(g: Geometry, E: ArrayLike, e: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The task in mechanism coordinates: (C_m = R^T (E + L e - m), e_m = R^T e), each ``(..., 3)``."""
    R, flat = mount_rotation(g), is_unrotated(g)
    C_m = _to_m(R, flat, centre(g, E, e) - g.m)
    e_m = _to_m(R, flat, np.asarray(e, dtype=float))
    return C_m, e_m


def points_to_world(g: Geometry, X_m: ArrayLike) -> NDArray[np.float64]:
    """Points ``(..., 3)`` or ``(..., k, 3)`` (with ``g`` broadcasting over ``...``) from R_m to R_w: m + R X_m."""
    X = np.asarray(X_m, dtype=float)
    extra = X.ndim - 1 - np.ndim(g.L)
    R, flat, m = mount_rotation(g), is_unrotated(g), g.m
    for _ in range(max(extra, 0)):
        R, flat, m = R[..., None, :, :], flat[..., None], m[..., None, :]
    return _to_w(R, flat, X) + m


def directions_to_world(g: Geometry, d_m: ArrayLike) -> NDArray[np.float64]:
    """Directions ``(..., 3)`` or ``(..., k, 3)`` from R_m to R_w: R d_m."""
    d = np.asarray(d_m, dtype=float)
    extra = d.ndim - 1 - np.ndim(g.L)
    R, flat = mount_rotation(g), is_unrotated(g)
    for _ in range(max(extra, 0)):
        R, flat = R[..., None, :, :], flat[..., None]
    return _to_w(R, flat, d)


def directions_to_mechanism(g: Geometry, d_w: ArrayLike) -> NDArray[np.float64]:
    """Directions ``(..., 3)`` from R_w to R_m: R^T d_w."""
    return _to_m(mount_rotation(g), is_unrotated(g), np.asarray(d_w, dtype=float))
