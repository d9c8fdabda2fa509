"""The compiled kernel's holding torque (MODEL.md 18.2, :mod:`arcube.evaluation.kernel._masses`) against
the NumPy reference (:mod:`arcube.evaluation.masses`, 65 bodies' Jacobians, itself checked against
central differences of an independent potential energy in tests/test_masses.py).

* every field of the results, per point and per design, through tests/compare.py's comparison
  (the holding torque to 1e-9 relative, its actuator exactly), on random designs with mounting
  rotations, tool offsets, all working modes, several gravity directions and mass settings, the z dyad
  open and closed; on designs near Table 2 over the reference patient, with and without the guards;
* batch = loop: a batch of designs over all points gives the bits of one design at one point at a time;
* no gravity: the holding torque is the drill-tip torque of MODEL.md 15.3 (another closed form);
* off (the default): the new fields are NaN and -1 and nothing else moves.
"""

from __future__ import annotations

import numpy as np
import pytest

from arcube.evaluation import kernel
from arcube.evaluation.reference import GUARDED_OPTIONS, evaluate_task
from arcube.evaluation.task import build_task
from arcube.io import load_trajectories
from arcube.model.body import mechanism_points
from arcube.model.mechanism import ALL_MODES, inverse_kinematics
from arcube.options import Loads, Masses, Options, Outputs

from compare import check
from designs import M_RIGHT, MASS_CASES, near_paper_designs, placed_case

HOLD = Outputs(holding_torque=True)
GRAVITIES = [(0.0, 0.0, -9.81), (3.0, -5.0, 7.0), (0.0, 9.81, 0.0)]


def _opts(c_z=None, gravity=(0.0, 0.0, -9.81), base: Options = Options(), **masses) -> Options:
    return base.replace(outputs=HOLD, guards=base.guards.replace(c_z=c_z), masses=Masses(gravity=gravity, **masses))


def _cases_points(seed, mount, L, mode_index, n=30):
    """A test_masses case with more poses, plus the same poses seen by a second, perturbed design."""
    x, E, e, mode = placed_case(seed, mount, L, mode_index, n=n)
    X = np.stack([x, x * np.r_[1.0 + 0.02 * np.sin(np.arange(23.0)), np.ones(4)]])
    return X, E, e, mode


@pytest.mark.parametrize(("seed", "mount", "L", "mode_index", "c_z"), MASS_CASES)
def test_kernel_equals_reference_on_random_designs(seed, mount, L, mode_index, c_z) -> None:
    X, E, e, mode = _cases_points(seed, mount, L, mode_index)
    for gravity, masses in zip(
        GRAVITIES, ({}, {"wall_mm": 1.0, "m_motor_kg": 2.5}, {"density_kg_m3": 7800.0, "m_delta_kg": 0.0})
    ):
        ref = check(X, E, e, mode, _opts(c_z, gravity, **masses))
        hold, torque = ref.points.holding_torque_Nm, ref.points.torque_Nm
        assert np.all(np.isfinite(hold[ref.points.reachable])) and ref.points.reachable.sum() >= 30
        assert np.nanmax(np.abs(hold - torque)) > 0.1  # the masses matter: N m-sized differences


def test_the_kernel_cases_cover_the_z_dyad_open_and_closed() -> None:
    states = set()
    for seed, mount, L, mode_index, c_z in MASS_CASES:
        X, E, e, mode = _cases_points(seed, mount, L, mode_index)
        sol = inverse_kinematics(X[0], E, e, mode)
        states |= set(mechanism_points(X[0], sol.E_m, sol.e, c_z=c_z, sol=sol).z_closes.tolist())
    assert states == {True, False}


@pytest.fixture(scope="module")
def patient() -> tuple[np.ndarray, np.ndarray]:
    """The reference patient's right-side trajectories, 15 points each."""
    plan = load_trajectories("reference")
    task = build_task(plan.entry, plan.target, 15)
    right = task.E[:, 0] > 0.0
    return task.E[right], task.e[right]


@pytest.mark.parametrize(
    "base", [Options(), GUARDED_OPTIONS, Options(z_dyad=True, c_z=150.0)], ids=["plain", "guarded", "z_dyad"]
)
def test_kernel_equals_reference_near_table_2(base, patient) -> None:
    E, e = patient
    X = near_paper_designs(8, 4, 0.01)
    modes = ALL_MODES[np.random.default_rng(6).integers(0, 16, len(X))]
    ref = check(X, E, e, modes, _opts(base.guards.c_z, base=base))
    assert np.any(ref.points.reachable) and np.all(np.isfinite(ref.holding_torque_max[ref.reachable_fraction > 0]))
    # gravity alone (no drilling load), and the exact path
    check(
        X,
        E,
        e,
        modes,
        _opts(base.guards.c_z, base=base).replace(loads=Loads(thrust_N=0.0, lateral_force_N=0.0)),
        exact=True,
    )


def test_batch_equals_loop(patient) -> None:
    E, e = patient
    X = near_paper_designs(5, 9, 0.01)
    X[:, 0:3] = M_RIGHT
    opts = _opts(250.0, (1.0, -2.0, -9.0))
    batch = kernel.evaluate_task_numba(X, E, e, ALL_MODES[0], opts)
    assert np.isfinite(batch.points.holding_torque_Nm).sum() > 20
    for i in range(len(X)):
        one = kernel.evaluate_task_numba(X[i], E, e, ALL_MODES[0], opts)  # few designs: the point-chunk path
        np.testing.assert_array_equal(one.points.holding_torque_Nm, batch.points.holding_torque_Nm[i])
        np.testing.assert_array_equal(one.holding_torque_max, batch.holding_torque_max[i])
        for k in range(0, len(E), 7):
            pt = kernel.evaluate_task_numba(X[i], E[k : k + 1], e[k : k + 1], ALL_MODES[0], opts)
            np.testing.assert_array_equal(pt.points.holding_torque_Nm[0], batch.points.holding_torque_Nm[i, k])
            np.testing.assert_array_equal(
                pt.points.holding_torque_actuator[0], batch.points.holding_torque_actuator[i, k]
            )


def test_without_gravity_the_holding_torque_is_the_drill_torque(patient) -> None:
    """MODEL.md 18.2 with g = 0 is 15.3's torque, which the kernel computes by another closed form."""
    E, e = patient
    X = near_paper_designs(6, 4, 0.01)
    got = kernel.evaluate_task_numba(X, E, e, ALL_MODES[0], _opts(gravity=(0.0, 0.0, 0.0)))
    p = got.points
    assert np.isfinite(p.torque_Nm).sum() > 20
    np.testing.assert_allclose(p.holding_torque_Nm, p.torque_Nm, rtol=1e-12, equal_nan=True)
    np.testing.assert_array_equal(p.holding_torque_actuator, p.torque_actuator)
    np.testing.assert_allclose(got.holding_torque_max, got.torque_max, rtol=1e-12, equal_nan=True)


def test_off_by_default_and_nothing_else_moves(patient) -> None:
    E, e = patient
    X = near_paper_designs(4, 4, 0.01)
    off = kernel.evaluate_task_numba(X, E, e, ALL_MODES[0], Options())
    on = kernel.evaluate_task_numba(X, E, e, ALL_MODES[0], _opts())
    assert np.all(np.isnan(off.points.holding_torque_Nm)) and np.all(off.points.holding_torque_actuator == -1)
    assert np.all(np.isnan(off.holding_torque_max)) and np.any(np.isfinite(on.holding_torque_max))
    for name in off.points._fields:
        if not name.startswith("holding"):
            np.testing.assert_array_equal(getattr(on.points, name), getattr(off.points, name), err_msg=name)
    ref = evaluate_task(X, E, e, ALL_MODES[0], Options())
    assert np.all(np.isnan(ref.points.holding_torque_Nm)) and np.all(np.isnan(ref.holding_torque_max))
    # a thin link is fine without the holding torque; with it, the wall must be thinner than the link
    kernel.evaluate_task_numba(X, E, e, ALL_MODES[0], Options(link_radius=1.5))
    with pytest.raises(Exception, match="wall"):
        kernel.evaluate_task_numba(X, E, e, ALL_MODES[0], _opts().replace(link_radius=1.5))
