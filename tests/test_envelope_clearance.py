"""The body's clearance to the envelope of the whole patient (MODEL.md 19.5): reference, kernel, guard, grading.

* the exact minimisation along a segment (reference: 49 candidates; kernel: slab clipping and the root of
  the squared distance's derivative) against dense samples and a bounded scalar minimiser; the arcs'
  lowest z against dense samples; their chord polylines within the stated sag;
* the clearance of whole bodies against a brute force over densely sampled axes (segments, points, arcs),
  within the stated bound, with the same part and region;
* the kernel equals the reference field by field (tests/test_kernel.py's comparison);
* a design beside and under the spine fails ``collision/envelope`` in both engines, one well above passes;
* the guard's grading is MODEL.md 16's, checked on a table whose clearance is computed here by hand;
* without an envelope, or with it but nothing asking for it, every result is bit for bit the same.
"""

from __future__ import annotations


import numpy as np
import pytest
import trimesh
from scipy.optimize import minimize_scalar

from compare import assert_matches, point_rtol as _point_rtol

from arcube.options import Outputs
from arcube.evaluation import kernel  # noqa: E402
from arcube.evaluation.anatomy import resolve_anatomy  # noqa: E402
from arcube.evaluation.envelope import Envelope, envelope_from_boxes, resolve_envelope  # noqa: E402
from arcube.evaluation.envelope_clearance import (  # noqa: E402
    ENVELOPE_ARC_CHORDS,
    _box_sd,
    arc_chord_points,
    arc_lowest_z,
    arc_sag_bound,
    envelope_clearance,
    pose_envelope_clearance,
    segment_box_min,
)
from arcube.evaluation.kernel._envelope_exact import _arc_lowest_z, _seg_box  # noqa: E402
from arcube.evaluation.reference import FAILURES, GUARDED_OPTIONS, IK_FAILURES, Options, evaluate_points, evaluate_task  # noqa: E402
from arcube.evaluation.task import build_task  # noqa: E402
from arcube.io import load_trajectories, select  # noqa: E402
from arcube.model.body import N_ARCS, N_SEGMENTS, PRIMITIVE_PART, BodyParts, BodyRadii, body_parts, mechanism_points  # noqa: E402
from arcube.model.design import Design  # noqa: E402
from arcube.model.frames import rotation_matrix  # noqa: E402
from arcube.model.mechanism import ALL_MODES  # noqa: E402

PLAN = load_trajectories("reference")
RIGHT = select(PLAN, side="R")
CODE = {name: i + 1 for i, name in enumerate(FAILURES)}
MODE = ALL_MODES[0]


def _designs(task, n: int, seed: int, spread: tuple[float, float, float] = (5.0, 20.0, 25.0)) -> np.ndarray:
    """Random designs whose cube diagonal points posterior, the TLS box centred on the task, L in [0, 200] mm,
    then moved by normal offsets of ``spread`` mm: bodies beside, above and in the envelope."""
    rng = np.random.default_rng(seed)
    X = np.zeros((n, 27))
    X[:, 3:16] = rng.uniform(30, 200, (n, 13))
    X[:, 16] = rng.uniform(50, 80, n)
    X[:, 17:19] = rng.uniform(-180, 180, (n, 2))
    X[:, 19:23] = rng.uniform(60, 90, (n, 4))
    X[:, 23:26] = (-135.0, -144.74, -67.63)
    X[:, 26] = rng.uniform(0, 200, n)
    R = rotation_matrix(np.radians(X[0, 23:26]))
    C = task.E.mean(axis=0) + X[:, 26:27] * task.e.mean(axis=0)
    X[:, :3] = C - (-X[:, 3:6] - X[:, 16:17]) @ R.T + rng.normal(0, 1, (n, 3)) * spread
    return X


@pytest.fixture(scope="module")
def task():
    return build_task(RIGHT.entry, RIGHT.target, 8)


@pytest.fixture(scope="module")
def near(task) -> np.ndarray:
    """40 designs (of 3000) whose stages solve the most points: every body has a clearance."""
    X = _designs(task, 3000, 5)
    r = kernel.evaluate_task_numba(X, task.E, task.e, MODE, Options())
    solved = np.sum((r.points.failure == 0) | (r.points.failure > 7), axis=1)
    return X[np.argsort(-solved, kind="stable")[:40]]


@pytest.fixture(scope="module")
def envelopes() -> dict[str, Envelope]:
    """The reference patient's default envelope, and the same with the table raised to z = 30 mm (so that it binds)."""
    return {
        "default": resolve_envelope("default", PLAN, None),
        "high table": resolve_envelope("default", PLAN, None, table_z=30.0),
    }


# ----------------------------------------------------------------------------- pieces


def _segments(rng, n: int) -> tuple[np.ndarray, ...]:
    c = rng.uniform(-20, 20, (n, 3))
    h = rng.uniform(2, 40, (n, 3))
    a = c + rng.uniform(-80, 80, (n, 3))
    b = a + rng.uniform(-120, 120, (n, 3))
    k = n // 8
    b[:k] = a[:k]  # points
    b[k : 2 * k, 1:] = a[k : 2 * k, 1:]  # along x
    a[2 * k : 3 * k] = c[2 * k : 3 * k] + rng.uniform(-0.5, 0.5, (k, 3)) * h[2 * k : 3 * k]  # starting inside the box
    b[3 * k : 4 * k] = 2 * c[3 * k : 4 * k] - a[3 * k : 4 * k]  # through the centre
    a[4 * k : 5 * k, 2] = c[4 * k : 5 * k, 2] + h[4 * k : 5 * k, 2] + 3.0  # parallel to and over the top face
    b[4 * k : 5 * k, 2] = a[4 * k : 5 * k, 2]
    return a, b, c, h


def test_segment_minimum_is_exact_in_both_engines() -> None:
    rng = np.random.default_rng(3)
    a, b, c, h = _segments(rng, 400)
    ref = segment_box_min(a, b, c, h)
    ker = np.array([_seg_box(*a[i], *b[i], *c[i], *h[i]) for i in range(len(a))])
    np.testing.assert_allclose(ker, ref, rtol=0, atol=1e-9)
    t = np.linspace(0.0, 1.0, 20001)
    for i in range(len(a)):
        f = lambda s: float(_box_sd((a[i] + s * (b[i] - a[i]))[None], c[i], h[i])[0])  # noqa: E731
        sampled = _box_sd(a[i] + t[:, None] * (b[i] - a[i]), c[i], h[i])
        step = np.linalg.norm(b[i] - a[i]) / (len(t) - 1)
        assert ref[i] <= sampled.min() + 1e-12 and ref[i] >= sampled.min() - step / 2 - 1e-12, i
        brent = minimize_scalar(f, bounds=(0.0, 1.0), method="bounded", options={"xatol": 1e-12}).fun
        assert ref[i] <= brent + 1e-9, (i, ref[i], brent)  # and it is a value of f on the segment: the least
    assert np.any(ref < 0) and np.any(ref > 0)
    assert np.all(np.isnan(segment_box_min(np.full(3, np.nan), b[0], c[0], h[0])))


def _arc_parts(rng, n: int) -> BodyParts:
    """BodyParts holding random great-circle arcs of up to 180 degrees (segments and points unused)."""
    a = rng.normal(size=(n, N_ARCS, 3))
    a /= np.linalg.norm(a, axis=-1, keepdims=True)
    w = rng.normal(size=(n, N_ARCS, 3))
    w -= np.sum(w * a, axis=-1, keepdims=True) * a
    w /= np.linalg.norm(w, axis=-1, keepdims=True)
    theta = rng.uniform(0.0, np.pi, (n, N_ARCS, 1))
    theta[:, 0] = 0.0  # a zero arc
    b = a * np.cos(theta) + w * np.sin(theta)
    return BodyParts(
        np.zeros((n, N_SEGMENTS, 2, 3)),
        np.zeros((n, 5, 3)),
        rng.uniform(-50, 50, (n, 3)),
        rng.uniform(50, 80, n),
        np.stack([a, b], axis=-2),
        np.ones(27),
    )


def test_arcs_lowest_point_and_chords() -> None:
    rng = np.random.default_rng(4)
    parts = _arc_parts(rng, 30)
    low = arc_lowest_z(parts)
    a, b = parts.arc_ends[..., 0, :], parts.arc_ends[..., 1, :]
    theta = np.arccos(np.clip(np.sum(a * b, axis=-1), -1.0, 1.0))
    phi = np.linspace(0.0, 1.0, 20001)
    chords = arc_chord_points(parts)
    for i in range(30):
        for j in range(N_ARCS):
            w = b[i, j] - np.dot(a[i, j], b[i, j]) * a[i, j]
            nw = np.linalg.norm(w)
            w = w / nw if nw > 1e-12 else w * 0.0
            dirs = np.cos(phi * theta[i, j])[:, None] * a[i, j] + np.sin(phi * theta[i, j])[:, None] * w
            pts = parts.arc_centre[i] + parts.arc_radius[i] * dirs
            z = pts[:, 2].min()
            r = parts.arc_radius[i]
            assert low[i, j] <= z + 1e-12 and low[i, j] >= z - r * (theta[i, j] / (len(phi) - 1)) ** 2, (i, j)
            assert _arc_lowest_z(*a[i, j], *b[i, j], parts.arc_centre[i, 2], r) == pytest.approx(low[i, j], abs=1e-12)
            # chord vertices on the arc, ends exact; every arc point within the sag of the polyline
            V = chords[i, j]
            np.testing.assert_allclose(np.linalg.norm(V - parts.arc_centre[i], axis=-1), r, rtol=1e-12)
            assert np.array_equal(V[0], parts.arc_centre[i] + r * a[i, j]) and np.array_equal(
                V[-1], parts.arc_centre[i] + r * b[i, j]
            )
            seg = V[1:] - V[:-1]
            s = np.clip(
                np.einsum("pkd,kd->pk", pts[::5, None] - V[:-1], seg) / np.maximum(np.sum(seg * seg, -1), 1e-300), 0, 1
            )
            gap = np.min(np.linalg.norm(pts[::5, None] - (V[:-1] + s[..., None] * seg), axis=-1), axis=-1)
            assert gap.max() <= arc_sag_bound(r, theta[i, j]) + 1e-9
    # the stated bound: 0.043 mm for r <= 80 mm and theta <= 90 deg; 0.5 mm up to r = 233 mm at 180 deg
    assert arc_sag_bound(80.0, np.pi / 2) < 0.043 and arc_sag_bound(233.0, np.pi) < 0.5


# ----------------------------------------------------------------------------- whole bodies


def _brute_force(parts: BodyParts, env: Envelope, step: float = 0.05) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per body (leading axis), the least over every primitive's axis sampled every ``step`` mm and over the regions
    of the region's distance minus the primitive's radius: (values (n, 27, regions), written here)."""
    n = parts.segments.shape[0]
    lines = np.concatenate([parts.segments, np.stack([parts.spheres, parts.spheres], axis=-2)], axis=-3)
    out = np.empty((n, 27, len(env.names)))
    for i in range(n):
        for k in range(lines.shape[1]):
            a, b = lines[i, k]
            m = int(np.ceil(np.linalg.norm(b - a) / step)) + 1
            pts = a + np.linspace(0, 1, m)[:, None] * (b - a)
            out[i, k] = env.region_distances(pts).min(axis=0)
        for j in range(N_ARCS):
            a, b = parts.arc_ends[i, j]
            th = np.arccos(np.clip(np.dot(a, b), -1, 1))
            w = b - np.dot(a, b) * a
            w = w / np.linalg.norm(w) if np.linalg.norm(w) > 1e-12 else 0 * w
            m = int(np.ceil(parts.arc_radius[i] * th / step)) + 1
            ph = np.linspace(0, th, m)[:, None]
            pts = parts.arc_centre[i] + parts.arc_radius[i] * (np.cos(ph) * a + np.sin(ph) * w)
            out[i, N_SEGMENTS + 5 + j] = env.region_distances(pts).min(axis=0)
    return out - parts.radius[:, None]


def test_clearance_equals_brute_force_over_the_body(task, near, envelopes) -> None:
    X = near[:12]
    k = np.arange(0, len(task), 10)  # 4 points per design
    mp = mechanism_points(X[:, None], task.E[k], task.e[k], MODE, motor_length=120.0)
    parts = body_parts(mp, BodyRadii())
    flat = BodyParts(
        *(np.reshape(f, (-1,) + np.shape(f)[2:]) if np.ndim(f) > 1 and f is not parts.radius else f for f in parts)
    )
    ok = np.all(np.isfinite(flat.segments), axis=(-1, -2, -3))
    flat = BodyParts(*(f[ok] if f is not flat.radius else f for f in flat))
    for name, env in envelopes.items():
        got = envelope_clearance(flat, env)
        brute = _brute_force(flat, env)
        best = brute.reshape(len(brute), -1).min(axis=-1)
        sag = float(arc_sag_bound(80.0, np.pi / 2))  # r <= 80, arcs <= 90 deg here
        assert np.all(got.clearance <= best + sag + 1e-9) and np.all(got.clearance >= best - 0.025 - sag - 1e-9), name
        # the part and the region named attain the least within the error (parts meeting at a joint tie)
        tol = 0.025 + 2 * sag + 1e-9
        per_part = np.full((len(brute), 24), np.inf)
        for p in range(27):
            per_part[:, PRIMITIVE_PART[p]] = np.minimum(per_part[:, PRIMITIVE_PART[p]], brute[:, p].min(axis=-1))
        at = np.arange(len(brute))
        assert np.all(per_part[at, got.part] <= best + tol) and np.all(
            brute.min(axis=1)[at, got.region] <= best + tol
        ), name
        alone = np.sort(per_part, axis=-1)[:, 1] > best + 2 * tol  # one part clearly closest: it is the one named
        assert alone.mean() > 0.2
        np.testing.assert_array_equal(got.part[alone], np.argmin(per_part, axis=-1)[alone])
    assert set(got.region.tolist()) >= {1, 2, 3}  # head, torso and the raised table bind somewhere


def test_kernel_equals_reference_field_by_field(task, near, envelopes) -> None:
    modes = ALL_MODES[np.random.default_rng(6).integers(0, 16, len(near))]
    seen_regions, seen_parts = set(), set()
    variants = (
        Options(envelope_clearance_mm=10.0),
        Options(outputs=Outputs(envelope_clearance=True)),
        Options(clearances=True),
        GUARDED_OPTIONS.replace(
            guards=GUARDED_OPTIONS.guards.replace(envelope_clearance_mm=20.0, self_clearance_mm=2.0)
        ),
    )
    for env, option_set in ((envelopes["default"], variants[:1]), (envelopes["high table"], variants)):
        for options in option_set:
            ref = evaluate_task(near, task.E, task.e, modes, options, envelope=env)
            rtol = _point_rtol(near, task.E, task.e, modes, ref)
            for want in (True, False):
                got = kernel.evaluate_task_numba(near, task.E, task.e, modes, options, want_points=want, envelope=env)
                assert_matches(got, ref, rtol, want_points=want)
            seen_regions |= set(ref.points.envelope_region.ravel().tolist())
            seen_parts |= set(ref.points.envelope_part.ravel().tolist())
            if options.guards.envelope_clearance_mm == 10.0:
                assert np.any(ref.points.failure == CODE["collision/envelope"]) and np.any(ref.w_G)
    assert seen_regions >= {0, 1, 2, 3} and len(seen_parts) >= 5
    # one design, the point-chunk path, and the exact path
    ref = evaluate_task(
        near[3], task.E, task.e, modes[3], Options(envelope_clearance_mm=10.0), envelope=envelopes["default"]
    )
    got = kernel.evaluate_task_numba(
        near[3],
        task.E,
        task.e,
        modes[3],
        Options(envelope_clearance_mm=10.0),
        exact=True,
        envelope=envelopes["default"],
    )
    assert_matches(got, ref, _point_rtol(near[3], task.E, task.e, modes[3], ref))


def test_the_kernels_carried_bounds_along_dense_paths(task, near, envelopes) -> None:
    """The kernel carries each pair's bound from point to point (its value less how far the primitive moved): along
    dense paths that sweep the body towards and away from the boxes, and jump between them, it still equals the
    reference at every point."""
    rng = np.random.default_rng(8)
    t = np.linspace(0.0, 1.0, 150)[:, None]
    E = np.concatenate(
        [
            task.E[0] + t * (80.0 * task.e[0] + (0.0, -60.0, 0.0)),
            task.E[20] + t * (0.0, 90.0, 40.0),
            task.E[rng.integers(0, len(task), 30)],
        ]
    )
    e = np.concatenate(
        [
            np.repeat(task.e[[0]], 150, axis=0),
            np.repeat(task.e[[20]], 150, axis=0),
            task.e[rng.integers(0, len(task), 30)],
        ]
    )
    X, env = near[:8], envelopes["high table"]
    ref = evaluate_task(X, E, e, MODE, Options(outputs=Outputs(envelope_clearance=True)), envelope=env)
    got = kernel.evaluate_task_numba(X, E, e, MODE, Options(outputs=Outputs(envelope_clearance=True)), envelope=env)
    assert_matches(got, ref, _point_rtol(X, E, e, MODE, ref))
    assert (
        np.sum(np.isfinite(ref.points.envelope_clearance_mm)) > 1000
        and len(set(ref.points.envelope_region.ravel().tolist())) >= 3
    )


def test_a_skin_mesh_envelope_in_both_engines(task, near) -> None:
    """A user's skin (a closed mesh, searched on the anatomy's grids) and a table: the kernel within the anatomy
    clearance's tolerance of the reference (tests/test_kernel.py CLEARANCE)."""
    skin = trimesh.creation.box(extents=(70.0, 90.0, 60.0))  # few triangles: its grids build in a second
    skin.apply_transform(trimesh.transformations.rotation_matrix(0.4, (1.0, 2.0, 0.5)))
    skin.apply_translation(task.E.mean(axis=0) + (0.0, 0.0, 20.0))
    env = Envelope(np.zeros((0, 7)), ("skin", "table"), 10.0, (skin,), "test skin")
    options = Options(envelope_clearance_mm=10.0)
    k = np.arange(0, len(task), 2)
    ref = evaluate_task(near[:8], task.E[k], task.e[k], MODE, options, envelope=env).points
    got = kernel.evaluate_task_numba(near[:8], task.E[k], task.e[k], MODE, options, envelope=env).points
    np.testing.assert_array_equal(np.isnan(got.envelope_clearance_mm), np.isnan(ref.envelope_clearance_mm))
    d = np.abs(got.envelope_clearance_mm - ref.envelope_clearance_mm)
    assert np.nanmax(d) <= 0.15
    assert set(ref.envelope_region[ref.envelope_region >= 0].tolist()) == {0, 1}
    decided = np.abs(ref.envelope_clearance_mm - 10.0) > 0.15
    np.testing.assert_array_equal(got.failure[decided], ref.failure[decided])


# ----------------------------------------------------------------------------- the guard


UNDER = (-135.0, 35.26, -112.37)
"""Mounting angles (deg) that turn the cube's diagonal to point anterior (-z): the frame m below the spine."""


def test_a_frame_beside_and_under_the_spine_fails_and_one_above_passes(task) -> None:
    env = resolve_envelope("default", PLAN, resolve_anatomy("default", "LPS", "reference"))
    options = Options(envelope_clearance_mm=10.0)
    x = Design.preset("paper").to_vector()
    x[:3] = (88.23, 79.40, 56.89)  # Table 2's links where the README places them for the right side: beside the neck
    under = _designs(task, 2000, 12, spread=(0.0, 0.0, 0.0))
    under[:, 23:26] = UNDER
    R = rotation_matrix(np.radians(UNDER))
    np.testing.assert_allclose(R @ np.ones(3) / np.sqrt(3), (0.0, 0.0, -1.0), atol=1e-4)
    C = task.E.mean(axis=0) + under[:, 26:27] * task.e.mean(axis=0)
    under[:, :3] = C - (-under[:, 3:6] - under[:, 16:17]) @ R.T
    plain = kernel.evaluate_task_numba(under, task.E, task.e, MODE, Options())
    reach = under[plain.w_G][:3]  # designs that reach every point, their frame far under the spine
    assert len(reach) >= 1 and np.all(reach[:, 2] < env.landmarks.z_s - 150.0)
    for X in (x, *reach):
        P = mechanism_points(X, task.E[:1], task.e[:1]).P[0]
        assert P[:, 2].min() < env.landmarks.z_s  # a crank pivot under the skin
        for run in (evaluate_task, kernel.evaluate_task_numba):
            r = run(X, task.E, task.e, MODE, options, envelope=env)
            solved = (r.points.failure == 0) | (r.points.failure > IK_FAILURES)
            assert solved.all() and not r.w_G
            assert np.all(r.points.failure == CODE["collision/envelope"])
            assert np.all(r.points.envelope_clearance_mm < 10.0)
    above = _designs(task, 400, 11, spread=(0.0, 0.0, 0.0))
    without = kernel.evaluate_task_numba(above, task.E, task.e, MODE, Options())
    got = kernel.evaluate_task_numba(above, task.E, task.e, MODE, options, envelope=env)
    assert (
        got.w_G.sum() >= 5 and np.all(without.w_G[got.w_G]) and np.sum(without.w_G) > np.sum(got.w_G)
    )  # the guard removed some
    pick = np.concatenate([np.flatnonzero(got.w_G)[:5], np.flatnonzero(without.w_G & ~got.w_G)[:5]])
    ref = evaluate_task(above[pick], task.E, task.e, MODE, options, envelope=env)
    np.testing.assert_array_equal(ref.w_G, got.w_G[pick])
    assert np.all(ref.envelope_clearance_min[:5] >= 10.0) and np.all(got.envelope_clearance_min[pick[:5]] >= 10.0)
    failed = ref.points.failure[5:]
    assert np.all((failed == 0) | (failed == CODE["collision/envelope"])) and np.all(np.any(failed > 0, axis=-1))


def _lowest_clearance(X: np.ndarray, task, table_z: float) -> np.ndarray:
    """Per point, the least z over the body's parts (segment ends, points, arcs sampled every 0.001 rad: written
    here) less each part's radius and the table: the clearance to a table alone, ``(P,)`` mm."""
    radii = BodyRadii()
    mp = mechanism_points(X, task.E, task.e, MODE, motor_length=radii.motor_length, arc_samples=1571)
    parts = body_parts(mp, radii)
    z = [parts.segments[..., s, :, 2].min(axis=-1) - radii.link for s in range(N_SEGMENTS - 1)]
    z.append(parts.segments[..., N_SEGMENTS - 1, :, 2].min(axis=-1) - radii.motor)
    z += [parts.spheres[..., s, 2] - radii.actuator for s in range(5)]
    z += [
        arc[..., 2].min(axis=-1) - radii.link
        for arc in (*np.moveaxis(mp.arc_alpha, -3, 0), *np.moveaxis(mp.arc_beta, -3, 0))
    ]
    return np.min(z, axis=0) - table_z


def test_grading_follows_model_16(task) -> None:
    above = _designs(task, 400, 11, spread=(0.0, 0.0, 0.0))
    r = kernel.evaluate_task_numba(above, task.E, task.e, MODE, Options())
    X = above[np.flatnonzero(r.w_G)[0]]
    low = _lowest_clearance(X, task, 0.0)
    table_z = float(np.min(low)) - 2.0  # the body 2 mm above the table at its lowest point
    env = envelope_from_boxes(np.zeros((0, 7)), [], table_z)
    c = low - table_z
    n = len(c)
    assert np.ptp(c) > 10.0  # limits below give shortfalls under the scale at some points and past it at others
    for limit in (1.0, 5.0, 10.0, 20.0, c.max() + 15.0):
        s = np.maximum(limit - c, 0.0)
        G = np.sum(np.minimum(s / 10.0, 1.0)) / n  # MODEL.md 16: min(s / S, 1) per point, S = 10 mm
        V = G / (1.0 + G) / (2 * n)
        for run in (evaluate_task, kernel.evaluate_task_numba):
            res = run(X, task.E, task.e, MODE, Options(envelope_clearance_mm=limit), envelope=env)
            np.testing.assert_allclose(res.points.envelope_clearance_mm, c, atol=1e-6)
            assert res.guard_grade == pytest.approx(G * n, abs=1e-6) and res.violation == pytest.approx(
                V, rel=1e-6, abs=1e-15
            )
            assert np.array_equal(res.points.failure == CODE["collision/envelope"], c < limit)
            assert (res.violation == 0.0) == bool(np.all(c >= limit)) == bool(res.w_G) and res.violation < 1 / (2 * n)
        if limit == c.max() + 15.0:
            assert G == 1.0  # every point's shortfall past the scale: each counts 1


def test_failure_order_and_both_terms(task, near, envelopes) -> None:
    """A point short of both the self clearance and the envelope reports collision/self (the earlier reason) and
    adds both terms; the envelope's comes after the anatomy's too."""
    options = Options(self_clearance_mm=1000.0, envelope_clearance_mm=1000.0)
    for run in (evaluate_task, kernel.evaluate_task_numba):
        r = run(near, task.E, task.e, MODE, options, envelope=envelopes["default"])
        solved = (r.points.failure == 0) | (r.points.failure > IK_FAILURES)
        assert solved.any() and np.all(r.points.failure[solved] == CODE["collision/self"])
        np.testing.assert_array_equal(r.points.guard_grade[solved], 2.0)
    assert (
        FAILURES.index("collision/patient")
        < FAILURES.index("collision/self")
        < FAILURES.index("collision/envelope")
        == len(FAILURES) - 1
    )


def test_without_an_envelope_every_result_is_unchanged(task, near, envelopes) -> None:
    env = envelopes["high table"]
    near = near[::2]
    for run in (evaluate_task, kernel.evaluate_task_numba):
        for options in (Options(), GUARDED_OPTIONS, Options(self_clearance_mm=2.0, clearances=True)):
            base = run(near, task.E, task.e, MODE, options)
            cases = [
                run(near, task.E, task.e, MODE, options, envelope=env),  # an envelope nothing asks for
                run(
                    near,
                    task.E,
                    task.e,
                    MODE,
                    options.replace(guards=options.guards.replace(envelope_clearance_mm=10.0)),
                ),  # a guard, no envelope
            ]
            if not options.outputs.clearances:  # computed, not guarded: every other field as before
                cases.append(
                    run(
                        near,
                        task.E,
                        task.e,
                        MODE,
                        options.replace(outputs=options.outputs.replace(envelope_clearance=True)),
                        envelope=env,
                    )
                )
            for k, other in enumerate(cases):
                for field in base._fields[1:]:
                    if field == "envelope_clearance_min" and k == 2:
                        continue
                    np.testing.assert_array_equal(getattr(other, field), getattr(base, field), err_msg=field)
                for field in base.points._fields:
                    if field.startswith("envelope") and (k == 2 or options.outputs.clearances and k == 0):
                        continue
                    np.testing.assert_array_equal(
                        getattr(other.points, field), getattr(base.points, field), err_msg=field
                    )
            assert np.all(np.isnan(base.points.envelope_clearance_mm)) and np.all(base.points.envelope_part == -1)


def test_program_states_batch_equals_loop_and_the_evaluation(task, near, envelopes) -> None:
    """The per-state clearance a program's check needs (MODEL.md 17.2): states along a line from a plan point."""
    env = envelopes["high table"]
    E = task.E[0] + np.linspace(0.0, 60.0, 25)[:, None] * task.e[0]
    e = np.broadcast_to(task.e[0], E.shape)
    X = near[0]
    batch = pose_envelope_clearance(X, E, e, env, MODE)
    loop = [pose_envelope_clearance(X, E[i], e[i], env, MODE) for i in range(len(E))]
    np.testing.assert_array_equal(batch.clearance, [v.clearance for v in loop])
    np.testing.assert_array_equal(batch.region, [v.region for v in loop])
    pts = evaluate_points(X, E, e, MODE, Options(outputs=Outputs(envelope_clearance=True)), envelope=env)
    np.testing.assert_array_equal(batch.clearance, pts.envelope_clearance_mm)
    np.testing.assert_array_equal(batch.part, pts.envelope_part)
    assert np.all(np.isfinite(batch.clearance)) and ENVELOPE_ARC_CHORDS == 24
