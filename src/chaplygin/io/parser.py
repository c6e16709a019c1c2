"""A safe parser for the expressions of system files.

User text is never handed to Python or to SymPy's own string parsers: it is
read by the small recursive-descent parser below, which builds SymPy objects
directly from a whitelist.  The grammar (``docs/system-files.md``)::

    expression := term (("+" | "-") term)*
    term       := unary (("*" | "/") unary)*
    unary      := ("+" | "-") unary | power
    power      := primary (("^" | "**") unary)?          # right-associative
    primary    := NUMBER | NAME | VELOCITY | NAME "(" arguments ")" | "(" expression ")"
    arguments  := expression ("," expression)*            # no trailing comma
    VELOCITY   := NAME "'"                                 # no space before the prime

* ``NUMBER``: ``2``, ``0.5``, ``.5``, ``1.5e-3``; always an **exact** rational
  (``0.1`` is ``1/10``), so derivations stay exact;
* ``NAME``: a parameter (a real SymPy ``Symbol``), a coordinate (a
  ``dynamicsymbol``), ``t`` (time), the constants ``pi`` and ``E``;
* ``x'``: the velocity of the coordinate ``x`` (a first derivative; ``x''`` is
  refused);
* the functions of :data:`FUNCTIONS`, with their number of arguments checked.

Limits (:data:`MAX_EXPRESSION_LENGTH`, :data:`MAX_TOKENS`, :data:`MAX_DEPTH`,
:data:`MAX_EXPONENT`, :data:`MAX_EXPONENT_NUMERATOR`, :data:`MAX_NUMBER_BITS`,
:data:`MAX_ROOT_BITS`, :data:`MAX_EXPANDED_TERMS`, :data:`MAX_HYPERBOLIC_TERMS`,
:data:`MAX_REDUCED_ANGLE`) are checked *before* SymPy is asked to build
anything that could be expensive, so hostile text such as ``9^9^9^9`` or a
hundred thousand nested parentheses is refused at once instead of hanging.

Every error is a :class:`ParseError` (a :class:`SystemFileError`): it names the
column, shows the text with a caret under it and says what is allowed.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import mpmath
import sympy as sp
from sympy.core.parameters import global_parameters

from chaplygin.core._symbols import TIME
from chaplygin.errors import ChaplyginError

__all__ = [
    "CONSTANTS",
    "ERROR_KINDS",
    "FUNCTIONS",
    "MAX_DEPTH",
    "MAX_EXPANDED_TERMS",
    "MAX_EXPONENT",
    "MAX_EXPONENT_NUMERATOR",
    "MAX_EXPRESSION_LENGTH",
    "MAX_HYPERBOLIC_TERMS",
    "MAX_LITERAL_DIGITS",
    "MAX_NAME_LENGTH",
    "MAX_NUMBER_BITS",
    "MAX_REDUCED_ANGLE",
    "MAX_ROOT_BITS",
    "MAX_TOKENS",
    "RESERVED",
    "Names",
    "ParseError",
    "SystemFileError",
    "check_name",
    "coordinate_function",
    "parameter_symbol",
    "parse_constant",
    "parse_expression",
    "preserved_state",
]

# ---------------------------------------------------------------------------- limits
#: Longest expression text, in characters.
MAX_EXPRESSION_LENGTH = 20_000
#: Most tokens (numbers, names, operators, primes, parentheses) in one expression.
MAX_TOKENS = 10_000
#: Deepest nesting of parentheses, function calls, unary signs and powers.
MAX_DEPTH = 50
#: Largest absolute value of a numeric exponent (and largest denominator of a rational one).
MAX_EXPONENT = 1000
#: Largest numerator of a rational coefficient in an exponent, that of a power or the argument of
#: ``exp`` (its constant term and the coefficient of each of its terms): SymPy's polynomial code
#: (used, e.g., when it decides whether ``sinh(u)`` is real) stores ``exp(p*u/q)`` as the power
#: ``p`` of a generator ``exp(u/q)``, in a list of ``p`` coefficients.
MAX_EXPONENT_NUMERATOR = 10_000
#: Largest exact number (in bits, numerator plus denominator) an expression may produce; also
#: the largest size of any constant (``exp(3000)`` is about ``2**4328``: refused), as ``log2 |c|``.
MAX_NUMBER_BITS = 4096
#: Largest (bits of the radicand) × (degree of the root) for an exact root of a number.
MAX_ROOT_BITS = 1024
#: Most terms the full expansion of an expression may have (SymPy expands kinetic energies).
MAX_EXPANDED_TERMS = 10_000
#: Most terms the argument of sinh, cosh or tanh may have when expanded into real and imaginary
#: parts (each coordinate, velocity and t counting two); see ``_Parser.check_hyperbolic``.  The
#: same bound applies to the base of a power whose exponent has a sum in a denominator (SymPy
#: splits such a base into real and imaginary parts too).
MAX_HYPERBOLIC_TERMS = 32
#: Largest constant ``c`` in ``asin``, ``acos`` or ``atan`` of ``sin(c)``, ``cos(c)`` or ``tan(c)``:
#: SymPy reduces ``c`` modulo π exactly there, which fails or takes minutes for huge ``c``.
MAX_REDUCED_ANGLE = 10**50
#: Most digits in one number literal, and the largest power of ten of its exponent.
MAX_LITERAL_DIGITS = 100
MAX_LITERAL_EXPONENT = 400
#: Longest parameter or coordinate name.
MAX_NAME_LENGTH = 64

#: The functions an expression may call, with their number of arguments.
FUNCTIONS: dict[str, int] = {
    "sin": 1,
    "cos": 1,
    "tan": 1,
    "asin": 1,
    "acos": 1,
    "atan": 1,
    "atan2": 2,
    "sinh": 1,
    "cosh": 1,
    "tanh": 1,
    "exp": 1,
    "log": 1,
    "sqrt": 1,
    "abs": 1,
    "sign": 1,
}
_SYMPY_FUNCTIONS: dict[str, Callable[..., sp.Expr]] = {
    "sin": sp.sin,
    "cos": sp.cos,
    "tan": sp.tan,
    "asin": sp.asin,
    "acos": sp.acos,
    "atan": sp.atan,
    "atan2": sp.atan2,
    "sinh": sp.sinh,
    "cosh": sp.cosh,
    "tanh": sp.tanh,
    "exp": sp.exp,
    "log": sp.log,
    "abs": sp.Abs,
    "sign": sp.sign,
}
_HYPERBOLIC = frozenset({"sinh", "cosh", "tanh"})
#: Named constants.
CONSTANTS: dict[str, sp.Expr] = {"pi": sp.pi, "E": sp.E}
#: Names that cannot be parameters or coordinates.
RESERVED = frozenset({"t", *CONSTANTS, *FUNCTIONS})

_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")
_TOKEN = re.compile(
    r"(?P<space>[ \t\r\n]+)"
    r"|(?P<number>(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?)"
    r"|(?P<name>[A-Za-z_][A-Za-z0-9_]*)"
    r"|(?P<op>\*\*|[-+*/^(),'])"
)
_NUMBER_PARTS = re.compile(r"([0-9]*)(?:\.([0-9]*))?(?:[eE]([+-]?[0-9]+))?\Z")
_UNDEFINED = (sp.S.ComplexInfinity, sp.S.NaN, sp.S.Infinity, sp.S.NegativeInfinity)

SYNTAX = (
    "Allowed: numbers (2, 0.5, 1e-3), names, x' (velocity of the coordinate x), "
    "+ - * / ^ ** and parentheses, and the functions " + ", ".join(FUNCTIONS) + "."
)


# ---------------------------------------------------------------------------- errors
def _excerpt(text: str, column: int, width: int = 72) -> tuple[str, int]:
    """The line of ``text`` that holds ``column``, cut to ``width`` around it; caret offset."""
    column = max(0, min(column, len(text)))
    start = text.rfind("\n", 0, column) + 1
    end = text.find("\n", column)
    end = len(text) if end < 0 else end
    line, col = text[start:end], column - start
    line = "".join(c if c.isprintable() else "?" for c in line)
    if len(line) > width:
        lo = max(0, min(col - width // 2, len(line) - width))
        hi = lo + width
        prefix, suffix = ("…" if lo > 0 else ""), ("…" if hi < len(line) else "")
        line, col = prefix + line[lo:hi] + suffix, col - lo + len(prefix)
    return line, col


class SystemFileError(ChaplyginError, ValueError):
    """A system file (or one of its expressions) is invalid.

    ``str(err)`` reads ``SOURCE: KEY: REASON``, then the offending text with a
    caret under the column, then what is allowed.

    Attributes
    ----------
    reason : str
        What is wrong.
    source : str or None
        The file (a path or ``"<string>"``).
    key : str or None
        Where in the file, e.g. ``[constraints] "x'"``.
    text : str or None
        The text that was being read (an expression, or a line of the file).
    column : int or None
        0-based column of the problem within :attr:`text`.
    line : int or None
        1-based line of the file, when known (TOML syntax errors).
    allowed : str or None
        What would be accepted.
    """

    def __init__(
        self,
        reason: str,
        *,
        source: str | None = None,
        key: str | None = None,
        text: str | None = None,
        column: int | None = None,
        line: int | None = None,
        allowed: str | None = None,
    ) -> None:
        self.reason = reason
        self.source = source
        self.key = key
        self.text = text
        self.column = column
        self.line = line
        self.allowed = allowed
        super().__init__(self._render())

    def _fields(self) -> dict[str, Any]:
        return {
            "source": self.source,
            "key": self.key,
            "text": self.text,
            "column": self.column,
            "line": self.line,
            "allowed": self.allowed,
        }

    def located(self, **where: Any) -> SystemFileError:
        """A copy with ``source``/``key``/``line`` filled in (values already set win for None)."""
        fields = self._fields()
        fields.update({k: v for k, v in where.items() if v is not None})
        return type(self)(self.reason, **fields)

    def _render(self) -> str:
        head = []
        if self.source:
            head.append(self.source)
        if self.line is not None:
            head.append(
                f"line {self.line}" + (f", column {self.column + 1}" if self.column is not None else "")
            )
        if self.key:
            head.append(self.key)
        lines = [": ".join([*head, self.reason])]
        if self.text is not None:
            shown, col = _excerpt(self.text, self.column or 0)
            lines.append("    " + shown)
            if self.column is not None:
                lines.append("    " + " " * col + "^")
        if self.allowed:
            lines.append(self.allowed)
        return "\n".join(lines)

    def __str__(self) -> str:
        return self._render()

    def __reduce__(self) -> tuple[Any, ...]:
        return (_rebuild, (type(self), self.reason, self._fields()))


def _rebuild(cls: type[SystemFileError], reason: str, fields: dict[str, Any]) -> SystemFileError:
    return cls(reason, **fields)


class ParseError(SystemFileError):
    """An expression does not follow the grammar, breaks a limit or has no value.

    Attributes
    ----------
    kind : str
        Why the text was refused, one of :data:`ERROR_KINDS`: ``"syntax"`` (not in the
        grammar), ``"name"`` (an unknown or misused name), ``"limit"`` (one of the limits
        of the module docstring), ``"value"`` (a division by zero, a singular function
        value, a constant that is not a finite real number) or ``"internal"`` (SymPy or
        mpmath failed on the expression: a bug of chaplygin's, to be reported).
    """

    def __init__(self, reason: str, *, kind: str = "syntax", **fields: Any) -> None:
        if kind not in ERROR_KINDS:
            raise ValueError(f"unknown kind of parse error {kind!r}; one of {', '.join(ERROR_KINDS)}")
        self.kind = kind
        super().__init__(reason, **fields)

    def _fields(self) -> dict[str, Any]:
        return {**super()._fields(), "kind": self.kind}


#: The kinds of :class:`ParseError`.
ERROR_KINDS = ("syntax", "name", "limit", "value", "internal")


# ---------------------------------------------------------------------------- names
def parameter_symbol(name: str) -> sp.Symbol:
    """The SymPy symbol of a parameter: a plain real symbol."""
    return sp.Symbol(name, real=True)


def coordinate_function(name: str) -> sp.Expr:
    """The coordinate ``name(t)``, the same object as ``dynamicsymbols(name)``."""
    return sp.Function(name)(TIME)


def check_name(name: Any, what: str = "name") -> str:
    """Check a parameter or coordinate name; return it, or raise :class:`ParseError`."""
    allowed = (
        "Names start with an ASCII letter, then letters, digits or _ "
        f"(at most {MAX_NAME_LENGTH} characters), e.g. m, theta, x_1; "
        "t, pi, E and the function names are reserved."
    )
    if not isinstance(name, str):
        raise ParseError(f"{what} must be a string, got {type(name).__name__} {name!r}", allowed=allowed)
    if len(name) > MAX_NAME_LENGTH:
        raise ParseError(f"{what} is longer than {MAX_NAME_LENGTH} characters", allowed=allowed)
    if not _NAME.match(name):
        bad = next((i for i, c in enumerate(name) if not (c.isascii() and (c.isalnum() or c == "_"))), 0)
        reason = f"{what} {name!r} is not a valid name"
        if name.startswith("_"):
            reason += " (names may not start with _)"
        raise ParseError(reason, text=name, column=bad, allowed=allowed)
    if name in RESERVED:
        kind = "time" if name == "t" else "a constant" if name in CONSTANTS else "a function"
        raise ParseError(f"{what} {name!r} is reserved ({kind})", text=name, column=0, allowed=allowed)
    return name


@dataclass(frozen=True)
class Names:
    """The names an expression may use.

    ``parameters`` maps names to symbols (see :func:`parameter_symbol`),
    ``coordinates`` names to ``dynamicsymbols``; ``time`` says whether ``t`` is
    allowed (it is not in numeric values such as ``[initial]``).
    """

    parameters: Mapping[str, sp.Symbol] = field(default_factory=dict)
    coordinates: Mapping[str, sp.Expr] = field(default_factory=dict)
    time: bool = True

    @classmethod
    def build(
        cls, parameters: Iterable[str] = (), coordinates: Iterable[str] = (), *, time: bool = True
    ) -> Names:
        """Names from plain strings: parameters become real symbols, coordinates dynamicsymbols."""
        return cls(
            {p: parameter_symbol(p) for p in parameters},
            {q: coordinate_function(q) for q in coordinates},
            time,
        )

    def describe(self) -> str:
        """The known names, for error messages."""
        parts = []
        if self.parameters:
            parts.append("parameters " + ", ".join(self.parameters))
        if self.coordinates:
            first = next(iter(self.coordinates))
            parts.append("coordinates " + ", ".join(self.coordinates) + f" (and velocities such as {first}')")
        if self.time:
            parts.append("time t")
        parts.append("constants " + ", ".join(CONSTANTS))
        return "Known names: " + "; ".join(parts) + "; functions " + ", ".join(FUNCTIONS) + "."

    def all(self) -> list[str]:
        return [*self.parameters, *self.coordinates, *(["t"] if self.time else []), *CONSTANTS, *FUNCTIONS]


# ---------------------------------------------------------------------------- parser
@dataclass
class _Token:
    kind: str  # "number", "name", "op", "end"
    text: str
    pos: int


@dataclass
class _Value:
    """A parsed subexpression and the number of terms its full expansion would have."""

    expr: sp.Expr
    terms: int
    pos: int


def _bits(r: sp.Rational) -> int:
    """Size of an exact rational: bits of the numerator, plus those of a denominator > 1."""
    q = int(r.q)
    return int(r.p).bit_length() + (q.bit_length() if q > 1 else 0)


def _log_bits(r: sp.Rational) -> float:
    """``log2 |p| + log2 q``: the bits each unit of exponent adds to a power of ``r``."""
    p, q = abs(int(r.p)), int(r.q)
    return (math.log2(p) if p > 1 else 0.0) + (math.log2(q) if q > 1 else 0.0)


def _numeric_factor_bits(expr: sp.Expr) -> tuple[float, float]:
    """Bits of the exact numbers SymPy would raise to a power with ``expr``.

    Returns ``(rational, radical)``: the bits of the rational coefficients among
    the factors of ``expr``, and Σ bits(radicand) × degree over its numeric
    radical factors such as ``2**(1/3)``.
    """
    rational = radical = 0.0
    for f in sp.Mul.make_args(expr):
        if f.is_Rational:
            rational += _log_bits(f)
        elif f.is_Pow and f.base.is_Rational and f.exp.is_Rational:
            radical += _log_bits(f.base) * int(f.exp.q)
    return rational, radical


class _Parser:
    def __init__(self, text: str, names: Names, velocity_message: str | None) -> None:
        self.text = text
        self.names = names
        self.velocity_message = velocity_message
        self.tokens = self._tokenize(text)
        self.i = 0
        self.depth = 0
        self.bounded: set[sp.Expr] = set()  # constants already checked by check_size
        self._complex: frozenset[sp.Expr] | None = None

    # ------------------------------------------------------------ helpers
    def error(self, reason: str, pos: int, allowed: str | None = SYNTAX, kind: str = "syntax") -> ParseError:
        return ParseError(reason, text=self.text, column=pos, allowed=allowed, kind=kind)

    def _tokenize(self, text: str) -> list[_Token]:
        tokens: list[_Token] = []
        pos = 0
        n = len(text)
        while pos < n:
            m = _TOKEN.match(text, pos)
            if m is None:
                raise self._bad_character(pos)
            kind = m.lastgroup
            assert kind is not None
            if kind != "space":
                tokens.append(_Token(kind, m.group(), pos))
                if len(tokens) > MAX_TOKENS:
                    raise self.error(
                        f"the expression has more than {MAX_TOKENS} tokens",
                        pos,
                        f"Limit: {MAX_TOKENS} numbers, names and operators per expression.",
                        "limit",
                    )
            pos = m.end()
        tokens.append(_Token("end", "", n))
        return tokens

    def _bad_character(self, pos: int) -> ParseError:
        c = self.text[pos]
        hints = {
            ".": "'.' is only a decimal point (0.5); attribute access is not part of the syntax",
            "[": "brackets are not part of the syntax; use parentheses ( )",
            "]": "brackets are not part of the syntax; use parentheses ( )",
            "{": "braces are not part of the syntax; use parentheses ( )",
            "}": "braces are not part of the syntax; use parentheses ( )",
            "=": "'=' is not part of an expression; a constraint is written as an expression that vanishes "
            "(lhs - (rhs)), an equation's right-hand side is the value of its key",
            '"': "quotes are not part of an expression",
            "'": "a prime ' follows a coordinate name, as in x'",
            "%": "'%' is not an operator here",
            "@": "'@' is not an operator here",
            ":": "':' is not part of the syntax",
            ";": "';' is not part of the syntax; write one expression",
            "\\": "backslashes are not part of the syntax",
            "|": "write abs(x) for the absolute value",
            "!": "'!' is not part of the syntax",
            "<": "comparisons are not part of the syntax",
            ">": "comparisons are not part of the syntax",
            "&": "'&' is not part of the syntax",
            "~": "'~' is not part of the syntax",
            "#": "comments belong in the TOML file, outside the quoted expression",
            "`": "backquotes are not part of the syntax",
            "$": "'$' is not part of the syntax",
            "?": "'?' is not part of the syntax",
        }
        if c in hints:
            reason = f"unexpected character {c!r}: {hints[c]}"
        elif not c.isascii():
            reason = f"unexpected character {c!r} (U+{ord(c):04X}): only ASCII letters, digits and operators are allowed"
        else:
            reason = f"unexpected character {c!r}"
        return self.error(reason, pos)

    def peek(self) -> _Token:
        return self.tokens[self.i]

    def take(self) -> _Token:
        tok = self.tokens[self.i]
        self.i += 1
        return tok

    def at(self, *ops: str) -> bool:
        tok = self.tokens[self.i]
        return tok.kind == "op" and tok.text in ops

    def enter(self, pos: int) -> None:
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise self.error(
                f"the expression is nested more than {MAX_DEPTH} levels deep",
                pos,
                f"Limit: {MAX_DEPTH} levels of parentheses, function calls, signs and powers.",
                "limit",
            )

    def leave(self) -> None:
        self.depth -= 1

    def check_defined(self, value: sp.Expr, pos: int) -> sp.Expr:
        if value.is_number and value.has(*_UNDEFINED):
            raise self.error(
                "the expression is undefined here (a division by zero or a singular function value)",
                pos,
                None,
                "value",
            )
        for factor in sp.Mul.make_args(value):  # exp(1e-300)*E is exp(1 + 1e-300): bound it again
            if isinstance(factor, sp.exp):
                self.check_exponent_numerators(factor.exp, pos, "the argument of exp")
        if value.is_Rational:
            if _bits(value) > MAX_NUMBER_BITS:
                raise self.error(
                    f"a number with more than {MAX_NUMBER_BITS} bits", pos, _NUMBER_LIMITS, "limit"
                )
            return value
        # Every constant is bounded as it is built, so that no evaluation by SymPy (which may happen
        # while building a later node) works at a precision as large as a constant's exponent.
        for c in [value] if value.is_number else [a for a in value.args if a.is_number]:
            if not c.is_Rational and c not in self.bounded:
                self.check_size(c, pos)
                self.bounded.add(c)
        return value

    def check_size(self, constant: sp.Expr, pos: int) -> None:
        """Refuse a constant above ``2**MAX_NUMBER_BITS`` in size, or not real (from 15 digits).

        Complex constants (``sqrt(-1)``, ``acos(2)``) have no place in a mechanical system, and
        SymPy's sign tests on functions of them can refine their precision without end.
        """
        value = self.evaluated(constant, pos)
        size = max((mpmath.mag(mpmath.mpf(f)) for f in value.atoms(sp.Float) if f != 0), default=0)
        real, imag = value.as_real_imag()
        if (
            imag.is_Float
            and imag != 0
            and (
                not real.is_Float
                or real == 0
                or mpmath.mag(mpmath.mpf(imag)) > mpmath.mag(mpmath.mpf(real)) - 40
            )
        ):
            raise self.error(
                f"this constant is not a finite real number (it is about {sp.sstr(value)[:60]})",
                pos,
                "Constants must be real: no square roots or logarithms of negative numbers, "
                "asin/acos only on [-1, 1].",
                "value",
            )
        if size > MAX_NUMBER_BITS:
            digits = size * 30103 // 100000  # log10(2) = 0.30103
            shown = f"about 10^{digits}" if digits < 10**9 else f"more than 10^(10^{len(str(digits)) - 1})"
            raise self.error(
                f"this constant is {shown} in size (limit 2^{MAX_NUMBER_BITS}, about 10^1233)",
                pos,
                _NUMBER_LIMITS,
                "limit",
            )

    def evaluated(self, constant: sp.Expr, pos: int) -> sp.Expr:
        """``constant`` to 15 digits, or to 100 where SymPy found a divisor 0 at 15.

        SymPy evaluates ``1/log(cosh(1e-17))`` by evaluating ``log(cosh(1e-17))``, which cancels
        to exactly 0 at its working precision, and then divides by it (``ZeroDivisionError``).
        More digits tell such a divisor from zero; one that is still 0 at 100 digits
        (``log(tanh(1e400))``, about ``-2*exp(-2e400)``) is refused.
        """
        try:
            return constant.evalf(15)
        except ZeroDivisionError:
            pass
        try:
            return constant.evalf(100)
        except ZeroDivisionError:
            raise self.error(
                "this constant divides by a number that cannot be told from zero at 100 digits",
                pos,
                "Divisors must differ from zero within 100 significant digits: write a tiny "
                "quantity itself (1e-40) rather than a difference that cancels (log(cosh(1e-60))).",
                "limit",
            ) from None

    def check_terms(self, terms: int, pos: int) -> int:
        if terms > MAX_EXPANDED_TERMS:
            raise self.error(
                f"this expression would expand to more than {MAX_EXPANDED_TERMS} terms",
                pos,
                f"Limit: the full expansion of an expression may have at most {MAX_EXPANDED_TERMS} terms.",
                "limit",
            )
        return terms

    # ------------------------------------------------------------ grammar
    def parse(self) -> sp.Expr:
        if self.peek().kind == "end":
            raise self.error("the expression is empty", 0, "Write an expression such as 0 or m*x'^2/2.")
        value = self.expression()
        tok = self.peek()
        if tok.kind != "end":
            raise self.unexpected(tok, after_operand=True)
        return value.expr

    def expression(self) -> _Value:
        first = self.term()
        terms = [first]
        while self.at("+", "-"):
            op = self.take()
            value = self.term()
            if op.text == "-":
                value = _Value(-value.expr, value.terms, value.pos)
            terms.append(value)
        if len(terms) == 1:
            return first
        exprs = [v.expr for v in terms]
        groups: dict[sp.Expr, int] = {}
        for e in exprs:
            for a in sp.Add.make_args(e):
                c, rest = a.as_coeff_Mul()
                if c.is_Rational:
                    groups[rest] = groups.get(rest, 0) + _bits(c)
                    if groups[rest] > MAX_NUMBER_BITS:
                        raise self.error(
                            f"the numbers in this sum add up to more than {MAX_NUMBER_BITS} bits",
                            first.pos,
                            _NUMBER_LIMITS,
                            "limit",
                        )
        count = self.check_terms(sum(v.terms for v in terms), first.pos)
        return _Value(self.check_defined(sp.Add(*exprs), first.pos), count, first.pos)

    def term(self) -> _Value:
        first = self.unary()
        factors = [first]
        while self.at("*", "/"):
            op = self.take()
            value = self.unary()
            if op.text == "/":
                value = self.power_of(value, _Value(sp.S.NegativeOne, 1, op.pos), op.pos)
            factors.append(value)
        if len(factors) == 1:
            return first
        rational = radical = 0.0
        for v in factors:
            r, q = _numeric_factor_bits(v.expr)
            rational += r
            radical += q
        if rational > MAX_NUMBER_BITS or radical > MAX_ROOT_BITS:
            raise self.error(
                "the numbers in this product are too large to multiply exactly",
                first.pos,
                _NUMBER_LIMITS,
                "limit",
            )
        count = 1
        for v in factors:
            count = self.check_terms(count * v.terms, first.pos)
        product = sp.Mul(*[v.expr for v in factors])
        return _Value(self.check_defined(product, first.pos), count, first.pos)

    def unary(self) -> _Value:
        if self.at("+", "-"):
            op = self.take()
            self.enter(op.pos)
            value = self.unary()
            self.leave()
            if op.text == "-":
                return _Value(self.check_defined(-value.expr, op.pos), value.terms, op.pos)
            return _Value(value.expr, value.terms, op.pos)
        return self.power()

    def power(self) -> _Value:
        base = self.primary()
        if self.at("^", "**"):
            op = self.take()
            self.enter(op.pos)
            exponent = self.unary()
            self.leave()
            return self.power_of(base, exponent, op.pos)
        return base

    def primary(self) -> _Value:
        tok = self.take()
        if tok.kind == "number":
            return _Value(self.number(tok), 1, tok.pos)
        if tok.kind == "name":
            if self.at("("):
                return self.call(tok)
            return self.name(tok)
        if tok.kind == "op" and tok.text == "(":
            self.enter(tok.pos)
            value = self.expression()
            self.leave()
            close = self.peek()
            if not self.at(")"):
                if close.kind == "end":
                    raise self.error("missing ')' to close this parenthesis", tok.pos)
                raise self.unexpected(close, after_operand=True)
            self.take()
            return _Value(value.expr, value.terms, tok.pos)
        self.i -= 1
        raise self.unexpected(tok, after_operand=False)

    def unexpected(self, tok: _Token, *, after_operand: bool) -> ParseError:
        if tok.kind == "end":
            return self.error("the expression ends too early: an operand is missing", tok.pos)
        if tok.kind == "op" and tok.text == "'":
            return self.error("a prime ' may only follow a coordinate name, as in x'", tok.pos)
        if after_operand:
            if tok.kind == "op" and tok.text == ")":
                return self.error("unmatched ')'", tok.pos)
            if tok.kind == "op" and tok.text == ",":
                return self.error(
                    "',' only separates the arguments of a function such as atan2(y, x)", tok.pos
                )
            if tok.kind in ("number", "name") or (tok.kind == "op" and tok.text == "("):
                return self.error(
                    f"missing operator before {tok.text!r} (write * for a product, e.g. 2*x)", tok.pos
                )
        if tok.kind == "op" and tok.text in (")", ","):
            return self.error(f"expected an operand before {tok.text!r}", tok.pos)
        return self.error(f"expected a number, a name or '(' but found {tok.text!r}", tok.pos)

    # ------------------------------------------------------------ atoms
    def number(self, tok: _Token) -> sp.Rational:
        m = _NUMBER_PARTS.match(tok.text)
        assert m is not None  # the tokenizer only produces valid literals
        whole, frac, exp = m.group(1), m.group(2) or "", m.group(3)
        digits = (whole + frac).lstrip("0")
        if len(digits) > MAX_LITERAL_DIGITS:
            raise self.error(
                f"a number with more than {MAX_LITERAL_DIGITS} digits", tok.pos, _NUMBER_LIMITS, "limit"
            )
        e = 0
        if exp is not None:
            if len(exp.lstrip("+-").lstrip("0")) > 4 or abs(int(exp)) > MAX_LITERAL_EXPONENT:
                raise self.error(
                    f"the exponent of a number may be at most {MAX_LITERAL_EXPONENT} in size",
                    tok.pos,
                    _NUMBER_LIMITS,
                    "limit",
                )
            e = int(exp)
        shift = e - len(frac)
        mantissa = int(digits or "0")
        value = sp.Rational(mantissa * 10**shift) if shift >= 0 else sp.Rational(mantissa, 10**-shift)
        return self.check_defined(value, tok.pos)

    def name(self, tok: _Token) -> _Value:
        name = tok.text
        primes: list[_Token] = []
        end = tok.pos + len(name)
        while self.at("'"):
            prime = self.take()
            if prime.pos != end:
                raise self.error(
                    f"a space before the prime: write {name}{chr(39) * (len(primes) + 1)} with no space "
                    "between the name and its prime",
                    end,
                )
            primes.append(prime)
            end += 1
        names = self.names
        if name in names.coordinates:
            q = names.coordinates[name]
            if not primes:
                return _Value(q, 1, tok.pos)
            if len(primes) > 1:
                raise self.error(
                    f"{name}{chr(39) * len(primes)} is a derivative of order {len(primes)}: only velocities "
                    f"({name}') may appear, accelerations are not part of a system",
                    primes[1].pos,
                )
            if self.velocity_message is not None:
                raise self.error(self.velocity_message, tok.pos, None, "name")
            return _Value(q.diff(TIME), 1, tok.pos)
        if primes:
            if name in names.parameters:
                what = "a parameter"
            elif name == "t" and names.time:
                what = "time"
            elif name in CONSTANTS:
                what = "a constant"
            else:
                what = None
            if what is not None:
                raise self.error(
                    f"{name} is {what}: only coordinates have velocities ({name}' is not defined)",
                    primes[0].pos,
                    names.describe(),
                    "name",
                )
        if name in names.parameters:
            return _Value(names.parameters[name], 1, tok.pos)
        if name == "t" and names.time:
            return _Value(TIME, 1, tok.pos)
        if name in CONSTANTS:
            return _Value(CONSTANTS[name], 1, tok.pos)
        if name in FUNCTIONS:
            raise self.error(f"{name} is a function: write {name}(...)", tok.pos, names.describe(), "name")
        reason = f"unknown name {name!r}"
        if name == "t":
            reason = "time t is not allowed here (a number is expected)"
        elif name.startswith("_"):
            reason += " (names may not start with _)"
        else:
            close = difflib.get_close_matches(name, names.all(), n=1)
            if close:
                reason += f" (did you mean {close[0]!r}?)"
        raise self.error(reason, tok.pos, names.describe(), "name")

    def call(self, tok: _Token) -> _Value:
        name = tok.text
        open_ = self.take()
        if name not in FUNCTIONS:
            if name in self.names.parameters or name in self.names.coordinates:
                raise self.error(
                    f"{name} is not a function: write {name}*(...) for a product",
                    open_.pos,
                    self.names.describe(),
                    "name",
                )
            reason = f"unknown function {name!r}"
            close = difflib.get_close_matches(name, list(FUNCTIONS), n=1)
            if close:
                reason += f" (did you mean {close[0]!r}?)"
            raise self.error(reason, tok.pos, "Functions: " + ", ".join(FUNCTIONS) + ".", "name")
        self.enter(open_.pos)
        args: list[_Value] = []
        if not self.at(")"):
            args.append(self.expression())
            while self.at(","):
                comma = self.take()
                if self.at(")"):
                    raise self.error(
                        f"a trailing comma after the last argument of {name}: remove the ','",
                        comma.pos,
                        "Arguments are separated by commas, with none after the last: atan2(y, x).",
                    )
                args.append(self.expression())
        if not self.at(")"):
            nxt = self.peek()
            if nxt.kind == "end":
                raise self.error(f"missing ')' to close the call of {name}", open_.pos)
            raise self.unexpected(nxt, after_operand=True)
        self.take()
        self.leave()
        arity = FUNCTIONS[name]
        if len(args) != arity:
            usage = "atan2(y, x)" if name == "atan2" else f"{name}(x)"
            raise self.error(
                f"{name} takes {arity} argument{'s' if arity > 1 else ''}, got {len(args)}",
                tok.pos,
                f"Write {usage}.",
            )
        if name == "sqrt":
            value = self.power_of(args[0], _Value(sp.S.Half, 1, tok.pos), tok.pos)
            return _Value(value.expr, value.terms, tok.pos)
        if name in _HYPERBOLIC or name == "abs":  # Abs splits its argument the same way
            self.check_hyperbolic(name, args[0].expr, tok.pos)
        elif name == "exp":
            self.check_exp(args[0].expr, tok.pos)
        elif name in ("asin", "acos", "atan"):
            self.check_reduced_angle(name, args[0].expr, tok.pos)
        result = _SYMPY_FUNCTIONS[name](*[a.expr for a in args])
        if name == "atan2" and result.has(sp.I):
            result = _real_atan2(args[0].expr, args[1].expr, result)
        return _Value(self.check_defined(result, tok.pos), 1, tok.pos)

    def check_hyperbolic(self, name: str, arg: sp.Expr, pos: int) -> None:
        """Refuse sinh/cosh/tanh of an argument too large for SymPy's test of whether it is real.

        Coordinates and ``t`` are not real symbols, so SymPy decides whether ``sinh(arg)`` is
        real by splitting ``arg`` into real and imaginary parts, fully expanded: for
        ``sinh((x + t)^16)`` that takes seconds, for ``sinh((x + t)^64)`` minutes (other
        functions do not do this).
        """
        cost = _complex_terms(arg, self.complex_atoms(), MAX_HYPERBOLIC_TERMS)
        if cost > MAX_HYPERBOLIC_TERMS:
            raise self.error(
                f"the argument of {name} is too large for SymPy: split into real and imaginary parts it "
                f"would expand to more than {MAX_HYPERBOLIC_TERMS} terms",
                pos,
                f"Limit: the argument of sinh, cosh, tanh or abs may expand to at most {MAX_HYPERBOLIC_TERMS} "
                "terms, counting each coordinate, velocity and t as two (its real and imaginary parts).",
                "limit",
            )

    def check_exp(self, arg: sp.Expr, pos: int) -> None:
        """Refuse ``exp(arg)`` when SymPy would compute a huge exact number or polynomial for it.

        ``exp(arg)`` is ``E**arg``: the numerators in ``arg`` are bounded as in any exponent (see
        :data:`MAX_EXPONENT_NUMERATOR`).  And SymPy rewrites ``exp(c*log(N))`` as ``N**c`` (after
        combining the logarithms anywhere inside ``arg``, with ``logcombine``), computing that power
        exactly even when the result is thrown away.  SymPy does that for each product term of
        ``arg``: inside each of its factors, and for the term itself when its other factors are
        numbers.  Each such product ``c*log(N)``, ``N`` a number, gets the limits of ``N**c``.
        """
        self.check_exponent_numerators(arg, pos, "the argument of exp")
        for term in sp.Add.make_args(arg):
            if not term.is_Mul:
                continue
            if all(f.is_comparable for f in term.args):
                self.check_log_power(term, pos)
            for factor in term.args:
                for node in sp.preorder_traversal(factor):
                    if node.is_Mul:
                        self.check_log_power(node, pos)

    def check_log_power(self, product: sp.Expr, pos: int) -> None:
        """Refuse ``c*log(N)*…`` (``N`` a number) when the power ``N**c`` is beyond the power limits."""
        c = product.as_coeff_Mul()[0]
        if not c.is_Rational or abs(c) == 1:
            return
        bits = 0.0
        for factor in product.args:
            for term in sp.Add.make_args(factor):
                for f in sp.Mul.make_args(term):
                    if isinstance(f, sp.log) and f.args[0].is_number:
                        bits += sum(_numeric_factor_bits(f.args[0]))
        q = int(c.q)
        if bits and (
            q > MAX_EXPONENT
            or bits * math.ceil(abs(c)) > MAX_NUMBER_BITS
            or (q > 1 and bits * q > MAX_ROOT_BITS)
        ):
            raise self.error(
                f"exp of {sp.sstr(c)[:40]}*log(...) of a number: SymPy would compute that number to the power "
                f"{sp.sstr(c)[:40]} exactly, which is too large",
                pos,
                "Limits: exp(c*log(N)) is the power N**c, and a power of a number may produce at most "
                f"{MAX_NUMBER_BITS} bits, with a denominator of the exponent of at most {MAX_EXPONENT} "
                f"and an exact root of at most {MAX_ROOT_BITS} bits × degree.",
                "limit",
            )

    def check_exponent_numerators(self, exponent: sp.Expr, pos: int, what: str) -> None:
        """Refuse an exponent with a rational coefficient whose numerator is above the limit."""
        for term in sp.Add.make_args(exponent):
            c = term.as_coeff_Mul(rational=True)[0]
            if c.is_Rational and abs(int(c.p)) > MAX_EXPONENT_NUMERATOR:
                raise self.error(
                    f"{what} has a number with a numerator above {MAX_EXPONENT_NUMERATOR} "
                    f"({sp.sstr(c)[:60]}): SymPy would store it as a polynomial of that degree",
                    pos,
                    f"Limit: the numbers in an exponent (and in the argument of exp), in lowest terms, have "
                    f"numerators of at most {MAX_EXPONENT_NUMERATOR}: exp(-0.5*x), exp(2.5), x^(3/2).",
                    "limit",
                )

    def check_reduced_angle(self, name: str, arg: sp.Expr, pos: int) -> None:
        """Refuse ``asin(sin(c))`` & co. for a huge constant ``c``: SymPy reduces ``c`` modulo π."""
        for inner in (arg, -arg):
            if isinstance(inner, (sp.sin, sp.cos, sp.tan, sp.cot)) and inner.args[0].is_number:
                value = inner.args[0].evalf(15)
                if value.is_Float and abs(value) > MAX_REDUCED_ANGLE:
                    raise self.error(
                        f"{name} of {type(inner).__name__} of a constant of about {sp.sstr(value.evalf(3))}: SymPy would "
                        "reduce that constant modulo pi exactly, which needs more digits than it has",
                        pos,
                        f"Limit: in asin, acos or atan of sin(c), cos(c) or tan(c), the constant c is at most "
                        f"10^{round(math.log10(MAX_REDUCED_ANGLE))} in size.",
                        "limit",
                    )

    def complex_atoms(self) -> frozenset[sp.Expr]:
        """The objects SymPy does not know to be real: coordinates, velocities, t."""
        if self._complex is None:
            coords = list(self.names.coordinates.values())
            self._complex = frozenset([*coords, *(q.diff(TIME) for q in coords), TIME])
        return self._complex

    # ------------------------------------------------------------ powers
    def power_of(self, base: _Value, exponent: _Value, pos: int) -> _Value:
        """``base ** exponent``, refused before SymPy computes anything too large."""
        b, e = base.expr, exponent.expr
        const = e if e.is_number else e.as_coeff_Add()[0]
        terms = 1
        if const != 0:
            if const.is_Rational:
                size, denominator = abs(const), int(const.q)
            else:
                try:
                    size, denominator = abs(complex(const.evalf(15))), 1
                except (TypeError, ValueError, OverflowError):
                    size = math.inf
                if not math.isfinite(size):
                    raise self.error("the exponent is not a finite number", pos, _POWER_LIMITS, "value")
            if size > MAX_EXPONENT or denominator > MAX_EXPONENT:
                raise self.error(
                    f"the exponent is too large (at most {MAX_EXPONENT} in size, with a denominator of "
                    f"at most {MAX_EXPONENT})",
                    pos,
                    _POWER_LIMITS,
                    "limit",
                )
            if const.is_Rational:
                rational, radical = _numeric_factor_bits(b)
                whole = math.ceil(size)
                numeric = rational + radical
                if numeric * whole > MAX_NUMBER_BITS:
                    raise self.error(
                        f"this power would compute a number of about {math.ceil(numeric * whole)} bits "
                        f"(limit {MAX_NUMBER_BITS})",
                        pos,
                        _POWER_LIMITS,
                        "limit",
                    )
                if denominator > 1 and numeric * denominator > MAX_ROOT_BITS:
                    raise self.error(
                        "this power would take an exact root of a large number "
                        f"({math.ceil(numeric)} bits, degree {denominator}; limit {MAX_ROOT_BITS} "
                        "bits × degree)",
                        pos,
                        _POWER_LIMITS,
                        "limit",
                    )
                if e.is_number and base.terms > 1 and whole >= 1:
                    expanded = _multinomial(base.terms, whole)
                    self.check_terms(expanded, pos)
                    if const > 0:
                        terms = expanded
        self.check_exponent_numerators(e, pos, "the exponent")
        if b == sp.E:
            self.check_exp(e, pos)
        # SymPy splits b into real and imaginary parts when the exponent has a sum in a
        # denominator, and takes re(x) to combine (x^a)^b (b not an integer)
        split = (
            "its exponent has a sum in a denominator"
            if not e.is_number and any(p.base.is_Add and p.exp.is_negative for p in e.atoms(sp.Pow))
            else "it is (or has a factor that is) a power, raised to an exponent that is not an integer"
            if e.is_integer is not True
            and any(isinstance(f, sp.Pow) for f in (b.args if isinstance(b, sp.Mul) else (b,)))
            else ""
        )
        if split and _complex_terms(b, self.complex_atoms(), MAX_HYPERBOLIC_TERMS) > MAX_HYPERBOLIC_TERMS:
            raise self.error(
                f"the base of this power is too large for SymPy: {split}, and SymPy splits such a "
                "base into real and imaginary parts, which would "
                f"expand to more than {MAX_HYPERBOLIC_TERMS} terms",
                pos,
                f"Limit: the base of a power like b^(1/(a + x)) may expand to at most {MAX_HYPERBOLIC_TERMS} "
                "terms, counting each coordinate, velocity and t as two (its real and imaginary parts).",
                "limit",
            )
        result = sp.Pow(b, e)
        if isinstance(result, (sp.Pow, sp.exp)):  # (x^a)^b may have become x^(a*b)
            self.check_exponent_numerators(result.as_base_exp()[1], pos, "the exponent")
        return _Value(self.check_defined(result, pos), terms, base.pos)


def _real_atan2(y: sp.Expr, x: sp.Expr, symbolic: sp.Expr) -> sp.Expr:
    """``atan2(y, x)`` of two real constants as ``atan(y/x)`` plus the quadrant's multiple of π.

    Where SymPy cannot decide the signs of ``y`` and ``x`` by its assumptions (``tan(E)``), its
    ``atan2`` is ``-I*log((x + I*y)/sqrt(x**2 + y**2))``: complex in form, and slow to evaluate
    (a sign test on it takes seconds).  The signs are decided numerically here, at 15 digits, as
    every constant is bounded; ``symbolic`` (SymPy's form) is kept when one of them is 0 there.
    """
    if not (y.is_number and x.is_number):
        return symbolic
    yv, xv = y.evalf(15), x.evalf(15)
    if not (yv.is_Float and xv.is_Float) or xv == 0 or yv == 0:
        return symbolic
    base = sp.atan(y / x)
    if xv > 0:
        return base
    return base + (sp.pi if yv > 0 else -sp.pi)


def _complex_terms(expr: sp.Expr, complex_atoms: frozenset[sp.Expr], cap: int) -> int:
    """Terms of ``expr`` expanded with each of ``complex_atoms`` as ``re + i·im`` (capped above ``cap``).

    A function counts two terms plus twice the terms of its arguments (SymPy splits those
    too, and ``f(re u + i im u)`` uses each part twice: ``cosh(re u) cos(im u)``, …), so the
    count doubles with each level of nesting, as SymPy's work does; ``1/z`` counts like
    ``z²`` (``re z / |z|²``) and ``z^(p/q)`` like ``z^⌈|p/q|⌉``; a function of real arguments
    that SymPy does not know to be real (``acos(k)``, real only for ``|k| ≤ 1``) counts two.
    """
    if expr in complex_atoms:
        return 2
    if not expr.args:
        return 1
    if not expr.has(*complex_atoms):
        if isinstance(expr, (sp.Add, sp.Mul, sp.Pow)):
            pass  # its parts may still hold such functions: count them below
        elif isinstance(expr, sp.Function) and expr.is_extended_real is not True:
            return 2
        else:
            return 1
    parts = [_complex_terms(a, complex_atoms, cap) for a in expr.args]
    if isinstance(expr, sp.Add):
        return min(sum(parts), cap + 1)
    if isinstance(expr, sp.Mul):
        out = 1
        for k in parts:
            out = min(out * k, cap + 1)
        return out
    if isinstance(expr, sp.Pow) and expr.exp.is_Rational:
        # z^n splits like the expanded power; 1/z into re z / |z|², |z|² = (re z)² + (im z)²;
        # z^(p/q) like z^⌈|p/q|⌉ (and worse)
        n = math.ceil(abs(expr.exp))
        return _multinomial(parts[0], min(n + (1 if expr.exp < 0 else 0), cap + 1), cap)
    # f(u) = f(re u + i im u): re u and im u each appear twice (cosh(re u) cos(im u), ...)
    return min(2 * sum(parts) + 2, cap + 1)


def _multinomial(terms: int, power: int, cap: int = MAX_EXPANDED_TERMS) -> int:
    """Number of terms of ``(a_1 + … + a_terms) ** power`` expanded (capped)."""
    if terms > cap or power > cap:
        return cap + 1
    return min(math.comb(terms + power - 1, power), cap + 1)


_NUMBER_LIMITS = (
    f"Limits: number literals have at most {MAX_LITERAL_DIGITS} digits and an exponent of at most "
    f"{MAX_LITERAL_EXPONENT}; exact numbers stay below {MAX_NUMBER_BITS} bits, and every constant "
    f"(e.g. exp(100)) below 2^{MAX_NUMBER_BITS} (about 10^1233) in size."
)
_POWER_LIMITS = (
    f"Limits: numeric exponents are at most {MAX_EXPONENT} in size; a power of a number may produce "
    f"at most {MAX_NUMBER_BITS} bits, an exact root at most {MAX_ROOT_BITS} bits × degree."
)


@contextmanager
def preserved_state() -> Iterator[None]:
    """Run a block with SymPy's usual settings and restore all global numeric state after it.

    SymPy evaluates numbers with mpmath, which keeps its working precision in a
    global context (``mpmath.mp.prec``/``dps``).  ``mpmath.workprec`` sets it
    *before* it computes the matching ``dps``; for an astronomically large
    precision that computation raises ``OverflowError`` and the precision stays
    astronomically large, so every later evaluation in the process fails or hangs.
    This restores the precision (and mpmath's ``trap_complex``/``pretty``) and
    SymPy's ``global_parameters`` whatever happens in the block, and runs the
    block with SymPy's defaults (``evaluate=True``, ``distribute=True``,
    ``exp_is_pow=False``), which the parser relies on.  SymPy's cache is left alone.
    """
    mp = mpmath.mp
    numeric = (mp.prec, mp.dps, mp.trap_complex, mp.pretty)
    gp = global_parameters
    flags = (gp.evaluate, gp.distribute, gp.exp_is_pow)
    defaults = (True, True, False)
    if flags != defaults:  # assigning clears SymPy's cache: only when needed
        gp.evaluate, gp.distribute, gp.exp_is_pow = defaults
    try:
        yield
    finally:
        if (mp.prec, mp.dps) != numeric[:2]:
            mp.prec = numeric[0]
            if mp.dps != numeric[1]:  # a state set through dps: dps first, then prec
                mp.dps = numeric[1]
                mp.prec = numeric[0]
        mp.trap_complex, mp.pretty = numeric[2:]
        if (gp.evaluate, gp.distribute, gp.exp_is_pow) != flags:
            gp.evaluate, gp.distribute, gp.exp_is_pow = flags


def _internal(exc: BaseException, text: str, column: int) -> ParseError:
    """A SymPy/mpmath/Python failure on ``text``, reported as a :class:`ParseError`."""
    detail = str(exc).splitlines()[0][:200] if str(exc) else ""
    return ParseError(
        f"SymPy could not build or evaluate this expression ({type(exc).__name__}"
        + (f": {detail}" if detail else "")
        + ")",
        text=text,
        column=column,
        kind="internal",
        allowed="This is a limitation of chaplygin; please report it with the expression. "
        "Rewriting the expression (e.g. smaller constants) may avoid it.",
    )


def parse_expression(
    text: str,
    names: Names | None = None,
    *,
    velocity_message: str | None = None,
) -> sp.Expr:
    """Parse ``text`` into a SymPy expression, using only the given ``names``.

    Parameters
    ----------
    text : str
        The expression, in the syntax described in the module docstring.
    names : Names, optional
        The parameters and coordinates it may use (default: none, plus ``t``).
    velocity_message : str, optional
        When given, velocities ``x'`` are refused with this message (e.g. in a
        potential energy).

    Raises
    ------
    ParseError
        With the column of the problem and what is allowed; also when SymPy or
        mpmath fail on the expression (``kind="internal"``).  Nothing else is
        raised, and mpmath's precision and SymPy's global parameters are the
        same afterwards (see :func:`preserved_state`).
    """
    if not isinstance(text, str):
        raise ParseError(f"expected a string, got {type(text).__name__}", allowed=SYNTAX)
    if len(text) > MAX_EXPRESSION_LENGTH:
        raise ParseError(
            f"the expression is {len(text)} characters long (limit {MAX_EXPRESSION_LENGTH})",
            text=text[:80],
            allowed=f"Limit: {MAX_EXPRESSION_LENGTH} characters per expression.",
        )
    parser: _Parser | None = None
    with preserved_state():
        try:
            parser = _Parser(text, names or Names(), velocity_message)
            return parser.parse()
        except SystemFileError:
            raise
        except Exception as exc:  # the boundary between user text and SymPy: never a traceback
            column = parser.tokens[max(parser.i - 1, 0)].pos if parser is not None else 0
            raise _internal(exc, text, column) from exc


def parse_constant(text: str) -> float:
    """A number given as an expression of constants only (``"pi/4"``, ``"2*sqrt(2)"``).

    Raises
    ------
    ParseError
        As :func:`parse_expression`, and when the value is not a finite real number.
    """
    expr = parse_expression(text, Names(time=False))
    with preserved_state():
        try:
            value = complex(expr.evalf(30))
        except (TypeError, ValueError, OverflowError):
            value = complex(math.nan)
        except Exception as exc:  # pragma: no cover - constants are bounded by the parser
            raise _internal(exc, text, 0) from exc
    if value.imag != 0 or not math.isfinite(value.real):
        raise ParseError(
            f"{text!r} is not a finite real number (it is {value})",
            text=text,
            column=0,
            allowed='Give a real number, e.g. 0.5 or "pi/4".',
            kind="value",
        )
    return value.real
