"""The settings of one optimization run, typed and validated once: :class:`RunSettings`.

Long module: one pydantic model; its fields and the validators that read several of them are one class.

``arcube optimize``'s flags, ``arcube.optimize(plan, RunSettings(...))`` and a run folder's
``config.toml`` all hold the same object. Python callers write Python values
(``free=["all", "mount", "L"]``, ``bounds={"p_x": (30, 250)}``, ``mode=(1, 1, -1, 1)``,
``maxima={"torque": 15}``); the command line's text forms (``"all,mount,L"``, ``"p_x=30:250"``,
``"+,+,-,+"``, ``["torque=15"]``) are accepted too. Every check lives on a field or in one
validator; an error names the field (``RunSettings.population must be >= 1, got 0``).

``config.toml``'s ``[settings]`` table is :meth:`RunSettings.to_table` (flat keys, the file format
since the first runs); :meth:`RunSettings.from_table` reads it back, old tables included: the
mapping between the typed settings and the file's keys lives here and nowhere else.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Mapping
from typing import Annotated, Any, ClassVar, Literal

from pydantic import BeforeValidator, Field, model_validator

from arcube.model.modes import DEFAULT_MODE_TEXT
from arcube.accuracy.settings import ToleranceSettings, parse_tol
from arcube.errors import InputError
from arcube.io.inputs import short_repr
from arcube.metrics import objectives_help
from arcube.evaluation.task import MAX_POINTS
from arcube.model.design import MAX_LENGTH_MM, PAPER_NAMES
from arcube.coerce import limit_pairs, mode_text
from arcube.optimization.bounds import DEFAULT_BOUNDS, FREE_GROUPS, parse_bounds, parse_free, resolve_bounds
from arcube.evaluation.envelope import TableZ, envelope_spec
from arcube.optimization.objectives import (
    OBJECTIVES,
    needs,
)
from arcube.patients.settings import Segments
from arcube.options import FLAT, GUARDED_OPTIONS, Options, Outputs, Settings, route_flat

__all__ = [
    "DEFAULT_BOUNDS",
    "FREE_GROUPS",
    "RunSettings",
    "check_algorithm",
    "parse_bounds",
    "parse_free",
    "resolve_bounds",
    "table_placement",
]

ALGORITHMS: tuple[str, ...] = ("mscmaes", "ga", "de", "cmaes", "nsga2", "nsga3", "docked")
DEFAULT_ALGORITHM = "mscmaes"
"""The default single-objective optimizer, chosen by measurement (docs: guide/optimize.md, "Which optimizer")."""
MULTI_OBJECTIVE_ALGORITHMS = frozenset({"nsga2", "nsga3"})
DEFAULT_PERIOD = 30
"""Generations over which the ftol criterion must hold (pymoo's default for one objective)."""


MAX_POPULATION = 10_000
"""Largest population: a generation is evaluated as one batch, whose arrays grow with population x
points (about 125 kB per design on the reference plan at 30 points with the NumPy engine: 1.3 GB at
this bound); a larger one exhausts the memory instead of running (the paper's GA uses 400)."""
MAX_STANDOFF_MM = 1000.0
"""Largest standoff (mm): a metre beyond the anatomy is already far outside the robot's reach; a
larger value is a unit mistake, and 1e308 overflows the approach lines to infinity."""


MAX_MARGIN_DEG = 180.0
"""Largest orientation margin mu (deg, model §12.2): |alpha_u - beta_u| <= min angle(e, +u) - mu with the angle at
most 180 deg, so a larger margin is one no design meets."""


def check_algorithm(name: str, population: int) -> None:
    """InputError for an unknown algorithm or a population it cannot use."""
    if name not in ALGORITHMS:
        raise InputError.of("RunSettings.algorithm", f"must be one of {', '.join(ALGORITHMS)}, got {name!r}")
    least = 4 if name in ("de", "nsga2", "nsga3", "cmaes") else 2
    if population < least:
        raise InputError.of("RunSettings.population", f"must be at least {least} for {name}, got {population}")


def _limits(kind: str) -> Any:
    """``{"torque": 15}`` or ``["torque=15"]`` -> ``{"torque": 15.0}``, checked (:func:`arcube.coerce.limit_pairs`:
    a name given twice or a value such as ``1_5`` is refused)."""

    def parse(value: Any) -> dict[str, float]:
        out: dict[str, float] = {}
        for name, number, shown in limit_pairs(value, param=f"RunSettings.{kind}", example="lateral_error=0.2"):
            if name not in OBJECTIVES:
                raise InputError.of(
                    f"RunSettings.{kind}", f"{shown!r}: unknown name {name!r} (known: {', '.join(OBJECTIVES)})"
                )
            if kind == "maxima" and number <= 0.0:
                raise InputError.of("RunSettings.maxima", f"{shown!r}: an upper limit must be > 0")
            out[name] = number
        return out

    return BeforeValidator(parse)


def _objectives(value: Any) -> tuple[str, ...]:
    if value is None:
        return ()
    text = value if isinstance(value, str) else ",".join(str(n) for n in value)
    names = tuple(n.strip() for n in text.split(","))
    if names == ("",):
        return ()
    for n in names:
        if n not in OBJECTIVES:
            raise InputError.of(
                "RunSettings.objectives", f"has an unknown objective {n!r} (known: {', '.join(OBJECTIVES)})"
            )
    if len(set(names)) != len(names):
        raise InputError.of("RunSettings.objectives", f"{','.join(names)!r}: an objective is named twice")
    return names


def _mode(value: Any) -> str:
    if isinstance(value, str) and value.strip().lower() == "free":
        return "free"
    return mode_text(value, param="RunSettings.mode")


def _text_list(value: Any) -> str | None:
    """``["C3", "C5"]`` or ``"C3,C5"`` -> ``"C3,C5"`` (the selection's text form)."""
    if value is None or isinstance(value, str):
        return value
    return ",".join(str(v) for v in value)


def _anatomy(value: Any) -> tuple[str, ...]:
    if value is None:
        return ()
    items = [os.fspath(value)] if isinstance(value, (str, os.PathLike)) else [os.fspath(a) for a in value]
    return () if items == ["none"] else tuple(items)


class RunSettings(Settings):
    """Everything that decides an optimization run except the plans themselves."""

    SHORT: ClassVar[dict[str, str]] = {"maxima": "max", "minima": "min", "tolerance_class": "class"}
    RENAMED: ClassVar[dict[str, str]] = {"tolerance": "ftol", "docking": "placement", "guards": "guarded"}
    RENAMED_VALUES: ClassVar[dict[str, dict[str, str]]] = {"aggregate": {"worst": "max"}}

    algorithm: str = DEFAULT_ALGORITHM
    """mscmaes (default: multi-start CMA-ES, population x generations evaluations), ga (the paper's), de, cmaes, nsga2 / nsga3 (several objectives), or docked (with dockings: the robot at its first docking, then every other docking's placement, then all together; model §19.3)."""
    population: int = Field(default=400, ge=1, le=MAX_POPULATION)
    """Population size (at most 10,000: each generation is evaluated as one batch)."""
    generations: int = Field(default=300, ge=1)
    """Maximum number of generations."""
    ftol: float = Field(default=1e-5, ge=0, allow_inf_nan=False)
    """Stop when the best feasible eta_G moves less than this over 30 generations; 0 runs every generation."""
    period: int = Field(default=DEFAULT_PERIOD, ge=1)
    """Generations over which the ftol criterion must hold (pymoo's period)."""
    points: int = Field(default=30, ge=2, le=MAX_POINTS)
    """Points per trajectory."""
    mode: Annotated[str, BeforeValidator(_mode)] = DEFAULT_MODE_TEXT
    """Working mode '+,+,+,+' (signs TMS x, TMS y, RTS x, RTS y) or 'free' (optimized)."""
    setups: Literal[1, 2] = 1
    """1, or 2: shared links, one placement per side (R and L)."""
    guarded: bool = False
    """Turn on the guards of model §8.2 (the z dyad's too when c_z is free, model §19.2)."""
    margin: float | None = Field(default=None, ge=0, le=MAX_MARGIN_DEG, allow_inf_nan=False)
    """Orientation margin mu (deg) of the spherical stage's cone (model §12.2), at most 180."""
    seed: int | None = Field(default=None, ge=0, lt=2**63)
    """Random seed (drawn and recorded when omitted)."""
    engine: str = "auto"
    """Evaluation engine: auto, numba or numpy."""
    aggregate: Literal["mean", "max"] = "mean"
    """Over several trajectory sets (or dockings): the mean or the largest (the worst) eta_G."""
    compactness: Literal["links", "bbox"] = "links"
    """nsga2's second objective: links (sum of link lengths) or bbox (bounding-box volume)."""
    checkpoint_every: int = Field(default=10, ge=1)
    """Write a checkpoint every K generations."""
    eliminate_duplicates: bool = False
    """ga: drop offspring equal to a design already in the population (pymoo's default; Matlab's ga, the paper's, keeps them)."""
    design_from: str = "paper"
    """Start design: 'paper' or a design JSON; fixed parameters keep its values."""
    c_z: float | None = Field(default=None, gt=0, le=MAX_LENGTH_MM, allow_inf_nan=False)
    """Second link of the z-leg dyad, mm: sets the start design's c_z (default the design file's, else d_z; model §6, 19.1)."""
    free: Annotated[tuple[str, ...], BeforeValidator(parse_free)] = PAPER_NAMES
    """Parameters to optimize, comma-separated names and groups: all (the paper's 23), mount (the three mounting angles), e.g. all,mount,L."""
    bounds: Annotated[dict[str, tuple[float, float]], BeforeValidator(parse_bounds)] = {}
    """Override bounds: NAME=LO:HI[,NAME=LO:HI...]."""
    side: Literal["R", "L"] | None = None
    """Keep trajectories of one side: R or L."""
    levels: Annotated[str | None, BeforeValidator(_text_list)] = None
    """Keep levels, e.g. C3-C5."""
    ids: Annotated[str | None, BeforeValidator(_text_list)] = None
    """Keep trajectory ids, e.g. 1,3,5."""
    transform: str | None = None
    """4x4 rigid transform (JSON) applied to every trajectory set."""
    anatomy: Annotated[tuple[str, ...], BeforeValidator(_anatomy)] = ()
    """Patient anatomy (model §14.2): none, default (the plan's default anatomy), or files FILE [FILE ...]: meshes (STL, OBJ, PLY) or segmentations (.seg.nrrd, .nii, .nii.gz)."""
    anatomy_frame: Literal["LPS", "RAS", "patient"] = "LPS"
    """Frame of the anatomy files: LPS (3D Slicer's default), RAS or patient."""
    segments: Segments = None
    """Segments of segmentation anatomy files (.seg.nrrd, .nii, .nii.gz) to keep: names or label values, comma-separated (C3,C4 or 3,4); default every labelled segment."""
    envelope: Annotated[tuple[str, ...], BeforeValidator(envelope_spec)] = ("none",)
    """The envelope of the whole patient and the table (model §19.5): default (a coarse body placed on the plan's landmarks), none, or skin mesh files (closed, the patient inside, in the anatomy's frame)."""
    table_z: TableZ | None = None
    """The operating table's top, mm, patient frame (z <= table_z is forbidden); default 240 mm below the posterior skin (model §19.5)."""
    objectives: Annotated[tuple[str, ...], BeforeValidator(_objectives), Field(description=objectives_help())] = ()
    maxima: Annotated[dict[str, float], _limits("maxima")] = {}
    """Upper limit NAME=VALUE (repeatable), e.g. --max lateral_error=0.2 --max torque=15 --max holding_torque=15 --max mass=3 --max lateral_error_rms=0.5."""
    minima: Annotated[dict[str, float], _limits("minima")] = {}
    """Lower limit NAME=VALUE (repeatable), e.g. --min clearance=5."""
    tolerance_class: Literal["f", "m", "c", "v"] = "m"
    """ISO 2768-1 class of the lengths and angles under which lateral_error_wc and lateral_error_rms are computed (model §20.1): f, m, c or v."""
    tol: Annotated[dict[str, float], BeforeValidator(lambda v: parse_tol(v, "RunSettings.tol"))] = {}
    """Tolerances set by hand for lateral_error_wc and lateral_error_rms, NAME=T (mm or deg): a source (r=0.02) or a group (lengths=0.05, angles=0.01, q0=0.05)."""
    placement: Literal["per-patient", "shared"] = "per-patient"
    """Over several trajectory sets: per-patient (each patient its own placement m, and mounting angles when free; the links shared) or shared (one placement for all, the paper's robust problem)."""
    dockings: Literal["per-side", "per-patient"] | None = None
    """One robot, several dockings (model §19): per-side (each plan's R trajectories one docking, its L ones another) or per-patient; each docking its own placement m and mounting angles, the rest shared; the violation the sum over dockings."""
    standoff: float | None = Field(default=None, ge=0, le=MAX_STANDOFF_MM, allow_inf_nan=False)
    """Also hold reach, guards and clearances along each trajectory's approach line, from this far (mm) beyond where its axis leaves the anatomy to its entry (model §17.1)."""
    options: Options = Options()
    """Clearance guards, body radii, loads and masses (the guards of ``guarded`` are added on top)."""

    @classmethod
    def prepare(cls, data: dict[str, Any]) -> dict[str, Any]:
        """Names and spellings folded (``algorithm``, ``placement``), flat option keys routed into ``options``, and the
        algorithm a list of objectives needs."""
        for key in ("algorithm", "placement"):
            if isinstance(data.get(key), str):
                data[key] = data[key].strip().lower()
        _route_flat(data)
        names = _objectives(data.get("objectives"))
        if len(names) > 1:  # model §15.5: two or three objectives -> NSGA-II, more -> NSGA-III
            data["algorithm"] = "nsga2" if len(names) <= 3 else "nsga3"
        return data

    @model_validator(mode="after")
    def _check(self) -> RunSettings:
        if self.algorithm not in ALGORITHMS:
            raise InputError.of(
                "RunSettings.algorithm", f"must be one of {', '.join(ALGORITHMS)}, got {self.algorithm!r}"
            )
        if len(self.objectives) == 1 and self.algorithm in MULTI_OBJECTIVE_ALGORITHMS:
            raise InputError.of(
                "RunSettings.algorithm",
                f"{self.algorithm} needs two or more objectives (got {self.objectives[0]} alone)",
            )
        check_algorithm(self.algorithm, self.population)
        if self.algorithm == "docked" and self.dockings is None:
            raise InputError.of("RunSettings.algorithm", "docked needs dockings (per-side or per-patient)")
        if self.dockings is not None and (self.setups != 1 or self.placement != "per-patient"):
            raise InputError.of(
                "RunSettings.dockings",
                "gives every docking its own placement: it needs RunSettings.setups 1 and RunSettings.placement "
                "per-patient",
            )
        if self.setups == 2 and self.side is not None:
            raise InputError.of(
                "RunSettings.setups", "2 uses both sides (one placement each); leave RunSettings.side out"
            )
        if not self.anatomy:
            if self.options.guards.clearance_mm is not None:
                raise InputError.of("Guards.clearance_mm", "needs an anatomy (anatomy default or mesh files)")
            if needs("clearance", self.objectives, self.limits):
                raise InputError(
                    "the clearance objective or limit needs an anatomy (default or mesh files)",
                    param="RunSettings.anatomy",
                )
        if needs("masses", self.objectives, self.limits):
            self.options.check_masses()
        if self.envelope == ("none",) and (
            self.options.guards.envelope_clearance_mm is not None
            or needs("envelope_clearance", self.objectives, self.limits)
        ):
            raise InputError.of(
                "RunSettings.envelope",
                "is none, but the clearance to the envelope is required (model §19.5): give envelope default or a skin mesh",
            )
        return self

    @property
    def limits(self) -> list[list[Any]]:
        """``[[name, "max" | "min", value], ...]``: the maxima, then the minima."""
        return [[n, "max", v] for n, v in self.maxima.items()] + [[n, "min", v] for n, v in self.minima.items()]

    @property
    def run_objectives(self) -> tuple[str, ...]:
        """The objectives, else eta_G (and ``compactness``, the older shorthand, for nsga2/nsga3)."""
        if self.objectives:
            return self.objectives
        return ("eta_G", self.compactness) if self.algorithm in MULTI_OBJECTIVE_ALGORITHMS else ("eta_G",)

    def accuracy_settings(self) -> ToleranceSettings:
        """The tolerances of the robust objectives and limits (``lateral_error_wc``, ``lateral_error_rms``)."""
        return ToleranceSettings(tolerance_class=self.tolerance_class, tol=self.tol)

    @property
    def all_bounds(self) -> dict[str, tuple[float, float]]:
        """Every parameter's bounds: the defaults with the overrides (c_z's too when it is free)."""
        return resolve_bounds(self.bounds, c_z="c_z" in self.free)

    def evaluation_options(self) -> Options:
        """The options the run's evaluations use: guards, body, loads, and only the outputs its
        objectives and limits need (the drill-tip metrics and the exact clearance cost time)."""
        guards = self.options.guards
        if self.guarded:
            on = GUARDED_OPTIONS.guards
            guards = guards.replace(
                rho_max_deg=on.rho_max_deg,
                min_transmission_deg=on.min_transmission_deg,
                kappa_max=on.kappa_max,
                single_assembly_mode=True,
            )
            if (
                "c_z" in self.free
            ):  # model §19.2: a design with a z-dyad link of its own has a z leg that can be assembled
                guards = guards.replace(z_dyad=True)
        clearance = needs("clearance", self.run_objectives, self.limits)
        outputs = Outputs(  # what the run computes follows from its objectives and limits alone (config.toml keeps no outputs)
            anatomy_clearance=clearance and guards.clearance_mm is None,
            tip_metrics=needs("tip_metrics", self.run_objectives, self.limits),
            clearance_min_exact=clearance,
            holding_torque=needs("holding_torque", self.run_objectives, self.limits),
            envelope_clearance=needs("envelope_clearance", self.run_objectives, self.limits),
        )
        return Options(
            guards=guards, body=self.options.body, loads=self.options.loads, masses=self.options.masses, outputs=outputs
        )

    # ------------------------------------------------------------------ config.toml's [settings] table
    def to_table(self) -> dict[str, Any]:
        """The flat ``[settings]`` table of config.toml: every key of :data:`TABLE_KEYS` in its order, a key of
        :data:`RECORDED` always, any other only when its value is not the default (so earlier tables stay as they
        were). A field is its own key; an option is its short name (:data:`FLAT_OPTIONS`); the limits are one key."""
        table: dict[str, Any] = {}
        for key in TABLE_KEYS:
            value, default = self._table_entry(key)
            if key in RECORDED or value != default:
                table[key] = plain_values(value)
        return table

    def _table_entry(self, key: str) -> tuple[Any, Any]:
        """(this run's value, the default) of one key of config.toml's [settings]."""
        if key in FLAT_OPTIONS:
            group, name = FLAT_OPTIONS[key]
            return getattr(getattr(self.options, group), name), getattr(getattr(_OPTIONS, group), name)
        if key == "limits":
            return self.limits, []
        return getattr(self, key), getattr(_defaults(), key)

    @classmethod
    def from_table(cls, table: Mapping[str, Any]) -> RunSettings:
        """Read a ``[settings]`` table, of this version or an older one (missing keys: what those
        runs ran: shared docking, duplicates eliminated, default body and loads)."""
        t = {cls.RENAMED.get(k, k): v for k, v in table.items() if k not in _DERIVED}  # a table of 0.2 or before
        t.setdefault("placement", "shared")  # runs before per-patient placement shared one
        for field, spellings in cls.RENAMED_VALUES.items():
            if isinstance(t.get(field), str) and t[field] in spellings:
                t[field] = spellings[t[field]]
        t.setdefault("eliminate_duplicates", True)  # and ran pymoo's default
        return cls(**t)

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any]) -> RunSettings:
        """The settings of a whole run config: its ``[settings]`` table and its ``[bounds]``."""
        table = cfg.get("bounds") or {}
        if not isinstance(table, Mapping):
            raise InputError(f"[bounds] must be a table of NAME = [low, high], got {short_repr(table)}")
        for k, v in table.items():
            if not (isinstance(v, (list, tuple)) and len(v) == 2 and all(_is_number(x) for x in v)):
                raise InputError(f"[bounds] {k} must be [low, high] (two numbers), got {short_repr(v)}")
        bounds = {k: (float(v[0]), float(v[1])) for k, v in table.items()}
        defaults = resolve_bounds(c_z=True)
        return cls.from_table({**cfg["settings"], "bounds": {k: v for k, v in bounds.items() if v != defaults.get(k)}})


_TABLE_GUARDS = ("z_dyad", "c_z", "rho_max_deg", "min_transmission_deg", "kappa_max", "single_assembly_mode")
"""Guards of 8.2 that a run can set one by one (beside ``guarded``); written only when set. ``c_z`` is the run's own
field now (the start design's, model §19.1), at the place the guard's c_z had."""
_MASS_KEYS = ("wall", "density", "m_delta", "m_motor", "gravity")
"""The masses of model §18.1 (their short names)."""
RECORDED = (
    *("algorithm", "population", "generations", "ftol", "period", "points", "mode", "setups", "guarded", "margin"),
    *("seed", "engine", "aggregate", "compactness", "checkpoint_every", "eliminate_duplicates", "design_from", "free"),
    *("side", "levels", "ids", "transform", "anatomy", "anatomy_frame", "clearance", "self_clearance"),
    *("link_radius", "actuator_radius", "motor_radius", "motor_length", "objectives", "limits", "encoder_deg"),
    *("thrust", "lateral_force", "actuator_stiffness", "placement"),
)
"""The keys of config.toml's [settings] that every run writes (those of the first runs, and placement)."""
TABLE_KEYS = (
    *RECORDED,
    *_TABLE_GUARDS,
    *("dockings", "standoff", "segments", "envelope", "table_z", "tolerance_class", "tol", "envelope_clearance"),
    *_MASS_KEYS,
)
"""Every key of config.toml's [settings], in the order it is written; those past :data:`RECORDED` only when set."""


@functools.cache
def _defaults() -> RunSettings:
    """The default settings (made once)."""
    return RunSettings()


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def plain_values(value: Any) -> Any:
    """A value as TOML holds it: tuples as lists (nested too), mappings as plain dicts (a settings value, a run
    config's frozen record)."""
    if isinstance(value, (tuple, list)):
        return [plain_values(v) for v in value]
    if isinstance(value, Mapping):
        return {k: plain_values(v) for k, v in value.items()}
    return value


def table_placement(table: Mapping[str, Any]) -> str:
    """The placement of a config.toml ``[settings]`` table, of this version or an older one."""
    return str(table.get("placement", table.get("docking", "shared")))


_DERIVED = ("engine_resolved", "trajectories")
"""Keys of the table that describe the run, not its settings (the engine found, the plans' sources)."""
FLAT_OPTIONS: dict[str, tuple[str, str]] = {
    key: FLAT[key] for key in TABLE_KEYS if key in FLAT and key not in RunSettings.model_fields
}
"""The table's (and the optimize keywords') flat names of :class:`~arcube.options.Options` fields: their short names
(a run's own field of that name, ``c_z``, is the field)."""
_OPTIONS = Options()


def _route_flat(data: dict[str, Any]) -> None:
    """In place: flat option keys (the table's and the keywords' short names, :data:`FLAT_OPTIONS`) into
    ``options``, a table's ``limits`` into ``maxima``/``minima``."""
    # by their full field names: a table's envelope_clearance is the guard's (mm), never outputs.envelope_clearance
    flat = {FLAT_OPTIONS[key][1]: data.pop(key) for key in FLAT_OPTIONS if data.get(key) is not None}
    for key in FLAT_OPTIONS:
        data.pop(key, None)  # None: the table's "not set"
    if flat:
        data["options"] = route_flat(flat, data.get("options"))
    if "limits" in data:
        limits = data.pop("limits") or []
        data.setdefault("maxima", {n: v for n, k, v in limits if k == "max"})
        data.setdefault("minima", {n: v for n, k, v in limits if k == "min"})
