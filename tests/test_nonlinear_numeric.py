"""Numerics for constraints nonlinear in the velocities (issue 30): every backend's right-hand
side against the exact SymPy evaluation of the same model, runs against closed forms, and the
refusals (a start on the singular set, a degenerate vakonomic Lagrangian)."""

from __future__ import annotations

import importlib.util
import math

import numpy as np
import pytest
import sympy as sp

import chaplygin as ch
from chaplygin import System
from chaplygin.core._sampling import StateSampler, parameter_values
from chaplygin.core._symbols import TIME
from chaplygin.errors import ChaplyginError, InputError
from chaplygin.models import registry
from chaplygin.models.equations import Equations
from chaplygin.numeric._modelcache import definition
from chaplygin.numeric.codegen import compile_model
from chaplygin.numeric.ensemble import simulate_ensemble
from chaplygin.numeric.simulate import initial_state
from chaplygin.numeric.stability import stability, steady_motions

#: the optional jax backend (chaplygin[jax]) is checked where it is installed
JAX = all(importlib.util.find_spec(name) is not None for name in ("jax", "diffrax"))
t = sp.Symbol("t")
x, y, z = (sp.Function(name)(t) for name in "xyz")
m, g, v, k = sp.symbols("m g v k", positive=True)
xd, yd, zd = (c.diff(t) for c in (x, y, z))


def isokinetic(branch: int = 1) -> System:
    return System(
        [x, y], m / 2 * (xd**2 + yd**2), [xd**2 + yd**2 - v**2], dependent=[x],
        potential_energy=m * g * y, branch=branch,
    )  # fmt: skip


def isokinetic_solved() -> System:
    return System([x, y], m / 2 * (xd**2 + yd**2), {xd: sp.sqrt(v**2 - yd**2)}, potential_energy=m * g * y)


def appell(branch: int = 1) -> System:
    return System(
        [x, y, z], m / 2 * (xd**2 + yd**2 + zd**2), [zd**2 - k**2 * (xd**2 + yd**2)], dependent=[z],
        potential_energy=m * g * z, branch=branch,
    )  # fmt: skip


def appell_solved() -> System:
    return System(
        [x, y, z],
        m / 2 * (xd**2 + yd**2 + zd**2),
        {zd: k * sp.sqrt(xd**2 + yd**2)},
        potential_energy=m * g * z,
    )


def appell_chaplygin() -> System:
    """Appell's constraint with the weight's field along y: a Chaplygin system (T, U and φ free of z),
    so that Lindelöf's equations and the vakonomic family exist."""
    return System(
        [x, y, z], m / 2 * (xd**2 + yd**2 + zd**2), [zd**2 - k**2 * (xd**2 + yd**2)], dependent=[z],
        potential_energy=m * g * y, branch=1,
    )  # fmt: skip


def randomish(seed: int = 3) -> System:
    """Three coordinates, T with an off-axis term, a constraint nonlinear in the velocities with
    coordinates and explicit time in it (coefficients drawn from ``seed``)."""
    rng = np.random.default_rng(seed)
    a, b, c, d, e = (sp.Rational(int(rng.integers(1, 9)), 10) for _ in range(5))
    T = m / 2 * (xd**2 + yd**2 + zd**2) + a * m * sp.cos(y) * xd * zd
    phi = k * sp.sqrt(xd**2 + (1 + b * x**2) * yd**2 + c) + d * sp.sin(y) * xd + e * t
    return System([x, y, z], T, {zd: phi}, potential_energy=m * g * z + a * x * y)


SYSTEMS = {
    "isokinetic": (isokinetic, ["chetaev", "voronets", "voronets/new", "chaplygin", "vakonomic"]),
    "isokinetic-solved": (isokinetic_solved, ["chetaev", "chaplygin/new"]),
    "appell": (appell, ["chetaev", "voronets", "voronets/new", "vakonomic"]),
    "appell-solved": (appell_solved, ["voronets"]),
    "appell-chaplygin": (appell_chaplygin, ["chaplygin", "chaplygin/new", "lindelof", "vakonomic_family"]),
    "random": (randomish, ["chetaev", "voronets", "voronets/new", "vakonomic"]),
}


def _exact_rhs(system: System, eqs: Equations, state: dict, mus: list[float]) -> list[float]:
    """dy/dt of the model's state from its symbolic accelerations, evaluated exactly (SymPy)."""
    values = {key: sp.Float(val, 30) for key, val in state.items()}
    values.update({mu: sp.Float(val, 30) for mu, val in zip(eqs._state, mus)})
    n = system.n
    velocities = [state[system._vars.xd[i]] for i in range(n)]
    reduced = registry.get(eqs.model).reduced
    unknowns = eqs._unknowns[: len(system._ind) if reduced else n + len(eqs._state)]  # (not λ)
    rates = [float(sp.N(eqs._accelerations[u].xreplace(values), 20)) for u in unknowns]
    return velocities + rates


@pytest.mark.parametrize("name", list(SYSTEMS))
def test_rhs_matches_exact_evaluation(name: str) -> None:
    """Each backend's dy/dt equals the exact SymPy value of ``equations(model).accelerations`` at
    random admissible states (the dependent velocities from φ, the branch chosen)."""
    build, models = SYSTEMS[name]
    system = build()
    rng = np.random.default_rng(7)
    params = parameter_values(system, rng)
    sampler = StateSampler(system, params)
    names = {p.name: val for p, val in params.items()}
    # (numba and jax compile for seconds: one reduced and one multiplier model of two systems)
    extra = (["numba"] if name == "isokinetic" else []) + (
        ["jax"] if JAX and name in ("isokinetic", "appell") else []
    )
    for label in models:
        model, _, form = label.partition("/")
        family = {"constants": [sp.Rational(1, 2)]} if model == "vakonomic_family" else {}
        eqs = system.equations(model, form or "classic", **family)
        reduced = registry.get(model).reduced
        backends = ["numpy", "c"] + (extra if label in ("voronets", "vakonomic") else [])
        compiled = {be: compile_model(system, model, form or "classic", be, **family) for be in backends}
        if model == "voronets" and not form:  # Novoselov's equations from the Chetaev matrices, numerically
            compiled["numeric"] = compile_model(system, model, backend="numpy", reduction="numeric")
        layout = compiled["numpy"].layout
        p = np.array([names.get(p, 0.5) for p in layout.parameters])  # (c_1 = 1/2)
        for _ in range(3):
            state = sampler.draw(rng)
            assert abs(float(system._f[0].xreplace(state))) < 1e-12  # admissible
            mus = list(rng.uniform(-0.3, 0.3, size=len(eqs._state)))
            ys = [state[c] for c in system._vars.x]
            ys += [state[system._vars.xd[i]] for i in (system._ind if reduced else range(system.n))]
            exact = np.array(_exact_rhs(system, eqs, state, mus))
            for be, cm in compiled.items():
                got = np.asarray(cm.rhs(float(state[TIME]), np.array(ys + mus), p))
                np.testing.assert_allclose(got, exact, rtol=1e-9, atol=1e-9, err_msg=f"{name} {label} {be}")


def test_random_system_runs_agree() -> None:
    """On the random system (off-axis T, coordinates and t in φ) the Chetaev run keeps |f| at the run's
    tolerance and Novoselov's equations (classic, new, the numeric reduction) follow it to 1e-9."""
    system, params = randomish(), {"m": 1.0, "g": 9.81, "k": 0.7}
    start = {"x": 0.2, "y": 0.1, "z": 0.0, "x'": 0.3, "y'": -0.2}
    truth = ch.simulate(system, "chetaev", 1.0, start, params, backend="c")
    assert truth.success and np.max(np.abs(truth.constraint_residual)) < 1e-9
    for form, reduction in (("classic", "symbolic"), ("new", "symbolic"), ("classic", "numeric")):
        tr = ch.simulate(system, "voronets", 1.0, start, params, form=form, reduction=reduction, backend="c")
        assert tr.success, tr.message
        for c in ("x", "y", "z", "x'", "y'", "z'"):
            np.testing.assert_allclose(tr[c], truth[c], atol=1e-9, err_msg=f"{form} {reduction} {c}")


APPELL_P = {"m": 1.0, "g": 9.81, "k": 0.5}
APPELL_0 = {"x": 0.0, "y": 0.0, "z": 0.0, "x'": 0.3, "y'": 0.4}


@pytest.mark.parametrize(
    ("backend", "model", "method"),
    [("numpy", "chetaev", "DOP853"), ("c", "chetaev", "DOP853"), ("numpy", "voronets", "DOP853"),
     ("c", "voronets", "DOP853"), ("numpy", "voronets", "gauss4"), ("c", "vakonomic", "DOP853")],
)  # fmt: skip
def test_appell_closed_form(backend: str, model: str, method: str) -> None:
    """Appell's weight, z' = +k |(x', y')|: a straight path, speed rate −g k/(1 + k²), z'' = −g k²/(1 + k²)
    (Appell 1911), to the run's tolerance, |f| at round-off; the run ends before the speed reaches 0.
    The vakonomic model (c = 0: μ = −m/2, not degenerate here) gives the same motion."""
    options = {"step": 1e-3} if method == "gauss4" else {"rtol": 1e-11, "atol": 1e-13}
    tr = ch.simulate(appell(), model, 0.1, APPELL_0, APPELL_P, backend=backend, method=method, **options)
    assert tr.success, tr.message
    kk, gg = APPELL_P["k"], APPELL_P["g"]
    speed = np.hypot(tr["x'"], tr["y'"])
    np.testing.assert_allclose(speed, 0.5 - gg * kk / (1 + kk**2) * tr.t, atol=1e-9)
    np.testing.assert_allclose(tr["z'"], kk * speed, atol=1e-9)
    np.testing.assert_allclose(tr["z"], kk * (0.5 * tr.t - gg * kk / (1 + kk**2) * tr.t**2 / 2), atol=1e-9)
    np.testing.assert_allclose(tr["y"] * 0.3, tr["x"] * 0.4, atol=1e-12)  # the line through the start
    assert np.max(np.abs(tr.constraint_residual)) < 1e-9


ISO_P = {"m": 1.0, "g": 9.81, "v": 1.0}
ISO_0 = {"x": 0.0, "y": 0.0, "y'": 0.3}


def test_lindelof_closed_form() -> None:
    """Lindelöf's equations of Appell's constraint with the field along y: T̃ = m (1 + k²)(x'² + y'²)/2,
    so y'' = −g/(1 + k²) and x' stays."""
    tr = ch.simulate(appell_chaplygin(), "lindelof", 1.0, APPELL_0, APPELL_P, backend="c")
    kk, gg = APPELL_P["k"], APPELL_P["g"]
    np.testing.assert_allclose(tr["y'"], 0.4 - gg / (1 + kk**2) * tr.t, atol=1e-9)
    np.testing.assert_allclose(tr["x'"], 0.3, atol=1e-12)
    np.testing.assert_allclose(tr["z'"], kk * np.hypot(tr["x'"], tr["y'"]), atol=1e-12)


def test_isokinetic_grim_reaper_and_branches_mirrored() -> None:
    """The isokinetic particle: y'/v = −tanh(g t/v − atanh(y'(0)/v)) and x = (v²/g)·(gd(s) − gd(s0)) (the
    grim reaper, gd the Gudermannian), for the implicit form (c) and the solved one (numpy); the other
    branch, x' = −√(v² − y'²), gives the mirrored run x → −x."""
    gg, vv = ISO_P["g"], ISO_P["v"]
    s0 = -math.atanh(0.3 / vv)
    runs = {
        "implicit": ch.simulate(isokinetic(), "voronets", 1.0, ISO_0, ISO_P, backend="c"),
        "solved": ch.simulate(isokinetic_solved(), "chetaev", 1.0, ISO_0, ISO_P, backend="numpy"),
    }
    s = gg * runs["implicit"].t / vv + s0
    gd = 2 * np.arctan(np.tanh(s / 2)) - 2 * math.atan(math.tanh(s0 / 2))
    for tr in runs.values():
        assert tr.success, tr.message
        np.testing.assert_allclose(tr["y'"], -vv * np.tanh(s), atol=1e-8)
        np.testing.assert_allclose(tr["x"], vv**2 / gg * gd, atol=1e-8)
        assert np.max(np.abs(tr.constraint_residual)) < 1e-8
    other = ch.simulate(isokinetic(0), "voronets", 1.0, ISO_0, ISO_P, backend="c")
    np.testing.assert_allclose(other["x"], -runs["implicit"]["x"], atol=1e-12)
    np.testing.assert_allclose(other["y"], runs["implicit"]["y"], atol=1e-12)


def test_isokinetic_vakonomic_catenary() -> None:
    """The vakonomic particle: w x' = c and w y' = c' − m g t with w = m + 2μ and x'² + y'² = v²
    (a catenary: the slope linear in arc length), for the multiplier form and the family; c < 0 gives
    w < 0 (the particle rises), where the family's M, the Hessian of T̃ + c φ, is negative: not a mass
    matrix to be checked (the numpy run was cut to no sample)."""
    mm, gg, vv = ISO_P["m"], ISO_P["g"], ISO_P["v"]
    xd0 = math.sqrt(vv**2 - 0.3**2)
    for c, backend in ((0.5, "c"), ("match", "c"), (-0.5, "numpy")):
        cc = mm * xd0 if c == "match" else c
        slope = cc / xd0 * 0.3
        for model in ("vakonomic", "vakonomic_family"):
            tr = ch.simulate(isokinetic(), model, 1.0, ISO_0, ISO_P, constants=c, backend=backend)
            assert tr.success, tr.message
            a = slope - mm * gg * tr.t
            expected = np.sign(cc) * vv * a / np.hypot(cc, a)
            np.testing.assert_allclose(tr["y'"], expected, atol=1e-8, err_msg=f"{model} {c}")


def test_vakonomic_degenerate_start_refused() -> None:
    """With c = 0 (the default) the isokinetic particle's μ(0) = −m/2 makes L + μ f degenerate
    (H + 2μ I = 0): refused at the start, naming μ(0) and the way out, not a singular matrix at t = 0."""
    for model in ("vakonomic", "lindelof"):
        with pytest.raises(InputError, match=r"degenerate at the initial state with μ\(0\) = \[-0.5\]"):
            ch.simulate(isokinetic(), model, 1.0, ISO_0, ISO_P, backend="numpy")


def test_run_that_stalls_at_the_branch_point_names_it(monkeypatch: pytest.MonkeyPatch) -> None:
    """Appell's weight rising (branch z' = +k|v|) stops at v = 0 (t = 0.5 (1 + k²)/(g k) = 0.1274), a
    branch point where Novoselov's equations chatter: the time-limit refusal names the singular set."""
    from chaplygin.numeric import simulate as module

    monkeypatch.setattr(module, "ESTIMATE_AFTER", 0.05)
    with pytest.raises(InputError, match=r"too long to run.*singular set.*x'\*\*2 \+ y'\*\*2"):
        ch.simulate(appell(), "voronets", 0.3, APPELL_0, APPELL_P, backend="c", time_limit=0.5)


def test_start_on_the_singular_set_refused() -> None:
    """A start where ∂f/∂q̇_dep is singular (a branch point) is refused, naming the singular set."""
    with pytest.raises(InputError, match=r"singular set.*x'\*\*2 \+ y'\*\*2 = 0"):
        ch.simulate(appell(), "chetaev", 1.0, {**APPELL_0, "x'": 0.0, "y'": 0.0}, APPELL_P)
    with pytest.raises(InputError, match=r"singular set.*v\*\*2 - y'\*\*2 = 0"):
        initial_state(isokinetic(), {"x": 0, "y": 0, "y'": 1.0}, ISO_P, 0.0)
    with pytest.raises(ChaplyginError, match=r"initial_states\[1\].*singular set"):
        simulate_ensemble(isokinetic(), "voronets", 0.5, [ISO_0, {**ISO_0, "y'": 1.0}], ISO_P, backend="c")


def test_branches_have_their_own_cache_key() -> None:
    """Two branches of one implicit constraint are different models: their disk-cache keys differ."""
    keys = {definition(isokinetic(b)) for b in (0, 1)}
    assert len(keys) == 2 and None not in keys
    assert definition(isokinetic(1)) == definition(isokinetic(1))


def test_ensemble_and_compare() -> None:
    """Ensembles fill the dependent velocities from φ (the branch) and agree with single runs;
    compare runs the true and vakonomic models of a nonlinear system."""
    starts = [ISO_0, {**ISO_0, "y'": -0.5}]
    ens = simulate_ensemble(isokinetic(), "voronets", 0.5, starts, ISO_P, backend="c")
    for j, start in enumerate(starts):
        tr = ch.simulate(isokinetic(), "voronets", 0.5, start, ISO_P, backend="c")
        assert ens.coordinates["x"][j] == pytest.approx(tr["x"][-1], abs=1e-8)
        assert ens.velocities_initial["x'"][j] == pytest.approx(math.sqrt(1 - start["y'"] ** 2), abs=1e-14)
    assert np.max(np.abs(ens.constraint_residual)) < 1e-8
    vak = simulate_ensemble(isokinetic(), "vakonomic", 1.0, starts, ISO_P, backend="c", constants=0.5)
    for j, start in enumerate(starts):  # the catenary: w y' = c' − m g t, w x' = c
        slope = 0.5 / math.sqrt(1 - start["y'"] ** 2) * start["y'"] - 9.81
        assert vak.velocities["y'"][j] == pytest.approx(slope / math.hypot(0.5, slope), abs=1e-8)
    cmp = ch.compare(isokinetic(), ["chetaev", "voronets", "vakonomic"], 0.5, ISO_0, ISO_P, backend="c")
    assert np.max(cmp.distance("voronets")) < 1e-8
    assert np.max(cmp.distance("vakonomic")) > 1e-3  # the grim reaper and the catenary differ
    # the paper's comparison by default: Lindelöf's T̃ = m v²/2 is constant, so Lindelöf's equations
    # do not apply (the registry says why) and are not among the default models
    why = registry.get("lindelof").obstruction(isokinetic())
    assert why is not None and why.startswith("T̃ = m*v**2/2") and "degenerate" in why
    default = ch.compare(isokinetic(), None, 0.5, ISO_0, ISO_P, backend="c")
    assert list(default.trajectories) == ["chaplygin", "vakonomic"]


def test_stability_of_an_isokinetic_circular_orbit() -> None:
    """ṙ² + r²θ̇² = v² in the potential k r²/2: the circle r0² = m v²/k is a steady motion (found by
    Newton from r = 0.4); the true
    motion's r̈ = (1 − ṙ²/v²)(v²/r − k r/m) gives eigenvalues ±i√(2k/m) (by hand); the multiplier
    model is linearised through Novoselov's equations, the vakonomic one is refused."""
    r, th = sp.Function("r")(t), sp.Function("theta")(t)
    kk = sp.Symbol("k", positive=True)
    rd, thd = r.diff(t), th.diff(t)
    system = System(
        [r, th], m / 2 * (rd**2 + r**2 * thd**2), [rd**2 + r**2 * thd**2 - v**2], dependent=[th],
        potential_energy=kk * r**2 / 2, branch=1,
    )  # fmt: skip
    params = {"m": 1.0, "k": 4.0, "v": 1.0}
    found = steady_motions(system, {"r": 0.4, "r'": 0.0}, params)  # Newton, from r = 0.4
    assert found.point["r"] == pytest.approx(0.5, abs=1e-12)
    for model in ("voronets", "chetaev"):
        st = stability(system, {"r": 0.5, "r'": 0.0, "theta": 0.0}, params, model=model)
        np.testing.assert_allclose(sorted(st.eigenvalues.imag), [-math.sqrt(8), math.sqrt(8)], rtol=1e-9)
        np.testing.assert_allclose(st.eigenvalues.real, 0, atol=1e-9)
    with pytest.raises(ChaplyginError, match="not linearised for constraints nonlinear"):
        stability(system, {"r": 0.5, "r'": 0.0, "theta": 0.0, "mu_1": 0.0}, params, model="vakonomic")
