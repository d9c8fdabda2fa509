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
from arcube.evaluation.kernel._summary import _finalize


@njit(cache=True, parallel=True, error_model="numpy")
def _kernel(
    geometry,
    modes,
    E,
    e,
    same_e,
    opt,
    full,
    split,
    chunk,
    grids,
    body,
    envelope,
    failure,
    eta,
    excess,
    dexterity,
    assembly,
    extra,
    detail,
    summary,
):
    """All designs x all points: ``_design_points`` then ``_finalize`` per design (their docs give the
    arguments). Per-point outputs are (D, P) arrays (``extra`` (D, P, N_EXTRA)), ``summary`` (D, N_SUMM).
    With ``split`` (few designs) each design's points run in tiles of ``chunk`` over the threads, in the
    (D, P) arrays; with ``full`` the designs run in parallel in them. Otherwise (neither) the per-point
    arrays are (1, 1) placeholders and each design works in rows of its own: no D x P temporaries."""
    n_des = geometry.shape[0]
    n_pts = E.shape[0]
    # the point range as plain int64 in all three calls (not the constant 0 nor prange's uint64): one compiled
    # _design_points instead of three (numba specializes a callee on each constant argument and each integer type)
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
            _design_points(
                np.int64(i),
                np.int64(k0),
                np.int64(k1),
                geometry,
                modes,
                E,
                e,
                same_e,
                opt,
                full,
                grids,
                body,
                envelope,
                failure[i],
                eta[i],
                excess[i],
                assembly[i],
                extra[i],
                detail,
            )
        for i in prange(n_des):
            _finalize(
                single_assembly_mode,
                ik_last[i],
                failure[i],
                eta[i],
                excess[i],
                assembly[i],
                dexterity[i],
                extra[i],
                summary[i],
            )
    elif full:
        for i in prange(n_des):
            _design_points(
                np.int64(i),
                np.int64(0),
                np.int64(n_pts),
                geometry,
                modes,
                E,
                e,
                same_e,
                opt,
                full,
                grids,
                body,
                envelope,
                failure[i],
                eta[i],
                excess[i],
                assembly[i],
                extra[i],
                detail,
            )
            _finalize(
                single_assembly_mode,
                ik_last[i],
                failure[i],
                eta[i],
                excess[i],
                assembly[i],
                dexterity[i],
                extra[i],
                summary[i],
            )
    else:
        for i in prange(n_des):
            failure_i = np.empty(n_pts, np.int16)
            eta_i = np.empty(n_pts)
            excess_i = np.empty(n_pts)
            assembly_i = np.empty(n_pts, np.int8)
            dexterity_i = np.empty(n_pts)
            extra_i = np.empty((n_pts, _N_EXTRA))
            _design_points(
                np.int64(i),
                np.int64(0),
                np.int64(n_pts),
                geometry,
                modes,
                E,
                e,
                same_e,
                opt,
                full,
                grids,
                body,
                envelope,
                failure_i,
                eta_i,
                excess_i,
                assembly_i,
                extra_i,
                detail,
            )
            _finalize(
                single_assembly_mode,
                ik_last[i],
                failure_i,
                eta_i,
                excess_i,
                assembly_i,
                dexterity_i,
                extra_i,
                summary[i],
            )
