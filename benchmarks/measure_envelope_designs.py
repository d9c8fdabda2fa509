"""Where earlier designs stand against the envelope of the whole patient (MODEL.md 19.5): a measurement, not a timing.

The reference plan's right side (30 points per trajectory, and each trajectory's approach line from its standoff),
the default anatomy and the default envelope of the reference patient, the NumPy reference. For each design: its
smallest envelope clearance, the part and region that bind, how many points fall short of 10 mm, and the failures
with the guards of ``arcube design`` (clearance 5 mm, self clearance 2 mm) and ``--envelope-clearance 10``.

* ``README R (seed 3)``: the design README.md's "A robot that can be built" chose for the right side (eta_G 1.2498),
  rerun with ``arcube design --trajectories reference --side R --anatomy default --seeds 3`` at commit 1a70928
  (mode +,+,+,-; every requirement met, as the README says);
* ``tests/test_program.py``: the design the program tests use (found without anatomy);
* ``Table 2 at the README's right placement``: the paper's links at m = (88.23, 79.40, 56.89).

Rerun: ``.venv/bin/python benchmarks/measure_envelope_designs.py``.
"""

from __future__ import annotations

import numpy as np

from arcube.evaluation.anatomy import resolve_anatomy
from arcube.evaluation.envelope import resolve_envelope
from arcube.evaluation.reference import FAILURES, Options, evaluate_task
from arcube.evaluation.standoff import approach_lines
from arcube.evaluation.task import build_task
from arcube.io import load_trajectories, select
from arcube.model.body import PART_NAMES
from arcube.model.design import PARAM_NAMES, Design
from arcube.model.mechanism import parse_mode

README_R3 = [
    -62.352288342217264, 114.45330801197736, 211.97545042570994, 134.25358753200973, 49.43016140576414, 49.624621177558666,
    165.7942798692232, 151.30997659437793, 165.13459982098598, 191.2899676261894, 199.04065088373505, 125.95783609670778,
    198.439480698985, 196.8632545324037, 83.51368447425182, 69.37007602300147, 65.8888681065896, -68.76213314247053,
    232.24055925396573, 51.219013214355726, 86.22609928327356, 68.53513223798478, 89.99298230990331, 113.4409115977316,
    -119.75719506458475, -77.29133538130984, 199.72079679505893,
]  # fmt: skip
TEST_PROGRAM = [
    -180.76484476919862, -157.46908828300167, 200.6853946773747, 38.47157725834808, 37.58585578457374, 70.96024445457583,
    176.01413818196406, 167.62615240420683, 163.81424854234908, 199.83721867879663, 187.76627761622083, 90.91341698557332,
    167.91480388710127, 176.66383953444745, 101.49967571608708, 94.1648183036713, 69.62303755883808, -84.00550363847071,
    174.95584389467882, 69.35973817628876, 75.66975313644457, 66.76323145703799, 69.57808592269254, 132.26627118962273,
    -26.77890980359885, -93.65404350391357, 129.15885510671012,
]  # fmt: skip


def main() -> None:
    plan = load_trajectories("reference")
    anatomy = resolve_anatomy("default", "LPS", "reference")
    env = resolve_envelope("default", plan, anatomy)  # the landmarks of the whole plan, both sides
    right = select(plan, side="R")
    task = build_task(right.entry, right.target, 30)
    Ea, ea = approach_lines(right.entry, right.target, anatomy, 30)
    marks = env.landmarks
    print(f"envelope: {env.source}")
    print(f"landmarks: x0 {marks.x0:.1f}, y_top {marks.y_top:.1f}, y_bot {marks.y_bot:.1f}, z_s {marks.z_s:.1f} mm")
    table2 = Design.preset("paper").to_vector()
    table2[:3] = (88.23, 79.40, 56.89)
    designs = {
        "README R (seed 3)": (np.array(README_R3), "+,+,+,-"),
        "tests/test_program.py": (np.array(TEST_PROGRAM), "+,+,+,+"),
        "Table 2 at the README's right placement": (table2, "+,+,+,+"),
    }
    options = Options(clearance_mm=5.0, self_clearance_mm=2.0, envelope_clearance_mm=10.0)
    for name, (x, mode) in designs.items():
        assert len(x) == len(PARAM_NAMES)
        m = x[:3]
        print(f"\n{name}: base m = ({m[0]:.1f}, {m[1]:.1f}, {m[2]:.1f}) mm: x - x0 = {m[0] - marks.x0:+.0f} mm (+: patient's right), "
              f"z - z_s = {m[2] - marks.z_s:+.0f} mm (+: posterior), y - y_top = {m[1] - marks.y_top:+.0f} mm (+: cranial)")  # fmt: skip
        for label, E, e in (("plan", task.E, task.e), ("approach lines", Ea, ea)):
            r = evaluate_task(x, E, e, parse_mode(mode), options, anatomy=anatomy.distance, envelope=env)
            p = r.points
            i = int(np.nanargmin(p.envelope_clearance_mm))
            fails = {FAILURES[c - 1]: int(np.sum(p.failure == c)) for c in np.unique(p.failure) if c}
            print(f"  {label:15s} envelope clearance min {p.envelope_clearance_mm[i]:7.1f} mm ({PART_NAMES[p.envelope_part[i]]} vs "
                  f"{env.names[p.envelope_region[i]]}); below 10 mm at {int(np.sum(p.envelope_clearance_mm < 10.0))}/{len(E)} points; "
                  f"anatomy clearance min {np.nanmin(p.clearance_mm):.1f} mm; failures {fails or 'none'}")  # fmt: skip
    print("\nrerun: .venv/bin/python benchmarks/measure_envelope_designs.py")


if __name__ == "__main__":
    main()
