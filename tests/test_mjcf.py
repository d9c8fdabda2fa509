"""MuJoCo export (:mod:`arcube.export.mjcf`), cross-checked by MuJoCo's own kinematics and dynamics.

* kinematic: with every hinge set from our IK, MuJoCo's forward kinematics puts the ``tip`` site at E,
  the ``holder`` site at H = E + (L + r) e, every joint site at the model's joint point (MODEL.md 14.1),
  and every loop closure (equality constraint) at zero violation, at every reachable point of the
  reference plan; two designs, one of them rotated and with a tool offset L > 0;
* dynamic: gravity off, only the five position actuators driven to our IK's angles point after point,
  MuJoCo's own loop closure brings the drill tip to E and the axis to e;
* masses (MODEL.md 18.1): every body's mass is the closed form of 18.1 restated here, their sum the
  moving mass; the motor's and a spherical link's inertia are recomputed from the sites; MuJoCo's
  torques that hold the weight, projected through the closed loops (G^T qfrc_bias), equal our dV/dq
  (MODEL.md 18.2), and applied as the actuators' torques they hold the tip within 0.05 mm with gravity on;
* the CLI's bad input ends as one ``error:`` line, exit 2, no file; the mass flags reach the model; the
  example script tracks a joints CSV.
"""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from arcube.errors import InputError  # noqa: E402
from arcube.options import Masses, Options  # noqa: E402
from arcube.evaluation.mass_bodies import MassModel  # noqa: E402
from arcube.evaluation.masses import gravity_torque_Nm, moving_mass_kg  # noqa: E402
from arcube.io.load import load_plan  # noqa: E402
from arcube.evaluation.task import build_task  # noqa: E402
from arcube.export.mjcf import ACTUATED, JOINT_NAMES, export_mjcf, joint_values  # noqa: E402
from arcube.model.body import mechanism_points  # noqa: E402
from arcube.model.design import Design  # noqa: E402

from designs import reaching_design  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "mujoco_drive.py"
N = 30
PAPER_RIGHT = {"m_x": 88.2, "m_y": 79.4, "m_z": 56.9}
"""Table 2's links placed so that every right-side point of the reference patient is reachable (+,+,+,+)."""
C_Z_PAPER = 162.0  # inside [153.95, 170.23] mm, the c_z that closes the z dyad at every solvable point


def _plan():
    ts = load_plan("reference")
    return ts, build_task(ts.entry, ts.target, N, ids=ts.ids)


def _design_a() -> Design:
    return Design.paper().replace(**PAPER_RIGHT)


def _design_b() -> Design:
    """Rotated (20, -35, 170) deg with L = 60 mm: of 400 random designs whose TLS box is centred on the task's
    mean C, the one reaching most points (as tests/test_mounting.py does); d_z = c_z then set so that the
    z dyad closes everywhere (2 d_z > max |Q_z - D_z|). A setup, not an oracle."""
    _, task = _plan()
    x = reaching_design((20.0, -35.0, 170.0), 60.0, seed=0, n=400, mode=0, task=task)  # mode 0: +,+,+,+
    with np.errstate(invalid="ignore"):
        mp = mechanism_points(x, task.E, task.e)
    x[11] = float(np.nanmax(np.linalg.norm(mp.Q[:, 2] - mp.D[:, 2], axis=-1))) / 2.0 + 5.0
    return Design.from_vector(x)


@pytest.fixture(scope="module")
def designs() -> dict[str, tuple[Design, float | None]]:
    return {"paper_right": (_design_a(), C_Z_PAPER), "rotated_offset": (_design_b(), None)}


def _set_joints(model, data, q: dict[str, np.ndarray], i: int) -> None:
    for name in JOINT_NAMES:
        data.qpos[model.joint(name).qposadr[0]] = q[name][i]


def _closure_gap(model, data) -> float:
    """Largest distance between the two points of any connect constraint (mm): body1's anchor and the
    compiler's matching point of body2 (eq_data[0:3], eq_data[3:6], each in its body's frame)."""
    worst = 0.0
    for k in range(model.neq):
        assert model.eq_type[k] == mujoco.mjtEq.mjEQ_CONNECT and model.eq_objtype[k] == mujoco.mjtObj.mjOBJ_BODY
        b1, b2 = model.eq_obj1id[k], model.eq_obj2id[k]
        p1 = data.xpos[b1] + data.xmat[b1].reshape(3, 3) @ model.eq_data[k, 0:3]
        p2 = data.xpos[b2] + data.xmat[b2].reshape(3, 3) @ model.eq_data[k, 3:6]
        worst = max(worst, float(np.linalg.norm(p1 - p2)))
    return worst


@pytest.mark.parametrize("which", ["paper_right", "rotated_offset"])
def test_mujoco_kinematics_reproduce_the_model_at_every_reachable_point(designs, which) -> None:
    design, c_z = designs[which]
    ts, task = _plan()
    model = mujoco.MjModel.from_xml_string(export_mjcf(design.with_extras(c_z=c_z), ts))
    data = mujoco.MjData(model)
    x = design.to_vector()
    L, r = design["L"], design["r"]
    assert (L > 0.0) == (which == "rotated_offset")
    q = joint_values(design, task.E, task.e, c_z=c_z)
    with np.errstate(invalid="ignore"):
        mp = mechanism_points(x, task.E, task.e, c_z=c_z)
    ok = np.all([np.isfinite(q[n]) for n in JOINT_NAMES], axis=0)
    assert ok.sum() == 150  # every right-side point
    sites = {f"P_{u}": mp.P[:, i] for i, u in enumerate("xyz")} | {f"D_{u}": mp.D[:, i] for i, u in enumerate("xyz")}
    sites |= {f"Q_{u}": mp.Q[:, i] for i, u in enumerate("xyz")} | {f"K_{u}": mp.K[:, i] for i, u in enumerate("xy")}
    sites |= {f"B_{u}": mp.B[:, i] for i, u in enumerate("xy")} | {"J_z": mp.J_z, "C": mp.C, "C_drill": mp.C, "O": mp.O}
    sites |= {f"coupler_{u}_T": mp.T[:, i] for i, u in enumerate("xy")} | {
        f"output_{u}_T": mp.T[:, i] for i, u in enumerate("xy")
    }
    sites |= {"beta_y_H": mp.H}
    eq_rows = []
    worst = {"tip": 0.0, "axis": 0.0, "holder": 0.0, "sites": 0.0, "closure": 0.0, "efc": 0.0}
    for i in np.flatnonzero(ok):
        _set_joints(model, data, q, i)
        mujoco.mj_forward(model, data)
        tip, holder = data.site("tip").xpos, data.site("holder").xpos
        worst["tip"] = max(worst["tip"], float(np.linalg.norm(tip - task.E[i])))
        axis = (holder - tip) / np.linalg.norm(holder - tip)
        worst["axis"] = max(worst["axis"], float(np.linalg.norm(axis - task.e[i])))
        worst["holder"] = max(worst["holder"], float(np.linalg.norm(holder - (task.E[i] + (L + r) * task.e[i]))))
        worst["sites"] = max(
            worst["sites"], max(float(np.linalg.norm(data.site(s).xpos - p[i])) for s, p in sites.items())
        )
        worst["closure"] = max(worst["closure"], _closure_gap(model, data))
        eq = data.efc_type[: data.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY
        eq_rows.append(int(eq.sum()))
        worst["efc"] = max(worst["efc"], float(np.abs(data.efc_pos[: data.nefc][eq]).max()))
        np.testing.assert_allclose(data.sensor("tip_pos").data, task.E[i], atol=1e-6)
        np.testing.assert_allclose(data.sensor("drill_axis").data, task.e[i], atol=1e-9)
    print(which, {k: f"{v:.2e}" for k, v in worst.items()})
    assert set(eq_rows) == {15}  # 5 connects: T_x twice, T_y twice, H
    assert worst["tip"] < 1e-6 and worst["holder"] < 1e-6 and worst["sites"] < 1e-6
    assert worst["axis"] < 1e-9
    assert worst["closure"] < 1e-6 and worst["efc"] < 1e-6


def test_model_structure_five_dof_named_actuators_and_assembled_key(designs) -> None:
    design, c_z = designs["rotated_offset"]
    ts, task = _plan()
    xml = export_mjcf(design.with_extras(c_z=c_z), ts, at="5:7")
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    assert [model.joint(j).name for j in range(model.njnt)] == list(JOINT_NAMES)
    assert [model.actuator(a).name for a in range(model.nu)] == list(ACTUATED)
    assert all(model.actuator(a).trnid[0] == model.joint(n).id for a, n in enumerate(ACTUATED))
    # qpos0 (each hinge's ref) is the assembled pose at 5:7, the keyframe too, with the actuator targets
    i = int(np.flatnonzero((task.trajectory == ts.ids.index("5")) & (task.k == 7))[0])
    q = joint_values(design, task.E[i], task.e[i], c_z=c_z)
    np.testing.assert_allclose(model.qpos0, [q[n] for n in JOINT_NAMES], atol=1e-12)
    key = model.key("assembled")
    np.testing.assert_allclose(key.qpos, model.qpos0, atol=0)
    np.testing.assert_allclose(key.ctrl, [q[n] for n in ACTUATED], atol=0)
    mujoco.mj_resetDataKeyframe(model, data, key.id)
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.site("tip").xpos, task.E[i], atol=1e-9)
    # 17 hinges, 15 constraint rows of rank 12: 5 degrees of freedom
    J = data.efc_J[: data.nefc * model.nv].reshape(data.nefc, model.nv)
    assert model.nv == 17 and np.linalg.matrix_rank(J, tol=1e-9 * np.abs(J).max()) == 12
    assert all(model.body_mass[b] > 0 for b in range(1, model.nbody))


@pytest.mark.parametrize(("which", "tid"), [("paper_right", "1"), ("rotated_offset", "9")])
def test_mujoco_dynamics_track_the_trajectory_with_five_actuators(designs, which, tid) -> None:
    design, c_z = designs[which]
    ts, task = _plan()
    model = mujoco.MjModel.from_xml_string(export_mjcf(design.with_extras(c_z=c_z), ts, at=f"{tid}:0"))
    model.opt.gravity[:] = 0.0
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("assembled").id)
    sel = np.flatnonzero(task.trajectory == ts.ids.index(tid))
    q = joint_values(design, task.E[sel], task.e[sel], c_z=c_z)
    act = [model.actuator(n).id for n in ACTUATED]
    tip_err, axis_err = [], []
    for j in range(len(sel)):
        data.ctrl[act] = [q[n][j] for n in ACTUATED]
        for _ in range(300):
            mujoco.mj_step(model, data)
        tip, holder = data.site("tip").xpos, data.site("holder").xpos
        axis = (holder - tip) / np.linalg.norm(holder - tip)
        tip_err.append(float(np.linalg.norm(tip - task.E[sel[j]])))
        axis_err.append(float(np.degrees(np.arccos(np.clip(axis @ task.e[sel[j]], -1.0, 1.0)))))
    print(which, f"tip {max(tip_err):.2e} mm, axis {max(axis_err):.2e} deg")
    assert max(tip_err) < 0.05
    assert max(axis_err) < 0.05
    # the passive joints followed too (same assembly mode all along)
    for n in JOINT_NAMES:
        assert abs(data.qpos[model.joint(n).qposadr[0]] - q[n][-1]) < 1e-3, n


def test_z_dyad_that_cannot_close_names_the_c_z_range_or_says_none_can() -> None:
    d = _design_a()
    with pytest.raises(InputError, match=r"^c_z in \[153\.9\d, 170\.2\d\] mm closes the z-leg dyad at every point"):
        export_mjcf(d)  # c_z = d_z = 53.6 mm is far too short
    with pytest.raises(InputError, match="no c_z closes it at every point"):
        export_mjcf(d.replace(d_z=30.0).with_extras(c_z=100.0))
    export_mjcf(d.with_extras(c_z=154.0))
    export_mjcf(d.with_extras(c_z=170.0))


def test_anatomy_meshes_become_static_mesh_geoms() -> None:
    from arcube.patients.anatomy import reference_anatomy

    meshes = reference_anatomy()
    model = mujoco.MjModel.from_xml_string(export_mjcf(_design_a().with_extras(c_z=C_Z_PAPER), anatomy=meshes))
    assert model.nmesh == len(meshes)
    geoms = [g for g in range(model.ngeom) if model.geom(g).name.startswith("anatomy_")]
    assert len(geoms) == len(meshes) and all(model.geom_bodyid[g] == 0 for g in geoms)
    assert np.all(model.geom_contype == 0) and np.all(model.geom_conaffinity == 0)


# ------------------------------------------------------------------------------------------ masses (MODEL.md 18.1, 18.2)


def _closed_form_masses(design: Design, c_z: float, m: MassModel) -> dict[str, float]:
    """Each MuJoCo body's mass from MODEL.md 18.1 by hand: tubes lambda x length, lambda = rho pi (r_o^2 - r_i^2);
    a spherical link is 12 chords of 2 r sin(phi / 24); the delta actuators ride at D_u (on knee_u)."""
    lam = (
        m.density_kg_m3
        * math.pi
        * ((m.link_radius_mm * 1e-3) ** 2 - ((m.link_radius_mm - m.wall_mm) * 1e-3) ** 2)
        * 1e-3
    )  # kg/mm
    out = {f"crank_{u}": lam * design[f"p_{u}"] for u in "xyz"}
    for u in "xy":
        out |= {
            f"input_{u}": lam * design[f"d_{u}"],
            f"coupler_{u}": lam * design[f"c_{u}"],
            f"output_{u}": lam * design[f"t_{u}"],
            f"knee_{u}": m.m_delta_kg,
        }
        for kind in ("alpha", "beta"):
            out[f"{kind}_{u}"] = lam * 12 * 2 * design["r"] * math.sin(math.radians(design[f"{kind}_{u}"]) / 24)
    out |= {
        "zdyad_d": lam * design["d_z"],
        "zdyad_c": lam * c_z,
        "platform": lam * 3 * math.sqrt(2) * design["r"],
        "drill": m.m_motor_kg,
    }
    return out


@pytest.mark.parametrize("which", ["paper_right", "rotated_offset"])
def test_body_masses_and_moving_mass_are_the_mass_model(designs, which) -> None:
    design, c_z = designs[which]
    cz = design["d_z"] if c_z is None else c_z
    masses = MassModel(wall_mm=1.5, density_kg_m3=7800.0, m_delta_kg=0.6, m_motor_kg=2.0, gravity=(1.0, -2.0, -9.0))
    options = Options(
        masses=Masses(
            wall_mm=masses.wall_mm,
            density_kg_m3=masses.density_kg_m3,
            m_delta_kg=masses.m_delta_kg,
            m_motor_kg=masses.m_motor_kg,
            gravity=masses.gravity,
        )
    )
    model = mujoco.MjModel.from_xml_string(export_mjcf(design.with_extras(c_z=c_z), options=options))
    got = {
        model.body(b).name: float(model.body_mass[b]) for b in range(2, model.nbody)
    }  # after world and the static base
    want = _closed_form_masses(design, cz, masses)
    assert set(got) - set(want) == {"knee_z"} and got["knee_z"] <= 1e-6  # MuJoCo's floor for a massless moving body
    for name, value in want.items():
        assert got[name] == pytest.approx(value, rel=1e-12), name
    total = sum(got.values())
    assert total == pytest.approx(sum(want.values()), abs=2e-6)
    assert total == pytest.approx(float(moving_mass_kg(design.to_vector(), replace(masses, c_z_mm=cz))), abs=2e-6)
    np.testing.assert_allclose(model.opt.gravity, [1000.0, -2000.0, -9000.0], rtol=0, atol=1e-12)  # m/s^2 -> mm/s^2


def test_inertias_of_the_motor_and_of_a_spherical_link(designs) -> None:
    """The drill motor: a cylinder H -> H + L_m e, inertia m (L_m^2/12 + rho_m^2/4) across e and none along it
    (its spin is the spindle's, 18.2); beta_x: 12 equal rods on the great circle from u_beta to e about C."""
    design, c_z = designs["rotated_offset"]
    m = MassModel()
    model = mujoco.MjModel.from_xml_string(export_mjcf(design.with_extras(c_z=c_z)))
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)

    def world_inertia(name: str) -> np.ndarray:
        b = model.body(name).id
        R = data.ximat[b].reshape(3, 3)
        return R @ np.diag(model.body_inertia[b]) @ R.T

    H, E = data.site("holder").xpos, data.site("tip").xpos
    e = (H - E) / np.linalg.norm(H - E)
    np.testing.assert_allclose(data.xipos[model.body("drill").id], H + 60.0 * e, atol=1e-9)
    across = m.m_motor_kg * (120.0**2 / 12 + 20.0**2 / 4)
    np.testing.assert_allclose(world_inertia("drill"), across * (np.eye(3) - np.outer(e, e)), atol=1e-6)

    C, B = data.site("C").xpos, data.site("B_x").xpos
    r, phi = design["r"], math.radians(design["beta_x"])
    ub = (B - C) / r
    s = np.linspace(0.0, 1.0, 13)[:, None]
    pts = C + r * (np.sin((1 - s) * phi) * ub + np.sin(s * phi) * e) / math.sin(phi)
    mass = model.body_mass[model.body("beta_x").id] / 12
    mid = 0.5 * (pts[1:] + pts[:-1])
    com = mid.mean(axis=0)
    inertia = sum(
        mass * (d @ d / 12 * np.eye(3) - np.outer(d, d) / 12) + mass * (q @ q * np.eye(3) - np.outer(q, q))
        for d, q in zip(pts[1:] - pts[:-1], mid - com)
    )
    np.testing.assert_allclose(data.xipos[model.body("beta_x").id], com, atol=1e-9)
    np.testing.assert_allclose(world_inertia("beta_x"), inertia, atol=1e-6 * np.abs(inertia).max())


def _loop_basis(model, data) -> np.ndarray:
    """G (17, 5): hinge rates per actuator rate at data's pose, the null space of the closures' Jacobian
    with its actuated rows scaled to the identity."""
    J = data.efc_J[: data.nefc * model.nv].reshape(data.nefc, model.nv)
    _, sv, vt = np.linalg.svd(J)
    N = vt[int(np.sum(sv > 1e-9 * sv[0])) :].T
    assert N.shape == (17, 5)
    return N @ np.linalg.inv(N[[model.joint(n).dofadr[0] for n in ACTUATED]])


@pytest.mark.parametrize(
    ("which", "gravity"), [("paper_right", (0.0, 0.0, -9.81)), ("rotated_offset", (2.0, -3.0, -9.0))]
)
def test_mujoco_gravity_torques_through_the_loops_equal_ours(designs, which, gravity) -> None:
    """At rest, the torques that hold the weight are G^T qfrc_bias (MuJoCo cuts the loops: an actuator's own
    entry is not its torque). They equal :func:`gravity_torque_Nm` (MODEL.md 18.2, dV/dq through our FK
    Jacobians) to 1e-5 N m: the one modelling difference is knee_z's floor mass of 1e-6 kg (MuJoCo refuses a
    massless moving body), whose weight moves a torque by at most 1e-6 kg x 9.81 m/s^2 x 1 m = 1e-5 N m."""
    design, c_z = designs[which]
    cz = design["d_z"] if c_z is None else c_z
    ts, task = _plan()
    model = mujoco.MjModel.from_xml_string(
        export_mjcf(design.with_extras(c_z=c_z), ts, options=Options(masses=Masses(gravity=gravity)))
    )
    model.opt.jacobian = mujoco.mjtJacobian.mjJAC_DENSE
    data = mujoco.MjData(model)
    sel = np.arange(0, len(task.E), 7)
    q = joint_values(design, task.E[sel], task.e[sel], c_z=c_z)
    ours = gravity_torque_Nm(
        design.to_vector(), task.E[sel], task.e[sel], np.ones(4), MassModel(gravity=gravity, c_z_mm=cz)
    )
    dofs = [model.joint(n).dofadr[0] for n in ACTUATED]
    worst, naive = 0.0, 0.0
    for j in np.flatnonzero(np.isfinite(ours).all(axis=1)):
        _set_joints(model, data, q, j)
        mujoco.mj_forward(model, data)
        theirs = _loop_basis(model, data).T @ data.qfrc_bias / 1e6  # kg mm^2/s^2 -> N m
        worst = max(worst, float(np.abs(theirs - ours[j]).max()))
        naive = max(naive, float(np.abs(data.qfrc_bias[dofs] / 1e6 - ours[j]).max()))
    print(
        which,
        f"|G^T qfrc_bias - dV/dq| {worst:.2e} N m, naive entries off by {naive:.2f} N m, |dV/dq| max {np.nanmax(np.abs(ours)):.2f}",
    )
    assert np.nanmax(np.abs(ours)) > 1.0
    assert worst < 1e-5
    assert naive > 0.1  # the actuated entries alone are not the holding torques


@pytest.mark.parametrize(("which", "tid"), [("paper_right", "1"), ("rotated_offset", "9")])
def test_our_gravity_torques_hold_the_pose_in_mujoco(designs, which, tid) -> None:
    """Gravity on: with our dV/dq as the actuators' torque at the pose (ctrl = q + tau / kp) the tip stays within
    0.05 mm of E; with the servos alone it sags by more than half a millimetre (so the torques carry the weight)."""
    design, c_z = designs[which]
    cz = design["d_z"] if c_z is None else c_z
    ts, task = _plan()
    model = mujoco.MjModel.from_xml_string(export_mjcf(design.with_extras(c_z=c_z), ts, at=f"{tid}:5"))
    data = mujoco.MjData(model)
    i = int(np.flatnonzero((task.trajectory == ts.ids.index(tid)) & (task.k == 5))[0])
    tau = gravity_torque_Nm(design.to_vector(), task.E[i], task.e[i], np.ones(4), MassModel(c_z_mm=cz))
    kp = model.actuator_gainprm[[model.actuator(n).id for n in ACTUATED], 0]
    err = {}
    for held in (True, False):
        mujoco.mj_resetDataKeyframe(model, data, model.key("assembled").id)
        data.ctrl[:] = model.key("assembled").ctrl + (tau * 1e6 / kp if held else 0.0)
        for _ in range(1000):
            mujoco.mj_step(model, data)
        err[held] = float(np.linalg.norm(data.site("tip").xpos - task.E[i]))
        assert np.abs(data.qvel).max() < 1e-3  # settled
    print(which, f"tip error with our gravity torques {err[True]:.2e} mm, servos alone {err[False]:.2f} mm")
    assert err[True] < 0.05
    assert err[False] > 0.5


# ------------------------------------------------------------------------------------------ CLI


def _run(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    return subprocess.run(
        [sys.executable, "-m", "arcube", *args], cwd=cwd, capture_output=True, text=True, timeout=120, env=env
    )


@pytest.fixture(scope="module")
def design_file(tmp_path_factory) -> Path:
    p = tmp_path_factory.mktemp("design") / "paper_right.json"
    p.write_text(json.dumps(_design_a().to_dict()))
    return p


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--format", "urdf", "--c-z", "162"], "unknown format"),
        (["--at", "77:0", "--c-z", "162"], "no trajectory with id '77'"),
        (["--at", "1:30", "--c-z", "162"], r"k must lie in 0\.\.29"),
        (["--at", "2:0", "--c-z", "162"], "no IK solution at trajectory 2, k=0"),
        (["--c-z", "60"], r"--c-z in \[153"),
        (["--c-z", "162", "--out", "{blocker}/model.xml"], "cannot write"),
        (["--c-z", "162", "--wall", "8"], r"--wall must be < the link radius \(8 mm\)"),
    ],
    ids=["format", "missing-id", "k-range", "unreachable", "z-dyad", "unwritable", "wall"],
)
def test_cli_bad_input_one_line_exit_2_no_file(tmp_path, design_file, extra, message, monkeypatch, capsys) -> None:
    """In this process (arcube.cli.main, as ``python -m arcube`` runs it; one case in a process of its own below)."""
    from harness import run_cli

    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli(_bad_export_argv(tmp_path, design_file, extra), capsys)
    _assert_refused(tmp_path, code, err, message)


def test_cli_bad_input_in_a_process_of_its_own_is_one_line_exit_2(tmp_path, design_file) -> None:
    """The same contract through ``python -m arcube`` (start-up, interrupt handling, the real stderr)."""
    res = _run(*_bad_export_argv(tmp_path, design_file, ["--at", "2:0", "--c-z", "162"]), cwd=tmp_path)
    _assert_refused(tmp_path, res.returncode, res.stderr, "no IK solution at trajectory 2, k=0")


def _bad_export_argv(tmp_path: Path, design_file: Path, extra: list[str]) -> list[str]:
    blocker = tmp_path / "blocker.txt"
    blocker.write_text("a file where a folder is needed\n")
    extra = [a.replace("{blocker}", str(blocker)) for a in extra]
    return ["export", "--design", str(design_file), "--out", str(tmp_path / "model.xml"), *extra]


def _assert_refused(tmp_path: Path, code: int, err: str, message: str) -> None:
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:"), err
    assert re.search(message, lines[0]), lines[0]
    assert "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["blocker.txt"]  # no file, no temporary left


def test_cli_mass_flags_set_the_masses_and_gravity(tmp_path, design_file) -> None:
    xml = tmp_path / "robot.xml"
    res = _run(
        "export",
        "--design",
        str(design_file),
        "--out",
        str(xml),
        "--c-z",
        "162",
        "--m-motor",
        "3",
        "--m-delta",
        "0.5",
        "--gravity",
        "0,-9.81,0",
        cwd=tmp_path,
    )
    assert res.returncode == 0, res.stderr
    model = mujoco.MjModel.from_xml_path(str(xml))
    assert model.body_mass[model.body("drill").id] == 3.0 and model.body_mass[model.body("knee_x").id] == 0.5
    np.testing.assert_allclose(model.opt.gravity, [0.0, -9810.0, 0.0], rtol=0, atol=1e-9)


def test_cli_thin_links_export_without_masses_unless_asked(tmp_path, design_file) -> None:
    """Links no thicker than the default 2 mm wall and no mass flag: the model is written without 18.1's masses and
    a note says so (as arcube evaluate drops the holding torque); with --wall the wall is refused."""
    xml = tmp_path / "robot.xml"
    res = _run(
        "export", "--design", str(design_file), "--out", str(xml), "--c-z", "162", "--link-radius", "1.5", cwd=tmp_path
    )
    assert res.returncode == 0 and res.stderr.startswith("note: --link-radius 1.5 mm"), res.stderr
    model = mujoco.MjModel.from_xml_path(str(xml))
    assert model.body_mass[model.body("drill").id] < 1e-3  # no 1.5 kg drill motor
    res = _run(
        "export",
        "--design",
        str(design_file),
        "--out",
        str(tmp_path / "r2.xml"),
        "--c-z",
        "162",
        "--link-radius",
        "1.5",
        "--wall",
        "2",
        cwd=tmp_path,
    )
    assert (
        res.returncode == 2
        and "--wall must be < the link radius (1.5 mm)" in res.stderr
        and not (tmp_path / "r2.xml").exists()
    )


def test_example_script_drives_the_exported_model_along_a_joints_csv(tmp_path, design_file) -> None:
    xml, csv = tmp_path / "robot.xml", tmp_path / "joints.csv"
    res = _run(
        "export",
        "--design",
        str(design_file),
        "--out",
        str(xml),
        "--c-z",
        "162",
        "--points",
        "10",
        "--at",
        "3:9",
        cwd=tmp_path,
    )
    assert res.returncode == 0, res.stderr
    res = _run(
        "joints", "--design", str(design_file), "--out", str(csv), "--points", "10", "--ids", "1,3", cwd=tmp_path
    )
    assert res.returncode == 0, res.stderr
    run = subprocess.run(
        [sys.executable, str(EXAMPLE), str(xml), str(csv), "--trajectory", "1"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr
    m = re.search(r"max tip error: ([0-9.]+) mm over (\d+) points", run.stdout)
    assert m, run.stdout
    print(run.stdout.strip().splitlines()[-1])
    assert int(m.group(2)) == 10
    assert float(m.group(1)) < 0.05
