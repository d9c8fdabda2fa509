"""Design optimization (arcube.optimization, arcube.optimize): problem, algorithms, runs, checkpoint/resume, executors, CLI.

Runs are small (tens of designs, tens of generations, few points) and use the NumPy engine, so
the file stays fast and does not depend on the compiled kernel.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from arcube.model.design import PAPER_NAMES, PAPER_TABLE2, PARAM_NAMES, Design
from arcube.errors import InputError
from arcube.evaluation.reference import evaluate_task
from arcube.optimization import run as runmod
from arcube.cli.optimize import register
from arcube.optimization.config import build_config
from arcube.optimization.run_config import RunConfig
from arcube.optimization.problem import (
    DEFAULT_BOUNDS,
    FitnessModel,
    TaskData,
    VariableSpace,
    mechanism_points,
    parse_free,
)
from arcube.evaluation.task import build_task
from arcube.io import load_trajectories, select

REPO = Path(__file__).resolve().parents[1]
PAPER = np.array([PAPER_TABLE2[n] for n in PARAM_NAMES])
LINKS = [n for n in PARAM_NAMES if n[0] in "fpdct" or n == "r"]
SMALL = ["--algorithm", "ga", "--engine", "numpy", "--quiet"]


def _app() -> typer.Typer:
    from arcube.cli import resume

    app = typer.Typer()
    register(app)
    resume.register(app)
    return app


def _cli(*args: str) -> object:
    return CliRunner().invoke(_app(), list(args))


def _ok(*args: str) -> dict:
    res = _cli(*args)
    assert res.exception is None, f"{res.exception!r}\n{res.output}"
    assert res.exit_code == 0, res.output
    out = Path(args[args.index("--out") + 1]) if "--out" in args else Path(args[1])
    return json.loads((out / "summary.json").read_text())


def _history(path: Path) -> list[list[str]]:
    """history.csv without its wall-clock column."""
    rows = list(csv.reader(path.open()))
    col = rows[0].index("seconds")
    return [r[:col] + r[col + 1 :] for r in rows]


def _untimed(summary: dict) -> dict:
    return {k: v for k, v in summary.items() if k not in ("wall_s", "eval_s", "resumed")}


def _task(side: str = "R", points: int = 5) -> TaskData:
    ts = select(load_trajectories("reference"), side=side)
    t = build_task(ts.entry, ts.target, points)
    return TaskData(0, 0, side, t.E, t.e)


def _config(**kw: object) -> dict:
    base = {
        "algorithm": "ga",
        "free": "all",
        "population": 20,
        "generations": 30,
        "points": 4,
        "seed": 5,
        "engine": "numpy",
        "ftol": 0.0,
        "side": "R",
    }
    base.update(kw)
    return build_config(["reference"], **base)


# --------------------------------------------------------------------------------- problem
def test_variable_space_decodes_free_fixed_setups_and_mode() -> None:
    space = VariableSpace(base=PAPER, free=("m_x", "m_y", "m_z", "r"), setups=2, mode=None)
    assert space.names == (
        "m_x",
        "m_y",
        "m_z",
        "r",
        "m_x_L",
        "m_y_L",
        "m_z_L",
        "mode_T_x",
        "mode_T_y",
        "mode_R_x",
        "mode_R_y",
    )
    assert space.xl[3] == DEFAULT_BOUNDS["r"][0] and space.xu[-1] == 1.0
    x = np.array([[10.0, 20.0, 30.0, 66.0, -10.0, -20.0, -30.0, 0.3, -0.2, 0.0, -1.0]])
    (right, left), modes = space.decode(x)
    assert right[0, :3].tolist() == [10.0, 20.0, 30.0] and left[0, :3].tolist() == [-10.0, -20.0, -30.0]
    assert right[0, 16] == left[0, 16] == 66.0
    fixed = [i for i, n in enumerate(PARAM_NAMES) if n not in ("m_x", "m_y", "m_z", "r")]
    assert np.array_equal(right[0, fixed], PAPER[fixed]) and np.array_equal(left[0, fixed], PAPER[fixed])
    assert modes.tolist() == [[1.0, -1.0, 1.0, -1.0]]
    x0 = space.encode(PAPER, mode=np.array([1.0, 1.0, -1.0, 1.0]))
    (r0, l0), m0 = space.decode(x0[None])
    assert np.allclose(r0[0], PAPER) and np.allclose(l0[0], PAPER) and m0[0].tolist() == [1.0, 1.0, -1.0, 1.0]
    assert parse_free("all") == PAPER_NAMES and parse_free("r,m_x") == ("m_x", "r")
    assert parse_free("all,mount,L") == PARAM_NAMES and parse_free("L,mount") == (
        "mount_rx",
        "mount_ry",
        "mount_rz",
        "L",
    )


def test_fitness_violation_is_zero_exactly_when_feasible_and_eta_matches_core() -> None:
    task = _task()
    model = FitnessModel(space=VariableSpace(base=PAPER, free=("m_x", "m_y", "m_z"), mode=np.ones(4)), tasks=(task,))
    X = np.array([[88.2, 79.4, 56.9], [31.8694, 11.9589, 192.0769], [90.0, 80.0, 55.0]])
    out = model.evaluate(X)
    params = np.tile(PAPER, (3, 1))
    params[:, :3] = X
    ref = evaluate_task(params, task.E, task.e)
    assert np.array_equal(out["VIOL"] == 0.0, ref.w_G) and ref.w_G[0] and not ref.w_G[1]
    assert np.array_equal(out["ETA"][ref.w_G], ref.eta_G[ref.w_G]) and np.all(np.isinf(out["ETA"][~ref.w_G]))
    assert np.array_equal(out["VIOL"], ref.violation) and out["F"].shape == (3, 1)
    assert np.all(out["F"][~ref.w_G, 0] > 1e6)


def test_margin_shortfall_follows_12_2() -> None:
    task = _task()
    model = FitnessModel(
        space=VariableSpace(base=PAPER, free=PAPER_NAMES, mode=np.ones(4)), tasks=(task,), margin_deg=5.0
    )
    ang = np.degrees(np.arccos(task.e[:, :2]))
    p = PAPER.copy()
    a, b = p[19:21], p[21:23]
    want = np.maximum(ang.max(0) + 5 - (a + b), 0) + np.maximum(np.abs(a - b) - (ang.min(0) - 5), 0)
    assert model.margin_shortfall(p[None])[0] == pytest.approx(np.radians(want.sum()))
    p[19:23] = [89.0, 89.0, 88.0, 88.0]  # wide cone, small |alpha - beta|: met
    assert model.margin_shortfall(p[None])[0] == 0.0


def test_mechanism_points_are_the_joints_of_model_3_1() -> None:
    task = _task()
    params = PAPER.copy()
    params[:3] = [88.2, 79.4, 56.9]
    pts = mechanism_points(params[None], task.E, task.e)[0]  # (P, 11, 3)
    m, f, p, r = params[:3], params[3:6], params[6:9], params[16]
    eye = np.eye(3)
    for leg in range(3):
        assert np.allclose(pts[:, leg], m - f[leg] * eye[leg])  # P_u = m - f_u u
        assert np.allclose(np.linalg.norm(pts[:, 3 + leg] - pts[:, leg], axis=1), p[leg])  # |D_u - P_u| = p_u
        assert np.allclose(pts[:, 3 + leg, leg], pts[:, 6 + leg, leg])  # D_u, Q_u share the u coordinate
        assert np.allclose(pts[:, 6 + leg], task.E + r * eye[leg])  # Q_u = E + r u
    assert np.allclose(pts[:, 9], task.E) and np.allclose(pts[:, 10], task.E + r * task.e)


def test_aggregate_max_is_the_worst_over_patients() -> None:
    t1 = _task()
    t2 = TaskData(1, 0, "shifted", t1.E + [0.0, 2.0, 0.0], t1.e)
    space = VariableSpace(base=PAPER, free=("m_x", "m_y", "m_z"), mode=np.ones(4))
    X = np.array([[88.2, 79.4, 56.9], [90.0, 80.0, 55.0]])
    per = [FitnessModel(space=space, tasks=(TaskData(0, 0, "", t.E, t.e),)).evaluate(X)["ETA"] for t in (t1, t2)]
    worst = FitnessModel(space=space, tasks=(t1, t2), n_patients=2, aggregate="max").evaluate(X)["ETA"]
    mean = FitnessModel(space=space, tasks=(t1, t2), n_patients=2, aggregate="mean").evaluate(X)["ETA"]
    assert np.array_equal(worst, np.maximum(per[0], per[1]))
    assert np.allclose(mean[np.isfinite(mean)], ((per[0] + per[1]) / 2)[np.isfinite(mean)])


# --------------------------------------------------------------------------------- runs
def test_paper_links_reach_the_right_side(tmp_path: Path) -> None:
    out = tmp_path / "run"
    s = _ok(
        "optimize",
        "--trajectories",
        "reference",
        "--out",
        str(out),
        "--design-from",
        "paper",
        "--free",
        "m_x,m_y,m_z",
        "--side",
        "R",
        "--population",
        "40",
        "--generations",
        "60",
        "--seed",
        "3",
        *SMALL,
    )
    assert s["feasible"] and s["eta_G"] is not None and s["points"] == 150
    best = Design.from_json(out / "best_design.json")
    assert all(best[n] == PAPER_TABLE2[n] for n in PARAM_NAMES if n not in ("m_x", "m_y", "m_z"))
    assert np.allclose([best["m_x"], best["m_y"], best["m_z"]], [88.2, 79.4, 56.9], atol=25.0)
    hist = list(csv.DictReader((out / "history.csv").open()))
    assert len(hist) == s["generations"] == 60 and float(hist[-1]["best_eta_G"]) == s["eta_G"]
    cfg = tomllib.loads((out / "config.toml").read_text())
    assert cfg["settings"]["seed"] == 3 and cfg["versions"]["pymoo"] and cfg["patients"][0]["sides"] == ["R"] * 5


def test_same_seed_same_best_design(tmp_path: Path) -> None:
    runs = []
    for name, seed in (("a", 9), ("b", 9), ("c", 10)):
        runmod.start(tmp_path / name, _config(seed=seed))
        runs.append((tmp_path / name / "best_design.json").read_bytes())
    assert runs[0] == runs[1] and runs[0] != runs[2]
    assert _history(tmp_path / "a" / "history.csv") == _history(tmp_path / "b" / "history.csv")


def test_nsga2_front_is_feasible_and_non_dominated(tmp_path: Path) -> None:
    s = runmod.start(tmp_path / "n", _config(algorithm="nsga2", population=40, generations=40))
    rows = list(csv.DictReader((tmp_path / "n" / "pareto.csv").open()))
    assert len(rows) == s["front_size"] >= 2
    task = _task(points=4)
    objs = []
    for row in rows:
        params = np.array([float(row[n]) for n in PARAM_NAMES])
        res = evaluate_task(params[None], task.E, task.e)  # independent re-evaluation
        assert row["feasible"] == "True" and bool(res.w_G[0])
        assert float(row["eta_G"]) == pytest.approx(float(res.eta_G[0]), rel=1e-12)
        links = sum(float(row[n]) for n in LINKS)
        assert float(row["links_sum_mm"]) == pytest.approx(links, rel=1e-12)
        assert float(row["bbox_volume_L"]) > 0
        objs.append((float(res.eta_G[0]), links))
    for i, a in enumerate(objs):
        for j, b in enumerate(objs):
            assert i == j or not (b[0] <= a[0] and b[1] <= a[1] and b != a), f"row {j} dominates row {i}"


def test_free_mode_and_two_setups(tmp_path: Path) -> None:
    cfg = _config(mode="free", setups=2, side=None, population=40, generations=40)
    s = runmod.start(tmp_path / "s", cfg)
    right, left = (
        Design.from_json(tmp_path / "s" / "best_design.json"),
        Design.from_json(tmp_path / "s" / "best_design_L.json"),
    )
    assert s["feasible"] and s["files"] == {"best_design_R": "best_design.json", "best_design_L": "best_design_L.json"}
    assert all(right[n] == left[n] for n in LINKS + ["o_x", "o_y", "alpha_x", "alpha_y", "beta_x", "beta_y"])
    assert (right["m_x"], right["m_y"], right["m_z"]) != (left["m_x"], left["m_y"], left["m_z"])
    assert [t["label"] for t in s["tasks"]] == ["reference R", "reference L"] and all(t["w_G"] for t in s["tasks"])
    from arcube.model.mechanism import parse_mode

    mode = parse_mode(s["mode"])
    for t, d in zip(s["tasks"], (right, left)):  # both placements feasible in the chosen mode
        ts = select(load_trajectories("reference"), side=t["label"][-1])
        task = build_task(ts.entry, ts.target, 4)
        assert evaluate_task(d.to_vector()[None], task.E, task.e, mode).w_G[0]


def test_several_trajectory_files_make_one_robust_problem(tmp_path: Path) -> None:
    ts = load_trajectories("reference")
    other = tmp_path / "other.csv"
    with other.open("w") as fh:
        fh.write("trajectory,level,side,entry_x,entry_y,entry_z,target_x,target_y,target_z\n")
        for i in range(len(ts)):
            e, t = ts.entry[i] + [1.0, 3.0, -2.0], ts.target[i] + [1.0, 3.0, -2.0]
            fh.write(f"{ts.ids[i]},{ts.levels[i]},{ts.sides[i]},{','.join(map(str, e))},{','.join(map(str, t))}\n")
    out = tmp_path / "rob"
    s = _ok(
        "optimize",
        "--trajectories",
        "reference",
        str(other),
        "--out",
        str(out),
        "--side",
        "R",
        "--aggregate",
        "max",
        "--population",
        "20",
        "--generations",
        "10",
        "--points",
        "3",
        "--seed",
        "1",
        "--ftol",
        "0",
        *SMALL,
    )
    cfg = tomllib.loads((out / "config.toml").read_text())
    assert [p["source"] for p in cfg["patients"]] == ["reference", str(other)] and len(s["tasks"]) == 2
    assert cfg["settings"]["aggregate"] == "max"


def test_subset_flags_reach_select_and_resume_cli_of_finished_run(tmp_path: Path) -> None:
    out = tmp_path / "ids"
    _ok(
        "optimize",
        "--trajectories",
        "reference",
        "--out",
        str(out),
        "--ids",
        "1,3,5",
        "--levels",
        "C3-C4",
        "--population",
        "10",
        "--generations",
        "3",
        "--points",
        "2",
        "--seed",
        "1",
        *SMALL,
    )
    cfg = tomllib.loads((out / "config.toml").read_text())
    assert cfg["patients"][0]["ids"] == ["1", "3"] and cfg["settings"]["levels"] == "C3-C4"
    res = _cli("resume", str(out), "--quiet")
    assert res.exit_code == 0 and res.exception is None


def test_tolerance_stops_early_and_zero_runs_every_generation(tmp_path: Path) -> None:
    a = runmod.start(tmp_path / "a", _config(free="m_x,m_y,m_z", generations=200, ftol=1e-3))
    b = runmod.start(tmp_path / "b", _config(free="m_x,m_y,m_z", generations=50, ftol=0.0))
    assert a["stopped_by"] == "tolerance" and a["generations"] < 200
    assert b["stopped_by"] == "generations" and b["generations"] == 50 and b["evaluations"] == 50 * 20


@pytest.mark.parametrize(("algorithm", "duplicates"), [("ga", False), ("ga", True), ("de", False), ("nsga2", False)])
def test_lean_bookkeeping_equals_pymoo_stock_components(algorithm: str, duplicates: bool) -> None:
    """The lean bookkeeping (arcube.optimization.lean) changes no draw and no decision of pymoo's algorithms."""
    from arcube.optimization.algorithms import make_algorithm, make_termination
    from arcube.optimization.problem import ArcubeProblem

    model = runmod.build_model(_config(algorithm=algorithm, population=30, points=3))
    x0 = model.space.encode(model.space.base)
    seen: dict[bool, list] = {}
    for lean in (True, False):
        algo = make_algorithm(algorithm, 30, 11, x0, eliminate_duplicates=duplicates, lean=lean)
        algo.setup(
            ArcubeProblem(model.space, model.n_obj, model.evaluate),
            termination=make_termination(algorithm, 25, 0.0),
            seed=11,
        )
        trace = []
        while algo.has_next():
            algo.next()
            pop, opt = algo.pop, algo.opt
            trace.append(
                (
                    pop.get("X"),
                    pop.get("F"),
                    pop.get("CV"),
                    pop.get("rank"),
                    pop.get("VIOL"),
                    opt.get("X"),
                    algo.evaluator.n_eval,
                )
            )
        seen[lean] = trace
    assert (
        len(seen[True]) == 25
        and any(np.any(t[2] > 0) for t in seen[True])
        and any(np.any(t[2] == 0) for t in seen[True])
    )
    for got, want in zip(seen[True], seen[False]):
        for a, b in zip(got, want):
            assert np.array_equal(a, b)


def test_duplicates_setting_is_recorded_and_old_configs_keep_pymoo_default(tmp_path: Path) -> None:
    assert _config().to_toml()["settings"]["eliminate_duplicates"] is False
    cfg = _config(eliminate_duplicates=True, generations=3)
    assert cfg.to_toml()["settings"]["eliminate_duplicates"] is True and "--eliminate-duplicates" in cfg.rerun
    runmod.start(tmp_path / "dup", cfg)
    old = _config(generations=3, seed=cfg.settings.seed).to_toml()
    del old["settings"]["eliminate_duplicates"]  # a config written before the setting existed
    runmod.start(tmp_path / "old", RunConfig.from_toml(old))
    assert (tmp_path / "old/best_design.json").read_bytes() == (tmp_path / "dup/best_design.json").read_bytes()
    assert _history(tmp_path / "old/history.csv") == _history(tmp_path / "dup/history.csv")


# --------------------------------------------------------------------------------- checkpoint / resume
class _Crash(Exception):
    pass


@pytest.mark.parametrize(
    ("algorithm", "generations"), [("ga", 25), ("de", 25), ("cmaes", 25), ("nsga2", 25), ("mscmaes", 100)]
)  # mscmaes: 20 x 100 evaluations = 21 batches
def test_crash_then_resume_equals_uninterrupted(tmp_path: Path, algorithm: str, generations: int) -> None:
    cfg = _config(algorithm=algorithm, checkpoint_every=4, generations=generations)
    ref = runmod.start(tmp_path / "ref", cfg)

    def crash(row: dict) -> None:
        if row["generation"] == 14:
            raise _Crash

    with pytest.raises(_Crash):
        runmod.start(tmp_path / "cut", cfg, on_generation=crash)
    assert json.loads((tmp_path / "cut/checkpoint/state.json").read_text())["generation"] == 12
    got = runmod.resume(tmp_path / "cut")
    assert got is not None and got["resumed"] == 1
    for name in ["best_design.json"] + (["pareto.csv"] if algorithm == "nsga2" else []):
        assert (tmp_path / "cut" / name).read_bytes() == (tmp_path / "ref" / name).read_bytes()
    assert _untimed(got) == _untimed(ref)
    assert _history(tmp_path / "cut/history.csv") == _history(tmp_path / "ref/history.csv")
    assert runmod.resume(tmp_path / "cut") is None  # finished: nothing to do


@pytest.mark.parametrize(
    "extra",
    [
        {"objectives": "eta_G,lateral_error", "maxima": ["torque=50"]},
        {"objectives": "eta_G,lateral_error,torque,deflection"},
    ],
)
def test_crash_then_resume_with_objectives_equals_uninterrupted(tmp_path: Path, extra: dict) -> None:
    """Runs with --objectives (NSGA-II, NSGA-III) and limits resume bit for bit like the others."""
    cfg = _config(checkpoint_every=4, generations=10, **extra)
    assert cfg.settings.algorithm == ("nsga3" if len(extra["objectives"].split(",")) > 3 else "nsga2")
    ref = runmod.start(tmp_path / "ref", cfg)

    def crash(row: dict) -> None:
        if row["generation"] == 6:
            raise _Crash

    with pytest.raises(_Crash):
        runmod.start(tmp_path / "cut", cfg, on_generation=crash)
    got = runmod.resume(tmp_path / "cut")
    assert got is not None and got["resumed"] == 1
    for name in ("best_design.json", "pareto.csv"):
        assert (tmp_path / "cut" / name).read_bytes() == (tmp_path / "ref" / name).read_bytes()
    assert _untimed(got) == _untimed(ref)


def test_kill9_then_resume_is_bit_identical(tmp_path: Path) -> None:
    args = [
        "optimize",
        "--trajectories",
        "reference",
        "--free",
        "all",
        "--population",
        "40",
        "--generations",
        "150",
        "--points",
        "10",
        "--seed",
        "7",
        "--ftol",
        "0",
        "--checkpoint-every",
        "5",
        *SMALL,
    ]
    env = {**os.environ, "PYTHONPATH": str(REPO / "src")}
    cut = tmp_path / "cut"
    proc = subprocess.Popen(
        [sys.executable, "-m", "arcube", *args, "--out", str(cut)],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    state, deadline, gen = cut / "checkpoint" / "state.json", time.monotonic() + 90, 0
    while time.monotonic() < deadline and proc.poll() is None and gen < 20:
        if state.exists():
            gen = json.loads(state.read_text())["generation"]
        time.sleep(0.005)
    proc.send_signal(signal.SIGKILL)
    _, err = proc.communicate()
    assert proc.returncode == -signal.SIGKILL, err.decode()
    assert not (cut / "summary.json").exists() and 20 <= json.loads(state.read_text())["generation"] < 150
    res = subprocess.run(
        [sys.executable, "-m", "arcube", "resume", str(cut), "--quiet"],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert res.returncode == 0, res.stderr
    ref = _ok(*args, "--out", str(tmp_path / "ref"))
    assert (cut / "best_design.json").read_bytes() == (tmp_path / "ref" / "best_design.json").read_bytes()
    assert _untimed(json.loads((cut / "summary.json").read_text())) == _untimed(ref)
    assert _history(cut / "history.csv") == _history(tmp_path / "ref" / "history.csv")


def test_corrupt_or_foreign_checkpoint_is_refused(tmp_path: Path) -> None:
    for name in ("a", "b"):
        runmod.start(tmp_path / name, _config(generations=12, checkpoint_every=5, seed=ord(name)))
    a_state = tmp_path / "a/checkpoint/state.json"
    state = json.loads(a_state.read_text())
    state["finished"] = False
    a_state.write_text(json.dumps(state))
    chunk = tmp_path / "a/checkpoint" / state["chunks"][0]["file"]
    good = chunk.read_bytes()
    chunk.write_bytes(good[:100] + bytes([good[100] ^ 0xFF]) + good[101:])  # one flipped byte
    with pytest.raises(InputError, match="corrupt checkpoint"):
        runmod.resume(tmp_path / "a")
    chunk.write_bytes(good)
    np.savez(
        chunk, digest=np.array([object()]), sizes=np.array([1]), F=np.zeros((1, 1)), VIOL=np.zeros(1), ETA=np.zeros(1)
    )
    state["chunks"][0]["sha256"] = __import__("hashlib").sha256(chunk.read_bytes()).hexdigest()
    a_state.write_text(json.dumps(state))  # consistent hash, but a pickled object inside: refused
    with pytest.raises(InputError, match="corrupt checkpoint"):
        runmod.resume(tmp_path / "a")
    a_state.write_text(
        (tmp_path / "b/checkpoint/state.json").read_text().replace('"finished": true', '"finished": false')
    )
    with pytest.raises(InputError, match="another run"):
        runmod.resume(tmp_path / "a")
    a_state.write_text("{not json")
    with pytest.raises(InputError, match="corrupt checkpoint"):
        runmod.resume(tmp_path / "a")
    a_state.write_text(json.dumps({"format": "something-else"}))
    with pytest.raises(InputError, match="not an arcube optimize checkpoint"):
        runmod.resume(tmp_path / "a")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="no config.toml"):
        runmod.resume(tmp_path / "empty")
    res = subprocess.run(
        [sys.executable, "-m", "arcube", "resume", str(tmp_path / "a")],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": str(REPO / "src")},
    )
    assert res.returncode == 2 and res.stderr.startswith("error: ") and res.stderr.count("\n") == 1


# --------------------------------------------------------------------------------- executors
def test_workers_and_dask_give_the_serial_result(tmp_path: Path) -> None:
    cfg = _config(population=24, generations=6, points=3, side=None)
    runmod.start(tmp_path / "serial", cfg)
    runmod.start(tmp_path / "workers", cfg, workers=2)
    want = (tmp_path / "serial/best_design.json").read_bytes()
    assert (tmp_path / "workers/best_design.json").read_bytes() == want
    assert _history(tmp_path / "workers/history.csv") == _history(tmp_path / "serial/history.csv")
    pytest.importorskip("distributed")
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        runmod.start(tmp_path / "dask", cfg, dask=cluster.scheduler_address)
    assert (tmp_path / "dask/best_design.json").read_bytes() == want
    assert _history(tmp_path / "dask/history.csv") == _history(tmp_path / "serial/history.csv")


# --------------------------------------------------------------------------------- flags
@pytest.mark.parametrize(
    "extra",
    [
        ["--algorithm", "sa"],
        ["--population", "1"],
        ["--generations", "0"],
        ["--ftol", "-1"],
        ["--points", "1"],
        ["--mode=+,+"],
        ["--free", "m_x,q"],
        ["--setups", "3"],
        ["--setups", "2", "--side", "R"],
        ["--margin", "-2"],
        ["--workers", "0"],
        ["--workers", "2", "--dask", "tcp://127.0.0.1:1"],
        ["--bounds", "p_x=10"],
        ["--bounds", "p_x=-5:10"],
        ["--engine", "fortran"],
        ["--aggregate", "median"],
        ["--design-from", "nope.json"],
        ["--trajectories", "missing.csv"],
        ["--side", "X"],
        ["--seed", "-1"],
        ["--compactness", "weight"],
    ],
)
def test_bad_flags_raise_one_line_input_error(tmp_path: Path, extra: list[str]) -> None:
    res = _cli("optimize", "--trajectories", "reference", "--out", str(tmp_path / "x"), *SMALL, *extra)
    assert isinstance(res.exception, InputError), (res.exception, res.output)
    assert "\n" not in str(res.exception) and str(res.exception)
    assert not (tmp_path / "x").exists()


def test_out_folder_must_be_new_and_main_cli_exits_2(tmp_path: Path) -> None:
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "config.toml").write_text("x")
    res = _cli("optimize", "--trajectories", "reference", "--out", str(tmp_path / "busy"), *SMALL)
    assert isinstance(res.exception, InputError) and "arcube resume" in str(res.exception)
    bad = subprocess.run(
        [
            sys.executable,
            "-m",
            "arcube",
            "optimize",
            "--trajectories",
            "reference",
            "--out",
            str(tmp_path / "y"),
            "--algorithm",
            "nope",
        ],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": str(REPO / "src")},
    )
    assert bad.returncode == 2 and bad.stderr.startswith("error: --algorithm") and bad.stderr.count("\n") == 1
