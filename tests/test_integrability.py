"""Integrability verdicts: conditions (28), (33) and the Frobenius test."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st
from sympy.physics.mechanics import dynamicsymbols

from chaplygin import System, compare_models, examples

t = dynamicsymbols._t
x, y, z = dynamicsymbols("x y z")
d = lambda q: q.diff(t)  # noqa: E731
T = (d(x) ** 2 + d(y) ** 2 + d(z) ** 2) / 2


def constant_along_constraints(system: System, f: sp.Expr) -> bool:
    """df/dt = 0 for every admissible velocity (an independent check of a relation), with real
    coordinates and time (SymPy differentiates |·| and sign of real arguments only)."""
    tr = sp.Symbol("t", real=True)
    real: dict[sp.Basic, sp.Basic] = {
        q: sp.Function(q.func.__name__, real=True)(tr) for q in system.coordinates
    }
    real[t] = tr
    to_real = lambda e: sp.sympify(e).xreplace(real)  # noqa: E731
    rate = to_real(f).diff(tr).subs({to_real(k): to_real(v) for k, v in system.constraints.items()})
    return sp.simplify(rate) == 0


def test_knife_edge_is_not_integrable() -> None:
    report = examples.knife_edge().integrability()
    assert not report.integrable
    assert not report.condition_28.holds and not report.condition_33.holds
    assert "not integrable" in str(report)


def test_sphere_is_not_integrable() -> None:
    report = examples.rolling_sphere().integrability()
    assert not report.integrable and not report.condition_28.holds
    assert report.relations == []


def test_integrating_factor_example() -> None:
    """exp(x)(2x ẋ + 2y ẏ + ż) = 0: not closed, but integrable: x² + y² + z = const."""
    s = System([x, y, z], T, [sp.exp(x) * (2 * x * d(x) + 2 * y * d(y) + d(z))], dependent=[z])
    report = s.integrability()
    assert report.integrable and report.frobenius.holds
    assert not report.condition_33.holds and report.condition_28.holds
    (rel,) = report.relations
    assert sp.simplify(rel - (x**2 + y**2 + z)).free_symbols <= set()
    assert constant_along_constraints(s, rel)


def test_closed_form_example() -> None:
    s = System([x, y, z], T, [2 * x * d(x) + 2 * y * d(y) + d(z)], dependent=[z])
    report = s.integrability()
    assert report.integrable and report.condition_33.holds and report.condition_28.holds


def test_homogeneous_form_with_integrating_factor_on_dependent_coordinate() -> None:
    """y ẋ − x ẏ = 0: B = y/x depends on the dependent y; Frobenius still decides."""
    s = System([x, y], (d(x) ** 2 + d(y) ** 2) / 2, [y * d(x) - x * d(y)], dependent=[y])
    report = s.integrability()
    assert report.integrable and not report.condition_33.holds
    (rel,) = report.relations
    assert constant_along_constraints(s, rel)


def test_rheonomic_affine_integrable() -> None:
    s = System([x, y, z], T, {d(z): d(x) + sp.cos(t)})
    report = s.integrability()
    assert report.integrable
    (rel,) = report.relations
    assert sp.simplify(rel - (z - x - sp.sin(t))).free_symbols <= set()


def test_affine_not_integrable() -> None:
    """ż = ẋ + x: the homogeneous part is exact but z − x = ∫x dt is no function of (q, t).

    (28) and (33) fail through their dt terms: ∂B/∂t − ∂B0/∂x = −1, ∂A_x/∂t − ∂A0/∂x = 1.
    """
    report = System([x, y, z], T, {d(z): d(x) + x}).integrability()
    assert not report.integrable
    assert report.condition_28.holds is False and report.condition_33.holds is False
    assert any("X_t" in label for label, _ in report.frobenius.failures)
    assert report.condition_28.failures == [("∂B[z, x]/∂t − ∂B0[z]/∂x", -1)]
    assert report.condition_33.failures == [("∂A[1, x]/∂t − ∂A0[1]/∂x", 1)]


T2 = (d(x) ** 2 + d(y) ** 2) / 2


def test_time_dependent_not_integrable_fails_28_and_33() -> None:
    """ẏ = t ẋ: ω = dy − t dx has ω ∧ dω = dy ∧ dx ∧ dt ≠ 0. (28) and (33) include the dt part of
    the constraint form (on main they said "holds" next to integrable=False)."""
    s = System([x, y], T2, {d(y): t * d(x)})
    report = s.integrability()
    assert not compare_models(s).condition_28  # the same (28) in the model comparison
    assert report.integrable is False
    assert report.condition_28.holds is False and report.condition_33.holds is False
    assert report.condition_33.failures == [("∂A[1, x]/∂t − ∂A0[1]/∂x", -1)]  # ∂(−t)/∂t − ∂0/∂x
    assert "(33): fails" in str(report) and "(28): fails" in str(report)


@pytest.mark.parametrize(
    ("rhs", "relation"),
    [(d(x) + 1, y - x - t), (t * d(x) + x, y - t * x)],
    ids=["y'=x'+1", "y'=t x'+x"],
)
def test_affine_time_dependent_integrable(rhs: sp.Expr, relation: sp.Expr) -> None:
    """ẏ = ẋ + 1 (y − x − t = const) and ẏ = t ẋ + x (d(y − t x) = dy − t dx − x dt): closed forms
    on (q, t); (28), (33) and Frobenius hold, and the relation found is the one derived by hand."""
    s = System([x, y], T2, {d(y): rhs})
    report = s.integrability()
    assert report.integrable and report.condition_28.holds and report.condition_33.holds
    assert constant_along_constraints(s, relation)  # the hand derivation, checked
    (found,) = report.relations
    assert sp.simplify(found - relation) == 0


def test_28_not_applicable_where_b_depends_on_dependent_coordinate() -> None:
    """ż = z ẋ + ẏ: (28) has nothing to fail (B_x = z, B_y = 1 are free of x, y), yet
    [X_x, X_y] = −∂z: not integrable. (28) says it does not apply, not "holds"."""
    report = System([x, y, z], T, {d(z): z * d(x) + d(y)}).integrability()
    assert report.integrable is False
    assert report.condition_28.holds is None and report.condition_28.verdict == "not applicable"
    assert "(28): not applicable" in str(report)


def test_heisenberg_is_not_integrable() -> None:
    s = System([x, y, z], (d(x) ** 2 + d(y) ** 2) / 2, {d(z): (x * d(y) - y * d(x)) / 2})
    assert not s.integrability().integrable


_pool = [sp.S.One, x, y, z, sp.sin(x), sp.cos(y), x * y, y * z, z**2, sp.exp(x)]


@given(
    st.lists(st.integers(0, len(_pool) - 1), min_size=3, max_size=3),
    st.lists(st.integers(-2, 2), min_size=3, max_size=3),
)
def test_frobenius_agrees_with_curl_criterion(idx: list[int], coef: list[int]) -> None:
    """n = 3, g = 1: integrable iff ω · curl ω = 0 (the classical form of dω ∧ ω = 0)."""
    A = [coef[0] * _pool[idx[0]], coef[1] * _pool[idx[1]] + x, 2 + sp.cos(coef[2] * _pool[idx[2]])]
    s = System([x, y, z], T, [A[0] * d(x) + A[1] * d(y) + A[2] * d(z)], dependent=[z])
    X, Y, Z = sp.symbols("X Y Z")
    a = [e.xreplace({x: X, y: Y, z: Z}) for e in A]
    curl = [
        sp.diff(a[2], Y) - sp.diff(a[1], Z),
        sp.diff(a[0], Z) - sp.diff(a[2], X),
        sp.diff(a[1], X) - sp.diff(a[0], Y),
    ]
    triple = sp.lambdify((X, Y, Z), sum(ai * ci for ai, ci in zip(a, curl)))
    rng = np.random.default_rng(1)
    integrable = all(abs(triple(*rng.uniform(0.3, 1.3, 3))) < 1e-10 for _ in range(6))
    assert s.integrability().integrable == integrable


_pool_t = [sp.S.One, t, x, y, t * x, sp.sin(t) * y, x * y, sp.cos(x), t**2, sp.exp(y)]


@st.composite
def _forms(draw: st.DrawFn) -> tuple[System, sp.Expr | None, list[sp.Expr]]:
    """A single constraint ω = Σ A_s dq_s + A_0 dt on (x, y, z, t), z dependent: dF of a random
    F(x, y, z, t) (closed, integrable, relation F), or dF plus a random term (usually not)."""
    F = sum((draw(st.integers(-2, 2)) * draw(st.sampled_from(_pool_t)) for _ in range(3)), sp.S.Zero)
    F += draw(st.sampled_from([z, 2 * z, sp.exp(z)]))  # ∂F/∂z ≠ 0: z can be solved for
    plain = sp.symbols("X Y Z S")  # ∂F/∂t with the coordinates held fixed
    to_plain, back = dict(zip((x, y, z, t), plain)), dict(zip(plain, (x, y, z, t)))
    form = [sp.diff(F.xreplace(to_plain), v).xreplace(back) for v in plain]
    perturbed = draw(st.booleans())
    if perturbed:
        form[draw(st.integers(0, 3))] += draw(st.sampled_from([sp.S(1), t, x, y, t * y, sp.sin(x)]))
    s = System([x, y, z], T, [sum(a * d(q) for a, q in zip(form[:3], (x, y, z))) + form[3]], dependent=[z])
    return s, None if perturbed else F, form


def _frobenius_by_hand(form: list[sp.Expr]) -> bool:
    """ω ∧ dω = 0 on (x, y, z, t) for one 1-form: every component ω_i(∂_j ω_k − ∂_k ω_j) + cyclic,
    at random points (written here, independently of chaplygin)."""
    X = sp.symbols("X Y Z S")
    w = [e.xreplace(dict(zip((x, y, z, t), X))) for e in form]
    comps = [
        w[i] * (sp.diff(w[k], X[j]) - sp.diff(w[j], X[k]))
        + w[j] * (sp.diff(w[i], X[k]) - sp.diff(w[k], X[i]))
        + w[k] * (sp.diff(w[j], X[i]) - sp.diff(w[i], X[j]))
        for i, j, k in ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3))
    ]
    f = sp.lambdify(X, comps)
    rng = np.random.default_rng(2)
    return all(np.allclose(f(*rng.uniform(-2, 2, 4)), 0, atol=1e-9) for _ in range(6))


@settings(max_examples=max(20, settings.default.max_examples))
@given(_forms())
def test_no_verdict_contradicts_integrable(case: tuple[System, sp.Expr | None, list[sp.Expr]]) -> None:
    """Random affine, time-dependent constraint forms: (33) holding implies integrable, and then a
    finite relation is verified by differentiation; (28), where it applies, agrees with the
    verdict; the verdict agrees with ω ∧ dω = 0 computed by hand."""
    s, F, form = case
    report = s.integrability()
    assert report.integrable == _frobenius_by_hand(form)
    if F is not None:  # dF: closed by construction
        assert report.condition_33.holds and constant_along_constraints(s, F)
    if report.condition_33.holds:
        assert report.integrable
        assert any(
            constant_along_constraints(s, r) for r in report.relations + ([F] if F is not None else [])
        )
    if report.condition_28.holds is not None:
        assert report.condition_28.holds == report.integrable


def test_abs_in_constraints_is_differentiated_in_closed_form() -> None:
    """d|cos y| = −sign(cos y) sin y dy: ż = |cos y| ẋ − x sign(cos y) sin y ẏ is d(x |cos y|);
    with sign(cos y) left out it is closed only where cos y > 0 (main: a bare SymPy printing error)."""
    exact = System([x, y, z], T, {d(z): sp.Abs(sp.cos(y)) * d(x) - x * sp.sign(sp.cos(y)) * sp.sin(y) * d(y)})
    report = exact.integrability()
    assert report.integrable and report.condition_33.holds
    (rel,) = report.relations
    assert constant_along_constraints(exact, rel) and rel.has(sp.Abs)
    half = System([x, y, z], T, {d(z): sp.Abs(sp.cos(y)) * d(x) - x * sp.sin(y) * d(y)})
    assert not half.integrability().integrable
