"""A run's config (what config.toml holds): validated settings, the plans' coordinates, the start design.

:func:`build_config` takes the plans and a :class:`~arcube.optimization.settings.RunSettings`
(or its fields as keywords), loads the trajectory sets and the start design, checks the anatomy
can be read, and returns the config dict that :mod:`arcube.optimization.run` writes to
``config.toml`` and runs.
"""

from __future__ import annotations

import secrets
from typing import Any

from arcube.errors import InputError
from arcube.evaluation.anatomy import resolve_anatomy
from arcube.evaluation.standoff import standoff_points
from arcube.io import TrajectorySet, load_trajectories, select
from arcube.model.design import PAPER_NAMES, Design
from arcube.optimization import run as runmod
from arcube.optimization.algorithms import make_termination
from arcube.optimization.settings import RunSettings, resolve_bounds
from arcube.options import validated

__all__ = ["build_config", "run_settings"]


def _load_patients(specs: list[Any], s: RunSettings) -> list[dict[str, Any]]:
    patients = []
    for spec in specs:
        ts = spec if isinstance(spec, TrajectorySet) else load_trajectories(spec, s.transform)
        if s.side is not None or s.levels is not None or s.ids is not None:
            ts = select(ts, side=s.side, levels=s.levels, ids=s.ids)
        if not len(ts.ids):
            raise InputError(f"{ts.source}: no trajectories to optimize over")
        if s.setups == 2:
            for sd in ("R", "L"):
                if sd not in ts.sides:
                    raise InputError.of("RunSettings.setups", f"2 needs R and L trajectories; {spec} has no side {sd} (after the selection)")
        patient = {
            "source": ts.source if isinstance(spec, TrajectorySet) else str(spec), "ids": list(ts.ids), "levels": list(ts.levels), "sides": list(ts.sides),
            "entry": [[float(v) for v in row] for row in ts.entry], "target": [[float(v) for v in row] for row in ts.target],
        }  # fmt: skip
        if s.standoff is not None:  # MODEL.md 17.1: computed once, with the anatomy as given, and kept in config.toml
            anatomy = resolve_anatomy(list(s.anatomy), s.anatomy_frame, spec) if s.anatomy else None
            S, _ = standoff_points(ts.entry, ts.target, anatomy, s.standoff)
            patient["standoff"] = [[float(v) for v in row] for row in S]
        patients.append(patient)
    return patients


def run_settings(settings: RunSettings | None = None, **fields: Any) -> RunSettings:
    """``settings`` with ``fields`` changed (flat names accepted: ``thrust=25``), validated once."""
    base = settings.model_dump() if settings is not None else {}
    return validated(RunSettings, {**base, **fields}) if fields or settings is None else settings


def build_config(trajectories: list[Any], settings: RunSettings | None = None, *, workers: int = 1, dask: str | None = None,
                 **fields: Any) -> dict[str, Any]:  # fmt: skip
    """The run's config for these plans (each a TrajectorySet or what ``load_trajectories`` reads).

    ``workers`` and ``dask`` say where the evaluations run (recorded, not part of the settings).
    """
    s = run_settings(settings, **fields)
    if not trajectories:
        raise InputError.of("plan", "give at least one trajectory set (CSV, .mrk.json, folder or 'reference')")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise InputError.of("workers", f"must be an integer >= 1, got {workers!r}")
    if dask:
        from arcube.optimization.executors import check_dask_address

        check_dask_address(dask)
    if dask and workers > 1:
        raise InputError.of("workers", "and dask exclude each other (the Dask cluster has its own workers)")
    make_termination(s.algorithm, s.generations, s.tolerance)
    if s.seed is None:
        s = s.replace(seed=secrets.randbelow(2**31))
    engine_resolved = runmod.check_engine(s.engine)
    design = Design.load(s.design_from)
    patients = _load_patients(trajectories, s)
    if s.anatomy:  # read now, so that a bad file stops the run before its folder exists
        for spec in trajectories:
            resolve_anatomy(list(s.anatomy), s.anatomy_frame, spec)
    table = {**s.to_table(), "engine_resolved": engine_resolved,
             "trajectories": [t.source if isinstance(t, TrajectorySet) else str(t) for t in trajectories]}  # fmt: skip
    cfg = runmod.new_run_config(table, s.all_bounds, design, patients, {"workers": workers, "dask": dask or ""})
    cfg["rerun"] = _rerun_command(table, s.all_bounds, cfg)
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
    for flag in ("clearance", "self_clearance", "standoff"):
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
    for flag in ("wall", "density", "m_delta", "m_motor", "gravity"):  # MODEL.md 18.1: in the table only when not the defaults
        if s.get(flag) is not None:
            value = s[flag]
            parts.append(f"--{flag.replace('_', '-')}=" + (",".join(repr(v) for v in value) if isinstance(value, list) else repr(value)))
    changed = [f"{k}={lo!r}:{hi!r}" for k, (lo, hi) in bounds.items() if (lo, hi) != resolve_bounds()[k]]
    if changed:
        parts.append("--bounds " + ",".join(changed))
    return " ".join(parts)
