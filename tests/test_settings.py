"""One settings model (arcube.options, arcube.RunSettings): declared checks that name the field,
Python values equal to the command line's text forms, config.toml's table read back (old tables
included), the CLI's flag table complete, and an optimizer that runs in memory."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest
import typer

import arcube
from arcube import Body, Guards, InputError, Loads, Masses, Options, RunSettings
from arcube.cli import app
from arcube.cli.projection import flag_message, flag_table
from arcube.optimization.settings import FLAT_OPTIONS


# --------------------------------------------------------------------------- Options
def test_flat_keywords_route_to_their_group() -> None:
    flat = Options(kappa_max=80.0, clearance_mm=5.0, link_radius=6.0, thrust_N=25.0, tip_metrics=False, body=True)
    grouped = Options(
        guards=Guards(kappa_max=80.0, clearance_mm=5.0),
        body=Body(link_radius=6.0),
        loads=Loads(thrust_N=25.0),
        outputs={"tip_metrics": False, "clearances": True},
    )
    assert flat == grouped
    assert flat.replace(thrust_N=30.0).loads.thrust_N == 30.0 and flat.replace(thrust_N=30.0).guards == flat.guards


@pytest.mark.parametrize(
    "make, param",
    [
        (lambda: Options(thrust_N=-1.0), "Loads.thrust_N"),
        (lambda: Loads(lateral_force_N=math.nan), "Loads.lateral_force_N"),
        (lambda: Options(loads={"encoder_deg": [0.01, 0.02]}), "Loads.encoder_deg"),
        (lambda: Options(link_radius=0.0), "Body.link_radius"),
        (lambda: Options(guards=Guards(rho_max_deg=95.0)), "Guards.rho_max_deg"),
        (lambda: Options().replace(self_clearance_mm=-2.0), "Guards.self_clearance_mm"),
        (lambda: Options(unknown_guard=True), "Options.unknown_guard"),
        (lambda: RunSettings(population=0), "RunSettings.population"),
        (lambda: RunSettings(population=8.5), "RunSettings.population"),
        (lambda: RunSettings(placement="each"), "RunSettings.placement"),
        (lambda: RunSettings(free=["all", "nope"]), "RunSettings.free"),
        (lambda: RunSettings(bounds={"L": (-10.0, -1.0)}), "RunSettings.bounds"),
        (lambda: RunSettings(maxima={"torque": -1}), "RunSettings.maxima"),
        (lambda: RunSettings(thrust=-3.0), "Loads.thrust_N"),
    ],
)
def test_a_bad_value_names_its_field_in_one_line(make, param: str) -> None:
    with pytest.raises(InputError) as info:
        make()
    assert info.value.param == param and str(info.value).startswith(param) and "\n" not in str(info.value)
    assert "--" not in str(info.value)


def test_a_flat_name_two_groups_share_is_refused_naming_both() -> None:
    """``envelope_clearance`` is the guard's short name (guards.envelope_clearance_mm, mm) and a field of outputs (a
    bool): Options(envelope_clearance=True) once set a 1 mm guard. Now refused, both named; the full names work."""
    with pytest.raises(InputError) as info:
        Options(envelope_clearance=True)
    text = str(info.value)
    assert (
        text.startswith("envelope_clearance names two settings")
        and "guards.envelope_clearance_mm" in text
        and "outputs.envelope_clearance" in text
    )
    with pytest.raises(InputError, match="names two settings"):
        arcube.evaluate("paper", "reference", points=3, envelope_clearance=10.0)
    assert Options(envelope_clearance_mm=10.0).guards.envelope_clearance_mm == 10.0
    with pytest.raises(InputError, match=r"^Guards.envelope_clearance_mm must be a number, got True$"):
        Guards(envelope_clearance_mm=True)  # pydantic alone reads True as 1.0
    assert (
        RunSettings(envelope_clearance=10.0, anatomy="default", envelope="default").options.guards.envelope_clearance_mm
        == 10.0
    )  # a table's name
    assert Options(outputs={"envelope_clearance": True}).guards.envelope_clearance_mm is None


def test_the_cli_names_the_flag_of_the_field() -> None:
    err = InputError.of("Loads.thrust_N", "must be >= 0, got -3.0")
    assert flag_message(err) == "--thrust must be >= 0, got -3.0"
    assert flag_message(InputError("plain message")) == "plain message"
    inside = InputError(
        "m.csv: 6 fitted measurements are too few; fit at least 7 (IdentifySettings.holdout sets how many are held out)"
    )
    assert flag_message(inside).endswith(
        "(--holdout sets how many are held out)"
    )  # a setting named inside the message too
    assert (
        flag_message(InputError("XIdentifySettings.holdouts stays")) == "XIdentifySettings.holdouts stays"
    )  # whole names only


# --------------------------------------------------------------------------- RunSettings: Python values
def test_python_values_equal_the_command_lines_text() -> None:
    py = RunSettings(
        free=["all", "mount", "L"],
        bounds={"p_x": (30, 250), "r": (50, 90)},
        mode=(1, 1, -1, 1),
        maxima={"torque": 15},
        minima={"clearance": 5},
        objectives=["eta_G", "torque"],
        anatomy="default",
        levels=["C3", "C4"],
        ids=[1, 3],
    )
    text = RunSettings(
        free="all,mount,L",
        bounds="p_x=30:250,r=50:90",
        mode="+,+,-,+",
        maxima=["torque=15"],
        minima=["clearance=5"],
        objectives="eta_G,torque",
        anatomy=["default"],
        levels="C3,C4",
        ids="1,3",
    )
    assert py == text
    assert py.free == arcube.PARAM_NAMES and py.algorithm == "nsga2"  # two objectives pick NSGA-II
    assert py.limits == [["torque", "max", 15.0], ["clearance", "min", 5.0]]


def test_guards_add_the_papers_guards_to_the_options() -> None:
    opts = RunSettings(guarded=True, self_clearance=2.0).evaluation_options()
    assert opts.guards == arcube.GUARDED_OPTIONS.guards.replace(self_clearance_mm=2.0)


# --------------------------------------------------------------------------- config.toml's table
def test_table_round_trip() -> None:
    s = RunSettings(
        algorithm="ga",
        population=20,
        generations=7,
        seed=5,
        free=["all", "L"],
        bounds={"L": (10, 150)},
        mode="free",
        setups=2,
        guarded=True,
        margin=3.0,
        anatomy="default",
        clearance=4.0,
        self_clearance=1.5,
        link_radius=7.0,
        thrust=22.0,
        encoder_deg=[0.01, 0.02, 0.01, 0.01, 0.01],
        maxima={"torque": 12},
        minima={"clearance": 3},
        kappa_max=80.0,
        placement="shared",
    )
    table = s.to_table()
    assert RunSettings.from_config({"settings": table, "bounds": s.all_bounds}) == s
    assert RunSettings.from_table(table) == s.replace(bounds={})  # the bounds are config.toml's own table
    # the file's flat keys, as every earlier run wrote them
    assert (table["clearance"], table["thrust"], table["link_radius"], table["limits"]) == (
        4.0,
        22.0,
        7.0,
        [["torque", "max", 12.0], ["clearance", "min", 3.0]],
    )


def _other_value(default):
    """A valid value that differs from a field's default (a bool flipped, numbers scaled, None -> 7)."""
    if isinstance(default, bool):
        return not default
    if isinstance(default, tuple):
        return tuple(1.5 * v if v else 1.0 for v in default)
    return 7.0 if default is None else 1.5 * default


_GROUPS = {"guards": Guards, "body": Body, "loads": Loads, "masses": Masses}


@pytest.mark.parametrize(
    "group, field", [(g, f) for g, cls in _GROUPS.items() for f in cls.model_fields if (g, f) != ("guards", "c_z")]
)
def test_every_option_set_alone_survives_the_table(group: str, field: str) -> None:
    """A run's config.toml must hold every option it ran with: a resume, the design job's reference check and
    the report all rebuild the run from the table (the envelope guard was once lost this way)."""
    value = _other_value(_GROUPS[group].model_fields[field].default)
    s = RunSettings(anatomy="default", envelope="default", options={group: {field: value}})
    assert getattr(getattr(s.options, group), field) == value
    back = RunSettings.from_table(s.to_table())
    assert getattr(getattr(back.options, group), field) == value and back == s


def test_masses_round_trip_through_the_table_and_are_written_only_when_set() -> None:
    """MODEL.md 18.1's settings: flat keys (wall, density, m_delta, m_motor, gravity) in config.toml only when
    not the defaults, so that every earlier table is written as it was."""
    assert not {"wall", "density", "m_delta", "m_motor", "gravity"} & set(RunSettings().to_table())
    s = RunSettings(wall=1.5, m_motor=2.5, gravity="0,-9.81,0", maxima={"holding_torque": 12, "mass": 4})
    table = s.to_table()
    assert (table["wall"], table["m_motor"], table["gravity"]) == (
        1.5,
        2.5,
        [0.0, -9.81, 0.0],
    ) and "density" not in table
    assert RunSettings.from_table(table) == s
    assert s.options.masses == Masses(wall_mm=1.5, m_motor_kg=2.5, gravity=(0.0, -9.81, 0.0))
    assert s.evaluation_options().masses == s.options.masses
    assert s.evaluation_options().outputs.holding_torque and s.evaluation_options().outputs.tip_metrics


def test_a_table_written_before_docking_loads_and_duplicates_reads_as_those_runs_ran() -> None:
    old = {  # the [settings] of a run folder written before --docking, --thrust and --eliminate-duplicates existed
        "algorithm": "ga",
        "population": 40,
        "generations": 10,
        "tolerance": 1e-5,
        "period": 30,
        "points": 10,
        "mode": "+,+,+,+",
        "setups": 1,
        "guards": False,
        "seed": 7,
        "engine": "auto",
        "engine_resolved": "numba",
        "aggregate": "mean",
        "compactness": "links",
        "checkpoint_every": 10,
        "design_from": "paper",
        "free": ["m_x", "m_y", "m_z"],
        "trajectories": ["reference"],
    }
    s = RunSettings.from_table(old)
    assert s.placement == "shared" and s.eliminate_duplicates is True and s.options == Options() and s.ftol == 1e-5
    assert s.free == ("m_x", "m_y", "m_z") and s.seed == 7


# --------------------------------------------------------------------------- the flag table
def _cli_flags() -> set[str]:
    flags: set[str] = set()
    todo = list(typer.main.get_command(app).commands.values())  # type: ignore[attr-defined]
    while todo:  # commands, and the subcommands of a group (arcube calibrate poses)
        sub = todo.pop()
        todo.extend(getattr(sub, "commands", {}).values())
        for param in sub.params:
            flags.update(o for o in param.opts if o.startswith("--"))
    return flags


def test_every_flag_in_the_table_exists() -> None:
    FLAGS = flag_table()
    missing = sorted({flag for flag in FLAGS.values() if flag not in _cli_flags()})
    assert not missing, f"flags in the table that no command has: {missing}"


def test_every_setting_with_a_flag_is_in_the_table() -> None:
    """A new setting gets its flag by one line in the table (the optimizer's own bookkeeping fields excepted)."""
    no_flag = {
        "period",
        "options",
        "guards",
    }  # period: pymoo's; options: the groups below; guards: a switch, not an error source
    run = {f"RunSettings.{n}" for n in RunSettings.model_fields if n not in no_flag}
    groups = {f"{cls.__name__}.{n}" for cls in (Guards, Body, Loads, Masses) for n in cls.model_fields}
    groups -= {"Guards.z_dyad", "Guards.c_z", "Guards.single_assembly_mode"}  # set by --guarded or not on the CLI
    assert sorted((run | groups) - flag_table().keys()) == []
    # and every flat optimize keyword of an option is a field of its group
    for key, (group, name) in FLAT_OPTIONS.items():
        assert name in type(getattr(Options(), group)).model_fields, key


# --------------------------------------------------------------------------- in memory
SMALL = {
    "algorithm": "ga",
    "population": 16,
    "generations": 4,
    "ftol": 0.0,
    "points": 5,
    "ids": "1,2",
    "seed": 3,
    "free": ["m_x", "m_y", "m_z", "L"],
    "checkpoint_every": 2,
}
_TIMES = ("wall_s", "eval_s", "files")


def _untimed(summary: dict) -> dict:
    return {k: v for k, v in summary.items() if k not in _TIMES}


@pytest.mark.parametrize(
    "extra", [{}, {"anatomy": "default", "clearance": 0.0, "design_from": "paper"}], ids=["plain", "anatomy"]
)
def test_in_memory_run_equals_the_folder_run_and_writes_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, extra: dict
) -> None:
    plan = arcube.load_trajectories("reference")
    empty = tmp_path / "cwd"
    empty.mkdir()
    monkeypatch.chdir(empty)
    result = arcube.optimize(plan, RunSettings(**SMALL, **extra))
    assert isinstance(result, arcube.OptimizeResult) and os.listdir(empty) == []
    run = arcube.optimize(plan, RunSettings(**SMALL, **extra), out=tmp_path / "run")
    assert _untimed(result.summary) == _untimed(run.summary)
    assert result.best_design == run.best_design
    for col in ("generation", "evaluations", "best_eta_G", "mean_eta_G", "feasible_fraction", "best_violation"):
        mine = result.history[col]  # history.csv leaves a non-finite value empty: NaN when read back
        np.testing.assert_array_equal(np.where(np.isfinite(mine), mine, np.nan), run.history[col], err_msg=col)


def test_optimize_refuses_a_folder_in_place_of_settings(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="settings must be an arcube.RunSettings"):
        arcube.optimize("reference", tmp_path / "run")  # type: ignore[arg-type]


def test_every_settings_field_has_a_description() -> None:
    """Every field of every settings model (the subclasses of arcube.validation.Settings in every module) says what it
    is: the help texts, the docs and the error messages read it."""
    import importlib
    import pkgutil
    import warnings

    import arcube
    from arcube.errors import RenamedWarning
    from arcube.validation import Settings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RenamedWarning)  # a module kept under its old name warns when imported
        for info in pkgutil.walk_packages(arcube.__path__, "arcube."):
            importlib.import_module(info.name)

    def subclasses(cls: type) -> list[type]:
        return [c for s in cls.__subclasses__() for c in (s, *subclasses(s))]

    classes = set(subclasses(Settings))
    assert {"Options", "Guards", "RunSettings", "ToleranceSettings"} <= {c.__name__ for c in classes}
    missing = [
        f"{c.__name__}.{n}" for c in classes for n, f in c.model_fields.items() if not (f.description or "").strip()
    ]
    assert not missing, f"settings fields without a description: {missing}"


# --------------------------------------------------------------------------- renamed settings (one release)
def test_an_old_name_is_taken_with_a_warning_and_never_beside_its_new_one() -> None:
    from arcube.errors import RenamedWarning

    with pytest.warns(RenamedWarning, match="RunSettings.tolerance is now RunSettings.ftol"):
        assert RunSettings(tolerance=0.5).ftol == 0.5
    with pytest.warns(RenamedWarning, match="RunSettings.docking is now RunSettings.placement"):
        assert RunSettings(docking="shared").placement == "shared"
    with pytest.warns(RenamedWarning):  # the old name replaced first, then its value folded as the new one's
        assert RunSettings(docking=" Per-Patient ").placement == "per-patient"
    with pytest.warns(RenamedWarning, match="'worst' is now spelt 'max'"):
        assert RunSettings(aggregate="worst").aggregate == "max"
    with pytest.warns(RenamedWarning):
        assert RunSettings().replace(tolerance=0.25).ftol == 0.25  # replace() takes the old name too
    with pytest.raises(InputError, match="RunSettings.tolerance and RunSettings.ftol are one setting"):
        RunSettings(tolerance=0.5, ftol=0.1)
    with pytest.warns(RenamedWarning, match="RunSettings.guards is now RunSettings.guarded"):
        assert RunSettings(guards=True).guarded is True  # the bool; RunSettings.options.guards is the group
    with pytest.raises(InputError, match="RunSettings.guards and RunSettings.guarded are one setting"):
        RunSettings(guards=True, guarded=True)


def test_an_old_keyword_beside_a_settings_object_warns_at_the_caller_s_line() -> None:
    """``arcube.optimize(plan, settings, guards=True)``: the settings object holds ``guarded`` (its default), the
    keyword is the old name of the same field: taken with a warning (it was refused as both names), and the warning,
    like every old name's, points at the caller's line, not into arcube or pydantic."""
    import arcube
    from arcube.errors import RenamedWarning
    from arcube.optimization.config import run_settings

    with pytest.warns(RenamedWarning, match="RunSettings.guards is now RunSettings.guarded") as record:
        assert run_settings(RunSettings(population=8), guards=True) == RunSettings(population=8, guarded=True)
    assert record[0].filename == __file__
    with pytest.warns(RenamedWarning) as record:
        RunSettings(tolerance=0.5)
    assert record[0].filename == __file__
    with pytest.warns(RenamedWarning, match="^guards is now guarded") as record:
        arcube.evaluate("paper", "reference", ids="1", points=3, guards=True, engine="numpy")
    assert record[0].filename == __file__


def test_the_guards_keyword_of_a_request_is_guarded_now() -> None:
    """``guards=True`` (before 0.3) asks for the guards of model §8.2 as ``guarded=True`` does, with a warning;
    both together are refused; the explorer's keyword likewise."""
    import arcube
    from arcube.errors import RenamedWarning
    from arcube.explorer import live_model

    placed = arcube.Design.paper().replace(m_x=88.23, m_y=79.40, m_z=56.89)  # reaches the right side's plan
    new = arcube.evaluate(placed, "reference", side="R", points=6, guarded=True, engine="numpy")
    with pytest.warns(RenamedWarning, match=r"^guards is now guarded \(the old name goes in the next release\)"):
        old = arcube.evaluate(placed, "reference", side="R", points=6, guards=True, engine="numpy")
    assert old.summary == new.summary and new.options.guards == arcube.GUARDED_OPTIONS.guards
    plain = arcube.evaluate(placed, "reference", side="R", points=6, engine="numpy")
    assert plain.summary["reachable_fraction"] == 1.0 and new.summary["failures"]["guard/rho_max"] > 0
    with pytest.raises(InputError, match="^guards and guarded are one setting"):
        arcube.evaluate("paper", "reference", points=4, guarded=True, guards=True)
    with pytest.warns(RenamedWarning, match="^guards is now guarded"):
        assert (
            live_model("paper", "reference", side="R", ids="1", points=4, envelope=None, guards=False).guarded is False
        )


def test_an_old_run_folders_keys_are_read_silently() -> None:
    import warnings

    from arcube.errors import RenamedWarning

    with warnings.catch_warnings():
        warnings.simplefilter("error", RenamedWarning)
        s = RunSettings.from_table({"tolerance": 0.0, "docking": "per-patient", "aggregate": "worst"})
    assert s.ftol == 0.0 and s.placement == "per-patient" and s.aggregate == "max"
    table = s.to_table()
    assert table["ftol"] == 0.0 and table["placement"] == "per-patient" and "tolerance" not in table
    with warnings.catch_warnings():
        warnings.simplefilter("error", RenamedWarning)
        guarded = RunSettings.from_table({"guards": True})  # the key before 0.3
    assert guarded.guarded is True and guarded.to_table()["guarded"] is True and "guards" not in guarded.to_table()


def test_the_old_flag_warns_in_the_users_words_and_the_run_records_the_new_name(tmp_path: Path) -> None:
    import subprocess
    import sys
    import tomllib

    out = tmp_path / "run"
    args = [
        "optimize",
        "--trajectories",
        "reference",
        "--ids",
        "1",
        "--points",
        "3",
        "--free",
        "m_x",
        "--algorithm",
        "ga",
    ]
    args += ["--population", "4", "--generations", "1", "--seed", "1", "--quiet", "--out", str(out)]
    args += ["--dockings", "per-patient"]  # --aggregate combines dockings or sets: with one set and none it is refused
    done = subprocess.run(
        [sys.executable, "-m", "arcube", *args, "--tolerance", "0", "--aggregate", "worst"],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    warned = [line for line in done.stderr.splitlines() if line.startswith("warning:")]
    assert warned == [
        "warning: --tolerance is now --ftol (the old name goes in the next release)",
        "warning: --aggregate 'worst' is now spelt 'max' (the old spelling goes in the next release)",
    ]
    settings = tomllib.loads((out / "config.toml").read_text())["settings"]
    assert settings["ftol"] == 0.0 and settings["aggregate"] == "max" and "tolerance" not in settings
    both = subprocess.run(
        [sys.executable, "-m", "arcube", *args[:-1], str(tmp_path / "b"), "--tolerance", "0", "--ftol", "0"],
        capture_output=True,
        text=True,
    )
    assert (
        both.returncode == 2
        and both.stderr.strip() == "error: --tolerance and --ftol are one setting (renamed): give --ftol"
    )


def test_the_old_guards_flag_of_evaluate_warns_and_turns_the_guards_on(capsys: pytest.CaptureFixture[str]) -> None:
    import json
    import warnings

    from arcube.cli import main
    from arcube.errors import RenamedWarning

    def run(*flags: str) -> int:
        with warnings.catch_warnings():
            warnings.simplefilter("always", RenamedWarning)  # the suite makes it an error; the CLI prints it
            try:
                main(["evaluate", "--side", "R", "--ids", "1", "--points", "4", "--engine", "numpy", "--json", *flags])
            except SystemExit as exc:
                return int(exc.code or 0)
        return 0

    assert run("--guarded") == 0
    new = json.loads(capsys.readouterr().out)
    assert run("--guards") == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out) == new and new["guards"]["kappa_max"] == 100.0
    assert "warning: --guards is now --guarded (the old name goes in the next release)" in captured.err
    assert run("--guards", "--guarded") == 2
    assert "error: --guards and --guarded are one setting (renamed): give --guarded" in capsys.readouterr().err


# every RunSettings field, set alone to a value that is not its default (a new field must be added here)
_NOT_DEFAULT = {
    "algorithm": "ga",
    "population": 40,
    "generations": 12,
    "ftol": 0.0,
    "period": 7,
    "points": 9,
    "mode": "+,-,+,-",
    "setups": 2,
    "guarded": True,
    "margin": 5.0,
    "seed": 11,
    "engine": "numpy",
    "aggregate": "max",
    "compactness": "bbox",
    "checkpoint_every": 3,
    "eliminate_duplicates": True,
    "design_from": "tests/data/one_robot.json",
    "c_z": 250.0,
    "free": ("m_x", "m_y", "L"),
    "bounds": {"m_x": (10.0, 20.0)},
    "side": "L",
    "levels": "C3-C5",
    "ids": "1,3",
    "transform": "T.json",
    "anatomy": ("default",),
    "anatomy_frame": "RAS",
    "segments": ("C3", "C4"),
    "envelope": ("default",),
    "table_z": -200.0,
    "objectives": ("eta_G", "torque"),
    "maxima": {"torque": 12.0},
    "minima": {"links": 100.0},
    "tolerance_class": "f",
    "tol": {"lengths": 0.05},
    "placement": "shared",
    "dockings": "per-side",
    "standoff": 15.0,
    "options": Options(loads=Loads(thrust_N=22.0), guards=Guards(kappa_max=90.0), body=Body(link_radius=7.0)),
}


@pytest.mark.parametrize("name", sorted(RunSettings.model_fields))
def test_every_run_setting_survives_config_toml(name: str) -> None:
    """House II: a run folder records every setting. Each field, set alone to a value other than its default, is read
    back equal from the config's [settings] and [bounds] tables (the envelope guard was once lost on this way)."""
    assert set(_NOT_DEFAULT) == set(RunSettings.model_fields), "give the new field a value in _NOT_DEFAULT"
    s = RunSettings(**{name: _NOT_DEFAULT[name]})
    assert getattr(s, name) != getattr(RunSettings(), name)
    back = RunSettings.from_config({"settings": s.to_table(), "bounds": s.all_bounds})
    assert back == s


def test_the_envelope_guard_survives_config_toml() -> None:
    s = RunSettings(envelope=("default",), options=Options(guards=Guards(envelope_clearance_mm=8.0)))
    assert RunSettings.from_config({"settings": s.to_table(), "bounds": s.all_bounds}) == s
