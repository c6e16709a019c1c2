"""The ``cuda`` ensemble backend (:mod:`chaplygin.numeric._cuda`), tested without a GPU.

The GPU kernel's source is C that also builds for the host (a loop over members standing in
for the threads).  Built so, it must take the C loop's steps exactly: the same states, samples,
observations, right-hand-side counts and statuses, bit for bit, members that fail included (a
singular mass matrix, a blow-up, the step budget).  That reference, the C loop of
:mod:`chaplygin.numeric._ckernel`, is not produced by the code under test: it is a separate
port of SciPy's DOP853 that test_backends.py checks against SciPy.  The driver of
``simulate_ensemble(backend="cuda")`` is run on the host build too (the pole checks of a reduced
model, the initial observations), and the device source must be valid C++ for NVRTC (checked
with the host's C++ compiler, and nvcc where there is one).  Tests on a real GPU skip without
CuPy and a device.
"""

from __future__ import annotations

import math
import shutil
import subprocess
import sys
from typing import Any

import numpy as np
import pytest

from cases import DISK_0, DISK_P, KNIFE_0, KNIFE_P, require_c_compiler
from chaplygin import ChaplyginError, examples
from chaplygin.numeric import _ckernel, _cuda
from chaplygin.numeric._loop import ensemble_dop853
from chaplygin.numeric.codegen import compile_model, parameter_vector
from chaplygin.numeric.ensemble import simulate_ensemble

require_c_compiler()


@pytest.fixture(scope="module")
def disk_c():
    return compile_model(examples.rolling_disk(), "chaplygin", "classic", "c")


@pytest.fixture(scope="module", params=["symbolic", "numeric"])
def disk_both(request):
    """The disk's Chaplygin equations reduced symbolically, and numerically (its ``fill`` then
    solves for the dependent velocities itself, with ``chaplygin_solve``)."""
    return compile_model(examples.rolling_disk(), "chaplygin", "classic", "c", reduction=request.param)


def _disk_members(c, count: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """Rolling disks at various tilts and spins; member 3 has no inertia at all (M = 0)."""
    rng = np.random.default_rng(3)
    Y0 = np.tile([DISK_0[name] for name in c.layout.state], (count, 1))
    Y0[:, c.layout.state.index("theta")] += rng.uniform(-0.25, 0.25, count)
    Y0[:, c.layout.state.index("phi'")] += rng.uniform(-1.0, 1.0, count)
    P = np.tile(parameter_vector(c.layout, DISK_P), (count, 1))
    for name in ("m", "A", "C"):
        P[3, c.layout.parameters.index(name)] = 0.0
    return Y0, P


def _assert_same(a: dict, b: dict, start: tuple | None = None) -> None:
    """``a`` and ``b`` bit for bit; ``start`` (compiled, t0, Y0, P): ``a`` is a kernel's run,
    ``b`` the C loop's, and the kernel's ``observed0`` is the C kernel's observe at the start."""
    if start is not None:
        c, t0, Y0, P = start
        a = dict(a)
        np.testing.assert_array_equal(a.pop("observed0"), [c.observe(t0, y, p) for y, p in zip(Y0, P)])
    assert a.keys() == b.keys()
    for key in a:
        assert a[key].shape == b[key].shape, key
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)  # NaN where NaN


def test_host_build_of_the_kernel_takes_the_c_loops_steps(disk_both):
    disk_c = disk_both
    Y0, P = _disk_members(disk_c)
    host = _cuda.HostKernel(disk_c.module, Y0.shape[1], P.shape[1])
    times = np.linspace(0.0, 3.0, 7)
    for budget in (0, 40):  # no limit; then a step budget that stops every member (code 4)
        ours = host.run((0.0, 3.0), Y0, P, times=times, max_steps=budget)
        ref = ensemble_dop853(disk_c, (0.0, 3.0), Y0, P, times=times, max_steps=budget, threads=1)
        _assert_same(ours, ref, (disk_c, 0.0, Y0, P))
        expected = [0 if budget == 0 else 4] * len(Y0)
        expected[3] = 5
        assert list(ours["code"]) == expected
        if budget == 0:  # NaN samples after the failure, and only there
            assert np.isnan(ours["samples"][3, 1:]).all() and np.isfinite(ours["samples"][[0, 1, 2]]).all()
    # final states only, a tighter tolerance and a bounded step
    _assert_same(
        host.run((0.0, 1.0), Y0, P, rtol=1e-12, atol=1e-14, max_step=0.05),
        ensemble_dop853(disk_c, (0.0, 1.0), Y0, P, rtol=1e-12, atol=1e-14, max_step=0.05, threads=1),
        (disk_c, 0.0, Y0, P),
    )
    # observe at many states at once, each with its own parameters: the C kernel's observe
    t = np.linspace(0.0, 1.0, len(Y0))
    expected_obs = np.array([disk_c.observe(ti, y, p) for ti, y, p in zip(t, Y0, P)])
    np.testing.assert_array_equal(host.observe(t, Y0, P), expected_obs)


def test_the_kernel_and_the_c_loop_share_one_dop853_source(disk_c):
    """The loop is written once (issue 32, item 6): the C loop library and the GPU kernel each
    hold :data:`~chaplygin.numeric._ckernel.DOP853` once, and nothing else in either source reads
    the tableau, so neither holds a step, error norm or dense output of its own."""
    kernel = _cuda.kernel_source(disk_c.module, len(disk_c.layout.state), len(disk_c.layout.parameters))
    for source in (kernel, _ckernel.loop_source()):
        assert source.count(_ckernel.DOP853) == 1 and source.count(_ckernel.tables()) == 1
        rest = source.replace(_ckernel.DOP853, "").replace(_ckernel.tables(), "")
        assert "DOP_" not in rest


def test_host_build_reports_the_c_loops_failures(failing):
    """A blow-up of ẍ = k ẋ² at t = 1/(k ẋ(0)) and a mass that drops to 0 at t = a (test_backends)."""
    c = compile_model(failing, "chaplygin", "classic", "c")
    params = [{"a": 100.0, "k": 1.0}, {"a": 0.5, "k": 0.0}, {"a": 100.0, "k": 0.1}]
    P = np.array([parameter_vector(c.layout, p) for p in params])
    start = {"x": 0.0, "y": 0.0, "z": 0.0, "x'": 1.0, "y'": 1.0}
    Y0 = np.tile([start[name] for name in c.layout.state], (len(P), 1))
    host = _cuda.HostKernel(c.module, Y0.shape[1], P.shape[1])
    times = np.linspace(0.0, 2.0, 21)
    ours = host.run((0.0, 2.0), Y0, P, times=times)
    _assert_same(ours, ensemble_dop853(c, (0.0, 2.0), Y0, P, times=times, threads=1), (c, 0.0, Y0, P))
    assert ours["code"][0] in (1, 2) and ours["t"][0] == pytest.approx(1.0, abs=1e-3)  # the blow-up
    assert ours["code"][1] == 5 and 0.0 < ours["t"][1] < 0.5  # a step that met the singular mass matrix
    assert ours["code"][2] == 0 and ours["t"][2] == 2.0  # blows up at t = 10 only


@pytest.fixture
def host_as_device(monkeypatch):
    """simulate_ensemble's "cuda" backend with the host build standing in for the GPU."""
    monkeypatch.setattr(_cuda, "device_problem", lambda: None)
    monkeypatch.setattr(_cuda, "DeviceKernel", _cuda.HostKernel)


def test_cuda_ensemble_stops_members_at_a_pole_as_the_c_backend(host_as_device):
    knife = examples.knife_edge()
    runs = {
        b: simulate_ensemble(knife, "chaplygin", 1.0, KNIFE_0, KNIFE_P, backend=b, keep=5)
        for b in ("cuda", "c")
    }
    ens, ref = runs["cuda"], runs["c"]
    assert ens.backend == "cuda" and list(ens.code) == [9, 0] and list(ens.failure) == ["pole", ""]
    assert ens.t[0] < math.pi / 2 - 1.2 <= ens.t_pole[0]
    for field in ("t", "y", "t_pole", "samples", "energy", "energy_initial", "constraint_residual"):
        np.testing.assert_array_equal(getattr(ens, field), getattr(ref, field), err_msg=field)
    assert ens.messages == ref.messages


def test_the_gpu_observes_a_reduced_models_start_in_its_own_run(host_as_device, monkeypatch):
    """A reduced model's start cannot be off its constraints (the dependent velocities are solved
    from them), so no check waits for it: the GPU observes the start in the run, from the states
    and parameters it uploaded for it, not in a pass (an upload, a launch) of its own.  The same
    start as the C backend's, bit for bit."""
    from chaplygin.numeric import ensemble as ensemble_module

    disk = examples.rolling_disk()
    starts = [{**DISK_0, "theta": 0.1 + 0.02 * k, "phi'": 1.0 + 0.1 * k} for k in range(6)]
    ref = simulate_ensemble(disk, "chaplygin", 0.5, starts, DISK_P, backend="c")

    def refused(*args: Any) -> None:
        raise AssertionError("observed in a pass of its own")

    monkeypatch.setattr(ensemble_module, "_observe_all", refused)
    ens = simulate_ensemble(disk, "chaplygin", 0.5, starts, DISK_P, backend="cuda")
    assert ens.backend == "cuda" and ens.success.all()
    for field in ("energy_initial", "energy", "y", "constraint_residual"):
        np.testing.assert_array_equal(getattr(ens, field), getattr(ref, field), err_msg=field)
    for name, values in ref.velocities_initial.items():
        np.testing.assert_array_equal(ens.velocities_initial[name], values, err_msg=name)


def _driven_knife() -> Any:
    """A knife edge whose track moves sideways as w sin t: y' = tan(phi) x' + w sin t."""
    import sympy as sp
    from sympy.physics.vector import dynamicsymbols

    from chaplygin import System

    t = sp.Symbol("t")
    x, y, phi = dynamicsymbols("x y phi")
    m, J, w = sp.symbols("m J w", positive=True)
    T = m / 2 * (x.diff(t) ** 2 + y.diff(t) ** 2) + J / 2 * phi.diff(t) ** 2
    return System([x, y, phi], T, [y.diff(t) - sp.tan(phi) * x.diff(t) - w * sp.sin(t)], dependent=[y])


_DRIVEN_P = {"m": 1.0, "J": 0.5, "w": 2.0}


def test_the_gpu_observes_a_start_at_its_own_time(host_as_device):
    """A constraint driven in time, started at t = 1: the start observed in the GPU's run (the
    reduced models) and before it (the multiplier model) is the C backend's, bit for bit
    (observed at t = 0 instead, the sideways velocity at the start would be off by w sin 1)."""
    starts = [{"x": 0.0, "y": 0.0, "phi": 0.2 * k, "x'": 1.0, "phi'": 0.3} for k in range(3)]
    for model in ("chaplygin", "voronets", "chetaev"):
        runs = {
            b: simulate_ensemble(_driven_knife(), model, (1.0, 1.5), starts, _DRIVEN_P, backend=b)
            for b in ("c", "cuda")
        }
        assert runs["cuda"].backend == "cuda" and runs["c"].success.all()
        for field in ("energy_initial", "energy", "y", "constraint_residual"):
            np.testing.assert_array_equal(
                getattr(runs["cuda"], field), getattr(runs["c"], field), err_msg=field
            )
        for name, values in runs["c"].velocities_initial.items():
            np.testing.assert_array_equal(runs["cuda"].velocities_initial[name], values, err_msg=name)
        np.testing.assert_allclose(
            runs["c"].velocities_initial["y'"], np.tan([0.0, 0.2, 0.4]) + 2 * np.sin(1.0)
        )


def test_a_multiplier_models_start_off_its_constraints_is_refused_before_the_run(host_as_device, monkeypatch):
    """The Chetaev model integrates every velocity: a row off the constraints is refused, naming
    it, on the GPU as on the CPU, before any member is integrated."""
    disk = examples.rolling_disk()
    Y0 = simulate_ensemble(disk, "chetaev", 0.01, [DISK_0] * 4, DISK_P, backend="c").y_initial.copy()
    layout = compile_model(disk, "chetaev", "classic", "c").layout
    Y0[2, layout.state.index("x'")] += 0.5

    def refused(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("integrated")

    monkeypatch.setattr(_cuda.HostKernel, "run", refused)
    monkeypatch.setattr("chaplygin.numeric._loop.ensemble_dop853", refused)
    for backend in ("cuda", "c"):
        with pytest.raises(ChaplyginError, match=r"rows \[2\] violate the constraints"):
            simulate_ensemble(disk, "chetaev", 0.5, Y0, DISK_P, backend=backend, time_limit=None)


def test_only_the_gpu_gets_parameters_given_as_numbers_as_one_row(host_as_device, monkeypatch):
    """Parameters given as numbers reach the GPU as one row seen by every member (a read-only
    view, uploaded as a row), also in blocks checked for poles (the knife edge); the CPU loops get
    a matrix they may write (numba would compile its loop again for a read-only array)."""
    from chaplygin.numeric import targets

    seen: dict[str, set[tuple[bool, bool]]] = {"c": set(), "cuda": set()}
    for backend in seen:
        kind = type(targets.get(backend))

        def spy(self, compiled, t_span, Y0, P, _original=kind.ensemble, _backend=backend, **kw):
            seen[_backend].add((P.strides[0] == 0, P.flags.writeable))
            return _original(self, compiled, t_span, Y0, P, **kw)

        monkeypatch.setattr(kind, "ensemble", spy)
    disk, knife = examples.rolling_disk(), examples.knife_edge()
    for backend in seen:
        simulate_ensemble(disk, "chaplygin", 0.2, [DISK_0] * 3, DISK_P, backend=backend, time_limit=None)
        simulate_ensemble(knife, "chaplygin", 1.0, KNIFE_0, KNIFE_P, backend=backend, keep=5, time_limit=None)
    assert seen == {"c": {(False, True)}, "cuda": {(True, False)}}
    # a system without parameters: a writable (n, 0) matrix for both (its strides are 0 too)
    seen = {"c": set(), "cuda": set()}
    bare = examples.knife_edge(m=1.0, J=0.5)
    for backend in seen:
        simulate_ensemble(bare, "chaplygin", 1.0, KNIFE_0, None, backend=backend, keep=5, time_limit=None)
    assert seen == {"c": {(True, True)}, "cuda": {(True, True)}}


def test_auto_takes_the_gpu_for_large_ensembles_only(host_as_device, monkeypatch):
    disk = examples.rolling_disk()
    monkeypatch.setattr(_cuda, "AUTO_MEMBERS", 3)
    small = simulate_ensemble(disk, "chaplygin", 0.5, [DISK_0] * 2, DISK_P)
    large = simulate_ensemble(disk, "chaplygin", 0.5, [DISK_0] * 3, DISK_P)
    assert (small.backend, large.backend) == ("c", "cuda")
    np.testing.assert_array_equal(large.y[0], small.y[0])
    monkeypatch.setattr(_cuda, "device_problem", lambda: "CuPy finds no CUDA device")
    assert simulate_ensemble(disk, "chaplygin", 0.5, [DISK_0] * 3, DISK_P).backend == "c"


def test_auto_runs_on_the_cpu_when_the_gpu_fails(monkeypatch):
    """A device that is there but refuses the kernel (NVRTC, a driver) costs "auto" a warning, not
    the ensemble; "cuda" asked for by name raises."""

    def refuse(*args, **kwargs):
        raise ChaplyginError("backend 'cuda': NVRTC could not compile the kernel (test)")

    monkeypatch.setattr(_cuda, "device_problem", lambda: None)
    monkeypatch.setattr(_cuda, "DeviceKernel", refuse)
    monkeypatch.setattr(_cuda, "AUTO_MEMBERS", 2)
    disk = examples.rolling_disk()
    with pytest.warns(UserWarning, match="runs on the CPU: the GPU failed .*NVRTC"):
        assert simulate_ensemble(disk, "chaplygin", 0.5, [DISK_0] * 2, DISK_P).backend == "c"
    with pytest.raises(ChaplyginError, match="NVRTC"):
        simulate_ensemble(disk, "chaplygin", 0.5, [DISK_0] * 2, DISK_P, backend="cuda")


def test_cuda_without_cupy_says_what_to_install(monkeypatch):
    monkeypatch.setattr(_cuda, "device_problem", lambda: "CuPy cannot be imported (ModuleNotFoundError)")
    with pytest.raises(
        ChaplyginError, match=r"backend 'cuda' cannot be used: CuPy cannot.*chaplygin\[cuda\]"
    ):
        simulate_ensemble(examples.rolling_disk(), "chaplygin", 1.0, [DISK_0], DISK_P, backend="cuda")
    with pytest.raises(ChaplyginError, match="backend 'cuda' cannot be used"):
        _cuda.DeviceKernel(compile_model(examples.rolling_disk(), "chaplygin", "classic", "c").module, 8, 5)


class _Array(np.ndarray):
    """A NumPy array with CuPy's ``get`` (which ``_fake_cupy`` logs, with its stream)."""

    log: Any = None

    def get(self, out: np.ndarray | None = None) -> np.ndarray:
        if _Array.log is not None:
            _Array.log()
        if out is None:
            return np.array(self)
        assert (
            out.flags.c_contiguous and out.shape == self.shape and out.dtype == self.dtype
        )  # (CuPy's demands)
        out[...] = self
        return out


def _fake_cupy(free_bytes: int) -> Any:
    """CuPy as far as DeviceKernel uses it: arrays are NumPy's, a kernel launch calls the host
    build of the same source, and the device has ``free_bytes`` free (to force chunks).  Its
    ``events`` list the uploads ("upload", shape, stream), the launches (kernel, members, stream),
    the waits for a stream, and the arrays made and copied back on the device (name, None,
    stream)."""
    import ctypes
    import types

    events: list[tuple[str, Any, Any]] = []
    current: list[Any] = [None]  # the stream of a `with stream:` block

    class Stream:
        def __init__(self, non_blocking: bool = False) -> None:
            assert non_blocking  # (not synchronised with the legacy default stream)

        def __enter__(self) -> Stream:
            current.append(self)
            return self

        def __exit__(self, *exc: Any) -> None:
            current.pop()

        status = 0  # what cudaStreamQuery says of it (its kernels ran when they were launched)

        @property
        def ptr(self) -> Stream:  # (the handle cudaStreamQuery is given: here the stream itself)
            return self

        def synchronize(self) -> None:
            events.append(("wait", None, self))

    def wrap(f):
        return lambda *a, **k: np.asarray(f(*a, **k)).view(_Array)

    def made(f):  # (an array made on the device, on the current stream)
        def call(*args, **kwargs):
            events.append((f.__name__, None, current[-1]))
            return wrap(f)(*args, **kwargs)

        return call

    _Array.log = lambda: events.append(("get", None, current[-1]))

    def upload(x, *args, **kwargs):
        if not isinstance(x, _Array):  # (from the host)
            events.append(("upload", np.shape(x), current[-1]))
        return wrap(np.asarray)(x, *args, **kwargs)

    def pointer(x):
        if isinstance(x, np.ndarray):
            return x.ctypes.data_as(ctypes.c_void_p)
        return x.item() if isinstance(x, np.generic) else x

    class RawModule:
        def __init__(self, code: str, options: tuple = ()) -> None:
            assert "--fmad=true" in options  # (the default: contraction into fused multiply-adds)
            digest, so = _ckernel.library(code, "cuda_host")
            self.lib, self.digest = ctypes.CDLL(str(so)), digest

        def get_function(self, name: str):
            fn = getattr(self.lib, f"{name}_{self.digest}")
            fn.argtypes = None

            def launch(grid, block, args):
                assert grid[0] * block[0] >= args[0] > (grid[0] - 1) * block[0]
                c_args = [pointer(x) for x in args]
                c_args = [ctypes.c_double(x) if isinstance(x, float) else x for x in c_args]
                c_args = [ctypes.c_long(x) if isinstance(x, int) else x for x in c_args]
                if name == "chaplygin_members":  # the host build: (start, stop, members, ...)
                    c_args = [ctypes.c_long(0), *c_args[:1], *c_args]
                events.append((name, int(args[0]), current[-1]))
                fn(*c_args)

            return launch

    class Device:
        id = 0
        mem_info = (free_bytes, 10 * free_bytes)

        def synchronize(self) -> None:
            pass

    runtime = types.SimpleNamespace(
        getDeviceCount=lambda: 1,
        deviceGetAttribute=lambda attribute, device: 2,
        streamQuery=lambda s: s.status,
    )
    cuda = types.SimpleNamespace(runtime=runtime, Device=Device, Stream=Stream)
    return types.SimpleNamespace(
        cuda=cuda, RawModule=RawModule, int64=np.int64, asarray=upload,
        ascontiguousarray=made(np.ascontiguousarray), empty=made(np.empty), zeros=made(np.zeros),
        full=made(np.full), broadcast_to=made(np.broadcast_to), events=events,
    )  # fmt: skip


def test_the_device_driver_with_a_stand_in_for_cupy(disk_c, monkeypatch):
    """DeviceKernel's layout (members last), chunks and launches, with CuPy replaced by NumPy and
    the kernel by its host build: the C loop's results, in chunks of 5 members of 12 (the memory
    of 5, two chunks on the device at a time), each launched before the one before it is
    downloaded, on alternate streams; what every chunk shares (the kept times, atol) on the
    device before either stream goes on; nothing on the legacy default stream."""
    Y0, P = _disk_members(disk_c)
    n, k = Y0.shape[1], 7
    per_member = 8 * 2 * (n + P.shape[1] + k * n + n + 2 * disk_c.module.N_OBSERVED + 4)
    cupy = _fake_cupy(int(5.5 * per_member / _cuda.MEMORY_SHARE))
    monkeypatch.setitem(sys.modules, "cupy", cupy)
    gpu = _cuda.DeviceKernel(disk_c.module, n, P.shape[1])
    assert gpu._chunk(len(Y0), per_member // 8) == 5
    # a preference the driver cannot take (the stand-in has none) is noted, not fatal
    assert "carveout not set" in _cuda.DeviceKernel(disk_c.module, n, P.shape[1], carveout=0).options[-1]
    times = np.linspace(0.0, 3.0, k)
    first, second = gpu.streams
    # made once for every kernel (CuPy's pool keeps freed blocks per stream)
    assert _cuda.DeviceKernel(disk_c.module, n, P.shape[1]).streams is gpu.streams
    # (without samples a member needs less memory: one chunk)
    for t_end, kept, sizes in ((3.0, times, [5, 5, 2]), (1.0, None, [12])):
        del cupy.events[:]
        ours = gpu.run((0.0, t_end), Y0, P, times=kept)  # (the start observed from each chunk's upload)
        assert None not in {e[2] for e in cupy.events}  # (every copy and launch on a stream of the run)
        assert cupy.events[:3] == [("upload", (k if kept is not None else 0,), first), ("upload", (n,), first),
                                   ("wait", None, first)]  # fmt: skip
        chunks = [(m, stream) for name, m, stream in cupy.events if name == "chaplygin_members"]
        assert chunks == [(m, (first, second)[i % 2]) for i, m in enumerate(sizes)]
        # each chunk's start observed on its stream before its members run
        assert [e[1:] for e in cupy.events if e[0] == "chaplygin_observe"] == chunks
        waits = [e[2] for e in cupy.events[3:] if e[0] == "wait"]
        assert waits == [stream for _, stream in chunks]  # each chunk waited for once, in order
        at = {
            e: [j for j, f in enumerate(cupy.events[3:]) if f[0] == e] for e in ("chaplygin_members", "wait")
        }
        for i in range(1, len(sizes)):  # chunk i launched before chunk i - 1 is waited for
            assert at["chaplygin_members"][i] < at["wait"][i - 1]
        _assert_same(
            ours, ensemble_dop853(disk_c, (0.0, t_end), Y0, P, times=kept, threads=1), (disk_c, 0.0, Y0, P)
        )
    # a start at t = 1 of a constraint driven in time: observed there
    driven = compile_model(_driven_knife(), "chaplygin", "classic", "c")
    Y1 = np.array([[0.0, 0.0, 0.2 * k, 1.0, 0.3] for k in range(4)])
    P1 = np.tile(parameter_vector(driven.layout, _DRIVEN_P), (4, 1))
    ran = _cuda.DeviceKernel(driven.module, 5, P1.shape[1]).run((1.0, 1.5), Y1, P1)
    np.testing.assert_array_equal(ran["observed0"], [driven.observe(1.0, y, p) for y, p in zip(Y1, P1)])

    # Ctrl-C while a chunk's kernel runs is taken at once, not when the kernel ends
    def interrupted(seconds: float) -> None:
        raise KeyboardInterrupt

    with monkeypatch.context() as busy:
        busy.setattr(type(first), "status", 600)  # cudaErrorNotReady
        busy.setattr(_cuda.time, "sleep", interrupted)
        with pytest.raises(KeyboardInterrupt):
            gpu.run((0.0, 1.0), Y0, P)
        # a stream whose kernel failed is not waited for forever: its synchronisation raises
        busy.setattr(type(first), "status", 700)  # cudaErrorIllegalAddress
        busy.setattr(_cuda.time, "sleep", lambda seconds: pytest.fail("waited for a stream that failed"))
        gpu.run((0.0, 1.0), Y0, P)
        assert cupy.events[-1][0] == "get" and ("wait", None, first) in cupy.events
    # no members: empty arrays (one chunk of none); a chunk of no members is refused
    empty = gpu.run((0.0, 1.0), Y0[:0], P[:0])
    assert empty["y"].shape == (0, n) and empty["observed0"].shape == (0, disk_c.module.N_OBSERVED)
    with pytest.raises(ChaplyginError, match="chunk = 0"):
        gpu.run((0.0, 1.0), Y0, P, chunk=0)
    # one parameter vector for all (simulate_ensemble's view of one row, for numbers): uploaded
    # as one row, the same results as the full matrix's
    del cupy.events[:]
    one = gpu.run((0.0, 1.0), Y0, np.broadcast_to(P[0], P.shape))
    assert ("broadcast_to", None, first) in cupy.events and None not in {e[2] for e in cupy.events}
    assert [e[1] for e in cupy.events if e[0] == "upload"] == [(0,), (n,), (n, len(Y0)), (P.shape[1],)]
    _assert_same(one, gpu.run((0.0, 1.0), Y0, np.tile(P[0], (len(P), 1))))
    t = np.linspace(0.0, 1.0, len(Y0))
    np.testing.assert_array_equal(gpu.observe(t, Y0, P), [disk_c.observe(*row) for row in zip(t, Y0, P)])
    # a launch capped at one warp per multiprocessor asks NVRTC for the strided entry (which the
    # stand-in cannot run: test_the_device_entry_covers_every_member_once_in_any_grid runs it)
    assert _cuda.DeviceKernel(disk_c.module, n, P.shape[1], resident=32).options[-1] == "-DCH_STRIDED"


# a stand-in for what NVRTC declares itself, so that the host's C++ compiler checks the device branch
_NVRTC_SHIM = r"""
#include <cmath>
#include <cstring>
using std::fabs; using std::sqrt; using std::pow; using std::nextafter;
#define __device__
#define __constant__
#define __global__
#define __noinline__
struct ch_dim3 { unsigned x; };
static ch_dim3 blockIdx, blockDim, threadIdx, gridDim;
static inline double __longlong_as_double(long long v) { double d; std::memcpy(&d, &v, 8); return d; }
"""


def test_the_device_source_is_valid_cuda_cpp(disk_both, tmp_path):
    """NVRTC compiles C++: the device branch (``__CUDACC__``) must be valid C++ (no jump over an
    initialisation, no C-only construct), with no host header of its own."""
    c = disk_both
    source = _cuda.kernel_source(c.module, len(c.layout.state), len(c.layout.parameters))
    # the one header is math.h of the host build (the fill's own include is taken out)
    assert [line for line in source.splitlines() if "#include" in line] == ["#include <math.h>"]
    assert source.index("#include") > source.index("#else")
    cxx = shutil.which("c++") or shutil.which("g++") or shutil.which("clang++")
    if cxx is None:  # pragma: no cover - CI has g++
        pytest.skip("no C++ compiler")
    (tmp_path / "shim.h").write_text(_NVRTC_SHIM)
    (tmp_path / "kernel.cu").write_text(source)
    cmd = [cxx, "-fsyntax-only", "-x", "c++", "-D__CUDACC__", "-include", str(tmp_path / "shim.h")]
    for variant in ([], ["-DCH_CALL_EVAL", "-DCH_LIBRARY_POW"]):  # DeviceKernel's inline=False, library_pow
        run = subprocess.run(
            [*cmd, *variant, str(tmp_path / "kernel.cu")], capture_output=True, text=True, check=False
        )
        assert run.returncode == 0, run.stderr[:3000]
    nvcc = shutil.which("nvcc")
    if nvcc:  # the real front end and ptxas, where the CUDA toolkit is installed (no GPU needed)
        run = subprocess.run(
            [nvcc, "-arch=sm_90", "--fmad=false", "-DCH_CALL_EVAL", "-cubin", "-Xptxas", "-v", "-x", "cu", str(tmp_path / "kernel.cu"),
             "-o", str(tmp_path / "k.cubin")],
            capture_output=True, text=True, check=False, timeout=300,
        )  # fmt: skip
        assert run.returncode == 0, run.stderr[:3000]
        # one copy of the right-hand side, called from each site (inline=False): the loop keeps its
        # registers (220 on sm_90; the disk's six inlined copies take 254)
        usage = run.stderr[run.stderr.index("properties for chaplygin_members") :]
        assert " 0 bytes spill stores" in usage.splitlines()[1], usage[:400]


# the launch of a grid on the host: every block's every thread in turn (the device branch, shimmed)
_GRID_DRIVER = r"""
extern "C" void ch_grid(unsigned grid, unsigned block, long members, CH_MEMBER_ARGS)
{
    gridDim.x = grid; blockDim.x = block;
    for (unsigned b = 0; b < grid; ++b)
        for (unsigned i = 0; i < block; ++i) {
            blockIdx.x = b; threadIdx.x = i;
            chaplygin_members(members, CH_MEMBER_CALL);
        }
}
"""


def test_the_device_entry_covers_every_member_once_in_any_grid(disk_c, tmp_path):
    """The GPU entry itself (the ``__CUDACC__`` branch, compiled by the host's C++ compiler with
    the flags of the C loop and a stand-in for the launch): grids of a thread per member (some
    idle), and of fewer threads each taking members in turn (``DeviceKernel(resident=...)``
    compiles the entry with ``CH_STRIDED``) give the host build's results bit for bit, which are
    the C loop's."""
    import ctypes

    cxx = shutil.which("c++") or shutil.which("g++") or shutil.which("clang++")
    if cxx is None:  # pragma: no cover - CI has g++
        pytest.skip("no C++ compiler")
    Y0, P = _disk_members(disk_c)
    m, n = Y0.shape
    source = _cuda.kernel_source(disk_c.module, n, P.shape[1])
    (tmp_path / "shim.h").write_text(_NVRTC_SHIM)
    (tmp_path / "kernel.cu").write_text(source + _GRID_DRIVER)
    flags = [f for f in _ckernel.FLAGS if f not in ("-std=c99", "-pedantic-errors")]
    for strided in ("", "-DCH_STRIDED"):
        subprocess.run(
            [cxx, "-x", "c++", "-D__CUDACC__", "-include", str(tmp_path / "shim.h"), *flags,
             *([strided] if strided else []), str(tmp_path / "kernel.cu"), "-o", str(tmp_path / f"grid{strided}.so")],
            check=True, capture_output=True, timeout=300,
        )  # fmt: skip
    reference = _cuda.HostKernel(disk_c.module, n, P.shape[1]).run((0.0, 2.0), Y0, P)
    del reference["observed0"]  # (the grid driver runs the members' entry only)
    assert list(reference["code"]) == [0, 0, 0, 5] + [0] * 8
    atol, none = np.full(n, 1e-12), np.empty(0)

    def ptr(a: np.ndarray) -> Any:
        return a.ctypes.data_as(ctypes.c_void_p)

    # a thread per member (12; 15, three idle), and, DeviceKernel(resident=...)'s, fewer (6, 5)
    for strided, blocks, block in (
        ("", 4, 3),
        ("", 5, 3),
        ("-DCH_STRIDED", 2, 3),
        ("-DCH_STRIDED", 1, 5),
        ("-DCH_STRIDED", 5, 3),
    ):
        grid = ctypes.CDLL(str(tmp_path / f"grid{strided}.so")).ch_grid
        # the start and the last state in one array: a member run twice would start again from
        # where it ended, and end elsewhere
        state, p = np.ascontiguousarray(Y0.T), np.ascontiguousarray(P.T)
        obs = np.full((disk_c.module.N_OBSERVED, m), np.nan)
        t_last, code, n_rhs = np.full(m, np.nan), np.full(m, -1), np.full(m, -1)
        grid(
            ctypes.c_uint(blocks), ctypes.c_uint(block), ctypes.c_long(m), ctypes.c_double(0.0),
            ctypes.c_double(2.0), ptr(state), ptr(p), ptr(none), ctypes.c_long(0), ctypes.c_double(1e-10),
            ptr(atol), ctypes.c_double(np.inf), ctypes.c_long(0), ptr(none), ptr(state), ptr(t_last),
            ptr(obs), ptr(code), ptr(n_rhs),
        )  # fmt: skip
        got = {"t": t_last, "y": state.T, "observed": obs.T, "code": code, "n_rhs": n_rhs}
        _assert_same(got, reference)


def test_a_capped_launch_keeps_whole_warps_on_every_multiprocessor():
    """``launch``: a thread per member (blocks of :func:`block_size`), or with ``resident`` at
    most that many threads per multiprocessor, in whole warps: 10⁶ members on 132 of them at
    128 per multiprocessor are 132 blocks of 128 threads, each thread taking ~59 members."""
    assert _cuda.launch(10**6, 132) == (128, math.ceil(10**6 / 128))
    assert _cuda.launch(10**6, 132, resident=128) == (128, 132)
    assert _cuda.launch(10**6, 132, resident=256) == (128, 264)
    assert _cuda.launch(10**6, 132, resident=64) == (64, 132)
    assert _cuda.launch(10**6, 132, resident=40) == (32, 132)  # (whole warps)
    assert _cuda.launch(1000, 132, resident=128) == (32, 32)  # (fewer members than the cap)
    assert _cuda.launch(1000, None, resident=128) == (128, 8)  # (multiprocessors unknown: no cap)


def test_small_ensembles_spread_over_every_multiprocessor():
    """Blocks of 128 threads put 1 000 members on 8 of an H100's 132 multiprocessors; smaller
    blocks (whole warps) on 32 of them; large ensembles keep blocks of 128."""
    assert _cuda.block_size(1000, 132) == 32 and math.ceil(1000 / 32) == 32
    assert _cuda.block_size(10_000, 132) == 96
    assert _cuda.block_size(10**6, 132) == _cuda.BLOCK == 128
    assert _cuda.block_size(5, 132) == 32 and _cuda.block_size(1000, None) == _cuda.BLOCK


# ------------------------------------------------------------------ on a GPU
_NO_GPU = _cuda.device_problem()


@pytest.mark.skipif(_NO_GPU is not None, reason=f"no GPU: {_NO_GPU}")
def test_gpu_kernel_agrees_with_the_c_loop(disk_c):  # pragma: no cover - needs a GPU
    Y0, P = _disk_members(disk_c, 64)
    times = np.linspace(0.0, 3.0, 7)
    # (without contraction into fused multiply-adds: the two builds below, one with -DCH_STRIDED,
    # need not contract alike, and are compared bit for bit)
    gpu = _cuda.DeviceKernel(disk_c.module, Y0.shape[1], P.shape[1], fmad=False).run(
        (0.0, 3.0), Y0, P, times=times, chunk=17
    )
    ref = ensemble_dop853(disk_c, (0.0, 3.0), Y0, P, times=times, threads=1)
    np.testing.assert_array_equal(gpu["code"], ref["code"])
    ok = ref["code"] == 0
    np.testing.assert_allclose(gpu["y"][ok], ref["y"][ok], rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(gpu["samples"][ok], ref["samples"][ok], rtol=1e-8, atol=1e-8)
    assert np.abs(gpu["n_rhs"] - ref["n_rhs"]).max() <= 0.05 * ref["n_rhs"].max()
    # one multiprocessor of 32 threads for the 64 members: each thread takes two in turn
    capped = _cuda.DeviceKernel(disk_c.module, Y0.shape[1], P.shape[1], resident=32, fmad=False)
    capped.multiprocessors = 1
    assert _cuda.launch(len(Y0), capped.multiprocessors, capped.resident) == (32, 1)
    _assert_same(capped.run((0.0, 3.0), Y0, P, times=times), gpu)


def test_row_maxima_of_the_ensembles_checks_are_numpys():
    """The constraint residuals of an ensemble (``_row_max_abs``, column at a time, for 10⁶
    members 4 ms instead of NumPy's 60 ms) are ``np.max(np.abs(a), axis=1)``, NaN rows included."""
    from chaplygin.numeric.ensemble import _row_max_abs

    a = np.random.default_rng(5).normal(size=(50, 8))
    a[3, 2], a[7, 0] = np.nan, -np.inf
    for cols in (slice(0, 1), slice(1, 3), slice(5, 8)):
        np.testing.assert_array_equal(_row_max_abs(a[:, cols]), np.max(np.abs(a[:, cols]), axis=1))
