"""Cost of the holding torque (MODEL.md 18.2) in the compiled kernel, against the kernel without it.

The holding torque is computed only where it is asked for (``Outputs.holding_torque``, on when an
objective, limit or requirement names ``holding_torque``, or by ``arcube evaluate``): every other run
keeps its speed. This measures what asking for it costs, over the drill-tip metrics of MODEL.md 15 it
needs (``tip_metrics``, the baseline: "without"); the kernel without any metric is shown for scale.

Designs as bench_tip.py: 400 designs x 300 points of the bundled reference plan (random links around a
posterior-facing mounting, those that reach the most points), then 400 jittered Table 2 designs that
reach every right-side point; summaries only (what the optimizer asks for) and per-point results.

Rerun: ``.venv/bin/python benchmarks/bench_masses.py`` (best of --repeats runs, one process;
``--designs 100`` for a quick look).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

import arcube
from arcube.evaluation.kernel import evaluate_task_numba, warm_up
from arcube.evaluation.task import build_task
from arcube.model.mechanism import ALL_MODES
from arcube.options import Options, Outputs

sys.path.insert(0, str(Path(__file__).parent))
from bench_clearance import best_time, designs  # noqa: E402

TARGET = 1.5
"""Largest acceptable cost ratio, holding torque on / off (tip metrics on in both)."""


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
    print(f"{X.shape[0]} designs x {len(task.E)} points; {count.mean() / len(task.E):.0%} of the points reachable on average")
    ratios = run(X, task, args.repeats)
    right = arcube.select(plan, side="R")
    task_r = build_task(right.entry, right.target, 60)
    x0 = arcube.Design.paper().replace(m_x=88.23, m_y=79.40, m_z=56.89).to_vector()
    X_r = x0 * (1.0 + 1e-3 * np.random.default_rng(args.seed).uniform(-1, 1, (args.designs, x0.size)) * (np.arange(x0.size) >= 3))
    reach = evaluate_task_numba(X_r, task_r.E, task_r.e, ALL_MODES[0], Options()).reachable_fraction.mean()
    print(f"{X_r.shape[0]} designs x {len(task_r.E)} right-side points; {reach:.0%} of the points reachable")
    ratios += run(X_r, task_r, args.repeats)
    print(f"largest ratio {max(ratios):.2f}x (target <= {TARGET}x): {'met' if max(ratios) <= TARGET else 'NOT met'}")
    print("rerun: .venv/bin/python benchmarks/bench_masses.py")


def run(X: np.ndarray, task, repeats: int) -> list[float]:
    """Best times of the three settings, per point; returns the on / off ratios."""
    none = Options(outputs=Outputs(tip_metrics=False))
    off = Options()  # the drill-tip metrics of MODEL.md 15, no holding torque
    on = Options(outputs=Outputs(holding_torque=True))
    n = X.shape[0] * len(task.E)
    ratios = []
    for want in (False, True):
        for opts in (none, off, on):  # compile every path first
            evaluate_task_numba(X[:2], task.E, task.e, ALL_MODES[0], opts, want_points=want)
        t = {name: best_time(lambda o=o: evaluate_task_numba(X, task.E, task.e, ALL_MODES[0], o, want_points=want), repeats)
             for name, o in (("none", none), ("off", off), ("on", on))}  # fmt: skip
        ratios.append(t["on"] / t["off"])
        what = "per-point results" if want else "summaries only"
        print(f"kernel, {what:18s}: no metrics {1e9 * t['none'] / n:5.0f} ns/point; tip metrics {1e9 * t['off'] / n:5.0f}; "
              f"with the holding torque {1e9 * t['on'] / n:5.0f} ({ratios[-1]:.2f}x)")
    return ratios


if __name__ == "__main__":
    main()
