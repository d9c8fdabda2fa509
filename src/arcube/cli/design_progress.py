"""What a user watching ``arcube design`` (or its resume) sees on stderr while the job runs.

Per seed: the generation, the evaluations done out of the seed's budget, the best eta_G found (or, while
no design is feasible yet, the smallest violation) and the time left; then the named stages after the
search (checking with the NumPy reference, building the program, writing the outputs). On a terminal a
Rich bar; otherwise (a CI log, a pipe) one plain line every :data:`LOG_EVERY_S` seconds and one per
event, so that a log shows the job is alive and how far it is.

Seeds that run in other processes (``--workers``, ``--dask``) send no generation to this one: then
:meth:`DesignProgress.watch` reads the last complete row of each running seed's ``history.csv``
(written every generation) and reports the seeds together.
"""

from __future__ import annotations

import csv
import math
import sys
import threading
import time
from pathlib import Path
from typing import Any, TextIO

__all__ = ["LOG_EVERY_S", "DesignProgress", "duration"]

LOG_EVERY_S = 10.0
"""Seconds between two plain progress lines when stderr is not a terminal."""


def duration(seconds: float) -> str:
    """``95`` -> ``1 min 35 s``; ``3700`` -> ``1 h 2 min``; NaN or inf -> ``unknown``."""
    if not math.isfinite(seconds) or seconds < 0:
        return "unknown"
    s = int(round(seconds))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60} s"
    return f"{s // 3600} h {(s % 3600) // 60} min"


def _best(row: dict[str, Any]) -> str:
    best = row.get("best_eta_G", math.inf)
    if isinstance(best, (int, float)) and math.isfinite(best):
        return f"best eta_G {best:.4g} (feasible {row.get('feasible_fraction', 0.0):.0%})"
    viol = row.get("best_violation", math.nan)
    return (
        f"none feasible yet, smallest violation {viol:.3g}"
        if isinstance(viol, (int, float)) and math.isfinite(viol)
        else "none feasible yet"
    )


def last_row(history: Path) -> dict[str, Any] | None:
    """The last complete row of a run's ``history.csv`` (numbers as floats), or None (no file or no row yet)."""
    try:
        text = history.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return None
    lines = text.splitlines(keepends=True)
    if len(lines) < 2 or not lines[-1].endswith("\n"):  # a row being written is not read
        lines = lines[:-1]
    if len(lines) < 2:
        return None
    row = next(csv.DictReader([lines[0], lines[-1]]), None)
    out: dict[str, Any] = {}
    for key, value in (row or {}).items():
        try:
            out[str(key)] = float(value) if value not in (None, "") else math.nan
        except ValueError:
            out[str(key)] = value
    return out


class DesignProgress:
    """Progress of a design job: pass :meth:`generation` as ``progress``, :meth:`seed` as ``on_seed`` and
    :meth:`stage` as ``on_stage`` to :func:`arcube.design` / :func:`arcube.resume`; use as a context manager.

    ``seeds``: the job's seeds in run order; ``budget``: evaluations per seed (population x generations);
    ``dockings``: the job's dockings (the time left weighs each row by what it evaluates:
    :func:`arcube.optimization.docked.row_work`); ``enabled``: False for ``--quiet``; ``stream``: stderr (tests give their own).
    """

    def __init__(
        self,
        seeds: list[int],
        budget: int,
        enabled: bool = True,
        stream: TextIO | None = None,
        clock: Any = time.monotonic,
        dockings: int = 1,
    ) -> None:
        self.seeds, self.budget, self.enabled = list(seeds), max(int(budget), 1), enabled
        self.dockings = max(int(dockings), 1)
        self.stream = sys.stderr if stream is None else stream
        self.clock = clock
        self.done: dict[int, dict[str, Any]] = {}
        self.first: tuple[int, int, float] | None = None  # (seed, evaluations, session s) at its first row seen
        self.last_log = -math.inf
        self.last_generation = -math.inf  # when generation() was last called (seeds in this process)
        self.started = clock()
        self.seen: dict[int, float] = {}  # seed -> evaluations at the first history row watched
        self.lock = threading.Lock()
        self.stop = threading.Event()
        self.watcher: threading.Thread | None = None
        self.bar: Any = None
        if enabled and self.stream.isatty():
            from rich.console import Console
            from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

            self.bar = Progress(
                TextColumn("{task.description}"),
                BarColumn(),
                TextColumn("{task.fields[status]}"),
                TimeElapsedColumn(),
                console=Console(file=self.stream),
            )
            self.task = self.bar.add_task("design", total=len(self.seeds) * self.budget, status="starting")

    def __enter__(self) -> DesignProgress:
        if self.bar is not None:
            from arcube.cli.common import LIVE_BARS

            self.bar.__enter__()
            LIVE_BARS[0] += 1
        return self

    def __exit__(self, *exc: Any) -> None:
        self.stop.set()
        if self.watcher is not None:
            self.watcher.join(timeout=5.0)
        if self.bar is not None:
            from arcube.cli.common import LIVE_BARS

            LIVE_BARS[0] -= 1
            self.bar.__exit__(*exc)

    def watch(self, study: str | Path) -> None:
        """Report seeds that run in other processes from their ``history.csv`` under ``study`` (the job's
        study folder), every second on a terminal and every :data:`LOG_EVERY_S` s otherwise; silent while
        :meth:`generation` is being called (the seeds run in this process)."""
        if not self.enabled or self.watcher is not None:
            return
        self.watcher = threading.Thread(target=self._poll, args=(Path(study),), name="design-progress", daemon=True)
        self.watcher.start()

    def _poll(self, study: Path) -> None:
        from arcube.optimization.folder import seed_dir

        while not self.stop.wait(1.0 if self.bar is not None else LOG_EVERY_S):
            if self.clock() - self.last_generation < 2 * LOG_EVERY_S:
                continue
            rows = {
                s: r
                for s in self.seeds
                if s not in self.done and (r := last_row(seed_dir(study, s) / "history.csv")) is not None
            }
            if rows:
                self.running(rows)

    def work(self, rows: float) -> float:
        """The work of a seed's first ``rows`` rows (docking evaluations; rows with one docking)."""
        from arcube.optimization.docked import row_work

        return row_work(rows, self.budget, self.dockings)

    def running(self, rows: dict[int, dict[str, Any]]) -> None:
        """The seeds running in other processes, each with its last history row."""
        parts, worked, ran = [], 0.0, 0.0
        evals = {seed: min(float(row.get("evaluations", 0.0)), float(self.budget)) for seed, row in rows.items()}
        for seed, row in sorted(rows.items()):
            e = evals[seed]
            self.seen.setdefault(seed, e)
            w = self.work(e)
            worked, ran = worked + w, ran + w - self.work(self.seen[seed])
            parts.append(
                f"seed {seed} generation {int(row.get('generation', 0))}, {int(e):,} evaluations, {_best(row)}"
            )
        done = sum(min(float(v.get("evaluations", self.budget)), float(self.budget)) for v in self.done.values())
        took = self.clock() - self.started
        left_work = (len(self.seeds) - len(self.done)) * self.work(self.budget) - worked  # docking evaluations left
        left = left_work / (ran / took) if ran > 0 and took > 0 else math.nan
        text = (
            f"{len(rows)} seeds running ({len(self.done)} of {len(self.seeds)} done): "
            + "; ".join(parts)
            + (f"; about {duration(left)} left" if math.isfinite(left) else "")
        )
        if self.bar is not None:
            self.bar.update(self.task, completed=done + sum(evals.values()))
        self._say(text, force=True)

    @property
    def current(self) -> int | None:
        """The seed running now: the first one not finished (seeds run one after the other)."""
        return next((s for s in self.seeds if s not in self.done), None)

    def _say(self, text: str, force: bool = False) -> None:
        if not self.enabled:
            return
        if self.bar is not None:
            self.bar.update(self.task, status=text)
            return
        with self.lock:  # the watcher thread writes too
            now = self.clock()
            if force or now - self.last_log >= LOG_EVERY_S:
                self.last_log = now
                self.stream.write(f"design: {text}\n")
                self.stream.flush()

    def generation(self, row: dict[str, Any]) -> None:
        """One generation of the running seed (a history row with its timing, :class:`~arcube.optimization.loop.Progress`)."""
        seed = self.current
        if seed is None:
            return
        self.last_generation = self.clock()
        k = self.seeds.index(seed)
        evals = min(int(row.get("evaluations", 0)), self.budget)
        session = float(row.get("session_s", 0.0))
        if self.first is None or self.first[0] != seed:  # a resumed seed starts with its earlier evaluations done
            self.first = (seed, evals, session)
        ran, took = self.work(evals) - self.work(self.first[1]), session - self.first[2]
        rate = ran / took if took > 0 and ran > 0 else math.nan  # docking evaluations per second
        full = self.work(self.budget)
        left = (full - self.work(evals) + (len(self.seeds) - k - 1) * full) / rate if rate == rate else math.nan
        text = (
            f"seed {seed} ({k + 1} of {len(self.seeds)}): generation {row.get('generation')}, {evals:,} of {self.budget:,} evaluations, "
            f"{_best(row)}" + (f"; about {duration(left)} left" if math.isfinite(left) else "")
        )
        if self.bar is not None:
            self.bar.update(self.task, completed=len(self.done) * self.budget + evals)
        self._say(text)

    def seed(self, seed: int, summary: dict[str, Any]) -> None:
        """A seed finished (its run's summary)."""
        self.done[seed] = summary
        eta = summary.get("eta_G")
        verdict = f"eta_G {eta:.4g}" if isinstance(eta, (int, float)) and math.isfinite(eta) else "no feasible design"
        if self.bar is not None:
            self.bar.update(self.task, completed=len(self.done) * self.budget)
        self._say(
            f"seed {seed} done ({len(self.done)} of {len(self.seeds)}): {verdict}, {summary.get('evaluations', 0):,} evaluations "
            f"in {duration(float(summary.get('wall_s', math.nan)))}",
            force=True,
        )

    def stage(self, text: str) -> None:
        """A named stage after the search ("checking seed 2 with the NumPy reference", ...)."""
        self._say(f"{text} ({duration(self.clock() - self.started)} so far)", force=True)
