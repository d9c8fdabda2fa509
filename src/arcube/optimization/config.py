"""Validated optimization settings: the flags of ``arcube optimize`` -> a run config (what config.toml holds).

:func:`build_config` checks every setting (raising :class:`~arcube.errors.InputError` with one
line), loads the trajectory sets and returns the config dict that :mod:`arcube.optimization.run`
writes to ``config.toml`` and runs.
"""

from __future__ import annotations

import math
import os
import secrets
from typing import Any

from arcube.evaluation.anatomy import resolve_anatomy
from arcube.errors import InputError
from arcube.evaluation.reference import Options, with_body, with_loads
from arcube.optimization.objectives import needs_clearance, parse_limits, parse_objectives
from arcube.model.body import BodyRadii
from arcube.io import TrajectorySet, load_trajectories, select
from arcube.model.design import ANGLE_NAMES, LENGTH_NAMES, PAPER_NAMES, Design
from arcube.model.mechanism import parse_mode
from arcube.optimization import run as runmod
from arcube.optimization.algorithms import DEFAULT_ALGORITHM, DEFAULT_PERIOD, check_algorithm, make_termination
from arcube.optimization.problem import AGGREGATES, COMPACTNESS, DOCKINGS, MULTI_OBJECTIVE_ALGORITHMS, parse_bounds, parse_free, resolve_bounds

__all__ = ["build_config"]


def _load_patients(specs: list[Any], transform: str | None, side: str | None, levels: str | None, ids: str | None, setups: int) -> list[dict[str, Any]]:
    patients = []
    for spec in specs:
        ts = spec if isinstance(spec, TrajectorySet) else load_trajectories(spec, transform)
        if side is not None or levels is not None or ids is not None:
            ts = select(ts, side=side, levels=levels, ids=ids)
        if setups == 2:
            for sd in ("R", "L"):
                if sd not in ts.sides:
                    raise InputError(f"--setups 2 needs R and L trajectories; {spec} has no side {sd} (after the subset flags)")
        patients.append({
            "source": ts.source if isinstance(spec, TrajectorySet) else str(spec), "ids": list(ts.ids), "levels": list(ts.levels), "sides": list(ts.sides),
            "entry": [[float(v) for v in row] for row in ts.entry], "target": [[float(v) for v in row] for row in ts.target],
        })  # fmt: skip
    return patients


def _anatomy_spec(anatomy: Any) -> list[str]:
    """``--anatomy`` values as a list of strings ([] for none)."""
    if anatomy is None:
        return []
    items = [os.fspath(anatomy)] if isinstance(anatomy, (str, os.PathLike)) else [os.fspath(a) for a in anatomy]
    return [] if items == ["none"] else items


def _check_bounds(bounds: dict[str, tuple[float, float]]) -> None:
    for name, (lo, hi) in bounds.items():
        if name in LENGTH_NAMES and lo <= 0.0:
            raise InputError(f"--bounds {name}: a length needs a lower bound > 0, got {lo:g}")
        if name in ANGLE_NAMES and name.startswith(("alpha", "beta")) and not (0.0 < lo and hi < 180.0):
            raise InputError(f"--bounds {name}: spherical link angles must stay within (0, 180) deg")


def build_config(
    trajectories: list[Any], design_from: str = "paper", free: str = "all", algorithm: str = DEFAULT_ALGORITHM, population: int = 400,
    generations: int = 300, tolerance: float = 1e-5, points: int = 30, mode: str = "+,+,+,+", setups: int = 1,
    guards: bool = False, margin: float | None = None, seed: int | None = None, workers: int = 1, dask: str | None = None,
    side: str | None = None, levels: str | None = None, ids: str | None = None, engine: str = "auto",
    aggregate: str = "mean", compactness: str = "links", bounds: str | None = None, checkpoint_every: int = 10,
    transform: str | None = None, eliminate_duplicates: bool = False,
    anatomy: Any = None, anatomy_frame: str = "LPS", clearance: float | None = None, self_clearance: float | None = None,
    link_radius: float = 8.0, actuator_radius: float = 25.0, motor_radius: float = 20.0, motor_length: float = 120.0,
    objectives: str | None = None, maxima: list[str] | None = None, minima: list[str] | None = None,
    encoder_deg: Any = 0.01, thrust: float = 30.0, lateral_force: float = 10.0, actuator_stiffness: Any = 1e4,
    docking: str = "per-patient",
) -> dict[str, Any]:  # fmt: skip
    """Validate the optimize flags and return the run's config (what config.toml holds)."""
    algorithm = algorithm.strip().lower()
    names = parse_objectives(objectives)
    limits = parse_limits(maxima, minima)
    if len(names) > 1:  # MODEL.md 15.5: two or three objectives -> NSGA-II, more -> NSGA-III
        algorithm = "nsga2" if len(names) <= 3 else "nsga3"
    elif names and algorithm in MULTI_OBJECTIVE_ALGORITHMS:
        raise InputError(f"--algorithm {algorithm} needs two or more --objectives (got {names[0]} alone)")
    loads = with_loads(Options(), encoder_deg=encoder_deg, thrust=thrust, lateral_force=lateral_force, stiffness=actuator_stiffness)
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
    docking = str(docking).strip().lower()
    if docking not in DOCKINGS:
        raise InputError(f"--docking must be one of {', '.join(DOCKINGS)}, got {docking!r}")
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
    body = with_body(Options(), clearance=clearance, self_clearance=self_clearance,
                        radii=BodyRadii(link_radius, actuator_radius, motor_radius, motor_length))  # fmt: skip
    anatomy_spec = _anatomy_spec(anatomy)
    if anatomy_spec:  # read now, so that a bad file stops the run before its folder exists
        for spec in trajectories:
            resolve_anatomy(anatomy_spec, anatomy_frame, spec)
    elif clearance is not None:
        raise InputError("--clearance needs an anatomy (--anatomy default or mesh files)")
    elif needs_clearance(names, limits):
        raise InputError("the clearance objective or limit needs an anatomy (--anatomy default or mesh files)")
    settings = {
        "algorithm": algorithm, "population": population, "generations": generations, "tolerance": tolerance,
        "period": DEFAULT_PERIOD, "points": points, "mode": mode_text, "setups": setups, "guards": guards, "margin": margin,
        "seed": seed, "engine": engine, "engine_resolved": engine_resolved, "aggregate": aggregate, "compactness": compactness,
        "checkpoint_every": checkpoint_every, "eliminate_duplicates": bool(eliminate_duplicates), "design_from": design_from, "free": list(free_names),
        "trajectories": [t.source if isinstance(t, TrajectorySet) else str(t) for t in trajectories], "side": side, "levels": levels, "ids": ids, "transform": transform,
        "anatomy": anatomy_spec, "anatomy_frame": anatomy_frame, "clearance": body.clearance_mm, "self_clearance": body.self_clearance_mm,
        "link_radius": body.link_radius, "actuator_radius": body.actuator_radius, "motor_radius": body.motor_radius, "motor_length": body.motor_length,
        "objectives": list(names), "limits": limits, "encoder_deg": list(loads.encoder_deg), "thrust": loads.thrust_N,
        "lateral_force": loads.lateral_force_N, "actuator_stiffness": list(loads.actuator_stiffness), "docking": docking,
    }  # fmt: skip
    cfg = runmod.new_run_config(settings, all_bounds, design, patients, {"workers": workers, "dask": dask or ""})
    cfg["rerun"] = _rerun_command(settings, all_bounds, cfg)
    return cfg


def _rerun_command(s: dict[str, Any], bounds: dict[str, tuple[float, float]], cfg: dict[str, Any]) -> str:
    parts = ["arcube optimize --trajectories", *s["trajectories"], "--out DIR", f"--design-from {s['design_from']}",
             f"--free {'all' if tuple(s['free']) == PAPER_NAMES else ','.join(s['free'])}", f"--algorithm {s['algorithm']}",
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
    if len(s["trajectories"]) > 1:
        parts.append(f"--docking {s['docking']}")
    if s.get("anatomy"):
        parts.append(f"--anatomy {' '.join(s['anatomy'])} --anatomy-frame {s['anatomy_frame']}")
    for flag in ("clearance", "self_clearance"):
        if s.get(flag) is not None:
            parts.append(f"--{flag.replace('_', '-')} {s[flag]!r}")
    for flag, default in (("link_radius", 8.0), ("actuator_radius", 25.0), ("motor_radius", 20.0), ("motor_length", 120.0)):
        if s.get(flag, default) != default:
            parts.append(f"--{flag.replace('_', '-')} {s[flag]!r}")
    if s.get("objectives"):
        parts.append(f"--objectives {','.join(s['objectives'])}")
    parts.extend(f"--{kind} {name}={value!r}" for name, kind, value in s.get("limits", []))
    for flag, default in (("encoder_deg", [0.01] * 5), ("thrust", 30.0), ("lateral_force", 10.0), ("actuator_stiffness", [1e4] * 5)):
        value = s.get(flag, default)
        if value != default:
            parts.append(f"--{flag.replace('_', '-')} " + (",".join(repr(v) for v in value) if isinstance(value, list) else repr(value)))
    changed = [f"{k}={lo!r}:{hi!r}" for k, (lo, hi) in bounds.items() if (lo, hi) != resolve_bounds()[k]]
    if changed:
        parts.append("--bounds " + ",".join(changed))
    return " ".join(parts)
