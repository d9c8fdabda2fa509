"""Virtual patients (MORPHOMETRY.md sections 1, 2, 4) and the ``patients`` command.

Oracles are the shared reference files and the numbers of MORPHOMETRY.md, typed in below;
angles are recomputed here from the written points with the document's definitions.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from arcube.errors import InputError
from arcube.patients.virtual import (
    build_patient,
    check_patient,
    draw_parameters,
    format_check,
    generate_patient,
    write_patient,
)
from arcube.cli.patients import register
from arcube.io import load_trajectories, read_csv

DATA = Path(__file__).parent / "data" / "trajectories"
LEVELS = ("C3", "C4", "C5", "C6", "C7")
N_COHORT = 1000


# ------------------------------------------------------------ independent helpers


def rot_x(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def local_angles(entry, target, tilt_deg: float, side: str) -> tuple[float, float]:
    """(medial, sagittal) in the vertebra frame, per the document's 'Conventions'."""
    d = rot_x(tilt_deg).T @ (np.asarray(target) - np.asarray(entry))
    sigma = 1.0 if side == "R" else -1.0
    return (math.degrees(math.atan2(-sigma * d[0], -d[2])), math.degrees(math.atan2(d[1], -d[2])))


def clipped_moments(mean: float, sd: float, lo: float, hi: float) -> tuple[float, float]:
    """Mean and SD of clip(N(mean, sd), lo, hi), by numerical integration."""
    z = np.linspace(-12, 12, 240001)
    w = np.exp(-z * z / 2)
    w /= w.sum()
    x = np.clip(mean + sd * z, lo, hi)
    m = float((w * x).sum())
    return m, math.sqrt(float((w * (x - m) ** 2).sum()))


def assert_sample_matches(values, mean, sd, lo, hi, what: str, k: float = 4.5) -> None:
    values = np.asarray(values, dtype=float)
    n = values.size
    m_exp, sd_exp = clipped_moments(mean, sd, lo, hi)
    se_mean, se_sd = sd_exp / math.sqrt(n), sd_exp / math.sqrt(2 * n)
    assert abs(values.mean() - m_exp) < k * se_mean, f"{what}: mean {values.mean():.3f} vs {m_exp:.3f}"
    assert abs(values.std(ddof=1) - sd_exp) < k * se_sd, f"{what}: SD {values.std(ddof=1):.3f} vs {sd_exp:.3f}"
    assert values.min() >= lo - 1e-12 and values.max() <= hi + 1e-12, what


# ------------------------------------------------------------ the mean patient


def test_mean_patient_reproduces_the_shared_csv_to_a_micrometre() -> None:
    ts, params = generate_patient(None, "pedicle")
    ref = load_trajectories("reference")
    assert (ts.ids, ts.levels, ts.sides) == (ref.ids, ref.levels, ref.sides)
    assert np.abs(ts.entry - ref.entry).max() < 1e-3
    assert np.abs(ts.target - ref.target).max() < 1e-3
    assert params["mean_patient"] is True and params["lordosis_deg"] == 18.6


def test_mean_patient_file_and_check_equal_the_shared_files(tmp_path: Path) -> None:
    ts, params = generate_patient(None)
    out = tmp_path / "mean.csv"
    write_patient(ts, params, out)
    bundled = Path(__file__).parents[1] / "src" / "arcube" / "data" / "reference_patient.csv"
    assert out.read_text() == bundled.read_text()
    text = format_check(check_patient(read_csv(out), params))
    assert text == (DATA / "reference_patient_check.txt").read_text()


def test_level_centres_of_the_reference_patient() -> None:
    """MORPHOMETRY.md section 4: centres (y, z) C3 (35.5, 2.3) ... C7 (-35.5, 2.3)."""
    params = draw_parameters(None)
    centres = params["derived"]["level_centre_mm"]
    expected = {"C3": (35.5, 2.3), "C4": (17.8, 0.6), "C5": (0, 0), "C6": (-17.8, 0.6), "C7": (-35.5, 2.3)}
    for lv, (y, z) in expected.items():
        assert centres[lv][1] == pytest.approx(y, abs=0.05) and centres[lv][2] == pytest.approx(z, abs=0.05)


def test_lateral_mass_entry_relative_to_pedicle_entry() -> None:
    """Section 2: RC entry = LM centre = pedicle entry + (-sigma (12.2/2 - 2), -2.5, 0) at C3-C6,
    + (-sigma 1.6, -2.5, 0) at C7, in the vertebra frame; Magerl 2 mm more medial, 2 mm cranial."""
    ped, _ = generate_patient(None, "pedicle")
    tilt = {"C3": 7.44, "C4": 3.72, "C5": 0.0, "C6": -3.72, "C7": -7.44}
    for technique, extra in (("roy-camille", (0.0, 0.0)), ("magerl", (2.0, 2.0)), ("an", (1.0, 0.0))):
        lm, _ = generate_patient(None, technique)
        for i, (lv, side) in enumerate(zip(ped.levels, ped.sides)):
            sigma = 1.0 if side == "R" else -1.0
            medial = (12.2 / 2 - 2.0 if lv != "C7" else 1.6) + extra[0]
            offset = rot_x(tilt[lv]).T @ (lm.entry[i] - ped.entry[i])
            np.testing.assert_allclose(offset, [-sigma * medial, -2.5 + extra[1], 0.0], atol=1e-9)


# ------------------------------------------------------------ recomputed angles per technique


@pytest.mark.parametrize("technique", ["pedicle", "roy-camille", "magerl", "an"])
def test_recomputed_angles_equal_drawn_parameters(tmp_path: Path, technique: str) -> None:
    for seed in range(15):
        ts, params = generate_patient(seed, technique)
        write_patient(ts, params, tmp_path / "p.csv")
        back = read_csv(tmp_path / "p.csv")  # 3-decimal points, as a user gets them
        tilt = params["lordosis_deg"] / 5 * np.array([2, 1, 0, -1, -2])
        for i, (lv, side) in enumerate(zip(back.levels, back.sides)):
            phi = float(tilt[LEVELS.index(lv)])
            medial, sagittal = local_angles(back.entry[i], back.target[i], phi, side)
            length = float(np.linalg.norm(back.target[i] - back.entry[i]))
            if technique == "pedicle":
                p = params["pedicle"][lv][side]
                assert medial == pytest.approx(p["TA_deg"], abs=0.01)
                assert sagittal == pytest.approx(p["SA_deg"], abs=0.01)
                _, sag_patient = local_angles(back.entry[i], back.target[i], 0.0, side)
                assert sag_patient == pytest.approx(p["SA_deg"] + phi, abs=0.01)
                assert length <= p["PAL_mm"] - 3.0 + 2e-3
                tip_local = rot_x(phi).T @ (back.target[i] - np.array(params["derived"]["level_centre_mm"][lv]))
                assert abs(tip_local[0]) >= 2.0 - 2e-3  # tip at least 2 mm from the midline
            else:
                s = params["lateral_mass"][lv][side]
                assert -medial == pytest.approx(s["lateral_deg"], abs=0.01)  # lateral = -medial
                assert sagittal == pytest.approx(s["cephalad_deg"], abs=0.01)
                assert length == pytest.approx(s["length_mm"], abs=3e-3)
        assert check_patient(back, params).max_angle_error < 0.01


def test_parameters_json_rebuilds_the_patient(tmp_path: Path) -> None:
    ts, params = generate_patient(11, "an")
    json_path = write_patient(ts, params, tmp_path / "p.csv")
    rebuilt = build_patient(json.loads(json_path.read_text()))
    np.testing.assert_array_equal(rebuilt.entry, ts.entry)
    np.testing.assert_array_equal(rebuilt.target, ts.target)


def test_seeded_draws_are_reproducible_and_shared_across_techniques() -> None:
    a, b = draw_parameters(5, "pedicle"), draw_parameters(5, "magerl")
    assert a == draw_parameters(5, "pedicle")
    assert a["pedicle"] == b["pedicle"] and a["lordosis_deg"] == b["lordosis_deg"]
    assert draw_parameters(6)["pedicle"] != a["pedicle"]
    assert "lateral_mass" not in a and "width_mm" not in b["lateral_mass"]["C7"]["R"]


@pytest.mark.parametrize("seed, technique", [(-1, "pedicle"), (1.5, "pedicle"), (1, "lateral")])
def test_bad_generator_arguments(seed, technique) -> None:
    with pytest.raises(InputError):
        draw_parameters(seed, technique)


# ------------------------------------------------------------ cohort statistics


@pytest.fixture(scope="module")
def pedicle_cohort() -> list[dict]:
    return [draw_parameters(seed, "pedicle") for seed in range(N_COHORT)]


def test_cohort_global_parameters_match_the_table(pedicle_cohort: list[dict]) -> None:
    assert_sample_matches([p["lordosis_deg"] for p in pedicle_cohort], 18.6, 10, -10, 45, "lordosis")
    for lv in LEVELS:
        assert_sample_matches([p["body_height_mm"][lv] for p in pedicle_cohort], 12.5, 1.4, 9, 16, f"H {lv}")
        assert_sample_matches([p["body_depth_mm"][lv] for p in pedicle_cohort], 16.5, 1.3, 12, 21, f"D {lv}")
    for pair in ("C3/C4", "C4/C5", "C5/C6", "C6/C7"):
        assert_sample_matches([p["disc_height_mm"][pair] for p in pedicle_cohort], 5.3, 1.0, 3, 8, pair)


# Table of section 1, typed from MORPHOMETRY.md: means C3..C7, SD, clip (SIP: none published,
# clipped at mean +- 3 SD by the generator's documented choice).
TABLE = {
    "TA_deg": ((47, 49, 46, 43, 39), 4.5, (25, 62)),
    "SA_deg": ((8, 4, 0, -4, -3), 6.0, (-25, 25)),
    "PAL_mm": ((30.5, 31.5, 32.5, 33.5, 33.5), 2.5, (24, 42)),
    "SIP_mm": ((1.87, 2.86, 3.85, 4.84, 5.83), 1.0, None),
    "XA_mm": ((0, 0, 0, 1.7, 1.7), 1.0, (-3, 5)),
}


def _bilateral_draws_match(cohort: list[dict], section: str, table: dict) -> None:
    """Each level's right and left draws of ``section`` against the table's (means, SD, clip), and their correlation."""
    for name, (means, sd, clip) in table.items():
        for k, lv in enumerate(LEVELS):
            lo, hi = clip if clip else (means[k] - 3 * sd, means[k] + 3 * sd)
            right = [p[section][lv]["R"][name] for p in cohort]
            left = [p[section][lv]["L"][name] for p in cohort]
            assert_sample_matches(right, means[k], sd, lo, hi, f"{name} {lv} R")
            assert_sample_matches(left, means[k], sd, lo, hi, f"{name} {lv} L")
            # rho = 0.7; SE of r is about (1 - rho^2)/sqrt(n) = 0.016. Clipping lowers it a little.
            r = np.corrcoef(right, left)[0, 1]
            assert abs(r - 0.7) < 4.5 * 0.51 / math.sqrt(N_COHORT), f"{name} {lv}: r = {r:.3f}"


def test_cohort_pedicle_parameters_and_correlation(pedicle_cohort: list[dict]) -> None:
    _bilateral_draws_match(pedicle_cohort, "pedicle", TABLE)


# Section 6, typed from MORPHOMETRY.md: the isthmus, means C3..C7, SD, range (mm)
ISTHMUS_TABLE = {
    "width_mm": ((4.7, 4.9, 5.4, 5.8, 6.4), 0.8, (2.5, 9.0)),
    "height_mm": ((6.4, 6.5, 6.6, 6.7, 6.9), 0.8, (4.0, 10.0)),
}


def test_cohort_isthmus_matches_section_6_and_leaves_every_other_draw_alone(pedicle_cohort: list[dict]) -> None:
    _bilateral_draws_match(pedicle_cohort, "isthmus", ISTHMUS_TABLE)
    # its own stream: a technique's draws of the same seed share the isthmus, and the pedicle draws do not depend on it
    a, b = draw_parameters(12, "pedicle"), draw_parameters(12, "magerl")
    assert a["isthmus"] == b["isthmus"] and a["pedicle"] == b["pedicle"]
    assert draw_parameters(None)["isthmus"]["C3"]["R"] == {"width_mm": 4.7, "height_mm": 6.4}


def test_a_drawn_patients_plan_carries_its_isthmus_and_the_mean_patients_does_not(tmp_path: Path) -> None:
    ts, params = generate_patient(31)
    write_patient(ts, params, tmp_path / "p.csv")
    back = read_csv(tmp_path / "p.csv")
    expected = [
        [params["isthmus"][lv][sd]["width_mm"], params["isthmus"][lv][sd]["height_mm"]]
        for lv, sd in zip(back.levels, back.sides)
    ]
    np.testing.assert_allclose(back.pedicle[:, :2], expected, atol=5e-4)  # 3 decimals in the CSV
    assert np.isnan(back.pedicle[:, 2:]).all()  # isthmus depth and screw: the defaults
    mean, mean_params = generate_patient(None)
    assert mean.pedicle is None


def test_cohort_geometry_recomputed_from_points(pedicle_cohort: list[dict]) -> None:
    """TA recomputed from the built points, per level, matches the table statistically."""
    ta = {lv: [] for lv in LEVELS}
    for params in pedicle_cohort[:N_COHORT]:
        ts = build_patient(params)
        tilt = params["lordosis_deg"] / 5 * np.array([2, 1, 0, -1, -2])
        for i, (lv, side) in enumerate(zip(ts.levels, ts.sides)):
            if side == "R":
                ta[lv].append(local_angles(ts.entry[i], ts.target[i], float(tilt[LEVELS.index(lv)]), side)[0])
    for k, lv in enumerate(LEVELS):
        assert_sample_matches(ta[lv], TABLE["TA_deg"][0][k], 4.5, 25, 62, f"TA from points {lv}")


def test_cohort_lateral_mass_parameters() -> None:
    """Section 2 table: lateral SD 4.8; cephalad 0/facet/15; lengths 11.4/14.05/12.8 SD 1.5.
    No range is published for these: the generator clips at mean +- 3 SD (documented choice)."""
    facet = {"C3": (50.6, 4.65), "C4": (44.9, 5.4), "C5": (40.2, 5.9), "C6": (42.8, 4.9), "C7": (45.0, 5.4)}
    specs = {
        "roy-camille": (10, lambda lv: (0.0, 5.0), 11.4),
        "magerl": (25, lambda lv: facet[lv], 14.05),
        "an": (30, lambda lv: (15.0, 5.0), 12.8),
    }
    n = 400  # per technique; keeps the run short, tolerances scale with 1/sqrt(n)
    for technique, (lateral, cephalad, length) in specs.items():
        cohort = [draw_parameters(seed, technique)["lateral_mass"] for seed in range(n)]
        for lv in LEVELS:
            screws = [c[lv][s] for c in cohort for s in ("R", "L")]  # independent per screw
            assert_sample_matches(
                [s["lateral_deg"] for s in screws],
                lateral,
                4.8,
                lateral - 14.4,
                lateral + 14.4,
                f"{technique} lateral {lv}",
            )
            m, sd = cephalad(lv)
            assert_sample_matches(
                [s["cephalad_deg"] for s in screws], m, sd, m - 3 * sd, m + 3 * sd, f"{technique} cephalad {lv}"
            )
            assert_sample_matches(
                [s["length_mm"] for s in screws], length, 1.5, length - 4.5, length + 4.5, f"{technique} length {lv}"
            )
            if lv != "C7":  # width: Jian 2023 mean 12.2 mm; SD 1.2 mm is the generator's assumption
                assert_sample_matches(
                    [s["width_mm"] for s in screws], 12.2, 1.2, 12.2 - 3.6, 12.2 + 3.6, f"{technique} width {lv}"
                )


# ------------------------------------------------------------ command line


@pytest.fixture()
def cli() -> tuple[CliRunner, typer.Typer]:
    app = typer.Typer()
    register(app)

    @app.command("noop")
    def noop() -> None:  # a second command keeps "patients" a named subcommand
        """Unused."""

    return CliRunner(), app


def test_cli_mean_writes_reference_and_prints_check(cli, tmp_path: Path) -> None:
    runner, app = cli
    out = tmp_path / "mean.csv"
    result = runner.invoke(app, ["patients", "--mean", "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert out.read_text() == load_reference_text()
    assert json.loads((tmp_path / "mean.json").read_text())["mean_patient"] is True
    expected = (DATA / "reference_patient_check.txt").read_text()
    assert expected in result.output


def load_reference_text() -> str:
    return (Path(__file__).parents[1] / "src" / "arcube" / "data" / "reference_patient.csv").read_text()


def test_cli_cohort_folder(cli, tmp_path: Path) -> None:
    runner, app = cli
    out = tmp_path / "cohort"
    args = ["patients", "--seed", "40", "--count", "3", "--technique", "magerl", "--out", str(out)]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    names = sorted(f.name for f in out.iterdir())
    assert names == sorted(
        [
            "cohort.toml",
            *(f"patient_00{k}.{ext}" for k in range(3) for ext in ("csv", "json", "anatomy.stl", "envelope.stl")),
        ]
    )  # MODEL.md 14.2, 19
    seeds = [json.loads((out / f"patient_00{k}.json").read_text())["seed"] for k in range(3)]
    assert seeds == [40, 41, 42]
    ts, _ = generate_patient(41, "magerl")
    back = read_csv(out / "patient_001.csv")
    assert np.abs(back.entry - ts.entry).max() <= 5e-4 + 1e-12
    assert result.output.count("# Sanity check (magerl, seed") == 3


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--out", "x.csv"], "seed is missing: give a seed for random patients, or ask for the mean patient"),
        (["--mean", "--seed", "1", "--out", "x.csv"], "mean excludes a seed"),
        (["--seed", "1", "--technique", "screw", "--out", "x.csv"], "technique 'screw'"),
        (["--seed", "1", "--count", "0", "--out", "x.csv"], "count 0"),
        (["--mean", "--count", "2", "--out", "d"], "count 2 for the mean patient would write identical patients"),
        (["--seed", "-3", "--out", "x.csv"], "seed -3"),
        (["--seed", "1", "--out", "x.json"], "must not end in .json"),
    ],
)
def test_cli_errors_raise_input_error(cli, tmp_path: Path, monkeypatch, args, needle) -> None:
    runner, app = cli
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(app, ["patients", *args])
    assert isinstance(result.exception, InputError), result.output
    assert needle in str(result.exception)
    assert not any(tmp_path.iterdir())  # nothing written


# ------------------------------------------------------------ every written anatomy reads back (Hardening III item 0)


def test_every_patient_of_a_cohort_reads_back_through_the_strict_readers(cli, tmp_path: Path) -> None:
    """``arcube patients --seed 1 --count 50``: every anatomy and envelope passes the mesh reader, and every
    arch holds its level's entries on its posterior face with at least 2 mm of bone in front of them.

    Seeds 2 and 25 drew entries in front of the body's posterior wall: their arches came out inside out, which
    the reader refused ("shell 4 encloses no positive volume") and which left the folder half written. (50 patients
    hold both; the 200 of seeds 1-200 are the check "patients-200" of benchmarks/slow_checks.py.)
    """
    from arcube.design_job.cohort import read_cohort
    from arcube.io.meshes import read_mesh
    from arcube.patients.anatomy import default_anatomy_boxes

    runner, app = cli
    out = tmp_path / "cohort"
    result = runner.invoke(app, ["patients", "--seed", "1", "--count", "50", "--out", str(out)])
    assert result.exit_code == 0, result.output
    plans = read_cohort(out / "cohort.toml")
    assert len(plans) == 50
    for k in range(50):
        stem = out / f"patient_{k:03d}"
        meshes = [
            read_mesh(stem.with_suffix(".anatomy.stl"), "patient"),
            read_mesh(stem.with_suffix(".envelope.stl"), "patient"),
        ]
        assert all(m.volume > 0 for m in meshes)
    # the geometry behind it, by hand: the arch's +z face (its third axis) holds the entries, 2 mm thick at least
    for seed in (2, 25, 60):
        ts, params = generate_patient(seed)
        arches = [b for b in default_anatomy_boxes(params) if b.name.endswith("arch")]
        for box, lv in zip(arches, LEVELS):
            normal = box.rotation[:, 2]
            face = float(box.centre @ normal) + box.half_extents[2]
            entries = ts.entry[[i for i, level in enumerate(ts.levels) if level == lv]]
            assert np.allclose(entries @ normal, face, atol=1e-9)
            assert 2 * box.half_extents[2] >= 2.0 - 1e-12


def test_a_cohort_that_fails_midway_leaves_nothing_behind(tmp_path: Path) -> None:
    """A failure while writing patient 2 of 3 (here: the envelope step) writes no file at all, in a new folder
    (which is not left behind) and in an existing one (which keeps only what it held)."""
    from arcube.patients.cohort import write_patients

    calls = []

    def envelope_that_fails_on_the_second(plan: Path) -> str:
        calls.append(plan)
        if len(calls) == 2:
            raise InputError(f"{plan}: refused on purpose")
        return ""

    new = tmp_path / "a" / "new"
    with pytest.raises(InputError, match="refused on purpose"):
        write_patients(False, 1, "pedicle", 3, new, beside=envelope_that_fails_on_the_second)
    assert not (tmp_path / "a").exists()
    kept = tmp_path / "kept"
    kept.mkdir()
    (kept / "notes.txt").write_text("mine")
    (kept / "patient_000.csv").write_text("old")
    calls.clear()
    with pytest.raises(InputError, match="refused on purpose"):
        write_patients(False, 1, "pedicle", 3, kept, beside=envelope_that_fails_on_the_second)
    assert sorted(f.name for f in kept.iterdir()) == ["notes.txt", "patient_000.csv"]
    assert (kept / "patient_000.csv").read_text() == "old"


def test_one_patient_into_a_folder_path(tmp_path: Path) -> None:
    """``--count 1 --out next``: a path that is not a CSV is a folder (created) with patient_000.csv and the cohort
    file, as for several patients (it once became a CSV named ``next`` whose envelope looked for ``next/anatomy``)."""
    from arcube.patients.cohort import write_patients

    texts = write_patients(False, 17, "pedicle", 1, tmp_path / "next")
    assert sorted(p.name for p in (tmp_path / "next").iterdir()) == [
        "cohort.toml",
        "patient_000.anatomy.stl",
        "patient_000.csv",
        "patient_000.json",
    ]
    assert 'name = "seed17"' in (tmp_path / "next" / "cohort.toml").read_text() and len(texts) == 2
