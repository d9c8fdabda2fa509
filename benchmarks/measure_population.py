"""The population job of docs/guide/population.md, measured: one robot designed on a training cohort, judged on a held-out one.

Runs, as a user does (subprocesses, ``--workers 2``)::

    arcube patients --seed 7 --count TRAIN --out train
    arcube patients --seed 17 --count HELD --out held_out
    arcube design --cohort train/cohort.toml --validate held_out/cohort.toml --out population --workers 2

and prints what the README's coverage table holds: training sides served, held-out sides served with the 95 % Wilson
interval, ``search_verdict_agreement`` (met by the re-check at the search's placement / feasible in the search, over
every docking of every seed: the target is 1.0), each seed's training sides served, what binds where a side is not
served (by the normalized violation of model §16), and the wall time. ``--held 0`` skips the validation.

Rerun: ``.venv/bin/python benchmarks/measure_population.py [--train 10] [--held 40] [--seeds 1-3] [--keep DIR]``
(the defaults are the guide's: about an hour on a 2-core machine).
"""

from __future__ import annotations

import argparse
import collections
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def arcube(args: list[str], cwd: Path) -> int:
    out = subprocess.run([sys.executable, "-m", "arcube", *args], cwd=cwd, capture_output=True, text=True)
    if out.returncode not in (0, 3):
        raise SystemExit(f"arcube {' '.join(args)} failed ({out.returncode}):\n{out.stderr}")
    return out.returncode


def binds(dockings: list[dict]) -> str:
    count = collections.Counter(d.get("binding") or "?" for d in dockings if not d.get("meets_requirements"))
    return ", ".join(f"{name} {n}" for name, n in count.most_common()) or "-"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--train", type=int, default=10, help="training patients (arcube patients --seed 7)")
    ap.add_argument("--held", type=int, default=40, help="held-out patients (arcube patients --seed 17); 0: none")
    ap.add_argument("--seeds", default="1-3")
    ap.add_argument("--keep", type=Path, help="keep the folders here")
    a = ap.parse_args()
    root = a.keep or Path(tempfile.mkdtemp(prefix="measure_population_"))
    root.mkdir(parents=True, exist_ok=True)
    arcube(["patients", "--seed", "7", "--count", str(a.train), "--out", "train"], root)
    job = ["design", "--cohort", "train/cohort.toml", "--out", "population", "--workers", "2", "--seeds", a.seeds]
    if a.held:
        arcube(["patients", "--seed", "17", "--count", str(a.held), "--out", "held_out"], root)
        job += ["--validate", "held_out/cohort.toml"]
    t0 = time.perf_counter()
    code = arcube([*job, "--quiet"], root)
    wall = time.perf_counter() - t0
    s = json.loads((root / "population" / "summary.json").read_text())
    train = s["training"]
    agree = s.get("search_verdict_agreement")
    print(f"arcube {' '.join(job)}: exit {code}, {wall / 60:.1f} min")
    print(f"robot kept: seed {s['seed']}, c_z {s['robot']['c_z']:.0f} mm, L {s['robot']['L']:.0f} mm, mode {s['mode']}")
    print(f"search_verdict_agreement: {'-' if agree is None else f'{agree:.3f}'}; sides served per seed: {s.get('seeds_served')}")
    print(f"training: {train['met']} of {train['sides']} sides served ({100 * train['coverage']:.0f} %, "
          f"{100 * train['coverage_low']:.0f}-{100 * train['coverage_high']:.0f} %); binds: {binds(s['dockings'])}")  # fmt: skip
    if a.held:
        h = s["held_out"]
        held = json.loads((root / "population" / "validation" / "summary.json").read_text())
        print(f"held out: {h['met']} of {h['sides']} sides served ({100 * h['coverage']:.1f} %, 95 % Wilson "
              f"{100 * h['coverage_low']:.1f}-{100 * h['coverage_high']:.1f} %); binds: {binds(held['dockings'])}")  # fmt: skip
    print(f"folders in {root}" if a.keep else "")


if __name__ == "__main__":
    main()
