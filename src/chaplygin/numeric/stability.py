"""Steady motions, linearisation and linear stability of a model's first-order system.

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

The verdict follows nonholonomic mechanics (Zenkov, Bloch & Marsden, *The energy-momentum method
for the stability of nonholonomic systems*, Dyn. Stab. Syst. 13 (1998)): zero eigenvalues that
come from the family of steady motions (right null vectors) are named, with the integrals whose
differentials annihilate the Jacobian (energy where it is conserved, any the caller gives), and a
motion is not called unstable for those neutral directions.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import sympy as sp

from chaplygin.core._symbols import TIME
from chaplygin.errors import ChaplyginError, InputError
from chaplygin.models import registry

if TYPE_CHECKING:
    from types import ModuleType

    from chaplygin.core.system import System
    from chaplygin.models.equations import Equations

__all__ = [
    "Crossing",
    "Linearization",
    "RootLocus",
    "Stability",
    "SteadyMotion",
    "linearize",
    "root_locus",
    "stability",
    "stability_conditions",
    "steady_motions",
]

#: a Jacobian entry below this times the Jacobian's largest entry counts as zero (dependency structure)
STRUCTURE_RTOL = 1e-9
#: an eigenvalue (a singular value) below this times the Jacobian's norm counts as zero
ZERO_RTOL = 1e-7
#: eigenvalues of least modulus are a zero eigenvalue's cluster when their elementary symmetric
#: functions e_k are below this times |J|^k (rounding leaves them near ε |J|^k)
CLUSTER_RTOL = 1e-10
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
    holonomic = "; ".join(f"{i}: {f}" for i, f in getattr(s, "_holonomic", ()))
    what = f"linearisation {eqs.model}/{eqs.form} holonomic [{holonomic}] constants {list(eqs.constants)}"
    key = _modelcache.source_key(s, what, LINEAR_FORMAT)
    found = _modelcache.load_source(key)
    source = found["source"] if found is not None else _linearisation_source(eqs)
    if found is None:
        _modelcache.store_source(key, source)
    module = import_source(source, "linear")
    eqs.__dict__["_linearised"] = module
    return module


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
    holonomic = [f for _, f in getattr(s, "_holonomic", ())]
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
    exprs = [energy_n.diff(y_k) for y_k in state_n]
    targets = [("dE", z, 0) for z in range(size)]
    for k, c in enumerate(own_n):
        exprs += [c.diff(y_k) for y_k in state_n]
        targets += [("dI", k * size + z, size) for z in range(size)]
    width = 2 * n + 1
    for b in range(len(rows)):
        a = rows_n[b * (n + 1) : (b + 1) * (n + 1)]
        row = sum((a[j] * xd_n[j] for j in range(n)), a[n])
        exprs += [*a, *(row.diff(x) for x in x_n)]
        targets += [("G", b * width + j, width) for j in range(width)]
    for k, f in enumerate(hol_n):
        exprs += [f, *(f.diff(x) for x in x_n)]
        targets += [("R", k, 0)] + [("H", k * n + j, n) for j in range(n)]
    extra = _Block(_at(exprs, _plain(to_num)), targets, "e_", skip_zero=len(exprs))

    def body(block: _Block) -> str:
        return "\n".join(_python_body(_Fill(block), [_assignments(block)]))

    return (
        f'"""Generated by chaplygin: the exact linearisation of the {eqs.model}/{eqs.form} equations '
        f'(chaplygin.numeric.stability)."""\n\nimport math\n\nimport numpy as np\n\n\n'
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
        hol = [i for i, _ in getattr(s, "_holonomic", ())]
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
        ``"lindelof"`` (the constraints substituted into T).
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
    registry.get(model, form)
    eqs = system.equations(model, form)
    cache = eqs.__dict__.setdefault("_linearizations", {})
    key = tuple(sorted((str(k), repr(v)) for k, v in (parameters or {}).items()))
    if key not in cache:
        cache[key] = Linearization(eqs, parameters)
    return cache[key]


# ---------------------------------------------------------------------------- the verdict
def _complex(z: complex, digits: int = 6, zero: float = 0.0) -> str:
    re, im = float(np.real(z)), float(np.imag(z))
    re, im = (0.0 if abs(re) <= zero else re) + 0.0, (0.0 if abs(im) <= zero else im) + 0.0
    if abs(im) <= 1e-14 * max(1.0, abs(re)):
        return f"{re:.{digits}g}"
    return f"{re:.{digits}g} {'+' if im >= 0 else '-'} {abs(im):.{digits}g}i"


def residual_text(value: float) -> str:
    """A residual as text: rounding noise (below 1e-12) as such, not as a machine's last digits."""
    return "below 1e-12" if value < 1e-12 else f"{value:.2g}"


def _mode(vector: np.ndarray, names: Sequence[str]) -> str:
    """A mode as its largest components, the largest scaled to 1."""
    k = int(np.argmax(np.abs(vector)))
    v = vector / vector[k]
    parts = [f"{name}: {_complex(c, 3)}" for name, c in zip(names, v) if abs(c) > 1e-3]
    return "(" + ", ".join(parts) + ")"


@dataclass
class Stability:
    """The linear stability of a steady motion (see :func:`stability`).

    Attributes
    ----------
    verdict : str
        One line: ``"asymptotically stable (modulo …)"``, ``"unstable (λ = …, mode …)"``,
        ``"linearly stable: …"`` or ``"undetermined: …"``.
    kind : str
        ``"asymptotically stable"``, ``"unstable"``, ``"linearly stable"`` or ``"undetermined"``.
    eigenvalues : ndarray
        The reduced Jacobian's eigenvalues, largest real part first; ``modes`` their vectors (columns)
        on ``variables``.
    zeros : list of str
        What explains each zero eigenvalue.
    """

    system: str
    model: str
    point: dict[str, float]
    variables: tuple[str, ...]
    ignorable: dict[str, float]
    jacobian: np.ndarray
    eigenvalues: np.ndarray
    modes: np.ndarray
    family_dimension: int
    zeros: list[str]
    integrals: dict[str, bool]
    kind: str
    verdict: str
    tolerance: float
    residual: float = field(default=0.0)

    def to_dict(self) -> dict[str, Any]:
        """Plain data (JSON-ready): the point, the eigenvalues as ``[re, im]`` pairs, the zeros,
        the integrals' checks, the verdict and the tolerance."""
        return {
            "system": self.system,
            "model": self.model,
            "point": dict(self.point),
            "variables": list(self.variables),
            "ignorable_rates": dict(self.ignorable),
            "eigenvalues": [[float(z.real), float(z.imag)] for z in self.eigenvalues],
            "family_dimension": self.family_dimension,
            "zeros": list(self.zeros),
            "integrals": dict(self.integrals),
            "kind": self.kind,
            "verdict": self.verdict,
            "tolerance": self.tolerance,
            "residual": self.residual,
        }

    @property
    def stable(self) -> bool | None:
        """True (asymptotically or linearly stable), False (unstable), None (undetermined)."""
        return {"unstable": False, "undetermined": None}.get(self.kind, True)

    def _lines(self) -> list[str]:
        point = ", ".join(f"{k} = {v + 0.0:.6g}" for k, v in self.point.items())
        drift = ", ".join(f"{k}' = {_complex(v, zero=1e-12)}" for k, v in self.ignorable.items())
        out = [
            f"Stability of a steady motion of {self.system} ({self.model} model)",
            f"  point: {point}",
            f"  reduced variables: {', '.join(self.variables)}"
            + (f"; ignorable, moving uniformly: {drift}" if drift else ""),
            "  eigenvalues: " + ", ".join(_complex(z, zero=self.tolerance) for z in self.eigenvalues),
        ]
        for reason in dict.fromkeys(self.zeros):
            count = self.zeros.count(reason)
            out.append(f"  {count} zero eigenvalue{'s' if count > 1 else ''}: {reason}")
        out += [
            f"  integral {name}: {'its differential annihilates J' if ok else 'NOT annihilating J'}"
            for name, ok in self.integrals.items()
        ]
        out.append(
            f"  (zero below {self.tolerance:.2g} = rtol x |J|, J balanced; steady-motion residual "
            f"{residual_text(self.residual)})"
        )
        out.append(f"  verdict: {self.verdict}")
        return out

    def __str__(self) -> str:
        return "\n".join(self._lines())

    def _repr_html_(self) -> str:
        return _html_pre("\n".join(self._lines()))


def _balancing(J: np.ndarray) -> np.ndarray:
    """The diagonal ``D`` of ``D⁻¹ J D`` balanced (``scipy.linalg.matrix_balance``, no permutation)."""
    if not J.size:
        return np.ones(0)
    from scipy.linalg import matrix_balance

    _, T = matrix_balance(J, permute=False)
    return np.diag(T).copy()


def _nullity(m: np.ndarray, tol: float) -> int:
    return int(np.sum(np.linalg.svd(m, compute_uv=False) <= tol)) if m.size else 0


def _zero_multiplicity(J: np.ndarray, values: np.ndarray, rtol: float) -> tuple[int, int]:
    """``(geometric, algebraic)`` multiplicity of the eigenvalue 0.

    The geometric one is the nullity of ``J`` (its singular values against ``rtol`` times its
    norm).  A defective zero eigenvalue (a Jordan chain over the family) comes out of ``eig`` as a
    cluster of size ``ε^(1/k)`` around 0, which no fixed tolerance on the eigenvalues recognises,
    and the nullities of ``J``'s powers confuse it with a small genuine eigenvalue beside a zero
    (the bicycle just past its capsize speed, ``λ = 0.004`` with ``|J| = 20``).  The symmetric
    functions of a rounded cluster stay as small as rounding makes them: the algebraic
    multiplicity is the largest ``m`` whose ``m`` eigenvalues of least modulus have every
    elementary symmetric function ``|e_k| ≤ CLUSTER_RTOL |J|^k`` (and at least the geometric one).
    """
    scale = float(np.linalg.norm(J, 2)) if J.size else 0.0
    if scale == 0.0:
        return J.shape[0], J.shape[0]
    geometric = _nullity(J, rtol * scale)
    smallest = values[np.argsort(np.abs(values), kind="stable")]
    algebraic = 0
    for m in range(1, len(smallest) + 1):
        coefficients = np.abs(np.poly(smallest[:m]))[1:]  # |e_1| … |e_m|
        if np.all(coefficients <= CLUSTER_RTOL * scale ** np.arange(1, m + 1)):
            algebraic = m
    return geometric, max(geometric, algebraic)


def _html_pre(text: str) -> str:
    """A result's text for Jupyter: its first line as the heading, the rest preformatted."""
    from chaplygin import _html

    head, *rest = text.splitlines()
    return _html.heading(head) + "<pre>" + _html.escape("\n".join(r.strip() for r in rest)) + "</pre>"


def _verdict(
    J: np.ndarray,
    names: Sequence[str],
    gradients: Mapping[str, np.ndarray],
    tol_rel: float = ZERO_RTOL,
) -> tuple[np.ndarray, np.ndarray, int, list[str], dict[str, bool], str, str, float]:
    # balanced first (a diagonal similarity, LAPACK's gebal): the reduced variables mix angles,
    # rates and multipliers whose scales differ by orders of magnitude, and every tolerance below
    # is relative to the norm, which balancing brings near the spectral radius
    D = _balancing(J)
    J = J * (1.0 / D)[:, None] * D[None, :]
    gradients = {name: grad * D for name, grad in gradients.items()}
    scale = float(np.linalg.norm(J, 2)) if J.size else 0.0
    tol = tol_rel * max(scale, 1e-300)
    values, vectors = np.linalg.eig(J) if J.size else (np.zeros(0, dtype=complex), np.zeros((0, 0)))
    vectors = D[:, None] * vectors
    family, n0 = _zero_multiplicity(J, values, tol_rel)
    zero = np.zeros(len(values), dtype=bool)
    zero[np.argsort(np.abs(values), kind="stable")[:n0]] = True
    values = np.where(zero, 0.0, values).astype(complex)
    real = np.where(np.abs(values.real) <= tol, 0.0, values.real)  # rounding does not order them
    order = np.lexsort((-np.imag(values), -real))
    values, vectors, zero = values[order], vectors[:, order], zero[order]
    integrals = {
        name: bool(np.linalg.norm(grad @ J) <= tol * max(float(np.linalg.norm(grad)), 1e-300))
        for name, grad in gradients.items()
        if np.linalg.norm(grad) > 0
    }
    consistent = [name for name, ok in integrals.items() if ok]
    rank = _rank([gradients[name] for name in consistent])
    from_family = min(n0, family)
    from_integrals = min(n0 - from_family, rank)
    zeros = [f"from the family of steady motions (its dimension here is {family})"] * from_family
    zeros += [
        f"a Jordan chain over the family, from the integrals {', '.join(consistent)} (changing their "
        "values moves the motion along the family)"
    ] * from_integrals
    unexplained = n0 - from_family - from_integrals
    zeros += ["not explained by the family or by an integral"] * unexplained
    rest = values[~zero]
    if rest.size and float(np.max(np.real(rest))) > tol:
        k = int(np.argmax(np.where(zero, -np.inf, np.real(values))))
        kind = "unstable"
        verdict = f"unstable (λ = {_complex(values[k])}, mode {_mode(vectors[:, k], names)})"
    elif unexplained:
        kind = "undetermined"
        verdict = (
            f"undetermined: {unexplained} zero eigenvalue(s) not explained by the family of steady "
            f"motions (dimension {family}) or by an integral"
            + (f" ({', '.join(consistent)})" if consistent else "")
        )
    elif rest.size and float(np.max(np.real(rest))) < -tol:
        kind = "asymptotically stable"
        verdict = f"asymptotically stable (modulo the family of steady motions, dimension {family})"
    elif not rest.size:
        kind = "linearly stable"
        verdict = "linearly stable: every eigenvalue is a neutral direction of the family of steady motions"
    else:
        kind = "linearly stable"
        axis = int(np.sum(np.abs(np.real(rest)) <= tol))
        verdict = (
            "linearly stable: all remaining eigenvalues on the imaginary axis (nonlinear stability not "
            "decided by the linearisation)"
            if axis == rest.size
            else f"linearly stable: {axis} remaining eigenvalue(s) on the imaginary axis, the others in the "
            "left half-plane (nonlinear stability not decided by the linearisation)"
        )
    return values, vectors, family, zeros, integrals, kind, verdict, tol


def _rank(rows: Sequence[np.ndarray]) -> int:
    """The number of independent rows (each scaled to norm 1 first)."""
    if not rows:
        return 0
    m = np.array([r / np.linalg.norm(r) for r in rows])
    singular = np.linalg.svd(m, compute_uv=False)
    return int(np.sum(singular > 1e-8 * singular[0]))


def _integral_gradients(
    lin: Linearization, y: np.ndarray, integrals: Mapping[str, Any] | None
) -> dict[str, np.ndarray]:
    out = lin.integral_gradients(y)
    for name, fn in (integrals or {}).items():
        if not callable(fn):
            raise InputError(
                f"integrals[{name!r}]: give a function of the state (a mapping of names to numbers) "
                "that returns the conserved quantity's value."
            )
        out[name] = _numeric_gradient(lin, y, fn)
    return out


def _numeric_gradient(
    lin: Linearization, y: np.ndarray, fn: Callable[[dict[str, float]], float]
) -> np.ndarray:
    """The gradient of a caller's integral along the reduced variables (central differences of the
    caller's function: the only finite differences here, on what the caller gives)."""
    point = lin._evaluate(y)
    P = lin._tangent(point)
    out = []
    for j in lin._kept:
        h = 1e-6 * max(1.0, abs(y[lin._free[j]]))
        values = [float(fn(dict(zip(lin.state, (y + sgn * h * P[:, j]).tolist())))) for sgn in (1, -1)]
        out.append((values[0] - values[1]) / (2 * h))
    return np.array(out)


def stability(
    system: System,
    point: Mapping[Any, Any],
    parameters: Mapping[Any, float] | None = None,
    *,
    model: str = "chetaev",
    form: str = "classic",
    integrals: Mapping[str, Callable[[dict[str, float]], float]] | None = None,
    rtol: float = ZERO_RTOL,
) -> Stability:
    """The linear stability of a steady motion of one model.

    Parameters
    ----------
    system : System
    point : mapping
        The steady motion, as initial states are written: coordinates by name (``"theta"``),
        velocities as ``"theta'"``, the vakonomic multipliers by name (``"mu_1"``); the ignorable
        coordinates may be left out, the dependent velocities follow from the constraints.
    parameters : mapping
        A number for every parameter.
    model : str
        ``"chetaev"`` (true motion; ``"chaplygin"``/``"voronets"`` give the same), ``"vakonomic"``,
        ``"lindelof"``.
    integrals : mapping, optional
        Further conserved quantities, each a function of the state (names to numbers); the energy is
        added where the system conserves it.
    rtol : float
        An eigenvalue, or a singular value, below ``rtol`` times the Jacobian's norm is zero.

    Returns
    -------
    Stability
        Eigenvalues, modes, the named zero eigenvalues and the verdict.

    Raises
    ------
    InputError
        If the point is not a steady motion of the model (the reduced rates do not vanish).
    """
    lin = linearize(system, model, parameters, form=form)
    y = lin.state_at(point)
    if isinstance(rtol, bool) or not isinstance(rtol, (int, float)) or not 0 < rtol < 1:
        raise InputError(f"rtol = {rtol!r}: give a number between 0 and 1 (the default is {ZERO_RTOL:g}).")
    return _stability_at(lin, y, integrals, rtol)


def _stability_at(
    lin: Linearization, y: np.ndarray, integrals: Mapping[str, Any] | None, rtol: float
) -> Stability:
    f, J = lin.reduced(y)
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(J))):
        raise InputError(
            f"point: the {lin.model} equations of {lin.system.name} are singular there (a pole of the "
            "mass matrix or of the solved constraints)."
        )
    scale = max(float(np.linalg.norm(J, 2)), 1.0) * max(1.0, float(np.max(np.abs(y))))
    residual = float(np.max(np.abs(f))) if f.size else 0.0
    if residual > 1e-8 * scale:
        worst = lin.variables[int(np.argmax(np.abs(f)))]
        raise InputError(
            f"point: not a steady motion of the {lin.model} model: the rate of {worst} is "
            f"{f[int(np.argmax(np.abs(f)))]:.3g}, not 0 (largest of the reduced rates); find one with "
            "steady_motions(system, guess=...)."
        )
    values, vectors, family, zeros, ints, kind, verdict, tol = _verdict(
        J, lin.variables, _integral_gradients(lin, y, integrals), rtol
    )
    point_f = lin._evaluate(y).f
    state = dict(zip(lin.state, y.tolist()))
    return Stability(
        system=lin.system.name,
        model=lin.model,
        point={name: state[name] for name in lin.variables},
        variables=lin.variables,
        ignorable={name: float(point_f[lin.state.index(name)]) for name in lin.ignorable},
        jacobian=J,
        eigenvalues=values,
        modes=vectors,
        family_dimension=family,
        zeros=zeros,
        integrals=ints,
        kind=kind,
        verdict=verdict,
        tolerance=tol,
        residual=residual,
    )


# ---------------------------------------------------------------------------- steady motions
@dataclass
class SteadyMotion:
    """A steady motion found by a Newton search (see :func:`steady_motions`).

    ``point`` gives the reduced variables (and the fixed ones) and the coordinates that holonomic
    relations fix; ``family_dimension`` is the dimension of the kernel of the equilibrium
    equations' Jacobian there: the number of parameters of the family of steady motions through it.
    """

    system: str
    model: str
    point: dict[str, float]
    fixed: tuple[str, ...]
    family_dimension: int
    residual: float

    def _repr_html_(self) -> str:
        return _html_pre(str(self))

    def __str__(self) -> str:
        point = ", ".join(f"{k} = {v + 0.0:.12g}" for k, v in self.point.items())
        return (
            f"Steady motion of {self.system} ({self.model} model): {point}\n"
            f"  held fixed: {', '.join(self.fixed) or 'nothing'}; family of steady motions of dimension "
            f"{self.family_dimension} through it; residual {residual_text(self.residual)}"
        )


def steady_motions(
    system: System,
    guess: Mapping[Any, Any] | None = None,
    parameters: Mapping[Any, float] | None = None,
    *,
    model: str = "chetaev",
    form: str = "classic",
    fixed: Sequence[str] | Mapping[str, Any] = (),
    solve_for: Sequence[str] | None = None,
    time_budget: float = 20.0,
) -> Any:
    """Steady motions (relative equilibria) of one model: symbolically, or by a Newton search.

    Parameters
    ----------
    system : System
    guess : mapping, optional
        A point near the steady motion, written as :func:`stability`'s ``point``.  Given: a Newton
        search (``scipy.optimize.root``, Levenberg–Marquardt, with the exact Jacobian) for the
        reduced variables not named in ``fixed``; returns a :class:`SteadyMotion`.  Omitted: the
        reduced equilibrium equations are solved with SymPy
        (:func:`chaplygin.analysis.steady.steady_family`) for ``solve_for`` (or unknowns it
        chooses) within ``time_budget`` seconds; returns a
        :class:`~chaplygin.analysis.steady.SteadyFamily`.  The symbolic route uses the reduced
        model of the motion (Chaplygin's or Voronets' equations for the true motion, Lindelöf's
        for the vakonomic one with ``c = 0``).
    parameters : mapping
        A number for every parameter (the Newton search); optional for the symbolic route.
    fixed : sequence of str, or mapping
        The Newton search: the variables kept at their guessed values (the family's parameters).
        The symbolic route: values (numbers or SymPy expressions) given to some variables before
        solving, e.g. ``{"theta": 0}``.
    solve_for : sequence of str, optional
        The symbolic route's unknowns (see :func:`chaplygin.analysis.steady.steady_family`).
    time_budget : float
        Seconds SymPy may spend solving (the symbolic route); a solve that takes longer is
        abandoned with a :class:`~chaplygin.errors.ChaplyginError` (it finishes unseen in a
        background thread, as Python cannot stop it).

    Returns
    -------
    SteadyMotion or SteadyFamily
        One steady motion (with a guess), or the family solved by SymPy (without).
    """
    if guess is None:
        from chaplygin.analysis.steady import steady_family

        reduced = _reduced_model(system, model)
        lin = linearize(system, reduced, parameters or _sample_parameters(system, reduced))
        held = dict(fixed) if isinstance(fixed, Mapping) else {}
        if fixed and not held:
            raise InputError("fixed: without a guess, give values: a mapping such as {'theta': 0}.")
        return steady_family(
            system, reduced, lin.ignorable, solve_for=solve_for, fixed=held, time_budget=time_budget
        )
    from scipy.optimize import root

    lin = linearize(system, model, parameters, form=form)
    y0 = lin.state_at(guess, guess=True)  # the relations' coordinates: where Newton starts
    fixed = list(fixed)
    for name in fixed:
        if name not in lin.variables:
            raise InputError(
                f"fixed: {name!r} is not a reduced variable of the {lin.model} model; they are "
                f"{', '.join(lin.variables)}."
            )
    positions = [lin._free[j] for j in lin._kept]
    unknown = [k for k, name in enumerate(lin.variables) if name not in fixed]

    def at(values: np.ndarray) -> np.ndarray:
        y = y0.copy()
        y[[positions[k] for k in unknown]] = values
        # the relations' coordinates from the guess's (solved) values: from 0, x² + y² = L² has no step
        return lin.admissible({i: y[i] for i in [*lin._free, *lin._hol]})

    def residual(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        f, J = lin.reduced(at(values))
        return f, J[:, unknown]

    start = y0[[positions[k] for k in unknown]]
    found = root(residual, start, jac=True, method="lm", options={"xtol": 1e-14, "ftol": 1e-14})
    y = at(found.x)
    f, J = lin.reduced(y)
    res = float(np.max(np.abs(f))) if f.size else 0.0
    finite = np.isfinite(res) and bool(np.all(np.isfinite(J)))
    scale = max(float(np.linalg.norm(J, 2)), 1.0) * max(1.0, float(np.max(np.abs(y)))) if finite else 0.0
    if not finite or res > 1e-9 * scale:
        raise ChaplyginError(
            f"steady_motions: no steady motion of the {lin.model} model near the guess (the Newton search "
            f"stopped with the largest reduced rate {res:.3g}); try another guess or fix other variables."
        )
    singular = np.linalg.svd(J, compute_uv=False)
    family = int(np.sum(singular <= ZERO_RTOL * max(float(singular[0]) if singular.size else 0.0, 1e-300)))
    state = dict(zip(lin.state, y.tolist()))
    # with the relations' coordinates, which stability() would otherwise solve again from 0
    point = {v: state[v] for v in [*lin.variables, *(lin.state[i] for i in lin._hol)]}
    return SteadyMotion(lin.system.name, lin.model, point, tuple(fixed), family, res)


def _reduced_model(system: System, model: str) -> str:
    entry = registry.get(model)
    if entry.reduced:
        return model
    if entry.is_true_motion:
        return registry.true_motion(system)
    reason = registry.get("lindelof").obstruction(system)
    if reason:
        raise ChaplyginError(
            f"steady_motions: the symbolic route needs a reduced model of the vakonomic motion "
            f"(Lindelöf's equations), which does not apply: {reason}. Give a guess for a Newton search."
        )
    return "lindelof"


def _sample_parameters(system: System, model: str) -> dict[str, float]:
    """Parameter values for the dependency structure only (random, positive)."""
    rng = np.random.default_rng(2029)
    names = [p.name for p in system.parameters] + [c.name for c in system.equations(model).constants]
    return {name: float(rng.uniform(0.5, 1.5)) for name in names}


# ---------------------------------------------------------------------------- root locus
@dataclass
class Crossing:
    """Where eigenvalues cross the imaginary axis along a root locus (see :meth:`RootLocus.crossings`).

    ``value``: the parameter there; ``eigenvalue``: the crossing eigenvalue there (``i ω`` of a
    complex pair, with ω ≥ 0, or 0); ``kind``: ``"a complex pair (oscillatory)"`` or ``"a real
    eigenvalue"``; ``change``: how many more eigenvalues have a positive real part past it, as the
    parameter increases (negative: the motion gains stability there).
    """

    value: float
    eigenvalue: complex
    kind: str
    change: int

    def __str__(self) -> str:
        where = "leave" if self.change < 0 else "enter"
        return (
            f"{self.value:.10g}: {self.kind} crosses the imaginary axis at {_complex(self.eigenvalue)} "
            f"({abs(self.change)} eigenvalue(s) {where} the right half-plane as it increases)"
        )


@dataclass
class RootLocus:
    """Eigenvalues of the reduced Jacobian along a family of steady motions (see :func:`root_locus`).

    ``values``: the parameter's values; ``eigenvalues``: one row per value, largest real part
    first; ``kinds``: the verdict's kind at each value; ``tolerances``: below what an eigenvalue
    counted as zero at each value.  :meth:`crossings` finds where eigenvalues cross the imaginary
    axis.
    """

    system: str
    model: str
    parameter: str
    values: np.ndarray
    eigenvalues: np.ndarray
    kinds: list[str]
    variables: tuple[str, ...]
    tolerances: np.ndarray = field(default_factory=lambda: np.zeros(0))
    _at: Callable[[float], np.ndarray] | None = field(default=None, repr=False, compare=False)

    def crossings(self, xtol: float = 1e-13) -> list[Crossing]:
        """Where eigenvalues cross the imaginary axis between the locus's values, refined.

        The zero eigenvalues every value has (the family of steady motions, the integrals) are
        set aside: the ``k`` eigenvalues of least modulus, ``k`` the fewest zero eigenvalues at any
        value.  Between two neighbouring values where the number of the others with a positive
        real part changes, bisection on that number (each step one evaluation of the generated
        Jacobian) narrows the interval to ``xtol`` relative; a real part counts as positive above
        ``1e-12`` times the Jacobian's scale (rounding noise of eigenvalues on the imaginary axis
        stays far below it).  Crossings between two values of the locus that cancel each other
        are not seen: give a finer grid.  The eigenvalues counted are ``eig``'s, none set to zero
        by a tolerance, so a crossing is as precise as they are: about 1e-10 relative for the
        bicycle's weave and capsize speeds; where two real eigenvalues meet the family's zeros
        (the upright coin's threshold) the four-fold cluster still leaves it near 1e-9.

        Returns
        -------
        list of Crossing
            In increasing order of the parameter (whatever the order of the locus's values).
        """
        if self._at is None or len(self.values) < 2:
            return []
        zero = np.abs(self.eigenvalues) <= self.tolerances[:, None]
        k = int(zero.sum(axis=1).min())
        scale = float(np.max(self.tolerances)) / ZERO_RTOL

        def others(values: np.ndarray) -> np.ndarray:
            return values[np.argsort(np.abs(values), kind="stable")[k:]]

        def unstable(values: np.ndarray) -> int:
            return int(np.sum(others(values).real > 1e-12 * scale))

        grid = np.unique(self.values)  # increasing: the values may be given in any order
        counts = [unstable(self._at(float(value))) for value in grid]
        found = []
        for i in np.flatnonzero(np.diff(counts)):
            lo, hi = float(grid[i]), float(grid[i + 1])
            c_lo = counts[i]
            while abs(hi - lo) > xtol * max(1.0, abs(lo)):
                mid = 0.5 * (lo + hi)
                if unstable(self._at(mid)) == c_lo:
                    lo = mid
                else:
                    hi = mid
            value = 0.5 * (lo + hi)
            if abs(value) <= 1e-9 * float(np.ptp(self.values)):
                value = 0.0  # at the grid's resolution, zero (the sleigh at rest)
            rest = others(self._at(value))
            at = complex(rest[int(np.argmin(np.abs(rest.real)))])
            # an odd change needs a real eigenvalue (conjugates cross together)
            pair = (counts[i + 1] - c_lo) % 2 == 0 and abs(at.imag) > 1e-12 * scale
            found.append(
                Crossing(
                    value,
                    complex(0.0, abs(at.imag)) if pair else 0j,
                    "a complex pair (oscillatory)" if pair else "a real eigenvalue",
                    counts[i + 1] - c_lo,
                )
            )
        return found

    def _repr_html_(self) -> str:
        return _html_pre(str(self))

    def __str__(self) -> str:
        lines = [f"Root locus of {self.system} ({self.model} model) against {self.parameter}"]
        for value, row, kind in zip(self.values, self.eigenvalues, self.kinds):
            largest = _complex(row[0], 4) if row.size else "-"
            lines.append(f"  {self.parameter} = {value:<10.4g} largest real part {largest:<20} {kind}")
        return "\n".join(lines)

    def plot(self, ax: Any = None) -> Any:
        """Real and imaginary parts of the eigenvalues against the parameter (matplotlib; imported
        here only); returns the figure."""
        import matplotlib.pyplot as plt

        if ax is None:
            fig, axes = plt.subplots(2, 1, sharex=True, figsize=(6.4, 5.6))
        else:
            axes = ax
            fig = axes[0].figure
        # one colour: the eigenvalues are sorted at each value, not followed along the locus
        along = np.repeat(self.values, self.eigenvalues.shape[1])
        axes[0].plot(along, self.eigenvalues.real.ravel(), ".", ms=3, color="C0")
        axes[1].plot(along, self.eigenvalues.imag.ravel(), ".", ms=3, color="C0")
        axes[0].axhline(0.0, color="0.5", lw=0.8)
        axes[0].set_ylabel("Re λ")
        axes[1].set_ylabel("Im λ")
        axes[1].set_xlabel(self.parameter)
        axes[0].set_title(f"{self.system}: {self.model} model")
        return fig


def root_locus(
    system: System,
    point: Mapping[Any, Any],
    vary: str,
    values: Sequence[float],
    parameters: Mapping[Any, float] | None = None,
    *,
    model: str = "chetaev",
    form: str = "classic",
    points: Callable[[float], Mapping[Any, Any]] | None = None,
) -> RootLocus:
    """The eigenvalues of the reduced Jacobian along a family of steady motions.

    Parameters
    ----------
    point : mapping
        A steady motion (as :func:`stability`'s ``point``).
    vary : str
        What changes: a variable of the point (``"phi'"``) or a parameter (``"g"``); with
        ``points``, any name (the bicycle's speed ``"v"``), a parameter's name also setting it.
    values : sequence of float
        Its values.
    points : callable, optional
        ``value -> point``: where the family's other variables change with ``vary`` (the lean of a
        turning disk), the steady motion at each value; ``point`` is then only the first guess.

    Notes
    -----
    The system is linearised once (:func:`linearize`); each further point costs one evaluation of
    the generated code, two small solves and an eigenvalue problem.  Varying a parameter
    recompiles nothing either: the generated code takes the parameters as an argument.
    """
    try:
        grid = np.asarray(values, dtype=float).ravel()
    except (TypeError, ValueError):
        raise InputError(f"values: give numbers for {vary}, not {values!r}.") from None
    if not grid.size or not np.all(np.isfinite(grid)):
        raise InputError(f"values: give at least one finite number for {vary}.")
    lin = linearize(system, model, parameters, form=form)
    is_parameter = vary in lin.parameters
    is_variable = not is_parameter
    if is_variable:
        try:
            _name(system, vary, list(lin.state))
        except InputError:
            if points is None:
                raise
            is_variable = False  # a label: points() gives the steady motion at each value

    def state(value: float) -> np.ndarray:
        where = dict(points(value)) if points is not None else dict(point)
        if is_variable:
            where[vary] = value
        return lin.state_at(where)

    def at(value: float, evaluate: Callable[[np.ndarray], Any]) -> Any:
        if is_parameter:
            lin._p[lin.layout.parameters.index(vary)] = value
        try:
            return evaluate(state(value))
        finally:
            if is_parameter:
                lin._p[:] = [lin.parameters[name] for name in lin.layout.parameters]

    def verdict(y: np.ndarray) -> Stability:
        return _stability_at(lin, y, None, ZERO_RTOL)

    def raw(y: np.ndarray) -> np.ndarray:  # no eigenvalue set to zero: for crossings()
        return np.linalg.eigvals(lin.reduced(y)[1])

    results = [at(float(value), verdict) for value in grid]
    return RootLocus(
        system.name,
        lin.model,
        vary,
        grid,
        np.array([r.eigenvalues for r in results]),
        [r.kind for r in results],
        lin.variables,
        np.array([r.tolerance for r in results]),
        lambda value: at(value, raw),
    )


def stability_conditions(system: System, point: Mapping[str, Any], *, model: str = "chetaev") -> Any:
    """The symbolic conditions for linear stability at ``point`` (names to numbers or SymPy
    expressions: ``{"theta": 0, "phi'": s, …}``), from the reduced model of the motion: see
    :func:`chaplygin.analysis.steady.stability_conditions`.  For a small reduced system."""
    from chaplygin.analysis.steady import stability_conditions as conditions

    reduced = _reduced_model(system, model)
    lin = linearize(system, reduced, _sample_parameters(system, reduced))
    return conditions(
        system, {k: v for k, v in point.items() if k not in lin.ignorable}, reduced, lin.ignorable
    )
