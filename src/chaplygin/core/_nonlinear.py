"""Velocity constraints nonlinear in the velocities: ``f_β(q, q̇, t) = 0``.

Given implicitly (a list of ``f_β`` with the dependent coordinates) or solved for the
dependent velocities, ``q̇_{ε+β} = φ_β(q, q̇_σ, t)`` (then ``f_β = q̇_{ε+β} − φ_β``), the
constraints are read here into the pieces every model uses:

* ``A = ∂f/∂q̇`` (g × n): the Appell–Chetaev condition on virtual displacements,
  ``Σ_s ∂f_β/∂q̇_s δq_s = 0`` (Appell 1911, Chetaev 1932), and the rows of the
  constraints differentiated in time, ``A q̈ + ∂f/∂q q̇ + ∂f/∂t = 0``;
* ``A_0 = f − A q̇``, so that ``A q̇ + A_0 = f`` still holds as an identity;
* the solved form ``φ`` (a branch of it chosen by the user where ``f = 0`` has several
  solutions), ``B = ∂φ/∂q̇_σ`` (``δq_{ε+β} = Σ_σ B_βσ δq_σ`` on the constraints: the
  Appell–Chetaev displacements, by the implicit function theorem) and
  ``B_0 = φ − B q̇_σ``, which vanishes exactly where φ is homogeneous of degree one in the
  velocities (Euler): then the constraint forces do no work along the motion.

For a constraint linear in the velocities these are form A's and form B's ``A``, ``B``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import sympy as sp

from chaplygin.core._fast import jacobian
from chaplygin.core._rational import normal_matrix
from chaplygin.core._symbols import describe
from chaplygin.errors import SystemDefinitionError

if TYPE_CHECKING:
    from chaplygin.core.system import System

__all__ = ["Nonlinear", "read_nonlinear", "singular_set"]


@dataclass(frozen=True)
class Nonlinear:
    """The internal pieces of nonlinear constraints (internal symbols)."""

    f: sp.Matrix
    A: sp.Matrix
    A0: sp.Matrix
    phi: dict[sp.Symbol, sp.Expr]
    B: sp.Matrix
    B0: sp.Matrix


def read_nonlinear(
    system: System, exprs: Sequence[sp.Expr], *, solved: bool, branch: int | None
) -> Nonlinear:
    """Read constraints of which at least one is nonlinear in the velocities.

    Parameters
    ----------
    exprs : the constraints in internal symbols: the right sides ``φ_β`` (``solved``) or
        the expressions ``f_β`` that vanish, one per dependent coordinate ``system._dep``.
    solved : whether ``exprs`` are solved for the dependent velocities (form B).
    branch : which solution of ``f = 0`` for the dependent velocities (implicit form only).
    """
    v = system._vars
    dep_xd = [v.xd[i] for i in system._dep]
    ind_xd = [v.xd[i] for i in system._ind]
    if solved:
        if branch is not None:
            raise SystemDefinitionError(
                "branch: the constraints are given solved for the dependent velocities, so there is "
                "no branch to choose (branch= picks a solution of implicit constraints)."
            )
        phi = dict(zip(dep_xd, exprs))
        f = sp.Matrix([xd - e for xd, e in zip(dep_xd, exprs)])
    else:
        f = sp.Matrix(list(exprs))
        phi = _solve(system, f, dep_xd, branch)
    A = jacobian(f, list(v.xd))
    A0 = f - A * sp.Matrix(v.xd)
    rhs = sp.Matrix([phi[x] for x in dep_xd])
    B = normal_matrix(jacobian(rhs, ind_xd))
    B0 = normal_matrix(rhs - B * sp.Matrix(ind_xd))
    _check_block(system, A, phi)
    return Nonlinear(f, A, A0, phi, B, B0)


def _solve(
    system: System, f: sp.Matrix, dep_xd: list[sp.Symbol], branch: int | None
) -> dict[sp.Symbol, sp.Expr]:
    """The solution of ``f = 0`` for the dependent velocities: the only one, or ``branch``."""
    names = ", ".join(system.coordinates[i].func.__name__ + "'" for i in system._dep)
    try:
        found = sp.solve(list(f), dep_xd, dict=True)
    except (NotImplementedError, ValueError):
        found = []
    found = [s for s in found if all(x in s and not s[x].has(*dep_xd) for x in dep_xd)]
    if not found:
        raise SystemDefinitionError(
            f"constraints: SymPy cannot solve the implicit constraints for {names}; give them solved, "
            f"as a mapping {{{names.split(', ')[0]}: expression, ...}} (form B), choosing the branch."
        )
    found.sort(key=lambda s: sp.default_sort_key([s[x] for x in dep_xd]))
    # a root's radicand expanded, as the user writes it: sqrt(v**2 - y'**2), not sqrt((v - y')*(v + y'))
    found = [{x: _expanded_roots(e) for x, e in s.items()} for s in found]

    def shown(k: int) -> str:
        return f"branch={k}: " + ", ".join(
            f"{system.coordinates[i].func.__name__}' = {describe(system.to_user(found[k][x]))}"
            for i, x in zip(system._dep, dep_xd)
        )

    if branch is None and len(found) > 1:
        raise SystemDefinitionError(
            f"constraints: the implicit constraints have {len(found)} solutions for {names}; choose "
            "one with branch=K (a system file's branch = K under [constraints]): "
            + "; ".join(shown(k) for k in range(len(found)))
            + "."
        )
    k = 0 if branch is None else branch
    if isinstance(k, bool) or not isinstance(k, int) or not 0 <= k < len(found):
        raise SystemDefinitionError(
            f"branch: expected an integer from 0 to {len(found) - 1}, got {k!r}; "
            + "; ".join(shown(j) for j in range(len(found)))
            + "."
        )
    return found[k]


def _expanded_roots(expr: sp.Expr) -> sp.Expr:
    """``expr`` with the base of every non-integer power expanded."""
    return expr.replace(
        lambda a: a.is_Pow and not a.exp.is_Integer, lambda a: sp.Pow(sp.expand(a.base), a.exp)
    )


def _check_block(system: System, A: sp.Matrix, phi: dict[sp.Symbol, sp.Expr]) -> None:
    """Refuse constraints whose block ``∂f/∂q̇_dep`` is singular wherever they hold: the
    Appell–Chetaev condition then does not determine the dependent displacements."""
    from chaplygin.core._sampling import vanishes

    block = A.extract(list(range(len(phi))), list(system._dep)).xreplace(phi)
    det = sp.together(block.det(method="berkowitz"))
    if det != 0 and not vanishes(sp.numer(det)):
        return
    which = "constraints[0]" if len(phi) == 1 else "the constraints"
    names = ", ".join(system.coordinates[i].func.__name__ + "'" for i in system._dep)
    raise SystemDefinitionError(
        f"{which}: ∂f/∂({names}) is singular wherever the constraints hold, so the Appell–Chetaev "
        "condition Σ ∂f/∂q̇_s δq_s = 0 leaves the virtual displacements undetermined (a constraint "
        "written as a square, (…)² = 0, is one case); write it without the square, or choose "
        "other dependent coordinates."
    )


def singular_set(system: System) -> list[sp.Expr]:
    """Expressions (internal symbols) whose zeros are the states where the solved constraints
    have no derivative (``B = ∂φ/∂q̇_σ`` has a pole): the branch points, where
    ``∂f/∂q̇_dep`` is singular on the constraints."""
    found: list[sp.Expr] = []
    xd = set(system._vars.xd)
    for entry in system._B:
        for factor in sp.Mul.make_args(sp.factor_terms(sp.denom(sp.together(entry)))):
            base = factor.base if factor.is_Pow else factor
            if base.free_symbols & xd and base not in found and not base.is_number:
                found.append(base)
    return found
