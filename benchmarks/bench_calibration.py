"""Speed and figures of calibration (MODEL.md 21) on the demo's robot at its right docking (tests/data/one_robot.json, the
one robot ``arcube design --trajectories reference`` finds) and the right side of the bundled reference plan (5 trajectories).

Speed (targets of issue 32 on this 2-core machine): pose selection from a few thousand candidates in seconds,
identification of 40-200 measurements in seconds. ``identify`` is timed twice: the fit alone (the budget's Monte
Carlo at 1 robot) and the whole call with the calibrated robot's budget (1000 robots on the plan's 150 points).

Figures (the README's): robots built to class m (seeds 1-3), measured with tracker noise (0.15 mm, 0.1 deg) at 40
greedy D-optimal poses and at 40 random ones among the same candidates; the largest and the 95th-percentile
lateral error over the plan (30 points per trajectory) when the controller uses the nominal design (before) and
the calibrated one (after: IK_calibrated - q0); the held-out tip and axis residuals against the noise level.

Rerun: ``PYTHONPATH=src .venv/bin/python benchmarks/bench_calibration.py`` (best of --repeats runs, one process).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np
from pathlib import Path

import arcube
from arcube.calibrate import (
    IdentifySettings,
    PoseSettings,
    SimulateSettings,
    identify,
    poses,
    simulate,
)
from arcube.calibrate.simulate import tip_errors
from arcube.evaluation.task import build_task


def best_time(fn: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--robots", type=int, default=3, help="simulated robots of the figures (seeds 1..N)")
    args = ap.parse_args()
    from arcube.pedicles.run import robot_dockings

    design = robot_dockings(Path(__file__).resolve().parents[1] / "tests" / "data" / "one_robot.json")["R"]
    mode = design.mode
    plan = arcube.select(arcube.load_trajectories("reference"), side="R")
    task = build_task(plan.entry, plan.target, 30)

    for points in (30, 60):
        s = PoseSettings(points=points)
        sel = poses(design, plan, mode, s)
        t = best_time(lambda s=s: poses(design, plan, mode, s), args.repeats)
        print(f"poses(): {sel.candidates} candidates reached of {sel.drawn} drawn, 40 chosen: {t:.2f} s; "
              f"O1 {sel.o1:.3f} (random {sel.o1_random:.3f}), condition {sel.condition_number:.0f} (random {sel.condition_number_random:.0f})")  # fmt: skip
    big = poses(design, plan, mode, PoseSettings(count=200))
    for n in (40, 100, 200):
        sim = simulate(design, big.measurements.take(np.arange(n)), SimulateSettings(seed=1))
        fit_only = IdentifySettings(samples=1)
        t_fit = best_time(lambda m=sim.measurements, s=fit_only: identify(design, m, mode, s), args.repeats)
        t_all = best_time(lambda m=sim.measurements: identify(design, m, mode, trajectories=plan), args.repeats)
        print(f"identify(), {n} measurements: fit {t_fit:.2f} s; with the budget (1000 robots x 150 plan points) {t_all:.2f} s")

    chosen = poses(design, plan, mode)
    print(f"\nfigures: class m robots, 40 poses, tracker noise 0.15 mm / 0.1 deg, holdout 0.25; lateral error over the plan "
          f"({len(task)} points), max / p95 in mm")  # fmt: skip
    x = design.to_vector()
    for seed in range(1, args.robots + 1):
        for name, meas in (("D-optimal", chosen.measurements), ("random", chosen.random)):
            sim = simulate(design, meas, SimulateSettings(seed=seed))
            res = identify(design, sim.measurements, mode, trajectories=plan)
            before = tip_errors(sim.design, sim.q0_deg, x, np.zeros(5), task.E, task.e, res.mode)["lateral_mm"]
            after = tip_errors(sim.design, sim.q0_deg, res.design, res.q0_deg, task.E, task.e, res.mode)["lateral_mm"]
            held = res.residual_rms()["held_out"]
            b = res.budget.summary
            print(f"seed {seed} {name:9s}: before {before.max():.2f} / {np.percentile(before, 95):.2f}, after {after.max():.3f} / "
                  f"{np.percentile(after, 95):.3f}; held-out residual tip {held['E_rms_mm']:.3f} mm (noise {np.sqrt(3) * 0.15:.3f}), "
                  f"axis {held['e_rms_deg']:.3f} deg (noise {np.sqrt(2) * 0.1:.3f}); sigma_hat {res.sigma_hat:.2f}; "
                  f"budget p95 {b['lateral_error_p95_mm']:.3f} mm (RMS {b['lateral_error_rms_mm']:.3f}); "
                  f"not identifiable: {', '.join(u['name'] + ' (with ' + ', '.join(c['name'] for c in u['confounded_with']) + ')' for u in res.unknown_rows() if not u['identifiable'])}")  # fmt: skip
    print("rerun: PYTHONPATH=src .venv/bin/python benchmarks/bench_calibration.py")


if __name__ == "__main__":
    main()
