"""House II: a run's configuration is one frozen object (RunConfig); config.toml is only its edge."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import arcube
from arcube.optimization import run as runmod
from arcube.optimization.config import build_config
from arcube.optimization.folder import read_config
from arcube.optimization.run_config import RunConfig
from arcube.optimization.settings import RunSettings

SMALL = {"population": 8, "generations": 2, "points": 3, "free": "m_x,m_y,m_z", "seed": 5}
DATA = Path(__file__).parent / "data"


@pytest.mark.parametrize(
    "fields",
    [
        {},
        {"placement": "per-patient", "aggregate": "max", "thrust": 25.0, "maxima": {"torque": 2.0}},
        {"setups": 2, "side": None, "maxima": {"mass": 9.0, "links": 900.0}, "self_clearance": 2.0, "m_motor": 2.5},
        {"free": "m_x,m_y,m_z,c_z", "guarded": True, "tolerance_class": "f", "ftol": 0.0},
    ],
)
def test_the_config_survives_its_file(fields: dict, tmp_path: Path) -> None:
    """Written to config.toml and read back, the config is the same object, and writes the same tables again."""
    plans = ["reference", "reference"] if fields.get("placement") else ["reference"]
    cfg = build_config(plans, **{**SMALL, **fields})
    table = cfg.to_toml()
    back = RunConfig.from_toml(table)
    assert back == cfg and back.to_toml() == table
    cfg2, raw = runmod.prepare(tmp_path / "run", cfg)
    assert cfg2 == cfg  # no anatomy: the folder adds nothing to the dockings' records
    read, raw_again = read_config(tmp_path / "run")
    assert read == cfg and raw_again == raw


def test_an_in_memory_run_writes_no_table(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """The optimizer takes the object: with config.toml's writers broken, an in-memory run still runs, to the
    same design as a run folder's (which writes them)."""
    folder = arcube.optimize("reference", out=tmp_path / "run", **SMALL)

    def refuse(*_: object) -> None:
        raise AssertionError("an in-memory run built config.toml's tables")

    monkeypatch.setattr(RunSettings, "to_table", refuse)
    monkeypatch.setattr(RunConfig, "to_toml", refuse)
    memory = arcube.optimize("reference", **SMALL)
    assert np.array_equal(memory.best_design.to_vector(), folder.best_design.to_vector())
    assert isinstance(memory.config, RunConfig) and memory.config.settings.seed == SMALL["seed"]


def test_the_config_cannot_be_changed_in_place() -> None:
    cfg = build_config(["reference"], **SMALL)
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.settings = RunSettings()  # type: ignore[misc]
    with pytest.raises(TypeError):
        cfg.patients[0]["ids"] = ["1"]  # type: ignore[index]
    with pytest.raises(TypeError):
        cfg.design["d_x"] = 1.0  # type: ignore[index]
    assert cfg.with_seed(7).settings.seed == 7 and cfg.settings.seed == 5
    assert cfg.with_seed(7).run_id != cfg.run_id and "--seed 7 " in cfg.with_seed(7).rerun


def test_a_config_of_0_2_reads_into_todays_names() -> None:
    """tests/data/run_0_2_killed/config.toml spells ``tolerance`` and ``aggregate = "worst"`` (arcube 0.2)."""
    cfg, _ = read_config(DATA / "run_0_2_killed")
    assert cfg.settings.ftol == 0.0 and cfg.settings.aggregate == "max" and cfg.settings.seed == 1
    assert cfg.trajectories == ("reference",) and cfg.engine_resolved == "numpy"
    assert cfg.to_toml()["settings"]["ftol"] == 0.0 and "tolerance" not in cfg.to_toml()["settings"]


@pytest.mark.parametrize("name", sorted(RunSettings.model_fields))
def test_every_run_setting_survives_the_written_file(name: str, tmp_path: Path) -> None:
    """Each setting, set alone, through config.toml's text as a run folder holds it (``tol``, a table of numbers,
    once stopped every run that set it: the file writer refused it)."""
    import tomllib

    from arcube.optimization.folder import to_toml
    from test_settings import _NOT_DEFAULT

    s = RunSettings(**{name: _NOT_DEFAULT[name]})
    text = to_toml({"settings": s.to_table(), "bounds": {k: list(v) for k, v in s.all_bounds.items()}})
    assert RunSettings.from_config(tomllib.loads(text)) == s


def test_the_rerun_line_reruns_the_same_settings(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """config.toml's ``rerun`` line, given to the command line, starts a run with the same settings (its tolerances
    were written as a Python dict once, a line the command line refused)."""
    import shlex

    from harness import run_cli

    # a limit on the robot as built: the class and tolerances count (the command line refuses them otherwise)
    maxima = {"torque": 5.0, "lateral_error_rms": 50.0}
    fields = {"tol": {"r": 0.02, "lengths": 0.05}, "maxima": maxima, "bounds": {"m_x": (10.0, 200.0)}}
    cfg = build_config(["reference"], **SMALL, **fields, thrust=25.0, tolerance_class="f")
    argv = shlex.split(cfg.rerun.replace(" DIR ", f" {tmp_path / 'again'} "))
    assert argv[:2] == ["arcube", "optimize"]
    code, _, err = run_cli([*argv[1:], "--quiet"], capsys)
    assert code == 0, err
    again, _ = read_config(tmp_path / "again")
    assert again.settings == cfg.settings


def test_the_config_pickles_as_itself_and_the_run_ignores_requested_outputs() -> None:
    """An in-memory result goes through pickle (processes, dask) with its config; and what the run evaluates follows
    from its objectives alone, as config.toml records them (a fresh run and its resume alike)."""
    import copy
    import pickle

    from arcube.options import Options, Outputs

    cfg = build_config(["reference"], **SMALL, tol={"r": 0.02})
    assert pickle.loads(pickle.dumps(cfg)) == cfg and copy.deepcopy(cfg) == cfg
    with pytest.raises(TypeError, match="unhashable"):
        hash(cfg)
    asked = RunSettings(options=Options(outputs=Outputs(clearances=True)))
    assert asked.evaluation_options() == RunSettings().evaluation_options()


def test_a_runs_summary_is_typed_and_still_its_json(tmp_path: Path) -> None:
    """House II: results get attributes. Every field of a run's summary (a single-objective run, a multi-objective
    one with c_z free and the holding torque) is declared by RunSummary; each reads as an attribute, the same value
    as the key; a field the run does not have reads None; the summary equals summary.json and dumps as it."""
    import json

    from arcube.optimization.run_results import RunSummary

    single = arcube.optimize("reference", out=tmp_path / "a", **SMALL)
    multi = arcube.optimize(
        "reference", **{**SMALL, "free": "m_x,m_y,m_z,c_z"}, objectives="eta_G,torque,holding_torque"
    )
    for summary in (single.summary, multi.summary):
        assert isinstance(summary, RunSummary) and set(summary) <= set(RunSummary.fields())
        assert all(getattr(summary, k) == summary[k] for k in summary)
    assert single.summary == json.loads((tmp_path / "a" / "summary.json").read_text())
    assert json.loads(json.dumps(single.summary)) == single.summary
    assert single.summary.front_size is None and multi.summary.front_size == multi.summary["front_size"]
    with pytest.raises(AttributeError, match="has no field 'etaG'"):
        single.summary.etaG  # noqa: B018
