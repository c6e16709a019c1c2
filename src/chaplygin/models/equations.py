"""The result of a derivation: equations, mass matrix, forcing and solved accelerations."""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping, Sequence
from functools import cached_property
from typing import TYPE_CHECKING, Any

import sympy as sp

from chaplygin.core import _fold
from chaplygin.core._angles import contracted, has_angle_sums
from chaplygin.core._rational import floated, linear_forms, normal_all, normal_matrix, simplified
from chaplygin.core._sampling import vanishes
from chaplygin.core._symbols import TIME, function_of_time, replace_shared, vsstrrepr
from chaplygin.errors import ChaplyginWarning, ModelError
from chaplygin.models.registry import MODELS

if TYPE_CHECKING:
    from chaplygin.core.system import System

__all__ = ["Equations"]


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
        forcing: sp.Matrix | Callable[[], sp.Matrix],
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
        #: F, or the function that computes it when first needed (:attr:`_F`)
        self._forcing = forcing
        self._solve = solve
        self._multipliers = list(multipliers)
        self._reactions = None if reactions is None else list(reactions)
        #: multipliers that are state variables (their derivatives are unknowns)
        self._state = list((derivatives or {}).keys())
        self._to_fun = dict(system._to_fun)
        for lam in self._multipliers:
            self._to_fun[lam] = function_of_time(lam.name)
        for mu, mu_dot in (derivatives or {}).items():
            self._to_fun[mu_dot] = self._to_fun[mu].diff(TIME)
        self.constants: tuple[sp.Symbol, ...] = tuple(constants)
        #: ``F`` as SymEngine expressions where the derivation has them (the code generator's
        #: input, spared a conversion), else None
        self._native_F: list[Any] | None = None

    @cached_property
    def _F(self) -> sp.Matrix:
        """``F`` of ``M·x = F`` (internal symbols); a derivation may leave it to be computed here,
        on first use: the compiled right-hand side takes :attr:`_native_F` where it is given."""
        forcing = self._forcing
        return forcing if isinstance(forcing, sp.MatrixBase) else forcing()

    @property
    def title(self) -> str:
        """A one-line description with the paper's equation number."""
        return MODELS[self.model].title(self.form, nonlinear=self.system.is_nonlinear)

    def _user(self, expr: sp.Expr) -> sp.Expr:
        return floated(replace_shared(expr, self._to_fun), self.system._float_prec)

    @cached_property
    def equations(self) -> list[sp.Eq]:
        """The equations of motion as a mechanics text writes them: ``sympy.Eq(M_i·x, F_i)``.

        The unknowns :attr:`unknowns` (accelerations, multipliers) on the left, each
        coefficient one cancelled fraction (trigonometric functions of angle sums expanded,
        ``sin² + cos² = 1`` applied, then sums of products read back as functions of angle
        sums: :func:`~chaplygin.core._angles.contracted`), the row cleared of the left side's
        denominators; on the right the terms in the velocities, collected by products of
        velocities, and the forces; a factor common to a side's terms taken out where that
        reads shorter.  A velocity constraint of a multiplier model reads ``Eq(expression, 0)``.
        Each equation is the model's residual times a factor that vanishes nowhere it is
        defined: ``eq.lhs - eq.rhs`` is 0 exactly where the residual is
        (:attr:`mass_matrix` and :attr:`forcing` are the unscaled ``M·x = F``).
        """
        velocities = [*self.system._vars.xd, *self._state]
        return [
            sp.Eq(self._shown(lhs), self._shown(rhs), evaluate=False)
            for lhs, rhs in linear_forms(self._residuals, self._unknowns, velocities)
        ]

    def _shown(self, expr: sp.Expr) -> sp.Expr:
        """An internal expression as displayed: user symbols; angle sums read back where the
        system was written with them (:func:`~chaplygin.core._angles.contracted`)."""
        return contracted(self._user(expr)) if self._angle_sums else self._user(expr)

    @cached_property
    def _angle_sums(self) -> bool:
        """Whether the system was written with trigonometric functions of sums of angles."""
        s = self.system
        written = [s.kinetic_energy, *s._given_constraints, *s.holonomic.values(), *s.forces.values()]
        return has_angle_sums(written + ([s.force_function] if s.force_function is not None else []))

    @cached_property
    def residuals(self) -> list[sp.Expr]:
        """``M·x − F`` row by row, as derived and unscaled, each one cancelled fraction where that
        is small: the expressions that vanish along a motion (:attr:`equations` shows them tidied)."""
        return [self._user(r) for r in normal_all(self._residuals)]

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

    def linear_system(self) -> tuple[sp.Matrix, sp.Matrix]:
        """``(M, F)`` of ``M·x = F`` as displayed: :attr:`mass_matrix` and :attr:`forcing` with each
        entry one cancelled fraction in normal form (the values unchanged)."""
        return tuple(m.applyfunc(self._shown) for m in (normal_matrix(self._M), normal_matrix(self._F)))

    @cached_property
    def _accelerations(self) -> dict[sp.Symbol, sp.Expr]:
        return self._solve()

    @property
    def accelerations(self) -> dict[sp.Expr, sp.Expr]:
        """The solved unknowns: ``{q.diff(t, 2): expression, λ(t): expression}``.

        Computed on first access, exactly and without general simplification:
        the small linear system is solved fraction-free and each solution is one
        cancelled fraction, with ``sin² + cos² = 1`` applied
        (:mod:`chaplygin.core._rational`).  Where that normal form would be very large
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
            result where it is shorter, within a budget of size and time
            (:func:`~chaplygin.core._rational.simplified`): a solution beyond it
            stays in its normal form, with a :class:`~chaplygin.errors.ChaplyginWarning`
            naming it.  The default normal form is exact already.
        """
        out = {self._user(k): self._shown(v) for k, v in self._accelerations.items()}
        if simplify:
            values, skipped = simplified(list(out.values()))
            if skipped:
                names = ", ".join(vsstrrepr(list(out)[k]) for k in skipped)
                warnings.warn(
                    f"not simplified (too large for sympy.simplify within its budget): {names}; "
                    "shown in their exact, cancelled normal form",
                    ChaplyginWarning,
                    stacklevel=2,
                )
            out = dict(zip(out, values))
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

    def power(self) -> sp.Expr:
        """Power ``Σ_s R_s q̇_s`` of the constraint forces along motions (the dependent velocities
        eliminated by the constraints).

        For the Chetaev model it is ``Σ_β λ_β Σ_s ∂f_β/∂q̇_s q̇_s``: zero where the constraints are
        homogeneous in the velocities (Euler: ``Σ_s ∂f/∂q̇_s q̇_s = k f = 0``), linear ones without
        a velocity-free term included, though their virtual work vanishes in every case; not zero
        otherwise (the isokinetic thermostat ``ẋ² + ẏ² = v²`` takes out the work of the applied
        forces: :attr:`System.is_affine <chaplygin.core.system.System.is_affine>` says which).
        """
        s = self.system
        reactions = self._require_reactions("power")
        power = sp.Add(*(r * v for r, v in zip(reactions, s._vars.xd))).xreplace(s._velocity_substitution)
        power = normal_all([power])[0]
        # (a root in φ: Σ ∂f/∂q̇_s q̇_s = k f is zero on the constraints, not in SymPy's normal form)
        return sp.S.Zero if power != 0 and vanishes(power) else self._user(power)

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
        hint = "pretty(full=True) or .equations have it whole"
        lines = [self._heading()]
        lines += [f"  {_fold.text(e, hint=hint, printer=vsstrrepr)}" for e in self.equations]
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
