"""One run's configuration as one frozen object: :class:`RunConfig`.

What an optimization run is (its settings, the dockings it optimizes over, the start design, the bounds)
and what records it (run id, versions, the command that reruns it). The optimizer, resume, the study,
the design job and the reports take this object; ``config.toml`` is written from it and read into it
here and only here (:meth:`RunConfig.to_toml`, :meth:`RunConfig.from_toml`), so an in-memory run
builds no table at all. A ``config.toml`` of an earlier version reads into the same object
(:meth:`~arcube.optimization.settings.RunSettings.from_table` maps its old keys and values).

```python
from arcube.optimization.config import build_config
cfg = build_config(["reference"], generations=3, seed=1)
cfg.settings.seed, len(cfg.patients), cfg.bounds["d_x"]      # 1, 1, (lo, hi) in mm
```
"""

from __future__ import annotations

import dataclasses
import re
import sys
import time
import uuid
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from arcube.errors import InputError
from arcube.optimization.settings import RunSettings, plain_values

__all__ = ["FORMAT_VERSION", "RUN_FORMAT", "RunConfig"]

RUN_FORMAT = "arcube-optimize-run"
"""config.toml's ``format``."""
FORMAT_VERSION = 1
"""The version of a run folder's format: config.toml's and the checkpoint's."""


def _frozen(value: Any) -> Any:
    """``value`` with every dict read-only and every list a tuple (a config's records cannot be changed in place)."""
    if isinstance(value, Mapping):
        return MappingProxyType({k: _frozen(v) for k, v in value.items()})
    if isinstance(value, (list, tuple)):
        return tuple(_frozen(v) for v in value)
    return value


def executor_table(table: Any, prefix: str = "executor.") -> dict[str, Any]:
    """A run folder's ``[executor]`` (``workers`` >= 1, ``dask`` an address or ""), checked: ValueError naming the key
    (after ``prefix``: a study.toml holds them at its top level)."""
    if not isinstance(table, Mapping):
        raise ValueError("executor must be a table (workers, dask)")
    workers, dask = table.get("workers", 1), table.get("dask", "")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"{prefix}workers must be a whole number >= 1, got {workers!r}")
    if not isinstance(dask, str):
        raise ValueError(f'{prefix}dask must be a scheduler address or "", got {dask!r}')
    if dask and not _ADDRESS.match(dask.strip()):  # the file's, not the command line's --dask
        raise ValueError(f'{prefix}dask {dask!r}: expected a scheduler address HOST:PORT or ""')
    return dict(table)


def _executor(table: Any) -> dict[str, Any]:
    """:func:`executor_table` of a config.toml; InputError naming the key (the reader names the file)."""
    try:
        return executor_table(table)
    except ValueError as exc:
        raise InputError(str(exc)) from None


_ADDRESS = re.compile(r"^(?:(?:tcp|tls|inproc|ucx|ws|wss)://)?(?:\[[0-9a-fA-F:.]+\]|[A-Za-z0-9_.-]+):\d{1,5}$")
"""A dask scheduler's address, ``[tcp://]HOST:PORT``."""


def check_dask_address(address: str) -> str:
    """``address`` if it names a scheduler as ``[tcp://]HOST:PORT``; InputError otherwise, before any
    connection is tried (a malformed one left dask's half-built client hanging at exit)."""
    if not isinstance(address, str) or not _ADDRESS.match(address.strip()):
        raise InputError.of("dask", f"{address!r}: expected a scheduler address HOST:PORT, e.g. tcp://10.0.0.5:8786")
    return address.strip()


@dataclass(frozen=True)
class RunConfig:
    """Everything one optimization run needs and records, read-only.

    ``patients`` holds one record per docking (model §19.1: a patient, or one side of one): its plan's
    ``source``, the trajectories' ``ids``/``levels``/``sides``, their ``entry``/``target`` points (mm,
    patient frame, shape (n, 3) as nested tuples) and, where set, its ``name``, ``side``, ``plan_index``,
    its own settings (``anatomy``, ``anatomy_frame``, ``segments``, ``envelope_spec``, ``table_z``), the
    ``standoff`` points of model §17.1, the placed ``envelope`` record of 19.5 (JSON text) and the
    anatomy file the run folder holds (``anatomy_file``, ``anatomy_source``).
    """

    settings: RunSettings
    """The run's settings (its seed is set: :func:`~arcube.optimization.config.build_config` draws one)."""
    patients: tuple[Mapping[str, Any], ...]
    """One read-only record per docking (above)."""
    design: Mapping[str, float]
    """The start design's parameters (mm, rad; model §13), with its ``c_z`` when it has one (19.1)."""
    bounds: Mapping[str, tuple[float, float]]
    """Every parameter's search bounds (lo, hi) as the run searches them."""
    trajectories: tuple[str, ...]
    """The plans as given (files, folders, ``reference``), one per patient."""
    engine_resolved: str
    """The evaluation engine found (``numba`` or ``numpy``)."""
    executor: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({"workers": 1, "dask": ""}))
    """Where the evaluations run (``workers``, ``dask``): recorded, not part of the result."""
    run_id: str = field(default_factory=lambda: uuid.uuid4().hex)
    created: str = field(default_factory=lambda: time.strftime("%Y-%m-%dT%H:%M:%S%z"))
    command: str = field(default_factory=lambda: " ".join(sys.argv))
    versions: Mapping[str, str] = field(default_factory=dict)
    """Python's and the numerical packages' versions at the start."""
    rerun: str | None = None
    """The command line that reruns this run."""

    __hash__ = None  # type: ignore[assignment]  # its records are mappings: equal configs, not hashable ones

    def __post_init__(self) -> None:
        for name in ("design", "bounds", "executor", "versions"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))
        object.__setattr__(self, "patients", tuple(_frozen(p) for p in self.patients))
        object.__setattr__(self, "trajectories", tuple(self.trajectories))

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        """Pickled (and deep-copied) as its fields' plain values, frozen again on the way back."""
        return type(self), tuple(plain_values(getattr(self, f.name)) for f in dataclasses.fields(self))

    def replace(self, **changes: Any) -> RunConfig:
        """A copy with ``changes`` (fields by name)."""
        return dataclasses.replace(self, **changes)

    def with_seed(self, seed: int) -> RunConfig:
        """This run with another seed and its own run id (a study's seed, model-wise the same run)."""
        import re

        rerun = self.rerun
        if rerun is not None:
            flag = RunSettings.flag("seed")
            rerun = re.sub(rf"{flag} \d+", f"{flag} {int(seed)}", rerun)
        return self.replace(settings=self.settings.replace(seed=int(seed)), run_id=uuid.uuid4().hex, rerun=rerun)

    def with_patients(self, patients: list[dict[str, Any]]) -> RunConfig:
        """A copy with these docking records (as a run folder's files complete them)."""
        return self.replace(patients=tuple(patients))

    def patient(self, i: int) -> dict[str, Any]:
        """Docking ``i``'s record as a plain, changeable dict."""
        return plain_values(self.patients[i])

    def own(self, i: int, name: str) -> Any:
        """Docking ``i``'s own value of a per-patient setting (``anatomy``, ``anatomy_frame``, ``segments``,
        ``table_z``; the envelope's spec is ``envelope_spec``), else the run's."""
        p = self.patients[i]
        key = "envelope_spec" if name == "envelope" else name
        return p[key] if key in p else getattr(self.settings, name)

    # ------------------------------------------------------------------ the run-folder edge
    def to_toml(self) -> dict[str, Any]:
        """config.toml's tables (what :func:`arcube.optimization.folder.to_toml` writes), in the order every
        earlier run wrote them."""
        table = {
            "format": RUN_FORMAT,
            "format_version": FORMAT_VERSION,
            "run_id": self.run_id,
            "created": self.created,
            "command": self.command,
            "versions": dict(self.versions),
            "settings": {
                **self.settings.to_table(),
                **self._legacy_c_z(),
                "engine_resolved": self.engine_resolved,
                "trajectories": list(self.trajectories),
            },
            "bounds": {k: [float(lo), float(hi)] for k, (lo, hi) in self.bounds.items()},
            "design": dict(self.design),
            "executor": dict(self.executor),
            "patients": [plain_values(p) for p in self.patients],
        }
        if self.rerun is not None:
            table["rerun"] = self.rerun
        return table

    def _legacy_c_z(self) -> dict[str, float]:
        """``{"c_z": ...}`` for a run of before whose c_z is the z-dyad guard's (:meth:`from_toml`), else nothing."""
        c_z = self.settings.options.guards.c_z
        return {} if self.settings.c_z is not None or c_z is None else {"c_z": c_z}

    @classmethod
    def from_toml(cls, table: Mapping[str, Any]) -> RunConfig:
        """The config a config.toml's tables describe (of this version or an earlier one); pydantic's
        errors and KeyError/TypeError/ValueError on a malformed table (the reader names the file)."""
        settings_table = table["settings"]
        settings = RunSettings.from_config(table)  # first: it names a [bounds] entry that is not a pair
        bounds = {k: (float(v[0]), float(v[1])) for k, v in (table.get("bounds") or {}).items()}
        design = dict(table.get("design") or {})
        if settings.c_z is not None and design.get("c_z") is None:
            # a folder written before c_z was the design's alone: its --c-z was the z-dyad guard's c_z (model §6,
            # graded in V_fit); it resumes as it ran (a new run's c_z is in its [design] too, model §19.1)
            legacy = settings.options.replace(c_z=settings.c_z)
            settings = settings.replace(c_z=None, options=legacy)
        return cls(
            settings=settings,
            patients=tuple(table["patients"]),
            design=design,
            bounds=bounds,
            trajectories=tuple(str(t) for t in settings_table.get("trajectories", ())),
            engine_resolved=str(settings_table["engine_resolved"]),
            executor=_executor(table.get("executor") or {}),
            run_id=str(table["run_id"]),
            created=str(table.get("created", "")),
            command=str(table.get("command", "")),
            versions=dict(table.get("versions") or {}),
            rerun=table.get("rerun"),
        )
