"""``python -m chaplygin`` and the ``chaplygin`` command: the command line (:mod:`chaplygin.apps.cli`)."""

from __future__ import annotations

import sys


def run() -> int:
    """Run the command line; return the exit status.  A Ctrl-C while it starts (its imports, before
    a command's own handling) ends as one inside a command does: a line, status 130, no traceback."""
    try:
        from chaplygin.apps.cli import main

        return main()
    except KeyboardInterrupt:
        sys.stderr.write("interrupted: no output was left half-written.\n")
        return 130


if __name__ == "__main__":
    raise SystemExit(run())
