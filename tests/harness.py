"""How the tests drive the program from outside: the command line in a subprocess (:func:`arcube`) and a
headless Chromium for the browser tests (:data:`CHROMIUM_SKIP`, :func:`start_chromium`)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest


def arcube(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """``python -m arcube ARGS`` in a subprocess (this interpreter), its output captured as text; 300 s at most."""
    return subprocess.run([sys.executable, "-m", "arcube", *args], capture_output=True, text=True, cwd=cwd, timeout=300)


# ----------------------------------------------------------------------------- headless Chromium (browser tests)
CHROMIUM, CHROMEDRIVER = "/usr/bin/chromium", "/usr/bin/chromedriver"
CHROMIUM_SKIP = pytest.mark.skipif(
    not (Path(CHROMIUM).exists() and Path(CHROMEDRIVER).exists()) and os.environ.get("CI") != "true",
    reason="headless Chromium not installed (apt-get install chromium chromium-driver)",
)
"""Skip a browser test when Chromium is missing, except on CI (CI=true), where that is a failure."""


def run_cli(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """``arcube ARGV`` in this process: (exit code, stdout, stderr), as captured by ``capsys``."""
    from arcube.cli import main

    try:
        main(argv)
        code = 0
    except SystemExit as exc:
        code = int(exc.code or 0)
    out = capsys.readouterr()
    return code, out.out, out.err


def cli_error(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    """``arcube ARGV`` in this process: (exit code, stderr)."""
    code, _, err = run_cli(argv, capsys)
    return code, err


def start_chromium(profile: Path, *args: str):  # noqa: ANN201 - a selenium driver
    """A headless Chromium driver with a fresh profile in ``profile``, the browser log kept, and ``args``
    added to the common ones; skips without selenium unless on CI."""
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        if os.environ.get("CI") == "true":
            raise
        pytest.skip("selenium not installed (pip install -e '.[test]')")
    assert os.path.exists(CHROMIUM) and os.path.exists(CHROMEDRIVER), (
        f"{CHROMIUM} or {CHROMEDRIVER} is missing (CI=true: install chromium and chromium-driver)"
    )
    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for arg in (
        "--headless=new",
        "--no-sandbox",
        "--disable-dev-shm-usage",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--no-first-run",
        *args,
        f"--user-data-dir={profile}",
    ):
        opts.add_argument(arg)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)


def assert_csvs_read_back(folder: Path) -> int:
    """Every CSV under ``folder`` reads back with Python's csv module and with pandas, every row at the header's field
    count (a field holding a comma is quoted); returns how many were read."""
    import csv

    import pandas as pd

    files = sorted(Path(folder).rglob("*.csv"))
    for path in files:
        with open(path, newline="", encoding="utf-8") as f:
            rows = list(csv.reader(f))
        assert rows, path
        assert all(len(r) == len(rows[0]) for r in rows), f"{path}: a row's field count differs from the header's"
        frame = pd.read_csv(path)
        assert frame.shape == (len(rows) - 1, len(rows[0])), path
    return len(files)


# ----------------------------------------------------------------------------- run folders written elsewhere
def skip_unless_replays_here(killed: Path, reference: Path, tmp: Path) -> None:
    """Skip a test resuming the killed run folder ``killed`` (a fixture written by older code on some machine) when
    this machine's floating point does not reproduce it, instead of failing for a reason that is not the code.

    A checkpoint logs the SHA-256 of each batch of designs the optimizer asked for, not the designs: a CPU with other
    SIMD features (numpy's ``simd_extensions``) can compute the GA's crossover and the evaluation differently in the
    last bits, and such a folder does not replay there. So the same configuration (``killed``'s config.toml, read by
    this code) is run afresh into ``tmp`` for as many generations as the checkpoint holds, and its batches' digests
    compared with the logged ones: other digests skip. A regression of the code would change them as well, so this
    fresh run's history is first asserted (not skipped) to be that of ``reference`` (a history.csv of the old code's
    run, generations 1 on; ``seconds`` left out), its numbers to 1e-9 relative: a regression breaks that on any
    machine, last bits of another CPU do not."""
    import csv
    import json
    import math

    import numpy as np

    from arcube.optimization.folder import read_config
    from arcube.optimization.run import start

    def digests(folder: Path) -> list[bytes]:
        state = json.loads((folder / "checkpoint" / "state.json").read_text(encoding="utf-8"))
        out = []
        for chunk in state["chunks"]:
            with np.load(folder / "checkpoint" / chunk["file"], allow_pickle=False) as z:
                out += [d.tobytes() for d in z["digest"]]
        return out

    def rows(path: Path) -> list[dict[str, str]]:
        with open(path, newline="", encoding="utf-8") as f:
            return [{k: v for k, v in row.items() if k != "seconds"} for row in csv.DictReader(f)]

    def close(a: str, b: str) -> bool:
        return a == b or (a != "" and b != "" and math.isclose(float(a), float(b), rel_tol=1e-9, abs_tol=0.0))

    generations = int(json.loads((killed / "checkpoint" / "state.json").read_text(encoding="utf-8"))["generation"])
    cfg, _ = read_config(killed)
    fresh = tmp / f"fresh_{generations}_generations"
    start(fresh, cfg.replace(settings=cfg.settings.replace(generations=generations)))
    ran, want = rows(fresh / "history.csv"), rows(reference)[:generations]
    assert len(ran) == len(want) == generations, (len(ran), len(want), generations)
    for got, old in zip(ran, want, strict=True):
        assert got.keys() == old.keys() and all(close(got[k], old[k]) for k in got), (
            f"{killed.name}: a fresh run of its config by this code is not the old code's run: {got} != {old}"
        )
    logged = digests(killed)
    if digests(fresh)[: len(logged)] != logged:
        pytest.skip(
            f"{killed} does not replay on this machine: made on a CPU with other SIMD features (floating point "
            "differs in the last bits; see the fixture's README or the test's docstring)"
        )
