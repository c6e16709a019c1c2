"""Every command cold and warm: a fresh cache against the same command run again.

Each command is a fresh ``chaplygin`` process (what a user runs).  Cold: in a new, empty
``CHAPLYGIN_CACHE`` folder; warm: the same command again in the folder the cold run filled.
The commands of one system are interleaved within each repeat (cold and warm of one command
back to back), and each repeat starts from new folders.  Reported: the best and the median
of the repeats, cold and warm, and warm / cold of the best; the load average at the start.
The goal of issue 31: warm at most a third of cold (ratio ≤ 0.33).  ``--cli`` compares
installations (before and after a change) in the same run, interleaved: each repeat runs
every command with each of them in turn.  ``chaplygin --help`` is timed beside them: the
command line's own start-up, and the floor of a warm command that runs a model (a process that
imports the command line, typer's coercion of options and NumPy); beside ``sweep``, the floor of
a warm sweep (the same and pyarrow.parquet).

    .venv/bin/python benchmarks/commands.py
    .venv/bin/python benchmarks/commands.py --systems snakeboard --commands check report --repeats 5
    .venv/bin/python benchmarks/commands.py --cli ../main/.venv/bin/chaplygin .venv/bin/chaplygin
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

CLI = str(Path(sys.executable).with_name("chaplygin"))
HERE = Path(__file__).resolve().parent

#: the systems: a gallery example written out as a system file, and the snakeboard of issue 31
SYSTEMS = {
    "rolling-disk": (None, "theta=0,psi'=0,theta'=0,phi'=3", "phi'=2:6:3"),
    "snakeboard": (HERE / "systems" / "snakeboard_spring.toml", "phi=0.5,theta'=0.5,psi'=0", "J=0.1:0.2:2"),
}


#: what every warm command that runs a model imports: the command line, typer's coercion of the
#: command's options (pydantic, imported only when a command runs; --help does not) and NumPy
COMMAND_FLOOR = "import numpy, typer._adapters, chaplygin.apps.cli"
#: what a warm sweep cannot avoid: the command line's start-up, typer's coercion of the command's
#: options (through pydantic, imported only when a command runs), NumPy (the runs' arrays) and
#: writing Parquet (it reads the system file's names and run plan from the cache: no SymPy)
FLOOR = COMMAND_FLOOR + ", pyarrow.parquet"


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


#: the processes' environment: bytecode written and reused as for a user, whatever
#: ``PYTHONDONTWRITEBYTECODE`` says here (else a module without bytecode is compiled in every run)
USER = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def wall(cli: str, args: list[str], env: dict[str, str]) -> float:
    start = time.perf_counter()
    subprocess.run([cli, *args], env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def row(label: str, cold: list[float], warm: list[float]) -> str:
    b0, b1 = min(cold), min(warm)
    m0, m1 = statistics.median(cold), statistics.median(warm)
    return f"{label:40} {b0:8.2f} / {m0:6.2f} {b1:8.2f} / {m1:6.2f} {b1 / b0:10.2f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--systems", nargs="+", default=list(SYSTEMS), choices=list(SYSTEMS))
    ap.add_argument("--commands", nargs="+", default=None, help="a subset of the commands (default: all)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument(
        "--cli", nargs="+", default=[CLI], help="chaplygin executables to compare (default: this one)"
    )
    args = ap.parse_args()
    clis = [str(Path(c).absolute()) for c in args.cli]
    print(f"load average at start: {os.getloadavg()[0]:.2f} (1 min), {os.cpu_count()} cores")
    for cli in clis:
        helps = [wall(cli, ["--help"], USER) for _ in range(args.repeats)]
        print(f"{cli}: chaplygin --help best {min(helps):.3f} s, median {statistics.median(helps):.3f} s")
    python = str(Path(clis[-1]).with_name("python"))
    floor = [wall(python, ["-c", COMMAND_FLOOR], USER) for _ in range(args.repeats)]
    print(
        f"floor of a warm command (a process importing {COMMAND_FLOOR[7:]}): best {min(floor):.3f} s, "
        f"median {statistics.median(floor):.3f} s"
    )
    print(
        f"{'system / command / cli':40} {'cold best/median [s]':>17} {'warm best/median [s]':>17} {'warm/cold':>10}"
    )
    with tempfile.TemporaryDirectory(prefix="chaplygin-commands-") as tmp:
        work = Path(tmp)
        for name in args.systems:
            path, at, grid = SYSTEMS[name]
            if path is None:  # a gallery example as the user gets it: a system file
                path = work / f"{name}.toml"
                shown = subprocess.run(
                    [clis[-1], "examples", "show", name], check=True, capture_output=True, text=True
                )
                path.write_text(shown.stdout, encoding="utf-8")
            lines = commands(str(path), at, grid, work / "out")
            chosen = args.commands or list(lines)
            times: dict[tuple[str, int], tuple[list[float], list[float]]] = {
                (c, i): ([], []) for c in chosen for i in range(len(clis))
            }
            for r in range(args.repeats):
                for c in chosen:
                    for i, cli in enumerate(clis):
                        env = USER | {"CHAPLYGIN_CACHE": str(work / f"cache-{name}-{c}-{i}-{r}")}
                        times[c, i][0].append(wall(cli, lines[c], env))
                        times[c, i][1].append(wall(cli, lines[c], env))
            for c in chosen:
                for i in range(len(clis)):
                    label = f"{name} {c}" + (f" [{i}]" if len(clis) > 1 else "")
                    print(row(label, *times[c, i]), flush=True)
            if "sweep" in chosen:  # a warm sweep starts the command line and writes Parquet: its floor
                floor = [wall(python, ["-c", FLOOR, str(path)], USER) for _ in range(args.repeats)]
                print(
                    f"{name + ' sweep floor (imports)':40} {'':17} "
                    f"{min(floor):8.2f} / {statistics.median(floor):6.2f}",
                    flush=True,
                )
        if len(clis) > 1:
            print("cli " + ", ".join(f"[{i}] {c}" for i, c in enumerate(clis)))


if __name__ == "__main__":
    main()
