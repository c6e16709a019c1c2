"""SciPy's DOP853 in plain Python on lists of floats: the ``numpy`` backend's stepper.

Why
---
The generated ``numpy``-backend code evaluates a right-hand side on Python
floats in a few microseconds.  Driven by SciPy's ``DOP853`` class, every
evaluation also paid for SciPy's array bookkeeping and a list ↔ array
conversion each way, more than the evaluation itself, and ``import
scipy.integrate`` alone took about 0.3 s: most of a short ``chaplygin
simulate``.  This stepper keeps the state, the stages and the dense output as
lists and imports nothing beyond :mod:`chaplygin.numeric._dop853`.

It is the same algorithm as SciPy's ``DOP853`` and as the compiled loops
(:func:`chaplygin.numeric._loop._k_dop853`, whose coefficients it shares):
the same initial step selection, step-size controller, combined 5th/3rd-order
error norm, minimum step ``10·spacing(t)``, and Hairer's 7th-order dense
output, computed only for steps that contain an output time.  Runs follow
SciPy's step sequence and agree with ``solve_ivp(method="DOP853")`` to
round-off (the tests check it).

The stage combinations are written out once, when this module is imported,
as list comprehensions over ``zip`` of the stages that have non-zero
coefficients (:func:`_source`, from the shared tableau): a few hundred
nanoseconds per stage for a small state, where a loop over an index or NumPy
on arrays this small costs several times more.

Failures
--------
The right-hand side reports a failure by raising :class:`StepFailure` (with
the time of the failing evaluation); the stepper then stops and returns the
samples so far and the last accepted step, as SciPy's stepper leaves them.
A step below the minimum ends the run with SciPy's message
(:data:`chaplygin.numeric._dop853.TOO_SMALL_STEP`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

from chaplygin.numeric import _dop853
from chaplygin.numeric._dop853 import StepFailure

__all__ = ["Run", "StepFailure", "dop853"]

Vector = list[float]
#: ``fun(t, y)``: the derivative at ``(t, y)`` as a new list; raises :class:`StepFailure`
Derivative = Callable[[float, Vector], Vector]


class Run(NamedTuple):
    """How :func:`dop853` ended: the samples it reached and where it stopped."""

    t: list[float]  # the output times reached
    y: list[Vector]  # the state at each
    message: str  # "" if it reached t1
    failed_inside: bool  # a StepFailure (smaller steps may get closer), not a too-small step
    t_last: float  # the last accepted step
    y_last: Vector
    t_fail: float  # the failing evaluation (NaN: none)


# ------------------------------------------------------------------ generated stage arithmetic
def _terms(coefficients: Sequence[float], stages: Sequence[int]) -> tuple[str, list[str]]:
    """``"c·a0 + c·a5 + …"`` over the non-zero ``coefficients`` of ``stages`` (``a{j}``: an entry
    of stage ``j``), and the stage names ``k{j}`` it needs, in order."""
    used = [(c, j) for c, j in zip(coefficients, stages) if c != 0.0]
    return " + ".join(f"{c!r} * a{j}" for c, j in used), [f"k{j}" for _, j in used]


def _zip(names: list[str], extra: Sequence[tuple[str, str]] = ()) -> str:
    """``"for y_, a0, a5 in zip(y, k0, k5)"``: ``extra`` (element, list) first, then the stages."""
    elements = [e for e, _ in extra] + [f"a{name[1:]}" for name in names]
    lists = [lst for _, lst in extra] + names
    return f"for {', '.join(elements)} in zip({', '.join(lists)})"


def _stage(s: int) -> str:
    """``k{s} = fun(t + c·h, y + h·Σ a_sj k_j)``, SciPy's ``rk_step`` arithmetic."""
    combination, names = _terms(_dop853.A[s][:s], range(s))
    state = f"[y_ + ({combination}) * h {_zip(names, [('y_', 'y')])}]"
    return f"    k{s} = fun(t + {_dop853.C[s]!r} * h, {state})"


def _source() -> str:
    """The functions ``_step``, ``_norms`` and ``_dense`` (see :func:`dop853`), written out from the tableau."""
    n = _dop853.N_STAGES
    every = ", ".join(f"k{j}" for j in range(n + 1))
    lines = ["def _step(fun, t, y, h, k0):", '    """Stages 1 … 12 of a step: ``(y_new, K)``."""']
    lines += [_stage(s) for s in range(1, n)]
    combination, names = _terms(_dop853.B, range(n))
    lines += [
        f"    y_new = [y_ + h * ({combination}) {_zip(names, [('y_', 'y')])}]",
        "    k12 = fun(t + h, y_new)",
        f"    return y_new, ({every})",
        "",
        "",
        "def _norms(y, y_new, K, rtol, atol):",
        '    """``(‖e5‖², ‖e3‖²)``, the errors scaled by ``atol + max(|y|, |y_new|)·rtol``."""',
        f"    {every} = K",
        "    n5 = n3 = 0.0",
    ]
    e5, names5 = _terms(_dop853.E5, range(n + 1))
    e3, names3 = _terms(_dop853.E3, range(n + 1))
    names = sorted(set(names5) | set(names3), key=lambda k: int(k[1:]))
    lines += [
        f"    {_zip(names, [('y_', 'y'), ('z_', 'y_new'), ('tol', 'atol')])}:",
        "        u = abs(y_)",
        "        v = abs(z_)",
        "        s = tol + (u if u > v else v) * rtol",
        f"        e = ({e5}) / s",
        "        n5 += e * e",
        f"        e = ({e3}) / s",
        "        n3 += e * e",
        "    return n5, n3",
        "",
        "",
        "def _dense(fun, t, y, h, y_new, K):",
        '    """The dense output of a step: three more stages, then the interpolant\'s 7 coefficients."""',
        f"    {every} = K",
    ]
    lines += [_stage(s) for s in range(n + 1, len(_dop853.C))]
    lines += [
        "    f0 = [z_ - y_ for z_, y_ in zip(y_new, y)]",
        "    f1 = [h * a0 - d for a0, d in zip(k0, f0)]",
        f"    f2 = [2.0 * d - h * (a{n} + a0) for d, a{n}, a0 in zip(f0, k{n}, k0)]",
    ]
    for r, row in enumerate(_dop853.D):
        combination, names = _terms(row, range(len(row)))
        lines.append(f"    f{3 + r} = [h * ({combination}) {_zip(names)}]")
    lines.append("    return f0, f1, f2, f3, f4, f5, f6")
    return "\n".join(lines) + "\n"


def _compiled() -> dict[str, Any]:
    namespace: dict[str, Any] = {}
    exec(compile(_source(), "<chaplygin.numeric._pyloop>", "exec"), namespace)  # our own text, not user's
    return namespace


_generated = _compiled()
_step: Callable[..., tuple[Vector, tuple[Vector, ...]]] = _generated["_step"]
_norms: Callable[..., tuple[float, float]] = _generated["_norms"]
_dense: Callable[..., tuple[Vector, ...]] = _generated["_dense"]


def _interpolate(F: tuple[Vector, ...], x: float, y: Vector) -> Vector:
    """SciPy's ``Dop853DenseOutput`` at ``t_old + x·h``: the Horner-like scheme alternating ``x`` and ``1 − x``."""
    u = 1 - x
    return [
        ((((((f6 * x + f5) * u + f4) * x + f3) * u + f2) * x + f1) * u + f0) * x + y_
        for f0, f1, f2, f3, f4, f5, f6, y_ in zip(*F, y)
    ]


def _rms(v: Vector) -> float:
    return math.sqrt(sum([x * x for x in v]) / len(v))


def _initial_step(
    fun: Derivative, t0: float, y0: Vector, f0: Vector, t1: float, max_step: float, rtol: float, atol: Vector
) -> float:
    """SciPy's ``select_initial_step`` (Hairer, Nørsett & Wanner, II.4) for DOP853 (order 7)."""
    interval = abs(t1 - t0)
    if interval == 0.0:
        return 0.0
    scale = [a + abs(y) * rtol for a, y in zip(atol, y0)]
    d0 = _rms([y / s for y, s in zip(y0, scale)])
    d1 = _rms([f / s for f, s in zip(f0, scale)])
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, interval)
    f1 = fun(t0 + h0, [y + h0 * f for y, f in zip(y0, f0)])
    d2 = _rms([(b - a) / s for a, b, s in zip(f0, f1, scale)]) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
    return min(100 * h0, h1, interval, max_step)


def dop853(
    fun: Derivative,
    t0: float,
    t1: float,
    y0: Vector,
    times: Sequence[float],
    *,
    rtol: float,
    atol: Vector,
    max_step: float = math.inf,
    first_step: float | None = None,
    progress: Callable[[float], None] | None = None,
    every: float = 0.1,
) -> Run:
    """Integrate ``y' = fun(t, y)`` from ``(t0, y0)`` to ``t1 > t0``, sampled at ``times``.

    Parameters
    ----------
    fun : callable
        ``fun(t, y)`` → the derivative as a new list; raises :class:`StepFailure` where it fails.
    t0, t1 : float
        Start and end (forward only).
    y0 : list of float
        The state at ``t0``.
    times : sequence of float
        Output times, increasing, within ``[t0, t1]``; one equal to ``t0`` is ``y0``.
    rtol, atol :
        As SciPy's (checked by the caller: :func:`chaplygin.numeric._dop853.tolerances`);
        ``atol`` one value per state entry.
    max_step, first_step : float
        As SciPy's (``first_step`` positive and at most ``t1 − t0``).
    progress : callable, optional
        Told the time reached after a step, at most every ``every`` seconds of wall time.

    Returns
    -------
    Run
        The samples reached and how the run ended.
    """
    if not t1 > t0:
        raise ValueError(f"dop853 integrates forward: t1 = {t1!r} is not after t0 = {t0!r}")
    out_t: list[float] = []
    out_y: list[Vector] = []
    n_times = len(times)
    k = 0
    if n_times and times[0] == t0:
        out_t.append(t0)
        out_y.append(list(y0))
        k = 1
    t, y = t0, list(y0)
    due = time.monotonic() + every
    try:
        f = fun(t, y)
        h_abs = _initial_step(fun, t, y, f, t1, max_step, rtol, atol) if first_step is None else first_step
        n = len(y)
        while k < n_times:
            min_step = 10 * abs(math.nextafter(t, math.inf) - t)
            if h_abs > max_step:
                h_abs = max_step
            elif h_abs < min_step:
                h_abs = min_step
            rejected = False
            while True:
                if h_abs < min_step:
                    return Run(out_t, out_y, _dop853.TOO_SMALL_STEP, False, t, y, math.nan)
                t_new = t + h_abs
                if t_new > t1:
                    t_new = t1
                h = t_new - t
                h_abs = abs(h)
                y_new, K = _step(fun, t, y, h, f)
                n5, n3 = _norms(y, y_new, K, rtol, atol)
                error = 0.0 if n5 == 0.0 and n3 == 0.0 else h_abs * n5 / math.sqrt((n5 + 0.01 * n3) * n)
                if error < 1.0:
                    if error == 0.0:
                        factor = _dop853.MAX_FACTOR
                    else:
                        factor = min(_dop853.MAX_FACTOR, _dop853.SAFETY * error**_dop853.ERROR_EXPONENT)
                    if rejected:
                        factor = min(1.0, factor)
                    h_abs *= factor
                    break
                h_abs *= max(_dop853.MIN_FACTOR, _dop853.SAFETY * error**_dop853.ERROR_EXPONENT)
                rejected = True
            finished = t_new >= t1
            if finished or times[k] <= t_new:  # dense output only for a step with a sample
                F = _dense(fun, t, y, h, y_new, K)
                while k < n_times and (finished or times[k] <= t_new):
                    out_t.append(times[k])
                    out_y.append(_interpolate(F, (times[k] - t) / h, y))
                    k += 1
            t, y, f = t_new, y_new, K[_dop853.N_STAGES]
            if progress is not None and time.monotonic() >= due:
                progress(t)
                due = time.monotonic() + every
            if finished:
                break
    except StepFailure as exc:
        return Run(out_t, out_y, str(exc), True, t, y, exc.t)
    return Run(out_t, out_y, "", False, t, y, math.nan)
