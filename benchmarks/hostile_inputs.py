"""What a user can count on under bad input, measured: a battery of hostile cases by class (issue
"Hardening II"), each run through the command line, and the outcome of each counted.

A case passes when the command ends as promised: exit 2 with exactly one line ``error: ...`` on stderr
and no file left behind (and the user's own files unchanged), or, for input that is valid but unusual
(a plan from a pipe), exit 0; Ctrl-C: exit 130 and the one line ``error: interrupted`` (or, once the
command has finished, a whole output). The table prints, per class, the cases tried and how many
kept the promise; then every case that did not.

Rerun: ``.venv/bin/python benchmarks/hostile_inputs.py`` (``--no-interrupts`` skips the Ctrl-C
cases, which run subprocesses: about a minute).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from designs import PROGRAM_DESIGN as DESIGN  # noqa: E402

import numpy as np  # noqa: E402

from arcube.cli import main  # noqa: E402
from arcube.model.design import Design  # noqa: E402
from arcube.motion.output import Program  # noqa: E402

Case = tuple[str, str, Callable[[Path], list[str]], str]
"""(class, name, setup(folder) -> argv, expected: "error" (exit 2, one line), "error:TEXT" (and the line holds TEXT:
the flag, file or key it must name) or "ok" (exit 0))."""


def run(argv: list[str], cwd: Path) -> tuple[int, str]:
    err = io.StringIO()
    old = os.getcwd()
    os.chdir(cwd)
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            try:
                main(argv)
                code = 0
            except SystemExit as exc:
                code = int(exc.code or 0)
    finally:
        os.chdir(old)
    return code, err.getvalue()


def synthetic_program(n: int = 6) -> Program:
    """A small program as the writer holds it (tests/test_hostile_readers.py's): increasing times, unit axes."""
    rng = np.random.default_rng(n)
    e = rng.normal(size=(n, 3))
    e /= np.linalg.norm(e, axis=1, keepdims=True)
    return Program(t_s=np.arange(n) * 0.01, segment=np.array((["approach", "drill", "retract", "transit"] * n)[:n]),
                   trajectory=np.array(["1"] * (n - 1) + ["1->2"]), E=rng.uniform(-80, 80, (n, 3)), e=e, q_deg=rng.uniform(-170, 170, (n, 5)),
                   q_dot_deg=rng.uniform(-30, 30, (n, 5)), summary={"order": ["1", "2"], "total_s": 0.05, "transits": [{"from": "1", "to": "2"}]},
                   tau_Nm=rng.uniform(-5, 5, (n, 5)))  # fmt: skip


def program_folder(base: Path, csv: Callable[[list[str]], list[str]] | None = None, summary: Callable[[dict], object] | None = None) -> Path:
    folder = base / "p"
    synthetic_program().write(folder)
    if csv is not None:
        lines = (folder / "program.csv").read_text().splitlines()
        (folder / "program.csv").write_text("\n".join(csv(lines)) + "\n")
    if summary is not None:
        data = json.loads((folder / "program.json").read_text())
        (folder / "program.json").write_text(summary(data) if isinstance(summary(data), str) else json.dumps(summary(data)))  # type: ignore[arg-type]
    return folder


def cell(lines: list[str], column: int, text: str) -> list[str]:
    row = lines[2].split(",")
    row[column] = text
    return [lines[0], lines[1], ",".join(row), *lines[3:]]


PROGRAM_DAMAGE: dict[str, tuple[Callable | None, Callable | None]] = {
    "program.csv is /dev/zero": (None, None), "program.json is /dev/zero": (None, None), "program.csv is a FIFO": (None, None),
    '"order": 5': (None, lambda d: {**d, "order": 5}), '"transits": null': (None, lambda d: {**d, "transits": None}),
    "text where a number belongs (JSON)": (None, lambda d: {**d, "total_s": "abc"}),
    "400-digit integer (JSON)": (None, lambda d: json.dumps(d).replace('"total_s": ', '"total_s": ' + "9" * 400 + ', "x": ')),
    "5000-digit integer (JSON)": (None, lambda d: json.dumps(d).replace('"total_s": ', '"total_s": ' + "9" * 5000 + ', "x": ')),
    "JSON nested 100,000 deep": (None, lambda d: '{"a": ' + "[" * 100_000 + "]" * 100_000 + "}"),
    "duplicated E_x column": (lambda ls: [ls[0] + ",E_x", *(ln + ",0" for ln in ls[1:])], None),
    "200,000-character cell": (lambda ls: cell(ls, 4, "x" * 200_000), None),
    "400-digit integer (CSV)": (lambda ls: cell(ls, 9, "9" * 400), None), "5000-digit integer (CSV)": (lambda ls: cell(ls, 9, "9" * 5000), None),
    "text where a number belongs (CSV)": (lambda ls: cell(ls, 4, "abc"), None), "1_5 in a cell": (lambda ls: cell(ls, 4, "1_5"), None),
    "+1e308 joint rate": (lambda ls: cell(ls, 14, "1e308"), None), "-1e308 joint rate": (lambda ls: cell(ls, 14, "-1e308"), None),
    "row one field too wide": (lambda ls: [ls[0], ls[1] + ",5", *ls[2:]], None), "row one field short": (lambda ls: [ls[0], ls[1].rsplit(",", 1)[0], *ls[2:]], None),
}  # fmt: skip


def program_cases() -> list[Case]:
    out: list[Case] = []
    for name, (csv, summary) in PROGRAM_DAMAGE.items():
        def setup(base: Path, name: str = name, csv: Callable | None = csv, summary: Callable | None = summary, cmd: str = "") -> list[str]:
            folder = program_folder(base, csv, summary)
            if "/dev/zero" in name or "FIFO" in name:
                target = folder / ("program.csv" if name.startswith("program.csv") else "program.json")
                target.unlink()
                os.mkfifo(target) if "FIFO" in name else os.symlink("/dev/zero", target)
            return ["report", str(folder)] if cmd == "report" else ["export", "--program", str(folder), "--out", str(base / "r.xml")]

        out.append(("program folders (report)", name, lambda b, s=setup: s(b, cmd="report"), "error"))
        out.append(("program folders (export --program)", name, lambda b, s=setup: s(b, cmd="export"), "error"))
    return out


HEADER = "trajectory,level,side,entry_x,entry_y,entry_z,target_x,target_y,target_z\n"
PLAN_DAMAGE = {
    "decimal comma (one field too many)": HEADER + "1,C3,R,19,681,2,3,40,50,60\n", "short row": HEADER + "1,C3,R,1,2,3,40,50\n",
    "duplicated column": HEADER.strip() + ",entry_x\n1,C3,R,1,2,3,40,50,60,1\n", "1_5": HEADER + "1,C3,R,1_5,2,3,40,50,60\n",
    "Arabic-Indic digits": HEADER + "1,C3,R,١٢,2,3,40,50,60\n", "0x10": HEADER + "1,C3,R,0x10,2,3,40,50,60\n",
    "400 digits": HEADER + f"1,C3,R,{'9' * 400},2,3,40,50,60\n", "200,000-character cell": HEADER + f"1,C3,R,1,2,3,40,50,60{',' + 'x' * 200_000}\n",
    "NUL byte": HEADER + "1,C3,R,1\x00,2,3,40,50,60\n", "300-digit coordinate": HEADER + f"1,C3,R,{'9' * 300}.5,2,3,40,50,60\n",
}  # fmt: skip


def plan_cases() -> list[Case]:
    out: list[Case] = []
    for name, text in PLAN_DAMAGE.items():
        def setup(base: Path, text: str = text) -> list[str]:
            (base / "plan.csv").write_text(text)
            return ["evaluate", "--trajectories", str(base / "plan.csv"), "--points", "3", "--report", str(base / "r.html")]

        out.append(("plan CSVs", name, setup, "error"))

    def latin1(base: Path) -> list[str]:
        (base / "plan.csv").write_bytes((HEADER + "1,C3,R,1,2,3,40,50,60 é\n").encode("latin-1"))
        return ["evaluate", "--trajectories", str(base / "plan.csv"), "--points", "3"]

    out.append(("plan CSVs", "Latin-1 bytes", latin1, "error"))
    out.append(("plan CSVs", "/dev/zero", lambda b: ["evaluate", "--trajectories", "/dev/zero", "--points", "3"], "error"))
    return out


def limit_cases() -> list[Case]:
    opt = ["optimize", "--trajectories", "reference"]
    prog = ["program", "--design", "design.json", "--trajectories", "reference", "--side", "R", "--ids", "5"]  # a design that runs it
    cases = {
        "--max torque=1_5": [*opt, "--max", "torque=1_5"], "--max torque=1 --max torque=50": [*opt, "--max", "torque=1", "--max", "torque=50"],
        "--no-torque --max torque=5": ["design", "--trajectories", "reference", "--no-torque", "--max", "torque=5"],
        "--min clearance=-21.25": ["design", "--trajectories", "reference", "--min", "clearance=-21.25", "--anatomy", "default"],
        "--dt 1e-7": [*prog, "--dt", "1e-7"], "--feed 1e-9": [*prog, "--feed", "1e-9"], "--approach-speed 1e-6": [*prog, "--approach-speed", "1e-6"],
        "--max-joint-speed 1e308": [*prog, "--max-joint-speed", "1e308"], "--thrust 1e308": [*prog, "--thrust", "1e308"],
        "--standoff 1e308 (design)": ["design", "--trajectories", "reference", "--standoff", "1e308"],
        "--population 1e8 (ga)": [*opt, "--algorithm", "ga", "--population", "100000000"],
        "--points 2e19": [*opt, "--points", "20000000000000000000"],
    }  # fmt: skip
    return [("limits and computation bounds", name, lambda b, a=argv: [*with_design(b, a), "--out", str(b / "out")], "error")
            for name, argv in cases.items()]  # fmt: skip


def with_design(base: Path, argv: list[str]) -> list[str]:
    """``argv``, with tests/test_program.py's design written as ``design.json`` (a design whose programs run)."""
    Design.from_dict(DESIGN).to_json(base / "design.json")
    return argv


def write_cases() -> list[Case]:
    def older_program(base: Path) -> list[str]:
        (base / "prog").mkdir()
        (base / "prog" / "program.csv").write_text("older")
        (base / "prog" / "program.json").mkdir()
        return with_design(base, ["program", "--design", "design.json", "--trajectories", "reference", "--side", "R", "--ids", "5", "--feed", "2",
                                  "--dt", "0.05", "--out", str(base / "prog")])  # fmt: skip

    def replay_folder(base: Path) -> list[str]:
        folder = program_folder(base)
        (base / "r.xml").write_text("<old/>")
        (base / "r.replay.csv").mkdir()
        return ["export", "--program", str(folder), "--out", str(base / "r.xml")]

    def fifo_report(base: Path) -> list[str]:
        os.mkfifo(base / "r.html")
        return ["evaluate", "--points", "3", "--ids", "1,2", "--report", str(base / "r.html")]

    return [("outputs of several files", "older program.csv + a folder named program.json", older_program, "error"),
            ("outputs of several files", "export where r.replay.csv is a folder", replay_folder, "error:r.replay.csv"),
            ("outputs of several files", "export --force where r.replay.csv is a folder", lambda b: [*replay_folder(b), "--force"],
             "error:r.replay.csv"),
            ("outputs of several files", "HTML report into a FIFO", fifo_report, "error"),
            ("outputs of several files", "HTML report into /proc", lambda b: ["evaluate", "--points", "3", "--report", "/proc/r.html"], "error")]  # fmt: skip


def message_cases() -> list[Case]:
    def big_mesh(base: Path) -> list[str]:
        import trimesh

        trimesh.creation.box(extents=(5000.0, 5000.0, 5000.0)).export(base / "big.stl")
        return ["evaluate", "--points", "3", "--ids", "1,2", "--engine", "numpy", "--anatomy", str(base / "big.stl")]

    return [("messages naming the culprit", "--at on an unreachable point", lambda b: ["export", "--at", "1:0", "--out", str(b / "r.xml")], "error"),
            ("messages naming the culprit", "--dask with --workers", lambda b: ["optimize", "--trajectories", "reference", "--dask", "127.0.0.1:8786",
                                                                                 "--workers", "2", "--out", str(b / "r")], "error"),
            ("messages naming the culprit", "a 300-digit --at", lambda b: ["export", "--at", "1:" + "9" * 300, "--out", str(b / "r.xml")], "error"),
            ("messages naming the culprit", "a mesh 5 m across", big_mesh, "error")]  # fmt: skip


ROBOT = ROOT / "tests" / "data" / "one_robot.json"
"""The demo's one robot (a design job's design.json: the robot and its two dockings)."""
NEW = "commands of this round (calibrate, tolerance, dock, breach)"
FILES = "files a user trusts (docking files, design files, single-file outputs)"


def docking_file(base: Path, side: str = "R") -> Path:
    """The demo robot's docking on ``side`` as a docking file (patient and side recorded), in ``base``."""
    from arcube.model.robot import design_at_side, write_docking

    path = base / f"reference_{side}" / "design.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    write_docking(design_at_side(ROBOT, side), path, "reference", side)
    return path


def poses_file(base: Path) -> Path:
    """The nominal poses of the right-side docking (``calibrate poses``): what is to be measured, not measurements."""
    d = docking_file(base)
    code, err = run(["calibrate", "poses", "--design", str(d), "--trajectories", "reference", "--side", "R", "--count", "12",
                     "--out", str(base / "poses.csv")], base)  # fmt: skip
    assert code == 0, err
    return base / "poses.csv"


def new_command_cases() -> list[Case]:
    def nominal_as_measured(base: Path) -> list[str]:
        poses = poses_file(base)
        return ["calibrate", "identify", "--design", str(base / "reference_R" / "design.json"), "--measurements", str(poses),
                "--out", str(base / "cal")]  # fmt: skip

    def other_designs_poses(base: Path) -> list[str]:
        poses_file(base)
        other = docking_file(base, "L")
        return ["calibrate", "identify", "--design", str(other), "--measurements", str(base / "poses.csv"), "--out", str(base / "cal")]

    def robot_without_parameters(base: Path) -> list[str]:
        (base / "robot.json").write_text(json.dumps({"m_x": 1.0, "mode": "+,+,+,+"}))
        return ["dock", "--robot", str(base / "robot.json"), "--trajectories", "reference", "--out", str(base / "out")]

    def cohort_error(base: Path) -> list[str]:
        (base / "cohort.toml").write_text('[[patient]]\nname = "a"\nplan = "missing.csv"\n')
        return ["dock", "--robot", str(ROBOT), "--cohort", str(base / "cohort.toml"), "--out", str(base / "out")]

    def shared_patient(base: Path) -> list[str]:
        (base / "plan.csv").write_text(HEADER + "1,C3,R,1,2,3,40,50,60\n")
        for name in ("train", "held"):
            (base / f"{name}.toml").write_text('[[patient]]\nname = "seed7"\nplan = "plan.csv"\nanatomy = "none"\n')
        return ["design", "--cohort", str(base / "train.toml"), "--validate", str(base / "held.toml"), "--out", str(base / "out")]

    def misspelt_pedicle_column(base: Path) -> list[str]:
        (base / "plan.csv").write_text(HEADER.rstrip("\n") + ",pedicle_widht_mm\n" + "1,C3,R,1,2,3,40,50,60,4.5\n")
        return ["breach", "--design", str(docking_file(base)), "--trajectories", str(base / "plan.csv"), "--out", str(base / "b")]

    breach = lambda b, *more: ["breach",  # noqa: E731 "--design", str(docking_file(b)), "--trajectories", "reference", "--side", "R", *more,
                                "--out", str(b / "b")]  # fmt: skip
    tol = lambda b, *more: ["tolerance",  # noqa: E731 "--design", str(docking_file(b)), "--trajectories", "reference", "--side", "R", *more,
                             "--out", str(b / "t")]  # fmt: skip
    return [
        (NEW, "calibrate poses --count 3 (below the identifiable minimum)",
         lambda b: ["calibrate", "poses", "--design", str(docking_file(b)), "--trajectories", "reference", "--side", "R", "--count", "3",
                    "--out", str(b / "p.csv")], "error"),
        (NEW, "identify on the nominal poses", nominal_as_measured, "error"),
        (NEW, "identify on another design's poses", other_designs_poses, "error"),
        (NEW, "tolerance --class x", lambda b: tol(b, "--class", "x"), "error"),
        (NEW, "tolerance --tol nosuch=1", lambda b: tol(b, "--tol", "nosuch=1"), "error"),
        (NEW, "dock: a robot file without robot parameters", robot_without_parameters, "error"),
        (NEW, "dock --starts 0", lambda b: ["dock", "--robot", str(ROBOT), "--trajectories", "reference", "--starts", "0", "--out", str(b / "o")], "error"),
        (NEW, "dock: a cohort whose plan is missing", cohort_error, "error"),
        (NEW, "design --validate sharing a patient name", shared_patient, "error"),
        (NEW, "breach --registration -1", lambda b: breach(b, "--registration", "-1"), "error"),
        (NEW, "breach --samples 0", lambda b: breach(b, "--samples", "0"), "error"),
        (NEW, "breach --calibration on a folder that is not one", lambda b: ["breach", "--calibration", str(b), "--trajectories", "reference",
                                                                              "--out", str(b / "o")], "error"),
        (NEW, "breach: a misspelt pedicle column", misspelt_pedicle_column, "error"),
    ]  # fmt: skip


def written(path: Path, text: str) -> list[str]:
    """Write ``text`` to ``path``; no arguments (a setup's first step, inside its argv list)."""
    path.write_text(text)
    return []


def file_cases() -> list[Case]:
    def partial_mount(base: Path) -> list[str]:
        d = json.loads(docking_file(base).read_text())
        del d["mount_rx"]
        (base / "d.json").write_text(json.dumps(d))
        return ["evaluate", "--design", str(base / "d.json"), "--trajectories", "reference", "--points", "3"]

    def existing(base: Path, argv: list[str], name: str) -> list[str]:
        (base / name).write_text("measured by hand")
        return argv

    return [
        (FILES, "--side L on a right-side docking file",
         lambda b: ["evaluate", "--design", str(docking_file(b)), "--trajectories", "reference", "--side", "L", "--points", "3"], "error"),
        (FILES, "a robot's design.json without --side", lambda b: ["evaluate", "--design", str(ROBOT), "--trajectories", "reference", "--points", "3"], "error"),
        (FILES, "a design file with a partial mounting group", partial_mount, "error"),
        (FILES, "calibrate poses onto an existing file",
         lambda b: existing(b, ["calibrate", "poses", "--design", str(docking_file(b)), "--trajectories", "reference", "--side", "R",
                                "--out", str(b / "m.csv")], "m.csv"), "error"),
        (FILES, "joints onto an existing file",
         lambda b: existing(b, ["joints", "--design", str(docking_file(b)), "--trajectories", "reference", "--side", "R", "--out", str(b / "j.csv")],
                            "j.csv"), "error"),
        (FILES, "export onto an existing file",
         lambda b: existing(b, ["export", "--design", str(docking_file(b)), "--trajectories", "reference", "--side", "R", "--out", str(b / "r.xml")],
                            "r.xml"), "error"),
        (FILES, "a semicolon-separated plan",
         lambda b: [*written(b / "p.csv", HEADER.replace(",", ";") + "1;C3;R;1;2;3;40;50;60\n"), "evaluate", "--trajectories", str(b / "p.csv")],
         "error"),
        (FILES, "an anatomy in an unknown format",
         lambda b: [*written(b / "a.vtk", "x"), "evaluate", "--points", "3", "--anatomy", str(b / "a.vtk")], "error"),
    ]  # fmt: skip


BOUNDS = "limits and computation bounds"
IGNORED = "flags that would be ignored (Hardening IV)"
MESSAGES = "messages naming the culprit"


def run_folder(base: Path, old: str, new: str) -> Path:
    """A run folder killed before its first checkpoint (``resume`` starts it), its config.toml's ``old`` made ``new``."""
    from arcube.optimization import run as runmod
    from arcube.optimization.config import build_config

    cfg = build_config(["reference"], population=4, generations=1, points=3, ids="1", free="m_x", seed=3)
    runmod.prepare(base / "run", cfg)
    text = (base / "run" / "config.toml").read_text()
    assert old in text, old
    (base / "run" / "config.toml").write_text(text.replace(old, new, 1))
    return base / "run"


def hardening4_cases() -> list[Case]:
    """Issue "Hardening IV": values beyond any robot, flags taken and ignored, a file path ending with '/', messages
    that named the wrong culprit, and the hostile battery's four (each must name its flag, file or key)."""

    def big_link(base: Path) -> list[str]:
        (base / "big.json").write_text(json.dumps({**Design.paper().to_dict(), "d_x": 1e9}))
        return ["evaluate", "--design", str(base / "big.json"), "--points", "3", "--report", str(base / "r.html")]

    def fifo_study(base: Path) -> list[str]:
        (base / "s").mkdir()
        os.mkfifo(base / "s" / "study.toml")
        (base / "s" / "base_config.toml").write_text("")
        return ["resume", str(base / "s")]

    def number_in_program_json(base: Path) -> list[str]:
        folder = program_folder(base)
        data = json.loads((folder / "program.json").read_text())
        (folder / "program.json").write_text(json.dumps({**data, "note": "@"}).replace('"@"', "9" * 5000))
        return ["report", str(folder)]

    def good_csv(base: Path) -> list[str]:
        (base / "good.csv").write_text("kept\n")
        return ["dock", "--robot", str(ROBOT), "--trajectories", "reference", "--out", str(base / "good.csv")]

    opt = lambda b, *more: ["optimize", "--trajectories", "reference", *more, "--out", str(b / "o")]  # noqa: E731
    rob = lambda b, cmd, *more: [cmd, "--design", str(ROBOT), "--trajectories", "reference", "--side", "R", *more, "--out", str(b / "o")]  # noqa: E731  # fmt: skip
    return [
        (BOUNDS, "a design file's d_x: 1e9", big_link, "error:d_x"),
        (BOUNDS, "--table-z 1e9", lambda b: ["evaluate", "--points", "3", "--envelope", "default", "--table-z", "1e9"], "error:--table-z"),
        (BOUNDS, "joints --speed 1e9", lambda b: ["joints", "--points", "3", "--speed", "1e9", "--out", str(b / "j.csv")], "error:--speed"),
        (BOUNDS, "--margin 1e9", lambda b: opt(b, "--margin", "1e9"), "error:--margin"),
        (BOUNDS, "study --best-known 1e300", lambda b: ["study", "--trajectories", "reference", "--best-known", "1e300", "--out", str(b / "s")],
         "error:--best-known"),
        (BOUNDS, "dock --max lateral_error=1e12", lambda b: ["dock", "--robot", str(ROBOT), "--trajectories", "reference", "--max",
                                                              "lateral_error=1e12", "--out", str(b / "d")], "error:--max"),
        (BOUNDS, "tolerance --docking-deg 720", lambda b: rob(b, "tolerance", "--docking-deg", "720"), "error:--docking-deg"),
        (BOUNDS, "--bounds d_x=1:1e9", lambda b: opt(b, "--bounds", "d_x=1:1e9"), "error:--bounds"),
        (IGNORED, "optimize --class f (no accuracy objective or limit)", lambda b: opt(b, "--class", "f"), "error:--class"),
        (IGNORED, "optimize --tol r=0.02 (no accuracy objective or limit)", lambda b: opt(b, "--tol", "r=0.02"), "error:--tol"),
        (IGNORED, "optimize --aggregate max (one plan)", lambda b: opt(b, "--aggregate", "max"), "error:--aggregate"),
        (IGNORED, "optimize --placement shared (one plan)", lambda b: opt(b, "--placement", "shared"), "error:--placement"),
        (IGNORED, "tolerance --class f --tol lengths=..,angles=..", lambda b: rob(b, "tolerance", "--class", "f", "--tol",
                                                                                   "lengths=0.05,angles=0.01"), "error:--class"),
        (IGNORED, "--anatomy-frame RAS with no anatomy", lambda b: ["evaluate", "--points", "3", "--anatomy-frame", "RAS"], "error:--anatomy-frame"),
        (FILES, "joints --out jdir/", lambda b: ["joints", "--points", "3", "--out", f"{b / 'jdir'}/"], "error:jdir/"),
        (MESSAGES, "dock --out onto a file", good_csv, "error:is a file, not a folder"),
        (MESSAGES, 'config.toml dask = "nonsense"', lambda b: ["resume", str(run_folder(b, 'dask = ""', 'dask = "nonsense"'))],
         "error:config.toml: executor.dask"),
        (MESSAGES, "config.toml [bounds] entry not a pair", lambda b: ["resume", str(run_folder(b, "m_x = [-400.0, 400.0]", "m_x = 5"))],
         "error:[bounds] m_x must be [low, high]"),
        (MESSAGES, "a FIFO study.toml", fifo_study, "error:study.toml: is a FIFO"),
        (MESSAGES, "calibrate simulate on a robot file without --side",
         lambda b: [*written(b / "p.csv", "x\n"), "calibrate", "simulate", "--design", str(ROBOT), "--poses", str(b / "p.csv"),
                    "--out", str(b / "m.csv")], "error:--side"),
        (FILES, "patients --mean --out /proc/p.csv", lambda b: ["patients", "--mean", "--out", "/proc/p.csv"], "error:/proc/p.csv:"),
        (FILES, "a 5000-digit integer in an unused key of program.json", number_in_program_json, "error:program.json: note:"),
        (FILES, "a missing second trajectory set of a design job", lambda b: ["design", "--trajectories", "reference", str(b / "missing.csv"),
                                                                               "--out", str(b / "d")], "error:missing.csv"),
    ]  # fmt: skip


class Hung(Exception):
    """A case that did not end within :data:`CASE_TIMEOUT_S` (e.g. a read blocked on a FIFO)."""


CASE_TIMEOUT_S = 120


def _alarm(signum: int, frame: object) -> None:
    raise Hung


def check(case: Case, base: Path) -> str | None:
    """None when the case kept the promise, else what happened."""
    _, name, setup, expected = case
    argv = setup(base)
    before = {p: (p.stat().st_size if p.is_file() else None) for p in base.rglob("*")}
    signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(CASE_TIMEOUT_S)
    try:
        code, err = run(argv, base)
    except Hung:
        return f"no answer within {CASE_TIMEOUT_S} s"
    except BaseException as exc:  # noqa: BLE001 - what escaped the command line, counted
        return f"escaped the CLI: {type(exc).__name__}: {str(exc)[:120]}"
    finally:
        signal.alarm(0)
    after = {p: (p.stat().st_size if p.is_file() else None) for p in base.rglob("*")}
    if expected == "ok":
        return None if code == 0 else f"exit {code}: {err.strip()[:200]}"
    if code != 2 or not err.startswith("error: ") or err.count("\n") != 1:
        return f"exit {code}: {err.strip()[:200]!r}"
    if expected.startswith("error:") and expected[len("error:") :] not in err:
        return f"does not name {expected[len('error:') :]!r}: {err.strip()[:200]!r}"
    if after != before:
        return f"files changed: {sorted(str(p.relative_to(base)) for p in set(after) ^ set(before))}"
    return None


def interrupt_cases(delays: tuple[float, ...]) -> list[tuple[str, str | None]]:
    """(name, None or what happened) for SIGINT at ``delays`` during evaluate --report and program."""
    results = []
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    for argv in (["evaluate", "--points", "30", "--engine", "numpy", "--anatomy", "default", "--report", "r.html"],
                 ["program", "--design", "design.json", "--trajectories", "reference", "--side", "R", "--ids", "5", "--feed", "2", "--dt", "0.05",
                  "--out", "prog"]):  # fmt: skip
        for delay in delays:
            base = Path(tempfile.mkdtemp())
            Design.from_dict(DESIGN).to_json(base / "design.json")
            p = subprocess.Popen([sys.executable, "-m", "arcube", *argv], cwd=base, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            time.sleep(delay)
            p.send_signal(signal.SIGINT)
            _, err = p.communicate(timeout=300)
            left = sorted(set(os.listdir(base)) - {"design.json"})
            whole = left in (["prog"], ["r.html", "r_dexterity.png"]) and p.returncode in (0, -signal.SIGINT) and err == ""
            ok = (p.returncode == 130 and err == "error: interrupted\n" and not left) or whole
            results.append((f"{argv[0]} at {delay:g} s", None if ok else f"exit {p.returncode}, {err.strip()[-120:]!r}, left {left}"))
            shutil.rmtree(base, ignore_errors=True)
    return results


def main_() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-interrupts", action="store_true")
    args = parser.parse_args()
    cases = [*program_cases(), *plan_cases(), *limit_cases(), *write_cases(), *message_cases(), *new_command_cases(), *file_cases(),
             *hardening4_cases()]  # fmt: skip
    table: dict[str, list[int]] = {}
    failures: list[str] = []
    for case in cases:
        base = Path(tempfile.mkdtemp())
        try:
            problem = check(case, base)
        finally:
            shutil.rmtree(base, ignore_errors=True)
        row = table.setdefault(case[0], [0, 0])
        row[0] += 1
        row[1] += problem is None
        if problem is not None:
            failures.append(f"{case[0]}: {case[1]}: {problem}")
    if not args.no_interrupts:
        for name, problem in interrupt_cases((0.2, 0.6, 1.2, 2.0, 3.0, 4.5)):
            row = table.setdefault("Ctrl-C (SIGINT at several moments)", [0, 0])
            row[0] += 1
            row[1] += problem is None
            if problem is not None:
                failures.append(f"Ctrl-C: {name}: {problem}")
    width = max(len(k) for k in table)
    print(f"{'class':<{width}}  cases  kept the promise")
    for k, (n, ok) in table.items():
        print(f"{k:<{width}}  {n:>5}  {ok:>5}")
    print(f"{'all':<{width}}  {sum(n for n, _ in table.values()):>5}  {sum(ok for _, ok in table.values()):>5}")
    for line in failures:
        print("FAILED", line, flush=True)


if __name__ == "__main__":
    main_()
