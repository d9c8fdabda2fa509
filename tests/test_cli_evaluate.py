"""``arcube evaluate``: the JSON contract, the table, and one-line errors with exit code 2."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from arcube.model.design import PARAM_NAMES, Design

from designs import REFERENCE_CSV
from harness import arcube, run_cli

JACOBIANS = {"J_LV", "J_AV", "J_sigma", "J_AS", "J_AP", "J_rho", "J_delta"}
HEADER = "trajectory,level,side,entry_x,entry_y,entry_z,target_x,target_y,target_z"


def test_json_contract_on_reachable_side(right_side_design: Path) -> None:
    out = arcube(
        "evaluate",
        "--design",
        str(right_side_design),
        "--trajectories",
        str(REFERENCE_CSV),
        "--side",
        "R",
        "--points",
        "7",
        "--json",
    )
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    assert set(doc["design"]) == set(PARAM_NAMES) and doc["mode"] == "+,+,+,+"
    assert len(doc["points"]) == 5 * 7
    rows = [r for r in csv.DictReader(REFERENCE_CSV.open()) if r["side"] == "R"]
    for p in doc["points"]:
        row = rows[[r["trajectory"] for r in rows].index(p["trajectory"])]
        entry = np.array([float(row[f"entry_{a}"]) for a in "xyz"])
        target = np.array([float(row[f"target_{a}"]) for a in "xyz"])
        np.testing.assert_allclose([p["x"], p["y"], p["z"]], entry + p["k"] / 6 * (target - entry), atol=1e-12)
        e = (entry - target) / np.linalg.norm(entry - target)
        assert np.isclose(np.sin(np.radians(p["theta_deg"])), e[0])
        assert p["reachable"] is True and p["failure"] is None
        assert set(p["kappa"]) == JACOBIANS and all(k >= 1.0 for k in p["kappa"].values())
        assert p["eta_L"] == pytest.approx(max(p["kappa"].values()))
        assert p["dexterity_pct"] == pytest.approx(100.0 / p["eta_L"])
        assert len(p["rho_deg"]) == 3 and len(p["delta_deg"]) == 2 and len(p["sigma_deg"]) == 2
    s = doc["summary"]
    assert s["n_points"] == 35 and s["w_G"] is True and s["reachable_fraction"] == 1.0
    assert s["eta_G"] == pytest.approx(np.mean([p["eta_L"] for p in doc["points"]]))
    dex = [p["dexterity_pct"] for p in doc["points"]]
    assert s["dexterity_pct"] == pytest.approx({"min": min(dex), "mean": float(np.mean(dex)), "max": max(dex)})


def test_unreachable_points_are_null_not_infinite() -> None:
    out = arcube(
        "evaluate", "--design", "paper", "--trajectories", "reference", "--points", "3", "--json", "--mode=-,+,+,-"
    )
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)  # json.loads would accept Infinity/NaN; check none were written
    assert "Infinity" not in out.stdout and "NaN" not in out.stdout
    assert doc["mode"] == "-,+,+,-"
    assert doc["summary"]["w_G"] is False and doc["summary"]["eta_G"] is None
    for p in doc["points"]:
        assert p["reachable"] is False and p["failure"] == "TLS/x"
        assert p["dexterity_pct"] == 0.0 and p["eta_L"] is None
        assert all(v is None for v in p["kappa"].values())


def test_table_names_the_failure_and_why() -> None:
    out = arcube("evaluate", "--design", "paper", "--trajectories", "reference")
    assert out.returncode == 0, out.stderr
    assert "TLS/x: 300" in out.stdout
    assert "RTS/x" in out.stdout and "no placement m can fix this" in out.stdout


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _bad_design(tmp_path: Path, **changes: object) -> Path:
    values: dict[str, object] = Design.preset("paper").to_dict()
    for k, v in changes.items():
        if v is None:
            del values[k]
        else:
            values[k] = v
    return _write(tmp_path / "design.json", json.dumps(values))


@pytest.mark.parametrize(
    ("case", "needle"),
    [
        ("missing_file", "no_such.csv"),
        ("missing_column", "target_z"),
        ("non_numeric", "entry_y"),
        ("nan", "row"),
        ("entry_equals_target", "entry"),
        ("design_missing", "missing parameter(s) r"),
        ("design_unknown", "unknown parameter 'q_z'"),
        ("design_negative", "length p_x must be positive"),
        ("bad_mode", "--mode"),
        ("bad_mode_signs", "--mode"),
        ("few_points", "--points"),
        ("unknown_flag", "--frobnicate"),
        ("unwritable_report", "/proc/arcube-no"),
    ],
)
def test_bad_input_exits_2_with_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], case: str, needle: str
) -> None:
    """In this process (arcube.cli.main, as ``python -m arcube`` runs it; one case in a process of its own below)."""
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli(_bad_input_argv(tmp_path, case), capsys)
    _assert_one_line_exit_2(tmp_path, code, out, err, needle)


def test_bad_input_in_a_process_of_its_own_exits_2_with_one_line(tmp_path: Path) -> None:
    """The same contract through ``python -m arcube`` (start-up, interrupt handling and the real stderr)."""
    out = arcube(*_bad_input_argv(tmp_path, "non_numeric"), cwd=tmp_path)
    _assert_one_line_exit_2(tmp_path, out.returncode, out.stdout, out.stderr, "entry_y")


def _bad_input_argv(tmp_path: Path, case: str) -> list[str]:
    good = REFERENCE_CSV.read_text().splitlines()
    traj = str(REFERENCE_CSV)
    extra: list[str] = []
    design = "paper"
    if case == "missing_file":
        traj = str(tmp_path / "no_such.csv")
    elif case == "missing_column":
        traj = str(_write(tmp_path / "t.csv", HEADER.rsplit(",", 1)[0] + "\n1,C3,R,1,2,3,4,5\n"))
    elif case == "non_numeric":
        traj = str(_write(tmp_path / "t.csv", f"{HEADER}\n1,C3,R,1,abc,3,4,5,6\n"))
    elif case == "nan":
        traj = str(_write(tmp_path / "t.csv", f"{HEADER}\n{good[1]}\n2,C3,L,1,nan,3,4,5,6\n"))
    elif case == "entry_equals_target":
        traj = str(_write(tmp_path / "t.csv", f"{HEADER}\n1,C3,R,1,2,3,1,2,3\n"))
    elif case == "design_missing":
        design = str(_bad_design(tmp_path, r=None))
    elif case == "design_unknown":
        design = str(_bad_design(tmp_path, q_z=10.0))  # c_z is a design file's own field (MODEL.md 19)
    elif case == "design_negative":
        design = str(_bad_design(tmp_path, p_x=-1.0))
    elif case == "bad_mode":
        extra = ["--mode=+,+,+"]
    elif case == "bad_mode_signs":
        extra = ["--mode=+,x,+,-"]
    elif case == "few_points":
        extra = ["--points", "1"]
    elif case == "unknown_flag":
        extra = ["--frobnicate"]
    elif case == "unwritable_report":  # /proc refuses new folders, even to root
        extra = ["--report", "/proc/arcube-no/report.html"]
    return ["evaluate", "--design", design, "--trajectories", traj, *extra]


def _assert_one_line_exit_2(tmp_path: Path, code: int, out: str, err: str, needle: str) -> None:
    assert code == 2, (out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("error: ") and needle in lines[0]
    assert "Traceback" not in err and out == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        p.name for p in tmp_path.iterdir() if p.suffix in {".csv", ".json"}
    )


def test_slicer_markups_evaluate_like_the_csv(tmp_path: Path, right_side_design: Path) -> None:
    """The same trajectories from a .mrk.json (LPS, as Slicer writes) give the same evaluation point for point."""
    from arcube.io.slicer import write_markups
    from arcube.io import load_trajectories

    mrk = tmp_path / "plan.mrk.json"
    write_markups(load_trajectories(REFERENCE_CSV), mrk)
    stored = json.loads(mrk.read_text())
    assert {m["coordinateSystem"] for m in stored["markups"]} <= {"LPS", "RAS"}
    docs = []
    for traj in (str(REFERENCE_CSV), str(mrk)):
        out = arcube("evaluate", "--design", str(right_side_design), "--trajectories", traj, "--points", "5", "--json")
        assert out.returncode == 0, out.stderr
        docs.append(json.loads(out.stdout))
    csv_doc, mrk_doc = docs
    assert len(csv_doc["points"]) == len(mrk_doc["points"]) == 50
    for a, b in zip(csv_doc["points"], mrk_doc["points"]):
        assert a["trajectory"] == b["trajectory"] and a["k"] == b["k"] and a["reachable"] == b["reachable"]
        for key in ("x", "y", "z", "psi_deg", "theta_deg", "dexterity_pct"):
            assert a[key] == pytest.approx(b[key], abs=1e-9)
        for name in JACOBIANS:
            assert (a["kappa"][name] is None) == (b["kappa"][name] is None)
            if a["kappa"][name] is not None:
                assert a["kappa"][name] == pytest.approx(b["kappa"][name], rel=1e-9)
    assert csv_doc["summary"]["reachable_fraction"] == mrk_doc["summary"]["reachable_fraction"] == 0.5
