"""Kane & Levinson's rattleback: chaplygin.bodies against SymPy's KanesMethod.

Run from the repository root::

    .venv/bin/python benchmarks/bodies.py

The peer route is written here: ``sympy.physics.mechanics.KanesMethod`` with the same
coordinates (Cardan angles ψ, θ, φ and the centre of mass x, y; generalized speeds q̇), the
contact point's horizontal velocity as the two velocity constraints, ``lambdify`` of the full
mass matrix and forcing, NumPy's ``solve`` and SciPy's ``solve_ivp`` (DOP853). chaplygin:
``rolling_body`` + ``simulate("chaplygin", backend="auto")``. Both integrate 20 s from the same
state through the spin reversal at rtol 1e-10, atol 1e-12; the final states and the relative
energy errors are printed.

Two pairs of rows:

* **numeric**: the body's parameters are numbers when the equations are built (both routes).
* **symbolic**: they stay symbols (a, b, c, h, m, A, B, C, D, g, as in PyDy's rattleback
  example and ``examples.rattleback()``): Kane's ``lambdify`` takes them as arguments, chaplygin's
  ``simulate`` as ``params``; the user can change them without deriving again.

Every route runs in a fresh Python process of its own (so no route profits from SymPy's
cache or imports left by another); chaplygin's with a fresh, empty ``$CHAPLYGIN_CACHE`` (so
the derivation, code generation and C compilation are timed). "build" is timed inside the
process from after the imports to a loaded right-hand side; "20 s" is the integration;
"process" is the whole child process from the parent (Python start-up and imports included).
The cold cache is empty: a first run after installation. chaplygin's DOP853 loop library is
part of the installation (built by ``setup.py`` when the checkout is installed with ``make`` or
``pip install -e``); where it is not, the cold run builds it too, in a thread beside the
derivation (~0.2 s of a second core): the script says which.
Then the **warm** rows: the symbolic chaplygin script again in a new process with the
cache the cold run left, and the command line ``python -m chaplygin simulate
example:rattleback`` (the same symbolic rattleback, its default numbers) cold, then warm.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SRC = ROOT / "src"
T_END, RTOL, ATOL = 20.0, 1e-10, 1e-12
STATE = ("psi", "theta", "phi", "x", "y", "psi'", "theta'", "phi'")
#: the parameters as examples.rattleback() names them (inertia m*[[A, D, 0], [D, B, 0], [0, 0, C]])
NAMES = ("a", "b", "c", "h", "m", "A", "B", "C", "D", "g")


def rot(axis: str, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return {
        "x": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
        "y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
    }[axis]


# ------------------------------------------------------------------------------ chaplygin
def chaplygin_route(P: dict[str, float], start: dict[str, float], symbolic: bool) -> dict[str, Any]:
    import sympy as sp

    from chaplygin import simulate
    from chaplygin.bodies import Ellipsoid, rolling_body

    t0 = time.perf_counter()
    if symbolic:  # what examples.rattleback() builds, written out
        a, b, c, h, m, A, B, C, g = sp.symbols("a b c h m A B C g", positive=True)
        D = sp.Symbol("D", real=True)
        params = dict(P)
    else:
        a, b, c, h, m, A, B, C, D, g = (P[k] for k in NAMES)
        params = {}
    body = rolling_body(
        Ellipsoid(a, b, c),
        mass=m,
        inertia=[[m * A, m * D, 0], [m * D, m * B, 0], [0, 0, m * C]],
        center_of_mass=(0, 0, -h),
        g=g,
    )
    simulate(body, "chaplygin", 1e-6, start, params, samples=2)  # derive, generate, compile
    build = time.perf_counter() - t0
    t0 = time.perf_counter()
    run = simulate(body, "chaplygin", T_END, start, params, samples=201, rtol=RTOL, atol=ATOL)
    sim = time.perf_counter() - t0
    drift = float(np.max(np.abs(run.energy - run.energy[0])) / abs(run.energy[0]))
    final = [float(run[k][-1]) for k in STATE]
    return {"build": build, "sim": sim, "final": final, "drift": drift, "backend": run.backend}


# ------------------------------------------------------------------------------ KanesMethod
def kane_route(P: dict[str, float], start: dict[str, float], symbolic: bool) -> dict[str, Any]:
    import sympy as sp
    from scipy.integrate import solve_ivp
    from sympy.physics import mechanics as me

    t0 = time.perf_counter()
    q = me.dynamicsymbols("psi theta phi x y")
    u = me.dynamicsymbols("u1:6")
    psi, theta, phi, x, y = q
    N = me.ReferenceFrame("N")
    Y = N.orientnew("Y", "Axis", [psi, N.z])
    L = Y.orientnew("L", "Axis", [theta, Y.x])
    B = L.orientnew("B", "Axis", [phi, L.y])
    if symbolic:
        a, b, c, h, m, A_, B_, C_, g = sp.symbols("a b c h m A B C g", positive=True)
        D_ = sp.Symbol("D", real=True)
        p_sym = [a, b, c, h, m, A_, B_, C_, D_, g]
        p_val = [P[k] for k in NAMES]
    else:
        a, b, c, h, m, A_, B_, C_, D_, g = (sp.nsimplify(P[k]) for k in NAMES)
        p_sym, p_val = [], []
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
    I = me.inertia(B, m * A_, m * B_, m * C_, m * D_, 0, 0)
    body = me.RigidBody("body", G, B, m, (I, G))
    kane = me.KanesMethod(
        N, q_ind=q, u_ind=u[:3], u_dependent=u[3:], kd_eqs=kd, velocity_constraints=constraints
    )
    kane.kanes_equations([body], [(G, -m * g * N.z)])
    args = [*q, *u, *p_sym]
    f = sp.lambdify(args, [kane.mass_matrix_full, kane.forcing_full], "numpy", cse=True)
    energy = sp.lambdify(args, body.kinetic_energy(N) + m * g * zG, "numpy", cse=True)
    build = time.perf_counter() - t0

    def rhs(_t: float, s: np.ndarray) -> np.ndarray:
        M, F = f(*s, *p_val)
        return np.linalg.solve(np.asarray(M, dtype=float), np.asarray(F, dtype=float).reshape(-1))

    qd0 = [start["psi'"], start["theta'"], start["phi'"]]
    # dependent speeds from the constraints at the start
    values = dict(zip(q, [start[k] for k in ("psi", "theta", "phi", "x", "y")])) | dict(zip(p_sym, p_val))
    Ac = np.array(sp.Matrix(constraints).jacobian(u).subs(values).evalf().tolist(), dtype=float)
    dep = np.linalg.solve(Ac[:, 3:], -Ac[:, :3] @ np.array(qd0))
    s0 = np.array([start[k] for k in ("psi", "theta", "phi", "x", "y")] + qd0 + list(dep))
    t0 = time.perf_counter()
    sol = solve_ivp(
        rhs, (0, T_END), s0, method="DOP853", rtol=RTOL, atol=ATOL, t_eval=np.linspace(0, T_END, 201)
    )
    sim = time.perf_counter() - t0
    e = energy(*sol.y, *p_val)
    final = [float(v) for v in np.concatenate([sol.y[:5, -1], sol.y[5:8, -1]])]
    return {"build": build, "sim": sim, "final": final, "drift": float(np.max(np.abs(e - e[0])) / abs(e[0]))}


ROUTES = {
    "chaplygin-numeric": lambda P, s: chaplygin_route(P, s, symbolic=False),
    "kane-numeric": lambda P, s: kane_route(P, s, symbolic=False),
    "chaplygin-symbolic": lambda P, s: chaplygin_route(P, s, symbolic=True),
    "kane-symbolic": lambda P, s: kane_route(P, s, symbolic=True),
}


# ------------------------------------------------------------------------------ the parent
def _env(cache: str) -> dict[str, str]:
    """A child's environment: its cache, this tree, and bytecode written and reused as for a user."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    return env | {"CHAPLYGIN_CACHE": cache, "PYTHONPATH": str(SRC)}


def spawn(route: str, data: str, cache: str) -> dict[str, Any]:
    """One route in a fresh process; its in-process numbers and the whole process's wall time."""
    t0 = time.perf_counter()
    out = subprocess.run(
        [sys.executable, __file__, "--route", route, data],
        env=_env(cache),
        capture_output=True,
        text=True,
        check=True,
    )
    wall = time.perf_counter() - t0
    return json.loads(out.stdout.strip().splitlines()[-1]) | {"process": wall}


def installed_loop() -> bool:
    """Whether the chaplygin under test has the DOP853 loop library its installation built."""
    code = "from chaplygin.numeric import _ckernel; print(bool(_ckernel.packaged_loop()))"
    out = subprocess.run(
        [sys.executable, "-c", code], env=_env(""), capture_output=True, text=True, check=True
    )
    return out.stdout.strip().splitlines()[-1] == "True"


def cli(cache: str, csv: Path) -> dict[str, Any]:
    """``python -m chaplygin simulate example:rattleback`` as a whole process."""
    command = [sys.executable, "-m", "chaplygin", "simulate", "example:rattleback", "-t", str(T_END)]
    command += ["-n", "201", "--rtol", str(RTOL), "--atol", str(ATOL), "-o", str(csv), "--force"]
    t0 = time.perf_counter()
    subprocess.run(command, env=_env(cache), capture_output=True, text=True, check=True)
    wall = time.perf_counter() - t0
    table = np.genfromtxt(csv, delimiter=",", names=True)
    header = csv.read_text(encoding="utf-8").splitlines()[0].split(",")
    final = [float(table[-1][header.index(k)]) for k in STATE]
    e = table["energy"]
    return {"process": wall, "final": final, "drift": float(np.max(np.abs(e - e[0])) / abs(e[0]))}


def row(label: str, r: dict[str, Any]) -> str:
    build = f"{r['build']:7.3f} s" if "build" in r else "      —  "
    sim = f"{r['sim']:7.3f} s" if "sim" in r else "      —  "
    return f"{label:41s} build {build}   20 s {sim}   process {r['process']:7.3f} s   energy error {r['drift']:.1e}"


def main() -> None:
    sys.path.insert(0, str(SRC))
    from chaplygin import examples

    entry = examples.get("rattleback")
    P = {k: float(entry.parameters[k]) for k in NAMES}
    start = dict(entry.initial)
    data = json.dumps({"P": P, "start": start})
    load = os.getloadavg()
    print(f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}", flush=True)
    if installed_loop():
        print("DOP853 loop library: built when chaplygin was installed (setup.py)", flush=True)
    else:
        print("DOP853 loop library: not installed; every cold chaplygin row also builds it", flush=True)
    with tempfile.TemporaryDirectory(prefix="chaplygin-bench-bodies-") as tmp:
        for kind in ("numeric", "symbolic"):
            print(f"-- parameters {kind}", flush=True)
            cache = tempfile.mkdtemp(dir=tmp)
            c = spawn(f"chaplygin-{kind}", data, cache)
            print(row(f"chaplygin [{c['backend']}], cold cache", c), flush=True)
            w = spawn(f"chaplygin-{kind}", data, cache) if kind == "symbolic" else None
            if w is not None:
                print(row(f"chaplygin [{w['backend']}], warm cache", w), flush=True)
            k = spawn(f"kane-{kind}", data, cache)
            print(row("KanesMethod + lambdify + solve_ivp", k), flush=True)
            print(
                f"   cold speed-up: build {k['build'] / c['build']:.2f}x, 20 s {k['sim'] / c['sim']:.1f}x, "
                f"process {k['process'] / c['process']:.2f}x; largest difference of the final states "
                f"{np.max(np.abs(np.subtract(c['final'], k['final']))):.1e}",
                flush=True,
            )
            if w is not None:
                print(
                    f"   warm speed-up: build {k['build'] / w['build']:.2f}x, process "
                    f"{k['process'] / w['process']:.2f}x",
                    flush=True,
                )
        print("-- command line, example:rattleback (symbolic parameters, default numbers)", flush=True)
        cache, csv = tempfile.mkdtemp(dir=tmp), Path(tmp) / "rattleback.csv"
        for label in ("cold cache", "warm cache (run plan)"):
            r = cli(cache, csv)
            print(row(f"chaplygin simulate, {label}", r), flush=True)
            print(
                f"   process speed-up against KanesMethod's (symbolic) {k['process'] / r['process']:.2f}x; "
                f"largest difference of the final states {np.max(np.abs(np.subtract(r['final'], k['final']))):.1e}",
                flush=True,
            )
    load = os.getloadavg()
    print(f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--route":
        sys.path.insert(0, str(SRC))
        given = json.loads(sys.argv[3])
        print(json.dumps(ROUTES[sys.argv[2]](given["P"], given["start"])))
    else:
        main()
