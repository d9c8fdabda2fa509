"""Wall time of a paper-scale optimization (GA, population 400 x 300 generations, tolerance 0).

Splits the time into evaluation (the core model, inside the batch calls) and optimizer overhead
(pymoo's selection/crossover/mutation/survival plus history and checkpoints). With
``--replay`` it also times ``resume`` replaying the whole finished run from its checkpoint
(optimizer overhead only, no evaluation) and checks the replayed result is identical.

    .venv/bin/python benchmarks/bench_optimize.py                  # paper scale (minutes with numpy)
    .venv/bin/python benchmarks/bench_optimize.py --generations 30 # scaled down
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import tempfile
import time
from pathlib import Path

from arcube.optimize import run as runmod
from arcube.optimize.cli import build_config


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--generations", type=int, default=300)
    ap.add_argument("--population", type=int, default=400)
    ap.add_argument("--points", type=int, default=30)
    ap.add_argument("--algorithm", default="ga")
    ap.add_argument("--engine", default="auto", help="auto, numba or numpy")
    ap.add_argument("--trajectories", default="reference")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--replay", action="store_true", help="also time a full replay (resume) of the finished run")
    args = ap.parse_args(argv)

    cfg = build_config(
        [args.trajectories], algorithm=args.algorithm, population=args.population, generations=args.generations,
        tolerance=0.0, points=args.points, seed=args.seed, engine=args.engine, workers=args.workers,
    )  # fmt: skip
    engine = cfg["settings"]["engine_resolved"]
    model = runmod.build_model(cfg)  # warm-up: numba compiles (or loads its cache) outside the timing
    t0 = time.perf_counter()
    model.evaluate(model.space.encode(model.space.base)[None])
    warm = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        t0 = time.perf_counter()
        summary = runmod.start(out, cfg)
        wall = time.perf_counter() - t0
        ev, gens, n = summary["eval_s"], summary["generations"], summary["evaluations"]
        n_pts = summary["points"]
        print(f"{args.algorithm}, population {args.population} x {gens} generations, {n_pts} task points, engine {engine}, workers {args.workers}")
        print(f"  warm-up         {warm:9.2f} s  (first evaluation, not counted below)")
        print(f"  wall            {wall:9.2f} s")
        print(f"  evaluation      {ev:9.2f} s  ({100 * ev / wall:5.1f} %)  {n / ev:,.0f} designs/s, {n * n_pts / ev:,.0f} design-points/s")
        print(f"  optimizer etc.  {wall - ev:9.2f} s  ({100 * (wall - ev) / wall:5.1f} %)  {1e3 * (wall - ev) / gens:.1f} ms/generation")
        print(f"  result          feasible={summary['feasible']} eta_G={summary['eta_G']} dexterity mean {summary['dexterity_pct']['mean']:.2f} %")
        if args.replay:
            reference = (out / "best_design.json").read_bytes()
            state = out / "checkpoint" / "state.json"
            st = json.loads(state.read_text())
            st["finished"] = False
            state.write_text(json.dumps(st))
            t0 = time.perf_counter()
            runmod.resume(out)
            replay = time.perf_counter() - t0
            same = (out / "best_design.json").read_bytes() == reference
            print(f"  full replay     {replay:9.2f} s  (resume of the finished run; identical result: {same})")
    cmd = [sys.executable, "benchmarks/bench_optimize.py", *(argv if argv is not None else sys.argv[1:])]
    print(f"rerun: {shlex.join(cmd)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
