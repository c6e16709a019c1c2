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

import operator
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import sympy as sp

from chaplygin.core._fast import jacobian
from chaplygin.core._rational import normal_matrix
from chaplygin.core._symbols import TIME, describe
from chaplygin.errors import SystemDefinitionError

if TYPE_CHECKING:
    from chaplygin.core.system import System

__all__ = ["Nonlinear", "read_nonlinear", "require_real", "singular_set"]


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
        for xd, e in phi.items():
            require_real(system, f"constraints[{_name(system, xd)}]", e)
    else:
        f = sp.Matrix(list(exprs))
        phi = _solve(system, f, dep_xd, branch)
    _require_smooth(system, [*f, *phi.values()], list(v.xd))
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
    """The solution of ``f = 0`` for the dependent velocities: the only real one, or ``branch``."""
    names = ", ".join(system.coordinates[i].func.__name__ + "'" for i in system._dep)
    _check_dependent(system, f, dep_xd)
    found = _solutions(list(f), dep_xd, {})
    if not found:
        raise SystemDefinitionError(
            f"constraints: SymPy cannot solve the implicit constraints for {names}; give them solved, "
            f"as a mapping {{{names.split(', ')[0]}: expression, ...}} (form B), choosing the branch."
        )
    real = [s for s in found if _real_somewhere([s[x] for x in dep_xd], "constraints")]
    if not real:
        listed = "; ".join(
            ", ".join(f"{_name(system, x)} = {_shown(system, s[x])}" for x in dep_xd) for s in found
        )
        raise SystemDefinitionError(
            f"constraints: the implicit constraints have no real solution for {names}: SymPy's "
            f"({listed}) are not real at any of {_SAMPLES} random real states, so the constraints "
            "cannot hold for real velocities."
        )
    found = sorted(real, key=lambda s: sp.default_sort_key([s[x] for x in dep_xd]))
    # a root's radicand expanded, as the user writes it: sqrt(v**2 - y'**2), not sqrt((v - y')*(v + y'))
    found = [{x: _expanded_roots(e) for x, e in s.items()} for s in found]

    def shown(k: int) -> str:
        return f"branch={k}: " + ", ".join(
            f"{_name(system, x)} = {_shown(system, found[k][x])}" for x in dep_xd
        )

    if branch is None and len(found) > 1:
        raise SystemDefinitionError(
            f"constraints: the implicit constraints have {len(found)} solutions for {names}; choose "
            "one with branch=K (a system file's branch = K under [constraints]): "
            + "; ".join(shown(k) for k in range(len(found)))
            + "."
        )
    k = 0 if branch is None else _index(branch)
    if k is None or not 0 <= k < len(found):
        raise SystemDefinitionError(
            f"branch: expected an integer from 0 to {len(found) - 1}, got {describe(branch)}; "
            + "; ".join(shown(j) for j in range(len(found)))
            + "."
        )
    return found[k]


def _expanded_roots(expr: sp.Expr) -> sp.Expr:
    """``expr`` with the base of every non-integer power expanded."""
    return expr.replace(
        lambda a: a.is_Pow and not a.exp.is_Integer, lambda a: sp.Pow(sp.expand(a.base), a.exp)
    )


#: functions whose value at a real point may be complex
_COMPLEX_AT_REAL = (sp.log, sp.asin, sp.acos, sp.acosh, sp.atanh, sp.LambertW)


def require_real(system: System, what: str, e: sp.Expr) -> None:
    """Refuse the constraint ``what`` (``e`` in internal symbols: the right side of a solved one,
    or the function that vanishes) where ``e`` is real nowhere (a root of a negative quantity):
    checked by numbers where ``e`` has a root or a function that can be complex at a real point,
    which costs a compilation."""
    roots = any(not p.exp.is_Integer for p in e.atoms(sp.Pow))
    if not (roots or e.has(*_COMPLEX_AT_REAL)):
        return
    if not _real_somewhere([e], what):
        raise SystemDefinitionError(
            f"{what} = {_shown(system, e)} is not real (or not finite) at any of {_SAMPLES} "
            "random real states, so the constraint cannot hold for real velocities."
        )


def _name(system: System, x: sp.Symbol) -> str:
    return describe(system.to_user(x))


def _shown(system: System, e: sp.Expr) -> str:
    return describe(system.to_user(e))


def _index(value: object) -> int | None:
    """``value`` as a Python integer (an int, NumPy's or SymPy's), None for anything else."""
    if isinstance(value, bool):
        return None
    try:
        return operator.index(value)  # type: ignore[arg-type]
    except TypeError:
        return None


def _solutions(
    f: list[sp.Expr], unknowns: list[sp.Symbol], known: dict[sp.Symbol, sp.Expr]
) -> list[dict[sp.Symbol, sp.Expr]]:
    """Every solution of ``f = 0`` for ``unknowns`` (``known`` substituted): an equation in one
    unknown at a time where there is one (its roots are the analytic branches, ``±e`` for
    ``v² = e²``, where a joint solve gives ``±√(e²)``, and each is much quicker), else jointly;
    each solution checked to make every ``f`` vanish."""
    from chaplygin.core._sampling import vanishes

    rest = [x for x in unknowns if x not in known]
    if not rest:
        return [dict(known)] if all(vanishes(e.xreplace(known)) for e in f) else []
    current = [e.xreplace(known) for e in f]
    single = next((e for e in current if len([x for x in rest if e.has(x)]) == 1), None)
    if single is None:
        joint = _sympy_solve([e for e in current if e.has(*rest)], rest)
        extended = [{**known, **s} for s in joint if all(x in s and not s[x].has(*rest) for x in rest)]
        _evaluate([s[x] for s in extended for x in rest], "constraints", count=1)
        return [s for e in extended for s in _solutions(f, unknowns, e)]
    (x,) = [x for x in rest if single.has(x)]
    roots = [s[x] for s in _sympy_solve([single], [x]) if x in s and not s[x].has(*rest)]
    _evaluate(roots, "constraints", count=1)  # (refuses LambertW and the like, naming it)
    return [s for r in roots for s in _solutions(f, unknowns, {**known, x: r})]


def _sympy_solve(f: list[sp.Expr], unknowns: list[sp.Symbol]) -> list[dict[sp.Symbol, sp.Expr]]:
    """SymPy's solutions (unchecked: :func:`_solutions` checks them), none where it gives up; one
    equation in one unknown without ``simplify`` (its roots as they come: ten to a hundred
    times quicker, and the same for the constraints met)."""
    try:
        if len(f) == len(unknowns) == 1:
            return [{unknowns[0]: r} for r in sp.solve(f[0], unknowns[0], check=False, simplify=False)]
        return sp.solve(f, unknowns, dict=True, check=False)
    except (NotImplementedError, ValueError):
        return []


#: random real states at which a solution must be real (somewhere) to be kept
_SAMPLES = 64
#: the magnitudes (log-uniform, either sign) of every symbol at those states: up to 1 in the
#: first half (√(1 − x² − y² − z²) is real there), up to 1e3 in the second (√(x'² − 100))
_MAGNITUDES = (1e-2, 1.0, 1e3)


def _random_points(symbols: Sequence[sp.Symbol], count: int, seed: int = 30) -> np.ndarray:
    """``count`` random real points: each symbol of either sign (positive where assumed so) and
    magnitude log-uniform in :data:`_MAGNITUDES`, as complex numbers (a root of a negative is
    complex)."""
    rng = np.random.default_rng(seed)
    low, middle, high = np.log10(_MAGNITUDES)
    top = np.where(np.arange(count) < count // 2, middle, high)[:, None]
    magnitude = 10 ** rng.uniform(low, top, size=(count, len(symbols)))
    sign = np.where(
        [bool(x.is_nonnegative) for x in symbols], 1.0, rng.choice((-1.0, 1.0), size=(count, len(symbols)))
    )
    return (sign * magnitude).astype(complex)


def _evaluate(exprs: Sequence[sp.Expr], what: str, count: int = _SAMPLES) -> np.ndarray:
    """``exprs`` at :func:`_random_points` (rows); a function with no numerical evaluation is refused."""
    from chaplygin.core._sampling import compile_function

    symbols = sorted(set().union(*(e.free_symbols for e in exprs)), key=str)
    try:
        fn = compile_function(list(exprs), symbols)
        with np.errstate(all="ignore"):
            return np.array(
                [np.asarray(fn(*p), dtype=complex).ravel() for p in _random_points(symbols, count)]
            )
    except NameError as exc:
        raise SystemDefinitionError(
            f"{what}: {getattr(exc, 'name', exc)} has no numerical evaluation in chaplygin; write the "
            "constraints with elementary functions (give them solved, as a mapping {q': expression}, "
            "where SymPy's solution needs another)."
        ) from None


def _sampled(exprs: Sequence[sp.Expr]) -> np.ndarray | None:
    """``exprs`` at :func:`_random_points` (rows) by SymEngine's evaluator, which generates no
    code (the rattleback's contact constraint: 0.07 s by ``lambdify``); None where it cannot."""
    from chaplygin.core._fast import evaluator

    symbols = sorted(set().union(*(e.free_symbols for e in exprs)), key=str)
    fn = evaluator(symbols, exprs) if symbols else None
    if fn is None:
        return None
    try:
        with np.errstate(all="ignore"):
            rows = np.asarray(fn(_random_points(symbols, _SAMPLES)), dtype=complex)
    except (RuntimeError, TypeError, ValueError):
        return None
    return rows.reshape(_SAMPLES, -1)


def _real_somewhere(values: Sequence[sp.Expr], what: str) -> bool:
    """Whether ``values`` (a solution for the dependent velocities) are real and finite together
    at one at least of :data:`_SAMPLES` random real states."""
    rows = _sampled(values)
    if rows is None:
        rows = _evaluate(values, what)
    finite = np.all(np.isfinite(rows), axis=1)
    real = np.all(np.abs(rows.imag) <= 1e-9 * (1 + np.abs(rows.real)), axis=1)
    return bool(np.any(finite & real))


def _singular_everywhere(samples: np.ndarray) -> bool:
    """Whether every one of the sampled square matrices that is real and finite is singular
    (False where none is: nothing to decide from)."""
    usable = [
        m.real
        for m in samples
        if np.all(np.isfinite(m)) and np.all(np.abs(m.imag) <= 1e-9 * (1 + np.abs(m.real)))
    ]
    return bool(usable) and not any(
        np.linalg.svd(m, compute_uv=False)[-1] > 1e-10 * max(1.0, np.abs(m).max()) for m in usable
    )


def _check_dependent(system: System, f: sp.Matrix, dep_xd: list[sp.Symbol]) -> None:
    """Refuse implicit constraints that cannot be solved for the dependent velocities anywhere:
    one without any of them, or ``∂f/∂q̇_dep`` singular at every random state."""
    names = ", ".join(_name(system, x) for x in dep_xd)
    for k, e in enumerate(f):
        if not e.has(*dep_xd):
            raise SystemDefinitionError(
                f"constraints[{k}] contains none of the dependent velocities {names}, so it cannot be "
                f"solved for them; choose dependent coordinates whose velocities it contains "
                f"(dependent=[...] names one per constraint)."
            )
    g = len(dep_xd)
    if _singular_everywhere(_evaluate(list(jacobian(f, dep_xd)), "constraints").reshape(-1, g, g)):
        raise SystemDefinitionError(
            f"constraints: ∂f/∂({names}) is singular at every sampled state, so the constraints "
            f"cannot be solved for {names} (they are dependent, or another coordinate's velocity "
            "is the one they fix); remove the redundant ones or choose other dependent coordinates."
        )


def _require_smooth(system: System, exprs: list[sp.Expr], velocities: list[sp.Symbol]) -> None:
    """Refuse a function with a kink (abs, sign, ...) of the velocities in nonlinear constraints:
    ``∂f/∂q̇`` (the Appell–Chetaev condition) and the differentiated constraints need it smooth."""
    from chaplygin.core._sampling import NOT_ANALYTIC

    for e in exprs:
        for node in e.atoms(*NOT_ANALYTIC):
            if node.has(*velocities):
                raise SystemDefinitionError(
                    f"constraints: {describe(system.to_user(node))} is not differentiable where its "
                    "argument vanishes, and the Appell–Chetaev condition and the differentiated "
                    "constraints need ∂f/∂q̇; write the branch on which the motion runs instead "
                    "(e.g. x' for abs(x') where x' > 0), or the constraint squared with branch=."
                )


def _check_block(system: System, A: sp.Matrix, phi: dict[sp.Symbol, sp.Expr]) -> None:
    """Refuse constraints whose block ``∂f/∂q̇_dep`` is singular wherever they hold: the
    Appell–Chetaev condition then does not determine the dependent displacements."""
    g = len(phi)
    block = A.extract(list(range(g)), list(system._dep)).xreplace(phi)
    if not _singular_everywhere(_evaluate(list(block), "constraints").reshape(-1, g, g)):
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
    """Expressions (internal symbols) whose zeros are the states where the constraints cannot be
    solved smoothly for the dependent velocities: where ``∂f/∂q̇_dep`` is singular on them (its
    determinant, the solved form substituted, vanishes: the multiplier models' ``A_dep`` is not
    invertible) or ``B = ∂φ/∂q̇_σ`` has a pole (the branch points)."""
    found: list[sp.Expr] = []
    state = {TIME, *system._vars.x, *system._vars.xd}  # (a factor of parameters only is no set)
    g = system.g
    block = system._A.extract(list(range(g)), list(system._dep)).xreplace(system._velocity_substitution)
    det = sp.together(block.det(method="berkowitz"))
    for part in (sp.numer(det), sp.denom(det), *(sp.denom(sp.together(e)) for e in system._B)):
        for factor in sp.Mul.make_args(sp.factor_terms(part)):
            base = factor.base if factor.is_Pow else factor
            if base.free_symbols & state and base not in found and not base.is_number:
                found.append(base)
    return found
