"""Objectives and limits of ``arcube optimize`` (MODEL.md 15.5): the optimizer's values and graded
violation against an independent evaluation of the same design with :func:`arcube.evaluate`, the
Pareto file against re-evaluating its rows, and bad flags.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

import arcube as ac
from arcube.model.design import PARAM_NAMES, Design
from arcube.optimization.config import build_config
from arcube.optimization.build import build_model

from designs import RIGHT_SIDE_M
from harness import arcube, run_cli


@pytest.fixture(scope="module")
def start(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("design") / "right.json"
    Design.preset("paper").replace(**RIGHT_SIDE_M).to_json(path)
    return path


def test_limits_add_their_normalized_shortfall(start: Path) -> None:
    ev = ac.evaluate(Design.load(start), "reference", side="R", points=6)
    s = ev.summary_json()
    assert s["w_G"]
    torque, lateral = s["torque_max_Nm"], s["lateral_error_max_mm"]
    common = {"design_from": str(start), "side": "R", "points": 6, "seed": 1, "engine": "numpy", "free": "m_x"}
    for maxima, want in [
        ([f"torque={torque / 2!r}"], (torque - torque / 2) / (torque / 2)),
        ([f"torque={2 * torque!r}"], 0.0),
        ([f"torque={torque / 2!r}", f"lateral_error={lateral / 4!r}"], 1.0 + 3.0),
    ]:
        model = build_model(build_config(["reference"], maxima=maxima, **common))
        out = model.evaluate(model.space.encode(model.space.base)[None, :])
        n = model.n_points  # MODEL.md 16: a design that reaches everything is graded G / (1 + G) / (2n)
        assert out["VIOL"][0] == pytest.approx(want / (1.0 + want) / (2 * n), rel=1e-9)
        assert np.isfinite(out["ETA"][0]) == (want == 0.0)


def test_objective_columns_are_the_evaluated_values(start: Path) -> None:
    ev = ac.evaluate(Design.load(start), "reference", side="R", points=6)
    s = ev.summary_json()
    common = {"design_from": str(start), "side": "R", "points": 6, "seed": 1, "engine": "numpy", "free": "m_x"}
    model = build_model(build_config(["reference"], objectives="eta_G,torque,axis_error,deflection", **common))
    assert model.n_obj == 4
    F = model.evaluate(model.space.encode(model.space.base)[None, :])["F"][0]
    np.testing.assert_allclose(
        F, [s["eta_G"], s["torque_max_Nm"], s["axis_error_max_deg"], s["deflection_max_mm"]], rtol=1e-9
    )


def test_pareto_rows_hold_27_parameters_and_reevaluate_to_their_objectives(start: Path, tmp_path: Path) -> None:
    out = arcube(
        "optimize",
        "--trajectories",
        "reference",
        "--side",
        "R",
        "--points",
        "6",
        "--design-from",
        str(start),
        "--free",
        "m_x,m_y,m_z,L",
        "--objectives",
        "eta_G,lateral_error",
        "--max",
        "torque=40",
        "--population",
        "12",
        "--generations",
        "4",
        "--seed",
        "3",
        "--quiet",
        "--out",
        str(tmp_path / "run"),
    )
    assert out.returncode == 0, out.stderr
    rows = list(csv.DictReader((tmp_path / "run" / "pareto.csv").open()))
    assert rows
    assert set(PARAM_NAMES) <= set(rows[0])
    for key in ("objective_eta_G", "objective_lateral_error", "torque_max_Nm", "tip_error_max_mm", "deflection_max_mm"):
        assert key in rows[0]
    for row in rows[:3]:
        d = Design.from_vector(np.array([float(row[n]) for n in PARAM_NAMES]))
        s = ac.evaluate(d, "reference", side="R", points=6).summary_json()
        assert float(row["objective_lateral_error"]) == pytest.approx(s["lateral_error_max_mm"], rel=1e-9)
        assert float(row["objective_eta_G"]) == pytest.approx(s["eta_G"], rel=1e-9)
        assert s["torque_max_Nm"] <= 40.0


def _holding_summary(start: Path, **masses) -> dict:
    """The summary of arcube.evaluate with the holding torque of MODEL.md 18.2 on (the reference engine)."""
    opts = ac.Options(outputs=ac.Outputs(holding_torque=True), masses=ac.Masses(**masses))
    return ac.evaluate(Design.load(start), "reference", side="R", points=6, options=opts, engine="numpy").summary_json()


def test_holding_torque_and_mass_limits_add_their_normalized_shortfall(start: Path) -> None:
    """MODEL.md 16 grading of --max holding_torque / --max mass, against an independent arcube.evaluate."""
    s = _holding_summary(start, m_motor_kg=2.0)
    hold, mass = s["holding_torque_max_Nm"], s["moving_mass_kg"]
    assert s["w_G"] and hold > s["torque_max_Nm"] + 0.1 and 2.0 < mass < 10.0
    common = {
        "design_from": str(start),
        "side": "R",
        "points": 6,
        "seed": 1,
        "engine": "numpy",
        "free": "m_x",
        "m_motor": 2.0,
    }
    for maxima, want in [
        ([f"holding_torque={hold / 2!r}"], 1.0),
        ([f"holding_torque={2 * hold!r}", f"mass={2 * mass!r}"], 0.0),
        ([f"mass={mass / 4!r}"], 3.0),
        ([f"holding_torque={hold / 2!r}", f"mass={mass / 2!r}"], 2.0),
    ]:
        model = build_model(build_config(["reference"], maxima=maxima, **common))
        out = model.evaluate(model.space.encode(model.space.base)[None, :])
        n = model.n_points
        assert out["VIOL"][0] == pytest.approx(want / (1.0 + want) / (2 * n), rel=1e-9)
        assert np.isfinite(out["ETA"][0]) == (want == 0.0)


@pytest.mark.parametrize("engine", ["numpy", "numba"])
def test_holding_torque_and_mass_objectives_are_the_evaluated_values(start: Path, engine: str) -> None:
    s = _holding_summary(start, gravity=(0.0, -9.81, 0.0))
    common = {
        "design_from": str(start),
        "side": "R",
        "points": 6,
        "seed": 1,
        "engine": engine,
        "free": "m_x",
        "gravity": "0,-9.81,0",
    }
    model = build_model(build_config(["reference"], objectives="eta_G,holding_torque,mass,torque", **common))
    F = model.evaluate(model.space.encode(model.space.base)[None, :])["F"][0]
    np.testing.assert_allclose(
        F, [s["eta_G"], s["holding_torque_max_Nm"], s["moving_mass_kg"], s["torque_max_Nm"]], rtol=1e-9
    )
    rep = model.report(model.space.encode(model.space.base))
    assert rep["holding_torque_max_Nm"] == pytest.approx(s["holding_torque_max_Nm"], rel=1e-9)
    assert rep["moving_mass_kg"] == pytest.approx(s["moving_mass_kg"], rel=1e-12)


def test_only_runs_that_use_the_masses_compute_or_report_them(start: Path) -> None:
    from arcube.optimization.settings import RunSettings

    common = {"design_from": str(start), "side": "R", "points": 6, "seed": 1, "engine": "numpy", "free": "m_x"}
    model = build_model(build_config(["reference"], objectives="eta_G,torque", **common))
    assert not model.options.outputs.holding_torque
    rep = model.report(model.space.encode(model.space.base))
    assert "holding_torque_max_Nm" not in rep and "moving_mass_kg" not in rep
    assert RunSettings(maxima={"holding_torque": 9}).evaluation_options().outputs.holding_torque
    assert not RunSettings(maxima={"mass": 9}).evaluation_options().outputs.holding_torque  # a design quantity
    with pytest.raises(ac.InputError, match="Masses.wall_mm must be < the link radius"):
        RunSettings(maxima={"mass": 9}, link_radius=2.0)
    RunSettings(maxima={"torque": 9}, link_radius=2.0)  # thin links without masses stay valid


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--wall", "9"], "--wall must be < the link radius"),
        (["--wall", "3", "--link-radius", "3"], "--wall"),
        (["--density", "-2700"], "--density"),
        (["--m-delta", "-1"], "--m-delta"),
        (["--m-motor", "nan"], "--m-motor"),
        (["--gravity", "0,-9.81"], "--gravity"),
        (["--gravity", "x,y,z"], "--gravity"),
        (["--max", "mass=0"], "must be > 0"),
        (["--max", "holding_torque=-1"], "must be > 0"),
        (["--objectives", "eta_G,mass", "--link-radius", "2"], "--wall"),
    ],
)
def test_bad_mass_flags_of_optimize_are_one_line_exit_2(args, needle, tmp_path: Path, capsys) -> None:
    """In this process (arcube.cli.main, as ``python -m arcube`` runs it; a bad flag in a process of its own is
    test_a_bad_flag_in_a_process_of_its_own_is_one_line_exit_2 below)."""
    code, _, err = run_cli(["optimize", "--trajectories", "reference", "--out", str(tmp_path / "run"), *args], capsys)
    assert code == 2, err
    assert err.count("\n") == 1 and needle in err and "Traceback" not in err
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--objectives", "eta_G,speed"], "unknown objective 'speed'"),
        (["--max", "torque"], "expected NAME=VALUE"),
        (["--max", "weight=3"], "unknown name 'weight'"),
        (["--min", "clearance=abc"], "is not a number"),
        (["--max", "torque=-1"], "must be > 0"),
        (["--objectives", "eta_G", "--algorithm", "nsga2"], "needs two or more"),
        (["--objectives", "eta_G,clearance"], "needs an anatomy"),
        (["--thrust", "-3"], "--thrust"),
    ],
)
def test_bad_objective_flags_are_one_line_exit_2(args, needle, tmp_path: Path, capsys) -> None:
    """In this process, as the mass flags above."""
    code, _, err = run_cli(["optimize", "--trajectories", "reference", "--out", str(tmp_path / "run"), *args], capsys)
    assert code == 2, err
    assert err.count("\n") == 1 and needle in err and "Traceback" not in err
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize(
    "args, needle", [(["--density", "-2700"], "--density"), (["--objectives", "eta_G,speed"], "unknown objective")]
)
def test_a_bad_flag_in_a_process_of_its_own_is_one_line_exit_2(args, needle, tmp_path: Path) -> None:
    """The contract of the two tests above through ``python -m arcube`` (start-up, interrupt handling, the real
    stderr), for one flag of each."""
    out = arcube("optimize", "--trajectories", "reference", "--out", str(tmp_path / "run"), *args)
    assert out.returncode == 2, out.stderr
    assert out.stderr.count("\n") == 1 and needle in out.stderr and "Traceback" not in out.stderr
    assert not (tmp_path / "run").exists()
