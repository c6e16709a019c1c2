"""Chetaev (Lagrange–d'Alembert) model: the true motion of a system with ideal constraints.

With form-A constraints ``Σ_s A_βs q̇_s + A_β0 = 0`` (eq. (1)) and Chetaev's
condition on virtual displacements ``Σ_s A_βs δq_s = 0`` (eq. (4)), the
equations with multipliers (eq. (6)/(35)) are::

    E_s(T) − Q_s = R_s ,     R_s = Σ_β λ_β A_βs ,     Σ_s A_βs q̇_s + A_β0 = 0

with ``E_s(F) = d/dt ∂F/∂q̇_s − ∂F/∂q_s``.

Sign convention
---------------
``R_s`` is the generalized *reaction force* acting on the system: it stands on
the right-hand side beside the applied forces, ``E_s(T) = Q_s + R_s``.  The
paper's ``R`` of eq. (7) is the opposite (``R^paper = −R``): it moves the
reaction to the left side.  The multipliers agree with the paper's for form-B
constraints (``A_{β,ε+β} = 1``, ``A_βσ = −B_βσ``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import sympy as sp

from ._symbols import total_derivative
from .equations import Equations, tidy

if TYPE_CHECKING:
    from .system import System

__all__ = ["chetaev_equations", "constraint_forces", "virtual_work"]


def lagrange_operator(system: System) -> list[sp.Expr]:
    """``E_s(T) = d/dt ∂T/∂q̇_s − ∂T/∂q_s`` for every coordinate (internal symbols)."""
    v = system._vars
    pairs = list(zip(v.x, v.xd)) + list(zip(v.xd, v.xdd))
    return [
        total_derivative(sp.diff(system._T, xd), pairs) - sp.diff(system._T, x)
        for x, xd in zip(v.x, v.xd)
    ]


def multiplier_symbols(system: System, prefix: str) -> list[sp.Symbol]:
    """Fresh symbols ``prefix_1 … prefix_g`` for the multipliers."""
    taken = {q.func.__name__ for q in system.coordinates}
    names = [f"{prefix}_{b + 1}" for b in range(system.g)]
    return [sp.Dummy(n + ("_" if n in taken else "")) for n in names]


def chetaev_equations(system: System) -> Equations:
    """The n + g equations of the Chetaev model, eq. (6)/(35).

    Unknowns are ``(q̈_1 … q̈_n, λ_1 … λ_g)``.  The residuals shown are the n
    dynamic equations and the g velocity constraints; the linear system
    ``M·x = F`` uses the constraints differentiated once in time::

        [ M   −Aᵀ ] [q̈]   [ Q − E(T)|_{q̈=0} ]
        [ A    0  ] [λ ] = [ −Ȧ q̇ − Ȧ_0      ]
    """
    v = system._vars
    n, g = system.n, system.g
    lam = multiplier_symbols(system, "lambda")
    E = lagrange_operator(system)
    A, A0 = system._A, system._A0
    residuals = [
        E[s] - system._Q[s] - sum((lam[b] * A[b, s] for b in range(g)), sp.S.Zero)
        for s in range(n)
    ]
    xd = sp.Matrix(v.xd)
    residuals += list(A * xd + A0) if g else []

    zero_acc = {a: 0 for a in v.xdd}
    M = sp.zeros(n + g, n + g)
    M[:n, :n] = system._M
    F = sp.zeros(n + g, 1)
    for s in range(n):
        F[s] = system._Q[s] - E[s].xreplace(zero_acc)
    if g:
        M[:n, n:] = -A.T
        M[n:, :n] = A
        pairs = list(zip(v.x, v.xd))
        adot = (A * xd + A0).applyfunc(lambda e: total_derivative(e, pairs))
        F[n:, 0] = -adot

    def solve() -> dict[sp.Symbol, sp.Expr]:
        return _solve_by_reduction(system, E, lam)

    return Equations(
        system, "chetaev", "classic", residuals, [*v.xdd, *lam], M, F, solve, multipliers=lam
    )


def _solve_by_reduction(
    system: System, E: list[sp.Expr], lam: list[sp.Symbol]
) -> dict[sp.Symbol, sp.Expr]:
    """Solve the multiplier system exactly, without inverting the (n+g) matrix.

    The differentiated constraints give ``q̈ = C q̈_σ + c``; projecting the
    dynamic equations on the constraint distribution (``Cᵀ(E − Q) = 0``) leaves
    the reduced ε × ε system; the multipliers follow from the rows of the
    dependent coordinates, ``A_depᵀ λ = (E − Q)_dep``.  Valid at every state
    ``(q, q̇)``, admissible or not.
    """
    v = system._vars
    ind, dep = system._ind, system._dep
    pairs = list(zip(v.x, v.xd)) + [(v.xd[i], v.xdd[i]) for i in ind]
    ind_xd = sp.Matrix([v.xd[i] for i in ind])
    dep_rhs = system._B * ind_xd + system._B0 if system.g else sp.zeros(0, 1)
    acc_dep = {v.xdd[i]: total_derivative(dep_rhs[b], pairs) for b, i in enumerate(dep)}
    residual = sp.Matrix([E[s] - system._Q[s] for s in range(system.n)]).xreplace(acc_dep)
    projected = system._C.T * residual
    ind_xdd = [v.xdd[i] for i in ind]
    Mr = projected.jacobian(ind_xdd)
    Fr = -projected.xreplace({a: 0 for a in ind_xdd})
    sol = Mr.LUsolve(Fr).applyfunc(tidy)
    out: dict[sp.Symbol, sp.Expr] = dict(zip(ind_xdd, sol))
    for a, expr in acc_dep.items():
        out[a] = tidy(expr.xreplace(out))
    if system.g:
        rows = sp.Matrix([residual[i] for i in dep]).xreplace(out)
        a_dep = system._A.extract(list(range(system.g)), list(dep))
        lam_sol = a_dep.T.LUsolve(rows)
        out.update({lam[b]: tidy(lam_sol[b]) for b in range(system.g)})
    return {a: out[a] for a in [*v.xdd, *lam]}


def constraint_forces(equations: Equations) -> dict[sp.Expr, sp.Expr]:
    """Generalized constraint (reaction) forces ``R_s = Σ_β λ_β A_βs``, eq. (7).

    Sign convention: ``E_s(T) = Q_s + R_s`` (the paper's R of eq. (7) is ``−R_s``).
    """
    s = equations.system
    lam = equations._multipliers
    return {
        q: equations._user(sum((lam[b] * s._A[b, k] for b in range(s.g)), sp.S.Zero))
        for k, q in enumerate(s.coordinates)
    }


def virtual_displacements(system: System) -> list[sp.Symbol]:
    """Symbols ``δq_s`` for the virtual displacements, in coordinate order."""
    return [sp.Symbol("δ" + q.func.__name__) for q in system.coordinates]


def virtual_work(equations: Equations, *, chetaev_condition: bool = True) -> sp.Expr:
    """Virtual work ``Σ_s R_s δq_s`` of the constraint forces, eqs. (8)-(9).

    With ``chetaev_condition=True`` the dependent displacements obey Chetaev's
    condition (4), ``δq_{ε+β} = Σ_σ B_βσ δq_σ``, and the result simplifies to 0:
    the constraints are ideal.  With ``False`` the general expression is returned.
    """
    s = equations.system
    dq = virtual_displacements(s)
    forces = constraint_forces(equations)
    work = sum((forces[q] * d for q, d in zip(s.coordinates, dq)), sp.S.Zero)
    if not chetaev_condition:
        return work
    ind = [dq[i] for i in s._ind]
    cond = {dq[i]: sum((s.B[b, k] * ind[k] for k in range(len(ind))), sp.S.Zero) for b, i in enumerate(s._dep)}
    work = sp.expand(work.xreplace(cond))
    return sp.Add(*[sp.cancel(c) * d for d, c in zip(ind, (work.coeff(d) for d in ind))])
