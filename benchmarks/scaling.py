"""How cost grows with size: a chain of N + 1 sleighs, chaplygin vs KanesMethod, same process.

For each N (``examples.sleigh_chain(N)``: N + 3 coordinates, N + 1 nonholonomic
constraints) this times, each from a cold SymPy cache:

chaplygin
    build     ``examples.sleigh_chain(N)`` (the System, with its validation)
    chetaev   the Chetaev equations (6) as SymPy expressions to read: mass matrix
              and forcing (``System.equations``; not needed to simulate)
    voronets  Voronets' equations, symbolically (only up to ``--symbolic-max``:
              the symbolic elimination of the dependent velocities grows very fast)
    codegen   the numerically reduced Voronets model (``reduction="numeric"``) of a
              fresh system: the Chetaev matrices derived in SymEngine
              (chaplygin.core._native), generated, cse'd and imported (numpy backend)
    jit       the same for the numba backend: generated, its ``fill`` built by the
              C compiler when large (chaplygin.numeric._cfill), and numba compiling ``rhs``
              (first call)
    compiled  build + jit: the system derived and compiled to native code
    total     build + codegen: from the system to a right-hand side to integrate
KanesMethod (the same chain: frames, points, rigid bodies, nonholonomic
constraints on the dependent speeds)
    derive    ``KanesMethod(...)`` + ``kanes_equations`` + ``mass_matrix_full``/``forcing_full``
    codegen   ``lambdify(..., cse=True)`` of the full mass matrix and forcing
    total     derive + codegen

``ratio_total`` is Kane's total over chaplygin's; ``ratio_symbolic`` compares the
symbolic derivations alone (Kane's derive over chaplygin's build + chetaev).

and µs per right-hand side, called from Python: chaplygin's generated
``rhs`` (numpy and numba backends) against the lambdified Kane functions
followed by ``numpy.linalg.solve``.  A step that would exceed ``--budget``
seconds is stopped (SIGALRM) and reported as ``>budget``.

    .venv/bin/python benchmarks/scaling.py                 # N = 1 2 4 8 16 32
    .venv/bin/python benchmarks/scaling.py --sizes 1 2 4 --budget 60
    .venv/bin/python benchmarks/scaling.py --crossover --repeat 3   # where reduction="auto" switches

``--crossover`` times, for chains of 5 to 9 coordinates whose first g = 1, 2, 3 bodies have
knife edges (the systems ``reduction="auto"`` decides by size alone: 4 or more constraints
always reduce numerically), chaplygin's route from nothing to a right-hand side with the default
backend (the C kernel), symbolic against numeric reduction, and Kane's derive + lambdify on the
same chain; interleaved, best and median of the repeats, each from a cold SymPy cache and an
empty code cache.

Every run starts with an empty code cache (a temporary ``CHAPLYGIN_CACHE``), so
code generation, the C compiler and numba all start cold; ``--warm`` keeps the
user's cache instead.
"""

from __future__ import annotations

import argparse
import atexit
import json
import math
import os
import shutil
import signal
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me
from sympy.core.cache import clear_cache

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

import chaplygin
from chaplygin import examples
from chaplygin.numeric import _modelcache
from chaplygin.numeric.codegen import compile_model


class OverBudget(Exception):
    pass


def _alarm(signum, frame):
    raise OverBudget


def timed(budget: float, fn, *args):
    """(seconds, value), or (inf, None) past the budget."""
    signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, budget)
    start = time.perf_counter()
    try:
        value = fn(*args)
    except OverBudget:
        return math.inf, None
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
    return time.perf_counter() - start, value


def per_call(fn, *args, seconds: float = 0.3) -> float:
    """µs per call (best of 3 batches)."""
    fn(*args)
    reps, start = 0, time.perf_counter()
    while time.perf_counter() - start < 0.05:
        fn(*args)
        reps += 1
    reps = max(1, int(reps * seconds / 0.05 / 3))
    best = math.inf
    for _ in range(3):
        start = time.perf_counter()
        for _ in range(reps):
            fn(*args)
        best = min(best, (time.perf_counter() - start) / reps)
    return best * 1e6


# ---------------------------------------------------------------- KanesMethod
def kane_chain(n: int, g: int | None = None):
    """The same chain for KanesMethod (knife edges on the first ``g`` bodies, all by default);
    returns (KanesMethod, q, u, parameters)."""
    g = n + 1 if g is None else g
    q = me.dynamicsymbols(f"x y theta0:{n + 1}")
    u = me.dynamicsymbols(f"u0:{n + 3}")
    m, inertia, length = sp.symbols("m I L", positive=True)
    frame = me.ReferenceFrame("N")
    origin = me.Point("O")
    origin.set_vel(frame, 0)
    point = origin.locatenew("P0", q[0] * frame.x + q[1] * frame.y)
    point.set_vel(frame, u[0] * frame.x + u[1] * frame.y)
    bodies, constraints, prev = [], [], point
    for i in range(n + 1):
        body_frame = frame.orientnew(f"B{i}", "Axis", [q[2 + i], frame.z])
        body_frame.set_ang_vel(frame, u[2 + i] * frame.z)
        if i:
            point = prev.locatenew(f"P{i}", -length * body_frame.x)
            point.v2pt_theory(prev, frame, body_frame)
        prev = point
        body = me.RigidBody(f"b{i}", point, body_frame, m, (me.inertia(body_frame, 0, 0, inertia), point))
        bodies.append(body)
        constraints.append(point.vel(frame).dot(body_frame.y))
    km = me.KanesMethod(
        frame,
        q_ind=q,
        u_ind=[u[0], u[2], *u[g + 2 :]],
        u_dependent=[u[1], *u[3 : g + 2]],
        kd_eqs=[qi.diff() - ui for qi, ui in zip(q, u)],
        velocity_constraints=constraints[:g],
    )
    km.kanes_equations(bodies, [])
    return km, q, u, [m, inertia, length]


def kane_derive(n: int, g: int | None = None):
    km, q, u, params = kane_chain(n, g)
    return km.mass_matrix_full, km.forcing_full, q, u, params


def kane_codegen(derived):
    M, F, q, u, params = derived
    args = [*q, *u, *params]
    return sp.lambdify(args, M, cse=True), sp.lambdify(args, F, cse=True), len(q), len(u)


# ---------------------------------------------------------------- chaplygin
def chaplygin_chetaev(system):
    eqs = system.equations("chetaev")
    return eqs.mass_matrix, eqs.forcing


def chaplygin_voronets(system):
    eqs = system.equations("voronets")
    return eqs.mass_matrix, eqs.forcing


def run(n: int, budget: float, symbolic_max: int, rng: np.random.Generator) -> dict:
    row: dict = {"N": n}
    clear_cache()
    row["build"], system = timed(budget, examples.sleigh_chain, n)
    row["chetaev"], _ = timed(budget, chaplygin_chetaev, system)
    row["voronets"] = timed(budget, chaplygin_voronets, system)[0] if n <= symbolic_max else None
    clear_cache()
    system = examples.sleigh_chain(n)  # fresh: nothing derived yet
    clear_cache()
    row["codegen"], compiled = timed(
        budget, lambda: compile_model(system, "voronets", backend="numpy", reduction="numeric")
    )
    y = rng.uniform(-0.3, 0.3, len(compiled.layout.state))
    values = {"m": 1.0, "I": 0.5, "L": 1.0}
    p = np.array([values[name] for name in compiled.layout.parameters])
    row["rhs_numpy_us"] = per_call(compiled.rhs, 0.0, y, p)
    fresh = examples.sleigh_chain(n)
    clear_cache()
    row["jit"], jitted = timed(
        budget, lambda: compile_model(fresh, "voronets", backend="numba", reduction="numeric")
    )
    if jitted is not None:
        extra, _ = timed(budget, jitted.rhs, 0.0, y, p)
        row["jit"] += extra
        row["rhs_numba_us"] = per_call(jitted.rhs, 0.0, y, p) if math.isfinite(extra) else None
    clear_cache()
    row["kane_derive"], derived = timed(budget, kane_derive, n)
    row["kane_codegen"], row["rhs_kane_us"] = math.inf, None
    if derived is not None:
        row["kane_codegen"], funcs = timed(budget, kane_codegen, derived)
        if funcs is not None:
            fM, fF, nq, nu = funcs
            # the same admissible state: chaplygin's full velocities as Kane's speeds
            qd = compiled.observe(0.0, y, p)[-system.n :]
            args = [*y[: system.n], *qd, values["m"], values["I"], values["L"]]

            def kane_rhs() -> np.ndarray:
                return np.linalg.solve(fM(*args), fF(*args)[:, 0])

            row["rhs_kane_us"] = per_call(kane_rhs)
            # Kane's u̇ are ordered independent (x, θ0) first, like chaplygin's state
            udot = kane_rhs()[nq : nq + 2]
            got = compiled.rhs(0.0, y, p)[system.n :]
            row["max_difference_vs_kane"] = float(np.max(np.abs(udot - got)))
    row["compiled"] = row["build"] + row["jit"]
    ours = row["build"] + row["codegen"]
    row["chaplygin_total"] = ours
    row["kane_total"] = row["kane_derive"] + row["kane_codegen"]
    row["ratio_total"] = row["kane_total"] / ours
    row["ratio_symbolic"] = row["kane_derive"] / (row["build"] + row["chetaev"])
    return row


def knife_edges(n: int, g: int):
    """``examples.sleigh_chain(n)`` with knife edges on its first ``g`` bodies only (dependent
    ``y, θ_1 … θ_{g−1}``): n + 3 coordinates, g constraints."""
    chain = examples.sleigh_chain(n)
    x, y, *th = chain.coordinates
    L = sp.Symbol("L", positive=True)
    dx, dy, dth = x.diff(), y.diff(), [tj.diff() for tj in th]
    cons = [
        -sp.sin(th[i]) * dx
        + sp.cos(th[i]) * dy
        - L * sp.Add(*(dth[j] * sp.cos(th[j] - th[i]) for j in range(1, i + 1)))
        for i in range(g)
    ]
    return chaplygin.System(chain.coordinates, chain.kinetic_energy, cons, dependent=[y, *th[1:g]])


def crossover(repeat: int, budget: float) -> None:
    """Symbolic against numeric reduction (default backend) and Kane, by size: see the docstring."""
    routes = {
        "symbolic": lambda n, g: compile_model(
            knife_edges(n, g), "voronets", backend="c", reduction="symbolic"
        ),
        "numeric": lambda n, g: compile_model(
            knife_edges(n, g), "voronets", backend="c", reduction="numeric"
        ),
        "kane": lambda n, g: kane_codegen(kane_derive(n, g)),
    }
    cases = [(n, g) for n in range(2, 7) for g in (1, 2, 3)]
    times: dict = {(case, route): [] for case in cases for route in routes}
    for _ in range(repeat):
        for case in cases:
            for route, fn in routes.items():  # interleaved
                clear_cache()
                _modelcache._LOADED.clear()  # compiled models this process holds: none
                os.environ["CHAPLYGIN_CACHE"] = tempfile.mkdtemp(prefix="chaplygin-crossover-")
                times[case, route].append(timed(budget, fn, *case)[0])
                shutil.rmtree(os.environ["CHAPLYGIN_CACHE"], ignore_errors=True)
    print(f"load average {os.getloadavg()[0]:.2f}; seconds from nothing to a right-hand side, best / median")
    print(f"{'coords':>6} {'g':>2} " + " ".join(f"{r:>15}" for r in routes) + "  faster")
    for case in cases:
        cells = {r: (min(times[case, r]), float(np.median(times[case, r]))) for r in routes}
        best = min(("symbolic", "numeric"), key=lambda r: cells[r][1])
        row = " ".join(f"{b:7.3f} / {m:5.3f}" for b, m in cells.values())
        print(f"{case[0] + 3:>6} {case[1]:>2} {row}  {best}", flush=True)


def fmt(value) -> str:
    if value is None:
        return "-"
    if isinstance(value, float) and math.isinf(value):
        return ">budget"
    return f"{value:.3g}" if isinstance(value, float) else str(value)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[1, 2, 4, 8, 16, 32])
    ap.add_argument("--budget", type=float, default=300.0, help="seconds allowed per step")
    ap.add_argument("--symbolic-max", type=int, default=2, help="largest N for symbolic Voronets")
    ap.add_argument("--json", type=Path, help="also write the rows here")
    ap.add_argument("--warm", action="store_true", help="use the user's code cache (default: a fresh one)")
    ap.add_argument("--crossover", action="store_true", help="symbolic vs numeric reduction by size")
    ap.add_argument("--repeat", type=int, default=3, help="repeats of --crossover")
    args = ap.parse_args()
    if args.crossover:
        crossover(args.repeat, args.budget)
        return
    if not args.warm:
        os.environ["CHAPLYGIN_CACHE"] = tempfile.mkdtemp(prefix="chaplygin-scaling-")
        atexit.register(shutil.rmtree, os.environ["CHAPLYGIN_CACHE"], ignore_errors=True)
    rng = np.random.default_rng(1)
    cols = [
        "N",
        "build",
        "chetaev",
        "voronets",
        "codegen",
        "jit",
        "compiled",
        "chaplygin_total",
        "kane_derive",
        "kane_codegen",
        "kane_total",
        "ratio_total",
        "ratio_symbolic",
        "rhs_numpy_us",
        "rhs_numba_us",
        "rhs_kane_us",
        "max_difference_vs_kane",
    ]
    print(" ".join(f"{c:>14}" for c in cols), flush=True)
    rows = []
    for n in args.sizes:
        row = run(n, args.budget, args.symbolic_max, rng)
        rows.append(row)
        print(" ".join(f"{fmt(row.get(c)):>14}" for c in cols), flush=True)
    finite = [
        (r["N"], r["chaplygin_total"]) for r in rows if r["N"] >= 4 and math.isfinite(r["chaplygin_total"])
    ]
    if len(finite) >= 2:
        slope = np.polyfit(np.log([a for a, _ in finite]), np.log([b for _, b in finite]), 1)[0]
        print(f"\nchaplygin build + numeric-Voronets codegen grows like N^{slope:.2f} (N >= 4)")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=2))


if __name__ == "__main__":
    main()
