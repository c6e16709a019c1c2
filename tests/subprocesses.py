"""Run a Python script in a fresh process against this tree's chaplygin and read its report.

Shared by the tests that need a new process (caches on disk, imports at start-up): the script
prints a JSON object as its last line of output.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Iterable
from pathlib import Path

import chaplygin

#: the folder holding this tree's ``chaplygin`` package (the child's ``PYTHONPATH``)
SRC = str(Path(chaplygin.__file__).resolve().parents[1])


def run_json(script: str, args: list[str], cache: Path, *, unset: Iterable[str] = (), **env: str) -> dict:
    """Run ``script`` with ``args`` on chaplygin's ``cache`` (``$CHAPLYGIN_CACHE``) and ``env``,
    without the variables ``unset``; its last line of output as a dict, the lines before as
    ``"stdout"``.  The process must succeed."""
    environ = {k: v for k, v in os.environ.items() if k not in set(unset)}
    environ |= {"CHAPLYGIN_CACHE": str(cache), "PYTHONPATH": SRC, **env}
    done = subprocess.run(
        [sys.executable, "-c", script, *args],
        capture_output=True,
        text=True,
        env=environ,
        timeout=600,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    lines = done.stdout.strip().splitlines()
    return {**json.loads(lines[-1]), "stdout": "\n".join(lines[:-1])}
