"""The registry of metrics: every figure the optimizer can minimize or bound, and every requirement of a design job,
declared once as a :class:`Metric`.

The optimizer's objectives and limits (``--objectives``, ``--max``, ``--min`` of ``arcube optimize``), the design job's
requirements (``--max``, ``--min``, ``--no-<name>`` of ``arcube design``, ``requirements.csv``, each docking's summary),
the command-line help that lists them, the reports and the explorer all read this table; the older names
(:data:`arcube.optimization.objectives.OBJECTIVES`, :data:`arcube.design_job.requirements.REQUIREMENTS`,
``DEFAULTS``, ...) are views of it. A new requirement on a figure the evaluation already computes is one entry here;
the docs page "Extending arcube" says step by step what a new figure, objective, input format or command touches.

The order of :data:`METRICS` is the order of the requirements in ``requirements.csv`` and of the names in messages.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "METRICS",
    "Metric",
    "metric",
    "objective_names",
    "objectives_help",
    "requirements_help",
    "LIMIT_BOUNDS",
    "MAX_ETA_G",
    "limit_bound",
]

OUTPUTS = frozenset({"tip_metrics", "clearance", "envelope_clearance", "holding_torque", "masses", "robust"})
"""What an evaluation computes only when asked (:class:`arcube.options.Outputs` and the run's extra passes)."""
SOURCES = frozenset({"batch", "eta_G", "mass", "links", "bbox", "robust", "program", "breach"})
"""Where the optimizer (or the chosen robot's check) takes a metric's value from."""
WHERE = ("whole line", "drill", "program", "screws")
"""Where a requirement holds: over each trajectory's whole line (standoff to target: the approach too, model §17.1),
where the drill works (entry to target), on the drilling program, on the screws (model §22)."""


@dataclass(frozen=True)
class Metric:
    """One figure: its name, unit, meaning, and how the optimizer, the design job and the reports use it.

    Attributes:
        name: the name users write (``--objectives NAME``, ``--max NAME=VALUE``).
        unit: the unit of its values ("" for a pure number).
        description: what it measures, one line (the command-line help and the docs list it).
        summary_key: the field of a run's ``summary.json`` (and of ``arcube.evaluate``'s summary) holding its value.
        objective: an objective and a limit of the optimizer; False for a requirement checked otherwise.
        maximized: larger is better (an objective column holds its negative).
        source: where the optimizer's per-design value comes from: ``batch`` (the worst of ``batch_field`` over the
            tasks: the largest, or the smallest when maximized), ``eta_G``, ``mass``, ``links``, ``bbox``, ``robust``
            (model §20.3's first order); ``program`` and ``breach`` are checked on the chosen robot only.
        batch_field: the attribute of a batch result (:class:`arcube.evaluation.result.BatchResult`) for ``batch``.
        needs: what the evaluation must compute for it (:data:`OUTPUTS`).
        requirement: ``min`` (value >= limit) or ``max`` (value <= limit) as a requirement of ``arcube design``; None:
            not a requirement.
        default_limit: the design job's limit unless changed or dropped (``--no-<name>``); None: only when asked.
        where: where the requirement holds (:data:`WHERE`).
        point_field: the per-point field of a result's ``points`` (:class:`arcube.evaluation.reference.PointResults`)
            the requirement is checked on by the NumPy reference.
        part_field: the per-point field naming where the value is attained, an index into ``part_names``.
        part_names: ``parts`` (the body's parts), ``actuators`` or ``envelope`` (part vs region of model §19.5).
        guard_option: for a ``min`` requirement the search meets as a guard: the :class:`arcube.options.Guards` field
            set to its limit.
        program_key: the figure in each actuator's ``motors`` entry of ``program.json`` (``program`` source).
        docking_key: the field of each docking's entry in a design job's ``summary.json`` that holds its value.
    """

    name: str
    unit: str
    description: str
    summary_key: str | None = None
    objective: bool = True
    maximized: bool = False
    source: str = "batch"
    batch_field: str | None = None
    needs: frozenset[str] = frozenset()
    requirement: str | None = None
    default_limit: float | None = None
    where: str = ""
    point_field: str | None = None
    part_field: str | None = None
    part_names: str = ""
    guard_option: str | None = None
    program_key: str | None = None
    docking_key: str | None = None

    @property
    def checked_after(self) -> bool:
        """A requirement checked on the chosen robot only, not searched for (a program, a Monte Carlo)."""
        return self.source in ("program", "breach")


_TIP = frozenset({"tip_metrics"})
METRICS: tuple[Metric, ...] = (
    Metric("clearance", "mm", "smallest clearance to the anatomy, mm (maximized; needs --anatomy)", "clearance_min_mm",
           maximized=True, batch_field="clearance_min", needs=frozenset({"clearance"}), requirement="min", default_limit=5.0,
           where="whole line", point_field="clearance_mm", part_field="clearance_part", part_names="parts",
           guard_option="clearance_mm", docking_key="clearance_mm"),
    Metric("self_clearance", "mm", "smallest clearance between the robot's own parts, mm", objective=False,
           requirement="min", default_limit=2.0, where="whole line", point_field="self_clearance_mm",
           guard_option="self_clearance_mm", docking_key="self_clearance_mm"),
    Metric("envelope_clearance", "mm", "smallest clearance to the envelope of the whole patient and the table, mm "
           "(maximized; model §19.5)", "envelope_clearance_min_mm", maximized=True, batch_field="envelope_clearance_min",
           needs=frozenset({"envelope_clearance"}), requirement="min", default_limit=10.0, where="whole line",
           point_field="envelope_clearance_mm", part_field="envelope_part", part_names="envelope",
           guard_option="envelope_clearance_mm", docking_key="envelope_clearance_mm"),
    Metric("lateral_error", "mm", "largest error across the drill axis, mm (15.2)", "lateral_error_max_mm",
           batch_field="lateral_error_max", needs=_TIP, requirement="max", default_limit=0.5, where="drill",
           point_field="lateral_error_mm", docking_key="lateral_error_mm"),
    Metric("axis_error", "deg", "largest drill-direction error, deg (15.2)", "axis_error_max_deg",
           batch_field="axis_error_max", needs=_TIP, requirement="max", default_limit=0.25, where="drill",
           point_field="axis_error_deg", docking_key="axis_error_deg"),
    Metric("torque", "N·m", "largest actuator torque under the drilling loads, N·m (15.3)", "torque_max_Nm",
           batch_field="torque_max", needs=_TIP, requirement="max", default_limit=20.0, where="drill",
           point_field="torque_Nm", part_field="torque_actuator", part_names="actuators", docking_key="torque_Nm"),
    Metric("holding_torque", "N·m", "largest actuator torque holding the robot's weight and the drilling loads, N·m (18.2)",
           "holding_torque_max_Nm", batch_field="holding_torque_max",
           needs=frozenset({"tip_metrics", "holding_torque", "masses"}), requirement="max", default_limit=20.0,
           where="drill", point_field="holding_torque_Nm", part_field="holding_torque_actuator", part_names="actuators",
           docking_key="holding_torque_Nm"),
    Metric("lateral_error_wc", "mm", "largest first-order worst-case lateral error of the robot as built to --class / "
           "--tol, mm (model §20.3)", "lateral_error_wc_mm", source="robust", needs=frozenset({"robust"}),
           requirement="max", where="drill"),
    Metric("lateral_error_rms", "mm", "largest RMS lateral error of the robot as built to --class / --tol, mm (model §20.3)",
           "lateral_error_rms_mm", source="robust", needs=frozenset({"robust"}), requirement="max", where="drill"),
    Metric("torque_peak", "N·m", "largest actuator torque over the drilling program, N·m (model §18.3)", objective=False,
           source="program", requirement="max", where="program", program_key="torque_peak_Nm"),
    Metric("power_peak", "W", "largest actuator power over the drilling program, W (model §18.3)", objective=False,
           source="program", requirement="max", where="program", program_key="power_peak_W"),
    Metric("breach_probability", "probability", "largest probability that a screw leaves its pedicle (model §22)",
           objective=False, source="breach", requirement="max", where="screws"),
    Metric("eta_G", "", "the paper's global conditioning index (mean of the worst kappa), lower is better", "eta_G",
           source="eta_G"),
    Metric("tip_error", "mm", "largest drill-tip error over the plan, mm (model §15.2)", "tip_error_max_mm",
           batch_field="tip_error_max", needs=_TIP),
    Metric("axial_error", "mm", "largest error along the drill axis, mm (15.2)", "axial_error_max_mm",
           batch_field="axial_error_max", needs=_TIP),
    Metric("deflection", "mm", "largest lateral tip deflection under the loads, mm (15.4)", "deflection_max_mm",
           batch_field="deflection_max", needs=_TIP),
    Metric("mass", "kg", "moving mass of the robot, kg (18.1)", "moving_mass_kg", source="mass",
           needs=frozenset({"masses"})),
    Metric("links", "mm", "sum of the 14 link lengths, mm", "links_sum_mm", source="links"),
    Metric("bbox", "L", "largest bounding-box volume of the body over a task, litres", "bbox_volume_L", source="bbox"),
)  # fmt: skip
"""Every metric, the requirements first in the order of ``requirements.csv``."""

_BY_NAME = {m.name: m for m in METRICS}

MAX_ETA_G = 1e6
"""Largest eta_G a user may give (``--best-known``, a limit on it): eta_G >= 1 is a condition number's mean (model
§8.3), and at 1e6 the dexterity 100/eta_G is 1e-4 %, a design that barely moves; a larger value is a typo."""
LIMIT_BOUNDS: dict[str, float] = {
    "mm": 1e4,  # 10 m: beyond the robot, the patient and the operating room (clearances, errors, link sums)
    "deg": 180.0,  # an axis error or angle beyond a half turn means nothing
    "N·m": 1e5,  # as the thrust's 1e5 N at a metre: beyond any actuator of a drilling robot
    "W": 1e6,  # a megawatt: beyond any actuator
    "kg": 1e4,  # as the masses of model §18.1 (at most 1e4 kg each)
    "L": 1e4,  # ten cubic metres: beyond the room the robot stands in
    "probability": 1.0,
    "": MAX_ETA_G,  # eta_G
}
"""The largest |limit| (``--max NAME=VALUE``, ``--min NAME=VALUE``) of a metric in each unit: beyond it a limit
holds for every design or none and is a unit mistake or a typo (``lateral_error=1e12``)."""


def limit_bound(name: str) -> tuple[float, str] | None:
    """(the largest |limit| of metric ``name``, its unit) (:data:`LIMIT_BOUNDS`); None for a name that is not a metric."""
    m = _BY_NAME.get(name)
    return None if m is None else (LIMIT_BOUNDS[m.unit], m.unit)


def metric(name: str) -> Metric:
    """The metric called ``name`` (KeyError for another name)."""
    return _BY_NAME[name]


def objective_names() -> tuple[str, ...]:
    """The objectives and limits of the optimizer: the paper's index eta_G first, then in registry order."""
    return ("eta_G", *(m.name for m in METRICS if m.objective and m.name != "eta_G"))


def objectives_help() -> str:
    """The objectives as the command-line help lists them (``--objectives`` of ``arcube optimize``)."""
    plain = [n for n in objective_names() if not metric(n).maximized and metric(n).source != "robust"]
    larger = [n for n in objective_names() if metric(n).maximized]
    built = [n for n in objective_names() if metric(n).source == "robust"]
    return (
        f"Objectives, comma-separated: {plain[0]} (default), {', '.join(plain[1:])}, {' and '.join(larger)} (maximized), "
        f"{' and '.join(built)} (as built to --class / --tol). Two or three: nsga2; more: nsga3."
    )


def requirements_help(kind: str) -> str:
    """The requirements of ``kind`` (``min`` / ``max``) as ``arcube design``'s ``--min`` / ``--max`` help lists them:
    the default ones with their limits, then those only set when asked, grouped by where they hold."""

    def item(m: Metric) -> str:
        unit = {"probability": " (0-1)", "": ""}.get(m.unit, f" ({m.unit.replace('·', ' ')})")
        return f"{m.name}={m.default_limit:g}{unit}" if m.default_limit is not None else f"{m.name}{unit}"

    ms = [m for m in METRICS if m.requirement == kind]
    on = [item(m) for m in ms if m.default_limit is not None]
    text = ("Change a lower limit: " if kind == "min" else "Change or add an upper limit: ") + ", ".join(on)
    for label, test in (
        ("at the plan's points", lambda m: m.source not in ("robust", "program", "breach")),
        ("as built to --class / --tol", lambda m: m.source == "robust"),
        ("on the drilling program", lambda m: m.source == "program"),
        ("on the screws, checked on the robot chosen (model §22)", lambda m: m.source == "breach"),
    ):
        more = [item(m) for m in ms if m.default_limit is None and test(m)]
        if more:
            text += f"; {label} (none by default): {', '.join(more)}"
    return text + "."
