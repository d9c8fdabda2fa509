"""The parallel driver: every design x every point, in tiles of points when designs are few."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from arcube.evaluation.kernel._layout import CODE_IK_LAST as _CODE_IK_LAST
from arcube.evaluation.kernel._layout import CODE_Z_DYAD as _CODE_Z_DYAD
from arcube.evaluation.kernel._layout import G_C_Z as _G_C_Z
from arcube.evaluation.kernel._layout import N_EXTRA as _N_EXTRA
from arcube.evaluation.kernel._layout import O_Z_DYAD as _O_Z_DYAD
from arcube.evaluation.kernel._layout import O_SINGLE_ASSEMBLY_MODE as _O_SAM
from arcube.evaluation.kernel._points import _design_points
from arcube.evaluation.kernel._state import Rows
from arcube.evaluation.kernel._summary import _finalize


@njit(cache=True, error_model="numpy")
def _design_rows(per_point, i):
    """Design i's :class:`~arcube.evaluation.kernel._state.Rows`: row i of each (D, P) array of ``per_point``."""
    return Rows(
        per_point.failure[i],
        per_point.eta[i],
        per_point.excess[i],
        per_point.assembly[i],
        per_point.dexterity[i],
        per_point.extra[i],
    )


@njit(cache=True, error_model="numpy")
def _own_rows(n_pts):
    """New :class:`~arcube.evaluation.kernel._state.Rows` of ``n_pts`` points, for a design that keeps no (D, P) row."""
    return Rows(
        np.empty(n_pts, np.int16),
        np.empty(n_pts),
        np.empty(n_pts),
        np.empty(n_pts, np.int8),
        np.empty(n_pts),
        np.empty((n_pts, _N_EXTRA)),
    )


@njit(cache=True, parallel=True, error_model="numpy")
def _kernel(inputs, grids, body, envelope, split, chunk, per_point, detail, summary):
    """All designs x all points: ``_design_points`` then ``_finalize`` per design (their docs give the
    arguments). ``per_point``: :class:`~arcube.evaluation.kernel._state.Rows` of (D, P) arrays (``extra``
    (D, P, N_EXTRA)), ``summary`` (D, N_SUMM).
    With ``split`` (few designs) each design's points run in tiles of ``chunk`` over the threads, in the
    (D, P) arrays; with ``inputs.full`` the designs run in parallel in them. Otherwise (neither) the per-point
    arrays are (1, 1) placeholders and each design works in rows of its own: no D x P temporaries."""
    geometry, opt, full = inputs.geometry, inputs.opt, inputs.full
    n_des = geometry.shape[0]
    n_pts = inputs.E.shape[0]
    # the point range as plain int64 in both calls (not the constant 0 nor prange's uint64): one compiled
    # _design_points instead of several (numba specializes a callee on each constant argument and each integer type)
    single_assembly_mode = opt[_O_SAM] != 0.0
    # the last IK failure code per design: the z dyad's too for a design with its own c_z (model §16's amendment)
    ik_last = np.empty(n_des, np.int64)
    for i in range(n_des):
        own = opt[_O_Z_DYAD] != 0.0 and geometry[i, _G_C_Z] == geometry[i, _G_C_Z]
        ik_last[i] = _CODE_Z_DYAD if own else _CODE_IK_LAST
    if split:
        n_chunk = (n_pts + chunk - 1) // chunk
        for tile in prange(n_des * n_chunk):
            i = tile // n_chunk
            k0 = (tile % n_chunk) * chunk
            k1 = min(n_pts, k0 + chunk)
            rows = _design_rows(per_point, i)
            _design_points(np.int64(i), np.int64(k0), np.int64(k1), inputs, grids, body, envelope, rows, detail)
        for i in prange(n_des):
            _finalize(single_assembly_mode, ik_last[i], _design_rows(per_point, i), summary[i])
    else:
        for i in prange(n_des):
            rows = _design_rows(per_point, i) if full else _own_rows(n_pts)
            _design_points(np.int64(i), np.int64(0), np.int64(n_pts), inputs, grids, body, envelope, rows, detail)
            _finalize(single_assembly_mode, ik_last[i], rows, summary[i])
