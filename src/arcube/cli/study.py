"""The ``study`` command: one optimization per seed, then best / median / worst.

It takes every option of ``arcube optimize`` (the same flags, generated from :class:`arcube.RunSettings`)
except ``--seed``, plus ``--seeds``; ``--workers`` and ``--dask`` spread the seeds, not the population.
``arcube resume STUDY_DIR`` finishes an interrupted study.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import typer

from arcube.cli.common import DASK, OUT, QUIET, WORKERS, RichBar, with_help
from arcube.cli.projection import Given, command, option

__all__ = ["SEEDS", "SeedProgress", "print_study", "register"]

SEEDS = option("--seeds", "Seeds, one run each: 1-5, 1,3,7 or 1-3,10. [default: 1-5]", params=("seeds",))
BEST_KNOWN = option(
    "--best-known", "An eta_G to draw as a line on the convergence figure.", float, params=("best_known",)
)
SEED_WORKERS = with_help(WORKERS, "Seeds run at once, each in its own process. [default: 1]")
SEED_DASK = with_help(
    DASK, "Address of a dask.distributed scheduler: each seed is one task (its workers must see the study folder)."
)


def print_study(study_dir: Path, summary: dict[str, Any]) -> None:
    """The per-seed table and best / median / worst of the first objective."""
    name = summary["objective"]
    extra = name != "eta_G"
    typer.echo(
        f"{'seed':>6}  {'feasible':8}  "
        + (f"{name:>14}  " if extra else "")
        + f"{'eta_G':>9}  {'violation':>9}  {'generations':>11}  "
        f"{'evaluations':>11}  {'wall s':>7}"
    )
    for r in summary["rows"]:
        value = f"{_num(r.get(f'objective_{name}')):>14}  " if extra else ""
        typer.echo(
            f"{r['seed']:>6}  {'yes' if r['feasible'] else 'NO':8}  {value}{_num(r['eta_G']):>9}  {_num(r['violation']):>9}  "
            f"{r['generations']:>11}  {r['evaluations']:>11}  {r['wall_s']:>7.1f}"
        )
    spread = f"; spread {summary['spread_pct']:.1f} %" if summary.get("spread_pct") is not None else ""
    typer.echo(
        f"{name} over {len(summary['seeds'])} seeds ({summary['feasible_seeds']} feasible): best {_num(summary['best'])} "
        f"(seed {summary['best_seed']}), median {_num(summary['median'])}, worst {_num(summary['worst'])}{spread}"
    )
    typer.echo(f"results in {study_dir} (study.csv, best_design.json, convergence.png)")


def _num(v: Any) -> str:
    return f"{v:.6g}" if isinstance(v, (int, float)) and math.isfinite(v) else "-"


class SeedProgress(RichBar):
    """Rich progress over seeds on stderr (a seed counts when its run finishes)."""

    def __init__(self, total: int, enabled: bool) -> None:
        from rich.progress import TextColumn, TimeElapsedColumn

        super().__init__(
            enabled, ("seeds", TextColumn("{task.fields[last]}"), TimeElapsedColumn()), total=total, last=""
        )

    def __call__(self, seed: int, summary: dict[str, Any]) -> None:
        if self.enabled:
            self.progress.advance(self.task)
            self.progress.update(self.task, last=f"seed {seed}: eta_G {_num(summary.get('eta_G'))}")


def study(given: Given) -> None:
    """Run the same optimization once per seed (in parallel with --workers or --dask) and report best / median / worst."""
    from arcube.api import study as study_api
    from arcube.cli.optimize import run_settings
    from arcube.coerce import seeds as checked_seeds

    seeds = given.get("seeds", "1-5")
    settings = run_settings(given)
    n = len(checked_seeds(seeds))
    with SeedProgress(n, enabled=not given.get("quiet")) as bar:
        result = study_api(
            given.get("plan"),
            given.get("out"),
            seeds=seeds,
            on_seed=bar,
            settings=settings,
            **{k: given.get(k) for k in ("workers", "dask", "best_known") if k in given},
        )
    print_study(given.get("out"), result.summary)


def register(app: typer.Typer) -> None:
    """Add the ``study`` command to ``app``."""
    from arcube.cli.optimize import PLANS, RUN_FLAGS

    out = with_help(
        OUT,
        "Study folder (created; must be new or empty): seed_<S>/ run folders, study.csv, summary.json, convergence.png, best_design.json.",
        required=True,
    )
    flags = [
        SEEDS,
        out,
        SEED_WORKERS,
        SEED_DASK,
        BEST_KNOWN,
        PLANS,
        *[f for f in RUN_FLAGS if f.key != "run.seed"],
        QUIET,
    ]
    command(app, "study", flags, study, help=study.__doc__ or "")
