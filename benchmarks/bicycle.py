"""The Whipple bicycle from nothing to its eigenvalues over 100 speeds: SymPy's route and chaplygin's, timed cold.

SymPy's route is the one its test suite takes (``sympy/physics/mechanics/tests/test_kane3.py``)
and a user would take: ``KanesMethod`` with the yaw, roll, pitch and steer angles as coordinates
(the pitch dependent through the configuration constraint "the front contact is on the
ground"), six speeds (yaw, roll, pitch, steer rates and the two wheels' rates; the wheels'
angles and the rear contact's position are ignorable and left out), the front contact's
velocity as three velocity constraints (yaw, pitch and front wheel rates dependent), then
``linearize(A_and_B=True, linear_solver="CRAMER")`` (its default LU "will often result in
divide-by-zero") at the upright straight run, the benchmark's numbers substituted, the 4×4
matrix of lean, steer and their rates evaluated at 100 speeds and its eigenvalues taken.
Written here for this benchmark (the paper's axes: x forward, y right, z down), with the
parameters of Meijaard, Papadopoulos, Ruina & Schwab, Proc. R. Soc. A 463 (2007), Table 1.

chaplygin's route is its public API as a user writes it (``tests/test_bicycle.py``
``test_table_2_from_the_public_api``): ``examples.get("whipple-bicycle")`` (the system and Table
1's numbers), ``chaplygin.root_locus`` along the upright straight run over the same speeds, and
``crossings()`` for the weave and capsize speeds (Table 2: 4.29238253634111 and 6.02426201538837
m/s); then, in the same process, a second ``root_locus`` over 100 other speeds: the cost of each
further speed once linearised.

Each route runs in a fresh Python process, so imports and every derivation count; chaplygin's
with a fresh, empty ``$CHAPLYGIN_CACHE`` (cold), then once more in a new process with the cache
the cold one filled (warm)::

    python benchmarks/bicycle.py              # both routes in one run, and the ratio
    python benchmarks/bicycle.py --sympy      # SymPy's route only
    python benchmarks/bicycle.py --chaplygin  # chaplygin's route only (cold, then warm)

Each prints the seconds of the whole process, those from its start to the eigenvalue table (the
stages), the eigenvalues at v = 5 m/s (Table 2 of the paper: −14.0783896927982,
−0.775341882195851 ± 4.46486771378823i, −0.322866429004087) and their largest distance from the
paper's; the ratio is chaplygin's cold seconds to the table over SymPy's. This file imports
nothing from chaplygin for the SymPy route.
"""

from __future__ import annotations

import time

START = time.perf_counter()  # the timed process starts here (imports included)

import argparse
import json
import os
import subprocess
import sys
import tempfile

#: Table 2's eigenvalues at v = 5 m/s
BENCHMARK_AT_5 = [
    -14.0783896927982,
    complex(-0.775341882195851, 4.46486771378823),
    complex(-0.775341882195851, -4.46486771378823),
    -0.322866429004087,
]
SPEEDS = [10.0 * k / 99 for k in range(100)]  # 0 … 10 m/s; 5 m/s is added as the 101st
OTHER_SPEEDS = [10.0 * (k + 0.5) / 99 for k in range(100)]  # chaplygin's further speeds, between those
#: Table 2's weave and capsize speeds, m/s
WEAVE_SPEED, CAPSIZE_SPEED = 4.29238253634111, 6.02426201538837


def sympy_route() -> dict:
    """SymPy's ``KanesMethod`` + ``linearize`` bicycle; eigenvalues at every speed."""
    import math

    import numpy as np
    import sympy as sp
    from sympy.physics.mechanics import KanesMethod, Point, ReferenceFrame, RigidBody, dynamicsymbols, inertia

    psi, phi, theta, delta = dynamicsymbols("psi phi theta delta")
    u_psi, u_phi, u_theta, u_delta, u_R, u_F = u = dynamicsymbols("u_psi u_phi u_theta u_delta u_R u_F")
    w, c, lam, g, r_R, r_F = sp.symbols("w c lam g r_R r_F", positive=True)
    m_R, m_B, m_H, m_F = sp.symbols("m_R m_B m_H m_F", positive=True)
    I_Rxx, I_Ryy, I_Fxx, I_Fyy = sp.symbols("I_Rxx I_Ryy I_Fxx I_Fyy", positive=True)
    I_Bxx, I_Byy, I_Bzz, I_Hxx, I_Hyy, I_Hzz = sp.symbols(
        "I_Bxx I_Byy I_Bzz I_Hxx I_Hyy I_Hzz", positive=True
    )
    x_B, x_H = sp.symbols("x_B x_H", positive=True)
    z_B, z_H, I_Bxz, I_Hxz = sp.symbols("z_B z_H I_Bxz I_Hxz", real=True)

    # as in SymPy's test: each frame turned so that one of its axes is the steer axis (B.z, down),
    # the paper's axes only as fixed frames for the inertias, and the lengths given by their
    # components along the steer-axis frames (symbols, their numbers computed below)
    d_B, d_S, d_H, d_F = (sp.symbols(f"{k}_x {k}_z", real=True) for k in ("d_B", "d_S", "d_H", "d_F"))
    N = ReferenceFrame("N")  # z down
    Y = N.orientnew("Y", "Axis", [psi, N.z])
    L = Y.orientnew("L", "Axis", [phi, Y.x])
    B = L.orientnew("B", "Axis", [theta + lam, L.y])  # the rear frame; B.z down the steer axis
    B_paper = B.orientnew("B_paper", "Axis", [-lam, B.y])
    H = B.orientnew("H", "Axis", [delta, B.z])  # the front frame
    H_paper = H.orientnew("H_paper", "Axis", [-lam, H.y])
    R, F = ReferenceFrame("R"), ReferenceFrame("F")  # the wheels: their angles are ignorable
    Y.set_ang_vel(N, u_psi * N.z)
    L.set_ang_vel(Y, u_phi * Y.x)
    B.set_ang_vel(L, u_theta * L.y)
    H.set_ang_vel(B, u_delta * B.z)
    R.set_ang_vel(B, u_R * B.y)
    F.set_ang_vel(H, u_F * H.y)

    P = Point("P")  # the rear contact; rolling: the rear wheel's point there is at rest
    P.set_vel(N, 0)
    R_o = P.locatenew("R_o", -r_R * L.z)
    R_o.v2pt_theory(P, N, R)
    B_o = R_o.locatenew("B_o", d_B[0] * B.x + d_B[1] * B.z)
    B_o.v2pt_theory(R_o, N, B)
    S = R_o.locatenew("S", d_S[0] * B.x + d_S[1] * B.z)  # where the steer axis meets the ground
    S.v2pt_theory(R_o, N, B)
    H_o = S.locatenew("H_o", d_H[0] * H.x + d_H[1] * H.z)
    H_o.v2pt_theory(S, N, H)
    F_o = S.locatenew("F_o", d_F[0] * H.x + d_F[1] * H.z)
    F_o.v2pt_theory(S, N, H)
    down = (N.z - N.z.dot(H.y) * H.y).normalize()
    Q = F_o.locatenew("Q", r_F * down)  # the front contact
    Q.v2pt_theory(F_o, N, F)

    bodies = [
        RigidBody("R", R_o, R, m_R, (inertia(B, I_Rxx, I_Ryy, I_Rxx), R_o)),
        RigidBody("B", B_o, B, m_B, (inertia(B_paper, I_Bxx, I_Byy, I_Bzz, 0, 0, I_Bxz), B_o)),
        RigidBody("H", H_o, H, m_H, (inertia(H_paper, I_Hxx, I_Hyy, I_Hzz, 0, 0, I_Hxz), H_o)),
        RigidBody("F", F_o, F, m_F, (inertia(H, I_Fxx, I_Fyy, I_Fxx), F_o)),
    ]
    loads = [(b.masscenter, b.mass * g * N.z) for b in bodies]
    kane = KanesMethod(
        N,
        q_ind=[psi, phi, delta],
        u_ind=[u_phi, u_delta, u_R],
        kd_eqs=[psi.diff() - u_psi, phi.diff() - u_phi, theta.diff() - u_theta, delta.diff() - u_delta],
        q_dependent=[theta],
        configuration_constraints=[Q.pos_from(P).dot(N.z)],
        u_dependent=[u_psi, u_theta, u_F],
        velocity_constraints=[Q.vel(N).dot(Y.x), Q.vel(N).dot(Y.y), Q.vel(N).dot(N.z)],
        constraint_solver="CRAMER",
    )
    stages = {"model": time.perf_counter()}
    kane.kanes_equations(bodies, loads)
    stages["kanes_equations"] = time.perf_counter()
    v = sp.Symbol("v")
    upright = {psi: 0, phi: 0, theta: 0, delta: 0, u_psi: 0, u_phi: 0, u_theta: 0, u_delta: 0}
    upright.update({u_R: -v / r_R, u_F: -v / r_F})
    upright.update({ui.diff(): 0 for ui in u})
    A, _, _ = kane.linearize(A_and_B=True, op_point=upright, linear_solver="CRAMER")
    stages["linearize"] = time.perf_counter()
    values = {
        w: 1.02, c: 0.08, lam: sp.pi / 10, g: 9.81, r_R: 0.3, r_F: 0.35, m_R: 2, m_B: 85, m_H: 4,
        m_F: 3, I_Rxx: 0.0603, I_Ryy: 0.12, I_Fxx: 0.1405, I_Fyy: 0.28, I_Bxx: 9.2, I_Byy: 11,
        I_Bzz: 2.8, I_Bxz: 2.4, I_Hxx: 0.05892, I_Hyy: 0.06, I_Hzz: 0.00708, I_Hxz: -0.00756,
        x_B: 0.3, z_B: -0.9, x_H: 0.9, z_H: -0.7,
    }  # fmt: skip
    # offsets (a, b) in the paper's axes, from the rear wheel's centre or the steer axis's foot,
    # as components along the steer-axis frames: (a cos λ − b sin λ, a sin λ + b cos λ)
    cl, sl = math.cos(math.pi / 10), math.sin(math.pi / 10)
    for d, (a, b) in zip(
        (d_B, d_S, d_H, d_F),
        ((0.3, -0.9 + 0.3), (1.02 + 0.08, 0.3), (0.9 - 1.02 - 0.08, -0.7), (-0.08, -0.35)),
    ):
        values.update({d[0]: a * cl - b * sl, d[1]: a * sl + b * cl})
    # A is over the independent states [ψ, φ, δ, u_φ, u_δ, u_R]; kept: φ, δ, u_φ, u_δ
    keep = [1, 2, 3, 4]
    A4 = sp.lambdify(v, A.xreplace(values).extract(keep, keep), "numpy")
    stages["numbers"] = time.perf_counter()
    eig = [np.linalg.eigvals(np.array(A4(s), dtype=float)) for s in [*SPEEDS, 5.0]]
    stages["eigenvalues"] = time.perf_counter()
    names, times = list(stages), [START, *stages.values()]
    seconds = {name: round(times[k + 1] - times[k], 2) for k, name in enumerate(names)}
    return {"at_5": [complex(z) for z in eig[-1]], "speeds": len(SPEEDS), "stages": seconds}


def chaplygin_route() -> dict:
    """chaplygin's public API, as a user writes it: ``example:whipple-bicycle`` (the system and
    Table 1's numbers), ``root_locus`` over the same speeds along the upright straight run (the
    rear wheel's rate ``−v/r_R``), ``crossings()`` for the weave and capsize speeds; then a second
    ``root_locus`` over 100 other speeds, the cost of each further speed once linearised.
    The eigenvalue the family of steady motions gives (the speed's own direction, 0) is set
    aside; the other four are the paper's."""
    import numpy as np

    import chaplygin
    from chaplygin import examples

    stages = {"imports": time.perf_counter()}
    entry = examples.get("whipple-bicycle")
    bike, numbers = entry.system(), entry.parameters
    stages["model"] = time.perf_counter()

    def upright(v: float) -> dict[str, float]:
        return {"phi": 0, "delta": 0, "phi'": 0, "delta'": 0, "theta_R'": -v / numbers["r_R"], "psi": 0}

    grid = sorted([*SPEEDS, 5.0])  # increasing, for crossings()
    locus = chaplygin.root_locus(bike, upright(5.0), "v", grid, numbers, points=upright)
    stages["root_locus"] = time.perf_counter()
    names, times = list(stages), [START, *stages.values()]
    seconds = {name: round(times[k + 1] - times[k], 2) for k, name in enumerate(names)}
    row = locus.eigenvalues[grid.index(5.0)]
    zero = int(np.argmin(np.abs(row)))
    at_5 = [complex(z) for k, z in enumerate(row) if k != zero]
    start = time.perf_counter()
    crossings = locus.crossings()
    after = {"crossings": round(time.perf_counter() - start, 3)}
    start = time.perf_counter()
    chaplygin.root_locus(bike, upright(5.0), "v", OTHER_SPEEDS, numbers, points=upright)
    after["further speed [ms]"] = round(1e3 * (time.perf_counter() - start) / len(OTHER_SPEEDS), 2)
    return {
        "at_5": at_5,
        "zero": abs(complex(row[zero])),
        "speeds": len(SPEEDS),
        "stages": seconds,
        "after": after,
        "crossings": [[c.value, c.change, c.kind] for c in crossings],
    }


def _distance(eigenvalues: list[complex]) -> float:
    left = sorted(eigenvalues, key=lambda z: (z.real, z.imag))
    right = sorted((complex(z) for z in BENCHMARK_AT_5), key=lambda z: (z.real, z.imag))
    return max(abs(a - b) for a, b in zip(left, right))


def _inside(route: str) -> None:
    """The timed process: one route, its result as one line of JSON."""
    result = (chaplygin_route if route == "chaplygin" else sympy_route)()
    result["at_5"] = [[z.real, z.imag] for z in result["at_5"]]
    print(json.dumps(result))


def _run(route: str, cache: str | None = None) -> tuple[float, dict]:
    """One route in a fresh process (``$CHAPLYGIN_CACHE=cache`` for chaplygin's): its wall seconds
    as the parent sees them and what it printed."""
    env = dict(os.environ, **({"CHAPLYGIN_CACHE": cache} if cache else {}))
    start = time.perf_counter()
    run = subprocess.run(
        [sys.executable, __file__, "--inside", route], capture_output=True, text=True, check=False, env=env
    )
    seconds = time.perf_counter() - start
    if run.returncode:
        sys.exit(run.stderr.strip() or f"the {route} route failed ({run.returncode})")
    return seconds, json.loads(run.stdout.splitlines()[-1])


def _report(name: str, seconds: float, doc: dict) -> tuple[float, float]:
    """Print one run; return its seconds from the process's start to the eigenvalue table, and
    of the whole process."""
    at_5 = [complex(*z) for z in doc["at_5"]]
    table = sum(doc["stages"].values())
    print(f"{name}: {seconds:.1f} s process, {table:.1f} s to the table of {doc['speeds']} speeds (+ 5 m/s)")
    print(
        "  eigenvalues at v = 5 m/s:",
        ", ".join(f"{z.real:.12g}{z.imag:+.12g}j" for z in sorted(at_5, key=lambda z: (z.real, z.imag))),
    )
    print(f"  largest distance from Table 2: {_distance(at_5):.2e}")
    if "zero" in doc:
        print(f"  the family's zero eigenvalue set aside: |{doc['zero']:.1e}|")
    print("  seconds by stage (imports and the model first):", doc["stages"])
    if "crossings" in doc:
        for (value, change, kind), (label, paper) in zip(
            doc["crossings"], (("weave", WEAVE_SPEED), ("capsize", CAPSIZE_SPEED))
        ):
            print(
                f"  {label} speed {value:.14g} m/s ({kind}, {change:+d}), off Table 2 by {abs(value - paper):.1e}"
            )
        if len(doc["crossings"]) != 2:
            print(f"  expected two crossings (weave, capsize), found {len(doc['crossings'])}")
        print("  after the table:", doc["after"])
    return table, seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    which = parser.add_mutually_exclusive_group()
    which.add_argument(
        "--chaplygin", action="store_true", help="time chaplygin's route only (cold, then warm)"
    )
    which.add_argument("--sympy", action="store_true", help="time SymPy's route only")
    parser.add_argument("--inside", choices=("sympy", "chaplygin"), help=argparse.SUPPRESS)  # timed process
    args = parser.parse_args()
    if args.inside:
        _inside(args.inside)
        return
    cold = {}  # route -> (seconds to the table, seconds of the process)
    if not args.chaplygin:
        cold["sympy"] = _report("sympy (KanesMethod + linearize CRAMER), cold", *_run("sympy"))
    if not args.sympy:
        with tempfile.TemporaryDirectory(prefix="chaplygin-bicycle-") as cache:
            cold["chaplygin"] = _report(
                f"chaplygin, cold (empty CHAPLYGIN_CACHE={cache})", *_run("chaplygin", cache)
            )
            _report(
                "chaplygin, warm (a new process, the cache the cold one filled)", *_run("chaplygin", cache)
            )
    if len(cold) == 2:
        (table, process), (sympy_table, sympy_process) = cold["chaplygin"], cold["sympy"]
        print(
            f"ratio chaplygin / SymPy, cold: {table / sympy_table:.3f} from nothing to the table, "
            f"{process / sympy_process:.3f} whole process (chaplygin's also finds the crossings and 100 more speeds)"
        )


if __name__ == "__main__":
    main()
