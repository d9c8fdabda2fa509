"""The registry of metrics (arcube.metrics): complete, consistent with what the evaluation computes, the one source
of the optimizer's and the design job's tables and help texts, and a new requirement on an existing figure is one entry."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import pytest

from arcube.metrics import METRICS, OUTPUTS, SOURCES, WHERE, metric, objective_names, requirements_help

ROOT = Path(__file__).resolve().parents[1]


def test_every_entry_is_well_formed() -> None:
    from arcube.evaluation.reference import PointResults, TaskResults
    from arcube.options import Guards

    names = [m.name for m in METRICS]
    assert len(names) == len(set(names))
    for m in METRICS:
        assert m.source in SOURCES and m.needs <= OUTPUTS, m.name
        assert m.description and m.name == m.name.strip(), m.name
        if m.objective:
            assert m.summary_key, m.name
            assert m.source != "batch" or m.batch_field in TaskResults._fields, m.name
        if m.requirement is None:
            assert m.default_limit is None and m.point_field is None and m.guard_option is None, m.name
            continue
        assert m.requirement in ("min", "max") and m.where in WHERE, m.name
        if not m.checked_after and m.source != "robust":  # checked at the plan's points by the NumPy reference
            assert m.point_field in PointResults._fields, m.name
            assert m.part_field is None or m.part_field in PointResults._fields, m.name
        # the search must see every requirement it is to meet: a max as a limit (an objective), a min as a guard
        if not m.checked_after:
            assert (m.requirement == "max" and m.objective) or m.guard_option in Guards.model_fields, m.name
        if m.source == "program":
            assert m.program_key


def test_summary_keys_are_the_fields_arcube_evaluate_writes() -> None:
    """Every objective whose value an evaluation computes is found under its summary key in ``arcube.evaluate``'s summary."""
    import arcube
    from arcube.options import Options

    ev = arcube.evaluate(
        "paper",
        "reference",
        points=3,
        engine="numpy",
        options=Options().replace(outputs=Options().outputs.replace(tip_metrics=True, holding_torque=True)),
    )
    summary = ev.summary
    for m in METRICS:
        if m.objective and m.source in ("batch", "eta_G", "mass"):
            assert m.summary_key in summary, m.name


def test_the_old_tables_are_views_of_the_registry() -> None:
    from arcube.design_job.requirements import CHECKED_AFTER, DEFAULTS, PROGRAM_FIGURES, REQUIREMENTS
    from arcube.optimization.objectives import MAXIMIZED, OBJECTIVES, SUMMARY_KEYS

    assert list(OBJECTIVES) == list(objective_names()) and OBJECTIVES["eta_G"] == metric("eta_G").description
    assert MAXIMIZED == {"clearance", "envelope_clearance"}
    assert SUMMARY_KEYS["clearance"] == "clearance_min_mm" and SUMMARY_KEYS["mass"] == "moving_mass_kg"
    # requirements.csv's rows follow the defaults' order, which the earlier files had
    assert list(DEFAULTS) == [
        "clearance",
        "self_clearance",
        "envelope_clearance",
        "lateral_error",
        "axis_error",
        "torque",
        "holding_torque",
    ]
    assert (
        REQUIREMENTS["holding_torque"] == ("max", "N·m", "drill") and REQUIREMENTS["breach_probability"][2] == "screws"
    )
    assert PROGRAM_FIGURES == {"torque_peak": "torque_peak_Nm", "power_peak": "power_peak_W"}
    assert set(CHECKED_AFTER) == {"torque_peak", "power_peak", "breach_probability"}


def test_the_help_texts_list_every_name() -> None:
    from arcube.optimization.settings import RunSettings

    text = RunSettings.model_fields["objectives"].description
    assert all(n in text for n in objective_names())
    for kind in ("min", "max"):
        listed = requirements_help(kind)
        assert all(m.name in listed for m in METRICS if m.requirement == kind), kind
        assert all(m.name not in listed.replace("_", " ") for m in METRICS if m.requirement not in (None, kind))
    assert "envelope_clearance=10" in requirements_help("min")  # the hand-written help had lost it


_NEW_REQUIREMENT = """
import dataclasses, json, sys
import numpy as np
import arcube.metrics as M

new = dataclasses.replace(M.metric("deflection"), requirement="max", where="drill", point_field="deflection_mm")
M.METRICS = tuple(new if m.name == "deflection" else m for m in M.METRICS)
M._BY_NAME["deflection"] = new

from arcube.design_job.requirements import REQUIREMENTS, assess, design_options, design_settings, requirements_from
from arcube.evaluation.engine import evaluate_task
from arcube.evaluation.task import build_task
from arcube.io.load import load_plan
from arcube.metrics import requirements_help
from arcube.model.robot import design_at_side
from arcube.options import Options
from arcube.coerce import design_mode

design = design_at_side(sys.argv[1], "R")
plan = load_plan("reference", side="R")
reqs = requirements_from(maxima={"deflection": 0.01}, drop=["clearance", "envelope_clearance"])
mode = design_mode(design)
rows = {r["requirement"]: r for r in assess([design.to_vector()], mode, [plan], [None], reqs,
                                            options=design_options(reqs), points=5, standoff_mm=20.0)}
drill = build_task(plan.entry, plan.target, 5)
opts = Options().replace(outputs=Options().outputs.replace(tip_metrics=True))
pts = evaluate_task(design.to_vector(), drill.E, drill.e, mode, opts, engine="numpy").points
print(json.dumps({"known": REQUIREMENTS.get("deflection"), "row": rows["deflection"]["value"],
                  "passed": rows["deflection"]["passed"], "by_hand": float(np.nanmax(pts.deflection_mm)),
                  "help": "deflection" in requirements_help("max"),
                  "maxima": design_settings(reqs).maxima.get("deflection")}))
"""


def test_a_requirement_on_an_existing_figure_is_one_entry() -> None:
    """Turning the deflection (an objective) into a requirement is one changed entry: ``--max deflection=...`` is then
    accepted, listed in the help, handed to the search as a limit, and checked by the NumPy reference at the plan's
    points to the same value as the largest deflection an evaluation of the drill task gives."""
    done = subprocess.run(
        [sys.executable, "-c", _NEW_REQUIREMENT, str(ROOT / "tests" / "data" / "one_robot.json")],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["known"] == ["max", "mm", "drill"] and out["help"] and out["maxima"] == 0.01
    assert out["row"] == pytest.approx(out["by_hand"], rel=1e-12) and out["by_hand"] > 0.01
    assert out["passed"] is False


def test_metric_is_frozen_and_unknown_names_fail() -> None:
    with pytest.raises(dataclasses.FrozenInstanceError):
        metric("torque").unit = "kN·m"  # type: ignore[misc]
    with pytest.raises(KeyError):
        metric("torq")
