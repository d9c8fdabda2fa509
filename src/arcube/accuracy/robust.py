"""Accuracy under manufacturing tolerances as a design figure (model §20.3): robust objectives and limits.

``lateral_error_wc`` and ``lateral_error_rms`` are, per design, the largest over the plan's points of the
first-order worst-case lateral error (the zonogon's farthest vertex) and of the RMS lateral error, under
the tolerances of a :class:`~arcube.accuracy.settings.ToleranceSettings` (ISO 2768-1 class m by default,
the joints' zero offsets, encoders and backlash). They are what ``arcube optimize --objectives
lateral_error_rms`` minimizes and what ``--max lateral_error_rms=0.5 --class f`` bounds, so that a design's
dimensions keep their accuracy once machined. The tolerances follow each design's own nominal sizes (ISO
2768-1 widens with the length), so a longer link also costs accuracy.

Two speeds of one figure: :func:`robust_errors` runs the compiled first order (Numba) design by design,
or the NumPy reference of :func:`arcube.accuracy.first_order.first_order` on the whole batch at once.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.accuracy.first_order import first_order
from arcube.accuracy.settings import ToleranceSettings
from arcube.accuracy.sources import sigmas

ROBUST_NAMES: tuple[str, str] = ("lateral_error_wc", "lateral_error_rms")
"""The robust figures, mm: worst case and RMS of the lateral error over the tolerance box (model §20.3)."""


def robust_errors(
    params: ArrayLike,
    modes: ArrayLike,
    E: ArrayLike,
    e: ArrayLike,
    settings: ToleranceSettings | None = None,
    engine: str = "numba",
    want: ArrayLike | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(lateral_error_wc, lateral_error_rms), each ``(D,)`` mm: the largest over the P points (E, e) ``(P, 3)``
    (R_w, mm) of each design ``params`` ``(D, 27)`` in its working mode ``modes`` ``(D, 4)`` (or one ``(4,)``).

    NaN for a design that misses a point (no first order there: the reach already makes it infeasible)
    and where ``want`` ``(D,)`` is False (not computed, to save time on designs already rejected).
    ``settings``: the tolerances (default: class m and model §20.1's joints); ``engine``: ``"numba"``
    (the compiled first order, one design at a time) or ``"numpy"`` (the reference, the batch at once).
    """
    s = ToleranceSettings() if settings is None else settings
    x = np.atleast_2d(np.asarray(params, dtype=float))
    D = x.shape[0]
    m = np.broadcast_to(np.asarray(modes, dtype=float), (D, 4))
    E_a, e_a = np.asarray(E, dtype=float).reshape(-1, 3), np.asarray(e, dtype=float).reshape(-1, 3)
    e_a = e_a / np.linalg.norm(e_a, axis=-1, keepdims=True)
    keep = np.ones(D, dtype=bool) if want is None else np.asarray(want, dtype=bool).reshape(D)
    wc, rms = np.full(D, np.nan), np.full(D, np.nan)
    idx = np.flatnonzero(keep)
    if idx.size == 0 or E_a.shape[0] == 0:
        return wc, rms
    T = s.tolerances(x[idx])  # (d, n): each design's own ISO tolerances
    sig = sigmas(T, s.distribution)
    if engine == "numpy":
        fo: Any = first_order(x[idx, None, :], E_a[None], e_a[None], m[idx, None, :], T[:, None, :], sig[:, None, :])
        lat, r, ok = np.asarray(fo.lateral_wc_mm), np.asarray(fo.lateral_rms_mm), np.asarray(fo.valid)
    else:
        from arcube.accuracy._kernel import first_order_numba

        parts = [first_order_numba(x[i], E_a, e_a, m[i], T[j], sig[j]) for j, i in enumerate(idx)]
        lat = np.stack([p.lateral_wc_mm for p in parts])
        r = np.stack([p.lateral_rms_mm for p in parts])
        ok = np.stack([p.valid for p in parts])
    every = ok.all(axis=1)
    wc[idx] = np.where(every, np.max(np.where(ok, lat, -np.inf), axis=1), np.nan)
    rms[idx] = np.where(every, np.max(np.where(ok, r, -np.inf), axis=1), np.nan)
    return wc, rms
