"""A compiled adaptive DOP853 loop that runs entirely inside numba.

Why hand-written
----------------
The issue asks for an integration loop whose cost per step is the right-hand
side's, not Python's.  SciPy's ``DOP853`` stepper adds about 15 µs of Python
to every right-hand-side call (about 180 µs per step) around a right-hand side
that numba evaluates in half a microsecond, and numba itself has no ODE
integrator.  The libraries that integrate inside
numba were checked and rejected:

* ``numbalsoda`` is unmaintained (last release 2022) and has no DOP853;
* ``numbakit-ode`` (``nbkode``) is unmaintained (last release 2022);
* CyRK's numba solver (``nbsolve_ivp``) is kept, but it has no dense output
  (its ``t_eval`` interpolates linearly between steps, far below the
  integration tolerance), compiles with ``fastmath=True``, and an exception in
  the right-hand side (numba raises ``LinAlgError`` for a singular mass matrix)
  escapes it and loses the trajectory so far;
* diffrax (JAX) is the well-kept compiled integrator and is the ``jax``
  backend (:mod:`chaplygin.numeric.jaxbackend`), but it is an optional extra.

So this module is a line-by-line port of SciPy's ``DOP853`` (Hairer's
8(5,3) pair with the 7th-order dense output of the Fortran code): the same
tableau, initial-step selection, step-size controller (safety 0.9, factors
0.2 … 10, no growth right after a rejection), combined 5th/3rd-order error norm,
minimum step ``10·spacing(t)`` and rtol floor ``100·eps``.  Runs therefore
follow SciPy's step sequence and agree with ``solve_ivp(method="DOP853")`` to
round-off, which the tests check.  Dense output (three extra stages) is
computed only for steps that contain an output time.

The right-hand side inside the loop is the generated ``fill`` (the model's
``M``, ``F`` and velocities, common subexpressions eliminated) followed by an
in-place Gaussian elimination with partial pivoting (``_k_solve``, the
generated modules' own) into preallocated work arrays: the same arithmetic as
the generated ``rhs``, which allocates its arrays on every call.  The tests
check that both agree.

Failures come back as a status, never as an exception: a step size below the
spacing of floating-point numbers, a non-finite derivative (a blow-up), an
exactly singular mass matrix (a zero pivot), an error raised inside the
generated code (caught in compiled code; its message is recovered by
evaluating the failing point once more from Python), or more steps than
``max_steps``.  The output samples up to the failure are returned.

How it is compiled
------------------
Once per installation, not once per model.  numba caches compiled functions
per source file, and a function that receives another jitted function as an
argument is recompiled in every process (its cache key names the argument).
So the kernels below take a model as a tuple of integers, ``m = (address, DIM,
N, N_OBSERVED)``: ``address`` is that of a C-callable ``fill`` (a
``numba.cfunc`` around the model's generated ``fill``, appended to its
generated module by :func:`loop_model`), which the kernels call through a
function pointer (:func:`chaplygin.numeric._fnptr.call_fill`).  Their source,
which names no model, is written once to the code cache (:func:`shared`, the
file named by the library version and the digest of its sources) and cached
there by numba: the first run of the installation compiles the loop (some
seconds), and a new model then compiles only its ``fill`` and that small
wrapper, which numba caches in turn.
"""

from __future__ import annotations

import functools
import inspect
import math
import os
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from chaplygin.errors import ChaplyginError
from chaplygin.numeric import _dop853

if TYPE_CHECKING:  # the C loop reads the tableau here: no SymPy, no compiled model needed
    from chaplygin.numeric._ckernel import CompiledModel

__all__ = [
    "STATUS",
    "LoopResult",
    "default_threads",
    "ensemble_dop853",
    "import_shared",
    "in_a_thread",
    "integrate_dop853",
    "kernel_lines",
    "loop_model",
    "shared_source",
]

EPS = _dop853.EPS

#: kernel status codes → meaning (the ensembles' per-member messages)
STATUS = {
    0: "success",
    1: "step size underflow (a blow-up, or a non-finite derivative: a singular mass matrix?)",
    2: "non-finite derivative (a blow-up)",
    3: "the right-hand side raised an error",
    4: "too many steps",
    5: "the mass matrix is singular",
    6: "the solver failed",  # jax backend: another diffrax failure
    # a velocity solved from the constraints is not finite, or (ensembles, chaplygin.numeric.ensemble)
    # they cannot be solved between two times checked; 7, 8: chaplygin.numeric.symmetric
    9: "a pole of the solved constraints",
    10: "interrupted",  # an ensemble stopped by Ctrl-C (ensemble_dop853 raises KeyboardInterrupt)
}

# ------------------------------------------------------------------ DOP853 tableau
# (chaplygin.numeric._dop853, shared with the C port and the numpy backend's list stepper; the
# kernels read these names as globals of the shared loop module, see _kernel_source)
_DOP_A: Any = _dop853.A
_DOP_B = _dop853.B
_DOP_C = _dop853.C
_DOP_E3 = _dop853.E3
_DOP_E5 = _dop853.E5
_DOP_D = _dop853.D

# ------------------------------------------------------------------ kernels
# Plain Python functions whose source is compiled by numba in the shared loop
# module (see ``_kernel_source``), where ``_k_call`` calls a model's ``fill``
# through its address (``m``, the model tuple ``(address, DIM, N, N_OBSERVED)``;
# :mod:`chaplygin.numeric._fnptr`).  The symmetric integrators append ``_k_call``,
# ``_k_fill`` and ``_k_eval`` to a model's own module instead, where ``fill`` is
# a global.  They are never called from here.
fill: Any = None  # placeholder: a generated module defines it


def _k_pivot(M, c):  # pragma: no cover - compiled
    """The row ``r ≥ c`` of largest ``|M[r, c]|`` (partial pivoting), and that magnitude."""
    piv = c
    big = abs(M[c, c])
    for r in range(c + 1, M.shape[0]):
        if abs(M[r, c]) > big:
            big = abs(M[r, c])
            piv = r
    return piv, big


def _k_solve(M, b):  # pragma: no cover - compiled
    """``b ← M⁻¹ b`` by Gaussian elimination with partial pivoting, in place; 5 if singular."""
    n = M.shape[0]
    for c in range(n):
        piv, big = _k_pivot(M, c)
        if big == 0.0:
            return 5
        if piv != c:
            for j in range(c, n):
                tmp = M[c, j]
                M[c, j] = M[piv, j]
                M[piv, j] = tmp
            tmp = b[c]
            b[c] = b[piv]
            b[piv] = tmp
        for r in range(c + 1, n):
            factor = M[r, c] / M[c, c]
            for j in range(c + 1, n):
                M[r, j] -= factor * M[c, j]
            b[r] -= factor * b[c]
    for c in range(n - 1, -1, -1):
        acc = b[c]
        for j in range(c + 1, n):
            acc -= M[c, j] * b[j]
        b[c] = acc / M[c, c]
    return 0


def _k_call(m, t, y, p, M, b, V, O):  # pragma: no cover - compiled
    """The module's own ``fill`` (``m`` unused); 0, or 3 if it raised.

    Only where the kernels are appended to a model's module (the symmetric
    integrators); the shared loop calls :func:`chaplygin.numeric._fnptr.call_fill`
    under this name, whose ``fill`` (a ``numba.cfunc``) catches the same way.
    """
    try:
        fill(t, y, p, M, b, V, O)
    except Exception:
        return 3
    return 0


def _k_fill(m, t, y, p, M, b, V, O):  # pragma: no cover - compiled
    """The model's ``fill`` into a zeroed ``M``; 0, or 3 if it raised."""
    for i in range(M.shape[0]):
        for j in range(M.shape[1]):
            M[i, j] = 0.0
    return _k_call(m, t, y, p, M, b, V, O)


def _k_eval(m, t, y, p, f, M, b, V, O):  # pragma: no cover - compiled
    """``f ← rhs(t, y, p)`` without allocating; 0, or a failure code.

    The generated ``fill`` writes ``M``, ``F`` (here ``b``), the velocities
    ``V`` and the observables ``O``; ``M·x = F`` is solved by Gaussian
    elimination with partial pivoting in place (the generated ``rhs``'s
    arithmetic without its allocations).  Codes: 2 a non-finite derivative,
    3 ``fill`` raised (e.g. a division by zero), 5 a singular mass matrix,
    9 a non-finite velocity (a pole of the solved constraints).
    """
    code = _k_fill(m, t, y, p, M, b, V, O)
    if code != 0:
        return code
    for i in range(V.size):
        if not math.isfinite(V[i]):
            return 9
    if _k_solve(M, b) != 0:
        return 5
    n_v = V.size
    for i in range(n_v):
        f[i] = V[i]
    for i in range(f.size - n_v):
        f[n_v + i] = b[i]
    for i in range(f.size):
        if not math.isfinite(f[i]):
            return 2
    return 0


def _k_stages(m, first, last, t, h, y, p, K, y_stage, wM, wb, wV, wO):  # pragma: no cover - compiled
    """DOP853 stages ``first … last − 1`` of a step of size ``h`` into ``K``.

    Returns ``(code, s)``: 0 or the failure code, and the last stage evaluated
    (the failing one, whose state is left in ``y_stage``), so ``s − first + 1``
    right-hand sides were evaluated.
    """
    for s in range(first, last):
        for i in range(y.size):
            acc = 0.0
            for j in range(s):
                acc += K[j, i] * _DOP_A[s, j]
            y_stage[i] = y[i] + acc * h
        code = _k_eval(m, t + _DOP_C[s] * h, y_stage, p, K[s], wM, wb, wV, wO)
        if code != 0:
            return code, s
    return 0, last - 1


def _k_observe(m, t, y, p, n_react, row, M, b, V, O):  # pragma: no cover - compiled
    """``row ← observe(t, y, p)`` (the generated ``observe``'s numbers), NaN where it fails."""
    if _k_fill(m, t, y, p, M, b, V, O) != 0:
        for j in range(row.size):
            row[j] = np.nan
        return
    for j in range(row.size):
        row[j] = O[j]
    n_v = V.size
    first = row.size - n_v - n_react  # the reactions: the last n_react unknowns of M·x = F
    if n_react > 0:
        singular = _k_solve(M, b) != 0
        for j in range(n_react):
            row[first + j] = np.nan if singular else b[M.shape[0] - n_react + j]
    for j in range(n_v):
        row[row.size - n_v + j] = V[j]


def _k_observe_new(m, t, y, p, n_react):  # pragma: no cover - compiled
    """``observe(t, y, p)`` as a new array (for samples taken from Python)."""
    row = np.empty(m[3])
    _k_observe(
        m, t, y, p, n_react, row, np.empty((m[1], m[1])), np.empty(m[1]), np.empty(m[2]), np.empty(m[3])
    )
    return row


def _k_evaluate(m, t, y, p):  # pragma: no cover - compiled
    """The generated ``evaluate``: ``(code, M, F, V, O)``, fresh zeroed arrays filled at ``(t, y, p)``."""
    M = np.zeros((m[1], m[1]))
    F = np.zeros(m[1])
    V = np.zeros(m[2])
    O = np.zeros(m[3])
    code = _k_fill(m, t, y, p, M, F, V, O)
    return code, M, F, V, O


def _k_rms(v):  # pragma: no cover - compiled
    s = 0.0
    for i in range(v.size):
        s += v[i] * v[i]
    return math.sqrt(s / v.size)


def _k_dop853(
    m, t0, t1, y0, p, t_out, rtol, atol, max_step, first_step, max_steps, out, halt
):  # pragma: no cover
    """Integrate the model ``m``'s ``rhs`` from ``(t0, y0)`` to ``t1``; ``out[j] ← y(t_out[j])``.

    ``halt`` (int64, 1): where another thread sets ``halt[0]``, the loop stops at its next step
    with status 10 (an interrupted ensemble, :func:`ensemble_dop853`).

    Returns ``(filled, status, t, y, n_rhs, n_steps, t_fail, y_fail, h_next)``:
    ``filled`` rows of ``out`` were written, ``(t, y)`` is the last accepted
    point, ``(t_fail, y_fail)`` the point whose evaluation failed (status 2, 3),
    ``h_next`` the step the loop would take next (0.0 after a failed evaluation): a
    loop stopped by ``max_steps`` and started again from ``(t, y)`` with
    ``first_step=h_next`` takes exactly the steps it would have taken.
    """
    B = _DOP_B
    C = _DOP_C
    E3 = _DOP_E3
    E5 = _DOP_E5
    D: Any = _DOP_D
    n = y0.size
    n_out = t_out.size
    direction = 1.0 if t1 >= t0 else -1.0
    K = np.empty((16, n))
    y = y0.copy()
    y_new = np.empty(n)
    y_stage = np.empty(n)
    f_new = np.empty(n)
    scale = np.empty(n)
    e5 = np.empty(n)
    e3 = np.empty(n)
    F = np.empty((7, n))
    # work space of _k_eval: M, F, velocities, observables of the generated fill()
    wM = np.empty((m[1], m[1]))
    wb = np.empty(m[1])
    wV = np.empty(m[2])
    wO = np.empty(m[3])
    n_rhs = 0
    n_steps = 0
    t = t0
    filled = 0
    while filled < n_out and direction * (t_out[filled] - t0) <= 0.0:
        out[filled, :] = y0
        filled += 1

    code = _k_eval(m, t, y, p, K[0], wM, wb, wV, wO)
    n_rhs += 1
    if code != 0:
        return filled, code, t, y, n_rhs, n_steps, t, y.copy(), 0.0

    # initial step: SciPy's select_initial_step (Hairer, Nørsett & Wanner, II.4)
    interval = abs(t1 - t0)
    if first_step > 0.0:
        h_abs = first_step
    elif n == 0 or interval == 0.0:
        h_abs = interval
    else:
        for i in range(n):
            scale[i] = atol[i] + abs(y[i]) * rtol
            e5[i] = y[i] / scale[i]
            e3[i] = K[0, i] / scale[i]
        d0 = _k_rms(e5)
        d1 = _k_rms(e3)
        h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
        h0 = min(h0, interval)
        for i in range(n):
            y_stage[i] = y[i] + h0 * direction * K[0, i]
        code = _k_eval(m, t + h0 * direction, y_stage, p, f_new, wM, wb, wV, wO)
        n_rhs += 1
        if code != 0:
            return filled, code, t, y, n_rhs, n_steps, t + h0 * direction, y_stage.copy(), 0.0
        for i in range(n):
            e5[i] = (f_new[i] - K[0, i]) / scale[i]
        d2 = _k_rms(e5) / h0
        if d1 <= 1e-15 and d2 <= 1e-15:
            h1 = max(1e-6, h0 * 1e-3)
        else:
            h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
        h_abs = min(100.0 * h0, h1, interval, max_step)

    status = 0
    while direction * (t - t1) < 0.0:
        if max_steps > 0 and n_steps >= max_steps:
            status = 4
            break
        if halt[0] != 0:
            status = 10
            break
        min_step = 10.0 * abs(np.nextafter(t, direction * np.inf) - t)
        if h_abs > max_step:
            h_abs = max_step
        elif h_abs < min_step:
            h_abs = min_step
        rejected = False
        accepted = False
        while not accepted:
            if h_abs < min_step:
                status = 1
                break
            t_new = t + h_abs * direction
            if direction * (t_new - t1) > 0.0:
                t_new = t1
            h = t_new - t
            h_abs = abs(h)
            code, s = _k_stages(m, 1, 12, t, h, y, p, K, y_stage, wM, wb, wV, wO)  # stages 1 … 11
            n_rhs += s
            if code != 0:
                return filled, code, t, y, n_rhs, n_steps, t + C[s] * h, y_stage.copy(), 0.0
            for i in range(n):
                acc = 0.0
                for j in range(12):
                    acc += K[j, i] * B[j]
                y_new[i] = y[i] + h * acc
            code = _k_eval(m, t + h, y_new, p, K[12], wM, wb, wV, wO)
            n_rhs += 1
            if code != 0:
                return filled, code, t, y, n_rhs, n_steps, t + h, y_new.copy(), 0.0
            # error norm (SciPy's DOP853._estimate_error_norm)
            for i in range(n):
                scale[i] = atol[i] + max(abs(y[i]), abs(y_new[i])) * rtol
                a5 = 0.0
                a3 = 0.0
                for j in range(13):
                    a5 += K[j, i] * E5[j]
                    a3 += K[j, i] * E3[j]
                e5[i] = a5 / scale[i]
                e3[i] = a3 / scale[i]
            n5 = 0.0
            n3 = 0.0
            for i in range(n):
                n5 += e5[i] * e5[i]
                n3 += e3[i] * e3[i]
            if n5 == 0.0 and n3 == 0.0:
                error = 0.0
            else:
                error = h_abs * n5 / math.sqrt((n5 + 0.01 * n3) * n)
            if error < 1.0:
                if error == 0.0:
                    factor = 10.0
                else:
                    factor = min(10.0, 0.9 * error ** (-1.0 / 8.0))
                if rejected:
                    factor = min(1.0, factor)
                h_abs *= factor
                accepted = True
            else:
                h_abs *= max(0.2, 0.9 * error ** (-1.0 / 8.0))
                rejected = True
        if status != 0:
            break
        n_steps += 1
        if filled < n_out and direction * (t_out[filled] - t_new) <= 0.0:
            # dense output: three more stages, then the 7th-order interpolant
            code, s = _k_stages(m, 13, 16, t, h, y, p, K, y_stage, wM, wb, wV, wO)
            n_rhs += s - 12
            if code != 0:
                return filled, code, t, y, n_rhs, n_steps, t + C[s] * h, y_stage.copy(), 0.0
            for i in range(n):
                dy = y_new[i] - y[i]
                F[0, i] = dy
                F[1, i] = h * K[0, i] - dy
                F[2, i] = 2.0 * dy - h * (K[12, i] + K[0, i])
                for r in range(4):
                    acc = 0.0
                    for j in range(16):
                        acc += D[r, j] * K[j, i]
                    F[3 + r, i] = h * acc
            while filled < n_out and direction * (t_out[filled] - t_new) <= 0.0:
                x = (t_out[filled] - t) / h
                for i in range(n):
                    v = 0.0
                    for r in range(7):
                        v += F[6 - r, i]
                        v *= x if r % 2 == 0 else 1.0 - x
                    out[filled, i] = v + y[i]
                filled += 1
        t = t_new
        for i in range(n):
            y[i] = y_new[i]
            K[0, i] = K[12, i]
    return filled, status, t, y, n_rhs, n_steps, t, y.copy(), h_abs


def _k_batch(
    m,
    t0,
    t1,
    Y0,
    P,
    t_out,
    rtol,
    atol,
    max_step,
    max_steps,
    n_react,
    out,
    last,
    t_last,
    obs,
    status,
    n_rhs,
    start,
    stop,
    halt,
):  # pragma: no cover
    """``_k_dop853`` for rows ``start … stop-1`` of ``Y0`` (parameters ``P[i]``); releases the GIL."""
    wM = np.empty((m[1], m[1]))
    wb = np.empty(m[1])
    wV = np.empty(m[2])
    wO = np.empty(m[3])
    for i in range(start, stop):
        _filled, st, t, y, nr, _ns, _tf, _yf, _h = _k_dop853(
            m, t0, t1, Y0[i], P[i], t_out, rtol, atol, max_step, 0.0, max_steps, out[i], halt
        )
        status[i] = st
        t_last[i] = t
        n_rhs[i] = nr
        last[i, :] = y
        _k_observe(m, t, y, P[i], n_react, obs[i], wM, wb, wV, wO)


_SERIAL_KERNELS = (
    _k_pivot,
    _k_solve,
    _k_fill,
    _k_eval,
    _k_stages,
    _k_observe,
    _k_observe_new,
    _k_evaluate,
    _k_rms,
    _k_dop853,
)
_NOGIL_KERNELS = (_k_batch,)


def _tuple_source(name: str, value: object) -> str:
    return f"{name} = np.array({value!r})"


def kernel_lines(kernels: tuple[Any, ...], decorator: str | None) -> list[str]:
    """The kernels' source lines, each function under ``decorator`` (none: plain Python)."""
    head = [decorator] if decorator else []
    return [line for fn in kernels for line in ("", "", *head, inspect.getsource(fn).rstrip())]


def shared_source(title: str, lines: list[str]) -> str:
    """The source of a kernel module shared by every model: numba's ``_jit``, ``_k_call``, then ``lines``.

    Its docstring names ``title`` and the library version with the digest of
    :mod:`chaplygin.numeric`'s source files (which include
    :mod:`chaplygin.numeric._fnptr`), so another installation or an edited
    one writes another file, compiled anew.
    """
    from chaplygin.numeric.cache import _version

    head = [f'"""{title} of chaplygin {_version()}, shared by every model."""', "", "import math", ""]
    head += ["import numpy as np", "from numba import njit", ""]
    head += ["from chaplygin.numeric._fnptr import call_fill as _k_call", ""]
    head += ["_jit = njit(cache=True, fastmath=False)"]
    return "\n".join([*head, *lines]) + "\n"


def import_shared(source: str, stem: str) -> ModuleType:
    """A :func:`shared_source` module, imported from the code cache (compiled by numba on first use).

    numba finds a compiled function by its source file's path.  Where ``NUMBA_CACHE_DIR`` names
    numba's cache, the source is kept there, beside what numba compiles from it, so that
    processes with different chaplygin caches (``$CHAPLYGIN_CACHE``) but one numba cache share
    the compiled kernels; otherwise it is in chaplygin's code cache.
    """
    from chaplygin.numeric.cache import import_source

    numba_cache = os.environ.get("NUMBA_CACHE_DIR")
    folder = Path(numba_cache) / "chaplygin-loop" if numba_cache else None
    return import_source(source, stem, folder)


def _kernel_source() -> str:
    """The shared loop module: the tableau and the kernels, calling ``fill`` by address."""
    parts = [
        "_nogil_jit = njit(cache=True, nogil=True, fastmath=False)",
        _tuple_source("_DOP_A", _DOP_A),
        _tuple_source("_DOP_B", list(_DOP_B)),
        _tuple_source("_DOP_C", list(_DOP_C)),
        _tuple_source("_DOP_E3", list(_DOP_E3)),
        _tuple_source("_DOP_E5", list(_DOP_E5)),
        _tuple_source("_DOP_D", [list(r) for r in _DOP_D]),
    ]
    parts += kernel_lines(_SERIAL_KERNELS, "@_jit") + kernel_lines(_NOGIL_KERNELS, "@_nogil_jit")
    return shared_source("The DOP853 loop", parts)


#: appended to (a copy of) a model's generated numba module: its ``fill`` as a C function for
#: the shared loop, and the model tuple ``(address, DIM, N, N_OBSERVED)`` the loop's kernels take
_FILL_C = '''

# ------------------------------------------------------------------ for the shared DOP853 loop
from numba import carray as _carray
from numba import cfunc as _cfunc
from numba import types as _types

_DOUBLES = _types.CPointer(_types.float64)


@_cfunc(_types.int32(_types.float64, *[_DOUBLES] * 6), cache=True)
def fill_c(t, y, p, M, F, V, O):
    """``fill`` on C pointers (chaplygin.numeric._loop); 0, or 3 if it raised."""
    try:
        fill(
            t,
            _carray(y, N + K),
            _carray(p, {n_p}),
            _carray(M, (DIM, DIM)),
            _carray(F, DIM),
            _carray(V, N),
            _carray(O, N_OBSERVED),
        )
    except Exception:
        return 3
    return 0


MODEL = (fill_c.address, DIM, N, N_OBSERVED)
'''


# ------------------------------------------------------------------ loading
@functools.cache
def shared() -> ModuleType:
    """The shared loop module: written to the code cache and compiled by numba once per
    installation (:func:`import_shared`)."""
    return import_shared(_kernel_source(), "dop853")


def loop_model(compiled: CompiledModel) -> CompiledModel:
    """A :class:`CompiledModel` that the shared DOP853 loop (:func:`shared`) integrates.

    ``compiled`` must come from the ``numba`` backend.  The new model's module
    is a copy of the generated one with :data:`_FILL_C` appended: ``fill`` as
    a C function (``fill_c``, a cached ``numba.cfunc``; compiling it and the
    ``fill`` it calls is all a new model costs) and ``MODEL``, the tuple the
    loop's kernels take.  (A copy, so that the file numba caches names no
    other generated module.)  Its ``rhs`` is the generated one; its
    ``observe`` gives the generated ``observe``'s numbers through the loop's
    kernels, which give NaN multipliers at a singular mass matrix instead of
    raising.
    """
    if compiled.backend != "numba":
        raise ChaplyginError(f"the compiled DOP853 loop needs the 'numba' backend, not {compiled.backend!r}.")
    if hasattr(compiled.module, "MODEL"):
        return compiled
    from chaplygin.numeric.cache import import_source

    source = Path(compiled.module.__file__).read_text(encoding="utf-8")
    module = import_source(source + _FILL_C.format(n_p=len(compiled.layout.parameters)), "fillc")
    model = type(compiled)(compiled.layout, module, "numba")
    # the generated observe's numbers, NaN (not an exception) where M is singular
    n_react = len(compiled.layout.reactions)
    kernel, m = shared()._k_observe_new, module.MODEL
    model.observe = lambda t, y, p: kernel(m, float(t), _floats(y), _floats(p), n_react)
    return model


def evaluator(module: ModuleType) -> Callable[..., tuple[np.ndarray, ...]]:
    """``evaluate(t, y, p)`` (fresh ``M, F, V, O``) of a :func:`loop_model`'s module, through the
    shared loop's kernels: nothing to compile.  Where ``fill`` raises, the generated
    ``evaluate`` raises the same error."""
    kernel, m, generated = shared()._k_evaluate, module.MODEL, module.evaluate

    def evaluate(t: float, y: Any, p: Any) -> tuple[np.ndarray, ...]:
        code, *arrays = kernel(m, float(t), _floats(y), _floats(p))
        return tuple(arrays) if code == 0 else generated(t, y, p)

    return evaluate


def _floats(a: Any) -> np.ndarray:
    """``a`` as a C-contiguous float64 array (what the loop's kernels take; no copy if it is one)."""
    return np.ascontiguousarray(a, dtype=float)


# ------------------------------------------------------------------ drivers
class LoopResult(NamedTuple):
    """What :func:`integrate_dop853` returns (a tuple: ``t, y, status, message, n_rhs``)."""

    t: np.ndarray
    y: np.ndarray
    status: str
    message: str
    n_rhs: int
    code: int = 0
    n_steps: int = 0
    #: the last accepted step, and where a failing evaluation was (NaN: none)
    t_last: float = math.nan
    y_last: np.ndarray | None = None
    t_fail: float = math.nan
    #: the step the loop would take next: where ``max_steps`` stopped it, ``first_step=h_next``
    #: from ``(t_last, y_last)`` goes on exactly as if it had not stopped
    h_next: float = math.nan


_tolerances = _dop853.tolerances


def in_a_thread(call: Any, halt: Any, watch: Any = None) -> Any:
    """``call()`` in a worker thread while this one waits, so that Ctrl-C is heard at once (a
    compiled kernel holds this thread until it returns): on ``KeyboardInterrupt``, ``halt()``
    asks the kernel to stop, and the interrupt is raised once it has.  ``watch()``, if given,
    is called every 0.1 s while it runs; what it raises stops the run the same way.

    It also keeps Ctrl-C out of numba's calls: a jitted function that returns arrays runs Python
    code (numba's ``_numba_unpickle``) to box them, and a ``KeyboardInterrupt`` raised there, in
    the main thread, comes out as ``SystemError: CPUDispatcher(...) returned a result with an
    exception set``; only the main thread runs signal handlers, so in a worker it cannot happen.
    """
    from concurrent.futures import ThreadPoolExecutor
    from concurrent.futures import TimeoutError as Waiting

    with ThreadPoolExecutor(max_workers=1) as pool:
        future = pool.submit(call)
        try:
            while True:
                try:
                    return future.result(timeout=None if watch is None else 0.1)
                except Waiting:
                    watch()
        except BaseException:
            halt()
            raise


def _message(
    module: ModuleType,
    code: int,
    t: float,
    t_fail: float,
    y_fail: np.ndarray,
    p: np.ndarray,
    max_steps: int,
    names: tuple[str, ...] = (),
) -> str:
    if code == 1:
        return f"the integrator stopped at t = {t:.6g}: {_dop853.TOO_SMALL_STEP}"
    if code == 2:
        return f"the solution blew up (non-finite derivative) at t = {t_fail:.6g}"
    if code == 3:
        try:  # once more from Python, for the exception's message
            module.rhs(t_fail, y_fail, p)
            why = "it raised an error"
        except Exception as exc:
            why = str(exc) or type(exc).__name__
        return f"the right-hand side failed at t = {t_fail:.6g}: {why}"
    if code == 4:
        return f"the integrator stopped at t = {t:.6g}: more than {max_steps} steps"
    if code == 5:
        return (
            f"the right-hand side failed at t = {t_fail:.6g}: the mass matrix is singular "
            f"(M·x = F has no unique solution)"
        )
    if code == 9:
        v = np.asarray(module.observe(t_fail, y_fail, p))[-len(names) :] if names else ()
        bad = [name + "'" for name, x in zip(names, v) if not math.isfinite(x)] or ["a velocity"]
        return (
            f"a pole at t = {t_fail:.6g}: {', '.join(bad)} (solved from the constraints) "
            f"{'is' if len(bad) == 1 else 'are'} not finite"
        )
    return ""


def integrate_dop853(
    model: CompiledModel,
    t_span: tuple[float, float],
    y0: np.ndarray,
    p: np.ndarray,
    times: np.ndarray,
    *,
    rtol: float = 1e-10,
    atol: float | np.ndarray = 1e-12,
    max_step: float = np.inf,
    first_step: float | None = None,
    max_steps: int = 0,
) -> LoopResult:
    """Integrate a numba or C model with the compiled DOP853 loop, sampled at ``times``.

    Parameters
    ----------
    model : CompiledModel
        From the ``numba`` backend (or :func:`loop_model`), or the ``c``
        backend (the same loop in C, :mod:`chaplygin.numeric._ckernel`).
    t_span : (t0, t1)
    y0, p : ndarray
        State and parameters in layout order.
    times : ndarray
        Output times, monotone in the direction of integration, within ``t_span``.
    rtol, atol, max_step, first_step :
        As for SciPy's ``DOP853``.
    max_steps : int
        Stop with a failure after this many accepted steps (0: no limit).

    Returns
    -------
    LoopResult
        ``(t, y, status, message, n_rhs)``: the output times reached and the
        states there (``len(t)`` rows, fewer than ``len(times)`` after a
        failure), ``"success"`` or ``"failed"``, why, and the number of
        right-hand-side evaluations.
    """
    if model.backend != "c":
        model = loop_model(model)
    t0, t1 = float(t_span[0]), float(t_span[1])
    y0 = np.ascontiguousarray(y0, dtype=float)
    p = np.ascontiguousarray(p, dtype=float)
    times = np.ascontiguousarray(times, dtype=float)
    lo, hi = min(t0, t1), max(t0, t1)
    if times.size and (times.min() < lo or times.max() > hi):
        raise ChaplyginError(f"times: every output time must lie within [{lo:g}, {hi:g}].")
    rtol, atol_v = _tolerances(rtol, atol, y0.size)
    if not max_step > 0:
        raise ChaplyginError("max_step must be positive.")
    out = np.empty((times.size, y0.size))
    if model.backend == "c":  # the same loop in C (chaplygin.numeric._ckernel)
        res = model.module.integrate(
            t0, t1, y0, p, times, rtol, atol_v, float(max_step), float(first_step or 0.0), int(max_steps)
        )
        out, filled, code, t, y, n_rhs, n_steps, t_fail, y_fail, h_next = (
            res.out,
            res.filled,
            res.code,
            res.t,
            res.y,
            res.n_rhs,
            res.n_steps,
            res.t_fail,
            res.y_fail,
            res.h_next,
        )
    else:  # in a worker thread: see in_a_thread (why: its docstring)
        kernel, halt = shared()._k_dop853, np.zeros(1, dtype=np.int64)
        args: tuple[Any, ...] = (model.module.MODEL, t0, t1, y0, p, times, rtol, atol_v, float(max_step))
        args += (float(first_step or 0.0), int(max_steps), out, halt)
        filled, code, t, y, n_rhs, n_steps, t_fail, y_fail, h_next = in_a_thread(
            lambda: kernel(*args), lambda: halt.__setitem__(0, 1)
        )
    message = _message(model.module, code, t, t_fail, y_fail, p, max_steps, model.layout.coordinates)
    status = "success" if code == 0 else "failed"
    if code == 0:
        message = f"reached t = {t1:g}"
    return LoopResult(
        times[:filled],
        out[:filled],
        status,
        message,
        int(n_rhs),
        int(code),
        int(n_steps),
        float(t),
        np.array(y),
        float(t_fail) if code else math.nan,
        float(h_next),
    )


def default_threads() -> int:
    """The CPU cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def ensemble_dop853(
    model: CompiledModel,
    t_span: tuple[float, float],
    Y0: np.ndarray,
    P: np.ndarray,
    *,
    times: np.ndarray | None = None,
    rtol: float = 1e-10,
    atol: float | np.ndarray = 1e-12,
    max_step: float = np.inf,
    max_steps: int = 0,
    threads: int | None = None,
) -> dict[str, np.ndarray]:
    """Integrate every row of ``Y0`` (parameters ``P``, one row each) on all cores.

    The members are cut into chunks that ``threads`` Python threads (default:
    every core this process may use) hand to the compiled loop, which runs
    without the GIL; small chunks keep the cores busy when members differ in
    cost.  ``model`` comes from the ``numba`` backend (the shared numba loop)
    or the ``c`` backend (the C port of it, :meth:`CKernel.batch
    <chaplygin.numeric._ckernel.CKernel.batch>`: the same steps and codes).

    Returns a dict of arrays: ``t`` (the last time reached), ``y`` (the state
    there), ``observed`` (``observe`` at that point), ``code`` (kernel status,
    see :data:`STATUS`), ``n_rhs``, and ``samples`` (``(N, len(times), n)``,
    only when ``times`` is given; rows after a failure are NaN).
    """
    from concurrent.futures import ThreadPoolExecutor

    if model.backend != "c":
        model = loop_model(model)
    t0, t1 = float(t_span[0]), float(t_span[1])
    Y0 = np.ascontiguousarray(Y0, dtype=float)
    P = np.ascontiguousarray(P, dtype=float)
    n_traj, n = Y0.shape
    if P.shape[0] != n_traj:
        raise ChaplyginError(f"P: one row of parameters per member ({n_traj}), not {P.shape[0]}.")
    rtol, atol_v = _tolerances(rtol, atol, n)
    t_out = np.empty(0) if times is None else np.ascontiguousarray(times, dtype=float)
    out = np.full((n_traj, t_out.size, n), np.nan)
    last = np.empty((n_traj, n))
    t_last = np.empty(n_traj)
    obs = np.empty((n_traj, int(model.module.N_OBSERVED)))
    code = np.empty(n_traj, dtype=np.int64)
    n_rhs = np.empty(n_traj, dtype=np.int64)
    workers = max(1, int(threads) if threads is not None else default_threads())
    chunk = max(1, min(64, n_traj // (8 * workers)))
    bounds = [(i, min(i + chunk, n_traj)) for i in range(0, n_traj, chunk)]
    halt = np.zeros(1, dtype=np.int64)  # set on Ctrl-C: every member stops at its next step
    if model.backend == "c":  # the C loop's batch (chaplygin.numeric._ckernel.CKernel.batch)
        batch, stop_all = model.module.batch, model.module.halt
    else:
        kernel, m, n_react = shared()._k_batch, model.module.MODEL, len(model.layout.reactions)

        def batch(*args: Any) -> None:  # CKernel.batch's arguments; the kernel's insert m, n_react
            kernel(m, *args[:9], n_react, *args[9:], halt)

        def stop_all(on: bool) -> None:
            halt[0] = int(on)

    def run(bound: tuple[int, int]) -> None:
        batch(
            t0,
            t1,
            Y0,
            P,
            t_out,
            rtol,
            atol_v,
            float(max_step),
            int(max_steps),
            out,
            last,
            t_last,
            obs,
            code,
            n_rhs,
            *bound,
        )

    # the chunks run in worker threads, even on one core, so that the main thread, waiting,
    # hears Ctrl-C: it then stops every loop at its next step and raises KeyboardInterrupt
    pool = ThreadPoolExecutor(max_workers=min(workers, len(bounds)))
    futures = [pool.submit(run, bound) for bound in bounds]
    try:
        for future in futures:
            future.result()
    except BaseException:
        stop_all(True)
        for future in futures:
            future.cancel()
        pool.shutdown(wait=True)
        stop_all(False)
        raise
    pool.shutdown()
    result = {"t": t_last, "y": last, "observed": obs, "code": code, "n_rhs": n_rhs}
    if times is not None:
        result["samples"] = out
    return result
