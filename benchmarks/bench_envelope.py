"""Cost of the envelope guard (MODEL.md 19.5) in the compiled kernel, with and without it.

400 designs x 300 points (the bundled reference plan, 30 points per trajectory), summaries only (what the
optimizer asks for), the default anatomy and default envelope of the reference patient. The designs are
those of ``bench_clearance.py`` (a cube diagonal pointing posterior, the TLS box centred on the task; the
400 that reach the most points of 4000), so most points get a body. Each configuration is timed as it is
and with ``--envelope-clearance 10`` added (the design requirement's default):

* the paper's evaluation (no body: the envelope guard adds the body itself);
* ``--clearance 5 --self-clearance 2`` with the guards of 8.2 (what ``arcube design``'s optimizer runs on the
  plan's points, without the drill-tip metrics);
* the same with the drill-tip metrics and the holding torque (``arcube design``'s plan tasks).

Also the cost of the envelope's clearance itself per point (full per-point output, guard off but the
clearance asked for), and the NumPy reference's, for scale.

The two runs of a configuration alternate, and each keeps its best of --repeats (on a shared machine the load
drifts; ``--threads 1`` keeps other processes' load out of the ratio).

Rerun: ``.venv/bin/python benchmarks/bench_envelope.py [--threads 1]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from bench_clearance import best_time, designs  # noqa: E402
from numba import set_num_threads  # noqa: E402

import arcube  # noqa: E402
from arcube.options import Outputs
from arcube.evaluation.anatomy import load_anatomy  # noqa: E402
from arcube.evaluation.envelope import resolve_envelope  # noqa: E402
from arcube.evaluation.kernel import evaluate_task_numba, warm_up  # noqa: E402
from arcube.evaluation.reference import GUARDED_OPTIONS, Options, evaluate_task  # noqa: E402
from arcube.evaluation.task import build_task  # noqa: E402
from arcube.model.mechanism import ALL_MODES  # noqa: E402


def with_envelope(options: Options, limit: float = 10.0) -> Options:
    return options.replace(guards=options.guards.replace(envelope_clearance_mm=limit))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--designs", type=int, default=400)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=None, help="Numba threads (default: Numba's)")
    args = ap.parse_args()
    if args.threads:
        set_num_threads(args.threads)
    plan = arcube.load_trajectories("reference")
    task = build_task(plan.entry, plan.target, 30)
    warm_up()
    X, count = designs(task, args.designs, args.seed)
    anatomy = load_anatomy("default", plan="reference")
    dist = anatomy.distance
    env = resolve_envelope("default", plan, anatomy)
    n_pts = X.shape[0] * len(task.E)
    guards = GUARDED_OPTIONS.guards.replace(clearance_mm=5.0, self_clearance_mm=2.0)
    job = Options(guards=guards, outputs={"clearance_min_exact": False, "tip_metrics": False})
    job_tip = Options(guards=guards, outputs={"clearance_min_exact": False, "tip_metrics": True, "holding_torque": True})
    cases = {
        "paper (no body)": (Options(), None),
        "--clearance 5 --self-clearance 2 --guarded": (job, dist),
        "  + tip metrics and holding torque": (job_tip, dist),
    }
    for opts, d in cases.values():  # compile every path first
        for o in (opts, with_envelope(opts)):
            evaluate_task_numba(X[:2], task.E, task.e, ALL_MODES[0], o, want_points=False, anatomy=d, envelope=env)
    print(f"{X.shape[0]} designs x {len(task.E)} points; {count.mean() / len(task.E):.0%} of the points reachable on average")
    share = evaluate_task_numba(X, task.E, task.e, ALL_MODES[0], Options(outputs=Outputs(envelope_clearance=True)), envelope=env).points
    solved = np.isfinite(share.envelope_clearance_mm)
    print(f"envelope clearance at the {solved.mean():.0%} of points the stages solve: median {np.nanmedian(share.envelope_clearance_mm):.1f} mm, "
          f"{np.mean(share.envelope_clearance_mm[solved] < 10.0):.0%} below 10 mm")  # fmt: skip
    for name, (opts, d) in cases.items():
        runs = {False: opts, True: with_envelope(opts)}
        best = {False: np.inf, True: np.inf}
        for _ in range(args.repeats):
            for on, o in runs.items():
                t = time.perf_counter()
                evaluate_task_numba(X, task.E, task.e, ALL_MODES[0], o, want_points=False, anatomy=d, envelope=env if on else None)
                best[on] = min(best[on], time.perf_counter() - t)
        a, b = 1e9 * best[False] / n_pts, 1e9 * best[True] / n_pts
        print(f"kernel, summaries only, {name:44s} {a:7.0f} ns/point, with --envelope-clearance 10: {b:7.0f} ns/point ({b / a:4.2f}x)")
    k = 4
    t = best_time(lambda: evaluate_task(X[:k], task.E, task.e, ALL_MODES[0], Options(outputs=Outputs(envelope_clearance=True)), envelope=env), 1)
    print(f"NumPy reference, envelope clearance only, {k} designs: {1e9 * t / (k * len(task.E)):,.0f} ns/point")
    print("rerun: .venv/bin/python benchmarks/bench_envelope.py")


if __name__ == "__main__":
    main()
