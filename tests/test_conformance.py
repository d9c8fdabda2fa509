"""Conformance of the array-first functions of :mod:`arcube.model`, in the spirit of
scikit-learn's ``check_estimator``: one reusable checker, :func:`check_array_function`, applied
to every public array function with inputs built from real designs and real task points.

The contract checked (the one the module docstrings state):

* **broadcast**: designs ``(D, 1, ...)`` against points ``(1, N, ...)`` give ``(D, N, ...)``
  outputs, each case equal (to 1e-12, NaN where NaN) to a call on that single case alone;
* **single**: a single case (no leading axes; a scalar where the core is a scalar) is the
  size-1 case: it equals the ``(1, ...)`` call and the matching slice of the batch, and so do
  a batch of designs against one point and one design against a batch of points;
* **nan**: NaN appears only at unreachable cases, i.e. where an argument of an IK equation
  has |arg| > 1 (or an assembly fails), never at reachable ones; where the function states it,
  exactly there; cases known to be reachable or unreachable by construction are classified so;
* **mutation**: no input array is modified.

Data. Three designs in the 27-parameter layout (the paper's Table 2 placed at m = (88.2, 79.4,
56.9) on the reference patient's right side; the same with a mounting rotation; with 1 % longer
links and a tool offset L = 3 mm), each in its own working mode. Points: drill poses of the
reference patient's right-side trajectories that all three reach (checked by an IK -> FK round
trip), poses only the first design reaches, poses moved 1 km away (no crank reaches: unreachable
by construction), a reversed drill axis and the axis +x (the spherical stage's leg x is
degenerate there: arg = inf).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray

from arcube.io.load import load_plan
from arcube.evaluation.task import build_task
from arcube.model import frames, poses
from arcube.model.body import mechanism_points
from arcube.model.design import INDEX, PARAM_NAMES, Design, full_params, unpack
from arcube.model.mechanism import ALL_MODES, forward_kinematics, inverse_kinematics, velocity_model
from arcube.model.stages import rts, tls, tms

RTOL = ATOL = 1e-12
CHECKS = ("broadcast", "single", "nan", "mutation")

# ============================================================================ the checker


@dataclass(frozen=True)
class Arg:
    """One positional argument: ``design`` ``(D, *core)``, ``point`` ``(N, *core)``, or ``grid``
    ``(D, N, *core)`` (a value that depends on both, e.g. joint angles of design d at point n)."""

    value: NDArray[Any]
    kind: str
    core_ndim: int = 1

    def batched(self) -> NDArray[Any]:
        """The argument as it enters the ``(D, N)`` batch: ``(D, 1, *core)``, ``(1, N, *core)``, ``(D, N, *core)``."""
        return {"design": lambda v: v[:, None], "point": lambda v: v[None], "grid": lambda v: v}[self.kind](self.value)

    def at(self, d: int | slice, n: int | slice) -> NDArray[Any]:
        """Case (d, n) with the leading axes the indices leave (an int drops its axis)."""
        return {"design": lambda v: v[d], "point": lambda v: v[n], "grid": lambda v: v[d, n]}[self.kind](self.value)


@dataclass(frozen=True)
class Inputs:
    """The arguments of a function and what is known about its cases by construction:
    ``known`` ``(D, N)`` int, 1 = reachable, 0 = unreachable, -1 = unknown."""

    args: tuple[Arg, ...]
    known: NDArray[np.int8] | None = None
    kwargs: Mapping[str, Any] = field(default_factory=dict)

    @property
    def shape(self) -> tuple[int, int]:
        D = N = 1
        for a in self.args:
            lead = a.value.shape[: a.value.ndim - a.core_ndim]
            if a.kind == "design":
                D = lead[0]
            elif a.kind == "point":
                N = lead[0]
            else:
                D, N = lead
        return D, N


def leaves(out: Any, prefix: str = "") -> dict[str, NDArray[Any]]:
    """Arrays of an output (array, tuple, NamedTuple, nested), keyed ``"0"``, ``"rho"``, ``"terms.F"``."""
    if isinstance(out, tuple):
        names = out._fields if hasattr(out, "_fields") else [str(i) for i in range(len(out))]
        return {k: v for name, item in zip(names, out) for k, v in leaves(item, f"{prefix}{name}.").items()}
    return {prefix.rstrip(".") or "out": np.asarray(out)}


def _same(got: NDArray[Any], want: NDArray[Any], what: str) -> None:
    assert got.shape == want.shape, f"{what}: shape {got.shape}, expected {want.shape}"
    if got.dtype.kind in "fc":
        np.testing.assert_allclose(got, want, rtol=RTOL, atol=ATOL, equal_nan=True, err_msg=what)
    else:
        np.testing.assert_array_equal(got, want, err_msg=what)


def _expand(mask: NDArray[np.bool_], shape: tuple[int, ...]) -> NDArray[np.bool_]:
    """A per-case (or per-leg) mask broadcast over the trailing axes of a leaf."""
    m = np.asarray(mask, dtype=bool)
    return np.broadcast_to(m.reshape(m.shape + (1,) * (len(shape) - m.ndim)), shape)


def check_array_function(
    fn: Callable[..., Any],
    make_args: Callable[[], Inputs],
    *,
    reachable: Callable[[Any, tuple[NDArray[Any], ...]], NDArray[np.bool_]] | None = None,
    nan_where: Callable[[Any, tuple[NDArray[Any], ...]], Mapping[str, NDArray[np.bool_]]] | None = None,
    checks: tuple[str, ...] = CHECKS,
) -> None:
    """Assert the array-function contract (module docstring) for ``fn`` on ``make_args()``.

    ``reachable(out, args)`` gives the ``(D, N)`` reachable cases of the batched call from its
    IK arguments (default: every case; then ``fn`` must never return NaN). ``nan_where(out,
    args)`` maps output leaves to the exact mask where they must be NaN (broadcast over trailing
    axes); other float leaves must be NaN-free at reachable cases, and every unreachable case
    must have a NaN somewhere. Raises AssertionError naming the failed check.
    """
    inputs = make_args()
    D, N = inputs.shape
    pristine = [a.value.copy() for a in inputs.args]
    call = lambda *xs: fn(*xs, **inputs.kwargs)  # noqa: E731
    batched_args = tuple(a.batched() for a in inputs.args)
    out = call(*batched_args)
    batch = leaves(out)
    for name, leaf in batch.items():
        assert leaf.shape[:2] == (D, N), f"broadcast: leaf {name} has shape {leaf.shape}, expected leading {(D, N)}"

    if "broadcast" in checks:
        for d in range(D):
            for n in range(N):
                single = leaves(call(*(a.at(d, n) for a in inputs.args)))
                assert single.keys() == batch.keys()
                for name, leaf in batch.items():
                    _same(
                        single[name],
                        leaf[d, n],
                        f"broadcast: leaf {name}, case (d={d}, n={n}) alone vs in the (D, N) batch",
                    )

    if "single" in checks:
        for d, n in sorted({(0, 0), (D - 1, N - 1), (D // 2, N // 2)}):
            one = leaves(call(*(a.at(d, n)[None] for a in inputs.args)))
            alone = leaves(call(*(a.at(d, n) for a in inputs.args)))
            for name, leaf in batch.items():
                _same(one[name], leaf[d, n][None], f"single: leaf {name}, size-1 call of case ({d}, {n}) vs the batch")
                _same(
                    alone[name],
                    one[name][0],
                    f"single: leaf {name}, case ({d}, {n}) without leading axes vs the size-1 call",
                )
            designs = leaves(call(*(a.at(slice(None), n) for a in inputs.args)))
            points = leaves(call(*(a.at(d, slice(None)) for a in inputs.args)))
            for name, leaf in batch.items():
                _same(designs[name], leaf[:, n], f"single: leaf {name}, all designs against the single point {n}")
                _same(points[name], leaf[d, :], f"single: leaf {name}, the single design {d} against all points")

    if "nan" in checks:
        reach = np.ones((D, N), bool) if reachable is None else np.asarray(reachable(out, batched_args), dtype=bool)
        assert reach.shape == (D, N)
        if inputs.known is not None:
            known = np.broadcast_to(inputs.known, (D, N))
            bad = np.argwhere((known == 1) & ~reach)
            assert not bad.size, f"nan: cases reachable by construction classified unreachable: {bad.tolist()}"
            bad = np.argwhere((known == 0) & reach)
            assert not bad.size, f"nan: cases unreachable by construction classified reachable: {bad.tolist()}"
        if reachable is not None:
            assert reach.any() and (~reach).any(), "nan: the data must hold reachable and unreachable cases"
        exact = {} if nan_where is None else dict(nan_where(out, batched_args))
        for name, mask in exact.items():
            got = np.isnan(batch[name])
            want = _expand(mask, got.shape)
            bad = np.argwhere(got != want)
            assert not bad.size, (
                f"nan: leaf {name} is NaN at {np.argwhere(got & ~want)[:5].tolist()} and finite at {np.argwhere(~got & want)[:5].tolist()} against its contract"
            )
        any_nan = np.zeros((D, N), bool)
        for name, leaf in batch.items():
            if leaf.dtype.kind != "f":
                continue
            isnan = np.isnan(leaf).reshape(D, N, -1).any(axis=-1)
            any_nan |= isnan
            if name not in exact:
                bad = np.argwhere(isnan & reach)
                assert not bad.size, f"nan: leaf {name} is NaN at reachable cases {bad[:5].tolist()}"
        bad = np.argwhere(~reach & ~any_nan)
        assert not bad.size, f"nan: unreachable cases {bad[:5].tolist()} have no NaN in any output"

    if "mutation" in checks:  # the batched call above, and calls on views of single cases
        call(*(a.at(0, 0) for a in inputs.args))
        call(*(a.at(slice(None), 0) for a in inputs.args))
        call(*(a.at(0, slice(None)) for a in inputs.args))
        for i, (a, before) in enumerate(zip(inputs.args, pristine)):
            assert np.array_equal(a.value, before, equal_nan=True), f"mutation: argument {i} was modified"


# ============================================================================ the data


@dataclass(frozen=True)
class Data:
    X: NDArray[np.float64]  # (D, 27) designs
    modes: NDArray[np.float64]  # (D, 4)
    E: NDArray[np.float64]  # (N, 3) drill tips, R_w
    e: NDArray[np.float64]  # (N, 3) drill axes
    known: NDArray[np.int8]  # (D, N) full-model reachability by construction
    far: NDArray[np.bool_]  # (N,) points moved 1 km away
    rho: NDArray[np.float64]  # (D, N, 3) joint values for the FK: the IK's where it is reachable, random elsewhere
    delta: NDArray[np.float64]  # (D, N, 2)
    assembly: NDArray[np.float64]  # (D, N, 3)
    fk_known: NDArray[np.int8]  # (D, N)
    E_m: NDArray[np.float64]  # (N, 3) the points in design 0's mechanism frame (stage inputs)
    e_m: NDArray[np.float64]  # (N, 3)
    sigma0: NDArray[np.float64]  # (N, 2) finite RTS outputs for the TMS stage (design 0's IK, random where NaN)
    rho0: NDArray[np.float64]  # (N, 3) finite TLS outputs (design 0's IK, random where NaN)
    delta0: NDArray[np.float64]  # (N, 2)
    asm0: NDArray[np.float64]  # (N, 3)


def _max_abs_arg(sol: Any) -> NDArray[np.float64]:
    args = np.concatenate([sol.tls_arg, sol.rts_arg, sol.tms_arg], axis=-1)
    return np.max(np.abs(args), axis=-1)


def _spread(idx: NDArray[np.intp], k: int) -> NDArray[np.intp]:
    assert idx.size >= k, f"only {idx.size} candidate points, need {k}"
    return idx[np.linspace(0, idx.size - 1, k).round().astype(int)]


@pytest.fixture(scope="module")
def data() -> Data:
    assert len(PARAM_NAMES) == 27 and PARAM_NAMES[23:] == ("mount_rx", "mount_ry", "mount_rz", "L")
    paper_right = Design.paper().replace(m_x=88.2, m_y=79.4, m_z=56.9)
    x0 = paper_right.to_vector()
    x1 = paper_right.replace(mount_rx=2.0, mount_ry=-3.0, mount_rz=1.5).to_vector()
    x2 = x0.copy()
    x2[INDEX["f_x"] : INDEX["r"] + 1] *= 1.01
    x2[INDEX["L"]] = 3.0
    X = np.stack([full_params(Design.from_vector(x).to_vector()) for x in (x0, x1, x2)])
    modes = ALL_MODES[[0, 6, 9]]
    ts = load_plan("reference", side="R")
    task = build_task(ts.entry, ts.target, 30, ids=ts.ids)

    sol = inverse_kinematics(X[:, None], task.E[None], task.e[None], modes[:, None])
    fk = forward_kinematics(X[:, None], sol.rho, sol.delta, sol.assembly)
    with np.errstate(invalid="ignore"):
        round_trip = (np.abs(fk.E - task.E).max(-1) < 1e-6) & (np.abs(fk.e - task.e).max(-1) < 1e-9)
        well_posed = _max_abs_arg(sol) < 0.99  # away from the branch points, where rounding is amplified
    ok = sol.reachable & round_trip
    both = _spread(np.flatnonzero((ok & well_posed).all(axis=0)), 4)
    only_first = _spread(np.flatnonzero(ok[0] & well_posed[0] & ~sol.reachable[2]), 2)

    far_shift = np.array([1000.0, -1000.0, 1000.0])
    E = np.concatenate(
        [task.E[both], task.E[only_first], task.E[both[:2]] + far_shift, task.E[both[1:2]], task.E[both[2:3]]]
    )
    e = np.concatenate([task.e[both], task.e[only_first], task.e[both[:2]], -task.e[both[1:2]], [[1.0, 0.0, 0.0]]])
    N = E.shape[0]
    far = np.zeros(N, bool)
    far[6:8] = True
    known = np.full((3, N), -1, np.int8)
    known[:, :4] = 1
    known[0, 4:6] = 1
    known[:, far] = 0

    rng = np.random.default_rng(2024)
    s = inverse_kinematics(X[:, None], E[None], e[None], modes[:, None])
    reach = np.asarray(s.reachable)

    def fill(values: NDArray[np.float64], lo: float, hi: float) -> NDArray[np.float64]:
        v = np.array(values, dtype=float)
        return np.where(np.isfinite(v), v, rng.uniform(lo, hi, v.shape))

    rho = fill(s.rho, -1.2, 1.2)
    delta = fill(s.delta, -np.pi, np.pi)
    assembly = np.where(reach[..., None], s.assembly, rng.choice([-1.0, 1.0], s.assembly.shape))
    fk_known = np.where(reach, 1, -1).astype(np.int8)
    E_m, e_m = frames.to_mechanism(unpack(X[0]), E, e)
    return Data(
        X=X,
        modes=modes,
        E=E,
        e=e,
        known=known,
        far=far,
        rho=rho,
        delta=delta,
        assembly=assembly,
        fk_known=fk_known,
        E_m=E_m,
        e_m=e_m,
        sigma0=fill(s.sigma[0], -np.pi, np.pi),
        rho0=rho[0],
        delta0=delta[0],
        asm0=assembly[0],
    )


def test_data_cover_the_cases(data: Data) -> None:
    """The data hold what the docstring promises (else the conformance checks are weaker)."""
    sol = inverse_kinematics(data.X[:, None], data.E[None], data.e[None], data.modes[:, None])
    reach = np.asarray(sol.reachable)
    assert reach[:, :4].all() and reach[0, 4:6].all() and not reach[2, 4:6].any() and not reach[:, data.far].any()
    assert not np.all(data.X[1, 23:26] == 0.0) and data.X[2, INDEX["L"]] > 0.0
    assert not reach[0, 9] and np.isinf(sol.rts_arg[0, 9, 0])  # e = +x: leg x of the RTS degenerates


# ============================================================================ the functions


def _g(data: Data, name: str, legs: slice = slice(None)) -> NDArray[np.float64]:
    """A geometry field of the three designs (mm, rad), ``(D, legs)``, or ``(D,)`` for ``r``."""
    value = np.array(getattr(unpack(data.X), name))
    return value if value.ndim == 1 else value[:, legs]


def _tls_ik(data: Data) -> Inputs:
    known = np.full((3, len(data.E)), -1, np.int8)
    known[:2, :6] = 1  # designs 0 and 1 share f, p, r; E_m is design 0's
    known[:, data.far] = 0
    return Inputs(
        (
            Arg(data.E_m, "point"),
            Arg(_g(data, "f"), "design"),
            Arg(_g(data, "p"), "design"),
            Arg(_g(data, "r"), "design", 0),
        ),
        known,
    )


def _tls_fk(data: Data) -> Inputs:
    return Inputs(
        (
            Arg(data.rho0, "point"),
            Arg(_g(data, "f"), "design"),
            Arg(_g(data, "p"), "design"),
            Arg(_g(data, "r"), "design", 0),
        )
    )


def _tms_plane(data: Data) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    lc = poses.leg_coords(data.E_m)[:, :2, :]
    return lc[..., 1], lc[..., 2]


def _tms_ik(data: Data) -> Inputs:
    v, w = _tms_plane(data)
    known = np.full((3, len(data.E)), -1, np.int8)
    known[0, :6] = 1
    return Inputs(
        (
            Arg(v, "point"),
            Arg(w, "point"),
            Arg(data.rho0[:, :2], "point"),
            Arg(data.sigma0, "point"),
            Arg(_g(data, "p", slice(0, 2)), "design"),
            Arg(_g(data, "d", slice(0, 2)), "design"),
            Arg(_g(data, "c"), "design"),
            Arg(_g(data, "t"), "design"),
            Arg(data.modes[:, 0:2], "design"),
        ),
        known,
    )


def _tms_fk(data: Data) -> Inputs:
    v, w = _tms_plane(data)
    known = np.full((3, len(data.E)), -1, np.int8)
    known[0] = data.fk_known[0]
    return Inputs(
        (
            Arg(v, "point"),
            Arg(w, "point"),
            Arg(data.rho0[:, :2], "point"),
            Arg(data.delta0, "point"),
            Arg(_g(data, "p", slice(0, 2)), "design"),
            Arg(_g(data, "d", slice(0, 2)), "design"),
            Arg(_g(data, "c"), "design"),
            Arg(_g(data, "t"), "design"),
            Arg(data.asm0[:, 0:2], "point"),
        ),
        known,
    )


def _rts_ik(data: Data) -> Inputs:
    known = np.full((3, len(data.E)), -1, np.int8)
    known[:2, :6] = 1  # designs 0 and 1 share alpha, beta, o; e_m is design 0's
    known[:, 9] = 0  # e = +x: no design's leg x can be solved (A = B = 0)
    return Inputs(
        (
            Arg(data.e_m, "point"),
            Arg(_g(data, "alpha"), "design"),
            Arg(_g(data, "beta"), "design"),
            Arg(_g(data, "o"), "design"),
            Arg(data.modes[:, 2:4], "design"),
        ),
        known,
    )


def _rts_fk(data: Data) -> Inputs:
    sigma = data.sigma0.copy()
    sigma[6:] = [[0.0, 0.0], [0.0, -0.5], [0.0, 1.0], [0.0, 2.0]]  # the first two do not assemble (radicand < 0)
    known = np.full((3, len(data.E)), -1, np.int8)
    known[:, :6] = 1  # design 0's IK sigma; the three designs share alpha, beta, o
    return Inputs(
        (
            Arg(sigma, "point"),
            Arg(_g(data, "alpha"), "design"),
            Arg(_g(data, "beta"), "design"),
            Arg(_g(data, "o"), "design"),
            Arg(data.asm0[:, 2], "point", 0),
        ),
        known,
    )


def _pose_inputs(data: Data) -> Inputs:
    return Inputs(
        (Arg(data.X, "design"), Arg(data.E, "point"), Arg(data.e, "point"), Arg(data.modes, "design")), data.known
    )


def _fk_inputs(data: Data) -> Inputs:
    return Inputs(
        (Arg(data.X, "design"), Arg(data.rho, "grid"), Arg(data.delta, "grid"), Arg(data.assembly, "grid")),
        data.fk_known,
    )


def _frame_inputs(data: Data) -> Inputs:
    return Inputs((Arg(data.X, "design"), Arg(data.E, "point"), Arg(data.e, "point")))


def _angle_inputs(data: Data) -> Inputs:
    psi = np.array([0.1, -0.5, 2.0])
    _, theta = poses.angles_from_e(data.e)
    return Inputs((Arg(psi, "design", 0), Arg(np.asarray(theta), "point", 0)))


def _direction_inputs(data: Data) -> Inputs:
    e = poses.e_from_angles(np.array([0.1, -0.5, 2.0])[:, None], np.linspace(-1.4, 1.4, len(data.E))[None])
    e[:, -1] = data.e[-1]
    return Inputs((Arg(e, "grid"),))


def _ik_velocity(params, E, e, mode):  # noqa: ANN001, ANN202
    """velocity_model at the IK solution (how the library calls it)."""
    return velocity_model(inverse_kinematics(params, E, e, mode), params)


def _to_mechanism(params, E, e):  # noqa: ANN001, ANN202
    return frames.to_mechanism(unpack(params), E, e)


def _unsolved(arg: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Where a stage has no solution: |arg| > 1, or arg undefined (NaN from an upstream stage)."""
    return ~(np.abs(arg) <= 1.0)


def _all_solved(arg: NDArray[np.float64]) -> NDArray[np.bool_]:
    return np.all(np.abs(arg) <= 1.0, axis=-1)


def _ik_nan(sol, args):  # noqa: ANN001, ANN202
    return {"rho": _unsolved(sol.tls_arg), "sigma": _unsolved(sol.rts_arg), "delta": _unsolved(sol.tms_arg)}


def _fk_nan(fk, args):  # noqa: ANN001, ANN202
    L = full_params(args[0])[..., INDEX["L"]]
    return {"e": ~fk.valid, "E": ~fk.valid & (L != 0.0)}


def _ik_reachable(out, args):  # noqa: ANN001, ANN202
    return inverse_kinematics(*args).reachable


@dataclass(frozen=True)
class Case:
    fn: Callable[..., Any]
    make_args: Callable[[Data], Inputs]
    reachable: Callable[..., NDArray[np.bool_]] | None = None
    nan_where: Callable[..., Mapping[str, NDArray[np.bool_]]] | None = None
    xfail: Mapping[str, str] = field(default_factory=dict)  # check -> reason (a library bug found here)


CASES: dict[str, Case] = {
    "tls.ik": Case(tls.ik, _tls_ik, lambda out, a: _all_solved(out[1]), lambda out, a: {"0": _unsolved(out[1])}),
    "tls.fk": Case(tls.fk, _tls_fk),
    "tms.ik": Case(tms.ik, _tms_ik, lambda out, a: _all_solved(out[1]), lambda out, a: {"0": _unsolved(out[1])}),
    "tms.fk": Case(tms.fk, _tms_fk, lambda out, a: _all_solved(out[1]), lambda out, a: {"0": _unsolved(out[1])}),
    "rts.ik": Case(rts.ik, _rts_ik, lambda out, a: _all_solved(out[1]), lambda out, a: {"0": _unsolved(out[1])}),
    "rts.fk": Case(rts.fk, _rts_fk, lambda out, a: out[1] >= 0.0, lambda out, a: {"0": ~(out[1] >= 0.0)}),
    "mechanism.inverse_kinematics": Case(inverse_kinematics, _pose_inputs, lambda sol, a: sol.reachable, _ik_nan),
    "mechanism.forward_kinematics": Case(forward_kinematics, _fk_inputs, lambda fk, a: fk.valid, _fk_nan),
    "mechanism.velocity_model(IK)": Case(_ik_velocity, _pose_inputs, _ik_reachable),
    "frames.to_mechanism": Case(_to_mechanism, _frame_inputs),
    "poses.e_from_angles": Case(poses.e_from_angles, _angle_inputs),
    "poses.angles_from_e": Case(poses.angles_from_e, _direction_inputs),
    "body.mechanism_points": Case(
        mechanism_points, _pose_inputs, lambda mp, a: mp.reachable, lambda mp, a: {"J_z": ~mp.z_closes}
    ),
}


def _params() -> list[Any]:
    out = []
    for name, case in CASES.items():
        for check in CHECKS:
            marks = [pytest.mark.xfail(strict=True, reason=case.xfail[check])] if check in case.xfail else []
            out.append(pytest.param(name, check, id=f"{name}-{check}", marks=marks))
    return out


@pytest.mark.parametrize(("name", "check"), _params())
def test_conformance(data: Data, name: str, check: str) -> None:
    case = CASES[name]
    with np.errstate(invalid="ignore", divide="ignore"):
        check_array_function(
            case.fn,
            functools.partial(case.make_args, data),
            reachable=case.reachable,
            nan_where=case.nan_where,
            checks=(check,),
        )


# ============================================================================ the checker has teeth


def _good(x, y):  # noqa: ANN001, ANN202
    """A conforming function: NaN exactly where |x + y| > 1."""
    s = np.asarray(x) + np.asarray(y)
    return np.arcsin(np.where(np.abs(s) <= 1.0, s, np.nan)), s


def _mixes_cases(x, y):  # noqa: ANN001, ANN202
    a, s = _good(x, y)
    return a + 1e-6 * np.nanmean(np.asarray(x)), s  # depends on the other designs in the batch


def _rank_dependent(x, y):  # noqa: ANN001, ANN202
    a, s = _good(x, y)
    return np.squeeze(a), s  # a size-1 call loses its axis


def _nan_when_reachable(x, y):  # noqa: ANN001, ANN202
    a, s = _good(x, y)
    return np.where(np.abs(s) < 0.1, np.nan, a), s


def _mutates(x, y):  # noqa: ANN001, ANN202
    out = _good(x, y)
    if isinstance(x, np.ndarray) and x.flags.writeable and x.size:
        x.flat[0] = 0.25  # writes through the view into the caller's array
    return out


def _toy_inputs() -> Inputs:
    x = np.array([0.0, 0.3, -0.4])
    y = np.array([0.1, -0.2, 0.5, 0.9, 3.0])
    return Inputs((Arg(x, "design", 0), Arg(y, "point", 0)))


def _toy_reachable(out, args):  # noqa: ANN001, ANN202
    return np.abs(out[1]) <= 1.0


def _toy_nan(out, args):  # noqa: ANN001, ANN202
    return {"0": np.abs(out[1]) > 1.0}


def test_checker_accepts_a_conforming_function() -> None:
    check_array_function(_good, _toy_inputs, reachable=_toy_reachable, nan_where=_toy_nan)


@pytest.mark.parametrize(
    ("fn", "check", "message"),
    [
        (_mixes_cases, "broadcast", "broadcast:"),
        (_rank_dependent, "single", "single:"),
        (_nan_when_reachable, "nan", "nan:"),
        (_mutates, "mutation", "mutation:"),
    ],
    ids=["mixes-cases", "rank-dependent", "nan-when-reachable", "mutates"],
)
def test_checker_rejects_a_broken_function(fn, check, message) -> None:  # noqa: ANN001
    with pytest.raises(AssertionError, match=message):
        check_array_function(fn, _toy_inputs, reachable=_toy_reachable, nan_where=_toy_nan, checks=(check,))
