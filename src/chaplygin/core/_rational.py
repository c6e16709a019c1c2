"""Exact rational arithmetic for solved accelerations: fraction-free solves, sin² + cos² = 1.

A derived mass matrix and forcing are rational functions of a few *kernels*:
the parameters, the velocities, and functions of the coordinates such as
``sin θ`` and ``cos θ``.  Treating each kernel as an independent variable makes
them elements of the field ``ℚ(kernels)``, where SymPy's sparse polynomials
solve a small linear system without fractions (``solve_den``:
``x = adj(M)·F / det M`` up to common factors) and cancel common factors
exactly.  Trigonometric functions are first written in the sines and cosines of
base angles (``sin(θ + ψ)``, ``tan θ``, ``sin 2θ`` in ``sin θ``, ``cos θ``, ``sin ψ``,
``cos ψ``: :mod:`chaplygin.core._angles`), so that one identity is left, the one
that links kernels in every rolling problem: ``sin²a + cos²a = 1``.  It is applied
by rewriting every even power of one of the two (``cos²a → 1 − sin²a``, or the
other way) — a normal form modulo the identity — before cancelling, so that factors such as ``cos²θ`` and
``1 − sin²θ`` cancel.  Both directions are tried and the shorter result is
kept.  Before that, the input's denominators (every sum met as ``1/(…)``) are
divided out of numerator and denominator wherever they divide both — the
fraction-free solve puts them in both, and rewritten by the identity they are
no longer recognisable, yet vanish together near the input's poles, where the
expanded fraction then loses every digit in floating point — and those left in
the denominator stay factors, unexpanded.

This replaces general simplification (``cancel`` of nested fractions, then
``trigsimp``), which cost seconds on the rolling disk; heavy simplification
stays available on request (:func:`simplified`).

Expressions enter the field through :meth:`Algebra.convert`, which walks the
expression tree once and multiplies out in sparse polynomial arithmetic (much
faster than SymPy's ``expand``), adding fractions over the least common multiple
of their denominators (a derivation's nested ``D²`` and ``D³`` give ``D³``, not ``D⁵``).  A rational power ``b**(p/q)`` is the kernel
``b**(1/q)`` to the power ``p``.  A Float is the exact rational of the decimal
it was written as (:func:`decimal`: 17.9 is 179/10), so that the numbers of a
system written with Float parameters cancel as exactly as symbols would
(``44.8·x − 44.8·x``, ``2·8.95 − 17.9``); the results then show their numbers as
Floats again, rounded once, at the input's precision.  (As independent kernels,
each Float, its negative, 1.0 and 2.0 were unrelated variables: nothing
cancelled, the expanded solve grew too large, and the nested solution lost
every digit in float64.)
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable, Sequence
from typing import Any

import sympy as sp
from mpmath.libmp import from_str, prec_to_dps, repr_dps, round_nearest, to_str
from sympy.polys.fields import FracElement, FracField
from sympy.polys.matrices import DomainMatrix
from sympy.polys.matrices.exceptions import DMNonInvertibleMatrixError
from sympy.polys.rings import PolyElement

from chaplygin.core._angles import angle_rewrites
from chaplygin.core._fast import gradient
from chaplygin.core._fold import size
from chaplygin.errors import ModelError

__all__ = [
    "Algebra",
    "TooLarge",
    "decimal",
    "exact_numbers",
    "floated",
    "linear_forms",
    "nested_inputs",
    "normal_all",
    "normal_matrix",
    "simplified",
    "solve_columns",
    "solve_linear",
    "zero_if_vanishing",
]

#: the largest polynomial (in terms) that normal forms are computed for; beyond it an
#: expanded result would be unreadable and its cancellation slow (see :class:`TooLarge`)
TERMS = 400


#: the most terms an intermediate product or power may have before it is formed
_WORK = 50 * TERMS
#: denominators up to this many terms are shown factored
_FACTOR_TERMS = 40


class TooLarge(Exception):
    """Expanded normal forms would be too large: the caller solves with nested expressions."""


def _check(*polys: PolyElement) -> None:
    if any(len(p) > TERMS for p in polys):
        raise TooLarge


#: a rational function as (numerator, denominator), not necessarily cancelled
Fraction = tuple[PolyElement, PolyElement]


def _split_power(expr: sp.Expr) -> tuple[sp.Expr, int] | None:
    """``b**e`` as (kernel, integer power) when ``e`` is rational; None otherwise."""
    base, exp = expr.args
    if exp.is_Integer:
        return base, int(exp)
    if exp.is_Rational:
        return base ** sp.Rational(1, exp.q), int(exp.p)
    return None


def decimal(number: sp.Float) -> sp.Rational:
    """The exact rational of the shortest decimal that rounds to ``number`` at its precision.

    The number as it was written: ``Float(17.9)`` is 179/10, not the binary value
    17.89999999999999857891452847979962825775146484375, so that 2 × 8.95 is 17.9 and
    17.9 × 44.8 is 801.92, exactly, as the Floats SymPy computed from them round to.
    """
    mpf, prec = number._mpf_, number._prec
    for digits in range(prec_to_dps(prec), repr_dps(prec) + 1):
        text = to_str(mpf, digits)
        if from_str(text, prec, round_nearest) == mpf:
            return sp.Rational(text)
    return sp.Rational(number)  # pragma: no cover - repr_dps digits always round-trip


def _kernels(exprs: Iterable[sp.Expr], rewrites: dict[sp.Expr, sp.Expr]) -> tuple[list[sp.Expr], int | None]:
    """The kernels of ``exprs`` (what is neither a number nor +, ·, or a rational power), and
    the largest precision of the Floats among the numbers (None without Floats); a function
    with a rewrite (:func:`~chaplygin.core._angles.angle_rewrites`) is looked into as rewritten."""
    found: dict[sp.Expr, None] = {}
    seen: set[sp.Expr] = set()
    prec: int | None = None
    stack = list(exprs)
    while stack:
        e = stack.pop()
        if e in seen:
            continue
        seen.add(e)
        if e.is_Rational:
            continue
        if e.is_Float:
            prec = max(prec or 0, e._prec)
            continue
        if e.is_Add or e.is_Mul:
            stack.extend(e.args)
        elif e in rewrites:
            stack.append(rewrites[e])
        elif e.is_Pow and (split := _split_power(e)) is not None:
            base, _ = split
            if base.is_Pow:  # b**(1/q): a kernel of its own
                found[base] = None
            else:
                stack.append(base)
        else:
            found[e] = None
    return sorted(found, key=sp.default_sort_key), prec


class Algebra:
    """The ring ``ℚ[kernels]`` of a batch of expressions, with fraction-free linear algebra.

    Parameters
    ----------
    exprs : every expression that will be converted (their kernels make the ring)
    """

    def __init__(self, exprs: Iterable[sp.Expr]) -> None:
        exprs = list(exprs)
        #: trigonometric functions in the sines and cosines of base angles
        self._rewrites = angle_rewrites(exprs)
        kernels, prec = _kernels(exprs, self._rewrites)
        kernels = kernels or [sp.Dummy("one")]
        #: the precision of the Floats in the input: the results' numbers are Floats of it
        self.prec = prec
        self.field = FracField(kernels, sp.QQ)
        self.ring = self.field.ring
        self._gen = dict(zip(kernels, self.ring.gens))
        where = {g: i for i, g in enumerate(kernels)}
        #: (index of sin a, index of cos a) for every angle a with both kernels
        self.pairs = [
            (i, where[sp.cos(g.args[0])])
            for i, g in enumerate(kernels)
            if isinstance(g, sp.sin) and sp.cos(g.args[0]) in where
        ]
        self._memo: dict[sp.Expr, Fraction] = {}
        #: (index of r, q, b) for every kernel r = b**(1/q) with b a polynomial free of r: r**q = b
        self.roots: list[tuple[int, int, PolyElement]] = []
        for i, g in enumerate(kernels):
            if g.is_Pow and g.exp.is_Rational and g.exp.p == 1 and g.exp.q > 1:
                try:
                    n, d = self.convert(g.base)
                except (TooLarge, KeyError):
                    continue
                if d == self.ring.one and all(m[i] == 0 for m in n.itermonoms()):
                    self.roots.append((i, int(g.exp.q), n))
        self._bottoms: dict[PolyElement, sp.Expr] = {}
        #: every sum met as a denominator (the base of a negative power): the candidates for
        #: the common factors of a solution's numerator and denominator (:meth:`_divide_out`)
        self._divisors: dict[PolyElement, None] = {}
        #: the irreducible factors of the denominators met by :meth:`_cancel` (solutions share theirs)
        self._factors: dict[PolyElement, list[tuple[PolyElement, int]]] = {}

    # ------------------------------------------------------------------ conversion
    def convert(self, expr: sp.Expr) -> Fraction:
        """``expr`` as a fraction of polynomials in the kernels (not cancelled)."""
        memo = self._memo
        if expr in memo:
            return memo[expr]
        ring = self.ring
        if expr.is_Rational or expr.is_Float:
            value = decimal(expr) if expr.is_Float else expr
            out = (ring.ground_new(sp.QQ(int(value.p), int(value.q))), ring.one)
        elif expr.is_Add:
            out = _sum([self.convert(a) for a in expr.args])
        elif expr.is_Mul:
            out = _product([self.convert(a) for a in expr.args])
        elif expr in self._gen:
            out = (self._gen[expr], ring.one)
        elif expr in self._rewrites:
            out = self.convert(self._rewrites[expr])
        elif expr.is_Pow and (split := _split_power(expr)) is not None:
            base, k = split
            n, d = (self._gen[base], ring.one) if base in self._gen else self.convert(base)
            if max(math.comb(len(n) + abs(k) - 1, abs(k)), math.comb(len(d) + abs(k) - 1, abs(k))) > _WORK:
                raise TooLarge  # a power of a sum with too many terms to expand
            out = (n**k, d**k) if k >= 0 else (d ** (-k), n ** (-k))
            if k < 0 and len(n) > 1 and not _eliminate(n, self.pairs).is_ground:
                self._divisors[n] = None  # (sin² + cos², which is 1, is none)
        else:  # pragma: no cover - every other expression is a kernel
            raise KeyError(expr)
        _check(*out)
        memo[expr] = out
        return out

    def to_expr(self, frac: FracElement) -> sp.Expr:
        """A field element back as a SymPy expression, common monomials and contents pulled out;
        where the input had Floats, its numbers are Floats again (:func:`_floated`)."""
        numer, denom = frac.numer, frac.denom
        if denom.LC < 0:
            numer, denom = -numer, -denom
        out = self._poly_expr(numer)
        if denom != 1:
            if denom not in self._bottoms:  # solutions often share their denominator
                self._bottoms[denom] = self._bottom(denom)
            out = out / self._bottoms[denom]
        return out if self.prec is None else _floated(out, self.prec)

    def _bottom(self, denom: PolyElement) -> sp.Expr:
        """A denominator as an expression: factored where it is small."""
        if len(denom) > _FACTOR_TERMS:
            return self._poly_expr(denom)
        unit, factors = denom.factor_list()
        return sp.Rational(int(unit.numerator), int(unit.denominator)) * sp.Mul(
            *(self._poly_expr(f) ** k for f, k in factors)
        )

    def _poly_expr(self, p: PolyElement) -> sp.Expr:
        if not p:
            return sp.S.Zero
        ring = p.ring
        monoms = p.listmonoms()
        low = tuple(min(m[i] for m in monoms) for i in range(ring.ngens))
        if any(low):
            p = p.exquo(ring({low: sp.QQ(1)}))
        content, p = p.primitive()
        if p.LC < 0:
            content, p = -content, -p
        factors = [g**e for g, e in zip(ring.symbols, low) if e]
        return sp.Mul(sp.Rational(int(content.numerator), int(content.denominator)), *factors, p.as_expr())

    # ------------------------------------------------------------------ normal form
    def reduce(self, frac: Fraction) -> FracElement:
        """``frac`` in normal form modulo sin² + cos² = 1, common factors cancelled.

        Raises ZeroDivisionError where the denominator vanishes by the identity.
        """
        denom, (numer,) = self._divide_out(frac[1], [frac[0]])
        if self.roots:  # (√b)² = b: √(x'² + y'²)² is x'² + y'², so that sums with it cancel
            numer, denom = _unroot(numer, self.roots), _unroot(denom, self.roots)
            if not denom:
                raise ZeroDivisionError
        # the input's denominators stay factors as they were written: expanded and rewritten
        # by the identity, a power of one that vanishes somewhere loses digits near there
        # (unless the identity cancels one against the numerator: cos²θ / (1 − sin²θ) is 1)
        kept = []
        rewritten: list[PolyElement] = []  # the numerator rewritten each way, when needed
        for f in self._divisors:
            while not (split := denom.div(f))[1]:
                rewritten = rewritten or [_eliminate(numer, pairs) for pairs in self._directions()]
                views = [_eliminate(f, pairs) for pairs in self._directions()]
                if not all(views):
                    raise ZeroDivisionError
                if any(not n.div(v)[1] for n, v in zip(rewritten, views)):
                    break
                denom = split[0]
                # the factor as written, but with sin² + cos² = 1 applied (its shortest view)
                kept.append(min(views, key=lambda v: _length((v, self.ring.one))))
        _check(numer, denom)
        candidates = []
        best = numer, denom
        for pairs in self._directions():
            # the second direction starts from the first's (smaller) cancelled result
            n, d = _eliminate(best[0], pairs), _eliminate(best[1], pairs)
            if not d:
                raise ZeroDivisionError
            best = self._cancel(n, d)
            candidates.append(best)
        if denom == 1 and not kept:
            candidates.append((numer, denom))  # a polynomial may read best as it was written
        # the fewest terms; on a tie the fewest minus signs (sin²θ + 2/5 rather than 7/5 − cos²θ)
        numer, denom = min(candidates, key=_length)
        # numerator and denominator are each exact in any of their views: each in its shortest
        # (cos²θ below the line rather than 1 − sin²θ, whichever way the numerator reads best)
        numer, denom = (
            min([p, *(_eliminate(p, pairs) for pairs in self._directions())], key=_size)
            for p in (numer, denom)
        )
        if kept:
            shown = self._bottom(denom) * sp.Mul(*(self._bottom(f) for f in kept))
            for f in kept:
                denom = denom * f
            if denom.LC < 0:  # to_expr shows the denominator with a positive leading coefficient
                numer, denom, shown = -numer, -denom, -shown
            self._bottoms[denom] = shown
        return self.field.raw_new(numer, denom)

    def _cancel(self, numer: PolyElement, denom: PolyElement) -> tuple[PolyElement, PolyElement]:
        """``numer.cancel(denom)``, the same pair, without a greatest common divisor: the
        denominator's irreducible factors (it is small; factored once for all the numerators
        over it) are divided out of both as often as they divide the numerator, which leaves a
        constant for their divisor, whose normalisation :func:`_coprime_cancel` repeats.  The
        vakonomic rolling disk's cancellations: 0.030 -> 0.013 s.  A large denominator is
        cancelled by SymPy's divisor, as is anything over another domain than ℚ."""
        if not numer:
            return numer, self.ring.one
        if len(denom) > _FACTOR_TERMS or self.ring.domain != sp.QQ:
            return numer.cancel(denom)
        factors = self._factors.get(denom)
        if factors is None:
            factors = [(f, k) for f, k in denom.factor_list()[1] if not f.is_ground]
            self._factors[denom] = factors
        for f, k in factors:
            for _ in range(k):
                quotient, remainder = numer.div(f)
                if remainder:
                    break
                numer, denom = quotient, denom.exquo(f)
        return _coprime_cancel(numer, denom)

    def _directions(self) -> list[list[tuple[int, int]]]:
        """The pairs of :func:`_eliminate` for each way of rewriting: sin² → 1 − cos², and back."""
        return [[(p[d], p[1 - d]) for p in self.pairs] for d in ((0, 1) if self.pairs else (0,))]

    def _divide_out(
        self, denom: PolyElement, numers: list[PolyElement]
    ) -> tuple[PolyElement, list[PolyElement]]:
        """``numers / denom`` with every input denominator that divides them all divided out.

        A fraction-free solve multiplies numerators and denominator alike by the denominators
        of the input (``adj(d·M)·d·F / det(d·M)``); the identity sin² + cos² = 1, applied
        before cancelling (:meth:`reduce`), rewrites such a common factor differently in the
        two, and cancelling no longer finds it.  Left in, it vanishes in both wherever the
        input's denominator does (the constraints' split at its singular set): an expression
        that is exact, but long, and that loses every digit in floating point near there
        (issue 27: the snakeboard's new form, off by 130 % at 0.05 rad from parallel
        wheels).  Dividing by the known candidates is exact and cheap, where a greatest
        common divisor of the expanded polynomials costs seconds.
        """
        for f in self._divisors:
            while True:
                qd, rd = denom.div(f)
                if rd:
                    break
                parts = [n.div(f) for n in numers]
                if any(r for _, r in parts):
                    break
                denom, numers = qd, [q for q, _ in parts]
        return denom, numers

    def matrix(self, entries: sp.Matrix) -> tuple[DomainMatrix, PolyElement]:
        """``entries`` as ``N / d``: a polynomial matrix over one common denominator."""
        fracs = [[self.convert(entries[i, j]) for j in range(entries.cols)] for i in range(entries.rows)]
        d = self.ring.one
        for row in fracs:
            for _, den in row:
                d = d.lcm(den)
        rows = [[num * d.exquo(den) for num, den in row] for row in fracs]
        return DomainMatrix(rows, entries.shape, self.ring.to_domain()), d

    def solve_den(self, A: DomainMatrix, b: DomainMatrix) -> tuple[DomainMatrix, PolyElement]:
        """``A·x = b`` over the polynomials: ``x = N / d`` (not cancelled).

        Raises ZeroDivisionError where ``A`` is singular, identically or by sin² + cos² = 1.
        """
        if A.shape[0] == 0:
            return DomainMatrix.zeros((0, b.shape[1]), A.domain), self.ring.one
        # a rough bound of the determinant's size: the product of the rows' largest entries
        estimate = 1
        for i in range(A.shape[0]):
            entries = [A[i, j].element for j in range(A.shape[1])] + [
                b[i, j].element for j in range(b.shape[1])
            ]
            estimate *= max(1, *map(len, entries))
        if estimate > 20 * TERMS:
            raise TooLarge
        try:
            num, den = A.solve_den(b)
        except DMNonInvertibleMatrixError:
            raise ZeroDivisionError from None
        den = getattr(den, "element", den)
        if not den or not _eliminate(den, self.pairs):
            raise ZeroDivisionError
        rows, cols = num.shape
        den, entries = self._divide_out(den, [num[i, j].element for i in range(rows) for j in range(cols)])
        _check(den, *entries)
        grid = [entries[i * cols : (i + 1) * cols] for i in range(rows)]
        return DomainMatrix(grid, num.shape, num.domain), den

    def fractions(self, N: DomainMatrix, d: PolyElement) -> list[FracElement]:
        """The entries of the column ``N / d``, each reduced (:meth:`reduce`)."""
        return [self.reduce((N[i, 0].element, d)) for i in range(N.shape[0])]


def _coprime_cancel(f: PolyElement, g: PolyElement) -> tuple[PolyElement, PolyElement]:
    """``f.cancel(g)`` over ℚ for ``f`` and ``g`` whose divisor is a constant: the steps of
    SymPy's ``PolyElement.cancel`` (denominators cleared, the integer cofactors, the unit that
    makes the denominator's leading coefficient positive), the divisor being the contents'."""
    ring = f.ring
    if not f:
        return f, ring.one
    integers = ring.clone(domain=ring.domain.get_ring())
    cq, f = f.clear_denoms()
    cp, g = g.clear_denoms()
    f, g = f.set_ring(integers), g.set_ring(integers)
    common = integers.domain.gcd(f.content(), g.content())
    p, q = f.quo_ground(common), g.quo_ground(common)
    _, cp, cq = integers.domain.cofactors(cp, cq)
    p, q = p.set_ring(ring).mul_ground(cp), q.set_ring(ring).mul_ground(cq)
    unit = q.canonical_unit()
    return (p, q) if unit == ring.domain.one else (p.mul_ground(unit), q.mul_ground(unit))


def _floated(expr: sp.Expr, prec: int) -> sp.Expr:
    """``expr`` with its numbers as Floats of ``prec`` bits, as SymPy's arithmetic on the input's
    Floats would show them: every number but the exponents, and the integers a double holds
    exactly (``sin a·cos b + 2·x``, not ``1.0·sin a·cos b + 2.0·x``)."""
    if expr.is_Rational:
        if expr.is_Integer and abs(expr) <= 2**53:
            return expr
        return sp.Float(expr, precision=prec)
    if expr.is_Atom or isinstance(expr, sp.Derivative):
        return expr
    if expr.is_Pow:
        return expr.func(_floated(expr.base, prec), expr.exp)
    return expr.func(*(_floated(a, prec) for a in expr.args))


def exact_numbers(expr: sp.Expr) -> tuple[sp.Expr, int | None]:
    """``expr`` with each Float replaced by the exact rational it was written as (:func:`decimal`),
    and the largest precision among them (None without Floats).

    SymPy's Float arithmetic rounds at every step: ``17.9·44.8`` is not the double nearest
    801.92, and a derivation's terms that cancel exactly in the numbers as written leave a
    residue of 10⁻¹² (the snakeboard's φ row).  Derived in exact rationals, they cancel.
    """
    floats = expr.atoms(sp.Float)
    if not floats:
        return expr, None
    return expr.xreplace({f: decimal(f) for f in floats}), max(f._prec for f in floats)


def floated(expr: Any, prec: int | None) -> Any:
    """An expression or matrix with its numbers shown as Floats of ``prec`` bits (as it is for None)."""
    if prec is None:
        return expr
    if isinstance(expr, sp.MatrixBase):
        return expr.applyfunc(lambda e: _floated(e, prec))
    return _floated(expr, prec)


def _size(p: PolyElement) -> tuple[int, int]:
    return len(p), sum(c < 0 for c in p.itercoeffs())


def _length(frac: Fraction) -> tuple[int, int]:
    n, d = frac
    return len(n) + len(d), sum(c < 0 for c in n.itercoeffs()) + sum(c < 0 for c in d.itercoeffs())


def _sum(parts: list[Fraction]) -> Fraction:
    ring = parts[0][0].ring
    groups: dict[PolyElement, PolyElement] = {}
    for n, d in parts:  # add numerators over equal denominators first
        groups[d] = groups.get(d, ring.zero) + n
    items = list(groups.items())
    d_out, n_out = items[0]
    for d, n in items[1:]:  # over the least common multiple: D² + D³ is over D³, not D⁵
        common = d_out.lcm(d)
        n_out = n_out * common.exquo(d_out) + n * common.exquo(d)
        d_out = common
    return n_out, d_out


def _product(parts: list[Fraction]) -> Fraction:
    n_out, d_out = parts[0]
    for n, d in parts[1:]:
        if len(n_out) * len(n) > _WORK or len(d_out) * len(d) > _WORK:
            raise TooLarge
        n_out, d_out = n_out * n, d_out * d
    return n_out, d_out


def _eliminate(p: PolyElement, pairs: list[tuple[int, int]]) -> PolyElement:
    """Rewrite ``x^e`` (e ≥ 2) as ``x^(e mod 2)·(1 − y²)^(e div 2)`` for each pair ``(x, y)``."""
    ring = p.ring
    for x, y in pairs:
        if all(m[x] < 2 for m in p.itermonoms()):
            continue
        one_minus = ring.one - ring.gens[y] ** 2
        powers: dict[int, PolyElement] = {}
        out = ring.zero
        for monom, coeff in p.iterterms():
            e = monom[x]
            if e < 2:
                out += ring({monom: coeff})
                continue
            rest = list(monom)
            rest[x] = e % 2
            if e // 2 not in powers:
                powers[e // 2] = one_minus ** (e // 2)
            out += ring({tuple(rest): coeff}) * powers[e // 2]
        p = out
    return p


def _unroot(p: PolyElement, roots: list[tuple[int, int, PolyElement]]) -> PolyElement:
    """Rewrite ``r^e`` (e ≥ q) as ``r^(e mod q)·b^(e div q)`` for each root ``r = b^(1/q)``."""
    ring = p.ring
    for i, q, base in roots:
        if all(m[i] < q for m in p.itermonoms()):
            continue
        powers: dict[int, PolyElement] = {}
        out = ring.zero
        for monom, coeff in p.iterterms():
            e = monom[i]
            if e < q:
                out += ring({monom: coeff})
                continue
            rest = list(monom)
            rest[i] = e % q
            if e // q not in powers:
                powers[e // q] = base ** (e // q)
            out += ring({tuple(rest): coeff}) * powers[e // q]
        p = out
    return p


def solve_linear(M: sp.Matrix, F: sp.Matrix, what: str = "the equations") -> list[sp.Expr]:
    """Solve ``M·x = F`` exactly: in normal form where that stays small, else by LU.

    Raises
    ------
    ModelError
        When ``M`` is singular (identically, or by sin² + cos² = 1).
    """
    n = M.rows
    if n == 0:
        return []
    try:
        alg = Algebra([*M, *F])
        N, _ = alg.matrix(M.row_join(F))  # one common denominator scales the whole system
        return [alg.to_expr(x) for x in alg.fractions(*alg.solve_den(N[:, :n], N[:, n:]))]
    except ZeroDivisionError:
        raise ModelError(f"{what} do not determine their unknowns: the mass matrix is singular.") from None
    except TooLarge:  # nested, from entries each in normal form (tan gone, a vanishing one 0)
        return list(nested_inputs(M).LUsolve(nested_inputs(F)))


def solve_columns(M: sp.Matrix, F: sp.Matrix, what: str) -> sp.Matrix:
    """``M⁻¹·F`` for a matrix ``F``, one column at a time by :func:`solve_linear`."""
    cols = [solve_linear(M, F[:, j], what) for j in range(F.cols)]
    return sp.Matrix(M.rows, F.cols, lambda i, j: cols[j][i])


def zero_if_vanishing(expr: sp.Expr) -> sp.Expr:
    """0 for an expression that vanishes identically (in normal form), else ``expr`` as it is.

    For the nested solve: such a forcing term is otherwise a sum of large terms that cancel
    only in exact arithmetic (a reduced form of the snakeboard, issue 27).
    """
    if expr.is_Number:
        return expr
    alg = Algebra([expr])
    try:
        numer, _ = alg.convert(expr)
    except TooLarge:
        return expr
    # the rewriting is a normal form modulo the identity: it is 0 exactly when numer is
    return sp.S.Zero if not _eliminate(numer, alg.pairs) else expr


def linear_forms(
    residuals: Sequence[sp.Expr], unknowns: Sequence[sp.Symbol], velocities: Sequence[sp.Symbol]
) -> list[tuple[sp.Expr, sp.Expr]]:
    """Each residual ``r``, affine in ``unknowns``, as ``(Σ_j M_j x_j, F)`` with ``r = Σ M_j x_j − F``.

    As a mechanics text writes an equation of motion: the accelerations (and multipliers)
    on the left, each coefficient one cancelled fraction in normal form; the row multiplied
    by the least common multiple of the left side's denominators, so that they are gone; the
    right side collected by products of the ``velocities`` (what is left is the forces), each
    coefficient cancelled; a factor common to a side's terms taken out where that reads
    shorter.  Every coefficient is exact: the row is the residual times a factor that vanishes
    nowhere the residual is defined.  A residual without unknowns (a velocity constraint) is
    ``(r, 0)``, unscaled: its multiplier's meaning depends on its scale.  One whose normal form
    would be too large is ``(Σ_j M_j x_j, −rest)``, each part in normal form where that is small.
    """
    alg = Algebra(residuals)
    gens = alg.ring.gens
    picked = [i for i, g in enumerate(gens) if alg.ring.symbols[i] in {*unknowns, *velocities}]
    left = [gens.index(alg._gen[x]) if x in alg._gen else None for x in unknowns]
    out = []
    for row, r in enumerate(residuals):
        try:
            out.append(_linear_form(alg, alg.reduce(alg.convert(r)), picked, left, row))
        except (TooLarge, ZeroDivisionError):
            grad = gradient(r, list(unknowns))
            parts = normal_all([*grad, r.xreplace({x: 0 for x in unknowns})])
            out.append((sp.Add(*(c * x for c, x in zip(parts, unknowns))), -parts[-1]))
    return out


def _linear_form(
    alg: Algebra, frac: FracElement, picked: list[int], left: list[int | None], row: int
) -> tuple[sp.Expr, sp.Expr]:
    """:func:`linear_forms` of one residual in normal form: its terms grouped by the powers of
    the ``picked`` kernels (unknowns and velocities); the groups with an unknown (``left``) on
    the left, the coefficient of the row's own unknown (the ``row``-th) with more + than − signs."""
    ring = alg.ring
    groups: dict[tuple[int, ...], PolyElement] = {}
    for monom, coeff in frac.numer.iterterms():
        key = tuple(monom[i] for i in picked)
        rest = tuple(0 if i in picked else e for i, e in enumerate(monom))
        groups[key] = groups.get(key, ring.zero) + ring({rest: coeff})
    unknown_at = [picked.index(i) for i in left if i is not None]
    on_left = [key for key in groups if any(key[k] for k in unknown_at)]
    if not on_left:  # a velocity constraint, as its multiplier multiplies it
        return alg.to_expr(frac), sp.S.Zero
    coeffs = {key: alg.reduce((p, frac.denom)) for key, p in groups.items()}
    scale = ring.one
    for key in on_left:
        scale = scale.lcm(coeffs[key].denom)
    scaled = {key: alg.reduce((c.numer * scale, c.denom)) for key, c in coeffs.items()}
    own = left[row] if row < len(left) else None
    lead = next((key for key in on_left if own is not None and key[picked.index(own)]), min(on_left))
    signs = [c > 0 for c in scaled[lead].numer.itercoeffs()]  # read with more + than − signs
    sign = 1 if 2 * sum(signs) > len(signs) or (2 * sum(signs) == len(signs) and signs[0]) else -1
    sides: tuple[list[sp.Expr], list[sp.Expr]] = ([], [])
    for key, c in scaled.items():
        monomial = sp.Mul(*(ring.symbols[picked[k]] ** e for k, e in enumerate(key)))
        on = key in on_left
        sides[0 if on else 1].append((sign if on else -sign) * alg.to_expr(c) * monomial)
    return _common(sp.Add(*sides[0])), _common(sp.Add(*sides[1]))


#: the largest side (symbols and operations) whose common factors are looked for: beyond it a
#: display folds the side anyway, and ``factor_terms`` costs a second
COMMON_NODES = 2000


def _common(side: sp.Expr) -> sp.Expr:
    """A side with the factors common to all its terms taken out (``a²m sin θ θ̇ (…)/5``),
    where that reads shorter; a side beyond :data:`COMMON_NODES` as it is."""
    if size(side, COMMON_NODES) > COMMON_NODES:
        return side
    out = sp.factor_terms(side)
    return out if len(str(out)) < len(str(side)) else side


def normal_matrix(M: sp.Matrix) -> sp.Matrix:
    """``M`` with each entry in normal form (:func:`normal_all`)."""
    return sp.Matrix(M.rows, M.cols, normal_all(list(M)))


_RECIPROCAL_TRIG = (sp.tan, sp.cot, sp.sec, sp.csc)


def nested_inputs(M: sp.Matrix) -> sp.Matrix:
    """``M``'s entries for a nested (LU) solve: each in normal form where that is 0, where the
    entry has ``tan``, ``cot``, ``sec`` or ``csc``, or where it is no larger, so that no
    identically zero sum (``sin θ − cos θ tan θ``, a product of sums that cancels) is carried
    into the solution; else as it is (expanded, a product of sums grows, and the nested
    solution with it: 2.5× on random 4-coordinate systems)."""
    entries = list(M)
    out = [
        n if n == 0 or e.has(*_RECIPROCAL_TRIG) or sp.count_ops(n) <= sp.count_ops(e) else e
        for e, n in zip(entries, normal_all(entries))
    ]
    return sp.Matrix(M.rows, M.cols, out)


def normal_all(exprs: Sequence[sp.Expr]) -> list[sp.Expr]:
    """Each expression as one cancelled fraction in normal form modulo sin² + cos² = 1.

    An expression whose normal form would be too large (:class:`TooLarge`) stays as it is.
    """
    alg = Algebra(exprs)
    out = []
    for e in exprs:
        try:
            out.append(alg.to_expr(alg.reduce(alg.convert(e))))
        except (TooLarge, ZeroDivisionError):
            out.append(e)
    return out


#: the largest expression (in operations) given to ``sympy.simplify``; a larger one, already in
#: normal form, rarely gets shorter and may take minutes (the roller racer's: 460 operations, 7 s,
#: 1 % shorter)
SIMPLIFY_OPS = 150
#: seconds ``sympy.simplify`` may spend on one set of results before the rest are left as they are
SIMPLIFY_SECONDS = 3.0


def simplified(exprs: Sequence[sp.Expr]) -> tuple[list[sp.Expr], list[int]]:
    """Heavy simplification (``sympy.simplify``) within a budget, each result kept where shorter.

    Only expressions of at most :data:`SIMPLIFY_OPS` operations are simplified, and only until
    :data:`SIMPLIFY_SECONDS` have passed; the others stay in their (exact, cancelled) normal form.

    Returns
    -------
    (results, skipped) : the expressions, and the indices of those not simplified
    """
    start = time.monotonic()
    out, skipped = [], []
    for k, expr in enumerate(exprs):
        ops = sp.count_ops(expr)
        if ops > SIMPLIFY_OPS or time.monotonic() - start > SIMPLIFY_SECONDS:
            out.append(expr)
            skipped.append(k)
            continue
        candidate = sp.simplify(expr)
        tan_back = candidate.has(sp.tan, sp.cot, sp.sec, sp.csc)  # the normal form has none
        out.append(candidate if sp.count_ops(candidate) < ops and not tan_back else expr)
    return out, skipped
