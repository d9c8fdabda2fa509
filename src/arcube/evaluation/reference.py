"""Judging a design on a task: reachability w_L, eta_L, guards, eta_G (model §8.2-8.3, 12.2, 16, 19.5).

Long module: the one reference evaluation (model §8, 12, 14-16, 19.5) reads top to bottom as the compiled
kernel's oracle, with its result types, which are the kernel's contract.

:func:`evaluate_task` is the one batch call the rest of the tool uses: designs ``(..., 27)``
against the P points of a task ``(P, 3)``; results have shape ``(..., P)`` per point and
``(...)`` per design. No Python loop over designs or points. The settings it reads are
:class:`arcube.options.Options` (re-exported here with :data:`GUARDED_OPTIONS`).

The graded violation is model §16's V = V_reach + V_fit: V_reach (12.2 over the inverse
kinematics alone) counts the points where sections 3-5 have no solution or eta_L = inf, plus their
domain excess; V_fit = G / (1 + G) / (2 P) < 1 / (2 P), G = (1/P) sum over the points that solve the
IK of each active guard's min(s / S, 1) (:data:`GRADE_SCALES`). So a design that misses a point
always ranks below one that solves the IK everywhere, and among those V grows with every shortfall.

model §16's amendment: for a design that carries its own z-dyad link c_z (19.1, 19.2; a ``c_z`` column that
is not NaN) and with the z-dyad guard on, the dyad's closure is part of the z leg's inverse kinematics: a
point where it cannot close counts in V_reach (with the closure shortfall as its domain excess) and none of
its guards count in V_fit. Its failure is still reported as ``guard/z_dyad``. Without an own c_z nothing changes.

The anatomy (``anatomy``: its signed distance, model §14.2) and the envelope of the whole patient
(``envelope``: an :class:`arcube.evaluation.envelope.Envelope`, 19.5) are data, passed beside the options;
without them (None) their clearances are NaN and their guards off, and every result is as before.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.model.design import unpack
from arcube.evaluation.indices import JACOBIAN_NAMES, condition_numbers
from arcube.model.mechanism import DEFAULT_MODE, IKSolution, inverse_kinematics
from arcube.evaluation.clearance import Distance, anatomy_clearance, self_clearance
from arcube.evaluation.envelope_clearance import envelope_clearance
from arcube.evaluation.masses import holding_torque_of_solution
from arcube.evaluation.performance import MAXIMUM_FIELDS, jacobians_of_solution, metrics_of_solution
from arcube.model.body import body_parts, mechanism_points
from arcube.options import GUARDED_OPTIONS, Options

if TYPE_CHECKING:
    from arcube.evaluation.envelope import Envelope

__all__ = [
    "FAILURES",
    "GRADE_SCALES",
    "GUARDED_OPTIONS",
    "IK_FAILURES",
    "Options",
    "PointResults",
    "TaskResults",
    "evaluate_points",
    "design_c_z",
    "dyad_in_reach",
    "evaluate_task",
    "failure_name",
    "fit_violation",
]
from arcube.model.stages import rts, zleg


FAILURES: tuple[str, ...] = (
    "TLS/x",
    "TLS/y",
    "TLS/z",
    "RTS/x",
    "RTS/y",
    "TMS/x",
    "TMS/y",
    *(f"singular/{name}" for name in JACOBIAN_NAMES),
    "guard/z_dyad",
    "guard/rho_max",
    "guard/transmission",
    "guard/kappa_max",
    "guard/single_assembly_mode",
    "collision/patient",
    "collision/self",
    "collision/envelope",
)
"""Failure reasons; a point reports the first that applies, checked in this order except that the
collision guards (model §14.3, 19.5) come after the other local guards and before the global
``guard/single_assembly_mode``. Code 0 in :attr:`PointResults.failure` means reachable; code
k >= 1 means ``FAILURES[k - 1]``. ``collision/envelope`` came last, so every earlier code kept its number."""

_CODE = {name: i + 1 for i, name in enumerate(FAILURES)}
IK_FAILURES = _CODE["guard/z_dyad"] - 1
"""Failure codes 1 .. IK_FAILURES are the inverse-kinematic failures of model §16 (a stage has no
solution, or eta_L = inf); the codes above are guards, which a point fails only once the IK solves it."""
GRADE_SCALES: dict[str, float] = {
    "z_dyad": 1.0,  # closure shortfall, already relative to d_z + c_z (8.2)
    "rho_max": float(np.deg2rad(10.0)),  # rad, of the summed |rho_u| excess
    "transmission": float(np.sin(np.deg2rad(20.0))),  # each of the seven sines its own term
    "clearance": 10.0,  # mm, anatomy and self clearance (14.3)
    "envelope": 10.0,  # mm, clearance to the envelope of the whole patient (19.5)
}
"""The scales S of model §16 by which a guard's shortfall s is graded, min(s / S, 1); ``kappa_max``'s
scale is kappa_max itself, ``single_assembly_mode`` counts 1 at each point outside the majority mode."""
_EXCESS_CAP = 10.0
"""Cap on one argument's excess in the graded violation, so that a degenerate argument (C/0)
cannot swamp the rest; the violation stays 0 exactly when every point is reachable."""


def failure_name(code: int) -> str | None:
    """The reason string of a failure code, None for 0 (reachable)."""
    return None if code == 0 else FAILURES[code - 1]


class PointResults(NamedTuple):
    """Per-point results, each ``(..., P)`` (plus a trailing axis where noted)."""

    reachable: NDArray[np.bool_]  # w_L with the active guards
    failure: NDArray[np.int16]  # 0 = reachable, else index + 1 into FAILURES
    kappa: NDArray[np.float64]  # (..., P, 7), NaN where the IK has no solution
    eta_L: NDArray[np.float64]  # +inf where unreachable
    dexterity_pct: NDArray[np.float64]  # 100/eta_L, 0 where unreachable
    excess: NDArray[np.float64]  # IK domain excess of 12.2 (0 where the IK solves the point; guards not included)
    guard_grade: NDArray[np.float64]  # model §16: sum over the active guards of min(s/S, 1); 0 where the IK fails
    rho: NDArray[np.float64]  # (..., P, 3) rad
    delta: NDArray[np.float64]  # (..., P, 2) rad
    sigma: NDArray[np.float64]  # (..., P, 2) rad
    clearance_mm: NDArray[np.float64]  # body to anatomy, signed (model §14.3); NaN when not computed or no IK
    clearance_part: NDArray[np.intp]  # index into arcube.model.body.PART_NAMES of the closest part, -1 if none
    self_clearance_mm: NDArray[np.float64]  # between the body's own parts; NaN when not computed or no IK
    envelope_clearance_mm: NDArray[
        np.float64
    ]  # body to the envelope of the whole patient, signed (model §19.5); NaN when not computed or no IK
    envelope_part: NDArray[
        np.intp
    ]  # index into arcube.model.body.PART_NAMES of the part closest to the envelope, -1 if none
    envelope_region: NDArray[
        np.intp
    ]  # index into the envelope's names (neck, head, torso, table...) of the region it binds on, -1 if none
    tip_error_mm: NDArray[np.float64]  # model §15.2-15.4 from here on; NaN where unreachable
    lateral_error_mm: NDArray[np.float64]
    axial_error_mm: NDArray[np.float64]
    axis_error_deg: NDArray[np.float64]
    torque_Nm: NDArray[np.float64]
    torque_actuator: NDArray[np.int64]  # index into ACTUATOR_NAMES of the largest torque, -1 where unreachable
    deflection_mm: NDArray[np.float64]
    holding_torque_Nm: NDArray[np.float64]  # model §18.2 (Outputs.holding_torque); NaN where off or unreachable
    holding_torque_actuator: NDArray[np.int64]  # index into ACTUATOR_NAMES of the largest holding torque, -1 where none


class TaskResults(NamedTuple):
    """A task's per-point results and per-design summary (each summary field ``(...)``)."""

    points: PointResults
    w_G: NDArray[np.bool_]
    reachable_fraction: NDArray[np.float64]
    eta_G: NDArray[np.float64]  # mean eta_L if w_G else +inf
    violation: NDArray[np.float64]  # model §16: violation_reach + G/(1+G)/(2P), G = guard_grade/P; 0 iff w_G
    violation_reach: NDArray[
        np.float64
    ]  # V_reach: fraction of IK failures + their excess; 0 iff the IK solves every point
    guard_grade: NDArray[np.float64]  # sum of points.guard_grade over the P points (not divided by P)
    dexterity_min: NDArray[np.float64]
    dexterity_mean: NDArray[np.float64]
    dexterity_max: NDArray[np.float64]
    clearance_min: NDArray[np.float64]  # min clearance_mm over reachable points (NaN if none)
    self_clearance_min: NDArray[np.float64]  # min self_clearance_mm over reachable points (NaN if none)
    envelope_clearance_min: NDArray[
        np.float64
    ]  # min envelope_clearance_mm over reachable points (NaN if none or not computed)
    tip_error_max: NDArray[np.float64]  # model §15.5: maxima over the reachable points (NaN if none)
    lateral_error_max: NDArray[np.float64]
    axial_error_max: NDArray[np.float64]
    axis_error_max: NDArray[np.float64]
    torque_max: NDArray[np.float64]
    deflection_max: NDArray[np.float64]
    holding_torque_max: NDArray[np.float64]  # model §18.2 over the reachable points (NaN if none or not computed)

    @property
    def fitness(self) -> NDArray[np.float64]:
        """GA fitness of model §8.3 (shaping only): eta_G if w_G else 1e6 (1 + unreachable fraction)."""
        return np.where(self.w_G, self.eta_G, 1e6 * (2.0 - self.reachable_fraction))


def _excess(arg: NDArray[np.float64]) -> NDArray[np.float64]:
    """Sum over the last axis of min(max(|arg| - 1, 0), cap); NaN arguments count 0."""
    x = np.clip(np.abs(arg) - 1.0, 0.0, _EXCESS_CAP)
    return np.sum(np.nan_to_num(x, nan=0.0), axis=-1)


def _first_failure(checks: list[tuple[str, NDArray[np.bool_]]], shape: tuple[int, ...]) -> NDArray[np.int16]:
    """Code of the first failing check (checks in FAILURES order); 0 where none fails."""
    code = np.zeros(shape, dtype=np.int16)
    for name, failed in reversed(checks):
        code = np.where(np.broadcast_to(failed, shape), np.int16(_CODE[name]), code)
    return code


def _grade(short: ArrayLike, scale: ArrayLike) -> NDArray[np.float64]:
    """One guard term of model §16, min(s / S, 1) (NaN propagates)."""
    return np.minimum(np.asarray(short) / scale, 1.0)


def _guard_checks(
    sol: IKSolution,
    params: ArrayLike,
    eta: NDArray[np.float64],
    options: Options,
    c_z: NDArray[np.float64] | None = None,
) -> list[tuple[str, NDArray[np.bool_], NDArray[np.float64]]]:
    """(reason, failed, grade) of each active local guard; ``grade`` is its model §16 term(s) at each
    point, sum of min(s / S, 1), 0 where undefined (NaN). Points without an IK solution are masked later.
    ``c_z``: each design's own z-dyad link (mm, :func:`design_c_z`), else the options' (d_z when None)."""
    g = unpack(params)
    out: list[tuple[str, NDArray[np.bool_], NDArray[np.float64]]] = []

    def add(reason: str, failed: NDArray[np.bool_], grade: NDArray[np.float64]) -> None:
        out.append((reason, failed, np.nan_to_num(grade, nan=0.0)))

    if options.guards.z_dyad:
        short = _z_dyad_shortfall(sol, params, options, c_z)
        add("guard/z_dyad", short > 0.0, _grade(short, GRADE_SCALES["z_dyad"]))
    if options.guards.rho_max_deg is not None:
        short = np.sum(np.maximum(np.abs(sol.rho) - np.deg2rad(options.guards.rho_max_deg), 0.0), axis=-1)
        add("guard/rho_max", short > 0.0, _grade(short, GRADE_SCALES["rho_max"]))
    if options.guards.min_transmission_deg is not None:
        T = sol.terms
        sa, sb = np.sin(g.alpha), np.sin(g.beta)
        sines = np.concatenate(
            [
                T.F / (g.d[..., :2] * g.c),
                T.H / (g.t * g.c),
                rts.J_AS_diag(sol.e, sol.u_beta) / (sa * sb),
                (rts.det_beta(sol.e, sol.u_beta) / (sb[..., 0] * sb[..., 1]))[..., None],
            ],
            axis=-1,
        )
        shorts = np.maximum(np.sin(np.deg2rad(options.guards.min_transmission_deg)) - np.abs(sines), 0.0)
        add(
            "guard/transmission",
            np.sum(shorts, axis=-1) > 0.0,
            np.sum(_grade(shorts, GRADE_SCALES["transmission"]), axis=-1),
        )
    if options.guards.kappa_max is not None:
        km = options.guards.kappa_max
        add("guard/kappa_max", eta > km, _grade(np.maximum(eta - km, 0.0), km))
    return out


def _z_dyad_shortfall(
    sol: IKSolution, params: ArrayLike, options: Options, c_z: NDArray[np.float64] | None
) -> NDArray[np.float64]:
    """How far the z dyad is from closing at each point, relative to d_z + c_z (section 6; 0 where it closes,
    NaN where the z leg has no solution). ``c_z``: each design's own, else the options' (d_z when None)."""
    g = unpack(params)
    c_z = (g.d[..., 2] if options.guards.c_z is None else options.guards.c_z) if c_z is None else c_z
    return zleg.closure_shortfall(zleg.span(sol.E_m, sol.rho[..., 2], g.p[..., 2]), g.d[..., 2], c_z)


def dyad_in_reach(params: ArrayLike, options: Options, c_z: ArrayLike | None) -> NDArray[np.bool_]:
    """Per design ``(...)``: True where the z dyad closes as part of the inverse kinematics (model §16's
    amendment): the z-dyad guard is on and the design has its own c_z (a ``c_z`` column, not NaN)."""
    shape = np.shape(unpack(params).d[..., 2])
    if c_z is None or not options.guards.z_dyad:
        return np.zeros(shape, dtype=bool)
    return ~np.isnan(np.broadcast_to(np.asarray(c_z, dtype=float), shape))


def design_c_z(params: ArrayLike, options: Options, c_z: ArrayLike | None) -> NDArray[np.float64] | None:
    """Each design's z-dyad link c_z (mm, model §19.1) ``(...)`` from a per-design column ``c_z`` broadcasting
    as ``params[..., 0]``: its value, else (NaN) ``Options.guards.c_z``, else d_z; None when no column is given
    (every design then takes the options' c_z, as before c_z became a design parameter)."""
    if c_z is None:
        return None
    d_z, own = np.broadcast_arrays(unpack(params).d[..., 2], np.asarray(c_z, dtype=float))
    fallback = d_z if options.guards.c_z is None else np.full(np.shape(d_z), float(options.guards.c_z))
    return np.where(np.isnan(own), fallback, own)


def evaluate_points(
    params: ArrayLike,
    E: ArrayLike,
    e: ArrayLike,
    mode: ArrayLike = DEFAULT_MODE,
    options: Options = Options(),
    anatomy: Distance | None = None,
    envelope: Envelope | None = None,
    c_z: ArrayLike | None = None,
) -> PointResults:
    """Local evaluation (no global guard): every argument broadcasts, results ``(...)``.

    Parameters: ``params`` ``(..., 27)`` (or ``(..., 23)``) mm/deg; ``E`` ``(..., 3)`` drill tips in R_w, mm;
    ``e`` ``(..., 3)`` unit drill axes; ``mode`` ``(..., 4)`` working-mode signs; ``c_z`` ``(...)`` each
    design's own z-dyad link, mm (:func:`design_c_z`; None: ``Options.guards.c_z``).
    """
    with np.errstate(invalid="ignore", divide="ignore"):
        sol = inverse_kinematics(params, E, e, mode)
        own = dyad_in_reach(params, options, c_z)
        return _judge(sol, params, options, anatomy, envelope, design_c_z(params, options, c_z), own)


def _body_clearances(
    sol: IKSolution,
    params: ArrayLike,
    options: Options,
    anatomy: Distance | None,
    shape: tuple[int, ...],
    envelope: Envelope | None = None,
    c_z: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], ...]:
    """(clearance, part, self clearance, envelope clearance, envelope part, envelope region) ``shape`` each:
    NaN / -1 where not asked for or without IK. ``c_z``: each design's own (None: the options')."""
    nan, none = np.full(shape, np.nan), np.full(shape, -1, dtype=np.intp)
    if not options.wants_body:
        return nan, none, nan, nan, none, none
    radii = options.radii
    mp = mechanism_points(
        params, sol.E_m, sol.e, c_z=options.guards.c_z if c_z is None else c_z, motor_length=radii.motor_length, sol=sol
    )
    parts = body_parts(mp, radii)
    selfc = np.broadcast_to(self_clearance(parts), shape) if options.wants_self_clearance else nan
    env: tuple[NDArray[Any], ...] = (nan, none, none)
    if envelope is not None and options.wants_envelope_clearance:
        env = tuple(np.broadcast_to(v, shape) for v in envelope_clearance(parts, envelope))
    if anatomy is None or not options.wants_clearance:
        return nan, none, selfc, *env
    clear, part = anatomy_clearance(parts, anatomy)
    return np.broadcast_to(clear, shape), np.broadcast_to(part, shape), selfc, *env


def _judge(
    sol: IKSolution,
    params: ArrayLike,
    options: Options,
    anatomy: Distance | None = None,
    envelope: Envelope | None = None,
    c_z: NDArray[np.float64] | None = None,
    dyad_ik: NDArray[np.bool_] | None = None,
) -> PointResults:
    """Every point's results; ``dyad_ik`` (broadcasting as the points): where an open z dyad is an IK failure
    (:func:`dyad_in_reach`, model §16's amendment)."""
    kappa = condition_numbers(sol, params)
    shape = kappa.shape[:-1]
    tls_bad = np.abs(sol.tls_arg) > 1.0
    rts_bad = np.abs(sol.rts_arg) > 1.0
    tms_bad = ~(np.abs(sol.tms_arg) <= 1.0)  # NaN (TLS or RTS failed first) also counts as bad
    stages_ok = ~(np.any(tls_bad, axis=-1) | np.any(rts_bad, axis=-1) | np.any(tms_bad, axis=-1))
    singular = ~np.isfinite(kappa) & stages_ok[..., None]
    eta_raw = np.max(np.where(np.isnan(kappa), np.inf, kappa), axis=-1)
    checks: list[tuple[str, NDArray[np.bool_]]] = [
        *((f"TLS/{leg}", tls_bad[..., i]) for i, leg in enumerate("xyz")),
        *((f"RTS/{leg}", rts_bad[..., i]) for i, leg in enumerate("xy")),
        *((f"TMS/{leg}", tms_bad[..., i]) for i, leg in enumerate("xy")),
        *((f"singular/{name}", singular[..., i]) for i, name in enumerate(JACOBIAN_NAMES)),
    ]
    excess = _excess(sol.tls_arg) + _excess(sol.rts_arg) + _excess(sol.tms_arg)  # 0 where the stages solve the point
    solved = stages_ok & ~np.any(singular, axis=-1)  # the IK solves the point (model §16)
    if dyad_ik is not None and np.any(dyad_ik):  # the amendment: an open z dyad is a point not reached
        short = _z_dyad_shortfall(sol, params, options, c_z)
        open_dyad = dyad_ik & stages_ok & (short > 0.0)
        excess = excess + np.where(open_dyad, short, 0.0)
        solved = solved & ~open_dyad
    clear, part, selfc, env, env_part, env_region = _body_clearances(
        sol, params, options, anatomy, shape, envelope, c_z
    )
    guards = _guard_checks(sol, params, eta_raw, options, c_z)
    scale = GRADE_SCALES["clearance"]
    if options.guards.clearance_mm is not None and anatomy is not None:
        short = np.maximum(options.guards.clearance_mm - clear, 0.0)  # mm, model §14.3
        guards.append(("collision/patient", short > 0.0, np.nan_to_num(_grade(short, scale), nan=0.0)))
    if options.guards.self_clearance_mm is not None:
        short = np.maximum(options.guards.self_clearance_mm - selfc, 0.0)
        guards.append(("collision/self", short > 0.0, np.nan_to_num(_grade(short, scale), nan=0.0)))
    if options.guards.envelope_clearance_mm is not None and envelope is not None:
        short = np.maximum(options.guards.envelope_clearance_mm - env, 0.0)  # mm, model §19.5
        guards.append(
            ("collision/envelope", short > 0.0, np.nan_to_num(_grade(short, GRADE_SCALES["envelope"]), nan=0.0))
        )
    grade: NDArray[np.float64] | float = 0.0
    for name, failed, term in guards:
        checks.append((name, failed & stages_ok))
        grade = grade + term
    failure = _first_failure(checks, shape)
    reachable = failure == 0
    perf = _performance(sol, params, options, c_z)
    eta = np.where(reachable, eta_raw, np.inf)
    with np.errstate(divide="ignore"):
        dex = np.where(reachable, 100.0 / eta, 0.0)
    pts = PointResults(
        reachable=reachable,
        failure=failure,
        kappa=np.where(stages_ok[..., None], kappa, np.nan),
        eta_L=eta,
        dexterity_pct=dex,
        excess=np.broadcast_to(excess, shape),
        guard_grade=np.broadcast_to(np.where(solved, grade, 0.0), shape),
        rho=np.broadcast_to(sol.rho, shape + (3,)),
        delta=np.broadcast_to(sol.delta, shape + (2,)),
        sigma=np.broadcast_to(sol.sigma, shape + (2,)),
        clearance_mm=np.where(stages_ok, clear, np.nan),
        clearance_part=np.where(stages_ok, part, -1),
        self_clearance_mm=np.where(stages_ok, selfc, np.nan),
        envelope_clearance_mm=np.where(stages_ok, env, np.nan),
        envelope_part=np.where(stages_ok, env_part, -1),
        envelope_region=np.where(stages_ok, env_region, -1),
        **{name: np.broadcast_to(perf[name] if perf else np.nan, shape) for name in MAXIMUM_FIELDS},
        torque_actuator=np.broadcast_to(perf["torque_actuator"] if perf else -1, shape),
        holding_torque_actuator=np.broadcast_to(perf["holding_torque_actuator"] if perf else -1, shape),
    )
    return _mask_performance(pts)


def _performance(
    sol: IKSolution, params: ArrayLike, options: Options, c_z: NDArray[np.float64] | None = None
) -> dict[str, Any] | None:
    """The drill-tip metrics of model §15 and, with ``Outputs.holding_torque``, the holding torque of
    18.2 (NaN and -1 without it) at the points of ``sol``, by field name; None without ``Outputs.tip_metrics``.
    ``c_z``: each design's own z-dyad link (None: the options')."""
    if not options.outputs.tip_metrics:
        return None
    J_E, J_e = jacobians_of_solution(sol, params)
    out: dict[str, Any] = metrics_of_solution(sol, params, options.loads, (J_E, J_e))._asdict()
    out["holding_torque_Nm"], out["holding_torque_actuator"] = np.nan, -1
    if options.outputs.holding_torque:
        hold = holding_torque_of_solution(sol, params, options, jacobians=(J_E, J_e), c_z=c_z)
        out["holding_torque_Nm"], out["holding_torque_actuator"] = hold.holding_torque_Nm, hold.holding_torque_actuator
    return out


def _mask_performance(pts: PointResults) -> PointResults:
    """NaN (and -1) for the metrics of model §15 where a point is not reachable."""
    r = pts.reachable
    fields = {name: np.where(r, getattr(pts, name), np.nan) for name in MAXIMUM_FIELDS}
    return pts._replace(
        torque_actuator=np.where(r, pts.torque_actuator, -1),
        holding_torque_actuator=np.where(r, pts.holding_torque_actuator, -1),
        **fields,
    )


def _single_assembly_mode(sol: IKSolution, pts: PointResults, ik_last: ArrayLike = IK_FAILURES) -> PointResults:
    """Fail the points whose assembly signs differ from the task's most common ones (per design).

    The reference triple is the most frequent (sign H_x, sign H_y, sign det) among the points
    that are reachable so far; ties go to the lowest code. The points that pass so far and differ
    from it fail; every point that the IK solves and that differs from it (whether or not it also
    fails a local guard) adds 1 to its ``guard_grade`` (model §16). ``ik_last`` ``(..., 1)``: the last failure
    code that is an IK failure (IK_FAILURES, or the z dyad's code for a design under model §16's amendment).
    """
    asm = sol.assembly
    code = ((asm[..., 0] > 0) * 4 + (asm[..., 1] > 0) * 2 + (asm[..., 2] > 0)).astype(np.int64)
    counts = np.sum((code[..., None] == np.arange(8)) & pts.reachable[..., None], axis=-2)
    ref = np.argmax(counts, axis=-1)
    other = code != ref[..., None]
    off = pts.reachable & other
    failure = np.where(off, np.int16(_CODE["guard/single_assembly_mode"]), pts.failure)
    reachable = failure == 0
    solved = (pts.failure == 0) | (pts.failure > ik_last)
    return _mask_performance(
        pts._replace(
            reachable=reachable,
            failure=failure,
            eta_L=np.where(reachable, pts.eta_L, np.inf),
            dexterity_pct=np.where(reachable, pts.dexterity_pct, 0.0),
            guard_grade=np.where(solved & other, pts.guard_grade + 1.0, pts.guard_grade),
        )
    )


def evaluate_task(
    params: ArrayLike,
    E: ArrayLike,
    e: ArrayLike,
    mode: ArrayLike = DEFAULT_MODE,
    options: Options = Options(),
    anatomy: Distance | None = None,
    envelope: Envelope | None = None,
    c_z: ArrayLike | None = None,
) -> TaskResults:
    """Evaluate designs ``(..., 27)`` (or ``(..., 23)``) on the P points of a task (``E``, ``e`` each ``(P, 3)``).

    ``mode`` broadcasts as ``(..., 4)`` (one working mode per design, or one for all).
    Per-point fields have shape ``(..., P)``; summaries ``(...)``. Dexterity statistics run
    over all P points, counting 0 at unreachable points. ``violation`` is model §16's V_reach + V_fit
    for this task alone (no --max/--min limits: the optimizer adds them, with several tasks, from
    ``violation_reach`` and ``guard_grade``). ``anatomy``: the anatomy's signed distance (model §14.3);
    ``envelope``: the envelope of the whole patient (19.5), whose landmarks come from the whole plan.
    ``c_z`` ``(...)``: each design's own z-dyad link c_z, mm (model §19.1; a column beside the 27
    parameters, broadcasting as ``params[..., 0]``; NaN or None: ``Options.guards.c_z``, else d_z).
    """
    p = np.asarray(params, dtype=float)[..., None, :]
    m = np.asarray(mode, dtype=float)[..., None, :]
    cz = design_c_z(params, options, c_z)
    own = dyad_in_reach(params, options, c_z)[..., None]
    ik_last = IK_FAILURES + own.astype(np.int16)  # the z dyad's code is an IK failure under the amendment
    with np.errstate(invalid="ignore", divide="ignore"):
        sol = inverse_kinematics(p, E, e, m)
        pts = _judge(sol, p, options, anatomy, envelope, None if cz is None else cz[..., None], own)
        if options.guards.single_assembly_mode:
            pts = _single_assembly_mode(sol, pts, ik_last)
        n = pts.reachable.shape[-1]
        n_bad = np.sum(~pts.reachable, axis=-1)
        w_G = n_bad == 0
        eta_G = np.where(w_G, np.mean(np.where(pts.reachable, pts.eta_L, 0.0), axis=-1), np.inf)
        n_ik = np.sum((pts.failure > 0) & (pts.failure <= ik_last), axis=-1)
        reach = np.where(n_ik == 0, 0.0, n_ik / n + np.sum(pts.excess, axis=-1))
        grade = np.sum(pts.guard_grade, axis=-1)
    return TaskResults(
        points=pts,
        w_G=w_G,
        reachable_fraction=1.0 - n_bad / n,
        eta_G=eta_G,
        violation=reach + fit_violation(grade / n, n),
        violation_reach=reach,
        guard_grade=grade,
        dexterity_min=np.min(pts.dexterity_pct, axis=-1),
        dexterity_mean=np.mean(pts.dexterity_pct, axis=-1),
        dexterity_max=np.max(pts.dexterity_pct, axis=-1),
        clearance_min=_min_reachable(pts.clearance_mm, pts.reachable),
        self_clearance_min=_min_reachable(pts.self_clearance_mm, pts.reachable),
        envelope_clearance_min=_min_reachable(pts.envelope_clearance_mm, pts.reachable),
        **{
            name.rsplit("_", 1)[0] + "_max": _max_reachable(getattr(pts, name), pts.reachable)
            for name in MAXIMUM_FIELDS
        },
    )


def fit_violation(G: ArrayLike, n: int) -> NDArray[np.float64]:
    """V_fit of model §16, G / (1 + G) / (2 n), from G >= 0 (+inf gives 1 / (2 n)) and n points: < 1 / (2 n)
    for finite G (up to rounding), 0 exactly when G = 0."""
    G = np.asarray(G, dtype=float)
    with np.errstate(invalid="ignore"):
        return np.where(np.isposinf(G), 1.0, G / (1.0 + G)) / (2.0 * n)


def _max_reachable(values: NDArray[np.float64], reachable: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Maximum over the reachable points (last axis); NaN where none is reachable."""
    v = np.where(reachable & ~np.isnan(values), values, -np.inf)
    out = np.max(v, axis=-1)
    return np.where(np.isfinite(out), out, np.nan)


def _min_reachable(values: NDArray[np.float64], reachable: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Minimum over the reachable points (last axis); NaN where none is reachable or nothing was computed."""
    v = np.where(reachable, values, np.inf)
    with np.errstate(invalid="ignore"):
        out = np.min(np.where(np.isnan(v), np.inf, v), axis=-1)
    return np.where(np.isfinite(out), out, np.nan)
