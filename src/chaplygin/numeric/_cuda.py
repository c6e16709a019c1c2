"""The ``cuda`` ensemble backend: one GPU thread per member, DOP853 with its own steps.

Why one kernel per model, one thread per member
-----------------------------------------------
``backend="jax"`` steps every member in lock-step under ``jax.vmap``: one kernel launch per
stage, every intermediate through global memory.  Here, as DiffEqGPU.jl does, the model is
compiled into one kernel in which each thread integrates one member from start to end with its
own adaptive step size, its state and stages in its own (register or cached local) memory.
The kernel is C: the model's generated ``fill`` (:mod:`chaplygin.numeric._cfill`, exactly the
source of the ``c`` backend) becomes a ``__device__`` function, and the DOP853 loop is the C
loop's own source, :data:`chaplygin.numeric._ckernel.DOP853` (a port of
:func:`chaplygin.numeric._loop._k_dop853`, SciPy's ``DOP853``), with the sizes compile-time
constants, the fill called directly, members-last arrays and every stage checked: the same
tableau, step-size controller, error norm, first-step guess, dense output at the requested
times, Gaussian elimination with partial pivoting, and failure codes
(:data:`chaplygin.numeric._loop.STATUS`: 1 step underflow, 2 a non-finite derivative, 4 the
step budget, 5 a singular mass matrix, 9 a non-finite velocity solved from the constraints).
Float64 throughout.

It is compiled by NVRTC through CuPy (``pip install 'chaplygin[cuda]'``): no CUDA toolkit
besides the driver and the NVRTC that CuPy's wheels bring, no numba-cuda (whose CUDA target
would compile the Python ``fill`` line by line, slowly for large models, and whose simulator
runs the kernel's Python, not its C).  NVRTC contracts into fused multiply-adds (``fmad``, its
default): on an H100 the rattleback's 10⁵ members ran 1.3× faster so (the rolling disk's as fast
either way), and they end as the C loop's do to 8·10⁻¹¹ of max(1, |y|) at t = 1 (2·10⁻¹¹
without), the statuses the same.  ``DeviceKernel(fmad=False)`` keeps the host build's arithmetic
(``-ffp-contract=off``), so that the results differ from the C loop's only by the last bits of
the device's ``sin``, ``pow``, … .

The same source, without a GPU
------------------------------
:func:`kernel_source` is C that also compiles with the host's C compiler
(:func:`chaplygin.numeric._ckernel.compiler`, :data:`~chaplygin.numeric._ckernel.FLAGS`):
``__CUDACC__`` (defined by NVRTC) selects ``__device__``/``__constant__`` and an
``extern "C" __global__`` entry in which a thread is a member; without it, a host function loops
over the members.  So the suite, which has no GPU, runs this very kernel source on the CPU
(:class:`HostKernel`) and checks it against the C loop: the same steps, the same numbers to
the last bit, the same statuses.

Layout
------
Members are the fastest index of every array the kernel reads or writes (struct of arrays):
``Y0[i * members + m]``, ``P[j * members + m]``, ``out[(k * n + i) * members + m]``, … , so
that the threads of a warp, neighbouring members, read and write neighbouring addresses.  The
driver of a run transposes each chunk's arrays on the host (NumPy; :meth:`DeviceKernel.observe`
on the device).  A large ensemble runs in chunks (:data:`PIECES`, and as many
as a share of the device's free memory needs, :data:`MEMORY_SHARE`), each launched on one of two
CUDA streams before the chunk before it is downloaded, so that the transfers overlap the kernels.
"""

from __future__ import annotations

import ctypes
import hashlib
import math
import time
from typing import Any

import numpy as np

from chaplygin.errors import ChaplyginError
from chaplygin.numeric import _ckernel
from chaplygin.numeric._ckernel import CKernel, CompiledModel, kernel_dir
from chaplygin.numeric._dop853 import tolerances

__all__ = [
    "AUTO_MEMBERS",
    "BLOCK",
    "INSTALL",
    "CudaModel",
    "DeviceKernel",
    "HostKernel",
    "block_size",
    "device_problem",
    "kernel_source",
    "launch",
]

#: ``backend="auto"`` takes the GPU from this many members on.  An H100 keeps about 270 000
#: threads resident (132 SMs × 2 048); below some 10⁴ members most of it idles while a launch,
#: two transfers and the transposes still cost milliseconds, and 16 CPU cores finish 10⁴ rolling
#: disks to t = 1 in about 0.1 s (issue 32's table: 34 900 members/s), so the GPU cannot win much.
AUTO_MEMBERS = 10_000
#: threads per block (at most: :func:`block_size`)
BLOCK = 128
#: the share of the device's free memory the chunks of members on it at a time may take
MEMORY_SHARE = 0.4
#: an ensemble runs in PIECES chunks (fewer where it has fewer than PIECE_MEMBERS members a chunk;
#: more where the device's free memory needs them), each launched before the one before it is
#: downloaded (two CUDA streams): the transfers of all but the first and the last chunk overlap
#: the kernels.  (On an H100, 10⁶ rolling disks: 0.45 s of kernel,
#: 0.05–0.16 s of download, 0.02 s of upload, one after the other in a single chunk.)
PIECES = 8
PIECE_MEMBERS = 125_000
#: how to get what the backend needs
INSTALL = (
    "pip install 'chaplygin[cuda]' (CuPy for CUDA 12, cupy-cuda12x; for CUDA 13 install "
    "cupy-cuda13x instead) on a machine with an NVIDIA GPU and its driver"
)

_PRELUDE = r"""/* chaplygin: DOP853, one thread per ensemble member (chaplygin.numeric._cuda).
   The same source builds for a GPU (NVRTC: __CUDACC__) and for the host (a loop over members). */
#ifdef __CUDACC__
#define CH_DEVICE __device__
#define CH_TABLE __constant__
#define CH_INF __longlong_as_double(0x7ff0000000000000LL)
#ifndef NAN
#define NAN __longlong_as_double(0x7ff8000000000000LL)
#endif
#ifndef INFINITY
#define INFINITY CH_INF
#endif
/* the right-hand side (fill and solve) inlined at each of its call sites: on an H100 the rolling
   disk's 10^6 members ran in 0.70 s so against 1.07 s with one called copy (-DCH_CALL_EVAL: fewer
   registers, no spills, a smaller kernel; the rattleback ran alike both ways) */
#ifdef CH_CALL_EVAL
#define CH_EVAL_ATTR __noinline__
#else
#define CH_EVAL_ATTR
#endif
/* pow(x, 2) of the fill as x * x (the library's pow is a call of some 150 instructions with
   spills; x * x is exact to the rounding); -DCH_LIBRARY_POW keeps the library's */
#ifndef CH_LIBRARY_POW
CH_DEVICE static inline double ch_pow(double x, double y) { return pow(x, y); }
CH_DEVICE static inline double ch_pow(double x, int n) { return n == 2 ? x * x : pow(x, (double)n); }
#define pow ch_pow
#endif
#else
#define CH_EVAL_ATTR
#include <math.h>
#define CH_DEVICE
#define CH_TABLE static const
#define CH_INF INFINITY
#endif
/* finite: x - x is 0 for a finite x, NaN for an infinite or NaN one (IEEE, no fast-math) */
#define CH_FINITE(x) ((x) - (x) == 0.0)
/* the loop of chaplygin.numeric._ckernel.DOP853: no interruption, every stage checked */
#define CH_HALTED 0
#define CH_FAST 0
"""

#: a member's work space (the sizes are constants) and the fill called directly
_WORK = r"""
typedef struct {
    double M[CH_DIM * CH_DIM + 1], b[CH_DIM + 1], V[CH_NV + 1], O[CH_NOBS + 1];
} ch_work;
#define CH_FILL(w, t, y, p) chaplygin_fill(t, y, p, (w)->M, (w)->b, (w)->V, (w)->O)
"""

_MEMBERS = r"""
/* member m of stride members (chaplygin_batch of the C loop, first_step 0): from Y0[:, m] with
   parameters P[:, m] to t1, samples out[k, :, m] at t_out[k] (NaN from a failure on), the last
   state reached last[:, m] at t_last[m], status[m], n_rhs[m] and obs[:, m] (observe there) */
CH_DEVICE static void ch_member(long m, long stride, double t0, double t1, const double *Y0,
                                const double *P, const double *t_out, long n_out, double rtol,
                                const double *atol, double max_step, long max_steps, double *out,
                                double *last, double *t_last, double *obs, long long *status_out,
                                long long *n_rhs_out)
{
    ch_work w;
    ch_result r;
    double p[CH_NP + 1], K[16 * CH_N], y[CH_N], y_new[CH_N], y_stage[CH_N], f_new[CH_N];
    double scale[CH_N], e5[CH_N], e3[CH_N], F[7 * CH_N];
    for (int j = 0; j < CH_NP; ++j) p[j] = P[j * stride + m];
    for (int i = 0; i < CH_N; ++i) y[i] = Y0[i * stride + m];
    ch_dop853(&w, t0, t1, y, p, t_out, n_out, rtol, atol, max_step, 0.0, max_steps, out, m, stride, K, y_new,
              y_stage, f_new, scale, e5, e3, F, (double *)0, &r);
    for (long k = r.filled; k < n_out; ++k)
        for (int i = 0; i < CH_N; ++i) out[(k * CH_N + i) * stride + m] = NAN;
    for (int i = 0; i < CH_N; ++i) last[i * stride + m] = y[i];
    t_last[m] = r.t;
    status_out[m] = r.status;
    n_rhs_out[m] = r.n_rhs;
    ch_observe(&w, r.t, y, p, m, stride, obs);
}

/* obs[:, m] <- observe(t[m], Y[:, m], P[:, m]) */
CH_DEVICE static void ch_observe_member(long m, long stride, const double *t, const double *Y,
                                        const double *P, double *obs)
{
    ch_work w;
    double p[CH_NP + 1], y[CH_N];
    for (int j = 0; j < CH_NP; ++j) p[j] = P[j * stride + m];
    for (int i = 0; i < CH_N; ++i) y[i] = Y[i * stride + m];
    ch_observe(&w, t[m], y, p, m, stride, obs);
}

#define CH_MEMBER_ARGS double t0, double t1, const double *Y0, const double *P, const double *t_out, \
    long n_out, double rtol, const double *atol, double max_step, long max_steps, double *out, \
    double *last, double *t_last, double *obs, long long *status, long long *n_rhs
#define CH_MEMBER_CALL t0, t1, Y0, P, t_out, n_out, rtol, atol, max_step, max_steps, out, last, \
    t_last, obs, status, n_rhs

#ifdef __CUDACC__
extern "C" __global__ void chaplygin_members(long members, CH_MEMBER_ARGS)
{
    long m = (long)blockIdx.x * blockDim.x + threadIdx.x;
#ifdef CH_STRIDED
    /* members m, m + threads, m + 2 threads, ...: a launch of fewer threads than members
       (DeviceKernel's resident; a loop here costs the disk's kernel 44 bytes of spills) */
    for (; m < members; m += (long)gridDim.x * blockDim.x) ch_member(m, members, CH_MEMBER_CALL);
#else
    if (m < members) ch_member(m, members, CH_MEMBER_CALL);
#endif
}

extern "C" __global__ void chaplygin_observe(long members, const double *t, const double *Y,
                                             const double *P, double *obs)
{
    long m = (long)blockIdx.x * blockDim.x + threadIdx.x;
    if (m < members) ch_observe_member(m, members, t, Y, P, obs);
}
#else
/* the host build: members start .. stop-1 of members, one after the other */
int chaplygin_members_@DIGEST@(long start, long stop, long members, CH_MEMBER_ARGS)
{
    for (long m = start; m < stop; ++m) ch_member(m, members, CH_MEMBER_CALL);
    return 0;
}

int chaplygin_observe_@DIGEST@(long members, const double *t, const double *Y, const double *P, double *obs)
{
    for (long m = 0; m < members; ++m) ch_observe_member(m, members, t, Y, P, obs);
    return 0;
}
#endif
"""


def _device_fill(fill_source: str) -> str:
    """The ``c`` backend's ``fill`` source as a function both builds call: ``chaplygin_fill``,
    ``__device__`` under NVRTC, no host header (the prelude includes ``math.h`` on the host)."""
    head = "void chaplygin_fill_@DIGEST@("
    if fill_source.count(head) != 1:
        raise ChaplyginError(f"the generated C fill has no single {head!r}; it cannot be put in a kernel")
    text = fill_source.replace("#include <math.h>\n", "")
    text = text.replace("static void chaplygin_solve(", "CH_DEVICE static void chaplygin_solve(")
    return text.replace(head, "CH_DEVICE static void chaplygin_fill(")


def kernel_source(kernel: CKernel, width: int, n_params: int) -> str:
    """The CUDA/C source of the ensemble kernel of one model (its ``c`` backend's ``kernel``).

    ``width`` is the length of the state, ``n_params`` of the parameter vector; the sizes are
    compile-time constants, so every array of a member is a fixed-size local array.  The loop is
    the ``c`` backend's own (:data:`chaplygin.numeric._ckernel.DOP853`).
    """
    sizes = {
        "CH_N": width,
        "CH_NV": kernel.N,
        "CH_DIM": kernel.DIM,
        "CH_NOBS": kernel.N_OBSERVED,
        "CH_NREACT": kernel.n_react,
        "CH_NP": n_params,
    }
    return "\n".join(
        [
            _PRELUDE,
            *(f"#define {name} {value}" for name, value in sizes.items()),
            _ckernel.tables(),
            _device_fill(kernel.fill_source),
            _WORK,
            _ckernel.DOP853,
            _MEMBERS,
        ]
    )


class CudaModel(CompiledModel):
    """A ``c``-backend model whose ensembles run on the GPU: ``rhs``/``observe`` are the C
    kernel's (host), :attr:`device` the GPU kernel (built on first use)."""

    def __init__(self, compiled: CompiledModel) -> None:
        super().__init__(compiled.layout, compiled.module, "cuda")
        self._device: DeviceKernel | None = None

    @property
    def device(self) -> DeviceKernel:
        if self._device is None:
            self._device = DeviceKernel(self.module, len(self.layout.state), len(self.layout.parameters))
        return self._device


def device_problem() -> str | None:
    """Why the GPU cannot be used here (None: CuPy is installed and sees a device)."""
    try:
        import cupy
    except Exception as exc:  # ImportError, or CuPy's own failure to find CUDA libraries
        return f"CuPy cannot be imported ({type(exc).__name__}: {exc})"
    try:
        count = int(cupy.cuda.runtime.getDeviceCount())
    except Exception as exc:  # CUDARuntimeError: no driver, no device
        return f"CuPy finds no CUDA device ({exc})"
    return None if count > 0 else "CuPy finds no CUDA device"


_STREAMS: dict[tuple[int, int], list[Any]] = {}
#: seconds between two looks at a stream whose kernel runs (:func:`_wait`)
POLL = 0.001
#: cudaErrorNotReady, what cudaStreamQuery says of a stream whose work runs
_NOT_READY = 600


def _wait(cupy: Any, stream: Any) -> None:
    """Until ``stream``'s work is over, looking every :data:`POLL` seconds: Ctrl-C is taken at
    once (a blocking synchronisation takes it only when the kernel ends: 10⁵ rattlebacks on an
    H100 are one chunk of some 4 s); then synchronised, which returns at once, or raises what
    went wrong (a failed kernel's error is not "not ready": ``Stream.done`` would stay False)."""
    while cupy.cuda.runtime.streamQuery(stream.ptr) == _NOT_READY:
        time.sleep(POLL)
    stream.synchronize()


def _run_streams(cupy: Any) -> list[Any]:
    """The two streams of :meth:`DeviceKernel.run`'s chunks on the current device, made once per
    process (and CuPy module) for every kernel: CuPy's memory pool keeps the blocks freed on a
    stream for that stream, so that runs on new streams would not reuse each other's memory."""
    key = (id(cupy), int(cupy.cuda.Device().id))
    if key not in _STREAMS:
        _STREAMS[key] = [cupy.cuda.Stream(non_blocking=True) for _ in range(2)]
    return _STREAMS[key]


def block_size(members: int, multiprocessors: int | None) -> int:
    """Threads per block: :data:`BLOCK`, or fewer (a multiple of 32, a warp) where blocks of
    :data:`BLOCK` would leave multiprocessors idle: 1 000 members in blocks of 128 run on 8 of an
    H100's 132, in blocks of 32 on 32 of them."""
    if not multiprocessors:
        return BLOCK
    per_processor = -(-members // multiprocessors)
    return int(min(BLOCK, max(32, 32 * -(-per_processor // 32))))


def launch(members: int, multiprocessors: int | None, resident: int | None = None) -> tuple[int, int]:
    """Threads per block (:func:`block_size`) and blocks of a launch: a thread per member, or at
    most ``resident`` threads (whole warps) per multiprocessor, each taking members in turn."""
    block = block_size(members, multiprocessors)
    blocks = math.ceil(members / block)
    if resident and multiprocessors:
        block = min(block, max(32, resident // 32 * 32))
        blocks = min(math.ceil(members / block), multiprocessors * max(1, resident // block))
    return block, blocks


def _soa(a: np.ndarray) -> np.ndarray:
    """Members last: (members, k) → (k, members), C-contiguous."""
    return np.ascontiguousarray(a.T)


def one_row(P: np.ndarray) -> bool:
    """Whether ``P`` (members × parameters) is one row seen by every member, a stride-0 view (as
    :func:`~chaplygin.numeric.ensemble.simulate_ensemble` makes for parameters given as numbers
    on the GPU); no parameters at all (strides 0 too) are not."""
    return bool(P.shape[0] and P.shape[1] and P.strides[0] == 0)


class _Arrays:
    """Checked inputs of one ensemble run."""

    def __init__(self, Y0: Any, P: Any, times: Any, rtol: float, atol: Any, n_obs: int) -> None:
        self.Y0 = np.ascontiguousarray(Y0, dtype=float)
        P = np.asarray(P, dtype=float)
        #: one row of parameters for every member (:func:`one_row`): each chunk uploads the row
        #: and repeats it on the device
        self.uniform = P.ndim == 2 and one_row(P)
        self.P = P if self.uniform else np.ascontiguousarray(P)
        self.members, self.n = self.Y0.shape
        if self.P.shape[0] != self.members:
            raise ChaplyginError(
                f"P: one row of parameters per member ({self.members}), not {self.P.shape[0]}."
            )
        self.rtol, self.atol = tolerances(rtol, atol, self.n)
        self.t_out = np.empty(0) if times is None else np.ascontiguousarray(times, dtype=float)
        self.n_obs = n_obs


def _result(
    t_last: np.ndarray,
    last: np.ndarray,
    obs: np.ndarray,
    code: np.ndarray,
    n_rhs: np.ndarray,
    samples: Any,
    obs0: np.ndarray,
) -> dict[str, np.ndarray]:
    """The arrays of :func:`chaplygin.numeric._loop.ensemble_dop853`, members first, and
    ``observed0``: ``observe`` at every member's start."""
    result = {"t": t_last, "y": last, "observed": obs, "code": code, "n_rhs": n_rhs, "observed0": obs0}
    if samples is not None:
        result["samples"] = samples
    return result


class HostKernel:
    """:func:`kernel_source` built by the host's C compiler: the GPU kernel's code, run on the CPU
    one member after another (tests, and ``benchmarks/gpu.py --check`` without a GPU)."""

    def __init__(self, kernel: CKernel, width: int, n_params: int) -> None:
        self.kernel = kernel
        self.source = kernel_source(kernel, width, n_params)
        digest, so = _ckernel.library(self.source, "cuda_host")
        lib = ctypes.CDLL(str(so))
        d, ll, i64, dbl = (
            ctypes.POINTER(ctypes.c_double),
            ctypes.POINTER(ctypes.c_longlong),
            ctypes.c_long,
            ctypes.c_double,
        )
        self._members = getattr(lib, f"chaplygin_members_{digest}")
        self._members.argtypes = [i64, i64, i64, dbl, dbl, d, d, d, i64, dbl, d, dbl, i64, d, d, d, d, ll, ll]
        self._observe = getattr(lib, f"chaplygin_observe_{digest}")
        self._observe.argtypes = [i64, d, d, d, d]
        self._lib = lib

    def run(
        self,
        t_span: tuple[float, float],
        Y0: np.ndarray,
        P: np.ndarray,
        *,
        times: np.ndarray | None = None,
        rtol: float = 1e-10,
        atol: Any = 1e-12,
        max_step: float = np.inf,
        max_steps: int = 0,
    ) -> dict[str, np.ndarray]:
        """Every row of ``Y0`` (parameters ``P``): the arrays of :func:`chaplygin.numeric._loop.ensemble_dop853`,
        and ``observed0``, ``observe`` at the start."""
        a = _Arrays(Y0, P, times, rtol, atol, self.kernel.N_OBSERVED)
        m, n, k = a.members, a.n, a.t_out.size
        y0, p = _soa(a.Y0), _soa(a.P)
        out, last = np.empty((k, n, m)), np.empty((n, m))
        t_last, obs = np.empty(m), np.empty((a.n_obs, m))
        code, n_rhs = np.empty(m, dtype=np.int64), np.empty(m, dtype=np.int64)

        def ptr(x: np.ndarray) -> Any:
            return x.ctypes.data_as(
                ctypes.POINTER(ctypes.c_longlong if x.dtype == np.int64 else ctypes.c_double)
            )

        self._members(
            0, m, m, float(t_span[0]), float(t_span[1]), ptr(y0), ptr(p), ptr(a.t_out), k, a.rtol,
            ptr(a.atol), float(max_step), int(max_steps), ptr(out), ptr(last), ptr(t_last), ptr(obs),
            ptr(code), ptr(n_rhs),
        )  # fmt: skip
        samples = np.ascontiguousarray(out.transpose(2, 0, 1)) if times is not None else None
        obs0 = self.observe(np.full(m, float(t_span[0])), a.Y0, a.P)
        return _result(t_last, _soa(last), _soa(obs), code, n_rhs, samples, obs0)

    def observe(self, t: np.ndarray, Y: np.ndarray, P: np.ndarray) -> np.ndarray:
        """``observe`` of every member at ``(t[m], Y[m], P[m])``, one row each."""
        t = np.ascontiguousarray(t, dtype=float)
        y, p = _soa(np.asarray(Y, dtype=float)), _soa(np.asarray(P, dtype=float))
        obs = np.empty((self.kernel.N_OBSERVED, len(t)))
        d = ctypes.POINTER(ctypes.c_double)
        self._observe(
            len(t), t.ctypes.data_as(d), y.ctypes.data_as(d), p.ctypes.data_as(d), obs.ctypes.data_as(d)
        )
        return _soa(obs)


class DeviceKernel:
    """:func:`kernel_source` compiled by NVRTC (CuPy), one thread per member.

    Raises :class:`~chaplygin.errors.ChaplyginError` without CuPy or a device (naming what to
    install), or where NVRTC refuses the source (the source is written to the kernel cache and
    its path given, with NVRTC's log).
    """

    def __init__(
        self,
        kernel: CKernel,
        width: int,
        n_params: int,
        *,
        fmad: bool = True,
        registers: int | None = None,
        inline: bool = True,
        library_pow: bool = False,
        carveout: int | None = None,
        resident: int | None = None,
    ) -> None:
        problem = device_problem()
        if problem is not None:
            raise ChaplyginError(f"backend 'cuda' cannot be used: {problem}; {INSTALL}.")
        import cupy

        self.cp = cupy
        self.kernel = kernel
        self.source = kernel_source(kernel, width, n_params)
        digest = hashlib.sha256(self.source.encode()).hexdigest()[:24]
        kernel_dir().mkdir(parents=True, exist_ok=True)
        self.path = kernel_dir() / f"cuda_{digest}.cu"  # the source, to read when NVRTC fails
        self.path.write_text(self.source, encoding="utf-8")
        # fmad: contraction into fused multiply-adds (off: the host build's arithmetic, module doc);
        # registers: NVRTC's --maxrregcount (more threads resident per SM, more spills);
        # inline: the right-hand side inlined at each of its call sites (else one called copy,
        # the prelude's CH_CALL_EVAL); library_pow: pow(x, 2) by the library's pow (CH_LIBRARY_POW);
        # resident: at most this many threads per multiprocessor, each taking members in turn
        # (fewer threads: their stages K, in local memory, may stay in L1)
        options: tuple[str, ...] = ("--fmad=true",) if fmad else ("--fmad=false",)
        if registers:
            options += (f"--maxrregcount={int(registers)}",)
        if not inline:
            options += ("-DCH_CALL_EVAL",)
        if library_pow:
            options += ("-DCH_LIBRARY_POW",)
        if resident:
            options += ("-DCH_STRIDED",)
        self.options = options
        self.resident = resident
        start = time.perf_counter()
        try:
            module = cupy.RawModule(code=self.source, options=options)
            self._members = module.get_function("chaplygin_members")
            self._observe = module.get_function("chaplygin_observe")
        except Exception as exc:  # cupy.cuda.compiler.CompileException carries NVRTC's log
            raise ChaplyginError(
                f"backend 'cuda': NVRTC could not compile the kernel ({type(exc).__name__}: "
                f"{str(exc)[:2000]}); its source is {self.path}"
            ) from None
        #: seconds NVRTC took (0 where CuPy found the kernel in its cache)
        self.compile_seconds = time.perf_counter() - start
        if carveout is not None:  # the shared-memory share of L1 in percent (0: all of it cache)
            try:  # CU_FUNC_ATTRIBUTE_PREFERRED_SHARED_MEMORY_CARVEOUT
                cupy.cuda.driver.funcSetAttribute(self._members.ptr, 9, int(carveout))
                self.options += (f"carveout={int(carveout)}",)
            except Exception as exc:  # a CuPy or driver without it
                self.options += (f"carveout not set: {exc}",)
        try:  # cudaDevAttrMultiProcessorCount
            self.multiprocessors: int | None = int(
                cupy.cuda.runtime.deviceGetAttribute(16, cupy.cuda.Device().id)
            )
        except Exception:  # a CuPy without it: blocks of BLOCK
            self.multiprocessors = None
        #: the two streams of :meth:`run`'s chunks (:func:`_run_streams`)
        self.streams = _run_streams(cupy)
        #: the host's seconds in the last :meth:`run`: host (checks, arrays), upload (uploads and
        #: launches), kernel (waiting for a chunk's kernel), download (time overlapped with a
        #: kernel, as a later chunk's upload and an earlier one's download, is counted once)
        self.timings: dict[str, float] = {}

    def _chunk(self, members: int, per_member: int) -> int:
        free, _ = self.cp.cuda.Device().mem_info
        return max(1, min(members, int(MEMORY_SHARE * free) // (8 * per_member)))

    def run(
        self,
        t_span: tuple[float, float],
        Y0: np.ndarray,
        P: np.ndarray,
        *,
        times: np.ndarray | None = None,
        rtol: float = 1e-10,
        atol: Any = 1e-12,
        max_step: float = np.inf,
        max_steps: int = 0,
        chunk: int | None = None,
    ) -> dict[str, np.ndarray]:
        """Every row of ``Y0`` (parameters ``P``) on the GPU, in chunks that fit its memory: the
        arrays of :func:`chaplygin.numeric._loop.ensemble_dop853`, and ``observed0``, ``observe``
        at the start (from the states and parameters already on the device: no second upload)."""
        cp = self.cp
        clock = {"host": time.perf_counter(), "upload": 0.0, "kernel": 0.0, "download": 0.0}
        a = _Arrays(Y0, P, times, rtol, atol, self.kernel.N_OBSERVED)
        m_all, n, k = a.members, a.n, a.t_out.size
        width_p = a.P.shape[1]
        # per member on the device: inputs and outputs (members-last; transposed on the host),
        # two chunks at a time
        per_member = n + width_p + k * n + n + 2 * a.n_obs + 4
        pieces = min(PIECES, max(1, m_all // PIECE_MEMBERS))
        if chunk is not None and chunk < 1:
            raise ChaplyginError(f"chunk = {chunk}: at least 1 member a chunk.")
        step = chunk or max(1, min(self._chunk(m_all, 2 * per_member), -(-m_all // pieces)))
        t_last, last = np.empty(m_all), np.empty((m_all, n))
        obs, obs0 = np.empty((m_all, a.n_obs)), np.empty((m_all, a.n_obs))
        code, n_rhs = np.empty(m_all, dtype=np.int64), np.empty(m_all, dtype=np.int64)
        samples = np.empty((m_all, k, n)) if times is not None else None
        streams = self.streams
        with streams[0]:  # (shared by every chunk: on the device before either stream goes on)
            t_out, atol_d = cp.asarray(a.t_out), cp.asarray(a.atol)
        streams[0].synchronize()
        clock["host"] = time.perf_counter() - clock["host"]

        def start(lo: int, stream: Any) -> tuple[int, int, Any, dict[str, Any]]:
            """Members lo .. hi-1 uploaded and launched on ``stream`` (returns at once)."""
            mark, hi = time.perf_counter(), min(m_all, lo + step)
            m = hi - lo
            with stream:  # (transposed on the host: a kernel on the device waits for free slots)
                y0 = cp.asarray(_soa(a.Y0[lo:hi]))
                if not width_p:
                    p = cp.zeros((0, m))
                elif a.uniform:
                    p = cp.ascontiguousarray(cp.broadcast_to(cp.asarray(a.P[0])[:, None], (width_p, m)))
                else:
                    p = cp.asarray(_soa(a.P[lo:hi]))
                # (the inputs kept with the outputs until the chunk is done: the kernels are queued)
                d = {"y0": y0, "p": p, "t0": cp.full(m, float(t_span[0])), "t": cp.empty(m)}
                d.update(out=cp.empty((k, n, m)), last=cp.empty((n, m)), obs=cp.empty((a.n_obs, m)))
                d.update(code=cp.empty(m, dtype=cp.int64), rhs=cp.empty(m, dtype=cp.int64))
                d["obs0"] = self._observe_device(d["t0"], y0, p)
                block, blocks = launch(m, self.multiprocessors, self.resident)
                self._members(
                    (blocks,), (block,),
                    (np.int64(m), np.float64(t_span[0]), np.float64(t_span[1]), y0, p, t_out, np.int64(k),
                     np.float64(a.rtol), atol_d, np.float64(max_step), np.int64(max_steps), d["out"], d["last"],
                     d["t"], d["obs"], d["code"], d["rhs"]),
                )  # fmt: skip
            clock["upload"] += time.perf_counter() - mark
            return lo, hi, stream, d

        def finish(lo: int, hi: int, stream: Any, d: dict[str, Any]) -> None:
            """Waits for a chunk's kernel and copies its results into rows lo .. hi-1, transposed
            on the host: a transposing kernel on the device would wait for the slots of the next
            chunk's (on an H100, 10⁶ disks in 8 chunks: 0.39 s of downloads, 0.07 s in one chunk)."""
            mark = time.perf_counter()
            _wait(cp, stream)
            clock["kernel"] += time.perf_counter() - mark
            mark = time.perf_counter()
            with stream:
                d["t"].get(out=t_last[lo:hi])
                d["code"].get(out=code[lo:hi])
                d["rhs"].get(out=n_rhs[lo:hi])
                for key, into in (("last", last), ("obs", obs), ("obs0", obs0)):
                    into[lo:hi] = d[key].get().T
                if samples is not None:
                    samples[lo:hi] = d["out"].get().transpose(2, 0, 1)
            clock["download"] += time.perf_counter() - mark

        # chunk i + 1 is launched before chunk i is downloaded: its kernel runs while the host
        # waits for chunk i's and copies its results
        pending = None
        for i, lo in enumerate(range(0, m_all, step)):
            job = start(lo, streams[i % 2])
            if pending is not None:
                finish(*pending)
            pending = job
        if pending is not None:
            finish(*pending)
        self.timings = clock
        return _result(t_last, last, obs, code, n_rhs, samples, obs0)

    def observe(self, t: np.ndarray, Y: np.ndarray, P: np.ndarray) -> np.ndarray:
        """``observe`` of every member at ``(t[m], Y[m], P[m])``, one row each, on the GPU."""
        cp = self.cp
        m = len(t)
        Y, P = np.asarray(Y, dtype=float), np.asarray(P, dtype=float)
        y = cp.ascontiguousarray(cp.asarray(Y).T)
        p = cp.ascontiguousarray(cp.asarray(P).T) if P.shape[1] else cp.zeros((0, m))
        obs = self._observe_device(cp.asarray(np.asarray(t, dtype=float)), y, p)
        return cp.ascontiguousarray(obs.T).get()

    def _observe_device(self, t: Any, y: Any, p: Any) -> Any:
        """``observe`` of the members of device arrays ``t`` (m), ``y`` (n × m), ``p``: n_obs × m."""
        m = len(t)
        obs = self.cp.empty((self.kernel.N_OBSERVED, m))
        if m:
            block = block_size(m, self.multiprocessors)
            self._observe((math.ceil(m / block),), (block,), (np.int64(m), t, y, p, obs))
        return obs
