"""Speed of the breach Monte Carlo (MODEL.md 22.4, issue 'Breach probability'): 10,000 samples x 10 screws.

The robot of tests/data/one_robot.json on both sides of the reference patient (10 screws, each side from its docking),
built to class m, registration 0.5 mm / 0.5 deg, thrust 30 N: the whole ``arcube.breach`` call (the draws, the robot's
displacements for every sample at once, the registration and deflection, the statistics), then the same draws through
the NumPy reference (one sample at a time) on a tenth of the samples, and the two paths' largest difference.
Target: 10,000 x 10 in <= 5 s on a 2-core machine. The ratio of the two paths, measured in one run, is what to compare.

Rerun: ``.venv/bin/python benchmarks/bench_breach.py [--samples 10000] [--repeat 3]``
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from arcube.accuracy import ToleranceSettings
from arcube.coerce import mode_signs
from arcube.io import load_trajectories, select
from arcube.pedicles import breach
from arcube.pedicles.geometry import pedicles
from arcube.pedicles.run import robot_dockings
from arcube.pedicles.sources import RobotModel, draw, robot_displacements, robot_displacements_reference

ROBOT = Path(__file__).resolve().parents[1] / "tests" / "data" / "one_robot.json"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--samples", type=int, default=10_000)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    breach(str(ROBOT), "reference", samples=100)  # imports and first calls out of the timing
    times = []
    for _ in range(a.repeat):
        t0 = time.perf_counter()
        r = breach(str(ROBOT), "reference", samples=a.samples)
        times.append(time.perf_counter() - t0)
    print(f"arcube.breach, {a.samples:,} samples x {len(r.pedicles.ids)} screws: best of {a.repeat} {min(times):.2f} s "
          f"(all: {', '.join(f'{t:.2f}' for t in times)} s); largest P(breach) {r.summary()['breach_probability']:.3f}")
    design = robot_dockings(ROBOT)["R"]
    plan = select(load_trajectories("reference"), side="R")
    p = pedicles(plan)
    x = design.to_vector()
    model = RobotModel(x, mode_signs(design.mode), ToleranceSettings().tolerances(x))
    n = max(1, a.samples // 10)
    draws = draw(np.random.default_rng(1), model, n, len(p.ids), 1, 0.5, 0.5)
    t0 = time.perf_counter()
    fast = robot_displacements(model, p.isthmus, -p.u, draws)
    t_fast = time.perf_counter() - t0
    t0 = time.perf_counter()
    slow = robot_displacements_reference(model, p.isthmus, -p.u, draws)
    t_slow = time.perf_counter() - t0
    print(f"robot displacements, {n:,} samples x {len(p.ids)} screws: batched {t_fast:.3f} s, reference (one sample at a time) "
          f"{t_slow:.3f} s: {t_slow / t_fast:.0f}x; largest difference {np.max(np.abs(fast - slow)):.2e} mm")


if __name__ == "__main__":
    main()
