"""arcube design: requirements, standoff lines (MODEL.md 17.1), the job's outputs and exit codes."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

import arcube
from arcube import InputError
from arcube.evaluation.anatomy import resolve_anatomy
from arcube.evaluation.standoff import approach_lines, exit_depths, standoff_points
from arcube.optimization.requirements import DEFAULTS, requirements_from


# --------------------------------------------------------------------------- requirements
def test_requirements_defaults_changes_and_drops() -> None:
    reqs = {r.name: (r.kind, r.limit) for r in requirements_from()}
    assert reqs == {"clearance": ("min", 5.0), "self_clearance": ("min", 2.0), "lateral_error": ("max", 0.5),
                    "axis_error": ("max", 0.25), "torque": ("max", 20.0)}  # fmt: skip
    changed = {r.name: r.limit for r in requirements_from({"clearance": 8}, {"torque": 15}, drop=["axis_error"])}
    assert changed == {"clearance": 8.0, "self_clearance": DEFAULTS["self_clearance"], "lateral_error": DEFAULTS["lateral_error"], "torque": 15.0}


@pytest.mark.parametrize(
    "minima, maxima, drop, needle",
    [({"speed": 1}, None, (), "unknown requirement"), (None, {"clearance": 5}, (), "give it as min"),
     ({"clearance": -1}, None, (), "finite number >= 0"), (None, {"torque": 0}, (), "> 0"), (None, None, ("mass",), "unknown requirement")],
)  # fmt: skip
def test_bad_requirements_are_one_line(minima, maxima, drop, needle) -> None:
    with pytest.raises(InputError, match=needle):
        requirements_from(minima, maxima, drop)


# --------------------------------------------------------------------------- standoff (MODEL.md 17.1)
def test_exit_depth_of_a_cube_by_hand() -> None:
    cube = trimesh.creation.box(extents=(10.0, 10.0, 10.0))  # [-5, 5]^3
    origins = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, -20.0], [20.0, 0.0, 0.0], [0.0, 3.0, 4.0]])
    dirs = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.6, 0.8]])
    # from the centre: leaves at z = 5; from below: enters at 15, leaves at 25; outside, away: 0;
    # from (0, 3, 4) along (0, .6, .8): leaves through z = 5 at t = 1.25
    np.testing.assert_allclose(exit_depths([cube], origins, dirs), [5.0, 25.0, 0.0, 1.25], atol=1e-12)


def test_standoff_is_just_outside_the_reference_anatomy() -> None:
    plan = arcube.load_trajectories("reference")
    anatomy = resolve_anatomy("default", "LPS", "reference")
    S, depth = standoff_points(plan.entry, plan.target, anatomy, 20.0)
    e = (plan.entry - plan.target) / np.linalg.norm(plan.entry - plan.target, axis=1)[:, None]
    np.testing.assert_allclose(S, plan.entry + depth[:, None] * e, atol=1e-9)
    t = depth - 20.0
    assert np.all((t > 40.0) & (t < 90.0))  # skin and muscle along steep cervical pedicle axes
    dist = anatomy.distance
    inside = dist(plan.entry + (t - 1.0)[:, None] * e)
    outside = dist(plan.entry + (t + 1.0)[:, None] * e)
    assert np.all(inside < 0.0) and np.all(outside > 0.0)
    no_anatomy, d0 = standoff_points(plan.entry, plan.target, None, 20.0)
    np.testing.assert_allclose(d0, 20.0) and np.testing.assert_allclose(no_anatomy, plan.entry + 20.0 * e)


def test_approach_lines_run_from_standoff_to_entry_on_the_axis() -> None:
    plan = arcube.load_trajectories("reference")
    E, e = approach_lines(plan.entry, plan.target, None, 7, 20.0)
    E = E.reshape(len(plan.ids), 7, 3)
    axis = (plan.entry - plan.target) / np.linalg.norm(plan.entry - plan.target, axis=1)[:, None]
    np.testing.assert_allclose(E[:, -1], plan.entry, atol=1e-9)
    np.testing.assert_allclose(E[:, 0], plan.entry + 20.0 * axis, atol=1e-9)
    np.testing.assert_allclose(e.reshape(len(plan.ids), 7, 3), np.repeat(axis[:, None], 7, axis=1))


# --------------------------------------------------------------------------- the command
def _arcube(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "arcube", *args], capture_output=True, text=True, cwd=cwd, timeout=600)


@pytest.mark.parametrize(
    "args, needle",
    [(["--min", "clearance"], "expected NAME=VALUE"), (["--min", "speed=3"], "unknown requirement"),
     (["--max", "torque=-2"], "--max"), (["--min", "clearance=-1"], "--min"), (["--seeds", "3-1"], "--seeds"),
     (["--seeds", "x"], "--seeds")],
)  # fmt: skip
def test_bad_design_input_is_one_line_exit_2_and_leaves_nothing(tmp_path: Path, args: list[str], needle: str) -> None:
    out = _arcube("design", "--trajectories", "reference", "--anatomy", "default", "--out", "d", "--quiet", *args, cwd=tmp_path)
    assert out.returncode == 2, out.stderr
    assert out.stderr.startswith("error: ") and out.stderr.count("\n") == 1 and needle in out.stderr
    assert not (tmp_path / "d").exists()


def test_design_without_trajectories_is_one_line(tmp_path: Path) -> None:
    out = _arcube("design", "--out", "d", "--quiet", cwd=tmp_path)
    assert out.returncode == 2 and out.stderr.count("\n") == 1 and not (tmp_path / "d").exists(), out.stderr
