"""The mechanical system: coordinates, kinetic energy, forces and linear velocity constraints.

Notation follows the seed paper (Liang & Chen 2000) and ``docs/theory.md``:
``n`` coordinates, ``g`` constraints, ``ε = n − g`` independent coordinates
``q_σ`` and dependent ones ``q_{ε+β}``.  Constraints are accepted in

* **form A**, eq. (1): ``Σ_s A_βs(q, t) q̇_s + A_β0(q, t) = 0``, and
* **form B**, eq. (2): ``q̇_{ε+β} = Σ_σ B_βσ(q, t) q̇_σ + B_β0(q, t)``,

the velocity-free terms ``A_β0``/``B_β0`` being Voronets' affine (rheonomic) case.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np
import sympy as sp
from symengine import DenseMatrix
from sympy.core.function import AppliedUndef

from chaplygin.core._fast import (
    _back,
    _restore_map,
    derivative,
    evaluator,
    gradient,
    jacobian,
    native,
    to_sympy,
)
from chaplygin.core._native import is_quadratic, linear_split, momenta, vanishes_at_rest
from chaplygin.core._operations import operation
from chaplygin.core._rational import exact_numbers, floated, normal_matrix, solve_columns
from chaplygin.core._symbols import (
    TIME,
    Vars,
    describe,
    file_syntax,
    functions_of_time,
    linear_coefficients,
    other_undefined,
    simplify_small,
)
from chaplygin.errors import SystemDefinitionError

if TYPE_CHECKING:
    from chaplygin.analysis.integrability import IntegrabilityReport
    from chaplygin.core._native import Native
    from chaplygin.models.equations import Equations

__all__ = ["System"]

_SAMPLES = 6  # random points used to decide that a matrix is singular everywhere


def _as_expr(value: Any, what: str | Callable[[], str]) -> sp.Expr:
    """Accept SymPy expressions and Python numbers; refuse everything else (``what`` names the
    input in the message: a string, or a function giving it, called only for a message)."""
    if isinstance(value, sp.Eq):
        return value.lhs - value.rhs
    if isinstance(value, sp.Expr):
        return value
    if callable(what):
        what = what()
    if isinstance(value, bool):
        raise SystemDefinitionError(f"{what}: expected a SymPy expression, got the boolean {value!r}.")
    if isinstance(value, int):
        return sp.Integer(value)
    if isinstance(value, float):
        return sp.Float(value)
    if isinstance(value, str):
        raise SystemDefinitionError(
            f"{what}: got the string {value!r}; give a SymPy expression built from the "
            "coordinates (chaplygin never evaluates text as code)."
        )
    raise SystemDefinitionError(
        f"{what}: expected a SymPy expression or a number, got {type(value).__name__} {value!r}."
    )


def _constants_key(constants: Any) -> Any:
    if isinstance(constants, Mapping):
        return tuple(sorted((str(k), str(v)) for k, v in constants.items()))
    if isinstance(constants, Sequence) and not isinstance(constants, str):
        return tuple(str(c) for c in constants)
    return None if constants is None else str(constants)


class System:
    """A mechanical system with linear (possibly affine) velocity constraints.

    Parameters
    ----------
    coordinates : sequence of dynamicsymbols
        Generalized coordinates ``q_1 … q_n``, functions of ``t`` made with
        ``sympy.physics.mechanics.dynamicsymbols``.  Velocities are their time
        derivatives ``q.diff(t)``.
    kinetic_energy : sympy.Expr
        ``T(q, q̇, t)``, a polynomial of degree at most two in the velocities.
    constraints : mapping or sequence
        Either form B, eq. (2): a mapping ``{q̇_dep: expression}`` whose values are
        linear in the independent velocities, optionally plus a velocity-free term
        ``B_β0(q, t)``; or form A, eq. (1): a sequence of expressions linear in the
        velocities that vanish (``sympy.Eq`` accepted), together with ``dependent``.
    dependent : sequence of dynamicsymbols, optional
        The dependent coordinates ``q_{ε+β}`` for form A, one per constraint, in
        the order of the constraints.
    potential_energy : sympy.Expr, optional
        ``V(q, t)``; the force function is then ``U = −V``.
    force_function : sympy.Expr, optional
        ``U(q, t)`` with generalized forces ``Q_s = ∂U/∂q_s``.  Not together with
        ``potential_energy``.
    forces : mapping, optional
        Non-potential generalized forces ``{coordinate: Q_s(q, q̇, t)}``.
    holonomic : mapping, optional
        Holonomic (configuration) constraints ``{q_dep: f(q, t)}``: each relation
        ``f = 0`` (``sympy.Eq`` accepted) fixes the coordinate it is keyed by, which
        must not be a dependent coordinate of the velocity constraints.  Its time
        derivative ``Σ_s ∂f/∂q_s q̇_s + ∂f/∂t = 0`` joins the velocity constraints
        (form A, the last rows of :attr:`A`), so every model treats it as a
        constraint; ``simulate`` solves the dependent coordinates from ``f = 0`` at
        the start and monitors ``f`` along the run.
    name : str, optional
        A human-readable name.

    Notes
    -----
    Every symbol other than ``t`` that appears in the input is a parameter
    (:attr:`parameters`).  Validation happens here, at construction: bad input
    raises :class:`~chaplygin.errors.SystemDefinitionError` naming the
    offending item.
    """

    def __init__(
        self,
        coordinates: Sequence[sp.Expr],
        kinetic_energy: sp.Expr,
        constraints: Mapping[sp.Expr, sp.Expr] | Sequence[sp.Expr],
        *,
        dependent: Sequence[sp.Expr] | None = None,
        potential_energy: sp.Expr | None = None,
        force_function: sp.Expr | None = None,
        forces: Mapping[sp.Expr, sp.Expr] | None = None,
        holonomic: Mapping[sp.Expr, sp.Expr] | None = None,
        branch: int | None = None,
        name: str | None = None,
    ) -> None:
        self.name = name or "system"
        self.coordinates: tuple[sp.Expr, ...] = self._check_coordinates(coordinates)
        self.n = len(self.coordinates)
        #: the precision of the Floats the system was written with (None: none); inside, exact
        self._float_prec: int | None = None
        self._vars = Vars(self.coordinates)
        self._to_sym = self._vars.to_symbols()
        self._to_fun = {value: key for key, value in self._to_sym.items()}
        v = self._vars

        self.kinetic_energy = _as_expr(kinetic_energy, "kinetic_energy")
        self._convert(self.kinetic_energy, "kinetic_energy", replace=False)  # _T when first needed
        self._check_kinetic_energy()

        if potential_energy is not None and force_function is not None:
            raise SystemDefinitionError(
                "give either potential_energy V or force_function U (U = -V), not both."
            )
        self.potential_energy = (
            None if potential_energy is None else _as_expr(potential_energy, "potential_energy")
        )
        if force_function is not None:
            self.force_function = _as_expr(force_function, "force_function")
        elif self.potential_energy is not None:
            self.force_function = -self.potential_energy
        else:
            self.force_function = sp.S.Zero
        what = "force_function" if force_function is not None else "potential_energy"
        self._U = self._convert(self.force_function, what)
        if self._U.has(*v.xd):
            raise SystemDefinitionError(
                f"{what} depends on the velocities; velocity-dependent forces go in forces={{...}}."
            )

        self.forces: dict[sp.Expr, sp.Expr] = {}
        self._Qnp: list[sp.Expr] = [sp.S.Zero] * self.n
        for key, value in (forces or {}).items():
            i = self._coordinate_index(key, "forces")
            what = f"forces[{self.coordinates[i].func.__name__}]"
            self.forces[self.coordinates[i]] = _as_expr(value, what)
            self._Qnp[i] = self._convert(self.forces[self.coordinates[i]], what)

        #: constraints nonlinear in the velocities (:mod:`chaplygin.core._nonlinear`): None if linear
        self._nonlinear: Any = None
        self._branch = branch
        self._read_constraints(constraints, dependent)
        if self._nonlinear is None and branch is not None:
            raise SystemDefinitionError(
                "branch: the constraints are linear in the velocities, so they have one solution "
                "for the dependent velocities; branch= applies to constraints nonlinear in them."
            )
        self._read_holonomic(holonomic)
        self.independent = tuple(self.coordinates[i] for i in self._ind)
        self.dependent = tuple(self.coordinates[i] for i in self._dep)
        self.g = len(self._dep)
        self.velocities = tuple(q.diff(TIME) for q in self.coordinates)

        symbols: set[sp.Symbol] = set()
        relations = [f for _, f in self._holonomic]  # (a constant in f is not in its derivative)
        for expr in (self.kinetic_energy, self._U, *self._Qnp, *self._constraint_parts(), *relations):
            symbols |= expr.free_symbols
        symbols -= {TIME, *v.x, *v.xd, *v.xdd}
        self.parameters: tuple[sp.Symbol, ...] = tuple(sorted(symbols, key=lambda s: s.name))
        self._check_reduced_mass_matrix()
        self._equations: dict[tuple[Any, ...], Equations] = {}

    # ------------------------------------------------------------------ input checks
    @staticmethod
    def _check_coordinates(coordinates: Sequence[sp.Expr]) -> tuple[sp.Expr, ...]:
        if isinstance(coordinates, (str, sp.Basic)) or not isinstance(coordinates, Iterable):
            raise SystemDefinitionError(
                "coordinates: expected a list of dynamicsymbols, e.g. dynamicsymbols('x y')."
            )
        coords = tuple(coordinates)
        if not coords:
            raise SystemDefinitionError("coordinates: at least one coordinate is needed.")
        for q in coords:
            if not (isinstance(q, AppliedUndef) and q.args == (TIME,)):
                hint = (
                    f" Use dynamicsymbols('{q}') instead of a plain Symbol."
                    if isinstance(q, sp.Symbol)
                    else ""
                )
                raise SystemDefinitionError(
                    f"coordinate {describe(q)} is not a function of t made with "
                    f"sympy.physics.mechanics.dynamicsymbols.{hint}"
                )
        names = [q.func.__name__ for q in coords]
        for nm in names:
            if names.count(nm) > 1:
                raise SystemDefinitionError(f"coordinate {nm} is listed more than once.")
        return coords

    def _coordinate_index(self, key: Any, where: str) -> int:
        """Index of a coordinate given as a dynamicsymbol or its name."""
        for i, q in enumerate(self.coordinates):
            if key == q or key == q.func.__name__:
                return i
        raise SystemDefinitionError(
            f"{where}: {describe(key)} is not one of the coordinates "
            f"{', '.join(q.func.__name__ for q in self.coordinates)}."
        )

    def _convert(
        self, expr: sp.Expr, what: str, *, allow_velocities: bool = True, replace: bool = True
    ) -> sp.Expr:
        """Check functions/derivatives in ``expr`` and replace them by plain symbols (unless not ``replace``)."""
        coords = set(self.coordinates)
        unknown = functions_of_time(expr) - coords
        if unknown:
            f = sorted(unknown, key=str)[0]
            raise SystemDefinitionError(
                f"{what} contains the unknown function {f.func.__name__}(t); the coordinates are "
                f"{', '.join(q.func.__name__ for q in self.coordinates)}. Add it to the "
                "coordinates, or write it as a plain Symbol if it is a constant."
            )
        odd = other_undefined(expr)
        if odd:
            f = sorted(odd, key=str)[0]
            raise SystemDefinitionError(
                f"{what} contains {describe(f)}: only functions of time t (dynamicsymbols) are understood."
            )
        for d in expr.atoms(sp.Derivative):
            if d.expr not in coords or d.variables != (TIME,):
                order = "a second or higher derivative" if d.expr in coords else "a derivative"
                raise SystemDefinitionError(
                    f"{what} contains {order} {describe(d)}; only first time derivatives of "
                    "the coordinates (velocities) may appear."
                )
        if not replace:
            return expr
        out = self._exact(expr).xreplace(self._to_sym)
        if not allow_velocities and out.has(*self._vars.xd):
            raise SystemDefinitionError(f"{what} must not depend on the velocities.")
        return out

    def _exact(self, expr: sp.Expr) -> sp.Expr:
        """``expr`` with its Floats as the exact rationals written (:func:`exact_numbers`): every
        derivation is exact; :meth:`to_user` shows the numbers as Floats again."""
        out, prec = exact_numbers(expr)
        if prec is not None:
            self._float_prec = max(prec, self._float_prec or 0)
        return out

    def _check_kinetic_energy(self) -> None:
        xd = self._vars.xd
        T = self._native_T
        quadratic = None if T is None else is_quadratic(T, self._native_xd, *self._native_momenta)
        if quadratic is None:  # not shown by SymEngine: SymPy's Poly decides
            poly = sp.Poly(self._T, *xd) if self._T.is_polynomial(*xd) else None
            quadratic = (
                (False, True) if poly is None else (poly.total_degree() <= 2, poly.total_degree() >= 2)
            )
        if not quadratic[0]:
            raise SystemDefinitionError(
                "kinetic_energy is not quadratic in the velocities: T must be a polynomial of "
                f"degree at most 2 in the velocities of {', '.join(q.func.__name__ for q in self.coordinates)}; "
                f"got T = {describe(self.kinetic_energy)}."
            )
        if not quadratic[1]:
            raise SystemDefinitionError(
                "kinetic_energy has no term quadratic in the velocities; "
                f"got T = {describe(self.kinetic_energy)}."
            )
        if T is not None and vanishes_at_rest(T, self._native_xd, self._native_momenta[0]):
            # T = T₂ shown by SymEngine here: :attr:`_quadratic_T` needs no SymPy expansion
            # (the rattleback's took 0.06 s of a cold build)
            self.__dict__["_quadratic_T"] = True

    def _read_constraints(self, constraints: Any, dependent: Sequence[sp.Expr] | None) -> None:
        v = self._vars
        if isinstance(constraints, Mapping):
            if dependent is not None:
                given = [self._coordinate_index(d, "dependent") for d in dependent]
            self._form = "B"
            dep: list[int] = []
            rhs: list[sp.Expr] = []
            for key, value in constraints.items():
                dep.append(self._dependent_velocity_index(key))
                rhs.append(_as_expr(value, lambda: f"constraints[{describe(key)}]"))  # noqa: B023 - used at once
            if len(set(dep)) != len(dep):
                raise SystemDefinitionError("constraints: a dependent velocity appears twice.")
            if dependent is not None and sorted(given) != sorted(dep):
                raise SystemDefinitionError(
                    "dependent does not match the velocities solved for in constraints."
                )
            self._dep = tuple(dep)
            self._ind = tuple(i for i in range(self.n) if i not in dep)
            self._given_constraints = tuple(rhs)  # as given (the key of chaplygin.numeric._modelcache)
            self._check_counts()
            ind_xd = [v.xd[i] for i in self._ind]
            internal, splits = [], []
            for d, expr in zip(dep, rhs):
                what = f"constraints[{self.coordinates[d].func.__name__}']"
                e = self._convert(expr, what)
                bad = [self.coordinates[j] for j in dep if e.has(v.xd[j])]
                if bad:
                    raise SystemDefinitionError(
                        f"{what} contains the dependent velocity {describe(bad[0].diff(TIME))}; "
                        "form B expresses dependent velocities through independent ones only."
                    )
                internal.append(e)
                # (unfactored: B and B_0 are put in normal form below, whatever form they come in)
                splits.append(linear_coefficients(e, ind_xd, factored=False))
            if any(split is None for split in splits):  # nonlinear in the velocities: φ given (every row)
                self._set_nonlinear(internal, solved=True)
                return
            from chaplygin.core._nonlinear import require_real

            for d, e in zip(dep, internal):  # (a root of a velocity-free term: real somewhere?)
                require_real(self, f"constraints[{self.coordinates[d].func.__name__}']", e)
            rows = [split[0] for split in splits if split is not None]
            consts = [split[1] for split in splits if split is not None]
            g = len(dep)
            # each coefficient in normal form (tan as sin/cos, cancelled), as form A's are solved
            self._B = normal_matrix(sp.Matrix(g, len(self._ind), [c for r in rows for c in r]))
            self._B0 = normal_matrix(sp.Matrix(g, 1, consts))
            self._A = sp.zeros(g, self.n)
            for b in range(g):
                self._A[b, dep[b]] = 1
                for k, i in enumerate(self._ind):
                    self._A[b, i] = -self._B[b, k]
            self._A0 = -self._B0
            return

        if isinstance(constraints, (str, sp.Basic)) or not isinstance(constraints, Iterable):
            raise SystemDefinitionError(
                "constraints: expected a mapping {dependent velocity: expression} (form B) or a "
                "list of expressions that vanish (form A) with dependent=[...]."
            )
        exprs = [_as_expr(c, f"constraints[{k}]") for k, c in enumerate(constraints)]
        self._form = "A"
        if exprs and dependent is None:
            raise SystemDefinitionError(
                f"constraints: {len(exprs)} implicit constraint(s) (form A) need "
                "dependent=[...] naming as many dependent coordinates."
            )
        dep = [self._coordinate_index(d, "dependent") for d in (dependent or [])]
        if len(dep) != len(exprs):
            raise SystemDefinitionError(
                f"dependent names {len(dep)} coordinate(s) but there are {len(exprs)} "
                "constraint(s); give one dependent coordinate per constraint."
            )
        if len(set(dep)) != len(dep):
            raise SystemDefinitionError("dependent: a coordinate is listed twice.")
        self._dep = tuple(dep)
        self._ind = tuple(i for i in range(self.n) if i not in dep)
        self._given_constraints = tuple(exprs)  # as given (the key of chaplygin.numeric._modelcache)
        self._check_counts()
        rows, consts = [], []
        fast = self._internal_native(exprs)  # SymEngine where it can, SymPy (A built here) where not
        for k, expr in enumerate(exprs):
            if any(not p.exp.is_Integer for p in expr.atoms(sp.Pow)):  # a root: real somewhere?
                from chaplygin.core._nonlinear import require_real

                require_real(self, f"constraints[{k}]", self._convert(expr, f"constraints[{k}]"))
            e = self._convert(expr, f"constraints[{k}]", replace=fast is None)
            split = (
                linear_coefficients(e, list(v.xd)) if fast is None else linear_split(fast[k], self._native_xd)
            )
            if split is None:
                internal = [self._convert(x, f"constraints[{j}]") for j, x in enumerate(exprs)]
                for j, x in enumerate(internal):
                    if not x.has(*v.xd):
                        self._refuse_velocity_free(j, exprs[j])
                self._set_nonlinear(internal)
                return
            if all(c == 0 for c in split[0]):
                self._refuse_velocity_free(k, expr)
            rows.append(split[0])
            consts.append(split[1])
        g = len(exprs)
        if fast is None:
            self._A = sp.Matrix(g, self.n, [c for r in rows for c in r])
            self._A0 = sp.Matrix(g, 1, consts)
        else:
            self._native_A = (rows, consts)
            self._restore = _restore_map(exprs)
        if g:
            self._check_dependent_block()  # B and B_0 are solved for when first needed
        else:
            self._B = sp.zeros(0, self.n)
            self._B0 = sp.zeros(0, 1)

    @staticmethod
    def _refuse_velocity_free(k: int, expr: sp.Expr) -> None:
        raise SystemDefinitionError(
            f"constraints[{k}] contains no velocity: {describe(expr)}. A finite "
            "(holonomic) relation f(q, t) = 0 goes in holonomic={coordinate it fixes: f} "
            "(a system file's [holonomic] table), or is used to eliminate a coordinate."
        )

    def _set_nonlinear(self, exprs: list[sp.Expr], *, solved: bool = False) -> None:
        """Constraints of which one at least is nonlinear in the velocities (internal ``exprs``:
        the solved right sides φ, or the implicit f): :mod:`chaplygin.core._nonlinear`."""
        from chaplygin.core._nonlinear import read_nonlinear

        self.__dict__.pop("_native_A", None)
        self.g = len(self._dep)
        found = read_nonlinear(self, exprs, solved=solved, branch=self._branch)
        self._nonlinear = found
        self._A, self._A0, self._B, self._B0 = found.A, found.A0, found.B, found.B0
        self._velocity_substitution = found.phi

    def _read_holonomic(self, holonomic: Any) -> None:
        """Append the time derivative of each relation ``f(q, t) = 0`` as the last velocity
        constraints (form A: ``Σ_s ∂f/∂q_s q̇_s + ∂f/∂t = 0``), its coordinate the last dependent."""
        self.holonomic: dict[sp.Expr, sp.Expr] = {}
        self._holonomic: tuple[tuple[int, sp.Expr], ...] = ()
        if holonomic is None:
            return
        if isinstance(holonomic, (str, sp.Basic)) or not isinstance(holonomic, Mapping):
            raise SystemDefinitionError(
                "holonomic: expected a mapping {coordinate: f(q, t)} of relations f = 0, each keyed "
                f"by the coordinate it fixes; got {describe(holonomic)}."
            )
        if self._nonlinear is not None:
            raise SystemDefinitionError(
                "holonomic: holonomic constraints beside constraints nonlinear in the velocities are "
                "not supported yet; eliminate the coordinate the relation fixes instead."
            )
        v = self._vars
        found: list[tuple[int, sp.Expr]] = []
        for key, value in holonomic.items():
            i = self._coordinate_index(key, "holonomic")
            name = self.coordinates[i].func.__name__
            what = f"holonomic[{name}]"
            if i in self._dep:
                raise SystemDefinitionError(
                    f"{what}: {name} is a dependent coordinate of the velocity constraints already; "
                    "key the relation by another coordinate it contains, or choose other dependent "
                    "coordinates for the velocity constraints."
                )
            if any(i == j for j, _ in found):
                raise SystemDefinitionError(f"holonomic: the coordinate {name} is keyed twice.")
            f = _as_expr(value, what)
            e = self._convert(f, what)
            if e.has(*v.xd):
                raise SystemDefinitionError(
                    f"{what} = {describe(f)} contains velocities; a holonomic constraint is a relation "
                    "f(q, t) = 0 between the coordinates (velocity relations go in constraints)."
                )
            if simplify_small(e.diff(v.x[i])) == 0:
                raise SystemDefinitionError(
                    f"{what} = {describe(f)} does not depend on {name} (∂f/∂{name} = 0), so it cannot "
                    "fix that coordinate; key it by a coordinate it contains."
                )
            self.holonomic[self.coordinates[i]] = f
            found.append((i, e))
        self.g = len(self._dep)
        a, a0 = self._A, self._A0  # (form A read in SymEngine: SymPy's A built now)
        self.__dict__.pop("_native_A", None)
        rows = sp.Matrix([[sp.factor_terms(derivative(e, x)) for x in v.x] for _, e in found])
        self._A = a.col_join(rows) if a.rows else rows
        self._A0 = a0.col_join(sp.Matrix([sp.factor_terms(derivative(e, TIME)) for _, e in found]))
        for name in ("_B", "_B0", "_C", "_velocity_substitution"):  # solved from A when needed
            self.__dict__.pop(name, None)
        self._dep = (*self._dep, *(i for i, _ in found))
        self._ind = tuple(i for i in range(self.n) if i not in self._dep)
        self._holonomic = tuple(found)
        self._check_counts()
        self.g = len(self._dep)
        self._check_dependent_block()

    @cached_property
    def _A(self) -> sp.Matrix:
        """``A`` of the constraints ``A q̇ + A_0 = 0`` (eq. (1)), from SymEngine's (form A) when first needed."""
        self._split_native_A()
        return self.__dict__["_A"]

    @cached_property
    def _A0(self) -> sp.Matrix:
        """``A_0`` of the constraints (see :attr:`_A`)."""
        self._split_native_A()
        return self.__dict__["_A0"]

    def _split_native_A(self) -> None:
        rows, consts = self._native_A
        flat = [sp.factor_terms(e) for e in _back([*(c for r in rows for c in r), *consts], self._restore)]
        self.__dict__["_A"] = sp.Matrix(self.g, self.n, flat[: self.g * self.n])
        self.__dict__["_A0"] = sp.Matrix(self.g, 1, flat[self.g * self.n :])

    def _pending_A(self) -> tuple[list[list[Any]], list[Any]] | None:
        """SymEngine's ``(rows of A, A_0)`` while SymPy's are not built (form A), else None."""
        return None if "_A" in self.__dict__ else self.__dict__.get("_native_A")

    def _constraint_matrix(self) -> Any:
        """``A`` for numerical checks: SymEngine's while there is no SymPy one, else :attr:`_A`."""
        pending = self._pending_A()
        if pending is None:
            return self._A
        return DenseMatrix(pending[0])

    @cached_property
    def _B(self) -> sp.Matrix:
        """``B`` of ``q̇_dep = B q̇_ind + B_0``: given in form B, solved for (lazily) in form A.

        Large form-A systems (a chain of sleighs) never need it symbolically when
        they are simulated with the numeric reduction (see :mod:`chaplygin.numeric.codegen`).
        """
        return self._solve_dependent(self._A.extract(list(range(self.g)), list(self._ind)))

    @cached_property
    def _B0(self) -> sp.Matrix:
        """``B_0`` of ``q̇_dep = B q̇_ind + B_0`` (see :attr:`_B`)."""
        return self._solve_dependent(self._A0)

    def _solve_dependent(self, rhs: sp.Matrix) -> sp.Matrix:
        """``−A_dep⁻¹·rhs``, each entry one cancelled fraction in normal form where that is small
        (trigonometric functions of angle sums expanded, ``sin² + cos² = 1``:
        :func:`~chaplygin.core._rational.solve_columns`), so that every reduced form starts from
        the shortest ``B``."""
        a_dep = self._A.extract(list(range(self.g)), list(self._dep))
        return solve_columns(a_dep, -rhs, "the constraints")

    def _dependent_velocity_index(self, key: Any) -> int:
        if isinstance(key, sp.Derivative) and key.variables == (TIME,) and key.expr in self.coordinates:
            return self.coordinates.index(key.expr)
        if isinstance(key, str) and key.endswith("'"):
            return self._coordinate_index(key[:-1], "constraints")
        if key in self.coordinates:
            raise SystemDefinitionError(
                f"constraints: the key {describe(key)} is a coordinate; form B keys are dependent "
                f"velocities such as {describe(key.diff(TIME))}."
            )
        raise SystemDefinitionError(
            f"constraints: the key {describe(key)} is not the velocity of a coordinate; form B "
            "keys are dependent velocities q.diff(t) of coordinates."
        )

    def _check_counts(self) -> None:
        if len(self._dep) >= self.n:
            raise SystemDefinitionError(
                f"{len(self._dep)} constraint(s) for {self.n} coordinate(s): there must be fewer "
                "constraints than coordinates (at least one independent velocity)."
            )

    def _numeric_samples(self, *matrices: Any) -> list[list[np.ndarray]]:
        """The ``matrices`` (free of velocities) at the same random configurations.

        Plain substitution and ``evalf``: for the few samples a check needs this is
        much cheaper than compiling the expressions.
        """
        from chaplygin.core._sampling import COORDINATE_RANGE, PARAMETER_RANGE

        rng = np.random.default_rng(20000843)
        # SymPy or SymEngine matrices: SymEngine's symbols come back without assumptions, so a
        # parameter is its name (the internal symbols are Dummies, which keep their identity)
        found = {to_sympy(s) for m in matrices for s in m.free_symbols} - {TIME, *self._vars.x}
        params = sorted({s.name: s for s in found}.values(), key=str)
        args = [TIME, *self._vars.x, *params]
        fast = evaluator(args, [e for m in matrices for e in m])
        out = []
        for _ in range(_SAMPLES):
            values = dict(zip([TIME, *self._vars.x], rng.uniform(*COORDINATE_RANGE, size=self.n + 1)))
            values.update(zip(params, rng.uniform(*PARAMETER_RANGE, size=len(params))))
            if fast is not None:
                with np.errstate(all="ignore"):
                    flat = np.asarray(fast([values[a] for a in args]), dtype=complex).ravel()
                sizes = np.cumsum([0, *(m.rows * m.cols for m in matrices)])
                out.append([flat[a:b].reshape(m.shape) for m, a, b in zip(matrices, sizes, sizes[1:])])
                continue
            floats = {k: sp.Float(v) for k, v in values.items()}
            by_name = {p.name: floats[p] for p in params}
            floats.update({s: by_name[s.name] for s in found})
            sample = []
            for m in matrices:
                m = m if isinstance(m, sp.MatrixBase) else sp.Matrix(m.tolist())
                try:
                    sample.append(
                        np.array(m.xreplace(floats).evalf().tolist(), dtype=complex).reshape(m.shape)
                    )
                except TypeError:  # zoo or nan: a singular point
                    sample.append(np.full(m.shape, np.nan))
            out.append(sample)
        return out

    @staticmethod
    def _full_rank(m: np.ndarray) -> bool:
        if not np.all(np.isfinite(m)):
            return False
        if m.size == 0:
            return True
        s = np.linalg.svd(m, compute_uv=False)
        return bool(s[-1] > 1e-10 * max(1.0, s[0]))

    def _check_dependent_block(self) -> None:
        g = len(self._dep)
        samples = [a for (a,) in self._numeric_samples(self._constraint_matrix())]
        if not any(self._full_rank(a) for a in samples):
            raise SystemDefinitionError(
                "constraints: the constraints are not independent (the constraint matrix A has "
                f"rank below {g} everywhere); remove the redundant ones."
            )
        if any(self._full_rank(a[:, list(self._dep)]) for a in samples):
            return
        from scipy.linalg import qr

        finite = [a for a in samples if np.all(np.isfinite(a))]
        good = [tuple(sorted(qr(finite[0], pivoting=True)[2][:g]))] if finite else []
        names = lambda c: "[" + ", ".join(self.coordinates[i].func.__name__ for i in c) + "]"  # noqa: E731
        raise SystemDefinitionError(
            f"dependent={names(self._dep)}: the constraints cannot be solved for these velocities "
            "(their block of A is singular everywhere). Choose other dependent coordinates, e.g. "
            + " or ".join(f"dependent={names(c)}" for c in good)
            + "."
        )

    def _check_reduced_mass_matrix(self) -> None:
        mass = self._M if self._native is None else DenseMatrix(self._native.H)
        samples = [
            c.T @ m @ c
            for m, a in self._numeric_samples(mass, self._constraint_matrix())
            if (c := self._numeric_C(a)) is not None
        ]
        if not any(self._full_rank(m) for m in samples):
            raise SystemDefinitionError(
                "the kinetic energy is degenerate on the constraint distribution: the reduced "
                "mass matrix C^T M C (C = [I; B]) is singular at every sampled configuration, so "
                "the accelerations of "
                f"{', '.join(q.func.__name__ for q in self.independent)} are not determined."
            )

    def _numeric_C(self, a: np.ndarray) -> np.ndarray | None:
        """``C = [I; B]`` (see :attr:`_C`) from a numerical ``A``; None where ``A_dep`` is singular."""
        if not (np.all(np.isfinite(a)) and self._full_rank(a[:, list(self._dep)])):
            return None
        c = np.zeros((self.n, len(self._ind)), dtype=a.dtype)
        c[list(self._ind), range(len(self._ind))] = 1
        if self.g:
            c[list(self._dep)] = -np.linalg.solve(a[:, list(self._dep)], a[:, list(self._ind)])
        return c

    # ------------------------------------------------------------------ derived data
    @cached_property
    def _M(self) -> sp.Matrix:
        """Mass matrix ``∂²T/∂q̇_i∂q̇_j`` in internal symbols."""
        return jacobian(gradient(self._T, self._vars.xd), self._vars.xd)

    @cached_property
    def _T(self) -> sp.Expr:
        """The kinetic energy in internal symbols."""
        return self._exact(self.kinetic_energy).xreplace(self._to_sym)

    def _internal_native(self, exprs: Sequence[sp.Expr]) -> list[Any] | None:
        """User expressions in internal symbols, in SymEngine (converted as they are and substituted
        there: SymPy's substitution costs more); None if SymEngine cannot represent them."""
        fast = native([*map(self._exact, exprs), *self._to_sym, *self._to_sym.values()])
        if fast is None:
            return None
        k, m = len(exprs), len(self._to_sym)
        rule = dict(zip(fast[k : k + m], fast[k + m :]))
        return [e.subs(rule) for e in fast[:k]]

    @cached_property
    def _quadratic_T(self) -> bool:
        """Whether T is a homogeneous quadratic form in the velocities, T = T₂ (then the energy
        ``T − U`` is Jacobi's integral: :func:`chaplygin.numeric.simulate.monitor`): T being a
        polynomial of degree at most 2 in them (checked on construction, which also fills this
        where SymEngine shows it), its value and gradient at zero velocity (``T₀`` and the
        coefficients of ``T₁``) vanish."""
        xd, T = self._vars.xd, self._T
        still = {v: sp.S.Zero for v in xd}
        alone = [T.xreplace({**still, v: v}) for v in xd]  # T₂ + T₁ + T₀ with one velocity moving
        parts = [T.xreplace(still), *(e.diff(v).xreplace(still) for e, v in zip(alone, xd))]
        return all(e == 0 or sp.expand(e) == 0 for e in parts)

    @cached_property
    def _native_T(self) -> Any:
        """The kinetic energy in internal symbols, in SymEngine; None if it cannot be represented."""
        fast = self._internal_native([self.kinetic_energy])
        return None if fast is None else fast[0]

    @cached_property
    def _native_momenta(self) -> tuple[list[Any], list[list[Any]]]:
        """SymEngine's ``∂T/∂q̇`` and mass matrix (rows), for the check of T and :attr:`_native`."""
        return momenta(self._native_T, self._native_xd)

    @cached_property
    def _native_xd(self) -> Any:
        """The internal velocity symbols, in SymEngine (None where SymEngine is not installed)."""
        return native(self._vars.xd)

    def _constraint_parts(self) -> list[Any]:
        """``A`` and ``A_0`` or, before SymEngine's are converted, the symbols in them (for :attr:`parameters`)."""
        pending = self._pending_A()
        if pending is None:
            return [self._A, self._A0]
        rows, consts = pending
        found = {to_sympy(x) for e in [*(c for r in rows for c in r), *consts] for x in e.free_symbols}
        return [self._restore.get(x, x) for x in found]

    @cached_property
    def _native(self) -> Native | None:
        """The system as SymEngine expressions (:mod:`chaplygin.core._native`); None if it cannot be."""
        from chaplygin.core._native import load

        return load(self)

    @cached_property
    def _C(self) -> sp.Matrix:
        """``n × ε`` matrix with ``q̇ = C q̇_σ + c_0`` on the constraints."""
        c = sp.zeros(self.n, len(self._ind))
        for k, i in enumerate(self._ind):
            c[i, k] = 1
        for b, i in enumerate(self._dep):
            for k in range(len(self._ind)):
                c[i, k] = self._B[b, k]
        return c

    @cached_property
    def _velocity_substitution(self) -> dict[sp.Symbol, sp.Expr]:
        """Dependent velocities in terms of independent ones: the tilde of the paper."""
        v = self._vars
        ind_xd = sp.Matrix([v.xd[i] for i in self._ind])
        rhs = self._B * ind_xd + self._B0 if self.g else sp.zeros(0, 1)
        return {v.xd[i]: rhs[b] for b, i in enumerate(self._dep)}

    @cached_property
    def _f(self) -> sp.Matrix:
        """The constraint functions ``f_β(q, q̇, t)`` that vanish (internal symbols): ``A q̇ + A_0``
        for linear constraints, the given (or ``q̇_dep − φ``) for nonlinear ones."""
        if self._nonlinear is not None:
            return self._nonlinear.f
        return self._A * sp.Matrix(self._vars.xd) + self._A0 if self.g else sp.zeros(0, 1)

    @property
    def is_nonlinear(self) -> bool:
        """True when a velocity constraint is nonlinear in the velocities, ``f_β(q, q̇, t) = 0``:
        :attr:`A` is then ``∂f/∂q̇`` (the Appell–Chetaev condition) and depends on the velocities,
        and :attr:`constraints` is the solved form (the branch chosen)."""
        return self._nonlinear is not None

    @cached_property
    def _lindelof_degenerate(self) -> list[str]:
        """Why Lindelöf's equations (Lagrange's on T̃) cannot determine the accelerations: for
        constraints nonlinear in the velocities T̃ need not be regular in them (the isokinetic
        particle's T̃ = m v²/2 is a constant); empty where its Hessian is regular somewhere."""
        from chaplygin.core._sampling import StateSampler, compile_function, parameter_values

        v = self._vars
        ind_xd = [v.xd[i] for i in self._ind]
        hessian = jacobian(gradient(self._T_reduced, ind_xd), ind_xd)
        rng = np.random.default_rng(30)
        sampler = StateSampler(self, parameter_values(self, rng))
        args = [TIME, *v.x, *v.xd, *sampler.parameters]
        fn = compile_function(hessian, args)  # (numbers: a symbolic determinant may not finish)
        for _ in range(_SAMPLES):
            state = sampler.draw(rng)
            with np.errstate(all="ignore"):
                h = np.asarray(fn(*(state[a] for a in args)), dtype=float)
            if self._full_rank(h):
                return []
        shown = simplify_small(sp.expand(self._T_reduced))
        return [
            f"T̃ = {describe(self.to_user(shown))} (the constraints substituted into T) is degenerate in "
            "the independent velocities (∂²T̃/∂q̇_σ∂q̇_τ is singular everywhere), so Lagrange's "
            "equations on T̃ do not determine the accelerations"
        ]

    @property
    def singular_set(self) -> list[sp.Expr]:
        """Expressions whose zeros are the states where nonlinear constraints cannot be solved
        smoothly for the dependent velocities (``∂f/∂q̇_dep`` singular on the constraints, a pole
        of ``B = ∂φ/∂q̇_σ``); empty for linear constraints."""
        return [self.to_user(e) for e in self._singular_set]

    @cached_property
    def _singular_set(self) -> list[sp.Expr]:
        """:attr:`singular_set` in internal symbols, found once (a determinant and its factors)."""
        from chaplygin.core._nonlinear import singular_set

        return singular_set(self) if self._nonlinear is not None else []

    @cached_property
    def _Q(self) -> list[sp.Expr]:
        """Total generalized forces ``Q_s = ∂U/∂q_s + Q_s^{np}``."""
        return [du + q for du, q in zip(gradient(self._U, self._vars.x), self._Qnp)]

    def to_user(self, expr: Any) -> Any:
        """Convert an internal expression (plain symbols, exact numbers) to dynamicsymbols, with
        the numbers of a system written with Floats shown as Floats."""
        return floated(expr.xreplace(self._to_fun), self._float_prec)

    # ------------------------------------------------------------------ public views
    @property
    def constraint_form(self) -> str:
        """``"A"`` (implicit, eq. (1)) or ``"B"`` (solved, eq. (2)): the form given."""
        return self._form

    @property
    def velocity_g(self) -> int:
        """Number of velocity constraints given as such: ``g`` less the holonomic relations, whose
        time derivatives are the last rows of :attr:`A`."""
        return self.g - len(self._holonomic)

    @property
    def epsilon(self) -> int:
        """Number of independent coordinates ``ε = n − g``."""
        return self.n - self.g

    @property
    def A(self) -> sp.Matrix:
        """Form-A coefficients ``A_βs`` (g × n, columns in coordinate order), eq. (1)."""
        return self.to_user(self._A)

    @property
    def A0(self) -> sp.Matrix:
        """Velocity-free terms ``A_β0`` of form A (zero for homogeneous constraints)."""
        return self.to_user(self._A0)

    @property
    def B(self) -> sp.Matrix:
        """Form-B coefficients ``B_βσ`` (g × ε, columns in the order of :attr:`independent`), eq. (2)."""
        return self.to_user(self._B)

    @property
    def B0(self) -> sp.Matrix:
        """Velocity-free terms ``B_β0`` of form B (Voronets' affine case)."""
        return self.to_user(self._B0)

    @property
    def constraints(self) -> dict[sp.Expr, sp.Expr]:
        """Form B, eq. (2): ``{q̇_{ε+β}: Σ_σ B_βσ q̇_σ + B_β0}``."""
        return {
            self.coordinates[i].diff(TIME): self.to_user(self._velocity_substitution[self._vars.xd[i]])
            for i in self._dep
        }

    @property
    def implicit_constraints(self) -> list[sp.Expr]:
        """Form A, eq. (1): the expressions ``Σ_s A_βs q̇_s + A_β0`` that vanish."""
        return [self.to_user(e) for e in self._f]

    @property
    def mass_matrix(self) -> sp.Matrix:
        """The unconstrained mass matrix ``∂²T/∂q̇_i ∂q̇_j`` (n × n)."""
        return self.to_user(self._M)

    @cached_property
    def _T_reduced(self) -> sp.Expr:
        return self._T.xreplace(self._velocity_substitution)

    @property
    def reduced_kinetic_energy(self) -> sp.Expr:
        """``T̃``: the constraints substituted into T, e.g. eq. (48) for the sphere."""
        return self.to_user(simplify_small(sp.expand(self._T_reduced)))

    @cached_property
    def is_affine(self) -> bool:
        """True when the constraints have a velocity-free term (``B_β0 ≠ 0``); for constraints
        nonlinear in the velocities, when the solved form ``φ`` is not homogeneous of degree one
        in the velocities (``B_0 = φ − B q̇_σ ≠ 0``): then the power of the constraint forces,
        ``Σ_β λ_β B_β0``, is not identically zero."""
        if self._nonlinear is not None:
            from chaplygin.core._sampling import vanishes

            return not all(vanishes(e) for e in self._B0)
        return any(e != 0 for e in self._A0)  # B_0 = −A_dep⁻¹ A_0

    @property
    def is_scleronomic(self) -> bool:
        """True when neither T, U, the forces nor the constraints depend explicitly on time."""
        return not any(e.has(TIME) for e in (self._T, self._U, *self._Qnp, self._B, self._B0))

    @property
    def conserves_energy(self) -> bool:
        """True when the motion (of either model) has an energy integral: no non-potential
        forces, homogeneous constraints, nothing that depends on time.  The integral is Jacobi's
        ``h = Σ q̇ ∂T/∂q̇ − T − U = T₂ − T₀ − U``, which is ``E = T − U`` where T is quadratic in
        the velocities.  Where it holds, a change of h measures the integration error; elsewhere
        a change of E is physics."""
        # (A and A_0, not B: the solved constraints B are not needed to know this)
        stationary = not any(e.has(TIME) for e in (self._T, self._U, *self._Qnp, self._A, self._A0, self._f))
        return stationary and not self.is_affine and all(f == 0 for f in self._Qnp)

    @cached_property
    def chaplygin_obstructions(self) -> list[str]:
        """Why this is not a Chaplygin system (empty list when it is one).

        A Chaplygin system has T, U, the forces and the constraint coefficients
        ``B`` (and ``B_0``) free of the dependent coordinates ``q_{ε+β}``.
        """
        dep_x = [self._vars.x[i] for i in self._dep]
        parts = [
            ("the kinetic energy T", [self._T]),
            ("the force function U", [self._U]),
            ("the generalized forces", self._Qnp),
            ("the constraint coefficients B", list(self._B) + list(self._B0)),
        ]
        out = []
        for what, exprs in parts:
            found = [x for x in dep_x if any(e.has(x) for e in exprs)]
            if found:
                names = ", ".join(self.to_user(x).func.__name__ for x in found)
                verb = "depend" if what.endswith(("forces", "B")) else "depends"
                out.append(f"{what} {verb} on the dependent coordinate(s) {names}")
        return out

    @property
    def is_chaplygin(self) -> bool:
        """True for a Chaplygin system: T, U, forces and B free of the dependent coordinates."""
        return not self.chaplygin_obstructions

    def parameter(self, key: Any) -> sp.Symbol:
        """The parameter symbol called ``key`` (a name or the symbol itself)."""
        for p in self.parameters:
            if key == p or key == p.name:
                return p
        raise SystemDefinitionError(
            f"{describe(key)} is not a parameter of {self.name}; the parameters are "
            f"{', '.join(p.name for p in self.parameters) or 'none'}."
        )

    # ------------------------------------------------------------------ derivations
    def equations(self, model: str = "chetaev", form: str = "classic", *, constants: Any = None) -> Equations:
        """Equations of motion of one model.

        Parameters
        ----------
        model : str
            Chetaev (true) motion: ``"chetaev"``, the n + g Lagrange–d'Alembert
            equations with multipliers λ, eq. (6)/(35); ``"chaplygin"``,
            Chaplygin's equations (15) (``form="classic"``) or the paper's new
            form (40) (``form="new"``), for Chaplygin systems; ``"voronets"``,
            Voronets' equations, valid when T, U or B depend on the dependent
            coordinates and for affine constraints.
            Vakonomic motion: ``"vakonomic"``, the n + g equations with
            multipliers μ, eqs. (17)-(18); ``"lindelof"``, Lindelöf's equations
            (22) (classic) or the new form (39); ``"vakonomic_family"``, the
            reduced family with constants ``c_β`` (classic or new form).
        form : {"classic", "new"}
            The form of the reduced equations; the multiplier models have one form.
        constants : mapping, sequence or None
            For ``"vakonomic_family"`` only: values of ``c_β`` (by name
            ``"c_1"``…, by index 1…g, or as a sequence); ``None`` keeps them as
            symbols.

        Returns
        -------
        Equations
        """
        key = (model, form, _constants_key(constants))
        if key not in self._equations:
            self._equations[key] = operation("derive")(self, model, form, constants)
        return self._equations[key]

    def integrated_multipliers(self, constants: Any = None) -> dict[sp.Expr, sp.Expr]:
        """Vakonomic multipliers ``μ_β(t)`` of the family member with constants ``c_β``.

        ``μ_β = c_β − ∂T/∂q̇_{ε+β}`` (form B; ``A_depᵀ μ = c − ∂T/∂q̇_dep`` in
        form A), the integral of (18b) for a Chaplygin system; ``constants`` as
        in :meth:`equations` (``None``: symbols ``c_β``).
        """
        return operation("integrated_multipliers")(self, constants)

    def with_holonomic(
        self, relations: Mapping[Any, Any], *, keep_constraints: bool = True, name: str | None = None
    ) -> System:
        """A new System: this one with the holonomic constraints ``relations`` added.

        Parameters
        ----------
        relations : mapping
            ``{q_dep: f(q, t)}`` as for the ``holonomic`` argument of :class:`System`;
            they join the system's own.
        keep_constraints : bool
            False drops the velocity constraints (the relations replace them: see
            :meth:`IntegrabilityReport.holonomic_system
            <chaplygin.analysis.integrability.IntegrabilityReport.holonomic_system>`).
        name : str, optional
            The new system's name (default: this one's).
        """
        if isinstance(relations, (str, sp.Basic)) or not isinstance(relations, Mapping):
            raise SystemDefinitionError(
                f"relations: expected a mapping {{coordinate: f(q, t)}}, got {describe(relations)}."
            )
        kept = range(self.velocity_g if keep_constraints else 0)
        given = [self._given_constraints[b] for b in kept]
        dep = [self.coordinates[self._dep[b]] for b in kept]
        constraints: Any = dict(zip((q.diff(TIME) for q in dep), given)) if self._form == "B" else given
        return System(
            self.coordinates,
            self.kinetic_energy,
            constraints,
            dependent=None if self._form == "B" else dep,
            potential_energy=self.potential_energy,
            force_function=self.force_function if self.potential_energy is None else None,
            forces=self.forces or None,
            holonomic={**self.holonomic, **relations},
            name=name or self.name,
        )

    def integrability(self) -> IntegrabilityReport:
        """Integrability of the constraints: conditions (28), (33) and Frobenius."""
        return operation("analyze")(self)

    def _repr_html_(self) -> str:
        from sympy.physics.vector.printing import vlatex

        from chaplygin import _html

        def listed(items: Iterable[Any]) -> str:
            return ", ".join(_html.math(vlatex(x)) for x in items) or "none"

        constraints = "<br/>".join(
            _html.math(vlatex(sp.Eq(k, v))) for k, v in list(self.constraints.items())[: self.velocity_g]
        )
        relations = "<br/>".join(_html.math(vlatex(sp.Eq(f, 0))) for f in self.holonomic.values())
        return _html.heading(f"System {self.name}") + _html.fields(
            [
                ("coordinates", listed(self.coordinates)),
                ("dependent", listed(self.dependent)),
                ("parameters", listed(self.parameters)),
                ("constraints", constraints or "none"),
                *([("holonomic constraints", relations)] if relations else []),
                ("kinetic energy", _html.math("T = " + vlatex(self.kinetic_energy))),
            ]
        )

    def __repr__(self) -> str:
        names = ", ".join(q.func.__name__ for q in self.coordinates)
        deps = ", ".join(q.func.__name__ for q in self.dependent)
        from chaplygin.core._brief import brief

        relations = "".join(
            f", {q.func.__name__}: {brief(f, 'system.holonomic holds it', file_syntax)} = 0"
            for q, f in self.holonomic.items()
        )
        return f"System({self.name!r}: coordinates [{names}], dependent [{deps}], g={self.g}{relations})"
