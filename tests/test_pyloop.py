"""The numpy backend's DOP853 on lists (chaplygin.numeric._pyloop): SciPy's steps without SciPy.

The stepper is SciPy's ``DOP853`` written for lists of floats, so it must take SciPy's steps
(``solve_ivp(method="DOP853")`` with ``t_eval``: the same samples to round-off and the same
number of right-hand-side evaluations), end a run where SciPy's stepper ends it, and give
``simulate`` the statuses and messages of the SciPy route it replaces.  Both sides of each
comparison evaluate the same generated right-hand side (``rhs`` is ``rhs_list`` on arrays), so
only the steppers' own arithmetic differs.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from chaplygin import examples
from chaplygin.models import registry
from chaplygin.numeric import codegen
from chaplygin.numeric._dop853 import TOO_SMALL_STEP, StepFailure
from chaplygin.numeric._pyloop import dop853
from chaplygin.numeric.codegen import compile_model
from chaplygin.numeric.simulate import _list_attempt, _pinned, _scipy_attempt, simulate
from randomsystems import Spec, systems
from subprocesses import run_json

DISK_P = {"m": 1.0, "r": 0.5, "A": 0.0625, "C": 0.125, "g": 9.81}
DISK_0 = {"psi": 0.0, "theta": 0.3, "phi": 0.0, "x": 0.0, "y": 0.0, "psi'": 2.0, "theta'": 0.0, "phi'": 5.0}


def _against_scipy(compiled, y0: np.ndarray, p: np.ndarray, t1: float, samples: int) -> None:
    """The list stepper on ``rhs_list`` and ``solve_ivp`` on ``rhs`` agree sample by sample, and
    evaluate the right-hand side equally often."""
    times = np.linspace(0.0, t1, samples)
    values, count = p.tolist(), [0]

    def fun(t: float, y: list[float]) -> list[float]:
        count[0] += 1
        return compiled.module.rhs_list(t, y, values)

    run = dop853(fun, 0.0, t1, y0.tolist(), times.tolist(), rtol=1e-10, atol=[1e-12] * len(y0))
    # (the sample at t0 is y0 on both sides; asked of solve_ivp, it would also compute the dense
    # output of the first step, three evaluations more, where no other sample falls in it)
    ref = solve_ivp(
        lambda t, y: compiled.rhs(t, y, p),
        (0.0, t1),
        y0,
        method="DOP853",
        t_eval=times[1:],
        rtol=1e-10,
        atol=1e-12,
    )
    assert ref.success and run.message == "" and not run.failed_inside
    assert run.t == times.tolist() and run.t_last == t1
    ys = np.array(run.y)
    assert np.array_equal(ys[0], y0)
    np.testing.assert_allclose(ys[1:], ref.y.T, rtol=1e-12, atol=1e-12 * np.max(np.abs(ref.y)))
    assert count[0] == ref.nfev


def test_rolling_disk_takes_scipys_steps() -> None:
    disk = examples.rolling_disk()
    compiled = compile_model(disk, "chaplygin", "classic", "numpy")
    y0 = np.array([DISK_0[name] for name in compiled.layout.state])
    p = np.array([DISK_P[name] for name in compiled.layout.parameters])
    _against_scipy(compiled, y0, p, 10.0, 101)


@given(spec=systems(), seed=st.integers(0, 2**32 - 1))
@settings(max_examples=4, deadline=None)
def test_random_systems_take_scipys_steps(spec: Spec, seed: int) -> None:
    system = spec.system
    compiled = compile_model(system, registry.true_motion(system), "classic", "numpy")
    rng = np.random.default_rng(seed)
    n = len(compiled.layout.coordinates)
    state = len(compiled.layout.state)
    y0 = np.concatenate([rng.uniform(0.2, 1.2, n), rng.uniform(-1.0, 1.0, state - n)])
    p = rng.uniform(0.5, 1.5, len(compiled.layout.parameters))
    _against_scipy(compiled, y0, p, 2.0, 21)


def test_a_step_too_small_ends_the_run_where_scipy_ends_it() -> None:
    """y' = y² from y(0) = 1 blows up at t = 1 without a non-finite value on the way: the step
    size underflows, and both steppers stop after the same last step."""
    count = [0]

    def fun(t: float, y: list[float]) -> list[float]:
        count[0] += 1
        return [y[0] * y[0]]

    times = [0.0, 0.5, 0.9, 2.0]
    run = dop853(fun, 0.0, 2.0, [1.0], times, rtol=1e-10, atol=[1e-12])
    ref = solve_ivp(lambda t, y: y * y, (0.0, 2.0), [1.0], method="DOP853", t_eval=times[1:])
    assert ref.status == -1 and ref.message == TOO_SMALL_STEP
    # SciPy's solve_ivp with the same tolerances as the run above
    ref = solve_ivp(
        lambda t, y: y * y, (0.0, 2.0), [1.0], method="DOP853", t_eval=times[1:], rtol=1e-10, atol=1e-12
    )
    assert run.message == ref.message == TOO_SMALL_STEP and not run.failed_inside
    assert run.t == [0.0, *ref.t] == [0.0, 0.5, 0.9]
    np.testing.assert_allclose(np.array(run.y)[1:, 0], ref.y[0], rtol=1e-12)
    assert run.t_last == pytest.approx(1.0, abs=1e-3) and math.isnan(run.t_fail)
    assert count[0] == ref.nfev


def test_a_failing_right_hand_side_keeps_the_samples_and_the_last_step() -> None:
    """A StepFailure inside a step: the step is not taken; the samples before it, the last
    accepted step and where the evaluation failed come back."""

    def fun(t: float, y: list[float]) -> list[float]:
        if t > 0.55:
            raise StepFailure(f"failed at {t}", t)
        return [1.0]

    run = dop853(fun, 0.0, 1.0, [0.0], [0.0, 0.25, 0.5, 0.75, 1.0], rtol=1e-10, atol=[1e-12], max_step=0.1)
    assert run.failed_inside and run.message == f"failed at {run.t_fail}"
    assert run.t == [0.0, 0.25, 0.5] and np.allclose(run.y, [[0.0], [0.25], [0.5]], atol=1e-14)
    assert run.t_last <= 0.55 < run.t_fail <= run.t_last + 0.1
    assert run.y_last == pytest.approx([run.t_last], abs=1e-14)


def test_progress_is_told_the_accepted_steps() -> None:
    seen: list[float] = []
    run = dop853(
        lambda t, y: [math.cos(t)],
        0.0,
        3.0,
        [0.0],
        [0.0, 3.0],
        rtol=1e-8,
        atol=[1e-10],
        max_step=0.5,
        progress=seen.append,
        every=0.0,
    )
    assert run.message == "" and run.y[-1] == pytest.approx([math.sin(3.0)], abs=1e-8)
    assert len(seen) >= 6 and seen == sorted(seen) and seen[-1] == 3.0
    assert all(0 < b - a <= 0.5 for a, b in zip([0.0, *seen], seen))


# ------------------------------------------------------------------ simulate's two routes
@pytest.mark.parametrize(
    ("params", "expected"),
    [
        ({"a": 100.0, "k": 1.0}, "t = 1"),  # a blow-up
        ({"a": 0.5, "k": 0.2}, "failed at t = 0.5: Matrix is singular"),
        ({"a": 100.0, "k": 0.2}, ""),  # no failure (the blow-up would be at t = 5)
    ],
)
def test_the_list_route_ends_runs_as_the_scipy_route_does(failing, params, expected) -> None:
    """simulate's attempts on the numpy backend: the list stepper and SciPy's, through the same
    retries (_pinned), give the same samples and the same message.

    (Not necessarily after the same evaluations: y and z move at constant velocity, so their part
    of each error estimate is round-off, which the two steppers' sums of the same stages make
    differently; the tests above count evaluations on motions where it is not.)"""
    compiled = compile_model(failing, "chaplygin", "classic", "numpy")
    p = np.array([params[name] for name in compiled.layout.parameters])
    y0 = np.array([0.0, 0.0, 0.0, 1.0, 1.0])
    times = np.linspace(0.0, 2.0, 40)  # (no sample at the blow-up, t = 1: it has no value)
    runs = [
        _pinned(attempt(compiled, 2.0, p, 1e-10, 1e-12), 0.0, y0, times, np.inf)
        for attempt in (_list_attempt, lambda *a: _scipy_attempt(*a, "DOP853"))
    ]
    (t_list, y_list, message, _), (t_scipy, y_scipy, scipy_message, _) = runs
    assert message == scipy_message and expected in message
    assert bool(message) == bool(expected)
    assert np.array_equal(t_list, t_scipy)
    np.testing.assert_allclose(y_list, y_scipy, rtol=1e-10, atol=1e-12)


def test_numpy_backend_uses_the_list_stepper_for_dop853_only(failing) -> None:
    params = {"a": 100.0, "k": 0.0}
    start = {"x": 0.0, "y": 0.0, "z": 0.0, "x'": 1.0, "y'": 1.0}
    run = simulate(failing, "chaplygin", 1.0, start, params, backend="numpy", samples=11)
    assert run.success and run.backend == "numpy"
    np.testing.assert_allclose(run["x"], run.t, atol=1e-12)
    rk45 = simulate(failing, "chaplygin", 1.0, start, params, backend="numpy", method="RK45", samples=11)
    assert rk45.success and rk45.rhs_evaluations != run.rhs_evaluations  # SciPy's RK45 stepper


# ------------------------------------------------------------------ the generated list solver
@pytest.mark.parametrize("n", range(1, codegen.UNROLL_SOLVE + 1))
def test_unrolled_solver_is_the_list_solver(n: int) -> None:
    """``_msolve`` (written out for DIM) gives ``_lsolve``'s numbers bit for bit: the same pivots
    and operations; a singular matrix raises LinAlgError in both."""
    module = compile_model(examples.rolling_disk(), "chaplygin", "classic", "numpy").module
    namespace: dict = {"np": np}
    exec(codegen._unrolled_solve(n), namespace)
    unrolled = namespace["_msolve"]
    rng = np.random.default_rng(n)
    for _ in range(20):
        m = rng.normal(size=(n, n)).tolist()
        b = rng.normal(size=n).tolist()
        copies = [row[:] for row in m], b[:]
        assert unrolled(m, b) == module._lsolve(*copies)
        assert copies != (m, b) or n == 1  # _lsolve works in place; _msolve leaves M and b alone
    singular = rng.normal(size=(n, n))
    singular[:, n - 1] = 0.0
    for solve in (unrolled, module._lsolve):
        with pytest.raises(np.linalg.LinAlgError, match="singular"):
            solve(singular.tolist(), [1.0] * n)


# ------------------------------------------------------------------ no SciPy on the numpy path
CLI = """
import json, sys
from chaplygin.apps.cli import main
code = main(sys.argv[1:])
print(json.dumps({"code": code, "sympy": "sympy" in sys.modules,
                  "scipy": sorted(m for m in sys.modules if m.startswith("scipy.integrate"))}))
"""


def test_numpy_backend_runs_import_no_scipy_integrate(tmp_path: Path) -> None:
    """The full path (a first run: derivation, code generation) and the warm run plan."""
    args = ["simulate", "example:rolling-disk", "-m", "chaplygin", "-t", "2", "-n", "21", "-b", "numpy"]
    reports = [
        run_json(CLI, [*args, "-o", str(tmp_path / f"{name}.npz")], tmp_path / "cache")
        for name in ("cold", "warm")
    ]
    cold, warm = reports
    assert cold["code"] == warm["code"] == 0 and cold["sympy"] and not warm["sympy"]
    assert cold["scipy"] == warm["scipy"] == []
