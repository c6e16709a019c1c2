"""The isokinetic particle (ẋ² + ẏ² = v², a uniform field) from nothing to a 20 s run: the route a
user takes by hand and chaplygin's, each in a fresh process, timed whole.

No peer library takes a constraint nonlinear in the velocities (``KanesMethod`` raises on one), so
the route a user would take instead is written here with SymPy and SciPy only: Lagrange's
equations with the Appell–Chetaev multiplier, ``m ẍ = 2λẋ``, ``m ÿ = −m g + 2λẏ``, and the
constraint differentiated once, ``2ẋẍ + 2ẏÿ = 0``, as ``M·[ẍ, ÿ, λ] = F`` built with SymPy,
``lambdify``-ed, solved by ``numpy.linalg.solve`` at every step of ``solve_ivp`` (DOP853, rtol 1e-10,
atol 1e-12). chaplygin's route is its public API: ``examples.isokinetic_particle()`` and
``chaplygin.simulate(system, "chetaev", 20, …)`` at the same tolerances (cold: an empty
``$CHAPLYGIN_CACHE``; warm: a new process with the cache the cold one filled).

Both print the seconds of the whole process and the final state's distance from the grim reaper
``y = a ln cos(x/a)``, ``a = v²/g`` (the closed form: the ground truth), so a fast wrong answer shows::

    python benchmarks/nonlinear.py        # both routes and the ratio
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time

PARAMETERS = {"m": 1.0, "g": 0.1, "v": 1.0}
START = {"x": 0.0, "y": 0.0, "y'": 0.0}
T_END = 20.0

BY_HAND = """
import math, numpy as np, sympy as sp
from scipy.integrate import solve_ivp
x, y, xd, yd, xdd, ydd, lam, m, g, v = sp.symbols("x y xd yd xdd ydd lam m g v")
T = m / 2 * (xd**2 + yd**2)
f = xd**2 + yd**2 - v**2
rows = [m * xdd - lam * sp.diff(f, xd), m * ydd + m * g - lam * sp.diff(f, yd), 2 * xd * xdd + 2 * yd * ydd]
unknowns = [xdd, ydd, lam]
M = sp.Matrix(rows).jacobian(unknowns)
F = -sp.Matrix(rows).subs({u: 0 for u in unknowns})
fM, fF = sp.lambdify([x, y, xd, yd, m, g, v], M), sp.lambdify([x, y, xd, yd, m, g, v], F)
p = (1.0, 0.1, 1.0)
def rhs(t, s):
    acc = np.linalg.solve(np.array(fM(*s, *p), float), np.array(fF(*s, *p), float).ravel())
    return [s[2], s[3], acc[0], acc[1]]
run = solve_ivp(rhs, (0, 20.0), [0.0, 0.0, 1.0, 0.0], method="DOP853", rtol=1e-10, atol=1e-12)
X, Y = run.y[0, -1], run.y[1, -1]
a = 1.0**2 / 0.1
print(f"{abs(Y - a * math.log(math.cos(X / a))):.2e}")
"""

CHAPLYGIN = """
import math
import chaplygin
from chaplygin import examples
s = examples.isokinetic_particle()
run = chaplygin.simulate(s, "chetaev", 20.0, {"x": 0.0, "y": 0.0, "y'": 0.0}, {"m": 1.0, "g": 0.1, "v": 1.0},
                         rtol=1e-10, atol=1e-12)
X, Y = run["x"][-1], run["y"][-1]
a = 1.0**2 / 0.1
print(f"{abs(Y - a * math.log(math.cos(X / a))):.2e}")
"""


def timed(code: str, env: dict[str, str]) -> tuple[float, str]:
    """Seconds of a fresh ``python -c code`` and what it printed."""
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    return time.perf_counter() - start, out.stdout.strip()


def main() -> None:
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "CHAPLYGIN_CACHE": cache}
        hand, hand_error = timed(BY_HAND, env)
        cold, cold_error = timed(CHAPLYGIN, env)
        warm, warm_error = timed(CHAPLYGIN, env)
    print(
        "isokinetic particle, t = 0 … 20, DOP853 rtol 1e-10 (whole processes, seconds; |y − a ln cos(x/a)| at the end)"
    )
    print(f"  by hand (SymPy + lambdify + solve_ivp): {hand:7.2f} s   error {hand_error}")
    print(f"  chaplygin, cold cache:                  {cold:7.2f} s   error {cold_error}")
    print(f"  chaplygin, warm cache:                  {warm:7.2f} s   error {warm_error}")
    print(f"  ratio chaplygin/by hand: cold {cold / hand:.2f}, warm {warm / hand:.2f}")


if __name__ == "__main__":
    main()
