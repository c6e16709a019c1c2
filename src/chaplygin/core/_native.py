"""The Chetaev model's ``M·x = F`` derived in SymEngine, for generated code.

:func:`chetaev_equations` derives the equations the user reads in SymPy; code
generation needs only the numbers, and deriving them in SymEngine end to end
(no conversion back, no SymPy assumption queries) derives and generates a
chain of nine sleighs in about 0.06 s, where the SymPy route took 0.5 s.  The system enters
as SymEngine expressions once (:class:`Native`, cached on the system) and
:func:`chetaev_matrices` returns exactly the matrices of
:func:`chaplygin.models.multipliers.multiplier_equations` for the Chetaev model,
unknowns ``[q̈_1 … q̈_n, λ_1 … λ_g]`` (eq. (6)/(35))::

    [ H   −Aᵀ ] [q̈]   [ Q − Σ_j ∂p/∂q_j q̇_j − ∂p/∂t + ∂T/∂q ]
    [ A    0  ] [λ ] = [ −Ȧ q̇ − Ȧ_0                          ]

with ``p = ∂T/∂q̇`` and ``H = ∂p/∂q̇``.  Systems SymEngine cannot represent
give ``None`` and the SymPy derivation is used.  ``tests/test_native.py``
checks the matrices against the SymPy ones on random systems.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import symengine as se

from chaplygin.core._fast import native
from chaplygin.core._symbols import TIME

if TYPE_CHECKING:
    from chaplygin.core.system import System

__all__ = [
    "Native",
    "chetaev_matrices",
    "is_quadratic",
    "linear_split",
    "load",
    "momenta",
    "vanishes_at_rest",
]


@dataclass(frozen=True)
class Native:
    """A system's data as SymEngine expressions (internal symbols).

    ``A`` is g × n (rows of the constraint matrix), ``Q`` the total
    generalized forces ``∂U/∂q_s + Q_s^{np}``.
    """

    t: Any
    x: list[Any]
    xd: list[Any]
    T: Any
    U: Any
    Q: list[Any]
    A: list[list[Any]]
    A0: list[Any]
    p: list[Any]
    H: list[list[Any]]


def momenta(T: Any, xd: list[Any]) -> tuple[list[Any], list[list[Any]]]:
    """The momenta ``p_s = ∂T/∂q̇_s`` and the mass matrix ``H_sj = ∂p_s/∂q̇_j`` (rows)."""
    p = [T.diff(v) for v in xd]
    return p, [[ps.diff(v) for v in xd] for ps in p]


def load(system: System) -> Native | None:
    """The system as SymEngine expressions, or None where SymEngine cannot represent it.

    T, the velocities and the momenta are the system's own (:attr:`System._native_T`,
    computed once for the check of T); the rest is converted here.
    """
    if system._native_T is None:
        return None
    v, n, g = system._vars, system.n, system.g
    split = system.__dict__.get("_native_A")  # form A, read in SymEngine
    A, A0 = split if split is not None else (system._A.tolist(), list(system._A0))
    fast = native([TIME, *v.x, system._U, *system._Qnp, *(a for row in A for a in row), *A0])
    if fast is None:
        return None
    t, x, U, rest = fast[0], fast[1 : 1 + n], fast[1 + n], fast[2 + n :]
    Q = [U.diff(xs) + q for xs, q in zip(x, rest[:n])]
    rows = [rest[n + b * n : n + (b + 1) * n] for b in range(g)]
    return Native(
        t, x, system._native_xd, system._native_T, U, Q, rows, rest[n + g * n :], *system._native_momenta
    )


def _total_derivative(e: Any, nat: Native) -> Any:
    """``∂e/∂t + Σ_j ∂e/∂q_j q̇_j`` (``e`` free of accelerations)."""
    return e.diff(nat.t) + sum((e.diff(x) * xd for x, xd in zip(nat.x, nat.xd)), se.Integer(0))


def chetaev_matrices(nat: Native) -> tuple[list[list[Any]], list[Any]]:
    """``(M, F)`` of the Chetaev model, eq. (6): M as rows, unknowns ``[q̈, λ]``."""
    n, g = len(nat.x), len(nat.A)
    M = [nat.H[s] + [-nat.A[b][s] for b in range(g)] for s in range(n)]
    M += [list(nat.A[b]) + [se.Integer(0)] * g for b in range(g)]
    F = [nat.Q[s] - _total_derivative(nat.p[s], nat) + nat.T.diff(nat.x[s]) for s in range(n)]
    phi = [sum((a * xd for a, xd in zip(nat.A[b], nat.xd)), nat.A0[b]) for b in range(g)]
    F += [-_total_derivative(e, nat) for e in phi]
    return M, F


def is_quadratic(T: Any, xd: list[Any], p: list[Any], H: list[list[Any]]) -> tuple[bool, bool] | None:
    """``(True, has a quadratic term)`` where ``T`` is shown a polynomial of degree ≤ 2 in ``xd``.

    ``p`` and ``H`` are :func:`momenta` of ``T``.  It is one when its Hessian
    ``H`` is free of ``xd`` and its second-order Taylor polynomial about
    ``xd = 0`` expands to ``T`` itself.  None where this does not show it
    (SymPy's ``Poly`` then decides, and explains a refusal).
    """
    zero = {v: se.Integer(0) for v in xd}
    speeds = set(xd)
    if any(h.free_symbols & speeds for row in H for h in row):
        return None
    taylor = T.xreplace(zero) + sum((pi.xreplace(zero) * v for pi, v in zip(p, xd)), se.Integer(0))
    taylor += (
        sum((H[i][j] * xd[i] * xd[j] for i in range(len(xd)) for j in range(len(xd))), se.Integer(0)) / 2
    )
    if se.expand(T - taylor) != 0:
        return None
    return True, any(h != 0 for row in H for h in row)


def vanishes_at_rest(T: Any, xd: list[Any], p: list[Any]) -> bool:
    """Whether ``T`` and its momenta ``p`` (:func:`momenta`) expand to 0 at ``xd = 0``: then a
    ``T`` of degree ≤ 2 in ``xd`` (:func:`is_quadratic`) is a homogeneous quadratic form (no
    ``T₁``, no ``T₀``).  False where the expansion does not show it."""
    zero = {v: se.Integer(0) for v in xd}
    return all(se.expand(e.xreplace(zero)) == 0 for e in [T, *p])


def linear_split(e: Any, xd: list[Any]) -> tuple[list[Any], Any] | None:
    """``e = Σ c_i q̇_i + c_0`` with the ``c`` free of ``xd`` (SymEngine), or None if ``e`` is not affine.

    The SymEngine counterpart of :func:`chaplygin.core._symbols.linear_coefficients`
    (which also factors the coefficients; :attr:`System._A` does that on conversion).
    """
    speeds = set(xd)
    coeffs = [e.diff(v) for v in xd]
    if any(c.free_symbols & speeds for c in coeffs):
        e = se.expand(e)
        coeffs = [e.diff(v) for v in xd]
        if any(c.free_symbols & speeds for c in coeffs):
            return None
    return coeffs, e.xreplace({v: se.Integer(0) for v in xd})
