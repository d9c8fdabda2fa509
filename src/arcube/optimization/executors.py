"""Where a population's designs are evaluated: in this process, in local worker processes, or on a
dask.distributed cluster. Each executor maps ``X`` ``(n, n_var)`` to the model's batch dict.

Local worker processes are :class:`WorkerProcess` es: they stop as on Ctrl-C when the command is interrupted or
terminated, and when their parent is gone, however it ended (:mod:`arcube.interrupts`). The command line makes
every process pool of the command one of them (:func:`worker_processes`: a study's seeds, a docking's sides), and
refuses more than :func:`max_workers` of them."""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import socket
import sys
from collections.abc import Iterator
from multiprocessing.context import SpawnContext, SpawnProcess
from typing import Any

import numpy as np

from arcube import interrupts
from arcube.errors import InputError
from arcube.optimization.checkpoint import Batch
from arcube.optimization.run_config import check_dask_address
from arcube.optimization.problem import FitnessModel, evaluate_with, worker_evaluate, worker_init

__all__ = [
    "DaskExecutor",
    "Executor",
    "ProcessExecutor",
    "WorkerProcess",
    "check_dask_address",
    "check_workers",
    "connect_dask",
    "make_executor",
    "max_workers",
    "worker_context",
    "worker_processes",
]


def max_workers() -> int:
    """The most local worker processes a command starts: 4 x this machine's CPUs (``os.cpu_count()``).

    Each worker is a CPU-bound process holding its own copy of the model (about 200 MB): past the CPU count they
    only compete for the cores and the memory; four times leaves room for a CPU count that under-reports (a
    container) and for tasks that wait on their files, and refuses a mistyped count before 10,000 processes exist."""
    return 4 * (os.cpu_count() or 1)


def check_workers(workers: int, name: str = "workers") -> int:
    """``workers`` if it is at most :func:`max_workers`; InputError naming ``name`` (the flag) otherwise."""
    most = max_workers()
    if workers > most:
        raise InputError.of(
            name,
            f"{workers}: at most {most} here (4 x the {os.cpu_count() or 1} CPUs of this machine; each worker is a "
            "process with its own copy of the model, and more than the CPUs only compete for them)",
        )
    return workers


class WorkerProcess(SpawnProcess):
    """A process of the spawn start method that stops with its parent and on its first interrupt.

    In the parent, :meth:`start` spawns it with SIGINT and SIGTERM blocked (a signal while it imports and unpickles
    its task waits, instead of a traceback) and records it, for :func:`arcube.interrupts.forward`. In the process,
    :meth:`run` sets up its signals and its watch of the parent (:func:`arcube.interrupts.worker_start`); once
    interrupted, a pool's worker takes no new task, and an interrupt while it waits for one ends it quietly."""

    def start(self) -> None:
        try:
            old: Any = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
        except (AttributeError, OSError, ValueError):
            old = None
        try:
            super().start()
            interrupts.started_worker(self)
        finally:
            if old is not None:
                signal.pthread_sigmask(signal.SIG_SETMASK, old)

    def run(self) -> None:
        try:
            parent = multiprocessing.parent_process()
            interrupts.worker_start(
                parent.pid if parent is not None and parent.pid else os.getppid(),
                parent.sentinel if parent is not None else None,
            )
            pool_worker = getattr(sys.modules.get("concurrent.futures.process"), "_process_worker", None)
            if self._target is pool_worker and self._args and hasattr(self._args[0], "get"):  # type: ignore[attr-defined]
                self._args = (_Calls(self._args[0]), *self._args[1:])  # type: ignore[attr-defined]
            super().run()
        except KeyboardInterrupt:
            # interrupted while it waited for a task, or after its task's own interrupt went to the parent: its files
            # are closed; no traceback, and no interpreter shut-down (a second or more under load)
            for stream in (sys.stdout, sys.stderr):
                with contextlib.suppress(Exception):
                    stream.flush()
            os._exit(interrupts.EXIT_CODE)


class _Calls:
    """A process pool's call queue as its worker reads it: an interrupted worker takes no new task."""

    def __init__(self, queue: Any) -> None:
        self.queue = queue

    def get(self, *args: Any, **kwargs: Any) -> Any:
        if interrupts.worker_interrupted():
            raise KeyboardInterrupt
        return self.queue.get(*args, **kwargs)


class _WorkerContext(SpawnContext):
    Process = WorkerProcess  # type: ignore[assignment]


def worker_context() -> Any:
    """The spawn start method with :class:`WorkerProcess` es, for a process pool's ``mp_context``."""
    return _WorkerContext()


@contextlib.contextmanager
def worker_processes() -> Iterator[None]:
    """Inside, every process of ``multiprocessing.get_context("spawn")`` is a :class:`WorkerProcess` (the command
    line's: the pools of a study's seeds and of a docking's sides ask for that context)."""
    ctx = multiprocessing.get_context("spawn")
    own = vars(ctx).get("Process")
    ctx.Process = WorkerProcess  # type: ignore[misc]
    try:
        yield
    finally:
        if own is None:
            del ctx.Process  # type: ignore[misc]
        else:
            ctx.Process = own  # type: ignore[misc]


def connect_dask(address: str) -> Any:
    """A ``distributed.Client`` of the scheduler at ``address``; InputError naming it when dask is
    missing or the scheduler cannot be reached. A refused TCP port fails at once: dask's client
    would retry it for its whole 20 s timeout."""
    try:
        from distributed import Client
    except ImportError:
        raise InputError.of("dask", "needs dask.distributed: pip install 'dask[distributed]'") from None
    address = check_dask_address(address)
    host, _, port = address.split("://")[-1].rpartition(":")
    if address.startswith("tcp://") or "://" not in address:
        try:
            socket.create_connection((host.strip("[]"), int(port)), timeout=5).close()
        except OSError as exc:
            raise InputError.of(
                "dask", f"{address}: cannot reach the scheduler ({type(exc).__name__}: {exc})"
            ) from None
    try:
        return Client(address, timeout=20, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise InputError.of("dask", f"{address}: cannot reach the scheduler ({type(exc).__name__}: {exc})") from None


def _merge(parts: list[Batch]) -> Batch:
    return {k: np.concatenate([p[k] for p in parts], axis=0) for k in parts[0]}


class Executor:
    """Evaluates a population batch with the model; subclasses split it into row chunks.
    Every design is evaluated independently, so the result does not depend on the split."""

    n_chunks = 1

    def __init__(self, model: FitnessModel) -> None:
        self.model = model

    def __call__(self, X: np.ndarray) -> Batch:
        chunks = [c for c in np.array_split(X, min(self.n_chunks, max(len(X), 1))) if len(c)]
        return _merge(self._map(chunks)) if len(chunks) > 1 else self.model.evaluate(X)

    def _map(self, chunks: list[np.ndarray]) -> list[Batch]:
        return [self.model.evaluate(c) for c in chunks]

    def close(self) -> None:
        pass


class ProcessExecutor(Executor):
    """The batches over ``workers`` local :class:`WorkerProcess` es (at most :func:`max_workers`: a run folder that
    asks for more gets that many; the result does not depend on the split)."""

    def __init__(self, model: FitnessModel, workers: int) -> None:
        from concurrent.futures import ProcessPoolExecutor

        super().__init__(model)
        self.n_chunks = workers = min(workers, max_workers())
        ctx = worker_context()  # spawn: no fork under threads (progress bar, dask)
        self.pool = ProcessPoolExecutor(workers, mp_context=ctx, initializer=worker_init, initargs=(model,))

    def _map(self, chunks: list[np.ndarray]) -> list[Batch]:
        return list(self.pool.map(worker_evaluate, chunks))

    def close(self) -> None:
        self.pool.shutdown(wait=True, cancel_futures=True)


class DaskExecutor(Executor):
    def __init__(self, model: FitnessModel, address: str) -> None:
        super().__init__(model)
        self.client = connect_dask(address)
        self.n_chunks = max(1, sum(self.client.nthreads().values()))
        self.model_future = self.client.scatter(model, broadcast=True)

    def _map(self, chunks: list[np.ndarray]) -> list[Batch]:
        futures = [self.client.submit(evaluate_with, self.model_future, c, pure=False) for c in chunks]
        return self.client.gather(futures)

    def close(self) -> None:
        self.client.close()


def make_executor(model: FitnessModel, workers: int = 1, dask: str | None = None) -> Executor:
    if dask:
        return DaskExecutor(model, dask)
    return ProcessExecutor(model, workers) if workers > 1 else Executor(model)
