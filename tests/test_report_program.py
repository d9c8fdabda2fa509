"""The drilling program in the HTML report (issue 20 item 5, issue 21 item 3), checked against the files.

The program folder is synthetic, written as text by :func:`designs.synthetic_program`: two trajectories of the reference plan's right
side (approach S -> A, drill A -> B, retract B -> S, a transit between the standoffs), the joint
angles from the IK of a placed paper design at each row, the rates as the test's own differences,
and the five torque columns as the test's own functions of time, with a ``motors`` summary. Every
claim of the report is re-derived from that text:

* the timeline's bars cover the CSV's runs of equal (segment, trajectory) rows, drills labelled;
* the rate traces are the CSV's rates, the acceleration traces (r[k+1] - r[k-1]) / (t[k+1] - t[k-1]);
  the limit lines are program.json's;
* the playback has one frame per chosen row, each span's first and last among them, and frame k's
  tip is the CSV's E at its row, its drill along the row's e;
* the torque-speed plot's peak marker is max |tau| of the CSV, at that row's |q_dot|;
* ``arcube report`` on a program folder writes report.html (exit 0); a broken program.csv exits 2
  with one line naming the file, and leaves no report.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from arcube.cli import main
from arcube.io import load_trajectories, select
from arcube.model.design import Design
from arcube.report.mechanism3d import SCENE_TRACES
from arcube.report.program_data import envelope, read_program
from arcube.report.program_html import DIV_IDS, motors_figure, program_section, timeline_figure
from arcube.report.program_scene import N_STATIC, playback_figure

from designs import JOINTS, PROGRAM_DESIGN, SYNTHETIC_MOTORS, synthetic_program
from naive import read_program_csv

PLACED = PROGRAM_DESIGN
"""A design that reaches the reference plan's right side from 25 mm outside the entries in mode +,+,+,+
(designs.PROGRAM_DESIGN, the design of tests/test_program.py, found by ``arcube optimize --free all,mount,L``)."""


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    return synthetic_program(tmp_path_factory.mktemp("program"))


def _runs(col: dict[str, np.ndarray]) -> list[tuple[int, int, str, str]]:
    """Runs of equal (segment, trajectory): (first, last, segment, trajectory), by a loop over the rows."""
    runs: list[list] = []
    for i, (s, tr) in enumerate(zip(col["segment"], col["trajectory"])):
        if runs and runs[-1][2] == s and runs[-1][3] == tr:
            runs[-1][1] = i
        else:
            runs.append([i, i, s, tr])
    return [tuple(r) for r in runs]


def test_the_timeline_bars_are_the_csv_segments(folder: Path) -> None:
    col = read_program_csv(folder)
    fig = timeline_figure(read_program(folder))
    bars = []
    for tr in fig.data:
        if tr.type == "bar":
            for base, width, (first, last, tid), text in zip(tr.base, tr.x, tr.customdata, tr.text):
                bars.append((first, last, tr.name, tid, base, base + width, text))
    bars.sort()
    runs = _runs(col)
    t = col["t_s"]
    assert [b[:4] for b in bars] == runs
    for (first, last, seg, tid), bar in zip(runs, bars):
        end = t[last + 1] if last + 1 < len(t) else t[last]  # a bar reaches the next segment's first row
        assert bar[4] == pytest.approx(t[first], abs=1e-12) and bar[5] == pytest.approx(end, abs=1e-12)
        assert bar[6] == (tid if seg == "drill" else "")
    assert {b[2] for b in bars} == {"approach", "drill", "retract", "transit"}


def test_rates_and_accelerations_against_the_limits(folder: Path) -> None:
    col = read_program_csv(folder)
    t = col["t_s"]
    fig = timeline_figure(read_program(folder))
    by_axis = {}
    for tr in fig.data:
        if tr.type == "scatter":
            by_axis.setdefault(tr.yaxis, {})[tr.name] = tr
    assert set(by_axis) == {"y2", "y3", "y4"}  # rates, accelerations, torques
    for j in JOINTS:
        r = col[f"{j}_dot"]
        acc = np.empty_like(r)
        acc[1:-1] = (r[2:] - r[:-2]) / (t[2:] - t[:-2])
        acc[0], acc[-1] = (r[1] - r[0]) / (t[1] - t[0]), (r[-1] - r[-2]) / (t[-1] - t[-2])
        assert np.array_equal(by_axis["y2"][j].x, t) and np.array_equal(by_axis["y2"][j].y, r)
        np.testing.assert_allclose(by_axis["y3"][j].y, acc, rtol=1e-12, atol=1e-9)
        np.testing.assert_array_equal(by_axis["y4"][j].y, col[f"tau_{j}_Nm"])
    lines = {(s.yref, s.y0) for s in fig.layout.shapes if s.type == "line"}
    assert {("y2", 30.0), ("y2", -30.0), ("y3", 120.0), ("y3", -120.0)} <= lines


def test_the_envelope_keeps_every_peak() -> None:
    rng = np.random.default_rng(3)
    y = np.cumsum(rng.normal(size=50_000))
    y[12_345] = 1e3
    keep = envelope(y, 3000)
    assert len(keep) <= 3002 and keep[0] == 0 and keep[-1] == len(y) - 1 and np.all(np.diff(keep) > 0)
    assert y[keep].max() == y.max() == 1e3 and y[keep].min() == y.min()
    # every bucket's extremes: the drawn line's envelope over any stretch of rows is the data's
    for a in range(0, len(y), 997):
        sel = keep[(keep >= a) & (keep < a + 997)]
        inside = y[a : a + 997]
        assert y[sel].max() <= inside.max() and y[sel].min() >= inside.min()


def test_the_playback_poses_the_robot_at_the_csv_rows(folder: Path) -> None:
    col = read_program_csv(folder)
    prog = read_program(folder)
    play = playback_figure(prog, Design.from_dict(PLACED).to_vector(), n_frames=40)
    fig = play.figure
    assert play.note == ""  # the design's IK gives the CSV's angles
    rows = [int(f.name[1:]) for f in fig.frames]
    assert rows == sorted(set(rows)) and 40 <= len(rows) <= 42
    assert {r for run in _runs(col) for r in run[:2]} <= set(rows)
    steps = fig.layout.sliders[0].steps
    assert [s.args[0][0] for s in steps] == [f.name for f in fig.frames]
    tip, drill = SCENE_TRACES.index("drill tip"), SCENE_TRACES.index("drill")
    E = np.stack([col["E_x"], col["E_y"], col["E_z"]], axis=1)
    e = np.stack([col["e_x"], col["e_y"], col["e_z"]], axis=1)
    for f, row in zip(fig.frames, rows):
        assert list(f.traces) == list(range(N_STATIC, N_STATIC + len(SCENE_TRACES)))
        d = f.data[tip]
        np.testing.assert_allclose([d.x[0], d.y[0], d.z[0]], E[row], atol=1e-9)
        line = f.data[drill]
        start, end = np.array([line.x[0], line.y[0], line.z[0]]), np.array([line.x[1], line.y[1], line.z[1]])
        np.testing.assert_allclose(start, E[row], atol=1e-9)
        np.testing.assert_allclose((end - start) / np.linalg.norm(end - start), e[row], atol=1e-9)
        assert f"t = {col['t_s'][row]:.2f} s" in f.layout.title.text and col["segment"][row] in f.layout.title.text


def test_the_playback_names_a_design_that_does_not_run_the_program(folder: Path) -> None:
    other = {**PLACED, "r": PLACED["r"] + 8.0}
    note = playback_figure(read_program(folder), Design.from_dict(other).to_vector(), n_frames=20).note
    assert "does not reproduce this program" in note


def test_the_motor_plot_marks_the_peak_and_rms_of_the_csv(folder: Path) -> None:
    col = read_program_csv(folder)
    fig = motors_figure(read_program(folder))
    t = col["t_s"]
    for k, j in enumerate(JOINTS):
        tau, speed = np.abs(col[f"tau_{j}_Nm"]), np.abs(col[f"{j}_dot"])
        peak = next(tr for tr in fig.data if tr.name == f"{j} peak")
        i = int(np.argmax(tau))
        assert peak.y[0] == tau.max() and peak.x[0] == speed[i]
        cloud = next(tr for tr in fig.data if tr.name == f"{j} operating points")
        pairs = set(zip(speed.tolist(), tau.tolist()))
        assert all((x, y) in pairs for x, y in zip(cloud.x, cloud.y))  # every drawn point is a row of the CSV
        axis = "y" if k == 0 else f"y{k + 1}"
        lines = sorted(s.y0 for s in fig.layout.shapes if s.yref == axis)
        rms = math.sqrt(
            sum((a**2 + b**2) / 2 * (t1 - t0) for a, b, t0, t1 in zip(tau[:-1], tau[1:], t[:-1], t[1:]))
            / (t[-1] - t[0])
        )
        assert lines == pytest.approx(sorted([rms, SYNTHETIC_MOTORS[j]["torque_peak_Nm"]]), rel=1e-12)


def test_the_motor_table_shows_program_json(folder: Path) -> None:
    html = program_section(read_program(folder))
    table = html[html.index("Motor sizing") :]
    table = table[: table.index("</table>")]
    head = re.findall(r"<th>([^<]*)</th>", table)
    cells = re.findall(r"<td>([^<]*)</td>", table)
    names = {
        "torque_peak_Nm": "peak |τ| (N·m)",
        "torque_rms_Nm": "RMS τ (N·m)",
        "speed_peak_deg_s": "peak |q̇| (deg/s)",
        "power_peak_W": "peak power (W)",
        "energy_J": "energy (J)",
        "torque_peak_gravity_Nm": "peak gravity τ (N·m)",
        "torque_peak_loads_only_Nm": "peak τ without masses (N·m)",
    }
    assert len(cells) == len(JOINTS) * len(head)
    for k, j in enumerate(JOINTS):
        row = dict(zip(head, cells[k * len(head) : (k + 1) * len(head)]))
        assert row["actuator"] == j
        for key, title in names.items():
            assert float(row[title]) == pytest.approx(SYNTHETIC_MOTORS[j][key], abs=5e-4)
        assert float(row["peak speed (rpm)"]) == pytest.approx(
            SYNTHETIC_MOTORS[j]["speed_peak_deg_s"] / 6.0, abs=5e-4
        )  # 1 rpm = 6 deg/s


def test_without_torques_there_is_no_motor_view(tmp_path: Path) -> None:
    prog = read_program(synthetic_program(tmp_path / "p", torques=False, motors=False))
    assert prog.tau_Nm is None and motors_figure(prog) is None
    html = program_section(prog)
    assert DIV_IDS["motors"] not in html and "Motor" not in html and DIV_IDS["timeline"] in html


def test_the_limits_table_flags_what_is_beyond(folder: Path) -> None:
    html = program_section(read_program(folder))
    fails = re.findall(r"<tr class='fail'><td>([^<]*)</td>", html)
    assert fails == ["self clearance, smallest (mm)"]  # 1.5 mm < 2 mm; every other value is within its limit
    assert "clearances are at up to 2000 of the rows" in html  # the note says where the clearance plot comes from
    rows = {
        cells[0]: cells[1:]
        for cells in (re.findall(r"<td>([^<]*)</td>", r) for r in re.findall(r"<tr[^>]*>(.*?)</tr>", html))
        if cells
    }
    assert rows["joint rate, largest (deg/s)"] == [
        "14.000",
        "delta_y",
        "30.000",
        "16.000",
    ]  # the largest of 10..14, limit 30
    assert (
        rows["body to anatomy, smallest (mm)"][::2] == ["7.500", "5.000"]
        and float(rows["body to anatomy, smallest (mm)"][3]) == 2.5
    )


def _cli(args: list[str]) -> int:
    try:
        main(args)
    except SystemExit as exc:
        return int(exc.code or 0)
    return 0


def test_arcube_report_on_a_program_folder(tmp_path: Path, capsys) -> None:
    folder = synthetic_program(tmp_path / "p")
    assert _cli(["report", str(folder)]) == 0
    out = capsys.readouterr()
    assert out.out.strip() == str(folder / "report.html") and out.err == ""
    html = (folder / "report.html").read_text()
    assert all(f'id="{div}"' in html for div in DIV_IDS.values())
    assert (
        not re.search(r"<script[^>]*\bsrc=", html) and html.count("plotly.js v") >= 1
    )  # plotly.js inline: opens offline


def test_arcube_report_without_a_design_has_no_playback(tmp_path: Path, capsys) -> None:
    folder = synthetic_program(tmp_path / "p")
    (folder / "design.json").unlink()
    assert _cli(["report", str(folder)]) == 0
    html = (folder / "report.html").read_text()
    assert DIV_IDS["playback"] not in html and "--design" in html
    design = tmp_path / "d.json"
    Design.from_dict(PLACED).to_json(design)
    assert _cli(["report", str(folder), "--design", str(design)]) == 0
    assert DIV_IDS["playback"] in (folder / "report.html").read_text()


@pytest.mark.parametrize(
    ("breakage", "message"),
    [
        (lambda text: text.replace(text.splitlines()[5].split(",")[4], "abc", 1), "row 6: E_y is not a number"),
        (lambda text: text.replace(",E_x,", ",X,", 1), "missing column(s) E_x"),
        (lambda text: text + "1.0,drill\n", "2 fields, the header has"),
        (lambda text: text.splitlines()[0] + "\n", "no rows"),
    ],
)
def test_a_broken_program_csv_exits_2_naming_it(tmp_path: Path, capsys, breakage, message: str) -> None:
    folder = synthetic_program(tmp_path / "p")
    path = folder / "program.csv"
    path.write_text(breakage(path.read_text()))
    assert _cli(["report", str(folder)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(path) in err and message in err and "Traceback" not in err, err
    assert not (folder / "report.html").exists()


def test_a_missing_program_json_exits_2(tmp_path: Path, capsys) -> None:
    folder = synthetic_program(tmp_path / "p")
    (folder / "program.json").unlink()
    assert _cli(["report", str(folder)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(folder / "program.json") in err and not (folder / "report.html").exists()


def test_a_design_report_shows_its_program(tmp_path: Path) -> None:
    """A report written into an ``arcube design`` folder (design.toml) picks up its program/ folder."""
    from arcube.api import evaluate
    from arcube.report import write_report

    job = tmp_path / "job"
    synthetic_program(job / "program")
    (job / "design.toml").write_text('format = "arcube-design"\n')
    ev = evaluate(
        Design.from_dict(PLACED), select(load_trajectories("reference"), side="R", ids="1,3"), points=4, engine="numpy"
    )
    html = write_report(ev, job / "report.html").read_text()
    assert all(f'id="{div}"' in html for div in DIV_IDS.values()) and "Drilling program" in html
    assert html.count("plotly.js v") == 1  # plotly.js once per page
    plain = write_report(ev, tmp_path / "alone.html").read_text()  # no design job around it: no program
    assert "Drilling program" not in plain
