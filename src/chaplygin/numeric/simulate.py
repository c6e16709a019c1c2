"""Numerical simulation of any model from one initial state, with invariants monitored.

Reduced models (Chaplygin, Voronets, Lindelöf, the vakonomic family) integrate
all coordinates and the independent velocities; the dependent coordinates
follow through the constraints.  The multiplier models integrate all
coordinates and velocities (and μ for the vakonomic model) with the
constraints imposed at acceleration level; their constraint residual shows the
drift.  Integration: with ``backend="c"`` (what ``"auto"``, the default, picks
for DOP853 where a C compiler is found; see :func:`choose_backend`) or
``backend="numba"`` and DOP853, a compiled port of SciPy's DOP853 that runs
entirely in C (:mod:`chaplygin.numeric._ckernel`) or inside numba (:mod:`chaplygin.numeric._loop`); with
``backend="numpy"`` and DOP853, the same port in plain Python on lists
(:mod:`chaplygin.numeric._pyloop`, no SciPy import); with ``backend="jax"``,
diffrax; otherwise (the other methods) SciPy's stepper classes driven step by
step.  Every path ends a failed run (step-size underflow, a singular mass
matrix, a blow-up) with a status, a message and the trajectory so far; after a
failure inside a step, the compiled loops and the Python steppers integrate
again from the last accepted step with smaller steps, so the samples reach the
failure whatever steps the integrator chose.

Before integrating, :func:`simulate` refuses (:class:`~chaplygin.errors.InputError`)
what cannot be a motion: non-finite parameters or initial values, a time span
or sample count that is not finite or too large, a start on a pole of the solved
constraints, and a reduced mass matrix that is not positive definite or is
ill-conditioned.  After integrating, a reduced model's run stops where its solved
constraints have a pole or its mass matrix stops being positive definite.
"""

from __future__ import annotations

import math
import os
import tempfile
import time
import weakref
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from chaplygin.errors import ChaplyginError, InputError
from chaplygin.models import registry
from chaplygin.numeric import targets
from chaplygin.numeric._dop853 import StepFailure as _StepFailure

if TYPE_CHECKING:  # SymPy, code generation and SciPy are imported where they are used: a
    # warm run of the command line (chaplygin.numeric._plan) needs none of them
    from chaplygin.core.system import System
    from chaplygin.models.registry import Model
    from chaplygin.numeric._ckernel import CompiledModel
    from chaplygin.numeric._plan import LoadedFile

__all__ = [
    "BACKENDS",
    "MAX_CONDITION",
    "MAX_SAMPLES",
    "METHODS",
    "TIME_LIMIT",
    "Trajectory",
    "choose_backend",
    "duration",
    "simulate",
    "vakonomic_constants",
]

#: chaplygin.numeric.symmetric.METHODS (the tests check that they agree; not imported: it compiles)
SYMMETRIC_METHODS = ("midpoint", "gauss4", "gauss6")
METHODS = ("DOP853", "RK45", "RK23", "Radau", "BDF", "LSODA", *SYMMETRIC_METHODS)
#: what ``backend=`` accepts: "auto" chooses one of the others (:func:`choose_backend`)
BACKENDS = ("auto", *targets.offered("simulate"))


def choose_backend(backend: str, method: str = "DOP853") -> str:
    """The backend that ``backend="auto"`` runs ``method`` with; any other value as it is.

    ``"auto"`` is ``"c"`` (the generated ``fill`` and the DOP853 loop in C,
    :mod:`chaplygin.numeric._ckernel`) for ``DOP853`` where a C compiler is found: it
    costs a fraction of a second to build once per model, nothing later (the
    kernel cache), and integrates at compiled speed, so it pays for itself on
    any run.  Otherwise ``"numpy"`` (no build step; plain Python).  numba is
    never chosen: its first compile of a model takes seconds, and importing it
    half a second more; ``backend="numba"`` still asks for it.
    """
    targets.require(backend, "simulate")  # (the table as it is now: BACKENDS is it at import)
    if backend != "auto":
        return backend
    if method == "DOP853" and targets.get("c").unavailable() is None:
        return "c"
    return "numpy"


class Monitor(NamedTuple):
    """What the ``energy`` column of a run holds (:func:`monitor`)."""

    #: the column's name: ``"energy"`` or ``"jacobi_integral"``
    column: str
    #: how it reads in words: ``"energy"`` or ``"Jacobi integral"``
    name: str
    #: its formula
    formula: str
    #: whether it is an invariant of the motion (its change is then an integration error)
    conserved: bool


def monitor(system: System) -> Monitor:
    """What the monitor of ``system``'s runs computes, and whether it is conserved.

    With no non-potential forces, homogeneous constraints and nothing that depends on time
    explicitly (:attr:`System.conserves_energy <chaplygin.System.conserves_energy>`), every
    model conserves Jacobi's integral ``h = Σ q̇_s ∂T/∂q̇_s − T − U = T₂ − T₀ − U`` (the vakonomic
    ones too: ``μ φ`` drops out of it, φ being homogeneous of degree one): the energy
    ``E = T − U`` where T is quadratic in the velocities, else — a kinetic energy with
    velocity-linear and velocity-free parts, e.g. a body written in a rotating frame — ``h``,
    a different number, which the column then holds and is named after.  Otherwise nothing is
    conserved in general and the column holds E, reported as a change, not a drift.
    """
    conserved = system.conserves_energy
    if conserved and not _quadratic(system):
        return Monitor("jacobi_integral", "Jacobi integral", "h = T₂ − T₀ − U", True)
    return Monitor("energy", "energy", "E = T − U", conserved)


def _quadratic(system: System) -> bool:
    """Whether T is a homogeneous quadratic form in the velocities (then ``h = T − U = E``):
    :attr:`chaplygin.System._quadratic_T` (a run plan's stand-in for the system keeps it too)."""
    return bool(system._quadratic_T)


#: the most samples one run returns: each is a row of every column in memory (10**6 samples
#: of a ten-coordinate system take about 0.2 GB, more while they are observed)
MAX_SAMPLES = 10**6
#: the largest condition number of the reduced mass matrix accepted at the start: beyond it
#: the accelerations lose more than about four of the sixteen digits of a double
MAX_CONDITION = 1e12


@dataclass
class Trajectory:
    """A simulated motion, sampled at :attr:`t`.

    Attributes
    ----------
    t : ndarray
        Sample times.
    coordinates, velocities : dict of str → ndarray
        Every coordinate and every velocity (``"x'"``), dependent ones included.
    multipliers : dict of str → ndarray
        λ (Chetaev) or μ (vakonomic) where the model has them.
    energy : ndarray
        The monitored quantity at each sample (:func:`monitor`): the energy ``E = T − U``,
        or, where T has velocity-linear and velocity-free parts but nothing depends on time
        (a rotating frame), Jacobi's integral ``h = T₂ − T₀ − U``, the column then named
        ``jacobi_integral`` (:attr:`energy_column`).  For rheonomic or affine constraints or
        non-potential forces it is E and not an invariant (:attr:`energy_conserved`).
    constraint_residual : ndarray
        ``max_β |Σ_s A_βs q̇_s + A_β0|`` at each sample (the holonomic relations' time
        derivatives among them).
    holonomic_residual : ndarray
        ``max_k |f_k(q, t)|`` of the holonomic constraints at each sample (empty for a
        system without them): the drift of the motion off ``f = 0``.
    notes : list of str
        What :func:`simulate` changed or assumed, e.g. a dependent coordinate of a holonomic
        constraint solved at the start (``z: 0.3 → 0.2955``).
    status, message : str
        ``"success"`` or ``"failed"``, and why.
    failure : str
        What stopped a failed run where a check of :func:`simulate` found it:
        ``"pole"`` (the solved constraints of a reduced model have a pole there),
        ``"mass"`` (the mass matrix stopped being positive definite); else ``""``.
    """

    model: str
    form: str
    backend: str
    t: np.ndarray
    coordinates: dict[str, np.ndarray]
    velocities: dict[str, np.ndarray]
    multipliers: dict[str, np.ndarray]
    energy: np.ndarray
    constraint_residual: np.ndarray
    status: str = "success"
    message: str = ""
    parameters: dict[str, float] = field(default_factory=dict)
    rhs_evaluations: int = 0
    failure: str = ""
    #: whether the monitored quantity is an invariant of the system (:func:`monitor`)
    energy_conserved: bool = True
    #: the monitored quantity's column: ``"energy"``, or ``"jacobi_integral"`` (:func:`monitor`)
    energy_column: str = "energy"
    #: ``max_k |f_k(q(t), t)|`` of the holonomic constraints (empty without them)
    holonomic_residual: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: what the run changed or assumed (a coordinate solved from a holonomic constraint)
    notes: list[str] = field(default_factory=list)

    @property
    def energy_label(self) -> str:
        """``"energy drift"`` where E is an invariant (an integration error), else ``"energy change"``;
        ``"Jacobi integral drift"`` where the column holds Jacobi's integral."""
        name = "Jacobi integral" if self.energy_column == "jacobi_integral" else "energy"
        return f"{name} {'drift' if self.energy_conserved else 'change'}"

    @property
    def success(self) -> bool:
        return self.status == "success"

    def __getitem__(self, name: str) -> np.ndarray:
        for table in (self.coordinates, self.velocities, self.multipliers):
            if name in table:
                return table[name]
        if name == self.energy_column:
            return self.energy
        if name in ("t", "constraint_residual") or (
            name == "holonomic_residual" and self.holonomic_residual.size
        ):
            return getattr(self, name)
        if name == "energy":
            raise KeyError(
                f"'energy': this system conserves Jacobi's integral h = T₂ − T₀ − U, not E = T − U "
                f"(its kinetic energy has velocity-linear or velocity-free parts): the column is "
                f"{self.energy_column!r}"
            )
        raise KeyError(f"{name!r}: the columns are {', '.join(self.columns)}")

    @property
    def columns(self) -> list[str]:
        """Column names in export order."""
        return [
            "t",
            *self.coordinates,
            *self.velocities,
            self.energy_column,
            "constraint_residual",
            *(["holonomic_residual"] if self.holonomic_residual.size else []),
            *self.multipliers,
        ]

    def table(self) -> np.ndarray:
        """All columns as one array (samples × columns)."""
        return np.column_stack([self[c] for c in self.columns])

    def energy_drift(self) -> float:
        """``max |E − E(0)| / max(1, |E(0)|)``."""
        if len(self.energy) == 0:
            return float("nan")
        e0 = self.energy[0]
        return float(np.max(np.abs(self.energy - e0)) / max(1.0, abs(e0)))

    def to_csv(self, path: str | os.PathLike[str]) -> Path:
        """Write the columns to a CSV file, atomically.

        Every number is written as the shortest text that reads back as the same float
        (``0.3``, not ``0.29999999999999999``): Python's ``repr``.
        """
        header = ",".join(self.columns)

        def write(fh: Any) -> None:
            fh.write(header + "\n")
            for row in self.table().tolist():
                fh.write(",".join(map(repr, row)) + "\n")

        return _atomic_write(path, write, text=True)

    def to_npz(self, path: str | os.PathLike[str]) -> Path:
        """Write the columns to a NumPy ``.npz`` archive (one array per column), atomically."""

        def write(fh: Any) -> None:
            arrays: dict[str, Any] = {c: self[c] for c in self.columns}
            np.savez(fh, **arrays)

        return _atomic_write(path, write, text=False)

    def __repr__(self) -> str:
        return (
            f"<Trajectory {self.model}/{self.form} [{self.backend}] {self.status}: "
            f"{len(self.t)} samples to t = {self.t[-1] if len(self.t) else float('nan'):g}>"
        )

    def _repr_html_(self) -> str:
        from matplotlib.figure import Figure

        from chaplygin import _html

        span = f"{self.t[0]:g} … {self.t[-1]:g}" if len(self.t) else "none"
        residual = float(np.max(self.constraint_residual, initial=0.0))
        rows = [
            ("model", f"{self.model}/{self.form}"),
            ("backend", self.backend),
            ("status", f"{self.status} {self.message}".strip()),
            ("t", span),
            ("samples", str(len(self.t))),
            (f"max {self.energy_label}", f"{self.energy_drift():.3g}"),
            ("max constraint residual", f"{residual:.3g}"),
            *(
                [("max holonomic residual", f"{float(np.max(self.holonomic_residual)):.3g}")]
                if self.holonomic_residual.size
                else []
            ),
            *(("note", note) for note in self.notes),
        ]
        text = _html.fields((label, _html.escape(value)) for label, value in rows)
        if len(self.t):
            ax = self.plot("coordinates", ax=Figure(figsize=(5, 3), layout="constrained").add_subplot())
            text += _html.png(ax.figure, alt=f"{self.model}/{self.form}: coordinates")
        return text

    def to_pandas(self) -> Any:
        """The samples as a ``pandas.DataFrame`` indexed by ``t``.

        One column per entry of :attr:`columns` after ``t`` (the names of :meth:`table` and
        :meth:`to_csv`); ``attrs`` holds ``model``, ``form``, ``backend``, ``status``,
        ``message``, ``failure``, ``rhs_evaluations`` and ``parameters`` (a dict).  Needs
        pandas (``pip install 'chaplygin[data]'``).
        """
        from chaplygin.numeric._dataout import trajectory_frame

        return trajectory_frame(self)

    def to_xarray(self) -> Any:
        """The samples as an ``xarray.Dataset`` with coordinate ``t``.

        One variable per entry of :attr:`columns` after ``t``, each with an attribute ``kind``
        (``coordinate``, ``velocity``, ``invariant``, ``multiplier``); the attributes are those
        of :meth:`to_pandas` with each parameter as a number ``param.NAME`` (attributes a
        netCDF file can hold).  Needs xarray (``pip install 'chaplygin[data]'``).
        """
        from chaplygin.numeric._dataout import trajectory_dataset

        return trajectory_dataset(self)

    def plot(
        self, what: str = "coordinates", ax: Any = None, *, path: tuple[str, str] | None = None, **kwargs: Any
    ) -> Any:
        """Draw the run with matplotlib and return the ``Axes``.

        Parameters
        ----------
        what : {"coordinates", "velocities", "invariants", "path"}
            Every coordinate, or every velocity, against ``t``; the relative energy drift
            ``|E − E(0)| / max(1, |E(0)|)`` and the constraint residual against ``t`` (log
            scale); or the path in a plane.  The path is that of the coordinates named ``x``
            and ``y`` — the contact point or the centre in every built-in example that moves
            in a plane — drawn with equal scales and its start marked; a trajectory without
            both draws the pair given as ``path``, and without it is refused.
        ax : matplotlib Axes, optional
            Where to draw; by default on a new pyplot figure.
        path : (str, str), optional
            The two coordinates of ``what="path"`` (horizontal, vertical).
        **kwargs
            Passed to ``Axes.plot`` for every curve (``lw=1``, ``alpha=0.5`` …).
        """
        from chaplygin.numeric._dataout import plot_trajectory

        return plot_trajectory(self, what, ax, path, **kwargs)


def _atomic_write(path: str | os.PathLike[str], write: Any, *, text: bool) -> Path:
    """Write through a temporary file in the same folder, then rename over ``path``.

    An error creating the folder or the temporary file names ``path`` (not the hidden temporary file).
    """
    target = Path(path)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp")
    except OSError as exc:
        raise type(exc)(exc.errno, exc.strerror or str(exc), str(target)) from None
    try:
        with os.fdopen(fd, "w", encoding="utf-8") if text else os.fdopen(fd, "wb") as fh:
            write(fh)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; a normal file follows the umask
        os.replace(tmp, target)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return target


def check_writable(target: str | os.PathLike[str], *, folder: bool = False) -> None:
    """Raise :class:`ChaplyginError`, naming ``target``, unless it can be written: a file (or,
    with ``folder``, a folder) there, and any missing folder above it, can be created.

    Run before the work whose result goes there, so that an unwritable output is found at once.
    A temporary file is created and deleted in the nearest folder that exists (the one that
    must accept it): the permission bits do not tell (root, read-only mounts, ACLs).
    """
    path = Path(target).absolute()
    if folder and path.is_dir():
        existing = path
    else:
        existing = next(p for p in path.parents if os.path.lexists(p))
    if not existing.is_dir():
        raise ChaplyginError(f"{target}: cannot be written there: {existing} is a file, not a folder.")
    try:
        fd, probe = tempfile.mkstemp(dir=existing, prefix=".chaplygin-probe-", suffix=".tmp")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise ChaplyginError(
            f"{target}: cannot be written there: the folder {existing} does not accept new files "
            f"({exc.strerror or exc})."
        ) from None


# ------------------------------------------------------------------ inputs
def _lookup(system: System, key: Any) -> tuple[str, int]:
    """``("q", i)`` for a coordinate, ``("v", i)`` for a velocity, given as symbol or name."""
    import sympy as sp

    from chaplygin.core._symbols import TIME

    names = [q.func.__name__ for q in system.coordinates]
    if isinstance(key, str):
        name = key.strip()
        if name.endswith("'") and name[:-1] in names:
            return "v", names.index(name[:-1])
        if name in names:
            return "q", names.index(name)
    elif isinstance(key, sp.Derivative) and key.expr in system.coordinates and key.variables == (TIME,):
        return "v", system.coordinates.index(key.expr)
    elif key in system.coordinates:
        return "q", system.coordinates.index(key)
    from chaplygin.core._symbols import describe

    raise ChaplyginError(
        f"initial: {describe(key)} is neither a coordinate nor a velocity of {system.name}; use "
        f"{', '.join(names)} or their velocities ({names[0]}' …)."
    )


def initial_state(
    system: System,
    initial: Mapping[Any, float],
    params: Mapping[str, float],
    t0: float,
    notes: list[str] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Full coordinates and velocities at ``t0`` from the user's initial data.

    Every coordinate and every independent velocity is needed, as finite
    numbers; dependent velocities follow from the constraints (a given one must
    agree with them).  A configuration where the constraints cannot be solved
    for the dependent velocities (a pole of ``q̇_dep = B q̇_σ + B_0``) is refused.
    The dependent coordinates of holonomic constraints are solved from ``f(q, t0) = 0``
    (:func:`solve_holonomic`); each value changed is told in ``notes``.
    """
    n = system.n
    q = np.full(n, np.nan)
    qd = np.full(n, np.nan)
    for key, value in initial.items():
        kind, i = _lookup(system, key)
        name = system.coordinates[i].func.__name__ + ("'" if kind == "v" else "")
        (q if kind == "q" else qd)[i] = _finite(value, f"initial: {name}", "a finite number")
    names = [c.func.__name__ for c in system.coordinates]
    missing = [names[i] for i in range(n) if np.isnan(q[i])]
    missing += [names[i] + "'" for i in system._ind if np.isnan(qd[i])]
    if missing:
        raise ChaplyginError(
            f"initial: missing {', '.join(missing)}; give every coordinate and the independent "
            f"velocities ({', '.join(names[i] + chr(39) for i in system._ind)})."
        )
    changed = solve_holonomic(system, q, params, t0)
    if notes is not None:
        notes += changed
    if not system.g:
        return q, qd
    # A_dep q̇_dep = −(A_ind q̇_σ + A_0), solved numerically (no symbolic B needed)
    ind, dep = list(system._ind), list(system._dep)
    dep_names = ", ".join(names[i] + "'" for i in dep)
    at = ", ".join(f"{names[i]} = {q[i]:.6g}" for i in range(n))
    given = qd.copy()
    # nonlinear constraints: the solved form (the branch chosen); A q̇ + A_0 = f, so the solve
    # below is a Newton step from it
    if system.is_nonlinear:
        qd[dep] = _nonlinear_velocities(system, q, qd, params, t0, at)
    a = _numeric(system, "[A | A_0]", lambda: system._A.row_join(system._A0), q, qd, params, t0)
    if np.isnan(a).any():  # not real, or 0/0: a denominator vanishes there
        raise _not_finite(system, params, t0)
    solvable = _solvable(a[:, :-1], dep)
    if not solvable and system.is_nonlinear:
        speeds = ", ".join(f"{names[i]}' = {qd[i]:.6g}" for i in ind)
        raise InputError(
            f"initial: the start ({at}, {speeds}) lies on the singular set of the constraints, "
            f"{singular_set_text(system)}; start away from it."
        )
    if not solvable:
        raise InputError(
            f"initial: the constraints cannot be solved for the dependent velocities ({dep_names}) "
            f"at {at}: this configuration is a pole of the solved constraints (their block of A "
            "is singular there). Start away from it, or choose other dependent coordinates."
        )
    implied_all = np.linalg.solve(a[:, dep], -(a[:, ind] @ qd[ind] + a[:, -1]))
    for i, implied in zip(dep, implied_all):
        if not np.isfinite(implied):
            raise InputError(
                f"initial: the constraints give {names[i]}' = {implied} at {at}; start where "
                "they give finite velocities."
            )
        if not np.isnan(given[i]) and abs(given[i] - implied) > 1e-9 * max(1.0, abs(implied)):
            branch = (
                f" (the solution branch={system._branch} of the implicit constraints)"
                if system._branch is not None
                else ""
            )
            raise ChaplyginError(
                f"initial: {names[i]}' = {given[i]:g} violates the constraints{branch}, which give "
                f"{names[i]}' = {implied:.12g} (residual {given[i] - implied:.3g})."
            )
        qd[i] = implied
    return q, qd


def _nonlinear_velocities(
    system: System, q: np.ndarray, qd: np.ndarray, params: Mapping[str, float], t0: float, at: str
) -> np.ndarray:
    """The dependent velocities from the solved form ``q̇_dep = φ(q, q̇_σ, t)`` of constraints
    nonlinear in the velocities; refused where φ is not real (outside the constraints' domain)."""

    def phi() -> Any:
        import sympy as sp

        return sp.Matrix([system._velocity_substitution[system._vars.xd[i]] for i in system._dep])

    # (φ holds no dependent velocity: those still NaN in qd do not enter)
    values = _numeric(system, "φ", phi, q, qd, params, t0).ravel()
    if np.isnan(values).any():  # a root of a negative number, or a pole: no real dependent velocity here
        names = ", ".join(system.coordinates[i].func.__name__ + "'" for i in system._dep)
        shown = ", ".join(f"{system.coordinates[i].func.__name__}' = {qd[i]:.6g}" for i in system._ind)
        raise InputError(
            f"initial: the constraints give no real {names} at {at}, {shown} (the solved form "
            f"{list(system.constraints.values())} is not real or not finite there); start where "
            "the constraints can hold."
        )
    return values


#: |f| below which a holonomic constraint holds at the start (the given value is then kept)
HOLONOMIC_TOL = 1e-10


#: NumPy functions made from a system, by system and name (kept off the System: it stays picklable)
_FUNCTIONS: weakref.WeakKeyDictionary[Any, dict[str, Any]] = weakref.WeakKeyDictionary()


def _functions(system: System, name: str, make: Callable[[], Any]) -> Any:
    """``make()`` once per system and ``name``: the functions :func:`_holonomic_functions` and
    :func:`_left_branch` evaluate along every run."""
    made = _FUNCTIONS.setdefault(system, {})
    if name not in made:
        made[name] = make()
    return made[name]


def _holonomic_functions(system: System) -> Any:
    """``(f, ∂f/∂q_dep)`` of the holonomic constraints as NumPy functions of
    ``(t, q_1 … q_n, parameters)``, made once per system."""

    def make() -> Any:
        import sympy as sp

        from chaplygin.core._symbols import TIME

        v = system._vars
        fs = sp.Matrix([f for _, f in system._holonomic])
        jac = fs.jacobian([v.x[i] for i, _ in system._holonomic])
        args = [TIME, *v.x, *system.parameters]
        return sp.lambdify(args, fs, "numpy"), sp.lambdify(args, jac, "numpy")

    return _functions(system, "holonomic", make)


def solve_holonomic(system: System, q: np.ndarray, params: Mapping[str, float], t0: float) -> list[str]:
    """Solve the holonomic constraints ``f(q, t0) = 0`` for their dependent coordinates, in place.

    The given values are the first guess of a Newton search (SciPy's ``root``, with the
    Jacobian ``∂f/∂q_dep``); where they satisfy ``|f| ≤`` :data:`HOLONOMIC_TOL` already they
    are kept.  Returns a note per value changed (``z: 0.3 → 0.2955…``).  Raises
    :class:`InputError` where no solution is found, or ``∂f/∂q_dep`` is singular there.
    """
    if not system._holonomic:
        return []
    dep = [i for i, _ in system._holonomic]
    names = [c.func.__name__ for c in system.coordinates]
    f, jac = _holonomic_functions(system)
    p = [params[s.name] for s in system.parameters]

    def at(values: np.ndarray, fun: Any) -> np.ndarray:
        x = q.copy()
        x[dep] = values
        with np.errstate(all="ignore"):
            return np.asarray(fun(t0, *x, *p), dtype=float)

    what = ", ".join(f"{names[i]}: {system.to_user(e)} = 0" for i, e in system._holonomic)
    guess = q[dep].copy()
    if np.all(np.abs(at(guess, f)) <= HOLONOMIC_TOL):
        solved = guess
    else:
        from scipy.optimize import root

        res = root(lambda u: at(u, f).ravel(), guess, jac=lambda u: at(u, jac), method="hybr")
        solved = np.asarray(res.x, dtype=float)
        if not np.all(np.isfinite(solved)) or not np.all(np.abs(at(solved, f)) <= HOLONOMIC_TOL):
            given = ", ".join(f"{names[i]} = {q[i]:.6g}" for i in dep)
            raise InputError(
                f"initial: the holonomic constraints ({what}) have no solution for "
                f"{', '.join(names[i] for i in dep)} near the given {given} (Newton's method "
                f"stopped at |f| = {np.max(np.abs(at(solved, f))):.3g}); give values closer to a solution."
            )
    jacobian = at(solved, jac)
    if not _solvable(jacobian, range(len(dep))):
        at_ = ", ".join(f"{names[i]} = {v:.6g}" for i, v in zip(dep, solved))
        raise InputError(
            f"initial: the holonomic constraints ({what}) do not fix "
            f"{', '.join(names[i] for i in dep)} at {at_}: ∂f/∂q_dep is singular there. Start "
            "away from this configuration, or key the relations by other coordinates."
        )
    notes = [
        f"{names[i]} solved from the holonomic constraint at the start: {q[i]:.12g} → {v:.12g}"
        for i, v in zip(dep, solved)
        if v != q[i]
    ]
    q[dep] = solved
    return notes


def holonomic_residual(
    system: System, t: np.ndarray, coordinates: Sequence[np.ndarray], params: Mapping[str, Any]
) -> np.ndarray:
    """``max_k |f_k(q, t)|`` at each time of ``t`` (the samples of a run, or one final time per
    ensemble member), ``coordinates`` the columns of ``q_1 … q_n`` and ``params`` numbers or
    columns by name; empty for a system without relations."""
    if not system._holonomic or not len(t):
        return np.zeros(0)
    f, _ = _holonomic_functions(system)
    with np.errstate(all="ignore"):
        out = f(t, *coordinates, *(params[s.name] for s in system.parameters))  # a row per relation
    values = np.array([np.broadcast_to(np.asarray(r, dtype=float).ravel(), np.shape(t)) for r in out])
    return np.max(np.abs(values), axis=0)


def _finite(value: Any, what: str, accepted: str) -> float:
    """``value`` as a float, or an :class:`InputError` naming ``what`` and what is ``accepted``."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        from chaplygin.core._symbols import describe

        raise InputError(f"{what} = {describe(value)} is not a number; give {accepted}.") from None
    if not math.isfinite(number):
        raise InputError(f"{what} = {number} is not finite; give {accepted}.")
    return number


def time_span(t_span: Any) -> tuple[float, float]:
    """``(t0, t1)`` from ``t_span`` (a number: the end, from 0), both finite, or an :class:`InputError`."""
    t0, t1 = (0.0, t_span) if np.isscalar(t_span) else t_span
    return (
        _finite(t0, "t_span: the start time", "a finite number"),
        _finite(t1, "t_span: the end time", "a finite number after the start"),
    )


def check_time_limit(time_limit: Any) -> float | None:
    """``time_limit`` in seconds (None: no limit), or an :class:`InputError` saying what is accepted."""
    if time_limit is None:
        return None
    try:
        seconds = math.nan if isinstance(time_limit, (bool, str)) else float(time_limit)
    except (TypeError, ValueError):
        seconds = math.nan
    if not seconds > 0:  # NaN fails too
        raise InputError(
            f"time_limit = {time_limit!r}: give a positive number of seconds, or None for no limit."
        )
    return seconds


def _solvable(a: np.ndarray, dep: Sequence[int], floor: float = 1e-10) -> bool:
    """Whether ``A`` (numbers, g × n) can be solved for the velocities ``dep``: its rows scaled
    to largest entry 1, the dependent block must be finite and of full rank (smallest singular
    value above ``floor``)."""
    if not np.all(np.isfinite(a)):
        return False
    scale = np.max(np.abs(a), axis=1, keepdims=True)
    if np.any(scale == 0):
        return False
    block = a[:, list(dep)] / scale
    return bool(np.linalg.svd(block, compute_uv=False)[-1] > floor)


def _parameters(system: System, parameters: Mapping[Any, float] | None) -> dict[str, float]:
    out: dict[str, float] = {}
    for key, value in (parameters or {}).items():
        name = system.parameter(key).name
        out[name] = _finite(value, f"parameters: {name}", "a finite number")
    missing = [p.name for p in system.parameters if p.name not in out]
    if missing:
        raise ChaplyginError(
            f"parameters: no value for {', '.join(missing)}; every parameter of {system.name} "
            f"({', '.join(p.name for p in system.parameters)}) needs a number."
        )
    return out


def _check_options(t0: float, t1: float, samples: Any, rtol: Any, atol: Any, max_step: Any) -> None:
    """Refuse a time span, sample count, tolerance or step bound no run can honour."""
    _finite(t0, "t_span: the start time", "a finite number")
    _finite(t1, "t_span: the end time", f"a finite number after the start ({t0:g})")
    if not t1 > t0:
        raise InputError(f"t_span: the end time {t1:g} must be after the start {t0:g}.")
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)):
        raise InputError(f"samples = {samples!r}: give a whole number from 2 to {MAX_SAMPLES}.")
    if not 2 <= samples <= MAX_SAMPLES:
        raise InputError(
            f"samples = {samples}: give from 2 (the start and the end) to {MAX_SAMPLES} samples "
            f"(each sample is a row of every column in memory; for finer output, simulate shorter spans)."
        )
    _finite(rtol, "rtol", "a positive finite tolerance, e.g. 1e-10")
    if not float(rtol) > 0:
        raise InputError(f"rtol = {rtol}: give a positive finite tolerance, e.g. 1e-10.")
    a = (
        np.asarray(atol, dtype=float)
        if np.ndim(atol)
        else np.asarray(_finite(atol, "atol", "a positive finite tolerance, e.g. 1e-12"))
    )
    if not (np.all(np.isfinite(a)) and np.all(a > 0)):
        raise InputError(f"atol = {atol}: give positive finite tolerances, e.g. 1e-12.")
    if not (float(max_step) > 0):  # NaN fails too
        raise InputError(f"max_step = {max_step}: give a positive bound on the step (inf: none).")


def _check_mass(
    system: System, q: np.ndarray, qd: np.ndarray, params: Mapping[str, float], t0: float
) -> None:
    """Refuse a start where the reduced mass matrix ``Cᵀ M C`` is not positive definite or is
    ill-conditioned (condition number above :data:`MAX_CONDITION`), naming the velocity along
    which the kinetic energy fails and the parameters of T that are not positive."""
    m = _numeric(system, "mass", lambda: _mass_matrix(system), q, qd, params, t0)
    c: np.ndarray | None = np.eye(system.n)[:, list(system._ind)]
    if system.g:
        a = _numeric(system, "constraints", system._constraint_matrix, q, qd, params, t0)
        c = system._numeric_C(a)
    ind = [system.coordinates[i].func.__name__ + "'" for i in system._ind]
    if c is None or not np.all(np.isfinite(m)):
        raise InputError("initial: the mass matrix is not finite at the initial state; start elsewhere.")
    reduced = c.T @ m @ c
    w, v = np.linalg.eigh((reduced + reduced.T) / 2)
    biggest = float(np.max(np.abs(w), initial=0.0))
    along = ind[int(np.argmax(np.abs(v[:, 0])))] if len(w) else ""
    if biggest == 0 or w[0] < -1e-12 * biggest:
        hint = _mass_hint(system, params)
        raise InputError(
            f"the kinetic energy is not positive definite at the initial state: it is "
            f"{'zero' if biggest == 0 else 'negative'} along {along} (eigenvalue {w[0]:.3g} of the "
            f"reduced mass matrix in {', '.join(ind)}); a motion needs T > 0 for every non-zero "
            f"admissible velocity.{hint}"
        )
    if w[0] <= biggest / MAX_CONDITION:
        hint = _mass_hint(system, params)
        raise InputError(
            f"the reduced mass matrix (in {', '.join(ind)}) is singular or nearly so at the initial "
            f"state: its condition number {biggest / w[0] if w[0] > 0 else math.inf:.3g} exceeds "
            f"{MAX_CONDITION:g}, so the accelerations are not determined along {along}.{hint}"
        )


def _mass_matrix(system: System) -> Any:
    """The mass matrix ``∂²T/∂q̇²``: SymPy's, or SymEngine's where the system was derived natively."""
    if system._native is None:
        return system._M
    from symengine import DenseMatrix

    return DenseMatrix(system._native.H)


def _mass_hint(system: System, params: Mapping[str, float]) -> str:
    """The end of :func:`_check_mass`'s messages: the parameters of T that are not positive."""
    symbols = {str(x) for x in system.kinetic_energy.free_symbols}
    bad = [f"{k} = {val:g}" for k, val in params.items() if k in symbols and val <= 0]
    if bad:
        return f" Check the parameters of T that are not positive: {', '.join(bad)}."
    return " Check the parameters and the kinetic energy."


def _check_vakonomic_start(
    system: System,
    model: str,
    mu: np.ndarray,
    q: np.ndarray,
    qd: np.ndarray,
    params: Mapping[str, float],
    t0: float,
) -> None:
    """Refuse a vakonomic start where ``L_v = T + U + Σ μ_β f_β`` is degenerate: for constraints
    nonlinear in the velocities its Hessian in them, ``H + Σ μ_β ∂²f_β/∂q̇²``, depends on μ, and
    where it is singular on the constraints (``Cᵀ(…)C``) the accelerations are not determined;
    e.g. ``ẋ² + ẏ² = v²`` with ``c = 0`` (the default, Lindelöf's choice) gives μ = −m/2 and
    ``H + 2μ I = 0``."""
    import sympy as sp

    xd = list(system._vars.xd)
    mass = _numeric(system, "M", lambda: system._M, q, qd, params, t0)
    a = _numeric(system, "A", lambda: system._A, q, qd, params, t0)
    c = system._numeric_C(a)
    if c is None:  # (the initial state refuses this already)
        return
    hessians = [
        _numeric(system, f"hessian {b}", partial(sp.hessian, f, xd), q, qd, params, t0)
        for b, f in enumerate(system._f)
    ]
    hv = mass + sum((m * h for m, h in zip(mu, hessians)), np.zeros_like(mass))
    reduced, plain = c.T @ hv @ c, c.T @ mass @ c
    w = np.linalg.eigvalsh((reduced + reduced.T) / 2)
    scale = float(np.max(np.abs(np.linalg.eigvalsh((plain + plain.T) / 2)), initial=0.0))
    if len(w) and np.all(np.isfinite(w)) and np.min(np.abs(w)) > scale / MAX_CONDITION:
        return
    shown = ", ".join(f"{x:.6g}" for x in mu)
    raise Degenerate(
        f"the vakonomic Lagrangian T + U + Σ μ_β f_β is degenerate at the initial state with "
        f"μ(0) = [{shown}]: its Hessian in the velocities on the constraints, "
        f"Cᵀ(∂²T/∂q̇² + Σ μ_β ∂²f_β/∂q̇²)C, is singular there (eigenvalue "
        f"{float(np.min(np.abs(w))) if len(w) else 0.0:.3g}; for constraints nonlinear in the "
        "velocities it depends on μ), so the vakonomic equations do not determine the accelerations. "
        + (
            "Lindelöf's equations are the vakonomic family at c = 0; model 'vakonomic_family' takes "
            "other constants (constants='match' gives μ(0) = 0)."
            if model == "lindelof"
            else "The constants c_β (the momenta of the dependent coordinates, default 0) fix μ(0): give "
            "other constants (constants='match' gives μ(0) = 0)"
            + (" or multipliers=[μ(0), ...]." if registry.get(model).multipliers_in_state else ".")
        )
    )


def _numeric(
    system: System,
    name: str,
    make: Callable[[], Any],
    q: np.ndarray,
    qd: np.ndarray,
    params: Mapping[str, float],
    t0: float,
) -> np.ndarray:
    """The SymPy or SymEngine matrix ``make()`` (internal symbols) at ``(t0, q, q̇)`` and the
    parameters; values that are not real are NaN.

    Its function of ``(t, q, q̇, parameters)`` (SymEngine's ``Lambdify``) is made once per system
    and ``name`` (:func:`_functions`), so a call costs microseconds, not a SymPy substitution.
    """
    fast, matrix = _functions(system, "at " + name, lambda: _start_function(system, make()))
    if fast is not None:
        numbers = [t0, *q, *qd, *(params[s.name] for s in system.parameters)]
        with np.errstate(all="ignore"):
            out = np.asarray(fast(numbers), dtype=complex).reshape(matrix.rows, matrix.cols)
        # (complex arithmetic leaves round-off in the imaginary parts of real values)
        return np.where(np.abs(out.imag) <= 1e-12 * np.maximum(1.0, np.abs(out.real)), out.real, np.nan)
    import sympy as sp

    from chaplygin.core._fast import to_sympy
    from chaplygin.core._symbols import TIME

    v = system._vars
    values = {TIME: t0, **dict(zip(v.x, q)), **dict(zip(v.xd, qd))}
    args = sorted({to_sympy(x) for x in matrix.free_symbols}, key=str)
    # SymEngine's symbols come back without assumptions: a parameter is known by its name
    numbers = [values[x] if x in values else params[x.name] for x in args]
    plain = sp.Matrix(matrix.tolist()).xreplace({x: sp.Float(val) for x, val in zip(args, numbers)})
    try:
        return np.array(plain.evalf().tolist(), dtype=float)
    except TypeError:  # zoo or nan: a singular point
        return np.full((matrix.rows, matrix.cols), np.nan)


def _start_function(system: System, matrix: Any) -> tuple[Any, Any]:
    """``(function, matrix)`` for :func:`_numeric`: SymEngine's ``Lambdify`` of ``matrix`` over
    ``(t, q_1 … q_n, q̇_1 … q̇_n, parameters)`` (complex values), or None where SymEngine cannot
    represent it (then SymPy substitutes at each call).

    The coordinates and velocities (SymPy ``Dummy`` symbols, numbered anew for each system) are
    renamed by position first: SymEngine orders the terms of a sum by their hashes, which for a
    ``Dummy`` depend on its number, so two equal systems would add the same terms in different
    orders and differ in the last digits.
    """
    import sympy as sp

    from chaplygin.core._fast import evaluator, to_sympy
    from chaplygin.core._symbols import TIME

    v = system._vars
    plain = {x: sp.Symbol(f"_chaplygin_state_{k}") for k, x in enumerate([*v.x, *v.xd])}
    exprs = [to_sympy(e).xreplace(plain) for e in matrix]
    return evaluator([TIME, *plain.values(), *system.parameters], exprs), matrix


def _vakonomic_setup(
    system: System, entry: Model, constants: Any, multipliers: Any
) -> tuple[Any, dict[str, Any] | None]:
    """Constants of the family, or the initial multipliers of the multiplier form, checked: each
    a finite number, one per constraint (a sequence, a mapping, or a number where g = 1), or
    ``constants="match"`` (:data:`MATCH`) or ``"zero"`` (every c_β = 0, as ``None``); anything
    else is refused with an :class:`InputError`.  ``entry``: the model (``registry.get``)."""
    model = entry.name
    if not (entry.constants or entry.multipliers_in_state):
        if constants is not None or multipliers is not None:
            raise ChaplyginError(f"constants/multipliers are for the vakonomic models, not for {model!r}.")
        return None, None
    if multipliers is not None and not entry.multipliers_in_state:
        raise InputError(
            f"multipliers: the reduced model {model!r} takes the constants c_β (constants=...), not "
            "μ(0); μ(0) is for model 'vakonomic', which integrates μ."
        )
    if multipliers is not None and constants is not None:
        raise InputError(
            "constants and multipliers: give one of them: μ(0) itself (multipliers=...), or the "
            "constants c_β it follows from (constants=..., or 'match' for μ(0) = 0)."
        )
    if multipliers is not None:
        if isinstance(multipliers, str):
            raise InputError(
                f"multipliers={multipliers!r}: multipliers takes μ(0) itself, one finite number per "
                f"constraint ({system.g}) as a sequence or a mapping by name (mu_1 …); for μ(0) = 0 "
                "(the vakonomic momenta starting equal to the true ones) give constants='match'."
            )
        return None, {"mu": _vakonomic_numbers(system, multipliers, "multipliers", "μ(0)")}
    if isinstance(constants, str) and constants == "match":
        c: Any = "match"
    elif constants is None or (isinstance(constants, str) and constants == "zero"):
        c = [0.0] * system.g
    else:
        c = _constant_values(system, _vakonomic_numbers(system, constants, "constants", "c_β"))
    return (c, None) if entry.constants else (None, {"constants": c})


def _vakonomic_numbers(system: System, value: Any, what: str, symbol: str) -> list[float] | dict[Any, float]:
    """``value`` as g finite floats (a sequence, or a number where g = 1) or a mapping of keys
    to finite floats (its keys are checked where the names are known)."""
    import sympy as sp

    g = system.g
    accepted = f"one finite number per constraint ({g}) as a sequence or a mapping by name" + (
        f" ({_constant_example(system)}), 'match' (μ(0) = 0) or 'zero' (every c_β = 0)"
        if what == "constants"
        else ""
    )
    if isinstance(value, Mapping):
        return {key: _finite(x, f"{what}: {key}", "a finite number") for key, x in value.items()}
    if isinstance(value, (str, bytes)) or not (
        isinstance(value, (Sequence, np.ndarray, int, float, np.number, sp.Basic))
    ):
        from chaplygin.core._symbols import describe

        raise InputError(f"{what} = {describe(value)}: give {symbol} as {accepted}.")
    values = list(np.ravel(np.asarray(value, dtype=object))) if np.ndim(value) else [value]
    if len(values) != g or (not np.ndim(value) and g != 1):
        raise InputError(
            f"{what}: {len(values)} value(s) given for {g} constraint(s); give {symbol} as {accepted}."
        )
    return [_finite(x, f"{what}[{k}]", "a finite number") for k, x in enumerate(values)]


def _constant_example(system: System) -> str:
    """``{'c_1': …, 'c_2': …}``: the Python form of the constants of ``system`` by name."""
    from chaplygin.models.vakonomic import constant_symbols

    return "{" + ", ".join(f"{c.name!r}: …" for c in constant_symbols(system)) + "}"


def _constant_values(system: System, given: list[float] | dict[Any, float]) -> list[float]:
    """The constants c_β in order, from :func:`_vakonomic_numbers` (a mapping by name or 1 … g)."""
    if isinstance(given, list):
        return given
    from chaplygin.models.vakonomic import constant_symbols

    names = [c.name for c in constant_symbols(system)]
    out: list[float | None] = [None] * system.g
    for key, value in given.items():
        k = key - 1 if isinstance(key, int) else names.index(str(key)) if str(key) in names else -1
        if not 0 <= k < system.g:
            raise InputError(
                f"constants: unknown key {key!r}; the keys are {', '.join(map(repr, names))} "
                f"(or 1 … {system.g}), e.g. constants={_constant_example(system)}; or give "
                "constants='match' or 'zero'."
            )
        out[k] = value
    missing = [name for name, value in zip(names, out) if value is None]
    if missing:
        raise InputError(
            f"constants: no value for {', '.join(missing)}; give every c_β a number, e.g. "
            f"constants={_constant_example(system)}."
        )
    return [float(x) for x in out if x is not None]


# ------------------------------------------------------------------ integration
class _Attempt(NamedTuple):
    """One integration from ``(t_start, y_start)``: the samples it reached and how it ended."""

    t: np.ndarray
    y: np.ndarray
    message: str  # "" on success
    retry: bool  # a right-hand side failed inside a step: smaller steps may get closer
    t_last: float  # the last accepted step
    y_last: np.ndarray | None
    t_fail: float
    n_rhs: int


#: a failure inside a step is pinned down to this fraction of max(1, |t|) before the run stops
PIN = 1e-9
#: the least wall time in seconds between two calls of a ``progress`` callback (see :func:`simulate`)
PROGRESS_EVERY = 0.1

#: ``progress(t)``: told the time an integration has reached (see :func:`simulate`)
Progress = Callable[[float], None]

#: the default ``time_limit`` of :func:`simulate` and of sweeps, in seconds: a run (or a sweep)
#: estimated to take longer is refused (``time_limit=None``, ``--time-limit 0``: no limit)
TIME_LIMIT = 3600.0
#: seconds of integration after which a run's whole duration is estimated from its pace
ESTIMATE_AFTER = 0.5


def duration(seconds: float) -> str:
    """``0.25 s``, ``42 s``, ``3 min 05 s``, ``2 h 07 min``, ``12 days``, ``more than a year``: a
    time, never a number too long to read (nor a limit of 0.01 s read as ``0 s``)."""
    if not seconds < 365 * 86400:  # (NaN too)
        return "more than a year"
    if seconds < 0.95:
        return f"{seconds:.2g} s"
    s = round(seconds)
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    if s < 48 * 3600:
        return f"{s // 3600} h {s % 3600 // 60:02d} min"
    return f"{s // 86400} days"


class Degenerate(InputError):
    """A vakonomic start where ``T + U + Σ μ_β f_β`` is degenerate (:func:`_check_vakonomic_start`)."""


class TooSlow(InputError):
    """A run refused by :func:`pace_check`: at its pace it would take longer than its time limit."""


def pace_check(
    total: float, limit: float, refusal: Callable[[str, str], str], instead: str
) -> Callable[[float], None]:
    """A callback told the progress ``done`` of a run (a time reached, steps taken) towards
    ``total``: :data:`ESTIMATE_AFTER` seconds after its first call (counted from there, so that
    a compilation in the first stretch does not count), it estimates the time left from the pace
    so far; beyond ``limit`` seconds it estimates again four times as late (a run that crawls
    near a pole, where the integrator then stops it, is beyond only at first) and, beyond again,
    raises :class:`InputError` with the message
    ``refusal(estimate, pace)``, the limit, and the advice ``instead`` (``"ask for a shorter
    time"``) or how to lift the limit; ``pace`` says how far the run went in how long."""
    origin: list[float] = []  # (wall time, done) of the first call
    checks = [0]  # estimates made: a second, later one confirms a refusal

    def told(done: float) -> None:
        if checks[0] >= 2 or done >= total:
            return
        now = time.monotonic()
        if not origin:
            origin.extend((now, done))
            return
        elapsed = now - origin[0]
        if elapsed < ESTIMATE_AFTER * 4 ** checks[0]:
            return
        checks[0] += 1
        left = elapsed * (total - done) / (done - origin[1]) if done > origin[1] else math.inf
        if left <= limit:
            checks[0] = 2  # within the limit: no more estimates
        elif checks[0] == 2:  # beyond it twice (a run that crawls near a pole and then stops
            # there, as the integrator finds it, is beyond it only at first)
            pace = f"from {origin[1]:.4g} to {done:.4g} in {elapsed:.1f} s"
            raise TooSlow(
                f"{refusal(duration(left), pace)}, beyond the limit of {duration(limit)}; "
                f"{instead}, or {_NO_LIMIT} to run it anyway."
            )

    return told


#: how a refusal by :func:`pace_check` says that the limit can be lifted (the command line says
#: ``--time-limit 0``: :mod:`chaplygin.apps._wording`)
_NO_LIMIT = "pass time_limit=None"


def _budget(progress: Progress | None, t1: float, limit: float | None) -> Progress | None:
    """``progress`` that also, once, refuses a run whose pace says it needs more than ``limit``
    seconds to reach ``t1`` (:func:`pace_check`)."""
    if limit is None:
        return progress
    check = pace_check(
        t1,
        limit,
        lambda left, pace: (
            f"t_end = {t1:g}: too long to run: the time left is estimated at {left} (t {pace})"
        ),
        "ask for a shorter time",
    )

    def told(t: float) -> None:
        if progress is not None:
            progress(t)
        check(t)

    return told


def simulate(
    system: System | LoadedFile,
    model: str,
    t_span: tuple[float, float] | float,
    initial: Mapping[Any, float] | None = None,
    parameters: Mapping[Any, float] | None = None,
    *,
    form: str = "classic",
    rtol: float = 1e-10,
    atol: float = 1e-12,
    method: str = "DOP853",
    samples: int = 1001,
    backend: str = "auto",
    constants: Any = None,
    multipliers: Any = None,
    max_step: float = np.inf,
    step: float | None = None,
    reduction: str = "auto",
    progress: Progress | None = None,
    time_limit: float | None = TIME_LIMIT,
) -> Trajectory:
    """Simulate one model of ``system`` (the front door :func:`chaplygin.numeric.simulate`).

    ``progress``, if given, is called with the time the integration has reached: at most
    every :data:`PROGRESS_EVERY` seconds of wall time (the Python steppers after a step, the
    compiled loops of the ``c`` and ``numba`` backends between runs of steps that continue
    exactly where they stopped), and once at the end with the last time reached (``t_end``
    for a run that succeeds).

    ``time_limit`` (seconds, default :data:`TIME_LIMIT`, one hour; None: no limit): after
    :data:`ESTIMATE_AFTER` seconds of integration, the whole run is estimated from its pace so
    far, and one estimated to take longer is stopped with an :class:`InputError` that gives the
    estimate (the symmetric methods: from the steps taken of the steps of the grid; not the
    ``jax`` backend).

    Inputs that cannot give a motion are refused with an :class:`InputError`
    before anything is derived or compiled: a start or end time that is not
    finite, ``samples`` outside ``2 … MAX_SAMPLES``, tolerances that are not
    positive and finite, parameters or initial values that are not finite, a
    start on a pole of the solved constraints, and a reduced mass matrix that is
    not positive definite or whose condition number exceeds :data:`MAX_CONDITION`.

    ``system`` may be a loaded system file (:func:`chaplygin.load`): its ``[initial]`` and
    ``[parameters]`` are then the defaults that ``initial`` and ``parameters`` override, and a
    warm run (the same file's bytes, model and options run before) integrates the compiled
    model stored for it without building the system: no SymPy (:mod:`chaplygin.numeric._plan`).
    """
    from chaplygin.numeric._plan import LoadedFile, simulate_file

    if isinstance(system, LoadedFile):
        options = {
            "form": form,
            "rtol": rtol,
            "atol": atol,
            "method": method,
            "samples": samples,
            "backend": backend,
            "constants": constants,
            "multipliers": multipliers,
            "max_step": max_step,
            "step": step,
            "reduction": reduction,
            "progress": progress,
            "time_limit": time_limit,
        }
        return simulate_file(system, model, t_span, initial, parameters, options)
    if initial is None:
        raise ChaplyginError(
            "initial: no initial state; give every coordinate and the independent velocities by "
            "name, e.g. {'x': 0.0, \"x'\": 1.0} (a loaded system file takes its [initial])."
        )
    t0, t1 = time_span(t_span)
    _check_options(t0, t1, samples, rtol, atol, max_step)
    time_limit = check_time_limit(time_limit)
    if method not in METHODS:
        raise ChaplyginError(f"method {method!r} is not one of {', '.join(METHODS)}.")
    auto = backend == "auto"
    backend = choose_backend(backend, method)
    params = _parameters(system, parameters)
    notes: list[str] = []
    q, qd = initial_state(system, initial, params, t0, notes)
    _check_mass(system, q, qd, params, t0)
    if method in SYMMETRIC_METHODS:  # fixed-step symmetric methods: chaplygin.numeric.symmetric
        tr = _simulate_symmetric(
            system,
            model,
            (t0, t1),
            initial,
            parameters,
            method=method,
            step=step,
            form=form,
            samples=samples,
            backend=backend,
            constants=constants,
            multipliers=multipliers,
            time_limit=time_limit,
        )
        if progress is not None and len(tr.t):
            progress(float(tr.t[-1]))
        tr.notes = notes + _kinks(system, tr, params, method)
        return _watch(system, tr, params, reduced=True)
    if step is not None:
        raise ChaplyginError(
            f"step: a fixed step size is for the symmetric methods ({', '.join(SYMMETRIC_METHODS)}); "
            f"method {method!r} adapts its steps to rtol/atol (bounded by max_step)."
        )
    entry = registry.get(model)  # the model, looked up once: what follows takes the entry
    family_c, vak = _vakonomic_setup(system, entry, constants, multipliers)
    if isinstance(family_c, str) and family_c == "match":
        family_c = _matching_constants(system, q, qd, params, t0)
    y0 = list(q) + ([*qd] if not entry.reduced else [qd[i] for i in system._ind])
    if entry.multipliers_in_state:
        y0 += list(_initial_multipliers(system, vak or {}, q, qd, params, t0))
    if entry.motion == "vakonomic" and system.is_nonlinear:
        mu = (
            np.array(y0[len(y0) - system.g :])
            if entry.multipliers_in_state
            else _multipliers_from_constants(
                system, np.asarray(family_c if family_c is not None else [0.0] * system.g), q, qd, params, t0
            )
        )
        _check_vakonomic_start(system, model, mu, q, qd, params, t0)
    from chaplygin.numeric.codegen import (
        BackendUnavailable,
        compile_model,
        parameter_vector,
    )

    try:
        compiled = compile_model(system, entry, form, backend, constants=family_c, reduction=reduction)
    except BackendUnavailable as exc:
        if not auto:
            raise
        compiled = compile_model(system, entry, form, "numpy", constants=family_c, reduction=reduction)
        notes.append(f"integrated by the numpy backend: {exc}")  # (auto's choice could not be built)
    compiled = targets.get(compiled.backend).looped(compiled, method)  # (numba: see _lost_definiteness)
    layout = compiled.layout

    p = parameter_vector(layout, params)
    try:
        tr = integrate(
            compiled,
            (t0, t1),
            np.array(y0),
            p,
            params,
            rtol=rtol,
            atol=atol,
            method=method,
            samples=samples,
            max_step=max_step,
            g=system.g,
            progress=progress,
            time_limit=time_limit,
        )
    except TooSlow as exc:
        if not (system.is_nonlinear and entry.reduced):
            raise
        # (Appell's weight rising on branch z' = +k|v| stops at v = 0 and the reduced run crawls there)
        raise TooSlow(
            f"{exc} A reduced run with constraints nonlinear in the velocities that crawls has often "
            f"met the singular set of the constraints, {singular_set_text(system)}."
        ) from None
    pole = None
    if entry.reduced and system.g and not sign_fixed(system):
        pole = _pole_between_samples(
            system,
            compiled,
            tr,
            (t0, t1),
            samples,
            np.array(y0),
            p,
            params,
            rtol=rtol,
            atol=atol,
            method=method,
            max_step=max_step,
        )
    tr.notes = notes
    return _watch(system, tr, params, reduced=entry.reduced, compiled=compiled, p=p, pole=pole)


def _kinks(system: System, tr: Trajectory, params: Mapping[str, float], method: str) -> list[str]:
    """Notes where the argument of an ``abs`` or ``sign`` of the system (in T, U, the forces or
    the constraints) changes sign between two samples: the equations have a kink or a jump there,
    past which a fixed-step ``method`` is not to be trusted: its error there did not fall with its
    step in the outside review (4.5e-5 at h = 1e-3 and at 2e-4), where DOP853's steps shorten."""
    import sympy as sp

    from chaplygin.core._symbols import TIME, describe
    from chaplygin.numeric.codegen import kink_arguments

    args = kink_arguments(system)
    if not args or len(tr.t) < 2:
        return []
    v, names = system._vars, [c.func.__name__ for c in system.coordinates]
    evaluate = _functions(
        system, "kinks", lambda: sp.lambdify([TIME, *v.x, *v.xd, *system.parameters], args, "numpy")
    )
    with np.errstate(all="ignore"):
        values = evaluate(
            tr.t,
            *(tr.coordinates[c] for c in names),
            *(tr.velocities[c + "'"] for c in names),
            *(params[par.name] for par in system.parameters),
        )
    notes = []
    for arg, value in zip(args, values):
        sign = np.sign(np.broadcast_to(np.asarray(value, dtype=float), tr.t.shape))
        k = np.flatnonzero(sign[1:] * sign[:-1] < 0)
        if k.size:
            notes.append(
                f"{describe(system.to_user(arg))} changes sign between t = {tr.t[k[0]]:.6g} and "
                f"{tr.t[k[0] + 1]:.6g}{f' ({k.size} times)' if k.size > 1 else ''}: the equations have "
                f"a kink or a jump there (abs, sign), and past it this fixed-step {method} run is not to "
                "be trusted (a smaller step does not cure it): run DOP853, which shortens its steps "
                "there, or split the run at the crossing"
            )
    return notes


def _simulate_symmetric(
    system: System,
    model: str,
    t_span: tuple[float, float],
    initial: Mapping[Any, float],
    parameters: Mapping[Any, float] | None,
    *,
    method: str,
    step: float | None,
    form: str = "classic",
    samples: int = 1001,
    backend: str = "numpy",
    constants: Any = None,
    multipliers: Any = None,
    time_limit: float | None = None,
) -> Trajectory:
    """:func:`chaplygin.numeric.simulate.simulate` with a symmetric fixed-step method.

    ``model`` is ``"chetaev"`` (integrated through Voronets' equations, then
    observed with the multipliers λ), ``"chaplygin"`` or ``"voronets"``.
    """
    from chaplygin.numeric.codegen import (
        compile_equations,
        compile_model,
        parameter_vector,
    )
    from chaplygin.numeric.symmetric import (
        TRUE_MODELS,
        _tolerant,
        grid,
        integrate_symmetric,
    )

    if model not in TRUE_MODELS:
        raise ChaplyginError(
            f"method {method!r} integrates the true (Chetaev) motion: model "
            f"{', '.join(map(repr, TRUE_MODELS))}, not {model!r}; use DOP853 for the other models."
        )
    entry = registry.get(model)  # the model, looked up once
    _vakonomic_setup(system, entry, constants, multipliers)  # refuses constants/multipliers
    if not targets.get(backend).symmetric:
        raise ChaplyginError(
            f"backend: the symmetric methods run with 'numba' (compiled) or 'numpy' (plain "
            f"Python), not {backend!r}."
        )
    t0, t1 = t_span
    h, _ = grid((t0, t1), samples, step)  # refuses a bad step before any work
    params = _parameters(system, parameters)
    q, qd = initial_state(system, initial, params, t0)
    with_multipliers = not entry.reduced
    reduced_model, reduced_form = ("voronets", "classic") if with_multipliers else (model, form)
    stepper = compile_model(system, reduced_model, reduced_form, backend)
    p = parameter_vector(stepper.layout, params)
    y0 = np.concatenate([q, qd[list(system._ind)]])
    res = integrate_symmetric(
        stepper, (t0, t1), y0, p, method=method, step=h, samples=samples, time_limit=time_limit
    )
    # observed with generated plain-Python code (nothing to compile): the reduced model's
    # own observables, or — for "chetaev" — the multiplier model's (λ among them) at (q, q̇)
    reduced = _tolerant(compile_model(system, reduced_model, reduced_form, "numpy"))
    observer, ys = reduced, res.y
    if with_multipliers:
        observer = _tolerant(compile_equations(system.equations(model), "numpy"))
        n = system.n
        velocities = [reduced.observe(t, y, p)[-n:] for t, y in zip(res.t, res.y)]
        ys = np.hstack([res.y[:, :n], np.reshape(velocities, (len(res.t), n))])
    p_obs = parameter_vector(observer.layout, params)
    tr = _trajectory(observer, res.t, ys, p_obs, params, res.status, res.message, res.n_rhs, system.g)
    tr.backend = backend
    return tr


# ------------------------------------------------------------------ checks along a run
#: at most this many points (:func:`_pole_between_samples`) check a run for poles between samples
POLE_CHECK_POINTS = 200_001


def _pole_between_samples(
    system: System,
    compiled: CompiledModel,
    tr: Trajectory,
    t_span: tuple[float, float],
    samples: int,
    y0: np.ndarray,
    p: np.ndarray,
    params: Mapping[str, float],
    **options: Any,
) -> tuple[float, str] | None:
    """A pole of the solved constraints that ``tr``'s samples do not show: ``(t, message)``, the
    first time checked at or past it and what it is, or None (``t_span``, ``samples``: those
    ``tr`` was asked for; ``options``: the other arguments of its :func:`integrate`).

    The samples see a pole where the sign of the solved constraints' determinant changes between
    two of them; a motion that crosses a pole and crosses back between two samples (few samples,
    a long run) shows none.  Where the integrator took more steps than there are samples, the run
    is integrated again (the same steps: only the dense output differs) with a sample at least
    every step on average (each right-hand side evaluation bounds a sixth of a step from above),
    up to :data:`POLE_CHECK_POINTS` points, and checked there by :func:`_pole`.
    """
    wanted = min(POLE_CHECK_POINTS, tr.rhs_evaluations // 6 + 1)
    if wanted <= samples:
        return None
    per = -(-(wanted - 1) // (samples - 1))  # the samples stay among the points checked
    # (only the state is needed there: the points are not observed)
    _, t, y, *_ = _samples(compiled, t_span, y0, p, samples=(samples - 1) * per + 1, **options)
    n = system.n
    k, why = _pole_at(system, t, y[:, :n], y[:, n : n + len(system._ind)], params)
    return (float(t[k]), why) if k < len(t) else None


def _watch(
    system: System,
    tr: Trajectory,
    params: Mapping[str, float],
    *,
    reduced: bool,
    compiled: CompiledModel | None = None,
    p: np.ndarray | None = None,
    pole: tuple[float, str] | None = None,
) -> Trajectory:
    """``tr`` cut at the first sample where the motion stops making sense, with status
    ``"failed"`` and a message that says where and along which coordinate.

    Checked at every sample: the velocities are finite; for reduced models (which solve
    the constraints for the dependent velocities) the constraints stay solvable — the
    dependent block of ``A`` neither becomes singular at a sample nor changes the sign of
    its determinant between two (a pole of ``q̇_dep = B q̇_σ + B_0`` crossed); where the
    generated ``M`` is the reduced mass matrix, it stays positive definite.
    """
    watched = _functions(system, "monitor", lambda: monitor(system))  # (how the energy column reads)
    tr.energy_conserved, tr.energy_column = watched.conserved, watched.column
    tr.holonomic_residual = holonomic_residual(
        system, tr.t, [tr.coordinates[c.func.__name__] for c in system.coordinates], params
    )
    k_bad, why, kind = len(tr.t), "", ""
    names = list(tr.coordinates)
    vel = np.column_stack([tr.velocities[c + "'"] for c in names]) if len(tr.t) else np.empty((0, 0))
    finite = np.all(np.isfinite(vel), axis=1) if len(tr.t) else np.empty(0, dtype=bool)
    if not np.all(finite):
        k = int(np.argmin(finite))
        bad = [c + "'" for c, x in zip(names, vel[k]) if not np.isfinite(x)]
        k_bad, kind = k, "pole"
        why = (
            f"a pole at t = {tr.t[k]:.6g}: the velocit{'y' if len(bad) == 1 else 'ies'} "
            f"{', '.join(bad)} {'is' if len(bad) == 1 else 'are'} not finite"
        )
    if (reduced or system.is_nonlinear) and system.g and k_bad > 0:
        # (constraints nonlinear in the velocities: a multiplier run stops at their singular set too)
        k, found = _pole(system, tr, params, k_bad)
        if k < k_bad:
            k_bad, why, kind = k, found, "pole"
    if system.is_nonlinear and not reduced and k_bad > 0:
        k, found = _left_branch(system, tr, params, k_bad)
        if k < k_bad:
            k_bad, why, kind = k, found, "branch"
    between = False  # a pole found between samples (:func:`_pole_between_samples`): cut at the time past it
    if pole is not None and (k := int(np.searchsorted(tr.t, pole[0]))) <= k_bad:
        # (also past the last sample of a failed run: the pole is why the integrator failed)
        if k < k_bad or (k == len(tr.t) and not tr.success):
            k_bad, why, kind, between = k, pole[1], "pole", True
    # (the vakonomic family's M for constraints nonlinear in the velocities is the Hessian of
    # T̃ + Σ c_β φ_β, not a mass matrix: it may be indefinite)
    mass = not system.is_nonlinear or registry.get(tr.model).is_true_motion
    if reduced and mass and compiled is not None and p is not None and k_bad > 0:
        k, found = _lost_definiteness(compiled, tr, p, k_bad)
        if k < k_bad:
            k_bad, why, kind, between = k, found, "mass", False
    if not between and (k_bad == len(tr.t) or (not tr.success and k_bad == len(tr.t) - 1)):
        if not tr.success and tr.message.startswith("a pole at"):  # the integrator met it (code 9)
            tr.failure = "pole"
        return tr  # (the last sample of a failed run: its own message says why)
    keep = slice(0, k_bad)
    for table in (tr.coordinates, tr.velocities, tr.multipliers):
        for key in table:
            table[key] = table[key][keep]
    tr.t, tr.energy, tr.constraint_residual = tr.t[keep], tr.energy[keep], tr.constraint_residual[keep]
    tr.holonomic_residual = tr.holonomic_residual[keep]
    tr.status, tr.failure = "failed", kind
    entry = registry.get(tr.model)
    tr.message = why + (
        f"; the {tr.model} equations do not hold there" if kind == "pole" and entry.reduced else ""
    )
    if kind == "pole" and entry.reduced and entry.is_true_motion:
        tr.message += (
            f" (the multiplier model {entry.fallback!r} does not solve the constraints and has no such pole)"
        )
    return tr


def _left_branch(system: System, tr: Trajectory, params: Mapping[str, float], stop: int) -> tuple[int, str]:
    """The first sample (before ``stop``) of a multiplier run whose dependent velocities are not the
    solved form's, ``q̇_dep ≠ φ(q, q̇_σ, t)``: the run crossed the singular set of constraints
    nonlinear in the velocities onto another solution of ``f = 0`` (``(stop, "")`` if none)."""
    from chaplygin.core._symbols import describe

    v, names = system._vars, [q.func.__name__ for q in system.coordinates]
    phi = [system._velocity_substitution[v.xd[i]] for i in system._dep]
    solve_phi, at_factors = _functions(system, "branch", lambda: _branch_functions(system))
    columns = [
        tr.t[:stop],
        *(tr.coordinates[c][:stop] for c in names),
        *(tr.velocities[names[i] + "'"][:stop] for i in system._ind),
        *(np.full(stop, params[par.name]) for par in system.parameters),
    ]
    with np.errstate(all="ignore"):
        solved = solve_phi(*columns)
        at = at_factors(*columns) if system._singular_set else []
    for value in at:  # a factor that fell by 12 orders of magnitude: the run sits on the set
        size = np.abs(np.broadcast_to(np.asarray(value, dtype=complex), (stop,)))
        low = size <= 1e-12 * size[0]
        if low.any():
            k = int(np.argmax(low))
            return k, (
                f"the singular set of the constraints at t = {tr.t[k]:.6g}, {singular_set_text(system)}; "
                "the motion on that solution of f = 0 does not go on from there"
            )
    for b, i in enumerate(system._dep):
        expected = np.broadcast_to(np.asarray(solved[b], dtype=complex), (stop,))
        actual = tr.velocities[names[i] + "'"][:stop]
        off = ~(np.abs(actual - expected) <= 1e-6 * (1 + np.abs(expected)))
        if off.any():
            k = int(np.argmax(off))
            where = f"between t = {tr.t[k - 1]:.6g} and {tr.t[k]:.6g}" if k else f"at t = {tr.t[k]:.6g}"
            return k, (
                f"the run left the solved form of the constraints, {names[i]}' = "
                f"{describe(system.to_user(phi[b]))}, {where}, for another solution of f = 0: it "
                f"crossed their singular set, {singular_set_text(system)}"
            )
    return stop, ""


def _branch_functions(system: System) -> tuple[Any, Any]:
    """The solved form φ and the factors of the singular set as NumPy functions of
    ``(t, q…, q̇_σ…, parameters…)`` (:func:`_left_branch`)."""
    import sympy as sp

    from chaplygin.core._symbols import TIME

    v = system._vars
    args = [TIME, *v.x, *(v.xd[i] for i in system._ind), *system.parameters]
    phi = [system._velocity_substitution[v.xd[i]] for i in system._dep]
    return sp.lambdify(args, phi, "numpy"), sp.lambdify(args, system._singular_set, "numpy")


def _pole(system: System, tr: Trajectory, params: Mapping[str, float], stop: int) -> tuple[int, str]:
    """The first sample (before ``stop``) at or just after a pole of the solved constraints;
    ``(stop, "")`` if none (the tests of :func:`pole_marks`, sample after sample)."""
    if stop == 0 or pole_free(system):
        return stop, ""
    names = [q.func.__name__ for q in system.coordinates]
    q = np.column_stack([tr.coordinates[c][:stop] for c in names])
    speeds = np.column_stack([tr.velocities[names[i] + "'"][:stop] for i in system._ind])
    return _pole_at(system, tr.t[:stop], q, speeds, params)


def _pole_at(
    system: System, t: np.ndarray, q: np.ndarray, speeds: np.ndarray, params: Mapping[str, float]
) -> tuple[int, str]:
    """:func:`_pole` at the points ``t`` (``q``: K × n coordinates, ``speeds``: K × ε independent
    velocities); ``(len(t), "")`` if none."""
    names = [c.func.__name__ for c in system.coordinates]
    singular, sign = pole_marks(system, t, q, params, speeds)
    k = first_pole(singular, sign)
    if k == len(t):
        return k, ""
    dep_names = ", ".join(names[i] + "'" for i in system._dep)
    if system.is_nonlinear:
        return k, (
            f"the singular set of the constraints {'at' if singular[k] else 'between'} t = "
            + (f"{t[k]:.6g}" if singular[k] else f"{t[k - 1]:.6g} and {t[k]:.6g}")
            + f", {singular_set_text(system)}"
        )
    if singular[k]:
        return k, (
            f"a pole of the solved constraints at t = {t[k]:.6g}: they cannot be solved for {dep_names} there"
        )
    return k, (
        f"a pole of the solved constraints between t = {t[k - 1]:.6g} and "
        f"{t[k]:.6g}: they cannot be solved for {dep_names} in between"
    )


def singular_set_text(system: System) -> str:
    """What the singular set of constraints nonlinear in the velocities is, in words (a clause
    that begins "where"): ``∂f/∂q̇_dep`` singular on them, the branch points of their solved form."""
    from chaplygin.core._symbols import describe

    dep = ", ".join(system.coordinates[i].func.__name__ + "'" for i in system._dep)
    where = " or ".join(f"{describe(e)} = 0" for e in system.singular_set)
    branch = f" (branch={system._branch})" if system._branch is not None else ""
    return (
        f"where ∂f/∂({dep}) is singular{' (' + where + ')' if where else ''}, a branch point: the "
        f"solutions of f = 0 for {dep} meet there and their solved form{branch} ends"
    )


def pole_marks(
    system: System,
    t: np.ndarray,
    q: np.ndarray,
    params: Mapping[str, Any],
    speeds: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """At ``K`` points ``(t[k], q[k])`` (``q``: K × n; each parameter a number or K numbers):
    ``(singular, sign)``.  For constraints nonlinear in the velocities ``speeds`` (K × ε) gives
    the independent velocities too: ``A = ∂f/∂q̇`` is taken on the constraints, and the
    branch points of their solved form (:attr:`System.singular_set`) are its factors.

    ``singular[k]``: ``A`` (or a factor of a denominator of its entries) is not finite there,
    or the dependent block of ``A`` is singular (rows scaled to largest entry 1, smallest
    singular value at most 1e-10, as :func:`_solvable`).  ``sign[k]``: the sign of ``det A_dep``
    times the factors of the denominators of ``A``'s entries (``tan φ`` counts as
    ``sin φ / cos φ``): where it changes between two points, a singular block or a pole of
    ``B`` lies between them.
    """
    count = len(t)
    evaluate, n_factors, _ = _pole_functions(system)
    if system.is_nonlinear and speeds is None:
        raise ValueError(
            "pole_marks: constraints nonlinear in the velocities need the independent velocities"
        )
    columns = [
        np.asarray(t, dtype=float),
        *np.asarray(q, dtype=float).T,
        *(np.asarray(speeds, dtype=float).T if system.is_nonlinear else ()),
        *(np.broadcast_to(np.asarray(params[par.name], dtype=float), (count,)) for par in system.parameters),
    ]
    g, n, dep = system.g, system.n, list(system._dep)
    # one column per value (a constant entry fills its column): A's entries, then the factors
    values = np.empty((g * n + max(n_factors, 1), count))
    values[g * n :] = 1.0
    with np.errstate(all="ignore"):
        for row, x in zip(values, evaluate(*columns)):
            row[:] = np.where(np.imag(x) == 0, np.real(x), np.nan) if np.iscomplexobj(x) else x
    a = values[: g * n].T.reshape(count, g, n)
    factors = values[g * n :].T
    finite = np.isfinite(values).all(axis=0)
    if not finite.all():
        a = np.where(np.isfinite(a), a, 0.0)
    scale = np.abs(a).max(axis=2, keepdims=True)
    usable = finite & (scale[:, :, 0] > 0).all(axis=1)
    a_dep = a[:, :, dep]
    block = a_dep / np.where(scale > 0, scale, 1.0)
    with np.errstate(all="ignore"):
        sign = np.sign(_dets(a_dep) * np.prod(factors, axis=1))
        # the smallest singular value of the scaled block (entries ≤ 1, so its largest is ≤ g)
        # is at least |det| / g^(g−1): the SVD only where that bound does not settle it
        unsure = ~(np.abs(_dets(block)) > 1e-10 * g ** (g - 1))
    small = np.zeros(count, dtype=bool)
    if np.any(unsure):
        small[unsure] = ~(np.linalg.svd(block[unsure], compute_uv=False)[:, -1] > 1e-10)
    singular = ~usable | small | (sign == 0)
    return singular, sign


def _dets(m: np.ndarray) -> np.ndarray:
    """The determinants of a stack of g × g matrices (written out for g ≤ 2: NumPy factors each)."""
    if m.shape[1] == 1:
        return m[:, 0, 0]
    if m.shape[1] == 2:
        return m[:, 0, 0] * m[:, 1, 1] - m[:, 0, 1] * m[:, 1, 0]
    return np.linalg.det(m)


def first_pole(singular: np.ndarray, sign: np.ndarray) -> int:
    """The first point (of :func:`pole_marks`, in the order of the run) at a pole or just past
    one: singular there, or the sign changed since the point before; ``len(sign)`` if none."""
    past = np.flatnonzero(singular | np.concatenate([[False], sign[1:] != sign[:-1]]))
    return int(past[0]) if past.size else len(sign)


def _pole_functions(system: System) -> tuple[Any, int, str]:
    """A NumPy function of ``(t, q…, parameters…)`` giving ``A``'s entries (row-major), then
    the distinct factors of the denominators of ``[A | A_0]``; how many factors; and how a run
    is watched for poles (:func:`_watch_level`: ``"none"``, ``"points"`` or ``"crossings"``).

    Generated as a module (:func:`_pole_source`), which the disk cache of compiled models
    (:mod:`chaplygin.numeric._modelcache`) keeps: a process that checks an equal system again
    imports it instead of factoring the denominators (0.2 s on the rattleback).
    """
    cached = system.__dict__.get("_pole_functions")
    if cached is not None:
        return cached
    from chaplygin.numeric import _modelcache, cache

    key = _modelcache.source_key(system, "pole-functions", POLE_FORMAT)
    found = _modelcache.load_source(key)
    if found is not None and type(found.get("factors")) is int and found.get("watch") in WATCH_LEVELS:
        source, n_factors, watch = found["source"], found["factors"], found["watch"]
    else:
        made = _pole_source(system)
        if made is None:  # not printable as NumPy source: lambdify, in memory only
            cached = _pole_lambdified(system)
            system.__dict__["_pole_functions"] = cached
            return cached
        source, n_factors, watch = made
        _modelcache.store_source(key, source, factors=n_factors, watch=watch)
    cached = (cache.import_source(source, "poles").poles, n_factors, watch)
    system.__dict__["_pole_functions"] = cached
    return cached


def pole_free(system: System) -> bool:
    """Whether the solved constraints have no pole that a motion could meet, so that a run is
    not checked for one at all: the dependent block of ``A`` and the denominators of
    ``[A | A_0]`` depend on neither t nor the coordinates (e.g. the rolling bodies'
    ``ẋ = …, ẏ = …``), and what the start satisfies holds all along."""
    return not system.g or _pole_functions(system)[2] == "none"


def sign_fixed(system: System) -> bool:
    """Whether the sign that the test of :func:`pole_marks` follows cannot change along any
    motion: :func:`pole_free`, or the dependent block of ``A`` is constant and each factor of the
    denominators keeps one sign for all real t, q and parameters (SymPy shows it nonnegative or
    nonpositive: the rattleback's ``a² sin²φ cos²θ + b² sin²θ + c² cos²φ cos²θ``).

    A run of such a system is checked at its own points only (the samples; an ensemble's start,
    kept samples and end), not at more points in between (no second integration, no grid): a
    change of sign between two points, which those would look for, cannot happen.  The zero of
    such a factor (it touches zero without changing sign) is seen only at a point that lands on
    it; a motion may pass it between two points unseen, with these checks as without them.
    """
    return not system.g or _pole_functions(system)[2] != "crossings"


#: how a run is watched for poles (:func:`_watch_level`)
WATCH_LEVELS = ("none", "points", "crossings")


#: bumped whenever :func:`_pole_source` writes other code
POLE_FORMAT = 4


def _pole_expressions(system: System) -> tuple[list[Any], list[Any]]:
    """``(arguments, expressions)`` of :func:`_pole_functions`: ``A``'s entries, then the distinct
    factors of the denominators of ``[A | A_0]`` (``tan φ`` counts as ``sin φ / cos φ``)."""
    import sympy as sp

    from chaplygin.core._symbols import TIME

    quotients = {
        sp.tan: lambda a: sp.sin(a) / sp.cos(a),
        sp.cot: lambda a: sp.cos(a) / sp.sin(a),
        sp.sec: lambda a: 1 / sp.cos(a),
        sp.csc: lambda a: 1 / sp.sin(a),
        sp.tanh: lambda a: sp.sinh(a) / sp.cosh(a),
        sp.coth: lambda a: sp.cosh(a) / sp.sinh(a),
    }
    factors: list[sp.Expr] = []
    v = system._vars
    if system.is_nonlinear:  # A = ∂f/∂q̇ on the constraints (q̇_dep = φ), and φ's branch points
        a = system._A.xreplace(system._velocity_substitution)
        speeds = [v.xd[i] for i in system._ind]
        return [TIME, *v.x, *speeds, *system.parameters], [*a, *system._singular_set]
    for entry in [*system._A, *system._A0]:
        for fn, quotient in quotients.items():
            entry = entry.replace(fn, quotient)
        for factor in sp.Mul.make_args(sp.denom(sp.together(entry))):
            base = factor.base if factor.is_Pow else factor
            if base.free_symbols and base not in factors:
                factors.append(base)
    return [TIME, *v.x, *system.parameters], [*system._A, *factors]


def _watch_level(system: System, exprs: list[Any]) -> str:
    """How a run is watched for poles, from :func:`_pole_expressions`'s ``exprs``: ``"none"``
    where the dependent block of ``A`` and every factor are free of t and the coordinates
    (:func:`pole_free`); ``"points"`` where the block is and every other factor keeps one sign
    for all real t, q and parameters (:func:`sign_fixed`; constraints linear in the velocities:
    the factors of nonlinear ones are branch points); else ``"crossings"``.  The parameters are
    taken as any real numbers, not as declared (``positive=True``): a run may be given values that
    a declaration excludes."""
    import sympy as sp

    from chaplygin.core._symbols import TIME

    moving = {TIME, *system._vars.x, *(system._vars.xd if system.is_nonlinear else ())}
    g, n = system.g, system.n
    block = [exprs[b * n + j] for b in range(g) for j in system._dep]
    factors = [e for e in exprs[g * n :] if moving & e.free_symbols]
    if any(moving & e.free_symbols for e in block):
        return "crossings"
    if not factors:
        return "none"
    if system.is_nonlinear:
        return "crossings"
    real = {s: sp.Dummy(s.name, real=True) for e in factors for s in e.free_symbols}
    one_sign = [e.xreplace(real) for e in factors]
    return "points" if all(e.is_nonnegative or e.is_nonpositive for e in one_sign) else "crossings"


def _pole_source(system: System) -> tuple[str, int, str] | None:
    """The module source of :func:`_pole_functions` (``poles(a0, a1, …)``, NumPy calls), the
    number of factors and :func:`_watch_level`; None where an expression cannot be printed so."""
    args, exprs = _pole_expressions(system)
    printed = numpy_lines(args, exprs)
    if printed is None:  # lambdify instead
        return None
    names, body = printed
    source = (
        f'"""Generated by chaplygin (pole functions, format {POLE_FORMAT}): the entries of A, then '
        'the factors of the denominators of [A | A_0]."""\n\n'
        "import numpy\n\n\n"
        f"def poles({', '.join(names)}):\n"
        "    return [\n" + "".join(f"        {line},\n" for line in body) + "    ]\n"
    )
    return source, len(exprs) - system.g * system.n, _watch_level(system, exprs)


def numpy_lines(args: Sequence[Any], exprs: Sequence[Any]) -> tuple[list[str], list[str]] | None:
    """``exprs`` printed as NumPy code, a line each, in the names ``a0, a1, …`` standing for
    ``args``: ``(those names, the lines)`` (the body of a generated module's function: the pole
    functions here, a run plan's mass matrix in :mod:`chaplygin.numeric._plan`); None where an
    expression holds anything but ``args`` or SymPy's printer cannot write it on one line."""
    import sympy as sp
    from sympy.printing.numpy import NumPyPrinter

    names = sp.symbols(f"a0:{len(args)}")
    rename = dict(zip(args, names))
    renamed = [sp.sympify(e).xreplace(rename) for e in exprs]
    if any(not e.free_symbols <= set(names) for e in renamed):
        return None
    printer = NumPyPrinter(
        {"fully_qualified_modules": True, "inline": True, "allow_unknown_functions": False}
    )
    try:
        lines = [printer.doprint(e) for e in renamed]
    except NotImplementedError:  # (SymPy's PrintMethodNotImplementedError)
        return None
    return None if any("\n" in line for line in lines) else ([str(x) for x in names], lines)


def _pole_lambdified(system: System) -> tuple[Any, int, str]:
    import sympy as sp

    args, exprs = _pole_expressions(system)
    n_factors = len(exprs) - system.g * system.n
    return sp.lambdify(args, exprs, modules="numpy"), n_factors, _watch_level(system, exprs)


def _lost_definiteness(compiled: CompiledModel, tr: Trajectory, p: np.ndarray, stop: int) -> tuple[int, str]:
    """The first sample (before ``stop``) where the generated ``M`` — the reduced mass matrix
    of a symbolically reduced model — is not positive definite; ``(stop, "")`` if none (and
    for the models whose ``M`` is not a mass matrix)."""
    module = compiled.module
    evaluate = getattr(module, "evaluate", None)
    if hasattr(module, "MODEL"):  # the shared numba loop's model: evaluate through it, compiling nothing
        from chaplygin.numeric._loop import evaluator

        evaluate = evaluator(module)
    if (
        evaluate is None
        or int(module.DIM) != int(module.K)
        or not registry.get(compiled.layout.model).reduced
    ):
        return stop, ""
    layout = compiled.layout
    for k in range(stop):
        y = np.array([tr[name][k] for name in layout.state], dtype=float)
        m = np.asarray(evaluate(float(tr.t[k]), y, p)[0], dtype=float)
        if not np.allclose(m, m.T, rtol=1e-9, atol=1e-12 * np.max(np.abs(m), initial=1.0)):
            return stop, ""  # not a symmetric mass matrix: nothing to check
        try:
            np.linalg.cholesky(m)
        except np.linalg.LinAlgError:
            w, vec = np.linalg.eigh(m)
            along = layout.velocities[int(np.argmax(np.abs(vec[:, 0])))]
            return k, (
                f"the mass matrix is no longer positive definite at t = {tr.t[k]:.6g}: the "
                f"kinetic energy is {'zero' if w[0] == 0 else 'negative' if w[0] < 0 else 'nearly zero'} "
                f"along {along} (eigenvalue {w[0]:.3g})"
            )
    return stop, ""


def _not_finite(system: System, params: Mapping[str, float], t0: float) -> InputError:
    """The error of a start where the equations have no finite real value."""
    given = ", ".join(f"{k} = {val:g}" for k, val in params.items())
    return InputError(
        f"{system.name}: the equations are not finite at the initial state (t = {t0:g}; {given}): "
        "a denominator vanishes there (a parameter of 0?); change the parameters or the initial values."
    )


def _matching_constants(
    system: System, q: np.ndarray, qd: np.ndarray, params: Mapping[str, float], t0: float
) -> list[float]:
    """The c with μ(0) = 0 — vakonomic momenta equal to the true ones: ``c_β = ∂T/∂q̇_{ε+β}`` at t0."""

    def momenta() -> Any:
        import sympy as sp

        return sp.Matrix([sp.diff(system._T, system._vars.xd[i]) for i in system._dep])

    values = _numeric(system, "∂T/∂q̇_dep", momenta, q, qd, params, t0).ravel()
    if np.isnan(values).any():
        raise _not_finite(system, params, t0)
    return [float(x) for x in values]


def _initial_multipliers(
    system: System,
    vak: dict[str, Any],
    q: np.ndarray,
    qd: np.ndarray,
    params: Mapping[str, float],
    t0: float,
) -> np.ndarray:
    names = [m for m in system.equations("vakonomic").multipliers]
    if "mu" in vak:
        given = vak["mu"]
        if isinstance(given, list):
            return np.array(given, dtype=float)
        labels = [m.func.__name__ for m in names]
        unknown = [k for k in given if k not in names and str(k) not in labels]
        values = [given.get(m, given.get(label)) for m, label in zip(names, labels)]
        if unknown or any(v is None for v in values):
            raise InputError(
                f"multipliers: {'unknown key ' + repr(unknown[0]) if unknown else 'missing values'}; "
                f"give μ(0) for {', '.join(labels)}."
            )
        return np.array(values, dtype=float)
    c = vak["constants"]
    if isinstance(c, str) and c == "match":
        return np.zeros(system.g)  # μ(0) = 0: vakonomic momenta equal the true ones
    return _multipliers_from_constants(system, np.asarray(c, dtype=float), q, qd, params, t0)


def _momenta(
    system: System, q: np.ndarray, qd: np.ndarray, params: Mapping[str, float], t0: float
) -> tuple[np.ndarray, np.ndarray]:
    """``∂T/∂q̇_dep`` and the columns ``A_dep`` of the dependent velocities in the constraints
    at a state: the vakonomic momenta of the dependent coordinates are
    ``∂L_v/∂q̇_dep = ∂T/∂q̇_dep + A_depᵀ μ``."""
    p = np.array(_matching_constants(system, q, qd, params, t0), dtype=float)
    a = _numeric(system, "constraints", system._constraint_matrix, q, qd, params, t0)
    return p, a[:, list(system._dep)]


def _multipliers_from_constants(
    system: System, c: np.ndarray, q: np.ndarray, qd: np.ndarray, params: Mapping[str, float], t0: float
) -> np.ndarray:
    """μ(0) from the constants c: ``A_depᵀ μ = c − ∂T/∂q̇_dep`` at t0 (eqs. (19)-(20) with c kept).

    c_β are the momenta ``∂L_v/∂q̇_{ε+β}`` of the dependent coordinates at the start; on a
    Chaplygin system without forces along the dependent coordinates they stay constant (the
    integral of (18b)), on any other system they are their values at t0.
    """
    p, a_dep = _momenta(system, q, qd, params, t0)
    try:
        mu = np.linalg.solve(a_dep.T, c - p)
    except np.linalg.LinAlgError:
        mu = np.full(system.g, np.nan)
    if not np.all(np.isfinite(mu)):
        raise InputError(
            "initial multipliers: the constraints cannot be solved for the dependent velocities at "
            "the initial state, so μ(0) does not follow from the constants; start elsewhere or "
            "give multipliers=[μ(0), ...]."
        )
    return mu


def vakonomic_constants(
    system: System,
    constants: Any,
    multipliers: Any,
    initial: Mapping[Any, float],
    parameters: Mapping[Any, float] | None = None,
    t0: float = 0.0,
) -> list[float]:
    """The constants c_β of the vakonomic motion that ``constants`` or ``multipliers`` ask for,
    as numbers: the momenta ``∂L_v/∂q̇_{ε+β} = ∂T/∂q̇_{ε+β} + Σ_α A_α,ε+β μ_α`` of the dependent
    coordinates at ``t0``.

    ``constants="match"`` gives ``c_β = ∂T/∂q̇_{ε+β}`` (μ(0) = 0: the vakonomic motion starts
    with the accelerations of the true one), ``"zero"`` or None every ``c_β = 0`` (Lindelöf's
    motion on a Chaplygin system), values themselves; ``multipliers`` (μ(0)) the c they give.
    Checked as by :func:`simulate`.
    """
    _, vak = _vakonomic_setup(system, registry.MODELS["vakonomic"], constants, multipliers)
    assert vak is not None
    params = _parameters(system, parameters)
    q, qd = initial_state(system, initial, params, t0)
    p, a_dep = _momenta(system, q, qd, params, t0)
    if "mu" in vak:
        return [float(x) for x in p + a_dep.T @ _initial_multipliers(system, vak, q, qd, params, t0)]
    c = vak["constants"]
    return [float(x) for x in (p if isinstance(c, str) else c)]


def integrate(
    compiled: CompiledModel,
    t_span: tuple[float, float],
    y0: np.ndarray,
    p: np.ndarray,
    params: dict[str, float],
    *,
    rtol: float,
    atol: float,
    method: str,
    samples: int,
    max_step: float,
    g: int,
    progress: Progress | None = None,
    time_limit: float | None = None,
) -> Trajectory:
    """Integrate ``compiled.rhs`` from ``y0`` and sample it (``progress``, ``time_limit``: see
    :func:`simulate`; the JAX backend neither reports nor estimates).

    ``c`` or ``numba`` backend with ``method="DOP853"``: the compiled loop of
    :mod:`chaplygin.numeric._ckernel` or :mod:`chaplygin.numeric._loop` (the whole integration in C or numba).  ``jax``
    backend with ``"DOP853"``, ``"RK45"`` or ``"RK23"``: diffrax
    (:mod:`chaplygin.numeric.jaxbackend`).  ``numpy`` backend with ``"DOP853"``: the
    generated ``rhs_list`` stepped by :mod:`chaplygin.numeric._pyloop` (SciPy's DOP853 on
    lists of floats).  Otherwise: SciPy's stepper class driven step by step, with dense
    output where a sample falls.

    When the right-hand side fails inside a step (a singular mass matrix, a
    non-finite value), the step is not taken; the compiled loop and the Python
    steppers then integrate again from the last accepted step with steps of at most
    half the distance to the failure, until it is pinned down to :data:`PIN`.
    So a failed run keeps every sample before the failure, whatever steps the
    integrator chose (a first step that jumps past all the samples included).
    """
    compiled, ts, ys, status, message, n_rhs = _samples(
        compiled,
        t_span,
        y0,
        p,
        rtol=rtol,
        atol=atol,
        method=method,
        samples=samples,
        max_step=max_step,
        progress=progress,
        time_limit=time_limit,
    )
    return _trajectory(compiled, ts, ys, p, params, status, message, n_rhs, g)


def _samples(
    compiled: CompiledModel,
    t_span: tuple[float, float],
    y0: np.ndarray,
    p: np.ndarray,
    *,
    rtol: float,
    atol: float,
    method: str,
    samples: int,
    max_step: float,
    progress: Progress | None = None,
    time_limit: float | None = None,
) -> tuple[CompiledModel, np.ndarray, np.ndarray, str, str, int]:
    """:func:`integrate` before anything is observed: ``(model, t, y, status, message, n_rhs)``,
    the model being the one that integrated (the shared loop's, for numba)."""
    times = np.linspace(t_span[0], t_span[1], samples)
    return targets.get(compiled.backend).integrate(
        compiled, t_span, y0, p, times, rtol=rtol, atol=atol, method=method, max_step=max_step,
        progress=progress, time_limit=time_limit,
    )  # fmt: skip


def _pinned(
    attempt: Callable[[float, np.ndarray, np.ndarray, float, float | None], _Attempt],
    t0: float,
    y0: np.ndarray,
    times: np.ndarray,
    max_step: float,
) -> tuple[np.ndarray, np.ndarray, str, int]:
    """Samples at ``times`` from ``attempt``s: after a failure inside a step, again from the
    last accepted step with ``max_step`` half the distance to the failure (see :func:`integrate`)."""
    t_parts, y_parts, n_rhs, k = [], [], 0, 0
    t_start, y_start, cap, first = t0, y0, max_step, None
    for _ in range(200):  # the distance to the failure halves every time: ~40 suffice
        run = attempt(t_start, y_start, times[k:], cap, first)
        t_parts.append(run.t)
        y_parts.append(run.y)
        n_rhs += run.n_rhs
        k += len(run.t)
        gap = run.t_fail - run.t_last
        if not (run.message and run.retry and gap > PIN * max(1.0, abs(run.t_fail))) or run.y_last is None:
            break
        t_start, y_start, cap = run.t_last, run.y_last, min(max_step, gap / 2)
        first = cap  # steps after the first stay within it, so the next failure is at most this far
    return np.concatenate(t_parts), np.concatenate(y_parts).reshape(k, len(y0)), run.message, n_rhs


def _loop_attempt(
    looped: CompiledModel, t1: float, p: np.ndarray, rtol: float, atol: Any, progress: Progress | None = None
) -> Callable[..., _Attempt]:
    """An attempt of :func:`_pinned` with the compiled DOP853 loop.

    The loop runs in stretches of steps (``max_steps``), each started where the last one
    stopped with the step it would have taken next, so the steps, the samples and the count of
    right-hand sides are those of one run; the stretches grow until each takes about
    :data:`PROGRESS_EVERY` seconds, and ``progress``, if given, is told the time reached after
    each.  Between two stretches Python runs its signal handlers: Ctrl-C (``KeyboardInterrupt``)
    stops a compiled run within a fraction of a second, whether or not anything is displayed.
    """
    from chaplygin.numeric._loop import integrate_dop853

    stopped = 4  # the loop's status "too many steps" (chaplygin.numeric._loop.STATUS): max_steps reached

    def attempt(
        t_start: float, y_start: np.ndarray, times: np.ndarray, cap: float, first: float | None
    ) -> _Attempt:
        t_parts, y_parts, n_rhs, stretch = [], [], 0, 64
        while True:
            started = time.monotonic()
            res = integrate_dop853(
                looped,
                (t_start, t1),
                y_start,
                p,
                times,
                rtol=rtol,
                atol=atol,
                max_step=cap,
                first_step=first,
                max_steps=stretch,
            )
            t_parts.append(res.t)
            y_parts.append(res.y)
            n_rhs += res.n_rhs - (len(t_parts) > 1)  # a resumed stretch evaluates f(t, y) once more
            if res.code != stopped or res.y_last is None:
                break
            if progress is not None:
                progress(res.t_last)
            times = times[len(res.t) :]
            t_start, y_start, first = res.t_last, res.y_last, res.h_next
            if time.monotonic() - started < PROGRESS_EVERY / 2:
                stretch = min(2 * stretch, 1 << 30)
        message = "" if res.code == 0 else res.message
        ts, ys = np.concatenate(t_parts), np.concatenate(y_parts)
        return _Attempt(ts, ys, message, res.code in (2, 3, 5, 9), res.t_last, res.y_last, res.t_fail, n_rhs)

    return attempt


def _list_attempt(
    compiled: CompiledModel,
    t1: float,
    p: np.ndarray,
    rtol: float,
    atol: Any,
    progress: Progress | None = None,
) -> Callable[..., _Attempt]:
    """An attempt of :func:`_pinned` with the plain-Python DOP853 of :mod:`chaplygin.numeric._pyloop`
    on the generated ``rhs_list`` (lists of floats): SciPy's steps, statuses and messages, but
    no array in a step and no SciPy import."""
    from chaplygin.numeric._dop853 import tolerances
    from chaplygin.numeric._pyloop import dop853

    rhs = compiled.module.rhs_list
    names = compiled.layout.coordinates
    n_state = len(compiled.layout.state)
    values = [float(x) for x in p]
    rtol, atol_v = tolerances(rtol, atol, n_state)
    atol_list = atol_v.tolist()
    count = [0]

    def fun(t: float, y: list[float]) -> list[float]:
        count[0] += 1
        try:
            dy = rhs(t, y, values)
        except (np.linalg.LinAlgError, ZeroDivisionError, ValueError, ArithmeticError) as exc:
            raise _StepFailure(f"the right-hand side failed at t = {t:.6g}: {exc}", t) from None
        if not math.isfinite(sum(dy)) and not all(map(math.isfinite, dy)):  # (a sum may overflow)
            raise _non_finite(names, dy, t)
        return dy

    def attempt(
        t_start: float, y_start: np.ndarray, times: np.ndarray, cap: float, first: float | None
    ) -> _Attempt:
        count[0] = 0
        run = dop853(
            fun,
            float(t_start),
            float(t1),
            [float(x) for x in y_start],
            times.tolist(),
            rtol=rtol,
            atol=atol_list,
            max_step=cap,
            first_step=first,
            progress=progress,
            every=PROGRESS_EVERY,
        )
        message = run.message
        if message and not run.failed_inside:  # a step too small, as _scipy_attempt reports it
            message = f"the integrator stopped at t = {run.t_last:.6g}: {message}"
        ys = np.array(run.y, dtype=float).reshape(len(run.t), n_state)
        return _Attempt(
            np.array(run.t, dtype=float),
            ys,
            message,
            run.failed_inside,
            float(run.t_last),
            np.array(run.y_last, dtype=float),
            run.t_fail,
            count[0],
        )

    return attempt


def _non_finite(names: Sequence[str], dy: Any, t: float) -> _StepFailure:
    """The failure of a derivative that is not finite: a pole where a velocity (solved from the
    constraints) is not, else a blow-up."""
    bad = [c + "'" for c, x in zip(names, dy[: len(names)]) if not math.isfinite(x)]
    if bad:
        return _StepFailure(
            f"a pole at t = {t:.6g}: the velocit{'y' if len(bad) == 1 else 'ies'} "
            f"{', '.join(bad)} {'is' if len(bad) == 1 else 'are'} not finite",
            t,
        )
    return _StepFailure(f"the solution blew up (non-finite derivative) at t = {t:.6g}", t)


def _scipy_attempt(
    compiled: CompiledModel,
    t1: float,
    p: np.ndarray,
    rtol: float,
    atol: Any,
    method: str,
    progress: Progress | None = None,
) -> Callable[..., _Attempt]:
    """An attempt of :func:`_pinned` with SciPy's stepper, driven step by step (``progress``
    told the time reached after a step, at most every :data:`PROGRESS_EVERY` seconds)."""
    import scipy.integrate as si

    rhs = compiled.rhs
    names = compiled.layout.coordinates

    def fun(t: float, y: np.ndarray) -> np.ndarray:
        count[0] += 1
        try:
            dy = rhs(t, y, p)
        except (np.linalg.LinAlgError, ZeroDivisionError, ValueError, ArithmeticError) as exc:
            raise _StepFailure(f"the right-hand side failed at t = {t:.6g}: {exc}", t) from None
        if not np.all(np.isfinite(dy)):
            raise _non_finite(names, dy, t)
        return dy

    count = [0]

    def attempt(
        t_start: float, y_start: np.ndarray, times: np.ndarray, cap: float, first: float | None
    ) -> _Attempt:
        count[0] = 0
        out = np.empty((len(times), len(y_start)))
        k, t_last, y_last = 0, t_start, y_start
        message, retry, t_fail = "", False, math.nan
        stepper = None
        try:
            stepper = getattr(si, method)(
                fun, t_start, y_start, t1, rtol=rtol, atol=atol, max_step=cap, first_step=first
            )
            if len(times) and times[0] == t_start:
                out[0], k = y_start, 1
            due = time.monotonic() + PROGRESS_EVERY
            while k < len(times):
                msg = stepper.step()
                if stepper.status == "failed":
                    message, t_fail = f"the integrator stopped at t = {stepper.t:.6g}: {msg}", stepper.t
                    break
                if progress is not None and time.monotonic() >= due:
                    progress(float(stepper.t))
                    due = time.monotonic() + PROGRESS_EVERY
                if times[k] > stepper.t and stepper.status != "finished":
                    continue  # no sample in this step: skip the dense output (extra evaluations)
                dense = stepper.dense_output()
                while k < len(times) and times[k] <= stepper.t:
                    out[k] = dense(times[k])
                    k += 1
                if stepper.status == "finished" and k < len(times):
                    out[k:] = dense(times[k:]).T
                    k = len(times)
            t_last, y_last = stepper.t, stepper.y
        except _StepFailure as exc:
            message, retry, t_fail = str(exc), True, exc.t
            if stepper is not None:  # (None: the stepper's own first evaluations failed)
                t_last, y_last = stepper.t, stepper.y
        return _Attempt(times[:k], out[:k], message, retry, float(t_last), np.array(y_last), t_fail, count[0])

    return attempt


def _trajectory(
    compiled: CompiledModel,
    times: np.ndarray,
    ys: np.ndarray,
    p: np.ndarray,
    params: dict[str, float],
    status: str,
    message: str,
    evaluations: int,
    g: int,
) -> Trajectory:
    layout = compiled.layout
    n = len(layout.coordinates)
    obs = targets.get(compiled.backend).observe_run(compiled, times, ys, p)
    n_react = len(layout.reactions)
    velocities = obs[:, obs.shape[1] - n :] if len(times) else np.empty((0, n))
    residual = np.max(np.abs(obs[:, 1 : 1 + g]), axis=1) if g and len(times) else np.zeros(len(times))
    multipliers = {name: obs[:, 1 + g + j] for j, name in enumerate(layout.reactions)} if n_react else {}
    base = n + len(layout.velocities)
    multipliers.update({name: ys[:, base + j] for j, name in enumerate(layout.multipliers)})
    return Trajectory(
        layout.model,
        layout.form,
        compiled.backend,
        times,
        {name: ys[:, i] for i, name in enumerate(layout.coordinates)},
        {name + "'": velocities[:, i] for i, name in enumerate(layout.coordinates)},
        multipliers,
        obs[:, 0] if len(times) else np.empty(0),
        residual,
        status,
        message,
        dict(params),
        evaluations,
    )
