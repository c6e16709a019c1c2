"""Backends and integrators: the compiled DOP853 loop, the jax backend, ensembles.

The compiled loop (``backend="numba"``, and its C port, ``backend="c"``) is a port of SciPy's DOP853, so it must
reproduce SciPy's runs (``backend="numpy"`` drives SciPy's stepper) to well
within the tolerance; failures must come back as a status with the trajectory
so far.  JAX tests are skipped when the optional extra is not installed.
"""

from __future__ import annotations

import numpy as np
import pytest

from chaplygin import ChaplyginError, System, examples
from chaplygin.numeric._ckernel import Unavailable, compiler
from chaplygin.numeric._loop import integrate_dop853, loop_model, shared
from chaplygin.numeric.codegen import compile_equations, compile_model
from chaplygin.numeric.ensemble import simulate_ensemble
from chaplygin.numeric.simulate import _initial_multipliers, initial_state, simulate

try:
    compiler()
    LOOPS = ["numba", "c"]
except Unavailable:  # pragma: no cover - every CI machine has a C compiler
    LOOPS = ["numba"]

DISK_P = {"m": 1.0, "r": 0.5, "A": 0.0625, "C": 0.125, "g": 9.81}
DISK_0 = {"psi": 0.0, "theta": 0.3, "phi": 0.0, "x": 0.0, "y": 0.0, "psi'": 2.0, "theta'": 0.0, "phi'": 5.0}
SPHERE_P = {"m": 1.0, "a": 1.0}
SPHERE_0 = {
    "psi": 0.3,
    "theta": 1.0,
    "phi": 0.1,
    "x": 0.0,
    "y": 0.0,
    "psi'": 0.5,
    "theta'": 0.4,
    "phi'": -0.7,
}


@pytest.fixture(scope="module")
def disk() -> System:
    return examples.rolling_disk()


@pytest.fixture(scope="module")
def sphere() -> System:
    return examples.rolling_sphere()


FAILING_0 = {"x": 0.0, "y": 0.0, "z": 0.0, "x'": 1.0, "y'": 1.0}


def _max_difference(a, b) -> float:
    assert a.columns == b.columns
    assert np.array_equal(a.t, b.t)
    return max(float(np.max(np.abs(a[c] - b[c]))) for c in a.columns)


# ------------------------------------------------------------------ compiled DOP853
@pytest.mark.parametrize("loop", LOOPS)
@pytest.mark.parametrize("which", ["disk", "sphere"])
def test_compiled_loop_reproduces_scipy_dop853(which, loop, disk, sphere):
    system, start, params = (disk, DISK_0, DISK_P) if which == "disk" else (sphere, SPHERE_0, SPHERE_P)
    scipy_run = simulate(system, "chaplygin", 10.0, start, params, backend="numpy", samples=101)
    loop_run = simulate(system, "chaplygin", 10.0, start, params, backend=loop, samples=101)
    assert scipy_run.success and loop_run.success, loop_run.message
    assert loop_run.backend == loop
    assert _max_difference(scipy_run, loop_run) < 1e-8
    # the same step controller as SciPy's: about the same number of right-hand-side evaluations
    # (not exactly: LAPACK's solve and the loop's elimination differ in round-off, which can tip a
    # step's acceptance differently on another machine)
    assert abs(loop_run.rhs_evaluations - scipy_run.rhs_evaluations) <= 0.05 * scipy_run.rhs_evaluations
    assert loop_run.energy_drift() < 1e-9


def test_loop_derivative_equals_generated_rhs(disk):
    """The loop's allocation-free fill + elimination gives the generated rhs's numbers."""
    model = loop_model(compile_equations(disk.equations("chaplygin"), "numba"))
    rng = np.random.default_rng(1)
    p = np.array([0.0625, 0.125, 9.81, 1.0, 0.5])
    times = np.array([0.0])
    for _ in range(5):
        y0 = rng.uniform(-1, 1, 8)
        # one sample at t0 and a tiny first step: the first derivative is what we compare
        first = np.empty(8)
        module = model.module
        M, b, V, O = (
            np.empty((module.DIM, module.DIM)),
            np.empty(module.DIM),
            np.empty(module.N),
            np.empty(module.N_OBSERVED),
        )
        assert shared()._k_eval(module.MODEL, 0.0, y0, p, first, M, b, V, O) == 0
        np.testing.assert_allclose(first, module.rhs(0.0, y0, p), rtol=1e-13, atol=1e-13)
    result = integrate_dop853(model, (0.0, 1.0), y0, p, times)
    _t, y, status, message, n_rhs = result[:5]
    assert status == "success" and message == "reached t = 1" and n_rhs > 0
    assert np.array_equal(y[0], y0)


def test_loop_observe_equals_generated_observe():
    """The loop's observe (energy, residuals, reactions λ, velocities) is the generated one."""
    system = examples.vertical_rolling_disk()
    eqs = system.equations("chetaev")
    model = loop_model(compile_equations(eqs, "numba"))
    ref = compile_equations(eqs, "numpy")
    assert model.layout.reactions  # λ are computed, not integrated
    rng = np.random.default_rng(3)
    p = np.array([1.3, 0.4, 0.7, 0.5])
    for _ in range(4):
        y = rng.uniform(-1, 1, len(model.layout.state))
        np.testing.assert_allclose(model.observe(0.0, y, p), ref.observe(0.0, y, p), rtol=1e-12, atol=1e-12)


@pytest.mark.skipif("c" not in LOOPS, reason="no C compiler")
def test_c_loop_is_the_numba_loop(disk):
    """The C port takes the numba loop's steps: the same evaluations, the same numbers to round-off."""
    runs = [simulate(disk, "chaplygin", 5.0, DISK_0, DISK_P, backend=b, samples=51) for b in ("numba", "c")]
    assert runs[0].rhs_evaluations == runs[1].rhs_evaluations
    assert _max_difference(*runs) < 1e-12


def _not_real_after() -> System:
    """ẍ = √(a − t) (ż = ẏ, ÿ = 0): the force is NaN from t = a on, inside a step."""
    import sympy as sp
    from sympy.physics.mechanics import dynamicsymbols

    from chaplygin.core._symbols import TIME

    x, y, z = dynamicsymbols("x y z")
    a = sp.Symbol("a", positive=True)
    T = sp.Rational(1, 2) * (x.diff(TIME) ** 2 + y.diff(TIME) ** 2)
    return System([x, y, z], T, {z.diff(TIME): y.diff(TIME)}, forces={x: sp.sqrt(a - TIME)}, name="not real")


@pytest.mark.skipif("c" not in LOOPS, reason="no C compiler")
@pytest.mark.parametrize(
    "which, params, code",
    [
        ("failing", {"a": 100.0, "k": 1.0}, 1),  # blows up: the step size underflows at t = 1
        ("failing", {"a": 0.5, "k": 0.0}, 5),  # the mass of y is 0 from t = 0.5 on
        ("not real", {"a": 0.55}, 2),  # NaN from t = 0.55 on
    ],
)
def test_c_loop_fails_where_the_numba_loop_fails(failing, which, params, code):
    """Issue 31: the C loop evaluates a step's stages without checking each value and checks the
    step again only where its error norm is not finite or a solve failed; a run that fails inside
    a step still ends where the numba loop, which checks every evaluation, ends: the same status,
    count, samples, last step and failing state."""
    system = failing if which == "failing" else _not_real_after()
    q, qd = initial_state(system, FAILING_0, dict.fromkeys(params, 1.0), 0.0)
    y0 = np.concatenate([q, qd[list(system._ind)]])
    runs = []
    for backend in ("numba", "c"):
        model = compile_model(system, "chaplygin", "classic", backend)
        p = np.array([params[name] for name in model.layout.parameters])
        runs.append(integrate_dop853(model, (0.0, 2.0), y0, p, np.linspace(0.0, 2.0, 21)))
    numba, c = runs
    assert numba.code == c.code == code, (numba.message, c.message)
    assert (numba.n_rhs, numba.n_steps, numba.message) == (c.n_rhs, c.n_steps, c.message)
    np.testing.assert_array_equal(numba.t, c.t)
    np.testing.assert_allclose(c.y, numba.y, rtol=1e-12, atol=1e-14)
    assert c.t_last == pytest.approx(numba.t_last, rel=1e-12)
    assert c.t_fail == pytest.approx(numba.t_fail, rel=1e-12)
    np.testing.assert_allclose(c.y_last, numba.y_last, rtol=1e-12, atol=1e-14)


@pytest.mark.skipif("c" not in LOOPS, reason="no C compiler")
def test_c_observe_and_rhs_equal_generated_code():
    """The C kernel's rhs and observe (energy, residuals, reactions λ, velocities) are the generated module's."""
    system = examples.vertical_rolling_disk()
    eqs = system.equations("chetaev")
    model, ref = compile_equations(eqs, "c"), compile_equations(eqs, "numpy")
    assert model.layout == ref.layout and model.layout.reactions
    rng = np.random.default_rng(4)
    p = np.array([1.3, 0.4, 0.7, 0.5])
    for _ in range(4):
        y = rng.uniform(-1, 1, len(model.layout.state))
        np.testing.assert_allclose(model.observe(0.0, y, p), ref.observe(0.0, y, p), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(model.rhs(0.0, y, p), ref.rhs(0.0, y, p), rtol=1e-12, atol=1e-12)


def test_numba_loop_other_methods_fall_back_to_scipy(disk):
    run = simulate(disk, "chaplygin", 1.0, DISK_0, DISK_P, backend="numba", method="RK45", samples=11)
    ref = simulate(disk, "chaplygin", 1.0, DISK_0, DISK_P, backend="numpy", method="RK45", samples=11)
    assert run.success and _max_difference(run, ref) < 1e-12


@pytest.mark.parametrize("backend", ["numpy", *LOOPS])
def test_blow_up_is_a_status_with_partial_trajectory(failing, backend):
    run = simulate(failing, "chaplygin", 2.0, FAILING_0, {"a": 100.0, "k": 1.0}, backend=backend, samples=21)
    assert run.status == "failed" and not run.success
    assert "t = 1" in run.message and ("step size" in run.message or "blew up" in run.message)
    # samples up to the blow-up at t = 1 (x = -ln(1 - t)), none after
    assert 2 <= len(run.t) < 21 and run.t[-1] <= 1.0
    before = run.t < 0.95
    np.testing.assert_allclose(run["x"][before], -np.log1p(-run.t[before]), rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("backend", ["numpy", *LOOPS])
@pytest.mark.parametrize("samples", [21, 201])
def test_singular_mass_matrix_is_a_status_with_partial_trajectory(failing, backend, samples):
    """The mass of y drops to 0 at t = 0.5: every sample before it is kept, whatever steps the
    integrator took (a step that fails is retried with smaller ones until the failure is pinned)."""
    run = simulate(
        failing, "chaplygin", 2.0, FAILING_0, {"a": 0.5, "k": 0.0}, backend=backend, samples=samples
    )
    assert run.status == "failed"
    assert "singular" in run.message.lower() and "t = 0.5" in run.message, run.message
    times = np.linspace(0.0, 2.0, samples)
    np.testing.assert_array_equal(run.t, times[times < 0.5])
    np.testing.assert_allclose(run["x"], run.t, atol=1e-12)  # uniform motion until then
    assert np.all(np.isfinite(run.table()))


@pytest.mark.parametrize("backend", ["numpy", *LOOPS])
def test_a_pole_of_the_solved_constraints_stops_a_reduced_run(backend):
    """The knife edge's ẏ = tan φ ẋ has a pole at φ = π/2, reached at t = π/2 − 1.2 ≈ 0.371:
    the reduced run stops at the sample before it (t = 0.35); the multiplier model runs on."""
    knife = examples.knife_edge()
    start = {"x": 0.0, "y": 0.0, "phi": 1.2, "x'": 1.0, "phi'": 1.0}
    params = {"m": 1.0, "J": 0.5}
    run = simulate(knife, "chaplygin", 1.0, start, params, backend=backend, samples=21)
    assert run.status == "failed" and run.failure == "pole", run.message
    assert "between t = 0.35 and 0.4" in run.message and "y'" in run.message
    assert run.t[-1] == pytest.approx(0.35)
    true = simulate(knife, "chetaev", 1.0, start, params, backend=backend, samples=21)
    assert true.success and true.failure == "" and true.energy_drift() < 1e-8


# ------------------------------------------------------------------ ensembles
def test_ensemble_final_states_equal_single_runs(disk):
    thetas = [0.1, 0.25, 0.4]
    starts = [{**DISK_0, "theta": th, "phi'": 4.0 + th} for th in thetas]
    ens = simulate_ensemble(disk, "chaplygin", 5.0, starts, DISK_P, backend="numba")
    assert ens.success.all() and np.all(ens.t == 5.0)
    for i, start in enumerate(starts):
        single = simulate(disk, "chaplygin", 5.0, start, DISK_P, backend="numba", samples=2)
        for name in ("psi", "theta", "phi", "x", "y", "psi'", "theta'", "phi'", "x'", "y'", "energy"):
            assert abs(ens[name][i] - single[name][-1]) < 1e-12, name
    assert np.max(ens.energy_drift()) < 1e-9
    # the same members as an array in layout order, and with samples kept
    layout = compile_equations(disk.equations("chaplygin"), "numpy").layout
    Y0 = np.array([[s[name] for name in layout.state] for s in starts])
    again = simulate_ensemble(disk, "chaplygin", 5.0, Y0, DISK_P, backend="numba", keep=6)
    np.testing.assert_allclose(again.y, ens.y, rtol=0, atol=1e-12)
    single = simulate(disk, "chaplygin", 5.0, starts[1], DISK_P, backend="numpy", samples=6)
    np.testing.assert_allclose(again.samples[1][:, 1], single["theta"], atol=1e-8)


def test_ensemble_parameter_sweep_and_a_failing_member(disk):
    """One member with no inertia at all (a zero mass matrix) fails; the others run on."""
    masses = np.array([1.0, 0.0, 2.0])
    params = {**DISK_P, "m": masses, "A": 0.0625 * masses, "C": 0.125 * masses}
    ens = simulate_ensemble(disk, "chaplygin", 2.0, [DISK_0] * 3, params, backend="numba")
    assert list(ens.status) == ["success", "failed", "success"]
    assert "singular" in ens.messages[1] and ens.t[1] == 0.0 and ens.code[1] == 5
    # mass scales out of the disk's motion
    np.testing.assert_allclose(ens.y[0], ens.y[2], rtol=1e-9, atol=1e-9)


def test_the_c_ensemble_takes_the_numba_ensembles_steps(disk):
    """backend="c" (what "auto" picks here) is a port of the numba loop: the same members give the
    same states, samples, statuses and step counts, a failing member included, on two threads."""
    from chaplygin.numeric._ckernel import Unavailable, compiler

    try:
        compiler()
    except Unavailable as exc:
        pytest.skip(f"no C loop here: {exc}")
    masses = np.array([1.0, 0.0, 2.0, 1.5])
    params = {**DISK_P, "m": masses, "A": 0.0625 * masses, "C": 0.125 * masses}
    starts = [{**DISK_0, "theta": 0.1 * k, "phi'": 4.0 + k} for k in range(4)]
    runs = {
        backend: simulate_ensemble(disk, "chaplygin", 3.0, starts, params, backend=backend, keep=7, threads=2)
        for backend in ("auto", "numba")
    }
    c, nb = runs["auto"], runs["numba"]
    assert (c.backend, nb.backend) == ("c", "numba")
    assert list(c.code) == list(nb.code) == [0, 5, 0, 0]
    np.testing.assert_array_equal(np.isnan(c.samples), np.isnan(nb.samples))  # NaN after the failure
    assert np.isnan(c.samples[1, 1:]).all() and not np.isnan(c.samples[[0, 2, 3]]).any()
    for field in ("y", "t", "energy", "constraint_residual"):
        np.testing.assert_allclose(getattr(c, field), getattr(nb, field), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(c.samples[[0, 2, 3]], nb.samples[[0, 2, 3]], rtol=1e-10, atol=1e-12)
    assert np.abs(c.rhs_evaluations - nb.rhs_evaluations).max() <= 0.05 * nb.rhs_evaluations.max()
    # a step budget stops every member where the numba loop stops it
    short = {
        b: simulate_ensemble(disk, "chaplygin", 3.0, starts[:1], DISK_P, backend=b, max_steps=5)
        for b in ("c", "numba")
    }
    assert list(short["c"].code) == list(short["numba"].code) == [4]
    assert short["c"].t[0] == short["numba"].t[0] < 3.0


def test_ensemble_input_errors(disk):
    with pytest.raises(ChaplyginError, match="shape"):
        simulate_ensemble(disk, "chaplygin", 1.0, np.zeros((2, 3)), DISK_P)
    with pytest.raises(ChaplyginError, match="backend"):
        simulate_ensemble(disk, "chaplygin", 1.0, [DISK_0], DISK_P, backend="numpy")
    for backend in ("auto", "c"):
        with pytest.raises(
            ChaplyginError,
            match=f"method 'Radau': backend '{backend}' integrates ensembles with 'DOP853' only",
        ):
            simulate_ensemble(disk, "chaplygin", 1.0, [DISK_0], DISK_P, backend=backend, method="Radau")
    with pytest.raises(ChaplyginError, match="parameters"):
        simulate_ensemble(disk, "chaplygin", 1.0, [DISK_0, DISK_0], {**DISK_P, "m": [1.0, 2.0, 3.0]})


def test_ensemble_dict_states_equal_array_states(disk):
    """Mappings are prepared in one vectorised step: the same states as an array in layout order,
    and the dependent velocities (and vakonomic μ(0)) of simulate's one-state path."""
    rng = np.random.default_rng(7)
    starts = [
        {**DISK_0, "theta": th, "psi": ps, "phi'": w}
        for th, ps, w in zip(rng.uniform(0.1, 0.4, 6), rng.uniform(-1, 1, 6), rng.uniform(3, 6, 6))
    ]
    layout = compile_equations(disk.equations("chaplygin"), "numpy").layout
    Y0 = np.array([[s[name] for name in layout.state] for s in starts])
    from_dicts = simulate_ensemble(disk, "chaplygin", 0.5, starts, DISK_P, keep=2)
    from_array = simulate_ensemble(disk, "chaplygin", 0.5, Y0, DISK_P, keep=2)
    assert np.array_equal(from_dicts.samples, from_array.samples) and np.array_equal(
        from_dicts.y, from_array.y
    )
    assert np.array_equal(from_dicts.samples[:, 0], Y0)
    # all velocities integrated: the dependent ones (x', y') follow from the constraints (the
    # preparation itself, chaplygin.numeric.ensemble._states: the same for every backend, and it spares
    # two more models compiled by numba)
    from chaplygin.models import registry
    from chaplygin.numeric.ensemble import _parameter_matrix, _states
    from chaplygin.numeric.simulate import _vakonomic_setup

    def prepared(system, model, states, params, constants=None):
        entry = registry.get(model)  # (the inner functions take the registry's entry)
        family_c, vak = _vakonomic_setup(system, entry, constants, None)
        layout = compile_model(system, entry, "classic", "numpy", constants=family_c).layout
        P, _ = _parameter_matrix(system, layout, params, len(states))
        return _states(system, entry, layout, states, P, vak, 0.0)

    chetaev = prepared(disk, "chetaev", starts, DISK_P)
    for k, start in enumerate(starts):
        q, qd = initial_state(disk, start, DISK_P, 0.0)
        np.testing.assert_allclose(chetaev[k], np.concatenate([q, qd]), rtol=1e-14, atol=1e-14)
    # vakonomic μ(0) from constants c, per member (parameters per member too)
    knife = examples.knife_edge()
    masses = np.array([1.0, 2.0, 3.0])
    knife_starts = [{"x": 0.0, "y": 0.0, "phi": 0.1 * k, "x'": 1.0 + k, "phi'": 0.5} for k in range(3)]
    vak = prepared(knife, "vakonomic", knife_starts, {"m": masses, "J": 2.0}, constants=[0.3])
    for k, start in enumerate(knife_starts):
        params = {"m": masses[k], "J": 2.0}
        q, qd = initial_state(knife, start, params, 0.0)
        mu = _initial_multipliers(knife, {"constants": [0.3]}, q, qd, params, 0.0)
        np.testing.assert_allclose(vak[k], np.concatenate([q, qd, mu]), rtol=1e-14, atol=1e-14)


def test_ensemble_dict_errors_name_the_member_and_key(disk):
    """(The Chaplygin model, which this module's numba runs compile anyway: the mappings are read
    and checked alike for every model, dependent velocities included.)"""

    def error(starts, **options) -> str:
        with pytest.raises(ChaplyginError) as info:
            simulate_ensemble(disk, "chaplygin", 1.0, starts, DISK_P, **options)
        return str(info.value)

    others = [DISK_0] * 3
    assert error([*others, {**DISK_0, "psy": 0.1}]).startswith(
        "initial_states[3]: 'psy' is neither a coordinate nor a velocity of"
    )
    lacking = {k: v for k, v in DISK_0.items() if k != "theta'"}
    assert error([DISK_0, DISK_0, lacking]).startswith(
        "initial_states[2]: missing theta'; give every coordinate"
    )
    assert error([DISK_0, {**DISK_0, "x": "east"}]) == (
        "initial_states[1]: x = 'east' is not a number; give a finite number."
    )
    assert error([DISK_0, {**DISK_0, "x'": 3.0}]).startswith(
        "initial_states[1]: x' = 3 violates the constraints"
    )
    assert error([DISK_0, np.zeros(10)]).startswith("initial_states[1]: expected a mapping")
    _, qd = initial_state(disk, DISK_0, DISK_P, 0.0)  # a given dependent velocity that agrees is accepted
    agreeing = {**DISK_0, "x'": float(qd[3]), "y'": float(qd[4])}
    ens = simulate_ensemble(disk, "chaplygin", 0.1, [DISK_0, agreeing], DISK_P)
    assert ens.success.all()


# ------------------------------------------------------------------ jax
@pytest.fixture(scope="module")
def jax_disk(disk):
    pytest.importorskip("jax")
    pytest.importorskip("diffrax")
    return compile_equations(disk.equations("chaplygin"), "jax")


def test_jax_functions_equal_generated_code(disk, jax_disk):
    ref = compile_equations(disk.equations("chaplygin"), "numpy")
    assert jax_disk.layout == ref.layout
    rng = np.random.default_rng(2)
    p = np.array([0.0625, 0.125, 9.81, 1.0, 0.5])
    for _ in range(3):
        y = rng.uniform(-1, 1, 8)
        np.testing.assert_allclose(jax_disk.rhs(0.0, y, p), ref.rhs(0.0, y, p), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(
            jax_disk.observe(0.0, y, p), ref.observe(0.0, y, p), rtol=1e-12, atol=1e-12
        )


def test_jax_simulate_agrees_with_scipy(disk, jax_disk):
    ref = simulate(disk, "chaplygin", 10.0, DISK_0, DISK_P, backend="numpy", samples=101)
    run = simulate(disk, "chaplygin", 10.0, DISK_0, DISK_P, backend="jax", samples=101)
    assert run.success and run.backend == "jax"
    assert _max_difference(ref, run) < 1e-7  # Dopri8, not DOP853: agreement to tolerance
    assert run.energy_drift() < 1e-8


def test_jax_failure_is_a_status(failing):
    pytest.importorskip("diffrax")
    run = simulate(failing, "chaplygin", 2.0, FAILING_0, {"a": 0.5, "k": 0.0}, backend="jax", samples=21)
    assert run.status == "failed" and "t = 0.5" in run.message
    assert 2 <= len(run.t) <= 6 and np.all(np.isfinite(run.table()))


def test_jax_ensemble_equals_single_runs(disk, jax_disk):
    starts = [{**DISK_0, "theta": th} for th in (0.3, 0.2)]
    ens = simulate_ensemble(disk, "chaplygin", 10.0, starts, DISK_P, backend="jax")
    assert ens.success.all()
    # the first member is test_jax_simulate_agrees_with_scipy's run (its solver is compiled)
    single = simulate(disk, "chaplygin", 10.0, starts[0], DISK_P, backend="jax", samples=101)
    for name in ("psi", "theta", "phi", "x", "y", "theta'", "x'", "energy"):
        assert abs(ens[name][0] - single[name][-1]) < 1e-10, name
    for i, start in enumerate(starts):
        numba_single = simulate(disk, "chaplygin", 10.0, start, DISK_P, backend="numba", samples=2)
        assert abs(ens["x"][i] - numba_single["x"][-1]) < 1e-7
