"""Time the numerical side: right-hand sides, integrators and ensembles, in one run.

Run from the repository root::

    .venv/bin/python benchmarks/simulate.py                  # everything (the README's numbers)
    .venv/bin/python benchmarks/simulate.py --quick          # t = 100 and 10^3 members: a smoke run
    .venv/bin/python benchmarks/simulate.py --only ensemble  # only the ensembles (e.g. on a GPU machine)
    .venv/bin/python benchmarks/simulate.py --json out.json  # also write the numbers

The problem is the issue's: the rolling disk (``examples.rolling_disk()``,
Chaplygin's equations), ``t = 0 … 1000``, ``rtol = 1e-10``, ``atol = 1e-12``,
1001 output samples.

1. **µs per right-hand-side evaluation** for each backend, called from Python
   (what a SciPy stepper pays per call) and, for the compiled backends, inside
   compiled code (what the compiled integrators pay).
2. **Wall time of one trajectory**: the baseline is what a user writes without
   chaplygin's numerics, in this process: ``sympy.lambdify`` of the mass matrix,
   forcing and constraint velocities of ``system.equations("chaplygin")`` and
   ``scipy.integrate.solve_ivp(method="DOP853")``.  Against it: ``simulate()``
   with each backend, and the compiled loop called directly.  Compilation and
   symbolic work are reported separately (numba and JAX caches are warmed
   first: one untimed run each).
3. **Ensemble throughput**: 10⁴ random initial states (``--ensemble-n``),
   ``simulate_ensemble`` with ``backend="c"`` and ``"numba"`` (all CPU cores, and one) and
   ``backend="jax"`` (``vmap``; on the GPU when JAX sees one), for a horizon of
   ``--ensemble-t`` (default 10: 10⁴ members to ``t = 1000`` take about an hour
   on two cores, see the README).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))  # this working tree, also when not installed

import sympy as sp
from scipy.integrate import solve_ivp

from chaplygin import examples
from chaplygin.core._symbols import TIME
from chaplygin.numeric.codegen import compile_equations, parameter_vector
from chaplygin.numeric.simulate import simulate

PARAMS = {"m": 1.0, "r": 0.5, "A": 0.0625, "C": 0.125, "g": 9.81}
START = {"psi": 0.0, "theta": 0.3, "phi": 0.0, "x": 0.0, "y": 0.0, "psi'": 2.0, "theta'": 0.0, "phi'": 5.0}
RTOL, ATOL = 1e-10, 1e-12

RESULTS: dict[str, object] = {}


def say(line: str = "") -> None:
    print(line, flush=True)


def best_of(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def per_call_us(fn, calls: int, repeat: int = 3) -> float:
    return best_of(lambda: [fn() for _ in range(calls)], repeat) / calls * 1e6


# --------------------------------------------------------------------------- machine
def machine() -> dict[str, str]:
    cpu = platform.processor() or ""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    info = {
        "cpu": cpu,
        "cores": str(len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": __import__("scipy").__version__,
        "sympy": sp.__version__,
        "numba": __import__("numba").__version__,
        "load average": " ".join(f"{x:.2f}" for x in os.getloadavg()),
    }
    try:
        import diffrax
        import jax

        info["jax"] = jax.__version__
        info["diffrax"] = diffrax.__version__
        info["jax devices"] = ", ".join(f"{d.platform}:{d.id} ({d.device_kind})" for d in jax.devices())
    except ImportError:
        info["jax"] = "not installed"
    return info


# --------------------------------------------------------------------------- baseline
def naive_lambdify(disk):
    """What a user writes: lambdify M, F and the constraint velocities, solve M·q̈ = F per call."""
    eqs = disk.equations("chaplygin")
    q = list(disk.coordinates)
    acc = list(eqs.unknowns)  # ψ'', θ'', φ''
    u = [a.args[0].diff(TIME) for a in acc]  # ψ', θ', φ'
    dep = [c for c in q if c.diff(TIME) in disk.constraints]
    params = [disk.parameter(name) for name in sorted(PARAMS)]
    # plain symbols for q(t) and q'(t) (derivatives first), as one does before lambdify
    qs, us = sp.symbols(f"q0:{len(q)}"), sp.symbols(f"u0:{len(u)}")
    derivatives, functions = dict(zip(u, us)), dict(zip(q, qs))

    def plain(expr):
        return expr.xreplace(derivatives).xreplace(functions)

    args = [qs, us, params]
    M = sp.lambdify(args, plain(eqs.mass_matrix))
    F = sp.lambdify(args, plain(eqs.forcing))
    V = sp.lambdify(args, [plain(disk.constraints[c.diff(TIME)]) for c in dep])
    ind_pos = [q.index(a.args[0]) for a in acc]
    dep_pos = [q.index(c) for c in dep]
    p = [PARAMS[name] for name in sorted(PARAMS)]
    n = len(q)

    def rhs(t, y):
        qq, uu = y[:n], y[n:]
        qdot = np.empty(n)
        qdot[ind_pos] = uu
        qdot[dep_pos] = V(qq, uu, p)
        udot = np.linalg.solve(
            np.asarray(M(qq, uu, p), dtype=float), np.asarray(F(qq, uu, p), dtype=float).ravel()
        )
        return np.concatenate([qdot, udot])

    return rhs


# --------------------------------------------------------------------------- parts
def part_rhs(disk, eqs, y0, p) -> None:
    say("== µs per right-hand-side evaluation (rolling disk, Chaplygin, 8 states) ==")
    rows = []
    baseline = naive_lambdify(disk)
    rows.append(("lambdify (no chaplygin), from Python", per_call_us(lambda: baseline(0.0, y0), 5000)))
    numpy_model = compile_equations(eqs, "numpy")
    rows.append(
        (
            "numpy backend (generated, CSE), from Python",
            per_call_us(lambda: numpy_model.rhs(0.0, y0, p), 5000),
        )
    )
    numba_model = compile_equations(eqs, "numba")
    numba_model.rhs(0.0, y0, p)
    rows.append(("numba backend rhs, from Python", per_call_us(lambda: numba_model.rhs(0.0, y0, p), 50000)))

    from numba import njit

    from chaplygin.numeric._loop import loop_model, shared

    module = loop_model(numba_model).module
    generated_rhs, k_eval, m = module.rhs, shared()._k_eval, module.MODEL

    @njit
    def drive_rhs(y, p, calls):
        s = 0.0
        for _i in range(calls):
            y[1] += 1e-12
            s += generated_rhs(0.0, y, p)[6]
        return s

    @njit
    def drive_eval(m, y, p, calls, f, M, b, V, O):
        s = 0.0
        for _i in range(calls):
            y[1] += 1e-12
            k_eval(m, 0.0, y, p, f, M, b, V, O)
            s += f[6]
        return s

    work = (
        np.empty(8),
        np.empty((module.DIM, module.DIM)),
        np.empty(module.DIM),
        np.empty(module.N),
        np.empty(module.N_OBSERVED),
    )
    drive_rhs(y0.copy(), p, 10)
    drive_eval(m, y0.copy(), p, 10, *work)
    calls = 1_000_000
    rows.append(
        ("numba backend rhs, inside numba", best_of(lambda: drive_rhs(y0.copy(), p, calls), 3) / calls * 1e6)
    )
    rows.append(
        (
            "numba loop's allocation-free rhs (fill + elimination), inside numba",
            best_of(lambda: drive_eval(m, y0.copy(), p, calls, *work), 3) / calls * 1e6,
        )
    )
    try:
        import jax

        jax_model = compile_equations(eqs, "jax")
        jax_model.rhs(0.0, y0, p)
        rows.append(
            ("jax backend rhs (jitted), from Python", per_call_us(lambda: jax_model.rhs(0.0, y0, p), 5000))
        )
        rhs_jax = jax_model.module.rhs_jax

        @jax.jit
        def chain(y, p):
            return jax.lax.fori_loop(0, 100_000, lambda i, yy: yy + 1e-9 * rhs_jax(0.0, yy, p), y)

        chain(y0, p).block_until_ready()
        rows.append(
            (
                "jax rhs inside jit (sequential fori_loop)",
                best_of(lambda: chain(y0, p).block_until_ready(), 3) / 100_000 * 1e6,
            )
        )
        batch = jax.jit(jax.vmap(rhs_jax, in_axes=(None, 0, None)))
        Y = np.tile(y0, (10_000, 1)) + 1e-3 * np.random.default_rng(0).standard_normal((10_000, 8))
        batch(0.0, Y, p).block_until_ready()
        rows.append(
            (
                "jax rhs vmapped over 10^4 states, per state",
                best_of(lambda: batch(0.0, Y, p).block_until_ready(), 5) / 10_000 * 1e6,
            )
        )
    except ImportError:
        say("  (jax not installed: pip install 'chaplygin[jax]')")
    for name, us in rows:
        say(f"  {name:<72s} {us:9.3f} µs")
    RESULTS["rhs_us"] = dict(rows)


def part_trajectory(disk, eqs, y0, p, t_end: float) -> None:
    say(f"\n== one trajectory: t = 0 … {t_end:g}, rtol = {RTOL:g}, atol = {ATOL:g}, 1001 samples ==")
    times = np.linspace(0.0, t_end, 1001)
    rows = []
    start = time.perf_counter()
    baseline = naive_lambdify(disk)
    setup = time.perf_counter() - start
    start = time.perf_counter()
    ref = solve_ivp(baseline, (0.0, t_end), y0, method="DOP853", rtol=RTOL, atol=ATOL, t_eval=times)
    base_wall = time.perf_counter() - start
    rows.append(("lambdify + solve_ivp DOP853 (baseline)", base_wall, setup, ref.nfev, 0.0))

    def runs(backend: str, label: str, repeat: int) -> None:
        simulate(disk, "chaplygin", 1.0, START, PARAMS, backend=backend, samples=1001)  # compile, warm caches
        best, tr = None, None
        for _ in range(repeat):
            start = time.perf_counter()
            tr = simulate(disk, "chaplygin", t_end, START, PARAMS, backend=backend, samples=1001)
            wall = time.perf_counter() - start
            best = wall if best is None else min(best, wall)
        assert tr is not None and tr.success, tr
        start = time.perf_counter()
        compile_equations(eqs, backend)
        codegen = time.perf_counter() - start
        table = np.column_stack([tr[c] for c in ("psi", "theta", "phi", "x", "y", "psi'", "theta'", "phi'")])
        diff = float(np.max(np.abs(table - ref.y.T)))
        rows.append((label, best, codegen, tr.rhs_evaluations, diff))

    runs("numpy", "simulate(backend='numpy'): DOP853 on Python lists", 1)
    runs("numba", "simulate(backend='numba'): compiled DOP853 loop", 3)
    runs("c", "simulate(backend='c'): the loop in C (the default)", 3)
    from chaplygin.numeric._loop import integrate_dop853, loop_model

    model = loop_model(compile_equations(eqs, "numba"))
    integrate_dop853(model, (0.0, t_end), y0, p, times, rtol=RTOL, atol=ATOL)
    wall = best_of(lambda: integrate_dop853(model, (0.0, t_end), y0, p, times, rtol=RTOL, atol=ATOL), 3)
    res = integrate_dop853(model, (0.0, t_end), y0, p, times, rtol=RTOL, atol=ATOL)
    rows.append(
        (
            "compiled DOP853 loop alone (integrate_dop853)",
            wall,
            0.0,
            res.n_rhs,
            float(np.max(np.abs(res.y - ref.y.T))),
        )
    )
    try:
        import jax  # noqa: F401

        runs("jax", "simulate(backend='jax'): diffrax Dopri8 (jit)", 1)
    except ImportError:
        pass
    say(
        f"  {'path':<52s} {'wall [s]':>9s} {'speed-up':>9s} {'setup [s]':>9s} {'RHS evals':>10s} {'max |Δy|':>9s}"
    )
    for name, wall, setup, nfev, diff in rows:
        say(f"  {name:<52s} {wall:9.3f} {base_wall / wall:8.1f}× {setup:9.3f} {nfev:10d} {diff:9.1e}")
    say("  (setup: lambdify for the baseline, compile_equations (code generation, CSE) for simulate;")
    say("   simulate's wall time includes it, the loop alone does not. max |Δy|: vs the baseline's samples)")
    fastest = min(rows[1:], key=lambda r: r[1])
    say(f"  fastest path: {fastest[0]}: {base_wall / fastest[1]:.0f}× faster than the baseline")
    RESULTS["trajectory"] = [
        {
            "path": r[0],
            "wall_s": r[1],
            "speedup": base_wall / r[1],
            "setup_s": r[2],
            "rhs_evaluations": int(r[3]),
            "max_diff": r[4],
        }
        for r in rows
    ]


def ensemble_states(n: int, seed: int = 0) -> list[dict[str, float]]:
    rng = np.random.default_rng(seed)
    theta = rng.uniform(0.05, 0.6, n)
    psid = rng.uniform(1.0, 3.0, n)
    phid = rng.uniform(3.0, 6.0, n)
    return [{**START, "theta": a, "psi'": b, "phi'": c} for a, b, c in zip(theta, psid, phid)]


def part_ensemble(disk, eqs, n: int, t_end: float, backends: list[str]) -> None:
    from chaplygin.numeric._loop import default_threads
    from chaplygin.numeric.ensemble import simulate_ensemble

    say(f"\n== ensemble: {n} initial states, t = 0 … {t_end:g}, rtol = {RTOL:g} (final states kept) ==")
    layout = compile_equations(eqs, "numpy").layout
    Y0 = np.array([[s[k] for k in layout.state] for s in ensemble_states(n)])
    rows = []
    cores = default_threads()
    runs = []
    for loop in ("c", "numba"):
        if loop in backends:
            runs += [(loop, cores), (loop, 1)] if cores > 1 else [(loop, 1)]
    if "jax" in backends:
        try:
            import jax

            runs.append(("jax", jax.devices()[0].platform))
        except ImportError:
            say("  (jax not installed)")
    for backend, how in runs:
        kwargs = {"threads": how} if backend != "jax" else {}
        simulate_ensemble(disk, "chaplygin", t_end, Y0[:8], PARAMS, backend=backend, **kwargs)  # compile
        ens = simulate_ensemble(disk, "chaplygin", t_end, Y0, PARAMS, backend=backend, **kwargs)
        label = (
            f"{backend} ({how} thread{'s' if how != 1 else ''})" if backend != "jax" else f"jax vmap ({how})"
        )
        rows.append(
            (
                label,
                ens.wall_time,
                n / ens.wall_time,
                int(np.count_nonzero(ens.code)),
                float(np.max(ens.energy_drift())),
                float(ens.rhs_evaluations.mean()),
            )
        )
    say(
        f"  {'engine':<24s} {'wall [s]':>9s} {'traj/s':>10s} {'failed':>7s} {'max drift':>10s} {'RHS/member':>11s}"
    )
    for label, wall, rate, failed, drift, evals in rows:
        say(f"  {label:<24s} {wall:9.2f} {rate:10.1f} {failed:7d} {drift:10.1e} {evals:11.0f}")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20  # KiB on Linux → GiB
    say(f"  peak resident memory of this process so far: {peak:.2f} GiB")
    RESULTS["ensemble"] = {
        "n": n,
        "t_end": t_end,
        "peak_rss_gib": peak,
        "rows": [
            {
                "engine": r[0],
                "wall_s": r[1],
                "trajectories_per_s": r[2],
                "failed": r[3],
                "max_energy_drift": r[4],
                "rhs_per_member": r[5],
            }
            for r in rows
        ],
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--t-end", type=float, default=1000.0, help="horizon of the single trajectory")
    parser.add_argument("--ensemble-n", type=int, default=10_000)
    parser.add_argument("--ensemble-t", type=float, default=10.0, help="horizon of the ensemble members")
    parser.add_argument("--only", choices=["rhs", "trajectory", "ensemble"], action="append")
    parser.add_argument("--ensemble-backends", default="c,numba,jax")
    parser.add_argument("--quick", action="store_true", help="t = 100 and 10^3 members")
    parser.add_argument("--json", type=Path, help="also write the numbers here")
    args = parser.parse_args()
    if args.quick:
        args.t_end, args.ensemble_n = 100.0, 1000
    parts = args.only or ["rhs", "trajectory", "ensemble"]

    info = machine()
    say("machine: " + "; ".join(f"{k} {v}" for k, v in info.items()))
    RESULTS["machine"] = info
    start = time.perf_counter()
    disk = examples.rolling_disk()
    eqs = disk.equations("chaplygin")
    say(f"derivation of the disk's Chaplygin equations: {time.perf_counter() - start:.2f} s\n")
    layout = compile_equations(eqs, "numpy").layout
    y0 = np.array([START[name] for name in layout.state])
    p = parameter_vector(layout, PARAMS)
    if "rhs" in parts:
        part_rhs(disk, eqs, y0, p)
    if "trajectory" in parts:
        part_trajectory(disk, eqs, y0, p, args.t_end)
    if "ensemble" in parts:
        part_ensemble(disk, eqs, args.ensemble_n, args.ensemble_t, args.ensemble_backends.split(","))
    if args.json:
        args.json.write_text(json.dumps(RESULTS, indent=2), encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
