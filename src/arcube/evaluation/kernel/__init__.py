"""Compiled evaluation kernel (Numba): :func:`evaluate_task_numba` == :func:`arcube.evaluation.reference.evaluate_task`.

One fused pass per (design, point): TLS IK (Eq 1), RTS IK (model §5.2), TMS IK (4.2), the
seven condition numbers by the closed forms of 8.1, the local guards of 8.2, the IK domain
excess of 12.2 and the guard grade of 16; with the options' outputs, the body clearances of 14.3
(``_clearance``, ``_self``) and 19.5 (``_envelope``), the drill-tip metrics of 15 (``_performance``)
and the holding torque of 18.2 (``_masses``, only with ``Outputs.holding_torque``). A design's points then get the global
``single_assembly_mode`` guard and the summaries (w_G, eta_G, the violation of model §16 and its
parts violation_reach and guard_grade, dexterity statistics). Designs run in parallel (``prange``,
Numba's default thread count); when there are fewer than two designs per thread, the points
are split into chunks instead. With ``want_points=False`` no designs x points array exists.

Agreement with the NumPy reference. The code repeats the reference's operations in its order
(sums left to right, ``einsum``'s (p0 + p2) + p1 of some NumPy builds for R^T a (``_scalar.rot_t``),
NumPy's pairwise summation over points, the
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

from arcube.evaluation.kernel import _cache
from arcube.evaluation.kernel._cache import clear_cache
from arcube.evaluation.kernel._clearance import block_gradients
from arcube.evaluation.kernel._driver import _kernel
from arcube.evaluation.kernel._layout import CHUNK, EXTRA, GEOMETRY, OPTIONS, SUMMARY, Layout
from arcube.evaluation.kernel._state import Inputs, Rows
from arcube.evaluation.mass_bodies import N_CHORDS, MassModel, slerp_coefficients
from arcube.evaluation.reference import Options, PointResults, TaskResults
from arcube.evaluation.reference import evaluate_task as _evaluate_task_numpy
from arcube.model import frames
from arcube.model.body import PRIMITIVES, SELF_PAIRS, primitive_radii
from arcube.model.design import N_PAPER, N_PARAMS, full_params, unpack
from arcube.model.mechanism import DEFAULT_MODE

__all__ = ["clear_cache", "evaluate_task_numba", "warm_up"]

_INTEGER_EXTRAS: dict[str, type] = {
    "clearance_part": np.intp,
    "envelope_part": np.intp,
    "envelope_region": np.intp,
    "torque_actuator": np.int64,
    "holding_torque_actuator": np.int64,
}
"""PointResults fields held as floats in the extra rows, and their dtypes."""


def _owned(a: np.ndarray) -> np.ndarray:
    """C-contiguous, writeable float64 (one compiled signature: Numba types read-only arrays apart)."""
    c = np.ascontiguousarray(a, dtype=np.float64)
    return c if c.flags.writeable else c.copy()


def _rows(layout: Layout, values: dict[str, Any], lead: tuple[int, ...]) -> np.ndarray:
    """Rows ``lead + (layout.size,)`` with each block of ``layout`` from ``values[name]`` (any shape
    that reshapes to ``lead + (width,)``); a block without a value, or a value without a block, raises."""
    if values.keys() != set(layout.names):
        raise ValueError(f"layout {layout.prefix}: blocks {sorted(set(layout.names) ^ values.keys())} not matched")
    out = np.empty(lead + (layout.size,))
    for name, width in layout.entries:
        at = layout.offset[name]
        out[..., at : at + width] = np.reshape(values[name], lead + (width,))
    return out


def _geometry(params: np.ndarray, c_z: np.ndarray | None = None) -> np.ndarray:
    """Per-design geometry rows ``(D, N_GEO)`` (``_layout.GEOMETRY``) of designs ``(D, 27)`` (mm, deg):
    the fields of :func:`arcube.model.design.unpack` (mm, rad), the trig of alpha and beta, the mounting
    rotation and whether it is I, computed with the same NumPy operations as the stage modules and
    arcube.model.frames; the spherical links' chords (``kernel._masses``); and each design's own z-dyad link
    ``c_z`` ``(D,)`` mm (model §19.1; NaN or None: the option's, else d_z: ``_scalar.z_link``)."""
    g = unpack(params)
    phi = np.concatenate([g.alpha, g.beta], axis=-1)  # (D, 4): alpha_x, alpha_y, beta_x, beta_y
    with np.errstate(invalid="ignore", divide="ignore"):  # degenerate arcs (phi = 0): NaN, as in the reference
        a, b = slerp_coefficients(phi)  # (D, 4, 13), as arcube.evaluation.mass_bodies samples the arcs
    values = {
        "m": g.m,
        "f": g.f,
        "p": g.p,
        "d": g.d,
        "c": g.c,
        "t": g.t,
        "r": g.r,
        "o": g.o,
        "sin_alpha": np.sin(g.alpha),
        "cos_alpha": np.cos(g.alpha),
        "cos_beta": np.cos(g.beta),
        "sin_beta": np.sin(g.beta),
        "rot": frames.mount_rotation(g),
        "L": g.L,
        "flat": frames.is_unrotated(g),
        "arc_chord": np.sin(phi / (2 * N_CHORDS)),
        "arc_a": np.sum(0.5 * (a[..., :-1] + a[..., 1:]), axis=-1),
        "arc_b": np.sum(0.5 * (b[..., :-1] + b[..., 1:]), axis=-1),
        "c_z": np.full(params.shape[0], np.nan) if c_z is None else c_z,
    }
    return _rows(GEOMETRY, values, (params.shape[0],))


def _optional(name: str, value: float | None, convert: Any) -> dict[str, Any]:
    """The pair of blocks of an optional threshold: ``<name>_on`` (1.0: active) and ``<name>`` (0.0 when off)."""
    return {f"{name}_on": value is not None, name: 0.0 if value is None else convert(value)}


def _option_vector(options: Options, exact: bool = False, anatomy: bool = False, envelope: bool = False) -> np.ndarray:
    """The option vector ``(N_OPT,)`` (``_layout.OPTIONS``): every setting the compiled code reads, as
    the reference compares it (``reference._guard_checks`` and ``_judge``). A new setting is one entry
    here and one in ``_layout.OPTIONS``; the two must name the same blocks."""
    guards, body, loads, masses, outputs = options.guards, options.body, options.loads, options.masses, options.outputs
    values: dict[str, Any] = {
        # Guards (model §8.2, 14.3)
        "z_dyad": guards.z_dyad,
        "c_z": np.nan if guards.c_z is None else float(guards.c_z),
        **_optional("rho_max", guards.rho_max_deg, np.deg2rad),
        **_optional("transmission", guards.min_transmission_deg, lambda deg: np.sin(np.deg2rad(deg))),
        **_optional("kappa_max", guards.kappa_max, float),
        "single_assembly_mode": guards.single_assembly_mode,
        **_optional("clearance", guards.clearance_mm, float),
        **_optional("self_clearance", guards.self_clearance_mm, float),
        **_optional("envelope", guards.envelope_clearance_mm, float),
        # Body (model §14.1)
        "motor_length": body.motor_length,
        # Loads (model §15): rad, N, N·mm/rad
        "encoder": np.radians(np.asarray(loads.encoder_deg, dtype=float)),
        "thrust": float(loads.thrust_N),
        "lateral_force": float(loads.lateral_force_N),
        "stiffness": 1000.0 * np.asarray(loads.actuator_stiffness, dtype=float),
        # Masses (model §18.1): kg/mm, kg, m/s^2 (unchecked against the link radius unless the holding torque is on)
        "link_mass": _link_mass(options),
        "m_delta": masses.m_delta_kg,
        "m_motor": masses.m_motor_kg,
        "gravity": np.asarray(masses.gravity, dtype=float),
        # Outputs, and how to compute them
        "exact": exact,
        "do_clearance": options.wants_clearance and anatomy,
        "do_self_clearance": options.wants_self_clearance,
        "tip_metrics": outputs.tip_metrics,
        "clearance_min_exact": outputs.clearance_min_exact,
        "holding_torque": outputs.tip_metrics and outputs.holding_torque,
        "do_envelope": options.wants_envelope_clearance and envelope,
    }
    values["clearance_on"] = values["clearance_on"] and anatomy  # the anatomy guard needs an anatomy
    values["envelope_on"] = values["envelope_on"] and envelope  # and the envelope guard an envelope
    return _rows(OPTIONS, values, ())


def _link_mass(options: Options) -> float:
    """lambda (kg/mm) of model §18.1, from :class:`arcube.evaluation.mass_bodies.MassModel` (which checks the wall
    against the link radius) when the holding torque is on; the same formula, unchecked, otherwise."""
    if options.outputs.tip_metrics and options.outputs.holding_torque:
        return MassModel.of(options).lambda_kg_per_mm
    ro, ri = options.body.link_radius * 1e-3, (options.body.link_radius - options.masses.wall_mm) * 1e-3
    return options.masses.density_kg_m3 * math.pi * (ro * ro - ri * ri) * 1e-3


_NO_GRID = (np.zeros(3), 1.0, np.zeros((2, 2, 2)))
_NO_BLOCKS = np.zeros((1, 1, 1, 3))
# Primitives tried first by the anatomy search (a good early bound prunes the rest): the spherical
# arcs and the four-bar outputs sit nearest the centre C, then the couplers, inputs and the rest.
_ORDER = np.array(
    [23, 24, 25, 26, 10, 11, 8, 9, 6, 7, 14, 15, 16, 17, 12, 13, 21, 22, 3, 4, 5, 18, 19, 20, 0, 1, 2], dtype=np.int64
)
assert sorted(_ORDER.tolist()) == list(range(len(PRIMITIVES)))


_BLOCKS: dict[int, tuple[Any, np.ndarray, np.ndarray]] = {}
"""Block gradient bounds per anatomy (keyed by id, checked by identity): computed once per anatomy."""


def _grids(distance: Any) -> tuple[Any, ...]:
    """The grids of an :class:`arcube.evaluation.sdf.AnatomyDistance` as the compiled lookup reads them (fine
    origin, spacing, values, coarse origin, spacing, values, fine and coarse block gradients); placeholders for None."""
    if distance is None:
        return (*_NO_GRID, *_NO_GRID, _NO_BLOCKS, _NO_BLOCKS)
    f, c = distance.fine, distance.coarse
    blocks = _BLOCKS.get(id(distance))
    if blocks is None or blocks[0] is not distance:
        blocks = (distance, block_gradients(f.values, f.spacing), block_gradients(c.values, c.spacing))
        _BLOCKS[id(distance)] = blocks
    return (
        _owned(f.origin),
        float(f.spacing),
        _owned(f.values),
        _owned(c.origin),
        float(c.spacing),
        _owned(c.values),
        blocks[1],
        blocks[2],
    )


def _body_context(options: Options, anatomy: Any) -> tuple[tuple[Any, ...], tuple[np.ndarray, ...]]:
    """(grids, body) of the compiled body clearances: ``grids`` = the anatomy's (:func:`_grids`), placeholders
    without an anatomy; ``body`` = (primitive radii (27,) mm, search order (27,), self-clearance pairs (n, 2))."""
    return _grids(anatomy), (primitive_radii(options.radii), _ORDER, SELF_PAIRS.astype(np.int64))


def _envelope_context(envelope: Any) -> tuple[Any, ...]:
    """The envelope of model §19.5 as the compiled code reads it (``_envelope._envelope_clearance``): (boxes (B, 7)
    mm, table z (NaN: none), whether there is a skin mesh, then the skin's grids (:func:`_grids`), flat: a tuple
    inside a tuple does not pass Numba's parallel loops); an empty one for None."""
    if envelope is None:
        return (np.zeros((0, 7)), math.nan, False, *_grids(None))
    table = math.nan if envelope.table_z is None else float(envelope.table_z)
    return (_owned(envelope.boxes), table, bool(envelope.skin), *_grids(envelope.skin_distance))


def evaluate_task_numba(
    params: ArrayLike,
    E: ArrayLike,
    e: ArrayLike,
    mode: ArrayLike = DEFAULT_MODE,
    options: Options = Options(),
    want_points: bool = True,
    *,
    exact: bool = False,
    anatomy: Any = None,
    envelope: Any = None,
    c_z: ArrayLike | None = None,
) -> TaskResults:
    """Same results as :func:`arcube.evaluation.reference.evaluate_task`, compiled (see the module doc).

    ``params`` ``(..., 27)`` (or ``(..., 23)``) mm/deg; ``E``, ``e`` ``(P, 3)``; ``mode`` broadcasting as ``(..., 4)``;
    results ``(batch..., P)`` per point and ``(batch...)`` per design, batch being the broadcast
    of ``params[..., :]`` and ``mode[..., :]``'s leading axes.
    With ``want_points=False`` the result's ``points`` is None (only the summaries are computed,
    with no designs x points arrays); the summaries are identical either way.
    ``exact=True`` evaluates every trigonometric function as the reference does (slower).
    ``anatomy``: an :class:`arcube.evaluation.sdf.AnatomyDistance` for the clearance of model §14.3;
    ``envelope``: an :class:`arcube.evaluation.envelope.Envelope` for the clearance of 19.5;
    ``c_z``: each design's own z-dyad link (mm, broadcasting as the batch; NaN or None: ``Guards.c_z``, else d_z).
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
        return _evaluate_task_numpy(p, E_a, e_a, m, options, anatomy, envelope, c_z)
    E_b, e_b = np.broadcast_arrays(E_a, e_a)
    batch = np.broadcast_shapes(p.shape[:-1], m.shape[:-1])
    n_des = math.prod(batch)
    n_pts = E_b.shape[0]
    if n_pts == 0 or n_des == 0:
        return _evaluate_task_numpy(p, E_a, e_a, m, options, anatomy, envelope, c_z)

    pf = _owned(np.broadcast_to(p, batch + (N_PARAMS,)).reshape(n_des, N_PARAMS))
    mf = _owned(np.broadcast_to(m, batch + (4,)).reshape(n_des, 4))
    Ec = _owned(E_b)
    ec = _owned(e_b)
    same_e = np.zeros(n_pts, dtype=np.bool_)
    bits = ec.view(np.int64)  # bitwise: -0.0 and 0.0 may take different RTS branches
    same_e[1:] = np.all(bits[1:] == bits[:-1], axis=-1)
    geometry = _geometry(
        pf, None if c_z is None else np.broadcast_to(np.asarray(c_z, dtype=float), batch).reshape(n_des)
    )
    # the fast path's angle-sum identities hold for signs only; other values (meaningless,
    # but accepted by the reference) take the reference's formulas
    exact = exact or not bool(np.all(np.abs(mf) == 1.0))
    opt = _option_vector(options, exact, anatomy is not None, envelope is not None)
    grids, body = _body_context(options, anatomy)
    env = _envelope_context(envelope if options.wants_envelope_clearance else None)

    split = n_des < 2 * get_num_threads() and n_pts >= 2 * CHUNK
    full = bool(want_points)
    shp = (n_des, n_pts) if full or split else (1, 1)  # else each design works in rows of its own
    failure = np.empty(shp, np.int16)
    eta = np.empty(shp)
    excess = np.empty(shp)
    dexterity = np.empty(shp)
    assembly = np.empty(shp, np.int8)
    extra = np.empty(shp + (EXTRA.size,))
    dp = (n_des, n_pts) if full else (1, 1)
    detail = (
        np.empty(dp + (7,)),
        np.empty(dp + (3,)),
        np.empty(dp + (2,)),
        np.empty(dp + (2,)),
    )  # kappa, rho, delta, sigma
    summary = np.empty((n_des, SUMMARY.size))
    _cache.ensure_fresh()
    inputs = Inputs(geometry, mf, Ec, ec, same_e, opt, full)
    per_point = Rows(failure, eta, excess, assembly, dexterity, extra)
    _kernel(inputs, grids, body, env, split, CHUNK, per_point, detail, summary)

    out_shape = batch + (n_pts,)
    points = None
    if full:
        kappa, rho, delta, sigma = detail

        def extra_field(name: str) -> np.ndarray:
            column = extra[..., EXTRA.offset[name]]
            return (column.astype(_INTEGER_EXTRAS[name]) if name in _INTEGER_EXTRAS else column).reshape(out_shape)

        points = PointResults(
            reachable=(failure == 0).reshape(out_shape),
            failure=failure.reshape(out_shape),
            kappa=kappa.reshape(out_shape + (7,)),
            eta_L=eta.reshape(out_shape),
            dexterity_pct=dexterity.reshape(out_shape),
            excess=excess.reshape(out_shape),
            rho=rho.reshape(out_shape + (3,)),
            delta=delta.reshape(out_shape + (2,)),
            sigma=sigma.reshape(out_shape + (2,)),
            **{name: extra_field(name) for name in EXTRA.names},
        )
    n_bad = summary[:, SUMMARY.offset["n_bad"]].astype(np.int64)
    return TaskResults(
        points=points,  # type: ignore[arg-type]
        w_G=(n_bad == 0).reshape(batch),
        **{name: summary[:, SUMMARY.offset[name]].reshape(batch) for name in SUMMARY.names if name != "n_bad"},
    )


def warm_up() -> float:
    """Drop a stale on-disk cache (see ``_cache``), then compile (or load from the cache) the kernel
    on a tiny input; returns the seconds it took."""
    t0 = time.perf_counter()
    _cache.ensure_fresh()
    from arcube.model.design import PAPER_TABLE2, PARAM_NAMES

    x = np.array([PAPER_TABLE2[n] for n in PARAM_NAMES])
    E = np.array([[-50.0, 10.0, 0.0], [-40.0, 20.0, 5.0]])
    e = np.array([[0.0, 0.0, 1.0], [0.0, 0.6, 0.8]])
    evaluate_task_numba(np.stack([x, x]), E, e, DEFAULT_MODE, Options(), want_points=True)
    evaluate_task_numba(x, E, e, DEFAULT_MODE, Options(), want_points=False)
    return time.perf_counter() - t0
