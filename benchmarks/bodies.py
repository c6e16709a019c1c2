"""Kane & Levinson's rattleback: chaplygin.bodies against SymPy's KanesMethod, in one run.

Run from the repository root::

    .venv/bin/python benchmarks/bodies.py

The peer route is written here: ``sympy.physics.mechanics.KanesMethod`` with the same
coordinates (Cardan angles ψ, θ, φ and the centre of mass x, y; generalized speeds q̇), the
contact point's horizontal velocity as the two velocity constraints, ``lambdify`` of the full
mass matrix and forcing, NumPy's ``solve`` and SciPy's ``solve_ivp`` (DOP853). chaplygin:
``rolling_body`` + ``simulate("chaplygin", backend="auto")`` with a fresh, empty cache (so the
derivation, code generation and C compilation are timed). Both integrate 20 s from the same
state through the spin reversal at rtol 1e-10, atol 1e-12; the final states and the relative
energy errors are printed.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import sympy as sp

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))

os.environ["CHAPLYGIN_CACHE"] = tempfile.mkdtemp(prefix="chaplygin-bench-bodies-")

from scipy.integrate import solve_ivp
from sympy.physics import mechanics as me

from chaplygin import examples, simulate
from chaplygin.bodies import Ellipsoid, initial_state, rolling_body

#: Kane & Levinson (1982), as the catalogue's example:rattleback states them (z up)
P = dict(examples.get("rattleback").parameters)
T_END, RTOL, ATOL = 20.0, 1e-10, 1e-12


def rot(axis: str, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return {
        "x": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
        "y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
    }[axis]


def chaplygin_route() -> tuple[float, float, np.ndarray, float]:
    t0 = time.perf_counter()
    I = [[P["A"], P["D"], 0], [P["D"], P["B"], 0], [0, 0, P["C"]]]
    body = rolling_body(
        Ellipsoid(P["a"], P["b"], P["c"]), mass=P["m"], inertia=I, center_of_mass=(0, 0, -P["h"]), g=P["g"]
    )
    start = initial_state(body, R=rot("x", 0.01) @ rot("y", 0.01), omega=[0.0, 0.0, 5.0])
    simulate(body, "chaplygin", 1e-6, start, {}, samples=2)  # derive, generate, compile
    build = time.perf_counter() - t0
    t0 = time.perf_counter()
    run = simulate(body, "chaplygin", T_END, start, {}, samples=201, rtol=RTOL, atol=ATOL)
    sim = time.perf_counter() - t0
    final = np.array([run[k][-1] for k in ("psi", "theta", "phi", "x", "y", "psi'", "theta'", "phi'")])
    drift = float(np.max(np.abs(run.energy - run.energy[0])) / abs(run.energy[0]))
    return build, sim, final, drift


def kane_route() -> tuple[float, float, np.ndarray, float]:
    t0 = time.perf_counter()
    q = me.dynamicsymbols("psi theta phi x y")
    u = me.dynamicsymbols("u1:6")
    psi, theta, phi, x, y = q
    N = me.ReferenceFrame("N")
    Y = N.orientnew("Y", "Axis", [psi, N.z])
    L = Y.orientnew("L", "Axis", [theta, Y.x])
    B = L.orientnew("B", "Axis", [phi, L.y])
    a, b, c = (sp.nsimplify(P[k]) for k in "abc")
    h, m, g = sp.nsimplify(P["h"]), sp.nsimplify(P["m"]), sp.nsimplify(P["g"])
    # downward normal in B, contact point (Kane & Levinson 1982): P = (a² n1, b² n2, c² n3)/ε
    n = [me.dot(-N.z, e) for e in (B.x, B.y, B.z)]
    eps = sp.sqrt(a**2 * n[0] ** 2 + b**2 * n[1] ** 2 + c**2 * n[2] ** 2)
    G_to_P = (a**2 * n[0] / eps) * B.x + (b**2 * n[1] / eps) * B.y + (c**2 * n[2] / eps + h) * B.z
    zG = -me.dot(G_to_P, N.z)
    O = me.Point("O")
    O.set_vel(N, 0)
    G = O.locatenew("G", x * N.x + y * N.y + zG * N.z)
    kd = [qi.diff() - ui for qi, ui in zip(q, u)]
    sub = {qi.diff(): ui for qi, ui in zip(q, u)}
    G.set_vel(N, G.pos_from(O).dt(N).subs(sub))
    B.set_ang_vel(N, B.ang_vel_in(N).subs(sub))
    contact = G.locatenew("P", G_to_P)
    contact.v2pt_theory(G, N, B)
    constraints = [me.dot(contact.vel(N), N.x), me.dot(contact.vel(N), N.y)]
    I = me.inertia(B, *(sp.nsimplify(P[k]) for k in ("A", "B", "C")), sp.nsimplify(P["D"]), 0, 0)
    body = me.RigidBody("body", G, B, m, (I, G))
    kane = me.KanesMethod(
        N, q_ind=q, u_ind=u[:3], u_dependent=u[3:], kd_eqs=kd, velocity_constraints=constraints
    )
    kane.kanes_equations([body], [(G, -m * g * N.z)])
    f = sp.lambdify([*q, *u], [kane.mass_matrix_full, kane.forcing_full], "numpy", cse=True)
    energy = sp.lambdify([*q, *u], body.kinetic_energy(N) + m * g * zG, "numpy", cse=True)
    build = time.perf_counter() - t0

    def rhs(_t: float, s: np.ndarray) -> np.ndarray:
        M, F = f(*s)
        return np.linalg.solve(np.asarray(M, dtype=float), np.asarray(F, dtype=float).reshape(-1))

    I_num = [[P["A"], P["D"], 0], [P["D"], P["B"], 0], [0, 0, P["C"]]]
    ref = rolling_body(
        Ellipsoid(P["a"], P["b"], P["c"]),
        mass=P["m"],
        inertia=I_num,
        center_of_mass=(0, 0, -P["h"]),
        g=P["g"],
    )
    start = initial_state(ref, R=rot("x", 0.01) @ rot("y", 0.01), omega=[0.0, 0.0, 5.0])
    qd0 = [start["psi'"], start["theta'"], start["phi'"]]
    # dependent speeds from the constraints at the start
    A_c = sp.Matrix(constraints).jacobian(u)
    vals = dict(zip(q, [start[k] for k in ("psi", "theta", "phi", "x", "y")]))
    Ac = np.array(A_c.subs(vals).evalf().tolist(), dtype=float)
    dep = np.linalg.solve(Ac[:, 3:], -Ac[:, :3] @ np.array(qd0))
    s0 = np.array([start[k] for k in ("psi", "theta", "phi", "x", "y")] + qd0 + list(dep))
    t0 = time.perf_counter()
    sol = solve_ivp(
        rhs, (0, T_END), s0, method="DOP853", rtol=RTOL, atol=ATOL, t_eval=np.linspace(0, T_END, 201)
    )
    sim = time.perf_counter() - t0
    e = energy(*sol.y)
    final = np.concatenate([sol.y[:5, -1], sol.y[5:8, -1]])
    return build, sim, final, float(np.max(np.abs(e - e[0])) / abs(e[0]))


def main() -> None:
    cb, cs, cf, cd = chaplygin_route()
    print(
        f"chaplygin  build+derive+compile {cb:7.3f} s   simulate 20 s {cs:7.3f} s   energy error {cd:.2e}",
        flush=True,
    )
    kb, ks, kf, kdr = kane_route()
    print(
        f"KanesMethod build+derive+lambdify {kb:7.3f} s   solve_ivp 20 s {ks:7.3f} s   energy error {kdr:.2e}"
    )
    print(
        f"speed-up: build {kb / cb:.1f}x, simulation {ks / cs:.1f}x;  largest difference of the final states "
        f"{np.max(np.abs(cf - kf)):.2e}"
    )


if __name__ == "__main__":
    main()
