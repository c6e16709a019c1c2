"""Chetaev (Lagrange–d'Alembert) model: the true motion of a system with ideal constraints.

With form-A constraints ``Σ_s A_βs q̇_s + A_β0 = 0`` (eq. (1)) and Chetaev's
condition on virtual displacements ``Σ_s A_βs δq_s = 0`` (eq. (4)), the
equations with multipliers (eq. (6)/(35)) are::

    E_s(T) − Q_s = R_s ,     R_s = Σ_β λ_β A_βs ,     Σ_s A_βs q̇_s + A_β0 = 0

with ``E_s(F) = d/dt ∂F/∂q̇_s − ∂F/∂q_s``.  Unknowns: ``(q̈_1 … q̈_n, λ_1 … λ_g)``;
the linear system ``M·x = F`` uses the constraints differentiated once::

    [ M   −Aᵀ ] [q̈]   [ Q − E(T)|_{q̈=0} ]
    [ A    0  ] [λ ] = [ −Ȧ q̇ − Ȧ_0      ]

Sign convention
---------------
``R_s`` is the generalized *reaction force* acting on the system: it stands on
the right-hand side beside the applied forces, ``E_s(T) = Q_s + R_s``.  The
paper's ``R`` of eq. (7) is the opposite (``R^paper = −R``): it moves the
reaction to the left side.  The multipliers agree with the paper's for form-B
constraints (``A_{β,ε+β} = 1``, ``A_βσ = −B_βσ``), e.g. eq. (10)
``λ_β = d/dt ∂T/∂q̇_{ε+β}`` for a Chaplygin system.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import sympy as sp

from chaplygin.models.equations import Equations
from chaplygin.models.multipliers import (
    lagrange_operator,
    multiplier_equations,
    multiplier_symbols,
)

if TYPE_CHECKING:
    from chaplygin.core.system import System

__all__ = ["chetaev_equations"]


def chetaev_equations(system: System) -> Equations:
    """The n + g equations of the Chetaev model, eq. (6)/(35)."""
    lam = multiplier_symbols(system, "lambda")
    E = lagrange_operator(system)
    A = system._A
    reactions = [sum((lam[b] * A[b, s] for b in range(system.g)), sp.S.Zero) for s in range(system.n)]
    dynamic = [E[s] - system._Q[s] - reactions[s] for s in range(system.n)]
    return multiplier_equations(system, "chetaev", dynamic, lam, reactions, multipliers=lam)
