"""The ``resume`` command: finish a killed optimization run, study or design job."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from arcube.cli.common import DASK, QUIET, WORKERS, with_help
from arcube.cli.design import print_design
from arcube.cli.optimize import Progress, print_summary
from arcube.cli.projection import Given, argument, command
from arcube.cli.study import SeedProgress, print_study
from arcube.errors import InputError

__all__ = ["register"]

RESUME_FLAGS = [
    with_help(WORKERS, "Override the run's local worker processes."),
    with_help(DASK, "Override: send batches to this dask scheduler."),
    QUIET,
]
RUN_DIR = argument(
    "run_dir",
    "Run folder of an interrupted 'arcube optimize', or the folder of an interrupted 'arcube study' or 'arcube design'.",
)


def resume(given: Given) -> None:
    """Continue a killed optimization run from its checkpoint, or finish a killed study or design job (same result as an uninterrupted one)."""
    from arcube.api import resume as resume_api
    from arcube.design_job import STUDY, is_design
    from arcube.optimization import folder, run as runmod

    run_dir: Path = given.get("run_dir")
    workers, dask, quiet = given.get("workers"), given.get("dask"), given.get("quiet")
    if workers is not None and workers < 1:
        raise InputError.of("workers", f"must be at least 1, got {workers}")
    if is_design(run_dir):
        from arcube.cli.design_progress import DesignProgress

        study, base = (
            folder.read_study(run_dir / STUDY, config=True) if folder.is_study(run_dir / STUDY) else ({}, None)
        )
        budget = max(base.settings.population * base.settings.generations, 1) if base is not None else 1
        with DesignProgress(study.get("seeds", []), budget, enabled=not quiet) as bar:
            bar.watch(run_dir / STUDY)
            result = resume_api(
                run_dir, workers=workers, dask=dask, on_seed=bar.seed, progress=bar.generation, on_stage=bar.stage
            )
        print_design(result)
        if not result.met:
            raise typer.Exit(3)
        return
    if folder.is_study(run_dir):
        seeds = folder.read_study(run_dir)[0]["seeds"]
        with SeedProgress(len(seeds), enabled=not quiet) as seed_bar:
            result = resume_api(run_dir, workers=workers, dask=dask, on_seed=seed_bar)
        print_study(run_dir, result.summary)
        return
    cfg, raw = folder.read_config(run_dir)
    runmod.load_checkpoint(run_dir, cfg, raw)  # refuse a corrupt or foreign checkpoint before anything else
    if folder.is_finished(run_dir):
        sys.stderr.write(f"{run_dir}: the run had already finished; nothing to resume\n")
        return
    settings = cfg.settings
    with Progress(settings.population * settings.generations, enabled=not quiet) as bar:
        run = resume_api(run_dir, progress=bar, workers=workers, dask=dask)
    print_summary(run_dir, run.summary)


def register(app: typer.Typer) -> None:
    """Add the ``resume`` command to ``app``."""
    command(app, "resume", RESUME_FLAGS, resume, help=resume.__doc__ or "", arguments=[RUN_DIR])
