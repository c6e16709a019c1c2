"""Trigonometric functions in the sines and cosines of a few base angles: one normal form for all.

A rolling problem's expressions hold ``sin(θ + ψ)``, ``cos θ``, ``tan θ`` and ``sin 2φ`` side
by side.  Treated as independent kernels, as a polynomial normal form treats them, identities
between them go unseen: ``sin θ − cos θ·tan θ`` is never found to be 0, and
``sin(θ + ψ)·cos θ − cos(θ + ψ)·sin θ`` is never ``sin ψ``.  :func:`angle_rewrites` maps every
trigonometric function whose argument is an integer combination of *base angles* to a rational
expression in the sines and cosines of those angles alone (addition formulas; ``tan = sin/cos``,
``sec = 1/cos``, ``csc = 1/sin``, ``cot = cos/sin``); then ``sin² + cos² = 1`` is the only
identity left, and the normal form of :mod:`chaplygin.core._rational` applies it.

The base angle of a symbol ``s`` is ``g·s`` with ``g`` the greatest common divisor of the
rational multiples of ``s`` that occur: ``sin 2φ`` alone stays ``sin 2φ``; beside ``sin φ`` it
is ``2 sin φ cos φ``; ``sin(θ/2)`` beside ``cos θ`` makes ``θ/2`` the base angle.  An argument
that is not such a combination (``sin(x·y)``, a Float multiple, a constant term) stays a kernel
of its own, and so does a multiple beyond :data:`MAX_MULTIPLE`, whose expansion would be long.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from fractions import Fraction

import sympy as sp
from sympy.simplify.fu import TR10i

from chaplygin.core._fold import size

__all__ = ["CONTRACT_NODES", "MAX_MULTIPLE", "angle_rewrites", "contracted", "has_angle_sums"]

#: the largest integer multiple of a base angle that is expanded (sin 4θ is 8 terms)
MAX_MULTIPLE = 4
#: the largest part (symbols and operations) whose angle sums are contracted for display:
#: SymPy's TR10i grows fast with size (14 s on the sleigh chain's solved form, whole)
CONTRACT_NODES = 1500

_TRIG = (sp.sin, sp.cos, sp.tan, sp.cot, sp.sec, sp.csc)


def _combination(arg: sp.Expr) -> dict[sp.Symbol, Fraction] | None:
    """``arg`` as ``{symbol: rational multiple}``; None where it is not such a combination."""
    out: dict[sp.Symbol, Fraction] = {}
    for term in sp.Add.make_args(arg):
        coeff, rest = term.as_coeff_Mul()
        if not (coeff.is_Rational and isinstance(rest, sp.Symbol)):
            return None
        out[rest] = out.get(rest, Fraction(0)) + Fraction(int(coeff.p), int(coeff.q))
    return {s: c for s, c in out.items() if c}


def _gcd(values: Iterable[Fraction]) -> Fraction:
    """The greatest rational ``g`` of which every value is an integer multiple."""
    values = list(values)
    num = math.gcd(*(v.numerator for v in values))
    den = math.lcm(*(v.denominator for v in values))
    return Fraction(num, den)


def _trig_of(exprs: Iterable[sp.Expr]) -> list[sp.Expr]:
    found: dict[sp.Expr, None] = {}
    seen: set[sp.Expr] = set()
    stack = list(exprs)
    while stack:
        e = stack.pop()
        if e in seen or e.is_Atom:
            continue
        seen.add(e)
        if isinstance(e, _TRIG):
            found[e] = None
        stack.extend(e.args)
    return sorted(found, key=sp.default_sort_key)


class _Expander:
    """cos and sin of integer combinations of base angles, by the addition formulas (memoised)."""

    def __init__(self) -> None:
        self._memo: dict[tuple[tuple[sp.Expr, int], ...], tuple[sp.Expr, sp.Expr]] = {}

    def cos_sin(self, terms: tuple[tuple[sp.Expr, int], ...]) -> tuple[sp.Expr, sp.Expr]:
        if terms in self._memo:
            return self._memo[terms]
        (angle, n), rest = terms[0], terms[1:]
        if rest:  # cos(a + b), sin(a + b)
            ca, sa = self.cos_sin(((angle, n),))
            cb, sb = self.cos_sin(rest)
            out = (ca * cb - sa * sb, sa * cb + ca * sb)
        elif n < 0:
            c, s = self.cos_sin(((angle, -n),))
            out = (c, -s)
        elif n == 1:
            out = (sp.cos(angle), sp.sin(angle))
        else:  # cos(n a) = cos((n - 1) a + a)
            c1, s1 = sp.cos(angle), sp.sin(angle)
            c, s = self.cos_sin(((angle, n - 1),))
            out = (sp.expand(c * c1 - s * s1), sp.expand(s * c1 + c * s1))
        self._memo[terms] = out
        return out


def angle_rewrites(exprs: Iterable[sp.Expr]) -> dict[sp.Expr, sp.Expr]:
    """Each trigonometric function of ``exprs`` that can be, in the sines and cosines of base angles.

    Returns
    -------
    dict
        ``{function: rewritten}``, only for the functions that change
        (``sin(θ + ψ) → sin θ cos ψ + sin ψ cos θ``, ``tan θ → sin θ / cos θ``).
    """
    funcs = _trig_of(exprs)
    combos = {f: _combination(f.args[0]) for f in funcs}
    multiples: dict[sp.Symbol, set[Fraction]] = {}
    for combo in combos.values():
        for s, c in (combo or {}).items():
            multiples.setdefault(s, set()).add(c)
    unit = {s: _gcd(cs) for s, cs in multiples.items()}
    expander = _Expander()
    out: dict[sp.Expr, sp.Expr] = {}
    for f in funcs:
        combo = combos[f]
        cos_sin: tuple[sp.Expr, sp.Expr] | None = None
        if combo:
            terms = tuple(
                (sp.Rational(unit[s].numerator, unit[s].denominator) * s, int(c / unit[s]))
                for s, c in sorted(combo.items(), key=lambda item: sp.default_sort_key(item[0]))
            )
            if all(abs(n) <= MAX_MULTIPLE for _, n in terms):
                cos_sin = expander.cos_sin(terms)
        if cos_sin is None:
            cos_sin = sp.cos(f.args[0]), sp.sin(f.args[0])
        c, s = cos_sin
        new = {sp.sin: s, sp.cos: c, sp.tan: s / c, sp.cot: c / s, sp.sec: 1 / c, sp.csc: 1 / s}[f.func]
        if new != f:
            out[f] = new
    return out


def contracted(expr: sp.Expr) -> sp.Expr:
    """``expr`` for display, its sums of products contracted back into functions of angle sums:
    ``sin ψ cos θ + sin θ cos ψ`` is ``sin(ψ + θ)`` (SymPy's ``fu`` rule TR10i, a fixed set of
    identities: the value is unchanged).

    The normal form expands every angle sum, so that identities between them are seen; a
    reader reads the sum.  A sum is contracted term by term, a fraction in its numerator and
    denominator, down to parts of at most :data:`CONTRACT_NODES`; a larger part stays as it is.
    """
    if not expr.has(sp.sin, sp.cos):
        return expr
    if size(expr, CONTRACT_NODES) <= CONTRACT_NODES:
        return TR10i(expr)
    if expr.is_Add or expr.is_Mul:
        return expr.func(*map(contracted, expr.args))
    if expr.is_Pow:
        return expr.func(contracted(expr.base), expr.exp)
    return expr


def has_angle_sums(exprs: Iterable[sp.Expr]) -> bool:
    """Whether a trigonometric function of a sum (``sin(θ + ψ)``) occurs in ``exprs``: where the
    input wrote none, a display has none to read back (:func:`contracted` is not tried)."""
    return any(f.args[0].is_Add for f in _trig_of(exprs))
