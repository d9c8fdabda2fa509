"""Time per point of the three ways to evaluate designs on a task (MODEL.md 8, 12.2).

Rerun with::

    cd /work/main && .venv/bin/python benchmarks/bench_evaluate.py

(options: ``--designs 400 --loop-points 300 --repeats 9 --seed 0``; ``NUMBA_NUM_THREADS`` sets the
kernel's threads). Workload: the bundled reference patient (10 trajectories x 30 points =
300 points) and random designs around the paper preset (Table 2) with m = (88.2, 79.4, 56.9),
which reaches the right-side trajectories; a second, all-reachable workload (the 5 right-side
trajectories x 60 points) times the kernel where every stage runs at every point.

(a) a per-point Python loop: inverse_kinematics of one (design, point), the seven Jacobians of
    arcube.model.mechanism.jacobians and np.linalg.cond of each (7 SVDs), timed on a subset of
    reachable points and extrapolated per point;
(b) the NumPy batch arcube.evaluation.evaluate_task;
(c) the Numba kernel arcube.evaluation.kernel.evaluate_task_numba (warm), want_points True and False
    (default fast path; the exact=True path, which evaluates every trigonometric function as
    the reference does, for comparison).

Times are the best of ``--repeats`` wall-clock runs (a loaded machine inflates them).
"""

from __future__ import annotations

import argparse
import csv
import os
import platform
import resource
import sys
import time
import tracemalloc
from importlib import resources

import numpy as np

from arcube.model.design import Design
from arcube.evaluation.reference import evaluate_task
from arcube.model.mechanism import DEFAULT_MODE, inverse_kinematics, jacobians
from arcube.evaluation.task import build_task

M_RIGHT = (88.2, 79.4, 56.9)


def reference_patient() -> tuple[np.ndarray, np.ndarray, list[str]]:
    text = resources.files("arcube").joinpath("data/reference_patient.csv").read_text(encoding="utf-8")
    rows = list(csv.DictReader(text.splitlines()))
    entry = np.array([[float(r[f"entry_{c}"]) for c in "xyz"] for r in rows])
    target = np.array([[float(r[f"target_{c}"]) for c in "xyz"] for r in rows])
    return entry, target, [r["side"] for r in rows]


def designs(n: int, seed: int) -> np.ndarray:
    """Paper preset with m = M_RIGHT, lengths and angles jittered by 3 %, m by 2 mm."""
    rng = np.random.default_rng(seed)
    x0 = Design.preset("paper").to_vector()
    x0[0:3] = M_RIGHT
    X = x0 * (1.0 + 0.03 * rng.standard_normal((n, x0.size)))
    X[:, 0:3] = x0[0:3] + 2.0 * rng.standard_normal((n, 3))
    return X


def best_time(fn, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def loop_time_per_point(X: np.ndarray, E: np.ndarray, e: np.ndarray, n_points: int, seed: int) -> tuple[float, int]:
    """(a): seconds per point of IK + 7 Jacobians + 7 np.linalg.cond, on reachable (design, point) pairs."""
    ok = evaluate_task(X, E, e).points.reachable
    pairs = np.argwhere(ok)
    rng = np.random.default_rng(seed)
    pick = pairs[rng.choice(len(pairs), size=min(n_points, len(pairs)), replace=False)]
    sink = 0.0
    t0 = time.perf_counter()
    for i, k in pick:
        sol = inverse_kinematics(X[i], E[k], e[k], DEFAULT_MODE)
        for J in jacobians(sol, X[i]).values():
            sink += np.linalg.cond(J)
    dt = time.perf_counter() - t0
    assert np.isfinite(sink)
    return dt / len(pick), len(pick)


def peak_traced(fn) -> float:
    """Peak of Python/NumPy allocations (tracemalloc) during fn, MiB. Numba's own allocations
    inside compiled code are not traced (the kernel allocates only per-design rows there)."""
    tracemalloc.start()
    tracemalloc.reset_peak()
    fn()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak / 2**20


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--designs", type=int, default=400)
    ap.add_argument("--loop-points", type=int, default=300, help="points timed in the Python loop (a)")
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()

    t_import = time.perf_counter()
    import numba

    from arcube.evaluation import kernel

    t_import = time.perf_counter() - t_import
    t_warm = kernel.warm_up()

    entry, target, side = reference_patient()
    task = build_task(entry, target, 30)
    E, e = task.E, task.e
    X = designs(args.designs, args.seed)
    n_des, n_pts = X.shape[0], E.shape[0]
    n = n_des * n_pts

    # first call on the real shapes (after warm_up: no compilation, just the first touch)
    t0 = time.perf_counter()
    ref = evaluate_task(X, E, e)
    t_first_numpy = time.perf_counter() - t0
    t0 = time.perf_counter()
    kernel.evaluate_task_numba(X, E, e)
    t_first_kernel = time.perf_counter() - t0

    t_loop, n_loop = loop_time_per_point(X, E, e, args.loop_points, args.seed)
    t_numpy = best_time(lambda: evaluate_task(X, E, e), max(2, args.repeats // 2))
    t_k_pts = best_time(lambda: kernel.evaluate_task_numba(X, E, e, want_points=True), args.repeats)
    t_k_sum = best_time(lambda: kernel.evaluate_task_numba(X, E, e, want_points=False), args.repeats)
    t_x_pts = best_time(lambda: kernel.evaluate_task_numba(X, E, e, want_points=True, exact=True), args.repeats)
    t_x_sum = best_time(lambda: kernel.evaluate_task_numba(X, E, e, want_points=False, exact=True), args.repeats)

    # all-reachable workload: right side, 60 points per trajectory (300 points)
    right = np.array([s == "R" for s in side])
    task_r = build_task(entry[right], target[right], 60)
    ref_r = evaluate_task(X, task_r.E, task_r.e)
    t_numpy_r = best_time(lambda: evaluate_task(X, task_r.E, task_r.e), max(2, args.repeats // 2))
    t_k_pts_r = best_time(lambda: kernel.evaluate_task_numba(X, task_r.E, task_r.e, want_points=True), args.repeats)
    t_k_sum_r = best_time(lambda: kernel.evaluate_task_numba(X, task_r.E, task_r.e, want_points=False), args.repeats)

    # agreement check on this workload (same summaries)
    out = kernel.evaluate_task_numba(X, E, e, want_points=False)
    agree = np.allclose(out.eta_G, ref.eta_G, rtol=1e-10, atol=0) and np.allclose(out.violation, ref.violation, rtol=1e-10, atol=0)
    agree &= np.allclose(out.dexterity_mean, ref.dexterity_mean, rtol=1e-10, atol=0)

    mem_numpy = peak_traced(lambda: evaluate_task(X, E, e))
    mem_k_pts = peak_traced(lambda: kernel.evaluate_task_numba(X, E, e, want_points=True))
    mem_k_sum = peak_traced(lambda: kernel.evaluate_task_numba(X, E, e, want_points=False))
    maxrss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB on Linux

    ns = 1e9
    print("AR-CUBE evaluation benchmark")
    print(f"  command : cd /work/main && .venv/bin/python benchmarks/bench_evaluate.py {' '.join(sys.argv[1:])}".rstrip())
    print(f"  machine : {platform.platform()}, {platform.processor() or platform.machine()}, "
          f"os.cpu_count()={os.cpu_count()}, Python {platform.python_version()}, NumPy {np.__version__}, "
          f"Numba {numba.__version__} ({numba.get_num_threads()} threads, layer {numba.threading_layer()})")  # fmt: skip
    print(f"  workload: {n_des} designs x {n_pts} points = {n} evaluations "
          f"(reference patient, 10 trajectories x 30; reachable {ref.points.reachable.mean():.1%}, "
          f"w_G = 1 for {int(ref.w_G.sum())} designs)")  # fmt: skip
    print(f"  kernel compile/load: import {t_import:.2f} s, warm_up() {t_warm:.2f} s "
          f"(first full-size call: kernel {t_first_kernel * 1e3:.1f} ms, NumPy {t_first_numpy * 1e3:.1f} ms)")  # fmt: skip
    print()
    print(f"  {'method':<52} {'ns/point':>10} {'total ms':>10}")
    rows = [
        (f"(a) Python loop: IK + 7 Jacobians + 7 cond ({n_loop} pts)", t_loop * ns, t_loop * n * 1e3),
        ("(b) NumPy batch evaluate_task", t_numpy / n * ns, t_numpy * 1e3),
        ("(c) Numba kernel, want_points=True", t_k_pts / n * ns, t_k_pts * 1e3),
        ("(c) Numba kernel, want_points=False", t_k_sum / n * ns, t_k_sum * 1e3),
        ("    same, exact=True (reference trig), points", t_x_pts / n * ns, t_x_pts * 1e3),
        ("    same, exact=True (reference trig), summaries", t_x_sum / n * ns, t_x_sum * 1e3),
    ]
    for name, v, tot in rows:
        print(f"  {name:<52} {v:>10.1f} {tot:>10.2f}")
    print()
    print(f"  speed-up kernel (points / summaries) vs loop : {t_loop * n / t_k_pts:>9.0f}x / {t_loop * n / t_k_sum:.0f}x")
    print(f"  speed-up kernel (points / summaries) vs NumPy: {t_numpy / t_k_pts:>9.1f}x / {t_numpy / t_k_sum:.1f}x")
    print(f"  summaries agree with NumPy to 1e-10: {bool(agree)}")
    print()
    print(f"  all-reachable workload (right side, 5 x 60 points; reachable {ref_r.points.reachable.mean():.1%}):")
    print(f"    NumPy {t_numpy_r / n * ns:.1f} ns/pt, kernel {t_k_pts_r / n * ns:.1f} ns/pt (points) / "
          f"{t_k_sum_r / n * ns:.1f} ns/pt (summaries): {t_numpy_r / t_k_pts_r:.1f}x / {t_numpy_r / t_k_sum_r:.1f}x")  # fmt: skip
    print()
    print(f"  peak traced allocations (tracemalloc): NumPy batch {mem_numpy:.1f} MiB, "
          f"kernel points {mem_k_pts:.1f} MiB, kernel summaries {mem_k_sum:.2f} MiB")  # fmt: skip
    print(f"  process peak RSS (ru_maxrss): {maxrss:.0f} MiB")


if __name__ == "__main__":
    main()
