"""House II item 4: c_z, the z-leg dyad's second link (model §6, 19.1), has one home, the design. ``--c-z`` sets the
design's value (export, optimize); a run records it in its start design and its result; export's keyword is an
alias for one release; a new run's options never hold one; an older folder (where --c-z set the guard's c_z) resumes
as it ran."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from harness import run_cli, skip_unless_replays_here

import arcube
from arcube.errors import InputError, RenamedWarning
from arcube.export.mjcf import export_mjcf
from arcube.optimization.build import build_model
from arcube.optimization.config import build_config
from arcube.optimization.run_config import RunConfig
from arcube.optimization.settings import RunSettings

PLACED = arcube.Design.paper().replace(m_x=88.23, m_y=79.40, m_z=56.89)
"""The paper's robot placed where it reaches the reference patient's right side (tests/test_hardening.py)."""


def _right() -> arcube.TrajectorySet:
    return arcube.select(arcube.load_trajectories("reference"), side="R")


def test_export_takes_c_z_from_the_design_and_the_old_keyword_warns() -> None:
    own = export_mjcf(PLACED.with_extras(c_z=160.0), _right())
    with pytest.warns(RenamedWarning, match=r"^export_mjcf\(c_z=\.\.\.\) is now the design's c_z"):
        old = export_mjcf(PLACED, _right(), c_z=160.0)
    assert old == own and "c_z = 160 mm" in own
    other = export_mjcf(PLACED.with_extras(c_z=165.0), _right())
    assert other != own  # the design's c_z is what is built
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RenamedWarning)
        with pytest.raises(InputError, match=r"^c_z must be a finite number of mm > 0, got -1"):
            export_mjcf(PLACED, _right(), c_z=-1.0)


def test_the_c_z_flag_of_export_sets_the_design_s(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    design = tmp_path / "d.json"
    PLACED.with_extras(c_z=150.0, mode="+,+,+,+").to_json(
        design
    )  # the flag wins over the file's own, as it sets the design's value
    out = tmp_path / "robot.xml"
    args = ["export", "--design", str(design), "--side", "R", "--c-z", "160", "--out", str(out)]
    assert run_cli(args, capsys)[0] == 0
    assert out.read_text() == export_mjcf(PLACED.with_extras(c_z=160.0), _right())
    code, _, err = run_cli(
        ["export", "--design", str(design), "--side", "R", "--c-z", "-3", "--out", str(out), "--force"], capsys
    )
    assert code == 2 and "error: --c-z must be a finite number of mm > 0, got -3.0" in err


def test_a_run_s_c_z_is_its_start_design_s(tmp_path: Path) -> None:
    """``--c-z`` sets the start design's c_z: config.toml's [design] carries it, the search evaluates every design
    with it (the problem's c_z of each candidate), and it wins over a design file's own."""
    cfg = build_config([arcube.load_trajectories("reference")], RunSettings(c_z=250.0, population=8, generations=1))
    assert cfg.design["c_z"] == 250.0 and cfg.settings.c_z == 250.0
    X = np.zeros((3, build_model(cfg).space.n_var))
    np.testing.assert_array_equal(build_model(cfg).space.c_z(X), [250.0] * 3)
    design = tmp_path / "d.json"
    PLACED.with_extras(c_z=150.0, mode="+,+,+,+").to_json(design)
    own = build_config([arcube.load_trajectories("reference")], RunSettings(design_from=str(design)))
    assert own.design["c_z"] == 150.0
    flag = build_config(
        [arcube.load_trajectories("reference")], RunSettings(design_from=str(design), c_z=250.0, population=8)
    )
    assert flag.design["c_z"] == 250.0
    assert RunConfig.from_toml(flag.to_toml()) == flag


def test_a_new_run_s_options_hold_no_c_z() -> None:
    with pytest.raises(InputError, match=r"^RunSettings.options.guards.c_z is the design's in a run") as info:
        build_config([arcube.load_trajectories("reference")], RunSettings(options=arcube.Options(c_z=300.0)))
    assert info.value.param == "RunSettings.options.guards.c_z"
    assert RunSettings(c_z=300.0).options.guards.c_z is None  # the keyword is the run's own field, not the guard's


def test_an_older_folder_s_c_z_stays_the_guard_s() -> None:
    """Before, ``--c-z`` wrote ``c_z`` in [settings] and nothing in [design]: such a folder is read as it ran (the
    z-dyad guard's c_z, model §6), and written back the same; a new run's c_z is in its [design] too."""
    cfg = build_config([arcube.load_trajectories("reference")], RunSettings(population=8))
    table = cfg.to_toml()
    table["settings"] = {**table["settings"], "c_z": 320.0}
    assert "c_z" not in table["design"]
    back = RunConfig.from_toml(table)
    assert "c_z" not in back.design and back.settings.c_z is None and back.settings.options.guards.c_z == 320.0
    assert back.settings.evaluation_options().guards.c_z == 320.0 and build_model(back).space.base_c_z is None
    assert back.to_toml()["settings"]["c_z"] == 320.0 and RunConfig.from_toml(back.to_toml()) == back
    assert RunConfig.from_toml(back.to_toml()).with_seed(5).settings.options.guards.c_z == 320.0  # a study's seed


@pytest.mark.parametrize("case", ["fixed", "free"])
def test_an_older_folder_with_c_z_killed_midway_resumes_as_it_ran(case: str, tmp_path: Path) -> None:
    """tests/data/run_c_z_guard (its README): folders of the code before, with ``--c-z 300`` (c_z fixed with the
    z-dyad guard on; c_z free from 300), killed after generation 3. Resumed here, each ends where the same run,
    uninterrupted by that code, ended: the same best design (bytes) and the same history. Skipped on a machine whose
    floating point does not reproduce the folders (made on X86_V3, README), once a fresh run of their config by this
    code is shown to run as the old code did (:func:`harness.skip_unless_replays_here`)."""
    import csv
    import shutil

    data = Path(__file__).parent / "data" / "run_c_z_guard"
    skip_unless_replays_here(data / f"{case}_killed", data / f"{case}_whole" / "history.csv", tmp_path)
    old = tmp_path / "old"
    shutil.copytree(data / f"{case}_killed", old)
    arcube.resume(old)
    whole = data / f"{case}_whole"
    mode = b',\n  "mode": "+,+,+,+"\n}'  # the run's working mode (its config.toml's), which design files now carry
    assert (old / "best_design.json").read_bytes() == (whole / "best_design.json").read_bytes().replace(b"\n}", mode)

    def untimed(path: Path) -> list[dict[str, str]]:
        return [{k: v for k, v in row.items() if k != "seconds"} for row in csv.DictReader(path.open())]

    assert untimed(old / "history.csv") == untimed(whole / "history.csv") and len(untimed(whole / "history.csv")) == 8


def test_a_run_s_report_evaluates_its_designs_with_their_c_z(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``arcube report`` takes c_z from the design the run wrote (it used to drop a design's own c_z and keep only
    the guard's); a folder written before, whose best_design.json has none, takes its ``[settings]`` c_z."""
    import json

    from arcube.report import run_report

    seen: list[tuple[float | None, float | None]] = []
    real = run_report.evaluate_design

    def spy(design, plan, points, signs, options, *args, **kwargs):  # noqa: ANN001, ANN002, ANN003
        seen.append((design.c_z, options.guards.c_z))
        return real(design, plan, points, signs, options, *args, **kwargs)

    monkeypatch.setattr(run_report, "evaluate_design", spy)
    out = tmp_path / "run"
    few = dict(algorithm="ga", population=4, generations=1, points=3, free="m_x", seed=1)
    arcube.optimize("reference", out=out, ids="1", c_z=300.0, **few)
    assert arcube.Design.load(str(out / "best_design.json")).c_z == 300.0  # the run's design carries it
    run_report.write_run_report(out)
    assert seen == [(300.0, 300.0)]
    best = json.loads((out / "best_design.json").read_text())
    del best["c_z"]  # as a run of before wrote it: c_z in [settings] alone
    (out / "best_design.json").write_text(json.dumps(best))
    seen.clear()
    run_report.write_run_report(out)
    assert seen == [(300.0, 300.0)]
    plain = tmp_path / "plain"
    arcube.optimize("reference", out=plain, ids="1", **few)
    seen.clear()
    run_report.write_run_report(plain)
    assert seen == [(None, None)]
