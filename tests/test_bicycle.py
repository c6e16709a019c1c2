"""The Whipple bicycle (``examples.whipple_bicycle``) against the benchmark of Meijaard,
Papadopoulos, Ruina & Schwab, Proc. R. Soc. A 463 (2007) 1955–1982.

The oracle is the paper's Table 2: the coefficient matrices of the linearised equations
``M q̈ + v C1 q̇ + (g K0 + v² K2) q = 0`` for ``q = (φ, δ)``, the eigenvalues at 5 m/s, the
weave and capsize speeds — published numbers, produced by none of the code under test.
The linearisation is done here, by hand: exact SymEngine derivatives of the model's
Chetaev system ``M·x = F`` (``x = (q̈, λ)``) at the upright straight-line motion, along
perturbations that keep the rolling constraints and the front wheel on the ground, and
linear algebra in 40-digit arithmetic (mpmath).
"""

from __future__ import annotations

from functools import cache

import mpmath as mp
import numpy as np
import pytest
import symengine as se
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols

from chaplygin import System, examples, simulate
from chaplygin.core._sampling import vanishes
from chaplygin.errors import ChaplyginError

# Table 2 of the paper (v in m/s)
TABLE_M = [[80.81722, 2.31941332208709], [2.31941332208709, 0.29784188199686]]
TABLE_C1 = [[0.0, 33.86641391492494], [-0.85035641456978, 1.68540397397560]]
TABLE_K0 = [[-80.95, -2.59951685249872], [-2.59951685249872, -0.80329488458618]]
TABLE_K2 = [[0.0, 76.59734589573222], [0.0, 2.65431523794604]]
EIGENVALUES_AT_5 = [
    -14.0783896927982,
    complex(-0.775341882195851, 4.46486771378823),
    complex(-0.775341882195851, -4.46486771378823),
    -0.322866429004087,
]
WEAVE_SPEED = 4.29238253634111
CAPSIZE_SPEED = 6.02426201538837

mp.mp.dps = 40


@cache
def catalogue_bike() -> System:  # one symbolic bicycle for the tests below
    return examples.get("whipple-bicycle").system()


@cache
def linearised() -> dict[str, mp.matrix]:
    """``M, C1, K0, K2`` of the bicycle's Chetaev equations at the upright straight run.

    With the state ``s = (φ, δ, φ̇, δ̇)`` the configuration is ``q(s)``: yaw, position and
    wheel angles at 0 (the motion does not depend on them), the pitch ``θ`` from the pitch
    relation (``f_φ dφ + f_θ dθ + f_δ dδ = 0``, the fifth row of A); the velocities ``q̇(s)``
    have ``θ̇_R = −v/r_R`` and the dependent ones solved from ``A(q) q̇ = 0``. Then
    ``dx/ds = M⁻¹ (dF/ds − dM/ds x₀)`` gives the accelerations' Jacobian ``[J_q, J_q̇]``, and
    the reduced mass matrix ``M_r = Cᵀ M_qq C`` (C: the admissible velocities per unit
    independent velocity) gives the paper's rows: ``v C1 = −M_r J_q̇``, ``g K0 + v² K2 = −M_r J_q``.
    """
    values = dict(examples.WHIPPLE_BENCHMARK)
    base_lam = values.pop("lam")  # kept a symbol while deriving (its radicals slow SymPy down)
    system = examples.whipple_bicycle(**values)
    eqs = system.equations("chetaev")
    v_ = system._vars
    n, g = system.n, system.g
    names = [q.func.__name__ for q in system.coordinates]
    q = {name: se.Symbol(name) for name in names}
    qd = {name: se.Symbol(name + "_d") for name in names}
    (lam_symbol,) = system.parameters
    plain = {**dict(zip(v_.x, q.values())), **dict(zip(v_.xd, qd.values()))}
    plain[lam_symbol] = se.Symbol("lam")
    to_se = {k: sp.Symbol(str(val)) for k, val in plain.items()}
    M = se.DenseMatrix(eqs._M.xreplace(to_se))
    F = se.DenseMatrix(eqs._F.xreplace(to_se))
    A = se.DenseMatrix(system._A.xreplace(to_se))
    r_R = values["r_R"]
    angles = ["phi", "theta", "delta"]  # the coordinates that M, F and A depend on (besides psi)
    zero = {q[name]: 0 for name in names}
    base = {**zero, se.Symbol("lam"): se.sympify(base_lam)}

    def number(e: se.Basic, at: dict) -> mp.mpf:
        return mp.mpf(str(se.sympify(e).subs(at).n(160, real=True)))

    def prepared(matrix: se.DenseMatrix, variable: se.Symbol | None = None) -> list[list[se.Basic]]:
        """The entries (differentiated by ``variable``) at the upright configuration: left
        functions of the velocities only."""
        rows, cols = matrix.shape
        entry = (lambda e: e) if variable is None else (lambda e: e.diff(variable))
        return [[entry(matrix[i, j]).subs(base) for j in range(cols)] for i in range(rows)]

    derivatives = {(key, None): prepared(matrix) for key, matrix in (("M", M), ("F", F), ("A", A))}
    for key, matrix in (("M", M), ("F", F), ("A", A)):
        for name in angles:
            derivatives[key, name] = prepared(matrix, q[name])
    derivatives["F", "speeds"] = prepared(F.jacobian(se.DenseMatrix([qd[nm] for nm in names])))

    def at_speed(speed: mp.mpf) -> dict[str, mp.matrix]:
        point: dict = {}

        def d(key: str, name: str | None) -> mp.matrix:  # a prepared matrix at this speed
            return mp.matrix([[number(e, point) for e in row] for row in derivatives[key, name]])

        ind = [names.index(k) for k in ("phi", "delta", "theta_R")]
        dep = list(system._dep)
        qdot = mp.matrix(n, 1)
        qdot[names.index("theta_R")] = -speed / mp.mpf(str(sp.N(r_R, 50)))
        a = d("A", None)
        a_dep = mp.matrix([[a[b, j] for j in dep] for b in range(g)])
        solved = mp.lu_solve(a_dep, -(a * qdot))
        for b, j in enumerate(dep):
            qdot[j] = solved[b]
        for k, name in enumerate(names):
            point[qd[name]] = se.Float(mp.nstr(qdot[k], 45), dps=45)
        m0 = d("M", None)
        f0 = d("F", None)
        x0 = mp.lu_solve(m0, f0)

        # admissible velocities per unit independent velocity: C (n × 3)
        C = mp.matrix(n, len(ind))
        for k, i in enumerate(ind):
            unit = mp.matrix(n, 1)
            unit[i] = 1
            col = mp.lu_solve(a_dep, -(a * unit))
            for b, j in enumerate(dep):
                unit[j] = col[b]
            for r in range(n):
                C[r, k] = unit[r]

        # perturbations of the state s = (φ, δ, φ̇, δ̇): dq and dq̇ of the full system
        dA = {name: d("A", name) for name in angles}
        pitch = g - 1  # the last constraint is the pitch relation differentiated in time
        theta_per = {
            name: -a[pitch, names.index(name)] / a[pitch, names.index("theta")] for name in ("phi", "delta")
        }
        directions = []
        for name in ("phi", "delta"):  # positions: the angle and the pitch it drags along
            dq = {name: mp.mpf(1), "theta": theta_per[name]}
            da = sum((dA[k] * dq[k] for k in dq), mp.zeros(g, n))
            ddot = mp.lu_solve(a_dep, -(da * qdot))  # A(q) q̇ = 0 keeps holding
            dqd = mp.matrix(n, 1)
            for b, j in enumerate(dep):
                dqd[j] = ddot[b]
            directions.append((dq, dqd))
        for k in range(2):  # velocities: the admissible q̇ of a unit φ̇ or δ̇
            directions.append(({}, C[:, k]))
        dM = {name: d("M", name) for name in angles}
        dFq = {name: d("F", name) for name in angles}
        dFqd = d("F", "speeds")
        J = mp.matrix(2, 4)
        for col, (dq, dqd) in enumerate(directions):
            dm = sum((dM[k] * dq[k] for k in dq), mp.zeros(n + g, n + g))
            df = sum((dFq[k] * dq[k] for k in dq), mp.zeros(n + g, 1)) + dFqd * dqd
            dx = mp.lu_solve(m0, df - dm * x0)
            for r, name in enumerate(("phi", "delta")):
                J[r, col] = dx[names.index(name)]
        mass = mp.matrix([[m0[i, j] for j in range(n)] for i in range(n)])
        reduced = C.T * mass * C
        Mr = mp.matrix([[reduced[i, j] for j in range(2)] for i in range(2)])
        return {
            "x0": x0,
            "M": Mr,
            "cross": mp.matrix([[reduced[i, 2] for i in range(2)]]),
            "K": -Mr * J[:, 0:2],
            "C": -Mr * J[:, 2:4],
            "J": J,
        }

    slow, one = at_speed(mp.mpf(0)), at_speed(mp.mpf(1))
    gravity = mp.mpf("9.81")
    return {
        "M": one["M"],
        "M0": slow["M"],
        "cross": one["cross"],
        "C1": one["C"],
        "K0": slow["K"] / gravity,
        "K2": one["K"] - slow["K"],
        "accelerations": one["x0"][:n],
        "check": at_speed(mp.mpf(5)),
    }


def close(ours: mp.matrix, table: list[list[float]], tol: float = 1e-10) -> bool:
    return all(abs(ours[i, j] - table[i][j]) < tol for i in range(2) for j in range(2))


@pytest.mark.slow
def test_linearised_bicycle_is_the_benchmark() -> None:
    """Table 2's M, C1, K0 and K2 (to the 14 digits printed: 1e-10), from the Chetaev equations."""
    lin = linearised()
    assert max(abs(a) for a in lin["accelerations"]) < 1e-30  # a steady motion: q̈ = 0
    assert max(abs(c) for c in lin["cross"]) < 1e-30  # the wheel's speed is decoupled
    assert close(lin["M"], TABLE_M) and close(lin["M0"], TABLE_M)
    assert close(lin["C1"], TABLE_C1)
    assert close(lin["K0"], TABLE_K0)
    assert close(lin["K2"], TABLE_K2)
    five = lin["check"]  # quadratic in v: the v = 5 matrices from those at 0 and 1
    assert close(five["C"] / 5, TABLE_C1) and close((five["K"] - 9.81 * lin["K0"]) / 25, TABLE_K2)


def characteristic(lin: dict, v: mp.mpf) -> list[mp.mpf]:
    """``a4 … a0`` of ``det(M s² + v C1 s + g K0 + v² K2)``."""
    M, C, K = lin["M"], v * lin["C1"], mp.mpf("9.81") * lin["K0"] + v**2 * lin["K2"]

    def mixed(P: mp.matrix, Q: mp.matrix) -> mp.mpf:  # the s-linear part of det(P + s Q)
        return P[0, 0] * Q[1, 1] + P[1, 1] * Q[0, 0] - P[0, 1] * Q[1, 0] - P[1, 0] * Q[0, 1]

    det = mp.det
    return [det(M), mixed(M, C), mixed(M, K) + det(C), mixed(C, K), det(K)]


@pytest.mark.slow
def test_bicycle_eigenvalues_weave_and_capsize_speeds() -> None:
    """At 5 m/s the eigenvalues of the reduced Jacobian ``[[0, I], [J_q, J_q̇]]`` are Table 2's;
    the weave speed (a Hopf crossing: Hurwitz's ``a1 a2 a3 − a0 a3² − a1² a4 = 0``) and the
    capsize speed (``det(g K0 + v² K2) = 0``) are the paper's to 1e-8."""
    lin = linearised()
    J = lin["check"]["J"]
    jacobian = mp.matrix(4, 4)
    jacobian[0, 2] = jacobian[1, 3] = 1
    for i in range(2):
        for j in range(4):
            jacobian[2 + i, j] = J[i, j]
    eigenvalues = sorted(
        mp.eig(jacobian, left=False, right=False), key=lambda z: (float(z.real), float(z.imag))
    )
    expected = sorted(EIGENVALUES_AT_5, key=lambda z: (complex(z).real, complex(z).imag))
    assert all(abs(complex(a) - b) < 1e-12 for a, b in zip(eigenvalues, expected)), eigenvalues

    def hurwitz(v: mp.mpf) -> mp.mpf:
        a4, a3, a2, a1, a0 = characteristic(lin, v)
        return a1 * a2 * a3 - a0 * a3**2 - a1**2 * a4

    assert abs(mp.findroot(hurwitz, 4.3) - WEAVE_SPEED) < 1e-8
    assert abs(mp.findroot(lambda v: characteristic(lin, v)[4], 6.0) - CAPSIZE_SPEED) < 1e-8
    # and the motion is stable between them, not below or above
    assert all(z.real < 0 for z in eigenvalues)


def test_pitch_relation_holds_upright_and_is_the_last_constraint() -> None:
    """The front contact's height vanishes at φ = θ = δ = 0 for every parameter value, and the
    fifth constraint of the system is its time derivative (what ``holonomic=`` will append)."""
    phi, theta, delta = dynamicsymbols("phi theta delta")
    f = examples.whipple_pitch_relation()
    assert sp.simplify(f.subs({phi: 0, theta: 0, delta: 0})) == 0
    bike = catalogue_bike()
    assert [q.name for q in bike.dependent] == ["x", "y", "psi", "theta_F", "theta"]
    assert [q.name for q in bike.independent] == ["phi", "delta", "theta_R"]
    assert vanishes(bike.implicit_constraints[4] - f.diff(dynamicsymbols._t))
    with pytest.raises(ChaplyginError, match="unknown parameter 'r'.*w, c, lam"):
        examples.whipple_bicycle(r=0.3)


def test_catalogue_state_is_admissible_and_too_large_for_a_file() -> None:
    """The default state satisfies the pitch relation (rolling upright-steered, leaning) and
    ``examples show`` refuses the system with the reason: T printed is ~2·10⁵ characters."""
    entry = examples.get("whipple-bicycle")
    phi, theta, delta = dynamicsymbols("phi theta delta")
    f = examples.whipple_pitch_relation(**entry.parameters)
    at = {phi: entry.initial["phi"], theta: entry.initial["theta"], delta: entry.initial["delta"]}
    assert abs(float(f.subs(at))) < 1e-15
    with pytest.raises(ChaplyginError, match="kinetic energy T.*characters long"):
        entry.dumps()


def test_bicycle_true_motion_compiles_by_the_numeric_reduction() -> None:
    """8 coordinates and 5 constraints: ``reduction="auto"`` reduces numerically (the symbolic
    Voronets equations of the bicycle did not finish in 10 minutes)."""
    from chaplygin.numeric import codegen

    bike = catalogue_bike()
    assert codegen._model_key(bike, "voronets", "classic", "numba", None, "auto")[1]
    sleighs = examples.sleigh_chain(2)  # 3 constraints: still symbolic
    assert not codegen._model_key(sleighs, "voronets", "classic", "numba", None, "auto")[1]


def test_cli_simulate_does_not_derive_what_it_reduces_numerically(monkeypatch, tmp_path) -> None:
    """``chaplygin simulate example:whipple-bicycle`` runs Voronets' equations by the numeric
    reduction: it must not derive them symbolically first (that took minutes); here the run
    itself is stubbed, and a symbolic derivation of the reduced model is refused."""
    from typer.testing import CliRunner

    from chaplygin.apps.cli import app
    from chaplygin.core.system import System
    from chaplygin.numeric import simulate as simulate_module

    derive = System.equations

    def equations(self, model="chetaev", form="classic", **kwargs):
        assert model not in ("voronets", "chaplygin"), f"derived {model} symbolically"
        return derive(self, model, form, **kwargs)

    def stub(*args, **kwargs):
        raise ChaplyginError("stubbed run")

    monkeypatch.setattr(System, "equations", equations)
    monkeypatch.setattr(simulate_module, "simulate", stub)
    out = tmp_path / "run.csv"
    result = CliRunner().invoke(app, ["simulate", "example:whipple-bicycle", "-t", "1", "-o", str(out)])
    assert "stubbed run" in result.output, result.output


def test_catalogue_bicycle_is_self_stable_at_5_m_per_s() -> None:
    """From the catalogue's state (5 m/s, leaning 0.05 rad), the true motion's lean dies away
    (5 m/s lies between the weave and capsize speeds: every eigenvalue has a negative real part),
    the energy is conserved and the rolling constraints hold along the run."""
    entry = examples.get("whipple-bicycle")
    bike = catalogue_bike()
    run = simulate(bike, "voronets", 5.0, entry.initial, entry.parameters, samples=11)
    assert run.success, run.message
    lean = np.abs(run["phi"])
    assert lean[-1] < 0.4 * entry.initial["phi"] and lean[-3:].max() < 0.5 * lean[:3].max()
    assert run.energy_drift() < 1e-9
    assert np.max(np.abs(run.constraint_residual)) < 1e-9
    # the forward speed stays about 5 m/s (the wheel's rate moves little while it weaves)
    speed = -entry.parameters["r_R"] * run["theta_R'"]
    assert np.all(np.abs(speed - 5.0) < 0.1)


# ---------------------------------------------------------------- the public stability API
def upright(v: float) -> dict[str, float]:
    """The upright straight run at speed v (the rear wheel's rate -v/r_R), and μ = 0."""
    return {"phi": 0, "delta": 0, "phi'": 0, "delta'": 0, "theta_R'": -v / 0.3, "psi": 0}


def test_table_2_from_the_public_api() -> None:
    """chaplygin.stability and root_locus(...).crossings() on the catalogue bicycle give the
    published eigenvalues at 5 m/s and the weave and capsize speeds to 1e-8; the zero eigenvalue
    is the family's (the speed), not a reason to call the run unstable."""
    import chaplygin

    bike, numbers = catalogue_bike(), examples.get("whipple-bicycle").parameters
    at5 = chaplygin.stability(bike, upright(5.0), numbers)
    assert at5.variables == ("phi", "delta", "phi'", "delta'", "theta_R'")
    assert set(at5.ignorable) == {"x", "y", "psi", "theta_R", "theta_F"}
    nonzero = np.sort_complex(at5.eigenvalues[np.abs(at5.eigenvalues) > 1e-6])
    np.testing.assert_allclose(nonzero, np.sort_complex(EIGENVALUES_AT_5), rtol=0, atol=1e-8)
    assert at5.kind == "asymptotically stable" and at5.family_dimension == 1
    locus = chaplygin.root_locus(bike, upright(5.0), "v", np.linspace(0.5, 10, 20), numbers, points=upright)
    weave, capsize = locus.crossings()
    assert abs(weave.value - WEAVE_SPEED) < 1e-8 and weave.change == -2 and weave.kind.startswith("a complex")
    assert abs(capsize.value - CAPSIZE_SPEED) < 1e-8 and capsize.change == 1
    for v, kind in (
        (4.2, "unstable"),
        (4.4, "asymptotically stable"),
        (6.0, "asymptotically stable"),
        (6.05, "unstable"),
    ):
        assert chaplygin.stability(bike, upright(v), numbers).kind == kind, v


@pytest.mark.slow
def test_vakonomic_bicycle_is_a_saddle_at_every_speed() -> None:
    """The vakonomic motion comes from a variational principle: its linearisation at the straight
    run (μ = 0, a steady vakonomic motion) is Hamiltonian, so its eigenvalues come in pairs ±λ and
    no speed is asymptotically stable. The front wheel's multiplier (holonomic) enters only as
    its rate, the normal force: ignorable."""
    import chaplygin

    bike, numbers = catalogue_bike(), examples.get("whipple-bicycle").parameters
    mus = {f"mu_{b}": 0.0 for b in range(1, 5)}
    for v in (2.0, 5.0):
        vak = chaplygin.stability(bike, {**upright(v), **mus}, numbers, model="vakonomic")
        assert "mu_5" in vak.ignorable and 250 < vak.ignorable["mu_5"] < 350  # ~ the front load, N
        values = np.sort_complex(vak.eigenvalues)
        np.testing.assert_allclose(values, np.sort_complex(-values), atol=1e-8 * max(abs(values)))
        assert vak.kind == "unstable"
