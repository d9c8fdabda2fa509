"""Robust design (MODEL.md 20.3 in the optimizer): ``lateral_error_wc`` and ``lateral_error_rms`` as objectives and limits.

Oracles: the accuracy budget of ``arcube tolerance`` (an independent path: :func:`arcube.accuracy.budget`) on the
same design and points; MODEL.md 15.2's encoder-only lateral error when every other tolerance is 0; the compiled
first order against the NumPy reference, the batch against a loop; MODEL.md 16's grading of a limit.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import arcube as ac
from arcube.accuracy import ToleranceSettings, budget
from arcube.accuracy.robust import robust_errors
from arcube.evaluation.task import build_task
from arcube.io import load_trajectories, select
from arcube.model.design import Design
from arcube.model.mechanism import parse_mode
from arcube.optimization.build import build_model
from arcube.optimization.config import build_config
from arcube.optimization.settings import RunSettings

from designs import RIGHT_SIDE_M
from harness import arcube, run_cli

POINTS = 6
CLASS_F_Q0 = {"tolerance_class": "f", "tol": {"q0": 0.05}}


@pytest.fixture(scope="module")
def start(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("design") / "right.json"
    Design.preset("paper").replace(**RIGHT_SIDE_M).to_json(path)
    return path


@pytest.fixture(scope="module")
def task():
    plan = select(load_trajectories("reference"), side="R")
    return build_task(plan.entry, plan.target, POINTS)


def _budget_figures(design: Design, task, settings: ToleranceSettings) -> tuple[float, float]:
    r = budget(design, task.E, task.e, "+,+,+,+", settings.replace(samples=2), engine="numpy")
    return r.summary["lateral_error_wc_mm"], r.summary["lateral_error_rms_mm"]


@pytest.mark.parametrize("engine", ["numpy", "numba"])
def test_objectives_are_the_budget_of_arcube_tolerance(start: Path, task, engine: str) -> None:
    common = {
        "design_from": str(start),
        "side": "R",
        "points": POINTS,
        "seed": 1,
        "engine": engine,
        "free": "m_x",
        **CLASS_F_Q0,
    }
    model = build_model(build_config(["reference"], objectives="eta_G,lateral_error_wc,lateral_error_rms", **common))
    x = model.space.encode(model.space.base)
    F = model.evaluate(x[None, :])["F"][0]
    wc, rms = _budget_figures(Design.load(start), task, ToleranceSettings(**CLASS_F_Q0))
    eta = ac.evaluate(Design.load(start), "reference", side="R", points=POINTS).summary_json()["eta_G"]
    np.testing.assert_allclose(F, [eta, wc, rms], rtol=1e-9)
    rep = model.report(x)
    assert (rep["lateral_error_wc_mm"], rep["lateral_error_rms_mm"], rep["tolerance_class"]) == (
        pytest.approx(wc, rel=1e-9),
        pytest.approx(rms, rel=1e-9),
        "f",
    )


def test_limits_add_their_normalized_shortfall(start: Path, task) -> None:
    wc, rms = _budget_figures(Design.load(start), task, ToleranceSettings())  # class m, the default
    common = {"design_from": str(start), "side": "R", "points": POINTS, "seed": 1, "engine": "numpy", "free": "m_x"}
    for maxima, want in [
        ([f"lateral_error_rms={rms / 2!r}"], 1.0),
        ([f"lateral_error_rms={2 * rms!r}", f"lateral_error_wc={2 * wc!r}"], 0.0),
        ([f"lateral_error_wc={wc / 4!r}"], 3.0),
    ]:
        model = build_model(build_config(["reference"], maxima=maxima, **common))
        out = model.evaluate(model.space.encode(model.space.base)[None, :])
        n = model.n_points
        assert out["VIOL"][0] == pytest.approx(want / (1.0 + want) / (2 * n), rel=1e-9)
        assert np.isfinite(out["ETA"][0]) == (want == 0.0)


def test_with_only_the_encoders_the_worst_case_is_the_perfect_robots_lateral_error(start: Path, task) -> None:
    """Every tolerance 0 but the encoders' (0.01 deg, MODEL.md 15.2's default): wc == 15.2's lateral_error."""
    only_encoders = ToleranceSettings(tol={"lengths": 0, "angles": 0, "q0": 0, "backlash": 0})
    x = Design.load(start).to_vector()
    wc, _ = robust_errors(x[None], parse_mode("+,+,+,+"), task.E, task.e, only_encoders, "numba")
    s = ac.evaluate(Design.load(start), "reference", side="R", points=POINTS).summary_json()
    assert wc[0] == pytest.approx(s["lateral_error_max_mm"], rel=1e-9)


def test_compiled_equals_reference_and_batch_equals_loop(start: Path, task) -> None:
    rng = np.random.default_rng(5)
    base = Design.load(start).to_vector()
    X = base + rng.normal(0.0, 0.05, (6, base.size)) * (
        np.arange(base.size) >= 3
    )  # links and angles moved, docking kept
    X[4, 3] = 5.0  # f_x far too short: misses points
    modes = np.array([parse_mode("+,+,+,+")] * 6)
    want = np.array([True, True, False, True, True, True])
    s = ToleranceSettings(tolerance_class="c", distribution="normal")
    fast = robust_errors(X, modes, task.E, task.e, s, "numba", want)
    ref = robust_errors(X, modes, task.E, task.e, s, "numpy", want)
    for a, b in zip(fast, ref):
        np.testing.assert_allclose(a, b, rtol=1e-9, equal_nan=True)
    assert np.isnan(fast[0][2]) and np.isnan(fast[1][2])  # not wanted: not computed
    assert np.isnan(fast[0][4])  # misses a point
    for i in np.flatnonzero(want & np.isfinite(fast[0])):
        one = robust_errors(X[i], modes[i], task.E, task.e, s, "numpy")
        assert (one[0][0], one[1][0]) == (pytest.approx(fast[0][i], rel=1e-9), pytest.approx(fast[1][i], rel=1e-9))
    assert np.sum(np.isfinite(fast[0])) >= 3


def test_the_tolerances_are_part_of_the_run(tmp_path: Path) -> None:
    s = RunSettings(tolerance_class="c", tol=["r=0.02", "q0=0.05"], maxima={"lateral_error_rms": 0.5})
    assert RunSettings.from_table(s.to_table()) == s
    assert "tolerance_class" not in RunSettings().to_table() and "tol" not in RunSettings().to_table()
    assert (
        s.accuracy_settings().tolerances(Design.preset("paper").to_vector())[
            ac.accuracy.SOURCE_NAMES.index("q0_delta_y")
        ]
        == 0.05
    )


@pytest.mark.parametrize(
    "flags, message",
    [
        (["--tol", "foo=1"], "--tol 'foo=1': unknown error source 'foo'"),
        (["--tol", "r=-1"], "--tol 'r=-1': a tolerance must be a finite number >= 0"),
        (["--class", "x"], "--class"),
    ],
)
def test_bad_tolerances_on_optimize_exit_2_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], flags: list[str], message: str
) -> None:
    """In this process (arcube.cli.main, as ``python -m arcube`` runs it; one case in a process of its own below)."""
    argv = ["optimize", "--trajectories", "reference", "--max", "lateral_error_rms=0.5", *flags]
    code, _, err = run_cli([*argv, "--out", str(tmp_path / "run")], capsys)
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "run").exists()


def test_a_bad_tolerance_in_a_process_of_its_own_exits_2_with_one_line(tmp_path: Path) -> None:
    """The same contract through ``python -m arcube`` (start-up, interrupt handling, the real stderr)."""
    argv = ["optimize", "--trajectories", "reference", "--max", "lateral_error_rms=0.5", "--tol", "foo=1"]
    out = arcube(*argv, "--out", str(tmp_path / "run"))
    message = "--tol 'foo=1': unknown error source 'foo'"
    assert out.returncode == 2 and message in out.stderr and len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert not (tmp_path / "run").exists()
