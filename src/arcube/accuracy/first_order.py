"""First-order accuracy budget (model §20.3): the NumPy reference of the compiled kernel.

At a plan point the drill tip and axis of the built robot move, to first order, by G_E delta and
G_e delta, where delta ``(n,)`` holds the deviation of every error source
(:data:`arcube.accuracy.sources.SOURCE_NAMES`, in mm or deg) and the columns of G_E, G_e ``(3, n)`` are
the derivatives of the FK (:mod:`arcube.model.sensitivity`): a parameter's own column, a joint
source's J_E / J_e column (the zero offset, encoder and backlash of one joint share it). Over the box
|delta_i| <= T_i:

* worst lateral = max over the box of |P_perp G_E delta|: the farthest vertex of the zonogon
  sum_i [-1, 1] T_i P_perp G_E,i in the plane perpendicular to e (:func:`zonogon_radius`, exact, O(n log n));
* worst axis = the same with G_e (its columns are perpendicular to e), in degrees;
* worst axial = sum_i T_i |e^T G_E,i|;
* RMS lateral = sqrt(sum_i sigma_i^2 |P_perp G_E,i|^2), sigma_i = T_i/sqrt(3) (uniform) or T_i/3 (normal);
* share of source i = sigma_i^2 |P_perp G_E,i|^2 / sum_j sigma_j^2 |P_perp G_E,j|^2 (0 where the sum is 0).

Every function broadcasts over leading axes (points; designs x points).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.accuracy.sources import IS_ANGLE, JOINT_COLUMN, PARAM_COLUMN
from arcube.evaluation.performance import spin_free_basis
from arcube.model.mechanism import DEFAULT_MODE
from arcube.model.sensitivity import pose_derivatives

_DEG = np.pi / 180.0


class FirstOrder(NamedTuple):
    """The first-order budget per point; fields ``(...)`` unless noted, NaN where the point is not reachable."""

    lateral_wc_mm: NDArray[np.float64]  # worst lateral error over the tolerance box
    axis_wc_deg: NDArray[np.float64]  # worst axis error
    axial_wc_mm: NDArray[np.float64]  # worst axial error
    lateral_rms_mm: NDArray[np.float64]  # RMS lateral error
    share: NDArray[np.float64]  # (..., n) each source's share of the lateral variance, sums to 1 (or 0)
    G_E: NDArray[np.float64]  # (..., 3, n) d E_real / d delta, mm per mm or per deg
    G_e: NDArray[np.float64]  # (..., 3, n) d e_real / d delta, per mm or per deg
    valid: NDArray[np.bool_]  # (...) the IK reaches the point and the derivatives are finite


def source_jacobians(
    params: ArrayLike, E: ArrayLike, e: ArrayLike, mode: ArrayLike = DEFAULT_MODE
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """(G_E, G_e, valid): G ``(..., 3, n)`` in R_w per unit of each source (mm, or deg), at the poses
    (E, e) ``(..., 3)`` reached in working mode ``mode``, for designs ``params`` ``(..., 27)``."""
    d = pose_derivatives(params, E, e, mode)
    is_param = PARAM_COLUMN >= 0
    scale = np.where(IS_ANGLE, _DEG, 1.0)  # per rad -> per deg
    G_E = (
        np.where(is_param, d.dE_dp[..., np.maximum(PARAM_COLUMN, 0)], d.dE_dq[..., np.maximum(JOINT_COLUMN, 0)]) * scale
    )
    G_e = (
        np.where(is_param, d.de_dp[..., np.maximum(PARAM_COLUMN, 0)], d.de_dq[..., np.maximum(JOINT_COLUMN, 0)]) * scale
    )
    return G_E, G_e, d.valid


def zonogon_radius(H: ArrayLike) -> NDArray[np.float64]:
    """max over s in [-1, 1]^n of |H s| for H ``(..., 2, n)``: the farthest vertex of the zonogon of the
    generators h_i (columns of H), exactly.

    Each h_i is turned into the upper half-plane (h and -h span the same segment), the generators are
    sorted by angle, and the vertices are -sum h + 2 (h_(1) + ... + h_(k)), k = 0..n, and their
    negatives (O(n log n)). NaN where H has a NaN.
    """
    h = np.asarray(H, dtype=float)
    x, y = h[..., 0, :], h[..., 1, :]
    flip = (y < 0.0) | ((y == 0.0) & (x < 0.0))
    x, y = np.where(flip, -x, x), np.where(flip, -y, y)
    order = np.argsort(np.arctan2(y, x), axis=-1, kind="stable")
    xs, ys = np.take_along_axis(x, order, axis=-1), np.take_along_axis(y, order, axis=-1)
    zero = np.zeros(xs.shape[:-1] + (1,))
    vx = 2.0 * np.concatenate([zero, np.cumsum(xs, axis=-1)], axis=-1) - np.sum(xs, axis=-1, keepdims=True)
    vy = 2.0 * np.concatenate([zero, np.cumsum(ys, axis=-1)], axis=-1) - np.sum(ys, axis=-1, keepdims=True)
    r = np.max(np.hypot(vx, vy), axis=-1)
    return np.where(np.any(np.isnan(h), axis=(-2, -1)), np.nan, r)


def budget_from_jacobians(
    G_E: ArrayLike, G_e: ArrayLike, e: ArrayLike, T: ArrayLike, sigma: ArrayLike, valid: ArrayLike | None = None
) -> FirstOrder:
    """The budget of model §20.3 from G_E, G_e ``(..., 3, n)``, unit axes ``e`` ``(..., 3)`` (R_w), tolerances
    ``T`` and standard deviations ``sigma`` ``(..., n)`` (mm or deg, as the columns of G)."""
    GE, Ge = np.asarray(G_E, dtype=float), np.asarray(G_e, dtype=float)
    ea = np.asarray(e, dtype=float)
    ea = ea / np.linalg.norm(ea, axis=-1, keepdims=True)
    T_, s_ = np.asarray(T, dtype=float), np.asarray(sigma, dtype=float)
    b = spin_free_basis(ea)  # (..., 3, 2): the plane perpendicular to e
    lat = np.swapaxes(b, -1, -2) @ GE  # (..., 2, n): P_perp G_E in that plane
    ax = np.swapaxes(b, -1, -2) @ Ge
    along = np.einsum("...i,...ij->...j", ea, GE)  # e^T G_E,i
    var = s_ * s_ * np.sum(lat * lat, axis=-2)  # (..., n)
    total = np.sum(var, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(total > 0.0, var / total, 0.0)
    ok = np.all(np.isfinite(GE), axis=(-2, -1)) & np.all(np.isfinite(Ge), axis=(-2, -1))
    if valid is not None:
        ok = ok & np.asarray(valid)
    lead = ok.shape

    def masked(a: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.where(ok[..., None] if a.ndim > len(lead) else ok, a, np.nan)

    return FirstOrder(
        lateral_wc_mm=masked(zonogon_radius(lat * T_[..., None, :])),
        axis_wc_deg=masked(np.rad2deg(zonogon_radius(ax * T_[..., None, :]))),
        axial_wc_mm=masked(np.sum(T_ * np.abs(along), axis=-1)),
        lateral_rms_mm=masked(np.sqrt(total[..., 0])),
        share=masked(share),
        G_E=GE,
        G_e=Ge,
        valid=ok,
    )


def first_order(
    params: ArrayLike, E: ArrayLike, e: ArrayLike, mode: ArrayLike, T: ArrayLike, sigma: ArrayLike
) -> FirstOrder:
    """The first-order budget (model §20.3) of designs ``(..., 27)`` at poses (E, e) ``(..., 3)`` in R_w reached
    in working mode ``mode``, with tolerances ``T`` and standard deviations ``sigma`` ``(..., n)`` (mm, deg)."""
    G_E, G_e, valid = source_jacobians(params, E, e, mode)
    return budget_from_jacobians(G_E, G_e, e, T, sigma, valid)
