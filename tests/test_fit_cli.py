"""``arcube evaluate`` with an anatomy and a 27-parameter design: the JSON contract of the issue
"Fit the patient", and its bad inputs (one line, exit 2, no traceback, nothing written)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
import trimesh

from arcube.model.body import PART_NAMES
from arcube.model.design import Design

from designs import REFERENCE_CSV, RIGHT_SIDE_M
from harness import arcube, run_cli


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("fit")
    design = d / "design27.json"
    Design.preset("paper").replace(**RIGHT_SIDE_M).to_json(design)
    assert len(json.loads(design.read_text())) == 27  # a 27-key design (MODEL.md 13)
    box = trimesh.creation.box(extents=(40.0, 40.0, 40.0))
    box.apply_translation((0.0, 0.0, -60.0))  # in front of the spine (patient frame), well away from the tips
    mesh = d / "block.stl"
    box.export(mesh)
    bad_key = d / "bad_key.json"
    text = design.read_text().replace('"mount_rx"', '"mount_rq"')
    bad_key.write_text(text)
    garbage = d / "garbage.stl"
    garbage.write_bytes(b"solid x\nthis is not an stl\n")
    return {"design": design, "mesh": mesh, "bad_key": bad_key, "garbage": garbage}


def test_json_contract_with_a_mesh_in_the_patient_frame(files) -> None:
    out = arcube(
        "evaluate",
        "--design",
        str(files["design"]),
        "--trajectories",
        str(REFERENCE_CSV),
        "--side",
        "R",
        "--points",
        "4",
        "--anatomy",
        str(files["mesh"]),
        "--anatomy-frame",
        "patient",
        "--json",
    )
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    pts = doc["points"]
    assert all({"clearance_mm", "clearance_part", "self_clearance_mm"} <= set(p) for p in pts)
    reach = [p for p in pts if p["reachable"]]
    assert reach and all(p["clearance_part"] in PART_NAMES for p in reach)
    s = doc["summary"]
    assert s["clearance_min_mm"] == min(p["clearance_mm"] for p in reach)
    assert s["clearance_min_part"] in PART_NAMES and isinstance(s["self_clearance_min_mm"], float)
    assert all(math.isfinite(p["clearance_mm"]) for p in reach)


@pytest.mark.parametrize(
    "extra, needle",
    [
        (["--anatomy", "missing.stl"], "missing.stl"),
        (["--anatomy", "GARBAGE"], "garbage.stl"),
        (["--anatomy", "MESH", "--anatomy-frame", "XYZ"], "--anatomy-frame"),
        (["--link-radius", "-1"], "--link-radius"),
        (["--motor-length", "nan"], "--motor-length"),
        (["--anatomy", "MESH", "--clearance", "-1"], "--clearance"),
        (["--anatomy", "MESH", "--clearance", "nan"], "--clearance"),
        (["--clearance", "5"], "needs an anatomy"),
        (["--design", "BADKEY"], "mount_rq"),
    ],
)
def test_bad_input_is_one_line_exit_2_and_writes_nothing(
    files, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], extra, needle
) -> None:
    """In this process (arcube.cli.main, as ``python -m arcube`` runs it; one case in a process of its own below)."""
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli(_bad_input_argv(files, tmp_path, extra), capsys)
    _assert_refused(tmp_path, code, out, err, needle)


def test_bad_input_in_a_process_of_its_own_is_one_line_exit_2(files, tmp_path: Path) -> None:
    """The same contract through ``python -m arcube`` (start-up, interrupt handling, the real stderr)."""
    out = arcube(*_bad_input_argv(files, tmp_path, ["--anatomy", "GARBAGE"]), cwd=tmp_path)
    _assert_refused(tmp_path, out.returncode, out.stdout, out.stderr, "garbage.stl")


def _bad_input_argv(files, tmp_path: Path, extra: list[str]) -> list[str]:
    subst = {"MESH": str(files["mesh"]), "GARBAGE": str(files["garbage"]), "BADKEY": str(files["bad_key"])}
    args = [subst.get(a, a) for a in extra]
    base = ["evaluate", "--trajectories", str(REFERENCE_CSV), "--points", "3", "--report", str(tmp_path / "r.html")]
    if "--design" not in args:
        base += ["--design", str(files["design"])]
    return [*base, *args]


def _assert_refused(tmp_path: Path, code: int, out: str, err: str, needle: str) -> None:
    assert code == 2, (out, err)
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert needle in err, err
    assert not (tmp_path / "r.html").exists() and not list(tmp_path.glob("*.png"))
