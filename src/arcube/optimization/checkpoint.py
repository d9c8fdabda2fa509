"""Checkpoints of an optimization run: the evaluation log and its replay.

The run is deterministic given its seed, so a checkpoint is the *evaluation log*: for each batch
the algorithm asked for, the SHA-256 of the asked X and the answers (F, VIOL, ETA) as float64
arrays, appended every ``checkpoint_every`` generations as ``checkpoint/evals_GGGGGG.npz``
(allow_pickle=False, listed with its own SHA-256 in ``checkpoint/state.json``; both written
atomically). Between checkpoints a generation costs one digest of its batch (about 0.1 ms at
population 400) and keeps the answers in memory; nothing is written.

``resume`` sets the algorithm up afresh from the seed and replays it through :class:`EvalLog`:
every asked batch must hash to the logged digest (else the checkpoint is refused) and gets the
logged answers without evaluating, so the algorithm goes through exactly the same states
(population, counters, termination windows, every RNG including CMA-ES's) as the uninterrupted
run; then it goes on live. Replay costs only the optimizer's own overhead.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import time
from collections import deque
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from arcube.errors import InputError
from arcube.io.files import atomic_write_bytes, atomic_write_text
from arcube.io.inputs import read_bytes
from arcube.optimization.run_config import FORMAT_VERSION, RunConfig

CHECKPOINT_FORMAT = "arcube-optimize-checkpoint"
Batch = dict[str, np.ndarray]
LOG_KEYS = ("F", "VIOL", "ETA")
EXTRA_KEYS = ("VIOL_D", "ETA_D")
"""Logged too when every batch has them: each docking's violation and eta_G (``(n, K)``, a model over dockings, model §19)."""


class BatchFunction(Protocol):
    def __call__(self, X: np.ndarray) -> Batch: ...


def digest(X: np.ndarray) -> bytes:
    a = np.ascontiguousarray(X, dtype=np.float64)
    return hashlib.sha256(repr(a.shape).encode() + a.tobytes()).digest()


class EvalLog:
    """Answers the problem's batches: from the replay queue while it lasts (checking digests), then
    live through the executor, logging what is new since the last checkpoint.

    ``eval_s`` is the time in the executor (the evaluation); ``call_s`` the whole time answering
    (evaluation plus digests and logging), so the caller can tell the optimizer's own time apart.
    With ``keep=False`` (a run held in memory) nothing is logged: it only times the executor."""

    def __init__(self, executor: BatchFunction, replay: list[tuple[bytes, Batch]], *, keep: bool = True) -> None:
        self.executor, self.replay, self.pending, self.keep = executor, deque(replay), [], keep
        self.calls, self.eval_s, self.call_s = 0, 0.0, 0.0

    def __call__(self, X: np.ndarray) -> Batch:
        t_call = time.perf_counter()
        try:
            return self._answer(X)
        finally:
            self.call_s += time.perf_counter() - t_call

    def _answer(self, X: np.ndarray) -> Batch:
        self.calls += 1
        if not self.keep:  # a run held in memory: no checkpoint to replay or write
            t0 = time.perf_counter()
            batch = self.executor(X)
            self.eval_s += time.perf_counter() - t0
            return batch
        d = digest(X)
        if self.replay:
            want, batch = self.replay.popleft()
            if want != d or len(batch["VIOL"]) != len(X):
                raise InputError(
                    f"checkpoint does not replay: batch {self.calls} asked for other designs than the logged run (other code or library versions, or a foreign checkpoint)"
                )
            return batch
        t0 = time.perf_counter()
        batch = self.executor(X)
        self.eval_s += time.perf_counter() - t0
        self.pending.append((d, batch))
        return batch


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def write_checkpoint(run_dir: Path, state: dict[str, Any], log: EvalLog, generation: int) -> None:
    ckdir = run_dir / "checkpoint"
    if log.pending:
        buf = io.BytesIO()
        entries = log.pending
        keys = (*LOG_KEYS, *(k for k in EXTRA_KEYS if all(k in b for _, b in entries)))
        np.savez(
            buf,
            digest=np.array([np.frombuffer(d, np.uint8) for d, _ in entries]),
            sizes=np.array([len(b["VIOL"]) for _, b in entries], dtype=np.int64),
            **{k: np.concatenate([b[k] for _, b in entries]).astype(np.float64) for k in keys},
        )
        name = f"evals_{generation:06d}.npz"
        atomic_write_bytes(ckdir / name, buf.getvalue())
        state["chunks"].append({"file": name, "sha256": _sha(buf.getvalue()), "calls": len(entries)})
        log.pending = []
    state["generation"] = generation
    history = run_dir / "history.csv"
    if history.exists():
        state["history_sha256"] = history_digest(history.read_bytes(), generation)
    state["state_sha256"] = _state_digest(state)
    atomic_write_text(ckdir / "state.json", json.dumps(state, indent=1, allow_nan=False) + "\n")


def history_digest(data: bytes, rows: int) -> str:
    """SHA-256 of history.csv's header and first ``rows`` rows (what a resume keeps)."""
    return _sha(b"\n".join(data.split(b"\n")[: rows + 1]))


def _state_digest(state: dict[str, Any]) -> str:
    """SHA-256 of state.json's content but its own digest (an edited state is refused)."""
    return _sha(
        json.dumps({k: v for k, v in state.items() if k != "state_sha256"}, sort_keys=True, allow_nan=False).encode(
            "utf-8"
        )
    )


def read_run_file(path: Path) -> bytes:
    """The bytes of a file of a run folder (arcube wrote it: a regular file only, never waiting on a FIFO put in its
    place); InputError naming the file."""
    return read_bytes(path, fail=lambda problem: InputError(f"{path}: {problem}"), pipes=False)


def load_checkpoint(
    run_dir: Path, cfg: RunConfig, cfg_raw: bytes
) -> tuple[dict[str, Any] | None, list[tuple[bytes, Batch]]]:
    """(state, replay entries); (None, []) when the run was killed before its first checkpoint."""
    path = run_dir / "checkpoint" / "state.json"
    if not os.path.lexists(path):
        saved = sorted(path.parent.glob("evals_*.npz")) if path.parent.is_dir() else []
        if len(saved) > 1:  # the second chunk is written after the first state.json: a state was there
            raise InputError(
                f"{path}: missing, but {path.parent} holds {len(saved)} saved chunks of generations: the state was "
                "removed, and resuming would start the run over and lose its history; put state.json back, or run "
                "again into a new folder"
            )
        return None, []
    try:
        state = json.loads(read_run_file(path).decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{path}: corrupt checkpoint ({exc})") from None
    if (
        not isinstance(state, dict)
        or state.get("format") != CHECKPOINT_FORMAT
        or state.get("format_version") != FORMAT_VERSION
    ):
        raise InputError(f"{path}: not an arcube optimize checkpoint")
    if state.get("run_id") != cfg.run_id or state.get("config_sha256") != _sha(cfg_raw):
        raise InputError(
            f"{path}: checkpoint of another run or config (run_id/config.toml do not match); refusing to resume"
        )
    # checkpoints written before these digests existed have neither: nothing to check then
    if "state_sha256" in state and state["state_sha256"] != _state_digest(state):
        raise InputError(
            f"{path}: edited or corrupt checkpoint state (it does not match its SHA-256); refusing to resume"
        )
    if "history_sha256" in state:
        data = read_run_file(run_dir / "history.csv")
        if history_digest(data, int(state["generation"])) != state["history_sha256"]:
            raise InputError(
                f"{run_dir / 'history.csv'}: edited or corrupt (its first {state['generation']} rows do not match the checkpoint); refusing to resume"
            )
    entries: list[tuple[bytes, Batch]] = []
    n_obj = len(cfg.settings.run_objectives)
    try:
        for ch in state["chunks"]:
            f = path.parent / str(ch["file"])
            if f.parent != path.parent:
                raise ValueError("bad chunk name")
            data = read_run_file(f)
            if _sha(data) != ch["sha256"]:
                raise ValueError(f"{f.name} does not match its SHA-256")
            with np.load(io.BytesIO(data), allow_pickle=False) as z:
                keys = (*LOG_KEYS, *(k for k in EXTRA_KEYS if k in z.files))
                arr = {k: z[k] for k in ("digest", "sizes", *keys)}
            sizes, n = arr["sizes"].astype(np.int64), int(arr["sizes"].sum())
            if (
                arr["digest"].shape != (len(sizes), 32)
                or arr["F"].shape != (n, n_obj)
                or arr["VIOL"].shape != (n,)
                or arr["ETA"].shape != (n,)
                or len(sizes) != ch["calls"]
            ):
                raise ValueError(f"{f.name} has inconsistent shapes")
            if any(arr[k].ndim != 2 or len(arr[k]) != n for k in keys[len(LOG_KEYS) :]):
                raise ValueError(f"{f.name} has inconsistent shapes")
            start = np.concatenate([[0], np.cumsum(sizes)])
            for i in range(len(sizes)):
                sl = slice(start[i], start[i + 1])
                entries.append((arr["digest"][i].tobytes(), {k: arr[k][sl] for k in keys}))
        int(state["generation"]), float(state["elapsed_s"])
    except (OSError, ValueError, KeyError, TypeError, EOFError) as exc:
        raise InputError(f"{path.parent}: corrupt checkpoint ({exc})") from None
    return state, entries
