"""The gallery's constraints nonlinear in the velocities against closed forms derived by hand.

Appell's weight (``ż² = k² (ẋ² + ẏ²)``, ``V = m g z``) and the isokinetic particle
(``ẋ² + ẏ² = v²``, ``V = m g y``): the derivations are on their gallery pages
(``docs/gallery/appell-weight.md``, ``docs/gallery/isokinetic-particle.md``) and in
``docs/nonlinear-constraints.md``. Every expected value below is one of those closed forms,
typed here, never an output of chaplygin: the symbolic checks put the closed forms into the
derived equations (exactly, with SymPy), the simulations compare runs with them to the
run's tolerance.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols

from chaplygin import ModelError, System, examples, simulate
from chaplygin.numeric import _cfill

t = dynamicsymbols._t
x, y, z = dynamicsymbols("x y z")
m, g, k, v = sp.symbols("m g k v", positive=True)
xd, yd, zd = (q.diff(t) for q in (x, y, z))
xdd, ydd, zdd = (q.diff(t, 2) for q in (x, y, z))
SPEED = sp.sqrt(xd**2 + yd**2)  # Appell's horizontal speed

try:
    _cfill.compiler()
    HAVE_CC = True
except _cfill.Unavailable:
    HAVE_CC = False
BACKENDS = ["numpy", pytest.param("c", marks=pytest.mark.skipif(not HAVE_CC, reason="no C compiler"))]


def zero(expr: sp.Expr) -> bool:
    return sp.simplify(expr) == 0


# ============================================================================ Appell's weight
def appell_closed_form(sigma: int) -> dict[str, sp.Expr]:
    """The true motion by hand (the page's derivation): ``v̇ = −σ g k/(1 + k²)`` along a fixed
    horizontal direction, ``z̈ = −g k²/(1 + k²)``, ``λ = m g/(1 + k²)`` for ``f = ż − σ k v``."""
    return {"vdot": -sigma * g * k / (1 + k**2), "zdd": -g * k**2 / (1 + k**2), "lam": m * g / (1 + k**2)}


@pytest.mark.parametrize("rising", [False, True])
def test_appell_true_accelerations_are_the_closed_form(rising: bool) -> None:
    """Chetaev's model, its multiplier and Novoselov's equations (Voronets-type, classic and new)
    against the closed form, on the branch ``ż = σ k v`` (σ = −1 falling, +1 rising)."""
    sigma = 1 if rising else -1
    s = examples.appell_weight(rising=rising)
    assert s.is_nonlinear and not s.is_affine and s.constraints == {zd: sigma * k * SPEED}
    on = {zd: sigma * k * SPEED}
    truth = appell_closed_form(sigma)
    chetaev = s.equations("chetaev")
    acc = chetaev.accelerations
    # the horizontal acceleration is along the velocity (a straight path) at the rate v̇
    assert zero(acc[xdd].xreplace(on) - truth["vdot"] * xd / SPEED)
    assert zero(acc[ydd].xreplace(on) - truth["vdot"] * yd / SPEED)
    assert zero(acc[zdd].xreplace(on) - truth["zdd"])
    # the constraint force R = λ ∂f/∂q̇ for f = ż − σ k v: (−σ k ẋ/v, −σ k ẏ/v, 1) m g/(1 + k²)
    (lam,) = chetaev.multipliers
    forces = {q: r.xreplace({lam: acc[lam]}).xreplace(on) for q, r in chetaev.constraint_forces().items()}
    expected = {x: -sigma * k * xd / SPEED, y: -sigma * k * yd / SPEED, z: sp.Integer(1)}
    assert all(zero(forces[q] - truth["lam"] * expected[q]) for q in (x, y, z))
    assert zero(chetaev.power().xreplace({lam: acc[lam]}))  # φ homogeneous of degree 1: no work
    for form in ("classic", "new"):  # V depends on z: Voronets-type (Novoselov's equations)
        reduced = s.equations("voronets", form=form).accelerations
        assert zero(reduced[xdd] - truth["vdot"] * xd / SPEED), form
        assert zero(reduced[ydd] - truth["vdot"] * yd / SPEED), form


def test_appell_implicit_and_solved_forms_give_one_motion() -> None:
    """``f = ż² − k² v²`` (the constructor) and ``f = ż + k v`` (solved) differ by the factor
    ``h = ż − k v ≠ 0`` on the branch: the Appell–Chetaev condition, and the motion, are one."""
    solved = System(
        [x, y, z], m / 2 * (xd**2 + yd**2 + zd**2), {zd: -k * SPEED}, potential_energy=m * g * z
    ).equations("chetaev")
    implicit = examples.appell_weight().equations("chetaev")
    on = {zd: -k * SPEED}
    for q in (xdd, ydd, zdd):
        assert zero((implicit.accelerations[q] - solved.accelerations[q]).xreplace(on))


@pytest.mark.parametrize("rising", [False, True])
def test_appell_vakonomic_motion_is_the_true_one_for_every_mu(rising: bool) -> None:
    """For ``L + μ f`` with ``f = ż² − k² v²`` the accelerations do not contain μ on the
    constraints and are Chetaev's; ``μ = M/(2 σ k v)`` with ``Ṁ = −m g/(1 + k²)`` (the page's
    multiplier M of ``f = ż − σ k v``), i.e. ``μ̇ = σ g (2 k² μ − m)/(2 k v (1 + k²))``."""
    sigma = 1 if rising else -1
    s = examples.appell_weight(rising=rising)
    vak = s.equations("vakonomic")
    (mu,) = vak.multipliers
    on = {zd: sigma * k * SPEED}
    true_acc = s.equations("chetaev").accelerations
    for q in (xdd, ydd, zdd):
        here = vak.accelerations[q].xreplace(on)
        assert zero(here - true_acc[q].xreplace(on)), q
        assert not sp.simplify(here).has(mu), q
    w = sp.Symbol("w", positive=True)  # the speed
    mudot = sigma * g * (2 * k**2 * mu - m) / (2 * k * w * (1 + k**2))
    assert zero(vak.accelerations[mu.diff(t)].xreplace(on) - mudot.subs(w, SPEED))
    # the same from M: μ(t) = (M0 − m g t/(1 + k²))/(2 σ k v(t)), v(t) = v0 − σ g k t/(1 + k²)
    M0, v0, tau = sp.symbols("M0 v0 tau")
    v_t = v0 - sigma * g * k * tau / (1 + k**2)
    mu_t = (M0 - m * g * tau / (1 + k**2)) / (2 * sigma * k * v_t)
    assert zero(sp.diff(mu_t, tau) - mudot.xreplace({mu: mu_t, w: v_t}))


@pytest.mark.parametrize("backend", BACKENDS)
def test_appell_run_is_the_closed_form(backend: str) -> None:
    """The catalogue's weight falls (σ = −1): a straight path, ``v = v0 + g k t/(1 + k²)``,
    ``z = −k (v0 t + ½ g k t²/(1 + k²))``, to the run's tolerance (rtol 1e-10)."""
    entry = examples.get("appell-weight")
    G, K = entry.parameters["g"], entry.parameters["k"]
    run = simulate(
        entry.system(), "chetaev", 3.0, entry.initial, entry.parameters, samples=31, backend=backend
    )
    assert run.success and run.backend == backend
    ux, uy = entry.initial["x'"], entry.initial["y'"]
    v0 = np.hypot(ux, uy)
    speed = v0 + G * K * run.t / (1 + K**2)
    travelled = v0 * run.t + G * K * run.t**2 / (2 * (1 + K**2))
    assert np.allclose(np.hypot(run["x'"], run["y'"]), speed, rtol=1e-8, atol=0)
    assert np.allclose(run["x"], ux / v0 * travelled, rtol=1e-8, atol=1e-10)
    assert np.allclose(run["y"], uy / v0 * travelled, rtol=1e-8, atol=1e-10)
    assert np.allclose(run["z"], -K * travelled, rtol=1e-8, atol=1e-10)
    assert run.energy_drift() < 1e-9  # the constraint force does no work


def test_appell_rising_weight_slows_the_wheel_to_the_branch_point() -> None:
    """σ = +1: ``v = v0 − g k t/(1 + k²)`` reaches the branch point v = 0 at
    ``t* = v0 (1 + k²)/(g k)`` (0.2548 s here); the run to 0.25 s follows it."""
    entry = examples.get("appell-weight")
    G, K = entry.parameters["g"], entry.parameters["k"]
    s = examples.appell_weight(rising=True)
    run = simulate(s, "chetaev", 0.25, entry.initial, entry.parameters, samples=11)
    assert run.success
    speed = 1.0 - G * K * run.t / (1 + K**2)  # v0 = 1
    assert speed[-1] < 0.02  # close to the branch point
    assert np.allclose(np.hypot(run["x'"], run["y'"]), speed, rtol=1e-7, atol=1e-9)
    assert np.allclose(run["z'"], K * speed, rtol=1e-7, atol=1e-9)


def test_appell_vakonomic_run_is_the_true_one() -> None:
    """From μ(0) = 0, −1, 5 (not the degenerate m/(2k²) = 2) the vakonomic run is the true one."""
    entry = examples.get("appell-weight")
    s = entry.system()
    true = simulate(s, "chetaev", 3.0, entry.initial, entry.parameters, samples=31)
    for mu0 in (0.0, -1.0, 5.0):
        run = simulate(s, "vakonomic", 3.0, entry.initial, entry.parameters, samples=31, multipliers=[mu0])
        assert run.success, run.message
        for name in ("x", "y", "z"):
            assert np.allclose(run[name], true[name], rtol=1e-8, atol=1e-10), (mu0, name)


# ============================================================================ isokinetic particle
def grim_reaper(theta0: sp.Expr, theta: sp.Expr) -> tuple[sp.Expr, sp.Expr]:
    """The true path from the origin by hand: with the velocity's angle θ (θ̇ = −(g/v) cos θ),
    ``x = a (θ0 − θ)``, ``y = a ln(cos θ/cos θ0)``, ``a = v²/g``."""
    a = v**2 / g
    return a * (theta0 - theta), a * sp.log(sp.cos(theta) / sp.cos(theta0))


def test_isokinetic_true_accelerations_are_the_closed_form() -> None:
    """Gauss's thermostat: the force along the velocity, ``λ' = m g ẏ/v²`` removes gravity's
    work, ``ÿ = −g ẋ²/v²``, ``ẍ = g ẋ ẏ/v²``; Novoselov's (Chaplygin-type) equations
    ``ÿ = −g (1 − ẏ²/v²)``; the power ``m g ẏ``."""
    s = examples.isokinetic_particle()
    assert s.is_nonlinear and s.is_affine and s.constraints == {xd: sp.sqrt(v**2 - yd**2)}
    on = {xd: sp.sqrt(v**2 - yd**2)}
    chetaev = s.equations("chetaev")
    acc = chetaev.accelerations
    assert zero((acc[xdd] - g * xd * yd / v**2).xreplace(on))
    assert zero(acc[ydd].xreplace(on) - (-g * (v**2 - yd**2) / v**2))
    (lam,) = chetaev.multipliers
    assert zero(chetaev.power().xreplace({lam: acc[lam]}).xreplace(on) - m * g * yd)
    for model in ("chaplygin", "voronets"):
        for form in ("classic", "new"):
            reduced = s.equations(model, form=form).accelerations
            assert zero(reduced[ydd] + g * (1 - yd**2 / v**2)), (model, form)
    # the path: θ̇ = −(g/v) cos θ and the grim reaper's ẋ = v cos θ, ẏ = v sin θ satisfy ÿ
    theta0, th = sp.symbols("theta0 theta")
    px, py = grim_reaper(theta0, th)
    theta_dot = -g / v * sp.cos(th)
    assert zero(sp.diff(px, th) * theta_dot - v * sp.cos(th)) and zero(
        sp.diff(py, th) * theta_dot - v * sp.sin(th)
    )
    assert zero(sp.diff(v * sp.sin(th), th) * theta_dot - (-g * (v**2 - (v * sp.sin(th)) ** 2) / v**2))
    # and it is y = y0 + a ln cos((x − x0)/a) with x0 = a θ0, y0 = −a ln cos θ0
    a = v**2 / g
    assert zero(
        sp.expand_log(
            py - (-a * sp.log(sp.cos(theta0)) + a * sp.log(sp.cos((px - a * theta0) / a))), force=True
        )
    )


def catenary(c: sp.Expr, p0: sp.Expr, tau: sp.Expr) -> dict[str, sp.Expr]:
    """The vakonomic motion with ``(m + 2μ) ẋ = c`` by hand: ``p = p0 − m g t`` the y-momentum
    ``(m + 2μ) ẏ``, the velocity ``v (c, p)/√(c² + p²)``; from the origin
    ``x = −A (asinh(p/c) − asinh(p0/c))``, ``y = −A (√(1 + p²/c²) − √(1 + p0²/c²))``,
    ``A = v c/(m g)``: ``y = y1 − A cosh((x − x1)/A)``."""
    p = p0 - m * g * tau
    A = v * c / (m * g)
    return {
        "x": -A * (sp.asinh(p / c) - sp.asinh(p0 / c)),
        "y": -A * (sp.sqrt(1 + p**2 / c**2) - sp.sqrt(1 + p0**2 / c**2)),
        "mu": (sp.sqrt(c**2 + p**2) / v - m) / 2,
        "A": A,
    }


def test_isokinetic_vakonomic_motions_are_catenaries() -> None:
    """The closed-form catenary, put into the derived vakonomic multiplier equations and into the
    family's ``ÿ = −(m g/c)(v² − ẏ²)^{3/2}/v²``, satisfies them exactly; Lindelöf's equations
    (the member c = 0, ``T̃ = ½ m v²`` constant) are refused."""
    s = examples.isokinetic_particle()
    c, p0, tau = sp.symbols("c p0 tau", positive=True)
    sol = catenary(c, p0, tau)
    velocity = {xd: sp.diff(sol["x"], tau), yd: sp.diff(sol["y"], tau)}
    assert zero(velocity[xd] ** 2 + velocity[yd] ** 2 - v**2)  # on the constraint
    assert zero((m + 2 * sol["mu"]) * velocity[xd] - c)  # the family's constant
    vak = s.equations("vakonomic")
    (mu,) = vak.multipliers
    state = {**velocity, mu: sol["mu"]}
    assert zero(vak.accelerations[xdd].xreplace(state) - sp.diff(sol["x"], tau, 2))
    assert zero(vak.accelerations[ydd].xreplace(state) - sp.diff(sol["y"], tau, 2))
    assert zero(vak.accelerations[mu.diff(t)].xreplace(state) - sp.diff(sol["mu"], tau))
    family = s.equations("vakonomic_family")
    (c1,) = family.constants
    expected = -(m * g / c1) * (v**2 - yd**2) ** sp.Rational(3, 2) / v**2
    assert zero(family.accelerations[ydd] - expected)
    assert zero(expected.xreplace({c1: c, yd: velocity[yd]}) - sp.diff(sol["y"], tau, 2))
    # the path is the catenary y = y1 − A cosh((x − x1)/A), x1 = A asinh(p0/c), y1 = A √(1 + p0²/c²)
    A = sol["A"]
    x1, y1 = A * sp.asinh(p0 / c), A * sp.sqrt(1 + p0**2 / c**2)
    assert zero(sp.simplify(sol["y"] - (y1 - A * sp.cosh((sol["x"] - x1) / A))).rewrite(sp.exp))
    with pytest.raises(ModelError, match=r"T̃ = m\*v\*\*2/2 .* is degenerate in the independent velocities"):
        s.equations("lindelof").accelerations  # noqa: B018


def path_error(run, a: float) -> float:
    """Largest distance in y of the run from the grim reaper through its start."""
    theta0 = np.arctan2(run["y'"][0], run["x'"][0])
    x0, y0 = run["x"][0] + a * theta0, run["y"][0] - a * np.log(np.cos(theta0))
    return float(np.max(np.abs(run["y"] - (y0 + a * np.log(np.cos((run["x"] - x0) / a))))))


@pytest.mark.parametrize("backend", BACKENDS)
def test_isokinetic_true_run_follows_the_grim_reaper(backend: str) -> None:
    """The catalogue's run 0 ≤ t ≤ 20 keeps the speed v and stays on y = y0 + a ln cos((x − x0)/a)."""
    entry = examples.get("isokinetic-particle")
    G, V = entry.parameters["g"], entry.parameters["v"]
    run = simulate(
        entry.system(), "chetaev", 20.0, entry.initial, entry.parameters, samples=41, backend=backend
    )
    assert run.success and run.backend == backend
    assert np.allclose(np.hypot(run["x'"], run["y'"]), V, rtol=1e-9, atol=0)
    assert path_error(run, V**2 / G) < 1e-8
    assert np.min(run["y'"]) < -0.8 * V  # bent well round: the check is not of a straight line
    # the time law: θ̇ = −(g/v) cos θ gives gd⁻¹(θ) = gd⁻¹(θ0) − g t/v
    theta = np.arctan2(run["y'"], run["x'"])
    assert np.allclose(np.arctanh(np.sin(theta)), np.arctanh(np.sin(theta[0])) - G * run.t / V, atol=1e-8)


@pytest.mark.parametrize("mu0", [0.0, 0.7])
def test_isokinetic_vakonomic_run_follows_the_catenary(mu0: float) -> None:
    """From μ(0): c = (m + 2 μ(0)) ẋ(0), the run stays on y = y1 − A cosh((x − x1)/A), A = v c/(m g)."""
    entry = examples.get("isokinetic-particle")
    M, G, V = (entry.parameters[n] for n in ("m", "g", "v"))
    run = simulate(
        entry.system(), "vakonomic", 20.0, entry.initial, entry.parameters, samples=41, multipliers=[mu0]
    )
    assert run.success, run.message
    c = (M + 2 * mu0) * np.sqrt(V**2 - entry.initial["y'"] ** 2)
    A = V * c / (M * G)
    p0 = (M + 2 * mu0) * entry.initial["y'"]  # the y-momentum (m + 2μ) ẏ
    x1, y1 = A * np.arcsinh(p0 / c), A * np.sqrt(1 + (p0 / c) ** 2)
    assert np.allclose(run["y"], y1 - A * np.cosh((run["x"] - x1) / A), atol=1e-8)
    assert path_error(run, V**2 / G) > 0.1  # not the true motion's path
