"""Numerical simulation of any model from one initial state, with invariants monitored.

Reduced models (Chaplygin, Voronets, Lindelöf, the vakonomic family) integrate
all coordinates and the independent velocities; the dependent coordinates
follow through the constraints.  The multiplier models integrate all
coordinates and velocities (and μ for the vakonomic model) with the
constraints imposed at acceleration level; their constraint residual shows the
drift.  Integration: with ``backend="c"`` (what ``"auto"``, the default, picks
for DOP853 where a C compiler is found; see :func:`choose_backend`) or
``backend="numba"`` and DOP853, a compiled port of SciPy's DOP853 that runs
entirely in C (:mod:`chaplygin._ckernel`) or inside numba (:mod:`chaplygin._loop`); with
``backend="jax"``, diffrax; otherwise SciPy's stepper classes (``DOP853`` by
default) driven step by step.  Every path ends a failed run (step-size
underflow, a singular mass matrix, a blow-up) with a status, a message and the
trajectory so far.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .errors import ChaplyginError

if TYPE_CHECKING:  # SymPy, code generation and SciPy are imported where they are used: a
    # warm run of the command line (chaplygin._quick) needs none of them
    from ._ckernel import CompiledModel
    from .system import System

__all__ = ["Trajectory", "simulate", "METHODS", "BACKENDS", "choose_backend"]

#: chaplygin.symmetric.METHODS (the tests check that they agree; not imported: it compiles)
SYMMETRIC_METHODS = ("midpoint", "gauss4", "gauss6")
METHODS = ("DOP853", "RK45", "RK23", "Radau", "BDF", "LSODA", *SYMMETRIC_METHODS)
#: what ``backend=`` accepts: "auto" chooses one of the others (:func:`choose_backend`)
BACKENDS = ("auto", "numpy", "numba", "c", "jax")


def choose_backend(backend: str, method: str = "DOP853") -> str:
    """The backend that ``backend="auto"`` runs ``method`` with; any other value as it is.

    ``"auto"`` is ``"c"`` (the generated ``fill`` and the DOP853 loop in C,
    :mod:`chaplygin._ckernel`) for ``DOP853`` where a C compiler is found: it
    costs a fraction of a second to build once per model, nothing later (the
    kernel cache), and integrates at compiled speed, so it pays for itself on
    any run.  Otherwise ``"numpy"`` (no build step; SciPy's steppers).  numba is
    never chosen: its first compile of a model takes seconds, and importing it
    half a second more; ``backend="numba"`` still asks for it.
    """
    if backend not in BACKENDS:
        raise ChaplyginError(f"unknown backend {backend!r}; the backends are {', '.join(map(repr, BACKENDS))}.")
    if backend != "auto":
        return backend
    if method == "DOP853":
        from ._ckernel import Unavailable, compiler

        try:
            compiler()
            return "c"
        except Unavailable:
            pass
    return "numpy"


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
        ``T − U`` at each sample (for rheonomic or affine constraints it is not
        an invariant).
    constraint_residual : ndarray
        ``max_β |Σ_s A_βs q̇_s + A_β0|`` at each sample.
    status, message : str
        ``"success"`` or ``"failed"``, and why.
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

    @property
    def success(self) -> bool:
        return self.status == "success"

    def __getitem__(self, name: str) -> np.ndarray:
        for table in (self.coordinates, self.velocities, self.multipliers):
            if name in table:
                return table[name]
        if name in ("t", "energy", "constraint_residual"):
            return getattr(self, name)
        raise KeyError(f"{name!r}: the columns are {', '.join(self.columns)}")

    @property
    def columns(self) -> list[str]:
        """Column names in export order."""
        return ["t", *self.coordinates, *self.velocities, "energy", "constraint_residual", *self.multipliers]

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
        """Write the columns to a CSV file, atomically."""
        header = ",".join(self.columns)

        def write(fh: Any) -> None:
            np.savetxt(fh, self.table(), delimiter=",", header=header, comments="", fmt="%.17g")

        return _atomic_write(path, write, text=True)

    def to_npz(self, path: str | os.PathLike[str]) -> Path:
        """Write the columns to a NumPy ``.npz`` archive (one array per column), atomically."""

        def write(fh: Any) -> None:
            np.savez(fh, **{c: self[c] for c in self.columns})

        return _atomic_write(path, write, text=False)

    def __repr__(self) -> str:
        return (
            f"<Trajectory {self.model}/{self.form} [{self.backend}] {self.status}: "
            f"{len(self.t)} samples to t = {self.t[-1] if len(self.t) else float('nan'):g}>"
        )


def _atomic_write(path: str | os.PathLike[str], write: Any, *, text: bool) -> Path:
    """Write through a temporary file in the same folder, then rename over ``path``."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp")
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


# ------------------------------------------------------------------ inputs
def _lookup(system: System, key: Any) -> tuple[str, int]:
    """``("q", i)`` for a coordinate, ``("v", i)`` for a velocity, given as symbol or name."""
    import sympy as sp

    from ._symbols import TIME

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
    raise ChaplyginError(
        f"initial: {key!r} is neither a coordinate nor a velocity of {system.name}; use "
        f"{', '.join(names)} or their velocities ({names[0]}' …)."
    )


def initial_state(
    system: System, initial: Mapping[Any, float], params: Mapping[str, float], t0: float
) -> tuple[np.ndarray, np.ndarray]:
    """Full coordinates and velocities at ``t0`` from the user's initial data.

    Every coordinate and every independent velocity is needed; dependent
    velocities follow from the constraints (a given one must agree with them).
    """
    n = system.n
    q = np.full(n, np.nan)
    qd = np.full(n, np.nan)
    for key, value in initial.items():
        kind, i = _lookup(system, key)
        (q if kind == "q" else qd)[i] = float(value)
    names = [c.func.__name__ for c in system.coordinates]
    missing = [names[i] for i in range(n) if np.isnan(q[i])]
    missing += [names[i] + "'" for i in system._ind if np.isnan(qd[i])]
    if missing:
        raise ChaplyginError(
            f"initial: missing {', '.join(missing)}; give every coordinate and the independent "
            f"velocities ({', '.join(names[i] + chr(39) for i in system._ind)})."
        )
    if not system.g:
        return q, qd
    # A_dep q̇_dep = −(A_ind q̇_σ + A_0), solved numerically (no symbolic B needed)
    ind, dep = list(system._ind), list(system._dep)
    a = _evaluate(system, system._A.row_join(system._A0), q, qd, params, t0)
    try:
        implied_all = np.linalg.solve(a[:, dep], -(a[:, ind] @ qd[ind] + a[:, -1]))
    except np.linalg.LinAlgError:
        raise ChaplyginError(
            "initial: the constraints cannot be solved for the dependent velocities "
            f"({', '.join(names[i] + chr(39) for i in dep)}) at this configuration."
        ) from None
    for i, implied in zip(dep, implied_all):
        if not np.isnan(qd[i]) and abs(qd[i] - implied) > 1e-9 * max(1.0, abs(implied)):
            raise ChaplyginError(
                f"initial: {names[i]}' = {qd[i]:g} violates the constraints, which give "
                f"{names[i]}' = {implied:.12g} (residual {qd[i] - implied:.3g})."
            )
        qd[i] = implied
    return q, qd


def _parameters(system: System, parameters: Mapping[Any, float] | None) -> dict[str, float]:
    out: dict[str, float] = {}
    for key, value in (parameters or {}).items():
        out[system.parameter(key).name] = float(value)
    missing = [p.name for p in system.parameters if p.name not in out]
    if missing:
        raise ChaplyginError(
            f"parameters: no value for {', '.join(missing)}; every parameter of {system.name} "
            f"({', '.join(p.name for p in system.parameters)}) needs a number."
        )
    return out


def _vakonomic_setup(
    system: System, model: str, constants: Any, multipliers: Any
) -> tuple[Any, dict[str, Any] | None]:
    """Constants of the family, or the initial multipliers of the multiplier form."""
    if model == "vakonomic_family":
        return ([0.0] * system.g if constants is None else constants), None
    if model == "vakonomic":
        if multipliers is not None:
            return None, {"mu": multipliers}
        return None, {"constants": [0.0] * system.g if constants is None else constants}
    if constants is not None or multipliers is not None:
        raise ChaplyginError(
            f"constants/multipliers are for the vakonomic models, not for {model!r}."
        )
    return None, None


# ------------------------------------------------------------------ integration
class _StepFailure(Exception):
    pass


def simulate(
    system: System,
    model: str,
    t_span: tuple[float, float] | float,
    initial: Mapping[Any, float],
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
) -> Trajectory:
    """Simulate one model of ``system`` (see :meth:`System.simulate`)."""
    t0, t1 = (0.0, float(t_span)) if np.isscalar(t_span) else map(float, t_span)  # type: ignore[arg-type]
    if not t1 > t0:
        raise ChaplyginError(f"t_span: the end time {t1:g} must be after the start {t0:g}.")
    if method not in METHODS:
        raise ChaplyginError(f"method {method!r} is not one of {', '.join(METHODS)}.")
    if samples < 2:
        raise ChaplyginError("samples: at least 2 are needed (the start and the end).")
    auto = backend == "auto"
    backend = choose_backend(backend, method)
    if method in SYMMETRIC_METHODS:  # fixed-step symmetric methods: chaplygin.symmetric
        from .symmetric import simulate_symmetric

        return simulate_symmetric(system, model, (t0, t1), initial, parameters, method=method, step=step,
                                  form=form, samples=samples, backend=backend, constants=constants,
                                  multipliers=multipliers)
    if step is not None:
        raise ChaplyginError(
            f"step: a fixed step size is for the symmetric methods ({', '.join(SYMMETRIC_METHODS)}); "
            f"method {method!r} adapts its steps to rtol/atol (bounded by max_step)."
        )
    params = _parameters(system, parameters)
    family_c, vak = _vakonomic_setup(system, model, constants, multipliers)
    q, qd = initial_state(system, initial, params, t0)
    if isinstance(family_c, str) and family_c == "match":
        family_c = _matching_constants(system, q, qd, params, t0)
    from .codegen import BackendUnavailable, compile_model, parameter_vector

    try:
        compiled = compile_model(system, model, form, backend, constants=family_c, reduction=reduction)
    except BackendUnavailable:
        if not auto:
            raise
        compiled = compile_model(system, model, form, "numpy", constants=family_c, reduction=reduction)
    layout = compiled.layout

    y0 = list(q) + ([*qd] if model in ("chetaev", "vakonomic") else [qd[i] for i in system._ind])
    if model == "vakonomic":
        y0 += list(_initial_multipliers(system, vak or {}, q, qd, params, t0))
    p = parameter_vector(layout, params)
    return integrate(compiled, (t0, t1), np.array(y0), p, params, rtol=rtol, atol=atol,
                     method=method, samples=samples, max_step=max_step, g=system.g)


def _evaluate(
    system: System, expr: Any, q: np.ndarray, qd: np.ndarray,
    params: Mapping[str, float], t0: float,
) -> Any:
    """``expr`` (internal symbols; a matrix gives an array) at time ``t0``, state ``(q, q̇)``
    and the parameter values (velocities that are NaN are left out)."""
    import sympy as sp

    from ._symbols import TIME

    v = system._vars
    values = {TIME: t0, **dict(zip(v.x, q)), **{x: val for x, val in zip(v.xd, qd) if not np.isnan(val)}}
    values.update({system.parameter(k): val for k, val in params.items()})
    out = expr.xreplace({k: sp.Float(x) for k, x in values.items()}).evalf()
    if isinstance(out, sp.MatrixBase):
        return np.array(out.tolist(), dtype=float)
    return float(out)


def _matching_constants(
    system: System, q: np.ndarray, qd: np.ndarray, params: Mapping[str, float], t0: float
) -> list[float]:
    """The c with μ(0) = 0 — vakonomic momenta equal to the true ones: ``c_β = ∂T/∂q̇_{ε+β}`` at t0."""
    import sympy as sp

    v = system._vars
    return [_evaluate(system, sp.diff(system._T, v.xd[i]), q, qd, params, t0) for i in system._dep]


def _initial_multipliers(
    system: System, vak: dict[str, Any], q: np.ndarray, qd: np.ndarray,
    params: Mapping[str, float], t0: float,
) -> np.ndarray:
    names = [m for m in system.equations("vakonomic").multipliers]
    if "mu" in vak:
        given = vak["mu"]
        values = [given[k] for k in range(system.g)] if isinstance(given, Sequence) else [
            given.get(m, given.get(m.func.__name__)) for m in names
        ]
        if any(v is None for v in values) or len(values) != system.g:
            raise ChaplyginError(
                f"multipliers: give μ(0) for {', '.join(m.func.__name__ for m in names)}."
            )
        return np.array(values, dtype=float)
    c = vak["constants"]
    if isinstance(c, str) and c == "match":
        return np.zeros(system.g)  # μ(0) = 0: vakonomic momenta equal the true ones
    from .vakonomic import family_obstructions

    problems = family_obstructions(system)
    if problems:
        raise ChaplyginError(
            f"initial multipliers: for {system.name} μ(0) does not follow from constants c ("
            + "; ".join(problems)
            + "); give multipliers=[μ(0), ...], or "
            "constants='match' to start with μ(0) = 0."
        )
    exprs = system.integrated_multipliers(c)
    return np.array([_evaluate(system, exprs[m].xreplace(system._to_sym), q, qd, params, t0) for m in names])


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
) -> Trajectory:
    """Integrate ``compiled.rhs`` from ``y0`` and sample it.

    ``c`` or ``numba`` backend with ``method="DOP853"``: the compiled loop of
    :mod:`chaplygin._ckernel` or :mod:`chaplygin._loop` (the whole integration in C or numba).  ``jax``
    backend with ``"DOP853"``, ``"RK45"`` or ``"RK23"``: diffrax
    (:mod:`chaplygin.jaxbackend`).  Otherwise: SciPy's stepper class driven
    step by step, with dense output where a sample falls.
    """
    times = np.linspace(t_span[0], t_span[1], samples)
    if compiled.backend == "c" and method == "DOP853":
        from ._loop import integrate_dop853

        res = integrate_dop853(compiled, t_span, y0, p, times, rtol=rtol, atol=atol, max_step=max_step)
        return _trajectory(compiled, res.t, res.y, p, params, res.status, res.message, res.n_rhs, g)
    if compiled.backend == "numba" and method == "DOP853":
        from ._loop import integrate_dop853, loop_model

        looped = loop_model(compiled)
        res = integrate_dop853(looped, t_span, y0, p, times, rtol=rtol, atol=atol, max_step=max_step)
        return _trajectory(looped, res.t, res.y, p, params, res.status, res.message, res.n_rhs, g)
    if compiled.backend == "jax" and method in ("DOP853", "RK45", "RK23"):
        from .jaxbackend import solve

        res = solve(compiled, t_span, y0, p, times, rtol=rtol, atol=atol, method=method, max_step=max_step)
        return _trajectory(compiled, res.t, res.y, p, params, res.status, res.message, res.n_rhs, g)

    import scipy.integrate as si

    rhs = compiled.rhs
    count = [0]

    def fun(t: float, y: np.ndarray) -> np.ndarray:
        count[0] += 1
        try:
            dy = rhs(t, y, p)
        except (np.linalg.LinAlgError, ZeroDivisionError, ValueError, ArithmeticError) as exc:
            raise _StepFailure(f"the right-hand side failed at t = {t:.6g}: {exc}") from None
        if not np.all(np.isfinite(dy)):
            raise _StepFailure(f"the solution blew up (non-finite derivative) at t = {t:.6g}")
        return dy

    out = np.empty((samples, len(y0)))
    status, message, k = "success", "", 0
    try:
        stepper = getattr(si, method)(fun, t_span[0], y0, t_span[1], rtol=rtol, atol=atol, max_step=max_step)
        out[0], k = y0, 1
        while k < samples:
            msg = stepper.step()
            if stepper.status == "failed":
                status, message = "failed", f"the integrator stopped at t = {stepper.t:.6g}: {msg}"
                break
            if times[k] > stepper.t and stepper.status != "finished":
                continue  # no sample in this step: skip the dense output (extra evaluations)
            dense = stepper.dense_output()
            while k < samples and times[k] <= stepper.t:
                out[k] = dense(times[k])
                k += 1
            if stepper.status == "finished" and k < samples:
                out[k:] = dense(times[k:]).T
                k = samples
    except _StepFailure as exc:
        status, message = "failed", str(exc)
    times, out = times[:k], out[:k]
    if status == "success":
        message = f"reached t = {t_span[1]:g}"
    return _trajectory(compiled, times, out, p, params, status, message, count[0], g)


def _trajectory(
    compiled: CompiledModel, times: np.ndarray, ys: np.ndarray, p: np.ndarray,
    params: dict[str, float], status: str, message: str, evaluations: int, g: int,
) -> Trajectory:
    layout = compiled.layout
    n = len(layout.coordinates)
    if compiled.backend == "c":  # every sample in one call
        obs = compiled.module.observe_many(times, ys, p)
    else:
        obs = np.array([compiled.observe(t, y, p) for t, y in zip(times, ys)]).reshape(len(times), compiled.n_observed)
    n_react = len(layout.reactions)
    velocities = obs[:, obs.shape[1] - n :] if len(times) else np.empty((0, n))
    residual = np.max(np.abs(obs[:, 1 : 1 + g]), axis=1) if g and len(times) else np.zeros(len(times))
    multipliers = {name: obs[:, 1 + g + j] for j, name in enumerate(layout.reactions)} if n_react else {}
    base = n + len(layout.velocities)
    multipliers.update({name: ys[:, base + j] for j, name in enumerate(layout.multipliers)})
    return Trajectory(
        layout.model, layout.form, compiled.backend, times,
        {name: ys[:, i] for i, name in enumerate(layout.coordinates)},
        {name + "'": velocities[:, i] for i, name in enumerate(layout.coordinates)},
        multipliers, obs[:, 0] if len(times) else np.empty(0), residual,
        status, message, dict(params), evaluations,
    )
