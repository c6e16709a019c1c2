"""``python -m chaplygin``: the command line (see :mod:`chaplygin.cli`)."""

from __future__ import annotations

from .cli import main

if __name__ == "__main__":
    raise SystemExit(main())
