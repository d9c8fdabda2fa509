"""Size measures of a design over a task: the joints' skeleton and its bounding box (model §12.1's
compactness objectives ``links`` and ``bbox``)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from arcube.model import frames
from arcube.model.design import SLICES, full_params, unpack
from arcube.model.poses import LEG_PERM
from arcube.model.stages import tls

Array = NDArray[np.float64]

__all__ = ["bounding_box", "mechanism_points"]


def mechanism_points(params: Array, E: Array, e: Array) -> Array:
    """Joint positions in R_w ``(n, P, 11, 3)``: P_x, P_y, P_z, D_x, D_y, D_z, Q_x, Q_y, Q_z, C, C + r e.

    In R_m: P_u = -f_u u (fixed pivots); D_u = (-f_u + p_u a_u) u + p_u sqrt(1 - a_u^2) w with
    a_u = (u + f_u + r)/p_u the Eq 1 argument (clipped to [-1, 1] where a leg cannot reach);
    Q_u = C + r u; the centre C = E + L e of the spherical stage and the drill holder C + r e
    (model §3.1, 5.1, 13); then mapped to R_w by the mounting rotation and m.
    """
    params = full_params(np.atleast_2d(params))
    n, P = params.shape[0], E.shape[0]
    f, p, r = params[:, SLICES["f"]], params[:, SLICES["p"]], params[:, SLICES["r"]]
    g = unpack(params[:, None, :])
    E_m, e_m = frames.to_mechanism(g, E[None, :, :], e[None, :, :])  # (n, P, 3) each
    arg = np.clip(tls.ik_argument(E_m, f[:, None, :], p[:, None, :], r[:, None]), -1.0, 1.0)
    pts = np.zeros((n, P, 11, 3))
    for leg, (u, _, w) in enumerate(LEG_PERM):  # world axes u, w of each leg (model §1.2)
        pts[:, :, leg, u] = -f[:, None, leg]
        pts[:, :, 3 + leg, u] = -f[:, None, leg] + p[:, None, leg] * arg[..., leg]
        pts[:, :, 3 + leg, w] = p[:, None, leg] * np.sqrt(1.0 - arg[..., leg] ** 2)
        pts[:, :, 6 + leg, :] = E_m
        pts[:, :, 6 + leg, u] += r[:, None]
    pts[:, :, 9, :] = E_m
    pts[:, :, 10, :] = E_m + r[:, None, None] * e_m
    return frames.points_to_world(g, pts)


def bounding_box(params: Array, E: Array, e: Array) -> tuple[Array, Array]:
    """Axis-aligned box in R_w ``(lo, hi)`` each ``(n, 3)`` mm of :func:`mechanism_points` over the task."""
    pts = mechanism_points(params, E, e)
    return pts.min(axis=(1, 2)), pts.max(axis=(1, 2))
