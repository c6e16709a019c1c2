"""Ground truth for constraints nonlinear in the velocities (issue 30), on random systems
(:func:`randomsystems.nonlinear_system`): every reduced form has the accelerations of its model's
multiplier system, solved numerically at random admissible states; the Appell–Chetaev model is
invariant under ``f → h·f``; a linear constraint written squared moves as the linear one; the
constraint forces do no virtual work, and no work along the motion exactly where the
constraints are homogeneous; and one system's Chetaev equations derived by hand here."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
import sympy as sp

from chaplygin import System
from chaplygin.core._sampling import StateSampler, parameter_values
from randomsystems import (
    NONLINEAR_KINDS,
    NonlinearSpec,
    matrix,
    nonlinear_system,
    number,
    numbers,
    seeded_system,
    t,
    with_branch,
)

SEEDS = range(8)
TOL = {"rel": 1e-7, "abs": 1e-7}


@cache
def spec_of(seed: int, **options: bool) -> NonlinearSpec:
    """The random system of ``seed`` (one object per seed and options: its derivations are
    shared by the tests), coefficients with many digits for every third seed."""
    return nonlinear_system(seed, floats=seed % 3 == 2, **options)


def admissible_states(spec: NonlinearSpec, count: int, seed: int = 0) -> list[dict]:
    """``count`` random states from chaplygin's sampler (public symbols, SymPy Floats), each
    checked here to satisfy the constraints as the test wrote them, ``f(q, q̇, t) = 0``."""
    s = spec.system
    rng = np.random.default_rng(seed)
    sampler = StateSampler(s, parameter_values(s, rng))
    out = []
    for _ in range(count):
        values = {s._to_fun.get(k, k): sp.Float(v) for k, v in sampler.draw(rng).items()}
        for f in spec.f:
            scale = 1 + sum(abs(number(term, values)) for term in sp.Add.make_args(sp.expand(f)))
            assert abs(number(f, values)) <= 1e-9 * scale, (f, values)
        out.append(values)
    return out


def solution(eqs, values: dict) -> dict:
    """``M x = F`` of ``eqs`` evaluated at ``values`` and solved with NumPy."""
    x = np.linalg.solve(matrix(eqs.mass_matrix, values), matrix(eqs.forcing, values)[:, 0])
    return dict(zip(eqs.unknowns, x))


def assert_same(got: dict, truth: dict, keys, what) -> None:
    for key in keys:
        assert got[key] == pytest.approx(truth[key], **TOL), (what, key)


def reduced_forms(system: System) -> list[tuple[str, str]]:
    out = [("voronets", "classic"), ("voronets", "new")]
    return out + ([("chaplygin", "classic"), ("chaplygin", "new")] if system.is_chaplygin else [])


def dependent_block(f: list[sp.Expr], system: System, values: dict) -> np.ndarray:
    """``∂f_β/∂q̇_{dep γ}`` of the constraints ``f`` as the test wrote them, at ``values``
    (SymPy's diff here, not the system's A)."""
    return np.array([numbers([sp.diff(fb, q.diff(t)) for q in system.dependent], values) for fb in f])


def given(system: System) -> list[sp.Expr]:
    """The constraints ``f = 0`` exactly as the test's generator gave them to ``system``."""
    if system.constraint_form == "A":
        return list(system._given_constraints)
    return [q.diff(t) - e for q, e in zip(system.dependent, system._given_constraints)]


# ------------------------------------------------------------------ the generator
def test_generator_draws_every_kind_and_option() -> None:
    """The seeds the tests use cover both input forms, Chaplygin and not, homogeneous and not,
    explicit time, two constraints, every kind; each system is read as nonlinear, its solved
    form is the one drawn, and is_affine says 'not homogeneous'."""
    specs = [spec_of(seed) for seed in SEEDS]
    assert {True, False} <= {s.implicit for s in specs} & {s.chaplygin for s in specs}
    assert {True, False} <= {s.homogeneous for s in specs} & {s.timed for s in specs}
    assert {1, 2} <= {s.system.g for s in specs}
    assert set().union(*(s.kinds for s in specs)) == set(NONLINEAR_KINDS)
    for spec in specs:
        s = spec.system
        assert s.is_nonlinear and s.is_chaplygin == spec.chaplygin
        assert s.is_affine == (not spec.homogeneous)
        values = admissible_states(spec, 1)[0]
        for v, phi in spec.phi.items():
            assert number(s.constraints[v], values) == pytest.approx(number(phi, values), rel=1e-12)


# ------------------------------------------------------------------ Chetaev: Novoselov's equations
@pytest.mark.parametrize("seed", SEEDS)
def test_reduced_forms_equal_the_multiplier_system(seed: int) -> None:
    """Novoselov's equations (Voronets' classic and new forms; Chaplygin's for Chaplygin systems)
    give the accelerations of the Appell–Chetaev multiplier system M x = F, solved by NumPy."""
    spec = spec_of(seed)
    s = spec.system
    independent = [q.diff(t, 2) for q in s.independent]
    for values in admissible_states(spec, 3, seed):
        truth = solution(s.equations("chetaev"), values)
        for model, form in reduced_forms(s):
            got = solution(s.equations(model, form), values)
            assert set(got) == set(independent), (model, form)
            assert_same(got, truth, independent, (model, form))


# ------------------------------------------------------------------ vakonomic: family and Lindelöf
@pytest.mark.parametrize("seed", SEEDS)
def test_vakonomic_family_equals_the_multiplier_system(seed: int) -> None:
    """The family member with constants c (and Lindelöf's, c = 0, where its mass matrix is
    regular) has the accelerations of the vakonomic multiplier system at μ with
    ∂T/∂q̇_dep + μ ∂f/∂q̇_dep = c (the integral of the dependent equations, computed here), which
    is also what ``integrated_multipliers(c)`` gives."""
    spec = spec_of(seed, chaplygin=True)
    s = spec.system
    vak = s.equations("vakonomic")
    rng = np.random.default_rng(seed)
    c = [sp.Float(x) for x in rng.uniform(-1, 1, size=s.g)]
    integrated = s.integrated_multipliers(c)
    independent = [q.diff(t, 2) for q in s.independent]
    lindelof_checked = 0
    for values in admissible_states(spec, 2, seed):
        for consts in (c, [0] * s.g):
            momenta = [number(sp.diff(s.kinetic_energy, q.diff(t)), values) for q in s.dependent]
            mu = np.linalg.solve(
                dependent_block(spec.f, s, values).T, np.array(consts, dtype=float) - momenta
            )
            state = {**values, **dict(zip(vak.multipliers, map(sp.Float, mu)))}
            truth = solution(vak, state)
            members = [s.equations("vakonomic_family", form, constants=consts) for form in ("classic", "new")]
            if consts is c:
                for m, expr in integrated.items():
                    assert number(expr, values) == pytest.approx(mu[vak.multipliers.index(m)], **TOL)
            else:
                lindelof = [s.equations("lindelof", form) for form in ("classic", "new")]
                regular = [e for e in lindelof if np.linalg.cond(matrix(e.mass_matrix, values)) < 1e8]
                lindelof_checked += len(regular)
                members += regular
            for eqs in members:
                assert_same(solution(eqs, values), truth, independent, (eqs.model, eqs.form, consts))
    assert lindelof_checked


# ------------------------------------------------------------------ f → h·f
@pytest.mark.parametrize("seed", SEEDS)
def test_models_are_invariant_under_a_factor(seed: int) -> None:
    """The Appell–Chetaev and vakonomic models of h·f = 0, h = 1 + q̇₁² + q₂² ≠ 0, move as
    those of f = 0: the same q̈ at admissible states, λ_h = λ/h, and μ_h = μ/h."""
    spec = spec_of(seed, implicit=True)
    s = spec.system
    q = s.coordinates
    h = 1 + q[0].diff(t) ** 2 + q[1] ** 2
    scaled = with_branch(
        list(q), s.kinetic_energy, [h * f for f in spec.f], list(s.dependent), spec.phi,
        first=s._branch, force_function=s.force_function, forces=s.forces or None,
    )  # fmt: skip
    accelerations = [qi.diff(t, 2) for qi in q]
    for values in admissible_states(spec, 2, seed):
        hv = number(h, values)
        truth, got = solution(s.equations("chetaev"), values), solution(scaled.equations("chetaev"), values)
        assert_same(got, truth, accelerations, "chetaev")
        for lam, lam_h in zip(s.equations("chetaev").multipliers, scaled.equations("chetaev").multipliers):
            assert got[lam_h] == pytest.approx(truth[lam] / hv, **TOL)
        mu = np.random.default_rng(seed).uniform(-1, 1, size=s.g)
        vak, vak_h = s.equations("vakonomic"), scaled.equations("vakonomic")
        truth = solution(vak, {**values, **dict(zip(vak.multipliers, map(sp.Float, mu)))})
        got = solution(vak_h, {**values, **dict(zip(vak_h.multipliers, map(sp.Float, mu / hv)))})
        assert_same(got, truth, accelerations, "vakonomic")


# ------------------------------------------------------------------ a linear constraint squared
@pytest.mark.parametrize("seed", SEEDS)
def test_a_linear_constraint_squared_moves_as_the_linear_one(seed: int) -> None:
    """q̇_dep² = (B q̇ + B₀)², the branch q̇_dep = B q̇ + B₀ chosen: the Chetaev and vakonomic
    multiplier forms and Novoselov's equations give the linear system's accelerations (λ and μ
    scale by ∂f/∂q̇_dep of the linear constraint over that of the squared one)."""
    linear = seeded_system(seed, forces=False).system
    phi = linear.constraints
    f = [v**2 - e**2 for v, e in phi.items()]
    squared = with_branch(
        list(linear.coordinates), linear.kinetic_energy, f, list(linear.dependent), phi,
        force_function=linear.force_function,
    )  # fmt: skip
    assert squared.is_nonlinear and squared.is_affine == linear.is_affine
    spec = NonlinearSpec(
        squared, ["squared"], True, linear.is_chaplygin, False, False, [v - e for v, e in phi.items()], phi
    )
    accelerations = [qi.diff(t, 2) for qi in linear.coordinates]
    independent = [qi.diff(t, 2) for qi in linear.independent]
    for values in admissible_states(spec, 2, seed):
        # (each constraint has its own dependent velocity only: the blocks are diagonal)
        ratio = np.diag(dependent_block(given(linear), linear, values)) / np.diag(
            dependent_block(f, squared, values)
        )
        truth = solution(linear.equations("chetaev"), values)
        got = solution(squared.equations("chetaev"), values)
        assert_same(got, truth, accelerations, "chetaev")
        pairs = zip(linear.equations("chetaev").multipliers, squared.equations("chetaev").multipliers)
        for b, (lam, lam_sq) in enumerate(pairs):
            assert got[lam_sq] == pytest.approx(truth[lam] * ratio[b], **TOL)
        for model, form in reduced_forms(squared):
            assert_same(solution(squared.equations(model, form), values), truth, independent, (model, form))
        mu = np.random.default_rng(seed).uniform(-1, 1, size=linear.g)
        vak, vak_sq = linear.equations("vakonomic"), squared.equations("vakonomic")
        truth = solution(vak, {**values, **dict(zip(vak.multipliers, map(sp.Float, mu)))})
        got = solution(vak_sq, {**values, **dict(zip(vak_sq.multipliers, map(sp.Float, mu * ratio)))})
        assert_same(got, truth, accelerations, "vakonomic")


# ------------------------------------------------------------------ work and power
@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("homogeneous", [True, False])
def test_virtual_work_vanishes_and_power_exactly_when_homogeneous(seed: int, homogeneous: bool) -> None:
    """Chetaev: the virtual work of the constraint forces is 0; their power
    Σ_β λ_β Σ_s ∂f_β/∂q̇_s q̇_s (computed here from the test's f and NumPy's λ) is what power()
    gives, 0 for homogeneous constraints (Euler) and not 0 otherwise."""
    spec = spec_of(seed, homogeneous=homogeneous)
    s = spec.system
    eqs = s.equations("chetaev")
    assert eqs.virtual_work() == 0
    power = eqs.power()
    if homogeneous:
        assert power == 0
    velocities = [q.diff(t) for q in s.coordinates]
    rows = [[sp.diff(f, v) for v in velocities] for f in spec.f]
    seen = []
    for values in admissible_states(spec, 2, seed):
        lam = solution(eqs, values)
        values.update({m: sp.Float(lam[m]) for m in eqs.multipliers})
        by_hand = sum(
            lam[m] * sum(a * number(v, values) for a, v in zip(numbers(row, values), velocities))
            for m, row in zip(eqs.multipliers, rows)
        )
        assert number(power, values) == pytest.approx(by_hand, **TOL)
        seen.append(by_hand)
    assert (max(abs(x) for x in seen) < 1e-9) == homogeneous


# ------------------------------------------------------------------ an independent derivation
def test_chetaev_equations_derived_by_hand() -> None:
    """E_s(T) − Q_s = Σ_β λ_β ∂f_β/∂q̇_s with f = 0 differentiated, derived here with SymPy's
    diff on the dynamicsymbols (not chaplygin's models) for a non-Chaplygin, implicit,
    time-dependent random system with forces, and solved: chaplygin's Chetaev and Novoselov
    accelerations are these."""
    spec = next(
        sp_
        for seed in range(40)
        if (sp_ := nonlinear_system(seed, implicit=True, chaplygin=False, timed=True)).system.forces
    )
    s = spec.system
    q = list(s.coordinates)
    velocities = [qi.diff(t) for qi in q]
    accelerations = [qi.diff(t, 2) for qi in q]
    lam = sp.symbols(f"lam1:{s.g + 1}")
    unknown = sp.symbols(f"a1:{s.n + 1}")  # the accelerations, replaced before the velocities
    U = s.force_function
    T = s.kinetic_energy
    equations = []
    for k, qi in enumerate(q):
        lagrange = sp.diff(sp.diff(T, velocities[k]), t) - sp.diff(T, qi)
        applied = sp.diff(U, qi) + s.forces.get(qi, 0)
        equations.append(
            lagrange - applied - sum(lam[b] * sp.diff(f, velocities[k]) for b, f in enumerate(spec.f))
        )
    equations += [sp.diff(f, t) for f in spec.f]
    for values in admissible_states(spec, 2):
        known = dict(values)
        numeric = [e.xreplace(dict(zip(accelerations, unknown))).xreplace(known) for e in equations]
        M, F = sp.linear_eq_to_matrix([sp.expand(e.doit()) for e in numeric], [*unknown, *lam])
        x = np.linalg.solve(np.array(M, dtype=float), np.array(F, dtype=float)[:, 0])
        truth = dict(zip([*accelerations, *lam], x))
        got = solution(s.equations("chetaev"), values)
        assert_same(got, truth, accelerations, "chetaev")
        for model, form in reduced_forms(s):
            assert_same(
                solution(s.equations(model, form), values),
                truth,
                [qi.diff(t, 2) for qi in s.independent],
                model,
            )
