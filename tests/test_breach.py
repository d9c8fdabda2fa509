"""arcube breach (MODEL.md 22): the probability that a screw leaves its pedicle, and what decides it.

Oracles: a closed form (only a registration translation and a circular room: |delta|^2 / s^2 is chi-square with two
degrees of freedom, P = exp(-a'^2 / (2 s^2)), s^2 = sigma_t^2 / 3); a screw wider than its pedicle; medial and
lateral by hand on mirrored screws; the deflection, linear in the thrust, alone (P is 0 or 1 as the one offset lies
inside or outside the room); the batched path against the one-sample-at-a-time reference; the same seed twice; a
calibration's covariance that is tiny (the robot's share vanishes) or not.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import arcube
from arcube.accuracy import ToleranceSettings
from arcube.calibrate.output import covariance_csv
from arcube.io import TrajectorySet, load_trajectories, select, write_csv
from arcube.options import Loads
from arcube.pedicles import breach
from arcube.pedicles.geometry import classify, pedicles
from arcube.pedicles.monte_carlo import BREACH_COLUMNS, wilson
from arcube.pedicles.sources import RobotModel, deflection, draw, robot_displacements, robot_displacements_reference
from arcube.coerce import mode_signs
from harness import cli_error, run_cli

ROBOT = Path(__file__).parent / "data" / "one_robot.json"
PERFECT = ToleranceSettings(tol={"lengths": 0.0, "angles": 0.0, "q0": 0.0}, encoder_deg=0.0, backlash_arcmin=0.0)
"""A robot built without error: every tolerance 0."""


def _right(width: float = 5.0, height: float = 5.0, screw: float = 3.5) -> TrajectorySet:
    """The reference patient's right side with every pedicle W x H and screws of ``screw`` mm (plan columns)."""
    ts = select(load_trajectories("reference"), side="R")
    ped = np.tile([width, height, np.nan, screw], (len(ts.ids), 1))
    return TrajectorySet(ts.ids, ts.levels, ts.sides, ts.entry, ts.target, "right", ped)


def _docking(side: str = "R") -> arcube.Design:
    from arcube.pedicles.run import robot_dockings

    return robot_dockings(ROBOT)[side]


def test_registration_translation_alone_gives_the_closed_form() -> None:
    room = 0.75  # W = H = 5, d = 3.5: a circular room
    sigma_t = 0.85
    n = 20_000
    r = breach(
        _docking(),
        _right(),
        tolerances=PERFECT,
        registration_mm=sigma_t,
        registration_deg=0.0,
        samples=n,
        seed=4,
        loads=Loads(thrust_N=0.0),
    )
    s2 = sigma_t**2 / 3.0
    expected = math.exp(-(room**2) / (2.0 * s2))
    low, high = r.interval
    assert np.all(r.pedicles.room == pytest.approx(room))
    assert np.all((low <= expected) & (expected <= high)), (r.p_breach, expected)
    assert np.all(r.p_alone[:, 0] == 0.0) and np.all(r.p_alone[:, 2] == 0.0)  # a perfect robot, no thrust


def test_a_screw_wider_than_its_pedicle_always_breaches() -> None:
    plan = _right(width=3.0, height=6.0, screw=3.5)
    r = breach(
        _docking(),
        plan,
        tolerances=PERFECT,
        registration_mm=0.0,
        registration_deg=0.0,
        samples=50,
        loads=Loads(thrust_N=0.0),
    )
    rows = r.rows()
    assert all(row["too_wide"] and row["p_breach"] == 1.0 and row["status"] == "screw_too_wide" for row in rows)
    # every screw too wide: P = 1 by geometry, never null (it was None, printed "largest P(breach) is - (screw None)")
    assert r.summary()["too_wide"] == list(plan.ids) and r.summary()["breach_probability"] == 1.0
    assert r.summary()["worst_screw"] == plan.ids[0] and r.summary()["deciding_source"] is None
    assert all(math.isnan(row["p_major"]) and math.isnan(row["p_medial"]) for row in rows)


def test_medial_and_lateral_follow_the_plans_side() -> None:
    """A right screw and its mirror image on the left, both moved 2 mm toward -x: medial on the right (toward the
    midline), lateral on the left; moved toward +x, the other way round. Moved up (+y): cranial on both."""
    plan = TrajectorySet(
        ("r", "l"),
        ("C4", "C4"),
        ("R", "L"),
        [[20.0, 0.0, 20.0], [-20.0, 0.0, 20.0]],
        [[2.0, 2.0, 0.0], [-2.0, 2.0, 0.0]],
        "mirror",
    )
    p = pedicles(plan)
    for dx, right, left in ((-2.0, "medial", "lateral"), (2.0, "lateral", "medial")):
        breach_, direction, _ = classify(p.offsets(np.array([[dx, 0.0, 0.0]] * 2)), p)
        assert breach_.all() and [("medial", "lateral")[int(k)] for k in direction] == [right, left]
    breach_, direction, _ = classify(p.offsets(np.array([[0.0, 3.0, 0.0]] * 2)), p)
    assert breach_.all() and list(direction) == [2, 2]


def test_the_deflection_alone_breaches_or_not_as_its_one_offset_lies() -> None:
    design = _docking()
    plan = _right()
    p = pedicles(plan)
    model = RobotModel(design.to_vector(), mode_signs(design.mode), np.zeros(41))
    d30 = deflection(model, p.isthmus, -p.u, 30.0, 1e4)
    q30 = np.sum((p.offsets(d30) / p.room) ** 2, axis=-1)  # (J,) where the one offset lies, relative to the room
    np.testing.assert_allclose(
        deflection(model, p.isthmus, -p.u, 60.0, 1e4), 2.0 * d30, rtol=1e-12
    )  # linear in the thrust
    j = int(np.argmax(q30))
    for q, inside in ((0.8, True), (1.25, False)):
        thrust = 30.0 * math.sqrt(q / q30[j])
        r = breach(
            design,
            plan,
            tolerances=PERFECT,
            registration_mm=0.0,
            registration_deg=0.0,
            samples=200,
            loads=Loads(thrust_N=thrust),
        )
        assert set(np.unique(r.p_breach)) <= {0.0, 1.0}
        assert r.p_breach[j] == (0.0 if inside else 1.0) and r.p_alone[j, 2] == r.p_breach[j]


def test_the_batched_path_equals_the_reference_sample_by_sample() -> None:
    design = _docking("L")
    plan = select(load_trajectories("reference"), side="L")
    p = pedicles(plan)
    T = ToleranceSettings(tolerance_class="c").tolerances(design.to_vector())
    model = RobotModel(design.to_vector(), mode_signs(design.mode), T)
    draws = draw(np.random.default_rng(9), model, 40, len(p.ids), 1, 0.5, 0.5)
    fast = robot_displacements(model, p.isthmus, -p.u, draws)
    slow = robot_displacements_reference(model, p.isthmus, -p.u, draws)
    assert np.isfinite(slow).all() and np.abs(slow).max() > 0.1  # real errors, class c
    np.testing.assert_allclose(fast, slow, rtol=1e-11, atol=1e-11)
    assert (classify(p.offsets(fast), p)[0] == classify(p.offsets(slow), p)[0]).all()


def test_the_same_seed_gives_the_same_table(tmp_path: Path, capsys) -> None:
    args = ["breach", "--design", str(ROBOT), "--trajectories", "reference", "--samples", "500", "--seed", "5"]
    assert run_cli([*args, "--out", str(tmp_path / "a")], capsys)[0] == 0
    assert run_cli([*args, "--out", str(tmp_path / "b")], capsys)[0] == 0
    a, b = (tmp_path / "a" / "breach.csv").read_text(), (tmp_path / "b" / "breach.csv").read_text()
    assert a == b and a.splitlines()[0].split(",")[: len(BREACH_COLUMNS)] == list(BREACH_COLUMNS)
    import csv

    with open(tmp_path / "a" / "breach.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 10 and all(None not in r for r in rows)
    p = np.array([float(r["p_breach"]) for r in rows])
    low, high = wilson(np.round(p * 500), 500)
    np.testing.assert_allclose([float(r["p_breach_low"]) for r in rows], low, rtol=1e-5)
    summary = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert summary["breach_probability"] == pytest.approx(p.max(), rel=1e-6)
    assert {"C3 R", "C7 L"} <= set(summary["per_level_side"]) and set(summary["per_docking"]) == {"R", "L"}
    assert (tmp_path / "a" / "breach_by_screw.png").read_bytes()[:4] == b"\x89PNG" and (
        tmp_path / "a" / "worst_screw.png"
    ).exists()


def _calibration(folder: Path, scale: float) -> Path:
    """A calibration folder by hand: the right docking's design, encoders and lost motion off, covariance scale^2 I."""
    folder.mkdir()
    (folder / "design.json").write_text(json.dumps(_docking().to_file_dict()))
    (folder / "calibration.json").write_text(json.dumps({"settings": {"encoder_deg": 0.0, "backlash_arcmin": 0.0}}))
    (folder / "covariance.csv").write_text(covariance_csv(np.eye(31) * scale**2))
    return folder


def test_a_calibration_draws_the_robot_from_its_covariance(tmp_path: Path) -> None:
    plan = select(load_trajectories("reference"), side="R")
    kw = {"registration_mm": 0.0, "registration_deg": 0.0, "samples": 400, "loads": Loads(thrust_N=0.0)}
    tiny = breach(None, plan, calibration=_calibration(tmp_path / "tiny", 1e-7), **kw)
    assert np.all(tiny.p_alone[:, 0] == 0.0) and np.all(tiny.offset_p95_mm < 1e-4)
    wide = breach(None, plan, calibration=_calibration(tmp_path / "wide", 0.3), **kw)
    assert np.all(wide.p_alone[:, 0] > 0.0) and np.all(wide.offset_p95_mm > 0.1)


@pytest.mark.parametrize(
    "cells, args, needle",
    [
        ({"pedicle_width_mm": "-4"}, [], "pedicle_width_mm must be a number of mm in (0, 30)"),
        ({"pedicle_width_mm": "nan"}, [], "row 2: pedicle_width_mm is not finite"),
        ({"screw_diameter_mm": "0"}, [], "screw_diameter_mm must be a number of mm in (0, 20)"),
        ({"screw_diameter_mm": "20"}, [], "screw_diameter_mm must be a number of mm in (0, 20)"),
        ({"pedicle_widht_mm": "5"}, [], "did you mean pedicle_width_mm"),
        ({}, ["--screw", "0"], "--screw"),
        ({}, ["--samples", "0"], "--samples"),
        ({}, ["--registration", "-1"], "--registration"),
        ({}, ["--calibration", "cal"], "and design"),
        ({}, ["--calibration", "nocov"], "has no covariance.csv"),
    ],
)
def test_bad_breach_input_is_one_line_exit_2_and_leaves_nothing(
    tmp_path: Path, monkeypatch, capsys, cells, args, needle
) -> None:
    monkeypatch.chdir(tmp_path)
    plan = select(load_trajectories("reference"), side="R")
    write_csv(plan, tmp_path / "plan.csv")
    if cells:
        lines = (tmp_path / "plan.csv").read_text().splitlines()
        lines[0] += "," + ",".join(cells)
        lines[1:] = [line + "," + ",".join(cells.values()) for line in lines[1:]]
        (tmp_path / "plan.csv").write_text("\n".join(lines) + "\n")
    _calibration(tmp_path / "cal", 0.1)
    _calibration(tmp_path / "nocov", 0.1)
    (tmp_path / "nocov" / "covariance.csv").unlink()
    design = [] if "nocov" in args else ["--design", str(ROBOT)]
    code, err = cli_error(
        ["breach", *design, "--trajectories", "plan.csv", "--samples", "50", "--out", "out", *args], capsys
    )
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1 and needle in err, err
    assert not (tmp_path / "out").exists()
