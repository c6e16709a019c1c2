"""Many initial conditions at once: final states without the dense trajectories.

:func:`simulate_ensemble` integrates one model from ``N`` initial states (and,
optionally, ``N`` sets of parameters) and keeps only what is asked for: by
default the state reached at the end, with the energy and the constraint
residual there.  Four engines:

* ``backend="c"`` (what ``"auto"``, the default, picks where a C compiler is
  found, below the GPU's share): the model's ``fill`` and the DOP853 loop in C
  (:mod:`chaplygin.numeric._ckernel`, a fraction of a second to build once per
  model), chunks of members handed by one Python thread per CPU core to the
  loop, which runs without the GIL;
* ``backend="numba"``: the same loop compiled by numba
  (:mod:`chaplygin.numeric._loop`; the same steps as SciPy's ``DOP853``, and as
  the C port), handed out the same way; its first compile takes seconds, once
  per installation and model;
* ``backend="jax"``: diffrax's ``Dopri8`` under ``jax.jit(jax.vmap(...))``,
  on a GPU when JAX sees one (optional extra ``chaplygin[jax]``);
* ``backend="cuda"`` (what ``"auto"`` picks from :data:`~chaplygin.numeric._cuda.AUTO_MEMBERS`
  members on where CuPy sees a GPU): the C backend's ``fill`` and its loop (the same C source)
  compiled into one GPU kernel, one thread per member with its own steps
  (:mod:`chaplygin.numeric._cuda`; optional extra ``chaplygin[cuda]``): the C loop's steps,
  statuses and, up to the last bits of the device's ``sin``, ``pow``, …, numbers.

A member that fails (step-size underflow, a blow-up, a singular mass matrix,
too many steps) does not stop the others: its status says so and its state is
the last one reached.  A member of a reduced model whose solved constraints meet
a pole stops there, as :func:`~chaplygin.numeric.simulate.simulate` does (code 9,
``failure`` ``"pole"``): it is checked, by the same tests, at :data:`POLE_CHECKS`
equally spaced times and at the samples kept, and a member that stepped more often than that
again as often as it stepped (up to ``POLE_CHECK_POINTS``).
"""

from __future__ import annotations

import math
import os
import time
import warnings
from collections.abc import Mapping, Sequence
from contextlib import suppress
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from chaplygin.errors import ChaplyginError, InputError
from chaplygin.models import registry
from chaplygin.numeric import _cuda, targets
from chaplygin.numeric._loop import STATUS
from chaplygin.numeric.codegen import CompiledModel, Layout
from chaplygin.numeric.simulate import (
    ESTIMATE_AFTER,
    POLE_CHECK_POINTS,
    TIME_LIMIT,
    _finite,
    _initial_multipliers,
    _vakonomic_setup,
    check_time_limit,
    duration,
    holonomic_residual,
    monitor,
    pole_free,
    sign_fixed,
    solve_holonomic,
    time_span,
)

if TYPE_CHECKING:
    from chaplygin.core.system import System
    from chaplygin.models.registry import Model

__all__ = ["ENSEMBLE_BACKENDS", "Ensemble", "simulate_ensemble"]

#: what ``backend=`` accepts; "auto" is "cuda" for an ensemble of at least
#: :data:`~chaplygin.numeric._cuda.AUTO_MEMBERS` members where CuPy sees a GPU, else "c" where a
#: C compiler is found, else "numba"
ENSEMBLE_BACKENDS = ("auto", *targets.offered("ensemble"))
#: the status code of a member that met a pole of its solved constraints (:data:`STATUS`)
POLE = 9
#: a reduced model's members are checked for a pole of the solved constraints at this many
#: equally spaced times, and at the samples kept
POLE_CHECKS = 101
#: the most numbers (members × check times × state) the samples of one block of members hold
_BLOCK_VALUES = 1 << 23


@dataclass
class Ensemble:
    """The outcome of :func:`simulate_ensemble` for ``N`` initial states.

    Attributes
    ----------
    layout : Layout
        Order of the columns of :attr:`y` (``layout.state``).
    t : ndarray, shape (N,)
        Time each member reached (``t1`` when it succeeded).
    y : ndarray, shape (N, len(layout.state))
        The state there.
    coordinates, velocities : dict of str → ndarray (N,)
        Every coordinate and every velocity (``"x'"``, dependent ones
        included) at :attr:`t`.
    y_initial : ndarray, shape (N, len(layout.state)), or None
        Each member's initial state (the multipliers of the vakonomic model included).
    velocities_initial : dict of str → ndarray (N,)
        Every velocity at the start, dependent ones included (from the constraints).
    energy, energy_initial : ndarray (N,)
        The monitored quantity at :attr:`t` and at the start: ``E = T − U``, or Jacobi's
        integral ``h = T₂ − T₀ − U`` where :attr:`energy_column` is ``"jacobi_integral"``
        (:func:`~chaplygin.numeric.simulate.monitor`).
    constraint_residual : ndarray (N,)
        ``max_β |f_β|`` at :attr:`t`: the constraint functions (``Σ_s A_βs q̇_s + A_β0`` for linear ones).
    holonomic_residual : ndarray (N,)
        ``max |f(q, t)|`` of the holonomic constraints at :attr:`t` (empty without them).
    notes : list of str
        What was changed at the start: the members whose holonomic coordinates were solved
        from ``f(q, t0) = 0`` (their count and the first few changes).
    code : ndarray of int (N,)
        0 for success, else why it failed (see :attr:`messages`).
    rhs_evaluations : ndarray of int (N,)
    times, samples : ndarray or None
        With ``keep`` times: the times and the states there, shape
        ``(N, len(times), len(layout.state))``; NaN after a failure.
    wall_time : float
        Seconds spent integrating (compilation excluded when it was cached).
    t_pole : ndarray (N,)
        For a member of a reduced model that met a pole of its solved constraints (code 9,
        :attr:`failure` ``"pole"``): the first time checked at or past the pole (the member
        stopped at :attr:`t`, the time checked before it); NaN for the others.
    """

    model: str
    form: str
    backend: str
    layout: Layout
    t: np.ndarray
    y: np.ndarray
    coordinates: dict[str, np.ndarray]
    velocities: dict[str, np.ndarray]
    energy: np.ndarray
    energy_initial: np.ndarray
    constraint_residual: np.ndarray
    code: np.ndarray
    rhs_evaluations: np.ndarray
    times: np.ndarray | None = None
    samples: np.ndarray | None = None
    wall_time: float = 0.0
    parameters: dict[str, np.ndarray] = field(default_factory=dict)
    t_pole: np.ndarray | None = None
    #: what :attr:`energy` holds: ``"energy"`` or ``"jacobi_integral"``
    energy_column: str = "energy"
    y_initial: np.ndarray | None = None
    velocities_initial: dict[str, np.ndarray] = field(default_factory=dict)
    holonomic_residual: np.ndarray = field(default_factory=lambda: np.zeros(0))
    notes: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.t)

    @property
    def success(self) -> np.ndarray:
        """Boolean mask of the members that reached the end."""
        return self.code == 0

    @property
    def status(self) -> np.ndarray:
        """``"success"`` or ``"failed"`` per member."""
        return np.where(self.code == 0, "success", "failed")

    @property
    def failure(self) -> np.ndarray:
        """Per member, as :attr:`Trajectory.failure <chaplygin.numeric.simulate.Trajectory.failure>`:
        ``"pole"`` where the solved constraints of a reduced model met a pole (code 9), else ``""``."""
        return np.where(self.code == POLE, "pole", "")

    @property
    def messages(self) -> list[str]:
        """Why each member stopped (``""`` for the successful ones)."""
        t_pole = self.t_pole if self.t_pole is not None else np.full(len(self.t), np.nan)
        return [
            ""
            if c == 0
            else f"stopped at t = {t:.6g}: {STATUS[POLE]} by t = {tp:.6g}"
            if c == POLE and np.isfinite(tp) and tp > t
            else f"stopped at t = {t:.6g}: {STATUS.get(int(c), 'failed')}"
            for c, t, tp in zip(self.code, self.t, t_pole)
        ]

    def energy_drift(self) -> np.ndarray:
        """``|E − E(0)| / max(1, |E(0)|)`` per member."""
        return np.abs(self.energy - self.energy_initial) / np.maximum(1.0, np.abs(self.energy_initial))

    def __getitem__(self, name: str) -> np.ndarray:
        for table in (self.coordinates, self.velocities):
            if name in table:
                return table[name]
        if name in self.layout.state:
            return self.y[:, self.layout.state.index(name)]
        if name == self.energy_column:
            return self.energy
        if name in ("t", "constraint_residual"):
            return getattr(self, name)
        raise KeyError(
            f"{name!r}: use a coordinate, a velocity, 't', {self.energy_column!r} or 'constraint_residual'"
        )

    def __repr__(self) -> str:
        failed = int(np.count_nonzero(self.code))
        return (
            f"<Ensemble {self.model}/{self.form} [{self.backend}]: {len(self)} members, "
            f"{failed} failed, {self.wall_time:.3g} s>"
        )

    def _repr_html_(self) -> str:
        """A summary table for notebooks: members, failures, the spread of energy drift and residual."""
        from chaplygin import _html

        drift, residual = self.energy_drift(), np.asarray(self.constraint_residual, dtype=float)

        def spread(a: np.ndarray) -> str:
            finite = a[np.isfinite(a)]
            return f"{np.median(finite):.3g} (median), {np.max(finite):.3g} (max)" if finite.size else "–"

        rows = [
            ("model", f"{self.model}/{self.form}"),
            ("backend", self.backend),
            ("members", str(len(self))),
            ("failed", str(int(np.count_nonzero(self.code)))),
            ("t reached", f"{np.min(self.t):g} … {np.max(self.t):g}" if len(self) else "–"),
            ("energy drift", spread(drift)),
            ("final constraint residual", spread(residual)),
            *(
                [("final holonomic residual", spread(np.asarray(self.holonomic_residual, dtype=float)))]
                if self.holonomic_residual.size
                else []
            ),
            ("wall time", f"{self.wall_time:.3g} s"),
        ]
        return _html.heading("Ensemble") + _html.fields((k, _html.escape(v)) for k, v in rows)

    def to_pandas(self) -> Any:
        """One row per member as a ``pandas.DataFrame`` indexed by ``run`` (0 … N−1).

        Columns named like a sweep's (:mod:`chaplygin.apps.sweep`): ``param.NAME`` (each member's
        parameters), ``initial.q`` and ``initial.q'`` for every coordinate (the member's start,
        dependent velocities included; and ``initial.mu_β`` of the vakonomic model), ``status``,
        ``message``, ``t_reached``, ``final.q`` and ``final.q'`` likewise at the end (and
        ``final.mu_β``), ``energy_initial``,
        ``energy_final``, ``energy_drift``, ``final.constraint_residual``,
        ``rhs_evaluations``; ``attrs``: ``model``, ``form``, ``backend``, ``members``,
        ``failed``, ``wall_time``.  The kept samples are in :meth:`to_xarray`.  Needs pandas
        (``pip install 'chaplygin[data]'``).
        """
        from chaplygin.numeric._dataout import ensemble_frame

        return ensemble_frame(self)

    def to_xarray(self) -> Any:
        """The members as an ``xarray.Dataset`` with dimension ``run``.

        The columns of :meth:`to_pandas` as variables over ``run``; with ``keep`` samples, a
        coordinate ``t`` (:attr:`times`) and one variable over ``(run, t)`` per entry of
        ``layout.state`` (NaN after a member failed).  Needs xarray
        (``pip install 'chaplygin[data]'``).
        """
        from chaplygin.numeric._dataout import ensemble_dataset

        return ensemble_dataset(self)


# ------------------------------------------------------------------ inputs
def _parameter_matrix(
    system: System, layout: Layout, parameters: Mapping[Any, Any] | None, n: int, one_row: bool = False
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """``P`` of shape (n, len(layout.parameters)): numbers broadcast, arrays of length n per member.
    ``one_row`` (:attr:`~chaplygin.numeric.targets.Target.one_parameter_row`): where every
    parameter is one number, ``P`` is one row seen n times, a read-only view."""
    columns: dict[str, np.ndarray] = {}
    uniform = True
    for key, value in (parameters or {}).items():
        name = system.parameter(key).name
        arr = np.asarray(value, dtype=float)
        uniform = uniform and arr.ndim == 0
        if arr.ndim == 0:
            arr = np.full(n, float(arr))
        if arr.shape != (n,):
            raise ChaplyginError(
                f"parameters: {name} must be a number or one value per member ({n}), not shape {arr.shape}."
            )
        columns[name] = arr
    missing = [name for name in layout.parameters if name not in columns]
    if missing:
        raise ChaplyginError(
            f"parameters: no value for {', '.join(missing)}; every parameter of {system.name} "
            f"({', '.join(layout.parameters)}) needs a number or an array."
        )
    kept = {name: columns[name] for name in layout.parameters}
    if not layout.parameters:
        return np.zeros((n, 0)), kept
    if uniform and one_row:
        return np.broadcast_to(
            np.array([columns[name][0] for name in layout.parameters]), (n, len(kept))
        ), kept
    return np.ascontiguousarray(np.column_stack(list(kept.values()))), kept


def _rows(P: np.ndarray, rows: slice | np.ndarray) -> np.ndarray:
    """``P[rows]``; where ``P`` is one row seen by every member (``one_row``), that row seen by
    each of ``rows`` (indexing would copy it out, once per member)."""
    if not _cuda.one_row(P):
        return P[rows]
    count = len(range(P.shape[0])[rows]) if isinstance(rows, slice) else len(rows)
    return np.broadcast_to(P[0], (count, P.shape[1]))


def _states(
    system: System,
    entry: Model,
    layout: Layout,
    initial_states: Any,
    P: np.ndarray | None,
    vak: dict[str, Any] | None,
    t0: float,
    notes: list[str] | None = None,
) -> np.ndarray:
    """``Y0`` (N × len(layout.state)) from an array in layout order or a list of mappings; what
    was solved at the start is told in ``notes``."""
    if isinstance(initial_states, np.ndarray) or (
        isinstance(initial_states, Sequence) and initial_states and not isinstance(initial_states[0], Mapping)
    ):
        Y0 = np.atleast_2d(np.asarray(initial_states, dtype=float))
        if Y0.ndim != 2 or Y0.shape[1] != len(layout.state):
            raise ChaplyginError(
                f"initial_states: an array of shape (N, {len(layout.state)}) in layout order "
                f"[{', '.join(layout.state)}], not shape {np.shape(initial_states)}."
            )
        if not np.all(np.isfinite(Y0)):
            bad = np.flatnonzero(~np.all(np.isfinite(Y0), axis=1))
            raise ChaplyginError(f"initial_states: rows {bad[:10].tolist()} are not finite.")
        return np.ascontiguousarray(Y0)
    if not isinstance(initial_states, Sequence) or not initial_states:
        raise ChaplyginError(
            "initial_states: give an (N, len(state)) array in layout order or a non-empty list "
            "of mappings like simulate()'s `initial`."
        )
    Q, QD = _given(system, initial_states)
    params = (
        {
            name: P[:, j]
            for j, name in enumerate(layout.parameters)
            if name in {p.name for p in system.parameters}
        }
        if P is not None
        else {}
    )
    changed = []
    for k in range(len(Q) if system._holonomic else 0):  # each member's start on f(q, t0) = 0
        told = solve_holonomic(system, Q[k], {name: float(v[k]) for name, v in params.items()}, t0)
        changed += [f"member {k}: {note}" for note in told[:1]]
    if changed and notes is not None:
        shown = "; ".join(changed[:3]) + ("; …" if len(changed) > 3 else "")
        notes.append(f"{len(changed)} member(s) solved from the holonomic constraints at the start ({shown})")
    if system.g:
        _dependent_velocities(system, Q, QD, params, t0)
    columns = [Q, QD if not entry.reduced else QD[:, list(system._ind)]]
    if entry.multipliers_in_state:
        columns.append(_multipliers(system, vak or {}, Q, QD, params, t0))
    return np.ascontiguousarray(np.column_stack(columns), dtype=float)


def _given(system: System, initial_states: Sequence[Any]) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates and velocities (N × n each, NaN where not given) from N mappings; every
    coordinate and independent velocity must be there (the messages name the member and key)."""
    from chaplygin.numeric.simulate import _lookup

    n, count = system.n, len(initial_states)
    Q, QD = np.full((count, n), np.nan), np.full((count, n), np.nan)
    where: dict[Any, tuple[str, int]] = {}  # a key's column, looked up once for all members
    for k, initial in enumerate(initial_states):
        if not isinstance(initial, Mapping):
            raise ChaplyginError(
                f"initial_states[{k}]: expected a mapping like simulate()'s `initial`, not "
                f"{type(initial).__name__} (or give every state as a row of one array)."
            )
        for key, value in initial.items():
            try:
                kind, i = where[key]
            except (KeyError, TypeError):  # new, or unhashable
                try:
                    kind, i = _lookup(system, key)
                except ChaplyginError as exc:
                    raise ChaplyginError(
                        f"initial_states[{k}]: {str(exc).removeprefix('initial: ')}"
                    ) from None
                with suppress(TypeError):
                    where[key] = kind, i
            label = system.coordinates[i].func.__name__ + ("'" if kind == "v" else "")
            (Q if kind == "q" else QD)[k, i] = _finite(
                value, f"initial_states[{k}]: {label}", "a finite number"
            )
    names = [c.func.__name__ for c in system.coordinates]
    needed = np.concatenate([np.isnan(Q), np.isnan(QD[:, list(system._ind)])], axis=1)
    if needed.any():
        k = int(np.flatnonzero(needed.any(axis=1))[0])
        labels = names + [names[i] + "'" for i in system._ind]
        missing = [label for label, lacking in zip(labels, needed[k]) if lacking]
        raise ChaplyginError(
            f"initial_states[{k}]: missing {', '.join(missing)}; give every coordinate and the "
            f"independent velocities ({', '.join(names[i] + chr(39) for i in system._ind)})."
        )
    return Q, QD


def _evaluate_all(
    system: System,
    exprs: Sequence[Any],
    Q: np.ndarray,
    QD: np.ndarray,
    params: Mapping[str, np.ndarray],
    t0: float,
) -> np.ndarray:
    """``exprs`` (internal symbols) at every member's state: one vectorised call, N × len(exprs)."""
    from chaplygin.core._sampling import compile_function
    from chaplygin.core._symbols import TIME

    v = system._vars
    f = compile_function(list(exprs), [TIME, *v.x, *v.xd, *(system.parameter(name) for name in params)])
    with np.errstate(all="ignore"):  # NaN velocities (not given yet) and poles show as NaN, not warnings
        values = f(t0, *Q.T, *QD.T, *params.values())
    return np.column_stack([np.broadcast_to(np.asarray(x, dtype=float), (len(Q),)) for x in values])


def _dependent_velocities(
    system: System, Q: np.ndarray, QD: np.ndarray, params: Mapping[str, np.ndarray], t0: float
) -> None:
    """Fill in the dependent velocities of every member from the constraints (``initial_state``
    for N members at once): ``A_dep q̇_dep = −(A_ind q̇_σ + A_0)``; a given one must agree.
    For constraints nonlinear in the velocities the solved form ``q̇_dep = φ`` (the branch
    chosen) comes first, and the solve is a Newton step from it."""
    ind, dep = list(system._ind), list(system._dep)
    names = [c.func.__name__ for c in system.coordinates]
    given_all = QD.copy()
    if system.is_nonlinear:
        phi = [system._velocity_substitution[system._vars.xd[i]] for i in dep]
        found = _evaluate_all(system, phi, Q, QD, params, t0)
        real = np.all(np.isfinite(found), axis=1)
        if not real.all():
            k = int(np.flatnonzero(~real)[0])
            raise ChaplyginError(
                f"initial_states[{k}]: the constraints give no real "
                f"{', '.join(names[i] + chr(39) for i in dep)} at this state (their solved form "
                f"{list(system.constraints.values())} is not real or not finite there)."
            )
        QD[:, dep] = found  # (the given ones kept in given_all, checked below)
    matrix = system._A.row_join(system._A0)
    a = _evaluate_all(system, list(matrix), Q, QD, params, t0).reshape(len(Q), *matrix.shape)
    lhs, rhs = a[:, :, dep], -(np.einsum("kij,kj->ki", a[:, :, ind], QD[:, ind]) + a[:, :, -1])
    solvable = np.all(np.isfinite(lhs), axis=(1, 2)) & np.all(np.isfinite(rhs), axis=1)
    solvable[solvable] = np.linalg.matrix_rank(lhs[solvable]) == len(dep)
    if not solvable.all():
        k = int(np.flatnonzero(~solvable)[0])
        if system.is_nonlinear:
            from chaplygin.numeric.simulate import singular_set_text

            raise ChaplyginError(
                f"initial_states[{k}]: the state lies on the singular set of the constraints, "
                f"{singular_set_text(system)}; start away from it."
            )
        raise ChaplyginError(
            f"initial_states[{k}]: the constraints cannot be solved for the dependent velocities "
            f"({', '.join(names[i] + chr(39) for i in dep)}) at this configuration."
        )
    implied = np.linalg.solve(lhs, rhs[:, :, None])[:, :, 0]
    given = given_all[:, dep]
    wrong = ~np.isnan(given) & (np.abs(given - implied) > 1e-9 * np.maximum(1.0, np.abs(implied)))
    if wrong.any():
        k, j = (int(x) for x in np.argwhere(wrong)[0])
        name = names[dep[j]]
        raise ChaplyginError(
            f"initial_states[{k}]: {name}' = {given[k, j]:g} violates the constraints, which give "
            f"{name}' = {implied[k, j]:.12g} (residual {given[k, j] - implied[k, j]:.3g})."
        )
    QD[:, dep] = implied


def _multipliers(
    system: System,
    vak: dict[str, Any],
    Q: np.ndarray,
    QD: np.ndarray,
    params: Mapping[str, np.ndarray],
    t0: float,
) -> np.ndarray:
    """μ(0) of every member of the vakonomic model (N × g).

    simulate's one-state path, for the first member, checks the request (and its μ(0) is every
    member's when μ(0) is given or ``constants="match"``); from constants c, ``μ = c − ∂T/∂q̇_dep``
    is evaluated for all members at once (one member after another where the family's
    integral does not apply: there c fixes the momenta at the start only).
    """
    first = _initial_multipliers(system, vak, Q[0], QD[0], {k: float(v[0]) for k, v in params.items()}, t0)
    c = vak.get("constants")
    if "mu" in vak or (isinstance(c, str) and c == "match"):
        return np.tile(first, (len(Q), 1))  # the same for every member
    if registry.family_obstructions(system):
        return np.array(
            [
                _initial_multipliers(
                    system, vak, Q[k], QD[k], {name: float(v[k]) for name, v in params.items()}, t0
                )
                for k in range(len(Q))
            ]
        )
    exprs = system.integrated_multipliers(c)
    names = system.equations("vakonomic").multipliers
    return _evaluate_all(system, [exprs[m].xreplace(system._to_sym) for m in names], Q, QD, params, t0)


def _row_max_abs(a: np.ndarray) -> np.ndarray:
    """``np.max(np.abs(a), axis=1)`` of a few columns, a column at a time: NumPy reduces a
    short row slowly (10⁶ rows of 2 columns: 60 ms; column by column 4 ms)."""
    out = np.abs(a[:, 0])
    for j in range(1, a.shape[1]):
        np.maximum(out, np.abs(a[:, j]), out=out)
    return out


def _observe_all(compiled: CompiledModel, t: np.ndarray, Y: np.ndarray, P: np.ndarray) -> np.ndarray:
    """``observe`` of every member (row ``k``: ``t[k]``, ``Y[k]``, ``P[k]``), by its target."""
    return targets.get(compiled.backend).observe_members(compiled, t, Y, P)


# ------------------------------------------------------------------ driver
def simulate_ensemble(
    system: System,
    model: str,
    t_span: tuple[float, float] | float,
    initial_states: Any,
    parameters: Mapping[Any, Any] | None = None,
    *,
    form: str = "classic",
    backend: str = "auto",
    rtol: float = 1e-10,
    atol: float = 1e-12,
    method: str = "DOP853",
    keep: Any = "final",
    constants: Any = None,
    multipliers: Any = None,
    max_step: float = np.inf,
    max_steps: int = 1_000_000,
    threads: int | None = None,
    reduction: str = "auto",
    time_limit: float | None = TIME_LIMIT,
) -> Ensemble:
    """Integrate ``model`` of ``system`` from many initial states.

    Parameters
    ----------
    system, model, t_span, form, rtol, atol, constants, multipliers, max_step, reduction :
        As for :func:`chaplygin.numeric.simulate.simulate`.
    initial_states : array (N, len(state)) or list of mappings
        Either states in layout order (``compile_model(system, model).layout.state``:
        coordinates, the integrated velocities, multipliers), or ``N``
        mappings like ``simulate``'s ``initial`` (dependent velocities follow
        from the constraints, computed for all members in one vectorised
        step; an error names the member, ``initial_states[k]``, and the key;
        the dependent coordinates of holonomic constraints are solved from
        ``f(q, t0) = 0`` for each member, as :func:`simulate` does, the given
        values the first guess).  An array in layout order is taken as it is.
        An array for a multiplier model (all velocities integrated) must
        satisfy the constraints.
    parameters : mapping
        A number for every parameter, or an array of ``N`` numbers (one per
        member) for a parameter sweep.
    backend : {"auto", "c", "numba", "jax", "cuda"}
        The compiled DOP853 loop on all CPU cores (``threads`` of them if
        given), in C or compiled by numba, or diffrax under ``jax.vmap``
        (``method`` ``"DOP853"`` → ``Dopri8``, ``"RK45"``, ``"RK23"``), or
        the C loop as a GPU kernel, one thread per member (``"cuda"``: needs
        CuPy, ``pip install 'chaplygin[cuda]'``, an NVIDIA GPU and a C compiler;
        ``threads`` and ``time_limit`` do not apply).
        ``"auto"``: ``"cuda"`` from :data:`~chaplygin.numeric._cuda.AUTO_MEMBERS` members on
        where CuPy sees a GPU, else ``"c"`` where a C compiler is found and the model's
        functions have C translations, else ``"numba"``.
    keep : "final", int, or sequence of times
        ``"final"``: only the end state.  An int ``k``: also ``k`` equally
        spaced samples; a sequence: samples at those times (states only, in
        :attr:`Ensemble.samples`).
    max_steps : int
        A member that needs more steps fails (0: no limit; not for jax).
    time_limit : float or None
        Seconds (default :data:`~chaplygin.numeric.simulate.TIME_LIMIT`, one hour; None: no
        limit).  Before the ensemble starts, the first member is integrated for up to half a
        second; an ensemble that this says would take longer (its pace, times the members, over
        the threads) is refused with an :class:`~chaplygin.errors.InputError` that gives the
        estimate (not for jax and cuda).  So is one whose kept samples would not fit in memory.

    Returns
    -------
    Ensemble
    """
    t0, t1 = time_span(t_span)
    if not t1 > t0:
        raise InputError(f"t_span: the end time {t1:g} must be after the start {t0:g}.")
    time_limit = check_time_limit(time_limit)
    if threads is not None and (
        isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1
    ):
        raise InputError(
            f"threads = {threads!r}: give a whole number of threads, 1 or more (None: every core)."
        )
    # the table as it is now (ENSEMBLE_BACKENDS is it at import)
    names = ("auto", *targets.offered("ensemble"))
    if backend not in names:
        raise ChaplyginError(f"backend {backend!r}: ensembles run on {', '.join(map(repr, names))}.")
    methods = ("DOP853",) if backend == "auto" else targets.get(backend).ensemble_methods
    if method not in methods:
        raise ChaplyginError(
            f"method {method!r}: backend {backend!r} integrates ensembles with "
            + (
                f"{methods[0]!r} only (backend='jax' has 'RK45' and 'RK23')."
                if len(methods) == 1
                else f"{', '.join(map(repr, methods))}."
            )
        )
    times = _keep_times(keep, t0, t1)
    entry = registry.get(model)  # the model, looked up once: what follows takes the entry
    family_c, vak = _vakonomic_setup(system, entry, constants, multipliers)
    if isinstance(family_c, str):  # "match": c_β = ∂T/∂q̇_dep at each member's own start
        raise ChaplyginError(
            f"constants='match': for {model!r} the constants follow from each member's start, and "
            "an ensemble compiles one model for all; give the numbers, or use model 'vakonomic' "
            "(μ integrated), where constants='match' starts every member with μ(0) = 0."
        )
    n = len(initial_states)
    if n == 0:
        raise ChaplyginError("initial_states: no initial states given.")
    compiled = _compile(system, entry, form, backend, family_c, reduction, n)
    backend = compiled.backend
    target = targets.get(backend)
    compiled = target.looped(compiled, method)  # (numba: its observe compiled and cached with the loop)
    layout = compiled.layout

    P, param_columns = _parameter_matrix(system, layout, parameters, n, target.one_parameter_row)
    notes: list[str] = []
    Y0 = _states(system, entry, layout, initial_states, P, vak, t0, notes)

    g = system.g
    n_coords = len(layout.coordinates)
    # a multiplier model integrates every velocity: its start may violate the constraints, and is
    # checked before the run; a reduced one solves the dependent velocities from them
    start_checked = bool(g) and not entry.reduced
    obs0 = None  # (observed in the run, on its device, where the target does so)
    if start_checked or not target.observes_start:
        obs0 = _observe_all(compiled, np.full(n, t0), Y0, P)
    if start_checked:
        assert obs0 is not None
        resid0 = _row_max_abs(obs0[:, 1 : 1 + g])
        speed = np.maximum(1.0, _row_max_abs(obs0[:, obs0.shape[1] - n_coords :]))
        bad = np.flatnonzero(resid0 > 1e-8 * speed)
        if bad.size:
            raise ChaplyginError(
                f"initial_states: rows {bad[:10].tolist()} violate the constraints (residual up to "
                f"{resid0[bad].max():.3g}); give states that satisfy them."
            )

    _check_memory(n, 0 if times is None else len(times), len(layout.state))
    if target.paced and time_limit is not None:
        _check_time(compiled, (t0, t1), Y0[0], P[0], rtol, atol, max_step, max_steps, n, threads, time_limit)

    def integrate(rows: slice | np.ndarray, sample_times: np.ndarray | None) -> dict[str, np.ndarray]:
        return target.ensemble(
            compiled, (t0, t1), Y0[rows], _rows(P, rows), times=sample_times, rtol=rtol, atol=atol,
            method=method, max_step=max_step, max_steps=max_steps, threads=threads,
        )  # fmt: skip

    start = time.perf_counter()
    # a reduced model's solved constraints may meet a pole (pole_free: not where they cannot)
    watch = entry.reduced and not pole_free(system)
    # the sign of the test may change (sign_fixed: not where it cannot): looked for in between
    crossings = watch and not sign_fixed(system)
    if watch:  # checked at the start, the kept times, the end and (crossings) POLE_CHECKS times

        def checked(members: np.ndarray, points: int) -> dict[str, np.ndarray]:
            grid = np.linspace(t0, t1, points)
            checks = grid if times is None else np.union1d(grid, times)
            block = max(1, _BLOCK_VALUES // (max(1, len(checks)) * Y0.shape[1]))
            parts = []
            for i in range(0, len(members), block):
                rows = members[i : i + block]
                part = integrate(rows, checks)
                _stop_at_poles(system, compiled, part, Y0[rows], _rows(P, rows), checks, t0)
                kept = part.pop("samples")
                if times is not None:  # the kept times among the checked ones
                    part["samples"] = kept[:, np.searchsorted(checks, times)]
                parts.append(part)
            return {key: np.concatenate([part[key] for part in parts]) for key in parts[0]}

        res = checked(np.arange(n), POLE_CHECKS if crossings else 0)
        # a member that took more steps than the times checked (each right-hand side bounds a
        # sixth of a step from above) may have crossed a pole and back between two of them: it is
        # integrated again (the same steps) and checked at least as often as it stepped
        need = np.minimum(POLE_CHECK_POINTS, np.asarray(res["n_rhs"]) // 6 + 1)
        again = np.flatnonzero(crossings & (need > POLE_CHECKS + (0 if times is None else len(times))))
        if again.size:
            redone = checked(again, int(need[again].max()))
            for key, value in redone.items():
                res[key][again] = value
    else:
        res = integrate(slice(None), times)
    wall = time.perf_counter() - start
    observed0 = res.pop("observed0", None)  # (the target's observes_start)
    obs0 = observed0 if obs0 is None else obs0
    assert obs0 is not None

    obs = res["observed"]
    velocities = obs[:, obs.shape[1] - n_coords :]
    velocities0 = obs0[:, obs0.shape[1] - n_coords :]
    residual = _row_max_abs(obs[:, 1 : 1 + g]) if g else np.zeros(n)
    return Ensemble(
        model=layout.model,
        form=layout.form,
        backend=backend,
        layout=layout,
        t=res["t"],
        y=res["y"],
        coordinates={name: res["y"][:, i] for i, name in enumerate(layout.coordinates)},
        velocities={name + "'": velocities[:, i] for i, name in enumerate(layout.coordinates)},
        energy=obs[:, 0],
        energy_initial=obs0[:, 0],
        energy_column=monitor(system).column,
        constraint_residual=residual,
        code=res["code"],
        rhs_evaluations=res["n_rhs"],
        times=times,
        samples=res.get("samples"),
        wall_time=wall,
        parameters=param_columns,
        holonomic_residual=holonomic_residual(
            system, res["t"], list(res["y"][:, : system.n].T), param_columns
        ),
        notes=notes,
        t_pole=res.get("t_pole", np.full(n, np.nan)),
        y_initial=Y0,
        velocities_initial={name + "'": velocities0[:, i] for i, name in enumerate(layout.coordinates)},
    )


def _stop_at_poles(
    system: System,
    compiled: CompiledModel,
    res: dict[str, np.ndarray],
    Y0: np.ndarray,
    P: np.ndarray,
    times: np.ndarray,
    t0: float,
) -> None:
    """End each member of ``res`` (:func:`~chaplygin.numeric._loop.ensemble_dop853`'s arrays, with
    ``samples`` at ``times``) where its solved constraints meet a pole, as ``simulate`` does.

    The tests of :func:`~chaplygin.numeric.simulate.pole_marks` run over the start, every sample
    reached and the last state, in the order of the run: a member singular at one of these
    points, or whose sign changes between two, gets code 9 (a pole), its time and state become
    those of the point before, its samples from the pole on NaN, and ``res["t_pole"]`` the time
    of the point at or past the pole (NaN for the other members; for a member the loop itself
    stopped with code 9, a non-finite velocity, the time it stopped).
    """
    from chaplygin.numeric.simulate import pole_marks

    layout = compiled.layout
    count, n_times = len(Y0), len(times)
    n = len(layout.coordinates)
    samples = res["samples"]
    # points: the start, the samples, the last state; those not reached (NaN samples) left out
    tt = np.concatenate(
        [np.full((count, 1), t0), np.broadcast_to(times, (count, n_times)), res["t"][:, None]], 1
    )
    qq = np.concatenate([Y0[:, None, :n], samples[:, :, :n], res["y"][:, None, :n]], axis=1)
    reached = np.all(np.isfinite(qq), axis=2)
    reached[:, 1:-1] &= times[None, :] <= res["t"][:, None]
    rows, cols = np.nonzero(reached)
    params = {name: P[rows, j] for j, name in enumerate(layout.parameters)}
    speeds = None
    if system.is_nonlinear:  # (a reduced state: the independent velocities follow the coordinates)
        e = slice(n, n + len(system._ind))
        vv = np.concatenate([Y0[:, None, e], samples[:, :, e], res["y"][:, None, e]], axis=1)
        speeds = vv[rows, cols]
    singular_at, sign_at = pole_marks(system, tt[rows, cols], qq[rows, cols], params, speeds)
    singular = np.zeros(reached.shape, dtype=bool)
    sign = np.full(reached.shape, np.nan)
    singular[rows, cols], sign[rows, cols] = singular_at, sign_at
    # the last point reached at or before each one (its sign: that of the run so far)
    before = np.maximum.accumulate(np.where(reached, np.arange(reached.shape[1]), 0), axis=1)
    member = np.arange(count)[:, None]
    changed = np.zeros(reached.shape, dtype=bool)
    changed[:, 1:] = reached[:, 1:] & (sign[:, 1:] != sign[member, before[:, :-1]])
    bad = reached & (singular | changed)
    t_pole = np.where(res["code"] == POLE, res["t"], np.nan)
    hit = np.flatnonzero(bad.any(axis=1))
    if hit.size:
        for key in ("t", "y", "code", "observed"):  # (writable: the jax backend's arrays are not)
            res[key] = np.array(res[key])
        k = np.argmax(bad[hit], axis=1)  # the first point at or past the pole
        last = np.where(k > 0, before[hit, np.maximum(k - 1, 0)], 0)  # the point before it
        t_pole[hit] = tt[hit, k]
        states = np.concatenate([Y0[:, None, :], samples, res["y"][:, None, :]], axis=1)
        res["t"][hit] = tt[hit, last]
        res["y"][hit] = states[hit, last]
        res["code"][hit] = POLE
        after = np.arange(n_times)[None, :] >= np.maximum(k - 1, 0)[:, None]  # samples from the pole on
        samples[hit] = np.where(after[:, :, None], np.nan, samples[hit])
        res["observed"][hit] = _observe_all(compiled, res["t"][hit], res["y"][hit], P[hit])
    res["t_pole"] = t_pole


def _check_memory(members: int, samples: int, width: int) -> None:
    """Refuse an ensemble whose arrays (the kept samples, the final states) would not fit in memory."""
    need = 8.0 * members * (samples + 2) * width
    try:
        have = float(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, ValueError, OSError):  # pragma: no cover - not POSIX
        return
    if need > have / 2:
        raise InputError(
            f"keep: {members} members × {samples} samples × {width} states need about {need / 2**30:.3g} GiB, "
            f"more than half of this machine's memory ({have / 2**30:.3g} GiB); keep fewer samples "
            "or split the ensemble."
        )


def _check_time(
    compiled: CompiledModel,
    t_span: tuple[float, float],
    y0: np.ndarray,
    p: np.ndarray,
    rtol: float,
    atol: Any,
    max_step: float,
    max_steps: int,
    members: int,
    threads: int | None,
    limit: float,
) -> None:
    """Integrate the first member for up to :data:`ESTIMATE_AFTER` seconds (in stretches of
    steps, the first one, which may compile, not timed) and refuse the ensemble if its pace says
    the whole would take longer than ``limit`` seconds on ``threads`` threads."""
    from chaplygin.numeric._loop import default_threads, integrate_dop853

    t0, t1 = t_span
    t, y, h, stretch, steps = t0, y0, None, 64, 0
    origin: tuple[float, float, int] | None = None
    while True:
        res = integrate_dop853(
            compiled,
            (t, t1),
            y,
            p,
            np.empty(0),
            rtol=rtol,
            atol=atol,
            max_step=max_step,
            first_step=h,
            max_steps=stretch,
        )
        steps += res.n_steps
        now = time.monotonic()
        if res.code != 4 or res.y_last is None or (max_steps and steps >= max_steps):
            return  # the first member ends (or fails) within the probe
        t, y, h = res.t_last, res.y_last, res.h_next
        if origin is None:
            origin = (now, t, steps)
            continue
        elapsed = now - origin[0]
        if elapsed >= ESTIMATE_AFTER:
            break
        stretch = min(2 * stretch, 1 << 30)
    per_member = elapsed * (t1 - t0) / (t - origin[1]) if t > origin[1] else math.inf
    if max_steps:  # a member stops after max_steps steps
        per_member = min(per_member, elapsed * max_steps / max(steps - origin[2], 1))
    workers = max(1, min(members, int(threads) if threads is not None else default_threads()))
    total = per_member * members / workers
    if total > limit:
        raise InputError(
            f"t_span: this ensemble would take about {duration(total)} ({members} members; the first "
            f"reached t = {t:.4g} of {t1:g} at its pace over {elapsed:.1f} s, on {workers} thread"
            f"{'s' if workers > 1 else ''}), beyond the limit of {duration(limit)}; ask for less, or "
            "pass time_limit=None to run it anyway."
        )


def _compile(
    system: System, model: Model, form: str, backend: str, constants: Any, reduction: str, members: int
) -> CompiledModel:
    """The compiled model for ``backend``; ``"auto"``: the GPU for :data:`~chaplygin.numeric._cuda.AUTO_MEMBERS`
    members or more where CuPy sees a device, else the C backend, else numba.  ``"cuda"`` is the
    ``c`` backend's model (its C ``fill`` goes into the GPU kernel) with the GPU kernel built."""
    from chaplygin.numeric.codegen import BackendUnavailable

    if backend != "auto":
        return targets.get(backend).compile_model(system, model, form, constants, reduction)
    cuda = targets.get("cuda")
    if members >= _cuda.AUTO_MEMBERS and cuda.unavailable() is None:
        try:
            return cuda.compile_model(system, model, form, constants, reduction)
        except ChaplyginError as exc:
            warnings.warn(f"backend 'auto' runs on the CPU: the GPU failed ({exc})", stacklevel=3)
    with suppress(BackendUnavailable):
        return targets.get("c").compile_model(system, model, form, constants, reduction)
    return targets.get("numba").compile_model(system, model, form, constants, reduction)


def _keep_times(keep: Any, t0: float, t1: float) -> np.ndarray | None:
    if isinstance(keep, str):
        if keep != "final":
            raise ChaplyginError(f"keep={keep!r}: use 'final', a number of samples, or times.")
        return None
    if np.isscalar(keep):
        k = int(keep)  # type: ignore[arg-type]
        if k < 2:
            raise ChaplyginError("keep: at least 2 samples (the start and the end).")
        return np.linspace(t0, t1, k)
    times = np.asarray(keep, dtype=float)
    if times.ndim != 1 or times.size == 0 or np.any(np.diff(times) < 0) or times[0] < t0 or times[-1] > t1:
        raise ChaplyginError(f"keep: increasing output times within [{t0:g}, {t1:g}].")
    return times
