"""``arcube demo --quick``: the whole pipeline writes run folders whose results stand on their own."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from arcube.model.design import Design
from arcube.evaluation.reference import evaluate_task
from arcube.evaluation.task import build_task
from arcube.io import load_trajectories, select


def test_quick_demo_writes_reports_and_reproducible_designs(tmp_path: Path) -> None:
    out = tmp_path / "demo"
    proc = subprocess.run(
        [sys.executable, "-m", "arcube", "demo", "--quick", "--out", str(out), "--engine", "numpy"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    assert "warning" not in proc.stderr, proc.stderr  # the demo used --ftol's old name and warned on every run
    assert "TLS/x: 300" in proc.stdout  # step 1 says why Table 2 as printed reaches nothing
    for run, side in (("paper_links_right", "R"), ("all_free_bilateral", None)):
        folder = out / run
        report = folder / "report.html"
        assert str(report) in proc.stdout and report.stat().st_size > 1_000_000  # plotly.js embedded
        summary = json.loads((folder / "summary.json").read_text())
        design = Design.from_json(folder / "best_design.json")
        ts = load_trajectories("reference")
        if side:
            ts = select(ts, side=side)
        task = build_task(ts.entry, ts.target, 10)
        res = evaluate_task(design.to_vector(), task.E, task.e)
        # The summary must describe the saved design, re-evaluated here from scratch.
        assert summary["feasible"] == bool(res.w_G)
        if summary["feasible"]:
            assert np.isclose(summary["eta_G"], float(res.eta_G), rtol=1e-9)
    links = Design.from_json(out / "paper_links_right" / "best_design.json").to_vector()
    np.testing.assert_array_equal(links[3:], Design.preset("paper").to_vector()[3:])  # only m was free
    # step 4: arcube design's folder, its requirement table re-read from the files it wrote
    design = out / "one_robot"
    summary = json.loads((design / "summary.json").read_text())
    assert str(design / "report.html") in proc.stdout and "4/4" in proc.stdout
    verdict = (
        "design meets every requirement" if summary["meets_requirements"] else "design does NOT meet every requirement"
    )
    assert verdict in proc.stdout
    assert summary["missed"] == [r["requirement"] for r in summary["requirements"] if not r["passed"]]
    assert (design / "requirements.csv").read_text().count("\n") == len(summary["requirements"]) + 1
    from harness import assert_csvs_read_back

    assert assert_csvs_read_back(out) >= 4  # every CSV the demo writes: csv and pandas, the header's field count
