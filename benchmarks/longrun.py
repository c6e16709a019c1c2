"""Long runs: energy and constraint error against wall time, for each integrator, in one process.

Run from the repository root::

    .venv/bin/python benchmarks/longrun.py            # t = 10^4 (the README's numbers, ~2 minutes)
    .venv/bin/python benchmarks/longrun.py --quick    # t = 10^3 and fewer settings: a smoke run
    .venv/bin/python benchmarks/longrun.py --t-end 1e5 --only "contact oscillator" --json out.json

Two conservative nonholonomic systems with homogeneous constraints:

* the rolling disk, ``examples.get("rolling-disk")`` (its parameters and initial state);
* the contact oscillator ``ẋ + y ż = 0``, ``H = ½|v|² + ½|q|² + ½ ε x² z²``, ε = 0.1, from
  ``x = 0, y = 1, z = 0, y' = 0.5, z' = 1`` (McLachlan & Perlmutter, J. Nonlinear Sci. 16, 2006).

Each is integrated to ``--t-end`` with ``backend="numba"`` by

* DOP853 (the compiled loop) at several tolerances (``atol = rtol/100``) on Voronets' reduced
  equations — the equations the symmetric methods integrate — and once on the Chetaev
  equations with multipliers, whose constraints hold only at acceleration level;
* the symmetric methods ``midpoint``, ``gauss4``, ``gauss6`` of :mod:`chaplygin.numeric.symmetric` at
  several steps, model ``"chetaev"`` (Voronets' equations stepped, the multiplier model observed).

Reported per run: wall time (compilation excluded: every path runs once, untimed, first),
right-hand-side evaluations, ``max |E − E0|`` over the whole run and over its first and last
tenth (a drift shows as last ≫ first), and the largest constraint residual.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))  # this working tree, also when not installed

from chaplygin import examples, simulate

DISK = examples.get("rolling-disk")
OSCILLATOR_START = {"x": 0.0, "y": 1.0, "z": 0.0, "y'": 0.5, "z'": 1.0}
OSCILLATOR_PARAMS = {"epsilon": 0.1}

#: (label, model, options) per system; --quick keeps the ones marked True
RUNS: dict[str, list[tuple[str, str, dict[str, Any], bool]]] = {
    "rolling disk": [
        ("DOP853 rtol=1e-7", "voronets", {"rtol": 1e-7}, True),
        ("DOP853 rtol=1e-8", "voronets", {"rtol": 1e-8}, False),
        ("DOP853 rtol=1e-10", "voronets", {"rtol": 1e-10}, True),
        ("DOP853 rtol=1e-12", "voronets", {"rtol": 1e-12}, False),
        ("DOP853 rtol=1e-10, multipliers", "chetaev", {"rtol": 1e-10}, True),
        ("midpoint h=0.04", "chetaev", {"method": "midpoint", "step": 0.04}, False),
        ("midpoint h=0.02", "chetaev", {"method": "midpoint", "step": 0.02}, True),
        ("gauss4 h=0.1", "chetaev", {"method": "gauss4", "step": 0.1}, True),
        ("gauss4 h=0.05", "chetaev", {"method": "gauss4", "step": 0.05}, False),
        ("gauss6 h=0.1", "chetaev", {"method": "gauss6", "step": 0.1}, True),
    ],
    "contact oscillator": [
        ("DOP853 rtol=1e-7", "voronets", {"rtol": 1e-7}, True),
        ("DOP853 rtol=1e-8", "voronets", {"rtol": 1e-8}, False),
        ("DOP853 rtol=1e-10", "voronets", {"rtol": 1e-10}, True),
        ("DOP853 rtol=1e-12", "voronets", {"rtol": 1e-12}, False),
        ("DOP853 rtol=1e-10, multipliers", "chetaev", {"rtol": 1e-10}, True),
        ("midpoint h=0.05", "chetaev", {"method": "midpoint", "step": 0.05}, True),
        ("midpoint h=0.02", "chetaev", {"method": "midpoint", "step": 0.02}, False),
        ("gauss4 h=0.2", "chetaev", {"method": "gauss4", "step": 0.2}, False),
        ("gauss4 h=0.1", "chetaev", {"method": "gauss4", "step": 0.1}, True),
        ("gauss6 h=0.2", "chetaev", {"method": "gauss6", "step": 0.2}, True),
    ],
}


def problems() -> dict[str, tuple[Any, dict[str, float], dict[str, float]]]:
    return {
        "rolling disk": (DISK.system(), DISK.initial, DISK.parameters),
        "contact oscillator": (examples.contact_oscillator(), OSCILLATOR_START, OSCILLATOR_PARAMS),
    }


def options(extra: dict[str, Any]) -> dict[str, Any]:
    out = {"backend": "numba", "samples": 1001, **extra}
    if "rtol" in out:
        out["atol"] = out["rtol"] / 100
    return out


def measure(
    system: Any,
    model: str,
    t_end: float,
    start: dict[str, float],
    params: dict[str, float],
    extra: dict[str, Any],
) -> dict[str, Any]:
    begin = time.perf_counter()
    tr = simulate(system, model, t_end, start, params, **options(extra))
    wall = time.perf_counter() - begin
    error = np.abs(tr.energy - tr.energy[0])
    tenth = max(1, len(error) // 10)
    return {
        "status": tr.status,
        "wall_s": wall,
        "rhs": tr.rhs_evaluations,
        "energy_max": float(np.max(error)),
        "energy_first": float(np.max(error[:tenth])),
        "energy_last": float(np.max(error[-tenth:])),
        "residual_max": float(np.max(tr.constraint_residual)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="t = 10^3 and fewer settings")
    parser.add_argument("--t-end", type=float, default=None, help="horizon (default 1e4; 1e3 with --quick)")
    parser.add_argument("--only", choices=sorted(RUNS), default=None, help="one system only")
    parser.add_argument("--json", type=Path, default=None, help="also write the numbers here")
    args = parser.parse_args()
    t_end = args.t_end or (1e3 if args.quick else 1e4)
    import numba
    import scipy

    print(
        f"Python {platform.python_version()}, NumPy {np.__version__}, SciPy {scipy.__version__}, "
        f"numba {numba.__version__}; {platform.machine()}, t = 0 … {t_end:g}, 1001 samples",
        flush=True,
    )
    results: dict[str, dict[str, Any]] = {}
    for name, (system, start, params) in problems().items():
        if args.only and name != args.only:
            continue
        runs = [r for r in RUNS[name] if r[3] or not args.quick]
        for _label, model, extra, _quick in runs:  # compile (and load) every path first
            simulate(system, model, 1.0, start, params, **options({**extra, "samples": 11}))
        print(f"\n== {name}, t = 0 … {t_end:g} ==", flush=True)
        print(
            f"  {'method':34s} {'wall [s]':>9s} {'RHS evals':>10s} {'max|ΔE|':>9s} "
            f"{'first 10%':>9s} {'last 10%':>9s} {'residual':>9s}",
            flush=True,
        )
        results[name] = {}
        for label, model, extra, _quick in runs:
            row = measure(system, model, t_end, start, params, extra)
            results[name][label] = row
            flag = "" if row["status"] == "success" else f"  ({row['status']})"
            print(
                f"  {label:34s} {row['wall_s']:9.2f} {row['rhs']:10d} {row['energy_max']:9.2e} "
                f"{row['energy_first']:9.2e} {row['energy_last']:9.2e} {row['residual_max']:9.1e}{flag}",
                flush=True,
            )
    if args.json:
        args.json.write_text(json.dumps({"t_end": t_end, "results": results}, indent=2))


if __name__ == "__main__":
    main()
