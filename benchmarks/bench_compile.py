"""Compile time of the compiled kernel on a cold cache: what every fresh install (and CI) pays once.

Runs ``arcube evaluate --points 3`` (the paper's design on the reference plan: the kernel with the
anatomy, the envelope, the clearances and the tip metrics) in a subprocess with an empty Numba cache
(``NUMBA_CACHE_DIR`` a new temporary folder), listening to Numba's compile events, then again with that
cache filled. Prints the wall time of both, the number of compiled specializations, and the functions whose
own compile time (without their callees') is largest, with how many specializations each has.

A function compiled several times is usually called with constant arguments: Numba compiles a callee
once per literal value of an integer or boolean argument (``_put(g, lines, 3, 0, ...)``), which is why the
kernel passes ``np.int64(0)`` and inlines its small helpers (see ``kernel/_body.py`` and ``kernel/_driver.py``).

Rerun: ``.venv/bin/python benchmarks/bench_compile.py [--top 15]``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

CHILD = r"""
import collections, json, sys, time
from numba.core import event

stack, rows = [], []

class Listener(event.Listener):
    def on_start(self, e):
        stack.append([e.data["dispatcher"].py_func.__qualname__, time.perf_counter(), 0.0])

    def on_end(self, e):
        name, t0, children = stack.pop()
        dt = time.perf_counter() - t0
        rows.append((name, dt - children))
        if stack:
            stack[-1][2] += dt

event.register("numba:compile", Listener())
from arcube.cli import main
try:
    main(["evaluate", "--points", "3", "--json"])
except SystemExit:
    pass
own = collections.defaultdict(lambda: [0, 0.0])
for name, seconds in rows:
    own[name][0] += 1
    own[name][1] += seconds
print(json.dumps({"compiles": len(rows), "seconds": sum(s for _, s in rows), "own": own}))
"""


def run(cache: str) -> tuple[float, dict]:
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", CHILD], env={**os.environ, "NUMBA_CACHE_DIR": cache}, capture_output=True, text=True, check=True)
    return time.perf_counter() - start, json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--top", type=int, default=15, help="functions listed")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="numba_cache_") as cache:
        cold, figures = run(cache)
        warm, again = run(cache)
    print(f"arcube evaluate --points 3, cold Numba cache: {cold:.1f} s wall, {figures['compiles']} compiled specializations, "
          f"{figures['seconds']:.1f} s compiling")  # fmt: skip
    print(f"the same with the cache filled: {warm:.1f} s wall, {again['compiles']} compiled")
    print(f"{'function':34} {'compiled':>8} {'own s':>7}")
    for name, (n, seconds) in sorted(figures["own"].items(), key=lambda kv: -kv[1][1])[: args.top]:
        print(f"{name:34} {n:>8} {seconds:>7.2f}")
    print("Rerun: .venv/bin/python benchmarks/bench_compile.py")


if __name__ == "__main__":
    main()
