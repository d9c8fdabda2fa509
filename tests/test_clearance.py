"""Body and clearance (MODEL.md 14.1, 14.3) against oracles written from the spec.

* every part of the body has the design's link lengths and spherical angles at every point;
* the clearance to a box and to a sphere equals the exact distance (closed forms, or the exact box
  distance sampled every 0.01 mm) within the stated 0.5 mm, for the NumPy reference and the kernel;
* the self clearance equals a brute-force minimum over densely sampled axes of the checked pairs;
* the collision guards fail exactly the points below their threshold and add the shortfall (mm);
* batch equals loop, kernel equals reference.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from arcube.evaluation.kernel import evaluate_task_numba
from arcube.evaluation.reference import FAILURES, Options, evaluate_task
from arcube.evaluation.sdf import AnatomyDistance
from arcube.model.body import PART_NAMES, PRIMITIVES, SELF_PAIRS, BodyRadii, body_parts, mechanism_points
from arcube.model.mechanism import ALL_MODES

from designs import reaching_design, reference_task

RADII = BodyRadii()


@pytest.fixture(scope="module")
def setup():
    task = reference_task()
    x = reaching_design((-135.0, -144.74, -67.63), 120.0, n=400)
    mp = mechanism_points(x, task.E, task.e, ALL_MODES[0], motor_length=RADII.motor_length)
    ok = np.asarray(mp.reachable)
    return task, x, mp, ok


def _angle(a, b):
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1)))


def test_every_part_has_the_design_lengths_at_every_point(setup) -> None:
    task, x, mp, ok = setup
    parts = body_parts(mp, RADII)
    seg = parts.segments[ok]
    length = np.linalg.norm(seg[:, :, 1] - seg[:, :, 0], axis=-1)
    want = {"frame": x[3:6], "crank": x[6:9], "input": x[9:11], "coupler": x[12:14], "output": x[14:16]}
    for kind, values in want.items():
        idx = [i for i, p in enumerate(PRIMITIVES[:18]) if p[0].startswith(kind + "_")]
        np.testing.assert_allclose(length[:, idx], np.broadcast_to(values, (len(seg), len(idx))), atol=1e-9)
    np.testing.assert_allclose(length[:, 17], RADII.motor_length, atol=1e-9)  # drill motor H -> H + L_m e
    # the platform joins Q_x, Q_y, Q_z: an equilateral triangle of side r sqrt(2) around C
    np.testing.assert_allclose(length[:, 14:17], x[16] * np.sqrt(2.0), atol=1e-9)
    closes = np.asarray(mp.z_closes)[ok]
    np.testing.assert_allclose(length[closes, 12], x[11], atol=1e-9)  # the z dyad: d_z, then c_z = d_z
    np.testing.assert_allclose(length[closes, 13], x[11], atol=1e-9)
    # actuators sit at the crank pivots P_u and at the crank tips D_u
    np.testing.assert_allclose(parts.spheres[ok][:, :3], seg[:, 3:6, 0], atol=1e-12)
    np.testing.assert_allclose(parts.spheres[ok][:, 3:5], seg[:, 3:5, 1], atol=1e-12)
    # spherical links: alpha_u from u_m to u_beta, beta_u from u_beta to e; drill holder H = C + r e, E = C - L e
    ends = parts.arc_ends[ok]
    np.testing.assert_allclose(
        _angle(ends[:, 0:2, 0], ends[:, 0:2, 1]), np.broadcast_to(x[19:21], (len(ends), 2)), atol=1e-7
    )
    np.testing.assert_allclose(
        _angle(ends[:, 2:4, 0], ends[:, 2:4, 1]), np.broadcast_to(x[21:23], (len(ends), 2)), atol=1e-7
    )
    np.testing.assert_allclose(ends[:, 2:4, 1], np.broadcast_to(task.e[ok][:, None], (len(ends), 2, 3)), atol=1e-12)
    np.testing.assert_allclose(seg[:, 17, 0], mp.C[ok] + x[16] * task.e[ok], atol=1e-9)
    np.testing.assert_allclose(mp.E[ok], task.E[ok], atol=1e-9)
    np.testing.assert_allclose(mp.C[ok], task.E[ok] + x[26] * task.e[ok], atol=1e-9)


def _axis_samples(parts, step: float = 0.01) -> list[np.ndarray]:
    """Per primitive, points along its axis every ``step`` mm at most, ``(P, n, 3)``: written here, not the code's."""
    out = []
    for s in range(18):
        a, b = parts.segments[:, s, 0], parts.segments[:, s, 1]
        n = int(np.ceil(np.max(np.linalg.norm(b - a, axis=-1)) / step)) + 1
        t = np.linspace(0.0, 1.0, n)[None, :, None]
        out.append(a[:, None] + t * (b - a)[:, None])
    for k in range(5):
        out.append(parts.spheres[:, k, None, :])
    for k in range(4):
        a, b = parts.arc_ends[:, k, 0], parts.arc_ends[:, k, 1]
        nrm = b - np.sum(a * b, axis=-1, keepdims=True) * a
        nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
        theta = np.arccos(np.clip(np.sum(a * b, axis=-1), -1, 1))
        n = int(np.ceil(np.max(parts.arc_radius * theta) / step)) + 1
        phi = np.linspace(0.0, 1.0, n)[None, :, None] * theta[:, None, None]
        out.append(
            parts.arc_centre[:, None]
            + parts.arc_radius[:, None, None] * (a[:, None] * np.cos(phi) + nrm[:, None] * np.sin(phi))
        )
    return out


def _exact_box(p, centre, half):
    q = np.abs(p - centre) - half
    return np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(np.max(q, axis=-1), 0.0)


def _oracle(parts, sdf_exact):
    values = np.stack([np.min(sdf_exact(pts), axis=-1) for pts in _axis_samples(parts)], axis=-1) - parts.radius
    return values.min(axis=-1), np.array([PART_NAMES.index(PRIMITIVES[i][0]) for i in np.argmin(values, axis=-1)])


def _check(setup, anatomy_sdf, exact) -> None:
    task, x, mp, ok = setup
    sel = np.flatnonzero(ok)[::6]
    mp_sel = mechanism_points(x, task.E[sel], task.e[sel], ALL_MODES[0], motor_length=RADII.motor_length)
    want, want_part = _oracle(body_parts(mp_sel, RADII), exact)
    assert want.min() < 5.0 and want.max() > -30.0  # the anatomy is close to the body: the check bites
    opts = Options(body=True)
    ref = evaluate_task(x, task.E[sel], task.e[sel], ALL_MODES[0], opts, anatomy_sdf)
    ker = evaluate_task_numba(x, task.E[sel], task.e[sel], ALL_MODES[0], opts, anatomy=anatomy_sdf)
    for got in (ref, ker):
        assert np.max(np.abs(got.points.clearance_mm - want)) <= 0.5
    assert np.max(np.abs(ker.points.clearance_mm - ref.points.clearance_mm)) <= 0.15
    # the part: where the oracle's best beats the runner-up by more than 1 mm, it is the one named
    assert np.mean(ref.points.clearance_part == want_part) > 0.6


def test_clearance_to_a_box_equals_the_exact_distance(setup) -> None:
    task, x, mp, ok = setup
    centre = mp.C[ok].mean(axis=0) - 45.0 * task.e[ok].mean(axis=0)
    half = np.array([45.0, 60.0, 25.0])
    box = (centre, half, np.eye(3))
    _check(setup, AnatomyDistance.from_boxes([box]), lambda p: _exact_box(p, centre, half))


def test_clearance_to_a_sphere_equals_the_exact_distance(setup) -> None:
    task, x, mp, ok = setup
    centre = mp.K[ok][:, 0].mean(axis=0) + np.array([0.0, 0.0, 25.0])
    R = 30.0
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=R)  # its faces lie within 0.09 mm of the sphere
    sphere.apply_translation(centre)
    _check(setup, AnatomyDistance.from_meshes([sphere]), lambda p: np.linalg.norm(p - centre, axis=-1) - R)


def test_self_clearance_equals_brute_force_over_the_checked_pairs(setup) -> None:
    task, x, mp, ok = setup
    sel = np.flatnonzero(ok)[::25]
    mp_sel = mechanism_points(x, task.E[sel], task.e[sel], ALL_MODES[0], motor_length=RADII.motor_length)
    parts = body_parts(mp_sel, RADII)
    samples = _axis_samples(parts, step=0.5)
    best = np.full(len(sel), np.inf)
    for i, j in SELF_PAIRS:
        for p in range(len(sel)):
            a, b = samples[i][p], samples[j][p]
            d = np.min(np.linalg.norm(a[:, None] - b[None], axis=-1)) - parts.radius[i] - parts.radius[j]
            best[p] = min(best[p], d)
    opts = Options(body=True)
    ref = evaluate_task(x, task.E[sel], task.e[sel], ALL_MODES[0], opts)
    ker = evaluate_task_numba(x, task.E[sel], task.e[sel], ALL_MODES[0], opts)
    # sampling every 0.5 mm overestimates by <= 0.5 mm; the chord polylines of the arcs by <= 0.2 mm
    assert np.all(ref.points.self_clearance_mm <= best + 0.2) and np.all(ref.points.self_clearance_mm >= best - 0.6)
    np.testing.assert_allclose(ker.points.self_clearance_mm, ref.points.self_clearance_mm, atol=1e-9)


def test_pairs_checked_follow_14_3() -> None:
    names = [p[0] for p in PRIMITIVES]
    pairs = {(names[i], names[j]) for i, j in SELF_PAIRS}
    assert ("frame_x", "frame_y") not in pairs  # they share O
    assert ("crank_x", "input_x") not in pairs  # they share D_x
    assert ("input_x", "coupler_x") not in pairs  # one leg, one stage
    assert ("spherical_alpha_x", "spherical_beta_y") not in pairs  # arcs are not checked against each other
    assert ("crank_x", "coupler_x") in pairs  # one leg, another stage, no shared joint
    assert ("frame_x", "crank_y") in pairs and ("input_x", "input_y") in pairs
    assert ("output_x", "spherical_alpha_x") not in pairs  # both hold Q_x


@pytest.mark.parametrize("engine", ["numpy", "numba"])
def test_collision_guards_fail_exactly_below_threshold_and_add_the_shortfall(setup, engine) -> None:
    task, x, mp, ok = setup
    centre = mp.C[ok].mean(axis=0) - 45.0 * task.e[ok].mean(axis=0)
    sdf = AnatomyDistance.from_boxes([(centre, np.array([45.0, 60.0, 25.0]), np.eye(3))])
    fn = evaluate_task if engine == "numpy" else (lambda *a: evaluate_task_numba(*a[:5], anatomy=a[5]))
    thin = {"link_radius": 1.0, "actuator_radius": 2.0, "motor_radius": 2.0}  # thin parts: some self clearances > 0
    free = fn(x, task.E, task.e, ALL_MODES[0], Options(body=True, **thin), sdf)
    clear, selfc = free.points.clearance_mm, free.points.self_clearance_mm
    base_ok = free.points.reachable
    c_min = float(np.nanquantile(clear[base_ok], 0.3))
    s_min = float(np.nanquantile(selfc[base_ok], 0.6))
    assert c_min > 0.0 and s_min > 0.0
    guarded = fn(x, task.E, task.e, ALL_MODES[0], Options(clearance_mm=c_min, self_clearance_mm=s_min, **thin), sdf)
    names = np.array([None] + list(FAILURES), dtype=object)[guarded.points.failure]
    np.testing.assert_array_equal(names[base_ok & (clear < c_min)], "collision/patient")
    np.testing.assert_array_equal(names[base_ok & (clear >= c_min) & (selfc < s_min)], "collision/self")
    assert np.array_equal(guarded.points.reachable, base_ok & (clear >= c_min) & (selfc >= s_min))
    # MODEL.md 16: reach first (the IK alone), then fit (each guard's shortfall over its 10 mm scale, at most 1)
    grade = np.where(
        base_ok,
        np.minimum(np.maximum(c_min - clear, 0) / 10.0, 1.0) + np.minimum(np.maximum(s_min - selfc, 0) / 10.0, 1.0),
        0.0,
    )
    n = len(task.E)
    G = np.sum(grade) / n
    want = (n - base_ok.sum()) / n + np.sum(free.points.excess) + G / (1.0 + G) / (2 * n)
    np.testing.assert_allclose(guarded.violation, want, rtol=1e-9)
    assert guarded.points.reachable.any() and guarded.clearance_min >= c_min
    assert np.isclose(free.clearance_min, np.nanmin(clear[base_ok]))


def test_batch_of_designs_equals_loop(setup) -> None:
    task, x, mp, ok = setup
    X = np.stack([x, x * np.r_[np.ones(23), 1.0, 1.0, 1.0, 0.9], reaching_design((0.0, 0.0, 0.0), 0.0, n=200)])
    centre = mp.C[ok].mean(axis=0) - 45.0 * task.e[ok].mean(axis=0)
    sdf = AnatomyDistance.from_boxes([(centre, np.array([45.0, 60.0, 25.0]), np.eye(3))])
    opts = Options(body=True)
    for fn in (evaluate_task, lambda *a: evaluate_task_numba(*a[:5], anatomy=a[5])):
        batch = fn(X, task.E, task.e, ALL_MODES[0], opts, sdf)
        for i in range(len(X)):
            one = fn(X[i], task.E, task.e, ALL_MODES[0], opts, sdf)
            np.testing.assert_allclose(batch.points.clearance_mm[i], one.points.clearance_mm, atol=1e-9)
            np.testing.assert_allclose(batch.points.self_clearance_mm[i], one.points.self_clearance_mm, atol=1e-9)


@pytest.mark.parametrize("guard, sam", [(False, False), (True, False), (True, True)])
def test_kernel_summaries_only_equal_the_per_point_minimum(setup, guard, sam) -> None:
    """Summaries-only runs start each point's search at a cap (the guard's limit or the smallest
    clearance so far): the summary must still be the minimum of the exact per-point values, and the
    graded violation (each point's shortfall) the same, within the search tolerance."""
    from arcube.evaluation.kernel._clearance import TOL_MM

    task, x, mp, ok = setup
    centre = mp.C[ok].mean(axis=0) - 45.0 * task.e[ok].mean(axis=0)
    sdf = AnatomyDistance.from_boxes([(centre, np.array([45.0, 60.0, 25.0]), np.eye(3))])
    thin = {"link_radius": 1.0, "actuator_radius": 2.0, "motor_radius": 2.0}
    free = evaluate_task_numba(
        x, task.E, task.e, ALL_MODES[0], Options(body=True, **thin), want_points=True, anatomy=sdf
    )
    clear = free.points.clearance_mm[free.points.reachable]
    c_min = float(np.quantile(clear, 0.3)) if guard else 0.0
    assert not guard or c_min > 0.0
    opts = Options(clearance_mm=c_min, single_assembly_mode=sam, **thin) if guard else Options(body=True, **thin)
    full = evaluate_task_numba(x, task.E, task.e, ALL_MODES[0], opts, want_points=True, anatomy=sdf)
    summ = evaluate_task_numba(x, task.E, task.e, ALL_MODES[0], opts, want_points=False, anatomy=sdf)
    passing = full.points.clearance_mm[full.points.reachable]
    assert passing.size > 10 and (not guard or passing.size < clear.size)
    assert abs(float(summ.clearance_min) - passing.min()) <= TOL_MM
    assert abs(float(summ.violation) - float(full.violation)) <= TOL_MM * len(task.E) / 10 + 1e-9
    assert float(summ.eta_G) == pytest.approx(float(full.eta_G), rel=1e-12)
    if guard:
        # what the optimizer runs: only the guard's decision and shortfall, the same violation; the
        # smallest clearance is then reported as a lower bound (the limit when every point clears it)
        decide = evaluate_task_numba(
            x, task.E, task.e, ALL_MODES[0], opts.replace(clearance_min_exact=False), want_points=False, anatomy=sdf
        )
        assert abs(float(decide.violation) - float(full.violation)) <= TOL_MM * len(task.E) / 10 + 1e-9
        assert float(decide.reachable_fraction) == pytest.approx(float(full.reachable_fraction), abs=2 / len(task.E))
        assert c_min - TOL_MM <= float(decide.clearance_min) <= passing.min() + TOL_MM


@pytest.mark.parametrize("sam", [False, True])
def test_self_guard_decision_only_gives_the_same_violation(setup, sam) -> None:
    """Summary-only runs that only decide the self-clearance guard (pairs pruned against its limit,
    arcs against their chord's capsule, straight pairs skipped while their bound carried from the
    previous point, less both parts' moves, stays above it) fail the same points by the same
    shortfall; with single_assembly_mode on too (it fails points only after all are seen)."""
    task, x, mp, ok = setup
    thin = {"link_radius": 1.0, "actuator_radius": 2.0, "motor_radius": 2.0}
    free = evaluate_task_numba(x, task.E, task.e, ALL_MODES[0], Options(body=True, **thin), want_points=True)
    s_min = float(np.nanquantile(free.points.self_clearance_mm[free.points.reachable], 0.5))
    assert s_min > 0.0
    opts = Options(self_clearance_mm=s_min, single_assembly_mode=sam, **thin)
    full = evaluate_task_numba(x, task.E, task.e, ALL_MODES[0], opts, want_points=True)
    decide = evaluate_task_numba(
        x, task.E, task.e, ALL_MODES[0], opts.replace(clearance_min_exact=False), want_points=False
    )
    assert 0.0 < float(full.reachable_fraction) < 1.0
    assert float(decide.reachable_fraction) == float(full.reachable_fraction)
    assert float(decide.violation) == pytest.approx(float(full.violation), rel=1e-12)


def test_carried_self_bounds_decide_as_the_exact_minimum_at_every_threshold(setup) -> None:
    """Along finely sampled lines the summary-only kernel skips a self-clearance pair while its bound
    carried from the previous point (less both parts' moves) stays above the limit: at every limit
    the graded violation and the reach equal those of the exact per-point minimum."""
    from arcube.evaluation.task import build_task

    task, x, mp, ok = setup
    a, b = task.E[::12], task.E[11::12]
    fine = build_task(np.concatenate([a, b]), np.concatenate([b, a]), 60)  # the same lines, 60 points each, both ways
    thin = {"link_radius": 1.0, "actuator_radius": 2.0, "motor_radius": 2.0}
    free = evaluate_task_numba(x, fine.E, fine.e, ALL_MODES[0], Options(body=True, **thin), want_points=True)
    values = free.points.self_clearance_mm[free.points.reachable]
    values = values[values > 0.0]  # a limit is >= 0
    assert values.size > 100 and np.ptp(values) > 5.0
    for q in np.linspace(0.05, 0.95, 10):
        opts = Options(self_clearance_mm=float(np.quantile(values, q)), **thin)
        full = evaluate_task_numba(x, fine.E, fine.e, ALL_MODES[0], opts, want_points=True)
        decide = evaluate_task_numba(
            x, fine.E, fine.e, ALL_MODES[0], opts.replace(clearance_min_exact=False), want_points=False
        )
        assert float(decide.reachable_fraction) == float(full.reachable_fraction), q
        assert float(decide.violation) == pytest.approx(float(full.violation), rel=1e-12), q
