"""chaplygin against CasADi, the route a robotics engineer who wants speed writes (issue 31).

Run from the repository root (CasADi is a benchmark dependency only)::

    .venv/bin/pip install "casadi>=3.6"                # or: pip install -e '.[bench]'
    .venv/bin/python benchmarks/casadi.py              # everything, best/median of 5 (a few minutes)
    .venv/bin/python benchmarks/casadi.py --repeat 3 --only processes
    .venv/bin/python benchmarks/casadi.py --only inprocess --systems snakeboard
    .venv/bin/python benchmarks/casadi.py --src /path/to/other/checkout/src
    .venv/bin/python benchmarks/casadi.py --json out.json

Two systems: the snakeboard with a steering spring (``benchmarks/systems/snakeboard_spring.toml``)
and the rolling disk (``benchmarks/systems/rolling_disk.toml``: ``examples.rolling_disk()`` with
``example:rolling-disk``'s parameters and state).  The CasADi side is written as its users write
it (:func:`snakeboard_casadi`, :func:`disk_casadi`): SX symbols, the Lagrangian, the multipliers'
KKT system ``[[M, -Aᵀ], [A, 0]] [q̈; λ] = [∂L/∂q - (∂²L/∂q̇∂q) q̇; -(∂(A q̇)/∂q) q̇]`` solved
symbolically with ``casadi.solve`` (the equations of the Chetaev model; a CasADi user does not
reduce them by hand), a start whose dependent velocities solve the constraints, and
``casadi.integrator`` with CVODES (rtol 1e-10, atol 1e-12, an output grid of 1001 times), with
Adams (the reference of every ratio) and with BDF.

1. **Whole processes** (``subprocess`` wall time; the rows interleaved, one of each per round):
   the CasADi script; ``chaplygin.load`` + ``chaplygin.simulate(f.system, model, 100, f.initial,
   f.parameters)`` (and ``chaplygin.simulate(f, model, 100)`` where the chaplygin under test
   takes a loaded file); ``chaplygin simulate FILE -m model -t 100 -o out.csv``; each with a warm
   cache (after an untimed run) and a cold one (an empty ``CHAPLYGIN_CACHE`` per run: the first
   run after installation; the C DOP853 loop is part of an installed chaplygin, built by its
   ``setup.py``, where the checkout under test was installed with ``pip install -e`` or ``make``;
   CasADi has no cache, its cold run is its warm run);
   the floors ``chaplygin --help``, typer's pydantic coercion of a command's options,
   ``import sympy, numpy``, ``import numpy`` and ``import casadi, numpy``.  Every process prints
   or writes its final state, checked against CasADi's.
2. **In process**: one ``chaplygin.simulate()`` call to t = 1, 100 and 1000 (the system loaded
   once, one untimed call first) against a call ``F(x0=...)`` of CasADi's integrator (built once
   per end time), interleaved; the final states compared.

The models: ``chetaev`` (multipliers, what the CasADi script computes) and ``chaplygin`` (the
reduced equations of both Chaplygin systems); ``--models`` picks others.  Reported: best and
median of ``--repeat``, the ratio of the best to CasADi's (Adams) best, and the goal of issue 31.
"""

from __future__ import annotations

import argparse
import csv
import functools
import inspect
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
# run as a script, this file's folder comes first on sys.path and its name would hide CasADi's
sys.path[:] = [p for p in sys.path if Path(p or os.curdir).resolve() != HERE]
try:
    import casadi as ca
except ImportError:
    raise SystemExit(
        "benchmarks/casadi.py needs CasADi (a benchmark dependency only): "
        "`.venv/bin/pip install 'casadi>=3.6'` (or `pip install -e '.[bench]'`)"
    ) from None

SRC = ROOT / "src"
if "--src" in sys.argv[:-1]:  # time another checkout of chaplygin (e.g. a git worktree)
    SRC = Path(sys.argv[sys.argv.index("--src") + 1]).resolve()
sys.path.insert(0, str(SRC))

import chaplygin

PYTHON = sys.executable
SYSTEMS = {
    "snakeboard": HERE / "systems" / "snakeboard_spring.toml",
    "disk": HERE / "systems" / "rolling_disk.toml",
}
T_END = 100.0
RESULTS: dict[str, Any] = {}


def say(line: str = "") -> None:
    print(line, flush=True)


# --------------------------------------------------------------------------- the CasADi user's code
# What a CasADi user writes; written out as the CasADi script of the whole-process rows and called
# in process.  Only `ca` (casadi) and `np` (numpy) are used.
def kkt_ode(q: Any, qd: Any, T: Any, V: Any, A: Any) -> Any:
    """The state derivative [q̇; q̈] of the Lagrange-d'Alembert equations with multipliers λ:
    M q̈ - Aᵀ λ = ∂L/∂q - (∂²L/∂q̇∂q) q̇ and A q̈ = -(∂(A q̇)/∂q) q̇, one symbolic solve."""
    L = T - V
    M = ca.hessian(T, qd)[0]
    f = ca.gradient(L, q) - ca.jacobian(ca.gradient(L, qd), q) @ qd
    n, g = q.numel(), A.size1()
    K = ca.vertcat(ca.horzcat(M, -A.T), ca.horzcat(A, ca.SX.zeros(g, g)))
    sol = ca.solve(K, ca.vertcat(f, -ca.jacobian(A @ qd, q) @ qd))
    return ca.vertcat(qd, sol[:n])


def consistent_start(q: Any, A: Any, q0: Any, v: Any, dependent: list[int]) -> Any:
    """[q0; q̇0]: the velocities ``v`` with those of the ``dependent`` coordinates solved from A q̇ = 0."""
    a = np.array(ca.Function("A", [q], [A])(q0))
    free = [i for i in range(len(q0)) if i not in dependent]
    v = np.array(v, dtype=float)
    v[dependent] = np.linalg.solve(a[:, dependent], -a[:, free] @ v[free])
    return np.concatenate([q0, v])


def cvodes(q: Any, qd: Any, ode: Any, t_end: float, method: str) -> Any:
    """CVODES on an output grid of 1001 times from 0 to ``t_end``; ``method``: adams or bdf."""
    grid = np.linspace(0.0, t_end, 1001)
    options = {
        "abstol": 1e-12,
        "reltol": 1e-10,
        "max_num_steps": 10**7,
        "linear_multistep_method": method,
    }
    return ca.integrator("F", "cvodes", {"x": ca.vertcat(q, qd), "ode": ode}, 0.0, grid, options)


def snakeboard_casadi(t_end: float, method: str) -> tuple[Any, Any]:
    """The snakeboard with a steering spring (snakeboard_spring.toml): integrator and start."""
    m, l, J, Jr = 1.0, 0.5, 0.1, 0.05
    q, qd = ca.SX.sym("q", 5), ca.SX.sym("qd", 5)
    x, y, th, psi, phi = ca.vertsplit(q)
    xd, yd, thd, psid, phid = ca.vertsplit(qd)
    T = m / 2 * (xd**2 + yd**2) + J / 2 * thd**2 + Jr / 2 * psid**2 + Jr * thd * psid + phid**2 / 2
    V = 50 * (phi - 0.5) ** 2
    A = ca.vertcat(
        ca.horzcat(-ca.sin(th + phi), ca.cos(th + phi), -l * ca.cos(phi), 0, 0),
        ca.horzcat(-ca.sin(th - phi), ca.cos(th - phi), l * ca.cos(phi), 0, 0),
    )
    F = cvodes(q, qd, kkt_ode(q, qd, T, V, A), t_end, method)
    return F, consistent_start(q, A, [0, 0, 0, 0, 0.3], [0, 0, 0.2, 1.0, 0], [0, 1])


def disk_casadi(t_end: float, method: str) -> tuple[Any, Any]:
    """The rolling disk (examples.rolling_disk(), example:rolling-disk's numbers): integrator and start."""
    m, r, A_, C, g = 1.0, 1.0, 0.25, 0.5, 9.81
    q, qd = ca.SX.sym("q", 5), ca.SX.sym("qd", 5)
    psi, th, phi, x, y = ca.vertsplit(q)
    psid, thd, phid, xd, yd = ca.vertsplit(qd)
    s, c = ca.sin, ca.cos
    vg = ca.vertcat(
        xd + r * (thd * c(th) * s(psi) + psid * s(th) * c(psi)),
        yd - r * (thd * c(th) * c(psi) - psid * s(th) * s(psi)),
        -r * thd * s(th),
    )
    T = m / 2 * ca.sumsqr(vg) + A_ / 2 * (thd**2 + psid**2 * c(th) ** 2) + C / 2 * (phid + psid * s(th)) ** 2
    V = m * g * r * c(th)
    A = ca.vertcat(
        ca.horzcat(0, 0, -r * c(psi), 1, 0),
        ca.horzcat(0, 0, -r * s(psi), 0, 1),
    )
    F = cvodes(q, qd, kkt_ode(q, qd, T, V, A), t_end, method)
    return F, consistent_start(q, A, [0, 0.1, 0, 0, 0], [0, 0, 6.0, 0, 0], [3, 4])


CASADI = {"snakeboard": snakeboard_casadi, "disk": disk_casadi}


def final(F: Any, y0: Any) -> np.ndarray:
    """The state at the end of the grid of one run of ``F`` from ``y0``."""
    return np.array(F(x0=y0)["xf"])[:, -1]


# --------------------------------------------------------------------------- the scripts run as processes
PRINT_FINAL = 'print(" ".join(repr(float(v)) for v in {}))\n'


def casadi_script(system: str, method: str) -> str:
    """The CasADi user's whole script: imports, the functions above, one run to t = 100."""
    parts: list[Callable[..., Any]] = [kkt_ode, consistent_start, cvodes, CASADI[system], final]
    return (
        "from __future__ import annotations\n\nimport casadi as ca\nimport numpy as np\n\n\n"
        + "\n\n".join(inspect.getsource(fn) for fn in parts)
        + f"\n\nxf = final(*{CASADI[system].__name__}({T_END!r}, {method!r}))\n"
        + PRINT_FINAL.format("xf")
    )


def chaplygin_script(path: Path, model: str, loaded_file: bool, names: Sequence[str]) -> str:
    """The chaplygin user's whole script: load the file, simulate to t = 100."""
    call = (
        f"chaplygin.simulate(f, {model!r}, {T_END!r})"
        if loaded_file
        else f"chaplygin.simulate(f.system, {model!r}, {T_END!r}, f.initial, f.parameters)"
    )
    values = [f"tr.coordinates[{n!r}][-1]" for n in names]
    values += ["tr.velocities[" + repr(n + "'") + "][-1]" for n in names]
    return f"import chaplygin\n\nf = chaplygin.load({str(path)!r})\ntr = {call}\n" + PRINT_FINAL.format(
        "[" + ", ".join(values) + "]"
    )


@dataclass
class Row:
    """One whole-process row: a command, its cache (warm, cold or none) and how it is judged."""

    label: str
    cmd: list[str]
    cache: str = ""  # "warm", "cold" or "" (none)
    system: str = ""
    csv_out: Path | None = None  # where the command writes its trajectory (the CLI)
    reference: str = "casadi"  # "casadi" (the system's CasADi Adams script) or "help"
    goal: float | None = None  # the bound on the ratio to the reference
    times: list[float] = field(default_factory=list)
    error: float | None = None  # max |final state - CasADi's|


def run(row: Row, warm_dir: Path) -> tuple[float, str]:
    """Wall time and stdout of one run of ``row``.  Its Python writes and reuses bytecode as a
    user's does, and imports chaplygin from the checkout under test."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["PYTHONPATH"] = os.pathsep.join([str(SRC), *filter(None, [env.get("PYTHONPATH")])])
    with tempfile.TemporaryDirectory() as fresh:
        env["CHAPLYGIN_CACHE"] = fresh if row.cache == "cold" else str(warm_dir)
        start = time.perf_counter()
        done = subprocess.run(row.cmd, env=env, capture_output=True, text=True, cwd=ROOT)
        wall = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"failed: {row.label}: {' '.join(row.cmd)}\n{done.stdout}\n{done.stderr}")
    return wall, done.stdout


def final_of(row: Row, stdout: str, names: Sequence[str]) -> np.ndarray | None:
    """The final state a process printed (or wrote to its CSV), in the CasADi state's order."""
    if row.csv_out is not None:
        with row.csv_out.open() as fh:
            *_, last = csv.DictReader(fh)
        return np.array([float(last[n]) for n in names] + [float(last[n + "'"]) for n in names])
    lines = stdout.strip().splitlines()
    return np.array([float(v) for v in lines[-1].split()]) if lines and row.system else None


def coordinate_names(path: Path) -> list[str]:
    """The coordinates of the system file ``path``, in its order (the CasADi state's)."""
    return [q.func.__name__ for q in chaplygin.load(path).system.coordinates]


def takes_loaded_file(model: str) -> str:
    """'' when ``chaplygin.simulate`` of the checkout under test takes a loaded file, else why not."""
    f = chaplygin.load(SYSTEMS["snakeboard"])
    try:
        chaplygin.simulate(f, model, 0.01)
    except Exception as exc:
        return f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
    return ""


def process_rows(systems: Sequence[str], models: Sequence[str], work: Path) -> list[Row]:
    """The rows of part 1: floors first, then per system CasADi, the Python API and the CLI."""
    rows = [
        Row("floor: chaplygin --help", [PYTHON, "-m", "chaplygin", "--help"]),
        # what a command that parses options adds to --help: typer 0.29 coerces every option of
        # the command run through pydantic (imported only then; --help does not)
        Row(
            "floor: the CLI + typer's pydantic coercion (imports)",
            [PYTHON, "-c", "import chaplygin.apps.cli, typer._adapters"],
        ),
        Row("floor: python -c 'import numpy'", [PYTHON, "-c", "import numpy"]),
        Row("floor: python -c 'import sympy, numpy'", [PYTHON, "-c", "import sympy, numpy"]),
        # SymPy's first sum imports sympy.tensor (Add.flatten does, each call): what any use pays
        Row(
            "floor: the same and SymPy's first sum",
            [PYTHON, "-c", "import sympy, numpy; sympy.Symbol('x') + 1"],
        ),
        Row("floor: python -c 'import casadi, numpy'", [PYTHON, "-c", "import casadi, numpy"]),
    ]
    why_not = takes_loaded_file(models[0])
    if why_not:
        say(f"   (chaplygin.simulate(loaded_file, model, t) not accepted here, rows skipped: {why_not})")
    for system in systems:
        path = SYSTEMS[system]
        names = coordinate_names(path)
        for method in ("adams", "bdf"):
            script = work / f"casadi_{system}_{method}.py"
            script.write_text(casadi_script(system, method))
            rows.append(
                Row(f"{system}: CasADi script, cvodes {method}", [PYTHON, str(script)], system=system)
            )
        for model in models:
            for loaded_file in (False, True) if not why_not else (False,):
                script = work / f"chaplygin_{system}_{model}_{int(loaded_file)}.py"
                script.write_text(chaplygin_script(path, model, loaded_file, names))
                form = "simulate(f, …)" if loaded_file else "simulate(f.system, …)"
                for cache, goal in (("warm", 1.5), ("cold", 4.0)):
                    rows.append(
                        Row(
                            f"{system}: load + {form} {model}, {cache}",
                            [PYTHON, str(script)],
                            cache,
                            system,
                            goal=goal,
                        )
                    )
            out = work / f"cli_{system}_{model}.csv"
            cmd = [PYTHON, "-m", "chaplygin", "simulate", str(path), "-m", model, "-t", repr(T_END)]
            for cache, bound, ref in (("warm", 2.0, "help"), ("cold", None, "casadi")):
                rows.append(
                    Row(
                        f"{system}: chaplygin simulate -m {model}, {cache}",
                        [*cmd, "-o", str(out), "--force"],
                        cache,
                        system,
                        csv_out=out,
                        reference=ref,
                        goal=bound,
                    )
                )
    return rows


def part_processes(systems: Sequence[str], models: Sequence[str], repeat: int, work: Path) -> None:
    say(f"\n1. Whole processes, t = {T_END:g}, {repeat} rounds (every row once per round)")
    rows = process_rows(systems, models, work)
    warm = work / "warm-cache"
    references = {s: final(*CASADI[s](T_END, "adams")) for s in systems}
    for row in rows:  # untimed: fills the warm cache, checks every final state
        _, out = run(row, warm)
        names = coordinate_names(SYSTEMS[row.system]) if row.system else []
        state = final_of(row, out, names)
        if state is not None:
            row.error = float(np.max(np.abs(state - references[row.system])))
    for _ in range(repeat):
        for row in rows:
            row.times.append(run(row, warm)[0])
    best = {row.label: min(row.times) for row in rows}
    width = max(len(row.label) for row in rows)
    say(f"   {'':{width}}  {'best':>7}  {'median':>7}  {'ratio':>12}  {'goal':>6}  max|Δ final| vs CasADi")
    for row in rows:
        ref: float | None
        if not row.system:
            ref, ref_name = None, ""
        elif row.reference == "help":
            ref, ref_name = best["floor: chaplygin --help"], "help"
        else:
            ref, ref_name = best[f"{row.system}: CasADi script, cvodes adams"], "CasADi"
        ratio = f"{min(row.times) / ref:5.2f}x {ref_name:6s}" if ref else ""
        goal = f"<= {row.goal:g}x" if row.goal else ""
        err = f"{row.error:.1e}" if row.error is not None else ""
        say(
            f"   {row.label:{width}}  {min(row.times):7.3f}  {statistics.median(row.times):7.3f}"
            f"  {ratio:>12}  {goal:>6}  {err}"
        )
        RESULTS[f"process: {row.label}"] = {
            "best": min(row.times),
            "median": statistics.median(row.times),
            "error": row.error,
        }


# --------------------------------------------------------------------------- in process
def part_inprocess(systems: Sequence[str], models: Sequence[str], repeat: int) -> None:
    goals = {1.0: 1.5, 100.0: 0.5}  # the bounds on chaplygin / CasADi (t = 1000: none)
    say(f"\n2. In process: one call, best and median of {repeat}, interleaved")
    for system in systems:
        f = chaplygin.load(SYSTEMS[system])
        names = coordinate_names(SYSTEMS[system])
        # (end time, route) -> one call returning the final state
        routes: dict[tuple[float, str], Callable[[], np.ndarray]] = {}
        for t_end in (1.0, 100.0, 1000.0):
            for method in ("adams", "bdf"):
                F, y0 = CASADI[system](t_end, method)
                routes[t_end, f"CasADi F(x0=…), cvodes {method}"] = functools.partial(final, F, y0)
            for model in models:

                def go(model: str = model, t_end: float = t_end) -> np.ndarray:
                    tr = chaplygin.simulate(f.system, model, t_end, f.initial, f.parameters)
                    return np.array(
                        [tr.coordinates[n][-1] for n in names] + [tr.velocities[n + "'"][-1] for n in names]
                    )

                routes[t_end, f"chaplygin.simulate() {model}"] = go
        states = {key: route() for key, route in routes.items()}  # compiles, loads, warms
        times: dict[tuple[float, str], list[float]] = {key: [] for key in routes}
        for _ in range(repeat):
            for key, route in routes.items():
                start = time.perf_counter()
                route()
                times[key].append(time.perf_counter() - start)
        say(f"   {system} ({SYSTEMS[system].name})")
        width = max(len(f"t = {t:g}: {name}") for t, name in routes)
        say(f"     {'':{width}}  {'best [ms]':>9}  {'median':>8}  {'ratio':>13}  {'goal':>6}  max|Δ final|")
        for key in routes:
            t_end, name = key
            ref = (t_end, "CasADi F(x0=…), cvodes adams")
            ratio = min(times[key]) / min(times[ref])
            goal = f"<= {goals[t_end]:g}x" if t_end in goals and name.startswith("chaplygin") else ""
            err = float(np.max(np.abs(states[key] - states[ref])))
            label = f"t = {t_end:g}: {name}"
            say(
                f"     {label:{width}}  {1e3 * min(times[key]):9.2f}  {1e3 * statistics.median(times[key]):8.2f}"
                f"  {ratio:6.2f}x CasADi  {goal:>6}  {err:.1e}"
            )
            RESULTS[f"inprocess: {system}: {label}"] = {
                "best": min(times[key]),
                "median": statistics.median(times[key]),
                "error": err,
            }


# --------------------------------------------------------------------------- machine
def machine() -> str:
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        rev = subprocess.run(
            ["git", "-C", str(SRC), "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(SRC), "status", "--porcelain", "."], capture_output=True, text=True, check=True
        ).stdout.strip()
        rev = f"git {rev}" + (" with uncommitted changes" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        rev = "no git checkout"
    import sympy

    return (
        f"cpu: {cpu}, {os.cpu_count()} logical CPUs, load average {os.getloadavg()[0]:.2f}\n"
        f"python {platform.python_version()}, numpy {np.__version__}, sympy {sympy.__version__}, "
        f"casadi {ca.__version__}, chaplygin {chaplygin.__version__} from {SRC} ({rev})"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="rounds / calls per row (best and median)")
    parser.add_argument("--only", choices=["processes", "inprocess"], default=None)
    parser.add_argument("--systems", default="snakeboard,disk", help="comma-separated: snakeboard, disk")
    parser.add_argument("--models", default="chetaev,chaplygin", help="comma-separated chaplygin models")
    parser.add_argument(
        "--src",
        default=str(ROOT / "src"),
        help="directory holding the chaplygin package to time (default: ./src)",
    )
    parser.add_argument("--json", default=None, help="also write the numbers to this file")
    args = parser.parse_args()
    systems = [s for s in args.systems.split(",") if s]
    unknown = [s for s in systems if s not in SYSTEMS]
    if unknown:
        parser.error(f"unknown system(s) {', '.join(unknown)}; known: {', '.join(SYSTEMS)}")
    models = [m for m in args.models.split(",") if m]
    say(machine())
    with tempfile.TemporaryDirectory() as work:
        if args.only in (None, "processes"):
            part_processes(systems, models, args.repeat, Path(work))
        if args.only in (None, "inprocess"):
            part_inprocess(systems, models, args.repeat)
    say(f"\nload average at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    if args.json:
        Path(args.json).write_text(json.dumps(RESULTS, indent=1))


if __name__ == "__main__":
    main()
