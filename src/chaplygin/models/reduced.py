"""Reduced equations of the Chetaev model: Chaplygin (15), the new form (40), Voronets.

Only the ε independent accelerations are unknown; the dependent velocities
(and accelerations) are eliminated by the constraints — the paper's tilde.
With ``D_σ F = ∂F/∂q_σ + Σ_α B_ασ ∂F/∂q_{ε+α}`` and
``p_β = (∂T/∂q̇_{ε+β})~``, Voronets' equations read::

    d/dt ∂T̃/∂q̇_σ − D_σ T̃ − Q̃_σ + Σ_β p_β W_βσ = 0,
    W_βσ = Σ_γ (D_σ B_βγ − D_γ B_βσ) q̇_γ + D_σ B_β0 − ∂_t B_βσ − Σ_α B_α0 ∂B_βσ/∂q_{ε+α},
    Q̃_σ = Q_σ + Σ_β B_βσ Q_{ε+β}.

For a Chaplygin system (nothing depends on ``q_{ε+β}``) ``D_σ = ∂/∂q_σ`` and
this is Chaplygin's eq. (15).  The affine terms in ``W`` (from ``B_β0`` and
explicit time) extend (15) to Voronets' rheonomic case.

The "new" form, eq. (40), differentiates the unreduced T and substitutes after::

    [E_σ(T) − Q_σ]~ + Σ_β B_βσ [E_{ε+β}(T) − Q_{ε+β}]~ = 0

(for a Chaplygin system ``E_{ε+β}(T) = d/dt ∂T/∂q̇_{ε+β}`` as printed in (40));
it is the multiplier system (6) with λ eliminated through (10).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cache
from typing import TYPE_CHECKING, Any

import sympy as sp

from chaplygin.core._fast import derivative, gradient, jacobian, native, shown_nonzero
from chaplygin.core._rational import solve_linear, zero_if_vanishing
from chaplygin.core._symbols import TIME, total_derivative
from chaplygin.models.equations import Equations

if TYPE_CHECKING:
    from chaplygin.core.system import System

__all__ = ["bracket_terms", "lagrange_reduced", "lindelof_defect", "reduced_equations"]


class Reduction:
    """Shared pieces of every reduced form: substitutions, D_σ, d/dt on the constraints."""

    def __init__(self, system: System) -> None:
        self.s = system
        v = system._vars
        self.ind_x = [v.x[i] for i in system._ind]
        self.ind_xd = [v.xd[i] for i in system._ind]
        self.ind_xdd = [v.xdd[i] for i in system._ind]
        self.dep_x = [v.x[i] for i in system._dep]
        self.dep_xd = [v.xd[i] for i in system._dep]
        self.sub = system._velocity_substitution
        self.eps = len(self.ind_x)
        #: (x, ẋ) pairs of the total time derivative on the constraint manifold
        self.pairs = (
            list(zip(self.ind_x, self.ind_xd))
            + [(x, self.sub[xd]) for x, xd in zip(self.dep_x, self.dep_xd)]
            + list(zip(self.ind_xd, self.ind_xdd))
        )

    def dt(self, expr: sp.Expr) -> sp.Expr:
        """Total time derivative along motions that satisfy the constraints."""
        return total_derivative(expr, self.pairs)

    def D(self, expr: sp.Expr, k: int) -> sp.Expr:
        """Voronets' derivative ``D_σ F = ∂F/∂q_σ + Σ_α B_ασ ∂F/∂q_{ε+α}``."""
        deps = [(a, x) for a, x in enumerate(self.dep_x) if expr.has(x)]
        grad = gradient(expr, [self.ind_x[k], *(x for _, x in deps)])
        return grad[0] + sum((self.s._B[a, k] * g for (a, _), g in zip(deps, grad[1:])), sp.S.Zero)

    def reduced_force(self, k: int) -> sp.Expr:
        """``Q̃_σ = (Q_σ + Σ_β B_βσ Q_{ε+β})~``."""
        s = self.s
        q = s._Q[s._ind[k]] + sum((s._B[b, k] * s._Q[i] for b, i in enumerate(s._dep)), sp.S.Zero)
        return q.xreplace(self.sub)


def bracket_terms(system: System) -> list[list[sp.Expr]]:
    """``W_βσ`` of Voronets' equations (internal symbols), indexed ``[β][σ]``.

    ``W_βσ`` is linear in the independent velocities; its coefficients are the
    dependent components of the Lie brackets of the constraint distribution
    (see :mod:`chaplygin.analysis.integrability`), so ``W ≡ 0`` exactly when the
    constraints are integrable.
    """
    r = Reduction(system)
    B, B0 = system._B, system._B0
    if system.is_nonlinear:
        # W_βσ = D_σ φ_β − d/dt ∂φ_β/∂q̇_σ (Novoselov); for φ = B q̇_σ + B_0 it is the sum below
        phi = [r.sub[x] for x in r.dep_xd]
        return [[r.D(phi[b], k) - r.dt(B[b, k]) for k in range(r.eps)] for b in range(system.g)]
    out = []
    for b in range(system.g):
        row = []
        for k in range(r.eps):
            w = sum(
                ((r.D(B[b, c], k) - r.D(B[b, k], c)) * r.ind_xd[c] for c in range(r.eps)),
                sp.S.Zero,
            )
            w += r.D(B0[b], k) - derivative(B[b, k], TIME)
            w -= sum((B0[a] * derivative(B[b, k], x) for a, x in enumerate(r.dep_x)), sp.S.Zero)
            row.append(w)
        out.append(row)
    return out


def momenta_dependent(system: System, r: Reduction) -> list[sp.Expr]:
    """``p_β = (∂T/∂q̇_{ε+β})~``: the momenta of the dependent coordinates, constraints substituted."""
    return [p.xreplace(r.sub) for p in gradient(system._T, r.dep_xd)]


def _lagrange_terms(system: System, r: Reduction) -> list[tuple[sp.Expr, sp.Expr, sp.Expr]]:
    """``(d/dt ∂T̃/∂q̇_σ, D_σ T̃, Q̃_σ)`` for each σ (:func:`lagrange_reduced`)."""
    Tt = system._T_reduced
    momenta = gradient(Tt, r.ind_xd)
    return [(r.dt(momenta[k]), r.D(Tt, k), r.reduced_force(k)) for k in range(r.eps)]


def lagrange_reduced(system: System, r: Reduction) -> list[sp.Expr]:
    """``d/dt ∂T̃/∂q̇_σ − D_σ T̃ − Q̃_σ``: Lagrange's operator on T̃ — Lindelöf's eq. (22)."""
    return [a - b - c for a, b, c in _lagrange_terms(system, r)]


def lindelof_defect(system: System, r: Reduction) -> list[sp.Expr]:
    """``Σ_β p_β W_βσ``: what Chaplygin's (15) adds to Lindelöf's (22)."""
    W = bracket_terms(system)
    p = momenta_dependent(system, r)
    return [sum((p[b] * W[b][k] for b in range(system.g)), sp.S.Zero) for k in range(r.eps)]


def _classic(system: System, r: Reduction) -> tuple[list[sp.Expr], list[Any] | None]:
    """Voronets' equations; Chaplygin's (15) for a Chaplygin system: the residuals, and the
    same sums taken in SymEngine (None where it cannot), for the generated code.

    The terms are converted to SymEngine here, once, and summed there: the code generator
    takes these sums instead of converting the residuals again, and their values at a random
    point show which forcing terms are nonzero (:func:`reduced_equations`: no exact test of
    those for a sum that cancels).
    """
    terms = _lagrange_terms(system, r)
    W = bracket_terms(system)
    p = momenta_dependent(system, r)

    def residuals(
        terms: Sequence[Sequence[Any]], p: Sequence[Any], W: Sequence[Sequence[Any]], zero: Any
    ) -> list[Any]:
        # d/dt ∂T̃/∂q̇_σ − D_σ T̃ − Q̃_σ + Σ_β p_β W_βσ, in SymPy or SymEngine
        return [
            a - b - c + sum((p[i] * W[i][k] for i in range(len(p))), zero)
            for k, (a, b, c) in enumerate(terms)
        ]

    fast = native([*(e for t in terms for e in t), *p, *(w for row in W for w in row)])
    if fast is None:
        return residuals(terms, p, W, sp.S.Zero), None
    eps, g = len(terms), system.g
    n = 3 * eps
    fw = fast[n + g :]
    return residuals(terms, p, W, sp.S.Zero), residuals(
        [fast[3 * k : 3 * k + 3] for k in range(eps)],
        fast[n : n + g],
        [fw[i * eps : (i + 1) * eps] for i in range(g)],
        0,
    )


def unreduced_tilde(system: System, r: Reduction) -> list[sp.Expr]:
    """The unreduced form (40): ``[E_σ(T) − Q_σ]~ + Σ_β B_βσ [E_{ε+β}(T) − Q_{ε+β}]~``."""
    from chaplygin.models.multipliers import lagrange_operator

    v = system._vars
    E = lagrange_operator(system)
    acc = {v.xdd[i]: r.dt(r.sub[v.xd[i]]) for i in system._dep}
    tilde = {**r.sub, **acc}
    rows = [(E[s] - system._Q[s]).xreplace(tilde) for s in range(system.n)]
    out = []
    for k, i in enumerate(system._ind):
        res = rows[i] + sum((system._B[b, k] * rows[j] for b, j in enumerate(system._dep)), sp.S.Zero)
        out.append(res)
    return out


def reduced_equations(system: System, model: str, form: str) -> Equations:
    """Chaplygin's or Voronets' equations in the classic or new form."""
    r = Reduction(system)
    if form != "classic":
        return reduced_system(system, model, form, unreduced_tilde(system, r), r)
    # (nonlinear constraints: W has accelerations too, d/dt ∂φ/∂q̇_σ; M is the residuals' Jacobian)
    mass = None if system.is_nonlinear else reduced_mass_matrix(system, r)
    residuals, fast = _classic(system, r)
    if fast is None:
        return reduced_system(system, model, form, residuals, r, mass=mass)
    # F = −(residuals at zero accelerations), in SymEngine for the code generator; where its
    # value shows it nonzero, the exact test for a cancelling sum (zero_if_vanishing) is spared
    rule = dict(zip(native(r.ind_xdd) or [], [0] * r.eps))
    forcing = [-e.xreplace(rule) for e in fast]
    shown = shown_nonzero(forcing)
    eqs = reduced_system(system, model, form, residuals, r, mass=mass, shown=shown)
    # (a term shown nonzero is F's as it stands; the others are 0 where SymPy's F is 0)
    eqs._native_F = forcing if all(shown) else [0 if f == 0 else e for f, e in zip(eqs._F, forcing)]
    return eqs


def reduced_mass_matrix(system: System, r: Reduction) -> sp.Matrix:
    """``∂²T̃/∂q̇_σ∂q̇_τ``: the coefficients of the independent accelerations in the classic
    residuals (:func:`_classic`).

    Only Lagrange's ``d/dt ∂T̃/∂q̇_σ`` has accelerations there (a System refuses them in T,
    V, the forces and the constraints), so differentiating the momenta ``∂T̃/∂q̇_σ`` gives the
    residuals' Jacobian (the same expressions) at a fraction of the cost: for the rattleback
    with symbolic parameters the momenta have 5,400 operations, the residuals 90,000 (the
    rest of the time derivative, ``D_σ T̃``, ``p_β W_βσ``).
    """
    return jacobian(gradient(system._T_reduced, r.ind_xd), r.ind_xd)


def reduced_system(
    system: System,
    model: str,
    form: str,
    residuals: list[sp.Expr],
    r: Reduction,
    *,
    mass: sp.Matrix | None = None,
    shown: Sequence[bool] | None = None,
    **extra: object,
) -> Equations:
    """Wrap ε residuals linear in the independent accelerations as :class:`Equations`.

    ``mass``, where the caller knows it, is the matrix of their coefficients (else it is
    the residuals' Jacobian in the accelerations).  ``shown``, where given, marks the forcing
    terms already shown not to vanish (:func:`chaplygin.core._fast.shown_nonzero`).
    """
    res = sp.Matrix(residuals)
    M = jacobian(res, r.ind_xdd) if mass is None else mass
    seen = shown or [False] * res.rows

    @cache
    def forcing() -> sp.Matrix:
        """F when first needed (the compiled right-hand side may take the derivation's SymEngine F)."""
        # a forcing term that vanishes identically is 0, not a sum that cancels only exactly: the
        # compiled right-hand sides solve M·x = F numerically (the snakeboard's classic φ row)
        F = -res.xreplace({a: 0 for a in r.ind_xdd})
        return sp.Matrix(F.rows, 1, [f if s else zero_if_vanishing(f) for f, s in zip(F, seen)])

    def solve() -> dict[sp.Symbol, sp.Expr]:
        return dict(zip(r.ind_xdd, solve_linear(M, forcing(), f"the {model} equations")))

    return Equations(system, model, form, residuals, r.ind_xdd, M, forcing, solve, **extra)  # type: ignore[arg-type]
