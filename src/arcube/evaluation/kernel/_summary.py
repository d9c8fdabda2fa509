"""Per-design summaries: the global single-assembly-mode guard, eta_L, dexterity, eta_G, violation."""

from __future__ import annotations

import numpy as np
from numba import njit

from arcube.evaluation.kernel._layout import CODE_SAM as _CODE_SAM
from arcube.evaluation.kernel._layout import INF as _INF
from arcube.evaluation.kernel._layout import NAN as _NAN
from arcube.evaluation.kernel._layout import S_CMIN as _S_CMIN, S_SMIN as _S_SMIN
from arcube.evaluation.kernel._layout import S_PERF as _S_PERF, X_PERF as _X_PERF
from arcube.evaluation.kernel._layout import S_DMAX as _S_DMAX, S_DMEAN as _S_DMEAN, S_DMIN as _S_DMIN, S_ETAG as _S_ETAG
from arcube.evaluation.kernel._layout import S_NBAD as _S_NBAD, S_RF as _S_RF, S_VIOL as _S_VIOL
from arcube.evaluation.kernel._scalar import _pairwise_sum


@njit(cache=True, error_model="numpy")
def _finalize(sam, fail, eta, exc, code, dex, extra, summ):
    """Global guard, then eta_L, dexterity and the summaries of one design (rows of length P)."""
    n = fail.shape[0]
    if sam:
        counts = np.zeros(8, np.int64)
        for k in range(n):
            if fail[k] == 0:
                counts[code[k]] += 1
        ref = 0
        for c in range(1, 8):
            if counts[c] > counts[ref]:
                ref = c
        for k in range(n):
            if fail[k] == 0 and code[k] != ref:
                fail[k] = _CODE_SAM
    n_bad = 0
    dmin = _INF
    dmax = -_INF
    for k in range(n):
        if fail[k] == 0:
            dk = 100.0 / eta[k]
        else:
            n_bad += 1
            eta[k] = _INF
            dk = 0.0
        dex[k] = dk
        if dk < dmin:
            dmin = dk
        if dk > dmax:
            dmax = dk
    frac_bad = n_bad / n
    summ[_S_NBAD] = n_bad
    summ[_S_RF] = 1.0 - frac_bad
    if n_bad == 0:
        summ[_S_ETAG] = _pairwise_sum(eta) / n
        summ[_S_VIOL] = 0.0
    else:
        summ[_S_ETAG] = _INF
        summ[_S_VIOL] = frac_bad + _pairwise_sum(exc)
    summ[_S_DMIN] = dmin
    summ[_S_DMEAN] = _pairwise_sum(dex) / n
    summ[_S_DMAX] = dmax
    cmin = _INF
    smin = _INF
    for k in range(n):
        if fail[k] == 0:
            if extra[k, 0] < cmin:
                cmin = extra[k, 0]
            if extra[k, 2] < smin:
                smin = extra[k, 2]
    summ[_S_CMIN] = cmin if cmin < _INF else _NAN
    summ[_S_SMIN] = smin if smin < _INF else _NAN
    # maxima of MODEL.md 15.5 over the reachable points (extra columns 0-4 and 6 of the metrics)
    for j in range(6):
        col = _X_PERF + (j if j < 5 else 6)
        vmax = -_INF
        for k in range(n):
            if fail[k] == 0:
                if extra[k, col] > vmax:
                    vmax = extra[k, col]
            else:
                for q in range(7):
                    extra[k, _X_PERF + q] = _NAN
                extra[k, _X_PERF + 5] = -1.0
        summ[_S_PERF + j] = vmax if vmax > -_INF else _NAN


