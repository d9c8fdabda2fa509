"""arcube.accuracy (MODEL.md 20): the ISO 2768-1 tables by hand, the settings' errors, the first order against
15.2 (encoders only), brute force (zonogon) and central differences of the FK, the Monte Carlo against the
linearization at tiny tolerances and its seeding, and the output folder."""

from __future__ import annotations

import csv
import io
import itertools
import json
import math

import numpy as np
import pytest
from designs import PROGRAM_DESIGN as DESIGN
from designs import SENSITIVITY_CASES as CASES, sensitivity_case as _case

from arcube.accuracy import SOURCE_NAMES, ToleranceSettings, budget, write
from arcube.report.accuracy import write_budget
from arcube.accuracy.first_order import first_order, source_jacobians, zonogon_radius
from arcube.accuracy.iso import angular_tolerance, linear_tolerance
from arcube.accuracy.monte_carlo import POSE_INDEX, monte_carlo, percentiles, pose_draws, robot_draws, split
from arcube.accuracy.sources import sigmas, tolerances
from arcube.errors import InputError
from arcube.evaluation.performance import forward_jacobian, tip_metrics
from arcube.evaluation.task import build_task
from arcube.io import load_trajectories, select
from arcube.model.design import Design
from arcube.model.mechanism import forward_kinematics, inverse_kinematics

ENCODER_ONLY = {"tol": {"lengths": 0.0, "angles": 0.0}, "q0_deg": 0.0, "backlash_arcmin": 0.0}
PROGRAM_MODE = np.ones(4)


def _plan(points: int = 5):
    ts = select(load_trajectories("reference"), side="R")
    task = build_task(ts.entry, ts.target, points, ids=ts.ids)
    return task, [task.ids[t] for t in task.trajectory]


# --------------------------------------------------------------------------- ISO 2768-1 (MODEL.md 20.1, by hand)
@pytest.mark.parametrize(
    ("cls", "size", "expected"),
    [
        ("m", 0.5, 0.1),
        ("m", 3.0, 0.1),
        ("c", 3.0, 0.2),
        ("c", 3.01, 0.3),
        ("c", 6.0, 0.3),
        ("c", 6.5, 0.5),
        ("c", 30.0, 0.5),
        ("c", 30.5, 0.8),
        ("c", 120.0, 0.8),
        ("c", 120.5, 1.2),
        ("c", 400.0, 1.2),
        ("c", 401.0, 2.0),
        ("c", 1000.0, 2.0),
        ("c", 1500.0, 3.0),
        ("f", 120.0, 0.15),
        ("f", 121.0, 0.2),
        ("f", 2.0, 0.05),
        ("m", 70.4, 0.3),
        ("m", 165.8, 0.5),
        ("v", 6.0, 0.5),
        ("v", 7.0, 1.0),
        ("v", 700.0, 4.0),
        # no ISO value: below 0.5 mm (L = 0) the 0.5-3 row; class v up to 3 mm its 3-6 value; above 2000 the last row
        ("m", 0.0, 0.1),
        ("f", 0.2, 0.05),
        ("v", 1.0, 0.5),
        ("v", 0.0, 0.5),
        ("m", 2500.0, 1.2),
    ],
)
def test_linear_table(cls, size, expected):
    assert linear_tolerance(size, cls) == pytest.approx(expected, abs=1e-15)


@pytest.mark.parametrize(
    ("cls", "leg", "arcmin"),
    [
        ("m", 5.0, 60),
        ("m", 10.0, 60),
        ("m", 10.5, 30),
        ("m", 50.0, 30),
        ("m", 51.0, 20),
        ("m", 120.0, 20),
        ("m", 121.0, 10),
        ("m", 400.0, 10),
        ("m", 401.0, 5),
        ("f", 70.0, 20),
        ("c", 5.0, 90),
        ("c", 30.0, 60),
        ("c", 70.0, 30),
        ("c", 200.0, 15),
        ("c", 500.0, 10),
        ("v", 5.0, 180),
        ("v", 30.0, 120),
        ("v", 70.0, 60),
        ("v", 200.0, 30),
        ("v", 500.0, 20),
    ],
)
def test_angular_table(cls, leg, arcmin):
    assert angular_tolerance(leg, cls) == pytest.approx(arcmin / 60.0, abs=1e-15)


def test_tolerances_of_a_design_by_source():
    x = Design.paper().to_vector()  # r = 70.4466, L = 0
    T = dict(zip(SOURCE_NAMES, tolerances(x, "m")))
    assert T["r"] == 0.3 and T["p_x"] == 0.5 and T["f_z"] == 0.3 and T["L"] == 0.1  # 134.1 -> 120-400; 56.8 -> 30-120
    assert T["alpha_x"] == T["o_y"] == pytest.approx(20 / 60)  # r in 50-120: 20'
    assert T["m_x"] == T["mount_rz"] == 0.0 and T["q0_delta_y"] == 0.1 and T["encoder_rho_x"] == 0.01
    assert T["backlash_rho_z"] == pytest.approx(1 / 60)
    assert len(T) == 41 and "d_z" not in T
    s = ToleranceSettings(
        tolerance_class="c", tol=["r=0.02", "lengths=0.05", "q0_rho_x=0.3"], backlash_arcmin=3, docking_mm=1.5
    )
    T = dict(zip(SOURCE_NAMES, s.tolerances(x)))
    assert T["r"] == 0.02 and T["f_x"] == T["L"] == 0.05  # a name beats its group, whatever the order
    assert T["beta_y"] == 0.5 and T["q0_rho_x"] == 0.3 and T["q0_rho_y"] == 0.1 and T["backlash_delta_x"] == 0.05
    assert T["m_z"] == 1.5 and T["mount_rx"] == 0.0


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"tolerance_class": "x"}, "ToleranceSettings.tolerance_class"),
        ({"tol": {"foo": 1.0}}, "ToleranceSettings.tol"),
        ({"tol": ["d_z=0.1"]}, "ToleranceSettings.tol"),
        ({"tol": ["r=-0.1"]}, "ToleranceSettings.tol"),
        ({"tol": ["r"]}, "ToleranceSettings.tol"),
        ({"tol": {"angles": "abc"}}, "ToleranceSettings.tol"),
        ({"q0_deg": -0.1}, "ToleranceSettings.q0_deg"),
        ({"backlash_arcmin": math.inf}, "ToleranceSettings.backlash_arcmin"),
        ({"samples": 0}, "ToleranceSettings.samples"),
        ({"samples": 10**7}, "ToleranceSettings.samples"),
        ({"distribution": "gauss"}, "ToleranceSettings.distribution"),
        ({"seed": -1}, "ToleranceSettings.seed"),
    ],
)
def test_bad_settings_raise_one_line_naming_the_field(kwargs, field):
    with pytest.raises(InputError) as info:
        ToleranceSettings(**kwargs)
    msg = str(info.value)
    assert info.value.param == field and msg.startswith(field) and "\n" not in msg and "--" not in msg


def test_bad_budget_input_raises_naming_it():
    task, _ = _plan(3)
    far = task.E + 5000.0
    with pytest.raises(InputError, match="^design reaches none of the 15 plan points") as info:
        budget(DESIGN_OBJ, far, task.e, PROGRAM_MODE, ToleranceSettings(samples=5))
    assert info.value.param == "design"
    with pytest.raises(InputError) as info:  # 100,000 robots x 60 points: over the memory cap
        budget(
            DESIGN_OBJ,
            np.tile(task.E, (4, 1)),
            np.tile(task.e, (4, 1)),
            PROGRAM_MODE,
            ToleranceSettings(samples=100_000),
        )
    assert info.value.param == "ToleranceSettings.samples"
    with pytest.raises(InputError) as info:
        budget(DESIGN_OBJ, task.E, task.e, "+,+,x,+")
    assert info.value.param == "mode"


DESIGN_OBJ = Design.from_dict(DESIGN)


# --------------------------------------------------------------------------- first order (MODEL.md 20.3)
@pytest.mark.parametrize("engine", ["numpy", "numba"])
@pytest.mark.parametrize(("seed", "mount", "L", "mode_index"), CASES)
def test_encoders_only_equal_model_15_2(seed, mount, L, mode_index, engine):
    x, E, e, mode = _case(seed, mount, L, mode_index, n=12)
    r = budget(x, E, e, mode, ToleranceSettings(samples=3, **ENCODER_ONLY), engine=engine)
    tm = tip_metrics(*forward_jacobian(x, E, e, mode), e, encoder_deg=0.01)
    assert r.reachable.all()
    np.testing.assert_allclose(r.first.lateral_wc_mm, tm.lateral_error_mm, rtol=1e-9)
    np.testing.assert_allclose(r.first.axis_wc_deg, tm.axis_error_deg, rtol=1e-9)
    np.testing.assert_allclose(r.first.axial_wc_mm, tm.axial_error_mm, rtol=1e-9)


def test_zonogon_equals_brute_force_over_every_sign_vector():
    rng = np.random.default_rng(4)
    for n in range(1, 13):
        H = rng.normal(size=(6, 2, n)) * rng.uniform(0.01, 10.0, size=(6, 1, n))
        H[0, :, 0] = 0.0  # a zero generator
        if n > 2:
            H[1, :, 1] = -2.5 * H[1, :, 2]  # two parallel ones (opposite)
            H[2, 1, :] = 0.0  # all on one line
        signs = np.array(list(itertools.product((-1.0, 1.0), repeat=n))).T  # (n, 2^n)
        brute = np.max(np.linalg.norm(H @ signs, axis=-2), axis=-1)
        np.testing.assert_allclose(zonogon_radius(H), brute, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(("seed", "mount", "L", "mode_index"), CASES[1:4])
def test_source_columns_equal_central_differences_of_the_fk(seed, mount, L, mode_index):
    """G_E, G_e per unit of each source (mm or deg): the FK of p + dp at q + dq, (dp, dq) = split(+-h on one source)."""
    x, E, e, mode = _case(seed, mount, L, mode_index, n=6)
    G_E, G_e, valid = source_jacobians(x, E, e, mode)
    assert valid.all() and G_E.shape == (6, 3, 41)
    sol = inverse_kinematics(x, E, e, mode)
    q = np.concatenate([sol.rho, sol.delta], axis=-1)
    h = 1e-4
    for i, name in enumerate(SOURCE_NAMES):
        ends = []
        for sign in (1.0, -1.0):
            delta = np.zeros(41)
            delta[i] = sign * h
            dp, dq = split(delta)
            fk = forward_kinematics(x + dp, (q + dq)[:, :3], (q + dq)[:, 3:], sol.assembly)
            ends.append(fk)
        for G, fd in ((G_E, (ends[0].E - ends[1].E) / (2 * h)), (G_e, (ends[0].e - ends[1].e) / (2 * h))):
            scale = np.max(np.abs(fd))
            assert np.max(np.abs(G[..., i] - fd)) <= 1e-5 * scale + 1e-10, name


def test_rms_and_shares_by_hand():
    """Two generators, hand-checked: RMS = sqrt(sum sigma^2 |P_perp g|^2), shares proportional, worst cases."""
    e = np.array([0.0, 0.0, 1.0])
    G_E = np.array([[3.0, 0.0], [0.0, 4.0], [2.0, -1.0]])  # lateral parts (3, 0) and (0, 4), axial 2 and -1
    G_e = np.array([[0.0, 0.01], [0.02, 0.0], [0.0, 0.0]])
    from arcube.accuracy.first_order import budget_from_jacobians

    T = np.array([0.5, 0.25])
    fo = budget_from_jacobians(G_E, G_e, e, T, sigmas(T, "uniform"))
    assert fo.lateral_wc_mm == pytest.approx(math.hypot(1.5, 1.0))
    assert fo.axial_wc_mm == pytest.approx(0.5 * 2 + 0.25 * 1)
    assert fo.axis_wc_deg == pytest.approx(math.degrees(math.hypot(0.01, 0.0025)))
    var = np.array([(0.5**2 / 3) * 9, (0.25**2 / 3) * 16])
    assert fo.lateral_rms_mm == pytest.approx(math.sqrt(var.sum()))
    np.testing.assert_allclose(fo.share, var / var.sum())
    fo = budget_from_jacobians(G_E, G_e, e, T, sigmas(T, "normal"))
    assert fo.lateral_rms_mm == pytest.approx(math.sqrt(((0.5 / 3) ** 2) * 9 + ((0.25 / 3) ** 2) * 16))


# --------------------------------------------------------------------------- Monte Carlo (MODEL.md 20.4)
def test_tiny_tolerances_monte_carlo_approaches_the_first_order():
    """At tolerances 1e-4 of class m's the built robots' exact errors are their linearization to second order.

    Bounds, and why: (1) each robot's exact lateral error at each point equals |P_perp G_E delta| for its own
    draws delta to within 1e-3 of the largest (the remainder is O(|delta|^2): ~1e-5 relative here), so its
    p95 per point equals the linearization's p95 to 1e-3; (2) the linear error never exceeds the zonogon's
    worst case, so the Monte Carlo maximum stays below it (x 1.001); (3) the RMS over N = 2000 robots is a
    sample estimate of the first-order RMS: its relative standard error is about CV(l^2) / (2 sqrt N) < 2 %,
    and 6 % is three of those.
    """
    task, _ = _plan(4)
    x = DESIGN_OBJ.to_vector()
    T = ToleranceSettings().tolerances(x) * 1e-4
    sol = inverse_kinematics(x, task.E, task.e, PROGRAM_MODE)
    q = np.concatenate([sol.rho, sol.delta], axis=-1)
    N, P = 2000, len(task)
    errors, per_robot = monte_carlo(x, task.E, task.e, q, sol.assembly, T, N, "uniform", seed=3)
    rng = np.random.default_rng(3)  # the same draws, in the documented order (one chunk: N x P < CHUNK)
    np.testing.assert_array_equal(robot_draws(rng, T, N, "uniform"), per_robot)
    delta = np.repeat(per_robot[:, None, :], P, axis=1)
    delta[..., POSE_INDEX] += pose_draws(rng, T, N, P, "uniform")
    fo = first_order(x, task.E, task.e, PROGRAM_MODE, T, sigmas(T, "uniform"))
    dE = np.einsum("pin,rpn->rpi", fo.G_E, delta)
    linear = np.linalg.norm(dE - np.einsum("rpi,pi->rp", dE, task.e)[..., None] * task.e, axis=-1)
    assert np.max(np.abs(errors.lateral_mm - linear)) <= 1e-3 * np.max(linear)
    np.testing.assert_allclose(percentiles(errors.lateral_mm, [95.0]), percentiles(linear, [95.0]), rtol=1e-3)
    assert np.all(np.max(errors.lateral_mm, axis=0) <= 1.001 * fo.lateral_wc_mm)
    np.testing.assert_allclose(np.sqrt(np.mean(errors.lateral_mm**2, axis=0)), fo.lateral_rms_mm, rtol=0.06)
    assert np.all(np.max(errors.axis_deg, axis=0) <= 1.001 * fo.axis_wc_deg)
    assert np.all(np.max(errors.axial_mm, axis=0) <= 1.001 * fo.axial_wc_mm)


def test_zero_tolerances_give_zero_error_and_the_same_seed_the_same_robots():
    task, ids = _plan(3)
    zero = ToleranceSettings(samples=20, tol={"lengths": 0, "angles": 0}, q0_deg=0, encoder_deg=0, backlash_arcmin=0)
    r = budget(DESIGN_OBJ, task.E, task.e, PROGRAM_MODE, zero, ids, task.k, engine="numpy")
    assert np.max(r.lateral_mm) < 1e-9 and r.summary["lateral_error_wc_mm"] == 0.0
    s = ToleranceSettings(samples=200, seed=7)
    a = budget(DESIGN_OBJ, task.E, task.e, PROGRAM_MODE, s, ids, task.k, engine="numpy")
    b = budget(DESIGN_OBJ, task.E, task.e, PROGRAM_MODE, s, ids, task.k, engine="numpy")
    c = budget(DESIGN_OBJ, task.E, task.e, PROGRAM_MODE, s.replace(seed=8), ids, task.k, engine="numpy")
    np.testing.assert_array_equal(a.robot_lateral_max_mm, b.robot_lateral_max_mm)
    np.testing.assert_array_equal(a.lateral_mm, b.lateral_mm)
    assert a.summary == b.summary
    assert not np.any(a.robot_lateral_max_mm == c.robot_lateral_max_mm) and a.summary != c.summary
    # the summary is what MODEL.md 20.4 defines: the 95th percentile over robots of each one's plan maximum
    assert a.summary["lateral_error_p95_mm"] == pytest.approx(np.percentile(a.robot_lateral_max_mm, 95))
    assert a.summary["axis_error_p95_deg"] == pytest.approx(np.percentile(a.robot_axis_max_deg, 95))
    assert a.summary["lateral_error_wc_mm"] == np.max(a.first.lateral_wc_mm)


def test_percentiles_count_infinity_as_the_largest_value():
    a = np.array([[1.0, 2.0], [3.0, np.inf], [2.0, 4.0], [np.inf, 5.0]])
    np.testing.assert_allclose(percentiles(a, [0.0, 50.0, 100.0], axis=0)[:, 0], [1.0, 2.5, np.inf])
    np.testing.assert_allclose(percentiles(a[:, 1:2], [50.0, 95.0]).ravel(), [4.5, np.inf])
    finite = np.random.default_rng(1).normal(size=(50, 3))
    np.testing.assert_allclose(percentiles(finite, [5.0, 50.0, 99.0]), np.percentile(finite, [5.0, 50.0, 99.0], axis=0))


# --------------------------------------------------------------------------- the output folder
def test_output_folder_files_columns_and_order(tmp_path):
    task, ids = _plan(4)
    E = task.E.copy()
    E[5] += 4000.0  # one point the design does not reach
    r = budget(DESIGN_OBJ, E, task.e, PROGRAM_MODE, ToleranceSettings(samples=50), ids, task.k)
    out = write_budget(r, tmp_path / "a" / "budget")
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [
            "tolerance.json",
            "tolerance_points.csv",
            "sensitivity.csv",
            "sources.png",
            "lateral_histogram.png",
            "trajectories.png",
        ]
    )
    data = json.loads((out / "tolerance.json").read_text())
    assert list(data["summary"]) == [
        "lateral_error_wc_mm",
        "axis_error_wc_deg",
        "axial_error_wc_mm",
        "lateral_error_rms_mm",
        "lateral_error_p95_mm",
        "axis_error_p95_deg",
    ]
    assert data["settings"]["samples"] == 50 and data["mode"] == "+,+,+,+" and data["reachable_points"] == len(task) - 1
    assert data["summary"]["lateral_error_wc_mm"] == pytest.approx(np.nanmax(r.first.lateral_wc_mm))
    rows = list(csv.reader(io.StringIO((out / "tolerance_points.csv").read_text())))
    assert rows[0] == [
        "trajectory",
        "point",
        "lateral_error_wc_mm",
        "axis_error_wc_deg",
        "axial_error_wc_mm",
        "lateral_error_rms_mm",
        "lateral_error_p50_mm",
        "lateral_error_p95_mm",
        "lateral_error_p99_mm",
        "lateral_error_max_mm",
    ]
    assert [(row[0], int(row[1])) for row in rows[1:]] == list(zip(ids, task.k.tolist()))
    assert rows[6][2:] == [""] * 8  # the unreached point: no values
    assert float(rows[1][2]) == r.first.lateral_wc_mm[0] and float(rows[1][7]) == r.lateral_mm[0, 1]
    sens = list(csv.DictReader(io.StringIO((out / "sensitivity.csv").read_text())))
    assert sorted(row["source"] for row in sens) == sorted(SOURCE_NAMES) and list(sens[0]) == [
        "source",
        "tolerance",
        "unit",
        "share",
    ]
    shares = [float(row["share"]) for row in sens]
    assert shares == sorted(shares, reverse=True) and sum(shares) == pytest.approx(1.0)
    assert {row["source"]: row["unit"] for row in sens}["backlash_rho_x"] == "deg"


def test_output_is_all_or_nothing(tmp_path, monkeypatch):
    task, ids = _plan(3)
    r = budget(DESIGN_OBJ, task.E, task.e, PROGRAM_MODE, ToleranceSettings(samples=10), ids, task.k, engine="numpy")
    full = tmp_path / "full"
    (full / "x.txt").parent.mkdir()
    (full / "x.txt").write_text("keep")
    with pytest.raises(InputError) as info:
        write(r, full)
    assert info.value.param == "out" and "\n" not in str(info.value)
    assert [p.name for p in full.iterdir()] == ["x.txt"]
    import arcube.report.accuracy as pictures

    def broken(_):
        raise OSError("disk full")

    monkeypatch.setitem(pictures.FIGURES, "trajectories.png", broken)
    with pytest.raises(OSError):
        write_budget(r, tmp_path / "new" / "budget")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["full"]  # nothing left behind, not even the parent
    monkeypatch.undo()
    empty = tmp_path / "empty"
    empty.mkdir()
    assert sorted(p.name for p in write(r, empty).iterdir()) == [
        "sensitivity.csv",
        "tolerance.json",
        "tolerance_points.csv",
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty", "full"]  # no temporary folder either
