"""Ensembles on a GPU (issue 32): ``backend="cuda"`` against ``"jax"`` and the C loop on all cores.

Run from the repository root (it puts this tree's ``src`` first on the path)::

    python benchmarks/gpu.py --check     # N members on the GPU against the C loop: differences, statuses
    python benchmarks/gpu.py --quick     # 10^3 … 10^6 members, at most ~10 s a cell
    python benchmarks/gpu.py             # 10^3 … 10^7 members, at most ~20 s a cell (~5 min on an H100)
    python benchmarks/gpu.py --sizes 1e5,1e6 --backends cuda,c --cases disk10 --max-seconds 60
    python benchmarks/gpu.py --host-build --sizes 1e2,1e3 --cases disk1   # this script without a GPU

Cases: the rolling disk (``examples.get("rolling-disk")``, Chaplygin's equations) to ``t = 1``
and ``t = 10``, and the rattleback (``examples.get("rattleback")``, its true motion) to ``t = 10``;
``rtol = 1e-10``, ``atol = 1e-12``, final states only.  Members start near the catalogue's state
(tilts and spins drawn uniformly, seed 0).  Each cell is one ``simulate_ensemble`` call (after one
untimed warm-up of the backend on 256 members: compilation, NVRTC); a size is skipped
when the last size's pace (for the C loop: the warm-up's) says it would take longer than
``--max-seconds``.  The rattleback is costly: some 9·10⁴ right-hand sides per member to t = 10
(its spin reverses), 0.02 s per member on one CPU core.  JAX recompiles for
every new number of members, so each of its cells runs twice and the second is reported; it
starts at 10⁴ members.  A cuda cell also runs twice where the first took under half of
``--max-seconds``: the second is reported (CuPy's memory pool then holds the size, as JAX's
does), the first in a note.

Columns: ``wall`` the whole ``simulate_ensemble`` call, ``loop`` its integration
(``Ensemble.wall_time``: for cuda the kernel and the transfers), trajectories/s and right-hand
sides/s over ``wall``, and the arithmetic rate against the device's double-precision peak.
Flops per right-hand side are counted, roughly, from the generated C ``fill``: its binary
``+ - * /`` operators, each call of ``sin``, ``cos``, ``sqrt``, ``pow``, … counted as 20 flops
(a double-precision ``sin`` on a GPU is some 20–40 instructions), the mass-matrix solve as
``2/3·dim³ + 2·dim²`` and DOP853's own stage arithmetic as ``20·n`` (240·n flops over the 12
evaluations of a step).  The peak is SMs × FP64 units per SM × 2 (a fused multiply-add) × clock
(``--peak-tflops`` overrides it); the kernel contracts into fused multiply-adds (``--no-fmad``:
not, and half that peak is its ceiling).  Under a cuda row, "(loop: …; outside the loop …)":
the host's seconds in each phase of the driver (``DeviceKernel.timings``: uploads and launches,
waiting for a chunk's kernel, downloads; overlapped time counted once) and in each step of
``simulate_ensemble`` around the loop (compile, parameters, states, observe, residuals, …).

``--check`` compares ``--check-members`` members of each case on the GPU with the C loop (the
same members, ``backend="c"``), among them members with no inertia (a singular mass matrix,
status 5) and a run with a step budget of 50 (the rattleback's stop there, status 4; the disk's
finish within it): the largest difference of the final
states, relative to max(1, |y|), and whether every status agrees; then the same members with the
parameters given as numbers (one row for all).  Without a GPU it runs the
kernel's host build (the same source compiled for the CPU) instead, and says so.
"""

from __future__ import annotations

import argparse
import importlib
import os
import platform
import re
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))  # this working tree, also when not installed
# JAX takes 75 % of the GPU's memory on first use unless told not to; CuPy shares the device here
os.environ.setdefault("XLA_PYTHON_CLIENT_PREALLOCATE", "false")

NEEDED = ("numpy", "sympy", "symengine", "mpmath")
OPTIONAL = ("cupy", "jax", "diffrax", "scipy", "numba")


def versions() -> list[str]:
    """What chaplygin needs on this path (and what the other backends need), with versions."""
    lines, missing = [], []
    for name in NEEDED + OPTIONAL:
        try:
            module = importlib.import_module(name)
            lines.append(f"{name} {getattr(module, '__version__', '?')}")
        except Exception as exc:  # ImportError, or a library that fails to load
            lines.append(f"{name} MISSING ({type(exc).__name__})")
            if name in NEEDED:
                missing.append(name)
    print("python", platform.python_version(), "|", ", ".join(lines), flush=True)
    if missing:
        sys.exit(
            f"gpu.py: chaplygin needs {', '.join(missing)} here; install them (pip install --no-deps ...)"
        )
    return lines


versions()

import numpy as np

from chaplygin import examples
from chaplygin.models import registry
from chaplygin.numeric import _cuda
from chaplygin.numeric import ensemble as _ensemble
from chaplygin.numeric.codegen import compile_model
from chaplygin.numeric.ensemble import simulate_ensemble

#: case → (catalogue name, t_end, model or None for the true motion)
CASES = {"disk1": ("rolling-disk", 1.0, "chaplygin"), "disk10": ("rolling-disk", 10.0, "chaplygin")}
CASES["rattleback1"] = ("rattleback", 1.0, None)
CASES["rattleback10"] = ("rattleback", 10.0, None)
#: FP64 units per SM by compute capability (A100: 32, H100/H200/B200: 64; consumer parts: 2)
FP64_PER_SM = {(6, 0): 32, (7, 0): 32, (8, 0): 32, (9, 0): 64, (10, 0): 64}
#: members of the untimed warm-up run of each backend and case
WARM = 256
#: JAX runs from this many members on (each size is compiled anew, and run twice)
JAX_FROM = 10_000
_CALL = re.compile(r"\b(sin|cos|tan|asin|acos|atan|atan2|sinh|cosh|tanh|exp|log|sqrt|pow|fabs|fmax|fmin)\(")


class Problem:
    """One case: its system, model, parameters, and members drawn near the catalogue's state."""

    def __init__(self, case: str) -> None:
        name, self.t_end, model = CASES[case]
        self.case = case
        entry = examples.get(name)
        self.system = entry.system()
        self.model = model or registry.true_motion(self.system)
        self.parameters = dict(entry.parameters)
        self.initial = dict(entry.initial)
        self.compiled = compile_model(self.system, self.model, "classic", "c")
        self.layout = self.compiled.layout
        self.flops = flops_per_rhs(self.compiled.module, len(self.layout.state))

    def states(self, members: int, seed: int = 0) -> np.ndarray:
        """``members`` initial states in layout order: tilts ±0.02 rad, velocities ×(1 ± 10 %)."""
        rng = np.random.default_rng(seed)
        base = np.array([self.initial[name] for name in self.layout.state])
        Y0 = np.tile(base, (members, 1))
        for j, name in enumerate(self.layout.state):
            if name in ("theta", "phi") and not name.endswith("'"):
                Y0[:, j] += rng.uniform(-0.02, 0.02, members)
            elif name.endswith("'"):
                Y0[:, j] *= rng.uniform(0.9, 1.1, members)
        return Y0

    def run(
        self, backend: str, Y0: np.ndarray, params: Any = None, t_end: float | None = None, **kw: Any
    ) -> Any:
        return simulate_ensemble(
            self.system, self.model, t_end or self.t_end, Y0, params or self.parameters, backend=backend,
            rtol=1e-10, atol=1e-12, time_limit=None, **kw,
        )  # fmt: skip


def flops_per_rhs(kernel: Any, n: int) -> float:
    """A rough count of the double-precision operations of one right-hand side (module doc)."""
    body = re.sub(r"/\*.*?\*/", "", kernel.fill_source, flags=re.S)
    body = body[body.index("chaplygin_fill_") :]
    ops = body.count(" + ") + body.count(" - ") + body.count("*") + body.count("/")
    calls = len(_CALL.findall(body))
    dim = kernel.DIM
    return ops + 20 * calls + (2 / 3) * dim**3 + 2 * dim**2 + 20 * n


def device() -> tuple[str, float | None]:
    """The GPU's name and its FP64 peak in flop/s (None where unknown)."""
    import cupy

    runtime = cupy.cuda.runtime
    props = runtime.getDeviceProperties(0)
    name = props["name"].decode() if isinstance(props["name"], bytes) else str(props["name"])
    try:
        sms = runtime.deviceGetAttribute(16, 0)  # cudaDevAttrMultiProcessorCount
        khz = runtime.deviceGetAttribute(13, 0)  # cudaDevAttrClockRate
        cc = (runtime.deviceGetAttribute(75, 0), runtime.deviceGetAttribute(76, 0))  # major, minor
        units = FP64_PER_SM.get((cc[0], 0), 2)
        return f"{name} (sm_{cc[0]}{cc[1]}, {sms} SMs, {khz / 1e6:.2f} GHz)", sms * units * 2 * khz * 1e3
    except Exception as exc:  # an attribute this CUDA does not have
        print(f"(peak unknown: {exc})")
        return name, None


def host_as_device() -> None:
    """Without a GPU: the kernel's host build stands in for it (``--check``, ``--host-build``)."""
    _cuda.device_problem = lambda: None  # type: ignore[assignment]
    _cuda.DeviceKernel = _cuda.HostKernel  # type: ignore[misc,assignment]


def check(cases: list[str], members: int) -> bool:
    """The GPU's members against the C loop's: the largest difference and the statuses."""
    good = True
    for case in cases:
        prob = Problem(case)
        Y0 = prob.states(members, seed=1)
        params = {k: np.full(members, v) for k, v in prob.parameters.items()}
        for k in ("m", "A", "B", "C", "D"):  # members 0 and 7: no inertia at all, a singular M
            if k in params:
                params[k][[0, 7]] = 0.0
        # per member (two without inertia), with a step budget, and as numbers (one row for all)
        for given, budget in ((params, 1_000_000), (params, 50), (prob.parameters, 1_000_000)):
            t = time.perf_counter()
            gpu = prob.run("cuda", Y0, given, max_steps=budget)
            t_gpu = time.perf_counter() - t
            if BUILT and given is params and budget == 1_000_000:
                print(
                    f"  (cuda kernel of {case}: {resident(BUILT[0])[1]}; NVRTC {BUILT[0].compile_seconds:.1f} s)"
                )
            t = time.perf_counter()
            ref = prob.run("c", Y0, given, max_steps=budget)
            t_c = time.perf_counter() - t
            same = np.array_equal(gpu.code, ref.code)
            ok = (gpu.code == 0) & (ref.code == 0)
            diff = np.abs(gpu.y - ref.y) / np.maximum(1.0, np.abs(ref.y))
            worst = float(diff[ok].max()) if ok.any() else 0.0
            rhs = np.abs(gpu.rhs_evaluations - ref.rhs_evaluations)
            codes = dict(zip(*np.unique(ref.code, return_counts=True)))
            print(
                f"check {case:13s} max_steps={budget:<8d} members={members} parameters "
                f"{'as numbers' if given is prob.parameters else 'per member'}: statuses "
                f"{'agree' if same else 'DIFFER'} {dict((int(k), int(v)) for k, v in codes.items())}; "
                f"max |Δy|/max(1,|y|) = {worst:.2e} on {int(ok.sum())} successful; members with other "
                f"RHS counts {int(np.count_nonzero(rhs))} (max {int(rhs.max())}); cuda {t_gpu:.2f} s, c {t_c:.2f} s",
                flush=True,
            )
            good &= same and worst < 1e-6
            if not same:
                bad = np.flatnonzero(gpu.code != ref.code)[:5]
                print(
                    "   first differing members:", [(int(i), int(gpu.code[i]), int(ref.code[i])) for i in bad]
                )
    return good


#: the cuda variants a backend label may name after "cuda:", joined by "+" (e.g. cuda:r128+nofmad)
VARIANTS = {
    "call": {"inline": False},  # one called copy of the right-hand side instead of inlined ones
    "libpow": {"library_pow": True},
    "nofmad": {"fmad": False},  # no contraction into fused multiply-adds (the host's arithmetic)
    "l1": {"carveout": 0},  # all of L1 as cache (the stages K live in local memory)
}
#: DeviceKernel options of the cell being run (set per backend label; read by the patched __init__)
TUNED: dict[str, Any] = {}
#: DeviceKernel options of every cuda label (--no-fmad, --maxrregcount)
BASE: dict[str, Any] = {}
#: the DeviceKernel built last (its registers, local memory, timings)
BUILT: list[Any] = []
#: a warm-up integrates to this share of the case's t_end (a slow kernel's warm-up stays short)
WARM_SHARE = 0.02


def variant(label: str) -> dict[str, Any]:
    """DeviceKernel options of a backend label: ``cuda`` {}, ``cuda:r128+call`` {registers: 128,
    inline: False}, ``cuda:w4`` {resident: 128} (4 warps per multiprocessor)."""
    options: dict[str, Any] = {}
    for token in label.partition(":")[2].split("+") if ":" in label else []:
        if token.startswith("r") and token[1:].isdigit():
            options["registers"] = int(token[1:])
        elif token.startswith("w") and token[1:].isdigit() and int(token[1:]) > 0:
            options["resident"] = 32 * int(token[1:])
        elif token in VARIANTS:
            options.update(VARIANTS[token])
        else:
            sys.exit(
                f"gpu.py: backend {label!r}: unknown cuda variant {token!r} (rN, wN, {', '.join(VARIANTS)})"
            )
    return options


def patch_device_kernel() -> None:
    """DeviceKernel built with :data:`TUNED`'s options, and remembered in :data:`BUILT`."""
    original = _cuda.DeviceKernel.__init__

    def tuned(self: Any, *a: Any, **kw: Any) -> None:
        original(self, *a, **{**kw, **TUNED})
        BUILT[:] = [self]

    _cuda.DeviceKernel.__init__ = tuned  # type: ignore[method-assign]


#: seconds simulate_ensemble spent in each step around the loop (:func:`patch_phases`)
PHASES: dict[str, float] = {}
_PHASE_OF = {
    "_compile": "compile",
    "_parameter_matrix": "parameters",
    "_states": "states",
    "_observe_all": "observe",
    "_row_max_abs": "residuals",
    "holonomic_residual": "holonomic",
}


def patch_phases() -> None:
    """The steps of simulate_ensemble around its loop, timed into :data:`PHASES`."""
    for name, phase in _PHASE_OF.items():
        original = getattr(_ensemble, name)

        def timed(*a: Any, _original: Any = original, _phase: str = phase, **kw: Any) -> Any:
            t = time.perf_counter()
            try:
                return _original(*a, **kw)
            finally:
                PHASES[_phase] = PHASES.get(_phase, 0.0) + time.perf_counter() - t

        setattr(_ensemble, name, timed)


def resident(kernel: Any, block: int = _cuda.BLOCK) -> tuple[int | None, str]:
    """Members the device runs at once (a wave), from the kernel's registers; and a description."""
    fn = getattr(kernel, "_members", None)
    regs, local = getattr(fn, "num_regs", None), getattr(fn, "local_size_bytes", None)
    sms = getattr(kernel, "multiprocessors", None)
    text = (
        f"{regs} registers, {local} bytes local memory per thread, options {getattr(kernel, 'options', '?')}"
    )
    if not (regs and sms):
        return None, text
    per_warp = -(-regs // 8) * 8 * 32  # registers are allocated per warp, 8 per thread at a time
    warps = min(64, 65536 // per_warp // (block // 32) * (block // 32))  # whole blocks per SM
    if getattr(kernel, "resident", None):  # (capped: wN)
        warps = min(warps, max(1, kernel.resident // 32))
    return sms * warps * 32, text + f"; {warps} warps per SM resident, a wave = {sms * warps * 32} members"


def cpu_quota() -> str:
    """The CPU time this process's control group may use, in cores ("no quota" where unlimited)."""
    v1 = Path("/sys/fs/cgroup/cpu")
    for read in (
        lambda: Path("/sys/fs/cgroup/cpu.max").read_text().split(),  # cgroup v2: "quota period"
        lambda: [(v1 / f"cpu.cfs_{k}_us").read_text().strip() for k in ("quota", "period")],  # v1
    ):
        try:
            quota, period = read()
        except (OSError, ValueError):
            continue
        if quota in ("max", "-1"):
            return "no quota"
        return f"a quota of {int(quota) / int(period):g} cores"
    return "quota unknown"


def bench(args: argparse.Namespace) -> None:
    sizes = [int(float(s)) for s in args.sizes.split(",")]
    backends = args.backends.split(",")
    problem = _cuda.device_problem()  # (None with --host-build)
    for label in [b for b in backends if b.startswith("cuda")]:
        variant(label)  # (an unknown variant stops here, before any work)
        if problem is not None:
            print(f"{label}: skipped ({problem})")
            backends.remove(label)
    if "jax" in backends:
        try:
            import chaplygin.numeric.jaxbackend  # noqa: F401
        except Exception as exc:
            print(f"jax: skipped ({exc})")
            backends.remove("jax")
    peak = args.peak_tflops * 1e12 if args.peak_tflops else None
    if problem is None and not args.host_build:
        name, found = device()
        peak = peak or found
        print(f"device: {name}; FP64 peak {peak / 1e12:.1f} TFLOP/s" if peak else f"device: {name}")
    cores = len(os.sched_getaffinity(0))
    print(f"CPU cores: {cores} ({cpu_quota()}); load average {os.getloadavg()[0]:.2f}", flush=True)
    rows = []
    head = f"{'case':13s} {'backend':12s} {'members':>9s} {'wall s':>8s} {'loop s':>8s} {'traj/s':>10s} "
    head += f"{'RHS/s':>9s} {'GFLOP/s':>8s} {'% peak':>7s} failed"

    def row(
        case: str, label: str, members: int, wall: float, loop: float, rhs: float, failed: Any, note: str = ""
    ) -> None:
        gflops = rhs * prob.flops / wall / 1e9
        share = f"{100 * gflops * 1e9 / peak:6.2f}%" if peak and label != "c" else "      -"
        rows.append((case, label, members, wall, loop, members / wall, note))
        print(
            f"{case:13s} {label:12s} {members:9d} {wall:8.3f} {loop:8.3f} {members / wall:10.4g} "
            f"{rhs / wall:9.3g} {gflops:8.2f} {share} {failed}{note}",
            flush=True,
        )

    for case in args.cases.split(","):
        prob = Problem(case)
        print(f"\n{case}: {prob.system.name}, {prob.model}, t = {prob.t_end:g}, state {len(prob.layout.state)}, "
              f"~{prob.flops:.0f} flops per RHS", flush=True)  # fmt: skip
        print(head)
        short = WARM_SHARE * prob.t_end
        for label in backends:
            backend = label.partition(":")[0]
            TUNED.clear()
            TUNED.update({**BASE, **variant(label)} if backend == "cuda" else {})
            guess = wave = None  # seconds: a guess for one member (c) or one wave (cuda); a wave measured
            capacity = None
            if backend != "jax":  # (JAX compiles anew for every number of members: no warm-up)
                t = time.perf_counter()
                prob.run(backend, prob.states(WARM), t_end=short)  # compile (C, NVRTC) and a first run
                first = time.perf_counter() - t
                t = time.perf_counter()
                prob.run(backend, prob.states(WARM), t_end=short)  # warm: what one run costs
                warm = time.perf_counter() - t
                # to t_end: C's members share the cores evenly (seconds per member); a GPU's time does
                # not grow with members until the device is full, and a full wave keeps the SMs
                # busier than WARM members do (×4, a guard only: the wave is measured below)
                guess = warm / WARM / WARM_SHARE if backend == "c" else 4 * warm / WARM_SHARE
                if backend == "cuda" and BUILT and not args.host_build:
                    capacity, text = resident(BUILT[0])
                    print(f"  ({label} kernel: {text})", flush=True)
                if backend == "cuda" and not capacity:  # (a wave unknown: seconds per member)
                    guess = guess / WARM
                print(f"  ({label} warm-up, {WARM} members to t = {short:g}: {first:.2f} s with compilation, "
                      f"then {warm:.3f} s)", flush=True)  # fmt: skip
                if backend == "c":  # what the cores add: the same members on one thread and on all
                    probe = prob.states(2 * WARM * cores)
                    paces = {}
                    for threads in (1, None, 1, None):
                        t = time.perf_counter()
                        prob.run(backend, probe, t_end=short, threads=threads)
                        paces[threads] = min(paces.get(threads, np.inf), time.perf_counter() - t)
                    print(f"  (c, {len(probe)} members to t = {short:g}, best of 2: 1 thread {paces[1]:.3f} s, "
                          f"{cores} threads {paces[None]:.3f} s: a speed-up of {paces[1] / paces[None]:.1f})",
                          flush=True)  # fmt: skip
            base = None  # (members, wall, loop, rhs) of the C loop's measured subset
            for members in sizes:
                if backend == "jax" and members < JAX_FROM:
                    continue
                if backend == "cuda":
                    waves = -(-members // capacity) if capacity else members  # (unknown: per member)
                    # the guess (a wave, or a member) bounds the first run, or the probe of one wave
                    pace, count = (wave, waves) if wave is not None else (guess, 1 if capacity else members)
                    if pace is not None and pace * count > args.max_seconds:
                        print(f"{case:13s} {label:12s} {members:9d}  skipped (estimate {pace * count:.3g} s "
                              f"= {count} x {pace:.3g} s{'' if wave else ', a guess'})")  # fmt: skip
                        continue
                    if wave is None and capacity and members > capacity:  # one full wave: the pace
                        t = time.perf_counter()
                        prob.run(backend, prob.states(capacity))
                        wave = time.perf_counter() - t
                        print(f"  ({label} one wave, {capacity} members: {wave:.3f} s)", flush=True)
                        if wave * waves > args.max_seconds:
                            print(
                                f"{case:13s} {label:12s} {members:9d}  skipped (estimate {wave * waves:.0f} s)"
                            )
                            continue
                elif (
                    backend == "c"
                    and guess is not None
                    and guess * members > args.max_seconds
                    and (base is not None or members > max(2 * cores, int(args.subset_seconds / guess)))
                ):
                    if base is None:  # a subset of these members, measured, and scaled
                        subset = min(members, max(2 * cores, int(args.subset_seconds / guess)))
                        ens = prob.run(backend, prob.states(members)[:subset])
                        base = (subset, ens.wall_time, float(ens.rhs_evaluations.sum()), ens.code)
                        guess = ens.wall_time / subset  # (the loop: the work around it is not scaled)
                    subset, loop, rhs, codes = base
                    scale = members / subset
                    row(case, label, members, loop * scale, loop * scale, rhs * scale,
                        f"{int(np.count_nonzero(codes))} of {subset}", f"  (extrapolated from {subset} members)")  # fmt: skip
                    continue
                elif backend == "jax" and guess is not None and guess * members > args.max_seconds:
                    print(f"{case:13s} {label:12s} {members:9d}  skipped (estimate {guess * members:.0f} s)")
                    continue
                Y0 = prob.states(members)
                PHASES.clear()
                if backend == "jax":
                    prob.run(backend, Y0)  # jit for this shape
                t = time.perf_counter()
                ens = prob.run(backend, Y0)
                wall = time.perf_counter() - t
                note = ""
                if backend == "cuda" and wall < args.max_seconds / 2:  # warm, as JAX's (its pool grown)
                    PHASES.clear()
                    t = time.perf_counter()
                    ens = prob.run(backend, Y0)
                    wall, note = time.perf_counter() - t, f"  (the first run at this size: {wall:.3f} s)"
                if backend != "cuda":
                    guess = wall / members
                elif not capacity:
                    wave = wall / members
                elif members >= capacity:
                    wave = wall / -(-members // capacity)
                row(case, label, members, wall, ens.wall_time, float(ens.rhs_evaluations.sum()),
                    int(np.count_nonzero(ens.code)), note)  # fmt: skip
                if backend == "cuda":  # (a host build has no phases of its loop)
                    parts = (
                        ", ".join(f"{k} {v:.3f}" for k, v in (BUILT[0].timings if BUILT else {}).items())
                        or "-"
                    )
                    steps = ", ".join(f"{k} {v:.3f}" for k, v in PHASES.items())
                    print(
                        f"{'':13s} {'':12s} {'':9s} (loop: {parts}; outside the loop {wall - ens.wall_time:.3f} s: "
                        f"{steps or 'no step timed'})"
                    )
            if backend == "cuda" and not args.host_build:  # CuPy's cached blocks back before JAX allocates
                import cupy

                cupy.get_default_memory_pool().free_all_blocks()
    print("\nspeed-up of each cuda variant (wall), same case and members:")
    for case, label, members, wall, *_ in rows:
        if not label.startswith("cuda"):
            continue
        others = {
            b: (w, note)
            for c, b, m, w, _, _, note in rows
            if c == case and m == members and not b.startswith("cuda")
        }
        ratios = ", ".join(
            f"{w / wall:.1f}x over {b}" + (" (extrapolated)" if note else "")
            for b, (w, note) in others.items()
        )
        print(f"  {case:13s} {label:12s} {members:9d}: {ratios or 'no other backend at this size'}")
    print("best trajectories/s of each backend (any size), and each cuda variant's over it:")
    for case in dict.fromkeys(r[0] for r in rows):
        best = {
            b: max(r[5] for r in rows if r[0] == case and r[1] == b)
            for b in dict.fromkeys(r[1] for r in rows if r[0] == case)
        }
        print(f"  {case:13s} " + ", ".join(f"{b} {v:.4g}" for b, v in best.items()))
        for b, v in best.items():
            if b.startswith("cuda"):
                over = ", ".join(f"{v / w:.1f}x {o}" for o, w in best.items() if not o.startswith("cuda"))
                print(f"  {'':13s} {b}: {over or '-'}")
    print("the cuda variants, at each case's largest size most of them ran (fastest first):")
    for case in dict.fromkeys(r[0] for r in rows):
        ran = {
            m: [(r[3], r[1]) for r in rows if r[0] == case and r[2] == m and r[1].startswith("cuda")]
            for m in sizes
        }
        size = max((m for m in sizes if ran[m]), key=lambda m: (len(ran[m]), m), default=None)
        if size is not None:
            times = sorted(ran[size])
            print(f"  {case:13s} {size:9d}: " + ", ".join(f"{v} {w:.3f} s" for w, v in times)
                  + f"  -> choose {times[0][1]}")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="compare the GPU with the C loop, then stop")
    parser.add_argument("--check-members", type=int, default=2000)
    parser.add_argument("--quick", action="store_true", help="10^3 … 10^6 members, --max-seconds 10")
    parser.add_argument("--sizes", default="1e3,1e4,1e5,1e6,1e7")
    parser.add_argument("--backends", default="cuda,jax,c")
    parser.add_argument("--cases", default=",".join(CASES))
    parser.add_argument(
        "--max-seconds", type=float, default=None, help="skip longer cells (20 s; --quick 10 s)"
    )
    parser.add_argument(
        "--subset-seconds",
        type=float,
        default=5.0,
        help="the C loop's measured subset, where it extrapolates",
    )
    parser.add_argument("--peak-tflops", type=float, default=None, help="the device's FP64 peak")
    parser.add_argument(
        "--no-fmad",
        action="store_true",
        help="no contraction into fused multiply-adds (the host's arithmetic)",
    )
    parser.add_argument(
        "--host-build", action="store_true", help="run 'cuda' on the kernel's host build (no GPU)"
    )
    parser.add_argument("--maxrregcount", type=int, default=None, help="NVRTC's register limit per thread")
    args = parser.parse_args()
    patch_device_kernel()
    patch_phases()
    if args.no_fmad or args.maxrregcount:  # (for every cuda label; variants: --backends cuda:r128,...)
        BASE.update({"fmad": not args.no_fmad, "registers": args.maxrregcount})
        print(f"kernel options: {BASE}")
    TUNED.update(BASE)
    options = [b for b in args.backends.split(",") if b.startswith("cuda:")] if args.host_build else []
    options += [f"--{k}" for k in ("no-fmad", "maxrregcount") if getattr(args, k.replace("-", "_"))]
    if args.check:
        problem = _cuda.device_problem()
        if problem is not None:
            if options:  # (the host build takes none of NVRTC's options)
                sys.exit(
                    f"gpu.py: no GPU ({problem}), and the kernel's host build takes no {', '.join(options)}"
                )
            print(f"no GPU ({problem}): checking the kernel's host build instead")
            host_as_device()
        sys.exit(0 if check(args.cases.split(","), args.check_members) else 1)
    if args.quick:
        args.sizes = "1e3,1e4,1e5,1e6"
    if args.max_seconds is None:
        args.max_seconds = 10.0 if args.quick else 20.0
    if args.host_build:
        if options:  # (the host build takes none of NVRTC's options: the same code under each name)
            sys.exit(
                f"gpu.py: --host-build runs the kernel's host build, which takes no {', '.join(options)}"
            )
        print(
            "cuda: the kernel's host build stands in for the GPU (a test of this script, not a measurement)"
        )
        host_as_device()
    bench(args)


if __name__ == "__main__":
    main()
