"""The README's breach table (MODEL.md 22, issue 'Breach probability'): P(breach) per level of the reference patient.

The robot: tests/data/one_robot.json (the one robot ``arcube design --trajectories reference --anatomy default`` finds,
the demo's), each side drilled from its docking. Three robots, each with a registration of 0.25, 0.5 and 1.0 mm
(and as many degrees), 30 N thrust, 10,000 samples (seed 1):

* built to ISO 2768 class m, not calibrated;
* built to class f, not calibrated;
* calibrated: a robot built to class m (``arcube calibrate simulate``, seed 1) measured at 40 poses chosen at each
  docking (``calibrate poses``, tracker noise 0.15 mm / 0.1 deg), identified (``calibrate identify``); its errors drawn
  from the identification's covariance.

For each: the largest P(breach) per level (over its two sides), and the largest over the plan. Then which of these meet
P(breach) <= 1 % at every screw, and, for the calibrated robot, the registration it takes (0.2 mm / deg down to
0.05): the largest P(breach) of the calibrated robot and of its registration alone (a perfect robot, no deflection).

Rerun: ``.venv/bin/python benchmarks/measure_breach.py [--samples 10000] [--keep DIR]`` (about 2 min on 2 cores).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import arcube
import arcube.calibrate as cal
from arcube.accuracy import ToleranceSettings
from arcube.calibrate import IdentifySettings, PoseSettings, SimulateSettings
from arcube.pedicles.run import robot_dockings

ROBOT = Path(__file__).resolve().parents[1] / "tests" / "data" / "one_robot.json"
LEVELS = ("C3", "C4", "C5", "C6", "C7")
REGISTRATIONS = (0.25, 0.5, 1.0)


def calibrations(root: Path) -> dict[str, Path]:
    """Side -> the folder of ``calibrate identify`` for a class-m robot measured at 40 poses at that docking."""
    out = {}
    for side, design in robot_dockings(ROBOT).items():
        file = root / f"design_{side}.json"
        design.to_json(file)
        plan = arcube.select(arcube.load_trajectories("reference"), side=side)
        cal.poses(str(file), plan, design.mode, PoseSettings(count=40), out=root / f"poses_{side}.csv")
        cal.simulate(str(file), root / f"poses_{side}.csv", SimulateSettings(tolerance_class="m", seed=1), out=root / f"measured_{side}.csv")
        cal.identify(str(file), root / f"measured_{side}.csv", design.mode, IdentifySettings(), trajectories=plan, out=root / f"calibrated_{side}")
        out[side] = root / f"calibrated_{side}"
    return out


def per_level(rows: list[dict]) -> dict[str, float]:
    return {lv: max(r["p_breach"] for r in rows if r["level"] == lv) for lv in LEVELS}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--samples", type=int, default=10_000)
    ap.add_argument("--keep", type=Path)
    a = ap.parse_args()
    root = a.keep or Path(tempfile.mkdtemp(prefix="measure_breach_"))
    root.mkdir(parents=True, exist_ok=True)
    cals = calibrations(root)
    print(f"| robot | registration (mm, deg) | {' | '.join(LEVELS)} | largest |")
    print("|---|---|" + "---|" * (len(LEVELS) + 1))
    results = {}
    for name in ("class m", "class f", "calibrated (class m, 40 poses)"):
        for reg in REGISTRATIONS:
            kw = {"registration_mm": reg, "registration_deg": reg, "samples": a.samples, "seed": 1}
            if name.startswith("calibrated"):
                rows = []
                for side, folder in cals.items():
                    plan = arcube.select(arcube.load_trajectories("reference"), side=side)
                    rows += arcube.breach(None, plan, calibration=folder, **kw).rows()
            else:
                rows = arcube.breach(str(ROBOT), "reference", tolerances=ToleranceSettings(tolerance_class=name[-1]), **kw).rows()
            lv = per_level(rows)
            worst = max(r["p_breach"] for r in rows)
            results[(name, reg)] = worst
            print(f"| {name} | {reg:g} | " + " | ".join(f"{100 * lv[k]:.1f} %" for k in LEVELS) + f" | {100 * worst:.1f} % |")
    ok = [f"{n}, registration {r:g}" for (n, r), w in results.items() if w <= 0.01]
    print(f"\nevery screw at P(breach) <= 1 %: {', '.join(ok) if ok else 'none of these'}")
    print("\ncalibrated robot, finer registration: | registration (mm, deg) | largest P(breach) | registration alone |")
    for reg in (0.2, 0.15, 0.1, 0.05):
        kw = {"registration_mm": reg, "registration_deg": reg, "samples": a.samples, "seed": 1}
        rows = [r for side, folder in cals.items()
                for r in arcube.breach(None, arcube.select(arcube.load_trajectories("reference"), side=side), calibration=folder, **kw).rows()]
        worst, alone = max(r["p_breach"] for r in rows), max(r["p_registration_alone"] for r in rows)
        print(f"| {reg:g} | {100 * worst:.1f} % | {100 * alone:.1f} % |")
    print(f"folders in {root}" if a.keep else "")


if __name__ == "__main__":
    main()
