"""Shared machinery of the two multiplier models (Chetaev and vakonomic).

Both models have n dynamic equations linear in the accelerations and in g
multiplier unknowns (``λ`` for Chetaev, ``μ̇`` for vakonomic), closed by the g
constraints.  The linear system ``M·x = F`` uses the constraints differentiated
once in time, ``A q̈ + Ȧ q̇ + Ȧ_0 = 0``; this module builds it, solves it
exactly by reduction, and computes constraint forces and their virtual work.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import sympy as sp
from sympy.polys.matrices import DomainMatrix

from chaplygin.core._fast import gradient, jacobian
from chaplygin.core._rational import Algebra, TooLarge, nested_inputs
from chaplygin.core._symbols import total_derivative
from chaplygin.errors import ModelError
from chaplygin.models.equations import Equations

if TYPE_CHECKING:
    from chaplygin.core.system import System

__all__ = ["lagrange_operator", "multiplier_equations", "multiplier_symbols"]


def lagrange_operator(system: System) -> list[sp.Expr]:
    """``E_s(T) = d/dt ∂T/∂q̇_s − ∂T/∂q_s`` for every coordinate (internal symbols)."""
    v = system._vars
    pairs = list(zip(v.x, v.xd)) + list(zip(v.xd, v.xdd))
    grad = gradient(system._T, [*v.xd, *v.x])
    n = system.n
    return [total_derivative(grad[s], pairs) - grad[n + s] for s in range(n)]


def multiplier_symbols(system: System, prefix: str) -> list[sp.Symbol]:
    """Fresh symbols ``prefix_1 … prefix_g`` for the multipliers."""
    taken = {q.func.__name__ for q in system.coordinates}
    names = [f"{prefix}_{b + 1}" for b in range(system.g)]
    return [sp.Dummy(n + ("_" if n in taken else "")) for n in names]


def _differentiated_constraints(system: System) -> sp.Matrix:
    """``Ȧ q̇ + Ȧ_0``: the velocity terms of the constraints differentiated in time (for constraints
    nonlinear in the velocities ``∂f/∂q q̇ + ∂f/∂t``, the rest of ``ḟ = A q̈ + …``)."""
    v = system._vars
    return system._f.applyfunc(lambda e: total_derivative(e, list(zip(v.x, v.xd))))


def multiplier_equations(
    system: System,
    model: str,
    dynamic: Sequence[sp.Expr],
    unknowns: Sequence[sp.Symbol],
    reactions: Sequence[sp.Expr],
    **extra: object,
) -> Equations:
    """Assemble the n + g equations of a multiplier model.

    Parameters
    ----------
    dynamic : n expressions ``E_s(T) − Q_s − R_s`` (linear in q̈ and in ``unknowns``).
    unknowns : the g multiplier unknowns (``λ`` or ``μ̇``).
    reactions : the generalized constraint forces ``R_s`` (``E_s(T) = Q_s + R_s``).
    extra : passed on to :class:`Equations`.
    """
    v = system._vars
    n, g = system.n, system.g
    xs = [*v.xdd, *unknowns]
    residuals = list(dynamic)
    residuals += list(system._f)
    dyn = sp.Matrix(list(dynamic))
    M = sp.zeros(n + g, n + g)
    F = sp.zeros(n + g, 1)
    M[:n, :] = jacobian(dyn, xs)
    F[:n, 0] = -dyn.xreplace({x: 0 for x in xs})
    if g:
        M[n:, :n] = system._A
        F[n:, 0] = -_differentiated_constraints(system)

    def solve() -> dict[sp.Symbol, sp.Expr]:
        try:
            return _solve_by_reduction(system, model, M, F, list(unknowns))
        except TooLarge:
            return _solve_nested(system, dyn, list(unknowns))

    return Equations(system, model, "classic", residuals, xs, M, F, solve, reactions=reactions, **extra)  # type: ignore[arg-type]


def _solve_by_reduction(
    system: System, model: str, M: sp.Matrix, F: sp.Matrix, unknowns: list[sp.Symbol]
) -> dict[sp.Symbol, sp.Expr]:
    """Solve ``M·x = F`` (:func:`multiplier_equations`) exactly, without inverting it.

    The differentiated constraints give the dependent accelerations,
    ``q̈_dep = B q̈_σ + c``; projecting the dynamic equations on the constraint
    distribution (``Cᵀ Aᵀ = 0`` removes the multiplier terms) leaves the reduced
    ε × ε system; the multiplier unknowns follow from the rows of the dependent
    coordinates.  This is the solution at every state, admissible or not.  All
    of it is exact arithmetic in one field of rational functions
    (:mod:`chaplygin.core._rational`).
    """
    v = system._vars
    n, g = system.n, system.g
    ind, dep = list(system._ind), list(system._dep)
    mass, react, force, drift = M[:n, :n], M[dep, n:], F[:n, :], F[n:, :]
    a_dep = system._A.extract(list(range(g)), dep)
    a_ind = system._A.extract(list(range(g)), ind)
    alg = Algebra([*mass, *react, *force, *a_dep, *(a_ind if system.is_nonlinear else system._B), *drift])
    # every quantity is a polynomial matrix over one denominator: X = Xn / dx
    Mn, dm = alg.matrix(mass)
    fn, df = alg.matrix(force)
    An, da = alg.matrix(a_dep)
    if system.is_nonlinear:  # B = −A_dep⁻¹ A_ind at every state (∂φ/∂q̇_σ only on the constraints)
        In, di = alg.matrix(-a_ind)
        Bn, db = alg.solve_den(An, In)
        Bn, db = Bn * da, db * di
    else:
        Bn, db = alg.matrix(system._B)
    Dn, dd = alg.matrix(drift)
    Rn, dr = alg.matrix(react)
    ring, dom = alg.ring, Mn.domain
    try:
        # A_dep q̈_dep + A_ind q̈_ind = drift  ⇒  q̈_dep = B q̈_ind + c,  c = cn / dc
        cn, dc = alg.solve_den(An, Dn)
        cn, dc = cn * da, dc * dd
        # q̈ = C q̈_ind + shift, with C = Cn / db = [I; B] and shift = Sn / dc = [0; c]
        rows_C = [[db if i == j else ring.zero for j in ind] for i in range(n)]
        rows_S = [[ring.zero] for _ in range(n)]
        for b, i in enumerate(dep):
            rows_C[i] = [Bn[b, k].element for k in range(len(ind))]
            rows_S[i] = [cn[b, 0].element]
        Cn = DomainMatrix(rows_C, (n, len(ind)), dom)
        Sn = DomainMatrix(rows_S, (n, 1), dom)
        # Cᵀ(M q̈ − f) = 0:  (Cnᵀ Mn Cn) q̈_ind = Cnᵀ (fn·dm·dc − df·Mn·Sn) · db / (df·dc)
        rn = fn * (dm * dc) - Mn * Sn * df
        yn, yd = alg.solve_den(Cn.transpose() * Mn * Cn, Cn.transpose() * rn)
        # q̈ = (Cn yn + Sn·yd·df) / (yd·df·dc)
        an, ad = Cn * yn + Sn * (yd * df), yd * df * dc
        acc = alg.fractions(an, ad)
        mult: list = []
        if g:
            # R λ = f_dep − M_dep q̈:  Rn λ = dr (fn_dep·dm·ad − df·Mn_dep·an) / (df·dm·ad)
            rest = fn.extract(dep, [0]) * (dm * ad) - Mn.extract(dep, list(range(n))) * an * df
            ln, ld = alg.solve_den(Rn, rest)
            mult = alg.fractions(ln * dr, ld * df * dm * ad)
    except ZeroDivisionError:
        raise ModelError(
            f"the {model} equations do not determine the accelerations: the mass matrix is singular."
        ) from None
    return dict(zip([*v.xdd, *unknowns], map(alg.to_expr, [*acc, *mult])))


def _solve_nested(system: System, dynamic: sp.Matrix, unknowns: list[sp.Symbol]) -> dict[sp.Symbol, sp.Expr]:
    """The reduction of :func:`_solve_by_reduction` by LU on SymPy expressions, unexpanded.

    For systems whose expanded normal forms are too large to read or to cancel
    (:class:`~chaplygin.core._rational.TooLarge`): the result is nested, like
    ``KanesMethod.rhs()``.
    """
    v = system._vars
    ind, dep, g = list(system._ind), list(system._dep), system.g
    ind_xdd = [v.xdd[i] for i in ind]
    acc_dep: dict[sp.Symbol, sp.Expr] = {}
    B, C = system._B, system._C
    if g:
        a_dep = nested_inputs(system._A.extract(list(range(g)), dep))
        if system.is_nonlinear:  # B = −A_dep⁻¹ A_ind at every state, as in _solve_by_reduction
            B = a_dep.LUsolve(-nested_inputs(system._A.extract(list(range(g)), ind)))
            C = sp.eye(system.n)[:, ind]
            for b, i in enumerate(dep):
                C[i, :] = B[b, :]
        c = a_dep.LUsolve(nested_inputs(-_differentiated_constraints(system)))
        acc_dep = {
            v.xdd[i]: sum((B[b, k] * a for k, a in enumerate(ind_xdd)), c[b]) for b, i in enumerate(dep)
        }
    projected = C.T * dynamic.xreplace({u: 0 for u in unknowns}).xreplace(acc_dep)
    Mr = nested_inputs(jacobian(projected, ind_xdd))
    out: dict[sp.Symbol, sp.Expr] = dict(
        zip(ind_xdd, Mr.LUsolve(nested_inputs(-projected.xreplace({a: 0 for a in ind_xdd}))))
    )
    out.update({a: e.xreplace(out) for a, e in acc_dep.items()})
    if g:
        rows = sp.Matrix([dynamic[i] for i in dep])
        rest = rows.xreplace({u: 0 for u in unknowns}).xreplace(out)
        out.update(zip(unknowns, nested_inputs(jacobian(rows, unknowns)).LUsolve(-rest)))
    return {a: out[a] for a in [*v.xdd, *unknowns]}
