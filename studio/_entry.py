"""The ``studio`` console script: loads the command line, so that Ctrl-C while it loads ends quietly.

The script generated for ``studio.cli:main`` would import the command line (numpy, typer, ...: a tenth
of a second) before any handler is in place, and Ctrl-C then printed Python's traceback. Here the
import runs under a handler; once the command line runs, typer turns Ctrl-C into exit code 130.
"""

from __future__ import annotations

import sys

__all__ = ["main"]

_INTERRUPTED = 130  # 128 + SIGINT, as shells report it


def main() -> None:
    try:
        from studio.cli import main as cli_main
    except KeyboardInterrupt:
        sys.exit(_INTERRUPTED)
    cli_main()
