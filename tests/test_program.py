"""The drilling program (MODEL.md 17, issue 20), checked by oracles that do not share its code.

The program's files are read back as text (``csv``), and every claim is re-derived from them:

* the FK (:func:`arcube.model.mechanism.forward_kinematics`) of each row's angles gives the row's
  E and e (1e-6 mm): the CSV is a program a controller can run;
* drill rows lie on the plan's line A -> B at the feed, approach and retract rows on the line
  S -> A; every trajectory is drilled from A to B;
* finite differences of the rows (rates (q[k+1] - q[k]) / dt, accelerations (q_dot[k+1] - q_dot[k])
  / dt and (q[k+1] - 2 q[k] + q[k-1]) / dt^2, tip speed) stay within the limits. A finite
  difference is a mean of the continuous derivative over its window, so it cannot exceed a bound the
  motion keeps; the tolerance only absorbs float rounding of the differences (values ~1e2 deg,
  dt^2 ~1e-4 s^2: ~1e-9 deg/s^2), 1e-6 absolute;
* at every row the NumPy reference (:func:`arcube.evaluation.reference.evaluate_points`) finds the
  IK, eta_L <= kappa_max, and clearances within the limits less 0.5 mm: the program is checked at
  states where no body or tool point moves more than 0.5 mm (MODEL.md 17.2), and a row lies between
  two of them, so a clearance (1-Lipschitz in the points' motion) can be below the checked value by
  at most the move of the parts between a checked state and the row (0.5 mm for two parts);
  the assembly-mode signs are those of the first row;
* the tool's clearance is measured with the exact distance to the test's box
  (:func:`arcube.evaluation.sdf.box_signed_distance`), not the program's grid.

The design is one an optimizer found for the right side of the reference plan with its lines from 25 mm
outside the entry (``arcube optimize --free all,mount,L --self-clearance 3 --guarded``, seed 4): a design
the default limits accept without anatomy. The anatomy tests build their own walls (boxes).
"""

from __future__ import annotations

import csv
import itertools
import json
import math
from pathlib import Path

import numpy as np
import pytest

from arcube.cli import main
from arcube.errors import InputError
from arcube.evaluation.anatomy import Anatomy
from arcube.evaluation.reference import evaluate_points
from arcube.evaluation.sdf import box_signed_distance
from arcube.model.mechanism import forward_kinematics, inverse_kinematics
from arcube.options import Guards, Options, Outputs
from arcube.patients.anatomy import Box
from arcube import program
from arcube.motion import Planner
from arcube.motion.order import shortest_order

from compare import STATE_RTOL, STATE_TOL, assert_fields_match
from designs import PROGRAM_COLUMNS, PROGRAM_DESIGN, PROGRAM_TORQUES, program_design, right_plan

TOL = 1e-6
ROW_CLEARANCE_TOL = 0.5  # mm, MODEL.md 17.2's resolution (module docstring)
MODE = np.ones(4)


def read_rows(folder: Path) -> dict[str, np.ndarray]:
    """program.csv as arrays, parsed from the text (every number must parse as a float)."""
    with open(folder / "program.csv", newline="") as fh:
        reader = csv.reader(fh)
        header = next(reader)
        data = list(reader)
    assert header in (
        PROGRAM_COLUMNS,
        PROGRAM_COLUMNS + PROGRAM_TORQUES,
    )  # the torques of MODEL.md 18.2 follow when masses are on
    cols = list(zip(*data))
    out = {name: np.array(cols[i]) for i, name in enumerate(header) if name in ("segment", "trajectory")}
    out.update({name: np.array(cols[i], dtype=float) for i, name in enumerate(header) if name not in out})
    out["E"] = np.stack([out["E_x"], out["E_y"], out["E_z"]], axis=1)
    out["e"] = np.stack([out["e_x"], out["e_y"], out["e_z"]], axis=1)
    out["q"] = np.stack([out[n] for n in PROGRAM_COLUMNS[9:14]], axis=1)
    out["qd"] = np.stack([out[n] for n in PROGRAM_COLUMNS[14:19]], axis=1)
    return out


def _wall(centre, half, rotation=np.eye(3)) -> tuple[Anatomy, Box]:
    box = Box(np.asarray(centre, float), np.asarray(half, float), np.asarray(rotation, float), "wall")
    return Anatomy((box.mesh(),), "test wall", boxes=(box,)), box


def _tool_clearance(E: np.ndarray, e: np.ndarray, box: Box, tool_length: float, radius: float = 1.5) -> np.ndarray:
    """Exact clearance of the tool E -> E + (L + r) e (sampled every 0.1 mm) to the box, minus its radius."""
    f = np.linspace(0.0, 1.0, int(tool_length / 0.1) + 1)
    pts = E[:, None, :] + f[None, :, None] * tool_length * e[:, None, :]
    d = box_signed_distance(pts.reshape(-1, 3), box.centre, box.half_extents, box.rotation).reshape(len(E), -1)
    return d.min(axis=1) - radius


def _assembly_of(E: np.ndarray, e: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return inverse_kinematics(program_design().to_vector(), E, e, MODE).assembly


def check_rows(rows: dict[str, np.ndarray], summary: dict, ts, dt: float, anatomy: Anatomy | None = None) -> None:
    """Every oracle of the module docstring on one program."""
    p = program_design().to_vector()
    E, e, q, seg, traj = rows["E"], rows["e"], np.radians(rows["q"]), rows["segment"], rows["trajectory"]
    assert np.allclose(rows["t_s"], np.arange(len(E)) * dt, atol=1e-9, rtol=0)
    # FK of each row's angles reproduces its pose, in the first row's assembly mode
    asm0 = _assembly_of(E[:1], e[:1])[0]
    fk = forward_kinematics(p, q[:, :3], q[:, 3:], asm0)
    assert fk.valid.all()
    assert np.max(np.linalg.norm(fk.E - E, axis=1)) < TOL
    assert np.max(np.linalg.norm(fk.e - e, axis=1)) < 1e-9
    # every trajectory drilled from A to B, on its line, at the feed; approach and retract on the axis
    lim = summary["limits"]
    axes = (ts.entry - ts.target) / np.linalg.norm(ts.entry - ts.target, axis=1, keepdims=True)
    assert sorted(summary["order"]) == sorted(ts.ids)
    for j, tid in enumerate(ts.ids):
        A, B, ax = ts.entry[j], ts.target[j], axes[j]
        mine = traj == tid
        for kind in ("approach", "drill", "retract"):
            idx = np.flatnonzero(mine & (seg == kind))
            rel = E[idx] - A
            along = rel @ ax
            assert np.max(np.linalg.norm(rel - along[:, None] * ax, axis=1)) < TOL  # on the plan's axis
            assert np.allclose(e[idx], ax, atol=1e-12)
        drill = np.flatnonzero(mine & (seg == "drill"))
        approach = np.flatnonzero(mine & (seg == "approach"))
        # every segment ends exactly where it should: the approach at A, the drill at B (the row after A is the drill's first)
        assert (
            np.linalg.norm(E[approach[-1]] - A) < 1e-9
            and approach[-1] + 1 == drill[0]
            and np.linalg.norm(E[drill[-1]] - B) < 1e-9
        )
        speed = np.linalg.norm(np.diff(E[drill[0] - 1 : drill[-1] + 1], axis=0), axis=1) / dt
        assert speed.max() <= lim["feed"] * (1 + TOL) and abs(np.median(speed) - lim["feed"]) < TOL
        for kind, v in (("approach", lim["approach_speed"]), ("retract", lim["retract_speed"])):
            idx = np.flatnonzero(mine & (seg == kind))
            assert np.linalg.norm(np.diff(E[max(idx[0] - 1, 0) : idx[-1] + 1], axis=0), axis=1).max() / dt <= v * (
                1 + TOL
            )
    # finite-difference rates and accelerations, tip speed in transit
    vmax, amax = lim["max_joint_speed_deg"], lim["max_joint_accel_deg"]
    qdeg, qddeg = rows["q"], rows["qd"]
    assert np.abs(qddeg).max() <= vmax + TOL
    assert (np.abs(np.diff(qdeg, axis=0)) / dt).max() <= vmax + TOL
    assert (np.abs(np.diff(qddeg, axis=0)) / dt).max() <= amax + TOL
    assert (np.abs(qdeg[2:] - 2 * qdeg[1:-1] + qdeg[:-2]) / dt**2).max() <= amax + TOL
    tr = (seg[:-1] == "transit") & (seg[1:] == "transit")
    assert (np.linalg.norm(np.diff(E, axis=0), axis=1)[tr] / dt).max(initial=0.0) <= lim["max_tip_speed"] * (1 + TOL)
    # the NumPy reference at every row; assembly signs those of the first row
    opts = Options(guards=Guards(kappa_max=lim["kappa_max"]), outputs=Outputs(clearances=True, tip_metrics=False))
    ref = evaluate_points(p, E, e, MODE, opts, anatomy=None if anatomy is None else anatomy.distance)
    assert ref.reachable.all() and ref.eta_L.max() <= lim["kappa_max"]
    assert ref.self_clearance_mm.min() >= lim["self_clearance"] - ROW_CLEARANCE_TOL
    if anatomy is not None:
        assert ref.clearance_mm.min() >= lim["clearance"] - ROW_CLEARANCE_TOL
    assert np.all(_assembly_of(E, e) == asm0)


# ----------------------------------------------------------------------------- without anatomy


@pytest.fixture(scope="module")
def right(tmp_path_factory: pytest.TempPathFactory):
    out = tmp_path_factory.mktemp("program") / "right"
    ts = right_plan("1,3,5")
    prog = program(program_design(), ts, out, dt=0.02)
    return prog, read_rows(out), json.loads((out / "program.json").read_text()), ts


def test_program_rows_meet_every_oracle(right) -> None:
    prog, rows, summary, ts = right
    check_rows(rows, summary, ts, 0.02)
    assert len(rows["t_s"]) == len(prog.t_s) == summary["rows"]


def test_program_summary(right) -> None:
    prog, rows, summary, ts = right
    assert summary["total_s"] == pytest.approx(rows["t_s"][-1])
    assert summary["drilling_s"] + summary["approach_s"] + summary["retract_s"] + summary["transit_s"] == pytest.approx(
        summary["total_s"]
    )
    drilled = [t for t, s in zip(rows["trajectory"], rows["segment"]) if s == "drill"]
    assert list(dict.fromkeys(drilled)) == summary["order"] == prog.order
    assert [t["method"] for t in summary["transits"]] == ["straight"] * 2
    # the feed sets the drilling time: each drill takes |A - B| / feed plus the ramps (< 0.1 s at 120 deg/s^2)
    for info in summary["trajectories"]:
        assert info["drilled_mm"] / 1.5 <= info["drill_s"] <= info["drilled_mm"] / 1.5 + 0.1
    assert summary["self_clearance_min_mm"] >= 2.0 and summary["eta_L_max"] <= 100.0
    assert max(summary["joint_speed_max_deg_s"].values()) <= 30.0 + TOL


def test_shortest_order_beats_the_given_one() -> None:
    """On a plan listed out of order (C7, C3, C5), the shortest order takes no longer than the given one."""
    ts = right_plan("1,5,9")
    scrambled = type(ts)(
        ("9", "1", "5"),
        tuple(ts.levels[i] for i in (2, 0, 1)),
        tuple(ts.sides[i] for i in (2, 0, 1)),
        ts.entry[[2, 0, 1]],
        ts.target[[2, 0, 1]],
        "scrambled",
    )
    kw = dict(dt=0.05, standoff_mm=5.0)
    best = program(program_design(), scrambled, None, order="shortest", **kw)
    given = program(program_design(), scrambled, None, order="given", **kw)
    assert given.order == ["9", "1", "5"]
    assert best.order in (["1", "5", "9"], ["9", "5", "1"])
    assert best.summary["transit_s"] < given.summary["transit_s"]


def test_shortest_order_is_exact_against_brute_force() -> None:
    rng = np.random.default_rng(7)
    for n in (2, 3, 5, 7):
        cost = rng.uniform(0.5, 5.0, (n, n))
        cost[rng.uniform(size=(n, n)) < 0.15] = math.inf
        order, exact = shortest_order(cost)
        brute = min(sum(cost[a, b] for a, b in zip(p[:-1], p[1:])) for p in itertools.permutations(range(n)))
        assert exact and sorted(order) == list(range(n))
        assert sum(cost[a, b] for a, b in zip(order[:-1], order[1:])) == pytest.approx(brute) or math.isinf(brute)


# ----------------------------------------------------------------------------- walls


def _standoffs(ts, s=20.0):
    ax = (ts.entry - ts.target) / np.linalg.norm(ts.entry - ts.target, axis=1, keepdims=True)
    return ts.entry + s * ax, ax


def test_a_wall_between_two_standoffs_makes_the_planner_go_around(tmp_path: Path) -> None:
    ts = right_plan("1,3")
    S, _ = _standoffs(ts)
    anatomy, box = _wall((S[0] + S[1]) / 2, (6.0, 1.5, 6.0))
    out = tmp_path / "wall"
    prog = program(program_design(), ts, out, anatomy=anatomy, order="given", dt=0.05, seed=1)
    summary = json.loads((out / "program.json").read_text())
    rows = read_rows(out)
    (tr,) = summary["transits"]
    assert tr["method"].startswith("planned") and tr["straight_blocked_by"] == "collision/tool"
    check_rows(rows, summary, ts, 0.05, anatomy)
    tool_length = PROGRAM_DESIGN["L"] + PROGRAM_DESIGN["r"]
    # the straight move in joint space between the transit's ends is blocked by the wall (exact distance)
    idx = np.flatnonzero(rows["segment"] == "transit")
    q0, q1 = np.radians(rows["q"][idx[0]]), np.radians(rows["q"][idx[-1] + 1])
    s = np.linspace(0.0, 1.0, 201)[:, None]
    qs = q0 + s * (q1 - q0)
    fk = forward_kinematics(
        program_design().to_vector(), qs[:, :3], qs[:, 3:], _assembly_of(rows["E"][:1], rows["e"][:1])[0]
    )
    assert _tool_clearance(fk.E, fk.e, box, tool_length).min() < -0.5
    # the program's transit goes around: its tool clears the wall at every row
    assert _tool_clearance(rows["E"][idx], rows["e"][idx], box, tool_length).min() >= -ROW_CLEARANCE_TOL
    assert summary["tool_clearance_min_mm"] >= 0.0 and prog.summary["clearance_min_mm"] >= 5.0


def _impassable_wall(ts) -> tuple[Anatomy, Box]:
    """A plate between the two standoffs, parallel to both tools (which it never crosses), 60 mm along them
    and 80 mm across: going round it takes the tip beyond the reach of the design (OMPL finds no path in 60 s)."""
    S, ax = _standoffs(ts)
    eb = ax.mean(axis=0) / np.linalg.norm(ax.mean(axis=0))
    d = S[0] - S[1]
    n = (d - (d @ eb) * eb) / np.linalg.norm(d - (d @ eb) * eb)
    rot = np.stack([eb, n, np.cross(eb, n)], axis=1)
    return _wall(S.mean(axis=0) - 10.0 * eb + 3.5 * n, (30.0, 1.0, 40.0), rot)


def test_an_impassable_wall_names_the_transit_and_the_constraint(tmp_path: Path, capsys) -> None:
    ts = right_plan("1,3")
    anatomy, _ = _impassable_wall(ts)
    with pytest.raises(InputError) as info:
        program(program_design(), ts, tmp_path / "lib", anatomy=anatomy, order="given", planner=Planner(time_s=1.0))
    message = str(info.value)
    assert "\n" not in message and message.startswith("transit 1 -> 3 blocked: collision/tool at E = (")
    assert not (tmp_path / "lib").exists()
    # the same through the CLI, with the wall as an STL in the patient frame
    stl = tmp_path / "wall.stl"
    anatomy.write_stl(stl)
    out = tmp_path / "cli"
    code = _cli(
        [
            "--ids",
            "1,3",
            "--anatomy",
            str(stl),
            "--anatomy-frame",
            "patient",
            "--order",
            "given",
            "--plan-time",
            "1",
            "--out",
            str(out),
            "--quiet",
        ]
    )
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and err.startswith("error: transit 1 -> 3 blocked: collision/tool")
    assert not out.exists()


# ----------------------------------------------------------------------------- the command


def _cli(args: list[str], design: str | None = None) -> int:
    argv = ["program", "--design", design or _DESIGN_FILE[0], "--trajectories", "reference", "--side", "R", *args]
    try:
        main(argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    return 0


_DESIGN_FILE: list[str] = []


@pytest.fixture(autouse=True)
def _design_file(tmp_path_factory: pytest.TempPathFactory) -> None:
    if not _DESIGN_FILE:
        path = tmp_path_factory.mktemp("design") / "design.json"
        program_design().to_json(path)
        _DESIGN_FILE.append(str(path))


def test_cli_writes_the_program(tmp_path: Path, capsys) -> None:
    out = tmp_path / "prog"
    assert _cli(["--ids", "5", "--out", str(out), "--feed", "2", "--dt", "0.05", "--quiet"]) == 0
    text = capsys.readouterr()
    assert text.err == "" and text.out.startswith("program: order 5;")
    rows = read_rows(out)
    summary = json.loads((out / "program.json").read_text())
    assert summary["limits"]["feed"] == 2.0 and set(rows["segment"]) == {"approach", "drill", "retract"}
    check_rows(rows, summary, right_plan("5"), 0.05)
    # the motor table printed: one line per actuator, its peak torque as program.json has it
    for joint in ("rho_x", "rho_y", "rho_z", "delta_x", "delta_y"):
        (line,) = [ln for ln in text.out.splitlines() if ln.startswith(joint + " ")]
        assert float(line.split()[1]) == pytest.approx(summary["motors"][joint]["torque_peak_Nm"], rel=5e-3)


@pytest.mark.parametrize(
    ("args", "start"),
    [
        (["--feed", "0"], "error: --feed must be > 0"),
        (["--approach-speed", "-1"], "error: --approach-speed must be > 0"),
        (["--max-joint-speed", "0"], "error: --max-joint-speed must be > 0"),
        (["--max-joint-accel", "-5"], "error: --max-joint-accel must be > 0"),
        (["--max-tip-speed", "0"], "error: --max-tip-speed must be > 0"),
        (["--dt", "0"], "error: --dt must be > 0"),
        (["--dt", "nan"], "error: --dt must be a finite number"),
        (["--order", "fastest"], "error: --order must be one of shortest, given"),
        (["--mode", "+,+"], "error: --mode: working mode must be four signs"),
        (["--ids", "1", "--design", "paper"], "error: approach 1 blocked: TLS/x at E = ("),
    ],
)
def test_bad_input_one_line_exit_2_nothing_written(tmp_path: Path, capsys, args: list[str], start: str) -> None:
    out = tmp_path / "prog"
    design = None
    if "--design" in args:
        i = args.index("--design")
        design, args = args[i + 1], args[:i] + args[i + 2 :]
    code = _cli([*args, "--out", str(out), "--quiet"], design)
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and err.startswith(start), err
    assert not out.exists()


def test_unwritable_output(tmp_path: Path, capsys) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    for out, says in ((blocker, "is a file, not a folder"), (blocker / "sub", "cannot write")):
        assert _cli(["--ids", "1", "--out", str(out), "--quiet"]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"error: --out {out}") and says in err and err.count("\n") == 1
    assert blocker.read_text() == "x"


def test_a_failed_run_keeps_no_partial_program(tmp_path: Path, monkeypatch) -> None:
    """If the second file cannot be put in place (a full disk at its rename), the first is not left either."""
    import os

    real = os.replace

    def failing(src, dst):
        if str(dst).endswith("program.json"):
            raise OSError(28, "No space left on device", str(dst))
        real(src, dst)

    monkeypatch.setattr(os, "replace", failing)
    out = tmp_path / "prog"
    with pytest.raises(OSError):
        program(program_design(), right_plan("5"), out, dt=0.05)
    assert not out.exists() or not any(out.iterdir())


def test_the_timeline_figure_shows_every_segment_and_the_limits(right, tmp_path: Path) -> None:
    """program.png is written beside the CSV; its figure draws one span per run of rows (each drill
    labelled with its trajectory) and the joint limits as lines at +-30 deg/s and +-120 deg/s^2."""
    import importlib

    from arcube.report.program import JOINTS, _spans, timeline_figure

    assert (
        JOINTS == importlib.import_module("arcube.motion.output").JOINTS
    )  # the figure labels q's columns as the CSV does
    prog, rows, summary, ts = right
    assert (prog.path / "program.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    spans = _spans(np.asarray(rows["segment"]), np.asarray(rows["trajectory"]))
    assert [(s, t) for _, _, s, t in spans if s == "drill"] == [("drill", k) for k in summary["order"]]
    assert spans[0][0] == 0 and spans[-1][1] == len(rows["t_s"]) - 1
    assert all(b[0] == a[1] + 1 for a, b in zip(spans, spans[1:]))  # contiguous, no row left out
    ax_seg, ax_rate, ax_acc = timeline_figure(prog).axes
    assert [t.get_text() for t in ax_seg.texts] == summary["order"]

    def levels(ax):
        return sorted({round(float(line.get_ydata()[0]), 9) for line in ax.get_lines() if line.get_linestyle() == "--"})

    assert levels(ax_rate) == [-30.0, 30.0] and levels(ax_acc) == [-120.0, 120.0]


def test_the_compiled_check_decides_as_the_reference() -> None:
    """MODEL.md 17.2 in the compiled kernel (``engine="numba"``) against the NumPy reference: on states along
    two approach lines run past their targets and back out beyond the standoff, with the wall anatomy, and on
    joint states of the straight move through the wall, eta_L and the self clearance agree to rounding. The body
    clearance: the compiled check's is a lower bound of the exact minimum over the axes (the kernel's search
    less its tolerance, 0.1 mm), the reference's an upper bound (samples every 0.25 mm: at most 0.125 mm
    above), so the compiled one is below by 0 to 0.225 mm; every decision and reason is the same, except
    where the reference's clearance is within that gap above its limit (the compiled check is stricter).
    Every field of the result, each with its tolerance in tests/compare.py (:data:`compare.STATE_TOL`; a field
    without one fails): the pose, joints, assembly signs, tool clearance and resolution points the same bits."""
    from arcube.motion.check import Checker
    from arcube.motion.limits import ProgramLimits

    ts = right_plan("1,3")
    S, ax = _standoffs(ts)
    anatomy, _ = _wall((S[0] + S[1]) / 2, (6.0, 1.5, 6.0))
    A = np.asarray(ts.entry)
    s = np.linspace(-90.0, 40.0, 300)
    E = np.concatenate([A[j] + s[:, None] * ax[j] for j in range(2)])
    e = np.repeat(ax, len(s), axis=0)
    checkers = {
        eng: Checker(program_design().to_vector(), MODE, ProgramLimits(), distance=anatomy.distance, engine=eng)
        for eng in ("numpy", "numba")
    }
    lines = {eng: c.poses(E, e, tool=True) for eng, c in checkers.items()}
    for c in checkers.values():
        c.assembly = lines["numpy"].assembly[0]
    q0, q1 = lines["numpy"].q[0], lines["numpy"].q[len(s)]
    qs = q0 + np.linspace(0.0, 1.0, 200)[:, None] * (q1 - q0)
    joint = {eng: c.joints(qs) for eng, c in checkers.items()}
    limit = ProgramLimits().clearance
    for states in (lines, joint):
        ref, fast = states["numpy"], states["numba"]
        assert_fields_match(fast, ref, STATE_TOL, STATE_RTOL, "StateChecks")  # every field, as compare.STATE_TOL says
        near = (ref.clearance >= limit) & (ref.clearance < limit + 0.225)
        same = ~near
        assert np.array_equal(ref.ok[same], fast.ok[same]) and list(ref.reason[same]) == list(fast.reason[same])
        assert np.all(fast.ok <= ref.ok) and near.mean() < 0.05
        assert 0 < ref.ok.sum() < len(ref.ok)  # both kinds of decision are tested
        assert np.allclose(ref.eta, fast.eta, rtol=1e-9) and np.allclose(
            ref.self_clearance, fast.self_clearance, atol=1e-9, equal_nan=True
        )
        both = np.isfinite(ref.clearance)
        assert np.array_equal(both, np.isfinite(fast.clearance))
        gap = ref.clearance[both] - fast.clearance[both]
        assert np.all(gap >= -1e-9) and np.all(gap <= 0.225)
    assert {"collision/patient", "collision/tool"} & set(joint["numpy"].reason) and set(lines["numpy"].reason) - {""}
