"""Judging designs on a task: indices, the NumPy reference, the compiled kernel and the engine.

Pipeline: trajectories (:mod:`arcube.io`) -> task points (:mod:`arcube.evaluation.task`) ->
evaluation (:mod:`arcube.evaluation.reference`, the readable NumPy reference, and
:mod:`arcube.evaluation.kernel`, the compiled kernel, behind :mod:`arcube.evaluation.engine`) ->
a result a person reads (:mod:`arcube.evaluation.result`).
"""

from __future__ import annotations
