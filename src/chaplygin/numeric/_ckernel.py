"""The ``c`` backend: a model's ``fill`` in C, integrated by a DOP853 loop in C.

Why C and not numba for the everyday path
------------------------------------------
numba compiles the DOP853 loop of :mod:`chaplygin.numeric._loop` once per
installation (8–15 s on a 2-core machine) and each model's ``fill`` in a second
or two, and ``import numba`` alone costs about half a second.  Here the loop is C, built
once per installation into a shared library: by ``setup.py`` into the installed package
(:func:`install_loop`), or, where that was not possible or the library there is not the one
this run would build (:func:`packaged_loop`), into the kernel cache on first use.  Each model
adds one small library of the kernel cache holding its generated ``fill`` (:mod:`chaplygin.numeric._cfill`), built
by the C compiler in a fraction of a second.  The loop calls ``fill`` through a
function pointer; Python reaches both through :mod:`ctypes` (no import of
numba, no compile on a warm cache).  ``ctypes`` releases the GIL during a call.

The loop is a line-by-line port of :func:`chaplygin.numeric._loop._k_dop853` (itself
SciPy's ``DOP853``): the same tableau, step-size control, error norm, dense
output, Gaussian elimination with partial pivoting and failure codes
(:data:`chaplygin.numeric._loop.STATUS`; a C ``fill`` raises nothing, so code 3 never
occurs).  Built with IEEE semantics (no fast-math, no FMA contraction), its
runs agree with the numba loop's to round-off, which the tests check.  One thing
differs in how, not in what: the 12 stages of a step are evaluated without checking
each value for a pole or a blow-up, and the step is evaluated again with the checks
only where its error norm is not finite or a solve failed (then it fails where the
numba loop fails, with its count); ``benchmarks/dop853_floor.py`` measures the loop
against a hand-written DOP853 on the same ``fill``.  Its source, :data:`DOP853`, is also the
loop of the GPU kernel (:mod:`chaplygin.numeric._cuda`), there with compile-time sizes.

The kernel cache
----------------
Libraries live in ``cache_dir()/kernels`` (``$CHAPLYGIN_CACHE`` moves it;
deleting the folder clears it).  Each is keyed by the SHA-256 of its C source,
the compiler command and its flags, written atomically, and recorded with the
SHA-256 of its bytes in a JSON file beside it.  On loading, a library whose
bytes do not match the record (truncated, edited, from a half-finished copy)
or that the dynamic loader refuses is deleted and built again.
:data:`STATS` counts builds and loads in this process.

This module imports neither SymPy nor numba: a warm run needs neither.
"""

from __future__ import annotations

import ctypes
import hashlib
import json
import os
import shlex
import shutil
import subprocess
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from chaplygin.numeric.cache import cache_dir

__all__ = ["FLAGS", "STATS", "CKernel", "CompiledModel", "Layout", "Unavailable", "compiler", "library"]

#: position-independent shared library, optimised, IEEE semantics kept (no -ffast-math, no FMA);
#: a diagnostic that means a value is not the one written is an error, not a warning: a constant
#: out of range (an integer literal beyond 64 bits is truncated, a floating one becomes inf or 0:
#: -pedantic-errors, -Werror=overflow) or a call of an undeclared function, which C89 rules
#: would take to return an int (-Werror=implicit-function-declaration); clang takes these too
FLAGS = (
    "-std=c99",
    "-O2",
    "-fPIC",
    "-shared",
    "-fno-math-errno",
    "-ffp-contract=off",
    "-pedantic-errors",
    "-Werror=overflow",
    "-Werror=implicit-function-declaration",
)

#: libraries built and loaded (from the kernel cache) by this process
STATS = {"built": 0, "loaded": 0, "discarded": 0}


class Unavailable(Exception):
    """Generated C cannot be used here; the message says why."""


@dataclass(frozen=True)
class Layout:
    """The fixed order of the state ``y`` and the parameters ``p`` of generated functions."""

    model: str
    form: str
    coordinates: tuple[str, ...]
    velocities: tuple[str, ...]
    multipliers: tuple[str, ...]
    parameters: tuple[str, ...]
    #: names of the multipliers computed (not integrated), e.g. Chetaev's λ
    reactions: tuple[str, ...] = ()

    @property
    def state(self) -> tuple[str, ...]:
        """Names of the entries of ``y``."""
        return self.coordinates + self.velocities + self.multipliers

    def describe(self) -> str:
        return (
            f"f(t, y, p) for the {self.model}/{self.form} equations\n"
            f"  y = [{', '.join(self.state)}]\n"
            f"  p = [{', '.join(self.parameters)}]"
        )


class CompiledModel:
    """Numerical functions of one model, all with signature ``(t, y, p)``.

    Attributes
    ----------
    layout : Layout
        The order of ``y`` and ``p`` (also in each function's docstring).
    rhs : callable
        ``dy/dt``.
    observe : callable
        ``[energy, constraint residuals (g), computed multipliers, full velocities (n)]``.
    module : module
        The generated module (its ``__file__`` is the source), or the
        :class:`CKernel` of the ``c`` backend.
    """

    def __init__(self, layout: Layout, module: Any, backend: str) -> None:
        self.layout = layout
        self.module = module
        self.backend = backend
        self.rhs: Callable[[float, np.ndarray, np.ndarray], np.ndarray] = module.rhs
        self.observe: Callable[[float, np.ndarray, np.ndarray], np.ndarray] = module.observe
        self.n_observed = int(module.N_OBSERVED)

    def __repr__(self) -> str:
        return f"<CompiledModel {self.backend}: {self.layout.describe()}>"


def compiler() -> list[str]:
    """The C compiler command, or raise :class:`Unavailable`.

    ``$CHAPLYGIN_CC`` (a command; ``none`` switches generated C off), else
    ``$CC``, else the first of ``cc``, ``gcc``, ``clang`` on ``PATH`` (POSIX only).
    """
    if os.name != "posix":
        raise Unavailable("generated C is only built on POSIX systems")
    chosen = os.environ.get("CHAPLYGIN_CC")
    if chosen is not None:
        if chosen.strip().lower() in ("", "none", "0", "off"):
            raise Unavailable(f"CHAPLYGIN_CC={chosen!r} switches it off")
        return shlex.split(chosen)
    if os.environ.get("CC"):
        return shlex.split(os.environ["CC"])
    path = os.environ.get("PATH")
    if path not in _FOUND:  # (a search of PATH stats a dozen files: once per PATH, not per run)
        _FOUND[path] = next(filter(None, map(shutil.which, ("cc", "gcc", "clang"))), "")
    if _FOUND[path]:
        return [_FOUND[path]]
    raise Unavailable("no C compiler (cc, gcc or clang) on PATH; set CHAPLYGIN_CC")


#: the compiler :func:`compiler` found on each ``PATH`` it searched ("": none)
_FOUND: dict[str | None, str] = {}


def kernel_dir() -> Path:
    """The folder of compiled kernels."""
    return cache_dir() / "kernels"


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _discard(*paths: Path) -> None:
    for path in paths:
        try:
            path.unlink()
        except OSError:
            pass


def _verified(so: Path, record: Path, digest: str) -> bool:
    """The library exists and its bytes are the ones recorded when it was built."""
    try:
        doc = json.loads(record.read_text(encoding="utf-8"))
        return isinstance(doc, dict) and doc.get("key") == digest and doc.get("sha256") == _sha256(so)
    except (OSError, ValueError):
        return False


def _compile(
    source: str, cmd: list[str], directory: Path, so: Path, record: Path | None, digest: str
) -> None:
    """Build ``source`` into ``so`` (atomically) and record its SHA-256 in ``record`` (if any)."""
    with tempfile.TemporaryDirectory(dir=directory) as tmp:
        c_file = os.path.join(tmp, "kernel.c")
        with open(c_file, "w", encoding="utf-8") as fh:
            fh.write(source)
        out = os.path.join(tmp, "kernel.so")
        try:
            run = subprocess.run(
                [cmd[0], *FLAGS, *cmd[1:], c_file, "-o", out, "-lm"],
                capture_output=True,
                text=True,
                timeout=600,
                check=False,
            )
        except (OSError, subprocess.TimeoutExpired) as exc:
            raise Unavailable(f"the C compiler {cmd[0]!r} could not run: {exc}") from None
        if run.returncode != 0 or not os.path.exists(out):
            first = " / ".join((run.stderr or run.stdout).strip().splitlines()[:3]) or "(no output)"
            raise Unavailable(f"the C compiler {cmd[0]!r} failed (exit {run.returncode}): {first}")
        meta = os.path.join(tmp, "kernel.json")
        with open(meta, "w", encoding="utf-8") as fh:
            json.dump({"key": digest, "sha256": _sha256(Path(out)), "compiler": cmd}, fh)
        os.replace(out, so)
        if record is not None:
            os.replace(meta, record)
    STATS["built"] += 1


def _key(source: str, cmd: list[str]) -> str:
    """The key of a library: its source, the compiler command and :data:`FLAGS` (24 hex digits)."""
    return hashlib.sha256("\0".join([source, *cmd, *FLAGS]).encode()).hexdigest()[:24]


def library(source: str, stem: str) -> tuple[str, Path]:
    """``source`` built into a verified shared library of the kernel cache: ``(digest, path)``.

    ``source`` may name its symbols ``@DIGEST@``, replaced by the key's first 24
    hex digits (unique symbols for libraries loaded into one namespace).
    Raises :class:`Unavailable` when there is no compiler or it fails.
    """
    cmd = compiler()
    digest = _key(source, cmd)
    directory = kernel_dir()
    so, record = directory / f"{stem}_{digest}.so", directory / f"{stem}_{digest}.json"
    if so.exists() and _verified(so, record, digest):
        STATS["loaded"] += 1
        return digest, so
    if so.exists() or record.exists():
        STATS["discarded"] += 1
        _discard(so, record)
    directory.mkdir(parents=True, exist_ok=True)
    _compile(source.replace("@DIGEST@", digest), cmd, directory, so, record, digest)
    return digest, so


_OPENED: dict[str, ctypes.CDLL] = {}


def _open(source: str, stem: str) -> tuple[str, ctypes.CDLL]:
    """The library of ``source``, loaded; rebuilt once if the dynamic loader refuses it."""
    digest, so = library(source, stem)
    if str(so) in _OPENED:
        return digest, _OPENED[str(so)]
    try:
        lib = ctypes.CDLL(str(so))
    except OSError:
        STATS["discarded"] += 1
        _discard(so, so.with_suffix(".json"))
        digest, so = library(source, stem)
        lib = ctypes.CDLL(str(so))
    _OPENED[str(so)] = lib
    return digest, lib


# ------------------------------------------------------------------ the DOP853 loop in C
def tables() -> str:
    """The DOP853 tableau (:mod:`chaplygin.numeric._dop853`) as C arrays ``DOP_A`` … ``DOP_D``,
    each qualified by the target's ``CH_TABLE``."""
    from chaplygin.numeric import _dop853 as tab

    lines = []
    for name in ("A", "B", "C", "E3", "E5", "D"):
        flat = np.asarray(getattr(tab, name), dtype=float).ravel()
        lines.append(
            f"CH_TABLE double DOP_{name}[{flat.size}] = {{{', '.join(repr(float(v)) for v in flat)}}};"
        )
    return "\n".join(lines)


def loop_source() -> str:
    """The C source of the DOP853 loop library: :data:`DOP853` with runtime sizes, and its entries."""
    return "\n".join([_LOOP_HEAD, tables(), DOP853, _LOOP_ENTRIES])


#: The DOP853 loop, written once for every code target: this library (``c``) and the GPU kernel
#: of :mod:`chaplygin.numeric._cuda`, whose host build the suite checks against this one bit for
#: bit.  The target defines before it: the sizes ``CH_N`` (the state), ``CH_NV`` (velocities
#: solved from the constraints, ``V``), ``CH_DIM`` (the mass matrix), ``CH_NOBS``, ``CH_NREACT``
#: (computed multipliers), constants or expressions of the work space ``w`` in scope; the type
#: ``ch_work`` (``M``, ``b``, ``V``, ``O``: arrays or pointers); ``CH_FILL(w, t, y, p)``, the
#: model's fill; ``CH_FINITE(x)``; ``CH_HALTED`` (nonzero: stop at the next step, status 10);
#: ``CH_FAST`` (1: a step's stages evaluated unchecked first, see ``ch_dop853``); ``CH_DEVICE``,
#: ``CH_EVAL_ATTR`` (qualifiers), ``CH_INF`` and the tables.  A member's samples and observations
#: are written at ``[(k * CH_N + i) * stride + m]``: its own rows with stride 1 and m = 0 (here),
#: members-last arrays with stride = members (the GPU).
DOP853 = r"""
CH_DEVICE static double ch_min(double a, double b) { return a < b ? a : b; }
CH_DEVICE static double ch_max(double a, double b) { return a > b ? a : b; }

/* w->b <- M^-1 b, Gaussian elimination with partial pivoting in place; 5 if singular */
CH_DEVICE static int ch_solve(ch_work *w)
{
    const int n = CH_DIM;
    double *M = w->M, *b = w->b;
    for (int c = 0; c < n; ++c) {
        int piv = c;
        double big = fabs(M[c * n + c]);
        for (int r = c + 1; r < n; ++r)
            if (fabs(M[r * n + c]) > big) { big = fabs(M[r * n + c]); piv = r; }
        if (big == 0.0) return 5;
        if (piv != c) {
            for (int j = c; j < n; ++j) { double tmp = M[c * n + j]; M[c * n + j] = M[piv * n + j]; M[piv * n + j] = tmp; }
            double tmp = b[c]; b[c] = b[piv]; b[piv] = tmp;
        }
        for (int r = c + 1; r < n; ++r) {
            double factor = M[r * n + c] / M[c * n + c];
            for (int j = c + 1; j < n; ++j) M[r * n + j] -= factor * M[c * n + j];
            b[r] -= factor * b[c];
        }
    }
    for (int c = n - 1; c >= 0; --c) {
        double acc = b[c];
        for (int j = c + 1; j < n; ++j) acc -= M[c * n + j] * b[j];
        b[c] = acc / M[c * n + c];
    }
    return 0;
}

CH_DEVICE static void ch_fill(ch_work *w, double t, const double *y, const double *p)
{
    const int size = CH_DIM * CH_DIM;
    for (int i = 0; i < size; ++i) w->M[i] = 0.0;
    CH_FILL(w, t, y, p);
}

/* f <- [V, M^-1 F]; checked: 9 where V is not finite (a pole of the constraints), 2 where f is
   not; unchecked, a value that is not finite is left in f (see the step of ch_dop853) */
CH_EVAL_ATTR CH_DEVICE static int ch_eval(ch_work *w, double t, const double *y, const double *p, double *f,
                                          int checked)
{
    const int n = CH_N, nv = CH_NV;
    ch_fill(w, t, y, p);
    if (checked) for (int i = 0; i < nv; ++i) if (!CH_FINITE(w->V[i])) return 9;
    if (ch_solve(w) != 0) return 5;
    for (int i = 0; i < nv; ++i) f[i] = w->V[i];
    for (int i = 0; i < n - nv; ++i) f[nv + i] = w->b[i];
    if (checked) for (int i = 0; i < n; ++i) if (!CH_FINITE(f[i])) return 2;
    return 0;
}

/* the stages first .. last-1 into K; on a failure *s_out is the failing stage, else last - 1 */
CH_DEVICE static int ch_stages(ch_work *w, int first, int last, double t, double h, const double *y,
                               const double *p, double *K, double *y_stage, int *s_out, int checked)
{
    const int n = CH_N;
    for (int s = first; s < last; ++s) {
        for (int i = 0; i < n; ++i) {
            double acc = 0.0;
            for (int j = 0; j < s; ++j) acc += K[j * n + i] * DOP_A[s * 16 + j];
            y_stage[i] = y[i] + acc * h;
        }
        int code = ch_eval(w, t + DOP_C[s] * h, y_stage, p, K + s * n, checked);
        if (code != 0) { *s_out = s; return code; }
    }
    *s_out = last - 1;
    return 0;
}

CH_DEVICE static double ch_rms(ch_work *w, const double *v)
{
    const int n = CH_N;
    double s = 0.0;
    for (int i = 0; i < n; ++i) s += v[i] * v[i];
    return sqrt(s / n);
}

/* to <- from (n values), unless to is a null pointer */
CH_DEVICE static void ch_keep(double *to, const double *from, int n)
{
    if (to) for (int i = 0; i < n; ++i) to[i] = from[i];
}

/* obs[j * stride + m] <- [O..., computed multipliers, V] at (t, y); NaN multipliers where M is singular */
CH_DEVICE static void ch_observe(ch_work *w, double t, const double *y, const double *p, long m, long stride,
                                 double *obs)
{
    const int n_obs = CH_NOBS, nv = CH_NV, n_react = CH_NREACT;
    ch_fill(w, t, y, p);
    for (int j = 0; j < n_obs; ++j) obs[j * stride + m] = w->O[j];
    int first = n_obs - nv - n_react;
    if (n_react > 0) {
        int singular = ch_solve(w) != 0;
        for (int j = 0; j < n_react; ++j) obs[(first + j) * stride + m] = singular ? NAN : w->b[CH_DIM - n_react + j];
    }
    for (int j = 0; j < nv; ++j) obs[(n_obs - nv + j) * stride + m] = w->V[j];
}

/* what a run of ch_dop853 did: samples filled, status (chaplygin.numeric._loop.STATUS),
   right-hand sides, steps, the time reached, where it failed, the next step (0 after a failure) */
typedef struct {
    long filled, status, n_rhs, n_steps;
    double t, t_fail, h_next;
} ch_result;

/* SciPy's DOP853 (chaplygin.numeric._loop._k_dop853) from (t0, y) to t1: y holds the start and,
   on return, the last state reached (at r->t); samples out[(k * CH_N + i) * stride + m] at
   t_out[k] for k < r->filled (rows after a failure left as they were); first_step 0: SciPy's
   guess; max_steps 0: no budget.  K (16 n values), y_new, y_stage, f_new, scale, e5, e3 (n
   each) and F (7 n) are its scratch; y_fail (a null pointer: not kept) receives the state where it failed
   (at r->t_fail), or the last state */
CH_DEVICE static void ch_dop853(ch_work *w, double t0, double t1, double *y, const double *p, const double *t_out,
                                long n_out, double rtol, const double *atol, double max_step, double first_step,
                                long max_steps, double *out, long m, long stride, double *K, double *y_new,
                                double *y_stage, double *f_new, double *scale, double *e5, double *e3, double *F,
                                double *y_fail, ch_result *r)
{
    const int n = CH_N;
    double direction = t1 >= t0 ? 1.0 : -1.0;
    long n_rhs = 0, n_steps = 0, filled = 0;
    double t = t0, t_new = t0, t_fail = t0, h_abs = 0.0, h_next = 0.0, interval = fabs(t1 - t0);
    int status = 0, code = 0, s = 0;  /* (declared before the first goto: C++ jumps over no initialisation) */
    ch_keep(y_fail, y, n);
    while (filled < n_out && direction * (t_out[filled] - t0) <= 0.0) {
        for (int i = 0; i < n; ++i) out[(filled * n + i) * stride + m] = y[i];
        filled += 1;
    }
    code = ch_eval(w, t, y, p, K, 1);
    n_rhs += 1;
    if (code != 0) { status = code; goto done; }

    if (first_step > 0.0) h_abs = first_step;
    else if (n == 0 || interval == 0.0) h_abs = interval;
    else {
        for (int i = 0; i < n; ++i) {
            scale[i] = atol[i] + fabs(y[i]) * rtol;
            e5[i] = y[i] / scale[i];
            e3[i] = K[i] / scale[i];
        }
        double d0 = ch_rms(w, e5), d1 = ch_rms(w, e3);
        double h0 = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
        h0 = ch_min(h0, interval);
        for (int i = 0; i < n; ++i) y_stage[i] = y[i] + h0 * direction * K[i];
        code = ch_eval(w, t + h0 * direction, y_stage, p, f_new, 1);
        n_rhs += 1;
        if (code != 0) { status = code; t_fail = t + h0 * direction; ch_keep(y_fail, y_stage, n); goto done; }
        for (int i = 0; i < n; ++i) e5[i] = (f_new[i] - K[i]) / scale[i];
        double d2 = ch_rms(w, e5) / h0, h1;
        if (d1 <= 1e-15 && d2 <= 1e-15) h1 = ch_max(1e-6, h0 * 1e-3);
        else h1 = pow(0.01 / ch_max(d1, d2), 1.0 / 8.0);
        h_abs = ch_min(ch_min(100.0 * h0, h1), ch_min(interval, max_step));
    }

    while (direction * (t - t1) < 0.0) {
        if (max_steps > 0 && n_steps >= max_steps) { status = 4; break; }
        if (CH_HALTED) { status = 10; break; }
        double min_step = 10.0 * fabs(nextafter(t, direction * CH_INF) - t);
        if (h_abs > max_step) h_abs = max_step;
        else if (h_abs < min_step) h_abs = min_step;
        int rejected = 0, accepted = 0;
        double h = 0.0;
        while (!accepted) {
            if (h_abs < min_step) { status = 1; break; }
            t_new = t + h_abs * direction;
            if (direction * (t_new - t1) > 0.0) t_new = t1;
            h = t_new - t;
            h_abs = fabs(h);
            /* CH_FAST: the stages unchecked: a value that is not finite in any of K's 13 rows makes
               the error norm not finite (0 * inf is NaN), and only then is the same step evaluated
               again with the checks, which fail where the checked loop always failed (the same
               values up to there) and count what it counted; without CH_FAST, checked once */
            double error = 0.0;
            int at_end = 0;
            for (int checked = !CH_FAST;; checked = 1) {
                code = ch_stages(w, 1, 12, t, h, y, p, K, y_stage, &s, checked);
                at_end = 0;
                if (code == 0) {
                    for (int i = 0; i < n; ++i) {
                        double acc = 0.0;
                        for (int j = 0; j < 12; ++j) acc += K[j * n + i] * DOP_B[j];
                        y_new[i] = y[i] + h * acc;
                    }
                    code = ch_eval(w, t + h, y_new, p, K + 12 * n, checked);
                    at_end = 1;
                }
                if (code == 0) {
                    for (int i = 0; i < n; ++i) {
                        scale[i] = atol[i] + ch_max(fabs(y[i]), fabs(y_new[i])) * rtol;
                        double a5 = 0.0, a3 = 0.0;
                        for (int j = 0; j < 13; ++j) { a5 += K[j * n + i] * DOP_E5[j]; a3 += K[j * n + i] * DOP_E3[j]; }
                        e5[i] = a5 / scale[i];
                        e3[i] = a3 / scale[i];
                    }
                    double n5 = 0.0, n3 = 0.0;
                    for (int i = 0; i < n; ++i) { n5 += e5[i] * e5[i]; n3 += e3[i] * e3[i]; }
                    if (n5 == 0.0 && n3 == 0.0) error = 0.0;
                    else error = h_abs * n5 / sqrt((n5 + 0.01 * n3) * n);
                }
                if (checked || (code == 0 && CH_FINITE(error))) break;
            }
            n_rhs += s + at_end;
            if (code != 0) {
                status = code;
                t_fail = at_end ? t + h : t + DOP_C[s] * h;
                ch_keep(y_fail, at_end ? y_new : y_stage, n);
                goto done;
            }
            if (error < 1.0) {
                double factor = error == 0.0 ? 10.0 : ch_min(10.0, 0.9 * pow(error, -1.0 / 8.0));
                if (rejected) factor = ch_min(1.0, factor);
                h_abs *= factor;
                accepted = 1;
            } else {
                h_abs *= ch_max(0.2, 0.9 * pow(error, -1.0 / 8.0));
                rejected = 1;
            }
        }
        if (status != 0) break;
        n_steps += 1;
        if (filled < n_out && direction * (t_out[filled] - t_new) <= 0.0) {
            code = ch_stages(w, 13, 16, t, h, y, p, K, y_stage, &s, 1);
            n_rhs += s - 12;
            if (code != 0) { status = code; t_fail = t + DOP_C[s] * h; ch_keep(y_fail, y_stage, n); goto done; }
            for (int i = 0; i < n; ++i) {
                double dy = y_new[i] - y[i];
                F[0 * n + i] = dy;
                F[1 * n + i] = h * K[i] - dy;
                F[2 * n + i] = 2.0 * dy - h * (K[12 * n + i] + K[i]);
                for (int q = 0; q < 4; ++q) {
                    double acc = 0.0;
                    for (int j = 0; j < 16; ++j) acc += DOP_D[q * 16 + j] * K[j * n + i];
                    F[(3 + q) * n + i] = h * acc;
                }
            }
            while (filled < n_out && direction * (t_out[filled] - t_new) <= 0.0) {
                double x = (t_out[filled] - t) / h;
                for (int i = 0; i < n; ++i) {
                    double v = 0.0;
                    for (int q = 0; q < 7; ++q) {
                        v += F[(6 - q) * n + i];
                        v *= (q % 2 == 0) ? x : 1.0 - x;
                    }
                    out[(filled * n + i) * stride + m] = v + y[i];
                }
                filled += 1;
            }
        }
        t = t_new;
        for (int i = 0; i < n; ++i) { y[i] = y_new[i]; K[i] = K[12 * n + i]; }
    }
    h_next = h_abs;  /* where max_steps stopped the loop: the step a resumed loop starts with */
    t_fail = t;
    ch_keep(y_fail, y, n);
done:
    r->filled = filled; r->status = status; r->n_rhs = n_rhs; r->n_steps = n_steps;
    r->t = t; r->t_fail = t_fail; r->h_next = h_next;
}
"""

_LOOP_HEAD = r"""
/* chaplygin: SciPy's DOP853 as a C loop over a generated fill(t, y, p, M, F, V, O): the loop of
   chaplygin.numeric._ckernel.DOP853 with sizes known at run time and the fill called through a
   pointer (see chaplygin.numeric._ckernel). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef void (*fill_t)(double, const double *, const double *, double *, double *, double *, double *);

typedef struct {
    fill_t fill;
    int dim, nv, n_obs, n, n_react;
    double *M, *b, *V, *O;
} ch_work;

#define CH_DEVICE
#define CH_EVAL_ATTR
#define CH_TABLE static const
#define CH_INF INFINITY
#define CH_N (w->n)
#define CH_NV (w->nv)
#define CH_DIM (w->dim)
#define CH_NOBS (w->n_obs)
#define CH_NREACT (w->n_react)
#define CH_FILL(w, t, y, p) (w)->fill(t, y, p, (w)->M, (w)->b, (w)->V, (w)->O)
#define CH_FINITE(x) isfinite(x)
#define CH_FAST 1

/* set from Python on an interrupt (Ctrl-C): every running loop stops at its next step, status 10 */
static volatile int halt_requested = 0;
#define CH_HALTED halt_requested
"""

_LOOP_ENTRIES = r"""
void chaplygin_halt_@DIGEST@(int on) { halt_requested = on; }

/* a work space for states of n values (n_react: the computed multipliers observed) */
static int work_init(ch_work *w, fill_t fill, int dim, int nv, int n_obs, int n, int n_react)
{
    w->fill = fill; w->dim = dim; w->nv = nv; w->n_obs = n_obs; w->n = n; w->n_react = n_react;
    w->M = malloc(sizeof(double) * (dim * dim + dim + nv + n_obs + 1));
    if (!w->M) return 0;
    w->b = w->M + dim * dim; w->V = w->b + dim; w->O = w->V + nv;
    return 1;
}

/* info: filled, status, n_rhs, n_steps; dinfo: t, t_fail, the next step (0 after a failure);
   y_last, y_fail: n each */
int chaplygin_dop853_@DIGEST@(fill_t fill, int dim, int nv, int n_obs, int n, double t0, double t1,
                    const double *y0, const double *p, const double *t_out, long n_out, double rtol,
                    const double *atol, double max_step, double first_step, long max_steps, double *out,
                    long *info, double *dinfo, double *y_last, double *y_fail)
{
    ch_work w;
    ch_result r;
    if (!work_init(&w, fill, dim, nv, n_obs, n, 0)) return -1;
    double *K = malloc(sizeof(double) * (16 * n + 8 * n + 7 * n + 1));
    if (!K) { free(w.M); return -1; }
    double *y = K + 16 * n, *y_new = y + n, *y_stage = y_new + n, *f_new = y_stage + n;
    double *scale = f_new + n, *e5 = scale + n, *e3 = e5 + n, *F = e3 + n;
    memcpy(y, y0, sizeof(double) * n);
    ch_dop853(&w, t0, t1, y, p, t_out, n_out, rtol, atol, max_step, first_step, max_steps, out, 0, 1, K, y_new,
              y_stage, f_new, scale, e5, e3, F, y_fail, &r);
    memcpy(y_last, y, sizeof(double) * n);
    info[0] = r.filled; info[1] = r.status; info[2] = r.n_rhs; info[3] = r.n_steps;
    dinfo[0] = r.t; dinfo[1] = r.t_fail; dinfo[2] = r.h_next;
    free(K);
    free(w.M);
    return 0;
}

/* rows[k] <- observe(ts[k], ys[k], p) for k < m */
int chaplygin_observe_@DIGEST@(fill_t fill, int dim, int nv, int n_obs, int n, int n_react, long m,
                     const double *ts, const double *ys, const double *p, double *rows)
{
    ch_work w;
    if (!work_init(&w, fill, dim, nv, n_obs, n, n_react)) return -1;
    for (long k = 0; k < m; ++k) ch_observe(&w, ts[k], ys + k * n, p, 0, 1, rows + k * n_obs);
    free(w.M);
    return 0;
}

/* members start .. stop-1 of an ensemble (chaplygin.numeric._loop._k_batch): member i starts at
   Y0[i] with parameters P[i] and fills out[i] (n_out samples; rows after a failure are left as
   they were), last[i], t_last[i], status[i], n_rhs[i] and obs[i] (observe at its last state) */
int chaplygin_batch_@DIGEST@(fill_t fill, int dim, int nv, int n_obs, int n, int n_p, int n_react,
                   double t0, double t1, const double *Y0, const double *P, const double *t_out,
                   long n_out, double rtol, const double *atol, double max_step, long max_steps,
                   double *out, double *last, double *t_last, double *obs, long *status, long *n_rhs,
                   long start, long stop)
{
    ch_work w;
    if (!work_init(&w, fill, dim, nv, n_obs, n, n_react)) return -1;
    double *y_fail = malloc(sizeof(double) * (n + 1));
    if (!y_fail) { free(w.M); return -1; }
    long info[4];
    double dinfo[3];
    int rc = 0;
    for (long i = start; i < stop && rc == 0; ++i) {
        const double *p = P + i * n_p;
        rc = chaplygin_dop853_@DIGEST@(fill, dim, nv, n_obs, n, t0, t1, Y0 + i * n, p, t_out, n_out, rtol,
                             atol, max_step, 0.0, max_steps, out + i * n_out * n, info, dinfo,
                             last + i * n, y_fail);
        status[i] = info[1]; n_rhs[i] = info[2]; t_last[i] = dinfo[0];
        ch_observe(&w, dinfo[0], last + i * n, p, 0, 1, obs + i * n_obs);
    }
    free(y_fail);
    free(w.M);
    return rc;
}

/* f <- rhs(t, y, p); the kernel status (0, 2, 5) */
int chaplygin_rhs_@DIGEST@(fill_t fill, int dim, int nv, int n_obs, int n, double t, const double *y,
                 const double *p, double *f)
{
    ch_work w;
    if (!work_init(&w, fill, dim, nv, n_obs, n, 0)) return -1;
    int code = ch_eval(&w, t, y, p, f, 1);
    free(w.M);
    return code;
}
"""


# ------------------------------------------------------------------ Python side
_D = ctypes.POINTER(ctypes.c_double)
_L = ctypes.POINTER(ctypes.c_long)
_I, _LONG, _DBL, _PTR = ctypes.c_int, ctypes.c_long, ctypes.c_double, ctypes.c_void_p


def _p(a: np.ndarray) -> Any:
    return a.ctypes.data_as(_D)


class _Loop(NamedTuple):
    dop853: Any
    observe: Any
    rhs: Any
    batch: Any
    halt: Any


_LOOP: list[_Loop] = []


#: where an installation keeps the loop library it built (``setup.py``: :func:`install_loop`)
PACKAGED = Path(__file__).resolve().parent
_PACKAGED_STEM = "_dop853_loop"
#: :func:`packaged_loop`'s answer, by folder and key
_PACKAGED_FOUND: dict[tuple[Path, str], tuple[str, ctypes.CDLL] | None] = {}


def install_loop(path: Path) -> None:
    """Build the loop library into ``path`` (``setup.py`` calls it when the package is installed),
    recorded as the kernel cache records its libraries, in ``_dop853_loop.json`` beside it.

    Its key (and its symbols') is the one :func:`library` would give it (source, compiler
    command, :data:`FLAGS`), so that :func:`packaged_loop` uses it only while all three are
    unchanged, and only while its bytes are the ones recorded.
    """
    cmd, source = compiler(), loop_source()
    digest = _key(source, cmd)
    path.parent.mkdir(parents=True, exist_ok=True)
    record = path.parent / f"{_PACKAGED_STEM}.json"
    _compile(source.replace("@DIGEST@", digest), cmd, path.parent, path, record, digest)


def packaged_loop() -> tuple[str, ctypes.CDLL] | None:
    """The loop library built when the package was installed, if it is there, its bytes are the
    ones recorded then (not a truncated or edited file, which the loader could crash on) and it
    is the one this process would build (same source, compiler command and flags); else None."""
    digest = _key(loop_source(), compiler())
    if (PACKAGED, digest) not in _PACKAGED_FOUND:
        found = None
        record = PACKAGED / f"{_PACKAGED_STEM}.json"
        for path in sorted(PACKAGED.glob(_PACKAGED_STEM + ".*")):
            if path.suffix not in (".so", ".dylib") or not _verified(path, record, digest):
                continue
            try:
                found = digest, ctypes.CDLL(str(path))
                break
            except OSError:  # not a library this system loads: the kernel cache builds one
                continue
        _PACKAGED_FOUND[PACKAGED, digest] = found
    return _PACKAGED_FOUND[PACKAGED, digest]


def loop() -> _Loop:
    """The loop library's functions: the installation's (:func:`packaged_loop`), else built into
    the kernel cache once."""
    if not _LOOP:
        digest, lib = packaged_loop() or _open(loop_source(), "dop853")
        dop = getattr(lib, f"chaplygin_dop853_{digest}")
        dop.argtypes = [
            _PTR,
            _I,
            _I,
            _I,
            _I,
            _DBL,
            _DBL,
            _D,
            _D,
            _D,
            _LONG,
            _DBL,
            _D,
            _DBL,
            _DBL,
            _LONG,
            _D,
            _L,
            _D,
            _D,
            _D,
        ]
        obs = getattr(lib, f"chaplygin_observe_{digest}")
        obs.argtypes = [_PTR, _I, _I, _I, _I, _I, _LONG, _D, _D, _D, _D]
        rhs = getattr(lib, f"chaplygin_rhs_{digest}")
        rhs.argtypes = [_PTR, _I, _I, _I, _I, _DBL, _D, _D, _D]
        batch = getattr(lib, f"chaplygin_batch_{digest}")
        batch.argtypes = [_PTR, _I, _I, _I, _I, _I, _I, _DBL, _DBL, _D, _D, _D, _LONG, _DBL, _D, _DBL, _LONG]
        batch.argtypes += [_D, _D, _D, _D, _L, _L, _LONG, _LONG]
        for fn in (dop, obs, rhs, batch):
            fn.restype = _I
        halt = getattr(lib, f"chaplygin_halt_{digest}")
        halt.argtypes, halt.restype = [_I], None
        _LOOP.append(_Loop(dop, obs, rhs, batch, halt))
    return _LOOP[0]


class LoopOutput(NamedTuple):
    """What :meth:`CKernel.integrate` returns: the numba kernel ``_k_dop853``'s results, and the samples."""

    out: np.ndarray
    filled: int
    code: int
    t: float
    y: np.ndarray
    n_rhs: int
    n_steps: int
    t_fail: float
    y_fail: np.ndarray
    h_next: float


class CKernel:
    """One model's C ``fill`` with the C loop: the ``module`` of a ``c``-backend model.

    Attributes ``DIM``, ``N``, ``K``, ``N_OBSERVED`` are those of the generated
    Python module; :meth:`rhs` and :meth:`observe` take ``(t, y, p)``.
    """

    def __init__(self, fill_source: str, dim: int, n: int, k: int, n_observed: int, n_react: int) -> None:
        self.fill_source = fill_source
        digest, lib = _open(fill_source, "fill")
        self.__file__ = str(kernel_dir() / f"fill_{digest}.so")
        self._fill = ctypes.cast(getattr(lib, f"chaplygin_fill_{digest}"), ctypes.c_void_p).value
        self.DIM, self.N, self.K, self.N_OBSERVED = dim, n, k, n_observed
        self.n_react = n_react
        self._loop = loop()

    def _shape(self) -> tuple[Any, int, int, int]:
        return self._fill, self.DIM, self.N, self.N_OBSERVED

    def rhs(self, t: float, y: np.ndarray, p: np.ndarray) -> np.ndarray:
        """``dy/dt``; raises ``LinAlgError`` at a singular mass matrix (as numpy's solve)."""
        y = np.ascontiguousarray(y, dtype=float)
        p = np.ascontiguousarray(p, dtype=float)
        f = np.empty(self.N + self.K)
        code = self._loop.rhs(*self._shape(), f.size, float(t), _p(y), _p(p), _p(f))
        if code == 5:
            raise np.linalg.LinAlgError("Matrix is singular.")
        return f

    def observe(self, t: float, y: np.ndarray, p: np.ndarray) -> np.ndarray:
        """``[energy, residuals, computed multipliers, velocities]`` (NaN multipliers where M is singular)."""
        return self.observe_many(np.array([float(t)]), np.asarray(y, dtype=float)[None, :], p)[0]

    def observe_many(self, ts: np.ndarray, ys: np.ndarray, p: np.ndarray) -> np.ndarray:
        """:meth:`observe` at every ``(ts[k], ys[k])``, one row each."""
        ts = np.ascontiguousarray(ts, dtype=float)
        ys = np.ascontiguousarray(ys, dtype=float).reshape(len(ts), -1)
        p = np.ascontiguousarray(p, dtype=float)
        rows = np.empty((len(ts), self.N_OBSERVED))
        if len(ts):
            self._loop.observe(
                *self._shape(), ys.shape[1], self.n_react, len(ts), _p(ts), _p(ys), _p(p), _p(rows)
            )
        return rows

    def batch(
        self,
        t0: float,
        t1: float,
        Y0: np.ndarray,
        P: np.ndarray,
        t_out: np.ndarray,
        rtol: float,
        atol: np.ndarray,
        max_step: float,
        max_steps: int,
        out: np.ndarray,
        last: np.ndarray,
        t_last: np.ndarray,
        obs: np.ndarray,
        status: np.ndarray,
        n_rhs: np.ndarray,
        start: int,
        stop: int,
    ) -> None:
        """Members ``start … stop-1`` of an ensemble, into the given arrays (as the numba kernel
        ``_k_batch``; C-contiguous float64 arrays, int64 ``status``/``n_rhs``, checked by the
        caller).  The GIL is released while it runs (ctypes)."""
        if (
            self._loop.batch(
                *self._shape(),
                Y0.shape[1],
                P.shape[1],
                self.n_react,
                float(t0),
                float(t1),
                _p(Y0),
                _p(P),
                _p(t_out),
                t_out.size,
                float(rtol),
                _p(atol),
                float(max_step),
                int(max_steps),
                _p(out),
                _p(last),
                _p(t_last),
                _p(obs),
                status.ctypes.data_as(_L),
                n_rhs.ctypes.data_as(_L),
                int(start),
                int(stop),
            )
            != 0
        ):
            raise MemoryError("the C loop could not allocate its work space")

    def halt(self, on: bool) -> None:
        """Ask every running C loop to stop at its next step (status 10), or no longer."""
        self._loop.halt(int(on))

    def integrate(
        self,
        t0: float,
        t1: float,
        y0: np.ndarray,
        p: np.ndarray,
        times: np.ndarray,
        rtol: float,
        atol: np.ndarray,
        max_step: float,
        first_step: float,
        max_steps: int,
    ) -> LoopOutput:
        """The C DOP853 loop from ``(t0, y0)`` to ``t1`` sampled at ``times`` (arguments validated by the caller)."""
        y0 = np.ascontiguousarray(y0, dtype=float)
        p = np.ascontiguousarray(p, dtype=float)
        times = np.ascontiguousarray(times, dtype=float)
        atol = np.ascontiguousarray(atol, dtype=float)
        n = y0.size
        out = np.empty((times.size, n))
        info = np.zeros(4, dtype=np.int64)
        dinfo = np.zeros(3)
        y_last, y_fail = np.empty(n), np.empty(n)
        if (
            self._loop.dop853(
                *self._shape(),
                n,
                float(t0),
                float(t1),
                _p(y0),
                _p(p),
                _p(times),
                times.size,
                float(rtol),
                _p(atol),
                float(max_step),
                float(first_step),
                int(max_steps),
                _p(out),
                info.ctypes.data_as(_L),
                _p(dinfo),
                _p(y_last),
                _p(y_fail),
            )
            != 0
        ):
            raise MemoryError("the C loop could not allocate its work space")
        filled = int(info[0])
        return LoopOutput(
            out[:filled],
            filled,
            int(info[1]),
            float(dinfo[0]),
            y_last,
            int(info[2]),
            int(info[3]),
            float(dinfo[1]),
            y_fail,
            float(dinfo[2]),
        )
