"""Inputs for fuzzing the expression parser: the documented grammar, mutations, token soup, bytes.

Shared by ``tests/test_fuzz.py`` (a few hundred inputs, drawn by Hypothesis) and
``benchmarks/fuzz.py`` (10⁶ inputs, drawn by :class:`random.Random`).  Every choice goes
through a :class:`Source`, so the same code serves both.

:func:`valid` writes an expression of the grammar of ``docs/system-files.md``::

    expression := term (("+" | "-") term)*
    term       := unary (("*" | "/") unary)*
    unary      := ("+" | "-") unary | power
    power      := primary (("^" | "**") unary)?
    primary    := NUMBER | NAME | VELOCITY | NAME "(" arguments ")" | "(" expression ")"
    arguments  := expression ("," expression)*
    VELOCITY   := NAME "'"                       (no space before the prime)

with the names of :data:`NAMES`, numbers of every spelling (huge and tiny exponents too),
whitespace anywhere except inside a token, and nesting within ``MAX_DEPTH``.  Such text may be
refused only for a limit (``kind == "limit"``: a number too large, too many terms…) or for
having no value (``kind == "value"``: ``1/0``, ``log(0)``); every other refusal is a bug.
:func:`mutated`, :func:`soup` and :func:`noise` write anything at all.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol, TypeVar

from chaplygin.io.parser import FUNCTIONS, MAX_DEPTH, Names

T = TypeVar("T")

PARAMETERS = ["m", "a", "k_1", "Mass"]
COORDINATES = ["x", "theta", "q2"]
NAMES = Names.build(PARAMETERS, COORDINATES)
#: Refusals that grammatical text may get: a documented limit, or no value.
ALLOWED_FOR_VALID = ("limit", "value")

#: Expressions that evaluate in any healthy process: run after fuzzing to show that nothing
#: global (mpmath's precision) was left broken; ``(text, value)``.
PROBES = [
    ("sign(sin(19))", 1.0),
    ("abs(tan(E))", abs(math.tan(math.e))),
    ("atan(acos(-0.5))", math.atan(math.acos(-0.5))),
    ("sin(19) + exp(1/3)", math.sin(19) + math.exp(1 / 3)),
    ("tan(10^300)/(1 + tan(10^300)^2)", None),  # needs ~1000 bits: a precision stuck low fails
]

_SPACES = ["", "", "", "", " ", "  ", "\t", "\n", "\r\n"]
_FUNCTIONS = sorted(FUNCTIONS)
_SMALL = ["0", "1", "2", "3", "7", "10", "0.5", ".25", "5.", "1.5e-3", "2E+2", "007", "100"]


class Source(Protocol):
    """Where the choices come from (Hypothesis data or a seeded ``random.Random``)."""

    def integer(self, lo: int, hi: int) -> int:
        """An integer in ``[lo, hi]``."""
        ...


def pick(source: Source, options: Sequence[T]) -> T:
    return options[source.integer(0, len(options) - 1)]


def chance(source: Source, percent: int) -> bool:
    return source.integer(1, 100) <= percent


# ---------------------------------------------------------------------------- valid text
def number(source: Source) -> str:
    """A number literal: small and common, or with many digits, or a huge or tiny exponent."""
    kind = source.integer(0, 9)
    if kind <= 4:
        return pick(source, _SMALL)
    digits = "".join(str(source.integer(0, 9)) for _ in range(source.integer(1, pick(source, [3, 20, 110]))))
    if kind == 5:
        return digits
    if kind == 6:
        cut = source.integer(0, len(digits))
        text = digits[:cut] + "." + digits[cut:]
        return text if text != "." else "0."
    exponent = pick(source, [1, 3, 17, 99, 300, 399, 400, 401, 450, 4000, 400000000])
    sign = pick(source, ["", "+", "-"])
    mantissa = pick(source, [digits, "1", "9.99", ".5", digits[:1] + "." + digits[1:]])
    return f"{mantissa}{pick(source, ['e', 'E'])}{sign}{exponent}"


def valid(source: Source, depth: int = 6, names: bool = True) -> str:
    """An expression of the grammar (``names=False``: constants only, as in ``[parameters]``)."""
    return _Writer(source, names).expression(depth)


class _Writer:
    def __init__(self, source: Source, names: bool) -> None:
        self.s = source
        self.names = names
        # parser depth used so far: parentheses, calls, unary signs and powers each add one
        self.level = 0

    def space(self) -> str:
        return pick(self.s, _SPACES)

    def room(self, depth: int, need: int = 1) -> bool:
        return depth > 0 and self.level + need <= MAX_DEPTH - 2

    def expression(self, depth: int) -> str:
        out = self.term(depth)
        for _ in range(self.s.integer(0, 3 if depth > 0 else 0)):
            out += self.space() + pick(self.s, ["+", "-"]) + self.space() + self.term(depth - 1)
        return out

    def term(self, depth: int) -> str:
        out = self.unary(depth)
        for _ in range(self.s.integer(0, 3 if depth > 0 else 0)):
            out += self.space() + pick(self.s, ["*", "/"]) + self.space() + self.unary(depth - 1)
        return out

    def unary(self, depth: int) -> str:
        if self.room(depth) and chance(self.s, 15):
            self.level += 1
            text = pick(self.s, ["-", "+", "-"]) + self.space() + self.unary(depth - 1)
            self.level -= 1
            return text
        return self.power(depth)

    def power(self, depth: int) -> str:
        base = self.primary(depth)
        if self.room(depth) and chance(self.s, 20):
            self.level += 1
            exponent = (
                self.unary(depth - 2) if chance(self.s, 50) else pick(self.s, ["2", "3", "-1", "0.5", "1000"])
            )
            self.level -= 1
            return base + self.space() + pick(self.s, ["^", "**"]) + self.space() + exponent
        return base

    def primary(self, depth: int) -> str:
        kind = self.s.integer(0, 9) if self.room(depth) else self.s.integer(0, 4)
        if kind <= 1:
            return number(self.s)
        if kind <= 4:
            return self.name()
        self.level += 1
        try:
            if kind <= 6:
                return "(" + self.space() + self.expression(depth - 1) + self.space() + ")"
            function = pick(self.s, _FUNCTIONS)
            args = [self.expression(depth - 1) for _ in range(FUNCTIONS[function])]
            return (
                function
                + self.space()
                + "("
                + self.space()
                + ("," + self.space()).join(args)
                + self.space()
                + ")"
            )
        finally:
            self.level -= 1

    def name(self) -> str:
        if not self.names:
            return pick(self.s, ["pi", "E"])
        kind = self.s.integer(0, 9)
        if kind <= 2:
            return pick(self.s, PARAMETERS)
        if kind <= 4:
            return pick(self.s, COORDINATES)
        if kind <= 7:
            return pick(self.s, COORDINATES) + "'"
        return pick(self.s, ["t", "pi", "E"])


# ---------------------------------------------------------------------------- anything
_TOKENS = [
    "x",
    "theta",
    "q2",
    "m",
    "Mass",
    "t",
    "pi",
    "E",
    "x'",
    "'",
    "''",
    " '",
    "0",
    "1",
    "1e400",
    "1e-400",
    "9",
    "0.5",
    ".",
    "e",
    "+",
    "-",
    "*",
    "/",
    "^",
    "**",
    "***",
    "(",
    ")",
    ",",
    ", )",
    " ",
    "\t",
    "sin(",
    "sqrt(",
    "atan2(",
    "exp(",
    "sinh(",
    "tan(",
    "log(",
    "abs(",
    "sign(",
    "acos(",
    "foo(",
    "_",
    "__import__",
    "[",
    "]",
    "=",
    '"',
    "lambda",
    ":",
    ";",
    "#",
    "\\",
    "θ",
    "\x00",
    "9^9^9^9",
    "(" * 30,
    ")" * 30,
]
_ALPHABET = "x'()^*+-/0123456789.eE sinhcoqrtbgpaxm,_\t\n"


def soup(source: Source) -> str:
    """A random sequence of tokens of the language and of things that are not."""
    return "".join(pick(source, _TOKENS) for _ in range(source.integer(0, 40)))


def noise(source: Source) -> str:
    """Random characters: bytes read as Latin-1, the grammar's alphabet, or any code point."""
    n = source.integer(0, 60)
    kind = source.integer(0, 2)
    if kind == 0:
        return bytes(source.integer(0, 255) for _ in range(n)).decode("latin-1")
    if kind == 1:
        return "".join(pick(source, _ALPHABET) for _ in range(n))
    return "".join(
        chr(c) for c in (source.integer(0, 0x10FFFF) for _ in range(n)) if not 0xD800 <= c < 0xE000
    )


def mutated(source: Source) -> str:
    """A valid expression with a few random edits (delete, insert, swap, repeat, cut)."""
    text = valid(source, depth=source.integer(1, 5))
    for _ in range(source.integer(1, 3)):
        n = len(text)
        i = source.integer(0, n)
        kind = source.integer(0, 4)
        if kind == 0 and n:
            text = text[: min(i, n - 1)] + text[min(i, n - 1) + 1 :]
        elif kind == 1:
            text = text[:i] + pick(source, _TOKENS) + text[i:]
        elif kind == 2 and n >= 2:
            j = min(i, n - 2)
            text = text[:j] + text[j + 1] + text[j] + text[j + 2 :]
        elif kind == 3:
            j = source.integer(i, n)
            text = text[:j] + text[i:j] * source.integer(2, 4) + text[j:]
        else:
            text = text[:i]
    return text


#: The families of :func:`draw`, in order.
FAMILIES = ("valid", "constant", "mutated", "soup", "noise")


def draw(source: Source) -> tuple[str, str]:
    """``(family, text)``: a valid expression (half the time), a constant one, or anything."""
    k = source.integer(0, 9)
    depth = source.integer(0, 6)
    if k <= 4:
        return "valid", valid(source, depth=depth)
    if k == 5:
        return "constant", valid(source, depth=depth, names=False)
    if k <= 7:
        return "mutated", mutated(source)
    if k == 8:
        return "soup", soup(source)
    return "noise", noise(source)
