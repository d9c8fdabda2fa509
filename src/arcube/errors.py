"""Error types shared by the whole package."""

from __future__ import annotations


class InputError(ValueError):
    """Bad user input (file, design, flag).

    The message is one line that names the source (file, row, parameter) and the problem;
    the CLI prints it as ``error: <message>`` and exits with code 2.
    """
