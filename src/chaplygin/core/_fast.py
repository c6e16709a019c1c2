"""SymEngine fast path for the hot symbolic work: differentiation and common subexpressions.

Everything the user sees stays SymPy; only derivatives and the common
subexpressions of generated code are computed in SymEngine (about 30× faster
than SymPy, whose assumption queries dominate). Each call
converts its input once and its results once; an input that is itself a result (the next
step of a derivation) is taken as the SymEngine value it was made from.  Symbols with
assumptions (a ``positive=True`` mass, say) come back from SymEngine without them, so they are
restored by name, in SymEngine, as the results are converted (:func:`_back`).  Anything
SymEngine cannot represent falls back to SymPy.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import Any

import sympy as sp

try:  # the import line names the converter; no user text ever reaches it
    from symengine import DenseMatrix as _se_matrix
    from symengine import Eq as _se_eq
    from symengine import Integer as _se_integer
    from symengine import Lambdify as _se_lambdify
    from symengine import Symbol as _se_symbol
    from symengine import cse as _se_cse
    from symengine import sympify as _to_symengine
    from symengine.lib.symengine_wrapper import Boolean as _se_boolean

    HAVE_SYMENGINE = True
except ImportError:  # pragma: no cover - symengine is a dependency
    HAVE_SYMENGINE = False

__all__ = [
    "HAVE_SYMENGINE",
    "cse",
    "evaluator",
    "gradient",
    "jacobian",
    "native",
    "shown_nonzero",
    "to_sympy",
    "total_derivative",
]


def _restore_map(exprs: Sequence[sp.Expr]) -> dict[sp.Symbol, sp.Symbol]:
    out = {}
    for e in exprs:
        for s in e.free_symbols:
            if type(s) is sp.Symbol and s.assumptions0:
                out[sp.Symbol(s.name)] = s
    return out


_UNSAFE = (sp.Abs, sp.sign, sp.re, sp.im)  # symengine 0.15 crashes on some of their derivatives


#: ``id(e)`` of a SymPy expression -> ``(e, its SymEngine value)``: the expressions
#: :func:`_back` made (with the value they were made from) and those :func:`_convert` converted.
#: A derivation hands its results straight back to the next step (Voronets' terms, the mass
#: matrix to the code generator) and differentiates the same pieces again (each entry of B
#: once per independent coordinate in D_σ): their conversions to SymEngine were most of its
#: time.  The expression itself is kept, so its id names it while the entry lives; the value
#: is a conversion of ``e`` (equal to it; SymEngine symbols carry no assumptions, here or in a
#: conversion), free of the ``_UNSAFE`` functions (tested, or computed from inputs that were).
#: Bounded, so that a long session does not keep every tree alive.
_MADE: dict[int, tuple[sp.Basic, Any]] = {}
_MADE_MAX = 4096


def _remember(exprs: Sequence[sp.Basic], values: Sequence[Any]) -> None:
    if len(_MADE) + len(exprs) > _MADE_MAX:
        _MADE.clear()
    for e, v in zip(exprs, values):
        if not isinstance(e, sp.Atom):
            _MADE[id(e)] = (e, v)


def _convert(exprs: Sequence[sp.Expr]) -> list[Any] | None:
    if not HAVE_SYMENGINE:
        return None
    made = [_MADE.get(id(e)) for e in exprs]
    known = [m[1] if m is not None and m[0] is e else None for m, e in zip(made, exprs)]
    new = [e for k, e in zip(known, exprs) if k is None]
    if any(e.has(*_UNSAFE) for e in new):
        return None
    try:
        converted = [_to_symengine(e) for e in new]
    except (RuntimeError, NotImplementedError, TypeError, AttributeError):
        return None
    _remember(new, converted)
    it = iter(converted)
    return [next(it) if k is None else k for k in known]


if HAVE_SYMENGINE:

    class _Kept(_se_symbol):
        """A SymEngine symbol that converts back to ``original``, the SymPy symbol with
        assumptions it stands for.  It lives only inside :func:`_back`, under a name of its
        own: were it named as the plain symbol, SymEngine would take the two for equal and
        keep the plain one in a node it finds unchanged by the substitution."""

        def __init__(self, original: sp.Symbol) -> None:
            self.original = original  # before SymEngine's init, which keeps this object
            super().__init__(f"{original.name} (kept {id(original)})", store_pickle=True)

        def __reduce__(self) -> tuple[Any, ...]:
            return (_Kept, (self.original,))

        def _sympy_(self) -> sp.Symbol:
            return self.original


def _back(values: Sequence[Any], restore: dict[sp.Symbol, sp.Symbol]) -> list[sp.Expr]:
    """SymEngine's ``values`` as SymPy expressions, their symbols named in ``restore`` (plain ->
    with assumptions) as given there: swapped in SymEngine for :class:`_Kept` stand-ins that
    convert to them (a substitution in SymPy afterwards rebuilt every node above them)."""
    shown = list(values)
    if restore:
        kept = {_se_symbol(plain.name): _Kept(original) for plain, original in restore.items()}
        shown = list(_se_matrix(shown).xreplace(kept)) if len(shown) > 1 else [shown[0].xreplace(kept)]
    out = [v._sympy_() for v in shown]
    _remember(out, values)
    return out


def _real(exprs: Sequence[sp.Expr]) -> tuple[dict[sp.Symbol, sp.Symbol], dict[sp.Symbol, sp.Symbol]]:
    """Real stand-ins for the symbols of ``exprs`` without assumptions (the internal ones, ``t``), and back.

    SymPy differentiates ``Abs``, ``sign``, ``re`` and ``im`` of real arguments in closed form
    (``d|x|/dx = sign(x)``); of a symbol it knows nothing about it leaves unevaluated
    derivatives of ``re`` and ``im`` that nothing can evaluate or print.
    """
    plain = {s for e in exprs for s in e.free_symbols if isinstance(s, sp.Symbol) and s.is_real is None}
    real = {s: sp.Dummy(s.name, real=True) for s in plain}
    return real, {v: k for k, v in real.items()}


def _sympy_jacobian(exprs: list[sp.Expr], variables: list[sp.Symbol]) -> sp.Matrix:
    real, back = _real(exprs + variables)
    return sp.Matrix(exprs).xreplace(real).jacobian([real.get(v, v) for v in variables]).xreplace(back)


def jacobian(exprs: Sequence[sp.Expr], variables: Sequence[sp.Symbol]) -> sp.Matrix:
    """``∂ exprs_i / ∂ variables_j`` as a SymPy matrix."""
    exprs, variables = list(exprs), list(variables)
    fast = _convert(exprs + variables)
    if fast is None:
        return _sympy_jacobian(exprs, variables)
    fe, fv = fast[: len(exprs)], fast[len(exprs) :]
    flat = _back([e.diff(x) for e in fe for x in fv], _restore_map(exprs))
    return sp.Matrix(len(exprs), len(variables), flat)


def derivative(expr: sp.Expr, variable: sp.Symbol) -> sp.Expr:
    """``∂ expr / ∂ variable`` in SymPy, ``Abs``, ``sign``, ``re`` and ``im`` differentiated in closed form."""
    if not expr.has(*_UNSAFE):
        return sp.diff(expr, variable)
    real, back = _real([expr, variable])
    return sp.diff(expr.xreplace(real), real.get(variable, variable)).xreplace(back)


def gradient(expr: sp.Expr, variables: Sequence[sp.Symbol]) -> list[sp.Expr]:
    """``[∂ expr / ∂ v for v in variables]``."""
    return list(jacobian([expr], variables))


def total_derivative(expr: sp.Expr, pairs: Sequence[tuple[sp.Symbol, sp.Expr]], time: sp.Symbol) -> sp.Expr:
    """``∂_t F + Σ ∂F/∂x · ẋ`` for the given ``(x, ẋ)`` pairs."""
    pairs = [(x, xd) for x, xd in pairs if xd != 0]
    fast = _convert([expr, time, *(x for x, _ in pairs), *(xd for _, xd in pairs)])
    if fast is None:
        grad = _sympy_jacobian([expr], [time, *(x for x, _ in pairs)])
        return grad[0] + sp.Add(*(g * xd for g, (_, xd) in zip(list(grad)[1:], pairs)))
    k = len(pairs)
    f, ft, fx, fxd = fast[0], fast[1], fast[2 : 2 + k], fast[2 + k :]
    result = f.diff(ft)
    for x, xd in zip(fx, fxd):
        result += f.diff(x) * xd
    restore = _restore_map([expr, *(xd for _, xd in pairs)])
    return _back([result], restore)[0]


def to_sympy(value: Any) -> sp.Basic:
    """A SymPy or SymEngine expression or a number as SymPy's (strict: text is refused, never parsed)."""
    return sp.sympify(value, strict=True)


def native(exprs: Sequence[Any]) -> list[Any] | None:
    """``exprs`` (SymPy, SymEngine or numbers, never text) as SymEngine expressions; None if SymEngine cannot."""
    if any(isinstance(e, str) for e in exprs):
        raise TypeError("native() converts expressions, not text")
    sympy = [e for e in exprs if isinstance(e, sp.Basic)]
    converted = _convert(sympy) if sympy else []
    if converted is None:
        return None
    it = iter(converted)
    return [next(it) if isinstance(e, sp.Basic) else _to_symengine(e) for e in exprs]


def cse(exprs: Sequence[Any], prefix: str = "c_") -> tuple[list[tuple[Any, Any]], list[Any]]:
    """Common subexpressions of ``exprs``: ``(replacements, reduced)`` as :func:`sympy.cse` returns.

    The new symbols are ``prefix0, prefix1, …`` in order of definition.  With
    SymEngine (expressions it can represent, SymPy's or its own) the results
    are SymEngine expressions, printed by :mod:`chaplygin.numeric._printing` without
    converting them back; otherwise SymPy's elimination (with its cheap
    "basic" optimisations) gives SymPy expressions.
    """
    fast = native(exprs)
    # SymEngine names its symbols x0, x1, …: a clash with the input's names takes SymPy's cse
    if fast is None or any(re.fullmatch(r"x\d+", str(s)) for e in fast for s in e.free_symbols):
        return sp.cse(
            [to_sympy(e) for e in exprs], symbols=sp.numbered_symbols(prefix), optimizations="basic"
        )
    pairs, reduced = _se_cse(fast)
    pairs, reduced = _numbers_only(pairs, reduced)
    rename = {s: _se_symbol(f"{prefix}{k}") for k, (s, _) in enumerate(pairs)}
    # one substitution of the whole list (a matrix): per expression, the map is converted each time
    done = (
        list(_se_matrix([v for _, v in pairs] + list(reduced)).xreplace(rename)) if rename else list(reduced)
    )
    return list(zip(rename.values(), done[: len(pairs)])), done[len(pairs) :]


def _numbers_only(
    pairs: list[tuple[Any, Any]], reduced: list[Any]
) -> tuple[list[tuple[Any, Any]], list[Any]]:
    """SymEngine's elimination without its truth-valued subexpressions.  A condition that two
    ``Piecewise`` share (``t < a``) becomes a symbol ``x0`` and each condition ``x0 == True``,
    which the code printed from it would have to hold as a number and compare with ``true`` (not
    C99).  Each such condition is put back where it was used."""
    back: dict[Any, Any] = {}
    kept = []
    for s, v in pairs:  # in order: a later one may use an earlier condition
        v = v.xreplace(back) if back else v
        if isinstance(v, _se_boolean):
            back[_se_eq(s, True)] = v  # (the node that uses it; matched before its symbol)
            back[s] = v
        else:
            kept.append((s, v))
    if not back:
        return pairs, reduced
    return kept, [r.xreplace(back) for r in reduced]


def shown_nonzero(exprs: Sequence[Any], seed: int = 31) -> list[bool]:
    """Whether each SymEngine expression is shown not to vanish identically by its value at one
    random rational point, computed twice: in double precision and in 200 bits (MPFR), the point
    rounded to each.  A nonzero value is the same number both times; an expression that is 0
    gives rounding noise, ~1e-16 and ~1e-60 of its terms, which never agree to six digits.  False
    (not shown) for agreeing values only short of that, a pole, or anything not evaluated.  The
    point enters as floating numbers, so that each operation is one rounded number (the exact
    rationals of an exact substitution grew with every operation: 0.04 s of the rattleback's
    build)."""
    import random

    rng = random.Random(seed)
    symbols = sorted({x for e in exprs for x in e.free_symbols}, key=str)
    point = {x: _se_integer(rng.randint(50, 150)) / _se_integer(rng.randint(90, 110)) for x in symbols}
    low_point = {x: v.n(53) for x, v in point.items()}
    high_point = {x: v.n(200) for x, v in point.items()}
    out = []
    for e in exprs:
        try:
            low = complex(e.subs(low_point).n(53, real=False))
            high = complex(e.subs(high_point).n(200, real=False))
        except (ArithmeticError, RuntimeError, TypeError, ValueError):
            out.append(False)
            continue
        size = abs(high)
        out.append(bool(0 < size < float("inf") and abs(low - high) <= 1e-6 * size))
    return out


def evaluator(args: Sequence[sp.Symbol], exprs: Sequence[sp.Expr], *, real: bool = False) -> Any | None:
    """A function of a sample ``(len(args),)`` returning the complex values of ``exprs`` (the
    real ones with ``real``: NaN where a value is not real).

    SymEngine's ``Lambdify`` (no code generation, so it is cheap to build); None
    when SymEngine cannot represent the expressions.  Singular points give
    ``inf``/``nan``.
    """
    fast = native(list(args) + list(exprs))
    if fast is None:
        return None
    try:
        return _se_lambdify(fast[: len(args)], fast[len(args) :], real=real)
    except (RuntimeError, NotImplementedError, TypeError):
        return None
