"""The design job keeps the seed that serves the most dockings as ``dock`` would find them (model §19.6), and says how
often the re-check agrees with the search (``search_verdict_agreement``).

Simulated ground truth: seeds whose dockings are met at the plan's points in known numbers, whose programs are blocked
at known dockings (the program builder replaced by a table), and whose dockings docked anew are met at known dockings
(the re-docking replaced by a table). The robot chosen, the dockings it serves and the agreement are counted by hand.
"""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import pytest

from arcube.design_job import choose
from arcube.design_job.choose import SeedCheck, agreement, choose_seed, judge_seed, search_feasible
from arcube.design_job.dockings import Docking


def _docking(k: int, at_points: bool) -> Docking:
    d = Docking(f"p{k}", "R", None, None, None, design=None)  # type: ignore[arg-type]
    d.rows = [{"requirement": "reach", "passed": at_points}]
    return d


def _check(seed: int, at_points: list[bool], etas: list[float], violations: list[float]) -> SeedCheck:
    docks = [_docking(k, ok) for k, ok in enumerate(at_points)]
    tasks = [{"label": f"p{k} R", "eta_G": eta} for k, eta in enumerate(etas)]
    summary = {"tasks": tasks, "docking_violations": violations, "feasible": not any(violations)}
    return SeedCheck({"seed": seed}, SimpleNamespace(path=None), SimpleNamespace(setups=1), summary, docks, Path("."))


@pytest.fixture
def world(monkeypatch: pytest.MonkeyPatch) -> dict:
    """``blocked[seed]``: dockings whose program is blocked; ``redocked[seed]``: dockings met once docked anew (with
    eta_G 9.0); ``calls``: (seed, which) of every re-docking."""
    w: dict = {"blocked": {}, "redocked": {}, "calls": []}

    def redock(cfg, dockings, which, folders, s, reqs, seed, **kw):  # noqa: ANN001, ANN003
        if which:  # as the real one: nothing to dock, nothing done
            w["calls"].append((seed, list(which)))
        met = [k for k in which if k in w["redocked"].get(seed, set())]
        for k in met:
            dockings[k].rows = [{"requirement": "reach", "passed": True}, {"requirement": "program", "passed": True}]
            dockings[k].redocked, dockings[k].eta_G = True, 9.0
        return met

    def build_program(folder, d, s, reqs):  # noqa: ANN001
        seed = int(Path(folder).parts[-3].split("_")[1]) if "dockings" in str(folder) else 0
        k = int(d.name[1:])
        return [{"requirement": "program", "passed": k not in w["blocked"].get(seed, set())}]

    monkeypatch.setattr("arcube.design_job.redock.redock", redock)
    monkeypatch.setattr(choose, "build_program", build_program)
    monkeypatch.setattr(choose.runmod, "read_config", lambda path: (None,))
    return w


def _judge(c: SeedCheck) -> SeedCheck:
    c.root = Path(f"stage/seed_{c.seed}")
    judge_seed(c, [], lambda text: None, 1, None)
    return c


def test_every_seed_is_docked_anew_before_the_seeds_are_compared(world: dict) -> None:
    # seed 1 comes first in the study's ranking: 4 of 5 met at the points, but 3 of those programs blocked -> serves 1
    # seed 2: 2 of 5 met at the points, both programmed; docked anew, 2 more are met -> serves 4
    world["blocked"][1] = {0, 1, 2}
    world["redocked"][2] = {2, 3}
    one = _judge(_check(1, [True] * 4 + [False], [2.0] * 5, [0.0] * 5))
    two = _judge(_check(2, [True, True, False, False, False], [3.0] * 5, [0.0, 0.0, 0.1, 0.1, 0.1]))
    assert [d.met for d in one.dockings] == [False, False, False, True, False] and one.served == 1
    assert [d.met for d in two.dockings] == [True, True, True, True, False] and two.served == 4
    # seed 1's blocked programs are docked anew too (after its points' misses): nothing met that way here
    assert world["calls"] == [(1, [4]), (1, [0, 1, 2]), (2, [2, 3, 4])]
    assert choose_seed([one, two]) is two
    assert two.worst_eta == 9.0  # the re-docked dockings' eta_G, not the search's
    # seed 1: the search called 5 feasible, the re-check met 1 at the search's placement; seed 2: 2 of 2
    assert agreement([one, two]) == pytest.approx(3 / 7)
    assert [d.met_at_search for d in two.dockings] == [True, True, False, False, False]


def test_ties_go_to_the_smaller_worst_eta_then_to_the_ranking(world: dict) -> None:
    a = _judge(_check(1, [True, True], [2.0, 2.5], [0.0, 0.0]))
    b = _judge(_check(2, [True, True], [2.0, 2.2], [0.0, 0.0]))
    c = _judge(_check(3, [True, True], [2.2, 2.0], [0.0, 0.0]))
    assert choose_seed([a, b, c]) is b and choose_seed([c, b]) is c  # b and c tie on (2 served, 2.2): the first wins
    assert agreement([a, b, c]) == 1.0


def test_a_seed_serving_none_has_no_eta_and_the_agreement_needs_a_feasible_docking(world: dict) -> None:
    a = _judge(_check(1, [False, False], [math.inf, math.inf], [0.5, 0.2]))
    assert a.served == 0 and math.isinf(a.worst_eta) and agreement([a]) is None


def test_search_feasibility_per_docking_and_for_older_runs() -> None:
    assert search_feasible({"docking_violations": [0.0, 1e-9, 0.0]}, 3) == [True, False, True]
    assert search_feasible({"feasible": True}, 2) == [True, True]  # a run written before the field
    assert search_feasible({"feasible": False, "docking_violations": [0.0]}, 2) == [False, False]
