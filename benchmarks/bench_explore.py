"""Live speed of ``arcube explore`` (issue 22): one slider move re-evaluates the design on the whole plan
and redraws within 100 ms.

The app runs as ``arcube explore`` starts it (placed paper design, reference plan, right side, 30
points per trajectory, default anatomy, the guards of ``arcube design``): 150 drill points and 150
approach points per evaluation, both clearances and the drill-tip metrics on. A move is a parameter
slider set through its viser handle (what a browser's slider message does on the server) and timed
until the worker has sent the redrawn scene and figures (``ExplorerApp.wait_idle``); the breakdown
is the worker's own: kernel on the plan, scene at the point shown (solids, closest pairs), sending.

``--browser`` also measures the round trip a person sees in headless Chromium: from the slider set
to the figures' text changing in the page (guards off there, so that every move changes eta_G).

Rerun: ``.venv/bin/python benchmarks/bench_explore.py [--moves 40] [--browser]``.
"""

from __future__ import annotations

import argparse
import socket
import time

import numpy as np

import arcube
from arcube.explorer import explore

PLACED = arcube.Design.paper().replace(m_x=88.23, m_y=79.40, m_z=56.89)
PARAMS = ("m_x", "p_x", "d_y", "r", "alpha_x", "L")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def moves(app, n: int, rng: np.random.Generator) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """``n`` slider moves of random parameters by a few mm / deg; wall ms and the worker's breakdown."""
    wall, parts = [], {k: [] for k in ("evaluate_ms", "scene_ms", "draw_ms")}
    for _ in range(n):
        name = PARAMS[rng.integers(len(PARAMS))]
        h = app.params[name]
        step = rng.uniform(0.5, 3.0)
        value = h.value + step if h.value + step <= h.max else h.value - step  # always a change: a move
        h.value = float(value)
        t0 = time.perf_counter()
        app.wait_idle()
        wall.append(1e3 * (time.perf_counter() - t0))
        for k in parts:
            parts[k].append(app.timings[k])
    return np.array(wall), {k: np.array(v) for k, v in parts.items()}


WAIT_FOR_CHANGE = """const [before, done] = arguments;
const check = () => document.body.innerText !== before;
if (check()) { done(true); } else {
  const obs = new MutationObserver(() => { if (check()) { obs.disconnect(); done(true); } });
  obs.observe(document.body, {subtree: true, childList: true, characterData: true});
}"""
"""Resolves once the page's text differs from ``before`` (checked on DOM mutations, not by polling)."""


def browser_round_trip(app, n: int) -> np.ndarray:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = "/usr/bin/chromium"
    for a in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1400,1000", "--enable-unsafe-swiftshader",
              "--host-resolver-rules=MAP * ~NOTFOUND , EXCLUDE 127.0.0.1"):  # fmt: skip
        opts.add_argument(a)
    drv = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=opts)
    try:
        drv.get(app.url)
        drv.set_script_timeout(30)
        drv.execute_async_script("const done = arguments[0]; const t = setInterval(() => {"
                                 "if (document.body.innerText.includes('η_G')) {clearInterval(t); done(true);}}, 50);")  # fmt: skip
        out = []
        for i in range(n):
            before = drv.execute_script("return document.body.innerText")
            app.params["m_x"].value = 80.0 + (i % 2) * 10.0 + 0.01 * i
            t0 = time.perf_counter()
            drv.execute_async_script(WAIT_FOR_CHANGE, before)
            out.append(1e3 * (time.perf_counter() - t0))
        return np.array(out)
    finally:
        drv.quit()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--moves", type=int, default=40)
    ap.add_argument("--browser", action="store_true", help="Also time the round trip in headless Chromium.")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    t0 = time.perf_counter()
    app = explore(PLACED, "reference", side="R", anatomy="default", port=free_port(), block=False)
    app.wait_idle(600)
    print(f"start (anatomy grids, kernel compile or cache load, first refresh): {time.perf_counter() - t0:.1f} s")
    try:
        n = len(app.model.task.E) + len(app.model.E_app)
        wall, parts = moves(app, args.moves, np.random.default_rng(args.seed))
        print(f"{args.moves} slider moves, {n} points each (drill + approach), clearances and tip metrics on:")
        print(f"  move -> redrawn (server): median {np.median(wall):.1f} ms, 90 % {np.percentile(wall, 90):.1f} ms, max {wall.max():.1f} ms"
              f"  [{'within' if np.percentile(wall, 90) <= 100 else 'OVER'} 100 ms]")  # fmt: skip
        for k, v in parts.items():
            print(f"  {k[:-3]:9s} median {np.median(v):6.1f} ms, max {v.max():6.1f} ms")
        app.guards.value = False
        app.wait_idle()
        if args.browser:
            rt = browser_round_trip(app, min(args.moves, 20))
            print(f"  move -> figures changed in headless Chromium: median {np.median(rt):.0f} ms, max {rt.max():.0f} ms")
    finally:
        app.stop()
    print("rerun: .venv/bin/python benchmarks/bench_explore.py [--browser]")


if __name__ == "__main__":
    main()
