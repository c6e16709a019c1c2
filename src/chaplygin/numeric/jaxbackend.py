"""The ``jax`` backend: the generated functions as JAX code, integrated with diffrax.

Optional: ``pip install chaplygin[jax]`` (jax, jaxlib, diffrax).  Importing
this module turns on JAX's 64-bit mode (``jax_enable_x64``), process-wide:
the tolerances of the other backends (``rtol = 1e-10``) are meaningless in
float32.

The functions are built from the same ``M·x = F``, velocities, energy and
constraint residuals as :mod:`chaplygin.numeric.codegen`'s generated module, with the
same :class:`~chaplygin.numeric.codegen.Layout` (``(t, y, p)`` argument order), by
``sympy.lambdify(..., modules="jax", cse=True)`` (exact numbers printed as their doubles,
:func:`chaplygin.numeric._printing.number`); ``x = solve(M, F)`` is
``jnp.linalg.solve``.  :func:`compile_jax` returns a
:class:`~chaplygin.numeric.codegen.CompiledModel` whose ``rhs`` and ``observe`` take
and return NumPy arrays (jitted; for host code and SciPy steppers) and whose
module also holds the traceable ``rhs_jax`` and ``observe_jax``.

Integration (:func:`solve`, :func:`solve_ensemble`) is diffrax's
``diffeqsolve``: ``Dopri8`` for ``method="DOP853"`` (``Dopri5`` for
``"RK45"``, ``Bosh3`` for ``"RK23"``), a ``PIDController`` with the same
``rtol``/``atol`` (an I-controller, safety 0.9, factors 0.2 … 10, like
SciPy's), ``jax.jit``, and ``jax.vmap`` over initial states for ensembles.
It runs on a GPU when JAX sees one.  Dopri8 is Prince & Dormand's 8(7) pair,
not Hairer's DOP853 8(5,3): both meet the tolerance, but their steps differ,
so results agree with SciPy's to the tolerance, not to round-off.

A failure is a status, not an exception: a step below ``10·spacing(t1)``
(``dt_min_reached``; a non-finite derivative from a blow-up or a singular
mass matrix makes diffrax shrink the step until then) or ``max_steps``
reached, with the samples before the failure.
"""

from __future__ import annotations

import hashlib
import inspect
import math
import re
from collections.abc import Callable
from types import ModuleType
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
import sympy as sp

from chaplygin.core._symbols import TIME
from chaplygin.errors import ChaplyginError
from chaplygin.numeric._ckernel import CompiledModel
from chaplygin.numeric._layout import state_symbols
from chaplygin.numeric._printing import number
from chaplygin.numeric.codegen import monitored

try:
    import jax
    import jax.numpy as jnp
except ImportError as exc:  # pragma: no cover - exercised only without the extra
    raise ChaplyginError("the 'jax' backend needs jax and diffrax: pip install 'chaplygin[jax]'") from exc

jax.config.update("jax_enable_x64", True)

if TYPE_CHECKING:
    from chaplygin.models.equations import Equations

__all__ = ["SOLVERS", "JaxResult", "compile_jax", "devices", "solve", "solve_ensemble"]

#: SciPy method name → diffrax solver class name
SOLVERS = {"DOP853": "Dopri8", "RK45": "Dopri5", "RK23": "Bosh3"}
#: right-hand-side evaluations per attempted step (FSAL solvers)
_STAGES = {"Dopri8": 13, "Dopri5": 6, "Bosh3": 3}


def devices() -> list[str]:
    """The devices JAX computes on, e.g. ``["cpu:0"]`` or ``["cuda:0"]``."""
    return [f"{d.platform}:{d.id}" for d in jax.devices()]


# ------------------------------------------------------------------ code
def _expressions(eqs: Equations) -> tuple[Any, list[sp.Expr], list[sp.Symbol], list[sp.Symbol], int, int]:
    """Layout, ``[*M, *F, *velocities, energy, *residuals]`` in ``(t, y, p)`` symbols, dims.

    The same expressions as ``codegen._source`` (keep the two in step; the
    tests compare this backend's ``observe`` with the numpy backend's).
    """
    s = eqs.system
    layout, to_num, velocities, k = state_symbols(eqs)
    full_xd = {s._vars.xd[i]: velocities[i] for i in range(s.n)}
    energy = monitored(s, s._T, s._U, s._vars.xd).xreplace(full_xd)
    residual = list(s._f.xreplace(full_xd))  # f at the full velocities (A holds q̇ where f is nonlinear)
    exprs = [*eqs._M, *eqs._F, *velocities, energy, *residual]
    n_y, n_p = len(layout.state), len(layout.parameters)
    ys = [sp.Symbol(f"_y{i}") for i in range(n_y)]
    ps = [sp.Symbol(f"_p{j}") for j in range(n_p)]
    t = sp.Symbol("_t")
    # to_num sends the system's symbols to y[i] / p[j]; send those to plain symbols
    plain = {}
    for value in to_num.values():
        base, (index,) = value.base.label.name, value.indices
        plain[value] = (ys if base == "y" else ps)[int(index)]
    exprs = [(sp.S.Zero + e).xreplace(to_num).xreplace(plain).xreplace({TIME: t}) for e in exprs]
    return layout, exprs, [t, *ys], ps, eqs._M.shape[0], k


def _printer() -> type:
    """SymPy's JAX printer, exact numbers printed as their doubles (:func:`~chaplygin.numeric._printing.number`):
    JAX converts an integer literal to int64 and fails on one beyond 64 bits."""
    from sympy.printing.numpy import JaxPrinter

    class Printer(JaxPrinter):
        def _print_Integer(self, expr: Any) -> str:
            return number(int(expr), 1, False)

        def _print_Rational(self, expr: Any) -> str:
            return number(int(expr.p), int(expr.q), False)

    return Printer


class _Fields(NamedTuple):
    rhs: Callable[..., Any]
    observe: Callable[..., Any]


def _build(eqs: Equations) -> tuple[Any, _Fields, dict[str, int], str]:
    layout, exprs, (t, *ys), ps, dim, k = _expressions(eqs)
    f = sp.lambdify([t, ys, ps], exprs, modules="jax", printer=_printer(), cse=True, docstring_limit=0)
    n = len(layout.coordinates)
    g = eqs.system.g
    n_react = len(layout.reactions)
    n_m = dim * dim

    def values(tt: Any, y: Any, p: Any) -> Any:
        y = jnp.asarray(y, dtype=jnp.float64)
        out = f(tt, y, p)
        return jnp.stack([jnp.asarray(v, dtype=jnp.float64) for v in out])

    def rhs_jax(tt: Any, y: Any, p: Any) -> Any:
        v = values(tt, y, p)
        M = v[:n_m].reshape(dim, dim)
        x = jnp.linalg.solve(M, v[n_m : n_m + dim])
        return jnp.concatenate([v[n_m + dim : n_m + dim + n], x[:k]])

    def observe_jax(tt: Any, y: Any, p: Any) -> Any:
        v = values(tt, y, p)
        base = n_m + dim + n
        parts = [v[base : base + 1 + g]]
        if n_react:
            M = v[:n_m].reshape(dim, dim)
            x = jnp.linalg.solve(M, v[n_m : n_m + dim])
            parts.append(x[dim - n_react :])
        parts.append(v[n_m + dim : base])
        return jnp.concatenate(parts)

    dims = {"DIM": dim, "N": n, "K": k, "N_OBSERVED": 1 + g + n_react + n, "G": g}
    return layout, _Fields(rhs_jax, observe_jax), dims, inspect.getsource(f)


_MODELS: dict[str, CompiledModel] = {}


def compile_jax(eqs: Equations) -> CompiledModel:
    """The JAX functions of ``eqs`` as a :class:`CompiledModel` (backend ``"jax"``).

    ``rhs``/``observe`` take and return NumPy arrays; ``module.rhs_jax`` and
    ``module.observe_jax`` are the traceable functions (for ``jit``, ``vmap``,
    ``grad``).  Models are kept per generated source, so that the solvers
    jitted for one (``solve``, ``solve_ensemble``) serve later calls too.
    """
    layout, fields, dims, source = _build(eqs)
    stable = re.sub(r"_Dummy_\d+", "_Dummy", source)  # lambdify numbers its argument names
    key = hashlib.sha256(f"{stable}\n{layout!r}\n{sorted(dims.items())}".encode()).hexdigest()
    if key in _MODELS:  # same functions: keep the jitted solvers compiled for them
        return _MODELS[key]
    rhs_jit = jax.jit(fields.rhs)
    observe_jit = jax.jit(fields.observe)
    module = ModuleType(f"chaplygin_jax_{eqs.model}_{eqs.form}")
    module.__doc__ = f"JAX functions (sympy.lambdify) of {layout.describe()}"
    vars(module).update(
        rhs=lambda t, y, p: np.asarray(rhs_jit(t, y, p)),
        observe=lambda t, y, p: np.asarray(observe_jit(t, y, p)),
        rhs_jax=fields.rhs,
        observe_jax=fields.observe,
        source=source,
        **dims,
    )
    model = CompiledModel(layout, module, "jax")
    model._solvers = {}  # type: ignore[attr-defined]
    _MODELS[key] = model
    return model


# ------------------------------------------------------------------ integration
class JaxResult(NamedTuple):
    """``(t, y, status, message, n_rhs)`` like :class:`chaplygin.numeric._loop.LoopResult`."""

    t: np.ndarray
    y: np.ndarray
    status: str
    message: str
    n_rhs: int
    code: int = 0
    n_steps: int = 0


def _diffrax() -> Any:
    try:
        import diffrax
    except ImportError as exc:  # pragma: no cover
        raise ChaplyginError("the 'jax' backend needs diffrax: pip install 'chaplygin[jax]'") from exc
    return diffrax


def _code(diffrax: Any, result: Any) -> Any:
    """diffrax's result → the loop's status codes (0 ok, 1 step underflow, 4 max steps, 6 other)."""
    R = diffrax.RESULTS
    return jnp.where(
        result == R.successful,
        0,
        jnp.where(result == R.dt_min_reached, 1, jnp.where(result == R.max_steps_reached, 4, 6)),
    )


def _solver_fn(model: CompiledModel, method: str, max_steps: int, final_only: bool) -> Callable[..., Any]:
    """A jitted ``(t0, t1, y0, p, ts, rtol, atol, dtmax, dtmin) → (ys, t_last, y_last, code, steps)``."""
    key = (method, max_steps, final_only)
    cache = model._solvers  # type: ignore[attr-defined]
    if key in cache:
        return cache[key]
    diffrax = _diffrax()
    solver = getattr(diffrax, SOLVERS[method])()
    term = diffrax.ODETerm(lambda t, y, args: model.module.rhs_jax(t, y, args))

    def one(t0: Any, t1: Any, y0: Any, p: Any, ts: Any, rtol: Any, atol: Any, dtmax: Any, dtmin: Any) -> Any:
        controller = diffrax.PIDController(rtol=rtol, atol=atol, dtmax=dtmax, dtmin=dtmin, force_dtmin=False)
        subs = (
            [diffrax.SubSaveAt(t1=True)]
            if final_only
            else [diffrax.SubSaveAt(ts=ts), diffrax.SubSaveAt(t1=True)]
        )
        sol = diffrax.diffeqsolve(
            term,
            solver,
            t0,
            t1,
            None,
            y0,
            args=p,
            saveat=diffrax.SaveAt(subs=subs),
            stepsize_controller=controller,
            max_steps=max_steps,
            throw=False,
            adjoint=diffrax.ForwardMode(),
        )
        ys = None if final_only else sol.ys[0]
        t_last, y_last = sol.ts[-1][-1], sol.ys[-1][-1]
        return ys, t_last, y_last, _code(diffrax, sol.result), sol.stats["num_steps"]

    fn = jax.jit(one)
    cache[key] = fn
    return fn


def _settings(t0: float, t1: float, rtol: float, atol: Any, max_step: float) -> tuple[Any, ...]:
    if not t1 > t0:
        raise ChaplyginError(f"t_span: the end time {t1:g} must be after the start {t0:g}.")
    rtol = max(float(rtol), 100 * float(np.finfo(float).eps))
    dtmax = float(max_step) if math.isfinite(max_step) else None
    dtmin = 10.0 * float(np.spacing(max(abs(t0), abs(t1), 1.0)))
    return rtol, jnp.asarray(atol, dtype=jnp.float64), dtmax, dtmin


def _message(code: int, t: float, method: str, max_steps: int) -> str:
    if code == 1:
        return (
            f"the integrator stopped at t = {t:.6g}: the step size fell below the spacing of "
            f"floating-point numbers (the solution blows up, or the derivative is not finite "
            f"there: a singular mass matrix?)"
        )
    if code == 4:
        return f"the integrator stopped at t = {t:.6g}: more than {max_steps} steps"
    return f"the integrator stopped at t = {t:.6g} ({SOLVERS[method]} failed)"


def solve(
    model: CompiledModel,
    t_span: tuple[float, float],
    y0: np.ndarray,
    p: np.ndarray,
    times: np.ndarray,
    *,
    rtol: float = 1e-10,
    atol: float = 1e-12,
    method: str = "DOP853",
    max_step: float = np.inf,
    max_steps: int = 1_000_000,
) -> JaxResult:
    """Integrate one initial state with diffrax, sampled at ``times`` (within ``t_span``)."""
    if method not in SOLVERS:
        raise ChaplyginError(f"method {method!r}: the jax backend has {', '.join(SOLVERS)}.")
    t0, t1 = float(t_span[0]), float(t_span[1])
    rtol, atol_j, dtmax, dtmin = _settings(t0, t1, rtol, atol, max_step)
    fn = _solver_fn(model, method, int(max_steps), False)
    ys, t_last, _y_last, code, steps = fn(
        t0,
        t1,
        jnp.asarray(y0, dtype=jnp.float64),
        jnp.asarray(p, dtype=jnp.float64),
        jnp.asarray(times, dtype=jnp.float64),
        rtol,
        atol_j,
        dtmax,
        dtmin,
    )
    ys = np.asarray(ys)
    code, t_last, steps = int(code), float(t_last), int(steps)
    times = np.asarray(times, dtype=float)
    reached = int(np.count_nonzero(times <= t_last)) if code else len(times)
    n_rhs = 1 + 2 + _STAGES[SOLVERS[method]] * steps
    if code == 0:
        return JaxResult(times, ys, "success", f"reached t = {t1:g}", n_rhs, 0, steps)
    return JaxResult(
        times[:reached],
        ys[:reached],
        "failed",
        _message(code, t_last, method, max_steps),
        n_rhs,
        code,
        steps,
    )


def solve_ensemble(
    model: CompiledModel,
    t_span: tuple[float, float],
    Y0: np.ndarray,
    P: np.ndarray,
    *,
    times: np.ndarray | None = None,
    rtol: float = 1e-10,
    atol: float = 1e-12,
    method: str = "DOP853",
    max_step: float = np.inf,
    max_steps: int = 1_000_000,
) -> dict[str, np.ndarray]:
    """``jax.vmap`` of the solve over the rows of ``Y0`` and ``P``.

    Returns the arrays of :func:`chaplygin.numeric._loop.ensemble_dop853`: ``t``,
    ``y`` (the last point reached), ``observed``, ``code``, ``n_rhs``, and
    ``samples`` when ``times`` is given.
    """
    if method not in SOLVERS:
        raise ChaplyginError(f"method {method!r}: the jax backend has {', '.join(SOLVERS)}.")
    t0, t1 = float(t_span[0]), float(t_span[1])
    rtol, atol_j, dtmax, dtmin = _settings(t0, t1, rtol, atol, max_step)
    final_only = times is None
    ts = jnp.zeros(0) if times is None else jnp.asarray(times, dtype=jnp.float64)
    jitted = _ensemble_jit(model, t0, t1, final_only, method, int(max_steps))
    ys, t_last, y_last, code, steps, obs = jitted(
        jnp.asarray(Y0, dtype=jnp.float64),
        jnp.asarray(P, dtype=jnp.float64),
        ts,
        rtol,
        atol_j,
        dtmax,
        dtmin,
    )
    steps = np.asarray(steps)
    out = {
        "t": np.asarray(t_last),
        "y": np.asarray(y_last),
        "observed": np.asarray(obs),
        "code": np.asarray(code).astype(np.int64),
        "n_rhs": (3 + _STAGES[SOLVERS[method]] * steps).astype(np.int64),
    }
    if times is not None:
        samples = np.asarray(ys).copy()
        samples[~np.isfinite(samples)] = np.nan
        out["samples"] = samples
    return out


def _ensemble_jit(
    model: CompiledModel, t0: float, t1: float, final_only: bool, method: str, max_steps: int
) -> Callable[..., Any]:
    """``jit(vmap(solve))`` (cached per model, method, ``max_steps`` and time span)."""
    cache = model._solvers  # type: ignore[attr-defined]
    full = ("ensemble", method, max_steps, final_only, t0, t1)
    if full in cache:
        return cache[full]
    one = _solver_fn(model, method, max_steps, final_only)
    observe = model.module.observe_jax

    def batch(Y0: Any, P: Any, ts: Any, rtol: Any, atol: Any, dtmax: Any, dtmin: Any) -> Any:
        def single(y0: Any, p: Any) -> Any:
            ys, t_last, y_last, code, steps = one(t0, t1, y0, p, ts, rtol, atol, dtmax, dtmin)
            return ys, t_last, y_last, code, steps, observe(t_last, y_last, p)

        return jax.vmap(single)(Y0, P)

    fn = jax.jit(batch)
    cache[full] = fn
    return fn
