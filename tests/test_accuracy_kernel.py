"""The compiled first order (arcube.accuracy._kernel) against the NumPy reference, field by field; its zonogon
against brute force; and the per-point functions an evaluation kernel would call against the reference."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from designs import SENSITIVITY_CASES as CASES, sensitivity_case as _case

from arcube.accuracy import ToleranceSettings, budget
from arcube.accuracy._kernel import _zonogon, first_order_numba, geometry_rows, lateral_errors, source_map
from arcube.accuracy.first_order import first_order
from arcube.accuracy.sources import IS_ANGLE, JOINT_COLUMN, PARAM_COLUMN, sigmas, tolerances
from arcube.model.mechanism import inverse_kinematics

SETTINGS = [
    ToleranceSettings(),
    ToleranceSettings(tolerance_class="c", docking_mm=0.5, docking_deg=0.2, distribution="normal"),
    ToleranceSettings(tolerance_class="f", tol={"r": 0.0, "q0_delta_x": 0.5}, backlash_arcmin=0.0),
]


def _points(seed, mount, L, mode_index):
    """Reachable poses, then the same poses moved out of reach (NaN rows in both engines)."""
    x, E, e, mode = _case(seed, mount, L, mode_index, n=10)
    return x, np.concatenate([E, E[:3] + 2000.0]), np.concatenate([e, e[:3]]), mode


@pytest.mark.parametrize("settings", SETTINGS)
@pytest.mark.parametrize(("seed", "mount", "L", "mode_index"), CASES)
def test_kernel_equals_numpy_field_by_field(seed, mount, L, mode_index, settings):
    x, E, e, mode = _points(seed, mount, L, mode_index)
    T = settings.tolerances(x)
    sig = sigmas(T, settings.distribution)
    ref = first_order(x, E, e, mode, T, sig)
    fast = first_order_numba(x, E, e, mode, T, sig)
    np.testing.assert_array_equal(fast.valid, ref.valid)
    assert ref.valid[:10].all() and not ref.valid[10:].any()
    for field in ref._fields:
        if field == "valid":
            continue
        a, b = np.asarray(getattr(fast, field)), np.asarray(getattr(ref, field))
        assert a.shape == b.shape, field
        np.testing.assert_array_equal(np.isnan(a), np.isnan(b), err_msg=field)
        # shares are fractions of 1 (a source along e, like L, has a share of rounding noise: compare absolutely);
        # every other field relative to its own column's largest value
        scale = (
            1.0
            if field == "share"
            else np.nanmax(np.abs(b), axis=0, keepdims=True)
            if b.ndim > 1
            else np.nanmax(np.abs(b))
        )
        assert np.nanmax(np.abs(a - b) / np.maximum(scale, 1e-300)) <= 1e-11, field


def test_budget_engines_agree():
    x, E, e, mode = _points(*CASES[2])
    s = ToleranceSettings(samples=30)
    a, b = budget(x, E, e, mode, s, engine="numba"), budget(x, E, e, mode, s, engine="numpy")
    for key, value in a.summary.items():
        assert value == pytest.approx(b.summary[key], rel=1e-11), key
    np.testing.assert_array_equal(a.lateral_mm, b.lateral_mm)  # the Monte Carlo is the same code
    np.testing.assert_allclose(a.share, b.share, rtol=1e-10, atol=1e-15)


def test_kernel_zonogon_equals_brute_force():
    rng = np.random.default_rng(9)
    for n in range(1, 13):
        for _ in range(4):
            H = rng.normal(size=(2, n)) * rng.uniform(0.01, 5.0, size=n)
            brute = np.max(np.linalg.norm(H @ np.array(list(itertools.product((-1.0, 1.0), repeat=n))).T, axis=0))
            assert _zonogon(H[0].copy(), H[1].copy(), np.empty(n)) == pytest.approx(brute, rel=1e-12)


@pytest.mark.parametrize(("seed", "mount", "L", "mode_index"), CASES)
def test_per_point_lateral_errors_from_an_ik_solution(seed, mount, L, mode_index):
    """What an evaluation kernel would call with its own IK values at each point: (worst case, RMS) as the reference."""
    x, E, e, mode = _case(seed, mount, L, mode_index, n=6)
    T = tolerances(x, "c")
    sig = sigmas(T, "uniform")
    ref = first_order(x, E, e, mode, T, sig)
    sol = inverse_kinematics(x, E, e, mode)
    geo = geometry_rows(x)
    col, scale = source_map(PARAM_COLUMN, JOINT_COLUMN, IS_ANGLE)
    n = T.shape[0]
    bufs = (np.empty(18), np.empty((2, 3, 32)), np.empty((2, 3, n)), np.empty(n), np.empty(n), np.empty(n), np.empty(n))
    for k in range(len(E)):
        trig = []
        for a in (*sol.rho[k], *sol.delta[k], *sol.sigma[k]):
            trig += [np.sin(a), np.cos(a)]
        wc, rms = lateral_errors(geo, T, sig, col, scale, *sol.E_m[k], *sol.e[k], *trig, *bufs)
        assert wc == pytest.approx(ref.lateral_wc_mm[k], rel=1e-11)
        assert rms == pytest.approx(ref.lateral_rms_mm[k], rel=1e-11)
