"""A run that stops on a bad input before its first generation leaves nothing behind."""

from __future__ import annotations

from pathlib import Path

import pytest

from harness import arcube


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
