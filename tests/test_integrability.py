"""Integrability verdicts: conditions (28), (33) and the Frobenius test."""

from __future__ import annotations

import numpy as np
import sympy as sp
from hypothesis import given
from hypothesis import strategies as st
from sympy.physics.mechanics import dynamicsymbols

from chaplygin import System, examples

t = dynamicsymbols._t
x, y, z = dynamicsymbols("x y z")
d = lambda q: q.diff(t)  # noqa: E731
T = (d(x) ** 2 + d(y) ** 2 + d(z) ** 2) / 2


def constant_along_constraints(system: System, f: sp.Expr) -> bool:
    """df/dt = 0 for every admissible velocity (an independent check of a relation)."""
    rate = f.diff(t).xreplace(system.constraints)
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
    """ż = ẋ + x: the homogeneous part is exact but z − x = ∫x dt is no function of (q, t)."""
    report = System([x, y, z], T, {d(z): d(x) + x}).integrability()
    assert not report.integrable
    assert report.condition_28.holds
    assert any("X_t" in label for label, _ in report.frobenius.failures)


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
