"""The tests' inputs, shared by every test module (``from designs import PAPER, reachable_poses``): designs,
poses, plans, tasks, data files and a synthetic program folder. A setup, not an oracle: whether the code
handles these inputs right is what the tests check, with the oracles of :mod:`naive`.

* Table 2 of the paper (:data:`PAPER`), random designs and the poses a design reaches, well away from
  every singularity (:func:`reachable_poses`, filtered by the oracle's transmission sines);
* 27-parameter designs placed with a mounting rotation and a tool offset so that they see a task exactly
  as a paper-frame design does (:func:`place`, :func:`placed_case`), and designs that reach the reference
  patient with a given mounting (:func:`reaching_design`);
* designs near Table 2 on the right side (:func:`near_paper_designs`) for the compiled kernel;
* the drilling program's design and plan (:data:`PROGRAM_DESIGN`, :func:`right_plan`), and a synthetic
  program folder written as text (:func:`synthetic_program`).
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from arcube.evaluation.reference import evaluate_task
from arcube.evaluation.task import build_task
from arcube.io import load_trajectories, select
from arcube.model import mechanism
from arcube.model.design import Design
from arcube.model.mechanism import ALL_MODES, inverse_kinematics
from arcube.motion.output import Program
from naive import ALL_MODES_ORACLE, get, leg_triple, oracle_config, rotation, transmission_sines, vec

REPO = Path(__file__).resolve().parents[1]
REFERENCE_CSV = REPO / "src" / "arcube" / "data" / "reference_patient.csv"
"""The reference patient's plan (10 trajectories, both sides), as shipped with the package."""

# ---------------------------------------------------------------------------------------------
# Designs.

PAPER = {
    "m_x": 31.8694,
    "m_y": 11.9589,
    "m_z": 192.0769,
    "f_x": 123.1147,
    "f_y": 116.9719,
    "f_z": 56.7787,
    "p_x": 134.099,
    "p_y": 149.9886,
    "p_z": 99.8766,
    "d_x": 79.2596,
    "d_y": 99.9402,
    "d_z": 53.5671,
    "c_x": 139.8911,
    "c_y": 106.8319,
    "t_x": 70.9301,
    "t_y": 65.3946,
    "r": 70.4466,
    "o_x": -19.2229,
    "o_y": 43.2917,
    "alpha_x": 52.6402,
    "alpha_y": 66.446,
    "beta_x": 50.0038,
    "beta_y": 62.1208,
}
"""Table 2 of the paper, copied from MODEL.md section 2 (not from arcube.model.design)."""

RIGHT_SIDE_M = {"m_x": 88.23, "m_y": 79.40, "m_z": 56.89}
"""Where Table 2's links, placed at m, reach the reference patient's right side (found by the paper-check search)."""
M_RIGHT = np.array([88.2, 79.4, 56.9])
"""The same m rounded, the centre of :func:`near_paper_designs`."""


def random_design(rng) -> np.ndarray:
    """A random design (23,) with m != 0 and dimensions that reach a good share of poses."""
    vals = {}
    for ax in "xyz":
        vals[f"m_{ax}"] = rng.choice([-1.0, 1.0]) * rng.uniform(20.0, 150.0)
        vals[f"f_{ax}"] = rng.uniform(20.0, 80.0)
        vals[f"p_{ax}"] = rng.uniform(60.0, 140.0)
        vals[f"d_{ax}"] = rng.uniform(80.0, 180.0)
    for ax in "xy":
        vals[f"c_{ax}"] = rng.uniform(120.0, 220.0)
        vals[f"t_{ax}"] = rng.uniform(40.0, 100.0)
        vals[f"o_{ax}"] = rng.uniform(-180.0, 180.0)
        vals[f"alpha_{ax}"] = rng.uniform(40.0, 85.0)
        vals[f"beta_{ax}"] = rng.uniform(40.0, 85.0)
    vals["r"] = rng.uniform(50.0, 80.0)
    return vec(vals)


def near_paper_designs(n: int, seed: int, spread: float) -> np.ndarray:
    """Around Table 2 with m on the right side; spread 0.03: mostly reachable, 0.15: all stages fail."""
    rng = np.random.default_rng(seed)
    x0 = Design.preset("paper").to_vector()[:23]  # the paper's 23 parameters
    x0[0:3] = M_RIGHT
    X = x0 * (1.0 + spread * rng.standard_normal((n, 23)))
    X[:, 0:3] = M_RIGHT + (2.0 if spread < 0.1 else 25.0) * rng.standard_normal((n, 3))
    if spread >= 0.1:
        X[:, 17:19] = rng.uniform(-270.0, 270.0, (n, 2))
        X[:, 19:23] = rng.uniform(40.0, 90.0, (n, 4))
    else:  # wider spherical links on half of them: the left side becomes reachable too
        X[::2, 19:23] = rng.uniform(70.0, 80.0, (len(X[::2]), 4))
    return X


# ---------------------------------------------------------------------------------------------
# Reachable poses.


def candidate_poses(rng, x, n, arg_max=0.95):
    """n poses with the tip inside the TLS box (|Eq 1 argument| <= arg_max) and e uniform on S^2."""
    f, p, r = leg_triple(x, "f"), leg_triple(x, "p"), get(x, "r")
    m = np.stack([get(x, "m_x"), get(x, "m_y"), get(x, "m_z")])
    arg = rng.uniform(-arg_max, arg_max, size=(n, 3))
    E = m + (p * arg - f - r)
    e = rng.normal(size=(n, 3))
    e /= np.linalg.norm(e, axis=-1, keepdims=True)
    return E, e


def reachable_poses(rng, x, mode, n, min_sine=0.1, max_batches=200):
    """n poses (E, e) that the IK reaches in working mode ``mode``, away from every singularity.

    Kept only where cos(rho_u) and all transmission sines exceed ``min_sine`` (computed by the
    oracle), so that finite differences and round trips are well conditioned. The IK only filters
    the candidates here; whether it is right is what the tests check.
    """
    Es, es = [], []
    count = 0
    for _ in range(max_batches):
        E, e = candidate_poses(rng, x, 4000)
        sol = mechanism.inverse_kinematics(x, E, e, mode)
        ok = np.asarray(sol.reachable)
        with np.errstate(invalid="ignore"):
            cfg = oracle_config(x, E, e, sol.rho, sol.delta, sol.sigma)
            s = transmission_sines(cfg)
            ok &= np.all(np.abs(s) > min_sine, axis=-1) & np.all(np.cos(sol.rho) > min_sine, axis=-1)
        Es.append(E[ok])
        es.append(e[ok])
        count += int(ok.sum())
        if count >= n:
            break
    E, e = np.concatenate(Es)[:n], np.concatenate(es)[:n]
    assert E.shape[0] == n, f"could only find {E.shape[0]} of {n} reachable poses"
    return E, e


# ---------------------------------------------------------------------------------------------
# Placed designs (MODEL.md 13): a mounting rotation and a tool offset.


def place(x23, mount, L, E_p, e_p):
    """The 27-parameter design (links of x23, rotation ``mount`` deg, offset L mm) and the task in R_w
    that it sees exactly as x23 (unrotated, L = 0) sees (E_p, e_p): e_w = R e_p, C_w = m + R (E_p - m),
    E_w = C_w - L e_w."""
    R = rotation(mount)
    m = x23[:3]
    e_w = e_p @ R.T
    E_w = m + (E_p - m) @ R.T - L * e_w
    return np.concatenate([x23, mount, [L]]), E_w, e_w


MASS_CASES = [
    # (design seed or None for the paper, mount (deg), L (mm), mode index, c_z)
    (None, (0.0, 0.0, 0.0), 0.0, 0, None),
    (None, (20.0, -35.0, 170.0), 60.0, 0, None),
    (11, (-135.0, -144.74, -67.63), 140.0, 5, None),
    (22, (0.0, 0.0, 0.0), 90.0, 10, None),
    (33, (30.0, 10.0, -50.0), 0.0, 15, 200.0),
    (44, (10.0, 80.0, 5.0), 150.0, 3, 250.0),
]
"""The placed cases of the masses' tests (tests/test_masses.py, tests/test_kernel_masses.py)."""


def placed_case(seed, mount, L, mode_index, n=8, rng_seed=7):
    """A placed design (27,) and n poses E, e (n, 3) it reaches in working mode ``mode_index`` (transmission
    sines > 0.2): Table 2 (seed None) or :func:`random_design` (seed), placed by :func:`place`."""
    x23 = vec(PAPER) if seed is None else random_design(np.random.default_rng(seed))
    mode = ALL_MODES_ORACLE[mode_index]
    E_p, e_p = reachable_poses(np.random.default_rng(rng_seed), x23, mode, n, min_sine=0.2)
    x, E, e = place(x23, np.array(mount), L, E_p, e_p)
    return x, E, e, mode


def reference_task():
    """The reference patient's ten trajectories, 12 points each (MODEL.md 1.4), read from the CSV's text."""
    rows = list(csv.DictReader(REFERENCE_CSV.open()))
    entry = np.array([[float(r[f"entry_{c}"]) for c in "xyz"] for r in rows])
    target = np.array([[float(r[f"target_{c}"]) for c in "xyz"] for r in rows])
    return build_task(entry, target, 12)


def reaching_design(mount, L: float, seed: int = 0, n: int = 600, mode: int = 0, task=None) -> np.ndarray:
    """Of n random designs (links within MODEL.md 12.1 bounds, the TLS box centred on the task's mean
    C in R_m), the one that reaches the most points of ``task`` (default :func:`reference_task`) in mode
    ``ALL_MODES[mode]``."""
    task = reference_task() if task is None else task
    rng = np.random.default_rng(seed)
    X = np.zeros((n, 27))
    X[:, 3:16] = rng.uniform(30, 200, (n, 13))
    X[:, 16] = rng.uniform(50, 80, n)
    X[:, 17:19] = rng.uniform(-180, 180, (n, 2))
    X[:, 19:23] = rng.uniform(50, 90, (n, 4))
    X[:, 23:26] = mount
    X[:, 26] = L
    C = (task.E + L * task.e).mean(axis=0)
    X[:, :3] = C - (-X[:, 3:6] - X[:, 16:17]) @ rotation(mount).T
    count = evaluate_task(X, task.E, task.e, ALL_MODES[mode]).points.reachable.sum(axis=1)
    return X[int(np.argmax(count))]


# ---------------------------------------------------------------------------------------------
# The drilling program (MODEL.md 17).

PROGRAM_DESIGN = {
    "m_x": -180.76484476919862,
    "m_y": -157.46908828300167,
    "m_z": 200.6853946773747,
    "f_x": 38.47157725834808,
    "f_y": 37.58585578457374,
    "f_z": 70.96024445457583,
    "p_x": 176.01413818196406,
    "p_y": 167.62615240420683,
    "p_z": 163.81424854234908,
    "d_x": 199.83721867879663,
    "d_y": 187.76627761622083,
    "d_z": 90.91341698557332,
    "c_x": 167.91480388710127,
    "c_y": 176.66383953444745,
    "t_x": 101.49967571608708,
    "t_y": 94.1648183036713,
    "r": 69.62303755883808,
    "o_x": -84.00550363847071,
    "o_y": 174.95584389467882,
    "alpha_x": 69.35973817628876,
    "alpha_y": 75.66975313644457,
    "beta_x": 66.76323145703799,
    "beta_y": 69.57808592269254,
    "mount_rx": 132.26627118962273,
    "mount_ry": -26.77890980359885,
    "mount_rz": -93.65404350391357,
    "L": 129.15885510671012,
}
"""A design an optimizer found for the right side of the reference plan with its lines from 25 mm outside the
entry (``arcube optimize --free all,mount,L --self-clearance 3 --guarded``, seed 4): one the program's default
limits accept without anatomy, in mode +,+,+,+."""
PROGRAM_COLUMNS = [
    "t_s",
    "segment",
    "trajectory",
    "E_x",
    "E_y",
    "E_z",
    "e_x",
    "e_y",
    "e_z",
    "rho_x",
    "rho_y",
    "rho_z",
    "delta_x",
    "delta_y",
    "rho_x_dot",
    "rho_y_dot",
    "rho_z_dot",
    "delta_x_dot",
    "delta_y_dot",
]
"""program.csv's columns (MODEL.md 17.4), written out."""
PROGRAM_TORQUES = ["tau_rho_x_Nm", "tau_rho_y_Nm", "tau_rho_z_Nm", "tau_delta_x_Nm", "tau_delta_y_Nm"]
"""The torque columns that follow when masses are on (MODEL.md 18.2)."""


def program_design() -> Design:
    """:data:`PROGRAM_DESIGN` as a Design."""
    return Design.from_dict(PROGRAM_DESIGN)


def right_plan(ids: str):
    """Trajectories ``ids`` ("1,3,5") of the reference plan's right side."""
    return select(load_trajectories("reference"), side="R", ids=ids)


JOINTS = ("rho_x", "rho_y", "rho_z", "delta_x", "delta_y")
"""The five actuated joints, in program.csv's order."""
SYNTHETIC_DT = 0.05
"""s between the rows of :func:`synthetic_program`."""
SYNTHETIC_LIMITS = {
    "max_joint_speed_deg": 30.0,
    "max_joint_accel_deg": 120.0,
    "max_tip_speed": 50.0,
    "clearance": 5.0,
    "self_clearance": 2.0,
    "kappa_max": 100.0,
    "tool_radius": 1.5,
    "dt": SYNTHETIC_DT,
}
"""program.json's ``limits`` in :func:`synthetic_program`."""
SYNTHETIC_MOTORS = {
    j: {
        "torque_peak_Nm": 3.5 + k,
        "torque_rms_Nm": 1.25 + k,
        "speed_peak_deg_s": 20.0 + k,
        "power_peak_W": 0.75 + k,
        "energy_J": 9.5 + k,
        "torque_peak_gravity_Nm": 0.5 + k,
        "torque_peak_loads_only_Nm": 2.25 + k,
    }
    for k, j in enumerate(JOINTS)
}
"""program.json's ``motors`` in :func:`synthetic_program`."""


def _line(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    return a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)


def synthetic_program(folder: Path, torques: bool = True, motors: bool = True) -> Path:
    """Write a synthetic program folder (program.csv, program.json, design.json) and return it.

    Two trajectories of the reference plan's right side (approach S -> A, drill A -> B, retract B -> S, a
    transit between the standoffs), the joint angles from the IK of :data:`PROGRAM_DESIGN` at each row, the
    rates as NumPy's differences, and (``torques``) five torque columns as functions of time; program.json's
    ``motors`` is :data:`SYNTHETIC_MOTORS` when ``motors``.
    """
    ts = select(load_trajectories("reference"), side="R")
    params = Design.from_dict(PROGRAM_DESIGN).to_vector()
    blocks = []  # (segment, trajectory, E (n, 3), e (n, 3))
    standoffs = []
    for j in (0, 1):
        A, B = np.asarray(ts.entry[j], float), np.asarray(ts.target[j], float)
        e = (A - B) / np.linalg.norm(A - B)
        S = A + 20.0 * e
        standoffs.append((S, e))
        tid = str(ts.ids[j])
        for seg, a, b, n in (("approach", S, A, 9), ("drill", A, B, 21), ("retract", B, S, 7)):
            blocks.append((seg, tid, _line(a, b, n), np.repeat(e[None], n, axis=0)))
        if j == 0:
            (S0, e0), S1 = (
                standoffs[0],
                ts.entry[1] + 20.0 * (ts.entry[1] - ts.target[1]) / np.linalg.norm(ts.entry[1] - ts.target[1]),
            )
            e1 = (ts.entry[1] - ts.target[1]) / np.linalg.norm(ts.entry[1] - ts.target[1])
            axes = _line(e0, e1, 12)
            blocks.append(
                (
                    "transit",
                    f"{ts.ids[0]}->{ts.ids[1]}",
                    _line(S0, S1, 12),
                    axes / np.linalg.norm(axes, axis=1, keepdims=True),
                )
            )
    seg = [b[0] for b in blocks for _ in range(len(b[2]))]
    traj = [b[1] for b in blocks for _ in range(len(b[2]))]
    E = np.concatenate([b[2] for b in blocks])
    e = np.concatenate([b[3] for b in blocks])
    sol = inverse_kinematics(params, E, e, np.ones(4))
    q = np.degrees(np.concatenate([sol.rho, sol.delta], axis=1))
    assert np.isfinite(q).all(), "the synthetic program must be reachable"
    t = np.arange(len(E)) * SYNTHETIC_DT
    qd = np.gradient(q, t, axis=0)
    header = [
        "t_s",
        "segment",
        "trajectory",
        "E_x",
        "E_y",
        "E_z",
        "e_x",
        "e_y",
        "e_z",
        *JOINTS,
        *(f"{j}_dot" for j in JOINTS),
    ]
    cols = [E, e, q, qd]
    if torques:
        header += [f"tau_{j}_Nm" for j in JOINTS]
        cols.append(np.stack([(k + 1) * np.sin(0.7 * t + k) - 0.3 * k for k in range(5)], axis=1))
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / "program.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for i in range(len(t)):
            w.writerow([repr(float(t[i])), seg[i], traj[i], *(repr(float(v)) for c in cols for v in c[i])])
    summary = {
        "order": [str(ts.ids[0]), str(ts.ids[1])],
        "total_s": float(t[-1]),
        "drilling_s": 2.0,
        "rows": len(t),
        "dt_s": SYNTHETIC_DT,
        "mode": "+,+,+,+",
        "clearance_min_mm": 7.5,
        "clearance_min_at": str(ts.ids[0]),
        "tool_clearance_min_mm": 3.25,
        "tool_clearance_min_at": traj[40],
        "self_clearance_min_mm": 1.5,
        "self_clearance_min_at": str(ts.ids[1]),
        "eta_L_max": 4.5,
        "eta_L_max_at": str(ts.ids[1]),
        "joint_speed_max_deg_s": {j: 10.0 + k for k, j in enumerate(JOINTS)},
        "joint_accel_max_deg_s2": {j: 50.0 for j in JOINTS},
        "tip_speed_max_transit_mm_s": 20.0,
        "limits": SYNTHETIC_LIMITS,
        "anatomy": None,
        "plan": "reference",
        "trajectories": [{"trajectory": str(ts.ids[0]), "level": "C3", "side": "R", "start_s": 0.0}],
        "transits": [],
    }
    if motors:
        summary["motors"] = SYNTHETIC_MOTORS
    (folder / "program.json").write_text(json.dumps(summary, indent=1))
    Design.from_dict(PROGRAM_DESIGN).to_json(folder / "design.json")
    return folder


SENSITIVITY_CASES = [
    # (design seed or None for the paper, mount (deg), L (mm), mode index)
    (None, (0.0, 0.0, 0.0), 0.0, 0),
    (None, (20.0, -35.0, 170.0), 60.0, 3),
    (11, (-135.0, -144.74, -67.63), 140.0, 5),
    (22, (113.4, -119.8, -77.3), 199.7, 10),
    (33, (30.0, 10.0, -50.0), 25.0, 15),
    (44, (-90.0, 45.0, 0.0), 90.0, 6),
]
"""The placed cases of the forward-kinematics derivatives' tests (tests/test_sensitivity.py, tests/test_accuracy*.py)."""


def sensitivity_case(seed, mount, L, mode_index, n=8, rng_seed=7):
    """As :func:`placed_case`, with poses of transmission sines > 0.15: (design (27,), E, e (n, 3), mode (4,))."""
    x23 = vec(PAPER) if seed is None else random_design(np.random.default_rng(seed))
    mode = ALL_MODES_ORACLE[mode_index]
    E_p, e_p = reachable_poses(np.random.default_rng(rng_seed), x23, mode, n, min_sine=0.15)
    x, E, e = place(x23, np.array(mount, dtype=float), L, E_p, e_p)
    return x, E, e, mode


DEMO = Design.from_json(REPO / "tests" / "data" / "demo_design.json")
"""The design ``arcube demo`` chooses on the reference patient's right side (README), working mode +,+,+,-."""
DEMO_MODE = DEMO.mode


def plan_right(points: int = 5):
    """The reference plan's right side: (TrajectorySet, Task)."""
    ts = select(load_trajectories("reference"), side="R")
    return ts, build_task(ts.entry, ts.target, points, ids=ts.ids)


def program_object(n: int = 6, torques: bool = True) -> Program:
    """A random :class:`~arcube.motion.output.Program` of ``n`` rows as the writer holds it (not written): increasing times, unit axes, bounded angles."""
    rng = np.random.default_rng(n)
    e = rng.normal(size=(n, 3))
    e /= np.linalg.norm(e, axis=1, keepdims=True)
    segments = np.array((["approach", "drill", "retract", "transit"] * n)[:n])
    return Program(
        t_s=np.arange(n) * 0.01,
        segment=segments,
        trajectory=np.array(["1"] * (n - 1) + ["1->2"]),
        E=rng.uniform(-80, 80, (n, 3)),
        e=e,
        q_deg=rng.uniform(-170, 170, (n, 5)),
        q_dot_deg=rng.uniform(-30, 30, (n, 5)),
        summary={
            "order": ["1", "2"],
            "total_s": 0.05,
            "transits": [{"from": "1", "to": "2"}],
            "limits": {"feed": 1.5, "dt": 0.01},
            "mode": "+,+,+,+",
            "motors": {"rho_x": {"torque_peak_Nm": 3.0}},
        },
        tau_Nm=rng.uniform(-5, 5, (n, 5)) if torques else None,
    )


def reference_right_csv() -> list[str]:
    """The lines of a plan CSV (header first) holding the reference patient's right-side trajectories, to the last
    digit: a plan file that a test can copy, move or edit."""
    ref = load_trajectories("reference")
    lines = ["trajectory,level,side,entry_x,entry_y,entry_z,target_x,target_y,target_z"]
    return lines + [
        f"{i},{lv},{sd}," + ",".join(repr(float(v)) for v in (*a, *b))
        for i, lv, sd, a, b in zip(ref.ids, ref.levels, ref.sides, ref.entry, ref.target)
        if sd == "R"
    ]
