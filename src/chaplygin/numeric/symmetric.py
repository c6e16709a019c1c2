"""Symmetric fixed-step integrators for the true (Chetaev) motion: Gauss–Legendre collocation.

Why
---
Explicit Runge–Kutta methods, DOP853 included, make an energy error that
grows linearly with time: over long runs of a conservative nonholonomic system
the energy drifts however small the tolerance.  Nonholonomic systems have no
symplectic structure to preserve, but those with homogeneous (linear in the
velocities, time-independent) constraints are **reversible**: with
``ρ(q, q̇) = (q, −q̇)`` the flow satisfies ``ρ ∘ φ_t = φ_{−t} ∘ ρ``.  A symmetric
one-step method applied to a ρ-reversible differential equation gives a
ρ-reversible map (Hairer, Lubich & Wanner, *Geometric Numerical Integration*,
2nd ed., Springer 2006, Thm. V.1.5), and for reversible integrable (or
near-integrable) systems a reversible method keeps the errors in the actions,
hence in the energy, bounded and of the size of the local error over very long
times, with no drift (ibid., ch. XI).  McLachlan & Perlmutter, "Integrators for
nonholonomic mechanical systems", *J. Nonlinear Sci.* 16 (2006) 283–328, show
the same for nonholonomic test problems — the rolling disk and the contact
oscillator among them — and that reversibility, not a discrete variational
structure, is what matters for the energy.

What is integrated
------------------
The reduced Chetaev equations, Voronets' form (Chaplygin's when the user asks
for ``model="chaplygin"``): the state is every coordinate ``q`` and the
independent velocities ``u = q̇_σ``,

    q̇ = B(q) u   (the dependent velocities from the constraints),
    u̇ = a(q, u)  (Voronets' / Chaplygin's equations solved),

an ordinary differential equation with no algebraic part, so the constraints
hold **exactly** (to round-off) at every step: the dependent velocities are
always computed from them.  For homogeneous constraints ``B(q)u`` is odd and
``a(q, u)`` even in ``u``: the equation is ρ-reversible with
``ρ(q, u) = (q, −u)``.  A run of ``model="chetaev"`` integrates these
equations and then evaluates the Chetaev model (the Lagrange–d'Alembert
equations with multipliers) at every sample: the trajectory has the multipliers
λ like any other Chetaev run.

Methods
-------
s-stage Gauss–Legendre collocation (HLW, §II.1.3): ``"midpoint"`` (s = 1, the
implicit midpoint rule, order 2), ``"gauss4"`` (s = 2, order 4) and
``"gauss6"`` (s = 3, order 6).  They are symmetric, and — being linear in the
state — compatible with the linear map ρ, hence reversible.  (A discrete
Lagrange–d'Alembert scheme was not chosen: it needs a discrete Lagrangian and a
discrete constraint per system and reaches order 2 only, while collocation of
the reduced equations reaches any even order with no system-specific work.)

The stage equations ``Z_i = h Σ_j a_ij f(t + c_j h, y + Z_j)`` are solved by a
simplified Newton iteration (the Jacobian of ``f`` at the start of each step,
by forward differences; the ``sn × sn`` iteration matrix ``I − h A ⊗ J``
factored once per step) **to round-off**: the iteration stops when the
increment falls below the floating-point spacing or stops decreasing there
(the criterion of Hairer's GNI codes), otherwise symmetry is lost and the
energy drifts after all.  The new state is ``y + h Σ_i b_i f(Y_i)`` summed with
compensated (Kahan) summation, so that round-off grows like a random walk
(Hairer, McLachlan & Razakarivony, "Achieving Brouwer's law with implicit
Runge–Kutta methods", *BIT* 48 (2008) 231–243).

Step size
---------
Fixed, given by ``step``: the step used is the largest ``h ≤ step`` that puts
every output sample on the grid of steps (``h = Δ / ⌈Δ / step⌉`` with ``Δ`` the
spacing of the samples), so that samples are steps of the method, not
interpolations, and keep its order.

How it runs
-----------
With ``backend="numba"`` the stepping loop is compiled once per installation,
not once per model, like the DOP853 loop (:mod:`chaplygin.numeric._loop`): its
kernels take the model tuple ``m = (address, DIM, N, N_OBSERVED)`` of
:func:`chaplygin.numeric._loop.loop_model` and call the model's ``fill``
through its address; their source, which names no model, is written once to
the code cache (:func:`shared`) and cached there by numba.  The first run of
the installation compiles them (some seconds); a new model then costs only its
``fill`` and the small C wrapper the DOP853 loop uses too.  With
``backend="numpy"`` the very same loop runs as plain Python over the generated
plain-Python ``fill`` (milliseconds per step: for short runs).
Failures — the Newton iteration not converging, a singular iteration or mass
matrix, a non-finite derivative, an error inside the generated code — end a run
with ``status == "failed"``, a message, and the samples up to that point.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from chaplygin.errors import ChaplyginError
from chaplygin.models import registry
from chaplygin.numeric import targets
from chaplygin.numeric._loop import (
    EPS,
    _k_call,
    _k_eval,
    _k_fill,
    _k_pivot,
    _k_solve,
    _message,
    import_shared,
    kernel_lines,
    loop_model,
    shared_source,
)
from chaplygin.numeric._loop import STATUS as _LOOP_STATUS
from chaplygin.numeric._loop import (
    in_a_thread as _in_a_thread,
)
from chaplygin.numeric.cache import import_source
from chaplygin.numeric.codegen import CompiledModel

if TYPE_CHECKING:
    pass

__all__ = [
    "METHODS",
    "STATUS",
    "TRUE_MODELS",
    "SymmetricResult",
    "extrapolation",
    "grid",
    "integrate_symmetric",
    "shared",
    "stepping_module",
    "tableau",
]

#: the fixed-step symmetric methods, by name → number of Gauss–Legendre stages
METHODS: dict[str, int] = {"midpoint": 1, "gauss4": 2, "gauss6": 3}
#: the models they integrate (the true motion)
TRUE_MODELS = tuple(m.name for m in registry.MODELS.values() if m.is_true_motion)
#: Newton iterations allowed per step before a run fails
MAX_ITERATIONS = 50
#: a run may take at most this many steps
MAX_STEPS = 10**10

#: kernel status codes → meaning (0, 2, 3, 5 come from the right-hand-side kernels shared with
#: chaplygin.numeric._loop, so they mean what they mean there)
STATUS = {
    **{code: _LOOP_STATUS[code] for code in (0, 2, 3, 5)},
    7: "the Newton iteration did not converge",
    8: "singular Newton matrix",
}


def tableau(method: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Butcher tableau ``(A, b, c)`` of a Gauss–Legendre method (HLW, Table II.1.3 / II.1.4).

    Parameters
    ----------
    method : {"midpoint", "gauss4", "gauss6"}

    Returns
    -------
    A : ndarray, shape (s, s)
    b, c : ndarray, shape (s,)
    """
    if method not in METHODS:
        raise ChaplyginError(f"method {method!r} is not a symmetric method; they are {', '.join(METHODS)}.")
    s = METHODS[method]
    if s == 1:
        return np.array([[0.5]]), np.array([1.0]), np.array([0.5])
    if s == 2:
        r = math.sqrt(3.0) / 6.0
        return (
            np.array([[0.25, 0.25 - r], [0.25 + r, 0.25]]),
            np.array([0.5, 0.5]),
            np.array([0.5 - r, 0.5 + r]),
        )
    r = math.sqrt(15.0)
    return (
        np.array(
            [
                [5 / 36, 2 / 9 - r / 15, 5 / 36 - r / 30],
                [5 / 36 + r / 24, 2 / 9, 5 / 36 - r / 24],
                [5 / 36 + r / 30, 2 / 9 + r / 15, 5 / 36],
            ]
        ),
        np.array([5 / 18, 4 / 9, 5 / 18]),
        np.array([0.5 - r / 10, 0.5, 0.5 + r / 10]),
    )


# ------------------------------------------------------------------ kernels
# Plain Python whose source is compiled by numba in the shared module (see ``shared``), where
# ``_k_eval`` calls a model's ``fill`` through its address in the model tuple ``m`` (the
# DOP853 loop's kernels, chaplygin.numeric._loop), or appended to a model's generated numpy
# module (``stepping_module``) and run as Python, where ``fill`` is a global and ``m`` gives
# only the sizes.  They are never called from here.
_GL_EPS = EPS


def _gl_lu(G, piv):  # pragma: no cover - compiled, or run as Python
    """LU factorisation of ``G`` with partial pivoting, in place; 8 if singular."""
    n = G.shape[0]
    for c in range(n):
        k, big = _k_pivot(G, c)  # defined where the kernels run
        piv[c] = k
        if big == 0.0:
            return 8
        if k != c:
            for j in range(n):
                tmp = G[c, j]
                G[c, j] = G[k, j]
                G[k, j] = tmp
        for r in range(c + 1, n):
            G[r, c] /= G[c, c]
            factor = G[r, c]
            for j in range(c + 1, n):
                G[r, j] -= factor * G[c, j]
    return 0


def _gl_lu_solve(G, piv, x):  # pragma: no cover - compiled, or run as Python
    """``x ← G⁻¹ x`` with the factors of :func:`_gl_lu`, in place."""
    n = G.shape[0]
    for c in range(n):
        k = piv[c]
        if k != c:
            tmp = x[c]
            x[c] = x[k]
            x[k] = tmp
    for r in range(n):
        acc = x[r]
        for j in range(r):
            acc -= G[r, j] * x[j]
        x[r] = acc
    for r in range(n - 1, -1, -1):
        acc = x[r]
        for j in range(r + 1, n):
            acc -= G[r, j] * x[j]
        x[r] = acc / G[r, r]


def _gl_newton_matrix(m, t, y, p, h, A, f0, f1, J, G, piv, Ys, wM, wb, wV, wO, stats):  # pragma: no cover
    """``G ← LU(I − h A ⊗ J)`` with ``J = ∂f/∂y`` at ``(t, y)`` by forward differences.

    Also leaves ``f0 = f(t, y)``.  Returns 0, or a status code (2, 3, 5, 8);
    a failed evaluation's state is left in ``Ys``.
    """
    n = y.size
    s = A.shape[0]
    for i in range(n):
        Ys[i] = y[i]
    code = _k_eval(m, t, Ys, p, f0, wM, wb, wV, wO)
    stats[0] += 1
    if code != 0:
        return code
    for j in range(n):
        Ys[j] = y[j] + math.sqrt(_GL_EPS * max(1e-5, abs(y[j])))
        delta = Ys[j] - y[j]
        code = _k_eval(m, t, Ys, p, f1, wM, wb, wV, wO)
        stats[0] += 1
        if code != 0:
            return code
        Ys[j] = y[j]
        for i in range(n):
            J[i, j] = (f1[i] - f0[i]) / delta
    for a in range(s):
        for i in range(n):
            for e in range(s):
                for j in range(n):
                    G[a * n + i, e * n + j] = -h * A[a, e] * J[i, j]
            G[a * n + i, a * n + i] += 1.0
    return _gl_lu(G, piv)


def _gl_stages(m, t, y, p, h, A, c, G, piv, Z, F, Ys, r, max_iter, wM, wb, wV, wO, stats):  # pragma: no cover
    """Simplified Newton for the stage increments ``Z`` (from the guess in ``Z``), to round-off.

    Stops when the scaled increment is below the floating-point spacing, or
    no longer decreases once below ``1000·eps`` (Hairer's GNI criterion).
    ``F`` holds ``f`` at the stages of the last iterate.  Returns ``(code,
    iterations, t_fail)``: 0 when converged, 7 when not in ``max_iter``
    iterations, or the evaluation's code (2, 3, 5) and where it arose (the
    stage state is left in ``Ys``).
    """
    n = y.size
    s = A.shape[0]
    previous = math.inf
    iterations = 0
    while iterations < max_iter:
        iterations += 1
        for a in range(s):
            for i in range(n):
                Ys[i] = y[i] + Z[a, i]
            code = _k_eval(m, t + c[a] * h, Ys, p, F[a], wM, wb, wV, wO)
            stats[0] += 1
            if code != 0:
                return code, iterations, t + c[a] * h
        for a in range(s):
            for i in range(n):
                acc = 0.0
                for e in range(s):
                    acc += A[a, e] * F[e, i]
                r[a * n + i] = h * acc - Z[a, i]
        _gl_lu_solve(G, piv, r)
        size = 0.0
        for a in range(s):
            for i in range(n):
                Z[a, i] += r[a * n + i]
                size = max(size, abs(r[a * n + i]) / max(1.0, abs(y[i])))
        if not math.isfinite(size):
            return 7, iterations, t
        if size <= _GL_EPS or (size >= previous and size <= 1e3 * _GL_EPS):
            return 0, iterations, t
        previous = size
    return 7, iterations, t


def _gl_integrate(m, t0, h, per_sample, y0, p, A, bw, c, E, max_iter, out, stats):  # pragma: no cover
    """Gauss–Legendre steps of size ``h`` from ``(t0, y0)``; ``out[k] ← y(t0 + k·per_sample·h)``.

    The first Newton guess continues the previous step's collocation
    polynomial (``Z ← E·Z``, see :func:`extrapolation`).  The Newton matrix is
    kept from step to step and refreshed when a step needs more than one
    iteration more than the step after the last refresh, or when a step with a
    kept matrix fails to converge (the step is then tried again).  ``stats``
    (int64, 6) receives the right-hand-side evaluations, the Newton iterations,
    the most iterations of a step, the Jacobians computed and the steps taken; where another
    thread sets ``stats[5]`` (Ctrl-C), the run stops at its next step with code 10.
    Returns ``(filled, code, t_fail, y_fail)``: ``filled`` rows of ``out``
    were written; ``code`` is 0, or a status code and the point where it arose.
    """
    n = y0.size
    s = bw.size
    ns = n * s
    wM = np.empty((m[1], m[1]))
    wb = np.empty(m[1])
    wV = np.empty(m[2])
    wO = np.empty(m[3])
    y = y0.copy()
    comp = np.zeros(n)
    f0 = np.empty(n)
    f1 = np.empty(n)
    J = np.empty((n, n))
    G = np.empty((ns, ns))
    piv = np.zeros(ns, dtype=np.int64)
    Z = np.empty((s, n))
    Zold = np.zeros((s, n))
    F = np.empty((s, n))
    Ys = np.empty(n)
    r = np.empty(ns)
    for i in range(n):
        out[0, i] = y0[i]
    step = 0
    refresh = True
    fresh = False
    baseline = 0
    for k in range(1, out.shape[0]):
        for _ in range(per_sample):
            t = t0 + step * h
            if stats[5] != 0:
                return k, 10, t, y
            while True:
                if refresh:
                    code = _gl_newton_matrix(m, t, y, p, h, A, f0, f1, J, G, piv, Ys, wM, wb, wV, wO, stats)
                    stats[3] += 1
                    if code != 0:
                        return k, code, t, Ys
                    refresh = False
                    fresh = True
                for a in range(s):
                    for i in range(n):
                        if step == 0:
                            Z[a, i] = c[a] * h * f0[i]
                        else:
                            acc = 0.0
                            for e in range(s):
                                acc += E[a, e] * Zold[e, i]
                            Z[a, i] = acc
                code, iterations, t_fail = _gl_stages(
                    m, t, y, p, h, A, c, G, piv, Z, F, Ys, r, max_iter, wM, wb, wV, wO, stats
                )
                stats[1] += iterations
                stats[2] = max(stats[2], iterations)
                if code == 0:
                    break
                if fresh:
                    return k, code, t_fail, Ys
                refresh = True  # a kept matrix may be too stale: refresh, try the step again
            if fresh:
                baseline = iterations
                fresh = False
            elif iterations > baseline + 1:
                refresh = True
            # y ← y + h Σ b_i f(Y_i), compensated summation
            for i in range(n):
                acc = 0.0
                for a in range(s):
                    acc += bw[a] * F[a, i]
                    Zold[a, i] = Z[a, i]
                inc = h * acc + comp[i]
                new = y[i] + inc
                comp[i] = inc - (new - y[i])
                y[i] = new
            step += 1
            stats[4] = step
        for i in range(n):
            out[k, i] = y[i]
    return out.shape[0], 0, t0 + step * h, y


def extrapolation(c: np.ndarray) -> np.ndarray:
    """``E`` with ``Z_next ≈ E · Z``: the collocation polynomial continued over the next step.

    The collocation polynomial of a step from ``y`` is ``u(t + θh) = y + Σ_j
    L_j(θ) Z_j`` (``L_j`` the Lagrange basis on the nodes ``0, c_1 … c_s``) and
    the new state is ``u(t + h)``; so ``E[i, j] = L_j(1 + c_i) − L_j(1)``, a
    guess accurate to ``O(h^{s+1})`` (Hairer, Lubich & Wanner, §VIII.6.1).
    """
    nodes = np.concatenate([[0.0], c])

    def basis(j: int, x: float) -> float:
        others = np.delete(nodes, j)
        return float(np.prod((x - others) / (nodes[j] - others)))

    s = len(c)
    return np.array([[basis(j + 1, 1.0 + c[i]) - basis(j + 1, 1.0) for j in range(s)] for i in range(s)])


_GL_KERNELS = (_gl_lu, _gl_lu_solve, _gl_newton_matrix, _gl_stages, _gl_integrate)


@functools.cache
def shared() -> ModuleType:
    """The compiled stepping kernels, shared by every model: compiled by numba once per installation.

    Their source imports the DOP853 loop's address call (``_k_call``) and holds its
    right-hand-side kernels; like the DOP853 loop's (:func:`chaplygin.numeric._loop.shared`),
    its first line names the library version and the digest of its source files, and where
    ``NUMBA_CACHE_DIR`` names numba's cache, it is kept there.
    """
    lines = [
        f"_GL_EPS = {EPS!r}",
        "_nogil_jit = njit(cache=True, nogil=True, fastmath=False)",
        *kernel_lines((_k_pivot, _k_solve, _k_fill, _k_eval, *_GL_KERNELS[:-1]), "@_jit"),
        *kernel_lines(_GL_KERNELS[-1:], "@_nogil_jit"),  # _gl_integrate: run in a thread (Ctrl-C)
    ]
    return import_shared(shared_source("The Gauss-Legendre kernels", lines), "gauss")


def stepping_module(compiled: CompiledModel) -> Any:
    """The generated module of a ``numpy`` model with the stepping kernels appended, as Python
    (imported once): ``fill`` is its own, so ``_k_call`` ignores the model tuple."""
    source = Path(compiled.module.__file__).read_text(encoding="utf-8")
    parts = [f"_GL_EPS = {EPS!r}", *kernel_lines((_k_call, _k_fill, _k_eval, *_GL_KERNELS), None)]
    return import_source(source + "\n".join(["", *parts]) + "\n", "gauss_numpy")


# ------------------------------------------------------------------ drivers
class SymmetricResult(NamedTuple):
    """What :func:`integrate_symmetric` returns."""

    t: np.ndarray
    y: np.ndarray
    status: str
    message: str
    n_rhs: int
    n_steps: int
    h: float
    newton_iterations: int
    jacobians: int
    code: int = 0


def grid(t_span: tuple[float, float], samples: int, step: float | None) -> tuple[float, int]:
    """The step ``h ≤ step`` that puts every sample on the grid, and the steps per sample.

    Raises
    ------
    ChaplyginError
        When ``step`` is not a positive finite number, or the run would take
        more than :data:`MAX_STEPS` steps.
    """
    if step is None or isinstance(step, bool) or not isinstance(step, (int, float, np.floating, np.integer)):
        raise ChaplyginError(
            f"step: the symmetric methods ({', '.join(METHODS)}) need a fixed step size, a "
            f"positive number (e.g. step=0.01), not {step!r}."
        )
    step = float(step)
    if not (step > 0 and math.isfinite(step)):
        raise ChaplyginError(f"step: the step size must be a positive finite number, not {step:g}.")
    spacing = (t_span[1] - t_span[0]) / (samples - 1)
    per_sample = max(1, math.ceil(spacing / step - 1e-9))
    if per_sample * (samples - 1) > MAX_STEPS:
        raise ChaplyginError(
            f"step: {step:g} would take {per_sample * (samples - 1):.3g} steps (at most "
            f"{MAX_STEPS:.0e}); choose a larger step."
        )
    return spacing / per_sample, per_sample


def integrate_symmetric(
    compiled: CompiledModel,
    t_span: tuple[float, float],
    y0: np.ndarray,
    p: np.ndarray,
    *,
    method: str,
    step: float,
    samples: int,
    max_iterations: int = MAX_ITERATIONS,
    time_limit: float | None = None,
) -> SymmetricResult:
    """Integrate a reduced model's ``dy/dt`` with a Gauss–Legendre method at a fixed step.

    Parameters
    ----------
    compiled : CompiledModel
        A reduced model (state ``[q, u]``) from the ``numpy`` or ``numba`` backend.
    t_span : (t0, t1)
    y0, p : ndarray
        State and parameters in layout order.
    method : {"midpoint", "gauss4", "gauss6"}
    step : float
        The largest step size allowed (see :func:`grid`).
    samples : int
        Equally spaced output times, the ends included.
    max_iterations : int
        Newton iterations per step before the run fails.
    time_limit : float, optional
        Seconds: a run whose pace over half a second says that its steps would take longer is
        stopped with an :class:`~chaplygin.errors.InputError` (see
        :func:`chaplygin.numeric.simulate.simulate`).

    Returns
    -------
    SymmetricResult
        Output times and states (fewer rows than ``samples`` after a failure),
        status, message and counts.
    """
    target = targets.get(compiled.backend)
    if not target.symmetric:
        raise ChaplyginError(
            f"backend: the symmetric methods run with 'numba' (compiled) or 'numpy' (plain "
            f"Python), not {compiled.backend!r}."
        )
    A, b, c = tableau(method)
    t0, t1 = float(t_span[0]), float(t_span[1])
    h, per_sample = grid((t0, t1), samples, step)
    if target.flavour == "numba":  # numba's module: the shared loop's kernels step it
        module = loop_model(compiled).module
        kernels: Any = shared()
        m = module.MODEL
    else:
        module = kernels = stepping_module(compiled)
        m = (0, module.DIM, module.N, module.N_OBSERVED)
    y0 = np.ascontiguousarray(y0, dtype=float)
    p = np.ascontiguousarray(p, dtype=float)
    out = np.empty((samples, y0.size))
    stats = np.zeros(6, dtype=np.int64)

    def run() -> tuple[int, int, float, np.ndarray]:
        with np.errstate(all="ignore"):  # plain Python (numpy backend): a blow-up is a status
            return kernels._gl_integrate(
                m, t0, h, per_sample, y0, p, A, b, c, extrapolation(c), int(max_iterations), out, stats
            )

    watch = None if time_limit is None else _pace(stats, (samples - 1) * per_sample, h, time_limit)
    filled, code, t_fail, y_fail = _in_a_thread(run, lambda: stats.__setitem__(5, 1), watch)
    times = np.linspace(t0, t1, samples)[:filled]
    n_steps = int(stats[4])
    if code == 0:
        status = "success"
        message = (
            f"reached t = {t1:g}: {n_steps} {method} steps of h = {h:.6g}, "
            f"{stats[1] / max(n_steps, 1):.2f} Newton iterations per step"
        )
    else:
        status = "failed"
        message = _failure(code, method, t_fail, h, int(max_iterations), module, y_fail, p)
    return SymmetricResult(
        times,
        out[:filled],
        status,
        message,
        int(stats[0]),
        n_steps,
        h,
        int(stats[1]),
        int(stats[3]),
        int(code),
    )


def _pace(stats: np.ndarray, total: int, h: float, limit: float) -> Any:
    """A ``watch`` for :func:`_in_a_thread`: refuses a run whose pace says it needs more than
    ``limit`` seconds (:func:`~chaplygin.numeric.simulate.pace_check`, told ``stats[4]``: the
    steps taken, from the first on, so that a compilation does not count)."""
    from chaplygin.numeric.simulate import pace_check

    check = pace_check(
        total,
        limit,
        lambda left, pace: (
            f"step: {total:.3g} steps of h = {h:.3g}: too long to run: the time left is "
            f"estimated at {left} (steps {pace})"
        ),
        "ask for a shorter time or a larger step",
    )

    def watch() -> None:
        if stats[4]:
            check(int(stats[4]))

    return watch


def _tolerant(compiled: CompiledModel) -> CompiledModel:
    """``compiled`` with an ``observe`` that gives NaN where the generated code raises.

    (E.g. ``log`` of a negative number, which compiled code turns into NaN
    without raising: the compiled stepper may have gone on past it.)
    """
    model = CompiledModel(compiled.layout, compiled.module, compiled.backend)
    width = compiled.n_observed

    def observe(t: float, y: np.ndarray, p: np.ndarray) -> np.ndarray:
        try:
            with np.errstate(all="ignore"):
                return compiled.observe(t, y, p)
        except (ArithmeticError, ValueError, np.linalg.LinAlgError):
            return np.full(width, np.nan)

    model.observe = observe
    return model


def _failure(
    code: int, method: str, t: float, h: float, max_iterations: int, module: Any, y: np.ndarray, p: np.ndarray
) -> str:
    """The message of a failed run (kernel status ``code``, see :data:`STATUS`) at ``(t, y)``.

    Codes 2, 3 and 5 come from the right-hand-side kernels shared with
    :mod:`chaplygin.numeric._loop`, and are worded by its ``_message``.
    """
    if code == 7:
        return (
            f"the Newton iteration for the {method} stages did not converge at t = {t:.6g} "
            f"in {max_iterations} iterations (h = {h:.3g}); try a smaller step"
        )
    if code == 8:
        return (
            f"the Newton matrix of the {method} stages is singular at t = {t:.6g} "
            f"(h = {h:.3g}); try a smaller step"
        )
    return _message(module, code, t, t, y, p, 0)
