"""Steady motions and stability conditions, symbolically: what SymPy can do for a small reduced model.

* :func:`steady_family`: the equilibrium equations of a reduced model (the rates of the coordinates
  that are not ignorable and the accelerations vanish) solved for some unknowns in terms of the
  others: a family of steady motions over its parameters;
* :func:`stability_conditions`: the characteristic polynomial of the reduced model's Jacobian at a
  (symbolic) steady motion, its zero roots (the family's, the integrals') factored out, and the
  conditions for linear stability as SymPy inequalities: Routh–Hurwitz (asymptotic stability), or,
  for a polynomial in λ² (a conservative system's), that every root ``s = λ²`` be real and negative.

The numerical side (the exact Jacobian, the verdict, root loci) is
:mod:`chaplygin.numeric.linearization`, which also finds the ignorable coordinates passed here.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import sympy as sp
from sympy.physics.vector.printing import vsstrrepr

from chaplygin.core._fast import jacobian
from chaplygin.errors import ChaplyginError, InputError
from chaplygin.models import registry

if TYPE_CHECKING:
    from chaplygin.core.system import System

__all__ = ["StabilityConditions", "SteadyFamily", "stability_conditions", "steady_family"]


def _names(system: System) -> dict[str, sp.Symbol]:
    """Internal symbols by the names points use: ``"q"`` and ``"q'"``."""
    v = system._vars
    out = {}
    for q, x, xd in zip(system.coordinates, v.x, v.xd):
        out[q.func.__name__] = x
        out[q.func.__name__ + "'"] = xd
    return out


def _reduced(
    system: System, model: str, ignorable: Sequence[str]
) -> tuple[list[sp.Symbol], list[sp.Expr], sp.Matrix, sp.Matrix]:
    """The reduced variables (internal symbols) of a reduced model: the coordinates that are not
    ignorable, then the independent velocities; the rates of those coordinates; and ``M``, ``F`` of
    the model (``M·q̈_σ = F``), the ignorable coordinates set to 0 (they drop out)."""
    if not registry.get(model).reduced:
        raise ChaplyginError(f"the symbolic route needs a reduced model, not {model!r}.")
    eqs = system.equations(model)
    v = system._vars
    subs = system._velocity_substitution
    zero = {v.x[i]: 0 for i, q in enumerate(system.coordinates) if q.func.__name__ in ignorable}
    kept = [i for i, q in enumerate(system.coordinates) if q.func.__name__ not in ignorable]
    variables = [v.x[i] for i in kept] + [v.xd[i] for i in system._ind]
    rates = [sp.sympify(subs.get(v.xd[i], v.xd[i]), strict=True).xreplace(zero) for i in kept]
    order = [eqs._unknowns.index(v.xdd[i]) for i in system._ind]
    M = eqs._M.extract(list(range(eqs._M.rows)), order).xreplace(zero)
    return variables, rates, M, eqs._F.xreplace(zero)


def _value(what: str, value: Any) -> sp.Expr:
    """A number or a SymPy expression (never text: chaplygin does not parse user strings)."""
    if isinstance(value, sp.Expr):
        return value
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return sp.Integer(value) if isinstance(value, int) else sp.Float(value)
    raise InputError(f"{what} = {value!r}: give a number or a SymPy expression (text is not parsed).")


@dataclass
class SteadyFamily:
    """A family of steady motions: ``solutions`` (each a mapping of solved variables to
    expressions in the others), over ``parameters`` (the variables left free), from ``equations``
    (the reduced equilibrium equations that are not identically zero), with ``fixed`` the values
    given first (the coordinates at rest have zero velocity).

    The solutions are SymPy's generic ones: a branch that exists only where a denominator
    vanishes (the upright disk's ``ψ' = 0``, where any spin is steady) is not among them; give it
    in ``fixed`` to see it.
    """

    system: str
    model: str
    equations: list[sp.Expr]
    solutions: list[dict[str, sp.Expr]]
    parameters: tuple[str, ...]
    fixed: dict[str, sp.Expr]

    def __str__(self) -> str:
        lines = [f"Steady motions of {self.system} ({self.model} model)"]
        lines += [f"  held: {k} = {v}" for k, v in self.fixed.items()]
        lines += [f"  equation: {vsstrrepr(e)} = 0" for e in self.equations]
        for k, sol in enumerate(self.solutions, 1):
            lines.append(f"  family {k}: " + "; ".join(f"{name} = {vsstrrepr(e)}" for name, e in sol.items()))
        lines.append(f"  parameters: {', '.join(self.parameters) or 'none'}")
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        from chaplygin import _html

        head, *rest = str(self).splitlines()
        return _html.heading(head) + "<pre>" + _html.escape("\n".join(rest)) + "</pre>"


#: what :func:`within` returns for work still running when its time is up
TIMED_OUT = object()


def within(work: Any, seconds: float | None) -> Any:
    """``work()`` in a daemon thread, waited for in steps of 0.1 s (so that Ctrl-C is heard at
    once); its exception is raised here; :data:`TIMED_OUT` past ``seconds`` (None: no limit), the
    work then finishing unseen (Python cannot stop a thread)."""
    result: list[Any] = []
    failed: list[BaseException] = []

    def run() -> None:
        try:
            result.append(work())
        except BaseException as exc:  # passed on to the caller's thread
            failed.append(exc)

    worker = threading.Thread(target=run, daemon=True)
    started = time.monotonic()
    worker.start()
    while worker.is_alive():
        worker.join(0.1)
        if seconds is not None and worker.is_alive() and time.monotonic() - started > seconds:
            return TIMED_OUT
    if failed:
        raise failed[0]
    return result[0]


def steady_family(
    system: System,
    model: str,
    ignorable: Sequence[str],
    *,
    solve_for: Sequence[str] | None = None,
    fixed: Mapping[str, Any] | None = None,
    time_budget: float = 20.0,
) -> SteadyFamily:
    """The steady motions of a reduced model, solved by SymPy (see the module's notes).

    Parameters
    ----------
    ignorable : sequence of str
        The ignorable coordinates (their values drop out; they move uniformly).
    solve_for : sequence of str, optional
        The unknowns to solve for (``"phi'"``); by default the last reduced variables (the
        velocities, then the coordinates), one per equation.
    fixed : mapping, optional
        Values (numbers or SymPy expressions) given to some variables first.
    time_budget : float
        Seconds SymPy may spend solving; beyond it a :class:`ChaplyginError` says so.
    """
    names = _names(system)
    variables, rates, _, F = _reduced(system, model, ignorable)
    by_symbol = {s: name for name, s in names.items()}
    held = {}
    for name, value in (fixed or {}).items():
        if name not in names or names[name] not in variables:
            raise InputError(
                f"fixed: {name!r} is not a reduced variable; they are "
                f"{', '.join(by_symbol[x] for x in variables)}."
            )
        held[names[name]] = _value(f"fixed: {name}", value)
    # the coordinates at rest: an independent velocity among their rates is zero, a dependent one's
    # rate (B q̇_σ) is an equation; every acceleration vanishes, so (M nonsingular) F = 0
    xd = set(system._vars.xd)
    at_rest = {r: 0 for r in rates if r in xd}
    subs = {**at_rest, **held}
    equations = []
    for e in [*(r for r in rates if r not in xd), *F]:
        e = sp.factor_terms(sp.expand(sp.numer(sp.together(sp.sympify(e, strict=True).xreplace(subs)))))
        if e != 0:
            equations.append(e)
    unknowns = [x for x in variables if x not in subs]
    if solve_for is not None:
        chosen = []
        for name in solve_for:
            if name not in names or names[name] not in unknowns:
                raise InputError(
                    f"solve_for: {name!r} is not an unknown here; the unknowns are {', '.join(by_symbol[x] for x in unknowns)}."
                )
            chosen.append(names[name])
    else:
        chosen = unknowns[-len(equations) :] if equations else []  # the last velocities first
    solutions = []
    if equations:
        try:
            found = within(lambda: sp.solve(equations, chosen, dict=True), time_budget)
        except Exception:  # SymPy gave up: no family in closed form, as when it runs out of time
            found = TIMED_OUT
        if found is TIMED_OUT:
            raise ChaplyginError(
                f"steady_motions: SymPy did not solve the {len(equations)} equilibrium equation(s) for "
                f"{', '.join(by_symbol[x] for x in chosen)} within {time_budget:g} s; give a guess for a Newton search."
            )
        solutions = [
            {by_symbol[k]: system.to_user(sp.factor_terms(v)) for k, v in sol.items()} for sol in found
        ]
    return SteadyFamily(
        system.name,
        model,
        [system.to_user(e) for e in equations],
        solutions,
        tuple(by_symbol[x] for x in unknowns if x not in chosen),
        {**{by_symbol[k]: 0 for k in at_rest}, **{by_symbol[k]: v for k, v in held.items()}},
    )


@dataclass
class StabilityConditions:
    """Linear stability conditions of a steady motion, symbolically.

    ``polynomial``: the characteristic polynomial ``det(λI − J)`` (in ``lam``); ``zero_roots``: the
    multiplicity of ``λ = 0`` factored out; ``reduced``: what is left; ``route``: ``"hurwitz"``
    (every Hurwitz determinant positive: asymptotic stability) or ``"even"`` (a polynomial in
    ``s = λ²``: every root real, negative and simple: all eigenvalues on the imaginary axis; for
    more than two roots in ``s`` only the necessary conditions, every coefficient of the sign of
    the leading one: ``"even, necessary only"``); ``conditions``: the inequalities.
    """

    polynomial: sp.Expr
    lam: sp.Symbol
    zero_roots: int
    reduced: sp.Expr
    route: str
    conditions: list[sp.Rel]

    def __str__(self) -> str:
        lines = [
            f"characteristic polynomial: {vsstrrepr(sp.factor(self.polynomial))}",
            f"zero roots factored out: {self.zero_roots}",
            "route: "
            + {
                "even": "roots in s = lam**2 real and negative",
                "even, necessary only": "roots in s = lam**2 real and negative: necessary conditions only",
                "hurwitz": "Routh-Hurwitz",
            }[self.route],
        ]
        lines += [f"  {vsstrrepr(c)}" for c in self.conditions]
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        from chaplygin import _html

        head, *rest = str(self).splitlines()
        return _html.heading(head) + "<pre>" + _html.escape("\n".join(rest)) + "</pre>"


def stability_conditions(
    system: System, point: Mapping[str, Any], model: str, ignorable: Sequence[str]
) -> StabilityConditions:
    """The conditions for linear stability at ``point`` (names to numbers or SymPy expressions)
    of a reduced model, from its symbolic Jacobian (see the module's notes)."""
    names = _names(system)
    variables, rates, M, F = _reduced(system, model, ignorable)
    values = {}
    for name, value in point.items():
        if name not in names or names[name] not in variables:
            raise InputError(
                f"point: {name!r} is not a reduced variable of the {model} model; they are "
                f"{', '.join(k for k, s in names.items() if s in variables)}."
            )
        values[names[name]] = _value(f"point: {name}", value)
    missing = [k for k, s in names.items() if s in variables and s not in values]
    if missing:
        raise InputError(f"point: missing {', '.join(missing)}.")
    tidy = lambda e: sp.cancel(sp.trigsimp(sp.sympify(e, strict=True).xreplace(values)))  # noqa: E731
    if any(tidy(r) != 0 for r in [*rates, *F]):
        raise InputError(
            f"point: not a steady motion of the {model} model (the reduced rates do not vanish)."
        )
    # where F = 0 the accelerations' Jacobian is M⁻¹ ∂F/∂z: nothing is inverted symbolically
    # before the point is substituted
    kinematic = jacobian(rates, variables).applyfunc(tidy)
    dynamic = M.applyfunc(tidy).LUsolve(jacobian(list(F), variables).applyfunc(tidy))
    J = kinematic.col_join(dynamic).applyfunc(sp.cancel)
    lam = sp.Symbol("lam")
    poly = sp.Poly(sp.expand(J.charpoly(lam).as_expr()), lam)
    coeffs = poly.all_coeffs()[::-1]  # a_0, a_1, ...
    zeros = 0
    while zeros < len(coeffs) - 1 and sp.simplify(coeffs[zeros]) == 0:
        zeros += 1
    rest = [sp.factor(c) for c in coeffs[zeros:]]
    reduced = sp.Add(*(c * lam**k for k, c in enumerate(rest)))
    degree = len(rest) - 1
    odd = [rest[k] for k in range(1, degree + 1, 2)]
    user = lambda e: system.to_user(sp.factor(e))  # noqa: E731
    if all(sp.simplify(c) == 0 for c in odd):
        b = [rest[k] for k in range(0, degree + 1, 2)]  # q(s) = Σ b_k s^k
        if len(b) == 2:
            conditions = [sp.StrictGreaterThan(user(b[0] * b[1]), 0)]
        elif len(b) == 3:
            conditions = [
                sp.StrictGreaterThan(user(b[1] ** 2 - 4 * b[0] * b[2]), 0),
                sp.StrictGreaterThan(user(b[1] * b[2]), 0),
                sp.StrictGreaterThan(user(b[0] * b[2]), 0),
            ]
        else:
            conditions = [sp.StrictGreaterThan(user(c * b[-1]), 0) for c in b[:-1]]
        route = "even" if len(b) <= 3 else "even, necessary only"
    else:
        monic = [sp.cancel(c / rest[-1]) for c in rest]
        n = degree
        a = [monic[n - k] for k in range(n + 1)]  # a[0] = 1, a[k]: coefficient of lam**(n-k)
        H = sp.Matrix(n, n, lambda i, j: a[2 * j - i + 1] if 0 <= 2 * j - i + 1 <= n else 0)
        conditions = [sp.StrictGreaterThan(user(H[:k, :k].det()), 0) for k in range(1, n + 1)]
        route = "hurwitz"
    return StabilityConditions(
        system.to_user(poly.as_expr()), lam, zeros, system.to_user(reduced), route, conditions
    )
