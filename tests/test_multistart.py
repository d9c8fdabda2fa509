"""The default optimizer, multi-start CMA-ES (arcube.optimization.multistart).

Oracles: cma's own bound transformation (one solution at a time) against the batched one; the
``cma`` package itself for the batched CMA-ES (its default parameters, and the same candidates
and stop generation from the same normal draws); the budget arithmetic; bit-identical results for
a seed whatever numpy's global generator holds; a restart happens when a run meets its stop
criteria. Crash and resume: tests/test_optimize.py (test_crash_then_resume_equals_uninterrupted,
with the other algorithms).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from arcube.optimization import run as runmod
from arcube.optimization.batch_cma import BatchCMA, parameters
from arcube.optimization.config import build_config
from arcube.optimization.multistart import MARGIN, POLISH_RUNS, RUNS, default_popsize, into_box

START = Path(__file__).resolve().parent / "data" / "right_side_design.json"


def _config(**kw: object) -> dict:
    base = {
        "free": "all",
        "population": 20,
        "generations": 100,
        "points": 3,
        "seed": 5,
        "engine": "numpy",
        "ftol": 0.0,
        "side": "R",
        "checkpoint_every": 4,
    }
    base.update(kw)
    return build_config(["reference"], **base)


def _rows(path: Path) -> list[dict[str, str]]:
    return [{k: v for k, v in r.items() if k != "seconds"} for r in csv.DictReader(path.open())]


def test_into_box_is_cmas_transformation_batched() -> None:
    from cma.transformations import BoxConstraintsLinQuadTransformation

    one = BoxConstraintsLinQuadTransformation([[0.0, 1.0]])
    rng = np.random.default_rng(0)
    Y = np.concatenate(
        [
            rng.normal(0.5, 0.4, (200, 23)),
            rng.normal(0.5, 30.0, (200, 23)),
            np.array([[-0.05, 1.05, 0.0, 1.0, 0.5] * 4 + [7.3, -7.3, 2.2]]),
        ]
    )
    want = np.array([one(y.copy()) for y in Y])
    got = into_box(Y)
    assert np.array_equal(got, want) and got.min() >= 0.0 and got.max() <= 1.0
    inner = (Y >= MARGIN) & (Y <= 1.0 - MARGIN)
    assert np.array_equal(got[inner], Y[inner])  # the identity inside the margins
    assert into_box(np.array([[-MARGIN, 1.0 + MARGIN]])).tolist() == [[0.0, 1.0]]


def test_batch_cma_parameters_are_cmas() -> None:
    import cma
    from cma.utilities.math import Mh

    for n, lam in ((23, 13), (3, 7), (5, 2), (40, 15)):
        es = cma.CMAEvolutionStrategy(np.full(n, 0.5), 0.3, {"popsize": lam, "verbose": -9, "seed": np.nan})
        p = parameters(n, lam)
        assert np.allclose(p["weights"], list(es.sp.weights), rtol=1e-12, atol=1e-15) and p["mu"] == es.sp.weights.mu
        want = {
            "mueff": es.sp.weights.mueff,
            "cc": es.sp.cc,
            "c1": es.sm.parameters()["c1"],
            "cmu": es.sm.parameters()["cmu"],
            "cs": es.adapt_sigma.cs,
            "damps": es.adapt_sigma.damps,
            "chin": Mh.chiN(n),
        }
        assert all(np.isclose(p[k], v, rtol=1e-12) for k, v in want.items()), (n, lam)


def test_batch_cma_samples_what_cma_samples_and_stops_when_it_stops() -> None:
    """Two runs (a rotated ellipsoid from two starts), each against a cma run fed the same normal draws:
    the same candidates to round-off for every generation, and the same stop (tolfun) generation."""
    import cma

    n, lam, tol = 6, 10, 1e-9
    Q = np.linalg.qr(np.random.default_rng(1).standard_normal((n, n)))[0]
    scale = 10.0 ** np.linspace(0, 3, n)

    def f(X: np.ndarray) -> np.ndarray:
        return np.sum((scale * ((X - 0.3) @ Q)) ** 2, axis=-1)

    starts = [np.full(n, 0.5), np.linspace(-1.0, 1.0, n)]
    batch = BatchCMA(2, n, lam, 0.4, tol)
    ours, theirs, stopped = [], [], [0, 0]
    for r, x0 in enumerate(starts):
        batch.restart(r, x0, np.random.default_rng(10 + r))
        g = np.random.default_rng(10 + r)
        opts = {
            "popsize": lam,
            "tolfun": tol,
            "tolfunhist": tol,
            "tolx": tol / 10,
            "maxiter": 10**9,
            "seed": np.nan,
            "verbose": -9,
            "randn": lambda *shape, g=g: g.standard_normal(shape),
        }
        theirs.append(cma.CMAEvolutionStrategy(x0, 0.4, opts))
    for gen in range(1, 400):
        U = batch.ask().reshape(2, lam, n)
        ours = batch.tell(f(U).ravel())
        for r, es in enumerate(theirs):
            if stopped[r]:
                continue
            X = np.asarray(es.ask())
            assert np.allclose(X, U[r], rtol=0, atol=1e-8), (r, gen)
            es.tell(list(X), list(f(X)))
            assert bool(es.stop()) == bool(ours[r]), (r, gen, es.stop())
            stopped[r] = gen if ours[r] else 0
        if all(stopped):
            break
    assert all(stopped) and 50 < min(stopped)
    assert all("tolfun" in es.stop() for es in theirs)


def test_default_is_mscmaes_and_spends_the_budget_in_full_batches(tmp_path: Path) -> None:
    cfg = _config()
    assert cfg.to_toml()["settings"]["algorithm"] == "mscmaes"
    s = runmod.start(tmp_path / "a", cfg)
    assert RUNS * default_popsize(23) == 104 and POLISH_RUNS * default_popsize(23) == 52
    rows = _rows(tmp_path / "a/history.csv")
    evals = [int(r["evaluations"]) for r in rows]
    # budget 20 x 100 = 2000: search in batches of 104 up to 90 % (17 x 104 = 1768 <= 1800), then polish in 52s (1976 <= 2000)
    assert evals == [104 * k for k in range(1, 18)] + [1768 + 52 * j for j in range(1, 5)]
    assert s["evaluations"] == 1976 and s["stopped_by"] == "evaluations" and s["generations"] == len(rows) == 21


def test_seed_gives_the_same_run_whatever_the_global_generator(tmp_path: Path) -> None:
    cfg = _config(generations=40, seed=11)
    np.random.seed(1)
    runmod.start(tmp_path / "a", cfg)
    state = np.random.get_state()
    np.random.seed(999)  # a different global state: no effect on the run, and the run does not touch it
    np.random.random(17)
    before = np.random.get_state()
    runmod.start(tmp_path / "b", cfg)
    after = np.random.get_state()
    assert all(np.array_equal(x, y) if isinstance(x, np.ndarray) else x == y for x, y in zip(before, after))
    assert state[1].tobytes() != before[1].tobytes()
    assert (tmp_path / "a/best_design.json").read_bytes() == (tmp_path / "b/best_design.json").read_bytes()
    assert _rows(tmp_path / "a/history.csv") == _rows(tmp_path / "b/history.csv")
    runmod.start(tmp_path / "c", _config(generations=40, seed=12))
    assert (tmp_path / "c/best_design.json").read_bytes() != (tmp_path / "a/best_design.json").read_bytes()


def test_runs_restart_and_the_best_is_kept(tmp_path: Path) -> None:
    """Three placement variables, Table 2's links: the runs converge and restart within the budget;
    the reported best is the lowest eta_G ever evaluated (history's best never rises)."""
    from arcube.optimization.algorithms import make_algorithm, make_termination
    from arcube.optimization.problem import ArcubeProblem

    cfg = _config(free="m_x,m_y,m_z", design_from=str(START), population=50, generations=200)
    model = runmod.build_model(cfg)
    algo = make_algorithm("mscmaes", 50, 3, model.space.encode(model.space.base), generations=200)
    seen: list[float] = []

    def batch(X: np.ndarray) -> dict:
        r = model.evaluate(X)
        seen.extend(np.asarray(r["ETA"], float).tolist())
        return r

    algo.setup(
        ArcubeProblem(model.space, 1, batch, penalty_only=True),
        termination=make_termination("mscmaes", 200, 0.0, population=50),
        seed=3,
    )
    best = []
    while algo.has_next():
        algo.next()
        best.append(float(algo.opt[0].get("ETA")))
    assert algo.started > RUNS  # some run met its stop criteria and was replaced
    assert best == sorted(best, reverse=True) and best[-1] == min(seen) < np.inf
    assert algo.evaluator.n_eval == len(seen) <= 10000
