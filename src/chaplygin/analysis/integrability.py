"""Integrability of linear velocity constraints: conditions (28), (33) and Frobenius.

* Condition (28), form B: ``∂B_βγ/∂q_σ − ∂B_βσ/∂q_γ = 0``, and for affine or
  time-dependent constraints also ``∂B_βσ/∂t − ∂B_β0/∂q_σ = 0`` (the dt part:
  ``(B_β, B_β0)`` is a gradient on ``(q_σ, t)``).  When B and B_0 are free of
  the dependent coordinates it is necessary and sufficient; otherwise it does
  not apply (it is reported as such, ``holds=None``).
* Condition (33), form A: the constraint 1-forms
  ``ω_β = Σ_s A_βs dq_s + A_β0 dt`` are closed on ``(q, t)``:
  ``∂A_βk/∂q_s − ∂A_βs/∂q_k = 0`` and ``∂A_βs/∂t − ∂A_β0/∂q_s = 0``.
  Sufficient, not necessary (integrating factors).
* **Frobenius**: the distribution annihilated by ``ω_β = Σ_s A_βs dq_s`` (plus
  ``A_β0 dt`` for rheonomic/affine constraints) is integrable iff it is closed
  under Lie brackets.  It is spanned by ``X_σ = ∂_σ + Σ_β B_βσ ∂_{ε+β}`` (and
  ``X_0 = ∂_t + Σ_β B_β0 ∂_{ε+β}``); the brackets have no independent
  components, so the test is that their dependent components
  ``D_σ B_βγ − D_γ B_βσ`` (and ``∂_t B_βσ + Σ_α B_α0 ∂B_βσ/∂q_{ε+α} − D_σ B_β0``)
  vanish — exactly the terms ``W_βσ`` of Voronets' equations.  This is
  equivalent to ``dω_β ∧ ω_1 ∧ … ∧ ω_g = 0``.

When the constraints are integrable, :func:`analyze` looks for the finite
relations ``f_β(q, t) = const`` (potentials of B, or integrating factors for a
single constraint) and returns only relations it has verified.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from itertools import combinations
from typing import TYPE_CHECKING, Any

import sympy as sp
from sympy.physics.vector.printing import vlatex, vsstrrepr

from chaplygin import _html
from chaplygin.core import _fold
from chaplygin.core._brief import brief
from chaplygin.core._fast import derivative
from chaplygin.core._rational import normal_all
from chaplygin.core._sampling import vanishes
from chaplygin.core._symbols import TIME, file_syntax
from chaplygin.models.reduced import Reduction

if TYPE_CHECKING:
    from chaplygin.core.system import System

__all__ = ["Condition", "IntegrabilityReport", "analyze"]

#: expressions up to this many operations are shown with their common factors taken out
SHOWN_OPS = 200


def shown(expr: sp.Expr) -> sp.Expr:
    """``expr`` as printed in a verdict: one cancelled fraction in the normal form of
    :func:`~chaplygin.core._rational.normal_all` (``tan`` as ``sin/cos``, ``sin² + cos² = 1``), so
    that it reads the same however the constraints were written; common factors taken out
    where it is small; left as it is where that normal form is too large to compute.
    """
    normal = normal_all([expr])[0]
    return sp.factor_terms(normal) if sp.count_ops(normal) <= SHOWN_OPS else normal


@dataclass
class Condition:
    """The verdict of one integrability test.

    Attributes
    ----------
    name : str
        ``"(28)"``, ``"(33)"`` or ``"Frobenius"``.
    holds : bool or None
        Whether every component vanishes; None where the condition does not
        apply to these constraints (the note says why).
    failures : list of (str, sympy.Expr)
        The non-vanishing components, labelled in the paper's indices.
    note : str
        What the test means for this system.
    """

    name: str
    holds: bool | None
    failures: list[tuple[str, sp.Expr]] = field(default_factory=list)
    note: str = ""

    @property
    def verdict(self) -> str:
        """``"holds"``, ``"fails"`` or ``"not applicable"``."""
        return "not applicable" if self.holds is None else "holds" if self.holds else "fails"

    def __str__(self) -> str:
        text = f"{self.name}: {self.verdict}"
        if self.failures:
            label, expr = self.failures[0]
            more = f" (and {len(self.failures) - 1} more)" if len(self.failures) > 1 else ""
            text += f" — {label} = {brief(expr, '.failures holds it')}{more}"
        return text + (f". {self.note}" if self.note else "")

    def _html_row(self) -> list[str]:
        first = ""
        if self.failures:
            label, expr = self.failures[0]
            more = f" (and {len(self.failures) - 1} more)" if len(self.failures) > 1 else ""
            first = (
                f"{_html.escape(label)} = {_fold.html_math(expr, escape=_html.escape)}{_html.escape(more)}"
            )
        return [_html.escape(self.name), self.verdict, first, _html.escape(self.note)]


@dataclass
class IntegrabilityReport:
    """Integrability verdicts for the constraints of a system.

    ``integrable`` is the Frobenius verdict (the true test).  ``relations``
    holds finite relations ``f(q, t)`` that stay constant along every motion,
    when they were found; each was verified.  The ``k``-th relation belongs to
    the ``k``-th constraint and contains its dependent coordinate;
    :meth:`holonomic_system` turns them into holonomic constraints.
    """

    system_name: str
    condition_28: Condition
    condition_33: Condition
    frobenius: Condition
    relations: list[sp.Expr] = field(default_factory=list)
    #: the system analysed (for :meth:`holonomic_system`)
    system: System | None = field(default=None, repr=False, compare=False)
    #: for constraints nonlinear in the velocities, why the verdict is what it is (else "")
    nonlinear: str = ""

    def holonomic_system(self, constants: Any = None) -> System:
        """The system with its velocity constraints replaced by their finite relations.

        Each relation ``f_β(q, t) = c_β`` found (:attr:`relations`) becomes the holonomic
        constraint ``f_β − c_β = 0`` of the dependent coordinate of its constraint; the
        system's own holonomic constraints stay.  The motions are the same: ``ḟ_β = 0`` is
        the constraint (up to a factor), and ``c_β`` selects the leaf of the foliation.

        Parameters
        ----------
        constants : sequence or mapping, optional
            The values ``c_β``: a sequence (one per velocity constraint, in order) or a
            mapping by dependent coordinate (symbol or name).  None: new parameters
            ``c_1 … c_g`` (named ``c_1_`` … where a name is taken).

        Raises
        ------
        ModelError
            If the constraints are not integrable, or no finite relation was found for them.
        """
        from chaplygin.errors import ModelError

        s = self.system
        if s is None:
            raise ModelError("this report has no system (it was not made by System.integrability()).")
        g = s.velocity_g
        if not g:
            raise ModelError(f"{s.name} has no velocity constraints to replace by finite relations.")
        if not self.integrable and self.frobenius.holds is None:
            raise ModelError(f"the constraints of {s.name} are not integrable: {self.nonlinear}")
        if not self.integrable:
            raise ModelError(
                f"the constraints of {s.name} are not integrable (Frobenius: "
                f"{self.frobenius.failures[0][0] if self.frobenius.failures else 'fails'} ≠ 0): "
                "there are no finite relations to replace them by."
            )
        if len(self.relations) < g:
            raise ModelError(
                f"the constraints of {s.name} are integrable, but no finite relation f(q, t) = c was "
                "found for them in closed form; give it yourself with "
                "system.with_holonomic({q_dep: f - c}, keep_constraints=False)."
            )
        keys = [s.coordinates[i] for i in s._dep[:g]]
        taken = {p.name for p in s.parameters} | {q.func.__name__ for q in s.coordinates}
        if constants is None:
            values: list[Any] = []
            for b in range(g):
                name = f"c_{b + 1}"
                while name in taken:
                    name += "_"
                values.append(sp.Symbol(name))
        elif isinstance(constants, Mapping):
            by_name = {(k if isinstance(k, str) else k.func.__name__): v for k, v in constants.items()}
            unknown = [k for k in by_name if k not in {q.func.__name__ for q in keys}]
            if unknown or len(by_name) != g:
                raise ModelError(
                    f"constants: give one value per dependent coordinate "
                    f"({', '.join(q.func.__name__ for q in keys)}); got {', '.join(map(str, by_name))}."
                )
            values = [by_name[q.func.__name__] for q in keys]
        else:
            values = list(constants)
            if len(values) != g:
                raise ModelError(f"constants: {len(values)} value(s) given for {g} relation(s).")
        relations = {q: f - c for q, f, c in zip(keys, self.relations, values)}
        return s.with_holonomic(relations, keep_constraints=False)

    @property
    def integrable(self) -> bool:
        return bool(self.frobenius.holds)

    @property
    def verdict(self) -> str:
        """The verdict in words: ``"integrable (holonomic), by the Frobenius test."`` or why not."""
        head = "integrable (holonomic)" if self.integrable else "not integrable (nonholonomic)"
        if self.nonlinear and self.frobenius.holds is None:
            return f"{head}: {self.nonlinear}"
        return f"{head}, by the Frobenius test." + (f" {self.nonlinear}" if self.nonlinear else "")

    def __str__(self) -> str:
        lines = [
            f"Constraints of {self.system_name}: {self.verdict}",
            f"  {self.condition_28}",
            f"  {self.condition_33}",
            f"  {self.frobenius}",
        ]
        if self.integrable:
            if self.relations:
                lines.append("  Finite relations (each = constant):")
                lines += [f"    {vsstrrepr(r)}" for r in self.relations]
            else:
                lines.append("  No finite relation was found in closed form.")
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        conditions = (self.condition_28, self.condition_33, self.frobenius)
        text = _html.heading(f"Constraints of {self.system_name}: {self.verdict}")
        text += _html.table(
            [c._html_row() for c in conditions], ["condition", "verdict", "first failure", "note"]
        )
        if self.relations:
            text += "<p>Finite relations (each = constant): "
            text += ", ".join(_html.math(vlatex(r)) for r in self.relations) + "</p>"
        return text


def _name(system: System, i: int) -> str:
    return system.coordinates[i].func.__name__


#: why the tests of linear constraints do not apply to constraints nonlinear in the velocities
NONLINEAR = (
    "the constraints are nonlinear in the velocities (φ not affine in them), and finite "
    "relations f(q, t) = 0 give constraints linear in the velocities."
)
#: why a test is not applicable to them
NOT_FOR_NONLINEAR = "A test of constraints linear in the velocities."


def analyze(system: System) -> IntegrabilityReport:
    """Run conditions (28), (33) and the Frobenius test on ``system``'s constraints.

    Constraints nonlinear in the velocities are nonholonomic when their solved form φ is not
    affine in the independent velocities (the tests, for distributions, do not apply: each
    is reported not applicable); where the branch chosen is affine in them, the tests are
    those of the linear constraints ``q̇_dep = φ``.
    """
    if system.is_nonlinear:
        return _nonlinear(system)
    s, v = system, system._vars
    ind, dep = s._ind, s._dep
    user = s.to_user

    dep_x = [v.x[i] for i in dep]
    timed = s.is_affine or any(e.has(TIME) for e in (*s._A, *s._B))
    fail28 = []
    for b, (k, c) in ((b, kc) for b in range(s.g) for kc in combinations(range(len(ind)), 2)):
        e = derivative(s._B[b, c], v.x[ind[k]]) - derivative(s._B[b, k], v.x[ind[c]])
        if not vanishes(e):
            label = f"∂B[{_name(s, dep[b])}, {_name(s, ind[c])}]/∂{_name(s, ind[k])} − ∂B[{_name(s, dep[b])}, {_name(s, ind[k])}]/∂{_name(s, ind[c])}"
            fail28.append((label, user(shown(e))))
    for b, k in ((b, k) for b in range(s.g) for k in range(len(ind)) if timed):
        e = derivative(s._B[b, k], TIME) - derivative(s._B0[b], v.x[ind[k]])
        if not vanishes(e):
            label = (
                f"∂B[{_name(s, dep[b])}, {_name(s, ind[k])}]/∂t − ∂B0[{_name(s, dep[b])}]/∂{_name(s, ind[k])}"
            )
            fail28.append((label, user(shown(e))))
    if any(e.has(*dep_x) for e in (*s._B, *s._B0)):
        c28 = Condition(
            "(28)",
            None,
            [],
            "B depends on the dependent coordinates, and (28) decides integrability only where it "
            "does not: see Frobenius.",
        )
    else:
        c28 = Condition(
            "(28)",
            not fail28,
            fail28,
            "B is free of the dependent coordinates, so (28) decides integrability"
            + (" (with its dt terms ∂B/∂t − ∂B0/∂q)." if timed else "."),
        )

    fail33 = []
    for b in range(s.g):
        for k, j in combinations(range(s.n), 2):
            e = derivative(s._A[b, j], v.x[k]) - derivative(s._A[b, k], v.x[j])
            if not vanishes(e):
                label = (
                    f"∂A[{b + 1}, {_name(s, j)}]/∂{_name(s, k)} − ∂A[{b + 1}, {_name(s, k)}]/∂{_name(s, j)}"
                )
                fail33.append((label, user(shown(e))))
        for k in range(s.n) if timed else ():
            e = derivative(s._A[b, k], TIME) - derivative(s._A0[b], v.x[k])
            if not vanishes(e):
                label = f"∂A[{b + 1}, {_name(s, k)}]/∂t − ∂A0[{b + 1}]/∂{_name(s, k)}"
                fail33.append((label, user(shown(e))))
    c33 = Condition(
        "(33)",
        not fail33,
        fail33,
        "Closed constraint forms"
        + (" (with their dt part A0 dt, on (q, t))" if timed else "")
        + "; sufficient for integrability, not necessary.",
    )

    from chaplygin.models.reduced import bracket_terms

    W = bracket_terms(s)
    r = Reduction(s)
    fail_f = []
    for b in range(s.g):
        for k in range(len(ind)):
            w = W[b][k]
            for c in range(len(ind)):
                if c > k:
                    e = derivative(w, r.ind_xd[c])
                    if not vanishes(e):
                        label = f"[X_{_name(s, ind[k])}, X_{_name(s, ind[c])}] along ∂{_name(s, dep[b])}"
                        fail_f.append((label, user(shown(e))))
            e0 = w.xreplace({x: 0 for x in r.ind_xd})
            if not vanishes(e0):
                label = f"[X_t, X_{_name(s, ind[k])}] along ∂{_name(s, dep[b])}"
                fail_f.append((label, user(shown(-e0))))
    cf = Condition(
        "Frobenius",
        not fail_f,
        fail_f,
        "Lie brackets of the constraint distribution (equivalent to dω ∧ ω_1 ∧ … ∧ ω_g = 0).",
    )
    relations = [user(f) for f in _finite_relations(s)] if cf.holds else []
    if s._holonomic:  # (the relations of the velocity constraints only: f = 0 is known already)
        relations = relations[: s.velocity_g]
    return IntegrabilityReport(s.name, c28, c33, cf, relations, system=s)


def _nonlinear(system: System) -> IntegrabilityReport:
    """:func:`analyze` for constraints nonlinear in the velocities."""
    from chaplygin.core.system import System

    ind_xd = [system._vars.xd[i] for i in system._ind]
    if any(e.has(*ind_xd) for e in (*system._B, *system._B0)):
        c28, c33, cf = (
            Condition(name, None, [], NOT_FOR_NONLINEAR) for name in ("(28)", "(33)", "Frobenius")
        )
        return IntegrabilityReport(system.name, c28, c33, cf, system=system, nonlinear=NONLINEAR)
    solved = {
        system.coordinates[i].diff(TIME): system.to_user(system._velocity_substitution[system._vars.xd[i]])
        for i in system._dep
    }
    linear = System(
        system.coordinates,
        system.kinetic_energy,
        solved,
        potential_energy=system.potential_energy,
        force_function=system.force_function if system.potential_energy is None else None,
        forces=system.forces or None,
        name=system.name,
    )
    report = analyze(linear)
    report.nonlinear = (
        "The constraints are nonlinear in the velocities, but on the branch chosen they are "
        "linear, "
        + ", ".join(f"{file_syntax(k)} = {file_syntax(e)}" for k, e in solved.items())
        + ": the tests are those of this linear form."
    )
    return report


# ---------------------------------------------------------------- finite relations
def _potential(grad: list[sp.Expr], variables: list[sp.Symbol]) -> sp.Expr | None:
    """``f`` with ``∂f/∂x_k = grad[k]`` (line integral along the axes), verified."""
    f = sp.S.Zero
    for k, x in enumerate(variables):
        rest = sp.cancel(grad[k] - derivative(f, x))
        if rest == 0:
            continue
        term = sp.integrate(rest, x)
        if term.has(sp.Integral):
            return None
        f += term
    ok = all(vanishes(derivative(f, x) - gk) for x, gk in zip(variables, grad))
    return sp.simplify(f) if ok else None


def _finite_relations(s: System) -> list[sp.Expr]:
    """Verified finite relations ``f(q, t) = const`` of integrable constraints."""
    v = s._vars
    ind_x = [v.x[i] for i in s._ind]
    dep_x = [v.x[i] for i in s._dep]
    timed = any(e.has(TIME) for e in (*s._B, *s._B0)) or s.is_affine
    extra = [TIME] if timed else []
    if not any(e.has(*dep_x) for e in (*s._B, *s._B0)):
        # Chaplygin-type constraints: q_{ε+β} − Φ_β(q_σ, t) with ∇Φ_β = (B_β, B_β0).
        out = []
        for b in range(s.g):
            grad = list(s._B.row(b)) + ([s._B0[b]] if timed else [])
            phi = _potential(grad, ind_x + extra)
            if phi is None:
                return []
            out.append(dep_x[b] - phi)
        return out
    if s.g != 1:
        return []
    # One constraint: search a few integrating factors μ for ω = Σ A_s dq_s + A_0 dt.
    coeffs = list(s._A.row(0)) + ([s._A0[0]] if timed else [])
    variables = list(v.x) + extra
    nonzero = [c for c in coeffs if c != 0]
    candidates = [sp.S.One] + [1 / c for c in nonzero] + [1 / c**2 for c in nonzero]
    candidates += [1 / (c1 * c2) for c1, c2 in combinations(nonzero, 2)]
    for mu in candidates:
        form = [sp.cancel(mu * c) for c in coeffs]
        closed = all(
            vanishes(derivative(form[j], variables[k]) - derivative(form[k], variables[j]))
            for k, j in combinations(range(len(variables)), 2)
        )
        if closed:
            f = _potential(form, variables)
            if f is not None:
                return [f]
    return []
