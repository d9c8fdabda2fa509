"""The README's breach table (MODEL.md 22, issue 'Breach probability'): P(breach) per level of the reference patient.

The robot: tests/data/one_robot.json (the one robot ``arcube design --trajectories reference --anatomy default`` finds,
the demo's), each side drilled from its docking. Three robots, each with a registration of 0.25, 0.5 and 1.0 mm
(and as many degrees), 30 N thrust, 10,000 samples (seed 1):

* built to ISO 2768 class m, not calibrated;
* built to class f, not calibrated;
* calibrated: a robot built to class m (``arcube calibrate simulate``, seed 1) measured at 40 poses chosen at each
  docking (``calibrate poses``, tracker noise 0.15 mm / 0.1 deg), identified (``calibrate identify``); its errors drawn
  from the identification's covariance.

For each: the largest P(breach) per level (over its two sides), and the largest over the plan, and per level the
registration needed for P(breach) <= 1 % at its worst screw (``--target 0.01``, first order: what_it_takes.csv). Then
which of these meet P(breach) <= 1 % at every screw, and, for the calibrated robot, the registration it takes (0.2 mm /
deg down to 0.05): the largest P(breach) of the calibrated robot and of its registration alone (a perfect robot, no
deflection). Last, the first-order P(breach) beside the Monte Carlo's, screw by screw (class m and calibrated, three
registrations), and the first order's time per screw (docs/guide/breach.md).

Rerun: ``.venv/bin/python benchmarks/measure_breach.py [--samples 10000] [--keep DIR]`` (about 3 min on 2 cores).
"""

from __future__ import annotations

import argparse
import math
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
    """Level -> the largest P(breach) over its reached screws (a screw not reached has none)."""
    return {lv: max((r["p_breach"] for r in rows if r["level"] == lv and r["reached"]), default=math.nan) for lv in LEVELS}


def not_reached(rows: list[dict]) -> str:
    return ", ".join(f"{r['trajectory']} ({r['level']} {r['side']})" for r in rows if not r["reached"])


def needed(takes: list[dict]) -> dict[str, float | None]:
    """Level -> the registration needed for the target at its worst screw (the smallest over the sides' results)."""
    out: dict[str, float | None] = {}
    for t in takes:
        if t["level"] in LEVELS:
            old, new = out.get(t["level"], math.inf), t["registration_needed"]
            out[t["level"]] = None if new is None or old is None else min(old, new)
    return out


def shown(r: float | None) -> str:
    return "none" if r is None else f"{r:.2f}"


def run(name: str, reg: float, cals: dict[str, Path], samples: int) -> tuple[list[dict], list[dict]]:
    """(rows, what it takes) of one robot and registration, both sides."""
    kw = {"registration_mm": reg, "registration_deg": reg, "samples": samples, "seed": 1, "target": 0.01}
    if name.startswith("calibrated"):
        rows, takes = [], []
        for side, folder in cals.items():
            plan = arcube.select(arcube.load_trajectories("reference"), side=side)
            r = arcube.breach(None, plan, calibration=folder, **kw)
            rows += r.rows()
            takes += r.summary()["what_it_takes"]
        return rows, takes
    r = arcube.breach(str(ROBOT), "reference", tolerances=ToleranceSettings(tolerance_class=name[-1]), **kw)
    return r.rows(), r.summary()["what_it_takes"]


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
    results, screws = {}, {}
    for name in ("class m", "class f", "calibrated (class m, 40 poses)"):
        for reg in REGISTRATIONS:
            rows, takes = run(name, reg, cals, a.samples)
            screws[(name, reg)] = rows
            lv = per_level(rows)
            worst = max(r["p_breach"] for r in rows if r["reached"])
            results[(name, reg)] = worst
            missed = f" (not reached: {not_reached(rows)})" if not_reached(rows) else ""
            print(f"| {name} | {reg:g} | " + " | ".join(f"{100 * lv[k]:.1f} %" for k in LEVELS) + f" | {100 * worst:.1f} % |{missed}")
        need = needed(takes)  # the registration needed does not depend on the registration given
        print(f"| {name} | needed for 1 % | " + " | ".join(shown(need[k]) for k in LEVELS) + " | |")
    ok = [f"{n}, registration {r:g}" for (n, r), w in results.items() if w <= 0.01]
    print(f"\nevery reached screw at P(breach) <= 1 %: {', '.join(ok) if ok else 'none of these'}")
    print("\ncalibrated robot, finer registration: | registration (mm, deg) | largest P(breach) | registration alone |")
    for reg in (0.2, 0.15, 0.1, 0.05):
        kw = {"registration_mm": reg, "registration_deg": reg, "samples": a.samples, "seed": 1}
        rows = [r for side, folder in cals.items()
                for r in arcube.breach(None, arcube.select(arcube.load_trajectories("reference"), side=side), calibration=folder, **kw).rows()]
        worst = max(r["p_breach"] for r in rows if r["reached"])
        alone = max(r["p_registration_alone"] for r in rows if r["reached"])
        print(f"| {reg:g} | {100 * worst:.1f} % | {100 * alone:.1f} % |")
    for name in ("class m", "calibrated (class m, 40 poses)"):
        print(f"\n{name}: P(breach) per screw, Monte Carlo [95 % interval] / first order")
        print("| screw | " + " | ".join(f"{reg:g} mm, deg" for reg in REGISTRATIONS) + " |")
        print("|---|" + "---|" * len(REGISTRATIONS))
        by_id = {reg: {r["trajectory"]: r for r in screws[(name, reg)]} for reg in REGISTRATIONS}
        for tid in sorted(by_id[REGISTRATIONS[0]], key=int):
            cells = []
            for reg in REGISTRATIONS:
                r = by_id[reg][tid]
                inside = r["p_breach_low"] <= r["p_first_order"] <= r["p_breach_high"]
                cells.append(
                    f"{100 * r['p_breach']:.1f} [{100 * r['p_breach_low']:.1f}-{100 * r['p_breach_high']:.1f}] / "
                    f"{100 * r['p_first_order']:.1f}{'' if inside else ' *'}"
                )
            print(f"| {tid} ({by_id[REGISTRATIONS[0]][tid]['level']} {by_id[REGISTRATIONS[0]][tid]['side']}) | " + " | ".join(cells) + " |")
        print("(* the first order outside the Monte Carlo's interval)")
    print(f"\nfirst order, time per screw: {first_order_time():.2f} ms (moments and P, class m, 10 screws, best of 5)")
    print(f"folders in {root}" if a.keep else "")


def first_order_time() -> float:
    """The first order's time per screw (ms): the moments (derivatives at the isthmus, registration, deflection) and P."""
    import time

    from arcube.coerce import mode_signs
    from arcube.pedicles.first_order import breach_first_order, moments
    from arcube.pedicles.geometry import pedicles
    from arcube.pedicles.sources import RobotModel

    best = math.inf
    for side, d in robot_dockings(ROBOT).items():
        plan = arcube.select(arcube.load_trajectories("reference"), side=side)
        x, tol = d.to_vector(), ToleranceSettings()
        model = RobotModel(x, mode_signs(d.mode), tol.tolerances(x), tol.distribution)
        p = pedicles(plan, 3.5)
        for _ in range(5):
            t = time.perf_counter()
            breach_first_order(moments(model, p, (side,) * len(p.ids), 30.0, 1e4), p, 0.5, 0.5)
            best = min(best, 1000 * (time.perf_counter() - t) / len(p.ids))
    return best


if __name__ == "__main__":
    main()
