"""The drawn mechanism closes: every animation frame of the report's 3D scene, and the geometry
arrays behind it, satisfy the closure equations of MODEL.md 3.1, 4.1, 5.1 and 6 to 1e-9.

The checks are written from MODEL.md (link lengths, planes, spherical angles), on the drawn
points themselves, not on the joint angles.
"""

from __future__ import annotations

import numpy as np
import pytest

from arcube.model.design import Design
from arcube.api import evaluate
from arcube.model.body import mechanism_points
from arcube.report.html import SCENE_TRACES, scene_figure

from designs import PAPER
from naive import NAMES, TRIADS, get, leg_triple, vec

TOL = 1e-9
PLACED = {**PAPER, "m_x": 88.23, "m_y": 79.40, "m_z": 56.89}
"""Table 2 placed so that it reaches every right-side trajectory of the reference patient."""


def angle(a, b):
    """Angle between vectors (..., 3), accurate at every angle (atan2 form)."""
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


def dist(a, b):
    return np.linalg.norm(np.asarray(a) - np.asarray(b), axis=-1)


@pytest.fixture(scope="module", params=[53.5671, 120.0], ids=["paper_dz", "dz120"])
def scene(request, tmp_path_factory):
    """The report's scene for the placed design (d_z as in Table 2: the dyad never closes; 120: it does)."""
    path = tmp_path_factory.mktemp("design") / "design.json"
    Design.from_dict({**PLACED, "d_z": request.param}).to_json(path)
    report = evaluate(str(path), "reference", points=30, side="R", engine="numpy")
    assert bool(report.results.w_G), "the placed design must reach every right-side point"
    return report, scene_figure(report)


def _traces(frame):
    """name -> (n, 3) array of the frame's drawn points, None gaps as NaN rows."""
    out = {}
    for name, tr in zip(SCENE_TRACES, frame.data):
        xyz = np.array([[np.nan if v is None else v for v in tr[c]] for c in "xyz"], dtype=float).T
        out[name] = xyz
    return out


def _split(xyz):
    """Polylines of a trace (split at NaN rows)."""
    parts, cur = [], []
    for row in xyz:
        if np.isnan(row).any():
            if cur:
                parts.append(np.array(cur))
            cur = []
        else:
            cur.append(row)
    if cur:
        parts.append(np.array(cur))
    return parts


def test_one_frame_per_reachable_point(scene):
    report, fig = scene
    assert len(fig.frames) == int(np.sum(report.results.points.reachable)) == len(report.task)
    assert len(fig.layout.sliders[0].steps) == len(fig.frames)


def test_every_frame_closes(scene):
    report, fig = scene
    x = report.design.to_vector()
    m = np.array([PLACED["m_x"], PLACED["m_y"], PLACED["m_z"]])
    f, p = leg_triple(x, "f"), leg_triple(x, "p")
    d, c, t = (np.array([get(x, f"{s}_x"), get(x, f"{s}_y")]) for s in ("d", "c", "t"))
    al, be = np.array([get(x, "alpha_x"), get(x, "alpha_y")]), np.array([get(x, "beta_x"), get(x, "beta_y")])
    r, d_z = get(x, "r"), get(x, "d_z")
    n_closed = 0
    for frame in fig.frames:
        i = int(frame.name[1:])
        E, e = report.task.E[i], report.task.e[i]
        tr = _traces(frame)
        frame_lines = _split(tr["frame"])
        cranks = _split(tr["cranks"])
        for u in range(3):
            u_hat, _, w_hat = TRIADS[u]
            O, P = frame_lines[u]
            np.testing.assert_allclose(O, m, atol=TOL)
            np.testing.assert_allclose(P, m - f[u] * u_hat, atol=TOL)  # P_u = -f_u û in R_m
            assert np.allclose(cranks[u][0], P, atol=TOL)
            assert abs(dist(cranks[u][1], P) - p[u]) < TOL  # crank |D_u - P_u| = p_u
            # D_u lies in the distal plane u = u_E + r, on the +ŵ side (principal branch).
            assert abs((cranks[u][1] - E) @ u_hat - r) < TOL
            assert (cranks[u][1] - P) @ w_hat >= -TOL
        for u, name in enumerate(("four-bar x", "four-bar y")):
            u_hat = TRIADS[u][0]
            ((D, K, T, Q),) = _split(tr[name])
            np.testing.assert_allclose(D, cranks[u][1], atol=TOL)
            np.testing.assert_allclose(Q, E + r * u_hat, atol=TOL)
            assert abs(dist(K, D) - d[u]) < TOL
            assert abs(dist(T, K) - c[u]) < TOL
            assert abs(dist(T, Q) - t[u]) < TOL
            for pt in (D, K, T, Q):  # the four-bar plane u = u_E + r
                assert abs((pt - E) @ u_hat - r) < TOL
        drill, holder = _split(tr["drill"])
        np.testing.assert_allclose(drill[0], E, atol=TOL)
        assert abs(angle(drill[1] - E, e)) < TOL
        H = holder[0]
        np.testing.assert_allclose(H, E + r * e, atol=TOL)
        for u, name in enumerate(("spherical x", "spherical y")):
            arc, (E2, B) = _split(tr[name])
            np.testing.assert_allclose(E2, E, atol=TOL)
            np.testing.assert_allclose(np.linalg.norm(arc - E, axis=-1), r, atol=TOL)  # on the sphere
            np.testing.assert_allclose(arc[0], E + r * TRIADS[u][0], atol=TOL)  # starts at E + r û = Q_u
            np.testing.assert_allclose(arc[-1], H, atol=TOL)  # ends at the drill holder
            S = (len(arc) + 1) // 2
            np.testing.assert_allclose(arc[S - 1], B, atol=TOL)
            assert abs(angle(arc[0] - E, B - E) - al[u]) < TOL  # proximal link alpha_u
            assert abs(angle(B - E, H - E) - be[u]) < TOL  # distal link beta_u
            # Each arc is a great circle: its points are coplanar with E and its two ends.
            for seg, a, b in ((arc[:S], arc[0], B), (arc[S - 1 :], B, H)):
                nrm = np.cross(a - E, b - E)
                assert np.max(np.abs((seg - E) @ nrm)) / (r**3) < TOL
        # z dyad: either closed (D_z -> J -> Q_z with links d_z, c_z = d_z) or drawn open (dashed).
        closed, open_ = _split(tr["z dyad"]), _split(tr["z dyad (open)"])
        assert len(closed) + len(open_) == 1
        Q_z = E + r * TRIADS[2][0]
        L = dist(Q_z, cranks[2][1])
        if closed:
            n_closed += 1
            ((Dz, J, Qz),) = closed
            np.testing.assert_allclose(Dz, cranks[2][1], atol=TOL)
            np.testing.assert_allclose(Qz, Q_z, atol=TOL)
            assert abs(dist(J, Dz) - d_z) < TOL and abs(dist(Qz, J) - d_z) < TOL
            assert abs((J - E)[2] - r) < TOL  # in the dyad plane z = z_E + r
            assert np.cross([0.0, 0.0, 1.0], Qz - Dz) @ (J - Dz) > 0  # documented elbow (+1)
            assert L <= 2 * d_z + TOL
        else:
            assert L > 2 * d_z  # c_z = d_z: it cannot close beyond 2 d_z
            assert "z dyad open" in frame.layout.title.text
    if d_z > 100:
        assert n_closed > 0


def test_geometry_arrays_close_in_every_working_mode(pose_bank):
    """Batch (designs x points) geometry at random reachable poses, all 16 working modes."""
    for x, mode, E, e in pose_bank[::3]:
        mp = mechanism_points(x, E, e, mode)
        assert mp.reachable.all()
        m = np.array([get(x, "m_x"), get(x, "m_y"), get(x, "m_z")])
        r = get(x, "r")
        for u in range(3):
            u_hat = TRIADS[u][0]
            np.testing.assert_allclose(
                mp.P[:, u], np.zeros((len(E), 1)) + m - get(x, f"f_{'xyz'[u]}") * u_hat, atol=TOL
            )
            np.testing.assert_allclose(dist(mp.D[:, u], mp.P[:, u]), get(x, f"p_{'xyz'[u]}"), atol=TOL)
            np.testing.assert_allclose((mp.D[:, u] - mp.Q[:, u]) @ u_hat, 0.0, atol=TOL)
        for u, leg in enumerate("xy"):
            np.testing.assert_allclose(dist(mp.K[:, u], mp.D[:, u]), get(x, f"d_{leg}"), atol=TOL)
            np.testing.assert_allclose(dist(mp.T[:, u], mp.K[:, u]), get(x, f"c_{leg}"), atol=TOL)
            np.testing.assert_allclose(dist(mp.T[:, u], mp.Q[:, u]), get(x, f"t_{leg}"), atol=TOL)
            np.testing.assert_allclose(angle(mp.Q[:, u] - E, mp.B[:, u] - E), get(x, f"alpha_{leg}"), atol=TOL)
            np.testing.assert_allclose(angle(mp.B[:, u] - E, mp.H - E), get(x, f"beta_{leg}"), atol=TOL)
            for arc in (mp.arc_alpha[:, u], mp.arc_beta[:, u]):
                np.testing.assert_allclose(np.linalg.norm(arc - E[:, None], axis=-1), r, atol=TOL)
        ok = mp.z_closes
        np.testing.assert_allclose(dist(mp.J_z[ok], mp.D[ok, 2]), get(x, "d_z"), atol=TOL)
        np.testing.assert_allclose(dist(mp.J_z[ok], mp.Q[ok, 2]), get(x, "d_z"), atol=TOL)
        assert np.isnan(mp.J_z[~ok]).all()


def test_batch_matches_single_and_unreachable_is_nan():
    """Designs x points broadcasting gives the same points as one design at a time; NaN where unreachable."""
    x = vec(PLACED)
    xs = np.stack([x, x + np.eye(23)[NAMES.index("m_x")] * 5.0])
    rng = np.random.default_rng(3)
    E = np.array([PLACED["m_x"] - 150.0, PLACED["m_y"] - 150.0, PLACED["m_z"] - 100.0]) + rng.normal(0, 5, (7, 3))
    e = np.tile([0.3, 0.0, 0.95], (7, 1))
    e /= np.linalg.norm(e, axis=-1, keepdims=True)
    batch = mechanism_points(xs[:, None, :], E[None], e[None])
    for k in range(2):
        one = mechanism_points(xs[k], E, e)
        np.testing.assert_allclose(batch.T[k], one.T, atol=1e-12, equal_nan=True)
    far = mechanism_points(x, E + 1000.0, e)
    assert not far.reachable.any() and np.isnan(far.D).all()
