"""Replay a drilling program in MuJoCo and compare the drill tip with the program's E.

Needs only ``mujoco`` and ``numpy`` (not arcube)::

    arcube program --design D.json --trajectories reference --side R --ids 1 --out prog
    arcube export --program prog --design D.json --c-z 400 --out robot.xml   # also robot.replay.csv
    python examples/mujoco_replay.py robot.xml robot.replay.csv

The model starts from its keyframe ``assembled``: the program's first row, at rest. At every row the
five position actuators (rho_x, rho_y, rho_z, delta_x, delta_y) get the program's angles plus a
feed-forward: the torque tau the motion needs, from MuJoCo's own inverse dynamics at the row's
state, projected through the closed loops,

    tau = G^T qfrc_inverse,    G (17 x 5): hinge rates per actuator rate (null space of the closures),

(MuJoCo cuts the loops in ``mj_inverse``: an actuator's own entry of ``qfrc_inverse`` is not its
torque), so ctrl = q + tau / kp. The rows' hinge rates are G qvel (the replay's ``qvel_*``), their
accelerations the central differences of those. Between rows the targets are interpolated linearly,
one ``mj_step`` per model timestep. Gravity is off unless ``--gravity`` (then tau holds the weight
too). Printed: the largest distance between the ``tip`` site and the program's E per segment kind
(mm), and on the drill segments.
"""

from __future__ import annotations

import argparse
import csv
import sys

import mujoco
import numpy as np

ACTUATED = ("rho_x", "rho_y", "rho_z", "delta_x", "delta_y")


def read_replay(path: str) -> dict[str, np.ndarray]:
    """The replay CSV of ``arcube export --program``: t (n,), segment (n,), E (n, 3) mm, ctrl and qvel
    (n, 5) rad and rad/s in ACTUATED order, qpos (n, nq) rad keyed by the model's joint names."""
    with open(path, newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    if not rows or any(f"ctrl_{n}" not in rows[0] for n in ACTUATED):
        sys.exit(f"error: {path}: not a replay CSV of 'arcube export --program'")
    col = lambda names: np.array([[float(r[n]) for n in names] for r in rows])  # noqa: E731
    qpos_names = [c for c in rows[0] if c.startswith("qpos_")]
    return {
        "t": col(["t_s"])[:, 0], "segment": np.array([r["segment"] for r in rows]), "E": col(["E_x_mm", "E_y_mm", "E_z_mm"]),
        "ctrl": col([f"ctrl_{n}" for n in ACTUATED]), "qvel": col([f"qvel_{n}" for n in ACTUATED]),
        "qpos": col(qpos_names), "qpos_names": np.array([c.removeprefix("qpos_") for c in qpos_names]),
    }  # fmt: skip


def actuated_basis(model: mujoco.MjModel, data: mujoco.MjData, dofs: list[int]) -> np.ndarray:
    """G (nv, 5) at data's pose: the hinge rates per actuator rate, the null space of the loop closures'
    Jacobian scaled so that its actuated rows are the identity (needs mj_forward first)."""
    J = data.efc_J[: data.nefc * model.nv].reshape(data.nefc, model.nv)
    _, s, vt = np.linalg.svd(J)
    rank = int(np.sum(s > 1e-9 * s[0]))
    N = vt[rank:].T
    return N @ np.linalg.inv(N[dofs])


def feedforward_ctrl(model: mujoco.MjModel, rp: dict[str, np.ndarray]) -> np.ndarray:
    """(n, 5) actuator targets: the program's angles plus tau / kp, tau = G^T qfrc_inverse at each row."""
    data = mujoco.MjData(model)
    dofs = [model.joint(n).dofadr[0] for n in ACTUATED]
    adr = [model.joint(n).qposadr[0] for n in rp["qpos_names"]]
    n = len(rp["t"])
    G = np.zeros((n, model.nv, 5))
    for i in range(n):
        data.qpos[adr] = rp["qpos"][i]
        mujoco.mj_forward(model, data)
        G[i] = actuated_basis(model, data, dofs)
    qvel = np.einsum("nij,nj->ni", G, rp["qvel"])
    qacc = np.gradient(qvel, rp["t"], axis=0) if n > 1 else np.zeros_like(qvel)
    tau = np.zeros((n, 5))
    for i in range(n):
        data.qpos[adr] = rp["qpos"][i]
        data.qvel[:] = qvel[i]
        data.qacc[:] = qacc[i]
        mujoco.mj_inverse(model, data)
        tau[i] = G[i].T @ data.qfrc_inverse
    kp = model.actuator_gainprm[[model.actuator(a).id for a in ACTUATED], 0]
    return rp["ctrl"] + tau / kp


def replay(model: mujoco.MjModel, rp: dict[str, np.ndarray], feedforward: bool = True) -> np.ndarray:
    """Drive the model along the replay from its keyframe; (n, 3) tip positions (mm) at the rows' times."""
    ctrl = feedforward_ctrl(model, rp) if feedforward else rp["ctrl"]
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("assembled").id)
    act = [model.actuator(a).id for a in ACTUATED]
    tip = model.site("tip").id
    data.ctrl[act] = ctrl[0]
    mujoco.mj_forward(model, data)
    out = np.zeros((len(rp["t"]), 3))
    out[0] = data.site_xpos[tip]
    for i in range(len(rp["t"]) - 1):
        steps = max(1, int(round((rp["t"][i + 1] - rp["t"][i]) / model.opt.timestep)))
        for s in range(steps):
            a = (s + 1) / steps
            data.ctrl[act] = (1.0 - a) * ctrl[i] + a * ctrl[i + 1]
            mujoco.mj_step(model, data)
        out[i + 1] = data.site_xpos[tip]
    return out


def main(argv: list[str] | None = None) -> float:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model", help="MJCF file written by 'arcube export --program'")
    ap.add_argument("replay", help="its replay CSV (robot.replay.csv beside robot.xml)")
    ap.add_argument("--gravity", action="store_true", help="keep the model's gravity (default: off)")
    ap.add_argument("--no-feedforward", action="store_true", help="targets only, no inverse-dynamics torque")
    args = ap.parse_args(argv)

    model = mujoco.MjModel.from_xml_path(args.model)
    model.opt.jacobian = mujoco.mjtJacobian.mjJAC_DENSE
    if not args.gravity:
        model.opt.gravity[:] = 0.0
    rp = read_replay(args.replay)
    tips = replay(model, rp, feedforward=not args.no_feedforward)
    err = np.linalg.norm(tips - rp["E"], axis=1)
    for kind in dict.fromkeys(rp["segment"]):
        sel = rp["segment"] == kind
        print(f"{kind:>9}: {int(sel.sum()):5d} rows, max tip error {err[sel].max():.6f} mm")
    drill = rp["segment"] == "drill"
    worst = float(err[drill].max()) if drill.any() else float("nan")
    print(f"max tip error on drill segments: {worst:.6f} mm over {int(drill.sum())} rows ({rp['t'][-1]:.2f} s simulated)")
    return worst


if __name__ == "__main__":
    main()
