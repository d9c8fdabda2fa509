"""Time to dock a built robot (MODEL.md 19.6, issue 'A robot for the population'): per side, and a cohort over workers.

``arcube dock`` as a user runs it, in a subprocess, with its defaults (8 starts, 6000 evaluations a side, every
requirement of arcube design, the report, accuracy budget and program of each side):

* the robot of ``--robot`` (default tests/data/one_robot.json, the one robot ``arcube design --trajectories reference``
  finds) on the reference patient's two sides, ``--workers 1``: the time per side;
* on ``--count`` virtual patients (``arcube patients --seed 17 --count N``: both sides each) with ``--workers 1`` and
  ``--workers 2``: the wall time, the time per side and the coverage.

Targets (2-core machine): one side <= 30 s; 80 sides (40 patients) <= 20 min with ``--workers 2``.

Rerun: ``.venv/bin/python benchmarks/bench_dock.py [--robot design.json] [--count 4] [--keep DIR]``
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROBOT = Path(__file__).resolve().parents[1] / "tests" / "data" / "one_robot.json"


def run(args: list[str], cwd: Path) -> tuple[float, dict]:
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-m", "arcube", *args], cwd=cwd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if out.returncode not in (0, 3):
        raise SystemExit(f"arcube {' '.join(args)} failed:\n{out.stderr}")
    return wall, json.loads((cwd / args[args.index("--out") + 1] / "summary.json").read_text())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--robot", type=Path, default=ROBOT)
    ap.add_argument("--count", type=int, default=4, help="virtual patients (two sides each)")
    ap.add_argument("--keep", type=Path, help="keep the folders here")
    a = ap.parse_args()
    root = a.keep or Path(tempfile.mkdtemp(prefix="bench_dock_"))
    root.mkdir(parents=True, exist_ok=True)
    robot = str(a.robot.resolve())
    subprocess.run([sys.executable, "-m", "arcube", "dock", "--robot", robot, "--trajectories", "reference", "--levels", "C3", "--out",
                    "warm", "--evaluations", "200", "--quiet"], cwd=root, capture_output=True)  # compile out of the timing  # fmt: skip
    wall, s = run(["dock", "--robot", robot, "--trajectories", "reference", "--out", "reference", "--quiet"], root)
    print(f"reference patient, 2 sides, --workers 1: {wall:.0f} s ({wall / 2:.1f} s a side), {s['met']} of {s['sides']} served")
    subprocess.run([sys.executable, "-m", "arcube", "patients", "--seed", "17", "--count", str(a.count), "--out", "cohort"], cwd=root,
                   capture_output=True, check=True)  # fmt: skip
    for workers in (1, 2):
        wall, s = run(["dock", "--robot", robot, "--cohort", "cohort/cohort.toml", "--out", f"cohort_w{workers}", "--workers", str(workers),
                       "--quiet"], root)  # fmt: skip
        print(f"{a.count} virtual patients, {s['sides']} sides, --workers {workers}: {wall:.0f} s ({wall / s['sides']:.1f} s a side), "
              f"{s['met']} of {s['sides']} served (coverage {100 * s['coverage']:.0f} %, {100 * s['coverage_low']:.0f}-"
              f"{100 * s['coverage_high']:.0f} %)")  # fmt: skip
    print(f"folders in {root}" if a.keep else "")


if __name__ == "__main__":
    main()
