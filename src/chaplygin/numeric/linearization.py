"""The exact linearisation of a model's first-order system, reduced for stability.

The first-order system is the one the generated code integrates (:mod:`chaplygin.numeric._layout`):
``y = (q, the velocities the model carries, the vakonomic multipliers μ)``, ``ẏ = f(y)`` with
``q̇`` the model's kinematics and the rest the leading entries of ``x = M⁻¹F``.  Its Jacobian is
exact to rounding, with no finite differences::

    ∂x/∂y_k = M⁻¹ (∂F/∂y_k − (∂M/∂y_k) x)

where ``∂(F − M·X)/∂y_k`` (at ``X = x``) and ``∂q̇/∂y_k`` are differentiated once (SymEngine) and
generated as code with common subexpressions (:func:`chaplygin.numeric.codegen.model_blocks`, the
code ``chaplygin export --jacobian`` prints), then evaluated per point.

Three reductions follow:

* **the admissible manifold**: a multiplier model carries every velocity, but the constraints
  ``A q̇ + A₀ = 0`` are invariant; perturbations are parametrised by the independent components
  (``δq̇_dep`` from the linearised constraints) and only the independent rows are kept, which
  removes the constraints' spurious zero eigenvalues.  Holonomic relations ``f(q) = 0`` (where
  the system has them) eliminate their dependent coordinates the same way;
* **ignorable coordinates**: those whose value no other variable's rate depends on (the largest
  such set, a fixed point over the dependency structure: the position and heading of a disk, its
  wheel angle).  The structure is read from the exact Jacobian at random admissible states, as
  the multiplier models' expressions depend on the heading through terms that cancel only on the
  constraint manifold.  They are dropped: what is left are the **reduced variables**;
* a **steady motion** (relative equilibrium) is an equilibrium of the reduced system: the reduced
  variables constant, the ignorable coordinates moving uniformly.

:mod:`chaplygin.numeric.stability` reads the verdict from it.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import sympy as sp

from chaplygin.core._fast import derivative
from chaplygin.core._symbols import TIME
from chaplygin.errors import ChaplyginError, InputError
from chaplygin.models import registry

if TYPE_CHECKING:
    from types import ModuleType

    from chaplygin.core.system import System
    from chaplygin.models.equations import Equations

__all__ = ["Linearization", "linearize"]

#: a Jacobian entry below this times the Jacobian's largest entry counts as zero (dependency structure)
STRUCTURE_RTOL = 1e-9
#: bumped whenever the generated linearisation changes shape (the disk cache's key)
LINEAR_FORMAT = 1


# ---------------------------------------------------------------------------- generated code
def _constants_of_motion(eqs: Equations) -> list[tuple[str, sp.Expr]]:
    """The vakonomic model's integrals ``c = A_depᵀ μ + ∂T/∂q̇_dep`` (the integral of (18b)), where
    the system meets the conditions of the vakonomic family (a Chaplygin system, homogeneous
    constraints, no force along a dependent coordinate); none otherwise."""
    s = eqs.system
    entry = registry.MODELS[eqs.model]
    if not entry.multipliers_in_state or registry.family_obstructions(s) or s.is_affine:
        return []
    v, dep, mus = s._vars, list(s._dep), list(eqs._state)
    out = []
    for b, i in enumerate(dep):
        c = sp.diff(s._T, v.xd[i]) + sum((s._A[k, i] * mus[k] for k in range(s.g)), sp.S.Zero)
        out.append((f"c_{b + 1}", c))
    return out


def _generated(eqs: Equations) -> ModuleType:
    """The module that evaluates the linearisation of ``eqs`` at ``(y, p)``, with three functions:

    * ``fill(t, y, p, M, F, V)``: the model's ``M·x = F`` and its velocities ``V = q̇``;
    * ``dfill(t, y, p, x, R, dV)``: ``R[j] = ∂(F − M·X)/∂y_j`` at ``X = x`` and ``dV[j] = ∂V/∂y_j``
      (:func:`chaplygin.numeric.codegen.model_blocks`, what ``chaplygin export --jacobian`` prints);
    * ``efill(t, y, p, dE, dI, G, H, R)``: the gradients of the energy and of the model's own
      integrals (:func:`_constants_of_motion`); for a multiplier model
      ``G = [A | A₀ | ∂(A q̇ + A₀)/∂q]``; the holonomic relations' values ``R = f`` and
      ``H = ∂f/∂q``.

    Derived once per equations object (SymEngine), printed with the code generator's common
    subexpressions, and kept in the disk cache of compiled models
    (:mod:`chaplygin.numeric._modelcache`): another process linearises an equal system without
    differentiating anything."""
    cached = eqs.__dict__.get("_linearised")
    if cached is not None:
        return cached
    from chaplygin.numeric import _modelcache
    from chaplygin.numeric.cache import import_source

    s = eqs.system
    holonomic = "; ".join(f"{i}: {f}" for i, f in s._holonomic)
    what = f"linearisation {eqs.model}/{eqs.form} holonomic [{holonomic}] constants {list(eqs.constants)}"
    key = _modelcache.source_key(s, what, LINEAR_FORMAT)
    found = _modelcache.load_source(key)
    source = found["source"] if found is not None else _linearisation_source(eqs)
    if found is None:
        _modelcache.store_source(key, source)
    module = import_source(source, "linear")
    eqs.__dict__["_linearised"] = module
    return module


def _d(e: Any, x: Any) -> Any:
    """``∂e/∂x``: SymEngine's, or SymPy's with ``Abs`` and ``sign`` differentiated in closed form
    (plain SymPy writes ``re``/``im`` derivatives for the time and the coordinates, not declared real)."""
    return derivative(e, x) if isinstance(e, sp.Basic) else e.diff(x)


def _linearisation_source(eqs: Equations) -> str:
    """The source of :func:`_generated`'s module."""
    from chaplygin.numeric._layout import state_symbols
    from chaplygin.numeric.codegen import (
        _assignments,
        _at,
        _Block,
        _common,
        _Fill,
        _plain,
        _python_body,
        model_blocks,
        monitored,
    )

    s = eqs.system
    _, to_num, velocities, _ = state_symbols(eqs)
    _, main, derivatives, _, _ = model_blocks(eqs, True)
    assert derivatives is not None
    v = s._vars
    state = sorted((x for x in to_num if str(to_num[x].base) == "y"), key=lambda x: int(to_num[x].indices[0]))
    size, n = len(state), s.n
    multiplier_model = not registry.MODELS[eqs.model].reduced
    energy = monitored(s, s._T, s._U, v.xd).xreplace(dict(zip(v.xd, velocities)))
    rows = [[*list(s._A.row(b)), s._A0[b]] for b in range(s.g)] if multiplier_model else []
    holonomic = [f for _, f in s._holonomic]
    own = [c for _, c in _constants_of_motion(eqs)]
    if any(sp.sympify(e).has(TIME) for e in [*eqs._M, *eqs._F, *velocities, *holonomic]):
        raise ChaplyginError(
            f"{s.name}: the {eqs.model} equations depend explicitly on the time t; steady motions and "
            "their stability are computed here for autonomous systems only."
        )
    flat_rows = [a for r in rows for a in r]
    items = _common([energy, *own, *flat_rows, *holonomic, *state, *v.x, *v.xd])
    cut = np.cumsum([0, 1, len(own), len(flat_rows), len(holonomic), size, n, n])
    (energy_n,), own_n, rows_n, hol_n, state_n, x_n, xd_n = (items[i:j] for i, j in itertools.pairwise(cut))
    exprs = [_d(energy_n, y_k) for y_k in state_n]
    targets = [("dE", z, 0) for z in range(size)]
    for k, c in enumerate(own_n):
        exprs += [_d(c, y_k) for y_k in state_n]
        targets += [("dI", k * size + z, size) for z in range(size)]
    width = 2 * n + 1
    for b in range(len(rows)):
        a = rows_n[b * (n + 1) : (b + 1) * (n + 1)]
        row = sum((a[j] * xd_n[j] for j in range(n)), a[n])
        exprs += [*a, *(_d(row, x) for x in x_n)]
        targets += [("G", b * width + j, width) for j in range(width)]
    for k, f in enumerate(hol_n):
        exprs += [f, *(_d(f, x) for x in x_n)]
        targets += [("R", k, 0)] + [("H", k * n + j, n) for j in range(n)]
    extra = _Block(_at(exprs, _plain(to_num)), targets, "e_", skip_zero=len(exprs))

    def body(block: _Block) -> str:
        return "\n".join(_python_body(_Fill(block), [_assignments(block)]))

    return (
        f'"""Generated by chaplygin: the exact linearisation of the {eqs.model}/{eqs.form} equations '
        f'(chaplygin.numeric.linearization)."""\n\nimport math\n\nimport numpy as np\n\n\n'
        f"def fill(t, y, p, M, F, V):\n{body(main)}\n\n\n"
        f"def dfill(t, y, p, x, R, dV):\n{body(derivatives)}\n\n\n"
        f"def efill(t, y, p, dE, dI, G, H, R):\n{body(extra)}\n"
    )


# ---------------------------------------------------------------------------- the linearisation
@dataclass(frozen=True)
class _Point:
    """One evaluation: the rate ``f``, the Jacobian ``J``, the gradients of the energy and the
    model's integrals, ``G``, ``H``."""

    f: np.ndarray
    J: np.ndarray
    dE: np.ndarray
    dI: np.ndarray
    G: np.ndarray
    H: np.ndarray
    R: np.ndarray


class Linearization:
    """The exact Jacobian of one model's first-order system, reduced (see the module's notes).

    Built by :func:`linearize`.  ``variables`` names the reduced variables (the coordinates that
    are not ignorable, the independent velocities ``name'``, the vakonomic multipliers); the
    ignorable coordinates are ``ignorable``; ``state`` names every entry of the model's state.
    """

    def __init__(self, eqs: Equations, parameters: Mapping[Any, float] | None) -> None:
        from chaplygin.numeric._layout import state_symbols

        s = self.system = eqs.system
        self.equations = eqs
        self.model = eqs.model
        self._module = _generated(eqs)
        layout, _, _, k = state_symbols(eqs)
        self.layout = layout
        self.state: tuple[str, ...] = layout.state
        self._n, self._k, self._dim, self._size = s.n, k, eqs._M.shape[0], len(layout.state)
        self._p = _parameter_vector(s, layout.parameters, parameters)
        self._last: tuple[bytes, _Point] | None = None  # the last point evaluated (see _evaluate)
        self._multiplier_model = not registry.MODELS[eqs.model].reduced
        #: the model's own integrals (the vakonomic constants c_β where they are integrals)
        self.integrals: tuple[str, ...] = tuple(name for name, _ in _constants_of_motion(eqs))
        n = s.n
        hol = [i for i, _ in s._holonomic]
        self._hol = hol
        self._free_q = [i for i in range(n) if i not in hol]
        if self._multiplier_model:
            velocities = [n + i for i in s._ind]
        else:
            velocities = list(range(n, n + len(s._ind)))
        mus = list(range(n + len(layout.velocities), self._size))
        self._free = self._free_q + velocities + mus
        # coordinates and multipliers may be ignorable (a holonomic relation's μ enters only as μ̇)
        candidates = [*range(len(self._free_q)), *range(len(self._free) - len(mus), len(self._free))]
        ignorable = _ignorable(self, candidates)
        self._kept = [j for j in range(len(self._free)) if j not in ignorable]
        self.ignorable: tuple[str, ...] = tuple(self.state[self._free[j]] for j in ignorable)
        self.variables: tuple[str, ...] = tuple(self.state[self._free[j]] for j in self._kept)
        self.parameters = dict(zip(layout.parameters, self._p.tolist()))

    # -------------------------------------------------------------- evaluation
    def _evaluate(self, y: np.ndarray) -> _Point:
        key = y.tobytes() + self._p.tobytes()  # a point is asked for several times in a row
        if self._last is not None and self._last[0] == key:
            return self._last[1]
        n, dim, size, k = self._n, self._dim, self._size, self._k
        g = self.system.g if self._multiplier_model else 0
        M, F, V = np.zeros((dim, dim)), np.zeros(dim), np.zeros(n)
        dR, dV = np.zeros((size, dim)), np.zeros((size, n))
        dE, dI = np.zeros(size), np.zeros((len(self.integrals), size))
        G, H, R = np.zeros((g, 2 * n + 1)), np.zeros((len(self._hol), n)), np.zeros(len(self._hol))
        module = self._module
        with np.errstate(all="ignore"):
            module.fill(0.0, y, self._p, M, F, V)
            x = _solve(M, F)
            module.dfill(0.0, y, self._p, x, dR, dV)  # M ∂x/∂y_j = ∂(F − M·X)/∂y_j at X = x
            dx = _solve(M, dR.T)
            module.efill(0.0, y, self._p, dE, dI, G, H, R)
        f = np.concatenate([V, x[:k]])
        J = np.vstack([dV.T, dx[:k]])
        self._last = (key, _Point(f, J, dE, dI, G, H, R))
        return self._last[1]

    def _tangent(self, point: _Point) -> np.ndarray:
        """``P`` (state × free): the admissible perturbation that each free variable's unit one makes."""
        s, n, size = self.system, self._n, self._size
        P = np.zeros((size, len(self._free)))
        P[self._free, range(len(self._free))] = 1.0
        if self._hol:
            H = point.H
            P[self._hol] = -_solve(H[:, self._hol], H[:, self._free_q] @ P[self._free_q])
        if self._multiplier_model and s.g:
            A, Gq = point.G[:, :n], point.G[:, n + 1 :]
            dep, ind = list(s._dep), list(s._ind)
            P[[n + i for i in dep]] = -_solve(A[:, dep], Gq @ P[:n] + A[:, ind] @ P[[n + i for i in ind]])
        return P

    def _restricted(self, y: np.ndarray) -> tuple[_Point, np.ndarray, np.ndarray]:
        """The evaluation at ``y``, the Jacobian on the free variables and the tangent ``P``."""
        point = self._evaluate(y)
        P = self._tangent(point)
        return point, (point.J @ P)[self._free], P

    def admissible(self, values: Mapping[int, float]) -> np.ndarray:
        """The full state from the free variables' values (by state index): the holonomic
        relations' coordinates by Newton's method from the values given, the dependent velocities
        from the constraints (multiplier models); NaN where they cannot be solved (a pole)."""
        y = np.zeros(self._size)
        for i, value in values.items():
            y[i] = value
        s, n = self.system, self._n
        for _ in range(50 if self._hol else 0):  # Newton on the holonomic relations' coordinates
            point = self._evaluate(y)
            if np.max(np.abs(point.R)) <= 1e-14 * max(1.0, float(np.max(np.abs(y[:n])))):
                break
            y[self._hol] -= _solve(point.H[:, self._hol], point.R)
        if self._multiplier_model and s.g:
            from chaplygin.numeric.simulate import _solvable

            G = self._evaluate(y).G
            A, A0 = G[:, :n], G[:, n]
            dep, ind = list(s._dep), list(s._ind)
            if not _solvable(A, dep):  # the criterion of simulate's initial states
                y[[n + i for i in dep]] = np.nan
            else:
                y[[n + i for i in dep]] = _solve(A[:, dep], -(A[:, ind] @ y[[n + i for i in ind]] + A0))
        return y

    def reduced(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(f, J)`` of the reduced system at the admissible state ``y``: the rates of the reduced
        variables and their Jacobian (exact to rounding)."""
        point, Jr, _ = self._restricted(y)
        kept = self._kept
        f = point.f[[self._free[j] for j in kept]]
        return f, Jr[np.ix_(kept, kept)]

    def integral_gradients(self, y: np.ndarray) -> dict[str, np.ndarray]:
        """The gradients, on the reduced variables (admissible perturbations), of the energy where
        the system conserves it and of the model's own integrals (:attr:`integrals`)."""
        point, _, P = self._restricted(y)
        out = {"energy": (point.dE @ P)[self._kept]} if self.system.conserves_energy else {}
        for name, grad in zip(self.integrals, point.dI):
            out[name] = (grad @ P)[self._kept]
        return out

    def state_at(self, point: Mapping[Any, Any], *, guess: bool = False) -> np.ndarray:
        """The full state of a steady motion given by name (coordinates, ``"name'"`` velocities,
        multipliers); the ignorable coordinates default to 0, the dependent velocities follow, and
        the holonomic relations' coordinates are solved from them (Newton, from the value given
        or 0; a value given must satisfy the relations, unless ``guess``: a Newton search's start)."""
        names = list(self.state)
        values: dict[int, float] = {}
        for key, value in point.items():
            name = _name(self.system, key, names)
            values[names.index(name)] = _number(value, f"point: {name}")
        needed = [self._free[j] for j in self._kept]
        missing = [names[i] for i in needed if i not in values]
        if missing:
            raise InputError(
                f"point: missing {', '.join(missing)}; a steady motion of the {self.model} model of "
                f"{self.system.name} gives {', '.join(self.variables)} (the ignorable "
                f"{', '.join(self.ignorable) or 'coordinates'} may be left out)."
            )
        dependent = [names[self._n + i] for i in self.system._dep] if self._multiplier_model else []
        given = {names[i]: v for i, v in values.items() if names[i] in dependent}
        y = self.admissible({i: v for i, v in values.items() if names[i] not in dependent})
        if not np.all(np.isfinite(y)):
            guessed = [names[i] for i in self._hol if i not in values]
            raise InputError(
                f"point: the constraints of {self.system.name} cannot be solved there (a pole of the solved "
                f"constraints{' or of the holonomic relations' if self._hol else ''}); choose other "
                "dependent coordinates, or another point"
                + (
                    f"; {', '.join(guessed)} {'was' if len(guessed) == 1 else 'were'} solved from the "
                    "holonomic relations starting at 0: give a value near the solution to start from."
                    if guessed
                    else "."
                )
            )
        off = [
            names[i]
            for i in self._hol
            if not guess and i in values and abs(y[i] - values[i]) > 1e-9 * max(1.0, abs(values[i]))
        ]
        if off:
            raise InputError(
                f"point: {', '.join(f'{name} = {values[names.index(name)]:g}' for name in off)} violates "
                f"the holonomic relations, which give {', '.join(f'{name} = {y[names.index(name)]:.12g}' for name in off)}."
            )
        for name, value in given.items():
            implied = y[names.index(name)]
            if abs(value - implied) > 1e-9 * max(1.0, abs(implied)):
                raise InputError(
                    f"point: {name} = {value:g} violates the constraints, which give {name} = {implied:.12g}."
                )
        return y


def _solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a⁻¹ b``, NaN where ``a`` is singular (every caller checks for non-finite results)."""
    try:
        return np.linalg.solve(a, b)
    except np.linalg.LinAlgError:
        return np.full(np.shape(b), np.nan)


def _name(system: System, key: Any, names: Sequence[str]) -> str:
    """The state name of a point's key: a coordinate or velocity (as the initial states are
    written: ``"x"``, ``"x'"``, or the dynamicsymbol), or a multiplier's name."""
    if isinstance(key, str) and key.strip() in names:
        return key.strip()
    from chaplygin.numeric.simulate import _lookup

    try:
        kind, i = _lookup(system, key)
    except ChaplyginError:
        raise InputError(
            f"point: {key!r} is not a variable of this model's state; the state is {', '.join(names)}."
        ) from None
    name = system.coordinates[i].func.__name__ + ("'" if kind == "v" else "")
    if name not in names:
        raise InputError(f"point: {name} is not carried by this model; its state is {', '.join(names)}.")
    return name


def _number(value: Any, what: str) -> float:
    from chaplygin.numeric.simulate import _finite

    return _finite(value, what, "a finite number")


def _parameter_vector(system: System, names: Sequence[str], given: Mapping[Any, float] | None) -> np.ndarray:
    values: dict[str, float] = {}
    for key, value in (given or {}).items():
        name = key if isinstance(key, str) else getattr(key, "name", str(key))
        if name not in names:
            raise InputError(
                f"parameters: {name!r} is not a parameter of {system.name}; the parameters are "
                f"{', '.join(names) or 'none'}."
            )
        values[name] = _number(value, f"parameters: {name}")
    missing = [name for name in names if name not in values]
    if missing:
        raise InputError(
            f"parameters: no value for {', '.join(missing)}; every parameter of {system.name} "
            f"({', '.join(names)}) needs a number."
        )
    return np.array([values[name] for name in names], dtype=float)


def _ignorable(lin: Linearization, candidates: Sequence[int]) -> list[int]:
    """The free coordinates and multipliers (``candidates``: positions among the free variables)
    whose value no other variable's rate depends on: the largest such set, from the Jacobian's
    structure at three random admissible states (an entry below :data:`STRUCTURE_RTOL` of the
    largest is zero).  A holonomic relation's vakonomic multiplier is one: it enters the
    equations only through its rate, as Chetaev's λ."""
    rng = np.random.default_rng(29)
    depends = np.zeros((len(lin._free), len(lin._free)), dtype=bool)
    found = 0
    for _ in range(12):
        values = {i: rng.uniform(0.3, 1.3) for i in [*lin._free, *lin._hol]}
        y = lin.admissible(values)
        _, Jr, _ = lin._restricted(y)
        if not np.all(np.isfinite(Jr)):
            continue
        depends |= np.abs(Jr) > STRUCTURE_RTOL * max(1.0, float(np.max(np.abs(Jr))))
        found += 1
        if found == 3:
            break
    if not found:
        raise ChaplyginError(
            f"{lin.system.name}: the {lin.model} equations could not be evaluated at any random state "
            "(singular mass matrix or constraints everywhere sampled)."
        )
    dropped = set(candidates)
    changed = True
    while changed:
        changed = False
        for i in range(len(lin._free)):
            if i in dropped:
                continue
            used = {j for j in dropped if depends[i, j]}
            if used:
                dropped -= used
                changed = True
    return sorted(dropped)


def linearize(
    system: System,
    model: str = "chetaev",
    parameters: Mapping[Any, float] | None = None,
    *,
    form: str = "classic",
) -> Linearization:
    """The exact linearisation of one model of ``system`` (see the module's notes).

    Parameters
    ----------
    system : System
        An autonomous system (no explicit time).
    model : str
        ``"chetaev"`` (the true motion with its multipliers), ``"chaplygin"`` or ``"voronets"``
        (the same motion reduced), ``"vakonomic"`` (the vakonomic motion, μ in the state),
        ``"lindelof"`` (the constraints substituted into T).  For constraints nonlinear in the
        velocities the true motion is linearised in its reduced form (Novoselov's equations,
        ``"chaplygin"`` or ``"voronets"``) and ``"vakonomic"`` is refused.
    parameters : mapping
        A number for every parameter.

    Returns
    -------
    Linearization
        Its :meth:`~Linearization.reduced` gives the reduced rates and Jacobian at a state, its
        ``variables`` and ``ignorable`` name what was kept and what was dropped.

    Raises
    ------
    ChaplyginError
        For an unknown model, a model that does not apply, a system with explicit time, or a
        parameter missing or not a number.
    """
    entry = registry.get(model, form)
    if system.is_nonlinear and not entry.reduced:
        # the multiplier models' admissible manifold f(q, q̇) = 0 is not linear in the velocities
        if not entry.is_true_motion:
            reduced = (
                "'lindelof' (its family at c = 0), where the system allows it"
                if registry.get("lindelof").obstruction(system) is None
                else "'vakonomic_family' with its constants c (a number for each, as a parameter); "
                "Lindelöf's equations (c = 0) do not apply here"
            )
            raise ChaplyginError(
                f"{system.name}: the {model} model (with multipliers) is not linearised for constraints "
                f"nonlinear in the velocities; the vakonomic motion's reduced form is {reduced}."
            )
        model, form = registry.true_motion(system), "classic"  # Novoselov's equations: the same motion
    eqs = system.equations(model, form)
    cache = eqs.__dict__.setdefault("_linearizations", {})
    key = tuple(sorted((str(k), repr(v)) for k, v in (parameters or {}).items()))
    if key not in cache:
        cache[key] = Linearization(eqs, parameters)
    return cache[key]
