"""The ``optimize`` and ``resume`` commands; :func:`register` adds them to a Typer app.

Bad input raises :class:`arcube.errors.InputError` (one line); the main CLI prints it as
``error: ...`` with exit code 2.
"""

from __future__ import annotations

import math
import secrets
import sys
from pathlib import Path
from typing import Annotated, Any

import typer

from arcube.design import ANGLE_NAMES, LENGTH_NAMES, PARAM_NAMES, Design
from arcube.errors import InputError
from arcube.mechanism import parse_mode
from arcube.optimize import run as runmod
from arcube.optimize.algorithms import DEFAULT_PERIOD, check_algorithm, make_termination
from arcube.optimize.problem import AGGREGATES, COMPACTNESS, parse_bounds, parse_free, resolve_bounds


def _load_patients(specs: list[str], transform: str | None, side: str | None, levels: str | None, ids: str | None, setups: int) -> list[dict[str, Any]]:
    from arcube.trajectories import load_trajectories, select

    patients = []
    for spec in specs:
        ts = load_trajectories(spec, transform)
        if side is not None or levels is not None or ids is not None:
            ts = select(ts, side=side, levels=levels, ids=ids)
        if setups == 2:
            for sd in ("R", "L"):
                if sd not in ts.sides:
                    raise InputError(f"--setups 2 needs R and L trajectories; {spec} has no side {sd} (after the subset flags)")
        patients.append({
            "source": str(spec), "ids": list(ts.ids), "levels": list(ts.levels), "sides": list(ts.sides),
            "entry": [[float(v) for v in row] for row in ts.entry], "target": [[float(v) for v in row] for row in ts.target],
        })  # fmt: skip
    return patients


def _check_bounds(bounds: dict[str, tuple[float, float]]) -> None:
    for name, (lo, hi) in bounds.items():
        if name in LENGTH_NAMES and lo <= 0.0:
            raise InputError(f"--bounds {name}: a length needs a lower bound > 0, got {lo:g}")
        if name in ANGLE_NAMES and name.startswith(("alpha", "beta")) and not (0.0 < lo and hi < 180.0):
            raise InputError(f"--bounds {name}: spherical link angles must stay within (0, 180) deg")


def build_config(
    trajectories: list[str], design_from: str = "paper", free: str = "all", algorithm: str = "ga", population: int = 400,
    generations: int = 300, tolerance: float = 1e-5, points: int = 30, mode: str = "+,+,+,+", setups: int = 1,
    guards: bool = False, margin: float | None = None, seed: int | None = None, workers: int = 1, dask: str | None = None,
    side: str | None = None, levels: str | None = None, ids: str | None = None, engine: str = "auto",
    aggregate: str = "mean", compactness: str = "links", bounds: str | None = None, checkpoint_every: int = 10,
    transform: str | None = None, eliminate_duplicates: bool = False,
) -> dict[str, Any]:  # fmt: skip
    """Validate the optimize flags and return the run's config (what config.toml holds)."""
    algorithm = algorithm.strip().lower()
    check_algorithm(algorithm, population)
    make_termination(algorithm, generations, tolerance)
    if not trajectories:
        raise InputError("--trajectories: give at least one trajectory set (CSV, .mrk.json, folder or 'reference')")
    if points < 2:
        raise InputError(f"--points must be at least 2, got {points}")
    if setups not in (1, 2):
        raise InputError(f"--setups must be 1 or 2, got {setups}")
    if setups == 2 and side is not None:
        raise InputError("--setups 2 uses both sides (one placement each); drop --side")
    mode_text = mode.strip().lower()
    if mode_text != "free":
        try:
            parse_mode(mode_text)
        except ValueError as exc:
            raise InputError(f"--mode: {exc}; or 'free'") from None
    if margin is not None and not (math.isfinite(margin) and margin >= 0.0):
        raise InputError(f"--margin must be a finite angle >= 0 (deg), got {margin}")
    if seed is None:
        seed = secrets.randbelow(2**31)
    if not 0 <= seed < 2**63:
        raise InputError(f"--seed must be an integer in [0, 2^63), got {seed}")
    if workers < 1:
        raise InputError(f"--workers must be at least 1, got {workers}")
    if dask and workers > 1:
        raise InputError("--workers and --dask exclude each other (the Dask cluster has its own workers)")
    if aggregate not in AGGREGATES:
        raise InputError(f"--aggregate must be one of {', '.join(AGGREGATES)}, got {aggregate!r}")
    if compactness not in COMPACTNESS:
        raise InputError(f"--compactness must be one of {', '.join(COMPACTNESS)}, got {compactness!r}")
    if checkpoint_every < 1:
        raise InputError(f"--checkpoint-every must be at least 1, got {checkpoint_every}")
    engine_resolved = runmod.check_engine(engine)
    free_names = parse_free(free)
    all_bounds = resolve_bounds(parse_bounds(bounds))
    _check_bounds(all_bounds)
    design = Design.load(design_from)
    patients = _load_patients(trajectories, transform, side, levels, ids, setups)
    settings = {
        "algorithm": algorithm, "population": population, "generations": generations, "tolerance": tolerance,
        "period": DEFAULT_PERIOD, "points": points, "mode": mode_text, "setups": setups, "guards": guards, "margin": margin,
        "seed": seed, "engine": engine, "engine_resolved": engine_resolved, "aggregate": aggregate, "compactness": compactness,
        "checkpoint_every": checkpoint_every, "eliminate_duplicates": bool(eliminate_duplicates), "design_from": design_from, "free": list(free_names),
        "trajectories": list(trajectories), "side": side, "levels": levels, "ids": ids, "transform": transform,
    }  # fmt: skip
    cfg = runmod.new_run_config(settings, all_bounds, design, patients, {"workers": workers, "dask": dask or ""})
    cfg["rerun"] = _rerun_command(settings, all_bounds, cfg)
    return cfg


def _rerun_command(s: dict[str, Any], bounds: dict[str, tuple[float, float]], cfg: dict[str, Any]) -> str:
    parts = ["arcube optimize --trajectories", *s["trajectories"], "--out DIR", f"--design-from {s['design_from']}",
             f"--free {'all' if len(s['free']) == len(PARAM_NAMES) else ','.join(s['free'])}", f"--algorithm {s['algorithm']}",
             f"--population {s['population']} --generations {s['generations']} --tolerance {s['tolerance']!r}",
             f"--points {s['points']} --mode={s['mode']} --setups {s['setups']} --seed {s['seed']} --engine {s['engine']}",
             f"--aggregate {s['aggregate']} --compactness {s['compactness']} --checkpoint-every {s['checkpoint_every']}"]  # fmt: skip
    for flag in ("side", "levels", "ids", "transform", "margin"):
        if s.get(flag) is not None:
            parts.append(f"--{flag} {s[flag]}")
    if s["guards"]:
        parts.append("--guards")
    if s["eliminate_duplicates"]:
        parts.append("--eliminate-duplicates")
    changed = [f"{k}={lo!r}:{hi!r}" for k, (lo, hi) in bounds.items() if (lo, hi) != resolve_bounds()[k]]
    if changed:
        parts.append("--bounds " + ",".join(changed))
    return " ".join(parts)


class _Progress:
    """Rich progress bar on stderr: generation, best eta_G, feasible fraction, evaluations/s, ETA."""

    def __init__(self, total: int, enabled: bool) -> None:
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

        console = Console(stderr=True)
        self.enabled, self.task, self.first_evals = enabled and console.is_terminal, None, None
        if not self.enabled:
            return

        self.progress = Progress(
            TextColumn("gen"), MofNCompleteColumn(), BarColumn(), TextColumn("best η_G {task.fields[best]}"),
            TextColumn("feasible {task.fields[feas]}"), TextColumn("{task.fields[eps]} eval/s"),
            TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn(), console=console,
        )  # fmt: skip
        self.task = self.progress.add_task("optimize", total=total, best="-", feas="-", eps="-")

    def __enter__(self) -> _Progress:
        if self.enabled:
            self.progress.__enter__()
        return self

    def __exit__(self, *exc: Any) -> None:
        if self.enabled:
            self.progress.__exit__(*exc)

    def __call__(self, row: dict[str, Any]) -> None:
        if not self.enabled:
            return
        if self.first_evals is None:
            self.first_evals = row["evaluations"]
        eps = (row["evaluations"] - self.first_evals) / row["session_s"] if row["session_s"] > 0 else 0.0
        best = row["best_eta_G"]
        self.progress.update(
            self.task, completed=row["generation"], best=f"{best:.4f}" if math.isfinite(best) else "none feasible",
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
        free: Annotated[str, typer.Option("--free", help="'all' or comma-separated parameters to optimize (the others are fixed).")] = "all",
        algorithm: Annotated[str, typer.Option("--algorithm", help="ga (default, the paper's), de, cmaes or nsga2 (eta_G vs compactness).")] = "ga",
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
        quiet: Annotated[bool, typer.Option("--quiet", help="No progress bar.")] = False,
        more_trajectories: Annotated[list[str] | None, typer.Argument(hidden=True, metavar="MORE_TRAJECTORIES")] = None,
    ) -> None:
        """Optimize the design (MODEL.md 12): minimize eta_G with every task point reachable."""
        specs = [*(trajectories or []), *(more_trajectories or [])]
        if more_trajectories and not trajectories:
            raise InputError(f"unexpected argument {more_trajectories[0]!r} (trajectory sets go after --trajectories)")
        if out is None:
            raise InputError("--out DIR is required (the run folder)")
        cfg = build_config(
            specs, design_from=design_from, free=free, algorithm=algorithm, population=population, generations=generations,
            tolerance=tolerance, points=points, mode=mode, setups=setups, guards=guards, margin=margin, seed=seed,
            workers=workers, dask=dask, side=side, levels=levels, ids=ids, engine=engine, aggregate=aggregate,
            compactness=compactness, bounds=bounds, checkpoint_every=checkpoint_every, transform=transform,
            eliminate_duplicates=eliminate_duplicates,
        )  # fmt: skip
        runmod.check_new_folder(out)
        with _Progress(generations, enabled=not quiet) as bar:
            summary = runmod.start(out, cfg, on_generation=bar)
        _print_summary(out, summary)

    @app.command()
    def resume(
        run_dir: Annotated[Path, typer.Argument(help="Run folder of an interrupted 'arcube optimize'.")],
        workers: Annotated[int | None, typer.Option("--workers", help="Override the run's local worker processes.")] = None,
        dask: Annotated[str | None, typer.Option("--dask", help="Override: send batches to this dask scheduler.")] = None,
        quiet: Annotated[bool, typer.Option("--quiet", help="No progress bar.")] = False,
    ) -> None:
        """Continue a killed optimization run from its checkpoint (same result as an uninterrupted run)."""
        if workers is not None and workers < 1:
            raise InputError(f"--workers must be at least 1, got {workers}")
        cfg, raw = runmod.read_config(run_dir)
        runmod.load_checkpoint(run_dir, cfg, raw)  # refuse a corrupt or foreign checkpoint before anything else
        with _Progress(int(cfg["settings"]["generations"]), enabled=not quiet) as bar:
            summary = runmod.resume(run_dir, workers=workers if workers is not None else (1 if dask else None), dask=dask, on_generation=bar)
        if summary is None:
            sys.stderr.write(f"{run_dir}: the run had already finished; nothing to resume\n")
            return
        _print_summary(run_dir, summary)
