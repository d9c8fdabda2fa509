"""A run's config (what config.toml holds): validated settings, the plans' coordinates, the start design.

:func:`build_config` takes the plans and a :class:`~arcube.optimization.settings.RunSettings`
(or its fields as keywords), loads the trajectory sets and the start design, checks the anatomy
can be read, and returns the config dict that :mod:`arcube.optimization.run` writes to
``config.toml`` and runs.
"""

from __future__ import annotations

import json
import secrets
from typing import Any

from arcube.errors import InputError
from arcube.evaluation.anatomy import resolve_anatomy
from arcube.evaluation.envelope import resolve_envelope
from arcube.evaluation.standoff import standoff_points
from arcube.io import TrajectorySet, load_trajectories, select
from arcube.model.design import Design
from arcube.optimization import run as runmod
from arcube.optimization.algorithms import make_termination
from arcube.optimization.build import check_engine
from arcube.optimization.settings import RunSettings
from arcube.options import Options, validated

__all__ = ["build_config", "run_settings"]


def _load_patients(specs: list[Any], s: RunSettings) -> list[dict[str, Any]]:
    patients = []
    for spec in specs:
        full = ts = spec if isinstance(spec, TrajectorySet) else load_trajectories(spec, s.transform)
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
        anatomy = resolve_anatomy(list(s.anatomy), s.anatomy_frame, spec, segments=s.segments) if s.anatomy else None
        if s.standoff is not None:  # MODEL.md 17.1: computed once, with the anatomy as given, and kept in config.toml
            S, _ = standoff_points(ts.entry, ts.target, anatomy, s.standoff)
            patient["standoff"] = [[float(v) for v in row] for row in S]
        if s.envelope != ("none",):  # MODEL.md 19.5: placed once on the whole plan (both sides), kept in config.toml
            envelope = resolve_envelope(list(s.envelope), full, anatomy, s.table_z, s.anatomy_frame)
            patient["envelope"] = json.dumps(envelope.to_record())
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
    engine_resolved = check_engine(s.engine)
    design = Design.load(s.design_from)
    patients = _load_patients(trajectories, s)
    if s.anatomy:  # read now, so that a bad file stops the run before its folder exists
        for spec in trajectories:
            resolve_anatomy(list(s.anatomy), s.anatomy_frame, spec, segments=s.segments)
    table = {**s.to_table(), "engine_resolved": engine_resolved,
             "trajectories": [t.source if isinstance(t, TrajectorySet) else str(t) for t in trajectories]}  # fmt: skip
    cfg = runmod.new_run_config(table, s.all_bounds, design, patients, {"workers": workers, "dask": dask or ""})
    cfg["rerun"] = _rerun_command(s, table["trajectories"])
    return cfg


def _text(value: Any) -> str:
    if isinstance(value, (list, tuple)):
        return ",".join(_text(v) for v in value)
    return repr(value) if isinstance(value, float) else str(value)


def _rerun_command(s: RunSettings, trajectories: list[str]) -> str:
    """The command line that reruns this run: every setting of ``s`` written out with its flag
    (:meth:`arcube.options.Settings.flag`, the rule the CLI's options are generated with), so that the
    line holds even when a default changes."""
    parts = ["arcube optimize", RunSettings.flag("trajectories"), *trajectories, RunSettings.flag("out"), "DIR", RunSettings.flag("seed"), str(s.seed)]
    for name in RunSettings.model_fields:
        value = getattr(s, name)
        if name in ("seed", "period", "options") or value is None or value == () or value == {} or value is False:
            continue
        flag = RunSettings.flag(name)
        if value is True:
            parts.append(flag)
        elif name in ("maxima", "minima"):
            parts += [f"{flag} {n}={v!r}" for n, v in value.items()]
        elif name == "bounds":
            parts.append(f"{flag} " + ",".join(f"{k}={lo!r}:{hi!r}" for k, (lo, hi) in value.items()))
        elif name == "anatomy":
            parts.append(f"{flag} {' '.join(value)}")
        else:
            parts.append(f"{flag}={_text(value)}" if name == "mode" else f"{flag} {_text(value)}")
    default = Options()
    for group in ("guards", "body", "loads", "masses"):
        model, mine, base = type(getattr(default, group)), getattr(s.options, group), getattr(default, group)
        for name in model.model_fields:
            value = getattr(mine, name)
            if value != getattr(base, name):
                parts.append(model.flag(name) if value is True else f"{model.flag(name)} {_text(value)}")
    return " ".join(parts)
