"""What a user watching ``arcube design`` (or its resume) sees on stderr while the job runs.

Per seed: the generation, the evaluations done out of the seed's budget, the best eta_G found (or, while
no design is feasible yet, the smallest violation) and the time left; then the named stages after the
search (checking with the NumPy reference, building the program, writing the outputs). On a terminal a
Rich bar; otherwise (a CI log, a pipe) one plain line every :data:`LOG_EVERY_S` seconds and one per
event, so that a log shows the job is alive and how far it is.
"""

from __future__ import annotations

import math
import sys
import time
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
    return f"none feasible yet, smallest violation {viol:.3g}" if isinstance(viol, (int, float)) and math.isfinite(viol) else "none feasible yet"


class DesignProgress:
    """Progress of a design job: pass :meth:`generation` as ``progress``, :meth:`seed` as ``on_seed`` and
    :meth:`stage` as ``on_stage`` to :func:`arcube.design` / :func:`arcube.resume`; use as a context manager.

    ``seeds``: the job's seeds in run order; ``budget``: evaluations per seed (population x generations);
    ``enabled``: False for ``--quiet``; ``stream``: stderr (tests give their own).
    """

    def __init__(self, seeds: list[int], budget: int, enabled: bool = True, stream: TextIO | None = None,
                 clock: Any = time.monotonic) -> None:  # fmt: skip
        self.seeds, self.budget, self.enabled = list(seeds), max(int(budget), 1), enabled
        self.stream = sys.stderr if stream is None else stream
        self.clock = clock
        self.done: dict[int, dict[str, Any]] = {}
        self.first: tuple[int, int, float] | None = None  # (seed, evaluations, session s) at its first row seen
        self.last_log = -math.inf
        self.started = clock()
        self.bar: Any = None
        if enabled and self.stream.isatty():
            from rich.console import Console
            from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

            self.bar = Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.fields[status]}"), TimeElapsedColumn(),
                                console=Console(file=self.stream))  # fmt: skip
            self.task = self.bar.add_task("design", total=len(self.seeds) * self.budget, status="starting")

    def __enter__(self) -> DesignProgress:
        if self.bar is not None:
            self.bar.__enter__()
        return self

    def __exit__(self, *exc: Any) -> None:
        if self.bar is not None:
            self.bar.__exit__(*exc)

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
        k = self.seeds.index(seed)
        evals = min(int(row.get("evaluations", 0)), self.budget)
        session = float(row.get("session_s", 0.0))
        if self.first is None or self.first[0] != seed:  # a resumed seed starts with its earlier evaluations done
            self.first = (seed, evals, session)
        ran, took = evals - self.first[1], session - self.first[2]
        rate = ran / took if took > 0 and ran > 0 else math.nan
        left = (self.budget - evals + (len(self.seeds) - k - 1) * self.budget) / rate if rate == rate else math.nan
        text = (f"seed {seed} ({k + 1} of {len(self.seeds)}): generation {row.get('generation')}, {evals:,} of {self.budget:,} evaluations, "
                f"{_best(row)}" + (f"; about {duration(left)} left" if math.isfinite(left) else ""))  # fmt: skip
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
        self._say(f"seed {seed} done ({len(self.done)} of {len(self.seeds)}): {verdict}, {summary.get('evaluations', 0):,} evaluations "
                  f"in {duration(float(summary.get('wall_s', math.nan)))}", force=True)  # fmt: skip

    def stage(self, text: str) -> None:
        """A named stage after the search ("checking seed 2 with the NumPy reference", ...)."""
        self._say(f"{text} ({duration(self.clock() - self.started)} so far)", force=True)
