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

from ._fast import gradient, jacobian
from ._symbols import total_derivative
from .equations import Equations, tidy

if TYPE_CHECKING:
    from .system import System

__all__ = ["lagrange_operator", "multiplier_symbols", "multiplier_equations", "virtual_work"]


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
    """``Ȧ q̇ + Ȧ_0``: the velocity terms of the constraints differentiated in time."""
    v = system._vars
    phi = system._A * sp.Matrix(v.xd) + system._A0
    return phi.applyfunc(lambda e: total_derivative(e, list(zip(v.x, v.xd))))


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
    residuals += list(system._A * sp.Matrix(v.xd) + system._A0) if g else []
    dyn = sp.Matrix(list(dynamic))
    M = sp.zeros(n + g, n + g)
    F = sp.zeros(n + g, 1)
    M[:n, :] = jacobian(dyn, xs)
    F[:n, 0] = -dyn.xreplace({x: 0 for x in xs})
    if g:
        M[n:, :n] = system._A
        F[n:, 0] = -_differentiated_constraints(system)

    def solve() -> dict[sp.Symbol, sp.Expr]:
        return _solve_by_reduction(system, dyn, list(unknowns))

    return Equations(system, model, "classic", residuals, xs, M, F, solve, reactions=reactions, **extra)  # type: ignore[arg-type]


def _solve_by_reduction(
    system: System, dynamic: sp.Matrix, unknowns: list[sp.Symbol]
) -> dict[sp.Symbol, sp.Expr]:
    """Solve ``M·x = F`` exactly, without inverting the (n+g) matrix.

    The differentiated constraints give the dependent accelerations,
    ``q̈ = C q̈_σ + c``; projecting the dynamic equations on the constraint
    distribution (``Cᵀ Aᵀ = 0`` removes the multiplier terms) leaves the reduced
    ε × ε system; the multiplier unknowns follow from the rows of the dependent
    coordinates.  This is the solution at every state, admissible or not.
    """
    v = system._vars
    ind, dep, g = system._ind, system._dep, system.g
    ind_xdd = [v.xdd[i] for i in ind]
    acc_dep: dict[sp.Symbol, sp.Expr] = {}
    if g:
        a_dep = system._A.extract(list(range(g)), list(dep))
        a_ind = system._A.extract(list(range(g)), list(ind))
        rhs = -(a_ind * sp.Matrix(ind_xdd) + _differentiated_constraints(system))
        acc_dep = dict(zip((v.xdd[i] for i in dep), a_dep.LUsolve(rhs)))
    base = dynamic.xreplace({u: 0 for u in unknowns}).xreplace(acc_dep)
    projected = system._C.T * base
    Mr = jacobian(projected, ind_xdd)
    Fr = -projected.xreplace({a: 0 for a in ind_xdd})
    sol = Mr.applyfunc(tidy).LUsolve(Fr.applyfunc(tidy)).applyfunc(tidy)
    out: dict[sp.Symbol, sp.Expr] = dict(zip(ind_xdd, sol))
    for a, expr in acc_dep.items():
        out[a] = tidy(expr.xreplace(out))
    if g:
        rows = sp.Matrix([dynamic[i] for i in dep])
        J = jacobian(rows, unknowns)
        rest = rows.xreplace({u: 0 for u in unknowns}).xreplace(acc_dep).xreplace(out)
        out.update(zip(unknowns, J.LUsolve(-rest).applyfunc(tidy)))
    return {a: out[a] for a in [*v.xdd, *unknowns]}


def virtual_displacements(system: System) -> list[sp.Symbol]:
    """Symbols ``δq_s`` for the virtual displacements, in coordinate order."""
    return [sp.Symbol("δ" + q.func.__name__) for q in system.coordinates]


def virtual_work(equations: Equations, *, chetaev_condition: bool = True) -> sp.Expr:
    """Virtual work ``Σ_s R_s δq_s`` of the constraint forces (internal symbols in, user out).

    With ``chetaev_condition=True`` the displacements obey Chetaev's condition
    (4), ``δq_{ε+β} = Σ_σ B_βσ δq_σ``, and the velocities the constraints
    (the state is admissible); the result is collected in the independent
    ``δq_σ``.
    """
    s = equations.system
    dq = virtual_displacements(s)
    reactions = equations._require_reactions("virtual_work")
    work: sp.Expr = sp.Add(*(r * d for r, d in zip(reactions, dq)))
    if chetaev_condition:
        ind = [dq[i] for i in s._ind]
        cond = {
            dq[i]: sum((s._B[b, k] * ind[k] for k in range(len(ind))), sp.S.Zero)
            for b, i in enumerate(s._dep)
        }
        work = sp.expand(work.xreplace(cond).xreplace(s._velocity_substitution))
        work = sp.Add(*[tidy(work.coeff(d)) * d for d in ind])
    return equations._user(work)
