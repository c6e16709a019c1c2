"""Every command cold and warm: a fresh cache against the same command run again.

Each command is a fresh ``chaplygin`` process (what a user runs).  Cold: in a new, empty
``CHAPLYGIN_CACHE`` folder; warm: the same command again in the folder the cold run filled.
The commands of one system are interleaved within each repeat (cold and warm of one command
back to back), and each repeat starts from new folders.  Reported: the best and the median
of the repeats, cold and warm, and warm / cold of the best; the load average at the start.
The goal of issue 31: warm at most a third of cold (ratio ≤ 0.33).

    .venv/bin/python benchmarks/commands.py
    .venv/bin/python benchmarks/commands.py --systems snakeboard --commands check report --repeats 5
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CLI = [str(Path(sys.executable).with_name("chaplygin"))]
HERE = Path(__file__).resolve().parent

#: the systems: a gallery example written out as a system file, and the snakeboard of issue 31
SYSTEMS = {
    "rolling-disk": (None, "theta=0.3,psi'=1,theta'=0,phi'=3", "phi'=2:6:3"),
    "snakeboard": (HERE / "systems" / "snakeboard_spring.toml", "phi=0.5,theta'=0.5,psi'=0", "J=0.1:0.2:2"),
}


def commands(file: str, at: str, grid: str, out: Path) -> dict[str, list[str]]:
    """The command lines timed, by name (every output goes under ``out``, overwritten)."""
    return {
        "derive": ["derive", file],
        "check": ["check", file],
        "simulate": ["simulate", file, "-t", "100", "-o", str(out / "run.csv"), "--force"],
        "compare": ["compare", file, "-t", "10", "-o", str(out / "compare"), "--force"],
        "report": ["report", file, "-t", "10", "-o", str(out / "report.html"), "--force"],
        "export": ["export", file, "--to", "c", "--jacobian", "-o", str(out / "model.c"), "--force"],
        "sweep": ["sweep", file, "-g", grid, "-t", "5", "-o", str(out / "sweep.parquet"), "--force"],
        "stability": ["stability", file, "--at", at],
    }


def wall(args: list[str], env: dict[str, str]) -> float:
    start = time.perf_counter()
    subprocess.run(CLI + args, env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--systems", nargs="+", default=list(SYSTEMS), choices=list(SYSTEMS))
    ap.add_argument("--commands", nargs="+", default=None, help="a subset of the commands (default: all)")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    print(f"load average at start: {os.getloadavg()[0]:.2f} (1 min), {os.cpu_count()} cores")
    print(
        f"{'system':14} {'command':10} {'cold best/median [s]':>22} {'warm best/median [s]':>22} {'warm/cold':>10}"
    )
    with tempfile.TemporaryDirectory(prefix="chaplygin-commands-") as tmp:
        work = Path(tmp)
        for name in args.systems:
            path, at, grid = SYSTEMS[name]
            if path is None:  # a gallery example as the user gets it: a system file
                path = work / f"{name}.toml"
                text = subprocess.run(
                    [*CLI, "examples", "show", name], check=True, capture_output=True, text=True
                )
                path.write_text(text.stdout, encoding="utf-8")
            lines = commands(str(path), at, grid, work / "out")
            chosen = args.commands or list(lines)
            cold: dict[str, list[float]] = {c: [] for c in chosen}
            warm: dict[str, list[float]] = {c: [] for c in chosen}
            for r in range(args.repeats):
                for c in chosen:
                    env = os.environ | {"CHAPLYGIN_CACHE": str(work / f"cache-{name}-{c}-{r}")}
                    cold[c].append(wall(lines[c], env))
                    warm[c].append(wall(lines[c], env))
            for c in chosen:
                b0, b1 = min(cold[c]), min(warm[c])
                m0, m1 = statistics.median(cold[c]), statistics.median(warm[c])
                print(
                    f"{name:14} {c:10} {b0:10.2f} / {m0:9.2f} {b1:10.2f} / {m1:9.2f} {b1 / b0:10.2f}",
                    flush=True,
                )


if __name__ == "__main__":
    main()
