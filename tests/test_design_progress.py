"""What ``arcube design`` tells a user on stderr while it runs (issue 34: a run a user can follow).

Hand-computed: the time left from the evaluation rate, the spacing of plain lines when stderr is not a
terminal, the stages after the search in their order, and nothing at all with --quiet.
"""

from __future__ import annotations

import io
import time
from pathlib import Path

from arcube.cli.design_progress import LOG_EVERY_S, DesignProgress, duration

from harness import arcube


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def _row(
    generation: int, evaluations: int, session_s: float, best: float = float("inf"), violation: float = 0.5
) -> dict:
    return {
        "generation": generation,
        "evaluations": evaluations,
        "session_s": session_s,
        "best_eta_G": best,
        "feasible_fraction": 0.25,
        "best_violation": violation,
    }


def test_durations_read_as_a_person_says_them() -> None:
    assert [duration(s) for s in (0, 59.4, 95, 3599, 3700, float("nan"), -1)] == [
        "0 s",
        "59 s",
        "1 min 35 s",
        "59 min 59 s",
        "1 h 1 min",
        "unknown",
        "unknown",
    ]


def test_plain_lines_every_few_seconds_with_the_time_left_from_the_rate() -> None:
    out, clock = io.StringIO(), Clock()
    p = DesignProgress([3, 7], budget=1000, stream=out, clock=clock)
    clock.t = 20.0
    p.generation(_row(1, 100, 10.0))  # first row: no rate yet, so no time left
    clock.t = 21.0
    p.generation(_row(2, 200, 20.0, best=1.5))  # within LOG_EVERY_S of the last line: not printed
    clock.t = 20.0 + LOG_EVERY_S
    p.generation(_row(3, 400, 40.0, best=1.25))  # 300 evaluations in 30 s: 10/s; 600 left of seed 3 + 1000 of seed 7
    lines = out.getvalue().splitlines()
    assert len(lines) == 2 and all(line.startswith("design: ") for line in lines)
    assert (
        lines[0]
        == "design: seed 3 (1 of 2): generation 1, 100 of 1,000 evaluations, none feasible yet, smallest violation 0.5"
    )
    assert lines[1] == (
        "design: seed 3 (1 of 2): generation 3, 400 of 1,000 evaluations, best eta_G 1.25 (feasible 25%); "
        "about 2 min 40 s left"
    )
    clock.t += 1.0
    p.seed(3, {"eta_G": 1.25, "evaluations": 1000, "wall_s": 95.0})  # an event: printed at once
    clock.t += 1.0
    p.generation(_row(1, 50, 5.0))  # seed 7 now; its own rate starts afresh
    clock.t += LOG_EVERY_S
    p.generation(_row(2, 150, 15.0))  # 100 in 10 s: 850 left -> 85 s
    clock.t += 1.0
    p.stage("checking seed 3's design with the NumPy reference")
    lines = out.getvalue().splitlines()[2:]
    assert lines[0] == "design: seed 3 done (1 of 2): eta_G 1.25, 1,000 evaluations in 1 min 35 s"
    assert lines[1].startswith("design: seed 7 (2 of 2): generation 2, 150 of 1,000 evaluations") and lines[1].endswith(
        "about 1 min 25 s left"
    )
    assert lines[2] == f"design: checking seed 3's design with the NumPy reference ({duration(clock.t)} so far)"


def test_quiet_says_nothing() -> None:
    out, clock = io.StringIO(), Clock()
    p = DesignProgress([1], budget=10, enabled=False, stream=out, clock=clock)
    p.generation(_row(1, 5, 1.0))
    p.seed(1, {"eta_G": None, "evaluations": 10, "wall_s": 2.0})
    p.stage("building")
    assert out.getvalue() == ""


def test_the_command_logs_its_seeds_and_stages_when_stderr_is_not_a_terminal(tmp_path: Path) -> None:
    out = arcube(
        "design",
        "--trajectories",
        "reference",
        "--ids",
        "5",
        "--anatomy",
        "default",
        "--points",
        "4",
        "--population",
        "20",
        "--generations",
        "3",
        "--seeds",
        "1,2",
        "--out",
        str(tmp_path / "d"),
        "--no-envelope-clearance",
    )
    assert out.returncode in (0, 3), out.stderr
    lines = [line for line in out.stderr.splitlines() if line.startswith("design: ")]
    assert lines and len(lines) == len(out.stderr.strip().splitlines())  # nothing else on stderr
    done = [line for line in lines if " done (" in line]
    assert [line.split()[2] for line in done] == ["1", "2"]
    stages = [line for line in lines if "so far)" in line]
    assert stages[0].startswith("design: checking seed ") and stages[-1].startswith("design: writing the report")
    assert lines.index(done[-1]) < lines.index(stages[0])


def test_seeds_in_other_processes_are_read_from_their_history(tmp_path: Path, monkeypatch) -> None:
    """--workers 2: no generation reaches this process; the last complete history rows do, with the time left."""
    import arcube.cli.design_progress as dp

    study = tmp_path / "study"
    header = "generation,evaluations,best_eta_G,mean_eta_G,feasible_fraction,best_violation,seconds\n"
    for seed, rows in (
        (1, ["1,100,,,0.0,3.5,1.0\n", "2,200,1.75,2.0,0.5,0.0,2.0\n", "3,3"]),
        (2, ["1,100,,,0.0,0.25,1.0\n"]),
    ):
        (study / f"seed_{seed}").mkdir(parents=True)
        (study / f"seed_{seed}" / "history.csv").write_text(header + "".join(rows))  # seed 1's last row is half written
    assert dp.last_row(study / "seed_1" / "history.csv")["evaluations"] == 200.0
    assert (
        dp.last_row(study / "seed_3" / "history.csv") is None
        and dp.last_row(study / "seed_2" / "history.csv")["best_violation"] == 0.25
    )
    out, clock = io.StringIO(), Clock()
    p = DesignProgress([1, 2, 3], budget=1000, stream=out, clock=clock)
    rows = {s: dp.last_row(study / f"seed_{s}" / "history.csv") for s in (1, 2)}
    p.running(rows)  # first sight: no rate yet
    clock.t = 10.0
    rows[1]["evaluations"], rows[2]["evaluations"] = 400.0, 300.0  # 400 more in 10 s: 40/s; 3000 - 700 left -> 57.5 s
    p.running(rows)
    lines = out.getvalue().splitlines()
    assert lines[0] == (
        "design: 2 seeds running (0 of 3 done): seed 1 generation 2, 200 evaluations, best eta_G 1.75 (feasible 50%); "
        "seed 2 generation 1, 100 evaluations, none feasible yet, smallest violation 0.25"
    )
    assert lines[1].endswith("; about 58 s left"), lines[1]
    # the watcher thread does the same from the files, and stops with the context
    monkeypatch.setattr(dp, "LOG_EVERY_S", 0.05)
    out2 = io.StringIO()
    with DesignProgress([1, 2, 3], budget=1000, stream=out2) as watched:
        watched.watch(study)
        deadline = time.monotonic() + 20.0
        while "2 seeds running" not in out2.getvalue() and time.monotonic() < deadline:
            time.sleep(0.02)
    assert "seed 1 generation 2, 200 evaluations" in out2.getvalue() and not watched.watcher.is_alive()


def test_the_time_left_of_a_docked_run_weighs_its_dearer_last_phases() -> None:
    """A simulated docked run over 4 dockings evaluating 100 dockings per second: phase A's rows (85 % of the budget)
    evaluate one docking, phase B's three, phase C's four. A seed of 1,000 rows is 850 + 50 x 3 + 100 x 4 = 1,400
    docking evaluations. At row 400 (in phase A, 3 s after row 100) the seed has 1,000 evaluations left and the next
    seed 1,400: 24 s, not the 16 s the row rate alone gives."""
    out, clock = io.StringIO(), Clock()
    p = DesignProgress([1, 2], budget=1000, stream=out, clock=clock, dockings=4)
    assert p.work(1000) == 850 + 50 * 3 + 100 * 4
    p.generation(_row(1, 100, 1.0))
    clock.t = LOG_EVERY_S
    p.generation(_row(4, 400, 4.0))
    assert out.getvalue().splitlines()[-1].endswith("about 24 s left")
    one = DesignProgress([1, 2], budget=1000, stream=io.StringIO(), clock=Clock())
    assert [one.work(r) for r in (0, 400, 1000)] == [0, 400, 1000]  # one docking: a row is a row
