"""A system file from nothing to a trajectory, whole processes: what a script pays before it integrates.

Run from the repository root::

    .venv/bin/python benchmarks/warmfile.py                          # best and median of 7
    .venv/bin/python benchmarks/warmfile.py --src /work/main/src     # and another checkout beside
    .venv/bin/python benchmarks/warmfile.py --casadi auto            # and benchmarks/casadi.py's CasADi script beside

Each route is a fresh ``python`` process, timed from start to exit, the routes interleaved in
every repeat (a shared machine's noise falls on all of them alike): the snakeboard of
``benchmarks/systems/snakeboard_spring.toml`` integrated to t = 100 (Chetaev's model, DOP853,
rtol 1e-10) by

- ``simulate(f)``: ``f = chaplygin.load(FILE); chaplygin.simulate(f, "chetaev", 100)``, warm (a
  run of the same file before: its run plan answers without SymPy) and cold (a fresh
  ``CHAPLYGIN_CACHE`` every run: derivation, code generation and the C build included);
- ``simulate(f.system)``: the same from the ``System`` (SymPy imported by the user's choice),
  warm and cold;
- ``chaplygin simulate FILE -t 100 -o out.csv``, warm, beside ``chaplygin --help`` (the command
  line's own start-up);
- the floors ``python -c "import numpy"`` and ``python -c "import sympy, numpy"``.

Byte code is cached under a private ``PYTHONPYCACHEPREFIX`` (as an installed package has it),
whatever ``PYTHONDONTWRITEBYTECODE`` says; the first, untimed round writes it and the caches.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
FILE = HERE / "systems" / "snakeboard_spring.toml"
LOADED = (
    f'import chaplygin; f = chaplygin.load(r"{FILE}"); assert chaplygin.simulate(f, "chetaev", 100).success'
)
SYSTEM = (
    f'import chaplygin; f = chaplygin.load(r"{FILE}"); '
    'assert chaplygin.simulate(f.system, "chetaev", 100, f.initial, f.parameters).success'
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--src", help="another checkout's src folder, timed beside this one")
    parser.add_argument(
        "--casadi",
        help="a CasADi script of the same run, timed beside; 'auto': the one benchmarks/casadi.py writes",
    )
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="warmfile-"))
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["PYTHONPYCACHEPREFIX"] = str(work / "pyc")
    out = str(work / "out.csv")

    def route(command: list[str], src: str | None = None, cache: str | None = None) -> object:
        def run() -> float:
            extra = {"PYTHONPATH": src} if src else {}
            folder = cache or tempfile.mkdtemp(prefix="cold-", dir=work)  # no cache given: cold
            started = time.perf_counter()
            done = subprocess.run(
                command, env={**env, **extra, "CHAPLYGIN_CACHE": folder}, capture_output=True, check=False
            )
            took = time.perf_counter() - started
            if cache is None:
                shutil.rmtree(folder, ignore_errors=True)
            return took if done.returncode == 0 else float("nan")

        return run

    py = sys.executable
    routes = {"import numpy": route([py, "-c", "import numpy"])}
    routes["import sympy, numpy"] = route([py, "-c", "import sympy, numpy"])
    if args.casadi == "auto":  # benchmarks/casadi.py's script of the snakeboard (cvodes, Adams)
        import importlib.util

        spec = importlib.util.spec_from_file_location("casadi_benchmark", HERE / "casadi.py")
        assert spec is not None and spec.loader is not None
        bench = sys.modules["casadi_benchmark"] = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(bench)  # (it imports CasADi itself, or says how to install it)
        args.casadi = str(work / "casadi_snakeboard.py")
        Path(args.casadi).write_text(bench.casadi_script("snakeboard", "adams"), encoding="utf-8")
    if args.casadi:
        routes["CasADi script"] = route([py, args.casadi])
    trees = {"this tree": str(HERE.parent / "src")} | ({"--src": args.src} if args.src else {})
    for label, src in trees.items():
        warm = str(work / f"cache-{len(routes)}")
        routes[f"{label}: simulate(f), warm"] = route([py, "-c", LOADED], src, warm)
        routes[f"{label}: simulate(f.system), warm"] = route([py, "-c", SYSTEM], src, warm)
        cli = [py, "-m", "chaplygin"]
        routes[f"{label}: chaplygin simulate, warm"] = route(
            [*cli, "simulate", str(FILE), "-t", "100", "-o", out, "--force"], src, warm
        )
        routes[f"{label}: chaplygin --help"] = route([*cli, "--help"], src, warm)
        routes[f"{label}: simulate(f), cold"] = route([py, "-c", LOADED], src)
        routes[f"{label}: simulate(f.system), cold"] = route([py, "-c", SYSTEM], src)
    for run in routes.values():  # byte code, caches and run plans
        run()
    times: dict[str, list[float]] = {label: [] for label in routes}
    for _ in range(args.repeat):
        for label, run in routes.items():
            times[label].append(run())
    shutil.rmtree(work, ignore_errors=True)
    print(f"{args.repeat} repeats, interleaved; load average {os.getloadavg()[0]:.2f} at the end")
    print(f"{'route':44s} {'best':>8s} {'median':>8s}")
    for label, ts in times.items():
        if any(t != t for t in ts):  # nan: the route failed (an older checkout without it)
            print(f"{label:44s} {'n/a':>8s} {'n/a':>8s}")
        else:
            print(f"{label:44s} {min(ts):7.3f}s {statistics.median(ts):7.3f}s")


if __name__ == "__main__":
    main()
