"""A run that stops on a bad input before its first generation leaves nothing behind."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from harness import arcube, skip_unless_replays_here


@pytest.mark.parametrize("existing", [False, True])
def test_unreachable_dask_scheduler_leaves_no_run_folder(tmp_path: Path, existing: bool) -> None:
    pytest.importorskip("distributed")
    out = tmp_path / "run"
    if existing:
        out.mkdir()  # an empty folder given as --out stays, empty
    res = arcube(
        "optimize",
        "--trajectories",
        "reference",
        "--generations",
        "2",
        "--population",
        "8",
        "--dask",
        "127.0.0.1:1",
        "--out",
        str(out),
    )
    assert res.returncode == 2, res.stderr
    assert res.stderr.startswith("error: --dask 127.0.0.1:1") and res.stderr.count("\n") == 1
    assert (out.is_dir() and not any(out.iterdir())) if existing else not out.exists()


def test_a_run_folder_of_0_2_killed_midway_resumes_to_the_uninterrupted_run(tmp_path: Path) -> None:
    """tests/data/run_0_2_killed was written by arcube 0.2 (commit 10763fc: ``--tolerance 0 --aggregate worst``, the
    names before 0.3) and killed with SIGKILL after its generation-10 checkpoint (history.csv holds 12 rows; the lock
    ``.running`` it left is kept). Resumed by this version, it ends where an uninterrupted run of the same settings
    under today's names ends: the same designs, the same history.

    Made on a CPU whose numpy ``simd_extensions`` found X86_V3 (AVX2, no AVX-512): its checkpoint stores digests of
    the design batches, and a CPU with other SIMD features can compute the GA's crossover (and the evaluation) in
    other last bits, so the folder does not replay there: skipped then, once a fresh run of its config by this code is
    shown to run as 0.2 did (:func:`harness.skip_unless_replays_here`)."""
    import shutil
    import warnings

    import arcube as lib
    from arcube.errors import RenamedWarning

    data = Path(__file__).parent / "data" / "run_0_2_killed"
    skip_unless_replays_here(data, data / "history.csv", tmp_path)
    old = tmp_path / "old"
    shutil.copytree(data, old)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RenamedWarning)  # an old folder is read silently
        resumed = lib.resume(old)
    fresh = lib.optimize(
        "reference",
        out=tmp_path / "fresh",
        points=30,
        free="m_x,m_y,m_z",
        algorithm="ga",
        population=20,
        generations=30,
        checkpoint_every=5,
        seed=1,
        aggregate="max",
        engine="numpy",
        ftol=0.0,
    )
    assert (old / "best_design.json").read_bytes() == (fresh.path / "best_design.json").read_bytes()
    untimed = [{k: v for k, v in row.items() if k != "seconds"} for row in csv.DictReader((old / "history.csv").open())]
    assert len(untimed) == 30
    assert untimed == [
        {k: v for k, v in row.items() if k != "seconds"} for row in csv.DictReader((fresh.path / "history.csv").open())
    ]
    assert resumed.summary["eta_G"] == fresh.summary["eta_G"]
