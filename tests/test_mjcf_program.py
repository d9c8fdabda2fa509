"""MuJoCo replay of a drilling program (``arcube export --program``, :mod:`arcube.export.replay`).

Oracles are the program's own files, read back as text by this test (``program.csv``: the tip E that
our IK put on the plan's lines, the angles, the times), never the exporter's output:

* the model is assembled at the program's first row: its keyframe puts MuJoCo's ``tip`` site on row 0's
  E (MuJoCo's own forward kinematics);
* the replay has one row per program row, at the same times, and its actuator targets are the
  program's angles (deg -> rad); its hinge angles, set in MuJoCo, put the tip on every row's E and
  leave every loop closure at rest (a kinematic replay);
* driven only through its five position actuators (``examples/mujoco_replay.py``: targets plus the
  inverse-dynamics feed-forward, gravity off), MuJoCo's closed-loop dynamics keep the tip within
  0.05 mm of the program's E on every drill row;
* the design comes from ``--design`` or from the folder (program.json's ``design``, or an ``arcube
  design`` job's design.json); a design that does not run the program, and bad input, end as one
  ``error:`` line, exit 2, and no file.

The program: trajectory 1 of the reference plan's right side, on the design of tests/test_program.py
(an optimizer's design that the default limits accept); c_z = 400 mm closes its z dyad at every row
(the exporter names the range [325.9, 485.8] mm, checked below). About 25 s of program, 2518 rows.
"""

from __future__ import annotations

import csv
import dataclasses
import importlib.util
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from arcube.cli import main  # noqa: E402
from arcube.errors import InputError  # noqa: E402
from arcube.export.mjcf import ACTUATED, JOINT_NAMES  # noqa: E402
from arcube.export.replay import export_program, read_program  # noqa: E402
from arcube.io import load_trajectories, select  # noqa: E402
from arcube.model.design import Design  # noqa: E402
from arcube import program  # noqa: E402

from designs import PROGRAM_DESIGN  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "mujoco_replay.py"
DESIGN = PROGRAM_DESIGN
"""designs.PROGRAM_DESIGN, the design of tests/test_program.py (a setup, not an oracle)."""
C_Z = "400"


def _program_csv(folder: Path) -> dict[str, np.ndarray]:
    """program.csv parsed from its text: t (n,), segment (n,), E (n, 3) mm, q (n, 5) deg."""
    with open(folder / "program.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    col = lambda names: np.array([[float(r[n]) for n in names] for r in rows])  # noqa: E731
    return {
        "t": col(["t_s"])[:, 0],
        "segment": np.array([r["segment"] for r in rows]),
        "E": col(["E_x", "E_y", "E_z"]),
        "e": col(["e_x", "e_y", "e_z"]),
        "q": col(list(ACTUATED)),
    }


def _cli(args: list[str]) -> int:
    try:
        main(["export", *args])
    except SystemExit as exc:
        return int(exc.code or 0)
    return 0


@pytest.fixture(scope="module")
def prog(tmp_path_factory: pytest.TempPathFactory):
    root = tmp_path_factory.mktemp("replay")
    folder = root / "program"
    built = program(Design.from_dict(DESIGN), select(load_trajectories("reference"), side="R", ids="1"), folder)
    design_file = root / "design.json"
    Design.from_dict(DESIGN).to_json(design_file)
    return built, folder, design_file


@pytest.fixture(scope="module")
def exported(prog, tmp_path_factory: pytest.TempPathFactory):
    _, folder, design_file = prog
    out = tmp_path_factory.mktemp("export") / "robot.xml"
    assert _cli(["--program", str(folder), "--design", str(design_file), "--c-z", C_Z, "--out", str(out)]) == 0
    return out, out.with_name("robot.replay.csv")


def test_model_at_first_row_and_kinematic_replay_reproduce_the_program(prog, exported) -> None:
    _, folder, _ = prog
    xml, replay = exported
    rows = _program_csv(folder)
    model = mujoco.MjModel.from_xml_path(str(xml))
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("assembled").id)
    mujoco.mj_forward(model, data)
    assert np.linalg.norm(data.site("tip").xpos - rows["E"][0]) < 1e-9
    with open(replay, newline="") as fh:
        rp = list(csv.DictReader(fh))
    assert len(rp) == len(rows["t"]) and len(rows["t"]) > 2000
    assert np.array_equal([float(r["t_s"]) for r in rp], rows["t"])
    assert [r["segment"] for r in rp] == list(rows["segment"])
    ctrl = np.array([[float(r[f"ctrl_{n}"]) for n in ACTUATED] for r in rp])
    np.testing.assert_allclose(ctrl, np.radians(rows["q"]), rtol=0, atol=1e-15)
    np.testing.assert_allclose(ctrl[0], model.key("assembled").ctrl, rtol=0, atol=1e-15)
    qpos = np.array([[float(r[f"qpos_{n}"]) for n in JOINT_NAMES] for r in rp])
    np.testing.assert_allclose(qpos[0], model.key("assembled").qpos, rtol=0, atol=1e-12)
    adr = [model.joint(n).qposadr[0] for n in JOINT_NAMES]
    tip, closure = 0.0, 0.0
    for i in range(len(rp)):
        data.qpos[adr] = qpos[i]
        mujoco.mj_forward(model, data)
        tip = max(tip, float(np.linalg.norm(data.site("tip").xpos - rows["E"][i])))
        closure = max(closure, float(np.abs(data.efc_pos[: data.nefc]).max()))
    print(f"kinematic replay: tip {tip:.2e} mm, closures {closure:.2e} mm over {len(rp)} rows")
    assert tip < 1e-6 and closure < 1e-6
    assert np.abs(np.diff(qpos, axis=0)).max() < 0.05  # continuous (no 2 pi jump) along 10 ms rows


def _example():
    spec = importlib.util.spec_from_file_location("mujoco_replay", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_mujoco_dynamics_keep_the_tip_on_the_program_while_drilling(prog, exported) -> None:
    """Gravity off, five position actuators only (targets + inverse-dynamics feed-forward, the example's
    controller): the tip stays within 0.05 mm of the program's E on every drill row."""
    _, folder, _ = prog
    xml, replay = exported
    rows = _program_csv(folder)
    ex = _example()
    model = mujoco.MjModel.from_xml_path(str(xml))
    model.opt.gravity[:] = 0.0
    model.opt.jacobian = mujoco.mjtJacobian.mjJAC_DENSE
    tips = ex.replay(model, ex.read_replay(str(replay)))
    err = np.linalg.norm(tips - rows["E"], axis=1)
    drill = rows["segment"] == "drill"
    print(f"tip error: drill {err[drill].max():.4f} mm over {drill.sum()} rows, whole program {err.max():.4f} mm")
    assert drill.sum() > 1000
    assert err[drill].max() < 0.05
    assert err.max() < 0.1


def test_example_script_replays_the_exported_program(prog, exported) -> None:
    _, folder, _ = prog
    xml, replay = exported
    run = subprocess.run(
        [sys.executable, str(EXAMPLE), str(xml), str(replay)], capture_output=True, text=True, timeout=300
    )
    assert run.returncode == 0, run.stderr
    last = run.stdout.strip().splitlines()[-1]
    print(last)
    value, n = last.split("max tip error on drill segments: ")[1].split(" mm over ")
    assert int(n.split()[0]) == int(np.sum(_program_csv(folder)["segment"] == "drill"))
    assert float(value) < 0.05


def _with_c_z() -> Design:
    """The program's design with the c_z that closes its z dyad at every row (c_z is the design's, model §19.1)."""
    return Design.from_dict(DESIGN).with_extras(c_z=float(C_Z))


def test_design_from_the_folder_and_unknown_columns(prog, tmp_path: Path) -> None:
    """An ``arcube design`` job folder (summary.json lists program/), a design.json in the folder or
    program.json's ``design`` give the design; columns beyond MODEL.md 17.3 (``tau_*_Nm``) are ignored;
    a Program object exports alike."""
    built, folder, design_file = prog
    reference = export_program(folder, _with_c_z())
    job = tmp_path / "job"
    shutil.copytree(folder, job / "program")
    shutil.copy(design_file, job / "design.json")
    (job / "summary.json").write_text(json.dumps({"files": {"design": "design.json", "program": "program"}}))
    with open(
        folder / "program.csv", newline=""
    ) as fh:  # a later program.csv with a column of its own (beside the torques)
        lines = fh.read().splitlines()
    (job / "program" / "program.csv").write_text(
        "\n".join([lines[0] + ",power_W"] + [ln + ",1.5" for ln in lines[1:]]) + "\n"
    )
    out = tmp_path / "a" / "robot.xml"
    assert _cli(["--program", str(job / "program"), "--c-z", C_Z, "--out", str(out)]) == 0
    assert out.with_name("robot.replay.csv").read_text() == reference.replay_csv
    assert out.read_text() == reference.xml.replace(str(folder), str(job / "program"))
    alone = tmp_path / "alone"
    shutil.copytree(folder, alone)
    summary = json.loads((alone / "program.json").read_text())
    (alone / "program.json").write_text(json.dumps({**summary, "design": {**DESIGN, "c_z": float(C_Z)}}))
    assert export_program(alone).replay_csv == reference.replay_csv  # the recorded design carries its c_z
    inside = tmp_path / "inside"
    shutil.copytree(folder, inside)
    _with_c_z().to_json(inside / "design.json")  # the design file beside the program, when program.json records none
    (inside / "program.json").write_text(json.dumps({k: v for k, v in summary.items() if k != "design"}))
    assert export_program(inside).replay_csv == reference.replay_csv
    assert export_program(built, _with_c_z()).replay_csv == reference.replay_csv


def test_whole_turns_of_delta_are_the_program_s(prog) -> None:
    """A program may turn delta by whole turns (it keeps delta continuous): the model's actuated hinge then
    starts at the program's angle, so the replay's targets never ask for a spurious turn; a design whose IK
    disagrees by anything else is refused, naming the row and the joint."""
    _, folder, _ = prog
    rows = read_program(folder)
    turned = dataclasses.replace(rows, q_deg=rows.q_deg + np.array([0.0, 0.0, 0.0, 360.0, -720.0]))
    ex = export_program(turned, _with_c_z())
    model = mujoco.MjModel.from_xml_string(ex.xml)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(model.key("assembled").ctrl, np.radians(turned.q_deg[0]), rtol=0, atol=1e-12)
    assert np.linalg.norm(data.site("tip").xpos - rows.E[0]) < 1e-9
    first = next(csv.DictReader(ex.replay_csv.splitlines()))
    assert float(first["ctrl_delta_y"]) == pytest.approx(np.radians(rows.q_deg[0, 4]) - 4 * np.pi, abs=1e-12)
    off = dataclasses.replace(
        rows, q_deg=rows.q_deg + np.array([0.0, 0.0, 0.0, 0.0, 1e-3]) * (np.arange(len(rows.t_s)) == 7)[:, None]
    )
    with pytest.raises(
        InputError,
        match=r"^design does not run this program: it gives delta_y = .* deg at row 7 \(t = 0\.07 s, approach 1\)",
    ):
        export_program(off, _with_c_z())


@pytest.mark.parametrize(
    ("args", "start"),
    [
        (["--c-z", C_Z], "error: --design is required: the program records no design"),
        (
            ["--design", "paper", "--c-z", C_Z],
            "error: --design does not run this program: it has no IK solution at row 0",
        ),
        (["--design", "{design}", "--c-z", "60"], r"error: --c-z in [325.86, 485.80] mm closes the z-leg dyad"),
        (
            ["--design", "{design}", "--c-z", C_Z, "--at", "1:0", "--points", "5"],
            "error: --at, --points: not with --program",
        ),
        (
            ["--design", "{design}", "--c-z", C_Z, "--program", "{missing}"],
            "error: --program {missing}: no such folder",
        ),
        (
            ["--design", "{design}", "--c-z", C_Z, "--out", "{replay_blocked}"],
            "error: --out {replay_blocked}: cannot write",
        ),
    ],
    ids=["no-design", "wrong-design", "z-dyad", "plan-options", "missing-folder", "replay-unwritable"],
)
def test_cli_bad_input_one_line_exit_2_no_file(prog, tmp_path: Path, capsys, args: list[str], start: str) -> None:
    _, folder, design_file = prog
    if "--design" not in args:  # a program folder from before program.json recorded its design
        old = tmp_path.parent / f"{tmp_path.name}-old-program"
        shutil.copytree(folder, old)
        summary = json.loads((old / "program.json").read_text())
        summary.pop("design")
        (old / "program.json").write_text(json.dumps(summary))
        folder = old
    (tmp_path / "robot.replay.csv").mkdir()  # only the replay-unwritable case writes to robot.xml here
    out = tmp_path / "out" / "robot.xml"
    names = {
        "design": str(design_file),
        "missing": str(tmp_path / "nothing"),
        "replay_blocked": str(tmp_path / "robot.xml"),
    }
    args = [a.format(**names) for a in args]
    if "--out" not in args:
        args += ["--out", str(out)]
    code = _cli(["--program", str(folder), *args])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and err.startswith(start.format(**names)), err
    assert not out.parent.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["robot.replay.csv"]  # no model left behind
