"""``python -m chaplygin``: the command line (see :mod:`chaplygin.apps.cli`)."""

from __future__ import annotations

from chaplygin.apps.cli import main

if __name__ == "__main__":
    raise SystemExit(main())
