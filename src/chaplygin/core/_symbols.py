"""Private symbol layer: dynamicsymbols on the outside, plain symbols inside.

The user writes coordinates as ``sympy.physics.mechanics.dynamicsymbols``
(functions of ``t``).  Differentiating with respect to ``q(t)`` and
``Derivative(q(t), t)`` is slow in SymPy, so every derivation works on plain
dummy symbols ``q``, ``qd`` (velocity) and ``qdd`` (acceleration) and converts
back only for what the user sees.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import sympy as sp

#: the time, ``sympy.physics.mechanics.dynamicsymbols._t`` (the same symbol: ``Symbol("t")``),
#: written here so that nothing imports ``sympy.physics`` (0.15 s, its units) unless asked
TIME: sp.Symbol = sp.Symbol("t")


def function_of_time(name: str) -> sp.Expr:
    """The coordinate ``name(t)``: the same object as ``dynamicsymbols(name)``."""
    return sp.Function(name)(TIME)


@dataclass(frozen=True)
class Vars:
    """Plain-symbol stand-ins for functions of time and their derivatives.

    ``funcs[i]`` is a dynamicsymbol; ``x[i]``, ``xd[i]``, ``xdd[i]`` stand for
    it and its first and second time derivatives.
    """

    funcs: tuple[sp.Expr, ...]
    x: tuple[sp.Symbol, ...] = field(init=False)
    xd: tuple[sp.Symbol, ...] = field(init=False)
    xdd: tuple[sp.Symbol, ...] = field(init=False)

    def __post_init__(self) -> None:
        names = [f.func.__name__ for f in self.funcs]
        object.__setattr__(self, "x", tuple(sp.Dummy(n) for n in names))
        object.__setattr__(self, "xd", tuple(sp.Dummy(n + "_d") for n in names))
        object.__setattr__(self, "xdd", tuple(sp.Dummy(n + "_dd") for n in names))

    def to_symbols(self) -> dict[sp.Expr, sp.Symbol]:
        """Map ``f, f', f''`` to the plain symbols (use with ``xreplace``)."""
        out: dict[sp.Expr, sp.Symbol] = {}
        for f, x, xd, xdd in zip(self.funcs, self.x, self.xd, self.xdd):
            out[f.diff(TIME, 2)] = xdd
            out[f.diff(TIME)] = xd
            out[f] = x
        return out

    def to_functions(self) -> dict[sp.Symbol, sp.Expr]:
        """Map the plain symbols back to ``f, f', f''``."""
        return {v: k for k, v in self.to_symbols().items()}


def total_derivative(
    expr: sp.Expr,
    pairs: Iterable[tuple[sp.Symbol, sp.Expr]],
) -> sp.Expr:
    """Total time derivative ``∂_t F + Σ ∂F/∂x · ẋ`` for the given ``(x, ẋ)`` pairs."""
    from chaplygin.core._fast import total_derivative as fast

    pairs = [(x, xd) for x, xd in pairs if expr.has(x)]
    if not pairs and not expr.has(TIME):
        return sp.S.Zero
    return fast(expr, pairs, TIME)


def linear_coefficients(
    expr: sp.Expr, variables: Sequence[sp.Symbol], *, factored: bool = True
) -> tuple[list[sp.Expr], sp.Expr] | None:
    """Split ``expr = Σ c_i v_i + c_0`` with the ``c`` free of ``variables``, each with its
    common factors taken out (``sympy.factor_terms``) unless not ``factored`` (for a caller that
    puts them in normal form at once).

    Returns ``None`` when ``expr`` is not affine in ``variables``.
    """
    from chaplygin.core._fast import gradient

    coeffs = gradient(expr, variables) if variables else []
    if variables and any(c.has(*variables) for c in coeffs):
        expr = sp.expand(expr)
        coeffs = gradient(expr, variables)
        if any(c.has(*variables) for c in coeffs):
            return None
    rest = expr.xreplace({v: 0 for v in variables})
    if not factored:
        return list(coeffs), rest
    return [sp.factor_terms(c) for c in coeffs], sp.factor_terms(rest)


def functions_of_time(expr: sp.Expr) -> set[sp.Expr]:
    """Undefined functions of ``t`` inside ``expr`` (``f(t)`` objects)."""
    from sympy.core.function import AppliedUndef

    return {f for f in expr.atoms(AppliedUndef) if f.args == (TIME,)}


def other_undefined(expr: sp.Expr) -> set[sp.Expr]:
    """Undefined functions whose argument is not exactly ``t``."""
    from sympy.core.function import AppliedUndef

    return {f for f in expr.atoms(AppliedUndef) if f.args != (TIME,)}


_TRIGSIMP_MAX_OPS = 120  # larger expressions are only factored, to keep display fast


def simplify_small(expr: sp.Expr) -> sp.Expr:
    """``factor_terms``, after ``trigsimp`` for small expressions with squared sines or cosines.

    ``trigsimp`` is slow; it only pays off where ``sin² + cos² = 1`` can apply.
    """
    squares = any(
        isinstance(p.base, (sp.sin, sp.cos)) and p.exp.is_number and abs(p.exp) >= 2
        for p in expr.atoms(sp.Pow)
    )
    if squares and sp.count_ops(expr) <= _TRIGSIMP_MAX_OPS:
        expr = sp.trigsimp(expr)
    return sp.factor_terms(expr)


def replace_shared(expr: Any, mapping: Mapping[sp.Basic, sp.Basic]) -> Any:
    """``expr.xreplace(mapping)`` (an expression or a matrix), visiting each distinct subexpression once.

    SymPy's ``xreplace`` walks the expression as a tree: a subexpression shared by many
    terms (a rolling body's solved accelerations are built of a few such) is walked again
    at every use, 1.7 million visits for the rattleback's.  Same result, as a walk of the DAG.
    """
    memo: dict[sp.Basic, sp.Basic] = dict(mapping)

    def walk(e: sp.Basic) -> sp.Basic:
        done = memo.get(e)
        if done is not None:
            return done
        args = [walk(a) for a in e.args]
        new = e.func(*args) if any(a is not b for a, b in zip(args, e.args)) else e
        memo[e] = new
        return new

    if isinstance(expr, sp.MatrixBase):  # a matrix is not hashable; its entries share one memo
        return expr.applyfunc(walk)
    return walk(expr)


def file_syntax(expr: sp.Basic) -> str:
    """An expression as the system files write it: ``q``, ``q'``, ``q''`` for a coordinate and
    its time derivatives (never ``Derivative(q(t), (t, 2))``), ``**`` for powers, ``abs(…)``.

    The one printer of expressions for output and for messages (:func:`describe`).  Terms are
    printed in SymPy's display order up to :data:`ORDERED_NODES` nodes; a larger expression (a
    rolling body's equations run to pages) keeps the order of its arguments, as deterministic
    and with nothing sorted: a third less time.
    """
    return str(_printer()({"order": None if _small(expr) else "none"}).doprint(expr))


#: the largest expression (nodes of its tree) printed with its terms sorted for display
ORDERED_NODES = 20_000


def _small(expr: sp.Basic) -> bool:
    """Whether ``expr``'s tree has at most :data:`ORDERED_NODES` nodes, counted on its DAG (a
    rolling body's equations share subexpressions: a few thousand distinct ones print to pages)."""
    size: dict[sp.Basic, int] = {}

    def count(e: sp.Basic) -> int:
        if e not in size:
            size[e] = 1 + sum(count(a) for a in e.args)
        return size[e]

    return count(expr) <= ORDERED_NODES


@functools.cache
def _printer() -> Any:
    """The printer class (built on first use: sympy.physics.vector is imported then)."""
    from sympy.physics.vector.printing import VectorStrPrinter

    class FilePrinter(VectorStrPrinter):
        """The file syntax, each distinct compound subexpression printed once.

        A rolling body's equations share subexpressions used thousands of times; SymPy's
        printer walks the tree and prints each use again (2 s for the rattleback's mass matrix
        and forcing, 0.1 s memoised).  The text of a compound node depends only on the node:
        its arguments are always printed nested, where a ``Float`` prints the same whatever the
        depth (only an atom printed alone differs, and atoms are not memoised).
        """

        def __init__(self, settings: dict[str, Any]) -> None:
            super().__init__(settings)
            self._printed: dict[sp.Basic, str] = {}

        def _print(self, expr: Any, **kwargs: Any) -> str:
            if kwargs or not isinstance(expr, sp.Basic) or not expr.args:
                return str(super()._print(expr, **kwargs))
            text = self._printed.get(expr)
            if text is None:
                text = self._printed[expr] = str(super()._print(expr))
            return text

        def _print_Abs(self, e: sp.Expr) -> str:
            return f"abs({self._print(e.args[0])})"

        def _print_Exp1(self, e: sp.Expr) -> str:
            return "exp(1)"

    return FilePrinter


def vsstrrepr(expr: Any) -> str:
    """``expr`` as ``str`` prints it with ``sympy.physics.vector`` loaded (``q'``-free, ``q(t)``
    as ``q``): :func:`sympy.physics.vector.printing.vsstrrepr`, imported on first use."""
    from sympy.physics.vector.printing import vsstrrepr as printed

    return str(printed(expr))


def describe(value: object) -> str:
    """``value`` for a message: SymPy objects in the file syntax (:func:`file_syntax`), anything
    else as its ``repr``."""
    return file_syntax(value) if isinstance(value, sp.Basic) else repr(value)


def pretty(exprs: Iterable[sp.Basic]) -> str:
    """A multi-line Unicode rendering of each expression (dots for time derivatives, Greek
    letters), one after another with a blank line between: what ``chaplygin demo`` and
    ``chaplygin derive --format pretty`` print."""
    from sympy.physics.vector.printing import VectorPrettyPrinter
    from sympy.printing.pretty.pretty_symbology import pretty_use_unicode

    printer = VectorPrettyPrinter({"use_unicode": True, "wrap_line": False})
    previous = pretty_use_unicode(True)  # Greek letters follow a global flag
    try:
        return "\n\n".join(printer.doprint(e) for e in exprs)
    finally:
        pretty_use_unicode(previous)
