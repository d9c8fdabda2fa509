"""Run and study folders edited, damaged or assembled by hand (a hostile-input review, 2026-11-28): each is refused
in one line naming the file, before any work. Before, an infinite point in config.toml ran the whole run and failed
writing its summary, a FIFO in place of a run file hung ``report`` and ``resume`` for ever, a removed checkpoint
state restarted the run and truncated its history, a seed folder of another study was ranked as this one's, and
study.toml's ``seeds = [1, 1]`` or ``workers = "x"`` went through (or ended in an internal error)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from arcube.errors import InputError
from arcube.optimization.checkpoint import load_checkpoint
from arcube.optimization.folder import is_finished, read_config, read_study
from arcube.optimization.study import resume_study

FLAGS = ["--trajectories", "reference", "--ids", "1,2", "--points", "3", "--algorithm", "ga", "--population", "8"]
MODE = "-,+,+,-"


def _study(folder: Path, generations: int) -> Path:
    out = subprocess.run(
        [sys.executable, "-m", "arcube", "study", *FLAGS, f"--mode={MODE}", "--generations", str(generations)]
        + ["--checkpoint-every", "1"]
        + ["--seeds", "1-2", "--out", str(folder), "--quiet"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr
    return folder


@pytest.fixture(scope="module")
def studies(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    base = tmp_path_factory.mktemp("studies")
    return _study(base / "s", 3), _study(base / "t", 2)


@pytest.fixture
def study(studies: tuple[Path, Path], tmp_path: Path) -> Path:
    return Path(shutil.copytree(studies[0], tmp_path / "s"))


def _edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert old in text, (path, old)
    path.write_text(text.replace(old, new, 1))


def test_a_point_that_is_not_finite_in_config_toml_is_refused(study: Path) -> None:
    config = study / "seed_1" / "config.toml"
    text = config.read_text()
    start = text.index("entry = [[") + len("entry = [[")
    config.write_text(text[:start] + "1e400" + text[text.index(",", start) :])
    with pytest.raises(InputError, match=r"config.toml: \[\[patients\]\] 1 \(reference\) trajectory 1: coordinates"):
        read_config(study / "seed_1")


@pytest.mark.parametrize("workers", ['"many"', "0", "true"])
def test_an_executor_that_is_not_one_is_refused(study: Path, workers: str) -> None:
    _edit(study / "seed_1" / "config.toml", "workers = 1", f"workers = {workers}")
    with pytest.raises(InputError, match=r"config.toml: .*executor.workers must be a whole number >= 1, got"):
        read_config(study / "seed_1")


@pytest.mark.parametrize(
    "old, new, says",
    [
        ("seeds = [1, 2]", "seeds = [1, 1]", "seed 1 is listed twice"),
        ("seeds = [1, 2]", "seeds = [true, 2]", "seeds must be whole numbers >= 0, got True"),
        ("seeds = [1, 2]", "seeds = [-1, 2]", "seeds must be whole numbers >= 0, got -1"),
        ("workers = 1", 'workers = "x"', "workers must be a whole number >= 1, got 'x'"),
    ],
)
def test_a_study_toml_edited_by_hand_is_refused_naming_it(study: Path, old: str, new: str, says: str) -> None:
    _edit(study / "study.toml", old, new)
    with pytest.raises(InputError, match=f"study.toml: {says}"):
        read_study(study)


def test_a_damaged_base_config_is_named_not_study_toml(study: Path) -> None:
    (study / "base_config.toml").write_text("[settings\n")
    with pytest.raises(InputError, match=r"base_config.toml: unreadable"):
        read_study(study)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
@pytest.mark.parametrize("name", ["config.toml", "checkpoint/state.json"])
def test_a_fifo_in_place_of_a_run_file_is_refused_not_waited_on(study: Path, name: str) -> None:
    run = study / "seed_1"
    cfg, raw = read_config(run)
    (run / name).unlink()
    os.mkfifo(run / name)
    if name == "config.toml":
        with pytest.raises(InputError, match=r"config.toml: is a FIFO \(named pipe\), not a regular file"):
            read_config(run)
    else:
        assert not is_finished(run)
        with pytest.raises(InputError, match=r"state.json: is a FIFO"):
            load_checkpoint(run, cfg, raw)


def test_a_removed_checkpoint_state_is_refused_not_started_over(study: Path) -> None:
    run = study / "seed_1"
    cfg, raw = read_config(run)
    (run / "checkpoint" / "state.json").unlink()
    chunks = sorted((run / "checkpoint").glob("evals_*.npz"))
    assert len(chunks) == 3  # one per generation (--checkpoint-every 1)
    with pytest.raises(InputError, match=r"state.json: missing, but .* holds 3 saved chunks"):
        load_checkpoint(run, cfg, raw)
    for chunk in chunks[1:]:  # killed between the first chunk and the first state: nothing to lose
        chunk.unlink()
    assert load_checkpoint(run, cfg, raw) == (None, [])


def test_a_seed_folder_of_another_study_is_refused(studies: tuple[Path, Path], study: Path) -> None:
    shutil.rmtree(study / "seed_2")
    shutil.copytree(studies[1] / "seed_2", study / "seed_2")  # the same seed, 2 generations instead of 3
    with pytest.raises(InputError, match=r"seed_2/config.toml: not seed 2 of this study"):
        resume_study(study)
    shutil.rmtree(study / "seed_2")
    shutil.copytree(studies[0] / "seed_2", study / "seed_2")  # its own: accepted (finished, nothing to run)
    assert resume_study(study)["seeds"] == [1, 2]


def test_a_runs_best_design_carries_its_working_mode(study: Path) -> None:
    """``arcube evaluate --design run/best_design.json`` evaluated a run of --mode -,+,+,- in +,+,+,+: the file did
    not say its mode."""
    import json

    from arcube.model.design import Design

    for seed in ("seed_1", "seed_2"):
        assert json.loads((study / seed / "summary.json").read_text())["mode"] == MODE
        assert Design.from_json(study / seed / "best_design.json").mode == MODE


def test_the_report_refuses_a_damaged_summary_and_takes_a_free_runs_mode_from_its_design(study: Path) -> None:
    import numpy as np

    from arcube.model.mechanism import parse_mode
    from arcube.report import run_report

    (study / "seed_1" / "summary.json").write_text("{")
    with pytest.raises(InputError, match=r"summary.json: damaged .*delete it for a report without it"):
        run_report.write_run_report(study / "seed_1")
    where = study / "seed_1" / "config.toml"
    chosen = run_report._mode({"mode": "free"}, {}, where, MODE)
    np.testing.assert_array_equal(chosen, parse_mode(MODE))
    with pytest.raises(InputError, match="neither summary.json nor best_design.json records it"):
        run_report._mode({"mode": "free"}, {}, where, None)


def test_a_start_design_that_is_not_finite_is_refused(study: Path) -> None:
    """A NaN in config.toml's [design] ran the whole run and failed writing best_design.json."""
    import re

    config = study / "seed_1" / "config.toml"
    text = config.read_text()
    edited = re.sub(r"(\[design\]\nm_x = )[^\n]+", r"\1nan", text)
    assert edited != text
    config.write_text(edited)
    with pytest.raises(InputError, match=r"config.toml: \[design\]: parameter m_x is not finite"):
        read_config(study / "seed_1")


def test_a_patients_table_whose_lists_differ_in_length_is_refused() -> None:
    """Three trajectory ids for two points: the check compared the lengths as a chain and let this one through."""
    from arcube.optimization.build import _points

    pat = {"source": "p", "ids": ["1", "2", "3"], "sides": ["R", "L"], "entry": [[0, 0, 0], [1, 0, 0]]}
    pat["target"] = [[0, 0, 20], [1, 0, 20]]
    with pytest.raises(InputError, match=r"\[\[patients\]\] 1 \(p\): entry and target must be one \[x, y, z\] per"):
        _points(0, pat)
    entry, target, sides = _points(0, {**pat, "ids": ["1", "2"]})
    assert entry.shape == target.shape == (2, 3) and sides == ["R", "L"]
