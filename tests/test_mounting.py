"""Mounting rotation and tool offset (MODEL.md 13): oracles written from the spec, not the code.

* the rotation R = R_z(rz) R_y(ry) R_x(rx) is rebuilt from elementary rotations by hand;
* a 27-parameter design must evaluate exactly like the paper's model (the four at 0) applied to
  the task transformed by hand: C = E + L e, then X_m = R^T (C - m), e_m = R^T e, placed back at m;
* IK -> FK returns the drill tip E (not C) and the axis e in the patient frame;
* the compiled kernel equals the NumPy reference with rotation and offset.
"""

from __future__ import annotations

import numpy as np
import pytest

from arcube.evaluation.kernel import evaluate_task_numba
from arcube.evaluation.reference import GUARDED_OPTIONS, Options, evaluate_task
from arcube.model.mechanism import ALL_MODES, forward_kinematics, inverse_kinematics

from designs import reaching_design, reference_task
from naive import rotation


def _by_hand(x: np.ndarray, E: np.ndarray, e: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The paper's model on the task moved by hand: returns (design with the four at 0, E', e')."""
    R = rotation(x[23:26])
    m, L = x[0:3], x[26]
    C = E + L * e
    E2 = m + (C - m) @ R  # row-wise R^T (C - m), placed back at m: R_m coincides with R_w there
    e2 = e @ R
    paper = x.copy()
    paper[23:27] = 0.0
    return paper, E2, e2


@pytest.mark.parametrize(
    ("mount", "L"),
    [
        ((0.0, 0.0, 0.0), 120.0),
        ((-135.0, -144.74, -67.63), 0.0),
        ((-135.0, -144.74, -67.63), 140.0),
        ((20.0, -35.0, 170.0), 60.0),
    ],
)
def test_rotated_design_equals_paper_model_on_task_transformed_by_hand(mount, L) -> None:
    task = reference_task()
    x = reaching_design(mount, L)
    paper, E2, e2 = _by_hand(x, task.E, task.e)
    for mode in (ALL_MODES[0], ALL_MODES[9]):
        for options in (Options(), GUARDED_OPTIONS):
            got = evaluate_task(x, task.E, task.e, mode, options)
            want = evaluate_task(paper, E2, e2, mode, options)
            assert np.array_equal(got.points.reachable, want.points.reachable)
            assert np.array_equal(got.points.failure, want.points.failure)
            np.testing.assert_allclose(got.points.kappa, want.points.kappa, rtol=1e-8, atol=0)
            for field in ("rho", "delta", "sigma"):
                np.testing.assert_allclose(getattr(got.points, field), getattr(want.points, field), rtol=0, atol=1e-9)
            np.testing.assert_allclose(got.violation, want.violation, rtol=1e-9, atol=1e-12)
    assert evaluate_task(x, task.E, task.e, ALL_MODES[0]).points.reachable.sum() > 50


def test_all_zero_additions_equal_the_23_parameter_model_bit_for_bit() -> None:
    task = reference_task()
    x27 = reaching_design((0.0, 0.0, 0.0), 0.0)
    for fn in (evaluate_task, evaluate_task_numba):
        a = fn(x27, task.E, task.e, ALL_MODES[3], GUARDED_OPTIONS)
        b = fn(x27[:23], task.E, task.e, ALL_MODES[3], GUARDED_OPTIONS)
        for f in a.points._fields:
            assert np.asarray(getattr(a.points, f)).tobytes() == np.asarray(getattr(b.points, f)).tobytes(), f


@pytest.mark.parametrize("mode", [0, 5, 10, 15])
def test_ik_then_fk_returns_the_drill_tip_and_axis_with_rotation_and_offset(mode) -> None:
    task = reference_task()
    x = reaching_design((-135.0, -144.74, -67.63), 140.0, mode=mode)
    sol = inverse_kinematics(x, task.E, task.e, ALL_MODES[mode])
    ok = sol.reachable
    assert ok.sum() > 20
    fk = forward_kinematics(x, sol.rho[ok], sol.delta[ok], sol.assembly[ok])
    assert fk.valid.all()
    np.testing.assert_allclose(fk.E, task.E[ok], atol=1e-8)
    np.testing.assert_allclose(fk.e, task.e[ok], atol=1e-10)


def test_kernel_equals_reference_with_rotation_and_offset() -> None:
    task = reference_task()
    rng = np.random.default_rng(11)
    X = np.stack(
        [
            reaching_design(tuple(rng.uniform(-180, 180, 3)), float(rng.uniform(0, 200)), seed=k, n=150, mode=6)
            for k in range(6)
        ]
    )
    X = np.concatenate([X, reaching_design((0.0, 0.0, 0.0), 90.0, n=150, mode=6)[None]])  # unrotated, with an offset
    assert evaluate_task(X, task.E, task.e, ALL_MODES[6]).points.reachable.any(axis=1).sum() >= 5
    for options in (Options(), GUARDED_OPTIONS):
        ref = evaluate_task(X, task.E, task.e, ALL_MODES[6], options)
        got = evaluate_task_numba(X, task.E, task.e, ALL_MODES[6], options)
        assert np.array_equal(got.points.failure, ref.points.failure)
        np.testing.assert_allclose(got.points.eta_L, ref.points.eta_L, rtol=1e-9)
        np.testing.assert_allclose(got.violation, ref.violation, rtol=1e-9, atol=1e-12)
