"""Cost of the body clearances (MODEL.md 14.3) in the compiled kernel, beside the kernel without them.

400 designs x 300 points (the bundled reference plan, 30 points per trajectory), summaries only
(what the optimizer asks for), the default anatomy of the reference patient:

* no clearance (the paper's evaluation, with mounting rotation and tool offset);
* ``--clearance 5`` (clearance to the anatomy, branch-and-bound over the body's axes): deciding the
  guard and its shortfall only (what ``arcube optimize`` runs unless clearance is an objective or a
  ``--min`` limit), and with the exact smallest clearance over the plan;
* ``--clearance 5 --self-clearance 2`` (plus the clearance between the robot's parts);
* the NumPy reference with clearance, on 4 designs (per point, for scale).

The designs: random links and spherical angles within MODEL.md 12.1 bounds around a cube corner
whose diagonal points posterior (mount -135, -144.74, -67.63 deg), L in [100, 160] mm, the TLS box
centred on the task; the 400 that reach the most points of 4000 (so that most points get a body).

Rerun: ``.venv/bin/python benchmarks/bench_clearance.py`` (prints best of --repeats runs).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import arcube
from arcube.evaluation.anatomy import load_anatomy
from arcube.evaluation.kernel import evaluate_task_numba, warm_up
from arcube.evaluation.reference import Options, evaluate_task
from arcube.evaluation.task import build_task
from arcube.model.frames import rotation_matrix
from arcube.model.mechanism import ALL_MODES


def designs(task, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    m = 10 * n
    X = np.zeros((m, 27))
    X[:, 3:16] = rng.uniform(30, 200, (m, 13))
    X[:, 16] = rng.uniform(50, 80, m)
    X[:, 17:19] = rng.uniform(-180, 180, (m, 2))
    X[:, 19:23] = rng.uniform(60, 90, (m, 4))
    X[:, 23:26] = (-135.0, -144.74, -67.63)
    X[:, 26] = rng.uniform(100, 160, m)
    R = rotation_matrix(np.radians(X[0, 23:26]))
    C = task.E.mean(axis=0) + X[:, 26:27] * task.e.mean(axis=0)
    X[:, :3] = C - (-X[:, 3:6] - X[:, 16:17]) @ R.T
    count = evaluate_task_numba(X, task.E, task.e, ALL_MODES[0], Options(), want_points=True).points.reachable.sum(axis=1)
    return X[np.argsort(-count)[:n]], count[np.argsort(-count)[:n]]


def best_time(fn, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--designs", type=int, default=400)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    plan = arcube.load_trajectories("reference")
    task = build_task(plan.entry, plan.target, 30)
    warm_up()
    X, count = designs(task, args.designs, args.seed)
    anatomy = load_anatomy("default", plan="reference")
    t0 = time.perf_counter()
    dist = anatomy.distance
    t_grid = time.perf_counter() - t0
    n_pts = X.shape[0] * len(task.E)
    cases = {
        "no clearance": (Options(), None),
        "--clearance 5 (guard only, the optimizer)": (Options(clearance_mm=5.0, clearance_min_exact=False), dist),
        "--clearance 5, exact smallest clearance": (Options(clearance_mm=5.0), dist),
        "--clearance 5 --self-clearance 2 (guards)": (Options(clearance_mm=5.0, self_clearance_mm=2.0, clearance_min_exact=False), dist),
    }
    for opts, d in cases.values():  # compile every path first
        evaluate_task_numba(X[:2], task.E, task.e, ALL_MODES[0], opts, want_points=False, anatomy=d)
    print(f"{X.shape[0]} designs x {len(task.E)} points; {count.mean() / len(task.E):.0%} of the points reachable on average")
    print(f"distance grids of the default anatomy: {t_grid:.2f} s to build, {dist.nbytes / 2**20:.0f} MiB")
    base = None
    for name, (opts, d) in cases.items():
        t = best_time(lambda: evaluate_task_numba(X, task.E, task.e, ALL_MODES[0], opts, want_points=False, anatomy=d), args.repeats)
        ns = 1e9 * t / n_pts
        base = base or ns
        print(f"kernel, summaries only, {name:44s} {ns:8.0f} ns/point  ({ns / base:4.1f}x)")
    k = 4
    t = best_time(lambda: evaluate_task(X[:k], task.E, task.e, ALL_MODES[0], Options(clearance_mm=5.0, self_clearance_mm=2.0), dist), 1)
    print(f"NumPy reference, --clearance 5 --self-clearance 2, {k} designs: {1e9 * t / (k * len(task.E)):,.0f} ns/point")
    print("rerun: .venv/bin/python benchmarks/bench_clearance.py")


if __name__ == "__main__":
    main()
