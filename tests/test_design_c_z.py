"""c_z, the z dyad's second link, as a parameter of each design (MODEL.md 19.1-19.2).

Oracles: one batch with a c_z per design equals the same designs one at a time with ``Guards.c_z``
(batch against loop); the compiled kernel equals the NumPy reference field by field with a c_z per design
(tests/compare.py's tolerances); the dyad's closure by hand, |Q_z - D_z| against [|d_z - c_z|, d_z + c_z];
the moving mass by hand (tests/naive.py); a design file without c_z reads as c_z = d_z.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from arcube.evaluation import kernel
from arcube.evaluation.masses import holding_torque, moving_mass_kg
from arcube.evaluation.reference import FAILURES, IK_FAILURES, Options, evaluate_task, fit_violation
from arcube.model.body import mechanism_points
from arcube.model.design import Design
from arcube.model.mechanism import ALL_MODES

from compare import assert_matches, point_rtol
from designs import DEMO, near_paper_designs, plan_right
from naive import mass_by_hand

CODE_Z = FAILURES.index("guard/z_dyad") + 1
OPTIONS = Options(z_dyad=True, clearances=True, tip_metrics=True, holding_torque=True)


@pytest.fixture(scope="module")
def case():
    """Designs near Table 2 on the right side, the right side's plan points, and a c_z per design: some
    that close the dyad everywhere, some that do not, one NaN (the options' c_z, else d_z)."""
    X = near_paper_designs(12, 4, 0.01)
    _, task = plan_right(6)
    mp = mechanism_points(X[:, None, :], task.E, task.e, ALL_MODES[0])
    span = np.linalg.norm(mp.Q[..., 2, :] - mp.D[..., 2, :], axis=-1)  # what the dyad must span, NaN where the IK fails
    lo, hi = np.nanmin(span, axis=-1), np.nanmax(span, axis=-1)
    c_z = np.where(
        np.arange(len(X)) % 2 == 0, hi - X[:, 11] + 1.0, 0.5 * (lo + hi) - X[:, 11]
    )  # closes everywhere / at some points
    c_z[3] = np.nan
    return X, task.E, task.e, c_z


def test_a_c_z_per_design_equals_one_design_at_a_time(case) -> None:
    """Batch against loop: each design alone with ``Guards.c_z`` = its c_z gives the same points; the violation
    differs only as MODEL.md 16's amendment says (an own c_z makes an open dyad a point not reached)."""
    X, E, e, c_z = case
    mode = ALL_MODES[0]
    batch = evaluate_task(X, E, e, mode, OPTIONS, c_z=c_z)
    assert np.any(batch.points.failure == CODE_Z) and np.any(
        batch.points.reachable
    )  # the guard fires at some points, not all
    shortfall = _dyad_shortfall_by_hand(X, E, e, mode, c_z)
    n = E.shape[0]
    for i in range(len(X)):
        one = evaluate_task(X[i], E, e, mode, OPTIONS if np.isnan(c_z[i]) else OPTIONS.replace(c_z=float(c_z[i])))
        for name in ("failure", "eta_L", "self_clearance_mm", "holding_torque_Nm"):
            np.testing.assert_allclose(
                getattr(batch.points, name)[i], getattr(one.points, name), rtol=1e-12, err_msg=name
            )
        if np.isnan(c_z[i]):  # the options' c_z: the dyad is a guard, as before
            np.testing.assert_allclose(batch.points.guard_grade[i], one.points.guard_grade, rtol=1e-12)
            assert batch.violation[i] == pytest.approx(one.violation, rel=1e-12)
            continue
        # the amendment by hand, from the one-at-a-time (guard) result and the dyad's span; the dyad is checked
        # where the stages of sections 3-5 solve the point (failure codes 1-7 are theirs)
        stages_fail = (one.points.failure >= 1) & (one.points.failure <= 7)
        opens = (np.nan_to_num(shortfall[i]) > 0.0) & ~stages_fail
        ik = ((one.points.failure > 0) & (one.points.failure <= IK_FAILURES)) | (one.points.failure == CODE_Z)
        reach = (
            0.0 if not ik.any() else ik.sum() / n + one.points.excess.sum() + np.nan_to_num(shortfall[i])[opens].sum()
        )
        grade = np.where(opens, 0.0, one.points.guard_grade)
        np.testing.assert_allclose(batch.points.guard_grade[i], grade, rtol=1e-12, atol=1e-15)
        assert batch.violation_reach[i] == pytest.approx(reach, rel=1e-12, abs=1e-15)
        assert batch.violation[i] == pytest.approx(reach + fit_violation(grade.sum() / n, n), rel=1e-12, abs=1e-15)
        if opens.any():
            assert batch.violation[i] >= 1.0 / n  # at least one point not reached


def _dyad_shortfall_by_hand(X, E, e, mode, c_z) -> np.ndarray:
    """(D, P): how far |Q_z - D_z| lies outside [|d_z - c_z|, d_z + c_z], over d_z + c_z; NaN where the stages fail."""
    mp = mechanism_points(X[:, None, :], E, e, mode)
    span = np.linalg.norm(mp.Q[..., 2, :] - mp.D[..., 2, :], axis=-1)
    d_z = X[:, 11][:, None]
    cz = np.where(np.isnan(c_z), X[:, 11], c_z)[:, None]
    return (np.maximum(span - (d_z + cz), 0.0) + np.maximum(np.abs(d_z - cz) - span, 0.0)) / (d_z + cz)


def test_the_options_c_z_stands_in_for_a_missing_one(case) -> None:
    X, E, e, c_z = case
    with_option = evaluate_task(X[3], E, e, ALL_MODES[0], OPTIONS.replace(c_z=90.0), c_z=np.nan)
    alone = evaluate_task(X[3], E, e, ALL_MODES[0], OPTIONS.replace(c_z=90.0))
    np.testing.assert_array_equal(with_option.points.failure, alone.points.failure)
    np.testing.assert_array_equal(with_option.points.holding_torque_Nm, alone.points.holding_torque_Nm)


def test_kernel_equals_reference_with_a_c_z_per_design(case) -> None:
    X, E, e, c_z = case
    for options in (OPTIONS, OPTIONS.replace(c_z=90.0)):
        for mode in (ALL_MODES[0], ALL_MODES[5]):
            ref = evaluate_task(X, E, e, mode, options, c_z=c_z)
            rtol = point_rtol(X, E, e, mode, ref)
            assert_matches(kernel.evaluate_task_numba(X, E, e, mode, options, c_z=c_z), ref, rtol)
            assert_matches(
                kernel.evaluate_task_numba(X, E, e, mode, options, want_points=False, c_z=c_z),
                ref,
                rtol,
                want_points=False,
            )


def test_the_guard_fails_exactly_where_the_dyad_cannot_span(case) -> None:
    """Closure by hand: the dyad (d_z, c_z) spans |Q_z - D_z| iff |d_z - c_z| <= |Q_z - D_z| <= d_z + c_z."""
    X, E, e, c_z = case
    mode = ALL_MODES[0]
    res = evaluate_task(X, E, e, mode, Options(z_dyad=True), c_z=c_z)
    mp = mechanism_points(X[:, None, :], E, e, mode)
    span = np.linalg.norm(mp.Q[..., 2, :] - mp.D[..., 2, :], axis=-1)
    cz = np.where(np.isnan(c_z), X[:, 11], c_z)[:, None]
    d_z = X[:, 11][:, None]
    opens = (span > d_z + cz) | (span < np.abs(d_z - cz))
    solved = (res.points.failure == 0) | (res.points.failure == CODE_Z)
    assert solved.any() and opens[solved].any() and (~opens[solved]).any()
    np.testing.assert_array_equal(res.points.failure[solved] == CODE_Z, opens[solved])


def test_moving_mass_counts_each_designs_own_c_z(case) -> None:
    X, _, _, c_z = case
    c_z = np.where(np.isnan(c_z), 77.0, c_z)
    got = moving_mass_kg(X, Options(), c_z=c_z)
    want = [mass_by_hand(x, c) for x, c in zip(X, c_z)]
    np.testing.assert_allclose(got, want, rtol=1e-12)


def test_holding_torque_with_a_c_z_column_equals_the_mass_models(case) -> None:
    X, E, e, _ = case
    from arcube.evaluation.mass_bodies import MassModel

    got = holding_torque(X[0], E, e, ALL_MODES[0], Options())
    model = MassModel.of(Options().replace(c_z=170.0))
    a = holding_torque(X[0], E, e, ALL_MODES[0], Options(), masses=model)
    from arcube.evaluation.masses import holding_torque_of_solution
    from arcube.model.mechanism import inverse_kinematics

    sol = inverse_kinematics(X[0], E, e, ALL_MODES[0])
    b = holding_torque_of_solution(sol, X[0], Options(), c_z=170.0)
    np.testing.assert_allclose(b.holding_torque_Nm, a.holding_torque_Nm, rtol=1e-13)
    assert not np.allclose(got.holding_torque_Nm, a.holding_torque_Nm)  # c_z moves the weight


def test_a_design_file_without_c_z_means_d_z(tmp_path) -> None:
    path = tmp_path / "old.json"
    values = {k: v for k, v in DEMO.to_dict().items()}
    path.write_text(json.dumps(values), encoding="utf-8")
    old = Design.from_json(path)
    assert old.c_z is None and old.c_z_mm == values["d_z"] and old.mode is None
    new = old.with_extras(c_z=300.0, mode="+,+,+,-")
    new.to_json(tmp_path / "new.json")
    back = Design.from_json(tmp_path / "new.json")
    assert back.c_z == 300.0 and back.mode == "+,+,+,-" and back.values == old.values
