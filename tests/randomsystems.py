"""Hypothesis strategies for random mechanical systems, and a plain numeric evaluator.

The evaluator puts numbers for the *public* dynamicsymbol expressions (``q``, ``q'``,
``q''``) and computes the expression with Python floats, one pass over its tree: it shares no
code with chaplygin's compiled sampling, so tests built on it are independent oracles.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import sympy as sp
from hypothesis import strategies as st
from sympy.physics.mechanics import dynamicsymbols

from chaplygin import System
from chaplygin.errors import SystemDefinitionError

t = dynamicsymbols._t
k_param = sp.Symbol("k", positive=True)


class Choices(Protocol):
    """The random choices a system is built from: Hypothesis' draws (:func:`systems`) or a
    seeded NumPy generator (:func:`seeded_system`)."""

    def integer(self, lo: int, hi: int) -> int: ...
    def boolean(self) -> bool: ...
    def choice(self, items: Sequence[Any]) -> Any: ...
    def permutation(self, n: int) -> list[int]: ...
    def coefficient(self) -> sp.Expr: ...


class _Drawn:
    """Choices drawn by Hypothesis (the draws :func:`systems` has always made, in that order)."""

    def __init__(self, draw: st.DrawFn) -> None:
        self.draw = draw

    def integer(self, lo: int, hi: int) -> int:
        return self.draw(st.integers(lo, hi))

    def boolean(self) -> bool:
        return self.draw(st.booleans())

    def choice(self, items: Sequence[Any]) -> Any:
        return self.draw(st.sampled_from(items))

    def permutation(self, n: int) -> list[int]:
        return self.draw(st.permutations(range(n)))

    def coefficient(self) -> sp.Expr:
        return sp.Integer(self.draw(st.integers(-2, 2).filter(bool)))


def decimal(rng: np.random.Generator, lo: float = 1e-3, hi: float = 1e3) -> sp.Rational:
    """A random number of 15 to 17 significant digits and magnitude between ``lo`` and ``hi``
    (log-uniform), as the exact rational of its decimal digits (as ``nsimplify`` makes of a
    float, and a system file of a decimal literal): numerators and denominators beyond 2**53."""
    digits = int(rng.integers(15, 18))
    value = 10 ** rng.uniform(np.log10(lo), np.log10(hi))
    return sp.Rational(f"{value:.{digits}g}")


class _Seeded:
    """Choices from a seeded NumPy generator; with ``floats``, coefficients of 15–17 significant
    digits and magnitudes in ``scale`` (:func:`decimal`, either sign) instead of ±1, ±2."""

    def __init__(self, rng: np.random.Generator, floats: bool, scale: tuple[float, float]) -> None:
        self.rng, self.floats, self.scale = rng, floats, scale

    def integer(self, lo: int, hi: int) -> int:
        return int(self.rng.integers(lo, hi + 1))

    def boolean(self) -> bool:
        return bool(self.rng.integers(2))

    def choice(self, items: Sequence[Any]) -> Any:
        return items[int(self.rng.integers(len(items)))]

    def permutation(self, n: int) -> list[int]:
        return [int(i) for i in self.rng.permutation(n)]

    def coefficient(self) -> sp.Expr:
        sign = self.choice([-1, 1])
        return sign * decimal(self.rng, *self.scale) if self.floats else sp.Integer(sign * self.integer(1, 2))


def _atom(choose: Choices, variables: list[sp.Expr]) -> sp.Expr:
    v = choose.choice(variables)
    kind = choose.integer(0, 5)
    return [sp.S.One, v, sp.sin(v), sp.cos(v), v**2, k_param * v][kind]


def _expr(choose: Choices, variables: list[sp.Expr], terms: int = 2) -> sp.Expr:
    out = sp.S.Zero
    for _ in range(choose.integer(1, terms)):
        out += choose.coefficient() * _atom(choose, variables) * _atom(choose, variables)
    return out


@dataclass
class Spec:
    """A random system and how it was made."""

    system: System
    chaplygin: bool
    affine: bool
    timed: bool


@st.composite
def systems(
    draw: st.DrawFn,
    *,
    chaplygin: bool | None = None,
    affine: bool | None = None,
    forces: bool | None = None,
    gyroscopic: bool | None = None,
    integrable: bool = False,
    dependent_forces: bool = True,
) -> Spec:
    """Random system: positive-definite configuration-dependent T, random constraints.

    ``chaplygin=True`` keeps T, U, forces and B free of the dependent
    coordinates; ``False`` lets them depend on them (Voronets' case).
    ``integrable=True`` makes each row of B the gradient of a random potential
    (so condition (28) holds); ``dependent_forces=False`` keeps non-potential
    forces off the dependent coordinates.
    """
    return _system(
        _Drawn(draw),
        chaplygin=chaplygin,
        affine=affine,
        forces=forces,
        gyroscopic=gyroscopic,
        integrable=integrable,
        dependent_forces=dependent_forces,
    )


def seeded_system(
    seed: int,
    *,
    floats: bool = False,
    scale: tuple[float, float] = (1e-3, 1e3),
    timed: bool | None = None,
    **options: Any,
) -> Spec:
    """The random system of ``seed`` (NumPy's generator), with :func:`systems`' ``options``;
    ``floats``: coefficients of 15–17 significant digits and magnitudes in ``scale`` (exact
    rationals, see :func:`decimal`); ``timed=True``: affine constraints that depend on time.
    For tests that build a few fixed systems once (a module-scoped fixture), not many."""
    return _system(_Seeded(np.random.default_rng(seed), floats, scale), timed=timed, **options)


def _system(
    choose: Choices,
    *,
    chaplygin: bool | None = None,
    affine: bool | None = None,
    forces: bool | None = None,
    gyroscopic: bool | None = None,
    integrable: bool = False,
    dependent_forces: bool = True,
    timed: bool | None = None,
) -> Spec:
    n = choose.integer(2, 4)
    g = choose.integer(1, min(2, n - 1))
    q = list(dynamicsymbols(f"q1:{n + 1}"))
    dep_idx = sorted(choose.permutation(n)[:g])
    dep = [q[i] for i in dep_idx]
    ind = [qi for qi in q if qi not in dep]
    is_chap = choose.boolean() if chaplygin is None else chaplygin
    is_affine = (choose.boolean() if affine is None else affine) or bool(timed)
    coeff_vars = ind if is_chap else q

    # T = ½ q̇ᵀ (D + L Lᵀ) q̇ (+ b·q̇): positive definite for every configuration.
    L = sp.Matrix(n, n, lambda i, j: _expr(choose, coeff_vars, 1) if choose.boolean() else 0)
    D = sp.diag(*[2 + sp.sin(choose.choice(coeff_vars)) for _ in range(n)])
    qd = [qi.diff(t) for qi in q]
    K = D + L * L.T
    # qd.T * K * qd written out: the same expression, without SymPy's matrix product (30 ms a system)
    T = sp.Add(*[sp.Add(*[qd[i] * K[i, j] for i in range(n)]) * qd[j] for j in range(n)]) / 2
    if gyroscopic or (gyroscopic is None and choose.boolean()):
        T += sum(_expr(choose, coeff_vars, 1) * v for v in qd)

    if integrable:
        potentials = [_expr(choose, ind, 3) for _ in dep]
        B = [[sp.diff(f, qi) for qi in ind] for f in potentials]
    else:
        B = [[_expr(choose, coeff_vars) for _ in ind] for _ in dep]
    is_timed = False
    constraints: dict[sp.Expr, sp.Expr] = {}
    for b, d in enumerate(dep):
        rhs = sum(B[b][s] * ind[s].diff(t) for s in range(len(ind)))
        if is_affine:
            b0 = _expr(choose, coeff_vars, 1)
            if timed or (timed is None and choose.boolean()):
                b0 *= sp.cos(t)
                is_timed = True
            rhs += b0
        constraints[d.diff(t)] = rhs

    U = _expr(choose, coeff_vars) if choose.boolean() else None
    Q = None
    if forces or (forces is None and choose.boolean()):
        s = choose.choice(q if dependent_forces else ind)
        Q = {s: -k_param * s.diff(t) + _expr(choose, coeff_vars, 1)}

    if choose.boolean():
        # Form A: multiply the solved constraints by an invertible configuration-dependent factor.
        exprs = [(2 + sp.cos(choose.choice(q))) * (d - rhs) for d, rhs in constraints.items()]
        system = System(q, T, exprs, dependent=dep, force_function=U, forces=Q, name="random")
    else:
        system = System(q, T, constraints, force_function=U, forces=Q, name="random")
    return Spec(system, is_chap, is_affine, is_timed)


# ------------------------------------------------------------------ numeric oracle
def random_state(system: System, rng: np.random.Generator) -> dict[sp.Expr, sp.Expr]:
    """Random ``t``, parameters, coordinates and independent velocities; dependent
    velocities from the constraints (form B as reported by the system); drawn again where
    constraints nonlinear in the velocities give no real dependent velocity."""
    for _ in range(100):
        values: dict[sp.Expr, sp.Expr] = {t: sp.Float(rng.uniform(0.2, 1.2))}
        values.update({p: sp.Float(rng.uniform(0.5, 1.5)) for p in system.parameters})
        values.update({q: sp.Float(rng.uniform(0.2, 1.2)) for q in system.coordinates})
        values.update({q.diff(t): sp.Float(rng.uniform(-1, 1)) for q in system.independent})
        try:
            for vel, rhs in system.constraints.items():
                values[vel] = sp.Float(number(rhs, values))
        except TypeError:  # a root of a negative number: outside the constraints' real domain
            if not system.is_nonlinear:
                raise
            continue
        return values
    raise AssertionError(f"no real admissible state of {system.name} in 100 draws")


_FLOAT_FUNCTIONS = {
    sp.sin: math.sin,
    sp.cos: math.cos,
    sp.tan: math.tan,
    sp.exp: math.exp,
    sp.log: math.log,
    sp.sinh: math.sinh,
    sp.cosh: math.cosh,
    sp.tanh: math.tanh,
    sp.atan: math.atan,
}


def numbers(exprs: Iterable[sp.Expr], values: dict[sp.Expr, sp.Expr]) -> list[float]:
    """Each of ``exprs`` at ``values``, in floats.

    A node that is a key of ``values`` takes its value (so ``q'(t)`` is matched before the
    ``q(t)`` inside it); numbers, sums, products, powers and the functions above are computed
    with Python floats, anything else by SymPy (``xreplace`` + ``evalf``). A subexpression met
    again, in one expression or another, is looked up, not recomputed: the derived equations
    are trees with many repeated subtrees, where ``xreplace`` + ``evalf`` takes seconds.
    """
    memo: dict[sp.Expr, float] = {key: float(value) for key, value in values.items()}

    def value(e: sp.Expr) -> float:
        if e in memo:
            return memo[e]
        if e.is_Number:
            out = float(e)
        elif e.is_Add:
            out = math.fsum(value(a) for a in e.args)
        elif e.is_Mul:
            out = math.prod(value(a) for a in e.args)
        elif e.is_Pow:
            out = value(e.base) ** value(e.exp)
        elif e.func in _FLOAT_FUNCTIONS:
            out = _FLOAT_FUNCTIONS[e.func](*(value(a) for a in e.args))
        else:
            out = float(sp.N(e.xreplace(values)))
        if not isinstance(out, float):  # a complex power
            raise TypeError(f"{e} is not real at these values")
        memo[e] = out
        return out

    return [value(sp.sympify(e)) for e in exprs]


def number(expr: sp.Expr, values: dict[sp.Expr, sp.Expr]) -> float:
    """``expr`` at ``values`` (see :func:`numbers`)."""
    return numbers([expr], values)[0]


def matrix(m: sp.Matrix, values: dict[sp.Expr, sp.Expr]) -> np.ndarray:
    return np.array(numbers(m, values), dtype=float).reshape(m.shape)


# ------------------------------------------------------------------ nonlinear constraints (issue 30)
#: the kinds of constraints nonlinear in the velocities that :func:`nonlinear_system` draws
NONLINEAR_KINDS = ("root", "quadratic", "polynomial", "rational")


@dataclass
class NonlinearSpec:
    """A random system with constraints nonlinear in the velocities, and how it was made.

    ``f``: the constraints as the test wrote them, ``f_β(q, q̇, t) = 0`` (dynamicsymbols; for a
    solved one ``q̇_dep − φ``); ``phi``: the solution ``{q̇_dep: φ}`` the system was built for
    (the branch chosen); ``homogeneous``: every φ homogeneous of degree one in the velocities
    (the constraint forces then do no work).
    """

    system: System
    kinds: list[str]
    implicit: bool
    chaplygin: bool
    homogeneous: bool
    timed: bool
    f: list[sp.Expr]
    phi: dict[sp.Expr, sp.Expr]


def _linear_form(
    choose: Choices, coeff_vars: list[sp.Expr], velocities: list[sp.Expr], first: int
) -> sp.Expr:
    """``Σ_σ c_σ(q) q̇_σ`` with random configuration-dependent coefficients: that of
    ``velocities[first]`` never zero, the others zero in a quarter of the draws."""
    out = sp.S.Zero
    for k, v in enumerate(velocities):
        if k == first or choose.integer(0, 3):
            out += _expr(choose, coeff_vars, 1) * v
    return out


def nonlinear_system(
    seed: int,
    *,
    kinds: Sequence[str] | None = None,
    implicit: bool | None = None,
    chaplygin: bool | None = None,
    homogeneous: bool | None = None,
    floats: bool = False,
    timed: bool | None = None,
    g: int | None = None,
) -> NonlinearSpec:
    """The random system of ``seed`` with constraints nonlinear in the velocities.

    T as in :func:`systems` (``½ q̇ᵀ(D + L Lᵀ)q̇``, off-diagonal and configuration-dependent, a
    gyroscopic term in some); ``g`` (1 or 2) dependent velocities, each of one kind:

    * ``"root"``: ``q̇_d² = ℓ₁² + ℓ₂² (+ P)``, ℓ_j linear forms in the independent velocities
      with coefficients in q (ℓ_j has the j-th: √ of a square is not analytic), P > 0
      velocity-free; φ = ±√(…), real everywhere;
    * ``"quadratic"``: ``q̇_d² + ℓ₁ q̇_d − ℓ₂² (− P) = 0``, φ = (−ℓ₁ ± √(ℓ₁² + 4ℓ₂² (+ 4P)))/2;
    * ``"polynomial"``: ``q̇_d = ℓ + c(q) q̇_σ q̇_τ + b(q)`` (never homogeneous);
    * ``"rational"``: ``q̇_d (1 + q̇_σ²) = ℓ (+ b(q))`` (never homogeneous).

    ``homogeneous`` (by default: even seeds) drops the velocity-free terms (P, b) of the first
    two kinds and draws only those, with two independent velocities (n = 3, g = 1 or n = 4,
    g = 2); the first constraint's kind is the next in turn every second seed; ``implicit`` gives the constraints as ``f = 0`` (times a factor ``2 + cos q`` that
    vanishes nowhere) with ``dependent=`` and the branch, else solved; ``chaplygin`` keeps
    everything free of the dependent coordinates; ``timed`` puts ``t`` in the constraints;
    ``floats``: coefficients of 15–17 significant digits (:func:`decimal`).
    """
    choose = _Seeded(np.random.default_rng(seed), floats, (0.1, 10.0))
    is_homog = seed % 2 == 0 if homogeneous is None else homogeneous
    # (φ homogeneous of degree one and not linear needs two independent velocities at least)
    n = choose.integer(3, 4) if is_homog else choose.integer(2, 3)
    g = g or (n - 2 if is_homog else choose.integer(1, min(2, n - 1)))
    q = list(dynamicsymbols(f"q1:{n + 1}"))
    dep_idx = sorted(choose.permutation(n)[:g])
    dep = [q[i] for i in dep_idx]
    ind = [qi for qi in q if qi not in dep]
    is_chap = choose.boolean() if chaplygin is None else chaplygin
    is_implicit = choose.boolean() if implicit is None else implicit
    is_timed = choose.boolean() if timed is None else timed
    coeff_vars = ind if is_chap else q
    qd = [qi.diff(t) for qi in q]
    ind_qd = [qi.diff(t) for qi in ind]

    L = sp.Matrix(n, n, lambda i, j: _expr(choose, coeff_vars, 1) if choose.boolean() else 0)
    D = sp.diag(*[2 + sp.sin(choose.choice(coeff_vars)) for _ in range(n)])
    K = D + L * L.T
    T = sp.Add(*[sp.Add(*[qd[i] * K[i, j] for i in range(n)]) * qd[j] for j in range(n)]) / 2
    if choose.boolean():
        T += sum(_expr(choose, coeff_vars, 1) * v for v in qd)

    timing = (2 + sp.sin(t)) if is_timed else sp.S.One
    pool = ("root", "quadratic") if is_homog else NONLINEAR_KINDS
    # (the first kind in turn: eight consecutive seeds draw every kind)
    pool = tuple(kinds or pool)
    drawn = [pool[(seed // 2) % len(pool)], *(choose.choice(pool) for _ in dep[1:])]
    f: list[sp.Expr] = []
    phi: dict[sp.Expr, sp.Expr] = {}
    for d, kind in zip(dep, drawn):
        v = d.diff(t)
        ell = [_linear_form(choose, coeff_vars, ind_qd, j % len(ind_qd)) for j in range(2)]
        positive = 0 if is_homog else (1 + _expr(choose, coeff_vars, 1) ** 2) * timing
        sign = choose.choice([-1, 1])
        if kind == "root":
            radicand = timing * ell[0] ** 2 + ell[1] ** 2 + positive
            fb, solution = v**2 - radicand, sign * sp.sqrt(radicand)
        elif kind == "quadratic":
            radicand = ell[0] ** 2 + 4 * timing * ell[1] ** 2 + 4 * positive
            fb, solution = (
                v**2 + ell[0] * v - timing * ell[1] ** 2 - positive,
                (-ell[0] + sign * sp.sqrt(radicand)) / 2,
            )
        elif kind == "polynomial":
            s1, s2 = choose.choice(ind_qd), choose.choice(ind_qd)
            b = _expr(choose, coeff_vars, 1) * timing
            solution = ell[0] + _expr(choose, coeff_vars, 1) * s1 * s2 + b
            fb = v - solution
        elif kind == "rational":
            s1 = choose.choice(ind_qd)
            b = _expr(choose, coeff_vars, 1) * timing
            fb, solution = v * (1 + s1**2) - ell[0] - b, (ell[0] + b) / (1 + s1**2)
        else:
            raise ValueError(f"unknown kind {kind!r}; one of {NONLINEAR_KINDS}")
        f.append(fb)
        phi[v] = solution

    U = _expr(choose, coeff_vars) if choose.boolean() else None
    Q = {choose.choice(ind): -k_param * choose.choice(ind).diff(t)} if choose.boolean() else None
    if is_implicit:
        f = [(2 + sp.cos(choose.choice(coeff_vars))) * fb for fb in f]
        system = with_branch(q, T, f, dep, phi, force_function=U, forces=Q, name="random nonlinear")
    else:
        f = [v - e for v, e in phi.items()]
        system = System(q, T, phi, force_function=U, forces=Q, name="random nonlinear")
    return NonlinearSpec(system, drawn, is_implicit, is_chap, is_homog, is_timed, f, phi)


def with_branch(
    coordinates: list[sp.Expr],
    T: sp.Expr,
    f: list[sp.Expr],
    dependent: list[sp.Expr],
    phi: dict[sp.Expr, sp.Expr],
    *,
    first: int | None = 0,
    **options: Any,
) -> System:
    """``System(coordinates, T, f, dependent=…)`` with the branch whose solved form is ``phi``
    (compared numerically at a random point: SymPy may write a root another way), trying
    ``first`` first."""
    rng = np.random.default_rng(1)
    point: dict[sp.Expr, sp.Expr] = {t: sp.Float(rng.uniform(0.2, 1.2))}
    point.update({qi: sp.Float(rng.uniform(0.2, 1.2)) for qi in coordinates})
    point.update({qi.diff(t): sp.Float(rng.uniform(-1, 1)) for qi in coordinates})
    point[k_param] = sp.Float(0.75)
    wanted = numbers(phi.values(), point)
    first = first or 0
    for branch in [first, *(b for b in range(4) if b != first)]:  # (branch=0 where there is one)
        try:
            system = System(coordinates, T, f, dependent=dependent, branch=branch, **options)
        except SystemDefinitionError:
            continue
        got = numbers([system.constraints[v] for v in phi], point)
        if np.allclose(got, wanted, rtol=1e-9, atol=1e-12):
            return system
    raise AssertionError(f"no branch of {f} gives {phi}")
