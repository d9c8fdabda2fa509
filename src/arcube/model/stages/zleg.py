"""The z leg's passive planar RRR dyad (model §6) [CHOICE + ADDITION].

The dyad (links d_z, c_z, axes along z) runs in the plane z = z_E + r from the crank tip
D_z, at (x, y) = (0, p_z cos rho_z), to Q_z = E + r z. It closes iff
|d_z - c_z| <= L_z <= d_z + c_z with L_z = sqrt(x_E^2 + (y_E - p_z cos rho_z)^2).
The paper never checks it; here it is a switchable guard, off by default.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def span(E_m: ArrayLike, rho_z: ArrayLike, p_z: ArrayLike) -> NDArray[np.float64]:
    """L_z (mm), the distance the dyad must span, ``(...)``; ``E_m`` ``(..., 3)`` in R_m."""
    Ea = np.asarray(E_m, dtype=float)
    return np.hypot(Ea[..., 0], Ea[..., 1] - np.asarray(p_z, dtype=float) * np.cos(rho_z))


def closure_shortfall(L: ArrayLike, d_z: ArrayLike, c_z: ArrayLike) -> NDArray[np.float64]:
    """How far L_z lies outside [|d_z - c_z|, d_z + c_z], relative to d_z + c_z; 0 when the dyad closes."""
    L_, d_, c_ = (np.asarray(v, dtype=float) for v in (L, d_z, c_z))
    reach = d_ + c_
    return (np.maximum(L_ - reach, 0.0) + np.maximum(np.abs(d_ - c_) - L_, 0.0)) / reach
