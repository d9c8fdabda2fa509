"""What the search's second judgement costs: ``arcube dock`` with and without the sweep of model §17.2's lines.

A candidate placement (or robot) that passes at its points is judged again on each drilling line, standoff to target,
every 0.5 mm (:func:`arcube.optimization.build.sweep_tasks`), so that the search calls feasible only what the
drilling program's check accepts. This prints, for ``arcube dock`` of the robot of ``--robot`` on the reference
patient's two sides (one worker, the command's defaults), the wall time and the sides served with the sweep (as
shipped) and without it (the fitness model's ``fine_tasks`` emptied, the search as before), and their ratio. Without
the sweep a side the search calls feasible can still be refused by its program: the "served" column says whether
the re-check then found another placement.

Rerun: ``.venv/bin/python benchmarks/bench_sweep.py [--robot design.json]`` (a few minutes).
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
NO_SWEEP = (
    "import dataclasses, sys\n"
    "import arcube.optimization.build as b\n"
    "plain = b.build_model\n"
    "b.build_model = lambda *a, **k: dataclasses.replace(plain(*a, **k), fine_tasks=())\n"
    "from arcube.cli import main\n"
    "sys.argv = ['arcube', *sys.argv[1:]]\n"
    "main()\n"
)


def dock(robot: Path, out: Path, sweep: bool) -> tuple[float, dict]:
    args = ["dock", "--robot", str(robot), "--trajectories", "reference", "--out", str(out), "--quiet"]
    cmd = [sys.executable, "-m", "arcube", *args] if sweep else [sys.executable, "-c", NO_SWEEP, *args]
    t0 = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if done.returncode not in (0, 3):
        raise SystemExit(f"{' '.join(cmd[:3])} ... failed ({done.returncode}):\n{done.stderr}")
    return wall, json.loads((out / "summary.json").read_text())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--robot", type=Path, default=ROBOT)
    a = ap.parse_args()
    root = Path(tempfile.mkdtemp(prefix="bench_sweep_"))
    dock(a.robot.resolve(), root / "warm", True)  # the kernel compiled out of the timing
    rows = []
    for sweep in (True, False):
        wall, s = dock(a.robot.resolve(), root / f"sweep_{sweep}", sweep)
        rows.append(wall)
        checked = [d.get("placements_checked") for d in s["dockings"]]
        print(f"sweep {'on ' if sweep else 'off'}: {wall:.0f} s for {s['sides']} sides ({wall / s['sides']:.1f} s a side), "
              f"{s['met']} served, placements re-checked per side {checked}")  # fmt: skip
    print(f"the sweep costs x{rows[0] / rows[1]:.2f} the wall time of a dock without it (one run, same machine)")


if __name__ == "__main__":
    main()
