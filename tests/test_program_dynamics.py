"""Actuator torques along a program and the motor figures (MODEL.md 18.2-18.3, issue 21), by oracles
that do not share the torques' code:

* **power balance**: tau . q_dot = dT/dt + dV/dt - f . E_dot, integrated from the start to every row
  (within 1 % of the motors' total absolute work), with T computed here from the
  bodies' Jacobians and the CSV's rates (the rod formula m (|v_a|^2 + v_a.v_b + |v_b|^2)/6, the motor's
  radial inertia), V from :func:`arcube.evaluation.masses.potential_energy_J`, E_dot from the rows'
  E; the torques come from second differences of the bodies' positions, a different route. Over the
  whole program (at rest at both ends): the integral of tau . q_dot = V_end - V_start + F_t x the
  drilled depth of the plan;
* with no masses the torques are the thrust's alone: |tau_i| = F_t |e^T J_E,i| on drill rows (MODEL.md
  15.3's torque per actuator with F_l = 0), 0 elsewhere;
* at a pose held still, the torques are the gravity torques dV/dq of the holding-torque reference;
* the motor figures are recomputed from ``program.csv``'s text (peak, RMS, speed, power, energy).
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from arcube.evaluation.mass_bodies import MassModel, bodies_of_solution
from arcube.evaluation.masses import gravity_torque_Nm, potential_energy_J
from arcube.evaluation.performance import jacobians_of_solution, tip_metrics
from arcube.model.mechanism import forward_kinematics, inverse_kinematics
from arcube.options import Loads, Masses, Options
from arcube import program
from arcube.motion.dynamics import program_torques

from designs import PROGRAM_COLUMNS, PROGRAM_TORQUES, program_design, right_plan

MODE = np.ones(4)


FAST = {
    "approach_speed": 100.0,
    "retract_speed": 100.0,
    "max_joint_speed_deg": 180.0,
    "max_joint_accel_deg": 3000.0,
    "max_tip_speed": 1000.0,
}
"""Limits that make inertia matter: at the defaults the program is slow enough that gravity and thrust
carry nearly all the power (a wrong inertia would hide in the balance's 1 %)."""


def _run(out: Path, masses: Masses, **limits: float):
    ts = right_plan("1,3")
    prog = program(
        program_design(),
        ts,
        out,
        feed=2.0,
        options=Options(masses=masses, loads=Loads(lateral_force_N=0.0)),
        masses=True,
        **limits,
    )
    with open(out / "program.csv", newline="") as fh:
        reader = csv.reader(fh)
        header = next(reader)
        data = list(zip(*reader))
    cols = {
        name: np.array(data[i], dtype=float) for i, name in enumerate(header) if name not in ("segment", "trajectory")
    }
    cols["segment"] = np.array(data[header.index("segment")])
    return prog, header, cols, json.loads((out / "program.json").read_text()), ts


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory):
    """The default limits and masses: gravity and thrust dominate."""
    return _run(tmp_path_factory.mktemp("dyn") / "prog", Masses())


@pytest.fixture(scope="module")
def fast(tmp_path_factory: pytest.TempPathFactory):
    """Gravity off and fast limits: inertia and thrust alone."""
    return _run(tmp_path_factory.mktemp("dyn") / "fast", Masses(gravity=(0.0, 0.0, 0.0)), **FAST)


def _cumulative(y: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The trapezoidal integral of y from t[0] to every t."""
    return np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * np.diff(t))])


def _kinetic_energy_J(params, E, e, q_dot, model: MassModel) -> np.ndarray:
    sol = inverse_kinematics(params, E, e, MODE)
    J_E, J_e = jacobians_of_solution(sol, params)
    b = bodies_of_solution(sol, params, model, (J_E, J_e))
    va = np.einsum("rkij,rj->rki", b.J_ends[:, :, 0], q_dot)
    vb = np.einsum("rkij,rj->rki", b.J_ends[:, :, 1], q_dot)
    rods = np.einsum("rk,rk->r", b.mass, (va * va).sum(-1) + (va * vb).sum(-1) + (vb * vb).sum(-1)) / 6.0
    spin = 0.5 * b.radial_inertia * np.sum(np.einsum("rij,rj->ri", J_e, q_dot) ** 2, axis=-1)
    return (rods + spin) * 1e-6  # kg mm^2/s^2 -> J


def test_the_csv_carries_the_torques(run) -> None:
    prog, header, cols, _, _ = run
    assert header == PROGRAM_COLUMNS + PROGRAM_TORQUES
    tau = np.stack([cols[c] for c in PROGRAM_TORQUES], axis=1)
    assert np.array_equal(tau, prog.tau_Nm)  # written with repr: read back exactly
    assert np.all(np.isfinite(tau))


@pytest.mark.parametrize("which", ["run", "fast"])
def test_power_balance_along_the_program(which: str, request: pytest.FixtureRequest) -> None:
    prog, _, cols, summary, ts = request.getfixturevalue(which)
    model = MassModel(gravity=tuple(summary["masses"]["gravity"]))
    p = program_design().to_vector()
    t = cols["t_s"]
    E = np.stack([cols[f"E_{a}"] for a in "xyz"], axis=1)
    e = np.stack([cols[f"e_{a}"] for a in "xyz"], axis=1)
    q_dot = np.radians(np.stack([cols[c] for c in PROGRAM_COLUMNS[14:19]], axis=1))
    tau = np.stack([cols[c] for c in PROGRAM_TORQUES], axis=1)
    power = np.sum(tau * q_dot, axis=1)
    T = _kinetic_energy_J(p, E, e, q_dot, model)
    V = potential_energy_J(p, E, e, MODE, model)
    drill = cols["segment"] == "drill"
    f = np.where(drill[:, None], Loads().thrust_N * e, 0.0)
    thrust_power = np.sum(f * np.gradient(E, t, axis=0), axis=1) / 1000.0  # f . E_dot, W
    # the balance integrated from the start to every row: the work the motors did so far against the energy
    # the robot gained and the work done on the bone. In integral form the rows where the acceleration
    # jumps (toppra's bang-bang pieces, which a row's finite differences straddle) do not dominate.
    work_so_far = _cumulative(power, t)
    gained = T - T[0] + V - V[0] - _cumulative(thrust_power, t)
    assert np.max(np.abs(work_so_far - gained)) <= 0.01 * _cumulative(np.abs(power), t)[-1]
    # over the whole program (rest to rest) no row is left out
    work = np.sum(0.5 * (power[1:] + power[:-1]) * np.diff(t))
    depth = np.sum(np.linalg.norm(np.asarray(ts.entry) - np.asarray(ts.target), axis=1))
    expected = V[-1] - V[0] + Loads().thrust_N * depth / 1000.0
    # exact in continuous time; the rows' differences cost ~1e-5 of the work at the default limits, ~1e-3 at FAST's
    assert abs(work - expected) <= (1e-3 if which == "run" else 1e-2) * _cumulative(np.abs(power), t)[-1]
    assert work > 0.5
    if which == "fast":  # inertia carries much of the power: the balance tests it
        assert np.max(T) > 0.05 and np.max(np.abs(np.gradient(T, t))) > 0.2 * np.max(np.abs(power))
    else:
        assert abs(V[-1] - V[0]) > 0.01


def test_without_masses_only_the_thrust_loads_the_motors(run) -> None:
    prog = run[0]
    p = program_design().to_vector()
    none = MassModel(density_kg_m3=0.0, m_delta_kg=0.0, m_motor_kg=0.0)
    drill = prog.segment == "drill"
    tq = program_torques(p, prog.E, prog.e, MODE, 0.01, drill, none, thrust_N=30.0, lateral_N=0.0)
    J_E, J_e = jacobians_of_solution(inverse_kinematics(p, prog.E, prog.e, MODE), p)
    per = tip_metrics(J_E, J_e, prog.e, thrust_N=30.0, lateral_N=0.0).torque_per_actuator_Nm
    assert np.allclose(np.abs(tq.tau_Nm[drill]), per[drill], rtol=1e-9, atol=1e-12)
    assert np.all(tq.tau_Nm[~drill] == 0.0)
    assert np.max(per[drill]) > 1.0


def test_a_pose_held_still_needs_the_gravity_torque() -> None:
    p = program_design().to_vector()
    ts = right_plan("5")
    A, B = np.asarray(ts.entry[0]), np.asarray(ts.target[0])
    e = (A - B) / np.linalg.norm(A - B)
    E = np.repeat(A[None], 7, axis=0)
    tq = program_torques(p, E, np.repeat(e[None], 7, axis=0), MODE, 0.01, np.zeros(7, bool), MassModel())
    expected = gravity_torque_Nm(p, A, e, MODE, MassModel())
    assert np.allclose(tq.tau_Nm, expected[None], rtol=1e-12, atol=1e-12)
    assert np.all(tq.inertia_Nm == 0.0) and np.max(np.abs(expected)) > 0.5


def test_motor_figures_from_the_csv(run) -> None:
    _, _, cols, summary, _ = run
    t = cols["t_s"]
    for i, name in enumerate(("rho_x", "rho_y", "rho_z", "delta_x", "delta_y")):
        tau, qd = cols[PROGRAM_TORQUES[i]], np.radians(cols[f"{name}_dot"])
        fig = summary["motors"][name]
        assert fig["torque_peak_Nm"] == pytest.approx(np.max(np.abs(tau)), rel=1e-12)
        rms = np.sqrt(np.sum(0.5 * (tau[1:] ** 2 + tau[:-1] ** 2) * np.diff(t)) / (t[-1] - t[0]))
        assert fig["torque_rms_Nm"] == pytest.approx(rms, rel=1e-9)
        assert fig["speed_peak_deg_s"] == pytest.approx(np.max(np.abs(cols[f"{name}_dot"])), rel=1e-12)
        assert fig["power_peak_W"] == pytest.approx(np.max(np.abs(tau * qd)), rel=1e-12)
        pw = np.maximum(tau * qd, 0.0)
        assert fig["energy_J"] == pytest.approx(np.sum(0.5 * (pw[1:] + pw[:-1]) * np.diff(t)), rel=1e-9)
    assert summary["masses"]["moving_mass_kg"] > Masses().m_motor_kg + 2 * Masses().m_delta_kg


def test_masses_off_keeps_the_plain_program(tmp_path: Path) -> None:
    prog = program(program_design(), right_plan("5"), tmp_path / "p", feed=2.0, masses=False)
    assert prog.tau_Nm is None and "motors" not in prog.summary
    assert (tmp_path / "p" / "program.csv").read_text().splitlines()[0] == ",".join(PROGRAM_COLUMNS)


def _mass_matrix(params, q: np.ndarray, assembly: np.ndarray, model: MassModel) -> np.ndarray:
    """M(q) ``(5, 5)`` from T = 1/2 q_dot^T M q_dot: each rod m (|v_a|^2 + v_a.v_b + |v_b|^2)/6, the motor's
    radial inertia; the pose by the forward kinematics (kg mm^2/rad^2)."""
    fk = forward_kinematics(params, q[:3], q[3:], assembly)
    sol = inverse_kinematics(params, fk.E, fk.e, MODE)
    J_E, J_e = jacobians_of_solution(sol, params)
    b = bodies_of_solution(sol, params, model, (J_E, J_e))
    Ja, Jb = b.J_ends[:, 0], b.J_ends[:, 1]  # (65, 3, 5)
    cross = np.einsum("k,kia,kib->ab", b.mass, Ja, Jb)
    M = (
        np.einsum("k,kia,kib->ab", b.mass, Ja, Ja)
        + np.einsum("k,kia,kib->ab", b.mass, Jb, Jb)
        + 0.5 * (cross + cross.T)
    )
    return M / 3.0 + b.radial_inertia * J_e.T @ J_e


def test_torques_follow_lagranges_equations_on_a_smooth_motion() -> None:
    """tau = d/dt (M q_dot) - dT/dq + dV/dq on q(t) = q0 + a sin(w t): M and V differentiated numerically
    through the forward kinematics (the torques' code takes point accelerations instead)."""
    p = program_design().to_vector()
    ts = right_plan("5")
    A, B = np.asarray(ts.entry[0]), np.asarray(ts.target[0])
    sol0 = inverse_kinematics(p, A, (A - B) / np.linalg.norm(A - B), MODE)
    q0 = np.concatenate([sol0.rho, sol0.delta])
    asm = sol0.assembly
    amp, w = np.radians([1.5, -1.0, 1.2, 2.0, -1.5]), np.array([2.1, 3.3, 1.7, 2.9, 3.7])  # rad, rad/s
    model = MassModel(gravity=(1.0, -2.0, -9.81))
    q_of = lambda t: q0 + amp * np.sin(w * t)  # noqa: E731
    qd_of = lambda t: amp * w * np.cos(w * t)  # noqa: E731
    for t in (0.13, 0.41, 0.77, 1.05):
        dt = 1e-3
        fk = forward_kinematics(
            p,
            np.stack([q_of(t + k * dt)[:3] for k in (-1, 0, 1)]),
            np.stack([q_of(t + k * dt)[3:] for k in (-1, 0, 1)]),
            asm,
        )
        assert np.all(fk.valid)
        tq = program_torques(p, fk.E, fk.e, MODE, dt, np.zeros(3, bool), model)
        h = 1e-5
        momentum = [_mass_matrix(p, q_of(t + s * h), asm, model) @ qd_of(t + s * h) for s in (-1, 1)]
        dT_dq, dV_dq = np.zeros(5), np.zeros(5)
        for i in range(5):
            step = np.eye(5)[i] * h
            qd = qd_of(t)
            Mp, Mm = _mass_matrix(p, q_of(t) + step, asm, model), _mass_matrix(p, q_of(t) - step, asm, model)
            dT_dq[i] = 0.5 * qd @ (Mp - Mm) @ qd / (2 * h)
            Vs = [
                potential_energy_J(
                    p,
                    *(lambda f: (f.E, f.e))(
                        forward_kinematics(p, (q_of(t) + s * step)[:3], (q_of(t) + s * step)[3:], asm)
                    ),
                    MODE,
                    model,
                )
                for s in (1, -1)
            ]
            dV_dq[i] = (Vs[0] - Vs[1]) / (2 * h)
        inertia = ((momentum[1] - momentum[0]) / (2 * h) - dT_dq) * 1e-6  # kg mm^2/s^2 -> N m
        assert np.allclose(tq.inertia_Nm[1], inertia, rtol=1e-4, atol=1e-4 * np.max(np.abs(inertia)))
        assert np.allclose(tq.gravity_Nm[1], dV_dq, rtol=1e-6, atol=1e-8)
        assert np.max(np.abs(inertia)) > 1e-3


def test_a_program_folder_reports_itself(run) -> None:
    """program.json records the design, so ``arcube report`` on the folder alone plays the program back, and the
    report's motor table shows program.json's figures."""
    from arcube.cli import main
    from arcube.report.program_html import DIV_IDS

    prog, _, _, summary, _ = run
    assert summary["design"] == pytest.approx(program_design().to_dict(), rel=0, abs=0)
    folder = prog.path
    try:
        main(["report", str(folder)])
    except SystemExit as exc:
        assert not exc.code
    html = (folder / "report.html").read_text()
    assert DIV_IDS["playback"] in html and "No playback" not in html
    assert f"{summary['motors']['rho_x']['torque_peak_Nm']:.3g}" in html


def test_the_clearances_along_time_are_the_references_at_those_rows(run) -> None:
    """program.json's clearance series (for the report's plot) is the NumPy reference's self clearance at the
    CSV rows it names, and the report draws it with its limit."""
    from arcube.evaluation.reference import evaluate_points
    from arcube.options import Options, Outputs
    from arcube.report.program_data import read_program
    from arcube.report.program_html import timeline_figure

    prog, _, cols, summary, _ = run
    series = summary["clearances_along_time"]
    rows = np.searchsorted(cols["t_s"], series["t_s"])
    assert np.allclose(cols["t_s"][rows], series["t_s"], rtol=0, atol=1e-12) and rows[-1] == len(cols["t_s"]) - 1
    E = np.stack([cols[f"E_{a}"] for a in "xyz"], axis=1)[rows]
    e = np.stack([cols[f"e_{a}"] for a in "xyz"], axis=1)[rows]
    ref = evaluate_points(
        program_design().to_vector(), E, e, MODE, Options(outputs=Outputs(clearances=True, tip_metrics=False))
    )
    assert np.allclose(series["self_clearance_mm"], ref.self_clearance_mm, rtol=0, atol=1e-9)
    assert min(series["self_clearance_mm"]) >= summary["self_clearance_min_mm"] - 0.5  # 17.2's states are finer
    fig = timeline_figure(read_program(prog.path))
    (trace,) = [tr for tr in fig.data if tr.name == "self"]
    assert list(trace.y) == pytest.approx(series["self_clearance_mm"], abs=1e-12)


@pytest.fixture(scope="module")
def lateral(tmp_path_factory: pytest.TempPathFactory):
    """One trajectory with the default loads: the lateral force's worst case enters the motor figures."""
    out = tmp_path_factory.mktemp("dyn") / "lateral"
    prog = program(program_design(), right_plan("5"), out, feed=2.0)
    return prog, json.loads((out / "program.json").read_text())


def test_motor_figures_add_the_lateral_force_on_drill_rows_only(lateral) -> None:
    """MODEL.md 18.3 with F_l = 10 N: the sizing torque is |tau_i| + F_l |P_perp J_E,i| on drill rows (J_E of the
    reference at the rows), |tau_i| elsewhere; the gravity column is the reference's dV/dq, the column without
    masses MODEL.md 15.3's per-actuator torque (its own code) over the drill rows."""
    prog, summary = lateral
    p = program_design().to_vector()
    J_E, J_e = jacobians_of_solution(inverse_kinematics(p, prog.E, prog.e, MODE), p)
    e = prog.e / np.linalg.norm(prog.e, axis=1, keepdims=True)
    across = J_E - e[:, :, None] * np.einsum("ri,rij->rj", e, J_E)[:, None, :]
    drill = prog.segment == "drill"
    lat = np.where(drill[:, None], Loads().lateral_force_N * np.linalg.norm(across, axis=1) / 1000.0, 0.0)
    size = np.abs(prog.tau_Nm) + lat
    qd = np.radians(prog.q_dot_deg)
    t = prog.t_s
    gravity = gravity_torque_Nm(p, prog.E, prog.e, MODE, MassModel())
    loads_only = tip_metrics(
        J_E[drill], J_e[drill], prog.e[drill], thrust_N=Loads().thrust_N, lateral_N=Loads().lateral_force_N
    ).torque_per_actuator_Nm
    assert np.max(lat) > 0.1 and np.all(lat[~drill] == 0.0)
    for i, name in enumerate(("rho_x", "rho_y", "rho_z", "delta_x", "delta_y")):
        fig = summary["motors"][name]
        assert fig["torque_peak_Nm"] == pytest.approx(np.max(size[:, i]), rel=1e-9)
        rms = np.sqrt(np.sum(0.5 * (size[1:, i] ** 2 + size[:-1, i] ** 2) * np.diff(t)) / (t[-1] - t[0]))
        assert fig["torque_rms_Nm"] == pytest.approx(rms, rel=1e-9)
        assert fig["power_peak_W"] == pytest.approx(np.max(size[:, i] * np.abs(qd[:, i])), rel=1e-9)
        pw = np.maximum(prog.tau_Nm[:, i] * qd[:, i] + lat[:, i] * np.abs(qd[:, i]), 0.0)
        assert fig["energy_J"] == pytest.approx(np.sum(0.5 * (pw[1:] + pw[:-1]) * np.diff(t)), rel=1e-9)
        assert fig["torque_peak_gravity_Nm"] == pytest.approx(np.max(np.abs(gravity[:, i])), rel=1e-9)
        assert fig["torque_peak_loads_only_Nm"] == pytest.approx(np.max(loads_only[:, i]), rel=1e-9)


def test_thin_links_without_mass_flags_give_a_program_without_torques(tmp_path: Path) -> None:
    """Links no thicker than the default 2 mm wall: as arcube evaluate, no mass model rather than an error about a
    wall the user never gave; asked for explicitly, the wall is refused naming it."""
    from arcube.errors import InputError
    from arcube.options import Body

    prog = program(
        program_design(), right_plan("5"), tmp_path / "thin", feed=2.0, options=Options(body=Body(link_radius=1.5))
    )
    assert prog.tau_Nm is None and "motors" not in prog.summary
    with pytest.raises(InputError, match="wall"):
        program(
            program_design(),
            right_plan("5"),
            tmp_path / "thin2",
            feed=2.0,
            options=Options(body=Body(link_radius=1.5)),
            masses=True,
        )
    assert not (tmp_path / "thin2").exists()
