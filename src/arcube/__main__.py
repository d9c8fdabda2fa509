"""``python -m arcube`` and the ``arcube`` script: install the Ctrl-C and SIGTERM handling, then import and run the CLI.

Importing the CLI takes seconds (NumPy, SciPy, pydantic, the commands); an interrupt in that time ends
the process with one line and exit code 130 (SIGTERM: 143; :func:`arcube.interrupts.start_up`), and so does one
after the command has finished, while Python shuts down.
"""

from __future__ import annotations


def main() -> None:
    """The ``arcube`` command: :func:`arcube.cli.main` under the Ctrl-C and SIGTERM handling of :mod:`arcube.interrupts`."""
    import arcube.interrupts as interrupts  # not ``from arcube import``: that asks the package's __getattr__ first

    interrupts.start_up()
    try:
        from arcube.cli import main as cli_main

        cli_main()
    finally:
        interrupts.start_up()


if __name__ == "__main__":
    main()
