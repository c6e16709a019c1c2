"""Rolling bodies built from their shape (chaplygin.bodies), each against an independent oracle:
the hand-written gallery systems, the multiplier systems, integrals from the literature, and a
Newton–Euler model of the rattleback written here with NumPy."""

from __future__ import annotations

import re

import numpy as np
import pytest
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols

import chaplygin
from chaplygin import InputError, SystemDefinitionError, examples, simulate
from chaplygin.bodies import (
    Disk,
    Ellipsoid,
    Paraboloid,
    Revolution,
    Sphere,
    SupportFunction,
    Torus,
    initial_state,
    motion,
    rolling_body,
)
from randomsystems import matrix, number, numbers, random_state

t = dynamicsymbols._t


def rot(axis: str, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return {
        "x": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
        "y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
        "z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]),
    }[axis]


# ---------------------------------------------------------------- identity with the gallery
def test_sphere_is_the_papers_sphere() -> None:
    m, a = sp.symbols("m a", positive=True)
    built = rolling_body(Sphere(a), mass=m, inertia=[2 * m * a**2 / 5] * 3, angles="euler")
    paper = examples.rolling_sphere()
    assert built.is_chaplygin and [q.name for q in built.coordinates] == ["psi", "theta", "phi", "x", "y"]
    # Same coordinates (z-x-z Euler angles, the centre's x, y): the constraints are the paper's (41)-(42) ...
    for vel, rhs in paper.constraints.items():
        assert sp.simplify(built.constraints[vel] - rhs) == 0
    # ... and the reduced equations are the same dynamics.
    report = chaplygin.equivalent(
        paper, paper.equations("chaplygin"), list(built.equations("chaplygin").equations)
    )
    assert report, report


def test_disk_is_the_gallery_disk() -> None:
    m, r, A, C, g = sp.symbols("m r A C g", positive=True)
    built = rolling_body(Disk(r), mass=m, inertia=[A, A, C], g=g)
    disk = examples.rolling_disk()
    psi, theta, _phi, x, y = disk.coordinates
    assert built.angles == "edge" and built.is_chaplygin
    assert sp.simplify(built.potential_energy - disk.potential_energy) == 0
    # The gallery's x, y are the contact point, the builder's the centre: x_G = x + r sinθ sinψ,
    # y_G = y − r sinθ cosψ (the gallery's docstring). Map the velocities by hand.
    shift = {x: r * sp.sin(theta) * sp.sin(psi), y: -r * sp.sin(theta) * sp.cos(psi)}
    for q in (x, y):
        expected = disk.constraints[q.diff(t)] + shift[q].diff(t)
        assert sp.simplify(built.constraints[q.diff(t)] - expected) == 0
    # The reduced equations contain only ψ, θ, φ: same accelerations at matched states.
    report = chaplygin.equivalent(
        disk, disk.equations("chaplygin"), list(built.equations("chaplygin").equations)
    )
    assert report, report


def test_general_shapes_reduce_to_the_special_ones() -> None:
    """Revolution and SupportFunction, given a sphere and an ellipsoid, build the same systems."""
    r = sp.Symbol("r", positive=True)
    inertia, com = [1, 1, sp.Rational(3, 2)], (0, 0, -sp.Rational(1, 5))
    sphere = rolling_body(Sphere(r), mass=1, inertia=inertia, center_of_mass=com)
    revolution = rolling_body(
        Revolution(lambda alpha: r + 0 * alpha), mass=1, inertia=inertia, center_of_mass=com
    )
    assert chaplygin.equivalent(
        sphere, sphere.equations("chaplygin"), list(revolution.equations("chaplygin").equations)
    )
    a, b, c = 3, 2, 1
    ellipsoid = rolling_body(Ellipsoid(a, b, c), mass=1, inertia=[2, 3, 4])
    h = SupportFunction(lambda u1, u2, u3: sp.sqrt(a**2 * u1**2 + b**2 * u2**2 + c**2 * u3**2))
    general = rolling_body(h, mass=1, inertia=[2, 3, 4])
    assert chaplygin.equivalent(
        ellipsoid, ellipsoid.equations("chaplygin"), list(general.equations("chaplygin").equations)
    )


# ---------------------------------------------------------------- reduced forms vs multipliers
@pytest.fixture(scope="module")
def torus() -> chaplygin.System:
    """A rounded disk with an off-centre centre of mass and a full inertia tensor: nothing special."""
    I = [[3, sp.Rational(1, 5), 0], [sp.Rational(1, 5), 2, sp.Rational(1, 10)], [0, sp.Rational(1, 10), 4]]
    return rolling_body(
        Torus(1, sp.Rational(1, 4)),
        mass=2,
        inertia=I,
        center_of_mass=(sp.Rational(1, 10), 0, sp.Rational(1, 20)),
        g=sp.Rational(981, 100),
    )


def _solve(eqs, values) -> dict:
    x = np.linalg.solve(matrix(eqs.mass_matrix, values), matrix(eqs.forcing, values)[:, 0])
    return dict(zip(eqs.unknowns, x))


def _difference(system, first, second, multipliers: dict | None = None, states: int = 6) -> float:
    """Largest relative difference |a − b| / max(1, |a|, |b|) of an independent acceleration of
    two sets of equations over random admissible states (equivalent()'s measure, the tests'
    evaluator); ``multipliers``: the state multipliers μ as expressions of the state."""
    rng = np.random.default_rng(6)
    independent = [q.diff(t, 2) for q in system.independent]
    worst = 0.0
    for _ in range(states):
        values = random_state(system, rng)
        values.update({m: sp.Float(number(e, values)) for m, e in (multipliers or {}).items()})
        a, b = _solve(first, values), _solve(second, values)
        for acc in independent:
            worst = max(worst, abs(a[acc] - b[acc]) / max(1.0, abs(a[acc]), abs(b[acc])))
    return worst


def test_reduced_forms_match_the_multiplier_systems(torus) -> None:
    rng = np.random.default_rng(18)
    for _ in range(3):
        values = random_state(torus, rng)
        truth = _solve(torus.equations("chetaev"), values)
        for model, form in [("chaplygin", "classic"), ("chaplygin", "new"), ("voronets", "classic")]:
            for acc, value in _solve(torus.equations(model, form), values).items():
                assert value == pytest.approx(truth[acc], rel=1e-8, abs=1e-8), (model, form, acc)
    # Lindelöf's equations (22) are the vakonomic multiplier system with μ = −∂T/∂q̇_dep (c = 0).
    lindelof, vakonomic = torus.equations("lindelof"), torus.equations("vakonomic")
    assert _difference(torus, lindelof, vakonomic, torus.integrated_multipliers([0, 0])) <= 1e-8


@pytest.mark.parametrize("form", ["classic", "new"])
def test_vakonomic_family_matches_the_vakonomic_multiplier_system(torus, form) -> None:
    """Every member of the reduced family (nonzero constants too, both forms) is the vakonomic
    multiplier system (17)-(18) with μ_β = c_β − ∂T/∂q̇_dep, at constraint-satisfying states."""
    vakonomic = torus.equations("vakonomic")
    for c in ([0, 0], [sp.Rational(3, 10), -sp.Rational(1, 5)]):
        model = "lindelof" if c == [0, 0] else "vakonomic_family"
        reduced = torus.equations(model, form, constants=None if model == "lindelof" else c)
        assert _difference(torus, reduced, vakonomic, torus.integrated_multipliers(c)) <= 1e-8, (model, c)
    # the test can fail: the family member with other constants is another motion
    other = torus.equations("vakonomic_family", form, constants=[sp.Rational(3, 10), -sp.Rational(1, 5)])
    assert _difference(torus, other, vakonomic, torus.integrated_multipliers([0, 0])) > 1e-8


# ---------------------------------------------------------------- Routh's sphere
def test_routh_sphere_keeps_energy_jellett_and_routh() -> None:
    """Sphere of radius r, centre of mass a below the centre on the axis, moments A, A, C.

    Jellett: J = (I ω)·s, Routh: ω₃ √(A C + m A (s₁² + s₂²) + m C s₃²), with s = rγ − a e₃ the vector
    from the contact point to the centre of mass and γ the upward vertical, all in body axes
    (Gray & Nickel 2000; Lynch & Bustamante 2009)."""
    r, a, m, A, C = 1.0, 0.3, 1.0, 0.4, 0.6
    body = rolling_body(Sphere(r), mass=m, inertia=[A, A, C], center_of_mass=(0, 0, -a), g=9.81)
    R0 = rot("x", 0.5) @ rot("y", 0.2)
    run = simulate(
        body, "chaplygin", 10.0, initial_state(body, R=R0, omega=[1.0, -0.5, 4.0]), {}, samples=201
    )
    assert run.success
    mo = motion(body, run)
    gamma = mo.R[:, 2, :]
    s = r * gamma - np.array([0, 0, a])
    jellett = np.einsum("ki,ki->k", mo.omega * [A, A, C], s)
    routh = mo.omega[:, 2] * np.sqrt(A * C + m * A * (s[:, 0] ** 2 + s[:, 1] ** 2) + m * C * s[:, 2] ** 2)
    assert np.ptp(jellett) < 1e-8 * np.max(np.abs(jellett))
    assert np.ptp(routh) < 1e-8 * np.max(np.abs(routh))
    assert np.ptp(mo.omega[:, 2]) > 1e-3  # ω₃ alone is not conserved: the test can fail
    assert run.energy_drift() < 1e-9
    assert np.max(np.abs(mo.contact[:, 2])) < 1e-12
    np.testing.assert_allclose(mo.R[0], R0, atol=1e-12)
    np.testing.assert_allclose(mo.omega[0], [1.0, -0.5, 4.0], atol=1e-12)


# ---------------------------------------------------------------- the rattleback
KL = {
    "a": 0.2,
    "b": 0.03,
    "c": 0.02,
    "h": 0.01,
    "m": 1.0,
    "A": 2e-4,
    "B": 1.6e-3,
    "C": 1.7e-3,
    "D": 2e-5,
    "g": 9.81,
}
"""Kane & Levinson (1982): ellipsoid semi-axes a, b, c; the centre of mass h below the centre;
central moments A, B, C per unit mass and the product D (here in axes with z up, obtained from
theirs, z down, by a half turn about x, which flips the sign of the xy product)."""


def _rattleback(D: float) -> chaplygin.System:
    p = KL
    I = [[p["A"], D, 0], [D, p["B"], 0], [0, 0, p["C"]]]
    return rolling_body(
        Ellipsoid(p["a"], p["b"], p["c"]), mass=p["m"], inertia=I, center_of_mass=(0, 0, -p["h"]), g=p["g"]
    )


@pytest.fixture(scope="module")
def rattleback() -> chaplygin.System:
    return _rattleback(KL["D"])


def _vertical_spin(body, spin: float, t_end: float):
    start = initial_state(body, R=rot("x", 0.01) @ rot("y", 0.01), omega=[0.0, 0.0, spin])
    run = simulate(body, "chaplygin", t_end, start, {}, samples=int(40 * t_end) + 1)
    mo = motion(body, run)
    return run, np.einsum("kij,kj->ki", mo.R, mo.omega)[:, 2]


def test_rattleback_reverses_one_way_only(rattleback) -> None:
    run, wz = _vertical_spin(rattleback, 5.0, 4.0)
    assert run.success and run.energy_drift() <= 1e-9
    assert np.min(wz) < -1.0  # spun counter-clockwise, it turns round
    assert np.argmax(wz < 0) * (run.t[1] - run.t[0]) < 3.0
    run, wz = _vertical_spin(rattleback, -5.0, 6.0)
    assert run.success and run.energy_drift() <= 1e-9
    assert np.all(wz < -2.0)  # clockwise: still clockwise after 6 s


def _newton_euler(state: np.ndarray, D: float, p: dict = KL) -> np.ndarray:
    """γ̇ = γ × ω, and the rolling rigid body about the contact point (Borisov & Mamaev 2002):
    [I + m(|r|² − r rᵀ)] ω̇ = −ω × Iω − m r × (ω × ṙ) − m r × (ω × (ω × r)) + m g r × γ,
    r = ∇h(−γ) − c from G to the contact, h the ellipsoid's support function; body axes."""
    gamma, w = state[:3], state[3:]
    A2 = np.array([p["a"], p["b"], p["c"]]) ** 2
    I = np.array([[p["A"], D, 0], [D, p["B"], 0], [0, 0, p["C"]]]) * p["m"]
    m, g, c = p["m"], p["g"], np.array([0, 0, -p["h"]])
    u = -gamma
    h = np.sqrt(A2 @ u**2)
    r = A2 * u / h - c
    hess = np.diag(A2) / h - np.outer(A2 * u, A2 * u) / h**3
    gamma_dot = np.cross(gamma, w)
    r_dot = hess @ (-gamma_dot)
    M = I + m * (r @ r * np.eye(3) - np.outer(r, r))
    rhs = (
        -np.cross(w, I @ w)
        - m * np.cross(r, np.cross(w, r_dot))
        - m * np.cross(r, np.cross(w, np.cross(w, r)))
    )
    rhs += m * g * np.cross(r, gamma)
    return np.concatenate([gamma_dot, np.linalg.solve(M, rhs)])


def _jacobian(f, x: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    return np.column_stack([(f(x + eps * e) - f(x - eps * e)) / (2 * eps) for e in np.eye(x.size)])


def _growth_newton_euler(spin: float, D: float) -> float:
    steady = np.array([0, 0, 1, 0, 0, spin], dtype=float)
    return float(np.max(np.linalg.eigvals(_jacobian(lambda s: _newton_euler(s, D), steady)).real))


def _growth_chaplygin(body, spin: float) -> float:
    """Linearise chaplygin's Chaplygin equations about θ = φ = 0, ψ̇ = spin (ψ is cyclic)."""
    eqs = body.equations("chaplygin")
    psi, theta, phi = body.independent
    state = [theta, phi, psi.diff(t), theta.diff(t), phi.diff(t)]
    order = [list(eqs.unknowns).index(q.diff(t, 2)) for q in (psi, theta, phi)]
    dim = eqs.mass_matrix.rows
    entries = [*eqs.mass_matrix, *eqs.forcing]

    def f(x: np.ndarray) -> np.ndarray:
        # M and F in floats (the tests' evaluator, not chaplygin's code; lambdify took seconds)
        mf = np.array(numbers(entries, {psi: 0.0, **dict(zip(state, x.tolist()))}))
        a = np.linalg.solve(mf[: dim * dim].reshape(dim, dim), mf[dim * dim :])[order]
        return np.array([x[3], x[4], a[0], a[1], a[2]])

    return float(np.max(np.linalg.eigvals(_jacobian(f, np.array([0, 0, spin, 0, 0], dtype=float))).real))


def test_rattleback_growth_rate_matches_newton_euler(rattleback) -> None:
    for spin in (5.0, -5.0, 1.0):
        expected = _growth_newton_euler(spin, KL["D"])
        assert _growth_chaplygin(rattleback, spin) == pytest.approx(expected, rel=1e-4, abs=1e-6)
    # the spin that reverses first in the simulation grows much faster
    assert _growth_newton_euler(5.0, KL["D"]) > 5 * _growth_newton_euler(-5.0, KL["D"]) > 0
    assert abs(_growth_newton_euler(5.0, 0.0)) < 1e-9  # no product of inertia: no preferred sense
    # the mirror rule: the mirror image (y → −y flips D) spun the other way behaves the same
    mirror = _rattleback(-KL["D"])
    assert _growth_chaplygin(mirror, -5.0) == pytest.approx(_growth_newton_euler(5.0, KL["D"]), rel=1e-4)


# ---------------------------------------------------------------- state conversion
def test_initial_state_round_trip_in_every_convention() -> None:
    R0 = rot("z", 0.3) @ rot("x", 0.4) @ rot("y", -0.2)
    w = [0.3, -1.2, 2.0]
    for angles in ("cardan", "edge", "euler"):
        body = rolling_body(Sphere(1), mass=1, inertia=[1, 1, 1], angles=angles, g=1)
        start = initial_state(body, R=R0, omega=w, position=(0.5, -1.0))
        run = simulate(body, "chaplygin", 0.1, start, {}, samples=2)
        mo = motion(body, run)
        np.testing.assert_allclose(mo.R[0], R0, atol=1e-12)
        np.testing.assert_allclose(mo.omega[0], w, atol=1e-12)
        np.testing.assert_allclose(mo.centre[0], [0.5, -1.0, 1.0], atol=1e-12)
        np.testing.assert_allclose(mo.contact[:, 2], 0, atol=1e-12)
        # a homogeneous ball: ω constant in space (Routh 1905)
        np.testing.assert_allclose(mo.R[1] @ mo.omega[1], R0 @ w, atol=1e-9)


# ---------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("build", "message"),
    [
        (lambda: Sphere(-1), "radius"),
        (lambda: Disk(0), "radius"),
        (lambda: Torus(1, "not a name"), "r:"),
        (lambda: Paraboloid(1, sp.Symbol("k", negative=True)), "rho2"),
        (lambda: rolling_body("sphere", mass=1, inertia=[1, 1, 1]), "Sphere, Disk"),
        (lambda: rolling_body(Sphere(1), mass=0, inertia=[1, 1, 1]), "mass"),
        (
            lambda: rolling_body(Sphere(1), mass=1, inertia=[[1, 0.1, 0], [0, 1, 0], [0, 0, 1]]),
            "inertia[1][0]",
        ),
        (
            lambda: rolling_body(Sphere(1), mass=1, inertia=[[1, 2, 0], [2, 1, 0], [0, 0, 1]]),
            "positive definite",
        ),
        (lambda: rolling_body(Sphere(1), mass=1, inertia=[1, 1, 3]), "triangle inequality"),
        (lambda: rolling_body(Sphere(1), mass=1, inertia=[1, 1, 1], center_of_mass=(0, 0, 2)), "outside"),
        (
            lambda: rolling_body(Paraboloid(1, 2), mass=1, inertia=[1, 1, 1], center_of_mass=(1, 0, 0)),
            "outside",
        ),
        (lambda: rolling_body(Sphere(1), mass=1, inertia=[1, 1, 1], angles="zyz"), "angles='zyz'"),
        (lambda: Revolution(lambda al: 1 - sp.cos(al) ** 2 * 3), "not convex"),
        (lambda: SupportFunction(lambda a, b, c: a**2 + b**2 + c**2), "homogeneous"),
        (lambda: SupportFunction(lambda a, b, c: -sp.sqrt(a**2 + b**2 + c**2)), "not convex"),
    ],
)
def test_bad_input_is_refused_with_the_key(build, message) -> None:
    with pytest.raises(SystemDefinitionError, match=re.escape(message)):
        build()


def test_bad_state_input_is_refused() -> None:
    body = rolling_body(Sphere(1), mass=1, inertia=[1, 1, 1], g=1)
    with pytest.raises(InputError, match="not a rotation"):
        initial_state(body, R=2 * np.eye(3), omega=[0, 0, 1])
    with pytest.raises(InputError, match="omega"):
        initial_state(body, R=np.eye(3), omega=[0, 1])
    with pytest.raises(InputError, match="singularity"):
        initial_state(body, R=rot("x", np.pi / 2), omega=[0, 0, 1])
    with pytest.raises(InputError, match="rolling_body"):
        initial_state(examples.rolling_disk(), R=np.eye(3), omega=[0, 0, 1])


def test_a_numeric_centre_of_mass_is_checked_without_lambdify(monkeypatch) -> None:
    """Whether a numeric point lies in an ellipsoid, decided by its support function evaluated in
    SymEngine (``lambdify`` and the NumPy namespace it imports took 0.07 s of the rattleback's
    build), agrees with the closed form ``x²/a² + y²/b² + z²/c² ≤ 1`` on points well inside and
    well outside (the test samples 400 directions)."""
    monkeypatch.setattr(sp, "lambdify", lambda *args, **kwargs: pytest.fail("lambdify called"))
    a, b, c = 0.2, 0.03, 0.02
    rng = np.random.default_rng(5)
    for _ in range(40):
        p = rng.uniform(-1, 1, 3) * (a, b, c) * 1.3
        level = float(np.sum((p / (a, b, c)) ** 2))
        if abs(level - 1) > 0.1:
            assert Ellipsoid(a, b, c).contains(p) is (level < 1)
    with pytest.raises(SystemDefinitionError, match="outside"):
        rolling_body(Ellipsoid(a, b, c), mass=1, inertia=[1, 1, 1], center_of_mass=(0, 0, -0.025))
