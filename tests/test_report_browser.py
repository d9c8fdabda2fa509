"""The HTML reports in a real browser (headless Chromium driven by Selenium).

Skipped when /usr/bin/chromium is missing, except on CI (env CI=true), where that is a failure.
A screenshot of each report is saved to the pytest tmp dir and, if ARCUBE_SCREENSHOT_DIR is
set, there too.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import time
from pathlib import Path

import pytest

from arcube.model.design import Design
from arcube.api import evaluate
from arcube.report import write_report
from arcube.report.html import DIV_IDS, TITLES
from arcube.report.run_report import write_run_report
from arcube.io import load_trajectories, select

from designs import PAPER, RIGHT_SIDE_M, synthetic_program
from harness import CHROMIUM_SKIP, start_chromium
from naive import read_program_csv

PLACED = {**PAPER, **RIGHT_SIDE_M}

pytestmark = CHROMIUM_SKIP


@pytest.fixture(scope="module")
def driver(tmp_path_factory):
    drv = start_chromium(tmp_path_factory.mktemp("chromium-profile"), "--disable-gpu", "--window-size=1300,1000")
    yield drv
    drv.quit()


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """A run folder as the optimizer writes it (config.toml, history.csv, best_design.json, summary.json)."""
    run = tmp_path_factory.mktemp("run")
    ts = select(load_trajectories("reference"), side="R")
    Design.from_dict(PLACED).to_json(run / "best_design.json")
    patient = "\n".join(
        [
            "[[patients]]",
            'source = "reference"',
            f"ids = {json.dumps(list(ts.ids))}",
            f"levels = {json.dumps(list(ts.levels))}",
            f"sides = {json.dumps(list(ts.sides))}",
            f"entry = {json.dumps(ts.entry.tolist())}",
            f"target = {json.dumps(ts.target.tolist())}",
        ]
    )
    (run / "config.toml").write_text(
        'format = "arcube-optimize-run"\nformat_version = 1\nrun_id = "test"\n\n[settings]\nalgorithm = "ga"\npopulation = 40\n'
        'generations = 25\npoints = 12\nmode = "+,+,+,+"\nguards = false\nsetups = 1\nseed = 7\nfree = ["m_x", "m_y", "m_z"]\n\n'
        + patient
        + "\n"
    )
    rows = ["generation,evaluations,best_eta_G,mean_eta_G,feasible_fraction,best_violation,seconds"]
    rows += [
        f"{g},{40 * g},{'' if g < 3 else 2.4 + 3.0 / g},{'' if g < 3 else 4.0 + 5.0 / g},{min(1.0, g / 15):.3f},0,{0.1 * g}"
        for g in range(1, 26)
    ]
    (run / "history.csv").write_text("\n".join(rows) + "\n")
    (run / "summary.json").write_text(
        json.dumps({"eta_G": 2.4, "feasible": True, "generations": 25, "mode": "+,+,+,+", "stopped_by": "generations"})
    )
    return run


def _open(driver, path: Path):
    driver.get_log("browser")  # start this page with an empty log (get_log drains it)
    driver.get(path.resolve().as_uri())
    for _ in range(100):  # wait for every plot to be drawn
        n = driver.execute_script("return document.querySelectorAll('.js-plotly-plot .main-svg').length")
        if n and driver.execute_script("return document.readyState") == "complete":
            break
        time.sleep(0.1)
    time.sleep(0.5)


def _plots(driver) -> dict[str, dict]:
    return {
        p["id"]: p
        for p in driver.execute_script(
            "return Array.from(document.querySelectorAll('.js-plotly-plot')).map(g => ({id: g.id, title: g.layout.title.text, names: g.data.map(t => t.name)}))"
        )
    }


def _mechanism(driver, div: str = DIV_IDS["scene"]) -> dict:
    """The coordinates of the scene's traces, as the browser holds them."""
    return driver.execute_script(
        "const g = document.getElementById(arguments[0]);"
        "return {title: g.layout.title.text, data: g.data.map(t => [t.name, Array.from(t.x || []), Array.from(t.y || []), Array.from(t.z || [])])};",
        div,
    )


def _move_slider(driver, step: int, div: str = DIV_IDS["scene"]) -> None:
    """Do what clicking slider step ``step`` does: Plotly.animate with that step's own args."""
    driver.set_script_timeout(20)
    driver.execute_async_script(
        "const done = arguments[arguments.length - 1]; const g = document.getElementById(arguments[0]);"
        "const s = g.layout.sliders[0].steps[arguments[1]];"
        "Plotly.animate(g, s.args[0], s.args[1]).then(() => done(true), e => done(String(e)));",
        div,
        step,
    )
    time.sleep(0.3)


def _screenshot(driver, name: str, tmp_path: Path, div: str = DIV_IDS["scene"]) -> Path:
    scene = driver.find_element("id", div)
    driver.execute_script("arguments[0].scrollIntoView()", scene)
    time.sleep(0.3)
    shot = tmp_path / f"{name}.png"
    scene.screenshot(str(shot))
    driver.execute_script("window.scrollTo(0, 0)")
    driver.save_screenshot(str(tmp_path / f"{name}_top.png"))
    target = os.environ.get("ARCUBE_SCREENSHOT_DIR")
    if target:
        Path(target).mkdir(parents=True, exist_ok=True)
        for p in (shot, tmp_path / f"{name}_top.png"):
            shutil.copy(p, Path(target) / p.name)
    assert shot.stat().st_size > 10_000
    return shot


def _errors(driver) -> list[dict]:
    return [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]


def _self_contained(html: str) -> None:
    assert not re.search(r"<script[^>]*\bsrc=", html), "scripts must be inline (the report opens with no network)"
    assert not re.search(r"<link[^>]*\bhref=\"?https?:", html)


def test_run_report_in_browser(driver, run_dir, tmp_path):
    html = write_run_report(run_dir)
    assert html == run_dir / "report.html"
    assert (run_dir / "report_dexterity.png").stat().st_size > 0 and (
        run_dir / "report_convergence.png"
    ).stat().st_size > 0
    _self_contained(html.read_text())
    _open(driver, html)
    plots = _plots(driver)
    assert set(plots) == set(DIV_IDS.values()) - {DIV_IDS["pareto"]}  # a GA run has no Pareto front
    assert plots[DIV_IDS["dexterity"]]["title"] == TITLES["dexterity"]
    assert plots[DIV_IDS["convergence"]]["title"] == TITLES["convergence"]
    assert plots[DIV_IDS["scene"]]["title"].startswith(TITLES["scene"])
    assert {"best η_G", "feasible %"} <= set(plots[DIV_IDS["convergence"]]["names"])
    assert {"cranks", "four-bar x", "four-bar y", "spherical x", "spherical y", "drill", "trajectories"} <= set(
        plots[DIV_IDS["scene"]]["names"]
    )
    before = _mechanism(driver)
    _move_slider(driver, 40)
    after = _mechanism(driver)
    assert after["title"] != before["title"] and "k = " in after["title"]
    moved = {b[0] for b, a in zip(before["data"], after["data"]) if b[1:] != a[1:]}
    assert {"cranks", "four-bar x", "four-bar y", "spherical x", "spherical y", "drill"} <= moved
    assert "trajectories" not in moved  # the patient does not move
    assert _errors(driver) == []
    _screenshot(driver, "run_report", tmp_path)


def test_evaluation_report_with_unreachable_points(driver, tmp_path):
    design = tmp_path / "design.json"
    Design.from_dict(PLACED).to_json(design)
    report = evaluate(str(design), "reference", points=8, engine="numpy")  # the left side is unreachable
    n_ok = int(report.results.points.reachable.sum())
    assert 0 < n_ok < len(report.task)
    html = write_report(report, tmp_path / "eval.html")
    assert (tmp_path / "eval_dexterity.png").exists() and not (tmp_path / "eval_convergence.png").exists()
    _self_contained(html.read_text())
    _open(driver, html)
    plots = _plots(driver)
    assert set(plots) == {DIV_IDS["dexterity"], DIV_IDS["tip"], DIV_IDS["scene"]}
    assert "unreachable" in plots[DIV_IDS["dexterity"]]["names"]
    # drill-tip panels: one value per reachable point, gaps at the others, as the JSON has them
    ys = driver.execute_script("return document.getElementById(arguments[0]).data[0].y", DIV_IDS["tip"])
    assert sum(v is not None for v in ys) == n_ok
    want = report.results.points.lateral_error_mm
    assert all((v is None) == (not ok) for v, ok in zip(ys, report.results.points.reachable))
    assert max(v for v in ys if v is not None) == pytest.approx(float(want[report.results.points.reachable].max()))
    n_steps = driver.execute_script(
        "return document.getElementById(arguments[0]).layout.sliders[0].steps.length", DIV_IDS["scene"]
    )
    assert n_steps == n_ok
    note = driver.execute_script(
        "return document.getElementById(arguments[0]).layout.annotations.map(a => a.text).join(' ')", DIV_IDS["scene"]
    )
    assert "unreachable" in note
    before = _mechanism(driver)
    _move_slider(driver, n_steps - 1)
    assert _mechanism(driver)["data"] != before["data"]
    assert _errors(driver) == []
    _screenshot(driver, "evaluation_report", tmp_path)


def test_evaluation_report_draws_the_anatomy_and_the_clearance(driver, tmp_path):
    design = tmp_path / "design.json"
    Design.from_dict(PLACED).to_json(design)
    report = evaluate(str(design), "reference", points=6, side="R", anatomy="default")
    html = write_report(report, tmp_path / "anat.html")
    _open(driver, html)
    plots = _plots(driver)
    assert "anatomy" in plots[DIV_IDS["scene"]]["names"]
    titles = driver.execute_script(
        "return document.getElementById(arguments[0]).layout.annotations.map(a => a.text)", DIV_IDS["tip"]
    )
    assert "clearance to the anatomy (mm)" in titles
    assert _errors(driver) == []


def test_program_report_in_browser(driver, tmp_path):
    """A program folder's report (arcube report DIR): the timeline, the motors and the playback render,
    and the playback's slider moves the robot to the row its step names."""
    from arcube.report.program_html import DIV_IDS as PROGRAM_DIVS
    from arcube.report.program_html import write_program_report

    folder = synthetic_program(tmp_path / "program")
    html = write_program_report(folder)
    _self_contained(html.read_text())
    _open(driver, html)
    assert set(_plots(driver)) == set(PROGRAM_DIVS.values())
    div = PROGRAM_DIVS["playback"]
    names = driver.execute_script(
        "return document.getElementById(arguments[0]).layout.sliders[0].steps.map(s => s.args[0][0])", div
    )
    before = _mechanism(driver, div)
    _move_slider(driver, len(names) - 1, div)
    after = _mechanism(driver, div)
    assert after["title"] != before["title"]
    row = int(names[-1][1:])
    col = read_program_csv(folder)
    tip = next(d for d in after["data"] if d[0] == "drill tip")
    assert [v[0] for v in tip[1:]] == pytest.approx([col["E_x"][row], col["E_y"][row], col["E_z"][row]], abs=1e-9)
    assert _errors(driver) == []
    _screenshot(driver, "program_report", tmp_path, div)
