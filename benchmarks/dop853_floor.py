"""The floor of chaplygin's C loop: a minimal hand-written DOP853 in C on the same right-hand side.

Run from the repository root::

    .venv/bin/python benchmarks/dop853_floor.py            # t = 100 and 1000, 7 repeats
    .venv/bin/python benchmarks/dop853_floor.py --quick    # t = 100, 3 repeats

What is compared (issue 31: "the loop's per-step work within 1.2× a hand-written DOP853 loop
on the same right-hand side"):

- **the fill alone**: the generated ``fill(t, y, p, M, F, V, O)`` of the model, called through
  the function pointer of chaplygin's own compiled library (the same machine code the loop
  calls), in a C loop: ns per call;
- **the right-hand side**: what one evaluation needs besides the fill, and the hand loop does
  too: ``M`` zeroed, ``fill``, ``M x = F`` solved by Gaussian elimination with partial pivoting
  (the multiplier models solve their (n + g)-square KKT system, the reduced ones their ε × ε
  mass matrix), ``f = [V, x]``;
- **the hand loop**: SciPy's DOP853 written out plainly in C (the fixed tableau of
  :mod:`chaplygin.numeric._dop853`, SciPy's initial step, error norm and step-size controller,
  the three extra stages and the dense output only in steps that hold a requested time), with
  no failure codes, no finiteness checks, no interruption and no stretches; built by the same
  compiler with the same flags (:data:`chaplygin.numeric._ckernel.FLAGS`) and calling the fill
  through the same pointer;
- **chaplygin's loop**: the C loop of the ``c`` backend (:mod:`chaplygin.numeric._ckernel`),
  called once for the whole span, as :func:`chaplygin.simulate` runs it (which calls it in
  stretches of steps; a stretch costs one right-hand side more).

Both loops take the same steps: their right-hand-side counts and samples are compared (they
agree to round-off).  The figures are ns per right-hand side (wall time of the run / count),
best and median of the repeats, interleaved (hand, chaplygin, hand, …), with the load average.
Times are this thread's CPU time (:func:`time.thread_time`): on a shared machine the wall time
also counts the time the process waits for a core.
"""

from __future__ import annotations

import argparse
import ctypes
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))  # this working tree, also when not installed

import chaplygin
from chaplygin import examples
from chaplygin.numeric import _dop853 as tableau
from chaplygin.numeric._ckernel import FLAGS, compiler, library
from chaplygin.numeric.codegen import compile_model, parameter_vector
from chaplygin.numeric.simulate import _parameters, initial_state

RTOL, ATOL, SAMPLES = 1e-10, 1e-12, 1001
DISK_P = {"m": 1.0, "r": 0.5, "A": 0.0625, "C": 0.125, "g": 9.81}
DISK_0 = {"psi": 0.0, "theta": 0.3, "phi": 0.0, "x": 0.0, "y": 0.0, "psi'": 2.0, "theta'": 0.0, "phi'": 5.0}

HAND_C = r"""
/* A minimal DOP853 (SciPy's) over a generated fill, for benchmarks/dop853_floor.py. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef void (*fill_t)(double, const double *, const double *, double *, double *, double *, double *);

@TABLES@

typedef struct { fill_t fill; int dim, nv; double *M, *b, *V, *O; } model_t;

/* b <- M^-1 b: Gaussian elimination with partial pivoting (what the model needs) */
static void solve(int n, double *M, double *b)
{
    for (int c = 0; c < n; ++c) {
        int piv = c;
        double big = fabs(M[c * n + c]);
        for (int r = c + 1; r < n; ++r) if (fabs(M[r * n + c]) > big) { big = fabs(M[r * n + c]); piv = r; }
        if (piv != c) {
            for (int j = c; j < n; ++j) { double s = M[c * n + j]; M[c * n + j] = M[piv * n + j]; M[piv * n + j] = s; }
            double s = b[c]; b[c] = b[piv]; b[piv] = s;
        }
        for (int r = c + 1; r < n; ++r) {
            double f = M[r * n + c] / M[c * n + c];
            for (int j = c + 1; j < n; ++j) M[r * n + j] -= f * M[c * n + j];
            b[r] -= f * b[c];
        }
    }
    for (int c = n - 1; c >= 0; --c) {
        double s = b[c];
        for (int j = c + 1; j < n; ++j) s -= M[c * n + j] * b[j];
        b[c] = s / M[c * n + c];
    }
}

static void rhs(const model_t *m, double t, const double *y, const double *p, double *f, int n)
{
    memset(m->M, 0, sizeof(double) * m->dim * m->dim);
    m->fill(t, y, p, m->M, m->b, m->V, m->O);
    solve(m->dim, m->M, m->b);
    memcpy(f, m->V, sizeof(double) * m->nv);
    memcpy(f + m->nv, m->b, sizeof(double) * (n - m->nv));
}

static double rms(const double *v, int n)
{
    double s = 0.0;
    for (int i = 0; i < n; ++i) s += v[i] * v[i];
    return sqrt(s / n);
}

/* the fill alone, reps times at (t, y): for the ns per call */
void bench_fill(fill_t fill, int dim, int nv, int n_obs, long reps, double t, const double *y, const double *p)
{
    double *M = calloc(dim * dim + dim + nv + n_obs + 1, sizeof(double));
    for (long r = 0; r < reps; ++r) fill(t, y, p, M, M + dim * dim, M + dim * dim + dim, M + dim * dim + dim + nv);
    free(M);
}

/* the right-hand side (zero M, fill, solve, copy), reps times at (t, y) */
void bench_rhs(fill_t fill, int dim, int nv, int n_obs, int n, long reps, double t, const double *y,
               const double *p, double *f)
{
    double *M = calloc(dim * dim + dim + nv + n_obs + 1, sizeof(double));
    model_t m = {fill, dim, nv, M, M + dim * dim, M + dim * dim + dim, M + dim * dim + dim + nv};
    for (long r = 0; r < reps; ++r) rhs(&m, t, y, p, f, n);
    free(M);
}

/* SciPy's DOP853 from (t0, y0) to t1 > t0, sampled at t_out (increasing, within [t0, t1]) into
   out; returns the number of right-hand sides */
long hand_dop853(fill_t fill, int dim, int nv, int n_obs, int n, double t0, double t1, const double *y0,
                 const double *p, const double *t_out, long n_out, double rtol, double atol, double *out)
{
    double *M = calloc(dim * dim + dim + nv + n_obs + 1, sizeof(double));
    model_t m = {fill, dim, nv, M, M + dim * dim, M + dim * dim + dim, M + dim * dim + dim + nv};
    double *K = malloc(sizeof(double) * 16 * n), *y = malloc(sizeof(double) * 6 * n);
    double *y_new = y + n, *ys = y_new + n, *sc = ys + n, *e5 = sc + n, *e3 = e5 + n;
    double *F = malloc(sizeof(double) * 7 * n);
    long n_rhs = 0, k = 0;
    double t = t0;
    memcpy(y, y0, sizeof(double) * n);
    while (k < n_out && t_out[k] <= t0) { memcpy(out + k * n, y0, sizeof(double) * n); ++k; }
    rhs(&m, t, y, p, K, n); ++n_rhs;
    /* the initial step (SciPy's select_initial_step) */
    for (int i = 0; i < n; ++i) { sc[i] = atol + fabs(y[i]) * rtol; e5[i] = y[i] / sc[i]; e3[i] = K[i] / sc[i]; }
    double d0 = rms(e5, n), d1 = rms(e3, n), h0 = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
    if (h0 > t1 - t0) h0 = t1 - t0;
    for (int i = 0; i < n; ++i) ys[i] = y[i] + h0 * K[i];
    rhs(&m, t + h0, ys, p, y_new, n); ++n_rhs;
    for (int i = 0; i < n; ++i) e5[i] = (y_new[i] - K[i]) / sc[i];
    double d2 = rms(e5, n) / h0, big = d1 > d2 ? d1 : d2;
    double h1 = (d1 <= 1e-15 && d2 <= 1e-15) ? fmax(1e-6, h0 * 1e-3) : pow(0.01 / big, 1.0 / 8.0);
    double h_abs = fmin(fmin(100.0 * h0, h1), t1 - t0);
    while (t < t1) {
        double min_step = 10.0 * (nextafter(t, INFINITY) - t), h, t_new, error;
        if (h_abs < min_step) h_abs = min_step;
        int rejected = 0;
        for (;;) {  /* a step, repeated with a smaller h until accepted */
            t_new = t + h_abs;
            if (t_new > t1) t_new = t1;
            h = t_new - t;
            h_abs = fabs(h);
            for (int s = 1; s < 12; ++s) {
                for (int i = 0; i < n; ++i) {
                    double a = 0.0;
                    for (int j = 0; j < s; ++j) a += K[j * n + i] * HA[s * 16 + j];
                    ys[i] = y[i] + a * h;
                }
                rhs(&m, t + HC[s] * h, ys, p, K + s * n, n);
            }
            for (int i = 0; i < n; ++i) {
                double a = 0.0;
                for (int j = 0; j < 12; ++j) a += K[j * n + i] * HB[j];
                y_new[i] = y[i] + h * a;
            }
            rhs(&m, t_new, y_new, p, K + 12 * n, n);
            n_rhs += 12;
            double n5 = 0.0, n3 = 0.0;
            for (int i = 0; i < n; ++i) {
                double s = atol + fmax(fabs(y[i]), fabs(y_new[i])) * rtol, a5 = 0.0, a3 = 0.0;
                for (int j = 0; j < 13; ++j) { a5 += K[j * n + i] * HE5[j]; a3 += K[j * n + i] * HE3[j]; }
                n5 += (a5 / s) * (a5 / s);
                n3 += (a3 / s) * (a3 / s);
            }
            error = (n5 == 0.0 && n3 == 0.0) ? 0.0 : h_abs * n5 / sqrt((n5 + 0.01 * n3) * n);
            if (error < 1.0) {
                double factor = error == 0.0 ? 10.0 : fmin(10.0, 0.9 * pow(error, -1.0 / 8.0));
                h_abs *= rejected ? fmin(1.0, factor) : factor;
                break;
            }
            h_abs *= fmax(0.2, 0.9 * pow(error, -1.0 / 8.0));
            rejected = 1;
        }
        if (k < n_out && t_out[k] <= t_new) {  /* dense output: three more stages */
            for (int s = 13; s < 16; ++s) {
                for (int i = 0; i < n; ++i) {
                    double a = 0.0;
                    for (int j = 0; j < s; ++j) a += K[j * n + i] * HA[s * 16 + j];
                    ys[i] = y[i] + a * h;
                }
                rhs(&m, t + HC[s] * h, ys, p, K + s * n, n);
            }
            n_rhs += 3;
            for (int i = 0; i < n; ++i) {
                double dy = y_new[i] - y[i];
                F[i] = dy;
                F[n + i] = h * K[i] - dy;
                F[2 * n + i] = 2.0 * dy - h * (K[12 * n + i] + K[i]);
                for (int r = 0; r < 4; ++r) {
                    double a = 0.0;
                    for (int j = 0; j < 16; ++j) a += HD[r * 16 + j] * K[j * n + i];
                    F[(3 + r) * n + i] = h * a;
                }
            }
            for (; k < n_out && t_out[k] <= t_new; ++k) {
                double x = (t_out[k] - t) / h;
                for (int i = 0; i < n; ++i) {
                    double v = 0.0;
                    for (int r = 0; r < 7; ++r) { v += F[(6 - r) * n + i]; v *= (r % 2 == 0) ? x : 1.0 - x; }
                    out[k * n + i] = v + y[i];
                }
            }
        }
        t = t_new;
        memcpy(y, y_new, sizeof(double) * n);
        memcpy(K, K + 12 * n, sizeof(double) * n);
    }
    free(F); free(y); free(K); free(M);
    return n_rhs;
}
"""


def _array(name: str, values: object) -> str:
    flat = np.asarray(values, dtype=float).ravel()
    return f"static const double {name}[{flat.size}] = {{{', '.join(repr(float(v)) for v in flat)}}};"


def hand_library() -> ctypes.CDLL:
    """The hand loop, built into the kernel cache by chaplygin's compiler and flags."""
    tables = [_array(n, getattr(tableau, k)) for n, k in [("HA", "A"), ("HB", "B"), ("HC", "C")]] + [
        _array(n, getattr(tableau, k)) for n, k in [("HE3", "E3"), ("HE5", "E5"), ("HD", "D")]
    ]
    _, so = library(HAND_C.replace("@TABLES@", "\n".join(tables)), "dop853_floor")
    lib = ctypes.CDLL(str(so))
    D, P, I, L, F = (
        ctypes.POINTER(ctypes.c_double),
        ctypes.c_void_p,
        ctypes.c_int,
        ctypes.c_long,
        ctypes.c_double,
    )
    lib.bench_fill.argtypes = [P, I, I, I, L, F, D, D]
    lib.bench_rhs.argtypes = [P, I, I, I, I, L, F, D, D, D]
    lib.hand_dop853.argtypes = [P, I, I, I, I, F, F, D, D, D, L, F, F, D]
    lib.hand_dop853.restype = L
    for fn in (lib.bench_fill, lib.bench_rhs):
        fn.restype = None
    return lib


def _p(a: np.ndarray) -> object:
    return a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


def problems() -> list[tuple[str, object, str, dict[str, float], dict[str, float]]]:
    board = chaplygin.load(ROOT / "benchmarks" / "systems" / "snakeboard_spring.toml")
    disk = examples.rolling_disk()
    return [
        ("snakeboard", board.system, model, dict(board.initial), dict(board.parameters))
        for model in ("chetaev", "chaplygin")
    ] + [("rolling disk", disk, model, DISK_0, DISK_P) for model in ("chetaev", "chaplygin")]


def measure(lib: ctypes.CDLL, system, model, start, values, t_ends, repeats) -> list[dict[str, object]]:
    params = _parameters(system, values)
    compiled = compile_model(system, model, "classic", "c")
    kernel = compiled.module
    q, qd = initial_state(system, start, params, 0.0)
    reduced = len(compiled.layout.velocities) < system.n
    y0 = np.concatenate([q, qd[list(system._ind)] if reduced else qd])
    p = parameter_vector(compiled.layout, params)
    n, dim, nv, n_obs = y0.size, kernel.DIM, kernel.N, kernel.N_OBSERVED - 0
    shape = (kernel._fill, dim, nv, n_obs)
    f = np.empty(n)
    reps = 200_000
    fill_ns = min(_timed(lambda: lib.bench_fill(*shape, reps, 0.0, _p(y0), _p(p))) for _ in range(5)) / reps
    rhs_ns = min(_timed(lambda: lib.bench_rhs(*shape, n, reps, 0.0, _p(y0), _p(p), _p(f))) for _ in range(5))
    rhs_ns /= reps
    rows = []
    for t1 in t_ends:
        times = np.linspace(0.0, t1, SAMPLES)
        atol = np.full(n, ATOL)
        hand_out = np.empty((SAMPLES, n))
        hand, ours = [], []
        counts = {}
        for _ in range(repeats):  # interleaved
            start_t = time.thread_time()
            counts["hand"] = lib.hand_dop853(
                *shape, n, 0.0, t1, _p(y0), _p(p), _p(times), SAMPLES, RTOL, ATOL, _p(hand_out)
            )
            hand.append(time.thread_time() - start_t)
            start_t = time.thread_time()
            res = kernel.integrate(0.0, t1, y0, p, times, RTOL, atol, np.inf, 0.0, 0)
            ours.append(time.thread_time() - start_t)
            counts["chaplygin"] = res.n_rhs
        assert res.code == 0 and res.filled == SAMPLES, res
        scale = np.max(np.abs(res.out), axis=0) + 1.0
        rows.append(
            {
                "t": t1,
                "rhs": counts,
                "fill ns": fill_ns,
                "rhs ns": rhs_ns,
                "hand ns/rhs": [
                    min(hand) / counts["hand"] * 1e9,
                    statistics.median(hand) / counts["hand"] * 1e9,
                ],
                "chaplygin ns/rhs": [
                    min(ours) / counts["chaplygin"] * 1e9,
                    statistics.median(ours) / counts["chaplygin"] * 1e9,
                ],
                "samples differ by": float(np.max(np.abs(res.out - hand_out) / scale)),
            }
        )
    return rows


def _timed(fn) -> float:
    start = time.thread_time()
    fn()
    return (time.thread_time() - start) * 1e9


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="t = 100 only, 3 repeats")
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    t_ends = (100.0,) if args.quick else (100.0, 1000.0)
    repeats = 3 if args.quick else args.repeats
    lib = hand_library()
    print(f"compiler {' '.join(compiler())} {' '.join(FLAGS)}")
    print(
        f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}; rtol {RTOL:g}, atol {ATOL:g}, {SAMPLES} samples"
    )
    print(
        f"{'system':13s} {'model':10s} {'t':>6s} {'RHS':>7s} {'fill':>5s} {'RHS':>5s} "
        f"{'hand loop':>11s} {'chaplygin':>11s} {'ratio':>9s} {'loop work':>9s} {'samples':>8s}"
    )
    print(
        f"{'':13s} {'':10s} {'':>6s} {'count':>7s} {'ns':>5s} {'ns':>5s} {'ns/RHS':>11s} {'ns/RHS':>11s} "
        f"{'':>9s} {'ns/RHS':>9s} {'differ':>8s}"
    )
    for name, system, model, start, values in problems():
        for row in measure(lib, system, model, start, values, t_ends, repeats):
            hand, ours = row["hand ns/rhs"], row["chaplygin ns/rhs"]
            count = row["rhs"]
            shown = f"{count['chaplygin']}" + (
                "" if count["hand"] == count["chaplygin"] else f"≠{count['hand']}"
            )
            work = f"{hand[0] - row['rhs ns']:.0f}/{ours[0] - row['rhs ns']:.0f}"
            print(
                f"{name:13s} {model:10s} {row['t']:6g} {shown:>7s} {row['fill ns']:5.0f} {row['rhs ns']:5.0f} "
                f"{hand[0]:5.0f}/{hand[1]:<5.0f} {ours[0]:5.0f}/{ours[1]:<5.0f} "
                f"{ours[0] / hand[0]:4.2f}/{ours[1] / hand[1]:<4.2f} {work:>9s} {row['samples differ by']:8.1e}"
            )
    print(
        "ns per RHS: best/median of the repeats (CPU time); ratio: chaplygin's loop / the hand loop; loop "
        "work: the loop's ns per RHS less the RHS's own (hand/chaplygin, best)"
    )
    print(f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
