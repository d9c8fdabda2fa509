"""arcube design with several dockings (MODEL.md 19, issue 30): one robot, a docking per side, the files it writes.

Oracles: the NumPy reference (``arcube evaluate --engine numpy`` on a docking's own design file, and
:func:`arcube.evaluate` on its approach lines) re-checks what the job reports per docking; the files agree with
each other (the robot's parameters are the same in every docking's file; each docking's placement is its
entry of ``design.json``; the top requirements.csv holds each requirement at the docking where it is tightest).
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

import arcube
from arcube.design_job.dockings import PLACEMENT, ROBOT_NAMES
from arcube.evaluation.anatomy import resolve_anatomy
from arcube.evaluation.envelope import resolve_envelope
from arcube.evaluation.standoff import standoff_points
from arcube.io import select
from arcube.model.design import PARAM_NAMES
from harness import CHROMIUM_SKIP, start_chromium
from harness import arcube as run_arcube

# Both sides of the reference patient at C3 (one trajectory a side), 8 points per line, 16,000 evaluations, seeds 1 and 2:
# about 50 s; the robot it finds meets every requirement at docking reference_R, its program built (reference_L misses
# some). (Seed 2's robot meets reference_R at the plan's points, but its program is blocked between them: not served.)
_BUDGET = ["--levels", "C3", "--points", "8", "--generations", "40", "--seeds", "1,2", "--quiet"]
"""Seeds 1 and 2: on a CPU without AVX-512 (an AMD EPYC) seed 1 alone finds no docking that meets everything (the
search takes another path in the last bits); seed 2 meets both there, seed 1 at least one on the machines before."""
_JOB = ["design", "--trajectories", "reference", "--anatomy", "default", *_BUDGET, "--out", "d"]
_ENTRY_KEYS = ["patient", "side", "m_x", "m_y", "m_z", "mount_rx", "mount_ry", "mount_rz"]


@pytest.fixture(scope="module")
def job(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("one_robot")
    out = run_arcube(*_JOB, cwd=root)
    assert out.returncode in (0, 3), out.stdout + out.stderr
    summary = json.loads((root / "d" / "summary.json").read_text())
    assert ("meets every requirement" in out.stdout) == (out.returncode == 0) == summary["meets_requirements"], (
        out.stdout
    )
    return root / "d"


def _csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_design_json_is_the_robot_and_its_dockings(job: Path) -> None:
    """design.json: the 22 robot parameters (c_z among them), the mode, and one entry per docking with exactly the
    issue's keys; each docking's file is the robot with that entry's placement, and every file names the mode."""
    robot = json.loads((job / "design.json").read_text())
    assert [(d["patient"], d["side"]) for d in robot["dockings"]] == [("reference", "R"), ("reference", "L")]
    assert all(
        list(d)[: len(_ENTRY_KEYS)] == _ENTRY_KEYS and set(d) - set(_ENTRY_KEYS) == {"entry", "target"}
        for d in robot["dockings"]
    )
    c3 = select(arcube.load_trajectories("reference"), levels="C3")
    for d in robot[
        "dockings"
    ]:  # each docking's trajectories, for arcube dock to carry its placement onto a new plan (MODEL.md 19.6)
        side = select(c3, side=d["side"])
        np.testing.assert_allclose(d["entry"], side.entry, atol=1e-4) and np.testing.assert_allclose(
            d["target"], side.target, atol=1e-4
        )
    assert set(robot) == {*ROBOT_NAMES, "mode", "dockings"} and len(ROBOT_NAMES) == 22
    assert 20.0 <= robot["c_z"] <= 500.0  # the default bounds of c_z (MODEL.md 19.1)
    for entry in robot["dockings"]:
        file = job / "dockings" / f"{entry['patient']}_{entry['side']}" / "design.json"
        d = arcube.Design.load(file)
        values = d.to_dict()
        assert {n: values[n] for n in PLACEMENT} == {n: entry[n] for n in PLACEMENT}
        assert {n: values[n] for n in PARAM_NAMES if n not in PLACEMENT} == {
            n: robot[n] for n in ROBOT_NAMES if n != "c_z"
        }
        assert d.c_z == robot["c_z"] and d.mode == robot["mode"]
        raw = json.loads(file.read_text())
        assert (raw["patient"], raw["side"]) == (entry["patient"], entry["side"])  # whose docking, which side
    with pytest.raises(arcube.InputError, match=r"one robot at 2 dockings.*dockings/<patient>_<side>/design.json"):
        arcube.Design.load(job / "design.json")  # no placement of its own: the message says which file to give


def test_requirements_name_the_docking_where_each_is_tightest(job: Path) -> None:
    """requirements.csv has a docking column; per requirement, its row is the docking's (in that docking's own table)
    with the smallest margin, a failing one first (MODEL.md 19.4)."""
    top = _csv(job / "requirements.csv")
    per = {
        label: {r["requirement"]: r for r in _csv(job / "dockings" / label / "requirements.csv")}
        for label in ("reference_R", "reference_L")
    }
    assert top and all(r["docking"] in per for r in top)
    for r in top:
        mine = per[r["docking"]][r["requirement"]]
        assert mine["value"] == r["value"] and mine["passed"] == r["passed"]
        for other in per.values():
            o = other.get(r["requirement"])
            if o is None:
                assert r["requirement"] == "program"  # a docking missed at the plan's points gets no program
                continue
            if r["passed"] == "pass":
                assert o["passed"] == "pass" and float(o["margin"]) >= float(r["margin"])


def test_a_docking_the_job_reports_as_met_is_met_by_the_numpy_reference(job: Path, tmp_path: Path) -> None:
    """The docking the job reports as met: its design file, re-checked by the NumPy reference on its plan's lines
    (``arcube evaluate --design``, the mode read from the file) and on its approach lines, meets clearance, self
    clearance, the envelope clearance, accuracy and torque at every point, the z dyad closed with its c_z. Every
    docking: the clearances the job reports are the reference's on the plan's lines (or smaller, on the approach lines)."""
    summary = json.loads((job / "summary.json").read_text())
    met = [d for d in summary["dockings"] if d["meets_requirements"]]
    assert met, "the fixture's robot meets every requirement at one docking at least"
    whole = arcube.load_trajectories("reference")
    c3 = select(whole, levels="C3")
    anatomy = resolve_anatomy("default", "LPS", "reference")
    envelope = resolve_envelope(["default"], whole, anatomy)  # placed on the whole plan as loaded, as the job's
    for d in summary["dockings"]:
        file = job / "dockings" / d["label"] / "design.json"
        ev = run_arcube(
            "evaluate",
            "--design",
            str(file),
            "--trajectories",
            "reference",
            "--side",
            d["side"],
            "--levels",
            "C3",
            "--anatomy",
            "default",
            "--engine",
            "numpy",
            "--json",
            "--points",
            "8",
            "--envelope",
            "none",
            cwd=tmp_path,
        )
        assert ev.returncode == 0, ev.stderr
        doc = json.loads(ev.stdout)
        plan = doc["summary"]
        assert (
            doc["mode"] == summary["mode"] and doc["guards"]["c_z"] == json.loads(file.read_text())["c_z"]
        )  # read from the file
        rows = {r["requirement"]: r for r in _csv(job / "dockings" / d["label"] / "requirements.csv")}
        for name in ("clearance", "self_clearance"):
            got, ref = float(rows[name]["value"]), plan[f"{name}_min_mm"]
            if rows[name]["segment"] == "drill":
                assert got == pytest.approx(ref, rel=1e-9, abs=1e-9), name
            else:
                assert got <= ref + 1e-9, name
        if not d["meets_requirements"]:
            continue
        design = arcube.Design.load(file)
        side = select(c3, side=d["side"])
        S, _ = standoff_points(side.entry, side.target, anatomy, 20.0)
        for what, entry, target in (("plan", side.entry, side.target), ("approach", S, side.entry)):
            lines = dataclasses.replace(side, entry=np.asarray(entry), target=np.asarray(target), source="approach")
            res = arcube.evaluate(
                design,
                lines,
                points=8,
                guarded=True,
                engine="numpy",
                anatomy=anatomy,
                envelope=envelope,
                clearance=5.0,
                self_clearance=2.0,
                envelope_clearance_mm=10.0,
                z_dyad=True,
                c_z=design.c_z,
            )
            s = res.summary
            assert s["reachable_fraction"] == 1.0 and s["failures"] == {}, (what, s["failures"])
            assert (
                s["clearance_min_mm"] >= 5.0
                and s["self_clearance_min_mm"] >= 2.0
                and s["envelope_clearance_min_mm"] >= 10.0
            ), what
            if what == "plan":
                assert (
                    s["lateral_error_max_mm"] <= 0.5 and s["axis_error_max_deg"] <= 0.25 and s["torque_max_Nm"] <= 20.0
                )
                assert math.isfinite(s["eta_G"])


# The budget of the kill-and-resume check below: both sides (two dockings) and both seeds, as the fixture's job, and a
# small search (24 x 40 evaluations a seed: 16 generations of the multi-start CMA-ES, a checkpoint after 10). What is
# resumed is the study (the seeds' checkpoints); the dockings are judged and their files written after it by the same
# code whether the job was interrupted or not, so the fixture's budget (a robot that meets every requirement) adds
# nothing to this check but a minute of search: that run is the check "design-resume-cohort" of
# benchmarks/slow_checks.py.
_RESUME_BUDGET = ["--levels", "C3", "--points", "8", "--population", "24", "--generations", "40", "--seeds", "1,2"]


def test_a_killed_cohort_job_resumes_to_the_same_robot(tmp_path: Path) -> None:
    """A job on both sides of the bundled patient given as a cohort file (its default anatomy, C3), killed (SIGKILL)
    after 10 generations of its first seed and resumed (``arcube resume``), writes the very robot the uninterrupted
    ``--trajectories`` job writes: design.json, every docking's design file and the summary's verdicts, byte for byte,
    and its exit code. (The suite's check that a killed design job resumes to the uninterrupted result.)"""
    import signal
    import subprocess
    import sys
    import time

    plan = ["--trajectories", "reference", "--anatomy", "default"]
    whole = run_arcube("design", *plan, *_RESUME_BUDGET, "--quiet", "--out", "whole", cwd=tmp_path)
    assert whole.returncode in (0, 3), whole.stdout + whole.stderr
    (tmp_path / "cohort.toml").write_text('[[patient]]\nname = "reference"\nplan = "reference"\nanatomy = "default"\n')
    flags = [
        "design",
        "--cohort",
        "cohort.toml",
        *_RESUME_BUDGET,
        "--quiet",
        "--out",
        "cut",
    ]  # its patient from the file
    proc = subprocess.Popen(
        [sys.executable, "-m", "arcube", *flags], cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )
    mark, deadline = tmp_path / "cut" / "study" / "seed_1" / "checkpoint" / "evals_000010.npz", time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None and not mark.exists():
        time.sleep(0.005)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)
    assert proc.returncode == -signal.SIGKILL and mark.exists() and not (tmp_path / "cut" / "summary.json").exists()
    res = run_arcube("resume", "cut", "--quiet", cwd=tmp_path)
    assert res.returncode == whole.returncode, res.stdout + res.stderr
    cut, job = tmp_path / "cut", tmp_path / "whole"
    assert (cut / "design.json").read_text() == (job / "design.json").read_text()
    for label in ("reference_R", "reference_L"):
        assert (cut / "dockings" / label / "design.json").read_text() == (
            job / "dockings" / label / "design.json"
        ).read_text(), label
    a, b = (json.loads((d / "summary.json").read_text()) for d in (cut, job))
    keys = ("meets_requirements", "mode", "seed", "eta_G", "requirements", "dockings", "missed_at")
    assert _untimed({k: a[k] for k in keys}) == _untimed({k: b[k] for k in keys})


def _untimed(value: object) -> object:
    """``value`` with the wall time a program row reports ("total 38.7 s, built in 2 s") cut to its program's own
    duration: how long the build took is the machine's, not the result."""
    if isinstance(value, dict):
        return {k: _untimed(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_untimed(v) for v in value]
    return value.split(", built in")[0] if isinstance(value, str) else value


@CHROMIUM_SKIP
def test_the_overview_report_fits_a_1400_px_screen(job: Path, tmp_path: Path) -> None:
    """Hardening III item 5, in a real browser at 1400 px: no table runs off the page (the robot's table hid L and c_z,
    the dockings table its links), the 3D panels of the dockings do not overlap, the accuracy section is there, and
    each docking's own report is titled with its patient and side."""
    import time

    html = (job / "report.html").read_text()
    assert "What the robot drills as built" in html and "as built, p95 (mm)" in html
    for label in ("reference_R", "reference_L"):
        page = (job / "dockings" / label / "report.html").read_text()
        assert f"<title>AR-CUBE docking: patient reference, side {label[-1]}</title>" in page
    driver = start_chromium(tmp_path / "profile", "--disable-gpu", "--window-size=1400,900")
    try:
        driver.get((job / "report.html").resolve().as_uri())
        for _ in range(100):
            if driver.execute_script("return document.querySelectorAll('.js-plotly-plot .main-svg').length >= 2"):
                break
            time.sleep(0.1)
        time.sleep(0.5)
        overflow = driver.execute_script("""return [...document.querySelectorAll('table')].filter(
            t => t.getBoundingClientRect().right > document.documentElement.clientWidth + 1).length""")
        assert overflow == 0, "a table runs off the right of a 1400 px window"
        assert driver.execute_script(
            "return document.documentElement.scrollWidth <= document.documentElement.clientWidth + 1"
        )
        boxes = driver.execute_script("""return [...document.querySelectorAll('.grid > div')].map(d => {
            const r = d.getBoundingClientRect(); return [r.left, r.top, r.right, r.bottom]; })""")
        assert len(boxes) == 2
        (l1, t1, r1, b1), (l2, t2, r2, b2) = boxes
        assert r1 <= l2 + 1 or r2 <= l1 + 1 or b1 <= t2 + 1 or b2 <= t1 + 1, f"the 3D panels overlap: {boxes}"
        assert "<a href='dockings/reference_R/report.html'>" in html
    finally:
        driver.quit()
