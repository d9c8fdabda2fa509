"""Cost of the drilling program (MODEL.md 17): planning time and validity checks per second.

* ``plan``: the whole program of the reference plan's right side (5 trajectories, order shortest,
  no anatomy), with the design of tests/test_program.py (every transit is the straight move);
* ``wall``: two trajectories (C3, C4) with a wall between their standoffs (the test's), so the
  transit is blocked and OMPL RRTConnect plans around it: the whole program, and the planner alone;
* ``torques``: what the actuator torques along the rows (MODEL.md 18.2) and the motor figures add
  to ``plan`` (the same program with ``masses=False``);
* ``checks``: states per second of the continuous check (:class:`arcube.motion.check.Checker`,
  the NumPy reference and the compiled kernel's ``engine="numba"``) with the default anatomy of the reference patient: the fine check of 17.2
  (axes sampled every 0.25 mm) and the planner's (every 2 mm), one state per call (what OMPL's state
  validity checker asks) and 200 per call (an edge or a line).

Rerun: ``.venv/bin/python benchmarks/bench_program.py`` (``--repeats N``: best of N runs).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from designs import program_design as _design, right_plan as _plan  # noqa: E402  (the tests' design and plan)
from test_program import _standoffs, _wall  # noqa: E402  (the test's standoffs and wall)

from arcube.evaluation.anatomy import load_anatomy  # noqa: E402
from arcube.motion import ProgramLimits, program  # noqa: E402
from arcube.motion.check import Checker  # noqa: E402


def best_time(fn, repeats: int) -> tuple[float, object]:
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    design = _design()

    t, prog = best_time(lambda: program(design, _plan("1,3,5,7,9"), None), args.repeats)
    s = prog.summary
    print(f"plan  (right side, 5 trajectories, no anatomy): {t:.2f} s; order {' '.join(s['order'])}, program {s['total_s']:.1f} s, "
          f"{s['rows']} rows, {s['checked_states']} states checked")  # fmt: skip
    t_plain, _ = best_time(lambda: program(design, _plan("1,3,5,7,9"), None, masses=False), args.repeats)
    print(f"torques (MODEL.md 18.2 along the {s['rows']} rows, motor figures): {t - t_plain:.2f} s of the {t:.2f} s "
          f"({(t - t_plain) / s['rows'] * 1e6:.0f} us per row; the program without masses {t_plain:.2f} s)")

    ts = _plan("1,3")
    S, _ = _standoffs(ts)
    anatomy, _ = _wall((S[0] + S[1]) / 2, (6.0, 1.5, 6.0))
    anatomy.distance  # the grids once, outside the timing
    t, prog = best_time(lambda: program(design, ts, None, anatomy=anatomy, order="given", seed=1), args.repeats)
    tr = prog.summary["transits"][0]
    print(f"wall  (C3 -> C4 blocked, planned around): {t:.2f} s for the program, of which OMPL {tr['planner_s']:.2f} s; "
          f"{tr['method']}, {tr['waypoints']} waypoints, transit {tr['duration_s']:.2f} s")  # fmt: skip

    plan = _plan("1,3,5,7,9")
    anat = load_anatomy("default", plan="reference")
    line = np.linspace(0.0, 1.0, 200)[:, None]
    E = plan.target[0] + line * (plan.entry[0] + 20 * (plan.entry[0] - plan.target[0]) / np.linalg.norm(plan.entry[0] - plan.target[0]) - plan.target[0])
    e = (plan.entry[0] - plan.target[0]) / np.linalg.norm(plan.entry[0] - plan.target[0])
    for engine in ("numpy", "numba"):
        checker = Checker(design.to_vector(), np.ones(4), ProgramLimits(), distance=anat.distance, engine=engine)
        checker.assembly = checker.poses(E[:1], e).assembly[0]  # also compiles the kernel, outside the timing
        coarse = checker.coarse()
        for name, c in (("fine (17.2)", checker), ("planner (2 mm)", coarse)):
            t1, _ = best_time(lambda: [c.poses(E[i : i + 1], e, tool=True) for i in range(20)], args.repeats)
            tb, _ = best_time(lambda: c.poses(E, e, tool=True), args.repeats)
            print(f"checks, {engine}, {name}: {20 / t1:,.0f} states/s one per call, {len(E) / tb:,.0f} states/s 200 per call")
    print("rerun: .venv/bin/python benchmarks/bench_program.py [--repeats N]")


if __name__ == "__main__":
    main()
