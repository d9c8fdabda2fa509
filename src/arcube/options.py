"""What the model is: the settings of one evaluation, as small validated groups.

:class:`Options` is made of four groups, each a frozen pydantic model whose ``Field`` constraints
are the only checks of its values:

* :class:`Guards`: the guards of MODEL.md 8.2, 14.3 and 19.5 (all off by default);
* :class:`Body`: the radii of the robot's body (MODEL.md 14.1);
* :class:`Loads`: the encoder resolution, drilling loads and actuator stiffness (MODEL.md 15);
* :class:`Masses`: the links' tubes, the actuators' and drill motor's masses, gravity (MODEL.md 18.1);
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
from typing import Annotated, Any

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, ValidationError, model_validator

from arcube.errors import InputError
from arcube.model.body import BodyRadii

__all__ = ["Body", "GUARDED_OPTIONS", "Guards", "Loads", "Masses", "Options", "Outputs", "Settings", "settings_error", "validated"]


class Settings(BaseModel):
    """Base of every settings group: frozen, unknown keys refused, defaults validated."""

    model_config = ConfigDict(frozen=True, extra="forbid", validate_default=True)

    def __init__(self, /, **data: Any) -> None:
        try:
            super().__init__(**data)
        except ValidationError as exc:
            raise settings_error(exc, type(self)) from None

    def replace(self, **changes: Any) -> Any:
        """A validated copy with ``changes`` (InputError naming the field on a bad value)."""
        data = self.model_dump()
        for key, value in changes.items():
            data[key] = value.model_dump() if isinstance(value, BaseModel) else value
        return validated(type(self), data)


def _five(value: Any) -> tuple[float, ...]:
    """One number or five (one per actuator: rho_x, rho_y, rho_z, delta_x, delta_y) -> a 5-tuple."""
    if isinstance(value, (str, bytes)):
        raise ValueError("must be one or five finite numbers > 0")
    items = list(value) if isinstance(value, Sequence) or hasattr(value, "__len__") else [value]
    if len(items) not in (1, 5):
        raise ValueError(f"must be one or five finite numbers > 0 (got {len(items)} numbers)")
    try:
        numbers = [float(v) for v in items]
    except (TypeError, ValueError):
        raise ValueError("must be one or five finite numbers > 0") from None
    if not all(math.isfinite(v) and v > 0.0 for v in numbers):
        raise ValueError("must be one or five finite numbers > 0")
    return tuple(numbers * 5 if len(numbers) == 1 else numbers)


PerActuator = Annotated[tuple[float, float, float, float, float], BeforeValidator(_five)]
"""Five positive finite numbers, one per actuator; one number means the same for all five."""

Mm = Annotated[float, Field(ge=0, allow_inf_nan=False)]
PositiveMm = Annotated[float, Field(gt=0, allow_inf_nan=False)]


class Guards(Settings):
    """Reachability guards: MODEL.md 8.2 ([ADDITION]), the clearances of 14.3 and the envelope of 19.5. All off by default."""

    z_dyad: bool = False
    """Check the z-leg dyad closure (MODEL.md 6)."""
    c_z: float | None = Field(default=None, gt=0, allow_inf_nan=False)
    """Second link of the z dyad (mm); None means c_z = d_z."""
    rho_max_deg: float | None = Field(default=None, gt=0, le=90)
    """|rho_u| <= rho_max (deg), away from the TLS singularity cos rho = 0."""
    min_transmission_deg: float | None = Field(default=None, gt=0, le=90)
    """|sin| of the four transmission angles (s_F, s_H, s_AS, s_AP) >= sin(this)."""
    kappa_max: float | None = Field(default=None, ge=1, allow_inf_nan=False)
    """eta_L <= kappa_max."""
    single_assembly_mode: bool = False
    """sign H_x, sign H_y, sign det[x_b, y_b, e] equal at all task points (global)."""
    clearance_mm: Mm | None = None
    """Clearance to the anatomy >= this (mm); failure ``collision/patient`` (MODEL.md 14.3)."""
    self_clearance_mm: Mm | None = None
    """Clearance between the robot's own parts >= this (mm); failure ``collision/self``."""
    envelope_clearance_mm: Mm | None = None
    """Clearance to the envelope of the whole patient and the table >= this (mm); failure ``collision/envelope``
    (MODEL.md 19.5; 10 mm is the design requirement's default)."""


class Body(Settings):
    """Radii of the robot's body (MODEL.md 14.1), mm."""

    link_radius: PositiveMm = 8.0
    """Radius of every link."""
    actuator_radius: PositiveMm = 25.0
    """Radius of the actuators at P_u and D_u."""
    motor_radius: PositiveMm = 20.0
    """Radius of the drill motor."""
    motor_length: PositiveMm = 120.0
    """Length L_m of the drill motor beyond the holder H."""

    @property
    def radii(self) -> BodyRadii:
        """The plain-value form the model layer takes."""
        return BodyRadii(self.link_radius, self.actuator_radius, self.motor_radius, self.motor_length)


class Loads(Settings):
    """Encoder resolution, drilling loads and actuator stiffness of MODEL.md 15."""

    encoder_deg: PerActuator = (0.01,) * 5
    """Position error bound of each actuator (15.2), deg."""
    thrust_N: float = Field(default=30.0, ge=0, allow_inf_nan=False)
    """Drilling thrust along e (15.3), N."""
    lateral_force_N: float = Field(default=10.0, ge=0, allow_inf_nan=False)
    """Largest lateral (skiving) force across e (15.3), N."""
    actuator_stiffness: PerActuator = (1e4,) * 5
    """Torsional stiffness of each actuator (15.4), N·m/rad."""


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
    """The mass model of MODEL.md 18.1: thin-walled aluminium tubes as links, the delta actuators
    riding on the cranks, the drill motor; gravity in the patient frame (prone: posterior up)."""

    wall_mm: float = Field(default=2.0, gt=0, le=1000.0, allow_inf_nan=False)
    """Wall thickness w of every moving link's tube (outer radius: Body.link_radius), mm; checked to be
    < Body.link_radius where the mass model is used (:class:`arcube.evaluation.bodies.MassModel`),
    so that thin links without masses stay valid."""
    density_kg_m3: float = Field(default=2700.0, gt=0, le=1e5, allow_inf_nan=False)
    """Density of the links' material, kg/m^3 (aluminium)."""
    m_delta_kg: float = Field(default=0.8, ge=0, le=1e4, allow_inf_nan=False)
    """Mass of each delta actuator at D_u (u = x, y), kg."""
    m_motor_kg: float = Field(default=1.5, ge=0, le=1e4, allow_inf_nan=False)
    """Mass of the drill motor (a solid cylinder from H to H + L_m e, radius Body.motor_radius), kg."""
    gravity: Annotated[tuple[float, float, float], BeforeValidator(_gravity)] = (0.0, 0.0, -9.81)
    """Gravity, m/s^2, patient frame."""


class Outputs(Settings):
    """What an evaluation computes beyond what its guards need (requests to the engine, not model)."""

    clearances: bool = False
    """Every body clearance at every point, even with no clearance guard on: to the anatomy and between the
    robot's parts (MODEL.md 14.3), and to the envelope of the whole patient when there is one (19.5)."""
    anatomy_clearance: bool = False
    """The clearance to the anatomy (when there is one) even without its guard (an optimizer objective)."""
    envelope_clearance: bool = False
    """The clearance to the envelope of the whole patient (when there is one, MODEL.md 19.5) even without its
    guard (an optimizer objective or limit)."""
    clearance_min_exact: bool = True
    """With a clearance guard, whether summary-only kernel runs find the exact smallest clearance
    (False: they only decide the guard and its shortfall, and report the limit as the smallest
    clearance when every point clears it; what an optimizer that does not optimize it needs)."""
    tip_metrics: bool = True
    """The drill-tip metrics of MODEL.md 15 (NaN when off: an optimizer that does not need them)."""
    holding_torque: bool = False
    """With ``tip_metrics``, also the holding torque of MODEL.md 18.2 at each point, from :class:`Masses`
    (off by default: every earlier result stays as it was, and thin links need no valid mass model)."""


_GROUPS: dict[str, type[Settings]] = {"guards": Guards, "body": Body, "loads": Loads, "masses": Masses, "outputs": Outputs}
_LEGACY = {"body": ("outputs", "clearances"), "want_clearance": ("outputs", "anatomy_clearance")}
"""Flat keywords of the former single ``Options`` whose names changed with the groups."""
FLAT: dict[str, tuple[str, str]] = {
    **{name: (group, name) for group, cls in _GROUPS.items() for name in cls.model_fields}, **_LEGACY,
}  # fmt: skip
"""Each flat keyword -> (group, field): ``Options(thrust_N=25)`` means ``Options(loads=Loads(thrust_N=25))``."""


class Options(Settings):
    """Everything that decides one evaluation: guards, body, loads, and what to compute.

    Flat keywords are still accepted and routed to their group (``Options(kappa_max=100)``,
    ``Options(body=True)`` for ``outputs.clearances``).
    """

    guards: Guards = Guards()
    body: Body = Body()
    loads: Loads = Loads()
    masses: Masses = Masses()
    outputs: Outputs = Outputs()

    @model_validator(mode="before")
    @classmethod
    def _route_flat(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        out: dict[str, Any] = {}
        flat: list[tuple[str, str, Any]] = []
        for key, value in data.items():
            if key in _GROUPS and not (key == "body" and isinstance(value, bool)):
                out[key] = value.model_dump() if isinstance(value, BaseModel) else value
            elif key in FLAT:
                flat.append((*FLAT[key], value))
            else:
                out[key] = value  # refused by extra="forbid", with its own name
        for group, name, value in flat:
            current = out.get(group, {})
            out[group] = {**(current if isinstance(current, dict) else dict(current)), name: value}
        return out

    @property
    def radii(self) -> BodyRadii:
        """The body radii of MODEL.md 14.1."""
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
        (``Body.link_radius``), which the mass model of MODEL.md 18.1 needs; else InputError naming the wall."""
        wall, radius = self.masses.wall_mm, self.body.link_radius
        if not wall < radius:
            raise InputError.of("Masses.wall_mm", f"must be < the link radius ({radius:g} mm), got {wall:g}")
        return self

    @property
    def wants_clearance(self) -> bool:
        """Whether the evaluation computes the clearance to the anatomy (when there is one)."""
        o = self.outputs
        return o.clearances or o.anatomy_clearance or self.guards.clearance_mm is not None

    @property
    def wants_self_clearance(self) -> bool:
        """Whether the evaluation computes the clearance between the body's own parts."""
        return self.outputs.clearances or self.guards.self_clearance_mm is not None

    @property
    def wants_envelope_clearance(self) -> bool:
        """Whether the evaluation computes the clearance to the envelope (when there is one, MODEL.md 19.5)."""
        o = self.outputs
        return o.clearances or o.envelope_clearance or self.guards.envelope_clearance_mm is not None

    @property
    def wants_body(self) -> bool:
        """Whether the evaluation computes the body at all."""
        return self.wants_clearance or self.wants_self_clearance or self.wants_envelope_clearance


GUARDED_OPTIONS = Options(guards=Guards(rho_max_deg=75.0, min_transmission_deg=20.0, kappa_max=100.0, single_assembly_mode=True))
"""The guards of MODEL.md 8.2 but z_dyad (``guards=True`` in the API)."""


def _param(model: type[BaseModel], loc: tuple[Any, ...]) -> str:
    """``Loads.thrust_N`` for the location ``("loads", "thrust_N")`` in ``Options``: the innermost
    model's name and the field, as a caller writes them."""
    cls: Any = model
    for i, item in enumerate(loc):
        field = cls.model_fields.get(item) if isinstance(item, str) and isinstance(cls, type) and issubclass(cls, BaseModel) else None
        if field is None:
            break
        sub = field.annotation
        if isinstance(sub, type) and issubclass(sub, BaseModel) and i + 1 < len(loc):
            cls = sub
            continue
        return f"{cls.__name__}.{item}"
    return f"{cls.__name__}.{'.'.join(str(x) for x in loc)}" if loc else cls.__name__


_PHRASES = {
    "greater_than_equal": "must be >= {ge}", "greater_than": "must be > {gt}", "less_than_equal": "must be <= {le}",
    "less_than": "must be < {lt}", "finite_number": "must be a finite number", "extra_forbidden": "is not a setting",
    "bool_parsing": "must be true or false", "bool_type": "must be true or false", "float_parsing": "must be a number",
    "float_type": "must be a number", "int_parsing": "must be an integer", "int_type": "must be an integer",
    "int_from_float": "must be an integer", "missing": "is required",
}  # fmt: skip


def settings_error(exc: ValidationError, model: type[BaseModel]) -> InputError:
    """The first problem of a pydantic ``ValidationError`` as one line naming the field."""
    err = exc.errors(include_url=False)[0]
    inner = (err.get("ctx") or {}).get("error")
    if isinstance(inner, InputError):  # a nested group's own __init__ already named its field
        return inner
    loc = tuple(x for x in err["loc"] if not (isinstance(x, str) and x.startswith("function-")))
    # A per-actuator tuple reports (field, index): name the field, not the slot.
    while loc and isinstance(loc[-1], int):
        loc = loc[:-1]
    param = _param(model, loc)
    phrase = _PHRASES.get(err["type"])
    if err["type"] == "literal_error":
        text = "must be one of " + str((err.get("ctx") or {}).get("expected", "")).replace("'", "").replace(" or ", ", ")
    elif phrase is not None:
        text = phrase.format(**{k: (f"{v:g}" if isinstance(v, (int, float)) else v) for k, v in (err.get("ctx") or {}).items()})
    else:
        text = str(err["msg"]).removeprefix("Value error, ")
        text = text if text.startswith(("must", "is ")) else f"is invalid: {text}"
    if err["type"] != "extra_forbidden" and "input" in err:
        text += f", got {err['input']!r}"
    return InputError(f"{param} {text}", param=param)


def validated(model: type[Any], data: Any = None, /, **fields: Any) -> Any:
    """``model(**data, **fields)`` validated; a bad value -> :class:`InputError` naming the field."""
    try:
        return model.model_validate({**(data or {}), **fields})
    except ValidationError as exc:  # model_validate does not pass through Settings.__init__
        raise settings_error(exc, model) from None
