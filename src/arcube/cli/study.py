"""The ``study`` command: one optimization per seed, then best / median / worst.

It takes every option of ``arcube optimize`` (the same names, defaults and checks: its parameter
list is copied from that command) except ``--seed``, plus ``--seeds``; ``--workers`` and ``--dask``
spread the seeds, not the population. ``arcube resume STUDY_DIR`` finishes an interrupted study.
"""

from __future__ import annotations

import inspect
import math
from pathlib import Path
from typing import Annotated, Any

import typer

from arcube.cli.common import RichBar, loads, plan_specs

STUDY_ONLY = {
    "seeds": Annotated[str, typer.Option("--seeds", help="Seeds, one run each: 1-5, 1,3,7 or 1-3,10.")],
    "out": Annotated[Path | None, typer.Option("--out", help="Study folder (created; must be new or empty): seed_<S>/ run folders, study.csv, summary.json, convergence.png, best_design.json.")],
    "workers": Annotated[int, typer.Option("--workers", help="Seeds run at once, each in its own process.")],
    "dask": Annotated[str | None, typer.Option("--dask", help="Address of a dask.distributed scheduler: each seed is one task (its workers must see the study folder).")],
    "best_known": Annotated[float | None, typer.Option("--best-known", help="An eta_G to draw as a line on the convergence figure.")],
}
DEFAULTS: dict[str, Any] = {"seeds": "1-5", "out": None, "workers": 1, "dask": None, "best_known": None}


def print_study(study_dir: Path, summary: dict[str, Any]) -> None:
    """The per-seed table and best / median / worst of the first objective."""
    name = summary["objective"]
    extra = name != "eta_G"
    typer.echo(f"{'seed':>6}  {'feasible':8}  " + (f"{name:>14}  " if extra else "") + f"{'eta_G':>9}  {'violation':>9}  {'generations':>11}  "
               f"{'evaluations':>11}  {'wall s':>7}")  # fmt: skip
    for r in summary["rows"]:
        value = f"{_num(r.get(f'objective_{name}')):>14}  " if extra else ""
        typer.echo(f"{r['seed']:>6}  {'yes' if r['feasible'] else 'NO':8}  {value}{_num(r['eta_G']):>9}  {_num(r['violation']):>9}  "
                   f"{r['generations']:>11}  {r['evaluations']:>11}  {r['wall_s']:>7.1f}")  # fmt: skip
    spread = f"; spread {summary['spread_pct']:.1f} %" if summary.get("spread_pct") is not None else ""
    typer.echo(f"{name} over {len(summary['seeds'])} seeds ({summary['feasible_seeds']} feasible): best {_num(summary['best'])} "
               f"(seed {summary['best_seed']}), median {_num(summary['median'])}, worst {_num(summary['worst'])}{spread}")  # fmt: skip
    typer.echo(f"results in {study_dir} (study.csv, best_design.json, convergence.png)")


def _num(v: Any) -> str:
    return f"{v:.6g}" if isinstance(v, (int, float)) and math.isfinite(v) else "-"


class SeedProgress(RichBar):
    """Rich progress over seeds on stderr (a seed counts when its run finishes)."""

    def __init__(self, total: int, enabled: bool) -> None:
        from rich.progress import TextColumn, TimeElapsedColumn

        super().__init__(enabled, ("seeds", TextColumn("{task.fields[last]}"), TimeElapsedColumn()), total=total, last="")

    def __call__(self, seed: int, summary: dict[str, Any]) -> None:
        if self.enabled:
            self.progress.advance(self.task)
            self.progress.update(self.task, last=f"seed {seed}: eta_G {_num(summary.get('eta_G'))}")


def register(app: typer.Typer) -> None:
    """Add the ``study`` command to ``app`` (after ``optimize``, whose options it copies)."""
    optimize = next(c.callback for c in app.registered_commands if c.callback is not None and c.callback.__name__ == "optimize")
    shared = [p for name, p in inspect.signature(optimize, eval_str=True).parameters.items() if name not in ("seed", *STUDY_ONLY)]

    def study(**kwargs: Any) -> None:
        """Run the same optimization once per seed (in parallel with --workers or --dask) and report best / median / worst."""
        from arcube.api import study as study_api

        out = kwargs.pop("out")
        specs = plan_specs(kwargs.pop("trajectories"), kwargs.pop("more_trajectories"), out, "study")
        seeds, quiet = kwargs.pop("seeds"), kwargs.pop("quiet")
        load = loads(kwargs.pop("encoder_deg"), kwargs.pop("thrust"), kwargs.pop("lateral_force"), kwargs.pop("actuator_stiffness"))
        settings = {**kwargs, **load}
        from arcube.optimization.study import parse_seeds

        n = len(parse_seeds(seeds))
        with SeedProgress(n, enabled=not quiet) as bar:
            result = study_api(specs, out, seeds=seeds, on_seed=bar, **settings)
        print_study(out, result.summary)

    own = [inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, annotation=ann, default=DEFAULTS[name]) for name, ann in STUDY_ONLY.items()]
    params = [p.replace(kind=inspect.Parameter.KEYWORD_ONLY) for p in shared if p.kind != inspect.Parameter.VAR_KEYWORD]
    study.__signature__ = inspect.Signature(own + params)  # type: ignore[attr-defined]
    study.__annotations__ = {}
    app.command()(study)
