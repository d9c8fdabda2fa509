"""MODEL.md 16's amendment: with a design's own c_z, a z leg that cannot close is a point not reached.

Properties, each on the NumPy reference and the compiled kernel:

1. a robot whose z dyad is open at one point ranks below every robot that closes it everywhere, whatever
   the guards cost the latter (V >= 1/n against V < 1/(2n));
2. with c_z not a design parameter (``Guards.c_z``, or a c_z column of NaN) nothing changes: the open dyad is
   graded as a guard, and a NaN column gives bit for bit what no column gives.

The dyad's span |Q_z - D_z| comes from the mechanism's points (tests' own geometry, not the graded code);
the c_z values are chosen from it by hand so that the dyad opens at exactly one point, or nowhere.
"""

from __future__ import annotations

import numpy as np
import pytest

from arcube.evaluation.engine import evaluate_task
from arcube.evaluation.reference import FAILURES, IK_FAILURES, Options
from arcube.model.body import mechanism_points
from arcube.model.mechanism import parse_mode

from designs import DEMO, plan_right

ENGINES = ("numpy", "numba")
CODE_Z = FAILURES.index("guard/z_dyad") + 1
COSTLY = Options(z_dyad=True, self_clearance_mm=1000.0, rho_max_deg=1.0, kappa_max=1.0)
"""Guards every point of the demo's robot fails, most terms saturated: the largest V_fit of a robot that reaches."""


@pytest.fixture(scope="module")
def case():
    """The demo's robot on the right side (30 points), and two c_z: one that closes the dyad everywhere, one
    that leaves it open at exactly the point of the longest span."""
    _, task = plan_right(6)
    x, mode = np.asarray(DEMO.values, dtype=float), parse_mode(DEMO.mode)
    mp = mechanism_points(x, task.E, task.e, mode)
    span = np.linalg.norm(mp.Q[..., 2, :] - mp.D[..., 2, :], axis=-1)
    assert np.isfinite(span).all()
    d_z = x[11]
    longest, second = np.sort(span)[-1], np.sort(span)[-2]
    c_close = longest - d_z + 5.0
    c_one = 0.5 * (longest + second) - d_z  # d_z + c_one lies between the two longest spans
    assert abs(d_z - c_close) < span.min() and abs(d_z - c_one) < span.min()
    return x, task.E, task.e, mode, c_close, c_one, int(np.argmax(span))


@pytest.mark.parametrize("engine", ENGINES)
def test_an_open_z_leg_at_one_point_ranks_below_every_robot_that_closes_it(case, engine) -> None:
    x, E, e, mode, c_close, c_one, worst = case
    n = E.shape[0]
    for options in (Options(z_dyad=True), COSTLY):
        closed = evaluate_task(x, E, e, mode, options, engine=engine, c_z=c_close)
        opened = evaluate_task(x, E, e, mode, options, engine=engine, c_z=c_one)
        assert closed.violation_reach == 0.0 and closed.violation < 1.0 / (2 * n)
        assert opened.points.failure[worst] == CODE_Z and (opened.points.failure == CODE_Z).sum() == 1
        assert opened.violation_reach >= 1.0 / n and opened.violation > closed.violation
        # the excess is the dyad's relative shortfall at that point, by hand
        shortfall = (
            np.linalg.norm(
                mechanism_points(x, E[worst], e[worst], mode).Q[2] - mechanism_points(x, E[worst], e[worst], mode).D[2]
            )
            - (x[11] + c_one)
        ) / (x[11] + c_one)
        assert opened.violation_reach == pytest.approx(1.0 / n + shortfall, rel=1e-9)
        assert opened.points.guard_grade[worst] == 0.0  # not graded as a guard any more
    # the costliest robot that closes the dyad still ranks above the cheapest that leaves it open at one point
    worst_closed = evaluate_task(x, E, e, mode, COSTLY, engine=engine, c_z=c_close).violation
    best_open = evaluate_task(x, E, e, mode, Options(z_dyad=True), engine=engine, c_z=c_one).violation
    assert worst_closed < 1.0 / (2 * n) < 1.0 / n <= best_open


@pytest.mark.parametrize("engine", ENGINES)
def test_with_c_z_not_a_design_parameter_the_open_dyad_stays_a_guard(case, engine) -> None:
    x, E, e, mode, _, c_one, worst = case
    n = E.shape[0]
    as_guard = evaluate_task(x, E, e, mode, Options(z_dyad=True, c_z=c_one), engine=engine)
    assert as_guard.points.failure[worst] == CODE_Z
    assert as_guard.violation_reach == 0.0 and 0.0 < as_guard.violation < 1.0 / (2 * n)
    assert as_guard.points.guard_grade[worst] > 0.0
    assert not ((as_guard.points.failure > 0) & (as_guard.points.failure <= IK_FAILURES)).any()


@pytest.mark.parametrize("engine", ENGINES)
def test_a_nan_c_z_column_is_bit_for_bit_no_column(case, engine) -> None:
    x, E, e, mode, _, c_one, _ = case
    for options in (Options(z_dyad=True, c_z=c_one), COSTLY.replace(c_z=c_one)):
        none = evaluate_task(x, E, e, mode, options, engine=engine)
        nan = evaluate_task(x, E, e, mode, options, engine=engine, c_z=np.nan)
        for name in ("violation", "violation_reach", "guard_grade", "eta_G"):
            assert np.array_equal(getattr(nan, name), getattr(none, name), equal_nan=True), name
        for name in ("failure", "excess", "guard_grade", "eta_L"):
            assert np.array_equal(getattr(nan.points, name), getattr(none.points, name), equal_nan=True), name
