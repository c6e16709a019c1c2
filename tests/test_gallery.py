"""Gallery systems against their known physics.

Every fact stated on a gallery page (``docs/gallery/*.md``) is checked here against an
independent oracle: a closed-form solution or a relation derived by hand (Newton–Euler, a
first integral, a linearization), never a number produced by chaplygin itself.  The sources
are cited on the pages and in the constructors' docstrings.
"""

from __future__ import annotations

import random
from functools import cache
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from sympy.core.function import AppliedUndef
from sympy.physics.mechanics import dynamicsymbols

from chaplygin import ModelError, System, compare_models, equivalent, examples, simulate
from chaplygin.apps.report import applicable_models

t = dynamicsymbols._t
ROOT = Path(__file__).resolve().parent.parent


def d(q: sp.Expr) -> sp.Expr:
    return q.diff(t)


def dd(q: sp.Expr) -> sp.Expr:
    return q.diff(t, 2)


def at(expr: sp.Expr, values: dict) -> float:
    """``expr`` at numbers: derivatives are replaced before the coordinates."""
    order = sorted(
        values, key=lambda k: -int(isinstance(k, sp.Derivative)) - int(getattr(k, "derivative_count", 0))
    )
    return float(expr.subs([(k, values[k]) for k in order]))


def vanishes(expr: sp.Expr, points: int = 3) -> bool:
    """Whether ``expr``, a rational function of sines and cosines (and tangents), velocities,
    coordinates and parameters, is identically zero -- decided exactly, without simplify.

    Sums and multiples in the angles are expanded (``expand_trig``); then, at each of
    ``points`` random points, every ``sin a``, ``cos a`` becomes ``2u/(1 + u²)``,
    ``(1 − u²)/(1 + u²)`` for a random rational ``u`` (the half-angle substitution, onto
    the circle but one point), and every other symbol or function of time a random
    rational (positive, for the parameters' assumptions): the value is an exact rational.
    An identity gives 0 at every point. A non-zero expression is a non-zero rational
    function of the values drawn (whatever relations it relies on, such as sin² + cos² = 1,
    hold on the substitution), and such a function vanishes at a random point of a grid of
    10¹² values per variable with probability of order its degree / 10¹².
    """
    e = sp.expand_trig(expr.replace(sp.tan, lambda a: sp.sin(a) / sp.cos(a)))
    rng = random.Random(28)

    def rational(low: int) -> sp.Rational:
        return sp.Rational(rng.randint(low, 10**6), rng.randint(1, 10**6))

    for _ in range(points):
        values: dict[sp.Expr, sp.Expr] = {v: rational(-(10**6)) for v in e.atoms(sp.Derivative)}
        for f in e.atoms(sp.sin, sp.cos):
            if sp.sin(f.args[0]) not in values:
                u = rational(-(10**6))
                values[sp.sin(f.args[0])] = 2 * u / (1 + u**2)
                values[sp.cos(f.args[0])] = (1 - u**2) / (1 + u**2)
        value = e.xreplace(values)
        value = value.xreplace({a: rational(1) for a in value.atoms(sp.Symbol, AppliedUndef)})
        assert value.is_Rational, f"vanishes() cannot evaluate {value} exactly"
        if value != 0:
            return False
    return True


def test_vanishes_decides_identities_exactly() -> None:
    """The oracle of the identities below: true ones pass, ones off by a tiny term do not."""
    a, b = dynamicsymbols("a b")
    m = sp.Symbol("m", positive=True)
    assert vanishes(sp.sin(a) ** 2 + sp.cos(a) ** 2 - 1)
    assert vanishes(sp.sin(a - b) - sp.sin(a) * sp.cos(b) + sp.cos(a) * sp.sin(b))
    assert vanishes(m * (sp.tan(a) * sp.cos(a) ** 2 - sp.sin(2 * a) / 2) * d(a) / (1 + sp.cos(b) ** 2))
    assert not vanishes(sp.sin(a - b) - sp.sin(a) * sp.cos(b))
    assert not vanishes(sp.sin(a) ** 2 + sp.cos(a) ** 2 - 1 + sp.Rational(1, 10**12) * d(b) * a)
    assert not vanishes(m * d(a) ** 2 * (sp.sin(a) ** 2 + sp.cos(a) ** 2) - d(a) ** 2)


@cache
def system(name: str, **parameters: float) -> System:
    """One cached instance per constructor call, so that derivations are shared between tests."""
    return getattr(examples, name)(**parameters)


# ============================================================================ catalogue
GALLERY = [
    "rolling-sphere",
    "knife-edge",
    "vertical-rolling-disk",
    "rolling-disk",
    "chaplygin-sleigh",
    "turntable-ball",
    "chaplygin-ball",
    "heisenberg",
    "contact-oscillator",
    "differential-drive",
    "sleigh-chain",
    "lindelof-problem",
    "routh-sphere",
    "rattleback",
    "appell-weight",
    "isokinetic-particle",
    "whipple-bicycle",
]
#: constraints nonlinear in the velocities: their runs against closed forms are in
#: tests/test_gallery_nonlinear.py (the Chetaev and vakonomic models)
NONLINEAR = ("appell-weight", "isokinetic-particle")


def test_catalogue_is_the_gallery() -> None:
    """Every gallery system is in the catalogue, and has a documentation page."""
    assert list(examples.catalogue()) == GALLERY
    for name in GALLERY:
        assert (ROOT / "docs" / "gallery" / f"{name}.md").is_file(), name
        assert f"gallery/{name}.md" in (ROOT / "docs" / "index.md").read_text(encoding="utf-8")


CHARTS = {  # (low, high, only the reduced forms: the multiplier forms use form A, with no pole)
    "chaplygin-sleigh": {"theta": (-0.5, 0.5, True)},  # ẏ = tan θ ẋ
    "turntable-ball": {"theta": (0.2, np.pi - 0.2, False)},  # z-x-z Euler angles
    "chaplygin-ball": {"theta": (0.3, np.pi - 0.3, False)},
    "sleigh-chain": {"theta0": (-0.5, 0.5, True)},
    # the bodies' angles are singular where cos θ = 0 (docs/bodies.md), in every form
    "lindelof-problem": {"theta": (-np.pi / 2 + 0.2, np.pi / 2 - 0.2, False)},
    "routh-sphere": {"theta": (-np.pi / 2 + 0.2, np.pi / 2 - 0.2, False)},
    "rattleback": {"theta": (-np.pi / 2 + 0.2, np.pi / 2 - 0.2, False)},
}


@pytest.mark.parametrize("name", GALLERY[4:-1])  # bicycle: test_bicycle.py
def test_catalogue_state_simulates_in_every_model(name: str) -> None:
    """The default state runs 0 ≤ t ≤ 20 in every model that applies, inside the chart."""
    entry = examples.get(name)
    s = entry.system()
    models, _ = applicable_models(s)
    assert ("chetaev", "classic") in models and ("vakonomic", "classic") in models
    for model, form in models:
        # (the isokinetic particle's c = 0 is Lindelöf's degenerate member: T̃ is constant)
        vakonomic = model == "vakonomic" or (model == "vakonomic_family" and s.is_nonlinear)
        options = {"constants": "match"} if vakonomic and (not s.is_chaplygin or s.is_nonlinear) else {}
        tr = simulate(s, model, 20.0, entry.initial, entry.parameters, form=form, samples=41, **options)
        assert tr.success, (model, form, tr.message)
        assert np.max(np.abs(tr.constraint_residual)) < 1e-7, (model, form)
        if not s.is_affine:
            assert tr.energy_drift() < 1e-8, (model, form)
        for coordinate, (low, high, reduced_only) in CHARTS.get(name, {}).items():  # away from poles
            if reduced_only and model in ("chetaev", "vakonomic"):  # form A: no pole there
                continue
            assert low < np.min(tr[coordinate]) and np.max(tr[coordinate]) < high, (model, form, coordinate)


# ============================================================================ knife edge
def test_knife_edge_true_motion_is_a_uniform_circle() -> None:
    """φ̈ = 0 and v̇ = 0: the edge runs round a circle of radius v/φ̇ at constant speed
    (Neimark & Fufaev 1972); the constraint force is normal to the blade and acts at the
    centre of mass, so it neither turns the blade nor changes its speed."""
    s = system("knife_edge")
    x, y, phi = s.coordinates
    acc = s.equations("chetaev").accelerations
    v = d(x) * sp.cos(phi) + d(y) * sp.sin(phi)
    assert acc[dd(phi)] == 0
    assert vanishes(d(v).xreplace(acc).xreplace(s.constraints))
    k = system("knife_edge", m=1, J=1)
    phi0, w, v0 = 0.3, 0.5, 0.8 / np.cos(0.3)
    tr = simulate(k, "chaplygin", 4.0, {"x": 0, "y": 0, "phi": phi0, "x'": 0.8, "phi'": w}, samples=21)
    assert np.allclose(tr["phi"], phi0 + w * tr.t, atol=1e-9)
    assert np.allclose(tr["x"], v0 / w * (np.sin(phi0 + w * tr.t) - np.sin(phi0)), atol=1e-8)
    assert np.allclose(tr["y"], -v0 / w * (np.cos(phi0 + w * tr.t) - np.cos(phi0)), atol=1e-8)


def test_knife_edge_lindelof_runs_away_from_the_blade_direction() -> None:
    """Lindelöf: T̃ = m ẋ²/(2 cos² φ) + J φ̇²/2, x cyclic, so p = m ẋ/cos² φ is constant and
    J φ̈ = (p²/m) sin φ cos φ: near φ = 0, φ ≈ φ̇0 sinh(kt)/k with k = ẋ0 √(m/J)."""
    s = system("knife_edge")
    x, _, phi = s.coordinates
    m, J = s.parameter("m"), s.parameter("J")
    assert vanishes(s.reduced_kinetic_energy - (m * d(x) ** 2 / (2 * sp.cos(phi) ** 2) + J * d(phi) ** 2 / 2))
    comparison = compare_models(s)
    assert comparison.verdict == "differ" and s.integrability().integrable is False
    assert s.integrability().frobenius.failures == [("[X_x, X_phi] along ∂y", -1 / sp.cos(phi) ** 2)]
    assert vanishes(comparison.defect[x] + m * d(x) * d(phi) * sp.tan(phi) / sp.cos(phi) ** 2)
    assert vanishes(comparison.defect[phi] - m * d(x) ** 2 * sp.tan(phi) / sp.cos(phi) ** 2)
    k = system("knife_edge", m=1, J=4)
    tr = simulate(k, "lindelof", 20.0, {"x": 0, "y": 0, "phi": 0.0, "x'": 0.1, "phi'": 1e-3}, samples=21)
    p = tr["x'"] / np.cos(tr["phi"]) ** 2
    assert np.ptp(p) < 1e-9
    rate = 0.1 * np.sqrt(1 / 4)
    assert np.allclose(tr["phi"], 1e-3 / rate * np.sinh(rate * tr.t), rtol=1e-4, atol=1e-9)
    true = simulate(k, "chaplygin", 20.0, {"x": 0, "y": 0, "phi": 0.0, "x'": 0.1, "phi'": 1e-3}, samples=21)
    assert np.allclose(true["phi"], 1e-3 * true.t, atol=1e-12)  # the true blade turns uniformly


# ============================================================================ Chaplygin sleigh
def test_chaplygin_sleigh_reduced_dynamics() -> None:
    """v̇ = a ω², ω̇ = −m a v ω / (I + m a²) (Bloch 2003, §1.7)."""
    s = system("chaplygin_sleigh")
    x, y, th = s.coordinates
    m, I, a = s.parameter("m"), s.parameter("I"), s.parameter("a")
    acc = s.equations("chetaev").accelerations
    v = x.diff(t) * sp.cos(th) + y.diff(t) * sp.sin(th)
    w = th.diff(t)
    assert vanishes((v.diff(t).xreplace(acc) - a * w**2).xreplace(s.constraints))
    assert vanishes((acc[th.diff(t, 2)] + m * a * v * w / (I + m * a**2)).xreplace(s.constraints))
    assert not s.integrability().integrable


def sleigh_closed_form(v0: float, w0: float, tt: np.ndarray, m: float = 1.0, I: float = 1.0, a: float = 1.0):
    """v = V tanh(kt + c0), ω = ±V √(m/J) sech(kt + c0), k = a m V/J, V = √(2E/m), J = I + m a²;
    the heading θ − θ0 = ±(√(J/m)/a) [gd(kt + c0) − gd(c0)], gd(u) = arctan(sinh u)."""
    J = I + m * a**2
    V = np.sqrt(v0**2 + J / m * w0**2)
    c0, k = np.arctanh(v0 / V), a * m * V / J
    u = k * tt + c0
    v = V * np.tanh(u)
    w = np.sign(w0) * V * np.sqrt(m / J) / np.cosh(u)
    heading = np.sign(w0) * np.sqrt(J / m) / a * (np.arctan(np.sinh(u)) - np.arctan(np.sinh(c0)))
    return v, w, heading


def test_sleigh_closed_form_solution() -> None:
    s = system("chaplygin_sleigh", m=1, I=1, a=1)
    tr = simulate(s, "chaplygin", 10.0, {"x": 0, "y": 0, "theta": 0, "x'": 1.0, "theta'": 0.3}, samples=21)
    v = tr["x'"] * np.cos(tr["theta"]) + tr["y'"] * np.sin(tr["theta"])
    cv, cw, heading = sleigh_closed_form(1.0, 0.3, tr.t)
    assert np.allclose(v, cv, atol=1e-9) and np.allclose(tr["theta'"], cw, atol=1e-9)
    assert np.allclose(tr["theta"], heading, atol=1e-9)


def test_sleigh_settles_to_straight_motion() -> None:
    """The sleigh's turning rate dies out, its speed tends to sqrt(2E/m) (Bloch 2003, §1.7) and its
    heading to θ0 + (√(J/m)/a)(π/2 − gd(c0))."""
    s = system("chaplygin_sleigh", m=1, I=1, a=1)
    # a gentle start keeps the heading away from θ = π/2, the pole of the split ẏ = tan θ ẋ
    tr = simulate(s, "chaplygin", 60.0, {"x": 0, "y": 0, "theta": 0, "x'": 1.0, "theta'": 0.3}, samples=61)
    assert tr.success and tr.energy_drift() < 1e-9
    assert abs(tr["theta'"][-1]) < 1e-3
    speed = np.hypot(tr["x'"][-1], tr["y'"][-1])
    assert speed == pytest.approx(np.sqrt(2 * tr.energy[0]), rel=1e-4)
    V = np.sqrt(1.0 + 2 * 0.3**2)
    limit = np.sqrt(2.0) * (np.pi / 2 - np.arctan(np.sinh(np.arctanh(1.0 / V))))
    assert tr["theta"][-1] == pytest.approx(limit, abs=2e-3)


def test_sleigh_moving_backwards_turns_round() -> None:
    """Straight motion with the centre of mass behind the edge (v < 0) is unstable: v passes
    through 0 and ends at +V.  The multiplier form has no chart pole at θ = π/2."""
    s = system("chaplygin_sleigh", m=1, I=1, a=1)
    tr = simulate(s, "chetaev", 20.0, {"x": 0, "y": 0, "theta": 0, "x'": -1.0, "theta'": 0.1}, samples=41)
    assert tr.success
    v = tr["x'"] * np.cos(tr["theta"]) + tr["y'"] * np.sin(tr["theta"])
    cv, _, heading = sleigh_closed_form(-1.0, 0.1, tr.t)
    assert np.allclose(v, cv, atol=1e-8) and np.allclose(tr["theta"], heading, atol=1e-8)
    assert v[0] < 0 < v[-1] and tr["theta"][-1] > np.pi


def test_sleigh_lindelof_is_the_knife_edge_lindelof() -> None:
    """On the constraint the cross term m a θ̇ (−ẋ sin θ + ẏ cos θ) vanishes, so T̃ is the knife
    edge's with J = I + m a²: Lindelöf's sleigh does not feel a at all, the true one does."""
    s = system("chaplygin_sleigh")
    x, _, th = s.coordinates
    m, I, a = s.parameter("m"), s.parameter("I"), s.parameter("a")
    knife = m * d(x) ** 2 / (2 * sp.cos(th) ** 2) + (I + m * a**2) * d(th) ** 2 / 2
    assert vanishes(s.reduced_kinetic_energy - knife)
    assert compare_models(s).verdict == "differ"


# ============================================================================ vertical rolling disk
def test_vertical_disk_rolls_round_a_circle() -> None:
    """θ̇ and φ̇ are constant (Bloch 2003, §1.4): the contact point runs round a circle of
    radius R θ̇/φ̇; Lindelöf's equations happen to be right, the other vakonomic motions are not."""
    s = system("vertical_rolling_disk")
    theta, phi, *_ = s.coordinates
    acc = s.equations("chetaev").accelerations
    assert acc[dd(theta)] == 0 and acc[dd(phi)] == 0
    assert compare_models(s).verdict == "lindelof_right_here"
    true = s.equations("chetaev")
    assert equivalent(s, s.equations("lindelof"), true)
    assert not equivalent(s, s.equations("vakonomic_family", constants=[1, 0]), true)
    n = system("vertical_rolling_disk", m=1, R=0.5, I=0.5, J=0.25)
    tr = simulate(
        n, "chaplygin", 10.0, {"theta": 0, "phi": 0.2, "x": 0, "y": 0, "theta'": 2.0, "phi'": 0.4}, samples=21
    )
    rho = 0.5 * 2.0 / 0.4
    assert np.allclose(tr["x"], rho * (np.sin(0.2 + 0.4 * tr.t) - np.sin(0.2)), atol=1e-8)
    assert np.allclose(tr["y"], -rho * (np.cos(0.2 + 0.4 * tr.t) - np.cos(0.2)), atol=1e-8)
    entry = examples.get("vertical-rolling-disk")  # R θ̇/φ̇ = 1 · 1/0.2 = 5
    tr = simulate(entry.system(), "chaplygin", 20.0, entry.initial, entry.parameters, samples=41)
    assert np.allclose(np.hypot(tr["x"], tr["y"] - 5.0), 5.0)


# ============================================================================ rolling disk
DISK = {"m": 1.0, "r": 1.0, "A": 0.25, "C": 0.5, "g": 9.81}
HOOP = {"m": 1.0, "r": 1.0, "A": 0.5, "C": 1.0, "g": 9.81}


def steady_spin(theta: float, Omega: float, p: dict) -> float:
    """s = φ̇ + Ω sin θ from A Ω² sin θ cos θ − (C + m r²) s Ω cos θ − m g r sin θ = 0 (hand-derived
    by Newton–Euler on the page; Routh 1905, art. 244; O'Reilly 1996)."""
    m, r, A, C, g = p["m"], p["r"], p["A"], p["C"], p["g"]
    return (A * Omega**2 * np.sin(theta) * np.cos(theta) - m * g * r * np.sin(theta)) / (
        (C + m * r**2) * Omega * np.cos(theta)
    )


@pytest.mark.parametrize("theta, Omega", [(0.3, 2.0), (-0.5, 3.0), (1.0, -4.0)])
def test_rolling_disk_steady_rolling_relation(theta: float, Omega: float) -> None:
    s = system("rolling_disk")
    psi, th, phi, *_ = s.coordinates
    spin = steady_spin(theta, Omega, DISK)
    phid = spin - Omega * np.sin(theta)
    state = {
        **{s.parameter(k): v for k, v in DISK.items()},
        psi: 0.4,
        th: theta,
        phi: 0.1,
        d(psi): Omega,
        d(th): 0.0,
        d(phi): phid,
    }
    for model in ("chaplygin", "lindelof"):  # the defect is ∝ θ̇: both models keep these
        acc = s.equations(model).accelerations
        assert all(abs(at(acc[dd(q)], state)) < 1e-9 for q in (psi, th, phi)), model
    start = {
        "psi": 0.0,
        "theta": theta,
        "phi": 0.0,
        "x": 0.0,
        "y": 0.0,
        "psi'": Omega,
        "theta'": 0.0,
        "phi'": phid,
    }
    tr = simulate(s, "chaplygin", 5.0, start, DISK, samples=26)
    assert np.ptp(tr["theta"]) < 1e-9 and np.ptp(tr["psi'"]) < 1e-9 and np.ptp(tr["phi'"]) < 1e-9
    # the contact point runs round a circle of radius r φ̇/Ω, the centre round one of radius r s/Ω
    rho = DISK["r"] * phid / Omega
    assert np.allclose(tr["x"], rho * np.sin(Omega * tr.t), atol=1e-8)
    assert np.allclose(tr["y"], -rho * (np.cos(Omega * tr.t) - 1), atol=1e-8)
    gx = tr["x"] + np.sin(theta) * np.sin(tr["psi"])
    gy = tr["y"] - np.sin(theta) * np.cos(tr["psi"])
    radius = np.hypot(gx, gy - rho)  # about the same centre (0, r φ̇/Ω)
    assert np.ptp(radius) < 1e-8 and radius[0] == pytest.approx(abs(DISK["r"] * spin / Omega), abs=1e-8)


def test_rolling_disk_defect_is_proportional_to_lean_rate() -> None:
    """(15) − (22): −m r² φ̇ θ̇ cos θ for ψ, 0 for θ, m r² ψ̇ θ̇ cos θ for φ; and the catalogue coin
    (φ̇ = 6, well above √(g/(3r)) ≈ 1.81) wobbles about the upright."""
    s = system("rolling_disk")
    psi, th, phi, *_ = s.coordinates
    m, r = s.parameter("m"), s.parameter("r")
    defect = compare_models(s).defect
    assert vanishes(defect[psi] + m * r**2 * d(phi) * d(th) * sp.cos(th))
    assert defect[th] == 0
    assert vanishes(defect[phi] - m * r**2 * d(psi) * d(th) * sp.cos(th))
    entry = examples.get("rolling-disk")
    tr = simulate(s, "chaplygin", 20.0, entry.initial, entry.parameters, samples=81)
    assert np.max(np.abs(tr["theta"])) < 0.3 and tr.energy_drift() < 1e-8


def test_rolling_disk_upright_rolling_and_spinning_are_steady() -> None:
    """θ = 0 satisfies the relation with Ω = 0 (rolling straight) or s = 0 (spinning about the
    vertical diameter)."""
    s = system("rolling_disk")
    for start in ({"psi'": 0.0, "phi'": 3.0}, {"psi'": 5.0, "phi'": 0.0}):
        tr = simulate(
            s,
            "chaplygin",
            2.0,
            {"psi": 0, "theta": 0, "phi": 0, "x": 0, "y": 0, "theta'": 0, **start},
            DISK,
            samples=11,
        )
        assert np.max(np.abs(tr["theta"])) < 1e-12


def upright_rate_squared(spin: float, p: dict, model: str) -> float:
    """Linearized about upright rolling with spin s (hand-derived on the page):
    (A + m r²) θ̈ = [m g r − K s²/A] θ, K = C (C + m r²) (true) or (C + m r²)² (Lindelöf)."""
    m, r, A, C, g = p["m"], p["r"], p["A"], p["C"], p["g"]
    K = C * (C + m * r**2) if model == "chaplygin" else (C + m * r**2) ** 2
    return (K * spin**2 / A - m * g * r) / (A + m * r**2)


@pytest.mark.parametrize("body", [DISK, HOOP], ids=["coin", "hoop"])
def test_rolling_disk_upright_stability(body: dict) -> None:
    """Upright rolling is stable iff s² > m g r A / (C (C + m r²)) — g/(3r) for a coin, g/(4r) for a
    hoop (Routh 1905, art. 244) — and wobbles at the linearized frequency; Lindelöf's equations
    put the threshold at m g r A / (C + m r²)² instead."""
    s = system("rolling_disk")
    m, r, A, C, g = (body[k] for k in ("m", "r", "A", "C", "g"))
    critical = np.sqrt(m * g * r * A / (C * (C + m * r**2)))
    assert critical**2 == pytest.approx(g / (3 * r) if C == 0.5 else g / (4 * r))
    theta0 = 0.01
    for model in ("chaplygin", "lindelof"):
        for spin in (2 * critical, 0.75 * critical, 0.5 * critical):
            K = C if model == "chaplygin" else C + m * r**2  # A ψ̇ + K s θ is constant
            start = {
                "psi": 0,
                "theta": theta0,
                "phi": 0,
                "x": 0,
                "y": 0,
                "psi'": -K * spin / A * theta0,
                "theta'": 0.0,
                "phi'": spin + K * spin / A * theta0 * np.sin(theta0),
            }
            tr = simulate(s, model, 1.5, start, body, samples=31)
            rate2 = upright_rate_squared(spin, body, model)
            if rate2 > 0:  # a wobble at the linearized frequency
                assert np.max(np.abs(tr["theta"] - theta0 * np.cos(np.sqrt(rate2) * tr.t))) < 5e-3 * theta0
            else:  # it falls, growing like cosh
                lam = np.sqrt(-rate2)
                assert np.max(np.abs(tr["theta"] / (theta0 * np.cosh(lam * tr.t)) - 1)) < 1e-2
    lindelof_critical2 = m * g * r * A / (C + m * r**2) ** 2  # g/(9r) coin, g/(8r) hoop
    assert lindelof_critical2 == pytest.approx(g / (9 * r) if C == 0.5 else g / (8 * r))
    # s = 0.75 critical: the true disk falls, Lindelöf's disk stays up
    assert (
        upright_rate_squared(0.75 * critical, body, "chaplygin")
        < 0
        < upright_rate_squared(0.75 * critical, body, "lindelof")
    )


# ============================================================================ ball on a turntable
def test_turntable_ball_centre_velocity_rotates_at_two_sevenths_omega() -> None:
    """ẍ = −(2/7)Ω ẏ, ÿ = (2/7)Ω ẋ: the centre circles with angular frequency 2Ω/7
    (Weltner 1979; Weckesser 1997)."""
    s = system("turntable_ball")
    assert s.is_affine and not s.is_chaplygin
    X, Y = s.dependent
    W = s.parameter("Omega")
    acc = s.equations("chetaev").accelerations
    assert vanishes(
        acc[X.diff(t, 2)].xreplace(s.constraints) + sp.Rational(2, 7) * W * s.constraints[Y.diff(t)]
    )
    assert vanishes(
        acc[Y.diff(t, 2)].xreplace(s.constraints) - sp.Rational(2, 7) * W * s.constraints[X.diff(t)]
    )
    with pytest.raises(ModelError):
        compare_models(s)  # B depends on x, y: no Lindelöf equations
    psi, theta, phi = s.independent
    omega_z = d(psi) + d(phi) * sp.cos(theta)
    assert vanishes(d(omega_z).xreplace(acc))  # ⅖ m a² ω̇ = −a e_z × F has no z part
    true = s.equations("chetaev")
    assert equivalent(s, s.equations("voronets"), true) and equivalent(
        s, s.equations("voronets", "new"), true
    )


def test_turntable_ball_circle_spin_and_moving_energy() -> None:
    """The centre runs round the circle of centre r0 + e_z × v0/κ and radius |v0|/κ, κ = 2Ω/7;
    ω_z is constant; the energy is not, but E − Ω L_z is (Fassò & Sansonetto 2016)."""
    entry = examples.get("turntable-ball")
    s = entry.system()
    m, a, W = (entry.parameters[k] for k in ("m", "a", "Omega"))
    tr = simulate(s, "voronets", 20.0, entry.initial, entry.parameters, samples=41)
    kappa = 2 * W / 7
    r0 = np.array([tr["x"][0], tr["y"][0]])
    v0 = np.array([tr["x'"][0], tr["y'"][0]])
    c = r0 + np.array([-v0[1], v0[0]]) / kappa
    cos, sin = np.cos(kappa * tr.t), np.sin(kappa * tr.t)
    assert np.allclose(tr["x"], c[0] + cos * (r0[0] - c[0]) - sin * (r0[1] - c[1]), atol=1e-8)
    assert np.allclose(tr["y"], c[1] + sin * (r0[0] - c[0]) + cos * (r0[1] - c[1]), atol=1e-8)
    assert np.allclose(c, [-1.25, 0.0]) and np.hypot(*v0) / kappa == pytest.approx(1.75)
    wz = tr["psi'"] + tr["phi'"] * np.cos(tr["theta"])
    assert np.ptp(wz) < 1e-9
    Lz = m * (tr["x"] * tr["y'"] - tr["y"] * tr["x'"]) + 0.4 * m * a**2 * wz
    assert np.ptp(tr.energy - W * Lz) < 1e-8 and np.ptp(tr.energy) > 0.1
    # the vakonomic motion from the same state is a different motion
    vak = simulate(s, "vakonomic", 20.0, entry.initial, entry.parameters, samples=41, constants="match")
    assert np.max(np.hypot(vak["x"] - tr["x"], vak["y"] - tr["y"])) > 1.0
    assert np.max(vak.energy) > 10 * vak.energy[0]  # the model, not a real ball


# ============================================================================ Chaplygin's ball
def rotation(psi: float, theta: float, phi: float) -> np.ndarray:
    """Body → space for z-x-z Euler angles: Rz(ψ) Rx(θ) Rz(φ)."""

    def rz(u: float) -> np.ndarray:
        return np.array([[np.cos(u), -np.sin(u), 0], [np.sin(u), np.cos(u), 0], [0, 0, 1]])

    rx = np.array([[1, 0, 0], [0, np.cos(theta), -np.sin(theta)], [0, np.sin(theta), np.cos(theta)]])
    return rz(psi) @ rx @ rz(phi)


def space_omega(tr, k: int) -> np.ndarray:
    psi, theta = tr["psi"][k], tr["theta"][k]
    dpsi, dtheta, dphi = tr["psi'"][k], tr["theta'"][k], tr["phi'"][k]
    return np.array(
        [
            dtheta * np.cos(psi) + dphi * np.sin(theta) * np.sin(psi),
            dtheta * np.sin(psi) - dphi * np.sin(theta) * np.cos(psi),
            dpsi + dphi * np.cos(theta),
        ]
    )


def contact_momentum(tr, inertia: np.ndarray, m: float, a: float) -> np.ndarray:
    """K = I ω + m a² (ω − (ω·e_z) e_z), the angular momentum about the contact point, in space."""
    out = []
    for k in range(len(tr.t)):
        w = space_omega(tr, k)
        R = rotation(tr["psi"][k], tr["theta"][k], tr["phi"][k])
        out.append(R @ inertia @ R.T @ w + m * a**2 * (w - w[2] * np.array([0.0, 0.0, 1.0])))
    return np.array(out)


BALL_START = {"psi": 0.2, "theta": 1.1, "phi": 0.3, "x": 0, "y": 0, "psi'": 0.4, "theta'": -0.3, "phi'": 0.8}


def test_chaplygin_ball_conserves_contact_angular_momentum() -> None:
    """K = Iω + m a² γ × (ω × γ) is constant in space (Chaplygin 1903; Borisov & Mamaev 2002);
    Lindelöf's ball loses it."""
    s = system("chaplygin_ball", m=1, a=1, A=sp.Rational(3, 10), B=sp.Rational(4, 10), C=sp.Rational(5, 10))
    inertia = np.diag([0.3, 0.4, 0.5])
    tr = simulate(s, "chaplygin", 20.0, BALL_START, samples=41)
    assert tr.success and tr.energy_drift() < 1e-9
    K = contact_momentum(tr, inertia, m=1.0, a=1.0)
    assert np.max(np.abs(K - K[0])) < 1e-8
    lindelof = simulate(s, "lindelof", 20.0, BALL_START, samples=41)
    assert lindelof.success and lindelof.energy_drift() < 1e-9
    K = contact_momentum(lindelof, inertia, m=1.0, a=1.0)
    assert np.max(np.abs(K - K[0])) > 1e-2
    assert compare_models(s).verdict == "differ"
    true = s.equations("chetaev")
    assert equivalent(s, s.equations("chaplygin"), true, symbolic=False)
    assert not equivalent(s, s.equations("lindelof"), true, symbolic=False)


def test_chaplygin_ball_with_equal_moments_keeps_its_angular_velocity() -> None:
    """A = B = C: K = (A + m a²) ω − m a² ω_z e_z constant gives ω constant; the centre moves
    uniformly on a straight line (Routh 1905)."""
    s = system("chaplygin_ball", m=1, a=1, A=sp.Rational(1, 4), B=sp.Rational(1, 4), C=sp.Rational(1, 4))
    tr = simulate(s, "chaplygin", 10.0, BALL_START, samples=21)
    w = np.array([space_omega(tr, k) for k in range(len(tr.t))])
    assert np.max(np.abs(w - w[0])) < 1e-8
    assert np.ptp(tr["x'"]) < 1e-8 and np.ptp(tr["y'"]) < 1e-8


# ============================================================================ Heisenberg system
def test_heisenberg_true_lines_and_vakonomic_circles() -> None:
    """Chetaev: straight lines; vakonomic: ẍ = −c ẏ, ÿ = c ẋ, circles (sub-Riemannian geodesics;
    Brockett 1981; Montgomery 2002, ch. 1)."""
    s = system("heisenberg")
    x, y, _ = s.coordinates
    true = s.equations("chetaev").accelerations
    assert true[x.diff(t, 2)] == 0 and true[y.diff(t, 2)] == 0
    fam = s.equations("vakonomic_family").accelerations
    (c,) = s.equations("vakonomic_family").constants
    assert vanishes(fam[x.diff(t, 2)] + c * y.diff(t))
    assert vanishes(fam[y.diff(t, 2)] - c * x.diff(t))
    # T does not depend on ż, so the Lindelöf defect vanishes: c = 0 gives the true lines too,
    # and only the members c ≠ 0 of the vakonomic family bend into circles
    assert compare_models(s).verdict == "lindelof_right_here"
    assert s.integrability().integrable is False
    assert [value for _, value in s.integrability().frobenius.failures] in ([1], [-1])  # [X_1, X_2] = ±∂z
    (lam,) = s.equations("chetaev").multipliers
    assert true[lam] == 0  # T has no ż: no constraint force at all
    assert equivalent(s, s.equations("lindelof"), s.equations("chetaev"))
    assert not equivalent(s, s.equations("vakonomic_family", constants=[1]), s.equations("chetaev"))


def test_heisenberg_motions_in_closed_form() -> None:
    """True: z = z0 + (x0 ẏ0 − y0 ẋ0) t/2 along the line.  Vakonomic with c: after one turn,
    2π/c, the path closes and z has gained the enclosed area π (|v|/c)² (Stokes)."""
    s = system("heisenberg")
    start = {"x": 1.0, "y": 0.5, "z": 0.0, "x'": 0.3, "y'": 1.0}
    tr = simulate(s, "chaplygin", 3.0, start, samples=7)
    assert np.allclose(tr["x"], 1.0 + 0.3 * tr.t) and np.allclose(tr["y"], 0.5 + tr.t)
    assert np.allclose(tr["z"], (1.0 * 1.0 - 0.5 * 0.3) * tr.t / 2)
    c = 2.0
    speed = np.hypot(0.3, 1.0)
    for model, options in (("vakonomic_family", {"constants": [c]}), ("vakonomic", {"multipliers": [c]})):
        tr = simulate(s, model, 2 * np.pi / c, start, samples=9, **options)
        assert np.allclose([tr["x"][-1], tr["y"][-1]], [1.0, 0.5], atol=1e-8), model
        assert tr["z"][-1] == pytest.approx(np.pi * (speed / c) ** 2, abs=1e-8), model
        centre = np.array([1.0, 0.5]) + np.array([-1.0, 0.3]) / c  # r0 + e_z × v0 / c
        assert np.allclose(np.hypot(tr["x"] - centre[0], tr["y"] - centre[1]), speed / c, atol=1e-8)


# ============================================================================ contact oscillator
def test_contact_oscillator_conserves_energy() -> None:
    """ẋ + y ż = 0 with V = ½|q|² + ½ε x² z²: homogeneous, time-independent constraint, so the
    energy is conserved (McLachlan & Perlmutter 2006 use such oscillators as test problems)."""
    s = system("contact_oscillator", eps=sp.Rational(1, 100))
    assert not s.integrability().integrable
    tr = simulate(s, "voronets", 100.0, {"x": 0.0, "y": 1.0, "z": 0.5, "y'": 0.2, "z'": 0.4}, samples=101)
    assert tr.success and tr.energy_drift() < 1e-9 and np.max(tr.constraint_residual) < 1e-9


def test_contact_oscillator_y_is_a_harmonic_oscillator() -> None:
    """The constraint has no ẏ term, so no constraint force acts along y: ÿ = −y for every ε,
    and ½(ẏ² + y²) is conserved on its own."""
    s = system("contact_oscillator")
    x, y, z = s.coordinates
    assert s.equations("chetaev").accelerations[dd(y)] == -y
    assert not s.is_chaplygin
    with pytest.raises(ModelError):
        compare_models(s)  # V depends on x: no Lindelöf equations
    assert equivalent(s, s.equations("voronets"), s.equations("chetaev"))
    assert equivalent(s, s.equations("voronets", "new"), s.equations("chetaev"))
    A = sp.Matrix([1, 0, y])  # ω = dx + y dz: ω ∧ dω = (A · curl A) dx∧dy∧dz
    curl = sp.Matrix([A[2].diff(y) - A[1].diff(z), A[0].diff(z) - A[2].diff(x), A[1].diff(x) - A[0].diff(y)])
    assert A.dot(curl) == 1
    start = {"x": 0.0, "y": 1.0, "z": 0.5, "y'": 0.2, "z'": 0.4}
    tr = simulate(s, "voronets", 20.0, start, {"epsilon": 0.5}, samples=41)
    assert np.allclose(tr["y"], np.cos(tr.t) + 0.2 * np.sin(tr.t), atol=1e-8)
    assert np.ptp(0.5 * (tr["y'"] ** 2 + tr["y"] ** 2)) < 1e-9 and tr.energy_drift() < 1e-9
    vak = simulate(s, "vakonomic", 20.0, start, {"epsilon": 0.5}, samples=41, constants="match")
    assert vak.success and np.max(np.abs(vak["z"] - tr["z"])) > 0.1


# ============================================================================ differential drive
def test_differential_drive_wheels_spin_freely() -> None:
    """Without torques and with the centre of mass on the axle, each wheel keeps its speed."""
    s = system("differential_drive")
    acc = s.equations("voronets").accelerations
    assert set(acc.values()) == {0}


def test_differential_drive_brackets_are_across_the_heading() -> None:
    """Voronets' extra terms vanish: with D_σ F = ∂F/∂q_σ + Σ_α B_ασ ∂F/∂q_α, the brackets
    D_L B_βR − D_R B_βL are (r²/2b)(sin θ, −cos θ, 0) for (x, y, θ), across the momentum m v (cos θ, sin θ)."""
    s = system("differential_drive")
    x, y, th, pl, pr = s.coordinates
    r, b = s.parameter("r"), s.parameter("b")
    B = {q: [s.constraints[d(q)].diff(d(u)) for u in (pl, pr)] for q in (x, y, th)}

    def D(k: int, F: sp.Expr) -> sp.Expr:
        return F.diff((pl, pr)[k]) + sum(B[q][k] * F.diff(q) for q in (x, y, th))

    W = [D(0, B[q][1]) - D(1, B[q][0]) for q in (x, y, th)]
    expected = [r**2 / (2 * b) * sp.sin(th), -(r**2) / (2 * b) * sp.cos(th), 0]
    assert all(vanishes(w - e) for w, e in zip(W, expected))


def test_differential_drive_kinematics_and_circle() -> None:
    """v = r(φ̇_R + φ̇_L)/2, θ̇ = r(φ̇_R − φ̇_L)/(2b) (Siegwart & Nourbakhsh 2004, ch. 3): constant
    wheel speeds drive the robot round a circle of radius b(φ̇_R + φ̇_L)/(φ̇_R − φ̇_L)."""
    s = system("differential_drive")
    x, y, th, pl, pr = s.coordinates
    r, b = s.parameter("r"), s.parameter("b")
    v = r * (d(pr) + d(pl)) / 2
    assert vanishes(s.constraints[d(x)] - v * sp.cos(th))
    assert vanishes(s.constraints[d(y)] - v * sp.sin(th))
    assert vanishes(s.constraints[d(th)] - r * (d(pr) - d(pl)) / (2 * b))
    entry = examples.get("differential-drive")
    tr = simulate(s, "voronets", 20.0, entry.initial, entry.parameters, samples=41)
    p = entry.parameters
    wl, wr = entry.initial["phi_L'"], entry.initial["phi_R'"]
    speed, turn = p["r"] * (wr + wl) / 2, p["r"] * (wr - wl) / (2 * p["b"])
    radius = p["b"] * (wr + wl) / (wr - wl)
    assert radius == pytest.approx(1.5) and speed / turn == pytest.approx(radius)
    assert np.allclose(tr["theta"], turn * tr.t, atol=1e-9)
    assert np.allclose(tr["x"], radius * np.sin(turn * tr.t), atol=1e-8)
    assert np.allclose(tr["y"], radius * (1 - np.cos(turn * tr.t)), atol=1e-8)


def test_differential_drive_is_a_chaplygin_system_in_other_coordinates() -> None:
    """With x, y, φ_L dependent (φ̇_L = φ̇_R − 2bθ̇/r) T and B are free of the dependent
    coordinates: a Chaplygin system, whose Lindelöf defect vanishes."""
    s = system("differential_drive")
    x, y, _, pl, _ = s.coordinates
    other = System(s.coordinates, s.kinetic_energy, s.implicit_constraints, dependent=[x, y, pl])
    assert not s.is_chaplygin and other.is_chaplygin
    comparison = compare_models(other)
    assert comparison.verdict == "lindelof_right_here" and not comparison.condition_28
    assert equivalent(other, other.equations("lindelof"), other.equations("chetaev"))
    assert not equivalent(
        other, other.equations("vakonomic_family", constants=[1, 0, 0]), other.equations("chetaev")
    )
    entry = examples.get("differential-drive")
    start = {k: v for k, v in entry.initial.items() if k != "phi_L'"}
    start["theta'"] = (
        entry.parameters["r"]
        * (entry.initial["phi_R'"] - entry.initial["phi_L'"])
        / (2 * entry.parameters["b"])
    )
    a = simulate(s, "voronets", 20.0, entry.initial, entry.parameters, samples=41)
    b = simulate(other, "chaplygin", 20.0, start, entry.parameters, samples=41)
    assert all(np.allclose(a[q], b[q], atol=1e-9) for q in ("x", "y", "theta", "phi_L", "phi_R"))


# ============================================================================ sleigh chain
@pytest.mark.parametrize("n", [1, 2])
def test_sleigh_chain_scales_and_conserves_energy(n: int) -> None:
    s = examples.sleigh_chain(n)
    assert s.n == n + 3 and s.g == n + 1 and s.epsilon == 2
    params = {"m": 1.0, "I": 0.5, "L": 1.0}
    start = {"x": 0.0, "y": 0.0, **{f"theta{i}": 0.1 * i for i in range(n + 1)}, "x'": 1.0, "theta0'": 0.05}
    # the lead heading stays far from θ0 = π/2, the pole of the split ẏ = tan θ0 ẋ
    tr = simulate(s, "voronets", 10.0, start, params, samples=21)
    assert tr.success and tr.energy_drift() < 1e-9


def test_sleigh_chain_is_the_geometric_chain() -> None:
    """T and the constraints equal those built from the knife-edge positions
    p_i = p_{i−1} − L (cos θ_i, sin θ_i), and the trailers obey the N-trailer kinematics
    θ̇_i = (v_{i−1}/L) sin(θ_{i−1} − θ_i) (Tilbury, Murray & Sastry 1995)."""
    n = 3
    s = examples.sleigh_chain(n)
    x, y, *th = s.coordinates
    m, I, L = s.parameter("m"), s.parameter("I"), s.parameter("L")
    px, py, T, A = x, y, sp.S.Zero, []
    for i, ti in enumerate(th):
        if i:
            px, py = px - L * sp.cos(ti), py - L * sp.sin(ti)
        T += m / 2 * (d(px) ** 2 + d(py) ** 2) + I / 2 * d(ti) ** 2
        A.append(-sp.sin(ti) * d(px) + sp.cos(ti) * d(py))
    assert vanishes(T - s.kinetic_energy)
    assert all(vanishes(a - b) for a, b in zip(A, s.implicit_constraints))
    speed = d(x) * sp.cos(th[0]) + d(y) * sp.sin(th[0])  # v_0 of the lead
    for i in range(1, n + 1):
        rate = speed / L * sp.sin(th[i - 1] - th[i])
        assert vanishes((s.constraints[d(th[i])] - rate).xreplace(s.constraints))
        speed = speed * sp.cos(th[i - 1] - th[i])


def test_sleigh_chain_lead_turns_uniformly() -> None:
    """Every force on the lead (its knife's, the hitch's) acts at its knife edge, its centre of
    mass: I θ̈0 = 0."""
    s = examples.sleigh_chain(2)
    assert s.equations("chetaev").accelerations[dd(s.coordinates[2])] == 0


@pytest.mark.parametrize("forward", [True, False])
def test_trailer_lines_up_forward_and_jackknifes_backward(forward: bool) -> None:
    """Lead running straight along x: δ = θ0 − θ1 obeys dδ/ds = −sin δ / L, so
    tan(δ/2) = tan(δ0/2) e^{−(x − x0)/L}: δ → 0 forwards, δ → π backwards."""
    s = system("sleigh_chain", n=1)
    v0 = 1.0 if forward else -1.0
    tr = simulate(
        s,
        "chetaev",
        5.0,
        {"x": 0, "y": 0, "theta0": 0, "theta1": 0.5, "x'": v0, "theta0'": 0.0},
        {"m": 1.0, "I": 0.5, "L": 1.0},
        samples=11,
    )
    assert np.max(np.abs(tr["theta0"])) < 1e-12 and np.max(np.abs(tr["y"])) < 1e-12
    assert np.allclose(tr["theta1"], 2 * np.arctan(np.tan(0.25) * np.exp(-tr["x"])), atol=1e-9)
    assert (abs(tr["theta1"][-1]) < 0.01) if forward else (tr["theta1"][-1] > 3.0)


def test_sleigh_chain_catalogue_lines_up_and_models() -> None:
    """The default lead runs straight (θ0 ≡ 0), both trailers line up; Voronets ≡ Chetaev; the
    vakonomic multiplier form (no Lindelöf equations: T depends on θ1, θ2) is another motion."""
    entry = examples.get("sleigh-chain")
    s = entry.system()
    true = simulate(s, "voronets", 20.0, entry.initial, entry.parameters, samples=41)
    check = simulate(s, "chetaev", 20.0, entry.initial, entry.parameters, samples=41)
    assert np.allclose(true["x"], check["x"], atol=1e-8) and np.allclose(
        true["theta1"], check["theta1"], atol=1e-8
    )
    assert np.max(np.abs(true["theta0"])) < 1e-9 and true.energy_drift() < 1e-9
    assert abs(true["theta1"][-1]) < 1e-3 and abs(true["theta2"][-1]) < 1e-3
    with pytest.raises(ModelError):
        compare_models(s)
    vak = simulate(s, "vakonomic", 20.0, entry.initial, entry.parameters, samples=41, constants="match")
    assert vak.success and np.max(np.abs(vak["x"] - true["x"])) > 1.0
