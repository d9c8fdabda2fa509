"""End-to-end checks moved out of the test suite for its time on CI (each property they hold is also held, at a
smaller size or in another form, by a test the suite runs; the test names where). Each runs the commands as a user
would, in a subprocess, and prints its wall time and PASS or FAIL with what differed; the script exits 1 when a
check fails.

* ``design-resume``: ``arcube design`` on one trajectory (id 5, right side), one seed, 56 x 60 evaluations,
  killed (SIGKILL) at its checkpoint after 20 generations and resumed with ``arcube resume``, against the same
  job run without interruption: the same exit code, design.json byte for byte, and the same verdicts, mode, seed,
  eta_G and requirement table. The suite holds the same with two seeds and two dockings, the job's patient given
  as a cohort file (tests/test_one_robot_design.py, test_a_killed_cohort_job_resumes_to_the_same_robot).
* ``design-resume-cohort``: that test at the budget of the file's fixture (both sides at C3, 8 points a line, 40
  generations of the default population, seeds 1 and 2: a robot that meets every requirement at one docking at
  least, its program built): the job with its patient given as a cohort file, killed after 10 generations of seed 1
  and resumed, against the uninterrupted ``--trajectories`` job: the same exit code, design.json and every docking's
  design file byte for byte, and the same verdicts (the program rows' build times aside). The test holds it with a
  smaller search, every docking judged and written after the resumed study by the same code.
* ``patients-200``: ``arcube patients --seed 1 --count 200``: the cohort file lists 200 patients and every anatomy
  and envelope passes the strict mesh reader with a positive volume (seeds 2 and 25 once came out inside out). The
  suite holds the same for the first 50 (tests/test_patients.py,
  test_every_patient_of_a_cohort_reads_back_through_the_strict_readers).

Rerun: ``.venv/bin/python benchmarks/slow_checks.py [NAME ...] [--keep DIR]`` (every check without a NAME).
"""

from __future__ import annotations

import argparse
import json
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path


def arcube(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "arcube", *args], capture_output=True, text=True, cwd=cwd, timeout=900)


def design_resume(root: Path) -> list[str]:
    """The problems found (none: the check passed)."""
    flags = ["--trajectories", "reference", "--ids", "5", "--anatomy", "default", "--points", "4", "--population", "56",
             "--generations", "60", "--seeds", "1", "--quiet"]  # fmt: skip
    whole = arcube("design", *flags, "--out", "whole", cwd=root)
    if whole.returncode not in (0, 3):
        return [f"the uninterrupted job exited {whole.returncode}: {whole.stderr.strip()[-2000:]}"]
    proc = subprocess.Popen([sys.executable, "-m", "arcube", "design", *flags, "--out", "cut"], cwd=root,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)  # fmt: skip
    mark, deadline = root / "cut" / "study" / "seed_1" / "checkpoint" / "evals_000020.npz", time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None and not mark.exists():
        time.sleep(0.005)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)
    if proc.returncode != -signal.SIGKILL or (root / "cut" / "summary.json").exists():
        return [f"the job was not killed half-way (exit {proc.returncode}, summary.json written)"]
    res = arcube("resume", "cut", "--quiet", cwd=root)
    problems = []
    if res.returncode != whole.returncode:
        problems.append(
            f"resume exited {res.returncode}, the uninterrupted job {whole.returncode}: {res.stderr.strip()}"
        )
    if (root / "cut" / "design.json").read_text() != (root / "whole" / "design.json").read_text():
        problems.append("design.json differs from the uninterrupted job's")
    a, b = (json.loads((root / d / "summary.json").read_text()) for d in ("cut", "whole"))
    for k in ("meets_requirements", "mode", "seed", "eta_G", "requirements"):
        if a[k] != b[k]:
            problems.append(f"summary.json's {k} differs: {a[k]!r} after resume, {b[k]!r} uninterrupted")
    return problems


def _untimed(value: object) -> object:
    """``value`` with the wall time a program row reports ("total 38.7 s, built in 2 s") cut to its program's own."""
    if isinstance(value, dict):
        return {k: _untimed(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_untimed(v) for v in value]
    return value.split(", built in")[0] if isinstance(value, str) else value


def design_resume_cohort(root: Path) -> list[str]:
    budget = ["--levels", "C3", "--points", "8", "--generations", "40", "--seeds", "1,2", "--quiet"]
    whole = arcube("design", "--trajectories", "reference", "--anatomy", "default", *budget, "--out", "whole", cwd=root)
    if whole.returncode not in (0, 3):
        return [f"the uninterrupted job exited {whole.returncode}: {whole.stderr.strip()[-2000:]}"]
    met = [
        d["label"]
        for d in json.loads((root / "whole" / "summary.json").read_text())["dockings"]
        if d["meets_requirements"]
    ]
    print(
        f"  the uninterrupted job: exit {whole.returncode}, every requirement met at {', '.join(met) or 'no docking'}"
    )
    problems: list[str] = []
    (root / "cohort.toml").write_text('[[patient]]\nname = "reference"\nplan = "reference"\nanatomy = "default"\n')
    proc = subprocess.Popen([sys.executable, "-m", "arcube", "design", "--cohort", "cohort.toml", *budget, "--out", "cut"],
                            cwd=root, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)  # fmt: skip
    mark, deadline = root / "cut" / "study" / "seed_1" / "checkpoint" / "evals_000010.npz", time.monotonic() + 600
    while time.monotonic() < deadline and proc.poll() is None and not mark.exists():
        time.sleep(0.005)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)
    if proc.returncode != -signal.SIGKILL or not mark.exists() or (root / "cut" / "summary.json").exists():
        return [f"the job was not killed after 10 generations (exit {proc.returncode})"]
    res = arcube("resume", "cut", "--quiet", cwd=root)
    if res.returncode != whole.returncode:
        problems.append(
            f"resume exited {res.returncode}, the uninterrupted job {whole.returncode}: {res.stderr.strip()}"
        )
    for file in ("design.json", "dockings/reference_R/design.json", "dockings/reference_L/design.json"):
        if (root / "cut" / file).read_text() != (root / "whole" / file).read_text():
            problems.append(f"{file} differs from the uninterrupted job's")
    a, b = (json.loads((root / d / "summary.json").read_text()) for d in ("cut", "whole"))
    for k in ("meets_requirements", "mode", "seed", "eta_G", "requirements", "dockings", "missed_at"):
        if _untimed(a[k]) != _untimed(b[k]):
            problems.append(f"summary.json's {k} differs after resume")
    return problems


def patients_200(root: Path) -> list[str]:
    from arcube.design_job.cohort import read_cohort
    from arcube.io.meshes import read_mesh

    out = arcube("patients", "--seed", "1", "--count", "200", "--out", "cohort", cwd=root)
    if out.returncode != 0:
        return [f"arcube patients exited {out.returncode}: {out.stderr.strip()[-2000:]}"]
    problems = []
    if len(read_cohort(root / "cohort" / "cohort.toml")) != 200:
        problems.append("cohort.toml does not list 200 patients")
    for k in range(200):
        stem = root / "cohort" / f"patient_{k:03d}"
        for path in (stem.with_suffix(".anatomy.stl"), stem.with_suffix(".envelope.stl")):
            try:
                volume = read_mesh(path, "patient").volume
            except Exception as exc:  # the reader's refusal is the finding
                problems.append(f"{path.name}: {exc}")
                continue
            if not volume > 0:
                problems.append(f"{path.name}: volume {volume}")
    return problems


CHECKS: dict[str, Callable[[Path], list[str]]] = {
    "design-resume": design_resume,
    "design-resume-cohort": design_resume_cohort,
    "patients-200": patients_200,
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("names", nargs="*", help=f"checks to run: {', '.join(CHECKS)} (default: all)")
    ap.add_argument("--keep", type=Path, help="keep each check's folder here")
    a = ap.parse_args()
    unknown = [n for n in a.names if n not in CHECKS]
    if unknown:
        ap.error(f"unknown check(s) {', '.join(unknown)}; known: {', '.join(CHECKS)}")
    failed = []
    for name in a.names or list(CHECKS):
        root = (a.keep / name) if a.keep else Path(tempfile.mkdtemp(prefix=f"slow_checks_{name}_"))
        root.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        try:
            problems = CHECKS[name](root)
        finally:
            if not a.keep:
                shutil.rmtree(root, ignore_errors=True)
        print(f"{name}: {'PASS' if not problems else 'FAIL'} in {time.perf_counter() - t0:.0f} s", flush=True)
        for p in problems:
            print(f"  {p}", flush=True)
        failed += [name] * bool(problems)
    print(f"{len(failed)} failed: {', '.join(failed)}" if failed else "every check passed")
    print("rerun: .venv/bin/python benchmarks/slow_checks.py [NAME ...] [--keep DIR]")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
