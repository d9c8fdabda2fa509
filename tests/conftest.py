"""Shared fixtures of the test suite; the shared code lives in four plain modules beside the tests:

* :mod:`naive`: the independent oracles, written from MODEL.md (parameter order, the 3-D construction of
  the mechanism, rotations, SVD condition numbers, masses by hand, program.csv read as text);
* :mod:`designs`: the inputs (Table 2, random designs, reachable poses, placed designs, the reference
  task, the drilling program's design and plan, a synthetic program folder, data paths);
* :mod:`compare`: two engines held equal field by field (the compiled kernel and the program's compiled
  check against their NumPy references, each with a tolerance for every field);
* :mod:`harness`: the command line in a subprocess, headless Chromium.

A test module imports them by name (``from naive import vec``, ``from designs import PAPER``), never
another test module. This needs no ``sys.path`` code: pytest's default import mode (``prepend``) inserts
the directory of each conftest.py and test module that is not in a package (tests/ has no
``__init__.py``) at the front of ``sys.path`` before importing it, so ``tests/`` is importable from the
first conftest on. ``arcube`` itself comes from the environment (``pip install -e .``; CI runs the suite
from a clean clone with an editable install).
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from designs import PAPER, RIGHT_SIDE_M, random_design, reachable_poses
from naive import ALL_MODES_ORACLE, vec

from arcube.model.design import Design


@pytest.fixture
def rng():
    return np.random.default_rng(20240601)


@pytest.fixture(scope="session")
def designs():
    """Four random designs, each with m != 0, fixed seeds."""
    return [random_design(np.random.default_rng(seed)) for seed in (11, 22, 33, 44)]


@pytest.fixture(scope="session")
def paper_design():
    return vec(PAPER)


@pytest.fixture(scope="session")
def pose_bank(designs):
    """For every design and every one of the 16 working modes, 12 well-conditioned reachable poses.

    Returns a list of (design, mode, E (12, 3), e (12, 3)).
    """
    rng = np.random.default_rng(777)
    bank = []
    for x in designs:
        for mode in ALL_MODES_ORACLE:
            E, e = reachable_poses(rng, x, mode, 12)
            bank.append((x, mode, E, e))
    return bank


@pytest.fixture(scope="module")
def right_side_design(tmp_path_factory: pytest.TempPathFactory):
    """Table 2's links placed where they reach the right side (found by the paper-check search), as a
    design file (one per test module)."""
    path = tmp_path_factory.mktemp("design") / "right.json"
    Design.preset("paper").replace(**RIGHT_SIDE_M).to_json(path)
    return path


SLOW_FIRST = (
    "test_dock.py",
    "test_one_robot_design.py",
    "test_design_job.py",
    "test_explore.py",
    "test_demo.py",
    "test_docs.py",
    "test_study.py",
    "test_hardening.py",
    "test_interrupts.py",
    "test_envelope_clearance.py",
    "test_program.py",
    "test_clearance.py",
    "test_report_browser.py",
    "test_optimize.py",
    "test_sigterm.py",
    "test_cli_evaluate.py",
    "test_hostile_readers.py",
    "test_breach_truth.py",
    "test_segmentations.py",
    "test_mjcf.py",
    "test_design_progress.py",
    "test_paper_check.py",
)
"""The files whose tests take longest (benchmarks of the suite: ``pytest --durations``, per file), in that order;
test_explore.py and test_report_browser.py (their browser tests run on CI, skipped without Chromium) where they were."""


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Start the slowest files first: pytest-xdist hands files to its workers in this order (``--dist loadfile``),
    so that no long file starts last and runs alone at the end. A stable sort: each file keeps its own order."""
    rank = {name: i for i, name in enumerate(SLOW_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


def pytest_configure(config: pytest.Config) -> None:
    """With xdist, every process the suite starts runs Numba's parallel loops on one thread (``NUMBA_NUM_THREADS=1``,
    inherited by the workers and the commands their tests start; a value already set is kept). The workers already
    fill the cores; two OpenMP threads in each of several processes on two cores wait at each loop's barrier for a
    thread that is not running, and a test that takes 10 s alone then took 100-170 s now and then.

    The files are handed out in the order of :data:`SLOW_FIRST`: pytest-xdist (3.6 and later) otherwise reorders the
    files by their number of tests (``--loadscope-reorder``, on by default), which started the long files with few
    tests (the demo, the design and docking jobs) last, one of them running alone at the end."""
    if not hasattr(config, "workerinput") and getattr(config.option, "numprocesses", None):
        os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    if getattr(config.option, "loadscopereorder", None):
        config.option.loadscopereorder = False


_COMPILE = (
    "from arcube.evaluation.kernel import warm_up; warm_up()",
    "import trimesh, arcube\n"
    "from arcube.evaluation.anatomy import Anatomy, resolve_anatomy\n"
    "resolve_anatomy('default', plan='reference').distance\n"
    "Anatomy.from_meshes([trimesh.creation.box(extents=(30.0, 30.0, 30.0))], 'warm-up').distance\n"
    "arcube.tolerance(arcube.Design.paper().replace(m_x=88.23, m_y=79.40, m_z=56.89), 'reference', side='R', levels='C3',"
    " points=3, samples=20, seed=1)",
)
"""What fills Numba's cache: the evaluation kernel; the distance grids and the accuracy kernel (two processes, one a core)."""


def pytest_sessionstart(session: pytest.Session) -> None:
    """With xdist, compile the kernels once before the workers start (a fresh clone, as CI, has no Numba cache).

    Otherwise every process that needs a kernel before the first one has written it to the cache compiles it again:
    both workers and the commands their tests start, four or more compilations of the same kernel at once on two
    cores (measured: the first tests of a cold run took 100-170 s instead of 2-20 s). The two parts run side by side,
    the evaluation kernel (the longest) in one process, everything else in the other. A part that fails is left to
    the tests to report."""
    if hasattr(session.config, "workerinput") or not getattr(session.config.option, "numprocesses", None):
        return
    import subprocess
    import sys

    procs = [
        subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        for code in _COMPILE
    ]
    for p in procs:
        p.wait()
