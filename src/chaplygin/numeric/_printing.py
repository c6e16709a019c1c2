"""Python and C source for SymEngine expressions: the printers of generated code.

Generated code is printed straight from the SymEngine expressions that
SymEngine's ``cse`` returns, without converting them back to SymPy (at a
thousand lines that conversion and SymPy's printers cost more than deriving
the equations).  The output follows SymPy's ``PythonCodePrinter`` and
``C99CodePrinter``: ``math.``-qualified functions in Python, ``math.h`` in C,
negative powers as divisions, floats with every digit (``repr``), operands
parenthesised by precedence.  An exact number is printed so that C, Python,
NumPy and numba all compute with the double nearest to it (:func:`number`): an
integer or a rational whose numerator and denominator are exact doubles (at
most 2**53) as it is (a rational as a floating-point quotient, which IEEE
arithmetic rounds correctly, never C's integer division); any other as its
correctly rounded double, the ``repr`` of Python's exact ``p / q`` — never an
integer literal beyond 64 bits, which a C compiler truncates with only a
warning and numba refuses.
Anything else (a function neither language has here, ``oo``, ``I``) and
every SymPy expression (SymPy's cse, where SymEngine cannot represent a model)
is printed by SymPy's printers.
"""

from __future__ import annotations

import math
from typing import Any

import symengine as se
import sympy as sp
from sympy.printing.c import C99CodePrinter
from sympy.printing.codeprinter import PrintMethodNotImplementedError
from sympy.printing.pycode import PythonCodePrinter

from chaplygin.errors import ChaplyginError, ModelError

__all__ = ["NotPrintable", "code", "impulse_message", "number"]


class NotPrintable(Exception):
    """This printer has no translation of a node; print the expression with SymPy."""


_ONE_ARG = (
    "sin",
    "cos",
    "tan",
    "asin",
    "acos",
    "atan",
    "sinh",
    "cosh",
    "tanh",
    "asinh",
    "acosh",
    "atanh",
    "exp",
    "log",
    "floor",
)
#: SymEngine function name → (Python, C)
_FUNCTIONS: dict[str, tuple[str, str]] = {
    **{name: (f"math.{name}", name) for name in _ONE_ARG},
    "ceiling": ("math.ceil", "ceil"),
    "Abs": ("abs", "fabs"),
    "atan2": ("math.atan2", "atan2"),
    "Max": ("max", "fmax"),
    "Min": ("min", "fmin"),
}
_CONSTANTS = {"Pi": math.pi, "Exp1": math.e}

# precedence: atoms and calls bind tightest, then powers, products, unary minus, sums
_ADD, _NEG, _MUL, _POW, _ATOM = 1, 2, 3, 4, 5
_REAL = (se.Integer, se.Rational, se.RealDouble)
#: integers up to this magnitude are exact doubles (and fit C's ``long long``)
EXACT = 2**53


def number(p: int, q: int, c: bool) -> str:
    """The exact number ``p/q`` (``q > 0``) as a C (``c``) or Python literal: its double.

    ``p`` and ``q`` within :data:`EXACT` print as they are, ``q > 1`` as a quotient
    of two doubles (``p.0/q.0`` in C, ``p/q`` in Python: one correctly rounded
    division; callers parenthesise it); any other number as the ``repr`` of its
    correctly rounded double.

    Raises
    ------
    ChaplyginError
        For a number beyond the range of doubles (about 1.8e308).
    """
    if abs(p) <= EXACT and q <= EXACT:
        if q == 1:
            return str(p)
        return f"{p}.0/{q}.0" if c else f"{p}/{q}"
    try:
        value = p / q  # Python's true division of integers rounds correctly
    except OverflowError:
        digits = len(str(abs(p))) - len(str(q))
        raise ChaplyginError(
            f"a number in the equations, about 10^{digits}, is beyond the range of double precision "
            "(about 1.8e308), so no generated code can compute with it; rescale the system's units."
        ) from None
    return repr(value)


class _C(C99CodePrinter):
    """SymPy's C printer with exact numbers printed by :func:`number`."""

    def _print_Integer(self, expr: Any) -> str:
        return number(int(expr), 1, True)

    def _print_Rational(self, expr: Any) -> str:
        return number(int(expr.p), int(expr.q), True)


class _Python(PythonCodePrinter):
    """SymPy's Python printer with exact numbers printed by :func:`number`."""

    def _print_Integer(self, expr: Any) -> str:
        return number(int(expr), 1, False)

    def _print_Rational(self, expr: Any) -> str:
        return number(int(expr.p), int(expr.q), False)


def code(expr: Any, language: str) -> str:
    """``expr`` (SymEngine or SymPy) as a ``"python"`` or ``"c"`` expression.

    Raises
    ------
    sympy.printing.codeprinter.PrintMethodNotImplementedError
        For a function the language has no translation of.
    ModelError
        For ``DiracDelta`` (a derivative of ``sign``), which no language evaluates.
    """
    if not isinstance(expr, sp.Basic):
        try:
            return _print(expr, language == "c")[0]
        except NotPrintable:
            expr = expr._sympy_()
    try:
        if language == "c":
            return _C({"strict": True}).doprint(expr)
        return _Python({"fully_qualified_modules": True, "standard": "python3"}).doprint(expr)
    except PrintMethodNotImplementedError:
        if expr.has(sp.DiracDelta):  # (no language has it: say why, rather than that C lacks it)
            raise ModelError(impulse_message([])) from None
        raise


def impulse_message(arguments: list[str]) -> str:
    """Why equations holding ``DiracDelta`` of ``arguments`` (file syntax; none known: []) are not run."""
    where = ", ".join(arguments) or "its argument"
    return (
        f"the equations contain DiracDelta({where}), the derivative of sign({where}) (or of an abs() "
        f"differentiated twice: sign() in a constraint's coefficient, abs() in a holonomic relation): "
        f"an impulse where {where} = 0, which no integrator here takes. If the motion stays on one "
        f"side of {where} = 0, write the expression for that side (sign(u) as 1 or -1, abs(u) as u "
        "or -u); sign() and abs() may stand in forces and abs() in the coefficients of constraints "
        "linear in the velocities."
    )


def _negative(e: Any) -> bool:
    """A real number below 0, or a product whose numerical coefficient is."""
    if isinstance(e, se.Mul):
        e = e.args[0]
    if isinstance(e, se.RealDouble):
        return float(e) < 0
    return isinstance(e, (se.Integer, se.Rational)) and int(e.p) < 0


def _print(e: Any, c: bool) -> tuple[str, int]:
    """(source, precedence) of ``e``; ``c``: C, else Python."""
    if isinstance(e, se.Dummy):  # never in generated code: every symbol is renamed first
        raise NotPrintable(f"Dummy {e}")
    if isinstance(e, se.Symbol):
        return e.name, _ATOM
    if isinstance(e, _REAL) and _negative(e):
        return f"-{_print(-e, c)[0]}", _NEG
    if isinstance(e, (se.Integer, se.Rational)):
        text = number(int(e.p), int(e.q), c)
        return (f"({text})" if "/" in text else text), _ATOM
    if isinstance(e, se.RealDouble):
        value = float(e)
        if not math.isfinite(value):
            raise NotPrintable(str(e))
        return repr(value), _ATOM
    name = type(e).__name__
    if name in _CONSTANTS:
        return repr(_CONSTANTS[name]), _ATOM
    if isinstance(e, se.Add):
        return _add(e, c), _ADD
    if isinstance(e, se.Mul):
        return _mul(e, c)
    if isinstance(e, se.Pow):
        return _pow(e, c)
    if name in _FUNCTIONS:
        args = ", ".join(_print(a, c)[0] for a in e.args)
        return f"{_FUNCTIONS[name][c]}({args})", _ATOM
    raise NotPrintable(name)


def _wrap(part: tuple[str, int], above: int) -> str:
    """The source of ``part``, in parentheses unless it binds tighter than ``above``."""
    text, prec = part
    return text if prec > above else f"({text})"


def _ordered(args: Any, c: bool) -> list[tuple[Any, tuple[str, int]]]:
    """``args`` of a sum or product with their printed forms, in the order of those texts.

    SymEngine's order of the terms of a sum or the factors of a product follows
    memory addresses and so changes between processes; printed in this order
    the generated source (and every cache keyed by it) does not.
    """
    return sorted(((a, _print(a, c)) for a in args), key=lambda item: item[1][0])


def _add(e: Any, c: bool) -> str:
    out = ""
    for term, printed in _ordered(e.args, c):
        if out and _negative(term):
            out += " - " + _wrap(_print(-term, c), _NEG)
        else:
            out += (" + " if out else "") + _wrap(printed, _ADD)
    return out


def _mul(e: Any, c: bool) -> tuple[str, int]:
    if _negative(e):
        return "-" + _wrap(_print(-e, c), _NEG), _NEG
    num, den = [], []
    for f in e.args:
        if isinstance(f, se.Pow) and _negative(f.args[1]):
            den.append(f.args[0] ** -f.args[1])
        else:
            num.append(f)
    top = "*".join(_wrap(p, _MUL) for _, p in _ordered(num, c)) or ("1.0" if c else "1")
    if not den:
        return top, _MUL
    bottom = "*".join(_wrap(p, _MUL) for _, p in _ordered(den, c))
    return f"{top}/{bottom if len(den) == 1 and not isinstance(den[0], se.Mul) else f'({bottom})'}", _MUL


def _pow(e: Any, c: bool) -> tuple[str, int]:
    base, exp = e.args
    if type(base).__name__ == "Exp1":
        return f"{_FUNCTIONS['exp'][c]}({_print(exp, c)[0]})", _ATOM
    if _negative(exp):
        return f"{'1.0' if c else '1'}/{_wrap(_print(base**-exp, c), _MUL)}", _MUL
    if exp == se.S.Half:
        return f"{'sqrt' if c else 'math.sqrt'}({_print(base, c)[0]})", _ATOM
    if c:
        return f"pow({_print(base, c)[0]}, {_print(exp, c)[0]})", _ATOM
    return f"{_wrap(_print(base, c), _POW)}**{_wrap(_print(exp, c), _POW)}", _POW
