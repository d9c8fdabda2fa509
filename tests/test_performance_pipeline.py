"""MODEL.md 15 through the pipeline: the compiled kernel against the NumPy reference, the JSON contract
of ``arcube evaluate``, and bad loads on the command line.

The reference metrics themselves are checked against independent oracles in test_performance.py;
here the kernel's closed-form forward Jacobian (dual basis of J_AP's rows) must give the same numbers
as the reference's generic 5x5 solve, with and without a mounting rotation and a tool offset.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from arcube.evaluation.kernel import evaluate_task_numba
from arcube.evaluation.performance import ACTUATOR_NAMES, PERFORMANCE_FIELDS
from arcube.evaluation.reference import Options, evaluate_task
from arcube.options import Loads
from arcube.model.mechanism import ALL_MODES

from designs import REFERENCE_CSV, reaching_design, reference_task
from harness import arcube, run_cli

SUMMARY = {
    "tip_error_max_mm",
    "lateral_error_max_mm",
    "axial_error_max_mm",
    "axis_error_max_deg",
    "torque_max_Nm",
    "deflection_max_mm",
}
POINT = {
    "tip_error_mm",
    "lateral_error_mm",
    "axial_error_mm",
    "axis_error_deg",
    "torque_Nm",
    "torque_actuator",
    "deflection_mm",
}


@pytest.mark.parametrize("mount, L", [((0.0, 0.0, 0.0), 0.0), ((-135.0, -144.74, -67.63), 120.0)])
def test_kernel_equals_reference(mount, L) -> None:
    task = reference_task()
    x = reaching_design(mount, L, n=300)
    X = np.stack([x, x * np.r_[np.ones(23), 1.0, 1.0, 1.0, 0.95]])
    opts = Options(
        loads=Loads(
            encoder_deg=[0.01, 0.02, 0.01, 0.005, 0.01],
            thrust_N=25.0,
            lateral_force_N=12.0,
            actuator_stiffness=[1e4, 2e4, 1e4, 5e3, 5e3],
        )
    )
    E = np.concatenate([task.E, task.E[:5] + 400.0])  # and five points out of reach
    e = np.concatenate([task.e, task.e[:5]])
    ref = evaluate_task(X, E, e, ALL_MODES[0], opts)
    ker = evaluate_task_numba(X, E, e, ALL_MODES[0], opts)
    summ = evaluate_task_numba(X, E, e, ALL_MODES[0], opts, want_points=False)
    reach = ref.points.reachable
    assert reach.any() and not reach.all()  # both kinds of points
    for name in PERFORMANCE_FIELDS:
        a, b = getattr(ref.points, name), getattr(ker.points, name)
        assert np.array_equal(np.isnan(a), ~reach) and np.array_equal(np.isnan(b), ~reach), name
        np.testing.assert_allclose(b[reach], a[reach], rtol=1e-9, err_msg=name)
        m = name.rsplit("_", 1)[0] + "_max"
        np.testing.assert_allclose(getattr(ker, m), getattr(ref, m), rtol=1e-9, err_msg=m)
        np.testing.assert_allclose(getattr(summ, m), getattr(ref, m), rtol=1e-9, err_msg=m)
        np.testing.assert_allclose(getattr(ref, m), np.nanmax(np.where(reach, a, np.nan), axis=-1), rtol=0, err_msg=m)
    np.testing.assert_array_equal(ker.points.torque_actuator, ref.points.torque_actuator)
    assert set(np.unique(ref.points.torque_actuator[~reach])) == {-1}


def test_loads_scale_as_the_model_says() -> None:
    """Accuracy is linear in the encoder bound, torque linear in the forces, deflection inverse in k."""
    task = reference_task()
    x = reaching_design((0.0, 0.0, 0.0), 0.0, n=300)
    base = evaluate_task_numba(x, task.E, task.e, ALL_MODES[0], Options())
    other = evaluate_task_numba(
        x,
        task.E,
        task.e,
        ALL_MODES[0],
        Options(loads=Loads(encoder_deg=0.03, thrust_N=60.0, lateral_force_N=20.0, actuator_stiffness=2e4)),
    )
    r = base.points.reachable
    for name, factor in [
        ("tip_error_mm", 3),
        ("lateral_error_mm", 3),
        ("axis_error_deg", 3),
        ("torque_Nm", 2),
        ("deflection_mm", 1),
    ]:
        np.testing.assert_allclose(
            getattr(other.points, name)[r], factor * getattr(base.points, name)[r], rtol=1e-12, err_msg=name
        )


def test_json_carries_the_metrics_with_their_names(right_side_design: Path) -> None:
    out = arcube(
        "evaluate",
        "--design",
        str(right_side_design),
        "--trajectories",
        str(REFERENCE_CSV),
        "--points",
        "5",
        "--json",
        "--thrust",
        "40",
        "--encoder-deg",
        "0.02",
    )
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    s = doc["summary"]
    assert SUMMARY <= set(s) and s["torque_max_actuator"] in ACTUATOR_NAMES
    reach = [p for p in doc["points"] if p["reachable"]]
    unreach = [p for p in doc["points"] if not p["reachable"]]
    assert reach and unreach
    assert all(POINT <= set(p) for p in doc["points"])
    assert all(p[k] is None for p in unreach for k in POINT)
    for key, field in [
        ("tip_error_max_mm", "tip_error_mm"),
        ("torque_max_Nm", "torque_Nm"),
        ("deflection_max_mm", "deflection_mm"),
    ]:
        assert s[key] == max(p[field] for p in reach)
    # lateral and axial are parts of the tip error: each at most the whole, and together at least it
    for p in reach:
        assert p["lateral_error_mm"] <= p["tip_error_mm"] * (1 + 1e-12)
        assert p["axial_error_mm"] <= p["tip_error_mm"] * (1 + 1e-12)
        assert p["lateral_error_mm"] + p["axial_error_mm"] >= p["tip_error_mm"] * (1 - 1e-12)


@pytest.mark.parametrize(
    "args, flag",
    [
        (["--thrust", "nan"], "--thrust"),
        (["--lateral-force", "-1"], "--lateral-force"),
        (["--actuator-stiffness", "0"], "--actuator-stiffness"),
        (["--encoder-deg", "0.01,0.02"], "--encoder-deg"),
        (["--encoder-deg", "fine"], "--encoder-deg"),
    ],
)
def test_bad_loads_are_one_line_exit_2(args, flag, capsys: pytest.CaptureFixture[str]) -> None:
    """In this process (arcube.cli.main, as ``python -m arcube`` runs it; one case in a process of its own below)."""
    code, _, err = run_cli(["evaluate", "--points", "3", *args], capsys)
    assert code == 2
    assert err.count("\n") == 1 and flag in err and "Traceback" not in err


def test_a_bad_load_in_a_process_of_its_own_is_one_line_exit_2() -> None:
    """The same contract through ``python -m arcube`` (start-up, interrupt handling, the real stderr)."""
    out = arcube("evaluate", "--points", "3", "--thrust", "nan")
    assert out.returncode == 2
    assert out.stderr.count("\n") == 1 and "--thrust" in out.stderr and "Traceback" not in out.stderr


@pytest.mark.parametrize("engine", ["numpy", "numba"])
def test_metrics_off_leave_everything_else_unchanged(engine) -> None:
    """``Options(tip_metrics=False)`` (what an optimizer that does not need them runs) gives NaN metrics
    and the very same reachability, eta and violation."""
    task = reference_task()
    x = reaching_design((0.0, 0.0, 0.0), 0.0, n=300)
    fn = evaluate_task if engine == "numpy" else evaluate_task_numba
    on = fn(x, task.E, task.e, ALL_MODES[0], Options())
    off = fn(x, task.E, task.e, ALL_MODES[0], Options(tip_metrics=False))
    for name in ("reachable", "failure", "eta_L", "excess", "kappa"):
        np.testing.assert_array_equal(getattr(off.points, name), getattr(on.points, name))
    assert np.isfinite(on.points.tip_error_mm).any() and np.isnan(off.points.tip_error_mm).all()
    assert (off.points.torque_actuator == -1).all() and np.isnan(off.torque_max)
    assert float(off.eta_G) == float(on.eta_G) and float(off.violation) == float(on.violation)
