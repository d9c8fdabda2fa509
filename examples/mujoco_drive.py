"""Drive an exported AR-CUBE MuJoCo model along a trajectory of ``arcube joints`` and compare the drill tip.

Needs only ``mujoco`` and ``numpy`` (not arcube)::

    arcube export --design my_design.json --c-z 160 --out robot.xml
    arcube joints --design my_design.json --out joints.csv
    python examples/mujoco_drive.py robot.xml joints.csv --trajectory 1

The model starts from its keyframe ``assembled``; the five position actuators (rho_x, rho_y, rho_z,
delta_x, delta_y) are ramped to the first point of the trajectory, then set point after point to the
CSV's angles (deg -> rad), with ``--steps`` simulation steps per point so that MuJoCo's own loop closure
settles. At each point the ``tip`` site is printed beside the CSV's x, y, z (mm, patient frame), and at
the end the largest distance. Gravity is off unless ``--gravity`` is given (the position servos alone
let the weight of the model's masses, MODEL.md 18.1, sag the tip by a millimetre or more;
``examples/mujoco_replay.py`` adds the torques that hold it).
"""

from __future__ import annotations

import argparse
import csv
import math
import sys

import mujoco
import numpy as np

ACTUATED = ("rho_x", "rho_y", "rho_z", "delta_x", "delta_y")


def read_joints(path: str, trajectory: str | None) -> tuple[str, list[dict[str, str]]]:
    """The reachable rows of one trajectory of an ``arcube joints`` CSV (the first trajectory by default)."""
    with open(path, newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        sys.exit(f"error: {path}: no rows")
    missing = [c for c in ("trajectory", "k", "x", "y", "z", *(f"{n}_deg" for n in ACTUATED)) if c not in rows[0]]
    if missing:
        sys.exit(f"error: {path}: not an 'arcube joints' CSV (missing {', '.join(missing)})")
    tid = rows[0]["trajectory"] if trajectory is None else trajectory
    keep = [r for r in rows if r["trajectory"] == tid and r.get("reachable", "true") == "true"]
    if not keep:
        sys.exit(f"error: {path}: no reachable point on trajectory {tid!r}")
    return tid, sorted(keep, key=lambda r: int(r["k"]))


def main(argv: list[str] | None = None) -> float:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model", help="MJCF file written by 'arcube export'")
    ap.add_argument("joints", help="CSV written by 'arcube joints' (same design, mode and plan)")
    ap.add_argument("--trajectory", help="trajectory id (default: the CSV's first)")
    ap.add_argument("--steps", type=int, default=3000, help="simulation steps per point (default 3000: long links settle slowly)")
    ap.add_argument("--ramp-steps", type=int, default=20000, help="steps to ramp from the keyframe to the first point (default 20000)")
    ap.add_argument("--gravity", action="store_true", help="keep the model's gravity (default: off)")
    args = ap.parse_args(argv)

    model = mujoco.MjModel.from_xml_path(args.model)
    data = mujoco.MjData(model)
    if not args.gravity:
        model.opt.gravity[:] = 0.0
    mujoco.mj_resetDataKeyframe(model, data, model.key("assembled").id)
    act = [model.actuator(n).id for n in ACTUATED]
    tip = model.site("tip").id

    tid, rows = read_joints(args.joints, args.trajectory)
    start = data.ctrl[act].copy()
    first = np.radians([float(rows[0][f"{n}_deg"]) for n in ACTUATED])
    for s in range(args.ramp_steps):  # ramp the targets in joint space: no jump through a singularity
        data.ctrl[act] = start + (first - start) * (s + 1) / args.ramp_steps
        mujoco.mj_step(model, data)

    worst = 0.0
    print(f"trajectory {tid}: k, CSV x y z (mm), MuJoCo tip x y z (mm), distance (mm)")
    for r in rows:
        data.ctrl[act] = np.radians([float(r[f"{n}_deg"]) for n in ACTUATED])
        for _ in range(args.steps):
            mujoco.mj_step(model, data)
        want = np.array([float(r[c]) for c in "xyz"])
        got = data.site_xpos[tip]
        err = float(np.linalg.norm(got - want))
        worst = max(worst, err) if math.isfinite(err) else math.inf
        print(f"{r['k']:>3}  {want[0]:9.3f} {want[1]:9.3f} {want[2]:9.3f}   {got[0]:9.3f} {got[1]:9.3f} {got[2]:9.3f}   {err:.6f}")
    print(f"max tip error: {worst:.6f} mm over {len(rows)} points")
    return worst


if __name__ == "__main__":
    main()
