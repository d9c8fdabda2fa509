"""Where a population's designs are evaluated: in this process, in local worker processes, or on a
dask.distributed cluster. Each executor maps ``X`` ``(n, n_var)`` to the model's batch dict."""

from __future__ import annotations

import re
import socket
from typing import Any

import numpy as np

from arcube.errors import InputError
from arcube.optimization.checkpoint import Batch
from arcube.optimization.problem import FitnessModel, evaluate_with, worker_evaluate, worker_init

__all__ = ["DaskExecutor", "Executor", "ProcessExecutor", "check_dask_address", "connect_dask", "make_executor"]


_ADDRESS = re.compile(r"^(?:(?:tcp|tls|inproc|ucx|ws|wss)://)?(?:\[[0-9a-fA-F:.]+\]|[A-Za-z0-9_.-]+):\d{1,5}$")


def check_dask_address(address: str) -> str:
    """``address`` if it names a scheduler as ``[tcp://]HOST:PORT``; InputError otherwise, before any
    connection is tried (a malformed one left dask's half-built client hanging at exit)."""
    if not isinstance(address, str) or not _ADDRESS.match(address.strip()):
        raise InputError.of("dask", f"{address!r}: expected a scheduler address HOST:PORT, e.g. tcp://10.0.0.5:8786")
    return address.strip()


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
    def __init__(self, model: FitnessModel, workers: int) -> None:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        super().__init__(model)
        self.n_chunks = workers
        ctx = multiprocessing.get_context("spawn")  # no fork under threads (progress bar, dask)
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
