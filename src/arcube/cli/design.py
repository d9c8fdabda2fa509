"""The ``design`` command: the main job for a new patient, a robot that meets every requirement.

Exit codes: 0 when the chosen design meets every requirement; 3 when none found does (the input
was fine: the output names the requirement(s) missed and what relaxing each would take); 2 for
bad input, 130 on Ctrl-C.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any

import typer

from arcube.cli.common import AnatomyFrameOpt, AnatomyOpt, EncoderOpt, numbers, plan_specs
from arcube.cli.flags import DensityOpt, GravityOpt, MDeltaOpt, MMotorOpt, WallOpt, given_masses, mass_keywords
from arcube.errors import InputError
from arcube.optimization.requirements import PROGRAM_FIGURES

Strs = Annotated[list[str] | None, typer.Option("--trajectories", help="Trajectory sets (CSV, .mrk.json, folder or 'reference'); several: one placement per patient.")]


def _pairs(items: list[str] | None, flag: str) -> dict[str, float]:
    out: dict[str, float] = {}
    for item in items or []:
        name, sep, value = str(item).partition("=")
        if not sep or not name.strip():
            raise InputError(f"{flag} {item!r}: expected NAME=VALUE, e.g. {flag} clearance=5")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise InputError(f"{flag} {item!r}: the value {value.strip()!r} is not a number") from None
    return out


def print_design(result: Any) -> None:
    """The requirements table and the verdict."""
    typer.echo(f"{'requirement':<22} {'limit':>9} {'value':>10} {'margin':>10}  {'':4}  where")
    for r in result.rows:
        w = r.get("where") or {}
        where = f"patient {w['patient']}, trajectory {w['trajectory']} ({w['segment']}, point {w['point']})" if w else ""
        part = f", {r['part']}" if r.get("part") and r["requirement"] != "program" else ""
        part = f"{r['part']}" if r["requirement"] == "program" and r["passed"] else part
        sign = ">=" if r["kind"] == "min" else "<="
        typer.echo(f"{r['requirement']:<22} {sign}{r['limit']:>7.4g} {_num(r['value']):>10} {_num(r['margin']):>10}  "
                   f"{'ok' if r['passed'] else 'FAIL':4}  {where}{part}")  # fmt: skip
    s = result.summary
    head = "meets every requirement" if result.met else "does NOT meet every requirement"
    typer.echo(f"design {head}: seed {s['seed']}, mode {s['mode']}, eta_G {_num(s.get('eta_G'))}; results in {result.path}")
    for r in result.missed:
        need = f">= {r['value']:.4g}" if r["kind"] == "max" else f"<= {r['value']:.4g}"
        if not math.isfinite(r["value"]) and r["requirement"] in PROGRAM_FIGURES:
            typer.echo(f"  missed: {r['requirement']} (not measured: no drilling program)")
        elif not math.isfinite(r["value"]):
            typer.echo(f"  missed: {r['requirement']} (not measured: the design reaches none of the points where it holds)")
        elif r["requirement"] == "program":
            typer.echo(f"  missed: program: {r['part']}")
        elif r["requirement"] in ("reach", "rho_max", "transmission", "kappa_max", "single_assembly_mode"):
            typer.echo(f"  missed: {r['requirement']} ({_num(r['value'])} {r['unit']}); a larger budget or more seeds may find a design")
        else:
            typer.echo(f"  missed: {r['requirement']} by {_num(-r['margin'])} {r['unit']}; the best design found meets a limit {need} "
                       f"(--{r['kind']} {r['requirement']}=...) or --no-{r['requirement'].replace('_', '-')}")  # fmt: skip


def _num(v: Any) -> str:
    return f"{v:.4g}" if isinstance(v, (int, float)) and math.isfinite(v) else "-"


def register(app: typer.Typer) -> None:
    """Add the ``design`` command to ``app``."""

    @app.command()
    def design(
        trajectories: Strs = None,
        out: Annotated[Path | None, typer.Option("--out", help="Design folder (created; must be new or empty).")] = None,
        anatomy: AnatomyOpt = None,
        anatomy_frame: AnatomyFrameOpt = "LPS",
        seeds: Annotated[str, typer.Option("--seeds", help="Seeds, one optimization each: 1-3, 1,3,7.")] = "1-3",
        minima: Annotated[list[str] | None, typer.Option("--min", help="Change a lower limit: clearance=5, self_clearance=2 (mm).")] = None,
        maxima: Annotated[list[str] | None, typer.Option("--max", help="Change or add an upper limit: lateral_error=0.5 (mm), axis_error=0.25 (deg), torque=20, holding_torque=20 (N m); on the program (none by default): torque_peak (N m), power_peak (W).")] = None,
        no_clearance: Annotated[bool, typer.Option("--no-clearance", help="Drop the clearance requirement.")] = False,
        no_self_clearance: Annotated[bool, typer.Option("--no-self-clearance", help="Drop the self-clearance requirement.")] = False,
        no_lateral_error: Annotated[bool, typer.Option("--no-lateral-error", help="Drop the lateral-error requirement.")] = False,
        no_axis_error: Annotated[bool, typer.Option("--no-axis-error", help="Drop the axis-error requirement.")] = False,
        no_torque: Annotated[bool, typer.Option("--no-torque", help="Drop the torque requirement.")] = False,
        no_holding_torque: Annotated[bool, typer.Option("--no-holding-torque", help="Drop the holding-torque requirement (MODEL.md 18.2: the robot's weight and the drilling loads).")] = False,
        wall: WallOpt = None,
        density: DensityOpt = None,
        m_delta: MDeltaOpt = None,
        m_motor: MMotorOpt = None,
        gravity: GravityOpt = None,
        encoder_deg: EncoderOpt = "0.01",
        objective: Annotated[str, typer.Option("--objective", help="What to minimize among the designs that meet the requirements: eta_G, or another objective name.")] = "eta_G",
        standoff: Annotated[float, typer.Option("--standoff", help="The drill waits this far outside the anatomy (MODEL.md 17.1), mm.")] = 20.0,
        points: Annotated[int, typer.Option("--points", help="Points per trajectory.")] = 30,
        side: Annotated[str | None, typer.Option("--side", help="Keep trajectories of one side: R or L (the robot is docked once per side, as in the paper).")] = None,
        levels: Annotated[str | None, typer.Option("--levels", help="Keep levels, e.g. C3-C5.")] = None,
        ids: Annotated[str | None, typer.Option("--ids", help="Keep trajectory ids, e.g. 1,3,5.")] = None,
        setups: Annotated[int, typer.Option("--setups", help="1, or 2: one robot docked once per side (R and L placements, shared links).")] = 1,
        population: Annotated[int, typer.Option("--population", help="Population size.")] = 400,
        generations: Annotated[int, typer.Option("--generations", help="Generations (the budget is population x generations evaluations per seed).")] = 100,
        tolerance: Annotated[float, typer.Option("--tolerance", help="ftol (see arcube optimize); 0 runs the whole budget.")] = 1e-5,
        algorithm: Annotated[str, typer.Option("--algorithm", help="The optimizer (default mscmaes).")] = "mscmaes",
        engine: Annotated[str, typer.Option("--engine", help="Evaluation engine of the optimizer: auto, numba or numpy (the check is always the NumPy reference).")] = "auto",
        workers: Annotated[int, typer.Option("--workers", help="Seeds run at once, each in its own process.")] = 1,
        dask: Annotated[str | None, typer.Option("--dask", help="Address of a dask.distributed scheduler: each seed is one task.")] = None,
        quiet: Annotated[bool, typer.Option("--quiet", help="No progress bar.")] = False,
        more_trajectories: Annotated[list[str] | None, typer.Argument(hidden=True, metavar="MORE_TRAJECTORIES")] = None,
    ) -> None:
        """Find a robot that meets every requirement for a plan and its anatomy (MODEL.md 16-17), checked by the NumPy reference."""
        from arcube.api import design as design_api
        from arcube.cli.study import SeedProgress
        from arcube.optimization.study import parse_seeds

        from arcube.options import Body

        specs = plan_specs(trajectories, more_trajectories, out, "design")
        masses = mass_keywords(given_masses(wall, density, m_delta, m_motor, gravity), Body().link_radius)
        drop = [n for n, off in (("clearance", no_clearance), ("self_clearance", no_self_clearance), ("lateral_error", no_lateral_error),
                                 ("axis_error", no_axis_error), ("torque", no_torque), ("holding_torque", no_holding_torque)) if off]  # fmt: skip
        n = len(parse_seeds(seeds))
        with SeedProgress(n, enabled=not quiet) as bar:
            result = design_api(
                specs, out, seeds=seeds, minima=_pairs(minima, "--min"), maxima=_pairs(maxima, "--max"), drop=drop, workers=workers,
                dask=dask, on_seed=bar, anatomy=anatomy, anatomy_frame=anatomy_frame, encoder_deg=numbers(encoder_deg, "--encoder-deg"),
                objectives=[objective] if objective != "eta_G" else None, standoff=standoff, points=points, side=side, levels=levels,
                ids=ids, setups=setups, population=population,
                generations=generations, tolerance=tolerance, algorithm=algorithm, engine=engine, **masses,
            )  # fmt: skip
        print_design(result)
        if not result.met:
            raise typer.Exit(3)
