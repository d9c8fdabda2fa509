"""Compiled evaluation kernel (Numba): :func:`evaluate_task_numba` == :func:`arcube.evaluation.reference.evaluate_task`.

One fused pass per (design, point): TLS IK (Eq 1), RTS IK (MODEL.md 5.2), TMS IK (4.2), the
seven condition numbers by the closed forms of 8.1, the local guards of 8.2 and the graded
excess of 12.2. A design's points then get the global ``single_assembly_mode`` guard and the
summaries (w_G, eta_G, violation, dexterity statistics). Designs run in parallel (``prange``,
Numba's default thread count); when there are fewer than two designs per thread, the points
are split into chunks instead. With ``want_points=False`` no designs x points array exists.

Agreement with the NumPy reference. The code repeats the reference's operations in its order
(sums left to right, ``einsum``'s (p0 + p2) + p1, NumPy's pairwise summation over points, the
Python/NumPy float modulo of the angle wrap, the same NaN/inf conventions), with two kinds of
shortcut in the default (fast) path, each exact in real arithmetic:

* TLS: cos(rho) = sqrt((1 - arg)(1 + arg)) and sin(rho) = -arg instead of cos/sin(-asin(arg));
* TMS: R = sqrt(A^2 + B^2) instead of hypot(A, B); cos(delta), sin(delta) from the angle sum
  delta = atan2(B, A) + eps acos(arg), i.e. ((A arg - eps B s) / R, (B arg + eps A s) / R)
  with s = sqrt(1 - arg^2); the delta output is atan2(sin delta, cos delta), mapped to [-pi, pi).

That saves ~15 libm calls per point (the RTS, which depends on the drill direction only, is
computed once per run of equal directions, i.e. once per trajectory). The results then differ
from the reference by rounding only: ~1e-13 relative at ordinary points, growing like
eps * kappa and eps / (1 - arg^2) near a singularity or a TMS limit, which is also how much the
reference itself moves between NumPy builds (AVX-512 NumPy uses SVML for arcsin, arccos and
arctan2, one ulp away from libm). ``exact=True`` evaluates every trigonometric function as the
reference does: bit for bit equal to a NumPy that uses libm (e.g. ``NPY_DISABLE_CPU_FEATURES=
"X86_V4 AVX512_ICL"``), ~2x slower.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
from numba import get_num_threads
from numpy.typing import ArrayLike

from arcube.evaluation.kernel._cache import invalidate_stale_cache

invalidate_stale_cache()

from arcube.evaluation.kernel._clearance import block_gradients  # noqa: E402
from arcube.evaluation.kernel._driver import _kernel  # noqa: E402
from arcube.evaluation.kernel._layout import (
    CHUNK as _CHUNK, G_CA as _G_CA, G_CB as _G_CB, G_FLAT as _G_FLAT, G_L as _G_L, G_O as _G_O, G_ROT as _G_ROT, G_SA as _G_SA, G_SB as _G_SB, N_GEO as _N_GEO,
    N_OPT, N_SUMM as _N_SUMM, O_CZ as _O_CZ, O_EXACT as _O_EXACT, O_KM as _O_KM, O_KM_ON as _O_KM_ON, O_RHO as _O_RHO,
    O_RHO_ON as _O_RHO_ON, O_SAM as _O_SAM, O_TR as _O_TR, O_TR_ON as _O_TR_ON, O_ZDYAD as _O_ZDYAD,
    S_DMAX as _S_DMAX, S_DMEAN as _S_DMEAN, S_DMIN as _S_DMIN, S_ETAG as _S_ETAG, S_NBAD as _S_NBAD, S_RF as _S_RF,
    S_VIOL as _S_VIOL, S_CMIN as _S_CMIN, S_SMIN as _S_SMIN, N_EXTRA as _N_EXTRA, X_CLR as _X_CLR, X_PART as _X_PART,
    X_SELF as _X_SELF, O_ANAT, O_DO_CLR, O_DO_SELF, O_CLR, O_CLR_ON, O_LM, O_SELF, O_SELF_ON,
)  # fmt: skip
from arcube.evaluation.kernel._layout import O_CMIN_EXACT, O_PERF, O_PERF_ON, S_PERF, X_PERF  # noqa: E402
from arcube.evaluation.kernel._performance import perf_vector  # noqa: E402
from arcube.evaluation.performance import PERFORMANCE_FIELDS  # noqa: E402
from arcube.evaluation.reference import Options, PointResults, TaskResults
from arcube.evaluation.reference import evaluate_task as _evaluate_task_numpy
from arcube.model import frames
from arcube.model.body import PRIMITIVES, SELF_PAIRS, primitive_radii
from arcube.model.design import N_PAPER, N_PARAMS, full_params, unpack
from arcube.model.mechanism import DEFAULT_MODE

__all__ = ["evaluate_task_numba", "warm_up"]



def _owned(a: np.ndarray) -> np.ndarray:
    """C-contiguous, writeable float64 (one compiled signature: Numba types read-only arrays apart)."""
    c = np.ascontiguousarray(a, dtype=np.float64)
    return c if c.flags.writeable else c.copy()


def _geometry(params: np.ndarray) -> np.ndarray:
    """Per-design rows (D, N_GEO): lengths, offsets in rad, the trig of alpha, beta, the mounting
    rotation and L, computed with the same NumPy operations as arcube.model.design.unpack, the
    stage modules and arcube.model.frames."""
    x = full_params(params)
    o = np.deg2rad(x[:, 17:19])
    alpha = np.deg2rad(x[:, 19:21])
    beta = np.deg2rad(x[:, 21:23])
    geo = np.empty((x.shape[0], _N_GEO))
    geo[:, 0:17] = x[:, 0:17]
    geo[:, _G_O : _G_O + 2] = o
    geo[:, _G_SA : _G_SA + 2] = np.sin(alpha)
    geo[:, _G_CA : _G_CA + 2] = np.cos(alpha)
    geo[:, _G_CB : _G_CB + 2] = np.cos(beta)
    geo[:, _G_SB : _G_SB + 2] = np.sin(beta)
    g = unpack(x)
    geo[:, _G_ROT : _G_ROT + 9] = frames.mount_rotation(g).reshape(-1, 9)
    geo[:, _G_L] = g.L
    geo[:, _G_FLAT] = frames.is_unrotated(g)
    return geo


_PERF_COLUMNS = tuple(zip((0, 1, 2, 3, 4, 6), PERFORMANCE_FIELDS))
"""(column in the metrics block of ``extra``, PointResults field) of MODEL.md 15's metrics."""


def _option_vector(options: Options, exact: bool = False, anatomy: bool = False) -> np.ndarray:
    """The guards as numbers, thresholds computed as evaluation._guard_checks computes them."""
    opt = np.zeros(N_OPT)
    opt[_O_ZDYAD] = float(options.guards.z_dyad)
    opt[_O_CZ] = np.nan if options.guards.c_z is None else float(options.guards.c_z)
    if options.guards.rho_max_deg is not None:
        opt[_O_RHO_ON] = 1.0
        opt[_O_RHO] = np.deg2rad(options.guards.rho_max_deg)
    if options.guards.min_transmission_deg is not None:
        opt[_O_TR_ON] = 1.0
        opt[_O_TR] = np.sin(np.deg2rad(options.guards.min_transmission_deg))
    if options.guards.kappa_max is not None:
        opt[_O_KM_ON] = 1.0
        opt[_O_KM] = float(options.guards.kappa_max)
    opt[_O_SAM] = float(options.guards.single_assembly_mode)
    opt[_O_EXACT] = float(exact)
    opt[O_DO_SELF] = float(options.wants_self_clearance)
    opt[O_DO_CLR] = float(options.wants_clearance and anatomy)
    opt[O_ANAT] = float(anatomy)
    opt[O_CLR_ON] = float(options.guards.clearance_mm is not None and anatomy)
    opt[O_CLR] = options.guards.clearance_mm if options.guards.clearance_mm is not None else 0.0
    opt[O_SELF_ON] = float(options.guards.self_clearance_mm is not None)
    opt[O_SELF] = options.guards.self_clearance_mm if options.guards.self_clearance_mm is not None else 0.0
    opt[O_LM] = options.body.motor_length
    opt[O_PERF_ON] = float(options.outputs.tip_metrics)
    opt[O_CMIN_EXACT] = float(options.outputs.clearance_min_exact)
    opt[O_PERF:O_PERF + 12] = perf_vector(options.loads.encoder_deg, options.loads.thrust_N, options.loads.lateral_force_N, options.loads.actuator_stiffness)
    return opt


_NO_GRID = (np.zeros(3), 1.0, np.zeros((2, 2, 2)))
_NO_BLOCKS = np.zeros((1, 1, 1, 3))
# Primitives tried first by the anatomy search (a good early bound prunes the rest): the spherical
# arcs and the four-bar outputs sit nearest the centre C, then the couplers, inputs and the rest.
_ORDER = np.array([23, 24, 25, 26, 10, 11, 8, 9, 6, 7, 14, 15, 16, 17, 12, 13, 21, 22, 3, 4, 5, 18, 19, 20, 0, 1, 2], dtype=np.int64)
assert sorted(_ORDER.tolist()) == list(range(len(PRIMITIVES)))


_BLOCKS: dict[int, tuple[Any, np.ndarray, np.ndarray]] = {}
"""Block gradient bounds per anatomy (keyed by id, checked by identity): computed once per anatomy."""


def _body_context(options: Options, anatomy: Any) -> tuple[Any, ...]:
    """(grids, radius (27,), order, pairs) for the compiled body clearances."""
    if anatomy is None:
        grids = (*_NO_GRID, *_NO_GRID, _NO_BLOCKS, _NO_BLOCKS)
    else:
        f, c = anatomy.fine, anatomy.coarse
        blocks = _BLOCKS.get(id(anatomy))
        if blocks is None or blocks[0] is not anatomy:
            blocks = (anatomy, block_gradients(f.values, f.spacing), block_gradients(c.values, c.spacing))
            _BLOCKS[id(anatomy)] = blocks
        grids = (_owned(f.origin), float(f.spacing), _owned(f.values), _owned(c.origin), float(c.spacing), _owned(c.values),
                 blocks[1], blocks[2])  # fmt: skip
    return grids, primitive_radii(options.radii), _ORDER, SELF_PAIRS.astype(np.int64)


def evaluate_task_numba(
    params: ArrayLike, E: ArrayLike, e: ArrayLike, mode: ArrayLike = DEFAULT_MODE,
    options: Options = Options(), want_points: bool = True, *, exact: bool = False, anatomy: Any = None,
) -> TaskResults:  # fmt: skip
    """Same results as :func:`arcube.evaluation.reference.evaluate_task`, compiled (see the module doc).

    ``params`` ``(..., 27)`` (or ``(..., 23)``) mm/deg; ``E``, ``e`` ``(P, 3)``; ``mode`` broadcasting as ``(..., 4)``;
    results ``(batch..., P)`` per point and ``(batch...)`` per design, batch being the broadcast
    of ``params[..., :]`` and ``mode[..., :]``'s leading axes.
    With ``want_points=False`` the result's ``points`` is None (only the summaries are computed,
    with no designs x points arrays); the summaries are identical either way.
    ``exact=True`` evaluates every trigonometric function as the reference does (slower).
    ``anatomy``: an :class:`arcube.evaluation.sdf.AnatomyDistance` for the clearance of MODEL.md 14.3.
    E or e not 2-D, no points or no designs: handed to the NumPy reference.
    """
    p = np.asarray(params, dtype=float)
    m = np.asarray(mode, dtype=float)
    E_a = np.asarray(E, dtype=float)
    e_a = np.asarray(e, dtype=float)
    if p.ndim < 1 or p.shape[-1] not in (N_PAPER, N_PARAMS):
        raise ValueError(f"design array must have last axis {N_PARAMS} (or {N_PAPER}), got shape {p.shape}")
    p = full_params(p)
    if m.ndim < 1 or m.shape[-1] != 4:
        raise ValueError(f"mode must have last axis 4, got shape {m.shape}")
    if E_a.ndim != 2 or e_a.ndim != 2 or E_a.shape[-1] != 3 or e_a.shape[-1] != 3:
        return _evaluate_task_numpy(p, E_a, e_a, m, options, anatomy)
    E_b, e_b = np.broadcast_arrays(E_a, e_a)
    batch = np.broadcast_shapes(p.shape[:-1], m.shape[:-1])
    n_des = math.prod(batch)
    n_pts = E_b.shape[0]
    if n_pts == 0 or n_des == 0:
        return _evaluate_task_numpy(p, E_a, e_a, m, options, anatomy)

    pf = _owned(np.broadcast_to(p, batch + (N_PARAMS,)).reshape(n_des, N_PARAMS))
    mf = _owned(np.broadcast_to(m, batch + (4,)).reshape(n_des, 4))
    Ec = _owned(E_b)
    ec = _owned(e_b)
    same_e = np.zeros(n_pts, dtype=np.bool_)
    bits = ec.view(np.int64)  # bitwise: -0.0 and 0.0 may take different RTS branches
    same_e[1:] = np.all(bits[1:] == bits[:-1], axis=-1)
    geo = _geometry(pf)
    # the fast path's angle-sum identities hold for signs only; other values (meaningless,
    # but accepted by the reference) take the reference's formulas
    exact = exact or not bool(np.all(np.abs(mf) == 1.0))
    opt = _option_vector(options, exact, anatomy is not None)
    body = _body_context(options, anatomy)

    n_threads = get_num_threads()
    split = n_des < 2 * n_threads and n_pts >= 2 * _CHUNK
    full = bool(want_points)
    rows = full or split
    shp = (n_des, n_pts) if rows else (1, 1)
    fail = np.empty(shp, np.int16)
    eta = np.empty(shp)
    exc = np.empty(shp)
    dex = np.empty(shp)
    code = np.empty(shp, np.int8)
    extra = np.empty(shp + (_N_EXTRA,))
    if full:
        kappa = np.empty((n_des, n_pts, 7))
        rho = np.empty((n_des, n_pts, 3))
        delta = np.empty((n_des, n_pts, 2))
        sigma = np.empty((n_des, n_pts, 2))
    else:
        kappa = np.empty((1, 1, 7))
        rho = np.empty((1, 1, 3))
        delta = np.empty((1, 1, 2))
        sigma = np.empty((1, 1, 2))
    summ = np.empty((n_des, _N_SUMM))
    _kernel(geo, mf, Ec, ec, same_e, opt, full, split, _CHUNK, *body[0], *body[1:],
            fail, eta, exc, dex, code, extra, kappa, rho, delta, sigma, summ)  # fmt: skip

    n_bad = summ[:, _S_NBAD].astype(np.int64)
    out_shape = batch + (n_pts,)
    points = None
    if full:
        points = PointResults(
            reachable=(fail == 0).reshape(out_shape),
            failure=fail.reshape(out_shape),
            kappa=kappa.reshape(out_shape + (7,)),
            eta_L=eta.reshape(out_shape),
            dexterity_pct=dex.reshape(out_shape),
            excess=exc.reshape(out_shape),
            rho=rho.reshape(out_shape + (3,)),
            delta=delta.reshape(out_shape + (2,)),
            sigma=sigma.reshape(out_shape + (2,)),
            clearance_mm=extra[..., _X_CLR].reshape(out_shape),
            clearance_part=extra[..., _X_PART].astype(np.intp).reshape(out_shape),
            self_clearance_mm=extra[..., _X_SELF].reshape(out_shape),
            **{name: extra[..., X_PERF + j].reshape(out_shape) for j, name in _PERF_COLUMNS},
            torque_actuator=extra[..., X_PERF + 5].astype(np.int64).reshape(out_shape),
        )

    def summary(col: int) -> np.ndarray:
        return summ[:, col].reshape(batch)

    return TaskResults(
        points=points,  # type: ignore[arg-type]
        w_G=(n_bad == 0).reshape(batch),
        reachable_fraction=summary(_S_RF),
        eta_G=summary(_S_ETAG),
        violation=summary(_S_VIOL),
        dexterity_min=summary(_S_DMIN),
        dexterity_mean=summary(_S_DMEAN),
        dexterity_max=summary(_S_DMAX),
        clearance_min=summary(_S_CMIN),
        self_clearance_min=summary(_S_SMIN),
        **{name.rsplit("_", 1)[0] + "_max": summary(S_PERF + j) for j, name in enumerate(PERFORMANCE_FIELDS)},
    )


def warm_up() -> float:
    """Compile (or load from the on-disk cache) the kernel on a tiny input; returns the seconds it took."""
    t0 = time.perf_counter()
    from arcube.model.design import PAPER_TABLE2, PARAM_NAMES

    x = np.array([PAPER_TABLE2[n] for n in PARAM_NAMES])
    E = np.array([[-50.0, 10.0, 0.0], [-40.0, 20.0, 5.0]])
    e = np.array([[0.0, 0.0, 1.0], [0.0, 0.6, 0.8]])
    evaluate_task_numba(np.stack([x, x]), E, e, DEFAULT_MODE, Options(), want_points=True)
    evaluate_task_numba(x, E, e, DEFAULT_MODE, Options(), want_points=False)
    return time.perf_counter() - t0
