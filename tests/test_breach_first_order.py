"""Issue "Breach II", item 4: the first-order breach probability and what it takes to reach a target (model §22).

Oracles: closed forms of a normal outside a circle (Rayleigh) and of a one-dimensional normal outside an interval;
sampling of a 2-D normal; the Monte Carlo where the first order is exact (the registration alone is a linear function
of normal draws); round trips of the inverse questions (the registration or screw found gives P = target); the as-built
class against its neighbours.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import norm

import arcube
from arcube.accuracy import ToleranceSettings
from arcube.coerce import mode_signs
from arcube.io import load_trajectories, select
from arcube.options import Loads
from arcube.pedicles.first_order import breach_first_order, moments, outside_ellipse, what_it_takes
from arcube.pedicles.geometry import pedicles
from arcube.pedicles.run import robot_dockings
from arcube.pedicles.sources import RobotModel
from harness import run_cli

ROBOT = Path(__file__).parent / "data" / "one_robot.json"
PERFECT = ToleranceSettings(tol={"lengths": 0.0, "angles": 0.0, "q0": 0.0}, encoder_deg=0.0, backlash_arcmin=0.0)


@pytest.mark.parametrize("sigma", [0.05, 0.4, 1.0, 3.0])
def test_a_centred_isotropic_normal_leaves_a_circle_as_rayleigh_says(sigma: float) -> None:
    got = outside_ellipse([0.0, 0.0], np.eye(2) * sigma**2, [1.0, 1.0])
    assert got == pytest.approx(math.exp(-1.0 / (2.0 * sigma**2)), abs=1e-12)


@pytest.mark.parametrize("m", [0.0, 0.3, 0.9, 1.6])
def test_a_normal_along_one_axis_leaves_the_interval(m: float) -> None:
    s = 0.5
    expected = norm.cdf((-1.0 - m) / s) + norm.sf((1.0 - m) / s)
    # the room 2 x 0.7: along w only, the ellipse is the interval [-2, 2] in mm, [-1, 1] in units of the room
    assert outside_ellipse([2.0 * m, 0.0], np.diag([(2.0 * s) ** 2, 0.0]), [2.0, 0.7]) == pytest.approx(
        expected, abs=1e-9
    )


def test_no_spread_gives_0_inside_and_1_outside_and_nan_stays_nan() -> None:
    np.testing.assert_array_equal(
        outside_ellipse([[0.5, 0.0], [0.0, 1.2]], np.zeros((2, 2, 2)), [[1.0, 1.0], [1.0, 1.0]]), [0.0, 1.0]
    )
    assert np.isnan(outside_ellipse([np.nan, 0.0], np.eye(2), [1.0, 1.0]))


@pytest.mark.parametrize("mean", [[0.5, -0.9], [1.5, 0.2]])
def test_an_anisotropic_normal_against_sampling(mean: list[float]) -> None:
    C = np.array([[0.3, 0.12], [0.12, 0.1]]) * (1.0 if mean[0] < 1 else 0.2)
    room = np.array([0.8, 1.3])
    x = np.random.default_rng(3).multivariate_normal(mean, C, 1_000_000)
    sampled = np.mean((x[:, 0] / room[0]) ** 2 + (x[:, 1] / room[1]) ** 2 > 1.0)
    assert outside_ellipse(mean, C, room) == pytest.approx(sampled, abs=2.5e-3)


def _right_model(tol: ToleranceSettings = PERFECT) -> tuple[RobotModel, object, object]:
    d = robot_dockings(ROBOT)["R"]
    ts = select(load_trajectories("reference"), side="R")
    x = d.to_vector()
    return RobotModel(x, mode_signs(d.mode), tol.tolerances(x), tol.distribution), pedicles(ts, 3.5), ts


def test_the_registration_alone_is_exact_to_first_order() -> None:
    """A perfect robot without thrust: the offset is t + omega x a, linear in normal draws: the first-order P is the
    exact one; the Monte Carlo (200,000 samples) agrees within four of its standard errors at every screw (the screws
    share one registration per sample, so their deviations move together: a 95 % interval per screw is too tight for
    five at once)."""
    model, p, ts = _right_model()
    mom = moments(model, p, ("R",) * 5, 0.0, 1e4)
    fo = breach_first_order(mom, p, 0.6, 0.8)
    d = robot_dockings(ROBOT)["R"]
    n = 200_000
    mc = arcube.pedicles.breach(
        d, ts, tolerances=PERFECT, registration_mm=0.6, registration_deg=0.8, samples=n, loads=Loads(thrust_N=0.0)
    )
    se = np.sqrt(fo * (1.0 - fo) / n)
    assert np.all(fo > 1e-3) and np.all(np.abs(mc.p_breach - fo) <= 4.0 * se), (fo, mc.p_breach)


def test_the_inverse_questions_round_trip() -> None:
    model, p, _ = _right_model(ToleranceSettings(tol={"lengths": 0.005, "angles": 0.0005, "q0": 0.001}))
    mom = moments(model, p, ("R",) * 5, 30.0, 1e4)
    reg, target = 0.2, 0.01
    fo = breach_first_order(mom, p, reg, reg)
    rows = what_it_takes(mom, p, fo, ("assessed",) * 5, reg, reg, target)
    assert [r["level"] for r in rows] == ["C3", "C4", "C5", "C6", "C7", "all"]
    assert rows[-1]["worst_trajectory"] == p.ids[int(np.argmax(fo))]
    for row in rows:
        j = p.ids.index(row["worst_trajectory"])
        r = row["registration_needed"]
        assert r is not None and 0.0 < r < 10.0
        at = breach_first_order(mom, p, r, r)[j]
        beyond = breach_first_order(mom, p, r * 1.01, r * 1.01)[j]
        assert at == pytest.approx(target, rel=1e-3) and beyond > target
        d_max = row["screw_max_mm"]
        from dataclasses import replace

        wider = replace(p, screw=np.full(5, d_max))
        assert breach_first_order(mom, wider, reg, reg)[j] == pytest.approx(target, rel=1e-3)
        assert d_max < min(p.width[j], p.height[j])


def test_as_built_names_the_coarsest_class_that_reaches_the_target() -> None:
    model, p, _ = _right_model()
    mom = moments(model, p, ("R",) * 5, 0.0, 1e4)
    classes = {}
    for c in ("v", "c", "m", "f"):
        built = ToleranceSettings(tolerance_class=c, encoder_deg=0.0, backlash_arcmin=0.0, tol={"q0": 0.0})
        other = RobotModel(model.design, model.mode, built.tolerances(model.design), built.distribution)
        classes[c] = moments(other, p, ("R",) * 5, 0.0, 1e4)
    p_class = {c: breach_first_order(m, p, 0.0, 0.0) for c, m in classes.items()}
    j = 0
    # a target between two classes' P at screw j: the finer one is named, the coarser does not reach it
    ordered = sorted(p_class, key=lambda c: p_class[c][j])  # finest first
    finest, next_ = ordered[0], ordered[1]
    target = 0.5 * (p_class[finest][j] + p_class[next_][j])
    rows = what_it_takes(mom, p, np.array([0.9, 0, 0, 0, 0.0]), ("assessed",) * 5, 0.0, 0.0, target, classes)
    assert rows[0]["worst_trajectory"] == p.ids[j] and rows[0]["as_built"] == finest
    none = what_it_takes(mom, p, np.array([0.9, 0, 0, 0, 0.0]), ("assessed",) * 5, 0.0, 0.0, 1e-9, classes)
    assert none[0]["as_built"] == "none"


def test_breach_writes_what_it_takes(tmp_path: Path, capsys) -> None:
    code, out, err = run_cli(
        ["breach", "--design", str(ROBOT), "--trajectories", "reference", "--samples", "300", "--target", "0.05"]
        + ["--out", str(tmp_path / "b")],
        capsys,
    )
    assert code == 0, err
    with open(tmp_path / "b" / "what_it_takes.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["level"] for r in rows] == ["C3", "C4", "C5", "C6", "C7", "all"]
    assert list(rows[0]) == [
        *("level", "worst_trajectory", "registration_needed", "screw_max_mm", "as_built"),
        *("p_breach", "p_first_order", "target"),
    ]
    assert all(r["target"] == "0.05" for r in rows) and "what it takes to bring P(breach) to 5.0 %" in out
    with open(tmp_path / "b" / "breach.csv", newline="") as f:
        screws = {r["trajectory"]: r for r in csv.DictReader(f)}
    for r in rows[:-1]:  # each level's worst screw by the Monte Carlo
        mine = [s for s in screws.values() if s["level"] == r["level"]]
        assert r["worst_trajectory"] == max(mine, key=lambda s: float(s["p_breach"]))["trajectory"]
