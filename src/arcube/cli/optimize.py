"""The ``optimize`` and ``resume`` commands; :func:`register` adds them to a Typer app.

Bad input raises :class:`arcube.errors.InputError` (one line); the main CLI prints it as
``error: ...`` with exit code 2.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Annotated, Any

import typer

from arcube.cli.common import (
    RichBar, plan_specs, ActuatorRadiusOpt, EncoderOpt, LateralForceOpt, StiffnessOpt, ThrustOpt, loads, AnatomyFrameOpt, AnatomyOpt, ClearanceOpt, LinkRadiusOpt, MotorLengthOpt, MotorRadiusOpt, SelfClearanceOpt,
)  # fmt: skip
from arcube.cli.flags import DensityOpt, GravityOpt, MDeltaOpt, MMotorOpt, WallOpt, given_masses, mass_keywords
from arcube.errors import InputError
from arcube.optimization import run as runmod


class _Progress(RichBar):
    """Rich progress bar on stderr: design evaluations out of the budget, best eta_G, feasible fraction, evaluations/s, ETA."""

    def __init__(self, total: int, enabled: bool) -> None:
        from rich.progress import TextColumn, TimeElapsedColumn, TimeRemainingColumn

        columns = ("evaluations", TextColumn("best η_G {task.fields[best]}"), TextColumn("feasible {task.fields[feas]}"),
                   TextColumn("{task.fields[eps]} eval/s"), TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn())  # fmt: skip
        super().__init__(enabled, columns, total=total, best="-", feas="-", eps="-")
        self.first_evals: int | None = None

    def __call__(self, row: dict[str, Any]) -> None:
        if not self.enabled:
            return
        if self.first_evals is None:
            self.first_evals = row["evaluations"]
        eps = (row["evaluations"] - self.first_evals) / row["session_s"] if row["session_s"] > 0 else 0.0
        best = row["best_eta_G"]
        self.progress.update(
            self.task, completed=row["evaluations"], best=f"{best:.4f}" if math.isfinite(best) else "none feasible",
            feas=f"{row['feasible_fraction']:.0%}", eps=f"{eps:,.0f}",
        )  # fmt: skip


def _print_summary(run_dir: Path, summary: dict[str, Any]) -> None:
    eta = summary["eta_G"]
    dex = summary["dexterity_pct"]
    head = "feasible" if summary["feasible"] else "NOT feasible"
    eta_text = f"eta_G {eta:.6g}" if eta is not None else "eta_G inf"
    typer.echo(f"{head}: {eta_text} (dexterity min/mean/max {dex['min']:.2f}/{dex['mean']:.2f}/{dex['max']:.2f} %), mode {summary['mode']}")
    typer.echo(
        f"{summary['generations']} generations, {summary['evaluations']} evaluations, {summary['wall_s']:.1f} s "
        f"(evaluation {summary['eval_s']:.1f} s), stopped by {summary['stopped_by']}, seed {summary['seed']}"
    )
    if "front_size" in summary:
        typer.echo(f"Pareto front: {summary['front_size']} designs in {run_dir / 'pareto.csv'}")
    typer.echo(f"results in {run_dir}")


Strs = Annotated[list[str] | None, typer.Option("--trajectories", help="Trajectory sets (CSV, .mrk.json, folder or 'reference'); several make a robust problem over patients.")]


def register(app: typer.Typer) -> None:
    """Add the ``optimize`` and ``resume`` commands to ``app``."""

    @app.command()
    def optimize(
        trajectories: Strs = None,
        out: Annotated[Path | None, typer.Option("--out", help="Run folder (created; must be new or empty).")] = None,
        design_from: Annotated[str, typer.Option("--design-from", help="Start design: 'paper' or a design JSON; fixed parameters keep its values.")] = "paper",
        free: Annotated[str, typer.Option("--free", help="Parameters to optimize, comma-separated names and groups: all (the paper's 23), mount (the three mounting angles), e.g. all,mount,L.")] = "all",
        algorithm: Annotated[str, typer.Option("--algorithm", help="mscmaes (default: multi-start CMA-ES, population x generations evaluations), ga (the paper's), de, cmaes, or nsga2 / nsga3 (several objectives).")] = "mscmaes",
        population: Annotated[int, typer.Option("--population", help="Population size.")] = 400,
        generations: Annotated[int, typer.Option("--generations", help="Maximum number of generations.")] = 300,
        tolerance: Annotated[float, typer.Option("--tolerance", help="ftol: stop when the best feasible eta_G moves less than this over 30 generations; 0 runs every generation.")] = 1e-5,
        points: Annotated[int, typer.Option("--points", help="Points per trajectory.")] = 30,
        mode: Annotated[str, typer.Option("--mode", help="Working mode '+,+,+,+' (signs TMS x, TMS y, RTS x, RTS y) or 'free' (optimized).")] = "+,+,+,+",
        setups: Annotated[int, typer.Option("--setups", help="1, or 2: shared links, one placement per side (R and L).")] = 1,
        guards: Annotated[bool, typer.Option("--guards", help="Turn on the guards of MODEL.md 8.2 (all but z_dyad).")] = False,
        margin: Annotated[float | None, typer.Option("--margin", help="Orientation margin mu (deg) of the spherical stage's cone (MODEL.md 12.2).")] = None,
        seed: Annotated[int | None, typer.Option("--seed", help="Random seed (drawn and recorded when omitted).")] = None,
        workers: Annotated[int, typer.Option("--workers", help="Local worker processes for each population batch.")] = 1,
        dask: Annotated[str | None, typer.Option("--dask", help="Address of a dask.distributed scheduler to send batches to.")] = None,
        side: Annotated[str | None, typer.Option("--side", help="Keep trajectories of one side: R or L.")] = None,
        levels: Annotated[str | None, typer.Option("--levels", help="Keep levels, e.g. C3-C5.")] = None,
        ids: Annotated[str | None, typer.Option("--ids", help="Keep trajectory ids, e.g. 1,3,5.")] = None,
        engine: Annotated[str, typer.Option("--engine", help="Evaluation engine: auto, numba or numpy.")] = "auto",
        aggregate: Annotated[str, typer.Option("--aggregate", help="Over several trajectory sets: mean or worst eta_G.")] = "mean",
        compactness: Annotated[str, typer.Option("--compactness", help="nsga2's second objective: links (sum of link lengths) or bbox (bounding-box volume).")] = "links",
        bounds: Annotated[str | None, typer.Option("--bounds", help="Override bounds: NAME=LO:HI[,NAME=LO:HI...].")] = None,
        checkpoint_every: Annotated[int, typer.Option("--checkpoint-every", help="Write a checkpoint every K generations.")] = 10,
        transform: Annotated[str | None, typer.Option("--transform", help="4x4 rigid transform (JSON) applied to every trajectory set.")] = None,
        eliminate_duplicates: Annotated[bool, typer.Option("--eliminate-duplicates", help="ga: drop offspring equal to a design already in the population (pymoo's default; Matlab's ga, the paper's, keeps them).")] = False,
        anatomy: AnatomyOpt = None,
        anatomy_frame: AnatomyFrameOpt = "LPS",
        clearance: ClearanceOpt = None,
        self_clearance: SelfClearanceOpt = None,
        link_radius: LinkRadiusOpt = 8.0,
        actuator_radius: ActuatorRadiusOpt = 25.0,
        motor_radius: MotorRadiusOpt = 20.0,
        motor_length: MotorLengthOpt = 120.0,
        objectives: Annotated[str | None, typer.Option("--objectives", help="Objectives, comma-separated: eta_G (default), tip_error, lateral_error, axial_error, axis_error, torque, deflection, holding_torque, mass, links, bbox, clearance (maximized). Two or three: nsga2; more: nsga3.")] = None,
        maxima: Annotated[list[str] | None, typer.Option("--max", help="Upper limit NAME=VALUE (repeatable), e.g. --max lateral_error=0.2 --max torque=15 --max holding_torque=15 --max mass=3.")] = None,
        minima: Annotated[list[str] | None, typer.Option("--min", help="Lower limit NAME=VALUE (repeatable), e.g. --min clearance=5.")] = None,
        encoder_deg: EncoderOpt = "0.01",
        thrust: ThrustOpt = 30.0,
        lateral_force: LateralForceOpt = 10.0,
        actuator_stiffness: StiffnessOpt = "1e4",
        docking: Annotated[str, typer.Option("--docking", help="Over several trajectory sets: per-patient (each patient its own placement m, and mounting angles when free; the links shared) or shared (one placement for all, the paper's robust problem).")] = "per-patient",
        standoff: Annotated[float | None, typer.Option("--standoff", help="Also hold reach, guards and clearances along each trajectory's approach line, from this far (mm) beyond where its axis leaves the anatomy to its entry (MODEL.md 17.1).")] = None,
        wall: WallOpt = None,
        density: DensityOpt = None,
        m_delta: MDeltaOpt = None,
        m_motor: MMotorOpt = None,
        gravity: GravityOpt = None,
        quiet: Annotated[bool, typer.Option("--quiet", help="No progress bar.")] = False,
        more_trajectories: Annotated[list[str] | None, typer.Argument(hidden=True, metavar="MORE_TRAJECTORIES")] = None,
    ) -> None:
        """Optimize the design (MODEL.md 12): minimize eta_G with every task point reachable."""
        specs = plan_specs(trajectories, more_trajectories, out, "run")
        masses = mass_keywords(given_masses(wall, density, m_delta, m_motor, gravity), link_radius)
        from arcube.api import optimize as optimize_api

        with _Progress(population * generations, enabled=not quiet) as bar:
            run = optimize_api(
                specs, out=out, progress=bar, workers=workers, dask=dask, design_from=design_from, free=free,
                algorithm=algorithm, population=population, generations=generations, tolerance=tolerance, points=points,
                mode=mode, setups=setups, guards=guards, margin=margin, seed=seed, side=side, levels=levels, ids=ids,
                engine=engine, aggregate=aggregate, compactness=compactness, bounds=bounds,
                checkpoint_every=checkpoint_every, transform=transform, eliminate_duplicates=eliminate_duplicates,
                anatomy=anatomy, anatomy_frame=anatomy_frame, clearance=clearance, self_clearance=self_clearance,
                link_radius=link_radius, actuator_radius=actuator_radius, motor_radius=motor_radius, motor_length=motor_length,
                objectives=objectives, maxima=maxima, minima=minima, docking=docking, standoff=standoff,
                **loads(encoder_deg, thrust, lateral_force, actuator_stiffness), **masses,
            )  # fmt: skip
        _print_summary(out, run.summary)

    @app.command()
    def resume(
        run_dir: Annotated[Path, typer.Argument(help="Run folder of an interrupted 'arcube optimize', or the folder of an interrupted 'arcube study' or 'arcube design'.")],
        workers: Annotated[int | None, typer.Option("--workers", help="Override the run's local worker processes.")] = None,
        dask: Annotated[str | None, typer.Option("--dask", help="Override: send batches to this dask scheduler.")] = None,
        quiet: Annotated[bool, typer.Option("--quiet", help="No progress bar.")] = False,
    ) -> None:
        """Continue a killed optimization run from its checkpoint, or finish a killed study or design job (same result as an uninterrupted one)."""
        if workers is not None and workers < 1:
            raise InputError(f"--workers must be at least 1, got {workers}")
        from arcube.api import resume as resume_api
        from arcube.cli.study import SeedProgress, print_study
        from arcube.design_job import STUDY, is_design
        from arcube.optimization import study as studymod

        if is_design(run_dir):
            from arcube.cli.design import print_design

            seeds = studymod.read_study(run_dir / STUDY)[0]["seeds"] if studymod.is_study(run_dir / STUDY) else []
            with SeedProgress(len(seeds), enabled=not quiet) as seed_bar:
                result = resume_api(run_dir, workers=workers, dask=dask, on_seed=seed_bar)
            print_design(result)
            if not result.met:
                raise typer.Exit(3)
            return

        if studymod.is_study(run_dir):
            seeds = studymod.read_study(run_dir)[0]["seeds"]
            with SeedProgress(len(seeds), enabled=not quiet) as seed_bar:
                result = resume_api(run_dir, workers=workers, dask=dask, on_seed=seed_bar)
            print_study(run_dir, result.summary)
            return
        cfg, raw = runmod.read_config(run_dir)
        runmod.load_checkpoint(run_dir, cfg, raw)  # refuse a corrupt or foreign checkpoint before anything else
        if runmod.is_finished(run_dir):
            sys.stderr.write(f"{run_dir}: the run had already finished; nothing to resume\n")
            return
        with _Progress(int(cfg["settings"]["population"]) * int(cfg["settings"]["generations"]), enabled=not quiet) as bar:
            run = resume_api(run_dir, progress=bar, workers=workers, dask=dask)
        summary = run.summary
        _print_summary(run_dir, summary)
