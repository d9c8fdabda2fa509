"""House II: results get attributes. A result's summary is its JSON object with each declared field an attribute."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import arcube
from arcube.summary import Summary

ROBOT = Path(__file__).parent / "data" / "one_robot.json"


def test_the_accuracy_budgets_summary_is_typed() -> None:
    t = arcube.tolerance(ROBOT, "reference", side="R", points=5, samples=50)
    assert isinstance(t.summary, arcube.ToleranceSummary) and tuple(t.summary) == arcube.ToleranceSummary.fields()
    assert all(getattr(t.summary, k) == t.summary[k] for k in t.summary)
    assert json.loads(json.dumps(t.summary)) == t.summary == t.summary.to_json()


def test_a_summary_reads_its_declared_fields_only() -> None:
    class Two(Summary):
        a: float
        b: str | None

    class Three(Two):
        c: int

    s = Three(a=1.5, c=2)
    assert Three.fields() == ("a", "b", "c") and (s.a, s.b, s.c) == (1.5, None, 2)
    with pytest.raises(AttributeError, match=r"Three has no field 'd' \(its fields: a, b, c\)"):
        s.d  # noqa: B018
    copy = s.to_json()
    copy["a"] = 9.0
    assert s.a == 1.5 and type(copy) is dict


def test_a_studys_summary_is_typed(tmp_path: Path) -> None:
    st = arcube.study(
        "reference", tmp_path / "st", seeds="1-2", population=8, generations=2, points=3, free="m_x,m_y,m_z"
    )
    s = arcube.Study.load(tmp_path / "st").summary
    assert isinstance(s, arcube.StudySummary) and tuple(s) == arcube.StudySummary.fields()
    assert s.best_seed in (1, 2) and s.seeds == [1, 2] and s == st.summary
    assert json.loads((tmp_path / "st" / "summary.json").read_text()) == s


def test_the_breach_summary_is_typed() -> None:
    from arcube.pedicles.run import robot_dockings

    r = arcube.breach(robot_dockings(ROBOT)["R"], "reference", side="R", samples=200, seed=1)
    s = r.summary()
    assert isinstance(s, arcube.BreachSummary) and tuple(s) == arcube.BreachSummary.fields()
    assert s.breach_probability == s["breach_probability"] and s.samples == 200
