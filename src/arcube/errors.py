"""Error types shared by the whole package."""

from __future__ import annotations


class InputError(ValueError):
    """Bad user input (file, design, parameter).

    The message is one line that names the source (file, row, parameter) and the problem;
    the CLI prints it as ``error: <message>`` and exits with code 2. A library error about one
    parameter names it as the caller wrote it (``points``, ``Loads.thrust_N``) and carries that
    name in :attr:`param`; the CLI replaces it with its flag (``--points``, ``--thrust``), in one
    place (:mod:`arcube.cli.projection`).
    """

    def __init__(self, message: str, *, param: str | None = None) -> None:
        super().__init__(message)
        self.param = param

    @classmethod
    def of(cls, param: str, problem: str) -> InputError:
        """``"<param> <problem>"``, e.g. ``InputError.of("points", "must be at least 2, got 1")``."""
        return cls(f"{param} {problem}", param=param)


class RenamedWarning(FutureWarning):
    """A setting, flag or value given by its old name, still taken for one release (the warning names the new one)."""
