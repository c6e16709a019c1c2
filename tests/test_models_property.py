"""Ground truth on random systems: every reduced form has the accelerations of the
Chetaev multiplier system (6)/(35) at states that satisfy the constraints."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from randomsystems import Spec, matrix, number, random_state, systems, t


def multiplier_solution(spec: Spec, values: dict) -> dict:
    """Solve the (n+g) Chetaev system M·x = F numerically with NumPy."""
    eqs = spec.system.equations("chetaev")
    x = np.linalg.solve(matrix(eqs.mass_matrix, values), matrix(eqs.forcing, values)[:, 0])
    return dict(zip(eqs.unknowns, x))


def reduced_solution(spec: Spec, model: str, form: str, values: dict) -> dict:
    eqs = spec.system.equations(model, form)
    x = np.linalg.solve(matrix(eqs.mass_matrix, values), matrix(eqs.forcing, values)[:, 0])
    return dict(zip(eqs.unknowns, x))


def reduced_models(spec: Spec) -> list[tuple[str, str]]:
    out = [("voronets", "classic"), ("voronets", "new")]
    if spec.system.is_chaplygin:
        out += [("chaplygin", "classic"), ("chaplygin", "new")]
    return out


@given(spec=systems(), seed=st.integers(0, 2**32 - 1))
def test_reduced_forms_match_multiplier_system(spec: Spec, seed: int) -> None:
    rng = np.random.default_rng(seed)
    values = random_state(spec.system, rng)
    truth = multiplier_solution(spec, values)
    for model, form in reduced_models(spec):
        got = reduced_solution(spec, model, form, values)
        for acc, value in got.items():
            assert value == pytest.approx(truth[acc], rel=1e-8, abs=1e-8), (model, form, acc)


def assert_reduced_forms_match(spec: Spec, model: str, states: int = 6) -> None:
    """Both forms of ``model`` give the multiplier system's q̈_σ at ``states`` random admissible
    states, each of them every independent acceleration."""
    rng = np.random.default_rng(0)
    independent = {q.diff(t, 2) for q in spec.system.independent}
    for _ in range(states):
        values = random_state(spec.system, rng)
        truth = multiplier_solution(spec, values)
        for form in ("classic", "new"):
            got = reduced_solution(spec, model, form, values)
            assert set(got) == independent, (model, form)
            for acc, value in got.items():
                assert value == pytest.approx(truth[acc], rel=1e-8, abs=1e-8), (model, form, acc)


@given(spec=systems(chaplygin=True))
def test_chaplygin_detection_and_forms(spec: Spec) -> None:
    assert spec.system.is_chaplygin
    assert_reduced_forms_match(spec, "chaplygin")


@given(spec=systems(chaplygin=False))
def test_voronets_on_non_chaplygin_systems(spec: Spec) -> None:
    assert_reduced_forms_match(spec, "voronets")


@given(spec=systems(), seed=st.integers(0, 2**32 - 1), admissible=st.booleans())
@settings(max_examples=8)
def test_solved_multiplier_accelerations(spec: Spec, seed: int, admissible: bool) -> None:
    """The symbolic solution of the Chetaev system (q̈ and λ) solves M·x = F, also
    at states that violate the velocity constraints."""
    rng = np.random.default_rng(seed)
    values = random_state(spec.system, rng)
    if not admissible:
        values.update({v: sp.Float(rng.uniform(-1, 1)) for v in spec.system.constraints})
    truth = multiplier_solution(spec, values)
    solved = spec.system.equations("chetaev").accelerations
    assert set(solved) == set(truth)
    for key, expr in solved.items():
        assert number(expr, values) == pytest.approx(truth[key], rel=1e-8, abs=1e-8), key


@given(spec=systems(affine=False, forces=False, gyroscopic=False), seed=st.integers(0, 2**32 - 1))
def test_energy_is_conserved_by_reduced_equations(spec: Spec, seed: int) -> None:
    """Physics oracle, independent of the multipliers: with homogeneous scleronomic
    constraints and potential forces only, d/dt (T − U) = 0 along the motion."""
    s = spec.system
    if not s.is_scleronomic:
        return
    values = random_state(s, np.random.default_rng(seed))
    got = reduced_solution(spec, "voronets", "classic", values)
    # dependent accelerations from the constraints differentiated in time
    for vel, rhs in s.constraints.items():
        got[vel.diff(t)] = number(rhs.diff(t), {**values, **got})
    values.update({k: sp.Float(v) for k, v in got.items()})
    energy = s.kinetic_energy - s.force_function
    assert number(energy.diff(t), values) == pytest.approx(0, abs=1e-9)


@given(spec=systems(), seed=st.integers(0, 2**32 - 1))
@settings(max_examples=12)
def test_classic_mass_matrix_is_the_jacobian_of_the_equations(spec: Spec, seed: int) -> None:
    """The classic forms' M is ∂²T̃/∂q̇_σ∂q̇_τ (models.reduced.reduced_mass_matrix, not the
    residuals' Jacobian): SymPy's own Jacobian of the printed equations in the accelerations
    must give the same numbers."""
    s = spec.system
    values = random_state(s, np.random.default_rng(seed))
    for model in ("voronets", "chaplygin") if s.is_chaplygin else ("voronets",):
        eqs = s.equations(model, "classic")
        oracle = sp.Matrix(eqs.residuals).jacobian(list(eqs.unknowns))
        assert matrix(eqs.mass_matrix, values) == pytest.approx(matrix(oracle, values), rel=1e-10, abs=1e-12)


@given(spec=systems(), seed=st.integers(0, 2**32 - 1))
@settings(max_examples=4)
def test_the_float_evaluator_is_sympys_evalf(spec: Spec, seed: int) -> None:
    """The oracle of these tests (randomsystems.number: floats, memoised on the expression's
    tree) gives SymPy's own numbers (xreplace + evalf) on the derived equations."""
    values = random_state(spec.system, np.random.default_rng(seed))
    eqs = spec.system.equations("chetaev")
    for e in [*eqs.mass_matrix, *eqs.forcing]:
        assert number(e, values) == pytest.approx(float(sp.N(e.xreplace(values))), rel=1e-12, abs=1e-12)
