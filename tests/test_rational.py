"""The exact solver behind every solved form (chaplygin.core._rational), against numeric oracles."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from chaplygin import ModelError
from chaplygin.core._rational import TERMS, TooLarge, normal_all, solve_linear
from randomsystems import number

a, b, k = sp.symbols("a b k", positive=True)
x, y = sp.symbols("x y")
KERNELS = [sp.sin(x), sp.cos(x), sp.sin(y), sp.cos(y), a, b, k, x, sp.sqrt(a), sp.Float(0.3)]


@st.composite
def polynomials(draw: st.DrawFn, terms: int = 3) -> sp.Expr:
    out = sp.S.Zero
    for _ in range(draw(st.integers(1, terms))):
        c = draw(st.integers(-3, 3).filter(bool))
        out += c * sp.Mul(*draw(st.lists(st.sampled_from(KERNELS), min_size=0, max_size=3)))
    return out


def _at(expr: sp.Expr, point: dict) -> float:
    """In floats, each repeated subexpression once (randomsystems.number; xreplace + evalf of
    the nested solutions took a third of the time)."""
    return number(expr, point)


def _point(rng: np.random.Generator) -> dict:
    return {s: sp.Float(rng.uniform(0.3, 1.3)) for s in (a, b, k, x, y)}


@settings(max_examples=25, deadline=None, derandomize=True)
@given(n=st.integers(1, 3), data=st.data())
def test_solution_solves_the_system(n: int, data: st.DataObject) -> None:
    """Oracle: NumPy's solve of the numeric system at random points."""
    M = sp.Matrix(n, n, lambda i, j: data.draw(polynomials()) + (3 if i == j else 0))
    F = sp.Matrix(n, 1, lambda i, j: data.draw(polynomials()) / (2 + sp.cos(x)))
    rng = np.random.default_rng(0)
    points = [_point(rng) for _ in range(3)]
    mats = [np.array([[_at(e, p) for e in row] for row in M.tolist()]) for p in points]
    if any(abs(np.linalg.det(m)) < 1e-6 for m in mats):
        return  # (near-)singular draws prove nothing
    try:
        sol = solve_linear(M, F)
    except ModelError:
        pytest.fail(f"a regular matrix was called singular: {M}")
    for p, m in zip(points, mats):
        truth = np.linalg.solve(m, np.array([_at(e, p) for e in F]))
        got = np.array([_at(e, p) for e in sol])
        np.testing.assert_allclose(got, truth, rtol=1e-9, atol=1e-9)


def test_the_identity_is_applied_and_factors_cancel() -> None:
    s, c = sp.sin(x), sp.cos(x)
    assert normal_all([s**2 + c**2, c**2 / (1 - s**2), (s**4 - c**4) / (s**2 - c**2)]) == [1, 1, 1]
    # A cos²x·u = A(1 − sin²x)·w: the solution cancels to u = w, whichever square is written
    assert solve_linear(sp.Matrix([[a * c**2]]), sp.Matrix([[a * (1 - s**2) * b]])) == [b]


def test_floats_stay_floats() -> None:
    """A Float comes out a Float: not the rational of its binary value (0.1 is not
    3602879701896397/2**55)."""
    f = sp.Float("0.1")
    (got,) = solve_linear(sp.Matrix([[3 * a]]), sp.Matrix([[f * a * b]]))
    assert got.atoms(sp.Float) and not any(r.q > 3 for r in got.atoms(sp.Rational))
    assert got.xreplace({b: 1}) == pytest.approx(0.1 / 3, rel=1e-15)


def test_singular_matrices_are_refused() -> None:
    s, c = sp.sin(x), sp.cos(x)
    with pytest.raises(ModelError, match="singular"):
        solve_linear(sp.Matrix([[a, b], [2 * a, 2 * b]]), sp.Matrix([1, 2]))
    with pytest.raises(ModelError, match="singular"):  # singular only by sin² + cos² = 1
        solve_linear(sp.Matrix([[s**2 + c**2, 1], [1, 1]]), sp.Matrix([1, 2]))


def test_large_systems_fall_back_to_nested_lu() -> None:
    """Expanded normal forms past TERMS terms give way to unexpanded LU, still exact."""
    rng = np.random.default_rng(1)
    kern = [sp.sin(x), sp.cos(x), sp.sin(y), sp.cos(y), a, b, k, x]

    def big() -> sp.Expr:
        return sp.Add(*(int(rng.integers(1, 4)) * sp.Mul(*rng.choice(kern, 3)) for _ in range(12)))

    M = sp.Matrix(4, 4, lambda i, j: big() + (40 if i == j else 0))
    F = sp.Matrix(4, 1, lambda i, j: big())
    from chaplygin.core._rational import Algebra

    with pytest.raises(TooLarge):  # the premise: this system is past the budget
        alg = Algebra([*M, *F])
        N, _ = alg.matrix(M.row_join(F))
        alg.solve_den(N[:, :4], N[:, 4:])
    sol = solve_linear(M, F)
    p = _point(rng)
    m = np.array([[_at(e, p) for e in row] for row in M.tolist()])
    np.testing.assert_allclose(
        [_at(e, p) for e in sol], np.linalg.solve(m, [_at(e, p) for e in F]), rtol=1e-9
    )
    assert TERMS >= 100  # the rolling bodies of the gallery stay in normal form


def test_powers_of_long_sums_are_not_expanded() -> None:
    """(a + b + k + x + y)**60 has 635376 terms expanded: the solve stays nested, and quick."""
    big = (a + b + k + x + y) ** 60
    (sol,) = solve_linear(sp.Matrix([[2 + sp.sin(x) ** 2]]), sp.Matrix([[big]]))
    assert sp.simplify(sol - big / (2 + sp.sin(x) ** 2)) == 0
    assert normal_all([big]) == [big]


@settings(max_examples=40, deadline=None, derandomize=True)
@given(top=polynomials(4), bottom=polynomials(3), common=polynomials(2), power=st.integers(0, 2))
def test_cancelling_by_the_denominators_factors_is_sympys_cancel(
    top: sp.Expr, bottom: sp.Expr, common: sp.Expr, power: int
) -> None:
    """Algebra._cancel (the denominator's factors divided out, then the contents) gives the very
    pair SymPy's ``PolyElement.cancel`` (a greatest common divisor) gives, common factors and
    rational coefficients included."""
    from chaplygin.core._rational import Algebra

    numer, denom = sp.expand(top * common**power / 3), sp.expand(bottom * common**power * sp.Rational(2, 5))
    alg = Algebra([numer, denom])
    n, d = alg.convert(numer)[0], alg.convert(denom)[0]
    if not d:
        return
    assert alg._cancel(n, d) == n.cancel(d)


def test_the_vakonomic_disk_is_solved_without_a_greatest_common_divisor(monkeypatch) -> None:
    """The rolling disk's vakonomic accelerations (their denominators are small) cancel by the
    denominators' factors: SymPy's gcd-based cancel is never called (it was 0.03 of 0.12 s)."""
    from sympy.polys.rings import PolyElement

    from chaplygin import examples

    def refuse(self: PolyElement, other: PolyElement) -> None:
        raise AssertionError("PolyElement.cancel was called")

    monkeypatch.setattr(PolyElement, "cancel", refuse)
    acc = examples.rolling_disk().equations("vakonomic").accelerations
    assert len(acc) == 7  # the 5 coordinates' accelerations and the 2 multipliers' rates
