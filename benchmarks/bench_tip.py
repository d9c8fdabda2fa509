"""Cost of the drill-tip metrics (MODEL.md 15) in the compiled kernel, against the kernel without them.

400 designs x 300 points (the bundled reference plan, 30 points per trajectory): the designs of
bench_clearance.py (random links around a posterior-facing mounting, the 400 that reach the most
points), so that most points get the forward Jacobian and the metrics; summaries only (what the
optimizer asks for) and per-point results.

Rerun: ``.venv/bin/python benchmarks/bench_tip.py`` (best of --repeats runs, one process).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

import arcube
from arcube.evaluation.kernel import evaluate_task_numba, warm_up
from arcube.evaluation.reference import Options
from arcube.evaluation.task import build_task
from arcube.model.mechanism import ALL_MODES

sys.path.insert(0, str(Path(__file__).parent))
from bench_clearance import best_time, designs  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--designs", type=int, default=400)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    plan = arcube.load_trajectories("reference")
    task = build_task(plan.entry, plan.target, 30)
    warm_up()
    X, count = designs(task, args.designs, args.seed)
    off, on = Options(tip_metrics=False), Options(tip_metrics=True)
    print(f"{X.shape[0]} designs x {len(task.E)} points; {count.mean() / len(task.E):.0%} of the points reachable on average")
    run(X, task, off, on, args.repeats)
    # every point reachable: Table 2's links placed for the right side, lengths jittered by 0.1 %
    right = arcube.select(plan, side="R")
    task_r = build_task(right.entry, right.target, 60)
    x0 = arcube.Design.paper().replace(m_x=88.23, m_y=79.40, m_z=56.89).to_vector()
    X_r = x0 * (1.0 + 1e-3 * np.random.default_rng(args.seed).uniform(-1, 1, (args.designs, x0.size)) * (np.arange(x0.size) >= 3))
    reach = evaluate_task_numba(X_r, task_r.E, task_r.e, ALL_MODES[0], off).reachable_fraction.mean()
    print(f"{X_r.shape[0]} designs x {len(task_r.E)} right-side points; {reach:.0%} of the points reachable")
    run(X_r, task_r, off, on, args.repeats)
    print("rerun: .venv/bin/python benchmarks/bench_tip.py")


def run(X, task, off: Options, on: Options, repeats: int) -> None:
    n = X.shape[0] * len(task.E)
    for want in (False, True):
        for opts in (off, on):  # compile both paths first
            evaluate_task_numba(X[:2], task.E, task.e, ALL_MODES[0], opts, want_points=want)
        t_off = best_time(lambda: evaluate_task_numba(X, task.E, task.e, ALL_MODES[0], off, want_points=want), repeats)
        t_on = best_time(lambda: evaluate_task_numba(X, task.E, task.e, ALL_MODES[0], on, want_points=want), repeats)
        what = "per-point results" if want else "summaries only"
        print(f"kernel, {what:18s}: without metrics {1e9 * t_off / n:6.0f} ns/point, with {1e9 * t_on / n:6.0f} ns/point "
              f"({t_on / t_off:.2f}x; target <= 2x)")


if __name__ == "__main__":
    main()
