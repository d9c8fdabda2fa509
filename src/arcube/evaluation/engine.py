"""One entry point for batch evaluation, whatever computes it.

``numpy`` is the readable reference (:func:`arcube.evaluation.evaluate_task`); ``numba`` is
the compiled kernel (:mod:`arcube.evaluation.kernel`), the default when it is importable.
"""

from __future__ import annotations

from typing import Any, Literal

from numpy.typing import ArrayLike

from arcube.evaluation.reference import Options, TaskResults
from arcube.evaluation.reference import evaluate_task as evaluate_task_numpy
from arcube.model.mechanism import DEFAULT_MODE

Engine = Literal["auto", "numba", "numpy"]
ENGINES: tuple[str, ...] = ("auto", "numba", "numpy")


def resolve(engine: str) -> str:
    """'auto' -> 'numba' when the kernel imports, else 'numpy'. Raises ValueError on an unknown name."""
    if engine not in ENGINES:
        raise ValueError(f"unknown engine {engine!r} (choose from {', '.join(ENGINES)})")
    if engine != "auto":
        return engine
    try:
        import arcube.evaluation.kernel  # noqa: F401
    except ImportError:
        return "numpy"
    return "numba"


def evaluate_task(
    params: ArrayLike,
    E: ArrayLike,
    e: ArrayLike,
    mode: ArrayLike = DEFAULT_MODE,
    options: Options = Options(),
    engine: str = "auto",
    want_points: bool = True,
    anatomy: Any = None,
    envelope: Any = None,
    c_z: ArrayLike | None = None,
) -> TaskResults:
    """Evaluate designs ``(..., 27)`` on a task's points ``(P, 3)``; see :func:`arcube.evaluation.reference.evaluate_task`.

    ``anatomy``: an :class:`arcube.evaluation.sdf.AnatomyDistance` for the clearance of model §14.3;
    ``envelope``: an :class:`arcube.evaluation.envelope.Envelope` for the clearance of 19.5 (None: none);
    ``c_z`` ``(...)``: each design's own z-dyad link, mm (model §19.1; None or NaN: ``Guards.c_z``, else d_z).

    ``want_points=False`` lets the compiled engine skip per-point outputs it does not need
    (the optimizer only reads the summaries); the summaries are the same either way.
    """
    if resolve(engine) == "numba":
        from arcube.evaluation.kernel import evaluate_task_numba

        return evaluate_task_numba(
            params, E, e, mode, options, want_points=want_points, anatomy=anatomy, envelope=envelope, c_z=c_z
        )
    return evaluate_task_numpy(params, E, e, mode, options, anatomy, envelope, c_z)
