"""Steady motions, linearisation and stability (issue 29, items 2, 3, 5) against published results.

Every expected value comes from a closed form or an independent derivation, never from chaplygin:

* the Chaplygin sleigh's straight line: ``λ = −m a v₀/(I + m a²)`` (Bloch 2003, §1.7); Lindelöf's
  sleigh (the constraint substituted into T) from its own T̃, derived here with SymPy;
* the upright rolling disk: ``λ² = [m g r − C (C + m r²) ω²/A]/(A + m r²)`` (Routh 1905, art. 244;
  McDonald 2000, §2.5), and ``KanesMethod.linearize`` on the disk built in the test;
* the steady turning of the disk: ``A Ω² sin θ cos θ − (C + m r²) s Ω cos θ − m g r sin θ = 0``
  (Routh 1905, art. 244; O'Reilly 1996; McDonald 2000, §2.2);
* the rattleback: an independent Newton–Euler model (``tests/test_bodies.py``), and reversibility
  (time reversal maps the spin n to −n and λ to −λ).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import sympy as sp
from sympy.physics.mechanics import KanesMethod, dynamicsymbols

import chaplygin
from chaplygin import examples
from chaplygin.errors import ChaplyginError, InputError

t = dynamicsymbols._t
SLEIGH = {"m": 2.0, "I": 0.7, "a": 0.4}
COIN = {"m": 1.3, "r": 0.7, "A": 1.3 * 0.49 / 4, "C": 1.3 * 0.49 / 2, "g": 9.81}


def _nonzero(values: np.ndarray, tol: float = 1e-7) -> np.ndarray:
    return np.sort_complex(values[np.abs(values) > tol])


# ---------------------------------------------------------------- the Chaplygin sleigh
@pytest.mark.parametrize("model", ["chetaev", "chaplygin"])
def test_sleigh_straight_line(model: str) -> None:
    sleigh = examples.chaplygin_sleigh()
    m, I, a = SLEIGH["m"], SLEIGH["I"], SLEIGH["a"]
    for v0 in (1.5, -0.8):
        # x' = v cos(theta): at theta = 0.3 the forward speed v0 needs x' = v0 cos(0.3)
        point = {"theta": 0.3, "x'": v0 * np.cos(0.3), "theta'": 0.0}
        result = chaplygin.stability(sleigh, point, SLEIGH, model=model)
        assert result.variables == ("theta", "x'", "theta'") and set(result.ignorable) == {"x", "y"}
        expected = -m * a * v0 / (I + m * a**2)
        np.testing.assert_allclose(_nonzero(result.eigenvalues), [expected], rtol=1e-12)
        assert result.family_dimension == 2 and len(result.zeros) == 2  # heading and speed
        assert result.integrals == {"energy": True}
        assert result.kind == ("asymptotically stable" if v0 > 0 else "unstable")  # the mass centre leads
    assert "asymptotically stable (modulo the family" in str(
        chaplygin.stability(sleigh, {"theta": 0, "x'": 1, "theta'": 0}, SLEIGH, model=model)
    )


def test_sleigh_vakonomic_is_lindelof_from_its_own_reduced_energy() -> None:
    """Lindelöf's sleigh: T̃ = ½ m x'² sec²θ + ½ (I + m a²) θ'² (the constraint y' = tan θ x'
    substituted); its Lagrange equations, linearised here by SymPy, give λ² = m v²/(I + m a²)."""
    th, x = dynamicsymbols("theta x")
    m, I, a = sp.symbols("m I a", positive=True)
    Tt = m / 2 * x.diff(t) ** 2 / sp.cos(th) ** 2 + (I + m * a**2) / 2 * th.diff(t) ** 2
    lagrange = [sp.diff(Tt.diff(q.diff(t)), t) - Tt.diff(q) for q in (x, th)]
    acc = sp.solve(lagrange, [x.diff(t, 2), th.diff(t, 2)], dict=True)[0]
    z = sp.symbols("z0:3")  # theta, x', theta'
    plain = {th.diff(t): z[2], x.diff(t): z[1], th: z[0]}
    rhs = sp.Matrix([th.diff(t), acc[x.diff(t, 2)], acc[th.diff(t, 2)]]).xreplace(plain)
    values = {z[0]: 0, z[1]: 1.5, z[2]: 0, m: SLEIGH["m"], I: SLEIGH["I"], a: SLEIGH["a"]}
    J = rhs.jacobian(z).subs(values)
    expected = np.sort_complex(np.array([complex(e) for e in J.eigenvals(multiple=True)]))
    sleigh = examples.chaplygin_sleigh()
    lindelof = chaplygin.stability(sleigh, {"theta": 0, "x'": 1.5, "theta'": 0}, SLEIGH, model="lindelof")
    np.testing.assert_allclose(np.sort_complex(lindelof.eigenvalues), expected, atol=1e-12)
    # the vakonomic model with mu = 0 is the c = 0 member: the same motion, one more variable
    vak = chaplygin.stability(
        sleigh, {"theta": 0, "x'": 1.5, "theta'": 0, "mu_1": 0}, SLEIGH, model="vakonomic"
    )
    np.testing.assert_allclose(_nonzero(vak.eigenvalues), _nonzero(expected), rtol=1e-10)
    assert vak.kind == lindelof.kind == "unstable"


# ---------------------------------------------------------------- the upright rolling disk
def _rate2(spin: float, p: dict) -> float:
    m, r, A, C, g = (p[k] for k in "mrACg")
    return (m * g * r - C * (C + m * r**2) * spin**2 / A) / (A + m * r**2)


def test_upright_disk_against_the_closed_form() -> None:
    disk = examples.rolling_disk()
    critical = np.sqrt(COIN["g"] / (3 * COIN["r"]))  # a uniform thin disk
    m, r, A, C, g = (COIN[k] for k in "mrACg")
    assert np.isclose(critical**2, m * g * r * A / (C * (C + m * r**2)))
    for factor in (0.6, 0.99, 1.01, 2.0):
        spin = factor * critical
        point = {"theta": 0, "psi'": 0, "theta'": 0, "phi'": spin}
        for model in ("chetaev", "chaplygin"):
            result = chaplygin.stability(disk, point, COIN, model=model)
            rate = np.sqrt(complex(_rate2(spin, COIN)))
            np.testing.assert_allclose(
                _nonzero(result.eigenvalues), np.sort_complex([rate, -rate]), rtol=1e-9
            )
            assert result.kind == ("linearly stable" if factor > 1 else "unstable")
            assert result.family_dimension == 2 and set(result.ignorable) == {"psi", "phi", "x", "y"}


def test_crossings_of_the_imaginary_axis_are_the_thresholds() -> None:
    """RootLocus.crossings: the sleigh's eigenvalue -m a v/(I + m a²) crosses at v = 0 exactly
    (unstable behind, stable ahead); the upright coin's real pair meets the family's zeros at
    ω² = m g r A/(C(C + m r²)) (a Jordan block there limits the precision, as documented)."""
    sleigh = chaplygin.root_locus(
        examples.chaplygin_sleigh(), {"theta": 0, "x'": 1, "theta'": 0}, "x'", np.linspace(-1, 1.1, 8), SLEIGH
    )
    [at_rest] = sleigh.crossings()
    unsorted = chaplygin.root_locus(  # a value appended out of order made a false second crossing
        examples.chaplygin_sleigh(), {"theta": 0, "x'": 1, "theta'": 0}, "x'", [-1, 1, -0.5], SLEIGH
    )
    assert [c.value for c in unsorted.crossings()] == [0.0]
    assert (at_rest.value, at_rest.eigenvalue, at_rest.change) == (0.0, 0j, -1)
    assert at_rest.kind == "a real eigenvalue" and "leave the right half-plane" in str(at_rest)
    m, r, A, C, g = (COIN[k] for k in "mrACg")
    critical = np.sqrt(m * g * r * A / (C * (C + m * r**2)))
    disk = chaplygin.root_locus(
        examples.rolling_disk(),
        {"theta": 0, "psi'": 0, "theta'": 0, "phi'": 1},
        "spin",
        np.linspace(-4, 4, 9),
        COIN,
        points=lambda w: {"theta": 0, "psi'": 0, "theta'": 0, "phi'": w},
    )
    found = disk.crossings()
    assert [c.change for c in found] == [1, -1]
    np.testing.assert_allclose([c.value for c in found], [-critical, critical], rtol=1e-9)


def test_a_small_eigenvalue_beside_the_familys_zero_is_not_a_zero() -> None:
    """The bicycle's reduced Jacobian (phi, delta, phi', delta', theta_R') just past its capsize
    speed, at 6.05 m/s: the family's zero and a real eigenvalue 0.0042.  The nullity of J² called
    the 0.0042 a second zero (a Jordan chain) and the motion asymptotically stable."""
    from chaplygin.numeric.stability import _verdict

    J = np.zeros((5, 5))
    J[0, 2] = J[1, 3] = 1.0
    J[2, :4] = [9.489774446773565, -33.19158838103705, -0.6384108213244296, -1.9996181639034798]
    J[3, :4] = [11.71947687196337, -41.26094800546167, 22.24467166159521, -18.66343644097035]
    growth = max(np.linalg.eigvals(J).real)
    assert 0.004 < growth < 0.0045  # numpy's eig: the capsize mode grows
    _, _, family, zeros, _, kind, verdict, _ = _verdict(J, ("phi", "delta", "phi'", "delta'", "theta_R'"), {})
    assert (family, len(zeros), kind) == (1, 1, "unstable") and "0.0042" in verdict
    # a true Jordan chain (rounded) is still one: two zeros, the family's dimension 1
    S = np.array([[1.0, 0.3, -0.7], [0.2, 1.1, 0.5], [-0.4, 0.6, 0.9]])
    jordan = S @ np.array([[0.0, 20.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, -3.0]]) @ np.linalg.inv(S)
    _, _, family, zeros, _, kind, _, _ = _verdict(jordan, ("a", "b", "c"), {})
    assert (family, len(zeros), kind) == (1, 2, "undetermined")  # no integral explains the chain


def test_upright_disk_symbolic_condition_is_the_formula() -> None:
    disk = examples.rolling_disk()
    s = sp.Symbol("s")
    cond = chaplygin.stability_conditions(disk, {"theta": 0, "psi'": 0, "theta'": 0, "phi'": s})
    assert cond.zero_roots == 2 and cond.route == "even" and len(cond.conditions) == 1
    assert "<pre>" in cond._repr_html_() and "roots in s = lam**2" in str(cond)
    m, r, A, C, g = sp.symbols("m r A C g", positive=True)
    formula = C * (C + m * r**2) * s**2 - m * g * r * A
    ratio = sp.simplify(cond.conditions[0].lhs / formula)
    assert ratio.free_symbols <= {m, r, A, C, g} and ratio.is_positive


def _kanes_disk(p: dict) -> tuple[KanesMethod, list, list, dict]:
    """The rolling disk in KanesMethod (u = q', x' and y' dependent through the no-slip constraints)."""
    from test_rolling_disk import Mechanics  # the same disk, frames and points, as the peer tests build it

    mech = Mechanics()
    q, u = mech.q, dynamicsymbols("u1:6")
    m, r, A, C, g = mech.params
    N, G, disk = mech.N, mech.centre, mech.disk
    to_u = dict(zip(mech.qd, u))
    G.set_vel(N, G.vel(N).xreplace(to_u))
    disk.frame.set_ang_vel(N, disk.frame.ang_vel_in(N).xreplace(to_u))
    km = KanesMethod(
        N,
        q_ind=q,
        u_ind=u[:3],
        kd_eqs=[qi.diff(t) - ui for qi, ui in zip(q, u)],
        u_dependent=u[3:],
        velocity_constraints=[sp.expand(c.xreplace(to_u)) for c in mech.slip[:2]],
    )
    km.kanes_equations([disk], [(G, -m * g * N.z)])
    return km, q, u, dict(zip((m, r, A, C, g), (p[k] for k in "mrACg")))


def test_upright_disk_against_kanes_method_linearize() -> None:
    km, q, u, values = _kanes_disk(COIN)
    spin = 2.5
    op = [{qi: 0 for qi in q}, {u[0]: 0, u[1]: 0, u[2]: spin, u[3]: COIN["r"] * spin, u[4]: 0}]
    op.append({ui.diff(t): 0 for ui in u})
    A_lin = km.linearize(op_point=op, A_and_B=True, linear_solver="CRAMER")[0]
    expected = _nonzero(np.linalg.eigvals(np.array(A_lin.subs(values).evalf(), dtype=float)))
    disk = examples.rolling_disk()
    for model in ("chetaev", "chaplygin"):
        point = {"theta": 0, "psi'": 0, "theta'": 0, "phi'": spin}
        result = chaplygin.stability(disk, point, COIN, model=model)
        np.testing.assert_allclose(_nonzero(result.eigenvalues), expected, rtol=1e-9)
    assert expected.size == 2 and np.all(np.abs(expected.real) < 1e-9)  # the wobble: ±iω


def test_turning_disk_against_kanes_method() -> None:
    """A steady turn: KanesMethod's equations (M_full, F_full, solved numerically here) differenced
    in the reduced variables (theta, psi', theta', phi') at heading 0, against the exact Jacobian."""
    km, q, u, values = _kanes_disk(COIN)
    psi, theta, phi, x, y = q
    z = sp.symbols("z0:10")
    plain = dict(zip([*q, *u], z))
    M = sp.lambdify(z, km.mass_matrix_full.xreplace(plain).subs(values), "numpy", cse=True)
    F = sp.lambdify(z, km.forcing_full.xreplace(plain).subs(values), "numpy", cse=True)
    r = COIN["r"]

    def rates(s: np.ndarray) -> np.ndarray:  # (theta, psi', theta', phi') at psi = 0
        state = [0.0, s[0], 0.0, 0.0, 0.0, s[1], s[2], s[3], r * s[3], 0.0]  # x' = r phi', y' = 0
        d = np.linalg.solve(np.array(M(*state), dtype=float), np.array(F(*state), dtype=float).ravel())
        return np.array([d[1], d[5], d[6], d[7]])  # theta', u1', u2', u3'

    disk = examples.rolling_disk()
    turn = chaplygin.steady_motions(
        disk, {"theta": 0.3, "psi'": 2.0, "theta'": 0, "phi'": 0.0}, COIN, fixed=["theta", "psi'"]
    ).point
    s0 = np.array([turn["theta"], turn["psi'"], 0.0, turn["phi'"]])
    assert np.max(np.abs(rates(s0))) < 1e-12  # steady in KanesMethod's equations too
    h = 1e-6
    J = np.column_stack([(rates(s0 + h * e) - rates(s0 - h * e)) / (2 * h) for e in np.eye(4)])
    expected = _nonzero(np.linalg.eigvals(J), tol=1e-5)
    for model in ("chetaev", "chaplygin"):
        result = chaplygin.stability(disk, turn, COIN, model=model)
        np.testing.assert_allclose(_nonzero(result.eigenvalues), expected, rtol=1e-6)
    assert result.kind == "unstable" and expected.size == 2  # the slow turn falls


# ---------------------------------------------------------------- the steady turning of the disk
def test_steady_turning_family_is_the_classical_relation() -> None:
    disk = examples.rolling_disk()
    family = chaplygin.steady_motions(disk)
    assert family.parameters == ("theta", "psi'") and len(family.solutions) == 1
    psi, theta, phi = dynamicsymbols("psi theta phi")
    m, r, A, C, g = sp.symbols("m r A C g", positive=True)
    Om, th = psi.diff(t), theta
    phid = family.solutions[0]["phi'"]
    s = phid + Om * sp.sin(th)
    relation = (
        A * Om**2 * sp.sin(th) * sp.cos(th) - (C + m * r**2) * s * Om * sp.cos(th) - m * g * r * sp.sin(th)
    )
    assert sp.simplify(relation) == 0
    # upright: rolling straight (psi' = 0, any spin) or spinning about a vertical diameter
    upright = chaplygin.steady_motions(disk, fixed={"theta": 0})
    assert upright.solutions == [{"phi'": 0}] and upright.parameters == ("psi'",)
    assert "family 1: phi&#x27; = 0" in upright._repr_html_()
    assert sp.factor(upright.equations[0]) == (C + m * r**2) * phi.diff(t) * psi.diff(t)
    # the Newton search, from a guess off the family, lands on it (lean and turning rate held)
    lean, rate = 0.3, 2.0
    found = chaplygin.steady_motions(
        disk, {"theta": lean, "psi'": rate, "theta'": 0, "phi'": 0.0}, COIN, fixed=["theta", "psi'"]
    )
    numbers = dict(zip((m, r, A, C, g), (COIN[k] for k in "mrACg")))
    closed = float(phid.subs(numbers).subs({Om: rate}).subs({th: lean}))
    assert found.point["phi'"] == pytest.approx(closed, rel=1e-12) and found.family_dimension == 2
    assert "held fixed: theta, psi&#x27;" in found._repr_html_()
    # the relation's steady turns along the turning rate: each is accepted as steady (to 1e-8)
    relation = sp.lambdify((Om, th), phid.subs(numbers))
    turns = chaplygin.root_locus(
        disk,
        {},
        "psi'",
        [1.5, 3.0, 6.0],
        COIN,
        points=lambda w: {"theta": lean, "theta'": 0, "phi'": relation(w, lean)},
    )
    assert turns.eigenvalues.shape == (3, 4) and turns.parameter == "psi'"


# ---------------------------------------------------------------- the rattleback
def test_rattleback_spin_locus_against_newton_euler() -> None:
    from test_bodies import KL, _growth_newton_euler

    body = examples.rattleback()
    params = examples.get("rattleback").parameters
    assert params == KL
    spins = np.array([-5.0, -1.0, 1.0, 5.0, -30.0, -300.0])
    locus = chaplygin.root_locus(
        body, {"theta": 0, "phi": 0, "theta'": 0, "phi'": 0}, "psi'", spins, params, model="chaplygin"
    )
    growth = locus.eigenvalues[:, 0].real
    expected = [_growth_newton_euler(n, KL["D"]) for n in spins]
    np.testing.assert_allclose(growth, expected, rtol=1e-4)
    # reversibility: the spin -n has the eigenvalues of n with their signs changed
    for k in range(2):
        np.testing.assert_allclose(
            np.sort_complex(locus.eigenvalues[k]), np.sort_complex(-locus.eigenvalues[3 - k]), atol=1e-8
        )
    assert growth[3] > 5 * growth[0] > 0  # n D > 0 grows ten times faster
    # Kane & Levinson's rattleback: the slow sense is not stable either, even spun fast
    assert locus.kinds == ["unstable"] * 6 and growth[5] < growth[4]
    chetaev = chaplygin.stability(body, {"theta": 0, "phi": 0, "theta'": 0, "phi'": 0, "psi'": 5.0}, params)
    np.testing.assert_allclose(chetaev.eigenvalues, locus.eigenvalues[3], rtol=1e-8, atol=1e-8)


# ---------------------------------------------------------------- bad input
def test_bad_points_are_named() -> None:
    sleigh = examples.chaplygin_sleigh()
    with pytest.raises(InputError, match=r"missing x'"):
        chaplygin.stability(sleigh, {"theta": 0, "theta'": 0}, SLEIGH)
    with pytest.raises(InputError, match=r"not a steady motion .* rate of theta is 0.5"):
        chaplygin.stability(sleigh, {"theta": 0, "x'": 1, "theta'": 0.5}, SLEIGH)
    with pytest.raises(InputError, match=r"'speed' is not a variable"):
        chaplygin.stability(sleigh, {"theta": 0, "x'": 1, "theta'": 0, "speed": 1}, SLEIGH)
    with pytest.raises(InputError, match=r"parameters: a = 'big' is not a number"):
        chaplygin.stability(sleigh, {"theta": 0, "x'": 1, "theta'": 0}, {**SLEIGH, "a": "big"})
    with pytest.raises(InputError, match=r"no value for a"):
        chaplygin.stability(sleigh, {"theta": 0, "x'": 1, "theta'": 0}, {"m": 1, "I": 1})
    with pytest.raises(InputError, match=r"y' = 3 violates the constraints"):
        chaplygin.stability(sleigh, {"theta": 0, "x'": 1, "theta'": 0, "y'": 3}, SLEIGH)
    with pytest.raises(InputError, match=r"cannot be solved there \(a pole"):
        chaplygin.stability(sleigh, {"theta": np.pi / 2, "x'": 1, "theta'": 0}, SLEIGH)
    with pytest.raises(ChaplyginError, match=r"no steady motion .* near the guess"):
        chaplygin.steady_motions(sleigh, {"theta": 0, "x'": 1, "theta'": 0.5}, SLEIGH, fixed=["x'", "theta'"])
    with pytest.raises(InputError, match=r"values: give numbers for x'"):
        chaplygin.root_locus(sleigh, {"theta": 0, "theta'": 0}, "x'", ["fast"], SLEIGH)
    with pytest.raises(InputError, match=r"rtol = 0: give a number between 0 and 1"):
        chaplygin.stability(sleigh, {"theta": 0, "x'": 1, "theta'": 0}, SLEIGH, rtol=0)
    with pytest.raises(InputError, match=r"point: phi' = 'w': give a number or a SymPy expression"):
        chaplygin.stability_conditions(
            examples.rolling_disk(), {"theta": 0, "psi'": 0, "theta'": 0, "phi'": "w"}
        )
    x = dynamicsymbols("x")
    forced = chaplygin.System([x], x.diff(t) ** 2 / 2, {}, potential_energy=x * sp.cos(t))
    with pytest.raises(ChaplyginError, match="explicitly on the time"):
        chaplygin.linearize(forced, "chetaev", {})


# ---------------------------------------------------------------- holonomic relations
def _cartesian_pendulum() -> chaplygin.System:
    """A pendulum of length L = 2 in Cartesian coordinates: x² + y² = L², y dependent."""
    x, y = dynamicsymbols("x y")
    m, g = sp.symbols("m g", positive=True)
    L = 2
    T = m / 2 * (x.diff(t) ** 2 + y.diff(t) ** 2)
    return chaplygin.System([x, y], T, [], potential_energy=m * g * y, holonomic={y: x**2 + y**2 - L**2})


@pytest.mark.parametrize("model", ["chetaev", "voronets", "vakonomic"])
def test_holonomic_relation_eliminates_its_coordinate(model: str) -> None:
    """In the vakonomic model the relation's multiplier enters only as its rate (as Chetaev's λ):
    it is ignorable, moving uniformly at the rate of the tension."""
    pendulum = _cartesian_pendulum()
    params = {"m": 0.5, "g": 9.81}
    hanging = chaplygin.stability(pendulum, {"x": 0, "y": -2.0, "x'": 0}, params, model=model)
    assert hanging.variables == ("x", "x'")
    if model == "vakonomic":
        assert list(hanging.ignorable) == ["mu_1"] and hanging.ignorable["mu_1"] != 0
    omega = np.sqrt(9.81 / 2.0)  # small oscillations of a pendulum
    np.testing.assert_allclose(np.sort_complex(hanging.eigenvalues), [-1j * omega, 1j * omega], rtol=1e-12)
    assert hanging.kind == "linearly stable"
    upside_down = chaplygin.stability(pendulum, {"x": 0, "y": 2.0, "x'": 0}, params, model=model)
    np.testing.assert_allclose(np.sort(upside_down.eigenvalues.real), [-omega, omega], rtol=1e-12)
    assert upside_down.kind == "unstable"


def test_steady_motions_keeps_the_holonomic_coordinate_guess() -> None:
    """The Newton search starts the relation's coordinate from the guess, not from 0, where
    x² + y² = L² has no Newton step (it crashed with numpy's 'SVD did not converge'); the
    spherical pendulum's conical motion has phi'² = g/(L cos θ) (cylindrical rho, phi, z; the
    closed forms by hand from the Lagrangian on the sphere)."""
    found = chaplygin.steady_motions(
        _cartesian_pendulum(), {"x": 0.3, "y": -np.sqrt(4 - 0.09), "x'": 0.1}, {"m": 0.5, "g": 9.81}
    )
    assert abs(found.point["x"]) < 1e-9 and abs(found.point["x'"]) < 1e-9
    rho, phi, z = dynamicsymbols("rho phi z")
    m, g = sp.symbols("m g", positive=True)
    T = m / 2 * (rho.diff(t) ** 2 + rho**2 * phi.diff(t) ** 2 + z.diff(t) ** 2)
    conical = chaplygin.System(
        [rho, phi, z], T, [], potential_energy=m * g * z, holonomic={z: rho**2 + z**2 - 1}
    )
    for model in ("chetaev", "voronets"):
        found = chaplygin.steady_motions(
            conical,
            {"rho": 0.6, "z": -0.8, "rho'": 0, "phi'": 3.0},
            {"m": 1, "g": 9.81},
            model=model,
            fixed=["rho"],
        )
        np.testing.assert_allclose(abs(found.point["phi'"]), np.sqrt(9.81 / 0.8), rtol=1e-10)
        # found.point gives z (stability() solved it from 0 before): small oscillations about the
        # cone at ω² = phi'² (1 + 3 cos² θ), cos θ = 0.8
        result = chaplygin.stability(conical, found.point, {"m": 1, "g": 9.81}, model=model)
        omega = np.sqrt(9.81 / 0.8 * (1 + 3 * 0.8**2))
        np.testing.assert_allclose(_nonzero(result.eigenvalues), [-1j * omega, 1j * omega], rtol=1e-9)
    # a guess's z is a start, not a value to check: z = -0.8 left over from rho = 0.6 at rho = 0.2
    # (refused as 'z = -0.8 violates the holonomic relations'; the command line's --vary --find did that)
    stale = chaplygin.steady_motions(
        conical, {"rho": 0.2, "z": -0.8, "rho'": 0, "phi'": 3.0}, {"m": 1, "g": 9.81}, fixed=["rho"]
    )
    cos = np.sqrt(1 - 0.2**2)
    np.testing.assert_allclose(
        [stale.point["z"], abs(stale.point["phi'"])], [-cos, np.sqrt(9.81 / cos)], rtol=1e-10
    )


# ---------------------------------------------------------------- the vakonomic disk
def test_vakonomic_upright_disk_is_lindelofs() -> None:
    """Lindelöf's threshold ω² > m g r A/(C + m r²)² and frequency (docs/gallery/rolling-disk.md,
    derived there by hand) in the vakonomic model with μ at Lindelöf's values (c = 0)."""
    disk = examples.rolling_disk()
    m, r, A, C, g = (COIN[k] for k in "mrACg")
    critical = np.sqrt(m * g * r * A) / (C + m * r**2)
    for factor in (0.8, 1.3, 2.5):
        spin = factor * critical
        point = {"psi": 0, "theta": 0, "psi'": 0, "theta'": 0, "phi'": spin, "mu_1": -m * r * spin, "mu_2": 0}
        vak = chaplygin.stability(disk, point, COIN, model="vakonomic")
        rate2 = (m * g * r - (C + m * r**2) ** 2 * spin**2 / A) / (A + m * r**2)
        rate = np.sqrt(complex(rate2))
        np.testing.assert_allclose(_nonzero(vak.eigenvalues), np.sort_complex([rate, -rate]), rtol=1e-9)
        assert vak.kind == ("linearly stable" if factor > 1 else "unstable")
        # energy and the vakonomic constants c_1, c_2 are integrals: dI·J = 0 (a check of both)
        assert vak.integrals == {"energy": True, "c_1": True, "c_2": True}
        assert len(vak.zeros) == 5 and not any("not explained" in z for z in vak.zeros)
        lindelof = chaplygin.stability(
            disk, {k: point[k] for k in ("theta", "psi'", "theta'", "phi'")}, COIN, model="lindelof"
        )
        np.testing.assert_allclose(_nonzero(lindelof.eigenvalues), _nonzero(vak.eigenvalues), rtol=1e-9)


def test_sleigh_routh_hurwitz_condition() -> None:
    v = sp.Symbol("v")
    cond = chaplygin.stability_conditions(examples.chaplygin_sleigh(), {"theta": 0, "x'": v, "theta'": 0})
    m, I, a = sp.symbols("m I a", positive=True)
    assert cond.route == "hurwitz" and cond.zero_roots == 2 and len(cond.conditions) == 1
    assert sp.simplify(cond.conditions[0].lhs / (a * v)).is_positive  # a v > 0: the centre of mass leads


def test_caller_integrals_and_displays(tmp_path) -> None:
    sleigh = examples.chaplygin_sleigh()
    m, I, a = SLEIGH["m"], SLEIGH["I"], SLEIGH["a"]

    def energy(state: dict) -> float:  # T on the constraint, by hand
        xd, yd, thd, th = state["x'"], state["y'"], state["theta'"], state["theta"]
        return (
            m / 2 * (xd**2 + yd**2)
            + m * a * thd * (-xd * np.sin(th) + yd * np.cos(th))
            + (I + m * a**2) / 2 * thd**2
        )

    point = {"theta": 0.2, "x'": 1.0, "theta'": 0}
    result = chaplygin.stability(
        sleigh, point, SLEIGH, integrals={"T": energy, "spin": lambda s: s["theta'"]}
    )
    assert result.integrals == {"energy": True, "T": True, "spin": False}
    assert "integral spin: NOT annihilating J" in str(result) and "<pre>" in result._repr_html_()
    assert json.loads(json.dumps(result.to_dict()))["integrals"] == {"energy": True, "T": True, "spin": False}
    locus = chaplygin.root_locus(sleigh, point, "x'", np.linspace(-1, 1, 5), SLEIGH)
    np.testing.assert_allclose(
        locus.eigenvalues.real.min(axis=1)[3:], -m * a * np.array([0.5, 1]) / np.cos(0.2) / (I + m * a**2)
    )
    # at rest, θ' makes a Jordan chain (θ drifts) that no integral explains: the energy's
    # differential vanishes there
    assert locus.kinds == ["unstable"] * 2 + ["undetermined"] + ["asymptotically stable"] * 2
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    locus.plot().savefig(tmp_path / "locus.png")
    assert (tmp_path / "locus.png").stat().st_size > 0
    assert "x' = 0.5" in str(locus)


def test_damped_oscillator_routh_hurwitz() -> None:
    """x'' + c x' + k x = 0: λ² + c λ + k, asymptotically stable iff c > 0 and k > 0 (Hurwitz:
    Δ1 = c, Δ2 = c k)."""
    x = dynamicsymbols("x")
    c, k = sp.symbols("c k", real=True)
    oscillator = chaplygin.System(
        [x], x.diff(t) ** 2 / 2, {}, potential_energy=k * x**2 / 2, forces={x: -c * x.diff(t)}
    )
    cond = chaplygin.stability_conditions(oscillator, {"x": 0, "x'": 0})
    assert cond.route == "hurwitz" and cond.zero_roots == 0
    assert [sp.factor(r.lhs) for r in cond.conditions] == [c, c * k]
    result = chaplygin.stability(oscillator, {"x": 0, "x'": 0}, {"c": 0.5, "k": 4.0})
    np.testing.assert_allclose(np.sort_complex(result.eigenvalues), np.roots([1, 0.5, 4.0])[::-1], rtol=1e-12)
    assert result.kind == "asymptotically stable" and result.integrals == {}


def test_linearisation_is_kept_in_the_disk_cache(monkeypatch, tmp_path) -> None:
    """An equal system linearised again (a new System object, as in a new process) differentiates
    nothing: the generated code comes from the cache of compiled models."""
    from chaplygin.numeric import linearization as module

    monkeypatch.setenv("CHAPLYGIN_CACHE", str(tmp_path))
    monkeypatch.delenv("CHAPLYGIN_MODEL_CACHE", raising=False)
    point = {"theta": 0.2, "x'": 1.0, "theta'": 0.1}
    first = chaplygin.linearize(examples.chaplygin_sleigh(), "chetaev", SLEIGH)
    expected = first.reduced(first.state_at(point))

    def differentiate(eqs):
        raise AssertionError("differentiated again")

    monkeypatch.setattr(module, "_linearisation_source", differentiate)
    again = chaplygin.linearize(examples.chaplygin_sleigh(), "chetaev", SLEIGH)
    for a, b in zip(again.reduced(again.state_at(point)), expected):
        np.testing.assert_array_equal(a, b)
