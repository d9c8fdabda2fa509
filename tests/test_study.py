"""Design studies (arcube study, arcube.study, arcube resume STUDY_DIR): reproducible, resumable, strict on bad input.

Oracles: a seed of a study is an ordinary run with that seed (compared with ``arcube optimize
--seed S``); a study killed half-way and resumed equals an uninterrupted one; the study's best,
median and worst are recomputed here from the seeds' own summary.json files.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import statistics
import subprocess
import sys
import time
from pathlib import Path

import pytest

import arcube
from arcube.cli.projection import flag_message
from arcube.errors import InputError
from arcube.coerce import seeds as checked_seeds
from arcube.optimization import study as studymod
from arcube.optimization.config import build_config
from harness import run_cli

REPO = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": str(REPO / "src")}
START = REPO / "tests" / "data" / "right_side_design.json"
"""Table 2's links placed where they reach the right side (m = 88.23, 79.40, 56.89): every seed starts feasible."""
SETTINGS = {
    "algorithm": "ga",
    "free": "m_x,m_y,m_z,r,o_x",
    "population": 16,
    "generations": 12,
    "points": 3,
    "engine": "numpy",
    "ftol": 0.0,
    "side": "R",
    "checkpoint_every": 3,
    "design_from": str(START),
}
FLAGS = [
    "--trajectories",
    "reference",
    "--algorithm",
    "ga",
    "--free",
    "m_x,m_y,m_z,r,o_x",
    "--population",
    "16",
    "--generations",
    "12",
    "--points",
    "3",
    "--engine",
    "numpy",
    "--ftol",
    "0",
    "--side",
    "R",
    "--checkpoint-every",
    "3",
    "--design-from",
    str(START),
    "--quiet",
]


def _cli(*args: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "arcube", *args], capture_output=True, text=True, env=ENV, timeout=timeout
    )


def _untimed_csv(path: Path) -> list[dict[str, str]]:
    return [{k: v for k, v in row.items() if k not in ("wall_s", "eval_s")} for row in csv.DictReader(path.open())]


def _same_study(a: Path, b: Path, seeds: list[int]) -> None:
    assert _untimed_csv(a / "study.csv") == _untimed_csv(b / "study.csv")
    assert (a / "best_design.json").read_bytes() == (b / "best_design.json").read_bytes()
    for s in seeds:
        assert (a / f"seed_{s}/best_design.json").read_bytes() == (b / f"seed_{s}/best_design.json").read_bytes()
    sa, sb = (json.loads((d / "summary.json").read_text()) for d in (a, b))
    assert {k: sa[k] for k in ("best", "median", "worst", "best_seed")} == {
        k: sb[k] for k in ("best", "median", "worst", "best_seed")
    }


@pytest.mark.parametrize(
    ("spec", "want"), [("1-5", [1, 2, 3, 4, 5]), ("7", [7]), ("3,1,2", [1, 2, 3]), ("1-3, 10", [1, 2, 3, 10])]
)
def test_parse_seeds(spec: str, want: list[int]) -> None:
    assert checked_seeds(spec) == want


@pytest.mark.parametrize("spec", ["", " ", "a", "1-", "-3", "3-1", "1,1", "1-3,2", "1.5", "0-5000"])
def test_parse_seeds_refuses(spec: str) -> None:
    with pytest.raises(InputError, match="^seeds") as info:  # the library names its argument; the CLI, its flag
        checked_seeds(spec)
    assert flag_message(info.value).startswith("--seeds")


def test_study_seeds_are_ordinary_runs_and_the_summary_is_their_statistics(tmp_path: Path) -> None:
    st = arcube.study("reference", tmp_path / "st", seeds="1-3", **SETTINGS)
    single = arcube.optimize("reference", out=tmp_path / "one", seed=2, **SETTINGS)
    assert (tmp_path / "st/seed_2/best_design.json").read_bytes() == (single.path / "best_design.json").read_bytes()
    etas = {s: json.loads((tmp_path / f"st/seed_{s}/summary.json").read_text())["eta_G"] for s in (1, 2, 3)}
    assert all(v is not None for v in etas.values()), etas  # these settings reach every point within 12 generations
    summary = st.summary
    assert summary["objective"] == "eta_G" and summary["seeds"] == [1, 2, 3] and summary["feasible_seeds"] == 3
    assert summary["best"] == min(etas.values()) and summary["worst"] == max(etas.values())
    assert summary["median"] == statistics.median(etas.values())
    assert summary["best_seed"] == min(etas, key=etas.get)
    assert st.best_design == arcube.Design.from_json(tmp_path / f"st/seed_{summary['best_seed']}/best_design.json")
    table = st.table
    assert list(table["seed"]) == [1, 2, 3] and list(table["objective_eta_G"]) == [etas[1], etas[2], etas[3]]
    assert (tmp_path / "st/convergence.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert set(st.runs) == {1, 2, 3} and st.runs[3].summary["seed"] == 3


def test_same_seeds_same_study_in_processes_or_not(tmp_path: Path) -> None:
    arcube.study("reference", tmp_path / "a", seeds="4,5", **SETTINGS)
    arcube.study("reference", tmp_path / "b", seeds="4,5", workers=2, **SETTINGS)
    _same_study(tmp_path / "a", tmp_path / "b", [4, 5])


def test_dask_study_equals_the_serial_one(tmp_path: Path) -> None:
    pytest.importorskip("distributed")
    from distributed import LocalCluster

    arcube.study("reference", tmp_path / "a", seeds="2,3", **SETTINGS)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        arcube.study("reference", tmp_path / "b", seeds="2,3", dask=cluster.scheduler_address, **SETTINGS)
    _same_study(tmp_path / "a", tmp_path / "b", [2, 3])


class _Crash(Exception):
    pass


def test_crashed_study_resumes_to_the_same_result(tmp_path: Path) -> None:
    arcube.study("reference", tmp_path / "ref", seeds="1-3", **SETTINGS)
    seen: list[int] = []

    def crash(row: dict) -> None:
        seen.append(row["generation"])
        if len(seen) > 12 + 7:  # seed 1 finished, seed 2 stopped in generation 8 (checkpoint at 6)
            raise _Crash

    with pytest.raises(_Crash):
        arcube.study("reference", tmp_path / "cut", seeds="1-3", progress=crash, **SETTINGS)
    assert studymod.is_study(tmp_path / "cut") and not (tmp_path / "cut/study.csv").exists()
    assert (tmp_path / "cut/seed_1/summary.json").exists() and not (tmp_path / "cut/seed_2/summary.json").exists()
    assert (tmp_path / "cut/seed_3/config.toml").exists()  # prepared, never started
    done: list[int] = []
    st = arcube.resume(tmp_path / "cut", on_seed=lambda seed, summary: done.append(seed))
    assert isinstance(st, arcube.Study) and sorted(done) == [1, 2, 3]
    assert json.loads((tmp_path / "cut/seed_2/summary.json").read_text())["resumed"] == 1
    _same_study(tmp_path / "cut", tmp_path / "ref", [1, 2, 3])


def test_kill9_study_then_resume_cli(tmp_path: Path) -> None:
    flags = [f for f in FLAGS]
    flags[flags.index("--generations") + 1] = "30"  # seed 2 killed at its first checkpoint (3): 27 generations left
    cut = tmp_path / "cut"
    proc = subprocess.Popen(
        [sys.executable, "-m", "arcube", "study", "--seeds", "1-3", "--out", str(cut), *flags],
        env=ENV,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    state, deadline = cut / "seed_2" / "checkpoint" / "state.json", time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None and not state.exists():
        time.sleep(0.005)
    proc.send_signal(signal.SIGKILL)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == -signal.SIGKILL, err.decode()
    assert not (cut / "study.csv").exists() and not (cut / "seed_2/summary.json").exists()
    res = _cli("resume", str(cut), "--quiet")
    assert res.returncode == 0, res.stderr
    assert "eta_G over 3 seeds" in res.stdout and "median" in res.stdout
    ref = _cli("study", "--seeds", "1-3", "--out", str(tmp_path / "ref"), *flags)
    assert ref.returncode == 0, ref.stderr
    _same_study(cut, tmp_path / "ref", [1, 2, 3])
    again = _cli("resume", str(cut), "--quiet")  # a finished study: nothing to run, the same result
    assert again.returncode == 0 and again.stdout == res.stdout


def test_killed_parallel_study_leaves_no_orphan_writing_and_resumes(tmp_path: Path) -> None:
    """kill -9 of a study running two seeds in child processes: the children stop at their next
    generation (they watch their parent), and resume gives the uninterrupted result."""
    flags = list(FLAGS)
    flags[flags.index("--generations") + 1] = "400"
    cut = tmp_path / "cut"
    proc = subprocess.Popen(
        [sys.executable, "-m", "arcube", "study", "--seeds", "1,2", "--workers", "2", "--out", str(cut), *flags],
        env=ENV,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    states, deadline = [cut / f"seed_{s}" / "checkpoint" / "state.json" for s in (1, 2)], time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None and not all(p.exists() for p in states):
        time.sleep(0.01)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(
        timeout=60
    )  # the pipe closes when the children are gone too  # the children notice within a generation and stop with a checkpoint
    sizes = [(cut / f"seed_{s}/history.csv").stat().st_size for s in (1, 2)]
    time.sleep(1.5)
    assert [(cut / f"seed_{s}/history.csv").stat().st_size for s in (1, 2)] == sizes
    assert not any((cut / f"seed_{s}/summary.json").exists() for s in (1, 2))
    res = _cli("resume", str(cut), "--quiet")
    assert res.returncode == 0, res.stderr
    ref = _cli("study", "--seeds", "1,2", "--out", str(tmp_path / "ref"), *flags)
    assert ref.returncode == 0, ref.stderr
    _same_study(cut, tmp_path / "ref", [1, 2])


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--seeds", ""], "--seeds is empty"),
        (["--seeds", "1-x"], "--seeds '1-x'"),
        (["--seeds", "5-1"], "runs backwards"),
        (["--seeds", "1,2", "--seed", "3"], "No such option: --seed"),
        (["--seeds", "1,2", "--workers", "0"], "--workers must be at least 1"),
        (["--seeds", "1,2", "--best-known", "-1"], "--best-known"),
        (["--seeds", "1,2", "--population", "1"], "--population"),
    ],
)
def test_bad_study_input_is_one_line_and_leaves_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    """In this process (arcube.cli.main, as ``python -m arcube`` runs it; one case in a process of its own below)."""
    out = tmp_path / "st"
    code, _, err = run_cli(["study", "--out", str(out), *FLAGS, *args], capsys)
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1, err
    assert message in err and "Traceback" not in err
    assert not out.exists()


def test_bad_study_input_in_a_process_of_its_own_is_one_line(tmp_path: Path) -> None:
    """The same contract through ``python -m arcube`` (start-up, interrupt handling, the real stderr)."""
    out = tmp_path / "st"
    res = _cli("study", "--out", str(out), *FLAGS, "--seeds", "5-1")
    assert res.returncode == 2 and res.stderr.startswith("error: ") and res.stderr.count("\n") == 1, res.stderr
    assert "runs backwards" in res.stderr and "Traceback" not in res.stderr
    assert not out.exists()


def test_unreachable_dask_scheduler_leaves_no_study(tmp_path: Path) -> None:
    pytest.importorskip("distributed")
    out = tmp_path / "st"
    res = _cli("study", "--out", str(out), *FLAGS, "--seeds", "1,2", "--dask", "127.0.0.1:1")
    assert res.returncode == 2 and res.stderr.startswith("error: --dask 127.0.0.1:1") and res.stderr.count("\n") == 1, (
        res.stderr
    )
    assert not out.exists()


def test_resume_of_a_folder_that_is_not_a_study_or_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """In this process (arcube.cli.main, as ``python -m arcube`` runs it)."""
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk/notes.txt").write_text("hello")
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "study.toml").write_text('format = "something-else"\n')
    for folder, message in (
        (tmp_path / "junk", "not an optimization run or study"),
        (tmp_path / "missing", "no such"),
        (broken, "not a study"),
    ):
        before = sorted(p.name for p in folder.iterdir()) if folder.exists() else None
        code, _, err = run_cli(["resume", str(folder), "--quiet"], capsys)
        assert code == 2 and err.startswith("error: ") and err.count("\n") == 1, err
        assert message in err
        assert (sorted(p.name for p in folder.iterdir()) if folder.exists() else None) == before


def test_study_refuses_a_used_folder_and_a_seed_setting(tmp_path: Path) -> None:
    (tmp_path / "used").mkdir()
    (tmp_path / "used/x").write_text("keep me")
    with pytest.raises(InputError, match="not an empty folder"):
        arcube.study("reference", tmp_path / "used", seeds="1", **SETTINGS)
    assert (tmp_path / "used/x").read_text() == "keep me"
    with pytest.raises(InputError, match="drop seed="):
        arcube.study("reference", tmp_path / "s", seeds="1", seed=4, **SETTINGS)
    assert not (tmp_path / "s").exists()
    cfg = build_config(["reference"], seed=9, **SETTINGS)
    assert studymod.seed_config(cfg, 3).settings.seed == 3 and "--seed 3 " in studymod.seed_config(cfg, 3).rerun


def test_best_known_line_on_the_convergence_plots(tmp_path: Path) -> None:
    from arcube.report.figures import read_history
    from arcube.report.html import convergence_figure

    run = arcube.optimize("reference", out=tmp_path / "run", seed=1, **SETTINGS)
    history = read_history(run.path / "history.csv")
    lines = [t for t in convergence_figure(history, 1.25).data if t.name == "best known 1.25"]
    assert (
        len(lines) == 1
        and list(lines[0].y) == [1.25, 1.25]
        and list(lines[0].x) == [history.generation[0], history.generation[-1]]
    )
    assert not [t for t in convergence_figure(history).data if str(t.name).startswith("best known")]
    assert arcube.write_report(run, best_known=1.25).exists()
    res = _cli("report", str(run.path), "--best-known", "0")
    assert res.returncode == 2 and res.stderr == "error: --best-known must be a positive number (an eta_G), got 0.0\n"
