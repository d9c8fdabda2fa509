"""The parallel driver: every design x every point, in tiles of points when designs are few."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from arcube.evaluation.kernel._layout import N_EXTRA as _N_EXTRA
from arcube.evaluation.kernel._layout import O_SAM as _O_SAM
from arcube.evaluation.kernel._points import _design_points
from arcube.evaluation.kernel._summary import _finalize


@njit(cache=True, parallel=True, error_model="numpy")
def _kernel(geo, modes, E, e, same_e, opt, full, split, chunk, fo, fh, fv, co, ch, cv, fg, cg, radius, order, pairs,
            fail_o, eta_o, exc_o, dex_o, code_o, extra_o, kappa_o, rho_o, delta_o, sigma_o, summ):  # fmt: skip
    """All designs x all points. With ``split`` (or ``full``), the per-point rows live in the
    (D, P) arrays; otherwise each design works in rows of its own (no D x P temporaries)."""
    n_des = geo.shape[0]
    n_pts = E.shape[0]
    sam = opt[_O_SAM] != 0.0
    if split:
        n_chunk = (n_pts + chunk - 1) // chunk
        for tile in prange(n_des * n_chunk):
            i = tile // n_chunk
            k0 = (tile % n_chunk) * chunk
            k1 = min(n_pts, k0 + chunk)
            _design_points(i, k0, k1, geo, modes, E, e, same_e, opt, full, fo, fh, fv, co, ch, cv, fg, cg, radius, order, pairs,
                           fail_o[i], eta_o[i], exc_o[i], code_o[i], extra_o[i], kappa_o, rho_o, delta_o, sigma_o)  # fmt: skip
        for i in prange(n_des):
            _finalize(sam, fail_o[i], eta_o[i], exc_o[i], code_o[i], dex_o[i], extra_o[i], summ[i])
    elif full:
        for i in prange(n_des):
            _design_points(i, 0, n_pts, geo, modes, E, e, same_e, opt, full, fo, fh, fv, co, ch, cv, fg, cg, radius, order, pairs,
                           fail_o[i], eta_o[i], exc_o[i], code_o[i], extra_o[i], kappa_o, rho_o, delta_o, sigma_o)  # fmt: skip
            _finalize(sam, fail_o[i], eta_o[i], exc_o[i], code_o[i], dex_o[i], extra_o[i], summ[i])
    else:
        for i in prange(n_des):
            fail = np.empty(n_pts, np.int16)
            eta = np.empty(n_pts)
            exc = np.empty(n_pts)
            code = np.empty(n_pts, np.int8)
            dex = np.empty(n_pts)
            extra = np.empty((n_pts, _N_EXTRA))
            _design_points(i, 0, n_pts, geo, modes, E, e, same_e, opt, full, fo, fh, fv, co, ch, cv, fg, cg, radius, order, pairs,
                           fail, eta, exc, code, extra, kappa_o, rho_o, delta_o, sigma_o)  # fmt: skip
            _finalize(sam, fail, eta, exc, code, dex, extra, summ[i])

