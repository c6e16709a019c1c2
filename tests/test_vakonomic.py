"""Vakonomic model, Lindelöf's equations and the reduced family (issue 3).

Ground truth is the vakonomic multiplier system (17)-(18) with μ_β = c_β − ∂T/∂q̇_{ε+β},
evaluated with the test's own evaluator (xreplace + evalf) and solved with NumPy.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from hypothesis import given
from hypothesis import strategies as st

from chaplygin import Equations, ModelError, System, classify, compare_models, equivalent, examples
from randomsystems import Spec, matrix, number, random_state, systems, t

chaplygin_systems = systems(chaplygin=True, dependent_forces=False)


def solve(eqs, values: dict) -> dict:
    x = np.linalg.solve(matrix(eqs.mass_matrix, values), matrix(eqs.forcing, values)[:, 0])
    return dict(zip(eqs.unknowns, x))


def vakonomic_momenta(system: System, c: list[float], values: dict) -> dict:
    """The integral of (18b): A_depᵀ μ = c − ∂T/∂q̇_dep (μ_β = c_β − ∂T/∂q̇_{ε+β} in form B)."""
    mu = system.equations("vakonomic").multipliers
    cols = [system.coordinates.index(q) for q in system.dependent]
    a_dep = matrix(system.A, values)[:, cols]
    rhs = [
        cb - number(sp.diff(system.kinetic_energy, q.diff(t)), values) for cb, q in zip(c, system.dependent)
    ]
    return {m: sp.Float(v) for m, v in zip(mu, np.linalg.solve(a_dep.T, rhs))}


def assert_same_accelerations(
    system: System, reduced: list[Equations], reference: Equations, states: int = 4
) -> None:
    """Each of ``reduced`` gives ``reference``'s q̈_σ, all of them, at ``states`` random
    admissible states (the test's evaluator; ``reference`` may have more unknowns, e.g. λ)."""
    rng = np.random.default_rng(0)
    independent = {q.diff(t, 2) for q in system.independent}
    for _ in range(states):
        values = random_state(system, rng)
        truth = solve(reference, values)
        for eqs in reduced:
            got = solve(eqs, values)
            assert set(got) == independent, (eqs.model, eqs.form)
            for acc, value in got.items():
                assert value == pytest.approx(truth[acc], rel=1e-8, abs=1e-8), (eqs.model, eqs.form, acc)


@given(spec=chaplygin_systems, seed=st.integers(0, 2**32 - 1))
def test_family_equals_multiplier_form_with_integrated_multipliers(spec: Spec, seed: int) -> None:
    s = spec.system
    rng = np.random.default_rng(seed)
    values = random_state(s, rng)
    c = list(rng.uniform(-1, 1, size=s.g))
    values.update(vakonomic_momenta(s, c, values))
    truth = solve(s.equations("vakonomic"), values)
    for form in ("classic", "new"):
        family = s.equations("vakonomic_family", form, constants=[sp.Float(x) for x in c])
        for acc, value in solve(family, values).items():
            assert value == pytest.approx(truth[acc], rel=1e-8, abs=1e-8), (form, acc)


@given(spec=chaplygin_systems, seed=st.integers(0, 2**32 - 1))
def test_lindelof_is_the_member_c_equal_zero(spec: Spec, seed: int) -> None:
    s = spec.system
    values = random_state(s, np.random.default_rng(seed))
    values.update(vakonomic_momenta(s, [0.0] * s.g, values))
    truth = solve(s.equations("vakonomic"), values)
    for form in ("classic", "new"):  # eq. (22) and eq. (39)
        for acc, value in solve(s.equations("lindelof", form), values).items():
            assert value == pytest.approx(truth[acc], rel=1e-8, abs=1e-8), (form, acc)
    assert_same_accelerations(
        s, [s.equations("lindelof")], s.equations("vakonomic_family", constants=[0] * s.g)
    )


@given(spec=systems(chaplygin=True, integrable=True, affine=False, dependent_forces=False))
def test_all_models_coincide_where_condition_28_holds(spec: Spec) -> None:
    s = spec.system
    comparison = compare_models(s)
    assert comparison.condition_28 and comparison.coincide and comparison.verdict == "coincide"
    forms = [("lindelof", "classic"), ("lindelof", "new"), ("chaplygin", "classic"), ("chaplygin", "new")]
    assert_same_accelerations(s, [s.equations(model, form) for model, form in forms], s.equations("chetaev"))


@given(
    spec=systems(chaplygin=True, affine=False, forces=False, gyroscopic=False), seed=st.integers(0, 2**32 - 1)
)
def test_vakonomic_motion_conserves_energy(spec: Spec, seed: int) -> None:
    """Jacobi integral of L_v = T + U + μ·φ: T − U is conserved for any μ (docs/theory.md, Energy)."""
    s = spec.system
    if not s.is_scleronomic:
        return
    rng = np.random.default_rng(seed)
    values = random_state(s, rng)
    eqs = s.equations("vakonomic")
    values.update({m: sp.Float(rng.uniform(-1, 1)) for m in eqs.multipliers})
    values.update({k: sp.Float(v) for k, v in solve(eqs, values).items()})
    assert number((s.kinetic_energy - s.force_function).diff(t), values) == pytest.approx(0, abs=1e-9)


# ------------------------------------------------------------------ the paper's §4
@pytest.fixture(scope="module")
def sphere():
    return examples.rolling_sphere()


def paper_equations(sphere):
    """The sphere's equations typed by hand from the paper, transcription errors corrected:
    Lindelöf's (52)-(54) (geodesic) and Chaplygin's (60)-(62) (true motion); m, a cancelled."""
    psi, theta, phi = sphere.independent
    d = lambda q: q.diff(t)  # noqa: E731
    dd = lambda q: q.diff(t, 2)  # noqa: E731
    s, c = sp.sin(theta), sp.cos(theta)
    f = sp.Rational(2, 5)
    precession = f * (dd(psi) + dd(phi) * c - d(phi) * d(theta) * s)
    lindelof = [
        precession,
        sp.Rational(7, 5) * dd(theta) - d(phi) ** 2 * s * c + f * d(phi) * d(psi) * s,
        dd(phi) * s**2 + 2 * d(theta) * d(phi) * s * c + f * (dd(phi) + dd(psi) * c - d(psi) * d(theta) * s),
    ]
    chaplygin = [
        precession,
        sp.Rational(7, 5) * (dd(theta) + d(phi) * d(psi) * s),
        dd(phi) * s**2
        + f * (dd(phi) + dd(psi) * c)
        + d(theta) * d(phi) * s * c
        - sp.Rational(7, 5) * d(theta) * d(psi) * s,
    ]
    return lindelof, chaplygin


def test_section_4_both_derivations_of_each_model_agree(sphere) -> None:
    assert equivalent(sphere, sphere.equations("lindelof", "classic"), sphere.equations("lindelof", "new"))
    assert equivalent(sphere, sphere.equations("chaplygin", "classic"), sphere.equations("chaplygin", "new"))
    differ = equivalent(sphere, sphere.equations("lindelof"), sphere.equations("chaplygin"))
    assert not differ and differ.max_residual > 0.1


def test_section_4_paper_equations_are_classified(sphere) -> None:
    lindelof, chaplygin = paper_equations(sphere)
    assert classify(sphere, lindelof).verdict == "lindelof"
    assert classify(sphere, chaplygin).verdict == "chetaev"
    wrong = [lindelof[0], chaplygin[1], lindelof[2] + sp.Rational(1, 10) * chaplygin[0]]
    wrong[1] = wrong[1] + sp.sin(sphere.independent[1]) * sphere.independent[0].diff(t)
    assert classify(sphere, wrong).verdict == "none"


def test_classifier_recovers_family_constants(sphere) -> None:
    member = sphere.equations("vakonomic_family", constants={"c_1": 0.25, "c_2": -1.5})
    result = classify(sphere, member.residuals)
    assert result.verdict == "vakonomic"
    assert result.constants == pytest.approx({"c_1": 0.25, "c_2": -1.5}, abs=1e-8)
    assert "c_1 = 0.25" in str(result)


def test_lindelof_defect_of_the_sphere(sphere) -> None:
    comparison = compare_models(sphere)
    assert comparison.verdict == "differ" and not comparison.condition_28
    psi, theta, phi = sphere.independent
    m, a = sphere.parameter("m"), sphere.parameter("a")
    d = lambda q: q.diff(t)  # noqa: E731
    # (15) − (22), by hand from (48) and (60)-(62) above, times m a²
    expected = m * a**2 * sp.sin(theta) * (d(phi) * sp.cos(theta) + d(psi))
    assert comparison.defect[psi] == 0
    assert sp.simplify(comparison.defect[theta] - expected * d(phi)) == 0
    assert sp.simplify(comparison.defect[phi] + expected * d(theta)) == 0


def test_vertical_disk_lindelof_happens_to_be_right() -> None:
    disk = examples.vertical_rolling_disk()
    comparison = compare_models(disk)
    assert not comparison.condition_28 and comparison.defect_vanishes
    assert comparison.verdict == "lindelof_right_here"
    assert "happen to be right" in str(comparison)
    result = classify(disk, disk.equations("lindelof"))
    assert result.verdict == "chetaev" and "happen to coincide" in result.note


# ------------------------------------------------------------------ forces and virtual work
def test_vakonomic_virtual_work(sphere) -> None:
    """(24)-(26): non-zero for the sphere, zero for integrable constraints."""
    work = sphere.equations("vakonomic").virtual_work()
    assert work != 0 and any(m in work.atoms(sp.Function) for m in sphere.equations("vakonomic").multipliers)
    x, y, z = (sp.Function(n)(t) for n in "xyz")
    T = (x.diff(t) ** 2 + y.diff(t) ** 2 + z.diff(t) ** 2) / 2
    closed = System([x, y, z], T, [2 * x * x.diff(t) + 2 * y * y.diff(t) + z.diff(t)], dependent=[z])
    factor = System(
        [x, y, z], T, [sp.exp(x) * (2 * x * x.diff(t) + 2 * y * y.diff(t) + z.diff(t))], dependent=[z]
    )
    for s in (closed, factor):
        assert sp.simplify(s.equations("vakonomic").virtual_work()) == 0
        assert s.equations("vakonomic").virtual_work(chetaev_condition=False) != 0


def test_integrated_multipliers_are_exposed(sphere) -> None:
    mu = sphere.equations("vakonomic").multipliers
    x, y = sphere.dependent
    m = sphere.parameter("m")
    got = sphere.integrated_multipliers({"c_1": 2, "c_2": 0})
    assert sp.simplify(got[mu[0]] - (2 - m * sphere.constraints[x.diff(t)])) == 0
    assert sp.simplify(got[mu[1]] + m * sphere.constraints[y.diff(t)]) == 0
    report = equivalent(
        sphere,
        sphere.equations("vakonomic"),
        sphere.equations("vakonomic_family", constants=[2, 0]),
        multipliers=got,
    )
    assert report and report.method == "numeric"


def test_vakonomic_constraint_forces_enter_as_reactions(sphere) -> None:
    eqs = sphere.equations("vakonomic")
    mu1, mu2 = eqs.multipliers
    R = eqs.constraint_forces()
    x, y = sphere.dependent
    assert R[x] == -mu1.diff(t) and R[y] == -mu2.diff(t)


def test_family_errors() -> None:
    x, y, z = (sp.Function(n)(t) for n in "xyz")
    T = (x.diff(t) ** 2 + y.diff(t) ** 2 + z.diff(t) ** 2) / 2
    voronets = System([x, y, z], T, {z.diff(t): z * y.diff(t)})
    with pytest.raises(ModelError, match="do not integrate.*model='vakonomic'"):
        voronets.equations("lindelof")
    with pytest.raises(ModelError, match="no Lindelöf equations"):
        compare_models(voronets)
    pushed = examples.rolling_sphere(forces={"x": sp.Symbol("F")})
    with pytest.raises(ModelError, match="along the dependent coordinate"):
        pushed.equations("vakonomic_family")
    s = examples.knife_edge()
    with pytest.raises(ModelError, match="2 value"):
        s.equations("vakonomic_family", constants=[1, 2])
    with pytest.raises(ModelError, match="belong to model 'vakonomic_family'"):
        s.equations("lindelof", constants=[1])
    with pytest.raises(ModelError, match="unknown key 'd_1'"):
        s.equations("vakonomic_family", constants={"d_1": 1})


def test_multipliers_may_carry_their_own_constants() -> None:
    knife = examples.knife_edge()
    vak, lin = knife.equations("vakonomic"), knife.equations("lindelof")
    mu = knife.integrated_multipliers()  # symbolic c_1
    assert equivalent(knife, vak, lin, multipliers=mu, parameters={"c_1": 0.0})
    assert not equivalent(knife, vak, lin, multipliers=mu, parameters={"c_1": 0.7})
    with pytest.raises(Exception, match="cannot evaluate"):
        equivalent(knife, vak, lin, multipliers={vak.multipliers[0]: sp.Symbol("w")})


def test_best_fit_residual_is_not_worse_than_lindelof() -> None:
    knife = examples.knife_edge()
    residuals = classify(knife, knife.equations("chaplygin")).residuals
    assert residuals["vakonomic_family"] <= residuals["lindelof"] + 1e-12
