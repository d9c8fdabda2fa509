"""Joint-space export (arcube.export.joints, ``arcube joints``): rates agree with finite differences of
the IK along the drilling path, time stamps are s/speed, the CSV has the documented columns."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from arcube.model.design import Design
from arcube.cli.projection import flag_message
from arcube.errors import InputError
from arcube.evaluation.reference import Options
from arcube.export.joints import CSV_COLUMNS, joint_trajectory
from arcube.model.mechanism import ALL_MODES
from arcube.cli import joints as joints_cli
from arcube.cli import report as report_cli
from arcube.evaluation.task import build_task
from arcube.io import load_trajectories, select

from designs import PAPER

PLACED = Design.from_dict({**PAPER, "m_x": 88.23, "m_y": 79.40, "m_z": 56.89})
SPEED = 2.5  # mm/s

EXPECTED_COLUMNS = (
    "trajectory,k,t_s,x,y,z,rho_x_deg,rho_y_deg,rho_z_deg,delta_x_deg,delta_y_deg,sigma_x_deg,sigma_y_deg,"
    "rho_x_dps,rho_y_dps,rho_z_dps,delta_x_dps,delta_y_dps,sigma_x_dps,sigma_y_dps,"
    "tau_rho_x_Nm,tau_rho_y_Nm,tau_rho_z_Nm,tau_delta_x_Nm,tau_delta_y_Nm,"
    "tau_rho_x_max_Nm,tau_rho_y_max_Nm,tau_rho_z_max_Nm,tau_delta_x_max_Nm,tau_delta_y_max_Nm,reachable"
).split(",")


def _wrap_deg(a):
    return (np.asarray(a) + 180.0) % 360.0 - 180.0


@pytest.mark.parametrize("mode", [ALL_MODES[0], ALL_MODES[5]], ids=["++++", "+-+-"])
def test_rates_match_central_differences_of_the_ik(mode):
    ts = select(load_trajectories("reference"), side="R")
    n = 1001  # neighbours ~0.03 mm apart: central differences are accurate to O(h^2)
    task = build_task(ts.entry, ts.target, n, ids=ts.ids)
    jt = joint_trajectory(PLACED, task, SPEED, mode)
    q = jt.q_deg.reshape(len(ts), n, 7)
    qd = jt.q_dot_dps.reshape(len(ts), n, 7)
    t = jt.t_s.reshape(len(ts), n)
    ok = jt.reachable.reshape(len(ts), n)
    # Keep interior points at least 30 samples (~1 mm) away from any unreachable point: at the
    # edge of the TMS workspace F -> 0 and delta_dot -> infinity, where no finite difference converges.
    far = ok.copy()
    for s in range(1, 31):
        far[:, s:] &= ok[:, :-s]
        far[:, :-s] &= ok[:, s:]
    inner = far[:, 1:-1]
    assert inner.sum() > 300
    fd = _wrap_deg(q[:, 2:] - q[:, :-2]) / (t[:, 2:] - t[:, :-2])[..., None]
    rate = qd[:, 1:-1][inner]
    err = np.abs(fd[inner] - rate)
    assert np.all(err <= 1e-3 * (np.abs(rate) + 1.0)), err.max()  # O(h^2) truncation, h ~ 0.03 mm
    # sigma depends on e only, and e is constant along a trajectory: its rate is exactly 0.
    assert np.all(qd[..., 5:][ok] == 0.0)
    assert np.all(q[..., 5:][ok] == q[:, :1, 5:].repeat(n, axis=1)[ok])


def test_thrust_torques_balance_the_power_of_drilling():
    """Virtual work along the drilling motion: the actuators' power tau . q_dot equals the power the
    thrust absorbs, F_t * speed (the tip moves against e at ``speed``, the bone pushes along +e);
    the rates come from the velocity model's inverse (B^-1 A), the torques from J_E^T: independent."""
    ts = select(load_trajectories("reference"), side="R")
    task = build_task(ts.entry, ts.target, 8, ids=ts.ids)
    opts = Options().replace(thrust_N=25.0, lateral_force_N=0.0)
    jt = joint_trajectory(PLACED, task, SPEED, options=opts)
    r = jt.reachable
    assert r.any()
    power = 1000.0 * np.sum(jt.tau_thrust_Nm[r] * np.radians(jt.q_dot_dps[r, :5]), axis=-1)  # N·mm/s
    np.testing.assert_allclose(power, 25.0 * SPEED, rtol=1e-8)
    # without a lateral force the worst case is the thrust's own torque, in magnitude
    np.testing.assert_allclose(jt.tau_max_Nm[r], np.abs(jt.tau_thrust_Nm[r]), rtol=1e-9, atol=1e-12)


def test_time_stamps_are_drilled_length_over_speed():
    ts = select(load_trajectories("reference"), side="R")
    task = build_task(ts.entry, ts.target, 30, ids=ts.ids)
    jt = joint_trajectory(PLACED, task, SPEED)
    expected = (task.k / 29.0) * ts.lengths[task.trajectory] / SPEED
    np.testing.assert_allclose(jt.t_s, expected, rtol=1e-12, atol=1e-12)
    assert jt.reachable.all()
    with pytest.raises(ValueError):
        joint_trajectory(PLACED, task, 0.0)


def test_csv_columns_and_unreachable_rows(tmp_path):
    ts = load_trajectories("reference")  # both sides: the left ones are unreachable for this placement
    task = build_task(ts.entry, ts.target, 6, ids=ts.ids)
    jt = joint_trajectory(PLACED, task, SPEED)
    assert 0 < jt.reachable.sum() < len(task)
    path = jt.write_csv(tmp_path / "joints.csv")
    rows = list(csv.reader(io.StringIO(path.read_text())))
    assert tuple(rows[0]) == CSV_COLUMNS == tuple(EXPECTED_COLUMNS)
    assert len(rows) == len(task) + 1
    for i, row in enumerate(rows[1:]):
        rec = dict(zip(rows[0], row))
        assert rec["trajectory"] == task.ids[task.trajectory[i]] and int(rec["k"]) == task.k[i]
        assert rec["reachable"] == ("true" if jt.reachable[i] else "false")
        joint_cells = row[6:20]
        if jt.reachable[i]:
            np.testing.assert_allclose(
                [float(v) for v in joint_cells], np.concatenate([jt.q_deg[i], jt.q_dot_dps[i]]), rtol=0, atol=0
            )
        else:
            assert all(v == "" for v in joint_cells)
        np.testing.assert_allclose([float(rec[c]) for c in "xyz"], task.E[i], rtol=0, atol=0)


def _app() -> typer.Typer:
    app = typer.Typer()

    @app.callback()
    def _root() -> None:
        """test app"""

    joints_cli.register(app)
    report_cli.register(app)
    return app


def test_joints_command(tmp_path):
    design = tmp_path / "d.json"
    PLACED.to_json(design)
    out = tmp_path / "j.csv"
    args = [
        "joints",
        "--design",
        str(design),
        "--trajectories",
        "reference",
        "--speed",
        "1.5",
        "--out",
        str(out),
        "--points",
        "7",
        "--side",
        "R",
        "--mode=+,+,+,+",
    ]
    res = CliRunner().invoke(_app(), args)
    assert res.exit_code == 0, res.output
    assert res.stdout.strip() == str(out)
    rows = list(csv.DictReader(io.StringIO(out.read_text())))
    assert len(rows) == 5 * 7 and all(r["reachable"] == "true" for r in rows)
    assert float(rows[6]["t_s"]) == pytest.approx(
        ts_len := float(select(load_trajectories("reference"), side="R").lengths[0]) / 1.5
    )
    assert ts_len > 0
    for bad, needle in ((["--speed", "0"], "--speed"), (["--mode=+,+"], "--mode"), (["--side", "Q"], "side")):
        res = CliRunner().invoke(
            _app(), [*args, "--force", *bad]
        )  # the CSV exists now: the bad flag, not the file, is refused
        assert isinstance(res.exception, InputError) and needle in flag_message(res.exception)  # what the CLI prints
        assert "\n" not in str(res.exception)


def test_report_command_rejects_a_folder_that_is_not_a_run(tmp_path):
    res = CliRunner().invoke(_app(), ["report", str(tmp_path)])
    assert isinstance(res.exception, InputError) and "config.toml" in str(res.exception)
    res = CliRunner().invoke(_app(), ["report", str(tmp_path / "missing")])
    assert isinstance(res.exception, InputError)
