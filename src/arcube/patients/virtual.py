"""Virtual patients: bilateral C3–C7 drilling trajectories from published morphometry.

Implements the construction of ``MORPHOMETRY.md`` section 4 (shared data folder) for the pedicle
technique (section 1) and the Roy-Camille, Magerl and An lateral-mass techniques (section 2),
and the step-6 sanity check. All lengths are mm, all user-facing angles degrees.

Frames: patient frame x = patient's right, y = superior, z = posterior, origin at the C5 body
centre. A vertebra frame has the same axes, sits at its body centre and is rotated about x by
the level's tilt φ: p_patient = c + R_x(φ) p_vertebra.

Choices where MORPHOMETRY.md gives no number (all marked in the code):
* a parameter without a published range (SIP, lateral-mass width, technique angles and
  lengths) is clipped at mean ± 3 SD, which only stops absurd tails;
* lateral-mass width SD 1.2 mm (the women/men difference is 1.3 mm, Schroeder et al.);
* Magerl cephalad SD per level = mean of the right and left SDs of PMC2219934 Table 2;
* the spino-laminar junction used by the check lies on the midline, 12.25 mm posterior to the
  body's posterior wall (calibrated: reproduces reference_patient_check.txt to 0.1 mm).
"""

from __future__ import annotations

import json
import math
import numbers
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from arcube.errors import InputError
from arcube.io.inputs import short_repr
from arcube.io.trajectories import TrajectorySet, atomic_write, write_csv
from arcube.patients.isthmus import LEVELS, draw_isthmus

__all__ = [
    "LEVELS",
    "TECHNIQUES",
    "PatientCheck",
    "build_patient",
    "check_patient",
    "draw_parameters",
    "format_check",
    "generate_patient",
    "level_frames",
    "write_patient",
]

TECHNIQUES = ("pedicle", "roy-camille", "magerl", "an")
_SIDES = (("R", 1.0), ("L", -1.0))  # side sign σ: +1 = patient's right (+x)


@dataclass(frozen=True)
class _Normal:
    """A normal draw clipped to [lo, hi]; lo/hi None → mean ∓ 3 SD (no published range)."""

    mean: float
    sd: float
    lo: float | None = None
    hi: float | None = None

    def bounds(self) -> tuple[float, float]:
        lo = self.mean - 3 * self.sd if self.lo is None else self.lo
        hi = self.mean + 3 * self.sd if self.hi is None else self.hi
        return lo, hi

    def clip(self, z: float) -> float:
        """Value for the standard-normal deviate ``z``."""
        lo, hi = self.bounds()
        return float(min(max(self.mean + self.sd * z, lo), hi))


# Section 1 table. Per-level means (C3..C7), SD, clip range.
LORDOSIS = _Normal(18.6, 10.0, -10.0, 45.0)  # C2–C7 posterior tangent, deg
BODY_HEIGHT = _Normal(12.5, 1.4, 9.0, 16.0)  # mm, every level
BODY_DEPTH = _Normal(16.5, 1.3, 12.0, 21.0)  # mm, every level
DISC_HEIGHT = _Normal(5.3, 1.0, 3.0, 8.0)  # mm, C3/4 .. C6/7
PEDICLE: dict[str, tuple[tuple[float, ...], float, float | None, float | None]] = {
    "TA_deg": ((47.0, 49.0, 46.0, 43.0, 39.0), 4.5, 25.0, 62.0),
    "SA_deg": ((8.0, 4.0, 0.0, -4.0, -3.0), 6.0, -25.0, 25.0),
    "PAL_mm": ((30.5, 31.5, 32.5, 33.5, 33.5), 2.5, 24.0, 42.0),
    "SIP_mm": ((1.87, 2.86, 3.85, 4.84, 5.83), 1.0, None, None),
    "XA_mm": ((0.0, 0.0, 0.0, 1.7, 1.7), 1.0, -3.0, 5.0),
}
RL_CORRELATION = 0.7
ANTERIOR_MARGIN_MM = 3.0  # drill stops short of the anterior cortex
MIN_TIP_MIDLINE_MM = 2.0  # tip kept this far from the midline
# Section 2. Lateral-mass centre from the pedicle entry (vertebra frame).
LM_WIDTH = _Normal(12.2, 1.2)  # Jian 2023 mean; SD assumed (see module docstring)
LM_ENTRY_TO_NOTCH_MM = 2.0  # C3–C6: pedicle entry 2 mm medial to the lateral notch
LM_C7_CENTRE_MEDIAL_MM = 1.6  # C7: pedicle entry 1.6 mm lateral to the centre
LM_CENTRE_BELOW_ENTRY_MM = 2.5  # every level: centre 2.5 mm below the pedicle entry
_FACET = (50.6, 44.9, 40.2, 42.8, 45.0)  # superior-facet angle, deg, C3..C7
_FACET_SD = (4.65, 5.4, 5.9, 4.9, 5.4)  # mean of right/left SDs, PMC2219934
# technique → (medial offset mm, cranial offset mm, lateral angle, per-level cephalad, length)
LATERAL_MASS: dict[str, tuple[float, float, _Normal, tuple[_Normal, ...], _Normal]] = {
    "roy-camille": (0.0, 0.0, _Normal(10.0, 4.8), (_Normal(0.0, 5.0),) * 5, _Normal(11.4, 1.5)),
    "magerl": (
        2.0,
        2.0,
        _Normal(25.0, 4.8),
        tuple(_Normal(m, s) for m, s in zip(_FACET, _FACET_SD)),
        _Normal(14.05, 1.5),
    ),
    "an": (1.0, 0.0, _Normal(30.0, 4.8), (_Normal(15.0, 5.0),) * 5, _Normal(12.8, 1.5)),
}
# Check only: midline spino-laminar junction, this far posterior to the body's posterior wall.
SPINOLAMINAR_BEHIND_BODY_MM = 12.25


def _rot_x(phi_deg: float) -> np.ndarray:
    """(3, 3) rotation about x with R (0, 1, 0) = (0, cos φ, sin φ)."""
    c, s = math.cos(math.radians(phi_deg)), math.sin(math.radians(phi_deg))
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def draw_parameters(seed: int | None = None, technique: str = "pedicle") -> dict[str, Any]:
    """Draw one patient's parameters (section 4 step 1); ``seed=None`` gives the mean patient.

    Draw order with ``numpy.random.default_rng(seed)``, one standard normal per value:
    lordosis; body heights C3..C7; body depths C3..C7; discs C3/4..C6/7; per level C3..C7 the
    right/left pairs (two normals each, ρ = 0.7) of TA, SA, PAL, SIP, XA; then, for lateral-mass
    techniques, per screw in row order (C3 R, C3 L, ..., C7 L): width (C3–C6 only, C7 does not
    use it), lateral angle, cephalad angle, length. The pedicle draws are therefore the same
    for every technique with the same seed.

    Returns:
        JSON-able dict: everything :func:`build_patient` needs (mm, degrees).
    """
    if technique not in TECHNIQUES:
        raise InputError.of("technique", f"{short_repr(technique)}: expected one of {', '.join(TECHNIQUES)}")
    if seed is not None:
        # numbers.Integral also admits numpy integers; bool is an int but never a meant seed.
        if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
            raise InputError.of("seed", f"{short_repr(seed)}: expected a non-negative integer")
        seed = int(seed)  # a plain int keeps the parameters JSON-able
    rng = None if seed is None else np.random.default_rng(seed)

    def z() -> float:
        return 0.0 if rng is None else float(rng.standard_normal())

    params: dict[str, Any] = {"technique": technique, "seed": seed, "mean_patient": seed is None}
    params["lordosis_deg"] = LORDOSIS.clip(z())
    params["body_height_mm"] = {lv: BODY_HEIGHT.clip(z()) for lv in LEVELS}
    params["body_depth_mm"] = {lv: BODY_DEPTH.clip(z()) for lv in LEVELS}
    params["disc_height_mm"] = {f"{a}/{b}": DISC_HEIGHT.clip(z()) for a, b in zip(LEVELS, LEVELS[1:])}
    rho = RL_CORRELATION
    pedicle: dict[str, Any] = {lv: {"R": {}, "L": {}} for lv in LEVELS}
    for k, lv in enumerate(LEVELS):
        for name, (means, sd, lo, hi) in PEDICLE.items():
            dist = _Normal(means[k], sd, lo, hi)
            z_right, z_other = z(), z()
            pedicle[lv]["R"][name] = dist.clip(z_right)
            pedicle[lv]["L"][name] = dist.clip(rho * z_right + math.sqrt(1 - rho * rho) * z_other)
    params["pedicle"] = pedicle
    if technique != "pedicle":
        medial, cranial, lateral, cephalad, length = LATERAL_MASS[technique]
        lm: dict[str, Any] = {lv: {} for lv in LEVELS}
        for k, lv in enumerate(LEVELS):
            for side, _ in _SIDES:
                screw: dict[str, float] = {}
                if lv != "C7":
                    screw["width_mm"] = LM_WIDTH.clip(z())
                screw["lateral_deg"] = lateral.clip(z())
                screw["cephalad_deg"] = cephalad[k].clip(z())
                screw["length_mm"] = length.clip(z())
                screw["medial_offset_mm"] = medial
                screw["cranial_offset_mm"] = cranial
                lm[lv][side] = screw
        params["lateral_mass"] = lm
    params["isthmus"] = draw_isthmus(seed)
    frames = level_frames(params)
    params["derived"] = {
        "level_tilt_deg": {lv: frames[lv][2] for lv in LEVELS},
        "level_centre_mm": {lv: [float(v) for v in frames[lv][0]] for lv in LEVELS},
    }
    return params


def level_frames(params: dict[str, Any]) -> dict[str, tuple[np.ndarray, np.ndarray, float]]:
    """Vertebra frames (section 4 steps 2–3): level → (centre (3,), R_x(φ) (3, 3), φ in deg)."""
    theta = params["lordosis_deg"] / 5.0
    tilt = {lv: (2 - k) * theta for k, lv in enumerate(LEVELS)}  # C3 2θ ... C7 −2θ
    h, disc = params["body_height_mm"], params["disc_height_mm"]

    def step(upper: str, lower: str) -> np.ndarray:
        """Centre of ``upper`` minus centre of ``lower``: spacing along their mean axis."""
        spacing = h[upper] / 2 + disc[f"{upper}/{lower}"] + h[lower] / 2
        mean_phi = math.radians((tilt[upper] + tilt[lower]) / 2)
        return spacing * np.array([0.0, math.cos(mean_phi), math.sin(mean_phi)])

    centre = {"C5": np.zeros(3)}
    for upper, lower in (("C4", "C5"), ("C3", "C4")):  # walk up from C5
        centre[upper] = centre[lower] + step(upper, lower)
    for upper, lower in (("C5", "C6"), ("C6", "C7")):  # walk down from C5
        centre[lower] = centre[upper] - step(upper, lower)
    return {lv: (centre[lv], _rot_x(tilt[lv]), tilt[lv]) for lv in LEVELS}


def _pedicle_local(params: dict[str, Any], lv: str, side: str, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """Pedicle entry and target in the vertebra frame (section 4 step 4), mm."""
    p = params["pedicle"][lv][side]
    h, d = params["body_height_mm"][lv], params["body_depth_mm"][lv]
    anchor = np.array([sigma * p["XA_mm"], h / 2 - p["SIP_mm"], -d / 2])
    direction = _unit(
        np.array([-sigma * math.tan(math.radians(p["TA_deg"])), math.tan(math.radians(p["SA_deg"])), -1.0])
    )
    entry = anchor - p["PAL_mm"] * direction
    depth = min(p["PAL_mm"] - ANTERIOR_MARGIN_MM, (sigma * entry[0] - MIN_TIP_MIDLINE_MM) / (-sigma * direction[0]))
    return entry, entry + depth * direction


def _lateral_mass_local(params: dict[str, Any], lv: str, side: str, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """Lateral-mass entry and target in the vertebra frame (section 4 step 5), mm."""
    s = params["lateral_mass"][lv][side]
    ped_entry, _ = _pedicle_local(params, lv, side, sigma)
    if lv == "C7":
        medial_shift = LM_C7_CENTRE_MEDIAL_MM
    else:  # centre = half a width medial to the lateral notch; entry is 2 mm medial to it
        medial_shift = s["width_mm"] / 2 - LM_ENTRY_TO_NOTCH_MM
    centre = ped_entry + np.array([-sigma * medial_shift, -LM_CENTRE_BELOW_ENTRY_MM, 0.0])
    entry = centre + np.array([-sigma * s["medial_offset_mm"], s["cranial_offset_mm"], 0.0])
    direction = _unit(
        np.array([sigma * math.tan(math.radians(s["lateral_deg"])), math.tan(math.radians(s["cephalad_deg"])), -1.0])
    )
    return entry, entry + s["length_mm"] * direction


def build_patient(params: dict[str, Any]) -> TrajectorySet:
    """Trajectories (unrounded, patient frame, mm) for ``params`` from :func:`draw_parameters`.

    Returns:
        10 trajectories ordered C3 R, C3 L, ..., C7 L with ids "1".."10".
    """
    frames = level_frames(params)
    local = _pedicle_local if params["technique"] == "pedicle" else _lateral_mass_local
    levels, sides, entry, target = [], [], [], []
    for lv in LEVELS:
        c, rot, _ = frames[lv]
        for side, sigma in _SIDES:
            e, t = local(params, lv, side, sigma)
            levels.append(lv)
            sides.append(side)
            entry.append(c + rot @ e)
            target.append(c + rot @ t)
    tag = "mean" if params["seed"] is None else f"seed={params['seed']}"
    ids = tuple(str(i) for i in range(1, len(levels) + 1))
    # a drawn patient's pedicle screws carry their isthmus (model §22.1); the mean patient's are the levels' means,
    # which a plan without the columns gets anyway (its CSV stays the bundled reference's)
    isthmus = params.get("isthmus")
    pedicle = None
    if params["technique"] == "pedicle" and params["seed"] is not None and isthmus is not None:
        pedicle = np.array(
            [
                [isthmus[lv][sd]["width_mm"], isthmus[lv][sd]["height_mm"], np.nan, np.nan]
                for lv, sd in zip(levels, sides)
            ]
        )
    return TrajectorySet(
        ids,
        tuple(levels),
        tuple(sides),
        np.array(entry),
        np.array(target),
        f"virtual:{params['technique']}:{tag}",
        pedicle,
    )


def generate_patient(seed: int | None = None, technique: str = "pedicle") -> tuple[TrajectorySet, dict[str, Any]]:
    """Draw and build one virtual patient; ``seed=None`` gives the mean patient."""
    params = draw_parameters(seed, technique)
    return build_patient(params), params


def write_patient(ts: TrajectorySet, params: dict[str, Any], csv_path: str | os.PathLike[str]) -> Path:
    """Write the CSV (3 decimals, section 4 step 6) and the parameters as JSON beside it.

    Returns:
        The JSON path (CSV path with suffix ``.json``).
    """
    csv_path = Path(csv_path)
    json_path = csv_path.with_suffix(".json")
    write_csv(ts, csv_path, decimals=3)
    atomic_write(json_path, json.dumps(params, indent=2) + "\n")
    return json_path


@dataclass(frozen=True)
class PatientCheck:
    """Step-6 check of one patient. Angles in degrees, lengths in mm.

    ``rows``: per trajectory (id, level, side, length, medial_local, medial_table, sagittal_local,
    sagittal_table, medial_patient, sagittal_patient, z). For lateral-mass techniques the
    medial columns hold −(lateral angle) and z is that of the lateral angle.
    ``per_level``: level → (tip gap, entry-to-spinolaminar right, left).
    """

    title: str
    tilts: dict[str, float]
    lordosis: float
    technique: str
    rows: list[tuple[str, str, str, float, float, float, float, float, float, float, float]]
    per_level: dict[str, tuple[float, float, float]]
    entry: np.ndarray

    @property
    def max_angle_error(self) -> float:
        """max |recomputed − table| over medial and sagittal local angles, deg."""
        return max(max(abs(r[4] - r[5]), abs(r[6] - r[7])) for r in self.rows)


def _angles(d: np.ndarray, sigma: float) -> tuple[float, float]:
    """(medial, sagittal) projected angles of drill direction ``d``, deg (conventions section)."""
    medial = math.degrees(math.atan2(-sigma * d[0], -d[2]))  # + toward the midline
    sagittal = math.degrees(math.atan2(d[1], -d[2]))  # + tip cephalad
    return medial, sagittal


def check_patient(ts: TrajectorySet, params: dict[str, Any]) -> PatientCheck:
    """Recompute lengths and angles from the (written, re-read) points of ``ts``.

    Raises:
        InputError: a trajectory without a C3–C7 level and an R/L side.
    """
    frames = level_frames(params)
    technique = params["technique"]
    rows = []
    tips: dict[tuple[str, str], np.ndarray] = {}
    slj: dict[tuple[str, str], float] = {}
    for i, tid in enumerate(ts.ids):
        lv, side = ts.levels[i], ts.sides[i]
        if lv not in LEVELS or side not in ("R", "L"):
            raise InputError(f"{ts.source} trajectory {tid}: check needs a C3–C7 level and side R/L")
        sigma = 1.0 if side == "R" else -1.0
        c, rot, _ = frames[lv]
        d = ts.target[i] - ts.entry[i]
        med_loc, sag_loc = _angles(rot.T @ d, sigma)
        med_pat, sag_pat = _angles(d, sigma)
        k = LEVELS.index(lv)
        if technique == "pedicle":
            p = params["pedicle"][lv][side]
            med_tab, sag_tab = p["TA_deg"], p["SA_deg"]
            z = (p["TA_deg"] - PEDICLE["TA_deg"][0][k]) / PEDICLE["TA_deg"][1]
        else:
            s = params["lateral_mass"][lv][side]
            lateral = LATERAL_MASS[technique][2]
            med_tab, sag_tab = -s["lateral_deg"], s["cephalad_deg"]
            z = (s["lateral_deg"] - lateral.mean) / lateral.sd
        rows.append((tid, lv, side, float(np.linalg.norm(d)), med_loc, med_tab, sag_loc, sag_tab, med_pat, sag_pat, z))
        tips[(lv, side)] = ts.target[i]
        e_local = rot.T @ (ts.entry[i] - c)
        z_junction = params["body_depth_mm"][lv] / 2 + SPINOLAMINAR_BEHIND_BODY_MM
        slj[(lv, side)] = math.hypot(e_local[0], e_local[2] - z_junction)  # axial plane
    per_level = {
        lv: (float(np.linalg.norm(tips[(lv, "R")] - tips[(lv, "L")])), slj[(lv, "R")], slj[(lv, "L")])
        for lv in LEVELS
        if (lv, "R") in tips and (lv, "L") in tips
    }
    what = "published means" if params["seed"] is None else f"seed {params['seed']}"
    return PatientCheck(
        f"{technique}, {what}",
        {lv: frames[lv][2] for lv in LEVELS},
        params["lordosis_deg"],
        technique,
        rows,
        per_level,
        ts.entry.copy(),
    )


def _f(value: float, spec: str) -> str:
    text = format(value, spec)
    # "-0.00" would suggest a sign the value does not have at this precision; keep the width.
    return text.replace("-", "+" if "+" in spec else " ", 1) if float(text) == 0.0 else text


def format_check(check: PatientCheck) -> str:
    """The check as text, laid out like ``reference_patient_check.txt``."""
    tilts = ", ".join(f"{lv} {_f(t, '+.1f')}" for lv, t in check.tilts.items())
    zname = "z(TA)" if check.technique == "pedicle" else "z(lat)"
    out = [
        f"# Sanity check ({check.title})",
        f"# C2-C7 lordosis {check.lordosis:.1f} deg -> level tilts: {tilts}",
        "# Angles recomputed from the written points. 'local' = in the vertebra's own frame",
        "# (level tilt removed), comparable with the table; 'patient' = in the patient frame.",
        "# For pedicles: medial_local must equal TA, sagittal_local must equal SA, and",
        "# sagittal_patient = SA + tilt. Lateral-mass screws have negative medial (= lateral).",
        "#   lvl sd     len  med_loc    table  sag_loc    table  med_pat  sag_pat" + f"{zname:>8}",
    ]
    for tid, lv, side, length, *angles, z in check.rows:
        cells = "".join(_f(v, "9.2f") for v in (length, *angles))
        out.append(f"{tid:<4}{lv:<4}{side}{cells}{_f(z, '+8.2f')}")
    lengths = np.array([r[3] for r in check.rows])
    ent = check.entry
    out += [
        f"# max |recomputed - table| = {check.max_angle_error:.4f} deg "
        "(from the 3-decimal CSV; should be ~0.01 or less)",
        f"# trajectory length: min {lengths.min():.1f}  mean {lengths.mean():.1f}  max {lengths.max():.1f} mm "
        f"(30 points -> spacing {lengths.mean() / 29:.2f} mm at mean)",
        "# per level: distance between right and left tips; distance from the spino-laminar",
        "# junction to the entry (axial plane; Sayin 2021 reports 22.9-23.8 mm on CT)",
    ]
    for lv, (gap, right, left) in check.per_level.items():
        out.append(f"#   {lv} tip gap {gap:5.1f} mm   entry-to-spinolaminar R {right:5.1f}  L {left:5.1f} mm")
    ax = np.abs(ent[:, 0])
    out.append(
        f"# entry points span: |x| {ax.min():.1f}-{ax.max():.1f}, y {ent[:, 1].min():.1f}.."
        f"{ent[:, 1].max():.1f}, z {ent[:, 2].min():.1f}..{ent[:, 2].max():.1f} mm"
    )
    return "\n".join(out) + "\n"
