"""Every seed of a finished ``arcube design`` folder, re-checked at every docking: a measurement, not a timing.

``arcube design`` re-checks the seeds in the order of their objective and stops at the first that meets every
requirement, so its summary says nothing of the others. This script re-checks each seed's robot as the job does
(:func:`arcube.design_job.dockings.assess_dockings`: the NumPy reference on every docking's plan lines and approach
lines, the z dyad closed with the robot's c_z; the drilling programs are not built) and prints, per seed: whether the
optimizer found it feasible, whether every sampled requirement holds at every docking, the worst docking's eta_G,
c_z, L and the seed's wall time; then per docking of each seed: clearance, self clearance, envelope clearance,
lateral error, holding torque (the smallest margin's docking first when a seed misses).

Rerun: ``.venv/bin/python benchmarks/measure_seeds.py DESIGN_FOLDER`` (for example the folder of the README's
``arcube design --trajectories reference --anatomy default --out robot --workers 2``).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from arcube.design_job.dockings import assess_dockings
from arcube.design_job.job import read_design, seed_dockings


def _v(rows: dict, name: str, digits: int) -> str:
    r = rows.get(name)
    return "-" if r is None or not math.isfinite(r["value"]) else f"{r['value']:.{digits}f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("folder", type=Path, help="a finished arcube design folder")
    args = ap.parse_args()
    _, reqs = read_design(args.folder)
    study = json.loads((args.folder / "study" / "summary.json").read_text())
    print(f"{'seed':>4} {'feasible':>8} {'met':>4} {'worst eta_G':>11} {'c_z':>6} {'L':>6} {'wall':>6}  missed")
    details = []
    for row in sorted(study["rows"], key=lambda r: r["seed"]):
        _, s, summary, dockings = seed_dockings(args.folder, int(row["seed"]))
        assess_dockings(dockings, reqs, s)
        met = bool(row["feasible"] and all(d.met for d in dockings))
        missed = sorted({f"{r['requirement']} at {d.label}" for d in dockings for r in d.rows if not r["passed"]})
        d0 = dockings[0].design
        eta = summary.get("eta_G")
        print(f"{row['seed']:>4} {'yes' if row['feasible'] else 'no':>8} {'yes' if met else 'no':>4} {'-' if eta is None else f'{eta:.4f}':>11} "
              f"{d0.c_z_mm:>6.1f} {d0['L']:>6.1f} {summary.get('wall_s', math.nan):>5.0f}s  {'; '.join(missed) or '-'}")  # fmt: skip
        details.append((row["seed"], dockings))
    print(f"\n{'seed':>4} {'docking':16} {'met':>4} {'clearance':>9} {'self':>6} {'envelope':>8} {'lateral':>7} {'holding':>7}")
    for seed, dockings in details:
        for d in dockings:
            rows = {r["requirement"]: r for r in d.rows}
            print(f"{seed:>4} {d.label:16} {'yes' if d.met else 'no':>4} {_v(rows, 'clearance', 1):>9} {_v(rows, 'self_clearance', 3):>6} "
                  f"{_v(rows, 'envelope_clearance', 2):>8} {_v(rows, 'lateral_error', 3):>7} {_v(rows, 'holding_torque', 1):>7}")  # fmt: skip
    print(f"Rerun: .venv/bin/python benchmarks/measure_seeds.py {args.folder}")


if __name__ == "__main__":
    main()
