"""The peer route for the rolling disk, as a user writes it without chaplygin.

SymPy's ``KanesMethod`` derives the equations (speeds ``u_i = q_i'``, the no-slip velocity
constraints making ``x'``, ``y'`` dependent speeds), ``lambdify`` turns the full mass matrix and
forcing into one NumPy function, NumPy solves ``M·ẋ = F`` at each call (as SymPy's and PyDy's
tutorials do: lambdifying the unsimplified ``rhs()`` instead makes each call ~100× slower) and
SciPy's ``solve_ivp`` (DOP853, rtol 1e-10, atol 1e-12) integrates the motion of
``example:rolling-disk``'s default state.  This file imports
nothing from chaplygin, so that run as a script it is the whole process a user would run::

    python benchmarks/peer_rolling_disk.py --t-end 100 --out peer.npz

It prints one JSON line: the seconds spent importing, deriving (``kanes_equations``),
lambdifying and integrating, and the number of right-hand-side evaluations.
``benchmarks/everyday.py`` and ``benchmarks/derive.py`` use :func:`kane_disk`.
"""

from __future__ import annotations

import time

_start = time.perf_counter()

import argparse
import json

import numpy as np
import sympy as sp
from scipy.integrate import solve_ivp
from sympy.physics.mechanics import (
    KanesMethod,
    Point,
    ReferenceFrame,
    RigidBody,
    dynamicsymbols,
    inertia,
)

#: example:rolling-disk's parameters and default state (a thin disk, A = m r²/4, C = m r²/2)
PARAMETERS = {"m": 1.0, "r": 1.0, "A": 0.25, "C": 0.5, "g": 9.81}
INITIAL = {"psi": 0.0, "theta": 0.1, "phi": 0.0, "x": 0.0, "y": 0.0, "psi'": 0.0, "theta'": 0.0, "phi'": 6.0}


def kane_disk(rhs: bool = True) -> tuple[KanesMethod, list, list, list, list]:
    """The rolling disk of ``chaplygin.examples.rolling_disk`` derived with KanesMethod.

    Same coordinates (ψ, θ, φ, x, y), speeds u_i = q_i', dependent speeds u4, u5 (x', y')
    through the no-slip velocity constraints; gravity on the centre.  Returns the method, the
    coordinates, the speeds, the parameters and the velocity constraints; with ``rhs`` the
    solved right-hand side ``km.rhs()`` is computed too (and cached on ``km``).
    """
    t = dynamicsymbols._t
    q = dynamicsymbols("psi theta phi x y")
    psi, theta, phi, x, y = q
    u = dynamicsymbols("u1:6")
    m, r, A, C, g = params = sp.symbols("m r A C g", positive=True)
    N = ReferenceFrame("N")
    Y = N.orientnew("Y", "Axis", [psi, N.z])
    L = Y.orientnew("L", "Axis", [theta, Y.x])
    D = L.orientnew("D", "Axis", [phi, L.y])
    origin = Point("O")
    origin.set_vel(N, 0)
    contact = origin.locatenew("P", x * N.x + y * N.y)
    centre = contact.locatenew("G", r * L.z)
    centre.set_vel(N, centre.pos_from(origin).dt(N))
    disk = RigidBody("disk", centre, D, m, (inertia(L, A, C, A), centre))
    slip = centre.vel(N) + D.ang_vel_in(N).cross(contact.pos_from(centre))
    to_u = dict(zip([qi.diff(t) for qi in q], u))
    constraints = [sp.expand(slip.dot(e).xreplace(to_u)) for e in (N.x, N.y)]
    km = KanesMethod(
        N,
        q_ind=q,
        u_ind=u[:3],
        kd_eqs=[qi.diff(t) - ui for qi, ui in zip(q, u)],
        u_dependent=u[3:],
        velocity_constraints=constraints,
    )
    km.kanes_equations([disk], [(centre, -m * g * N.z)])
    if rhs:
        km.rhs()
    return km, list(q), list(u), list(params), constraints


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--t-end", type=float, default=100.0)
    parser.add_argument("--samples", type=int, default=1001)
    parser.add_argument("--out", default=None, help="write t and the coordinates to this .npz")
    args = parser.parse_args()
    imported = time.perf_counter()

    km, q, u, params, constraints = kane_disk(rhs=False)
    derived = time.perf_counter()
    f = sp.lambdify([*q, *u, *params], [km.mass_matrix_full, km.forcing_full])
    values = [PARAMETERS[p.name] for p in params]
    # the dependent speeds x', y' from the constraints at the initial state
    start = {qi: INITIAL[qi.name] for qi in q}
    start.update({ui: INITIAL[qi.name + "'"] for qi, ui in zip(q[:3], u[:3])})
    start.update(sp.solve([c.subs(start).subs(dict(zip(params, values))) for c in constraints], u[3:]))
    y0 = np.array([float(start[s]) for s in (*q, *u)])
    lambdified = time.perf_counter()

    calls = 0

    def fun(_t: float, state: np.ndarray) -> np.ndarray:
        nonlocal calls
        calls += 1
        M, F = f(*state, *values)
        return np.linalg.solve(M, F).ravel()

    times = np.linspace(0.0, args.t_end, args.samples)
    sol = solve_ivp(fun, (0.0, args.t_end), y0, method="DOP853", rtol=1e-10, atol=1e-12, t_eval=times)
    integrated = time.perf_counter()
    if args.out:
        np.savez(args.out, t=sol.t, **{qi.name: sol.y[i] for i, qi in enumerate(q)})
    print(
        json.dumps(
            {
                "import": imported - _start,
                "derive": derived - imported,
                "lambdify": lambdified - derived,
                "integrate": integrated - lambdified,
                "rhs_calls": calls,
                "success": bool(sol.success),
            }
        )
    )


if __name__ == "__main__":
    main()
