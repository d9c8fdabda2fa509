"""What the model is: the settings of one evaluation, as small validated groups.

:class:`Options` is made of four groups, each a frozen pydantic model whose ``Field`` constraints
are the only checks of its values:

* :class:`Guards`: the guards of model §8.2, 14.3 and 19.5 (all off by default);
* :class:`Body`: the radii of the robot's body (model §14.1);
* :class:`Loads`: the encoder resolution, drilling loads and actuator stiffness (model §15);
* :class:`Masses`: the links' tubes, the actuators' and drill motor's masses, gravity (model §18.1);
* :class:`Outputs`: what to compute beyond what the guards need (engine requests, not model).

A bad value raises :class:`~arcube.errors.InputError` naming the field as the caller wrote it
(``Loads.thrust_N must be >= 0, got -1.0``); the CLI maps that name to its flag.

```python
import arcube
opts = arcube.Options(guards=arcube.Guards(clearance_mm=5.0), loads=arcube.Loads(thrust_N=25.0))
opts.replace(kappa_max=80.0).guards.kappa_max     # 80.0: flat names route to their group
```
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Annotated, Any, ClassVar

from pydantic import BaseModel, BeforeValidator, Field

from arcube.errors import InputError
from arcube.model.body import BodyRadii
from arcube.validation import Settings, renamed_keyword, settings_error, validated  # noqa: F401 (the base of every settings group, used from here)

__all__ = [
    "Body",
    "FLAT",
    "GUARDED_OPTIONS",
    "Guards",
    "Loads",
    "Masses",
    "Options",
    "Outputs",
    "Settings",
    "request_options",
    "route_flat",
    "settings_error",
    "validated",
]


def _five(value: Any, limit: float, unit: str) -> tuple[float, ...]:
    """One number or five (one per actuator: rho_x, rho_y, rho_z, delta_x, delta_y) -> a 5-tuple, each in
    (0, ``limit``]."""
    what = f"must be one or five finite numbers > 0 and <= {limit:g} {unit}"
    if isinstance(value, (str, bytes)):
        raise ValueError(what)
    items = list(value) if isinstance(value, Sequence) or hasattr(value, "__len__") else [value]
    if len(items) not in (1, 5):
        raise ValueError(f"{what} (got {len(items)} numbers)")
    try:
        numbers = [float(v) for v in items]
    except (TypeError, ValueError):
        raise ValueError(what) from None
    if not all(math.isfinite(v) and 0.0 < v <= limit for v in numbers):
        raise ValueError(what)
    return tuple(numbers * 5 if len(numbers) == 1 else numbers)


def per_actuator(limit: float, unit: str) -> Any:
    """Five positive finite numbers up to ``limit`` (``unit``), one per actuator; one number means the same for all
    five."""
    return Annotated[tuple[float, float, float, float, float], BeforeValidator(lambda v: _five(v, limit, unit))]


MAX_ENCODER_DEG = 10.0
"""Largest encoder error bound, deg: beyond it the actuator is not positioned at all."""
MAX_STIFFNESS = 1e9
"""Largest actuator stiffness, N·m/rad: at 1e9 a 100 N·m torque deflects 1e-7 rad; more is a rigid actuator or a typo."""
EncoderDeg = per_actuator(MAX_ENCODER_DEG, "deg")
"""Five encoder error bounds in (0, 10] deg."""
Stiffness = per_actuator(MAX_STIFFNESS, "N m/rad")
"""Five actuator stiffnesses in (0, 1e9] N·m/rad."""

MAX_BODY_MM = 1000.0
"""Largest clearance, radius or length of the body, mm: a metre is beyond any part of the robot (1e9 is a typo)."""
Mm = Annotated[float, Field(ge=0, le=MAX_BODY_MM, allow_inf_nan=False)]
PositiveMm = Annotated[float, Field(gt=0, le=MAX_BODY_MM, allow_inf_nan=False)]


class Guards(Settings):
    """Reachability guards: model §8.2 ([ADDITION]), the clearances of 14.3 and the envelope of 19.5. All off by default."""

    SHORT: ClassVar[dict[str, str]] = {
        "clearance_mm": "clearance",
        "self_clearance_mm": "self_clearance",
        "envelope_clearance_mm": "envelope_clearance",
    }

    z_dyad: bool = False
    """Check the z-leg dyad closure (model §6)."""
    c_z: float | None = Field(default=None, gt=0, allow_inf_nan=False)
    """Second link of the z dyad (mm) for the guard of model §6 on a design vector that has none of its own; None means c_z = d_z. A design's own c_z (``Design.c_z``, model §19.1) is c_z's home: every command and run sets it there (``--c-z``), and an evaluation of a design takes it from there."""
    rho_max_deg: float | None = Field(default=None, gt=0, le=90)
    """|rho_u| <= rho_max (deg), away from the TLS singularity cos rho = 0."""
    min_transmission_deg: float | None = Field(default=None, gt=0, le=90)
    """|sin| of the four transmission angles (s_F, s_H, s_AS, s_AP) >= sin(this)."""
    kappa_max: float | None = Field(default=None, ge=1, allow_inf_nan=False)
    """eta_L <= kappa_max."""
    single_assembly_mode: bool = False
    """sign H_x, sign H_y, sign det[x_b, y_b, e] equal at all task points (global)."""
    clearance_mm: Mm | None = None
    """Guard: clearance to the anatomy >= this (mm); failure ``collision/patient`` (model §14.3)."""
    self_clearance_mm: Mm | None = None
    """Guard: clearance between the robot's own parts >= this (mm); failure ``collision/self``."""
    envelope_clearance_mm: Mm | None = None
    """Guard: clearance to the envelope of the whole patient and the table >= this (mm); failure ``collision/envelope``
    (model §19.5; 10 mm is the design requirement's default)."""


_RADII = BodyRadii()
"""model §14.1's default radii (mm), written once in the model layer."""


class Body(Settings):
    """Radii of the robot's body (model §14.1), mm."""

    link_radius: PositiveMm = _RADII.link
    """Radius of the links (model §14.1), mm."""
    actuator_radius: PositiveMm = _RADII.actuator
    """Radius of the actuators at P_u and D_u, mm."""
    motor_radius: PositiveMm = _RADII.motor
    """Radius of the drill motor, mm."""
    motor_length: PositiveMm = _RADII.motor_length
    """Length L_m of the drill motor beyond the holder H, mm."""

    @property
    def radii(self) -> BodyRadii:
        """The plain-value form the model layer takes."""
        return BodyRadii(self.link_radius, self.actuator_radius, self.motor_radius, self.motor_length)


class Loads(Settings):
    """Encoder resolution, drilling loads and actuator stiffness of model §15."""

    SHORT: ClassVar[dict[str, str]] = {"thrust_N": "thrust", "lateral_force_N": "lateral_force"}

    encoder_deg: EncoderDeg = (0.01,) * 5
    """Position error bound of the actuators (model §15.2), deg: one value, or five (rho_x,rho_y,rho_z,delta_x,delta_y)."""
    thrust_N: float = Field(default=30.0, ge=0, le=1e5, allow_inf_nan=False)
    """Drilling thrust along the drill axis (model §15.3), N (at most 1e5: ten tonnes-force, beyond any drill)."""
    lateral_force_N: float = Field(default=10.0, ge=0, le=1e5, allow_inf_nan=False)
    """Largest lateral (skiving) force across the drill axis (model §15.3), N (at most 1e5)."""
    actuator_stiffness: Stiffness = (1e4,) * 5
    """Torsional stiffness of the actuators (model §15.4), N·m/rad: one value or five."""


def _gravity(value: Any) -> tuple[float, float, float]:
    """Three finite numbers (m/s^2, patient frame), as a sequence or ``"0,0,-9.81"``."""
    items = value.split(",") if isinstance(value, str) else value
    try:
        g = tuple(float(v) for v in items)
    except (TypeError, ValueError):
        raise ValueError("must be three numbers (m/s^2, patient frame), e.g. 0,0,-9.81") from None
    if len(g) != 3 or not all(math.isfinite(v) for v in g):
        raise ValueError("must be three finite numbers (m/s^2, patient frame), e.g. 0,0,-9.81")
    if math.hypot(*g) > MAX_GRAVITY:
        raise ValueError(f"must be at most {MAX_GRAVITY:g} m/s^2 in magnitude (a centrifuge's, not a typo of mm/s^2)")
    return g  # type: ignore[return-value]


MAX_GRAVITY = 1000.0
"""m/s^2: the largest gravity :class:`Masses` takes (100 g), so that torques stay finite."""


class Masses(Settings):
    """The mass model of model §18.1: thin-walled aluminium tubes as links, the delta actuators
    riding on the cranks, the drill motor; gravity in the patient frame (prone: posterior up)."""

    SHORT: ClassVar[dict[str, str]] = {
        "wall_mm": "wall",
        "density_kg_m3": "density",
        "m_delta_kg": "m_delta",
        "m_motor_kg": "m_motor",
    }

    wall_mm: float = Field(default=2.0, gt=0, le=1000.0, allow_inf_nan=False)
    """Wall of the links' tubes (model §18.1), mm; < the link radius where the mass model is used."""
    density_kg_m3: float = Field(default=2700.0, gt=0, le=1e5, allow_inf_nan=False)
    """Density of the links' material, kg/m^3 (aluminium)."""
    m_delta_kg: float = Field(default=0.8, ge=0, le=1e4, allow_inf_nan=False)
    """Mass of each delta actuator (riding at D_x, D_y), kg."""
    m_motor_kg: float = Field(default=1.5, ge=0, le=1e4, allow_inf_nan=False)
    """Mass of the drill motor (a solid cylinder from H to H + L_m e), kg."""
    gravity: Annotated[tuple[float, float, float], BeforeValidator(_gravity)] = (0.0, 0.0, -9.81)
    """Gravity in the patient frame, m/s^2, three numbers (prone: posterior up)."""


class Outputs(Settings):
    """What an evaluation computes beyond what its guards need (requests to the engine, not model)."""

    clearances: bool = False
    """Every body clearance at every point, even with no clearance guard on: to the anatomy and between the
    robot's parts (model §14.3), and to the envelope of the whole patient when there is one (19.5)."""
    anatomy_clearance: bool = False
    """The clearance to the anatomy (when there is one) even without its guard (an optimizer objective)."""
    envelope_clearance: bool = False
    """The clearance to the envelope of the whole patient (when there is one, model §19.5) even without its
    guard (an optimizer objective or limit)."""
    clearance_min_exact: bool = True
    """With a clearance guard, whether summary-only kernel runs find the exact smallest clearance
    (False: they only decide the guard and its shortfall, and report the limit as the smallest
    clearance when every point clears it; what an optimizer that does not optimize it needs)."""
    tip_metrics: bool = True
    """The drill-tip metrics of model §15 (NaN when off: an optimizer that does not need them)."""
    holding_torque: bool = False
    """With ``tip_metrics``, also the holding torque of model §18.2 at each point, from :class:`Masses`
    (off by default: every earlier result stays as it was, and thin links need no valid mass model)."""


_GROUPS: dict[str, type[Settings]] = {
    "guards": Guards,
    "body": Body,
    "loads": Loads,
    "masses": Masses,
    "outputs": Outputs,
}
_LEGACY = {"body": ("outputs", "clearances"), "want_clearance": ("outputs", "anatomy_clearance")}
"""Flat keywords of the former single ``Options`` whose names changed with the groups."""
FLAT: dict[str, tuple[str, str]] = {
    **{name: (group, name) for group, cls in _GROUPS.items() for name in cls.model_fields},
    **{cls.short(name): (group, name) for group, cls in _GROUPS.items() for name in cls.SHORT},
    **_LEGACY,
}
"""Each flat keyword -> (group, field): a field's name or short name (``Options(thrust_N=25)``,
``Options(thrust=25)`` and ``arcube.optimize(..., thrust=25)`` mean ``Options(loads=Loads(thrust_N=25))``)."""


def _shared_names() -> dict[str, list[str]]:
    meanings: dict[str, list[str]] = {}
    for group, cls in _GROUPS.items():
        for name in (*cls.model_fields, *(cls.short(n) for n in cls.SHORT)):
            meanings.setdefault(name, []).append(f"{group}.{cls.field_of(name)}")
    return {name: where for name, where in meanings.items() if len(where) > 1}


AMBIGUOUS: dict[str, list[str]] = _shared_names()
"""Flat keywords that two groups share (a field of one, a short name of another): refused, naming both, never guessed."""


def route_flat(data: dict[str, Any], options: Any = None) -> dict[str, Any]:
    """The groups of :class:`Options` (as dicts) with the flat keywords of ``data`` routed into them,
    on top of ``options`` (an :class:`Options`, a dict of groups, or None). ``data`` keeps the rest."""
    base = options.model_dump() if isinstance(options, BaseModel) else dict(options or {})
    out = {
        k: (v.model_dump() if isinstance(v, BaseModel) else dict(v)) if isinstance(v, (BaseModel, dict)) else v
        for k, v in base.items()
    }
    for key in [k for k in data if k in FLAT and not (k == "body" and not isinstance(data[k], bool))]:
        if key in AMBIGUOUS:
            ways = " or ".join(
                f"Options({g}={_GROUPS[g].__name__}({f}=...))" for g, f in (a.split(".") for a in AMBIGUOUS[key])
            )
            raise InputError.of(
                key, f"names two settings, {' and '.join(AMBIGUOUS[key])}: give the one meant by its group, {ways}"
            )
        group, name = FLAT[key]
        current = out.get(group, {})
        out[group] = {**(current if isinstance(current, dict) else dict(current)), name: data.pop(key)}
    return out


class Options(Settings):
    """Everything that decides one evaluation: guards, body, loads, and what to compute.

    Flat keywords are still accepted and routed to their group (``Options(kappa_max=100)``,
    ``Options(body=True)`` for ``outputs.clearances``).
    """

    guards: Guards = Guards()
    """The guards of model §8.2 and the clearance limits of 14.3 and 19.5."""
    body: Body = Body()
    """The robot's body: link and joint radii of model §14.1."""
    loads: Loads = Loads()
    """The drilling loads of model §15.3."""
    masses: Masses = Masses()
    """The masses of model §18.1."""
    outputs: Outputs = Outputs()
    """What to compute beyond what the guards need."""

    @classmethod
    def prepare(cls, data: dict[str, Any]) -> dict[str, Any]:
        """Flat names (``thrust``, ``clearance``) routed into their groups (:func:`route_flat`)."""
        rest = data
        groups = {
            k: rest.pop(k) for k in list(rest) if k in _GROUPS and not (k == "body" and isinstance(rest[k], bool))
        }
        return {**route_flat(rest, groups), **rest}  # what is left is refused by extra="forbid", with its own name

    @property
    def radii(self) -> BodyRadii:
        """The body radii of model §14.1."""
        return self.body.radii

    def flat(self) -> dict[str, Any]:
        """Every field under its flat name (``thrust_N``, ``body`` for ``outputs.clearances``): the
        ``guards`` object of ``arcube evaluate --json``, as it always was."""
        legacy = {field: key for key, (_, field) in _LEGACY.items()}
        out: dict[str, Any] = {}
        for group in _GROUPS:
            for name, value in getattr(self, group).model_dump().items():
                out[legacy.get(name, name)] = list(value) if isinstance(value, tuple) else value
        return out

    def check_masses(self) -> Options:
        """``self``, once the links' wall (``Masses.wall_mm``) is checked thinner than their radius
        (``Body.link_radius``), which the mass model of model §18.1 needs; else InputError naming the wall."""
        wall, radius = self.masses.wall_mm, self.body.link_radius
        if not wall < radius:
            raise InputError.of("Masses.wall_mm", f"must be < the link radius ({radius:g} mm), got {wall:g}")
        return self

    def mass_model_on(self, asked: bool | None = None) -> bool:
        """Whether the mass model of model §18.1 applies, checked (:meth:`check_masses`) when it does.

        ``asked``: True (required), False (no masses: no torques, a massless export), or None: the mass
        model unless the masses are the defaults and the links are too thin for the default wall (then
        none, rather than an error about a wall the caller never gave)."""
        if asked is False:
            return False
        if asked is None and self.masses == Masses() and self.body.link_radius <= self.masses.wall_mm:
            return False
        self.check_masses()
        return True

    def _wants(self, asked: bool, limit: float | None) -> bool:
        # a clearance is computed when every clearance is asked for, when this one is, or when a guard limits it
        return self.outputs.clearances or asked or limit is not None

    @property
    def wants_clearance(self) -> bool:
        """Whether the evaluation computes the clearance to the anatomy (when there is one)."""
        return self._wants(self.outputs.anatomy_clearance, self.guards.clearance_mm)

    @property
    def wants_self_clearance(self) -> bool:
        """Whether the evaluation computes the clearance between the body's own parts."""
        return self._wants(False, self.guards.self_clearance_mm)

    @property
    def wants_envelope_clearance(self) -> bool:
        """Whether the evaluation computes the clearance to the envelope (when there is one, model §19.5)."""
        return self._wants(self.outputs.envelope_clearance, self.guards.envelope_clearance_mm)

    @property
    def wants_body(self) -> bool:
        """Whether the evaluation computes the body at all."""
        return self.wants_clearance or self.wants_self_clearance or self.wants_envelope_clearance


GUARDED_OPTIONS = Options(
    guards=Guards(rho_max_deg=75.0, min_transmission_deg=20.0, kappa_max=100.0, single_assembly_mode=True)
)
"""The guards of model §8.2 but z_dyad (``guarded=True`` in the API, ``--guarded``)."""


def request_options(options: Options | None = None, guarded: bool = False, **changes: Any) -> Options:
    """The options of one request (an evaluation, a program, an export, the explorer): ``options``
    (else the paper's, with the guards of model §8.2 when ``guarded``), changed by flat keywords
    (a field's name or short name: ``thrust=25``, ``link_radius=6``, ``clearance=5``)."""
    if options is not None and not isinstance(options, Options):
        raise InputError.of("options", f"must be an arcube.Options, got {type(options).__name__}")
    guarded = renamed_keyword(changes, "guards", "guarded", guarded, False)  # its name before 0.3
    base = options if options is not None else (GUARDED_OPTIONS if guarded else Options())
    unknown = [k for k in changes if k not in FLAT]
    if unknown:
        raise InputError.of(unknown[0], f"is not a setting (settings: {', '.join(sorted(FLAT))})")
    return base.replace(**changes) if changes else base
