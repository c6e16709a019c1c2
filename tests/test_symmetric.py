"""Symmetric fixed-step methods for the true motion (chaplygin.numeric.symmetric, issue 8).

* empirical order of convergence against a closed form (the vertical rolling disk) and against
  a tight DOP853 reference on a nonlinear problem (the rolling disk);
* reversibility: flipping the velocities and stepping back returns to the start;
* bounded energy error with no trend over t = 10⁴ on the rolling disk and on the contact
  oscillator, while DOP853 at a comparable number of right-hand-side evaluations drifts linearly;
* constraints exact to round-off, the Chetaev model's multipliers, failures, bad input, the CLI.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from typer.testing import CliRunner

from chaplygin import ChaplyginError, examples, simulate
from chaplygin.apps.cli import app
from chaplygin.numeric import symmetric
from chaplygin.numeric.codegen import compile_equations, parameter_vector
from chaplygin.numeric.simulate import METHODS
from chaplygin.numeric.symmetric import METHODS as SYMMETRIC
from chaplygin.numeric.symmetric import extrapolation, integrate_symmetric, tableau

DISK = examples.get("rolling-disk")
OSC_START = {"x": 0.0, "y": 1.0, "z": 0.0, "y'": 0.5, "z'": 1.0}
OSC_PARAMS = {"epsilon": 0.1}
ORDERS = {"midpoint": 2, "gauss4": 4, "gauss6": 6}


@pytest.fixture(scope="module")
def disk():
    return DISK.system()


@pytest.fixture(scope="module")
def oscillator():
    return examples.contact_oscillator()


# ---------------------------------------------------------------- the methods themselves
@pytest.mark.parametrize("method", SYMMETRIC)
def test_tableaus_are_gauss_legendre(method: str) -> None:
    """Order conditions up to 2s (B(2s), C(s)) and symmetry (c ↔ 1 − c, b reversed)."""
    A, b, c = tableau(method)
    s = len(b)
    for k in range(1, 2 * s + 1):
        assert abs(b @ c ** (k - 1) - 1 / k) < 1e-15
    for k in range(1, s + 1):
        assert np.allclose(A @ c ** (k - 1), c**k / k, atol=1e-15)
    assert np.allclose(c + c[::-1], 1.0) and np.allclose(b, b[::-1])
    assert np.allclose(A + A[::-1, ::-1], np.outer(np.ones(s), b))  # symmetric method
    # the extrapolation continues polynomials of degree ≤ s exactly
    E = extrapolation(c)
    for k in range(1, s + 1):  # u(x) = x^k, u(0) = 0
        assert np.allclose(E @ c**k, (1 + c) ** k - 1.0, atol=1e-13)


def test_methods_are_offered_by_simulate() -> None:
    assert set(SYMMETRIC) <= set(METHODS)


# ---------------------------------------------------------------- convergence order
def _vertical_disk_closed_form(t: float, start: dict[str, float], R: float) -> dict[str, float]:
    """The vertical disk's true motion.

    Lagrange–d'Alembert with δx = R cos φ δθ, δy = R sin φ δθ: J φ̈ = 0 and
    m R (ẍ cos φ + ÿ sin φ) + I θ̈ = (m R² + I) θ̈ = 0 (ẍ cos φ + ÿ sin φ = R θ̈). So θ̇ = ω
    and φ̇ = Ω are constant and ẋ = R ω cos φ, ẏ = R ω sin φ integrate to
    x = x0 + (R ω / Ω)(sin φ − sin φ0), y = y0 − (R ω / Ω)(cos φ − cos φ0).
    """
    w, W = start["theta'"], start["phi'"]
    phi = start["phi"] + W * t
    rho = R * w / W
    return {
        "theta": start["theta"] + w * t,
        "phi": phi,
        "x": start["x"] + rho * (math.sin(phi) - math.sin(start["phi"])),
        "y": start["y"] - rho * (math.cos(phi) - math.cos(start["phi"])),
        "theta'": w,
        "phi'": W,
        "x'": R * w * math.cos(phi),
        "y'": R * w * math.sin(phi),
    }


def _orders(errors: list[float]) -> np.ndarray:
    return np.log2(np.array(errors[:-1]) / np.array(errors[1:]))


@pytest.mark.parametrize("method", SYMMETRIC)
def test_order_on_the_vertical_disk_closed_form(method: str) -> None:
    system = examples.vertical_rolling_disk()
    start = {"theta": 0.1, "phi": 0.4, "x": 1.0, "y": -2.0, "theta'": 2.0, "phi'": 1.3}
    params = {"m": 1.0, "R": 0.5, "I": 0.3, "J": 0.2}
    T = 8.0
    exact = _vertical_disk_closed_form(T, start, params["R"])
    steps = {"midpoint": (16, 32, 64, 128), "gauss4": (8, 16, 32, 64), "gauss6": (8, 16, 32, 64)}[method]
    errors = []
    for n in steps:
        tr = simulate(system, "chetaev", T, start, params, method=method, step=T / n, samples=2)
        assert tr.success, tr.message
        assert f"{n} {method} steps" in tr.message
        errors.append(max(abs(tr[name][-1] - value) for name, value in exact.items()))
    orders = _orders(errors)
    assert np.all(np.abs(orders - ORDERS[method]) < 0.15), (errors, orders)


@pytest.mark.parametrize("method", ["midpoint", "gauss4"])
def test_order_on_the_rolling_disk(disk, method: str) -> None:
    """A nonlinear problem: against DOP853 at rtol = 1e-13 (the same reduced equations)."""
    T = 2.0
    ref = simulate(
        disk, "voronets", T, DISK.initial, DISK.parameters, rtol=1e-13, atol=1e-14, samples=2, backend="numba"
    )
    steps = {"midpoint": (40, 80, 160, 320), "gauss4": (20, 40, 80, 160)}[method]
    errors = []
    for n in steps:
        tr = simulate(
            disk,
            "voronets",
            T,
            DISK.initial,
            DISK.parameters,
            method=method,
            step=T / n,
            samples=2,
            backend="numba",
        )
        errors.append(max(abs(tr[name][-1] - ref[name][-1]) for name in (*ref.coordinates, *ref.velocities)))
    orders = _orders(errors)
    assert np.all(np.abs(orders - ORDERS[method]) < 0.2), (errors, orders)


# ---------------------------------------------------------------- reversibility, backends
def test_reversible_and_numpy_equals_numba(disk) -> None:
    """ρ(q, u) = (q, −u): Φ_h ∘ ρ ∘ Φ_h^N = ρ to round-off (symmetric + ρ-compatible)."""
    eqs = disk.equations("voronets")
    y0 = np.array([0.0, 0.1, 0.0, 0.0, 0.0, 0.3, -0.2, 6.0])
    runs = {}
    for backend in ("numpy", "numba"):
        compiled = compile_equations(eqs, backend)
        p = parameter_vector(compiled.layout, DISK.parameters)
        forth = integrate_symmetric(compiled, (0.0, 1.0), y0, p, method="gauss4", step=0.05, samples=2)
        flipped = forth.y[-1].copy()
        flipped[5:] *= -1
        back = integrate_symmetric(compiled, (0.0, 1.0), flipped, p, method="gauss4", step=0.05, samples=2)
        expected = y0.copy()
        expected[5:] *= -1
        assert np.max(np.abs(back.y[-1] - expected)) < 1e-12
        runs[backend] = forth.y[-1]
    assert np.max(np.abs(runs["numpy"] - runs["numba"])) < 1e-12


def test_the_compiled_kernels_are_shared_by_every_model(disk, oscillator) -> None:
    """numba compiles the stepping kernels once, not once per model (they call ``fill`` by address)."""
    for system, start, params in ((disk, DISK.initial, DISK.parameters), (oscillator, OSC_START, OSC_PARAMS)):
        tr = simulate(
            system, "voronets", 0.2, start, params, method="gauss4", step=0.1, samples=2, backend="numba"
        )
        assert tr.success, tr.message
    kernel = symmetric.shared()._gl_integrate
    assert len(kernel.signatures) == 1, kernel.signatures
    assert sum(kernel.stats.cache_misses.values()) + sum(kernel.stats.cache_hits.values()) == 1


# ---------------------------------------------------------------- what a run returns
def test_chetaev_run_has_multipliers_and_exact_constraints(disk) -> None:
    sym = simulate(
        disk,
        "chetaev",
        2.0,
        DISK.initial,
        DISK.parameters,
        method="gauss4",
        step=0.0025,
        samples=21,
        backend="numba",
    )
    dop = simulate(disk, "chetaev", 2.0, DISK.initial, DISK.parameters, samples=21)
    assert sym.success and sym.columns == dop.columns
    assert sym.model == "chetaev" and sym.backend == "numba" and sym.rhs_evaluations > 0
    assert np.max(sym.constraint_residual) < 1e-13
    for name in dop.columns:
        assert np.max(np.abs(sym[name] - dop[name])) < 1e-8 * max(1.0, np.max(np.abs(dop[name]))), name
    assert np.max(np.abs(sym["lambda_2"])) > 0.1  # the friction force is there


def test_step_is_fitted_to_the_samples(oscillator) -> None:
    tr = simulate(oscillator, "voronets", 2.0, OSC_START, OSC_PARAMS, method="midpoint", step=0.3, samples=3)
    assert "8 midpoint steps of h = 0.25" in tr.message
    assert np.array_equal(tr.t, [0.0, 1.0, 2.0])


# ---------------------------------------------------------------- long runs: energy
def _windows(tr, count: int = 10) -> tuple[np.ndarray, float]:
    """max |E − E0| over ``count`` consecutive windows, and the linear trend over the run."""
    error = np.abs(tr.energy - tr.energy[0])
    width = len(error) // count
    maxima = np.array([np.max(error[k * width : (k + 1) * width + 1]) for k in range(count)])
    slope = np.polyfit(tr.t, error, 1)[0]
    return maxima, slope * (tr.t[-1] - tr.t[0])


LONG_RUNS = {
    # system: (symmetric method, step), DOP853 rtol at a comparable number of evaluations
    "rolling-disk": (("gauss4", 0.1), 1e-8),
    "contact-oscillator": (("gauss4", 0.1), 1e-10),
    "contact-oscillator-midpoint": (("midpoint", 0.05), 1e-10),
}


@pytest.mark.parametrize("case", list(LONG_RUNS))
def test_energy_bounded_over_t_1e4_while_dop853_drifts(case: str, disk, oscillator) -> None:
    system, start, params = (
        (disk, DISK.initial, DISK.parameters)
        if case == "rolling-disk"
        else (oscillator, OSC_START, OSC_PARAMS)
    )
    (method, step), rtol = LONG_RUNS[case]
    T = 1e4
    sym = simulate(
        system, "chetaev", T, start, params, method=method, step=step, samples=1001, backend="numba"
    )
    dop = simulate(
        system, "voronets", T, start, params, rtol=rtol, atol=rtol / 100, samples=1001, backend="numba"
    )
    assert sym.success and dop.success, (sym.message, dop.message)
    assert dop.rhs_evaluations > 0.5 * sym.rhs_evaluations  # comparable (or more) work
    assert np.max(sym.constraint_residual) < 1e-12
    windows, trend = _windows(sym)
    assert windows[-1] <= 1.5 * np.max(windows[:3]), windows  # bounded
    assert abs(trend) <= 0.1 * np.max(windows), (trend, windows)  # no trend
    windows, trend = _windows(dop)
    assert windows[-1] >= 5 * windows[0], windows  # drifts ...
    assert trend >= 0.8 * np.max(windows), (trend, windows)  # ... linearly


# ---------------------------------------------------------------- failures and bad input
def test_newton_failure_returns_partial_trajectory(oscillator) -> None:
    tr = simulate(oscillator, "chetaev", 40.0, OSC_START, OSC_PARAMS, method="midpoint", step=2.0, samples=21)
    assert tr.status == "failed"
    assert "Newton iteration for the midpoint stages did not converge" in tr.message
    assert "smaller step" in tr.message
    assert 0 < len(tr.t) < 21 and np.all(np.isfinite(tr["x"]))
    compiled = compile_equations(oscillator.equations("voronets"), "numpy")
    p = parameter_vector(compiled.layout, OSC_PARAMS)
    res = integrate_symmetric(
        compiled,
        (0.0, 1.0),
        np.array([0.0, 1.0, 0.0, 0.5, 1.0]),
        p,
        method="gauss4",
        step=0.1,
        samples=2,
        max_iterations=1,
    )
    assert res.status == "failed" and res.code == 7 and "in 1 iterations" in res.message


def test_blow_up_is_a_status() -> None:
    from sympy.physics.mechanics import dynamicsymbols

    from chaplygin import System

    t = dynamicsymbols._t
    x, z = dynamicsymbols("x z")
    s = System([x, z], (x.diff(t) ** 2 + z.diff(t) ** 2) / 2, {z.diff(t): x.diff(t)}, force_function=x**4)
    tr = simulate(
        s, "chaplygin", 10.0, {"x": 1.0, "z": 0.0, "x'": 1.0}, samples=101, method="midpoint", step=0.01
    )
    assert tr.status == "failed" and "blew up" in tr.message
    assert 0 < len(tr.t) < 101 and np.all(np.isfinite(tr["x"]))


def test_a_raising_right_hand_side_is_reported_like_the_dop853_loop() -> None:
    """``fill`` raising (a division by zero in numba) is status 3 with the exception's text, in
    the same words for the compiled DOP853 loop and the symmetric methods."""
    import sympy as sp
    from sympy.physics.mechanics import dynamicsymbols

    from chaplygin import System

    t = dynamicsymbols._t
    x, z = dynamicsymbols("x z")
    c = sp.Symbol("c")
    s = System(
        [x, z], (x.diff(t) ** 2 + z.diff(t) ** 2) / 2, {z.diff(t): x.diff(t)}, force_function=-(x**2) / c
    )
    start, params = {"x": 1.0, "z": 0.0, "x'": 1.0}, {"c": 0.0}
    loop = simulate(s, "chaplygin", 1.0, start, params, backend="numba", samples=11)
    gauss = simulate(
        s, "chaplygin", 1.0, start, params, backend="numba", method="gauss4", step=0.1, samples=11
    )
    for tr in (loop, gauss):
        assert tr.status == "failed"
        assert tr.message == "the right-hand side failed at t = 0: division by zero", tr.message


def test_bad_input(disk, oscillator) -> None:
    def run(model: str = "chetaev", **kw):
        return simulate(disk, model, 1.0, DISK.initial, DISK.parameters, **kw)

    with pytest.raises(ChaplyginError, match=r"method 'gauss' is not one of .*midpoint, gauss4, gauss6"):
        run(method="gauss")
    with pytest.raises(ChaplyginError, match=r"step: the symmetric methods .* need a fixed step size"):
        run(method="gauss4")
    for bad in (-0.1, 0.0, float("nan"), float("inf")):
        with pytest.raises(ChaplyginError, match="step: the step size must be a positive finite number"):
            run(method="gauss4", step=bad)
    with pytest.raises(ChaplyginError, match="step: the symmetric methods"):
        run(method="midpoint", step="0.1")
    with pytest.raises(
        ChaplyginError, match=r"step: a fixed step size is for the symmetric methods .*'DOP853'"
    ):
        run(step=0.1)
    for model in ("lindelof", "vakonomic", "vakonomic_family"):
        with pytest.raises(
            ChaplyginError,
            match=rf"integrates the true \(Chetaev\) motion: model 'chetaev', "
            rf"'chaplygin', 'voronets', not '{model}'",
        ):
            run(model=model, method="gauss4", step=0.1)
    with pytest.raises(ChaplyginError, match="backend: the symmetric methods run with 'numba'"):
        run(method="gauss4", step=0.1, backend="jax")
    with pytest.raises(ChaplyginError, match="would take"):
        run(method="gauss4", step=1e-12)
    with pytest.raises(ChaplyginError, match="not a Chaplygin system"):
        simulate(oscillator, "chaplygin", 1.0, OSC_START, OSC_PARAMS, method="gauss4", step=0.1)


def test_cli(tmp_path) -> None:
    runner = CliRunner()
    out = tmp_path / "disk.csv"
    args = [
        "simulate",
        "example:vertical-rolling-disk",
        "--model",
        "chetaev",
        "--t-end",
        "2",
        "--samples",
        "5",
        "--out",
        str(out),
    ]
    result = runner.invoke(app, [*args, "--method", "gauss4", "--step", "0.1"])
    assert result.exit_code == 0, result.output
    assert "success" in result.stdout and "max constraint residual 0" in result.stdout
    header = out.read_text().splitlines()[0].split(",")
    assert "lambda_1" in header and len(out.read_text().splitlines()) == 6
    unknown = runner.invoke(app, [*args, "--force", "--method", "leapfrog"])
    assert unknown.exit_code == 2 and "gauss4" in unknown.output
    missing = runner.invoke(app, [*args, "--force", "--method", "midpoint"])
    assert missing.exit_code == 2 and "--step" in missing.output
    wrong = runner.invoke(
        app, [*args, "--force", "--model", "lindelof", "--method", "midpoint", "--step", "0.1"]
    )
    assert wrong.exit_code == 1 and "true (Chetaev) motion" in wrong.stderr
