"""The compiled kernel (arcube.evaluation.kernel) against the NumPy reference (arcube.evaluation.evaluate_task).

Agreement asserted, field by field for every field of TaskResults and PointResults (a field without
a tolerance in :data:`compare.POINT_TOL` / :data:`compare.SUMMARY_TOL` fails; the comparison is
tests/compare.py's, shared with the other kernel tests): the same shapes and dtypes; failure
codes, reachability, w_G, reachable_fraction, parts and actuators identical; NaN and +-inf at the
same places; finite values to 1e-10 relative (angles, the excess, the guard grade and the violations
of MODEL.md 16: 1e-10 of max(|value|, 1); the drill-tip metrics, a closed form against a 5x5 solve: 10x that; the
clearances as tests/test_clearance.py). The one allowance is rounding amplified by the conditioning of the
point itself: the reference's own last-bit noise (e.g. AVX-512 NumPy's SVML arcsin/arccos/
arctan2 against libm) grows like eps * kappa near a singular Jacobian and like eps / (1 - arg^2)
near a four-bar limit (arg = TMS argument of Eq 3), so the tolerance of a point is
max(1e-10, 1e-13 kappa_max, 1e-13 / (1 - arg^2)), computed from the reference's solution.
For the well-conditioned points (kappa < 1000, 1 - arg^2 > 1e-3) this is exactly 1e-10.
"""

from __future__ import annotations

import csv
import math
from importlib import resources

import numpy as np
import pytest

from arcube.evaluation.performance import MAXIMUM_FIELDS
from arcube.evaluation import kernel
from arcube.model.design import Design
from arcube.evaluation.reference import FAILURES, GUARDED_OPTIONS, Options, PointResults, TaskResults, evaluate_task
from arcube.model.mechanism import ALL_MODES, inverse_kinematics
from arcube.evaluation.task import build_task

from compare import POINT_TOL, SUMMARY_TOL, assert_matches, check, point_rtol, tolerances
from designs import near_paper_designs

CODE = {name: i + 1 for i, name in enumerate(FAILURES)}


# ------------------------------------------------------------------------------ data


@pytest.fixture(scope="module")
def points() -> tuple[np.ndarray, np.ndarray]:
    """The reference patient (10 trajectories x 30 points) plus 120 scattered poses around it."""
    text = resources.files("arcube").joinpath("data/reference_patient.csv").read_text(encoding="utf-8")
    rows = list(csv.DictReader(text.splitlines()))
    entry = np.array([[float(r[f"entry_{c}"]) for c in "xyz"] for r in rows])
    target = np.array([[float(r[f"target_{c}"]) for c in "xyz"] for r in rows])
    task = build_task(entry, target, 30)
    rng = np.random.default_rng(7)
    k = rng.integers(0, len(task), 120)
    E = task.E[k] + 25.0 * rng.standard_normal((120, 3))
    e = task.e[k] + 0.6 * rng.standard_normal((120, 3))
    e /= np.linalg.norm(e, axis=-1, keepdims=True)
    # runs of equal directions (the kernel reuses the RTS along them) and single directions
    return np.concatenate([task.E, E]), np.concatenate([task.e, e])


@pytest.fixture(scope="module")
def designs() -> np.ndarray:
    return np.concatenate([near_paper_designs(24, 1, 0.03), near_paper_designs(24, 2, 0.15)])


# ------------------------------------------------------------------------------ tests


def test_comparator_has_a_tolerance_for_every_field() -> None:
    """A result field without a tolerance, or a tolerance for a field that is gone, fails the comparison."""
    assert set(POINT_TOL) == set(PointResults._fields) and set(SUMMARY_TOL) == set(TaskResults._fields[1:])
    with pytest.raises(AssertionError, match="without a tolerance"):
        tolerances(POINT_TOL, (*PointResults._fields, "new_field"), "PointResults")
    with pytest.raises(AssertionError, match="no longer has"):
        tolerances(SUMMARY_TOL, TaskResults._fields[2:], "TaskResults")


def test_warm_up_compiles() -> None:
    assert kernel.warm_up() >= 0.0


def test_all_16_working_modes(designs, points) -> None:
    E, e = points
    seen = np.zeros(len(FAILURES) + 1, dtype=bool)
    for mode in ALL_MODES:
        ref = check(designs, E, e, mode)
        seen[np.unique(ref.points.failure)] = True
    # the data reach every branch: reachable points and every stage failure (TLS, RTS, TMS)
    assert seen[0] and seen[1:8].all(), np.flatnonzero(seen)
    assert np.all(designs[:, 0:3] != 0.0)


def test_per_design_modes(designs, points) -> None:
    E, e = points
    modes = ALL_MODES[np.random.default_rng(3).integers(0, 16, len(designs))]
    check(designs, E, e, modes)
    check(designs, E, e, modes, GUARDED_OPTIONS)


GUARDS = {
    "none": (Options(), None),
    "guarded": (GUARDED_OPTIONS, None),
    "z_dyad": (Options(z_dyad=True), "guard/z_dyad"),
    "z_dyad_c_z": (Options(z_dyad=True, c_z=150.0), "guard/z_dyad"),
    "rho_max": (Options(rho_max_deg=50.0), "guard/rho_max"),
    "transmission": (Options(min_transmission_deg=30.0), "guard/transmission"),
    "kappa_max": (Options(kappa_max=5.0), "guard/kappa_max"),
    "single_assembly_mode": (Options(single_assembly_mode=True), "guard/single_assembly_mode"),
}


@pytest.mark.parametrize("name", list(GUARDS))
def test_guards(name, designs, points) -> None:
    options, reason = GUARDS[name]
    E, e = points
    modes = ALL_MODES[np.random.default_rng(5).integers(0, 16, len(designs))]
    ref = check(designs, E, e, modes, options)
    if reason is not None:  # the guard really fires on this data
        assert np.any(ref.points.failure == CODE[reason])
    if name == "guarded":
        assert np.any(ref.points.failure == CODE["guard/single_assembly_mode"])


LIGHT_GUARDS = Options(single_assembly_mode=True, kappa_max=100.0, min_transmission_deg=10.0)


@pytest.mark.parametrize("options", [Options(), LIGHT_GUARDS], ids=["plain", "guarded"])
def test_designs_that_reach_the_whole_task(options, points) -> None:
    """Finite eta_G: the right-side trajectories, which designs close to Table 2 reach."""
    E, e = points[0][:300], points[1][:300]  # the reference patient
    right = E[:, 0] > 0.0  # the side-R trajectories (1, 3, 5, 7, 9) lie at x > 0
    X = near_paper_designs(40, 4, 0.01)
    modes = ALL_MODES[np.random.default_rng(6).integers(0, 16, len(X))]
    ref = check(X, E[right], e[right], ALL_MODES[0], options)
    assert np.any(ref.w_G) and np.all(np.isfinite(ref.eta_G[ref.w_G]))
    ref = check(X, E[right], e[right], modes, options)
    assert np.any(ref.w_G)


def test_exact_path(designs, points) -> None:
    E, e = points
    modes = ALL_MODES[np.random.default_rng(9).integers(0, 16, len(designs))]
    ref = check(designs, E, e, modes, GUARDED_OPTIONS, exact=True)
    rtol_pt = point_rtol(designs, E, e, modes, ref)
    fast = kernel.evaluate_task_numba(designs, E, e, modes, GUARDED_OPTIONS)
    exact = kernel.evaluate_task_numba(designs, E, e, modes, GUARDED_OPTIONS, exact=True)
    assert_matches(fast, exact, rtol_pt)


def _numpy_trig_is_libm() -> bool:
    """Whether NumPy's float64 trigonometry returns libm's bits (no SVML), as the kernel's does."""
    x = np.linspace(-0.999, 0.999, 2001)
    y = np.linspace(-3.0, 3.0, 2001)
    pairs = [
        (np.arcsin(x), [math.asin(v) for v in x]),
        (np.arccos(x), [math.acos(v) for v in x]),
        (np.arctan2(x, y), [math.atan2(a, b) for a, b in zip(x, y)]),
        (np.sin(y), [math.sin(v) for v in y]),
        (np.cos(y), [math.cos(v) for v in y]),
    ]  # (not hypot: CPython's math.hypot is its own algorithm, not libm's)
    return all(np.array_equal(a, np.array(b)) for a, b in pairs)


_TIP_FIELDS = frozenset(
    {
        *MAXIMUM_FIELDS,
        "torque_actuator",
        "holding_torque_actuator",
        *(f.rsplit("_", 1)[0] + "_max" for f in MAXIMUM_FIELDS),
    }
)


def test_exact_path_is_bitwise_where_numpy_uses_libm(designs, points) -> None:
    """exact=True repeats the reference operation for operation: same bits, when NumPy's trig
    functions are libm's (not AVX-512 SVML; try NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL")."""
    if not _numpy_trig_is_libm():
        pytest.skip("NumPy's SIMD trigonometry differs from libm in the last bit on this machine")
    E, e = points
    modes = ALL_MODES[np.random.default_rng(2).integers(0, 16, len(designs))]
    for X, m in ((designs, modes), (designs[0], modes[0])):
        for options in (Options(), GUARDED_OPTIONS, Options(z_dyad=True)):
            got = kernel.evaluate_task_numba(X, E, e, m, options, exact=True)
            ref = evaluate_task(X, E, e, m, options)
            # the drill-tip metrics (MODEL.md 15) are a closed form in the kernel and a 5x5 solve in the
            # reference: equal to 1e-9, not bit for bit (tests/test_performance_pipeline.py)
            for field in (f for f in ref.points._fields if f not in _TIP_FIELDS):
                np.testing.assert_array_equal(getattr(got.points, field), getattr(ref.points, field), err_msg=field)
            for field in (f for f in ref._fields[1:] if f not in _TIP_FIELDS):
                np.testing.assert_array_equal(getattr(got, field), getattr(ref, field), err_msg=field)


def test_summaries_identical_with_and_without_points(designs, points) -> None:
    E, e = points
    a = kernel.evaluate_task_numba(designs, E, e, ALL_MODES[5], GUARDED_OPTIONS, want_points=True)
    b = kernel.evaluate_task_numba(designs, E, e, ALL_MODES[5], GUARDED_OPTIONS, want_points=False)
    assert b.points is None
    for field in a._fields[1:]:
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))


def test_shapes_broadcasting_and_point_chunks(designs, points) -> None:
    E, e = points
    # one design: per-point (P,), summaries 0-d; few designs take the point-chunk path
    one = check(designs[0], E, e, ALL_MODES[3], GUARDED_OPTIONS)
    assert one.points.eta_L.shape == (len(E),)
    got = kernel.evaluate_task_numba(designs[0], E, e, ALL_MODES[3], GUARDED_OPTIONS)
    assert got.points.kappa.shape == (len(E), 7) and np.shape(got.eta_G) == ()
    # chunked and per-design paths give the same bits
    many = kernel.evaluate_task_numba(designs, E, e, ALL_MODES[3], GUARDED_OPTIONS)
    for field in ("failure", "kappa", "eta_L", "excess", "guard_grade", "delta"):
        np.testing.assert_array_equal(getattr(got.points, field), getattr(many.points, field)[0])
    for field in ("violation", "violation_reach", "guard_grade"):
        np.testing.assert_array_equal(getattr(got, field), getattr(many, field)[0])
    # designs (2, 3, 23) against modes (3, 4): batch (2, 3)
    X = designs[:6].reshape(2, 3, 23)
    ref = check(X, E, e, ALL_MODES[[0, 7, 12]], Options(single_assembly_mode=True))
    assert ref.points.kappa.shape == (2, 3, len(E), 7) and ref.eta_G.shape == (2, 3)
    # one design against several modes: batch (4,)
    check(designs[30], E[:50], e[:50], ALL_MODES[:4])


def test_exact_boundaries_and_axis_directions() -> None:
    """Round-number geometry: TLS arguments exactly +-1 and 0, drill axes along the world axes."""
    x = Design.preset("paper").to_vector()
    x[0:3] = 0.0
    x[3:6] = (100.0, 100.0, 40.0)  # f
    x[6:9] = (140.0, 150.0, 120.0)  # p
    x[16] = 60.0  # r: (u + f + r)/p = 1 at u = p - 160, -1 at u = -p - 160, 0 at u = -160
    x[19:23] = (80.0, 80.0, 75.0, 75.0)
    us = []
    for p_u, f_u in ((140.0, 100.0), (150.0, 100.0), (120.0, 40.0)):
        us.append([p_u - f_u - 60.0, -p_u - f_u - 60.0, -f_u - 60.0, -f_u - 60.0 + 7.0])
    grid = np.array(np.meshgrid(*us, indexing="ij")).reshape(3, -1).T
    dirs = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.6, 0.0, 0.8], [0.0, -0.6, 0.8]])
    E = np.repeat(grid, len(dirs), axis=0)
    e = np.tile(dirs, (len(grid), 1))
    for options in (Options(), GUARDED_OPTIONS, Options(z_dyad=True)):
        ref = check(np.stack([x, x]), E, e, ALL_MODES[[0, 9]], options)
        check(np.stack([x, x]), E, e, ALL_MODES[[0, 9]], options, exact=True)
    tls = inverse_kinematics(x, E, e).tls_arg
    assert np.any(np.abs(tls) == 1.0) and np.any(tls == 0.0)
    assert np.any(ref.points.failure == CODE["singular/J_rho"])  # rho = 0: G = 0


def test_degenerate_designs_follow_ieee_like_numpy(points) -> None:
    """Zero links (an invalid design, but a valid array) give inf/NaN as in NumPy, never an exception."""
    E, e = points
    X = np.repeat(near_paper_designs(1, 8, 0.01), 5, axis=0)
    X[0, 14] = 0.0  # t_x = 0: H_x = 0, transmission sine 0/0
    X[1, 8] = 0.0  # p_z = 0: TLS argument +-inf
    X[2, 9] = 0.0  # d_x = 0: TMS A = B = 0
    X[3, 19] = 0.0  # alpha_x = 0: RTS A = B = 0
    X[4, 21:23] = 90.0  # beta = 90 deg
    for options in (Options(), GUARDED_OPTIONS, Options(z_dyad=True, c_z=1.0)):
        check(X, E, e, ALL_MODES[0], options)
        check(X, E, e, ALL_MODES[0], options, exact=True)


def test_engine_dispatch(designs, points) -> None:
    from arcube.evaluation.engine import evaluate_task as dispatch

    E, e = points
    a = dispatch(designs[:4], E, e, ALL_MODES[0], GUARDED_OPTIONS, engine="numba", want_points=False)
    b = kernel.evaluate_task_numba(designs[:4], E, e, ALL_MODES[0], GUARDED_OPTIONS, want_points=False)
    np.testing.assert_array_equal(a.eta_G, b.eta_G)
    np.testing.assert_array_equal(a.violation, b.violation)
