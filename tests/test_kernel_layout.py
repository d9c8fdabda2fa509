"""The compiled kernel's bookkeeping: one parameter layout, generated row layouts, settings read, cache.

* :data:`arcube.model.design.SLICES` is the design array's layout: it tiles PARAM_NAMES by group,
  ``unpack`` and the kernel's geometry rows follow it;
* the kernel's ``G_*``/``O_*``/``S_*``/``X_*`` offsets are generated from their declared blocks and
  from the result types' fields, and every setting of Options reaches the kernel;
* the two summation orders of the mounting rotation are the ones their docstrings name;
* importing the kernel touches no cache file; ``clear_cache`` and the staleness check do.
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from arcube.evaluation import kernel, reference
from arcube.evaluation.kernel import _cache, _layout
from arcube.evaluation.kernel._layout import EXTRA, GEOMETRY, OPTIONS, SUMMARY, Layout
from arcube.evaluation.performance import MAXIMUM_FIELDS, PERFORMANCE_FIELDS
from arcube.evaluation.reference import PointResults, TaskResults
from arcube.model import frames
from arcube.model.design import ANGLE_GROUPS, ANGLE_NAMES, INDEX, PARAM_NAMES, SLICES, Geometry, unpack
from arcube.options import Body, Guards, Loads, Masses, Options, Outputs

ROOT = Path(__file__).resolve().parents[1]


def _names(key: str) -> list[str]:
    """The PARAM_NAMES of a Geometry field: ``key`` itself, or ``key_*``."""
    return [n for n in PARAM_NAMES if n == key or n.startswith(key + "_")]


# ----------------------------------------------------------------------------- the design array


def test_slices_tile_the_design_array_by_group() -> None:
    assert list(SLICES) == [f.name for f in dataclasses.fields(Geometry)]
    covered: list[int] = []
    for key, at in SLICES.items():
        idx = [at] if isinstance(at, int) else list(range(at.start, at.stop))
        assert [PARAM_NAMES[i] for i in idx] == _names(key), key
        assert isinstance(at, int) == (_names(key) == [key]), key  # an int exactly for a scalar parameter
        covered += idx
    assert covered == list(range(len(PARAM_NAMES)))
    assert {n for key in ANGLE_GROUPS for n in _names(key)} == ANGLE_NAMES


def test_unpack_takes_each_field_by_its_names() -> None:
    x = np.random.default_rng(0).uniform(-200.0, 200.0, (4, 2, len(PARAM_NAMES)))
    g = unpack(x)
    for key in SLICES:
        cols = x[..., [INDEX[n] for n in _names(key)]]
        want = np.deg2rad(cols) if key in ANGLE_GROUPS else cols
        want = want[..., 0] if isinstance(SLICES[key], int) else want
        np.testing.assert_array_equal(getattr(g, key), want, err_msg=key)
    np.testing.assert_array_equal(unpack(x[0, 0, :23]).mount, np.zeros(3))  # the paper's 23: additions at 0


def test_geometry_rows_hold_the_unpacked_design() -> None:
    x = np.random.default_rng(1).uniform(-200.0, 200.0, (5, len(PARAM_NAMES)))
    x[0, 23:26] = 0.0  # one unrotated design
    rows, g = kernel._geometry(x), unpack(x)
    assert rows.shape == (5, GEOMETRY.size) == (5, _layout.N_GEO)

    def block(name: str) -> np.ndarray:
        return rows[:, GEOMETRY.offset[name] : GEOMETRY.offset[name] + GEOMETRY.width[name]]

    for key in ("m", "f", "p", "d", "c", "t", "r", "o"):
        np.testing.assert_array_equal(block(key), np.reshape(getattr(g, key), (5, -1)), err_msg=key)
        assert GEOMETRY.width[key] == len(_names(key))
    np.testing.assert_array_equal(block("sin_alpha"), np.sin(g.alpha))
    np.testing.assert_array_equal(block("cos_beta"), np.cos(g.beta))
    np.testing.assert_array_equal(block("rot"), frames.mount_rotation(g).reshape(5, 9))
    np.testing.assert_array_equal(block("L")[:, 0], g.L)
    np.testing.assert_array_equal(block("flat")[:, 0], [1.0, 0.0, 0.0, 0.0, 0.0])


# ----------------------------------------------------------------------------- generated row layouts


@pytest.mark.parametrize("layout", [GEOMETRY, OPTIONS, SUMMARY, EXTRA], ids=lambda lay: lay.prefix)
def test_layout_constants_are_its_offsets(layout: Layout) -> None:
    at = 0
    for name, width in layout.entries:
        assert layout.offset[name] == at and getattr(_layout, f"{layout.prefix}_{name.upper()}") == at, name
        at += width
    assert layout.size == at
    assert {"G": _layout.N_GEO, "O": _layout.N_OPT, "S": _layout.N_SUMM, "X": _layout.N_EXTRA}[layout.prefix] == at


def test_result_rows_follow_the_result_types() -> None:
    """A summary column per TaskResults field (n_bad for w_G), an extra column per PointResults field
    without an array of its own: a new result field gets its column from the types alone."""
    assert SUMMARY.names == ("n_bad", *TaskResults._fields[2:])
    assert set(EXTRA.names) | set(_layout.POINT_ARRAYS) == set(PointResults._fields)
    assert not set(EXTRA.names) & set(_layout.POINT_ARRAYS)
    assert all(SUMMARY.width[n] == 1 for n in SUMMARY.names) and all(EXTRA.width[n] == 1 for n in EXTRA.names)
    s_cols, x_cols = _layout.MAXIMA.T
    tip = TaskResults._fields.index("tip_error_max")
    assert [SUMMARY.names[c] for c in s_cols] == list(TaskResults._fields[tip:])  # MODEL.md 15.5, the last fields
    assert [EXTRA.names[c] for c in x_cols] == [EXTRA.names[c] for c in _layout.METRIC_COLUMNS] == list(MAXIMUM_FIELDS)
    assert (
        MAXIMUM_FIELDS == (*PERFORMANCE_FIELDS, "holding_torque_Nm") and TaskResults._fields[-1] == "holding_torque_max"
    )  # MODEL.md 18.2


def test_geometry_rows_hold_the_arcs_chords_and_slerp_sums() -> None:
    """The per-design sums of the holding torque's collapsed chords (kernel._masses), against the 13 slerp
    samples of each spherical link summed here by hand: sum_k (c_k + c_{k+1}) / 2 of sin(k phi / 12) / sin(phi)."""
    x = np.random.default_rng(3).uniform(30.0, 150.0, (4, len(PARAM_NAMES)))
    rows, g = kernel._geometry(x), unpack(x)
    phi = np.concatenate([g.alpha, g.beta], axis=-1)
    k = np.arange(13)
    b = np.sin(k[None, None, :] * phi[..., None] / 12.0) / np.sin(phi[..., None])
    a = b[..., ::-1]  # sin((1 - s) phi) / sin(phi): the samples in reverse
    trapezoid = lambda c: c[..., 1:-1].sum(axis=-1) + 0.5 * (c[..., 0] + c[..., -1])  # noqa: E731
    block = lambda name: rows[:, GEOMETRY.offset[name] : GEOMETRY.offset[name] + 4]  # noqa: E731
    np.testing.assert_allclose(block("arc_a"), trapezoid(a), rtol=1e-14)
    np.testing.assert_allclose(block("arc_b"), trapezoid(b), rtol=1e-14)
    np.testing.assert_allclose(block("arc_chord"), np.sin(phi / 24.0), rtol=1e-15)


def test_layout_refuses_repeated_blocks() -> None:
    with pytest.raises(ValueError, match="repeated"):
        Layout("Z", [("a", 1), ("a", 2)])
    with pytest.raises(ValueError, match="case"):
        Layout("Z", [("a", 1), ("A", 1)]).constants()


def test_excess_cap_is_the_reference_one() -> None:
    assert _layout.EXCESS_CAP == reference._EXCESS_CAP


# ----------------------------------------------------------------------------- settings


SAMPLES = {
    Guards: {
        "z_dyad": True,
        "c_z": 150.0,
        "rho_max_deg": 50.0,
        "min_transmission_deg": 30.0,
        "kappa_max": 5.0,
        "single_assembly_mode": True,
        "clearance_mm": 3.0,
        "self_clearance_mm": 2.0,
        "envelope_clearance_mm": 10.0,
    },
    Body: {"link_radius": 3.0, "actuator_radius": 9.0, "motor_radius": 7.0, "motor_length": 80.0},
    Loads: {"encoder_deg": 0.02, "thrust_N": 12.0, "lateral_force_N": 3.0, "actuator_stiffness": 2e3},
    Masses: {
        "wall_mm": 3.0,
        "density_kg_m3": 7800.0,
        "m_delta_kg": 0.5,
        "m_motor_kg": 2.0,
        "gravity": (0.0, -9.81, 0.0),
    },
    Outputs: {
        "clearances": True,
        "anatomy_clearance": True,
        "clearance_min_exact": False,
        "tip_metrics": False,
        "holding_torque": True,
        "envelope_clearance": True,
    },
}
"""A value other than the default for every setting (a new setting needs one here)."""
GROUP = {Guards: "guards", Body: "body", Loads: "loads", Masses: "masses", Outputs: "outputs"}


def _seen(options: Options) -> tuple[np.ndarray, ...]:
    """What the compiled code gets of ``options``: the option vector (with an anatomy and an envelope) and the body radii."""
    return kernel._option_vector(options, anatomy=True, envelope=True), kernel._body_context(options, None)[1][0]


@pytest.mark.parametrize("group", list(SAMPLES), ids=lambda g: g.__name__)
def test_every_setting_reaches_the_kernel(group) -> None:
    assert set(SAMPLES[group]) == set(group.model_fields), f"a sample value for every {group.__name__} field"
    base = _seen(Options())
    for name, value in SAMPLES[group].items():
        changed = _seen(Options(**{GROUP[group]: group(**{name: value})}))
        assert any(not np.array_equal(a, b, equal_nan=True) for a, b in zip(base, changed)), (
            f"{group.__name__}.{name} is not read"
        )


def test_option_vector_blocks() -> None:
    o = kernel._option_vector(
        Options(rho_max_deg=50.0, min_transmission_deg=30.0, encoder_deg=0.02, actuator_stiffness=2e3), exact=True
    )
    block = {name: o[OPTIONS.offset[name] : OPTIONS.offset[name] + w] for name, w in OPTIONS.entries}
    assert block["rho_max_on"][0] == 1.0 and block["rho_max"][0] == np.deg2rad(50.0)
    assert block["transmission"][0] == np.sin(np.deg2rad(30.0)) and block["kappa_max_on"][0] == 0.0
    np.testing.assert_array_equal(block["encoder"], np.radians([0.02] * 5))
    np.testing.assert_array_equal(block["stiffness"], [2e6] * 5)  # N·m/rad -> N·mm/rad
    assert np.isnan(block["c_z"][0]) and block["exact"][0] == 1.0 and block["tip_metrics"][0] == 1.0
    assert kernel._option_vector(Options(clearance_mm=3.0))[OPTIONS.offset["clearance_on"]] == 0.0  # no anatomy


# ----------------------------------------------------------------------------- rotation helpers


def test_rotation_helpers_sum_in_their_named_orders() -> None:
    from arcube.evaluation.kernel._scalar import rot, rot_t

    _cache.ensure_fresh()
    rng = np.random.default_rng(2)
    x = np.zeros((50, len(PARAM_NAMES)))
    x[:, SLICES["mount"]] = rng.uniform(-180.0, 180.0, (50, 3))
    rows, a = kernel._geometry(x), 100.0 * rng.standard_normal((50, 3))
    R = rows[:, GEOMETRY.offset["rot"] :][:, :9]
    p = R.reshape(-1, 3, 3) * a[:, None, :]  # p[k, i, j] = R_ij a_j
    q = np.swapaxes(R.reshape(-1, 3, 3), 1, 2) * a[:, None, :]  # (R^T)_ij a_j
    got = np.array([rot(rows[k], *a[k]) for k in range(50)])
    got_t = np.array([rot_t(rows[k], *a[k]) for k in range(50)])
    np.testing.assert_array_equal(got, (p[..., 0] + p[..., 1]) + p[..., 2])
    np.testing.assert_array_equal(got_t, (q[..., 0] + q[..., 2]) + q[..., 1])
    flat = kernel._geometry(np.zeros((1, len(PARAM_NAMES))))[0]
    assert rot(flat, 1.5, -2.0, 3.0) == rot_t(flat, 1.5, -2.0, 3.0) == (1.5, -2.0, 3.0)


# ----------------------------------------------------------------------------- the on-disk cache


def _python(code: str) -> str:
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True, timeout=300
    )
    return out.stdout.strip()


def test_import_touches_no_cache_and_the_fingerprint_is_stable() -> None:
    """Importing checks nothing (the check runs at the first compiled call); the fingerprint is the
    same in every process (else each process would drop the cache)."""
    out = _python(
        "import arcube.evaluation.kernel as k; from arcube.evaluation.kernel import _cache as c; print(c._checked, c.fingerprint())"
    )
    checked, fp = out.split()
    assert checked == "False" and fp == _cache.fingerprint()


def test_fingerprint_follows_the_frozen_constants(monkeypatch) -> None:
    before = _cache.fingerprint()
    monkeypatch.setattr(_layout, "S_ETA_G", _layout.S_ETA_G + 100)
    assert _cache.fingerprint() != before


def test_clear_cache_and_the_staleness_check(tmp_path, monkeypatch) -> None:
    monkeypatch.setattr(_cache, "_CACHE", tmp_path)
    for name in ("a.nbi", "a.1.nbc", "keep.pyc"):
        (tmp_path / name).write_text("x")
    assert kernel.clear_cache() == 2 and sorted(p.name for p in tmp_path.iterdir()) == ["keep.pyc"]
    (tmp_path / "b.nbi").write_text("x")
    (tmp_path / _cache._STAMP).write_text(_cache.fingerprint())
    monkeypatch.setattr(_cache, "_checked", False)
    _cache.ensure_fresh()  # stamped with the current fingerprint: kept
    assert (tmp_path / "b.nbi").exists()
    (tmp_path / _cache._STAMP).write_text("stale")
    monkeypatch.setattr(_cache, "_checked", False)
    _cache.ensure_fresh()  # another fingerprint: dropped, and stamped anew
    assert not (tmp_path / "b.nbi").exists() and (tmp_path / _cache._STAMP).read_text() == _cache.fingerprint()
    (tmp_path / "c.nbi").write_text("x")
    (tmp_path / _cache._STAMP).write_text("stale")
    _cache.ensure_fresh()  # once per process
    assert (tmp_path / "c.nbi").exists()
