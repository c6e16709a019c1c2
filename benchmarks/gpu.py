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
(its spin reverses), 0.15 s per member on one CPU core.  JAX recompiles for
every new number of members, so each of its cells runs twice and the second is reported; it
starts at 10⁴ members.

Columns: ``wall`` the whole ``simulate_ensemble`` call, ``loop`` its integration
(``Ensemble.wall_time``: for cuda the kernel and the transfers), trajectories/s and right-hand
sides/s over ``wall``, and the arithmetic rate against the device's double-precision peak.
Flops per right-hand side are counted, roughly, from the generated C ``fill``: its binary
``+ - * /`` operators, each call of ``sin``, ``cos``, ``sqrt``, ``pow``, … counted as 20 flops
(a double-precision ``sin`` on a GPU is some 20–40 instructions), the mass-matrix solve as
``2/3·dim³ + 2·dim²`` and DOP853's own stage arithmetic as ``20·n`` (240·n flops over the 12
evaluations of a step).  The peak is SMs × FP64 units per SM × 2 (a fused multiply-add) × clock
(``--peak-tflops`` overrides it); the kernel runs without FMA contraction (``--fmad`` allows it),
so half that peak is its ceiling.

``--check`` compares ``--check-members`` members of each case on the GPU with the C loop (the
same members, ``backend="c"``), among them members with no inertia (a singular mass matrix,
status 5) and a run stopped by a step budget (status 4): the largest difference of the final
states, relative to max(1, |y|), and whether every status agrees.  Without a GPU it runs the
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
from chaplygin.numeric.codegen import compile_model
from chaplygin.numeric.ensemble import simulate_ensemble

#: case → (catalogue name, t_end, model or None for the true motion)
CASES = {"disk1": ("rolling-disk", 1.0, "chaplygin"), "disk10": ("rolling-disk", 10.0, "chaplygin")}
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

    def run(self, backend: str, Y0: np.ndarray, params: Any = None, **kw: Any) -> Any:
        return simulate_ensemble(
            self.system, self.model, self.t_end, Y0, params or self.parameters, backend=backend,
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
    """Without a GPU: the kernel's host build stands in for it (``--check`` only)."""
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
        for budget in (1_000_000, 50):
            t = time.perf_counter()
            gpu = prob.run("cuda", Y0, params, max_steps=budget)
            t_gpu = time.perf_counter() - t
            t = time.perf_counter()
            ref = prob.run("c", Y0, params, max_steps=budget)
            t_c = time.perf_counter() - t
            same = np.array_equal(gpu.code, ref.code)
            ok = (gpu.code == 0) & (ref.code == 0)
            diff = np.abs(gpu.y - ref.y) / np.maximum(1.0, np.abs(ref.y))
            worst = float(diff[ok].max()) if ok.any() else 0.0
            rhs = np.abs(gpu.rhs_evaluations - ref.rhs_evaluations)
            codes = dict(zip(*np.unique(ref.code, return_counts=True)))
            print(
                f"check {case:13s} max_steps={budget:<8d} members={members}: statuses "
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


def bench(args: argparse.Namespace) -> None:
    sizes = [int(float(s)) for s in args.sizes.split(",")]
    backends = args.backends.split(",")
    problem = _cuda.device_problem()  # (None with --host-build)
    if "cuda" in backends and problem is not None:
        print(f"cuda: skipped ({problem})")
        backends.remove("cuda")
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
    print(f"CPU cores: {len(os.sched_getaffinity(0))}; load average {os.getloadavg()[0]:.2f}", flush=True)
    rows = []
    head = f"{'case':13s} {'backend':7s} {'members':>9s} {'wall s':>8s} {'loop s':>8s} {'traj/s':>10s} "
    head += f"{'RHS/s':>9s} {'GFLOP/s':>8s} {'% peak':>7s} failed"
    for case in args.cases.split(","):
        prob = Problem(case)
        print(f"\n{case}: {prob.system.name}, {prob.model}, t = {prob.t_end:g}, state {len(prob.layout.state)}, "
              f"~{prob.flops:.0f} flops per RHS", flush=True)  # fmt: skip
        print(head)
        for backend in backends:
            pace = None
            if backend != "jax":  # (JAX compiles anew for every number of members: no warm-up)
                t = time.perf_counter()
                prob.run(backend, prob.states(WARM))  # warm-up: compile (C, NVRTC)
                warm = time.perf_counter() - t
                print(f"  ({backend} warm-up at {WARM} members: {warm:.2f} s)", flush=True)
                # the CPU's pace is the warm-up's (members share the cores evenly); a GPU's only
                # shows from a size that fills the device, so its first size always runs
                pace = warm / WARM if backend == "c" else None
            for members in sizes:
                if backend == "jax" and members < JAX_FROM:
                    continue
                if pace is not None and pace * members > args.max_seconds:
                    print(f"{case:13s} {backend:7s} {members:9d}  skipped (estimate {pace * members:.0f} s)")
                    continue
                Y0 = prob.states(members)
                if backend == "jax":
                    prob.run(backend, Y0)  # jit for this shape
                t = time.perf_counter()
                ens = prob.run(backend, Y0)
                wall = time.perf_counter() - t
                pace = wall / members
                rhs = float(ens.rhs_evaluations.sum())
                gflops = rhs * prob.flops / wall / 1e9
                share = f"{100 * gflops * 1e9 / peak:6.2f}%" if peak and backend != "c" else "      -"
                row = (case, backend, members, wall, ens.wall_time, members / wall, rhs / wall, gflops)
                rows.append(row)
                print(
                    f"{case:13s} {backend:7s} {members:9d} {wall:8.3f} {ens.wall_time:8.3f} {members / wall:10.4g} "
                    f"{rhs / wall:9.3g} {gflops:8.2f} {share} {int(np.count_nonzero(ens.code))}",
                    flush=True,
                )
            if backend == "cuda" and not args.host_build:  # CuPy's cached blocks back before JAX allocates
                import cupy

                cupy.get_default_memory_pool().free_all_blocks()
    print("\nspeed-up of cuda (wall), same case and members:")
    for case, backend, members, wall, *_ in rows:
        if backend != "cuda":
            continue
        others = {b: w for c, b, m, w, *_ in rows if c == case and m == members and b != "cuda"}
        ratios = (
            ", ".join(f"{w / wall:.1f}x over {b}" for b, w in others.items())
            or "no other backend at this size"
        )
        print(f"  {case:13s} {members:9d}: {ratios}")
    print("best trajectories/s of each backend (any size), and cuda's over it:")
    for case in dict.fromkeys(r[0] for r in rows):
        best = {
            b: max(r[5] for r in rows if r[0] == case and r[1] == b)
            for b in dict.fromkeys(r[1] for r in rows if r[0] == case)
        }
        ratios = ", ".join(
            f"{b} {v:.4g}" + (f" (cuda {best['cuda'] / v:.1f}x)" if "cuda" in best and b != "cuda" else "")
            for b, v in best.items()
        )
        print(f"  {case:13s} {ratios}")


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
    parser.add_argument("--peak-tflops", type=float, default=None, help="the device's FP64 peak")
    parser.add_argument("--fmad", action="store_true", help="let NVRTC contract into fused multiply-adds")
    parser.add_argument(
        "--host-build", action="store_true", help="run 'cuda' on the kernel's host build (no GPU)"
    )
    parser.add_argument("--maxrregcount", type=int, default=None, help="NVRTC's register limit per thread")
    args = parser.parse_args()
    if args.fmad or args.maxrregcount:
        original = _cuda.DeviceKernel.__init__
        tuned = {"fmad": args.fmad, "registers": args.maxrregcount}
        print(f"kernel options: {tuned}")

        def with_options(self: Any, *a: Any, **kw: Any) -> None:
            original(self, *a, **{**kw, **tuned})

        _cuda.DeviceKernel.__init__ = with_options  # type: ignore[method-assign]
    if args.check:
        problem = _cuda.device_problem()
        if problem is not None:
            print(f"no GPU ({problem}): checking the kernel's host build instead")
            host_as_device()
        sys.exit(0 if check(args.cases.split(","), args.check_members) else 1)
    if args.quick:
        args.sizes = "1e3,1e4,1e5,1e6"
    if args.max_seconds is None:
        args.max_seconds = 10.0 if args.quick else 20.0
    if args.host_build:
        print(
            "cuda: the kernel's host build stands in for the GPU (a test of this script, not a measurement)"
        )
        host_as_device()
    bench(args)


if __name__ == "__main__":
    main()
