"""A simulated robot built to a tolerance class, measured at given poses: :func:`simulate`; and what a
controller's model makes a robot drill: :func:`tip_errors`.

The robot: the design's parameters plus deviations dp and its zero offsets plus dq0, drawn once
(:func:`arcube.accuracy.monte_carlo.robot_draws`, ISO 2768-1 class ``tolerance_class``, model §20.1),
seeded. At each pose of the poses file the encoders read q_cmd (the file's joint angles), the real
joints are q_cmd + q0 + dq0 (q0: a calibrated design's zero offsets, else 0), and the tool is at
FK_{p+dp}(q) in the robot's assembly mode (:func:`arcube.calibrate.model.robot_assembly`: the one
whose nominal FK at the file's joint angles is nearest the file's nominal poses; :func:`poses` chooses
them all in one). Then the tracker: E plus normal noise sigma_E on each axis, e plus normal noise sigma_e
(radians) on each axis, renormalised (to first order, an angle error of sigma_e about each of the two
directions perpendicular to e). The generator draws the robot first, then the noise.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arcube.model.modes import DEFAULT_MODE_TEXT
from arcube.accuracy.monte_carlo import robot_draws, split
from arcube.accuracy.settings import ToleranceSettings
from arcube.calibrate.design_file import StartDesign, calibrated_dict, design_digest, load_design
from arcube.calibrate.measurements import Measurements, measurements_csv, read_measurements
from arcube.calibrate.model import robot_assembly, unknown_values
from arcube.calibrate.settings import SimulateSettings
from arcube.errors import InputError
from arcube.model.mechanism import forward_kinematics, inverse_kinematics


@dataclass(frozen=True)
class Simulation:
    """A simulated robot and its measurements."""

    measurements: Measurements  # the measured poses (the rows the robot assembles at)
    design: NDArray[np.float64]  # (27,) the real robot's parameters (mm, deg)
    q0_deg: NDArray[np.float64]  # (5,) its real zero offsets, deg
    nominal: StartDesign  # the design it was built to
    assembly: NDArray[np.float64]  # (N, 3) assembly mode of each measured pose
    dropped: tuple[int, ...]  # rows of the poses file where the built robot does not assemble (not measured)
    settings: SimulateSettings

    @property
    def deviations(self) -> NDArray[np.float64]:
        """``(31,)`` the real values minus the nominal ones of the unknowns of :mod:`arcube.calibrate.model` (mm, deg)."""
        return unknown_values(self.design, self.q0_deg) - unknown_values(self.nominal.vector, self.nominal.q0_deg)


def simulate(
    design: Any,
    poses: Measurements | str | os.PathLike[str],
    settings: SimulateSettings | None = None,
    out: str | os.PathLike[str] | None = None,
) -> Simulation:
    """Build a robot to ``settings.tolerance_class`` and measure it at the poses (module doc).

    Args:
        design: the nominal design (Design, preset, design JSON plain or calibrated, 27 numbers).
        poses: a poses file (:func:`arcube.calibrate.poses`'s CSV, or any file in the measurement columns) or
            :class:`Measurements`. A file whose ``design`` column names another design is refused.
        settings: :class:`SimulateSettings`.
        out: if given, the measurement CSV written (atomically).

    Raises:
        InputError: a bad or foreign poses file, joint angles the design cannot take, or a robot that
            assembles at none of the poses.
    """
    settings = SimulateSettings() if settings is None else settings
    start = load_design(design)
    m = poses if isinstance(poses, Measurements) else read_measurements(poses)
    x = start.vector
    digest = design_digest(x, start.q0_deg)
    if m.design is not None and m.design != digest:
        raise InputError(
            f"{m.source}: the poses were chosen for another design (digest {m.design}, this design's is {digest}); "
            "choose poses for this design (calibrate poses)"
        )
    asm = robot_assembly(x, start.q0_deg, (m.q_deg, m.E, m.e), 0.15, np.deg2rad(0.1), m.where)
    tol = ToleranceSettings(
        tolerance_class=settings.tolerance_class,
        q0_deg=settings.q0_deg,
        docking_mm=settings.docking_mm,
        docking_deg=settings.docking_deg,
        distribution=settings.distribution,
    )
    rng = np.random.default_rng(settings.seed)
    dp, dq0 = split(robot_draws(rng, tol.tolerances(x), 1, settings.distribution)[0])
    x_real = x + dp
    q0_real = start.q0_deg + np.rad2deg(dq0)
    q = np.deg2rad(m.q_deg + q0_real)
    with np.errstate(invalid="ignore", divide="ignore"):
        fk = forward_kinematics(x_real, q[:, :3], q[:, 3:], asm)
    good = fk.valid & np.all(np.isfinite(fk.E), axis=1) & np.all(np.isfinite(fk.e), axis=1)
    if not good.any():
        raise InputError(f"{m.source}: the simulated robot (seed {settings.seed}) assembles at none of the poses")
    n = int(good.sum())
    E = fk.E[good] + rng.normal(0.0, 1.0, (n, 3)) * settings.sigma_mm
    e = fk.e[good] + rng.normal(0.0, 1.0, (n, 3)) * np.deg2rad(settings.sigma_deg)
    e = e / np.linalg.norm(e, axis=1, keepdims=True)
    keep = np.flatnonzero(good)
    taken = m.take(keep)
    meas = Measurements(
        taken.q_deg,
        E,
        e,
        taken.pose,
        m.design,
        f"simulated robot (class {settings.tolerance_class}, seed {settings.seed})",
        None,
    )
    dropped = tuple(int(m.rows[i]) if m.rows else i + 1 for i in np.flatnonzero(~good))
    if out is not None:  # the measurements and, beside them, the robot they were taken on (a rehearsal's ground truth)
        from arcube.io.files import atomic_write_files

        truth = calibrated_dict(x_real, q0_real, start.mode or DEFAULT_MODE_TEXT, start.c_z)
        atomic_write_files(
            {out: measurements_csv(meas).encode(), truth_path(out): (json.dumps(truth, indent=2) + "\n").encode()}
        )
    return Simulation(meas, x_real, q0_real, start, asm[good], dropped, settings)


def truth_path(measurements: str | os.PathLike[str]) -> Path:
    """Where :func:`simulate` writes the simulated robot's true design beside its measurements: ``<stem>.truth.json``
    (a calibrated design file: the 27 parameters and q0_* it was built with; ``arcube evaluate --design`` reads it)."""
    p = Path(measurements)
    return p.with_name(p.stem + ".truth.json")


def tip_errors(
    real_design: ArrayLike,
    real_q0_deg: ArrayLike,
    model_design: ArrayLike,
    model_q0_deg: ArrayLike,
    E: ArrayLike,
    e: ArrayLike,
    mode: ArrayLike,
) -> dict[str, NDArray[np.float64]]:
    """What a controller that believes (model_design, model_q0) makes the real robot (real_design, real_q0) drill
    at the poses (E, e) ``(P, 3)``: it commands q_read = IK_model(X) - q0_model (working mode ``mode``); the real
    joints are q_read + q0_real; the tool is at FK_real(q) in the assembly mode of the model's IK.

    Returns ``lateral_mm`` = |P_perp dE|, ``axial_mm`` = |e^T dE|, ``tip_mm`` = |dE| (dE = E_real - E) and
    ``axis_deg`` = angle(e_real, e), each ``(P,)``; NaN where the model's IK or the real FK has no solution."""
    E_a = np.asarray(E, dtype=float)
    e_a = np.asarray(e, dtype=float)
    e_a = e_a / np.linalg.norm(e_a, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        sol = inverse_kinematics(model_design, E_a, e_a, mode)
        q_read = np.rad2deg(np.concatenate([sol.rho, sol.delta], axis=-1)) - np.asarray(model_q0_deg, dtype=float)
        q = np.deg2rad(q_read + np.asarray(real_q0_deg, dtype=float))
        fk = forward_kinematics(real_design, q[:, :3], q[:, 3:], sol.assembly)
    ok = sol.reachable & fk.valid
    dE = fk.E - E_a
    along = np.sum(dE * e_a, axis=-1)
    lateral = np.linalg.norm(dE - along[:, None] * e_a, axis=-1)
    axis = np.rad2deg(np.arctan2(np.linalg.norm(np.cross(fk.e, e_a), axis=-1), np.sum(fk.e * e_a, axis=-1)))
    nan = np.nan
    return {
        "lateral_mm": np.where(ok, lateral, nan),
        "axial_mm": np.where(ok, np.abs(along), nan),
        "tip_mm": np.where(ok, np.linalg.norm(dE, axis=-1), nan),
        "axis_deg": np.where(ok, axis, nan),
    }
