"""Per-patient placement (--placement per-patient|shared; --docking before 0.3) of the robust problem over several trajectory sets.

Oracles: a per-patient design re-evaluated patient by patient with ``arcube.evaluate`` gives what the
run (and the study) reports; the decoded designs of a patient differ from the first patient's only
in the docked parameters; with one patient the two dockings are the same problem (bit-identical
runs); configs written before the setting shared one placement.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import arcube
from arcube.errors import InputError
from arcube.model.design import INDEX, PARAM_NAMES
from arcube.optimization import run as runmod
from arcube.optimization.config import build_config
from arcube.optimization.run_config import RunConfig
from arcube.optimization.build import build_model
from arcube.optimization.problem import VariableSpace, parse_free

REPO = Path(__file__).resolve().parents[1]
START = REPO / "tests" / "data" / "right_side_design.json"
SMALL = {
    "algorithm": "ga",
    "population": 16,
    "generations": 10,
    "points": 3,
    "engine": "numpy",
    "ftol": 0.0,
    "side": "R",
    "design_from": str(START),
}


@pytest.fixture(scope="module")
def second_patient(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The reference plan moved by (30, -20, 15) mm and turned 2 deg about z: another patient in another frame."""
    d = tmp_path_factory.mktemp("patient2")
    c, s = np.cos(np.radians(2.0)), np.sin(np.radians(2.0))
    T = np.array([[c, -s, 0.0, 30.0], [s, c, 0.0, -20.0], [0.0, 0.0, 1.0, 15.0], [0.0, 0.0, 0.0, 1.0]])
    (d / "T.json").write_text(json.dumps(T.tolist()))
    arcube.write_csv(arcube.load_trajectories("reference", transform=str(d / "T.json")), d / "p2.csv")
    return d / "p2.csv"


def test_genes_and_decode_per_patient() -> None:
    base = arcube.Design.paper().to_vector()
    free = parse_free("all,mount")
    mode = np.ones(4)
    per = VariableSpace(base=base, free=free, patients=3, placement="per-patient", setups=2, mode=mode)
    shared = VariableSpace(base=base, free=free, patients=3, placement="shared", setups=2, mode=mode)
    docked = ("m_x", "m_y", "m_z", "mount_rx", "mount_ry", "mount_rz")
    assert shared.names == (*free, "m_x_L", "m_y_L", "m_z_L") and shared.n_slots == 2
    assert per.names == (
        *free,
        "m_x_L",
        "m_y_L",
        "m_z_L",
        *(f"{n}_p2" for n in docked),
        "m_x_L_p2",
        "m_y_L_p2",
        "m_z_L_p2",
        *(f"{n}_p3" for n in docked),
        "m_x_L_p3",
        "m_y_L_p3",
        "m_z_L_p3",
    )
    assert per.n_slots == 6 and [per.slot(p, s) for p in range(3) for s in range(2)] == list(range(6))
    rng = np.random.default_rng(3)
    X = per.xl + rng.random((5, per.n_var)) * (per.xu - per.xl)
    params, _ = per.decode(X)
    assert len(params) == 6
    col = {n: i for i, n in enumerate(per.names)}
    for p in range(3):
        for s in range(2):
            got = params[per.slot(p, s)]
            others = [INDEX[n] for n in PARAM_NAMES if n not in docked]
            assert np.array_equal(got[:, others], params[0][:, others])  # links, angles, L: shared by everyone
            for n in docked:
                if s == 1 and n in ("m_x", "m_y", "m_z"):
                    gene = f"{n}_L" + (f"_p{p + 1}" if p else "")
                else:
                    gene = n + (f"_p{p + 1}" if p else "")
                assert np.array_equal(got[:, INDEX[n]], X[:, col[gene]])
    x = per.encode(base)
    assert x.shape == (per.n_var,) and all(x[col[f"m_x_p{p}"]] == base[0] for p in (2, 3))


def test_one_patient_per_patient_docking_is_the_shared_problem(tmp_path: Path) -> None:
    a = arcube.optimize("reference", out=tmp_path / "a", placement="per-patient", free="m_x,m_y,m_z,r", seed=3, **SMALL)
    b = arcube.optimize("reference", out=tmp_path / "b", placement="shared", free="m_x,m_y,m_z,r", seed=3, **SMALL)
    assert (a.path / "best_design.json").read_bytes() == (b.path / "best_design.json").read_bytes()
    assert not list(a.path.glob("best_design_p*.json"))


def test_configs_without_docking_share_the_placement(second_patient: Path) -> None:
    cfg = build_config(["reference", str(second_patient)], free="m_x,m_y,m_z,r", seed=1, **SMALL)
    assert cfg.to_toml()["settings"]["placement"] == "per-patient" and "--placement per-patient" in cfg.rerun
    assert build_model(cfg).space.n_var == 4 + 3
    table = cfg.to_toml()
    del table["settings"]["placement"]  # a config written before placement existed
    cfg = RunConfig.from_toml(table)
    assert build_model(cfg).space.placement == "shared" and build_model(cfg).space.n_var == 4


def test_per_patient_study_re_evaluates_patient_by_patient(tmp_path: Path, second_patient: Path) -> None:
    plans = ["reference", str(second_patient)]
    st = arcube.study(plans, tmp_path / "st", seeds="1-2", free="m_x,m_y,m_z,r,o_x", **{**SMALL, "generations": 25})
    assert st.summary["feasible_seeds"] == 2
    best = st.summary["best_seed"]
    run = st.runs[best]
    designs = run.designs
    assert len(designs) == 2 and designs[0] == arcube.Design.from_json(run.path / "best_design_p1.json")
    a, b = designs[0].to_vector(), designs[1].to_vector()
    assert np.array_equal(a[3:], b[3:]) and not np.array_equal(a[:3], b[:3])  # shared links, own placement
    listed = json.loads((run.path / "best_design.json").read_text())["placements"]
    assert [(p["patient"], p["m_x"]) for p in listed] == [(1, a[0]), (2, b[0])]
    assert arcube.Design.from_json(run.path / "best_design.json") == designs[0]
    summary = run.summary
    etas = []
    for k, (design, plan) in enumerate(zip(designs, plans)):
        ev = arcube.evaluate(design, arcube.load_trajectories(plan), points=3, side="R", engine="numpy")
        assert ev.summary["w_G"] and summary["tasks"][k]["eta_G"] == pytest.approx(ev.summary["eta_G"], rel=1e-12)
        etas.append(ev.summary["eta_G"])
    assert st.summary["best"] == pytest.approx(np.mean(etas), rel=1e-12)  # --aggregate mean over the patients
    assert summary["placement"] == "per-patient"
    report = arcube.write_report(run)
    assert report.name == "report.html" and (run.path / "report_p2.html").exists()
    assert second_patient.name in (run.path / "report_p2.html").read_text()


def test_shared_docking_keeps_one_placement(tmp_path: Path, second_patient: Path) -> None:
    run = arcube.optimize(
        ["reference", str(second_patient)],
        out=tmp_path / "sh",
        placement="shared",
        free="m_x,m_y,m_z,r",
        seed=2,
        **SMALL,
    )
    assert "placements" not in json.loads((run.path / "best_design.json").read_text())
    assert run.designs[0] == run.designs[1] == run.best_design


def test_bad_docking_is_one_line_and_leaves_nothing(tmp_path: Path, second_patient: Path) -> None:
    with pytest.raises(InputError, match="RunSettings.placement must be one of per-patient, shared"):
        build_config(["reference", str(second_patient)], placement="each", seed=1, **SMALL)
    out = tmp_path / "run"
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "arcube",
            "optimize",
            "--trajectories",
            "reference",
            str(second_patient),
            "--placement",
            "both",
            "--out",
            str(out),
            "--quiet",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 2 and res.stderr == "error: --placement must be one of per-patient, shared, got 'both'\n"
    assert not out.exists()
    assert runmod.placement_file(1) == "best_design_p2.json" and runmod.placement_file(0, 1) == "best_design_p1_L.json"


def test_per_patient_files_with_two_setups_and_a_missing_design_is_an_error(
    tmp_path: Path, second_patient: Path
) -> None:
    both = {**SMALL, "side": None, "generations": 3}
    run = arcube.optimize(
        ["reference", str(second_patient)], out=tmp_path / "two", setups=2, free="m_x,m_y,m_z,r", seed=1, **both
    )
    names = sorted(p.name for p in run.path.glob("best_design*.json"))
    assert names == [
        "best_design.json",
        "best_design_L.json",
        "best_design_p1.json",
        "best_design_p1_L.json",
        "best_design_p2.json",
        "best_design_p2_L.json",
    ]
    assert (run.path / "best_design_L.json").read_bytes() == (run.path / "best_design_p1_L.json").read_bytes()
    listed = json.loads((run.path / "best_design.json").read_text())["placements"]
    assert [(p["patient"], p["side"]) for p in listed] == [(1, "R"), (1, "L"), (2, "R"), (2, "L")]
    (run.path / "best_design_p2.json").unlink()
    with pytest.raises(InputError, match="best_design_p2.json"):
        _ = run.designs
    with pytest.raises(InputError, match="best_design_p2.json is missing"):
        arcube.write_report(run)
