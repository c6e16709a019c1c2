"""Ensembles stop a member where the solved constraints of a reduced model meet a pole, as
``simulate`` does: on every backend, with the pole's status, time and NaN samples after it.

Whether a member's motion reaches the pole is decided independently of the check under test:
the multiplier model (``chetaev``), which does not solve the constraints and has no pole, is
integrated on a fine grid, and the pole (``cos θ = 0`` for ``ẏ = tan θ ẋ``) is where the sign
of ``cos θ`` changes; for the knife edge with φ̇ = 1 it is at t = π/2 − 1.2 exactly.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols

from cases import KNIFE_0, KNIFE_P
from chaplygin import System, examples, simulate
from chaplygin.numeric._ckernel import Unavailable, compiler
from chaplygin.numeric.ensemble import simulate_ensemble

try:
    compiler()
    BACKENDS = ["c", "numba"]
except Unavailable:  # pragma: no cover - every CI machine has a C compiler
    BACKENDS = ["numba"]
try:
    import jax  # noqa: F401

    BACKENDS.append("jax")
except ImportError:
    pass

SLEIGH_P = {"m": 1.0, "I": 0.3, "a": 0.4, "g": 2.0}
SLEIGH_0 = [
    {"x": 0.0, "y": 0.0, "theta": th, "x'": v, "theta'": w}
    for th, v, w in [(0.2, 1.0, 0.5), (0.0, 1.0, 0.0), (-0.3, 0.5, -0.2), (1.0, 0.5, 1.0), (1.3, 0.2, 0.5)]
]


def sleigh_on_an_incline() -> System:
    """Chaplygin's sleigh on a slope falling along −x: the knife edge at (x, y), ẏ = tan θ ẋ."""
    t = sp.Symbol("t")
    x, y, th = dynamicsymbols("x y theta")
    m, inertia, a, g = sp.symbols("m I a g", positive=True)
    xd, yd, thd = x.diff(t), y.diff(t), th.diff(t)
    T = m / 2 * (xd**2 + yd**2) + m * a * thd * (-xd * sp.sin(th) + yd * sp.cos(th))
    T += (inertia + m * a**2) / 2 * thd**2
    return System(
        [x, y, th],
        T,
        [-sp.sin(th) * xd + sp.cos(th) * yd],
        dependent=[y],
        potential_energy=m * g * x,
        name="sleigh on an incline",
    )


def first_crossing(system: System, heading: str, start: dict, params: dict, t_end: float) -> float:
    """When the true motion's heading first crosses ±π/2 (inf: not before t_end)."""
    true = simulate(system, "chetaev", t_end, start, params, samples=3001)
    assert true.success
    c = np.cos(true[heading])
    k = np.flatnonzero(np.sign(c[1:]) != np.sign(c[:-1]))
    return float(true.t[k[0] + 1]) if k.size else math.inf


@pytest.mark.parametrize("backend", BACKENDS)
def test_ensemble_members_stop_at_a_pole_on_every_backend(backend: str) -> None:
    knife = examples.knife_edge()
    ens = simulate_ensemble(knife, "chaplygin", 1.0, KNIFE_0, KNIFE_P, backend=backend)
    pole = math.pi / 2 - 1.2
    assert list(ens.code) == [9, 0] and list(ens.failure) == ["pole", ""], ens.messages
    assert list(ens.status) == ["failed", "success"]
    assert ens.t[0] <= pole <= ens.t_pole[0] and ens.t_pole[0] - ens.t[0] <= 0.0101
    assert "pole of the solved constraints" in ens.messages[0] and ens.messages[1] == ""
    # the state reported is the motion's there (φ = 1.2 + t), not one past the pole
    assert abs(ens["phi"][0] - (1.2 + ens.t[0])) < 1e-8 and ens["phi"][0] < math.pi / 2
    # with samples kept: those from the pole on are NaN, as for any failure
    kept = simulate_ensemble(knife, "chaplygin", 1.0, KNIFE_0, KNIFE_P, backend=backend, keep=21)
    assert kept.samples is not None and kept.times is not None
    assert kept.t[0] == pytest.approx(0.37) and kept.t_pole[0] == pytest.approx(0.38)
    assert np.all(np.isfinite(kept.samples[0, :8])) and np.all(np.isnan(kept.samples[0, 8:]))  # t ≥ 0.4
    assert np.allclose(kept.samples[1, -1], kept.y[1], rtol=1e-12, atol=0)  # the run's own samples
    assert np.all(np.isfinite(kept.samples[1])) and kept.code[1] == 0

    sleigh = sleigh_on_an_incline()
    crossing = [first_crossing(sleigh, "theta", s, SLEIGH_P, 3.0) for s in SLEIGH_0]
    assert sum(map(math.isfinite, crossing)) == 4  # four members reach the pole, one does not
    ens = simulate_ensemble(sleigh, "chaplygin", 3.0, SLEIGH_0, SLEIGH_P, backend=backend)
    for k, when in enumerate(crossing):
        if math.isfinite(when):
            assert ens.failure[k] == "pole" and ens.t[k] < when <= ens.t_pole[k] + 0.0011, ens.messages[k]
            # stopped before it: cos θ keeps the sign it started with
            assert math.cos(ens["theta"][k]) * math.cos(SLEIGH_0[k]["theta"]) > 0
        else:
            assert ens.code[k] == 0 and ens.t[k] == 3.0 and np.isnan(ens.t_pole[k])


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_velocity_that_stops_being_finite_is_a_pole_in_simulate_and_ensembles(backend: str) -> None:
    """ẏ = √x ẋ stops being real at x = 0, reached at t ≈ 0.0977 from x = 0.1, ẋ = −1: the loop
    itself stops there (a non-finite velocity), which simulate and the ensemble both call a pole
    (on main, simulate's failure was '' beside the message 'a pole at t = …')."""
    t = sp.Symbol("t")
    x, y = dynamicsymbols("x y")
    edge = System([x, y], (x.diff(t) ** 2 + y.diff(t) ** 2) / 2, {y.diff(t): sp.sqrt(x) * x.diff(t)})
    start = {"x": 0.1, "y": 0.0, "x'": -1.0}
    ens = simulate_ensemble(edge, "chaplygin", 1.0, [start], {}, backend=backend)
    assert ens.code[0] != 0 and 0.09 < ens.t[0] < 0.0977, ens.messages
    if backend == "jax":  # diffrax rejects the non-finite steps until the step underflows
        return
    assert ens.failure[0] == "pole", ens.messages
    run = simulate(edge, "chaplygin", 1.0, start, {}, samples=11, backend=backend)
    assert run.failure == "pole" and "y'" in run.message, run.message


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_pole_crossed_and_back_between_checked_times_stops_the_member(backend: str) -> None:
    """φ = 0.3 ± t to t = 200π: the 101 times checked are 2π apart, where cos φ has the same sign,
    though φ meets ±π/2 every π (first at t = π/2 ∓ 0.3). A member that stepped more often than
    the times checked is checked again as often as it stepped (on 1300154: 'success' for all)."""
    starts = [{"x": 0.0, "y": 0.0, "phi": 0.3, "x'": 1.0, "phi'": w} for w in (1.0, -1.0, 0.0)]
    ens = simulate_ensemble(
        examples.knife_edge(), "chaplygin", (0.0, 200 * math.pi), starts, KNIFE_P, backend=backend
    )
    assert list(ens.failure) == ["pole", "pole", ""]
    for k, first in enumerate((math.pi / 2 - 0.3, math.pi / 2 + 0.3)):
        assert ens.t[k] < first <= ens.t_pole[k] < first + 1.0  # (not past a second pole)
    assert ens.t[2] == pytest.approx(200 * math.pi)


def sleigh_with_a_slip(denominator: sp.Expr) -> System:
    """A knife edge whose constraint ẏ = sin θ ẋ / √d has a denominator d of x (A_dep = 1)."""
    t = sp.Symbol("t")
    x, y, th = dynamicsymbols("x y theta")
    m, inertia = sp.symbols("m I", positive=True)
    xd, yd, thd = x.diff(t), y.diff(t), th.diff(t)
    d = denominator.subs(sp.Symbol("x"), x)
    T = m / 2 * (xd**2 + yd**2) + inertia / 2 * thd**2
    return System([x, y, th], T, [yd - sp.sin(th) * xd / sp.sqrt(d)], dependent=[y], name="slipping sleigh")


def test_a_denominator_of_one_sign_is_checked_at_the_runs_own_points_only(monkeypatch) -> None:
    """ẏ = sin θ ẋ / √(1 + x²) (as the rattleback's √(a² sin²φ cos²θ + b² sin²θ + c² cos²φ cos²θ)):
    1 + x² keeps its sign, so no change of sign can occur between two points, and neither
    simulate nor the ensemble integrates again to look for one (simulate checks its samples;
    the ensemble, keeping no samples, its start and end, with no grid of 101 times): on 5d469ee
    both did, and the rattleback's ensemble of 64 members to t = 10 took 5.5 s instead of 1.4 s.
    A denominator that changes sign (4 − x²), or whose sign depends on a parameter's value
    (c + x² with c declared positive: a run may be given c < 0), is still looked for in between;
    every run is the multiplier model's motion."""
    from chaplygin.numeric import simulate as simulate_module
    from chaplygin.numeric import targets

    X, c = sp.Symbol("x"), sp.Symbol("c", positive=True)
    start = {"x": 0.1, "y": 0.0, "theta": 0.3, "x'": 1.0, "theta'": 0.7}
    params = {"m": 1.0, "I": 0.5, "c": 1.5}
    runs: list[int] = []
    checks: list[int | None] = []
    real_samples, real_ensemble = simulate_module._samples, targets.LoopTarget.ensemble

    def samples(*args, **kwargs):
        runs.append(kwargs["samples"])
        return real_samples(*args, **kwargs)

    def ensemble(self, *args, **kwargs):
        checks.append(None if kwargs["times"] is None else len(kwargs["times"]))
        return real_ensemble(self, *args, **kwargs)

    monkeypatch.setattr(simulate_module, "_samples", samples)
    monkeypatch.setattr(targets.LoopTarget, "ensemble", ensemble)
    for d, between in ((1 + X**2, False), (4 - X**2, True), (c + X**2, True)):
        system = sleigh_with_a_slip(d)
        p = {k: v for k, v in params.items() if k in {s.name for s in system.parameters}}
        runs.clear()
        checks.clear()
        tr = simulate(system, "chaplygin", 1.0, start, p, samples=3, backend=BACKENDS[0])
        assert tr.success and runs[0] == 3 and len(runs) == (2 if between else 1), (d, runs)
        ens = simulate_ensemble(system, "chaplygin", 1.0, [start], p, backend=BACKENDS[0])
        assert list(ens.code) == [0] and checks[0] == (101 if between else 0), (d, checks)
        # the same motion as the multiplier model's, which solves nothing and has no pole
        true = simulate(system, "chetaev", 1.0, start, p, samples=3, backend=BACKENDS[0])
        for name in ("x", "y", "theta"):
            assert abs(ens[name][0] - tr[name][-1]) < 1e-9 and abs(tr[name][-1] - true[name][-1]) < 1e-8


def test_a_parameter_declared_positive_but_given_a_negative_value_still_shows_the_pole() -> None:
    """ẏ = ẋ / (c + sin²θ) with c declared positive but run with c = −1/4: the denominator
    changes sign where sin θ = 1/2 (θ = π/6, at t = π/6 for θ̇ = 1), a pole, reported by
    simulate and the ensemble (in review of cd63aa5, which trusted the declaration, both ran
    through it to t = 31.4 with "success" and the wrong motion)."""
    t = sp.Symbol("t")
    x, y, th = dynamicsymbols("x y theta")
    m, c = sp.Symbol("m", positive=True), sp.Symbol("c", positive=True)
    xd, yd, thd = x.diff(t), y.diff(t), th.diff(t)
    T = m / 2 * (xd**2 + yd**2 + thd**2)
    system = System([x, y, th], T, [yd - xd / (c + sp.sin(th) ** 2)], dependent=[y], name="c + sin²θ")
    start, params = {"x": 0.0, "y": 0.0, "theta": 0.0, "x'": 1.0, "theta'": 1.0}, {"m": 1.0, "c": -0.25}
    tr = simulate(system, "chaplygin", 31.4, start, params, samples=5, backend=BACKENDS[0])
    assert tr.failure == "pole" and tr.t[-1] < math.pi / 6, tr.message
    ens = simulate_ensemble(system, "chaplygin", 31.4, [start], params, backend=BACKENDS[0])
    assert list(ens.code) == [9] and ens.t[0] <= math.pi / 6 <= ens.t_pole[0], ens.messages


def test_the_zero_of_a_one_signed_denominator_at_a_sample_is_reported() -> None:
    """ẏ = ẋ / √(ε² + φ²) with ε = 0 and φ = t − 1: the denominator keeps its sign and touches
    zero at t = 1, a sample of simulate's and one the ensemble keeps, where the constraints
    cannot be solved: reported there by both, as before cd63aa5 (a motion that meets such a
    zero between two points passes it unseen: docs/reliability.md says so)."""
    t = sp.Symbol("t")
    x, y, phi = dynamicsymbols("x y phi")
    m, eps = sp.Symbol("m", positive=True), sp.Symbol("eps", real=True)
    xd, yd, phid = x.diff(t), y.diff(t), phi.diff(t)
    T = m / 2 * (xd**2 + yd**2 + phid**2)
    system = System([x, y, phi], T, [yd - xd / sp.sqrt(eps**2 + phi**2)], dependent=[y], name="touch")
    start, params = {"x": 0.0, "y": 0.0, "phi": -1.0, "x'": 1.0, "phi'": 1.0}, {"m": 1.0, "eps": 0.0}
    tr = simulate(system, "chaplygin", 2.0, start, params, samples=5, backend=BACKENDS[0])
    assert tr.failure == "pole" and "at t = 1:" in tr.message, tr.message
    ens = simulate_ensemble(system, "chaplygin", 2.0, [start], params, keep=5, backend=BACKENDS[0])
    assert list(ens.code) == [9] and ens.t_pole[0] == 1.0 and ens.t[0] < 1.0, ens.messages
