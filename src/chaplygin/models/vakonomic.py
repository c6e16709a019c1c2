"""Vakonomic (variational) model: Lindelöf's equations and the family of vakonomic motions.

The constraints enter the variational principle with multipliers ``μ_β``
(eqs. (16)-(17)): the action of ``L_v = T + U + Σ_β μ_β φ_β`` with
``φ_β = Σ_s A_βs q̇_s + A_β0`` is stationary for variations of q and μ.  The
equations (form A; (18a)-(18b) when A comes from form B) are::

    E_s(T) − Q_s + E_s(Σ_β μ_β φ_β) = 0 ,     φ_β = 0

i.e. ``E_s(T) − Q_s + Σ_β [μ̇_β A_βs + μ_β Σ_k (∂A_βs/∂q_k − ∂A_βk/∂q_s) q̇_k] = 0`` for
homogeneous scleronomic constraints.  Unknowns are ``q̈`` and ``μ̇``; ``μ`` is
part of the state.  The constraint forces (23) are ``R_s = −E_s(Σ μ φ)``
(convention ``E_s(T) = Q_s + R_s``, as for the Chetaev model); their virtual
work (24)-(26) does not vanish in general: the constraints are not ideal.

For a Chaplygin system without forces along the dependent coordinates,
(18b) integrates: ``μ_β = c_β − ∂T/∂q̇_{ε+β}``, and the motion obeys the
reduced **vakonomic family**::

    E_σ(T̃) − Q̃_σ + Σ_β c_β W_βσ = 0            (classic)
    [E_σ(T) − Q_σ]~ + Σ_β B_βσ [d/dt ∂T/∂q̇_{ε+β}]~ − Σ_β (p_β − c_β) W_βσ = 0   (new, (39))

with ``W_βσ = Σ_γ (∂B_βγ/∂q_σ − ∂B_βσ/∂q_γ) q̇_γ`` (plus affine terms) and
``p_β = (∂T/∂q̇_{ε+β})~``.  The member ``c = 0`` is **Lindelöf's equations (22)**:
substitute the constraints into T, then apply Lagrange's equations.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import sympy as sp

from chaplygin.core._fast import derivative, gradient
from chaplygin.core._rational import solve_linear
from chaplygin.core._symbols import total_derivative
from chaplygin.errors import ModelError
from chaplygin.models import registry
from chaplygin.models.equations import Equations
from chaplygin.models.multipliers import (
    lagrange_operator,
    multiplier_equations,
    multiplier_symbols,
)
from chaplygin.models.reduced import (
    Reduction,
    bracket_terms,
    lagrange_reduced,
    lindelof_defect,
    reduced_system,
    unreduced_tilde,
)
from chaplygin.models.registry import family_obstructions

if TYPE_CHECKING:
    from chaplygin.core.system import System

__all__ = [
    "constant_symbols",
    "family_obstructions",
    "integrated_multipliers",
    "vakonomic_equations",
    "vakonomic_family",
]


def vakonomic_equations(system: System) -> Equations:
    """The n + g vakonomic equations with multipliers μ, eqs. (17)-(18)."""
    v = system._vars
    mu = multiplier_symbols(system, "mu")
    mu_dot = [sp.Dummy(m.name + "_d") for m in mu]
    phi = system._f
    L_c = sum((mu[b] * phi[b] for b in range(system.g)), sp.S.Zero)
    pairs = list(zip(v.x, v.xd)) + list(zip(v.xd, v.xdd)) + list(zip(mu, mu_dot))
    E = lagrange_operator(system)
    grad = gradient(L_c, [*v.xd, *v.x])
    n = system.n
    reactions = [-(total_derivative(grad[s], pairs) - grad[n + s]) for s in range(n)]
    dynamic = [E[s] - system._Q[s] - reactions[s] for s in range(system.n)]
    return multiplier_equations(
        system,
        "vakonomic",
        dynamic,
        mu_dot,
        reactions,
        multipliers=mu,
        derivatives=dict(zip(mu, mu_dot)),
    )


def constant_symbols(system: System) -> list[sp.Symbol]:
    """The constants ``c_1 … c_g`` of the vakonomic family (renamed if a parameter has the name)."""
    taken = {p.name for p in system.parameters}
    return [sp.Symbol(f"c_{b + 1}" + ("_" if f"c_{b + 1}" in taken else "")) for b in range(system.g)]


def _constants(system: System, constants: Any) -> list[sp.Expr]:
    symbols = constant_symbols(system)
    if constants is None:
        return list(symbols)
    if system.g == 1 and not isinstance(constants, (Mapping, Sequence)):
        constants = [constants]
    if isinstance(constants, Mapping):
        values = list(symbols)
        for key, value in constants.items():
            names = [s.name for s in symbols]
            k = key - 1 if isinstance(key, int) else names.index(str(key)) if str(key) in names else None
            if k is None or not 0 <= k < system.g:
                raise ModelError(f"constants: unknown key {key!r}; use {', '.join(names)} or 1…{system.g}.")
            values[k] = value if isinstance(value, sp.Basic) else sp.nsimplify(value)
        return values
    if isinstance(constants, Sequence) and not isinstance(constants, str):
        if len(constants) != system.g:
            raise ModelError(f"constants: {len(constants)} value(s) given for {system.g} constraint(s).")
        return [c if isinstance(c, sp.Basic) else sp.nsimplify(c) for c in constants]
    raise ModelError(
        "constants: give a mapping {'c_1': value, ...}, a sequence of g values, or None for symbols."
    )


def _require_family(system: System) -> None:
    problems = family_obstructions(system)
    if problems:
        raise ModelError(
            f"the vakonomic multipliers of {system.name} do not integrate: (18b) reads "
            "d/dt(∂T/∂q̇_{ε+β} + μ_β) = (terms from ∂T/∂q_{ε+β}, B, forces) ≠ 0 because "
            + "; ".join(problems)
            + ". The reduced family and Lindelöf's equations exist only for Chaplygin systems "
            "without forces along the dependent coordinates; use model='vakonomic' (the "
            "multiplier form) instead."
        )


def integrated_multipliers(system: System, constants: Any = None) -> dict[sp.Expr, sp.Expr]:
    """The vakonomic multipliers of the member with constants ``c``: the integral of (18b).

    ``A_depᵀ μ = c − (∂T/∂q̇_dep)~`` — in form B simply ``μ_β = c_β − ∂T/∂q̇_{ε+β}``,
    eqs. (19)-(20) with ``c_β`` kept.  Returns ``{μ_β(t): expression}`` in the
    system's dynamicsymbols (dependent velocities eliminated).
    """
    _require_family(system)
    c = _constants(system, constants)
    v, g = system._vars, system.g
    p = [derivative(system._T, v.xd[i]).xreplace(system._velocity_substitution) for i in system._dep]
    a_dep = system._A.extract(list(range(g)), list(system._dep)).xreplace(system._velocity_substitution)
    mu = solve_linear(a_dep.T, sp.Matrix(c) - sp.Matrix(p), "the integrated multipliers (18b)")
    names = system.equations("vakonomic").multipliers
    return {name: system.to_user(e) for name, e in zip(names, mu)}


def vakonomic_family(system: System, model: str, form: str, constants: Any = None) -> Equations:
    """The reduced vakonomic family (``model="vakonomic_family"``) or Lindelöf's equations (c = 0)."""
    _require_family(system)
    r = Reduction(system)
    c = _constants(system, constants) if registry.get(model).constants else [sp.S.Zero] * system.g
    W = bracket_terms(system)
    family = [sum((c[b] * W[b][k] for b in range(system.g)), sp.S.Zero) for k in range(r.eps)]
    if form == "classic":
        base = lagrange_reduced(system, r)
    else:
        base = [a - b for a, b in zip(unreduced_tilde(system, r), lindelof_defect(system, r))]
    residuals = [a + f for a, f in zip(base, family)]
    free = tuple(s for s in constant_symbols(system) if any(e.has(s) for e in c))
    return reduced_system(system, model, form, residuals, r, constants=free)
