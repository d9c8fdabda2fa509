"""Re-paste the live ``arcube COMMAND --help`` output into docs/cli.md.

Run ``.venv/bin/python docs/regen_cli_help.py`` after changing a command's options; the docs test
``test_cli_reference_lists_the_live_options`` fails until you do.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from typer.testing import CliRunner

from arcube.cli import app

CLI_MD = Path(__file__).with_name("cli.md")
BLOCK = re.compile(r"```text\n(Usage: arcube (?:\[OPTIONS\] COMMAND|(\w+(?: \w+)?)).*?)```", re.DOTALL)


def live_help(command: str) -> str:
    """The ``--help`` text of ``arcube COMMAND`` ('' for the root; ``"calibrate poses"`` for a subcommand), 80 columns, no colour."""
    env = {"COLUMNS": "80", "TERM": "dumb", "NO_COLOR": "1"}
    os.environ.update(env)
    result = CliRunner().invoke(app, [*command.split(), "--help"] if command else ["--help"], env=env)
    return result.output.rstrip() + "\n"


def main() -> None:
    text = CLI_MD.read_text(encoding="utf-8")
    new = BLOCK.sub(lambda m: "```text\n" + live_help(m.group(2) or "") + "```", text)
    CLI_MD.write_text(new, encoding="utf-8")
    print(f"{CLI_MD}: {'updated' if new != text else 'unchanged'}")


if __name__ == "__main__":
    main()
