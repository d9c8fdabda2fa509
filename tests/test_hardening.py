"""The CLI's promise under interrupts, races and damaged run folders: a one-line error with the right
exit code, nothing deleted that another process owns, and no edited checkpoint trusted."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from arcube.optimization import run as runmod

SMALL = [
    "--trajectories",
    "reference",
    "--ids",
    "1,3",
    "--points",
    "5",
    "--algorithm",
    "ga",
    "--population",
    "20",
    "--ftol",
    "0",
    "--seed",
    "7",
    "--quiet",
    "--engine",
    "numpy",
]


def _arcube(*args: str, cwd: Path, timeout: float = 600) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "arcube", *args], capture_output=True, text=True, cwd=cwd, timeout=timeout
    )


def test_ctrl_c_exits_130_with_one_line_and_leaves_a_resumable_run(tmp_path: Path) -> None:
    p = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "arcube",
            "optimize",
            *SMALL,
            "--generations",
            "5000",
            "--checkpoint-every",
            "1",
            "--out",
            "r",
        ],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    state = tmp_path / "r" / "checkpoint" / "state.json"
    deadline = time.monotonic() + 120
    while not state.exists() and time.monotonic() < deadline and p.poll() is None:
        time.sleep(0.2)
    assert state.exists(), "no checkpoint within 120 s"
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 130 and err == "error: interrupted\n", err
    cfg, raw = runmod.read_config(tmp_path / "r")
    saved, _ = runmod.load_checkpoint(tmp_path / "r", cfg, raw)  # a resume would accept it
    assert saved is not None and saved["generation"] >= 1 and not runmod.is_finished(tmp_path / "r")


def test_two_runs_started_into_one_folder_one_runs_nothing_is_deleted(tmp_path: Path) -> None:
    for trial in range(3):
        out = f"r{trial}"
        procs = [
            subprocess.Popen(
                [sys.executable, "-m", "arcube", "optimize", *SMALL, "--generations", "5", "--out", out],
                cwd=tmp_path,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
            )
            for _ in range(2)
        ]
        results = [(p.wait(timeout=600), p.stderr.read()) for p in procs]  # type: ignore[union-attr]
        codes = sorted(rc for rc, _ in results)
        assert codes == [0, 2], results
        refused = next(err for rc, err in results if rc == 2)
        assert refused.count("\n") == 1 and refused.startswith("error: ")
        assert json.loads((tmp_path / out / "summary.json").read_text())["generations"] == 5
        assert not (tmp_path / out / ".running").exists()


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    base = tmp_path_factory.mktemp("run")
    out = _arcube("optimize", *SMALL, "--generations", "4", "--checkpoint-every", "1", "--out", "r", cwd=base)
    assert out.returncode == 0, out.stderr
    return base / "r"


def _unfinish(run: Path, tmp_path: Path) -> Path:
    """A copy of the finished run that looks interrupted (state not finished, no summary)."""
    import shutil

    copy = tmp_path / "copy"
    shutil.copytree(run, copy)
    (copy / "summary.json").unlink()
    return copy


def test_an_edited_checkpoint_state_is_refused(finished_run: Path, tmp_path: Path) -> None:
    run = _unfinish(finished_run, tmp_path)
    path = run / "checkpoint" / "state.json"
    state = json.loads(path.read_text())
    state["generation"] = state["generation"] + 10  # "generation edited past the end"
    path.write_text(json.dumps(state))
    out = _arcube("resume", str(run), "--quiet", cwd=tmp_path)
    assert out.returncode == 2 and "edited or corrupt checkpoint state" in out.stderr and out.stderr.count("\n") == 1, (
        out.stderr
    )


def test_a_damaged_history_is_refused_by_resume(finished_run: Path, tmp_path: Path) -> None:
    run = _unfinish(finished_run, tmp_path)
    lines = (run / "history.csv").read_text().splitlines()
    lines[2] = "2,40,garbage,,,,"
    (run / "history.csv").write_text("\n".join(lines) + "\n")
    out = _arcube("resume", str(run), "--quiet", cwd=tmp_path)
    assert out.returncode == 2 and "history.csv: edited or corrupt" in out.stderr and out.stderr.count("\n") == 1, (
        out.stderr
    )


@pytest.mark.parametrize(
    ("damage", "needle"),
    [
        (lambda data: data + "é,1\n".encode("latin-1"), "not UTF-8 text"),
        (lambda data: bytes(range(256)) * 4, "not UTF-8 text"),
        (lambda data: data.replace(b"\n", b",7\n", 2), "fields, the header has"),
    ],
)
def test_a_damaged_history_is_refused_by_the_report(finished_run: Path, tmp_path: Path, damage, needle: str) -> None:
    """A binary or damaged history.csv is a damaged run folder: the report says so (one line, exit 2,
    no report written) instead of drawing around it."""
    import shutil

    run = tmp_path / "damaged"
    shutil.copytree(finished_run, run)
    (run / "history.csv").write_bytes(damage((run / "history.csv").read_bytes()))
    out = _arcube("report", str(run), cwd=tmp_path)
    assert (
        out.returncode == 2
        and out.stderr.count("\n") == 1
        and out.stderr.startswith(f"error: {run / 'history.csv'}")
        and needle in out.stderr
    ), out.stderr
    assert "delete it for a report without the convergence plot" in out.stderr and not (run / "report.html").exists()


def test_without_its_history_a_run_is_reported_without_the_convergence_plot(finished_run: Path, tmp_path: Path) -> None:
    """What the refusal above advises: history.csv deleted, the report is written and says it has no convergence plot
    (the same for every damage, so once, not per damaged history)."""
    import shutil

    run = tmp_path / "damaged"
    shutil.copytree(finished_run, run)
    (run / "history.csv").unlink()
    out = _arcube("report", str(run), cwd=tmp_path)
    assert out.returncode == 0 and out.stderr == "", out.stderr
    assert "no convergence plot (the run folder has no history.csv)" in (run / "report.html").read_text()


@pytest.mark.parametrize(
    ("edit", "needle"),
    [
        (("population = 20", 'population = "twenty"'), "settings.population must be an integer, got 'twenty'"),
        (("seed = 7", 'seed = "x"'), "settings.seed must be an integer, got 'x'"),
        (('algorithm = "ga"', "algorithm = 5"), "settings.algorithm is invalid"),
    ],
)
def test_resume_names_the_config_file_and_its_key(
    finished_run: Path, tmp_path: Path, edit: tuple[str, str], needle: str
) -> None:
    run = _unfinish(finished_run, tmp_path)
    config = (run / "config.toml").read_text()
    assert f"\n{edit[0]}\n" in config
    (run / "config.toml").write_text(config.replace(f"\n{edit[0]}\n", f"\n{edit[1]}\n"))
    out = _arcube("resume", str(run), "--quiet", cwd=tmp_path)
    assert (
        out.returncode == 2
        and out.stderr.startswith(f"error: {run / 'config.toml'}: {needle}")
        and out.stderr.count("\n") == 1
    ), out.stderr


@pytest.mark.parametrize("points", ["20000000000000000000", "1000000000"])
def test_points_are_bounded_and_leave_no_folder(tmp_path: Path, points: str) -> None:
    out = _arcube("optimize", "--trajectories", "reference", "--points", points, "--out", "r", "--quiet", cwd=tmp_path)
    assert out.returncode == 2 and "--points must be" in out.stderr and out.stderr.count("\n") == 1, out.stderr
    assert not (tmp_path / "r").exists()


def test_an_anatomy_metres_wide_is_refused_before_its_grids_are_allocated() -> None:
    import trimesh

    from arcube import InputError
    from arcube.evaluation.sdf import AnatomyDistance

    with pytest.raises(InputError, match=r"^anatomy spans 3000 x 3000 x 3000 mm: .* GiB .* in mm"):
        AnatomyDistance.from_meshes([trimesh.creation.box(extents=(3000.0, 3000.0, 3000.0))])


def test_the_api_checks_what_the_cli_checks() -> None:
    import numpy as np

    import arcube
    from arcube import InputError
    from arcube.io.trajectories import TrajectorySet

    with pytest.raises(InputError, match="expected 27 values"):
        arcube.evaluate([1.0] * 26, "reference")
    with pytest.raises(InputError, match="^points must be an integer"):
        arcube.evaluate("paper", "reference", points=2.5)  # type: ignore[arg-type]
    hand = TrajectorySet(("1",), ("C3",), ("R",), np.array([[np.nan, 0.0, 0.0]]), np.array([[0.0, 0.0, 1.0]]), "hand")
    with pytest.raises(InputError, match="not finite"):
        arcube.evaluate("paper", hand)
    with pytest.raises(InputError, match="^RunSettings.population"):
        arcube.RunSettings(population=8.5)
    # a preset name is a design for the MuJoCo export too (it used to fail converting 'paper' to float)
    xml = arcube.export_mjcf(
        arcube.Design.paper().replace(m_x=88.23, m_y=79.40, m_z=56.89).with_extras(c_z=160.0),
        arcube.select(arcube.load_trajectories("reference"), side="R"),
    )
    assert "<mujoco" in xml and xml.rstrip().endswith("</mujoco>")
    with pytest.raises(InputError, match="reaches no point"):
        arcube.export_mjcf("paper", "reference")


def test_a_dask_address_without_port_is_refused_at_once(tmp_path: Path) -> None:
    start = time.monotonic()
    out = _arcube(
        "optimize",
        "--trajectories",
        "reference",
        "--dask",
        "127.0.0.1",
        "--out",
        "r",
        "--quiet",
        cwd=tmp_path,
        timeout=120,
    )
    assert out.returncode == 2 and out.stderr.startswith(
        "error: --dask '127.0.0.1': expected a scheduler address HOST:PORT"
    )
    assert out.stderr.count("\n") == 1 and time.monotonic() - start < 30 and not (tmp_path / "r").exists()


@pytest.mark.parametrize(
    "args",
    [["joints", "--points", "3", "--ids", "1,2", "--out", ""], ["optimize", "--trajectories", "reference", "--out="]],
)
def test_an_empty_out_is_not_the_current_folder(tmp_path: Path, args: list[str]) -> None:
    out = _arcube(*args, cwd=tmp_path)
    assert (
        out.returncode == 2
        and out.stderr == "error: --out: empty path (give a file or folder name)\n"
        and os.listdir(tmp_path) == []
    )
