"""Two engines held equal field by field: the compiled kernel against the NumPy reference (MODEL.md 8-18,
:func:`check`, :func:`assert_matches`) and the program's compiled check against its reference (MODEL.md 17.2,
:data:`STATE_TOL`), both through :func:`assert_fields_match`: every field of the result type must have a
tolerance in its table (:class:`Tol`), and a field without one, or a tolerance for a field that is gone,
fails the comparison.

The kernel's tolerances: the same shapes and dtypes; failure codes, reachability, w_G, reachable_fraction,
parts and actuators identical; NaN and +-inf at the same places; finite values to 1e-10 relative (angles,
the excess, the guard grade and the violations of MODEL.md 16: 1e-10 of max(|value|, 1); the drill-tip
metrics, a closed form against a 5x5 solve: 10x that; the clearances as tests/test_clearance.py). The one
allowance is rounding amplified by the conditioning of the point itself: the reference's own last-bit noise
(e.g. AVX-512 NumPy's SVML arcsin/arccos/arctan2 against libm) grows like eps * kappa near a singular
Jacobian and like eps / (1 - arg^2) near a four-bar limit (arg = TMS argument of Eq 3), so the tolerance of
a point is max(1e-10, 1e-13 kappa_max, 1e-13 / (1 - arg^2)), computed from the reference's solution
(:func:`point_rtol`). For the well-conditioned points (kappa < 1000, 1 - arg^2 > 1e-3) this is exactly 1e-10.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from arcube.evaluation import kernel
from arcube.evaluation.reference import Options, evaluate_task
from arcube.model.mechanism import ALL_MODES, inverse_kinematics
from arcube.motion.limits import ProgramLimits

RTOL = 1e-10


@dataclass(frozen=True)
class Tol:
    """How a field of one engine's result must equal the reference's. Always: the same shape and dtype.
    ``exact``: the same values. Otherwise floats with NaN and +-inf at the same places and, where finite,
    |got - reference| <= rel * rtol * max(|reference|, floor) + abs, rtol being the tolerance the comparison
    is given (for the kernel, the point's tolerance of the module doc; per-design fields: the largest over
    the design's points)."""

    exact: bool = False
    rel: float = 1.0
    floor: float = 0.0
    abs: float = 0.0
    where: tuple[str, float] | None = None
    """(field, value): ``exact`` only at the points where that field of the reference exceeds the value,
    and negative (none, -1) at the same places everywhere."""
    below: float | None = None
    """One-sided: the value may be below the reference's by up to this much (and above it by the tolerance)."""
    skip: tuple[str, float, float] | None = None
    """(field, lo, hi): not compared at the rows where that field of the reference is in [lo, hi)."""


EXACT = Tol(exact=True)
TIP = Tol(rel=10.0, floor=1e-3)
"""The drill-tip metrics of MODEL.md 15: a closed form in the kernel, a 5x5 solve in the reference, equal to
1e-9 relative (tests/test_performance_pipeline.py), growing with the conditioning like the other fields.
A metric that is 0 in exact arithmetic (joint errors that cancel along a world axis) comes out as
rounding noise, ~1e-15 of the design's other values and different in each engine: hence the floor,
1e-9 of max(|value|, 1e-3) in the metric's unit (mm, deg, N·m)."""
ACTUATOR = Tol(exact=True, where=("torque_Nm", 1e-6))
"""The actuator of the largest torque, where that torque (N·m) is not 0 up to rounding (-1 at the same points)."""
HOLDING_ACTUATOR = Tol(exact=True, where=("holding_torque_Nm", 1e-6))
"""The same for the holding torque of MODEL.md 18.2 (tests/test_kernel_masses.py turns it on)."""
CLEARANCE = Tol(abs=0.15)
"""Clearance to the anatomy, mm: the kernel's branch and bound stops within TOL_MM = 0.1 of the field's
minimum along the body, the reference samples every 0.25 mm (within 0.125); as tests/test_clearance.py."""
SELF_CLEARANCE = Tol(rel=0.0, abs=1e-9)
"""Self clearance, mm: the same closest-point formulas and chord polylines in both (tests/test_clearance.py)."""
ENVELOPE = Tol(rel=0.0, abs=1e-9)
"""Clearance to the envelope of the whole patient (MODEL.md 19.5), mm: both engines minimise exactly along every
segment (by different methods), the arcs as the same chord polylines; they agree to rounding (tests/test_envelope.py
runs them with the default envelope, where these fields are not NaN). With a skin mesh it is searched as the anatomy
(CLEARANCE's tolerance; tests/test_envelope.py)."""

GRADE = Tol(floor=1.0)
"""The guard grade of MODEL.md 16 (a sum of terms min(s/S, 1), unitless): as the graded excess; its terms
come from the same shortfalls the failure codes (compared exactly) are decided by."""

POINT_TOL: dict[str, Tol] = {
    "reachable": EXACT,
    "failure": EXACT,
    "kappa": Tol(),
    "eta_L": Tol(),
    "dexterity_pct": Tol(),
    "excess": Tol(floor=1.0),
    "guard_grade": GRADE,
    "rho": Tol(floor=1.0),
    "delta": Tol(floor=1.0),
    "sigma": Tol(floor=1.0),
    "clearance_mm": CLEARANCE,
    "clearance_part": EXACT,
    "self_clearance_mm": SELF_CLEARANCE,
    "envelope_clearance_mm": ENVELOPE,
    "envelope_part": EXACT,
    "envelope_region": EXACT,
    "tip_error_mm": TIP,
    "lateral_error_mm": TIP,
    "axial_error_mm": TIP,
    "axis_error_deg": TIP,
    "torque_Nm": TIP,
    "torque_actuator": ACTUATOR,
    "deflection_mm": TIP,
    "holding_torque_Nm": TIP,
    "holding_torque_actuator": HOLDING_ACTUATOR,
}
"""Every PointResults field: how the kernel's must equal the reference's (a field missing here fails)."""
SUMMARY_TOL: dict[str, Tol] = {
    "w_G": EXACT,
    "reachable_fraction": EXACT,
    "eta_G": Tol(),
    "violation": Tol(floor=1.0),
    "violation_reach": Tol(floor=1.0),
    "guard_grade": GRADE,
    "dexterity_min": Tol(),
    "dexterity_mean": Tol(),
    "dexterity_max": Tol(),
    "clearance_min": CLEARANCE,
    "self_clearance_min": SELF_CLEARANCE,
    "envelope_clearance_min": ENVELOPE,
    "tip_error_max": TIP,
    "lateral_error_max": TIP,
    "axial_error_max": TIP,
    "axis_error_max": TIP,
    "torque_max": TIP,
    "deflection_max": TIP,
    "holding_torque_max": TIP,
}
"""Every TaskResults summary field (all but ``points``), as :data:`POINT_TOL`."""

BODY_CLEARANCE_GAP = 0.225
"""mm: the program's compiled check takes the kernel's body clearance less its tolerance (0.1 mm), a lower
bound of the exact minimum over the axes; the reference samples every 0.25 mm, an upper bound (at most
0.125 mm above): the compiled clearance is below the reference's by 0 to 0.225 mm (MODEL.md 17.2)."""
STATE_RTOL = 1e-9
"""The relative tolerance :data:`STATE_TOL` is applied with (eta_L: the kernel's condition numbers)."""
_NEAR_LIMIT = ("clearance", ProgramLimits().clearance, ProgramLimits().clearance + BODY_CLEARANCE_GAP)
STATE_TOL: dict[str, Tol] = {
    "ok": Tol(exact=True, skip=_NEAR_LIMIT),
    "reason": Tol(exact=True, skip=_NEAR_LIMIT),
    "E": EXACT,
    "e": EXACT,
    "q": EXACT,
    "assembly": EXACT,
    "tool_clearance": EXACT,
    "points": EXACT,
    "eta": Tol(),
    "self_clearance": SELF_CLEARANCE,
    "clearance": Tol(rel=0.0, abs=1e-9, below=BODY_CLEARANCE_GAP),
    "envelope_clearance": ENVELOPE,
}
"""Every :class:`arcube.motion.check.StateChecks` field: how the compiled check's (``engine="numba"``) must
equal the reference's, applied with rtol :data:`STATE_RTOL`, with the default limits
(:class:`~arcube.motion.limits.ProgramLimits`). The pose, the IK's joints and assembly signs, the tool
clearance and the points that measure the resolution are NumPy in both engines: the same bits. eta_L and the
self clearance come from the kernel: equal to rounding. The body clearance is one-sided
(:data:`BODY_CLEARANCE_GAP`); so the decision and its reason are the same except at the states whose reference
clearance lies within that gap above the limit (where the compiled check is the stricter)."""


def point_rtol(params: np.ndarray, E: np.ndarray, e: np.ndarray, mode: np.ndarray, ref) -> np.ndarray:
    """Per-point tolerance (see the module doc), shape (..., P)."""
    p = np.asarray(params, dtype=float)[..., None, :]
    m = np.asarray(mode, dtype=float)[..., None, :]
    with np.errstate(invalid="ignore", divide="ignore"):
        sol = inverse_kinematics(p, E, e, m)
        arg = np.where(np.abs(sol.tms_arg) <= 1.0, sol.tms_arg, 0.0)
        margin = np.min(1.0 - arg * arg, axis=-1)
        kap = np.where(np.isfinite(ref.points.kappa), ref.points.kappa, 0.0).max(axis=-1)
        return np.maximum.reduce([np.full_like(kap, RTOL), 1e-13 * kap, 1e-13 / np.maximum(margin, 1e-300)])


def _same_float(name: str, a, b, rtol, scale_floor: float = 0.0, atol: float = 0.0, below: float | None = None) -> None:
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    assert a.shape == b.shape, f"{name}: shape {a.shape} != {b.shape}"
    assert np.array_equal(np.isnan(a), np.isnan(b)), f"{name}: NaN at different places"
    assert np.array_equal(np.isposinf(a), np.isposinf(b)), f"{name}: +inf at different places"
    assert np.array_equal(np.isneginf(a), np.isneginf(b)), f"{name}: -inf at different places"
    fin = np.isfinite(b)
    tol = np.broadcast_to(rtol, b.shape) * np.maximum(np.abs(b), scale_floor) + atol
    if below is not None:  # one-sided: a - b in [-below, tol]
        diff = np.where(fin, a, 0.0) - np.where(fin, b, 0.0)
        bad = (diff > np.where(fin, tol, 0.0)) | (diff < -below)
        assert not bad.any(), (
            f"{name}: {bad.sum()} values off, {name} - reference in [{diff.min():.3g}, {diff.max():.3g}], not [-{below:g}, tol]"
        )
        return
    err = np.abs(np.where(fin, a, 0.0) - np.where(fin, b, 0.0))
    bad = err > np.where(fin, tol, 0.0)
    assert not bad.any(), (
        f"{name}: {bad.sum()} values off, worst rel {np.max(err / np.maximum(tol, 1e-300) * RTOL):.3g}"
    )


def _same(name: str, got_all, ref_all, tol: Tol, rtol: np.ndarray) -> None:
    """Field ``name`` of two results under its :class:`Tol`; ``rtol`` gets trailing axes to the field's
    (kappa's 7, rho's 3, ...)."""
    got, ref = np.asarray(getattr(got_all, name)), np.asarray(getattr(ref_all, name))
    assert got.dtype == ref.dtype, f"{name}: dtype {got.dtype} != {ref.dtype}"
    if tol.skip is not None:
        assert got.shape == ref.shape, f"{name}: shape {got.shape} != {ref.shape}"
        field, lo, hi = tol.skip
        by = np.asarray(getattr(ref_all, field))
        keep = ~((by >= lo) & (by < hi))
        got, ref = got[keep], ref[keep]
        rtol = np.asarray(rtol)[keep] if np.ndim(rtol) else rtol
    if tol.exact:
        assert got.shape == ref.shape, f"{name}: shape {got.shape} != {ref.shape}"
        if tol.where is not None:
            field, value = tol.where
            above = np.abs(np.asarray(getattr(ref_all, field))) > value  # NaN (not computed): not above
            np.testing.assert_array_equal(got < 0, ref < 0, err_msg=f"{name}: none (-1) at different places")
            got, ref = got[above], ref[above]
        np.testing.assert_array_equal(got, ref, err_msg=name)
        return
    rt = np.reshape(rtol, np.shape(rtol) + (1,) * (ref.ndim - np.ndim(rtol)))
    _same_float(name, got, ref, tol.rel * rt, scale_floor=tol.floor, atol=tol.abs, below=tol.below)


def tolerances(table: dict[str, Tol], fields: tuple[str, ...], kind: str) -> dict[str, Tol]:
    """``table`` after checking that it names exactly ``fields`` (a new result field cannot go unchecked)."""
    missing, stale = set(fields) - set(table), set(table) - set(fields)
    assert not missing, f"{kind} fields without a tolerance in tests/compare.py: {sorted(missing)}"
    assert not stale, f"tolerances for fields {kind} no longer has: {sorted(stale)}"
    return table


def assert_fields_match(
    got, ref, table: dict[str, Tol], rtol, kind: str, fields: tuple[str, ...] | None = None
) -> None:
    """Every field of the named tuple ``got`` equals the reference ``ref``'s as ``table`` says (``fields``:
    the fields compared, default all of ``ref``'s); ``rtol`` a scalar or an array of the fields' leading axes."""
    for name, tol in tolerances(table, ref._fields if fields is None else fields, kind).items():
        _same(name, got, ref, tol, rtol)


def assert_matches(got, ref, rtol_pt: np.ndarray, *, want_points: bool = True) -> None:
    """``got`` (kernel) equals ``ref`` (NumPy) in every field, each as POINT_TOL / SUMMARY_TOL say."""
    assert_fields_match(got, ref, SUMMARY_TOL, rtol_pt.max(axis=-1), "TaskResults", ref._fields[1:])
    if not want_points:
        assert got.points is None
        return
    assert_fields_match(got.points, ref.points, POINT_TOL, rtol_pt, "PointResults")


def check(params, E, e, mode=ALL_MODES[0], options=Options(), **kw):
    """Run both engines, assert agreement (with and without points); return the reference result."""
    ref = evaluate_task(params, E, e, mode, options)
    rtol_pt = point_rtol(params, E, e, mode, ref)
    assert_matches(kernel.evaluate_task_numba(params, E, e, mode, options, **kw), ref, rtol_pt)
    assert_matches(
        kernel.evaluate_task_numba(params, E, e, mode, options, want_points=False, **kw),
        ref,
        rtol_pt,
        want_points=False,
    )
    return ref
