"""The derivation cache from the command line: first ``chaplygin derive`` against the second.

Each target is derived by a fresh ``chaplygin`` process (what a user runs) in an
empty cache directory (a temporary ``CHAPLYGIN_CACHE``): once cold, then
``--repeats`` times more from the cache.  The baseline in the same run is the
same command with ``--no-cache``.  Reported: best wall time of each, and the ratio.

    .venv/bin/python benchmarks/cache.py
    .venv/bin/python benchmarks/cache.py --targets example:rolling-disk:chaplygin --repeats 5
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CLI = [str(Path(sys.executable).with_name("chaplygin"))]


def wall(args: list[str], env: dict[str, str]) -> float:
    start = time.perf_counter()
    subprocess.run(CLI + args, env=env, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "--targets",
        nargs="+",
        default=["example:rolling-disk:chaplygin", "example:rolling-sphere:chaplygin"],
        help="SOURCE:MODEL pairs (SOURCE an example: name or a system file)",
    )
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    print(f"{'target':40} {'--no-cache [s]':>15} {'first [s]':>10} {'cached [s]':>11} {'ratio':>7}")
    for target in args.targets:
        source, model = target.rsplit(":", 1)
        command = ["derive", source, "--model", model]
        with tempfile.TemporaryDirectory(prefix="chaplygin-cache-") as tmp:
            env = os.environ | {"CHAPLYGIN_CACHE": tmp}
            uncached = min(wall([*command, "--no-cache"], env) for _ in range(2))
            first = wall(command, env)
            cached = min(wall(command, env) for _ in range(args.repeats))
        print(f"{target:40} {uncached:15.2f} {first:10.2f} {cached:11.3f} {first / cached:6.1f}×", flush=True)


if __name__ == "__main__":
    main()
