"""Per-design summaries: the global single-assembly-mode guard, eta_L, dexterity, eta_G, the violation
of model §16 (V_reach, the guard grade, V = V_reach + V_fit)."""

from __future__ import annotations

import numpy as np
from numba import njit

from arcube.evaluation.kernel._layout import CODE_SAM as _CODE_SAM
from arcube.evaluation.kernel._layout import INF as _INF
from arcube.evaluation.kernel._layout import MAXIMA, NAN as _NAN
from arcube.evaluation.kernel._layout import (
    S_CLEARANCE_MIN,
    S_DEXTERITY_MAX,
    S_DEXTERITY_MEAN,
    S_DEXTERITY_MIN,
    S_ETA_G,
)
from arcube.evaluation.kernel._layout import S_ENVELOPE_CLEARANCE_MIN, X_ENVELOPE_CLEARANCE_MM
from arcube.evaluation.kernel._layout import (
    S_GUARD_GRADE,
    S_N_BAD,
    S_REACHABLE_FRACTION,
    S_SELF_CLEARANCE_MIN,
    S_VIOLATION,
)
from arcube.evaluation.kernel._layout import S_VIOLATION_REACH, X_CLEARANCE_MM, X_GUARD_GRADE, X_SELF_CLEARANCE_MM
from arcube.evaluation.kernel._performance import _no_metrics
from arcube.evaluation.kernel._scalar import _pairwise_sum


@njit(cache=True, error_model="numpy")
def _finalize(single_assembly_mode, ik_last, rows, summary):
    """The global guard, then eta_L, dexterity and the summaries of one design, from its
    :class:`~arcube.evaluation.kernel._state.Rows` ``rows`` (P,).

    ``failure`` gains the single-assembly-mode failures; ``eta`` holds eta_raw and gets eta_L (+inf where
    unreachable); ``excess`` and ``assembly`` as ``_points._design_points`` wrote them; ``dexterity`` gets
    100 / eta_L (%, 0 where unreachable); ``extra`` (P, N_EXTRA) loses the tip metrics of the points that
    fail and its guard grade gains 1 at each point the IK solves outside the majority assembly mode (as
    ``reference._single_assembly_mode``); ``summary`` (N_SUMM,) gets the ``S_*`` columns. Failure codes
    1 .. ``ik_last`` are IK failures (CODE_IK_LAST, or CODE_Z_DYAD under model §16's amendment).
    """
    failure, eta, excess, assembly, dexterity, extra = rows
    n = failure.shape[0]
    if single_assembly_mode:
        counts = np.zeros(8, np.int64)
        for k in range(n):
            if failure[k] == 0:
                counts[assembly[k]] += 1
        ref = 0
        for c in range(1, 8):
            if counts[c] > counts[ref]:
                ref = c
        for k in range(n):
            if assembly[k] != ref and (failure[k] == 0 or failure[k] > ik_last):
                extra[k, X_GUARD_GRADE] = extra[k, X_GUARD_GRADE] + 1.0
                if failure[k] == 0:
                    failure[k] = _CODE_SAM
    n_bad = 0
    n_ik = 0
    dmin = _INF
    dmax = -_INF
    for k in range(n):
        if failure[k] == 0:
            dk = 100.0 / eta[k]
        else:
            n_bad += 1
            if failure[k] <= ik_last:
                n_ik += 1
            eta[k] = _INF
            dk = 0.0
        dexterity[k] = dk
        if dk < dmin:
            dmin = dk
        if dk > dmax:
            dmax = dk
    summary[S_N_BAD] = n_bad
    summary[S_REACHABLE_FRACTION] = 1.0 - n_bad / n
    if n_bad == 0:
        summary[S_ETA_G] = _pairwise_sum(eta) / n
    else:
        summary[S_ETA_G] = _INF
    summary[S_DEXTERITY_MIN] = dmin
    summary[S_DEXTERITY_MEAN] = _pairwise_sum(dexterity) / n
    summary[S_DEXTERITY_MAX] = dmax
    cmin = _INF
    smin = _INF
    emin = _INF
    graded = False
    for k in range(n):
        if extra[k, X_GUARD_GRADE] != 0.0:
            graded = True
        if failure[k] == 0:
            if extra[k, X_CLEARANCE_MM] < cmin:
                cmin = extra[k, X_CLEARANCE_MM]
            if extra[k, X_SELF_CLEARANCE_MM] < smin:
                smin = extra[k, X_SELF_CLEARANCE_MM]
            if extra[k, X_ENVELOPE_CLEARANCE_MM] < emin:
                emin = extra[k, X_ENVELOPE_CLEARANCE_MM]
        else:
            _no_metrics(extra[k])
    # model §16: V = V_reach + G / (1 + G) / (2n), G = (guard grades summed over the points) / n; the sum is
    # skipped where every grade is 0 (no guard, or all passed: a sum of zeros is 0.0)
    reach = 0.0 if n_ik == 0 else n_ik / n + _pairwise_sum(excess)
    grade = _pairwise_sum(extra[:, X_GUARD_GRADE]) if graded else 0.0
    G = grade / n
    summary[S_VIOLATION_REACH] = reach
    summary[S_GUARD_GRADE] = grade
    summary[S_VIOLATION] = reach + G / (1.0 + G) / (2.0 * n)
    summary[S_CLEARANCE_MIN] = cmin if cmin < _INF else _NAN
    summary[S_SELF_CLEARANCE_MIN] = smin if smin < _INF else _NAN
    summary[S_ENVELOPE_CLEARANCE_MIN] = emin if emin < _INF else _NAN
    # the maxima of model §15.5 over the reachable points
    for j in range(MAXIMA.shape[0]):
        col = MAXIMA[j, 1]
        vmax = -_INF
        for k in range(n):
            if failure[k] == 0 and extra[k, col] > vmax:
                vmax = extra[k, col]
        summary[MAXIMA[j, 0]] = vmax if vmax > -_INF else _NAN
