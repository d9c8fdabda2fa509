"""``arcube demo``: the README's main job on the bundled reference patient.

1. Evaluate the paper's design (Table 2) and say what it cannot reach and why.
2. Keep Table 2's links and search only the placement m for the right side.
3. Run the paper's GA (population 400, up to 300 generations, ftol 1e-5) with all 23
   parameters free on both sides.
4. ``arcube design`` on both sides: one robot, docked once per side (model §19), that clears the
   patient, its whole body, the table and itself and meets every default requirement at both dockings,
   with a drilling program per docking (three seeds of 40,000 evaluations, two at a time).

Each optimization writes a run folder with its HTML report; the paths are printed at the end.
"""

from __future__ import annotations

import time
from pathlib import Path

import typer

from arcube.cli.common import DESIGN, ENGINE, OUT, SEED, TRAJECTORIES, with_help
from arcube.cli.projection import Given, command, option
from arcube.coerce import engine_name

REFERENCE = "reference"


def _optimize(out: Path, *, seed: int, engine: str, quick: bool, **flags: object) -> Path:
    """One quiet optimization run into ``out`` with its report; returns the report path."""
    from arcube.optimization import run as runmod
    from arcube.optimization.config import build_config
    from arcube.report.run_report import write_run_report

    sizes = {"population": 40, "generations": 15, "points": 10} if quick else {}
    cfg = build_config([REFERENCE], seed=seed, engine=engine, **{**flags, **sizes})  # type: ignore[arg-type]
    summary = runmod.start(out, cfg)
    eta = summary["eta_G"]
    dex = summary["dexterity_pct"]
    verdict = f"feasible, eta_G = {eta:.4f}" if summary["feasible"] else "NOT feasible"
    typer.echo(
        f"  {verdict}; inverted dexterity min/mean/max {dex['min']:.2f} / {dex['mean']:.2f} / {dex['max']:.2f} %; "
        f"{summary['generations']} generations in {summary['wall_s']:.1f} s"
    )
    return write_run_report(out)


def _design(out: Path, *, seed: int, engine: str, quick: bool) -> Path:
    """``arcube design`` on both sides of the reference plan into ``out`` (one robot, a docking per side, model §19);
    prints its requirement table, returns its report."""
    from arcube.api import design as design_api
    from arcube.cli.design import print_design
    from arcube.cli.design_progress import DesignProgress
    from arcube.design_job import DESIGN_GENERATIONS, STUDY
    from arcube.optimization.settings import RunSettings

    sizes = {"population": 12, "generations": 2, "points": 4} if quick else {}
    # three seeds, two at a time, as arcube design runs by default: the job takes the best seed whose
    # robot meets every requirement at both dockings, programs included
    seeds = [seed, seed + 1, seed + 2]
    budget = sizes.get("population", RunSettings().population) * sizes.get("generations", DESIGN_GENERATIONS)
    with DesignProgress(
        seeds, budget, dockings=2
    ) as bar:  # the reference patient's two sides  # eight minutes of search: the seeds' progress on stderr
        bar.watch(out / STUDY)
        result = design_api(
            REFERENCE,
            out,
            seeds=seeds,
            anatomy="default",
            engine=engine,
            workers=1 if quick else 2,
            on_seed=bar.seed,
            progress=bar.generation,
            on_stage=bar.stage,
            **sizes,
        )  # type: ignore[arg-type]
    print_design(result)
    return out / "report.html"


def run_demo(out: Path, seed: int = 1, engine: str = "auto", quick: bool = False) -> list[Path]:
    """Run the four steps into ``out`` (must be new or empty); returns the written reports."""
    from arcube.report import text as report_text
    from arcube.api import evaluate
    from arcube.optimization import run as runmod

    runmod.check_new_folder(out)
    engine = engine_name(engine)
    started = time.perf_counter()
    typer.echo("1/4  The paper's design (Table 2) on the bundled reference patient (bilateral C3-C7 pedicle screws)")
    report_text.print_evaluation(evaluate("paper", REFERENCE, engine=engine))
    typer.echo("\n2/4  Table 2's links, placement m searched for the right side (GA, m_x, m_y, m_z free)")
    reports = [
        _optimize(
            out / "paper_links_right",
            seed=seed,
            engine=engine,
            quick=quick,
            design_from="paper",
            free="m_x,m_y,m_z",
            side="R",
            population=100,
            generations=60,
            ftol=0.0,
            algorithm="ga",
        ),
    ]
    scale = "tiny population (--quick)" if quick else "the paper's GA: population 400, up to 300 generations, ftol 1e-5"
    typer.echo(f"\n3/4  All 23 dimensions free, both sides ({scale})")
    reports.append(
        _optimize(
            out / "all_free_bilateral",
            seed=seed,
            engine=engine,
            quick=quick,
            population=400,
            generations=300,
            ftol=1e-5,
            algorithm="ga",
        )
    )
    typer.echo(
        "\n4/4  One robot for both sides, docked once per side, that fits the patient and meets every default requirement"
        f" at both dockings (arcube design, robot and dockings free, seeds {seed}-{seed + 2}"
        + (", tiny budget (--quick): expect it to fall short)" if quick else ")")
    )
    reports.append(_design(out / "one_robot", seed=seed, engine=engine, quick=quick))
    typer.echo(f"\ndone in {time.perf_counter() - started:.0f} s (engine {engine}). Reports:")
    for path in reports:
        typer.echo(f"  {path}")
    typer.echo("Run folders hold config.toml, history.csv, best_design.json and summary.json; rerun a design with")
    typer.echo(
        f"  arcube evaluate {DESIGN.name} {out / 'all_free_bilateral' / 'best_design.json'} {TRAJECTORIES.name} reference"
    )
    typer.echo(
        "The paper's GA lands in a seed-dependent basin; arcube optimize's default (mscmaes, multi-start CMA-ES) goes"
    )
    typer.echo(
        "further at the same budget, and 'arcube study --seeds 1-5' shows the spread over seeds (docs: guide/optimize.md, 'Which optimizer')."
    )
    return reports


FLAGS = [
    with_help(OUT, "Folder for the demo's run folders (new or empty); default ./arcube-demo[-N]."),
    with_help(SEED, "Random seed of both optimizations. [default: 1]"),
    ENGINE,
    option("--quick", "Tiny populations (a smoke run of the pipeline, seconds).", bool),
]


def demo(given: Given) -> None:
    """Evaluate the paper's design, optimize it, and write run folders with HTML reports."""
    out = given.get("out")
    run_demo(
        out if out is not None else _fresh_folder(Path("arcube-demo")),
        seed=given.get("seed", 1),
        engine=given.get("engine", "auto"),
        quick=bool(given.get("quick")),
    )


def register(app: typer.Typer) -> None:
    """Add the ``demo`` command to ``app``."""
    command(app, "demo", FLAGS, demo, help=demo.__doc__ or "")


def _fresh_folder(base: Path) -> Path:
    """``base``, or ``base-2``, ``base-3``... : the first that is absent or empty, so reruns never collide."""
    candidate, n = base, 1
    while candidate.exists() and (not candidate.is_dir() or any(candidate.iterdir())):
        n += 1
        candidate = base.with_name(f"{base.name}-{n}")
    return candidate
