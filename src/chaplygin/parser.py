"""A safe parser for the expressions of system files.

User text is never handed to Python or to SymPy's own string parsers: it is
read by the small recursive-descent parser below, which builds SymPy objects
directly from a whitelist.  The grammar (``docs/system-files.md``)::

    expression := term (("+" | "-") term)*
    term       := unary (("*" | "/") unary)*
    unary      := ("+" | "-") unary | power
    power      := primary (("^" | "**") unary)?          # right-associative
    primary    := NUMBER | NAME | NAME "'" | NAME "(" arguments ")" | "(" expression ")"
    arguments  := expression ("," expression)*

* ``NUMBER``: ``2``, ``0.5``, ``.5``, ``1.5e-3``; always an **exact** rational
  (``0.1`` is ``1/10``), so derivations stay exact;
* ``NAME``: a parameter (a real SymPy ``Symbol``), a coordinate (a
  ``dynamicsymbol``), ``t`` (time), the constants ``pi`` and ``E``;
* ``x'``: the velocity of the coordinate ``x`` (a first derivative; ``x''`` is
  refused);
* the functions of :data:`FUNCTIONS`, with their number of arguments checked.

Limits (:data:`MAX_EXPRESSION_LENGTH`, :data:`MAX_TOKENS`, :data:`MAX_DEPTH`,
:data:`MAX_EXPONENT`, :data:`MAX_NUMBER_BITS`, :data:`MAX_ROOT_BITS`,
:data:`MAX_EXPANDED_TERMS`) are checked *before* SymPy is asked to build
anything that could be expensive, so hostile text such as ``9^9^9^9`` or a
hundred thousand nested parentheses is refused at once instead of hanging.

Every error is a :class:`ParseError` (a :class:`SystemFileError`): it names the
column, shows the text with a caret under it and says what is allowed.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import sympy as sp

from ._symbols import TIME
from .errors import ChaplyginError

__all__ = [
    "SystemFileError",
    "ParseError",
    "Names",
    "parse_expression",
    "parse_constant",
    "check_name",
    "parameter_symbol",
    "coordinate_function",
    "FUNCTIONS",
    "CONSTANTS",
    "RESERVED",
    "MAX_EXPRESSION_LENGTH",
    "MAX_TOKENS",
    "MAX_DEPTH",
    "MAX_EXPONENT",
    "MAX_NUMBER_BITS",
    "MAX_ROOT_BITS",
    "MAX_EXPANDED_TERMS",
    "MAX_LITERAL_DIGITS",
    "MAX_NAME_LENGTH",
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
#: Largest exact number (in bits, numerator plus denominator) an expression may produce.
MAX_NUMBER_BITS = 4096
#: Largest (bits of the radicand) × (degree of the root) for an exact root of a number.
MAX_ROOT_BITS = 1024
#: Most terms the full expansion of an expression may have (SymPy expands kinetic energies).
MAX_EXPANDED_TERMS = 10_000
#: Most digits in one number literal, and the largest power of ten of its exponent.
MAX_LITERAL_DIGITS = 100
MAX_LITERAL_EXPONENT = 400
#: Longest parameter or coordinate name.
MAX_NAME_LENGTH = 64

#: The functions an expression may call, with their number of arguments.
FUNCTIONS: dict[str, int] = {
    "sin": 1, "cos": 1, "tan": 1, "asin": 1, "acos": 1, "atan": 1, "atan2": 2,
    "sinh": 1, "cosh": 1, "tanh": 1, "exp": 1, "log": 1, "sqrt": 1, "abs": 1, "sign": 1,
}
_SYMPY_FUNCTIONS: dict[str, Callable[..., sp.Expr]] = {
    "sin": sp.sin, "cos": sp.cos, "tan": sp.tan, "asin": sp.asin, "acos": sp.acos,
    "atan": sp.atan, "atan2": sp.atan2, "sinh": sp.sinh, "cosh": sp.cosh, "tanh": sp.tanh,
    "exp": sp.exp, "log": sp.log, "abs": sp.Abs, "sign": sp.sign,
}
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
            "source": self.source, "key": self.key, "text": self.text, "column": self.column,
            "line": self.line, "allowed": self.allowed,
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
            head.append(f"line {self.line}" + (f", column {self.column + 1}" if self.column is not None else ""))
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
    """An expression does not follow the grammar or breaks a limit."""


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
            parts.append(
                "coordinates " + ", ".join(self.coordinates) + f" (and velocities such as {first}')"
            )
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

    # ------------------------------------------------------------ helpers
    def error(self, reason: str, pos: int, allowed: str | None = SYNTAX) -> ParseError:
        return ParseError(reason, text=self.text, column=pos, allowed=allowed)

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
                        f"the expression has more than {MAX_TOKENS} tokens", pos,
                        f"Limit: {MAX_TOKENS} numbers, names and operators per expression.",
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
                f"the expression is nested more than {MAX_DEPTH} levels deep", pos,
                f"Limit: {MAX_DEPTH} levels of parentheses, function calls, signs and powers.",
            )

    def leave(self) -> None:
        self.depth -= 1

    def check_defined(self, value: sp.Expr, pos: int) -> sp.Expr:
        if value.is_number and value.has(*_UNDEFINED):
            raise self.error(
                "the expression is undefined here (a division by zero or a singular function value)", pos,
                None,
            )
        if value.is_Rational and _bits(value) > MAX_NUMBER_BITS:
            raise self.error(f"a number with more than {MAX_NUMBER_BITS} bits", pos, _NUMBER_LIMITS)
        return value

    def check_terms(self, terms: int, pos: int) -> int:
        if terms > MAX_EXPANDED_TERMS:
            raise self.error(
                f"this expression would expand to more than {MAX_EXPANDED_TERMS} terms", pos,
                f"Limit: the full expansion of an expression may have at most {MAX_EXPANDED_TERMS} terms.",
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
                            first.pos, _NUMBER_LIMITS,
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
                "the numbers in this product are too large to multiply exactly", first.pos,
                _NUMBER_LIMITS,
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
                return self.error("',' only separates the arguments of a function such as atan2(y, x)", tok.pos)
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
            raise self.error(f"a number with more than {MAX_LITERAL_DIGITS} digits", tok.pos, _NUMBER_LIMITS)
        e = 0
        if exp is not None:
            if len(exp.lstrip("+-").lstrip("0")) > 4 or abs(int(exp)) > MAX_LITERAL_EXPONENT:
                raise self.error(
                    f"the exponent of a number may be at most {MAX_LITERAL_EXPONENT} in size", tok.pos,
                    _NUMBER_LIMITS,
                )
            e = int(exp)
        shift = e - len(frac)
        mantissa = int(digits or "0")
        value = (
            sp.Rational(mantissa * 10**shift) if shift >= 0 else sp.Rational(mantissa, 10**-shift)
        )
        return self.check_defined(value, tok.pos)  # type: ignore[return-value]

    def name(self, tok: _Token) -> _Value:
        name = tok.text
        primes = []
        while self.at("'"):
            primes.append(self.take())
        names = self.names
        if name in names.coordinates:
            q = names.coordinates[name]
            if not primes:
                return _Value(q, 1, tok.pos)
            if len(primes) > 1:
                raise self.error(
                    f"{name}{chr(39) * len(primes)} is a derivative of order {len(primes)}: only velocities "
                    f"({name}') may appear, accelerations are not part of a system", primes[1].pos,
                )
            if self.velocity_message is not None:
                raise self.error(self.velocity_message, tok.pos, None)
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
                    primes[0].pos, names.describe(),
                )
        if name in names.parameters:
            return _Value(names.parameters[name], 1, tok.pos)
        if name == "t" and names.time:
            return _Value(TIME, 1, tok.pos)
        if name in CONSTANTS:
            return _Value(CONSTANTS[name], 1, tok.pos)
        if name in FUNCTIONS:
            raise self.error(f"{name} is a function: write {name}(...)", tok.pos, names.describe())
        reason = f"unknown name {name!r}"
        if name == "t":
            reason = "time t is not allowed here (a number is expected)"
        elif name.startswith("_"):
            reason += " (names may not start with _)"
        else:
            close = difflib.get_close_matches(name, names.all(), n=1)
            if close:
                reason += f" (did you mean {close[0]!r}?)"
        raise self.error(reason, tok.pos, names.describe())

    def call(self, tok: _Token) -> _Value:
        name = tok.text
        open_ = self.take()
        if name not in FUNCTIONS:
            if name in self.names.parameters or name in self.names.coordinates:
                raise self.error(
                    f"{name} is not a function: write {name}*(...) for a product", open_.pos,
                    self.names.describe(),
                )
            reason = f"unknown function {name!r}"
            close = difflib.get_close_matches(name, list(FUNCTIONS), n=1)
            if close:
                reason += f" (did you mean {close[0]!r}?)"
            raise self.error(reason, tok.pos, "Functions: " + ", ".join(FUNCTIONS) + ".")
        self.enter(open_.pos)
        args: list[_Value] = []
        if not self.at(")"):
            args.append(self.expression())
            while self.at(","):
                self.take()
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
                f"{name} takes {arity} argument{'s' if arity > 1 else ''}, got {len(args)}", tok.pos,
                f"Write {usage}.",
            )
        if name == "sqrt":
            value = self.power_of(args[0], _Value(sp.S.Half, 1, tok.pos), tok.pos)
            return _Value(value.expr, value.terms, tok.pos)
        result = _SYMPY_FUNCTIONS[name](*[a.expr for a in args])
        return _Value(self.check_defined(result, tok.pos), 1, tok.pos)

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
                    size, denominator = abs(complex(const.evalf(15))), 1  # type: ignore[arg-type]
                except (TypeError, ValueError, OverflowError):
                    size = math.inf
                if not math.isfinite(size):
                    raise self.error("the exponent is not a finite number", pos, _POWER_LIMITS)
            if size > MAX_EXPONENT or denominator > MAX_EXPONENT:
                raise self.error(
                    f"the exponent is too large (at most {MAX_EXPONENT} in size, with a denominator of "
                    f"at most {MAX_EXPONENT})", pos, _POWER_LIMITS,
                )
            if const.is_Rational:
                rational, radical = _numeric_factor_bits(b)
                whole = math.ceil(size)
                numeric = rational + radical
                if numeric * whole > MAX_NUMBER_BITS:
                    raise self.error(
                        f"this power would compute a number of about {math.ceil(numeric * whole)} bits "
                        f"(limit {MAX_NUMBER_BITS})", pos, _POWER_LIMITS,
                    )
                if denominator > 1 and numeric * denominator > MAX_ROOT_BITS:
                    raise self.error(
                        "this power would take an exact root of a large number "
                        f"({math.ceil(numeric)} bits, degree {denominator}; limit {MAX_ROOT_BITS} "
                        "bits × degree)", pos, _POWER_LIMITS,
                    )
                if e.is_number and base.terms > 1 and whole >= 1:
                    expanded = _multinomial(base.terms, whole)
                    self.check_terms(expanded, pos)
                    if const > 0:
                        terms = expanded
        result = sp.Pow(b, e)
        return _Value(self.check_defined(result, pos), terms, base.pos)


def _multinomial(terms: int, power: int) -> int:
    """Number of terms of ``(a_1 + … + a_terms) ** power`` expanded (capped)."""
    if terms > MAX_EXPANDED_TERMS or power > MAX_EXPANDED_TERMS:
        return MAX_EXPANDED_TERMS + 1
    return math.comb(terms + power - 1, power)


_NUMBER_LIMITS = (
    f"Limits: number literals have at most {MAX_LITERAL_DIGITS} digits and an exponent of at most "
    f"{MAX_LITERAL_EXPONENT}; exact numbers stay below {MAX_NUMBER_BITS} bits."
)
_POWER_LIMITS = (
    f"Limits: numeric exponents are at most {MAX_EXPONENT} in size; a power of a number may produce "
    f"at most {MAX_NUMBER_BITS} bits, an exact root at most {MAX_ROOT_BITS} bits × degree."
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
        With the column of the problem and what is allowed.
    """
    if not isinstance(text, str):
        raise ParseError(f"expected a string, got {type(text).__name__}", allowed=SYNTAX)
    if len(text) > MAX_EXPRESSION_LENGTH:
        raise ParseError(
            f"the expression is {len(text)} characters long (limit {MAX_EXPRESSION_LENGTH})",
            text=text[:80], allowed=f"Limit: {MAX_EXPRESSION_LENGTH} characters per expression.",
        )
    parser = _Parser(text, names or Names(), velocity_message)
    try:
        return parser.parse()
    except RecursionError:  # pragma: no cover - MAX_DEPTH keeps the recursion shallow
        raise ParseError("the expression is nested too deeply", text=text, column=0) from None


def parse_constant(text: str) -> float:
    """A number given as an expression of constants only (``"pi/4"``, ``"2*sqrt(2)"``)."""
    expr = parse_expression(text, Names(time=False))
    try:
        value = complex(expr.evalf(30))  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError):
        value = complex(math.nan)
    if value.imag != 0 or not math.isfinite(value.real):
        raise ParseError(
            f"{text!r} is not a finite real number (it is {value})", text=text, column=0,
            allowed="Give a real number, e.g. 0.5 or \"pi/4\".",
        )
    return value.real
