"""The everyday path, in one run: what a user meets first, against the peer route written by hand.

Run from the repository root::

    .venv/bin/python benchmarks/everyday.py              # everything (benchmarks/README.md's table)
    .venv/bin/python benchmarks/everyday.py --repeat 3   # fewer repeats
    .venv/bin/python benchmarks/everyday.py --json out.json

The peer route is ``benchmarks/peer_rolling_disk.py``: SymPy's ``KanesMethod`` derives the
rolling disk, ``lambdify`` + NumPy's ``solve`` evaluate it and SciPy's ``solve_ivp`` (DOP853,
rtol 1e-10, atol 1e-12) integrates ``example:rolling-disk``'s default state to t = 100 —
the same motion ``chaplygin simulate example:rolling-disk -m chaplygin -t 100`` computes.

1. **Solved accelerations**, in this process, SymPy's cache cleared before each repeat, best
   of ``--repeat``: KanesMethod's ``kanes_equations`` + ``rhs()`` against chaplygin's build +
   derivation + ``Equations.accelerations`` of the rolling disk for every model; the sphere; the
   5-coordinate unicycle carrying a damped pendulum (``benchmarks/systems/
   unicycle_pendulum.toml``: load, derive, solve and the displayed equations — what ``chaplygin
   derive`` computes); Voronets' equations of random 4-coordinate systems (the generator of the
   property tests, derandomized).  ``count_ops`` of the results beside.
2. **Whole processes**, median of ``--repeat`` wall times: the peer script against ``chaplygin
   simulate`` with each backend, with a *cold* cache (a fresh ``CHAPLYGIN_CACHE`` each run:
   derivation, code generation and compilation included) and a *warm* one (after one untimed
   run); ``chaplygin derive`` of the unicycle file, cold and warm.  The final states of the peer
   and of chaplygin are compared, so both computed the same motion.
3. **The long run**: t = 1000 in this process, the peer's right-hand side with ``solve_ivp``
   against ``simulate(backend="c")`` (warm), and ``numba``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import sympy as sp
from sympy.core.cache import clear_cache

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))  # this working tree, also when not installed
sys.path.insert(0, str(ROOT / "tests"))  # the random systems of the property tests

import peer_rolling_disk

from chaplygin import (
    examples,
    simulate,
)
from chaplygin.io.files import load

PYTHON = sys.executable
CLI = [PYTHON, "-m", "chaplygin"]
UNICYCLE = ROOT / "benchmarks" / "systems" / "unicycle_pendulum.toml"
MODELS = ("chaplygin", "voronets", "chetaev", "vakonomic", "lindelof", "vakonomic_family")
RESULTS: dict[str, float] = {}


def say(line: str = "") -> None:
    print(line, flush=True)


def best(task: Callable[[], object], repeat: int) -> tuple[float, object]:
    """Best wall time of ``repeat`` runs, each after clearing SymPy's cache; and a result."""
    times, out = [], None
    for _ in range(repeat):
        clear_cache()
        start = time.perf_counter()
        out = task()
        times.append(time.perf_counter() - start)
    return min(times), out


def ops(exprs: object) -> int:
    values = exprs.values() if isinstance(exprs, dict) else exprs
    return sum(sp.count_ops(e) for e in values)  # type: ignore[union-attr]


# --------------------------------------------------------------------------- 1. symbolic
def part_symbolic(repeat: int) -> None:
    say(f"1. Solved accelerations (in process; best of {repeat}, SymPy cache cleared each time)")
    (
        peer_rolling_disk.kane_disk(rhs=True),
        examples.rolling_disk().equations("chetaev").accelerations,
    )  # imports
    kane_t, kane = best(lambda: peer_rolling_disk.kane_disk(rhs=True)[0].rhs(), repeat)
    RESULTS["kane rhs"] = kane_t
    say(
        f"   {'rolling disk, KanesMethod kanes_equations + rhs()':58s} {kane_t:7.3f} s  ops {ops(list(kane)):6d}"
    )
    for model in MODELS:
        t, acc = best(lambda: examples.rolling_disk().equations(model).accelerations, repeat)
        RESULTS[f"disk {model}"] = t
        say(
            f"   {'rolling disk, chaplygin ' + model:58s} {t:7.3f} s  ops {ops(acc):6d}"
            f"  {t / kane_t:5.2f}x Kane's time"
        )
    for model in ("chaplygin", "chetaev", "vakonomic", "lindelof"):
        t, acc = best(lambda: examples.rolling_sphere().equations(model).accelerations, repeat)
        RESULTS[f"sphere {model}"] = t
        say(f"   {'sphere, chaplygin ' + model:58s} {t:7.3f} s  ops {ops(acc):6d}")

    def unicycle(model: str) -> object:
        eqs = load(UNICYCLE).system.equations(model)
        return eqs.equations, eqs.accelerations

    for model in ("chaplygin", "chetaev"):
        t, (_, acc) = best(lambda: unicycle(model), repeat)
        RESULTS[f"unicycle {model}"] = t
        say(
            f"   {'unicycle + pendulum (5 coordinates), ' + model + ', load+derive+print':58s} {t:7.3f} s  ops {ops(acc):6d}"
        )

    from hypothesis import HealthCheck, given, settings

    from randomsystems import systems

    specs: list = []

    @settings(
        max_examples=200,
        database=None,
        derandomize=True,
        deadline=None,
        suppress_health_check=list(HealthCheck),
    )
    @given(spec=systems(chaplygin=False))
    def collect(spec: object) -> None:
        if spec.system.n == 4 and len(specs) < 8:  # type: ignore[attr-defined]
            specs.append(spec)

    collect()
    times = []
    for spec in specs:
        t, _ = best(lambda: (lambda e: (e.equations, e.accelerations))(spec.system.equations("voronets")), 1)
        times.append(t)
    RESULTS["voronets random max"] = max(times)
    say(
        f"   {f'Voronets, {len(times)} random 4-coordinate systems: median / max':58s} "
        f"{statistics.median(times):7.3f} / {max(times):.3f} s"
    )


# --------------------------------------------------------------------------- 2. processes
def run(cmd: list[str], env: dict[str, str] | None = None) -> float:
    """Wall time of one process.  Its Python writes and reuses bytecode as a user's does, even where
    this one was started with ``PYTHONDONTWRITEBYTECODE`` (which recompiles every module each run)."""
    env = {k: v for k, v in (os.environ if env is None else env).items() if k != "PYTHONDONTWRITEBYTECODE"}
    start = time.perf_counter()
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"failed: {' '.join(cmd)}\n{done.stdout}\n{done.stderr}")
    return wall


def median_wall(
    cmd: list[str], repeat: int, cold: bool, warm_dir: str, before: list[str] | None = None
) -> float:
    """Median wall time of ``cmd``: on an empty cache (``cold``) or ``warm_dir``; ``before`` runs
    first, untimed, on the same empty cache (another system: what the installation keeps)."""
    times = []
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as fresh:
            env = {**os.environ, "CHAPLYGIN_CACHE": fresh if cold else warm_dir}
            if before is not None:
                run(before, env)
            times.append(run(cmd, env))
    return statistics.median(times)


def part_processes(repeat: int, work: Path) -> None:
    say(f"\n2. Whole processes (median of {repeat} wall times)")
    peer_out = work / "peer.npz"
    peer_t = statistics.median(
        run([PYTHON, str(ROOT / "benchmarks" / "peer_rolling_disk.py"), "--out", str(peer_out)])
        for _ in range(repeat)
    )
    RESULTS["peer process"] = peer_t
    say(f"   {'peer: KanesMethod + lambdify + solve_ivp, t = 100 (one script)':58s} {peer_t:7.3f} s")
    warm_dir = str(work / "cache")
    ours = work / "ours.npz"
    for backend in ("auto", "c", "numpy", "numba"):
        cmd = [
            *CLI,
            "simulate",
            "example:rolling-disk",
            "-m",
            "chaplygin",
            "-t",
            "100",
            "-o",
            str(ours),
            "--force",
            "-b",
            backend,
        ]
        run(cmd, {**os.environ, "CHAPLYGIN_CACHE": warm_dir})  # fills the warm cache
        # "new system": an empty cache after a run of another system (the Chaplygin sleigh), so what
        # is compiled once per installation (the C and numba DOP853 loops) is there already
        other = [*cmd[:4], "example:chaplygin-sleigh", *cmd[5:]]
        for label, cold, before in (("cold", True, None), ("new system", True, other), ("warm", False, None)):
            t = median_wall(cmd, repeat, cold, warm_dir, before)
            RESULTS[f"simulate {backend} {label}"] = t
            say(
                f"   {'chaplygin simulate -t 100 -b ' + backend + ', ' + label + ' cache':58s} {t:7.3f} s"
                f"  {t / peer_t:5.2f}x the peer"
            )
    # the floor under the numba backend: a process that only imports numba and calls one function
    # from numba's on-disk cache (numba's import, LLVM and its typing registries; nothing of ours)
    floor = work / "numba_floor.py"
    floor.write_text("import numba\n\n@numba.njit(cache=True)\ndef f(x):\n    return x + 1.0\n\nf(1.0)\n")
    run([PYTHON, str(floor)])  # fills numba's cache next to the script
    t = statistics.median(run([PYTHON, str(floor)]) for _ in range(repeat))
    RESULTS["numba floor"] = t
    say(
        f"   {'floor: a script importing numba, one cached njit call':58s} {t:7.3f} s  {t / peer_t:5.2f}x the peer"
    )
    a, b = np.load(peer_out), np.load(ours)
    diff = max(abs(a[k][-1] - b[k][-1]) for k in ("psi", "theta", "phi", "x", "y"))
    say(f"   (final states of the peer and chaplygin differ by at most {diff:.1e})")
    cmd = [*CLI, "derive", str(UNICYCLE), "-m", "chaplygin"]
    run(cmd, {**os.environ, "CHAPLYGIN_CACHE": warm_dir})
    for label, cold in (("cold", True), ("warm", False)):
        t = median_wall(cmd, repeat, cold, warm_dir)
        RESULTS[f"derive unicycle {label}"] = t
        say(f"   {'chaplygin derive unicycle_pendulum.toml, ' + label + ' cache':58s} {t:7.3f} s")


# --------------------------------------------------------------------------- 3. long run
def part_long(t_end: float) -> None:
    from scipy.integrate import solve_ivp

    say(f"\n3. The long run, t = {t_end:g}, in this process")
    km, q, u, params, constraints = peer_rolling_disk.kane_disk(rhs=False)
    f = sp.lambdify([*q, *u, *params], [km.mass_matrix_full, km.forcing_full])
    values = [peer_rolling_disk.PARAMETERS[p.name] for p in params]
    init = peer_rolling_disk.INITIAL
    start = {qi: init[qi.name] for qi in q} | {ui: init[qi.name + "'"] for qi, ui in zip(q[:3], u[:3])}
    start.update(sp.solve([c.subs(start).subs(dict(zip(params, values))) for c in constraints], u[3:]))
    y0 = np.array([float(start[s]) for s in (*q, *u)])

    def fun(_t: float, y: np.ndarray) -> np.ndarray:
        M, F = f(*y, *values)
        return np.linalg.solve(M, F).ravel()

    t0 = time.perf_counter()
    solve_ivp(
        fun, (0, t_end), y0, method="DOP853", rtol=1e-10, atol=1e-12, t_eval=np.linspace(0, t_end, 1001)
    )
    peer = time.perf_counter() - t0
    say(f"   {'peer: lambdify(M, F) + solve_ivp DOP853':58s} {peer:7.3f} s")
    disk = examples.get("rolling-disk")
    system = disk.constructor()
    for backend in ("c", "numba"):

        def go() -> object:
            return simulate(
                system, "chaplygin", t_end, disk.initial, disk.parameters, samples=1001, backend=backend
            )

        go()  # compile (or load) first
        t = best(go, 3)[0]
        RESULTS[f"long {backend}"] = t
        say(
            f"   {'chaplygin simulate(backend=' + repr(backend) + ')':58s} {t:7.3f} s  {peer / t:6.0f}x faster"
        )


def machine() -> str:
    model = "unknown"
    for line in Path("/proc/cpuinfo").read_text().splitlines() if Path("/proc/cpuinfo").exists() else []:
        if line.startswith("model name"):
            model = line.split(":", 1)[1].strip()
            break
    load_avg = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return (
        f"cpu: {model}, {os.cpu_count()} logical CPUs, load average {load_avg:.1f}; "
        f"python {platform.python_version()}, sympy {sp.__version__}, numpy {np.__version__}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--t-long", type=float, default=1000.0)
    parser.add_argument("--only", choices=["symbolic", "processes", "long"], default=None)
    parser.add_argument("--json", default=None, help="also write the numbers to this file")
    args = parser.parse_args()
    say(machine())
    with tempfile.TemporaryDirectory() as work:
        if args.only in (None, "symbolic"):
            part_symbolic(args.repeat)
        if args.only in (None, "processes"):
            part_processes(args.repeat, Path(work))
        if args.only in (None, "long"):
            part_long(args.t_long)
    if args.json:
        Path(args.json).write_text(json.dumps(RESULTS, indent=1))


if __name__ == "__main__":
    main()
