"""Decide whether two sets of equations of motion are the same dynamics on the constraints.

Two sets of equations describe the same motion when, at every state that
satisfies the constraints, they give the same accelerations of the
independent coordinates.  :func:`equivalent` first tries to prove this
symbolically (for small expressions), then evaluates both at many random
admissible states and reports the largest relative difference.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import sympy as sp
from sympy.physics.vector.printing import vsstrrepr

from chaplygin import _html
from chaplygin.core._sampling import StateSampler, compile_function, parameter_values
from chaplygin.core._symbols import TIME, describe, file_syntax, functions_of_time, total_derivative
from chaplygin.errors import ChaplyginError
from chaplygin.models.equations import Equations

if TYPE_CHECKING:
    from chaplygin.core.system import System

__all__ = ["EquationsLike", "EquivalenceReport", "equivalent"]

EquationsLike = Equations | Sequence[Any] | Mapping[Any, Any]

_SYMBOLIC_MAX_OPS = 600
#: states where the equations' matrix is this near singular (1/condition number) are skipped
_CONDITION = 1e-10


@dataclass
class EquivalenceReport:
    """Outcome of :func:`equivalent`; true in a boolean context when equivalent.

    Attributes
    ----------
    equivalent : bool
    method : str
        ``"symbolic"`` (proved by simplification) or ``"numeric"`` (random
        admissible states).
    max_residual : float
        Largest relative difference ``|a − b| / max(1, |a|, |b|)`` of an
        independent acceleration over the samples (0.0 when proved symbolically).
    samples : int
        Number of admissible states evaluated.
    worst : dict
        The acceleration and state where the largest difference was seen.
    checked : dict
        Where the states were drawn: a range for each coordinate (angles
        around the circle, other coordinates with both signs), t, the
        velocities and the parameters; empty when proved symbolically.
    """

    equivalent: bool
    method: str
    max_residual: float
    samples: int
    tolerance: float
    worst: dict[str, Any] = field(default_factory=dict)
    checked: dict[str, str] = field(default_factory=dict)

    def __bool__(self) -> bool:
        return self.equivalent

    def __str__(self) -> str:
        verdict = "equivalent" if self.equivalent else "NOT equivalent"
        if self.method == "symbolic":
            return f"{verdict} (proved symbolically)"
        text = (
            f"{verdict}: largest relative difference {self.max_residual:.3g} over "
            f"{self.samples} random admissible states (tolerance {self.tolerance:g})"
        )
        if not self.equivalent and self.worst:
            text += f"; worst at {self.worst['acceleration']}"
        return text + f"; sampled {where(self.checked)}"

    def _repr_html_(self) -> str:
        rows = [
            ("verdict", "equivalent" if self.equivalent else "NOT equivalent"),
            ("method", self.method),
            ("largest relative difference", f"{self.max_residual:.3g}"),
            ("samples", str(self.samples)),
            ("tolerance", f"{self.tolerance:g}"),
        ]
        if self.checked:
            rows.append(("sampled", where(self.checked)))
        if not self.equivalent and self.worst:
            rows.append(("worst at", str(self.worst.get("acceleration", ""))))
        return _html.fields((label, _html.escape(value)) for label, value in rows)


class Inconsistent(ChaplyginError):
    """Equations with no solution at an admissible state: they contradict the constraints there."""

    def __init__(self, label: str, mismatch: float) -> None:
        super().__init__(f"{label}: the equations are inconsistent at a random admissible state.")
        self.label, self.mismatch = label, mismatch


def where(checked: Mapping[str, str]) -> str:
    """``checked`` of a report in one line: ``x ∈ ±[0.1, 10], phi ∈ (-π, π), ...``."""
    return ", ".join(f"{name} ∈ {span}" for name, span in checked.items())


class _Linear:
    """Equations reduced to ``M(state)·x = F(state)`` in internal symbols."""

    def __init__(
        self, system: System, eqs: EquationsLike, label: str, constants: Sequence[sp.Symbol] = ()
    ) -> None:
        self.system = system
        self.label = label
        v = system._vars
        #: multipliers that are state variables (μ of the vakonomic model)
        self.extra_state: list[sp.Symbol] = []
        self.constants: list[sp.Symbol] = list(constants)
        if isinstance(eqs, Equations):
            if eqs.system is not system:
                raise ChaplyginError(f"{label}: these equations were derived for another system.")
            self.unknowns = list(eqs._unknowns)
            self.M, self.F = eqs._M, eqs._F
            self.extra_state = list(eqs._state)
            self.constants = list(eqs.constants)
            self.names = {u: eqs._user(u) for u in eqs._state}
            self.symbolic: Equations | None = eqs
            self._back = dict(eqs._to_fun)
            return
        self.symbolic = None
        if isinstance(eqs, Mapping):
            rows = [sp.Eq(k, val) for k, val in eqs.items()]
        elif isinstance(eqs, (str, sp.Basic)) or not isinstance(eqs, Sequence):
            raise ChaplyginError(
                f"{label}: expected an Equations object, a list of equations (sympy.Eq or "
                "expressions equal to zero) or a mapping {q.diff(t, 2): expression}."
            )
        else:
            rows = list(eqs)
        exprs = []
        for k, row in enumerate(rows):
            if isinstance(row, sp.Eq):
                exprs.append(row.lhs - row.rhs)
            elif isinstance(row, sp.Expr):
                exprs.append(row)
            else:
                raise ChaplyginError(f"{label}[{k}]: {describe(row)} is not a SymPy equation or expression.")
        to_sym = dict(system._to_sym)
        multipliers = []
        self.names = {}
        others = set().union(*(functions_of_time(e) for e in exprs)) - set(system.coordinates)
        for f in sorted(others, key=str):
            to_sym[f] = sp.Dummy(f.func.__name__)
            if any(e.has(f.diff(TIME)) for e in exprs):  # μ(t) with μ̇: μ is state, μ̇ unknown
                to_sym[f.diff(TIME)] = sp.Dummy(f.func.__name__ + "_d")
                self.extra_state.append(to_sym[f])
                self.names[to_sym[f]] = f
                multipliers.append(to_sym[f.diff(TIME)])
            else:  # λ(t) alone: an unknown like the accelerations
                multipliers.append(to_sym[f])
        self._back = {v: k for k, v in to_sym.items()}
        converted = [e.xreplace(to_sym) for e in exprs]
        leftover = [d for e in converted for d in e.atoms(sp.Derivative)]
        if leftover:
            raise ChaplyginError(f"{label}: cannot interpret {self._shown(leftover[0])}.")
        unknowns = [a for a in v.xdd if any(e.has(a) for e in converted)] + multipliers
        res = sp.Matrix(converted)
        self.unknowns = unknowns
        self.M = res.jacobian(unknowns)
        if any(e.has(*unknowns) for e in self.M):
            raise ChaplyginError(
                f"{label}: the equations are not linear in the accelerations and multipliers."
            )
        self.F = -res.xreplace({u: 0 for u in unknowns})
        extra = (
            (self.M.free_symbols | self.F.free_symbols)
            - set(system.parameters)
            - {TIME, *v.x, *v.xd, *v.xdd, *unknowns, *self.extra_state, *self.constants}
        )
        if extra:
            raise ChaplyginError(
                f"{label}: unknown symbol(s) {', '.join(sorted(map(str, extra)))}; the system's "
                f"parameters are {', '.join(p.name for p in system.parameters) or 'none'}."
            )

    def _shown(self, internal: sp.Expr) -> str:
        """An internal symbol or expression as the user wrote it (``q''``, ``lambda_1``), for messages."""
        return file_syntax(internal.xreplace(self._back))

    def compile(self, args: list[sp.Symbol]) -> None:
        s, v = self.system, self.system._vars
        M, F = self.M, self.F
        dep_unknown = [v.xdd[i] for i in s._dep if v.xdd[i] in self.unknowns]
        if dep_unknown:  # add the differentiated constraints q̈_dep = B q̈_σ + Ḃ q̇_σ + Ḃ_0
            pairs = list(zip(v.x, v.xd)) + [(v.xd[i], v.xdd[i]) for i in s._ind]
            extra_unknowns = [v.xdd[i] for i in s._ind if v.xdd[i] not in self.unknowns]
            self.unknowns = self.unknowns + extra_unknowns
            M = M.row_join(sp.zeros(M.rows, len(extra_unknowns)))
            for i in s._dep:
                rhs = s._velocity_substitution[v.xd[i]]
                row = v.xdd[i] - total_derivative(rhs, pairs)
                M = M.col_join(sp.Matrix([row]).jacobian(self.unknowns))
                F = F.col_join(sp.Matrix([-row.xreplace({a: 0 for a in v.xdd})]))
        missing = [v.xdd[i] for i in s._ind if v.xdd[i] not in self.unknowns]
        if missing:
            raise ChaplyginError(
                f"{self.label}: the equations do not determine "
                + ", ".join(map(self._shown, missing))
                + " (they do not contain them)."
            )
        self.args = args + self.extra_state + self.constants
        self._f = compile_function([M, F], self.args)
        self.index = {u: k for k, u in enumerate(self.unknowns)}
        self.independent = [self.index[v.xdd[i]] for i in s._ind]

    def accelerations(self, values: Mapping[sp.Symbol, float]) -> np.ndarray | None:
        """Independent accelerations at ``values`` (None where the equations are not finite)."""
        with np.errstate(all="ignore"):
            M, F = self._f(*(values[a] for a in self.args))
        M = np.atleast_2d(np.asarray(M, dtype=float))
        F = np.asarray(F, dtype=float).reshape(-1)
        if not (np.all(np.isfinite(M)) and np.all(np.isfinite(F))):
            return None
        x, _, rank, singular = np.linalg.lstsq(M, F, rcond=None)
        if rank < M.shape[1]:
            raise ChaplyginError(
                f"{self.label}: the equations do not determine all of "
                + ", ".join(map(self._shown, self.unknowns))
                + " at a random admissible state."
            )
        if singular[-1] < _CONDITION * singular[0]:  # near a singularity: the solve is not to be trusted
            return None
        mismatch = float(np.linalg.norm(M @ x - F)) / max(1.0, float(np.linalg.norm(F)))
        if mismatch > 1e-8:
            raise Inconsistent(self.label, mismatch)
        return x[self.independent]


class _States:
    """Random admissible states with values for parameters, constants and state multipliers."""

    def __init__(
        self,
        system: System,
        reps: Sequence[_Linear],
        *,
        parameters: Mapping[Any, float] | None,
        multipliers: Mapping[Any, sp.Expr] | None,
        seed: int,
    ) -> None:
        self.system, self.reps = system, reps
        self.rng = np.random.default_rng(seed)
        constants = {c.name: c for r in reps for c in r.constants}
        from chaplygin.models.vakonomic import constant_symbols

        family = {c.name for c in constant_symbols(system)}
        for expr in (multipliers or {}).values():
            if isinstance(expr, sp.Basic):  # c_β of integrated_multipliers(): more constants
                for sym in expr.free_symbols:
                    if getattr(sym, "name", None) in family:
                        constants.setdefault(sym.name, sym)
        given = dict(parameters or {})
        fixed_constants = {constants[str(k)]: float(given.pop(k)) for k in list(given) if str(k) in constants}
        params = parameter_values(system, self.rng, given)
        self.constants = {
            c: fixed_constants.get(c, float(self.rng.uniform(-1, 1))) for c in constants.values()
        }
        self.sampler = StateSampler(system, params, [e for r in reps for e in (*r.M, *r.F)])
        v = system._vars
        self.state_symbols = [TIME, *v.x, *v.xd, *params]
        for r in reps:
            r.compile(self.state_symbols)
        self.given_multipliers = self._compile_multipliers(multipliers or {})

    def _compile_multipliers(self, given: Mapping[Any, sp.Expr]) -> dict[str, Any]:
        out = {}
        args = self.state_symbols + list(self.constants)
        known = {str(r.names[m].func.__name__): m for r in self.reps for m in r.extra_state}
        for key, expr in given.items():
            name = (
                key.func.__name__
                if isinstance(key, sp.Expr) and hasattr(key, "func") and key.args == (TIME,)
                else str(key)
            )
            if name not in known:
                raise ChaplyginError(
                    f"multipliers: {name} is not a state multiplier of these equations; they have "
                    f"{', '.join(known) or 'none'}."
                )
            value = expr.xreplace(self.system._to_sym) if isinstance(expr, sp.Basic) else sp.Float(expr)
            unknown = value.free_symbols - set(args)
            if unknown:
                raise ChaplyginError(
                    f"multipliers[{name}]: cannot evaluate "
                    f"{', '.join(sorted(file_syntax(self.system.to_user(u)) for u in unknown))}; "
                    "write μ in the coordinates, velocities and parameters of the system."
                )
            out[name] = compile_function(value, args)
        return out

    def draw(self) -> tuple[dict[sp.Symbol, float], dict[sp.Symbol, float]]:
        """One admissible state, plus values for constants and state multipliers."""
        state = self.sampler.draw(self.rng)
        values = dict(state)
        values.update(self.constants)
        args = [values[s] for s in self.state_symbols + list(self.constants)]
        for r in self.reps:
            for m in r.extra_state:
                name = r.names[m].func.__name__
                f = self.given_multipliers.get(name)
                values[m] = float(f(*args)) if f else float(self.rng.uniform(-1, 1))
        return state, values


def _symbolic_proof(system: System, a: _Linear, b: _Linear) -> bool:
    """Compare solved accelerations symbolically — only where solving them stays cheap."""
    if a.symbolic is None or b.symbolic is None or a.extra_state or b.extra_state:
        return False
    size = sum(sp.count_ops(e) for r in (a, b) for e in (*r.M, *r.F))
    if size > _SYMBOLIC_MAX_OPS:
        return False
    sub = system._velocity_substitution
    for acc in (system._vars.xdd[i] for i in system._ind):
        ea, eb = a.symbolic._accelerations.get(acc), b.symbolic._accelerations.get(acc)
        if ea is None or eb is None:
            return False
        diff = (ea - eb).xreplace(sub)
        if sp.count_ops(diff) > _SYMBOLIC_MAX_OPS:
            return False
        if sp.trigsimp(sp.cancel(sp.expand(diff))) != 0:
            return False
    return True


def equivalent(
    system: System,
    first: EquationsLike,
    second: EquationsLike,
    *,
    parameters: Mapping[Any, float] | None = None,
    multipliers: Mapping[Any, sp.Expr] | None = None,
    samples: int = 24,
    tolerance: float = 1e-8,
    seed: int = 0,
    symbolic: bool = True,
) -> EquivalenceReport:
    """Are ``first`` and ``second`` the same dynamics on the constraint manifold?

    Parameters
    ----------
    system : System
    first, second : Equations, list of sympy.Eq or expressions, or mapping
        Equations of motion written with the system's dynamicsymbols: an
        :class:`Equations` object, a list of equations (expressions are taken
        ``= 0``; multipliers such as ``λ(t)`` may appear and are eliminated, and
        a multiplier that appears differentiated, like the vakonomic ``μ(t)``,
        is a state variable), or a mapping ``{q.diff(t, 2): expression}`` of
        solved accelerations.  Equations that contain dependent accelerations
        are completed with the differentiated constraints.
    parameters : mapping, optional
        Numeric values of (some) parameters and of constants ``c_β`` of a
        vakonomic family; the others are drawn at random (the same for both).
    multipliers : mapping, optional
        State multipliers as expressions of the state, e.g.
        ``{mu_1: c_1 - T.diff(x.diff(t))}``; without it they are drawn at random.
    samples : int
        Number of random admissible states.
    tolerance : float
        Largest relative difference accepted.
    seed : int
        Seed of the random states (the check is reproducible).
    symbolic : bool
        Try a symbolic proof first (for small expressions).

    Returns
    -------
    EquivalenceReport
    """
    constants = [c for e in (first, second) if isinstance(e, Equations) for c in e.constants]
    a = _Linear(system, first, "first", constants)
    b = _Linear(system, second, "second", constants)
    if symbolic and not parameters and not multipliers and _symbolic_proof(system, a, b):
        return EquivalenceReport(True, "symbolic", 0.0, 0, tolerance)
    states = _States(system, [a, b], parameters=parameters, multipliers=multipliers, seed=seed)
    watched = [system.to_user(system._vars.xdd[i]) for i in system._ind]
    worst: dict[str, Any] = {}
    max_res, used, tries = 0.0, 0, 0
    while used < samples and tries < 20 * samples:
        tries += 1
        state, values = states.draw()
        shown_state = {vsstrrepr(system.to_user(key)): val for key, val in state.items()}
        try:
            xa, xb = a.accelerations(values), b.accelerations(values)
        except Inconsistent as exc:  # no solution here: they cannot be the same dynamics
            used += 1
            if exc.mismatch > max_res:
                max_res = exc.mismatch
                what = f"the constraints (the {exc.label} equations have no solution there)"
                worst = {"acceleration": what, "first": np.nan, "second": np.nan, "state": shown_state}
            continue
        if xa is None or xb is None:
            continue
        used += 1
        res = np.abs(xa - xb) / np.maximum(1.0, np.maximum(np.abs(xa), np.abs(xb)))
        k = int(np.argmax(res))
        if res[k] > max_res:
            max_res = float(res[k])
            worst = {
                "acceleration": vsstrrepr(watched[k]),
                "first": float(xa[k]),
                "second": float(xb[k]),
                "state": shown_state,
            }
    if used == 0:
        raise ChaplyginError("no random admissible state gave finite values for both sets of equations.")
    verdict = bool(max_res <= tolerance)
    return EquivalenceReport(verdict, "numeric", max_res, used, tolerance, worst, states.sampler.where())
