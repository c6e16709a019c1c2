"""The zero test ``vanishes``: numbers first (interval arithmetic), exact normalisation after."""

from __future__ import annotations

import pytest
import sympy as sp

from chaplygin.core import _sampling
from chaplygin.core._sampling import vanishes

x, y, z = sp.symbols("x y z")


def _no_symbolic_path(monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the symbolic path ran")

    monkeypatch.setattr(_sampling.sp, "cancel", refuse)
    monkeypatch.setattr(_sampling.sp, "simplify", refuse)


def test_a_large_non_zero_expression_is_decided_by_the_numbers(monkeypatch: pytest.MonkeyPatch) -> None:
    # (x + y + z)**12 expanded minus the same power with one coefficient off by 1/1000
    big = sp.expand((x + y + z) ** 12)
    other = big - sp.Rational(1, 1000) * x**12
    _no_symbolic_path(monkeypatch)
    assert not vanishes(big - other)  # the difference is x**12/1000
    assert not vanishes(sp.sin(x) * big - sp.sin(x) * other)


def test_zero_expressions_are_zero_without_the_symbolic_path(monkeypatch: pytest.MonkeyPatch) -> None:
    _no_symbolic_path(monkeypatch)
    assert vanishes(sp.sin(x) ** 2 + sp.cos(x) ** 2 - 1)
    assert vanishes((x + y) ** 5 - sp.expand((x + y) ** 5))
    assert vanishes(sp.sqrt(x * y) ** 2 / y - x)


def test_non_zero_near_cancelling_terms() -> None:
    # terms of size ~1 that cancel to 10⁻⁶: far above round-off, so certainly non-zero
    assert not vanishes((x + y) ** 2 - x**2 - 2 * x * y - y**2 + sp.Rational(1, 10**6))
    assert vanishes((x + y) ** 2 - x**2 - 2 * x * y - y**2)


def test_rounding_left_over_from_floats_is_zero_as_before() -> None:
    # 0.1·3 − 0.3 is 5.6e-17, a Float no interval can tell from rounding: the float test's zero
    leftover = sp.Float(0.1) * 3 * x - sp.Float(0.3) * x
    assert leftover != 0
    assert vanishes(leftover)
    assert not vanishes(leftover + sp.Float(1e-3) * y)


def test_what_intervals_cannot_evaluate_goes_the_exact_way() -> None:
    # a complex value on the sampled range (x < 1 in part of it) and a function without intervals
    assert vanishes(sp.sqrt(x - 1) ** 2 - x + 1)
    assert vanishes(sp.atan(x) + sp.atan(1 / x) - sp.pi / 2)
    assert not vanishes(sp.atan(x) - x)
