"""Coverage first (model §19.6) counts a docking as served only with its drilling program built.

Simulated ground truth: three seeds, none serving every docking, whose dockings are met at the plan's points in
known numbers and whose programs are blocked at known dockings (the program builder is replaced by a table). The
robot chosen must be the one serving the most dockings with programs, and no more programs built than needed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace

import pytest

from arcube.design_job import job


@dataclass
class FakeDocking:
    label: str
    rows: list = field(default_factory=list)
    name: str = "p"
    side: str = "R"

    @property
    def met(self) -> bool:
        return bool(self.rows) and all(r["passed"] for r in self.rows)


def _entry(seed: int, met_at_points: int, n: int = 5) -> tuple:
    docks = [FakeDocking(f"p{k}_R", [{"requirement": "reach", "passed": k < met_at_points}]) for k in range(n)]
    return ({"seed": seed}, None, SimpleNamespace(setups=1), {"tasks": []}, docks)


@pytest.fixture
def blocked(monkeypatch: pytest.MonkeyPatch) -> tuple[dict[int, set[int]], list[int]]:
    table: dict[int, set[int]] = {}  # seed -> the dockings whose program is blocked
    built: list[int] = []

    def programs(out: Path, entry: tuple, reqs: object, say: object, which: list) -> None:
        seed = entry[0]["seed"]
        built.append(seed)
        for d in which:
            k = int(d.label[1:].split("_")[0])
            d.rows.append({"requirement": "program", "passed": k not in table.get(seed, set())})

    monkeypatch.setattr(job, "_programs", programs)
    return table, built


def test_the_seed_serving_most_with_programs_is_chosen(tmp_path: Path, blocked: tuple) -> None:
    table, built = blocked
    a, b, c = _entry(1, 4), _entry(2, 3), _entry(3, 2)
    table[1] = {0, 1, 2}  # seed 1 meets 4 at the points, but 3 of its programs are blocked: it serves 1
    table[2] = set()  # seed 2 serves its 3
    chosen, now = job._most_served(tmp_path, [a, b, c], [], lambda s: None, None)
    assert chosen[0]["seed"] == 2 and now == 2 and sum(d.met for d in chosen[4]) == 3
    assert built == [1, 2]  # seed 3 (2 at the points) cannot beat 3: its programs are never built


def test_a_seed_already_programmed_is_not_built_again(tmp_path: Path, blocked: tuple) -> None:
    table, built = blocked
    a, b = _entry(1, 3), _entry(2, 2)
    for d in a[4][:3]:
        d.rows.append({"requirement": "program", "passed": True})  # its programs built by the re-check already
    chosen, now = job._most_served(tmp_path, [b, a], [], lambda s: None, 7)
    assert chosen[0]["seed"] == 1 and built == [] and now == 7
    assert math.isinf(job._worst_met_eta({"tasks": []}, []))
