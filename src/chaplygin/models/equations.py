"""The result of a derivation: equations, mass matrix, forcing and solved accelerations."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from functools import cached_property
from typing import TYPE_CHECKING

import sympy as sp
from sympy.physics.mechanics import dynamicsymbols
from sympy.physics.vector.printing import vsstrrepr

from chaplygin.core import _fold
from chaplygin.core._fast import gradient
from chaplygin.core._symbols import TIME, replace_shared
from chaplygin.errors import ModelError
from chaplygin.models._rational import normal_all, simplified
from chaplygin.models.registry import MODELS

if TYPE_CHECKING:
    from chaplygin.core.system import System

__all__ = ["Equations"]


def readable(residuals: Sequence[sp.Expr], unknowns: Sequence[sp.Symbol]) -> list[sp.Expr]:
    """Each residual as ``Σ c_j x_j + c_0`` in the unknowns, every ``c`` in normal form (for display).

    The residuals are affine in the unknowns; a residual that is not (a velocity
    constraint of a multiplier model has no unknowns) is shown as a whole.
    """
    rows = [(gradient(r, list(unknowns)), r.xreplace({x: 0 for x in unknowns})) for r in residuals]
    parts = normal_all([c for grad, rest in rows for c in (*grad, rest)])
    out, k = [], 0
    for grad, _ in rows:
        coeffs, rest = parts[k : k + len(grad)], parts[k + len(grad)]
        k += len(grad) + 1
        out.append(sp.Add(*(c * x for c, x in zip(coeffs, unknowns)), rest))
    return out


class Equations:
    """Equations of motion of one model, with the linear system ``M·x = F`` they form.

    Attributes
    ----------
    system : System
        The system they were derived for.
    model, form : str
        As passed to :meth:`System.equations`.
    unknowns : tuple
        ``x``: second derivatives of the coordinates (and the multipliers
        ``λ_β(t)`` for the Chetaev model), in this order.
    multipliers : tuple
        The multipliers as dynamicsymbols (empty for reduced models).

    Notes
    -----
    Expressions use the system's dynamicsymbols: ``q``, ``q.diff(t)``,
    ``q.diff(t, 2)``.  For reduced models the dependent velocities are already
    eliminated by the constraints (the paper's tilde).
    """

    def __init__(
        self,
        system: System,
        model: str,
        form: str,
        residuals: Sequence[sp.Expr],
        unknowns: Sequence[sp.Symbol],
        mass_matrix: sp.Matrix,
        forcing: sp.Matrix,
        solve: Callable[[], dict[sp.Symbol, sp.Expr]],
        *,
        multipliers: Sequence[sp.Symbol] = (),
        derivatives: Mapping[sp.Symbol, sp.Symbol] | None = None,
        reactions: Sequence[sp.Expr] | None = None,
        constants: Sequence[sp.Symbol] = (),
    ) -> None:
        self.system = system
        self.model = model
        self.form = form
        self._residuals = list(residuals)
        self._unknowns = list(unknowns)
        self._M = mass_matrix
        self._F = forcing
        self._solve = solve
        self._multipliers = list(multipliers)
        self._reactions = None if reactions is None else list(reactions)
        #: multipliers that are state variables (their derivatives are unknowns)
        self._state = list((derivatives or {}).keys())
        self._to_fun = dict(system._to_fun)
        for lam in self._multipliers:
            self._to_fun[lam] = dynamicsymbols(lam.name)
        for mu, mu_dot in (derivatives or {}).items():
            self._to_fun[mu_dot] = self._to_fun[mu].diff(TIME)
        self.constants: tuple[sp.Symbol, ...] = tuple(constants)

    @property
    def title(self) -> str:
        """A one-line description with the paper's equation number."""
        return MODELS[self.model].title(self.form)

    def _user(self, expr: sp.Expr) -> sp.Expr:
        return replace_shared(expr, self._to_fun)

    @cached_property
    def equations(self) -> list[sp.Eq]:
        """The equations of motion, each as ``sympy.Eq(expression, 0)``."""
        return [sp.Eq(self._user(r), 0, evaluate=False) for r in readable(self._residuals, self._unknowns)]

    @property
    def unknowns(self) -> tuple[sp.Expr, ...]:
        return tuple(self._user(u) for u in self._unknowns)

    @property
    def multipliers(self) -> tuple[sp.Expr, ...]:
        return tuple(self._user(m) for m in self._multipliers)

    @cached_property
    def mass_matrix(self) -> sp.Matrix:
        """``M`` of ``M·x = F`` in the model's unknowns :attr:`unknowns` (not simplified)."""
        return self._user(self._M)

    @cached_property
    def forcing(self) -> sp.Matrix:
        """``F`` of ``M·x = F`` in the model's unknowns :attr:`unknowns` (not simplified)."""
        return self._user(self._F)

    @cached_property
    def _accelerations(self) -> dict[sp.Symbol, sp.Expr]:
        return self._solve()

    @property
    def accelerations(self) -> dict[sp.Expr, sp.Expr]:
        """The solved unknowns: ``{q.diff(t, 2): expression, λ(t): expression}``.

        Computed on first access, exactly and without general simplification:
        the small linear system is solved fraction-free and each solution is one
        cancelled fraction, with ``sin² + cos² = 1`` applied
        (:mod:`chaplygin.models._rational`).  Where that normal form would be very large
        the solution is left nested, as ``KanesMethod.rhs()`` gives it.  See
        :meth:`solve` for heavier simplification.
        """
        return self.solve()

    def solve(self, *, simplify: bool = False) -> dict[sp.Expr, sp.Expr]:
        """The solved unknowns, as :attr:`accelerations`.

        Parameters
        ----------
        simplify : bool
            Also pass each solution through ``sympy.simplify``, keeping the
            result where it is shorter.  Slow (seconds to minutes on larger
            systems); the default normal form is exact already.
        """
        out = {self._user(k): self._user(v) for k, v in self._accelerations.items()}
        if simplify:
            out = {k: simplified(v) for k, v in out.items()}
        return out

    # -------------------------------------------------------------- constraint forces
    def constraint_forces(self) -> dict[sp.Expr, sp.Expr]:
        """Generalized constraint forces ``R_s`` of a multiplier model.

        Chetaev: ``R_s = Σ_β λ_β A_βs``, eq. (7); vakonomic: eq. (23).
        Convention: ``E_s(T) = Q_s + R_s`` — the reaction acts beside the
        applied forces (the paper's R of eq. (7) is ``−R_s``).
        """
        reactions = self._require_reactions("constraint_forces")
        return {q: self._user(r) for q, r in zip(self.system.coordinates, reactions)}

    def virtual_work(self, *, chetaev_condition: bool = True) -> sp.Expr:
        """Virtual work ``Σ_s R_s δq_s`` of the constraint forces, eqs. (8)-(9) and (24)-(26).

        With ``chetaev_condition=True`` the displacements ``δq_s`` (symbols
        ``δq``) satisfy Chetaev's condition (4) and the velocities the
        constraints.  The result is 0 for the Chetaev model (ideal
        constraints) and in general not for the vakonomic one.
        """
        s = self.system
        dq = virtual_displacements(s)
        work: sp.Expr = sp.Add(*(r * d for r, d in zip(self._require_reactions("virtual_work"), dq)))
        if chetaev_condition:
            ind = [dq[i] for i in s._ind]
            cond = {
                dq[i]: sum((s._B[b, k] * ind[k] for k in range(len(ind))), sp.S.Zero)
                for b, i in enumerate(s._dep)
            }
            work = sp.expand(work.xreplace(cond).xreplace(s._velocity_substitution))
            work = sp.Add(*[c * d for c, d in zip(normal_all([work.coeff(d) for d in ind]), ind)])
        return self._user(work)

    def _require_reactions(self, what: str) -> list[sp.Expr]:
        if self._reactions is None:
            raise ModelError(
                f"{what} needs the multiplier form of the model; the {self.model!r} equations "
                "have the multipliers eliminated. Use system.equations('chetaev') or "
                "system.equations('vakonomic')."
            )
        return self._reactions

    # -------------------------------------------------------------- printing
    def __str__(self) -> str:
        lines = [self._heading()]
        lines += [f"  {vsstrrepr(e.lhs)} = 0" for e in self.equations]
        return "\n".join(lines)

    def pretty(self, *, full: bool = False) -> str:
        """A multi-line Unicode rendering, one equation after another; an equation beyond a
        screen is folded into a one-line summary unless ``full`` (:mod:`chaplygin.core._fold`)."""
        shown = _fold.pretty(self.equations, full=full, hint="pretty(full=True) prints it whole")
        return f"{self._heading()}\n\n" + "\n\n".join(shown)

    def latex(self, *, full: bool = True) -> str:
        """LaTeX of the equations, with dots for time derivatives, a long one broken into lines;
        with ``full=False`` an equation beyond a screen is folded into a summary."""
        return _fold.latex(self.equations, full=full)

    def _repr_latex_(self) -> str:
        from chaplygin import _html

        title = _html.latex_text(self._heading())
        body = self.latex(full=False)
        return f"$\\displaystyle \\begin{{array}}{{l}} {title} \\\\ {body} \\end{{array}}$"

    def _repr_html_(self) -> str:
        from chaplygin import _html

        return _fold.html(self.equations, escape=_html.escape, heading=_html.heading(self._heading()))

    def _heading(self) -> str:
        return f"{self.title} - {self.system.name}"

    def __repr__(self) -> str:
        return f"<Equations {self.model}/{self.form} of {self.system.name}: {len(self._residuals)} equations>"


def virtual_displacements(system: System) -> list[sp.Symbol]:
    """Symbols ``δq_s`` for the virtual displacements, in coordinate order."""
    return [sp.Symbol("δ" + q.func.__name__) for q in system.coordinates]
