"""Time to one robot against the number of dockings (MODEL.md 19, issue 30).

``arcube design`` as a user runs it, in a subprocess, with its default requirements, envelope and budget
(3 seeds unless ``--seeds``), ``--workers 2``, on virtual patients from ``arcube patients --seed 7 --count 5``
(both sides of each: two dockings a patient):

* 1 docking:   the first patient's right side (``--cohort`` of that patient, ``--side R``);
* 2 dockings:  the first patient, both sides;
* 4 dockings:  the first two patients;
* 10 dockings: all five (the cohort of issue 30).

and, with ``--reference``, the bundled reference patient's two sides (``--trajectories reference
--anatomy default``: the README's command). For each it prints the wall time of the whole job (the optimizer,
the NumPy re-check, the reports, the accuracy budgets, the programs), the optimizer's evaluations (a row is one
robot at every docking), whether one robot met every requirement at every docking, the worst docking's eta_G,
and what binds when one did not. The numbers to compare are the ratios of one run: the machine is shared.

Rerun: ``.venv/bin/python benchmarks/bench_dockings.py [--counts 1,2,4,10] [--reference] [--seeds 1-3]
[--generations N] [--keep DIR]`` (about an hour with the defaults on a 2-core machine; ``--generations 40``
for a quick look at how the cost grows, with a budget too small to meet the requirements).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

from arcube.patients.cohort import cohort_toml


def cohort(src: Path, count: int) -> Path:
    """A cohort file in ``src`` (beside the patients' files) with the first ``count`` patients of ``src/cohort.toml``."""
    patients = tomllib.loads(src.joinpath("cohort.toml").read_text())["patient"]
    path = src / f"cohort_{count}.toml"
    path.write_text(cohort_toml(patients[:count]))
    return path


def run(args: list[str], out: Path) -> dict:
    """``arcube design ARGS --out OUT`` timed; the figures of its summary.json."""
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "arcube", "design", *args, "--out", str(out)], check=False, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if proc.returncode not in (0, 3):
        raise SystemExit(f"arcube design {' '.join(args)} failed ({proc.returncode}): {proc.stderr.strip()}")
    s = json.loads((out / "summary.json").read_text())
    binds = "; ".join(f"{r['requirement']} at {r.get('docking', '-')} by {-r['margin']:.3g}" for r in s["requirements"] if not r["passed"]) or "-"
    return {"wall_s": wall, "evaluations": s["evaluations"], "met": s["meets_requirements"], "eta_G": s["eta_G"],
            "dockings": len(s.get("dockings", [])) or 1, "binds": binds}  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--counts", default="1,2,4,10", help="numbers of dockings: 1, 2, 4, 10 (2 a patient beyond 1)")
    ap.add_argument("--reference", action="store_true", help="also the reference patient's two sides")
    ap.add_argument("--seeds", default="1-3")
    ap.add_argument("--workers", default="2")
    ap.add_argument("--generations", default=None, help="the optimizer's generations (default: arcube design's)")
    ap.add_argument("--keep", type=Path, default=None, help="keep the design folders here (new or empty)")
    args = ap.parse_args()
    counts = [int(c) for c in args.counts.split(",")]
    if any(c not in (1, 2, 4, 6, 8, 10) for c in counts):
        raise SystemExit("--counts: 1 or an even number up to 10 (two dockings a patient)")
    root = args.keep or Path(tempfile.mkdtemp(prefix="bench_dockings_"))
    root.mkdir(parents=True, exist_ok=True)
    subprocess.run([sys.executable, "-m", "arcube", "patients", "--out", str(root / "vp"), "--seed", "7", "--count", "5"],
                   check=True, capture_output=True)  # fmt: skip
    common = ["--seeds", args.seeds, "--workers", args.workers, "--quiet"]
    if args.generations:
        common += ["--generations", args.generations]
    jobs = []
    if args.reference:
        jobs.append(("reference, both sides", ["--trajectories", "reference", "--anatomy", "default", *common], root / "reference"))
    for n in counts:
        file = cohort(root / "vp", max(1, n // 2))
        side = ["--side", "R"] if n == 1 else []
        jobs.append((f"{max(1, n // 2)} virtual patient(s)", ["--cohort", str(file), *side, *common], root / f"dockings_{n}"))
    print(f"arcube design, seeds {args.seeds}, --workers {args.workers}, folders in {root}")
    print(f"{'job':24} {'dockings':>8} {'wall':>9} {'evaluations':>11} {'s/1k rows':>9} {'met':>4} {'eta_G':>7}  binds")
    for name, job_args, out in jobs:
        r = run(job_args, out)
        per = r["wall_s"] / r["evaluations"] * 1000
        eta = f"{r['eta_G']:.4f}" if r["eta_G"] is not None else "-"
        print(f"{name:24} {r['dockings']:>8} {r['wall_s']:>8.0f}s {r['evaluations']:>11,} {per:>9.2f} {'yes' if r['met'] else 'no':>4} "
              f"{eta:>7}  {r['binds']}", flush=True)  # fmt: skip
    print("Rerun: .venv/bin/python benchmarks/bench_dockings.py " + " ".join(sys.argv[1:]))


if __name__ == "__main__":
    main()
