"""Large systems: the numeric reduction equals the symbolic one, SymEngine's cse is exact,
B is solved for only when needed."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me
from hypothesis import given, settings
from hypothesis import strategies as st

from chaplygin import ChaplyginError, examples, simulate
from chaplygin.core._fast import cse
from chaplygin.numeric.codegen import compile_model
from randomsystems import Spec, systems


def rhs_pair(system, model: str, backend: str = "numpy"):
    return (
        compile_model(system, model, backend=backend, reduction="numeric"),
        compile_model(system, model, backend=backend, reduction="symbolic"),
    )


def assert_same_rhs(system, model: str, rng: np.random.Generator, states: int = 5) -> None:
    numeric, symbolic = rhs_pair(system, model)
    assert numeric.layout.state == symbolic.layout.state
    assert numeric.layout.parameters == symbolic.layout.parameters
    assert numeric.layout.form == "numeric"
    for _ in range(states):
        y = rng.uniform(-0.7, 0.7, len(numeric.layout.state))
        p = rng.uniform(0.5, 2.0, len(numeric.layout.parameters))
        t = float(rng.uniform(0, 1))
        a, b = numeric.rhs(t, y, p), symbolic.rhs(t, y, p)
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-10)
        # energy, residual and the velocities agree too (the residual is round-off)
        oa, ob = numeric.observe(t, y, p), symbolic.observe(t, y, p)
        np.testing.assert_allclose(oa, ob, rtol=1e-9, atol=1e-10)
        assert np.all(np.abs(oa[1 : 1 + system.g]) < 1e-10)


@given(spec=systems(), seed=st.integers(0, 2**32 - 1))
@settings(max_examples=10)
def test_numeric_reduction_equals_voronets_on_random_systems(spec: Spec, seed: int) -> None:
    """Affine, time-dependent, form A and B, with and without dependent-coordinate terms."""
    assert_same_rhs(spec.system, "voronets", np.random.default_rng(seed), states=3)


@pytest.mark.parametrize("name", ["rolling_sphere", "turntable_ball", "chaplygin_ball"])
def test_numeric_reduction_equals_chaplygin_and_voronets_on_examples(name: str) -> None:
    system = getattr(examples, name)()
    for model in ("chaplygin", "voronets") if system.is_chaplygin else ("voronets",):
        assert_same_rhs(system, model, np.random.default_rng(7))


def test_numeric_reduction_of_a_sleigh_chain() -> None:
    assert_same_rhs(examples.sleigh_chain(2), "voronets", np.random.default_rng(3))


def test_auto_reduces_numerically_from_six_coordinates() -> None:
    """A knife edge carrying three free rotors (6 coordinates, 1 constraint) reduces numerically,
    the rolling disk (5 coordinates, 2 constraints) symbolically: from 6 coordinates on the numeric
    route is the faster one from nothing to a right-hand side (``benchmarks/scaling.py
    --crossover``: 7–8 coordinates with 3 knife edges 0.4–0.5 s against 1.2–1.5 s symbolic); and
    the run ``auto`` picks gives the symbolic equations' accelerations."""
    from chaplygin import System
    from chaplygin.numeric.codegen import reduces_numerically

    x, y, th, a, b, c = me.dynamicsymbols("x y theta a b c")
    T = sum(q.diff() ** 2 for q in (x, y, th, a, b, c)) / 2 + sp.cos(a) * th.diff() * b.diff()
    knife = System([x, y, th, a, b, c], T, [sp.sin(th) * x.diff() - sp.cos(th) * y.diff()], dependent=[y])
    assert reduces_numerically(knife, "voronets")
    assert not reduces_numerically(examples.rolling_disk(), "chaplygin")
    auto = compile_model(knife, "voronets")
    assert auto.layout.form == "numeric"
    symbolic = compile_model(knife, "voronets", reduction="symbolic")
    rng = np.random.default_rng(5)
    y0, p = rng.uniform(-0.7, 0.7, len(auto.layout.state)), np.array([])
    np.testing.assert_allclose(auto.rhs(0.0, y0, p), symbolic.rhs(0.0, y0, p), rtol=1e-12, atol=1e-14)


def test_chaplygin_of_a_non_chaplygin_system_is_refused_numerically_too() -> None:
    with pytest.raises(ChaplyginError, match="not a Chaplygin system"):
        compile_model(examples.sleigh_chain(1), "chaplygin", reduction="numeric")
    with pytest.raises(ChaplyginError, match="reduction 'fast'.*'auto', 'symbolic', 'numeric'"):
        compile_model(examples.rolling_sphere(), "chaplygin", reduction="fast")


def test_large_chain_needs_no_symbolic_B_and_conserves_energy() -> None:
    """A chain of 13 sleighs (15 coordinates, 13 constraints): symbolic B is never formed."""
    chain = examples.sleigh_chain(12)
    initial = {c.func.__name__: 0.05 * ((-1) ** i) for i, c in enumerate(chain.coordinates)}
    initial.update({"x'": 1.0, "theta0'": 0.1})
    tr = simulate(chain, "voronets", 1.0, initial, {"m": 1.0, "I": 0.5, "L": 1.0}, samples=5)
    assert "_B" not in chain.__dict__  # lazily solved for, never needed here
    assert tr.success and tr.energy_drift() < 1e-8
    assert np.max(tr.constraint_residual) < 1e-12


def test_symengine_cse_is_exact() -> None:
    x, y, z = sp.symbols("x y z")
    exprs = [
        sp.sin(x + y) ** 2 + sp.cos(x + y) * z,
        sp.sqrt(x**2 + 1) / (x + y) + sp.Rational(1, 3),
        sp.exp(z) * sp.sin(x + y),
        sp.S(2),
    ]
    replacements, reduced = cse(exprs)
    assert [str(s) for s, _ in replacements] == [f"c_{k}" for k in range(len(replacements))]
    for e, r in zip(exprs, reduced):
        for s, v in reversed(replacements):
            r = r.xreplace({s: v})
        assert sp.simplify(e - r) == 0
    x0 = sp.Symbol("x0")  # a name SymEngine would use for its own symbols: SymPy's cse instead
    replacements, reduced = cse([sp.sin(x0) + sp.sin(x0) ** 2])
    assert reduced[0].has(x0) or any(v.has(x0) for _, v in replacements)


def test_numeric_reduction_of_a_chain_equals_kanes_method() -> None:
    """An independent oracle: KanesMethod with dependent speeds on the same chain (N = 3)."""
    import importlib.util
    from pathlib import Path

    import sympy.physics.mechanics as me  # noqa: F401 - the benchmark builds the Kane chain with it

    path = Path(__file__).resolve().parents[1] / "benchmarks" / "scaling.py"
    spec = importlib.util.spec_from_file_location("scaling_benchmark", path)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    n = 3
    M, F, q, u, params = bench.kane_derive(n)
    fM = sp.lambdify([*q, *u, *params], M)
    fF = sp.lambdify([*q, *u, *params], F)
    chain = examples.sleigh_chain(n)
    compiled = compile_model(chain, "voronets", reduction="numeric")
    values = {"m": 1.3, "I": 0.7, "L": 0.9}
    p = np.array([values[k] for k in compiled.layout.parameters])
    rng = np.random.default_rng(11)
    for _ in range(4):
        y = rng.uniform(-0.6, 0.6, len(compiled.layout.state))
        qd = compiled.observe(0.0, y, p)[-chain.n :]  # all velocities, on the constraints
        x = np.linalg.solve(
            fM(*y[: chain.n], *qd, values["m"], values["I"], values["L"]),
            fF(*y[: chain.n], *qd, values["m"], values["I"], values["L"])[:, 0],
        )
        np.testing.assert_allclose(
            compiled.rhs(0.0, y, p)[chain.n :], x[len(q) : len(q) + 2], rtol=1e-9, atol=1e-12
        )
