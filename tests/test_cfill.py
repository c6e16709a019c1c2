"""The numba backend's C ``fill`` (chaplygin.numeric._cfill): the same numbers as the Python ``fill``,
through every path that calls it, and a clear fallback where no C compiler can build it."""

from __future__ import annotations

import subprocess
import warnings
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from chaplygin import examples
from chaplygin.numeric import _cfill, _ckernel, codegen
from chaplygin.numeric.codegen import compile_model
from chaplygin.numeric.ensemble import simulate_ensemble
from chaplygin.numeric.simulate import simulate
from randomsystems import Spec, systems

try:
    _cfill.compiler()
    HAVE_CC = True
except _cfill.Unavailable:
    HAVE_CC = False

needs_cc = pytest.mark.skipif(not HAVE_CC, reason="no C compiler")


def uses_c(compiled) -> bool:
    return "_c_fill" in Path(compiled.module.__file__).read_text(encoding="utf-8")


@pytest.fixture
def always_c(monkeypatch):
    """Every numba model gets a C fill, however small."""
    monkeypatch.setattr(codegen, "C_FILL_FROM_LINES", 0)


def compile_both(make_system, model: str, monkeypatch, **kw):
    """(numba with the C fill, numpy with the Python fill) of fresh copies of one system."""
    monkeypatch.setattr(codegen, "C_FILL_FROM_LINES", 0)
    c = compile_model(make_system(), model, backend="numba", **kw)
    monkeypatch.setattr(codegen, "C_FILL_FROM_LINES", 10**9)
    py = compile_model(make_system(), model, backend="numpy", **kw)
    assert uses_c(c) and not uses_c(py)
    return c, py


def assert_same(c, py, rng: np.random.Generator, states: int = 4) -> None:
    assert c.layout == py.layout
    for _ in range(states):
        y = rng.uniform(-0.7, 0.7, len(c.layout.state))
        p = rng.uniform(0.5, 2.0, len(c.layout.parameters))
        t = float(rng.uniform(0, 1))
        np.testing.assert_allclose(c.rhs(t, y, p), py.rhs(t, y, p), rtol=1e-11, atol=1e-12)
        np.testing.assert_allclose(c.observe(t, y, p), py.observe(t, y, p), rtol=1e-11, atol=1e-12)


def assert_same_fill(c, py, rng: np.random.Generator, states: int = 2) -> None:
    """What ``fill`` writes (``M``, ``F``, the velocities, the observables: entry by entry, before
    any solve), through ``evaluate``: numba compiles only it and ``fill``, not ``rhs`` and
    ``observe``, whose code around ``fill`` is the same for every model (:func:`assert_same`)."""
    assert c.layout == py.layout
    for _ in range(states):
        y = rng.uniform(-0.7, 0.7, len(c.layout.state))
        p = rng.uniform(0.5, 2.0, len(c.layout.parameters))
        t = float(rng.uniform(0, 1))
        for ours, theirs in zip(c.module.evaluate(t, y, p), py.module.evaluate(t, y, p), strict=True):
            np.testing.assert_allclose(ours, theirs, rtol=1e-11, atol=1e-12)


@needs_cc
@pytest.mark.parametrize("model", ["chetaev", "chaplygin", "vakonomic"])
def test_c_fill_equals_python_fill_on_the_rolling_disk(model: str, monkeypatch) -> None:
    c, py = compile_both(examples.rolling_disk, model, monkeypatch)
    assert_same(c, py, np.random.default_rng(11))


@needs_cc
@given(spec=systems(), seed=st.integers(0, 2**32 - 1))
@settings(max_examples=4)
def test_c_fill_equals_python_fill_on_random_systems(spec: Spec, seed: int) -> None:
    """Affine and time-dependent constraints, both reductions (the numeric one solves in C);
    the rolling disk's test above runs rhs and observe on a C fill."""
    mp = pytest.MonkeyPatch()
    try:
        for model, reduction in (("chetaev", "auto"), ("voronets", "numeric")):
            c, py = compile_both(lambda: spec.system, model, mp, reduction=reduction)
            assert_same_fill(c, py, np.random.default_rng(seed))
            # each compile caches on the system's equations: start the next one afresh
            spec.system.equations("chetaev").__dict__.pop("_compiled", None)
    finally:
        mp.undo()


@needs_cc
def test_compiled_loop_and_symmetric_method_run_on_a_c_fill(monkeypatch) -> None:
    """A sleigh chain (numeric reduction, so ``fill`` solves for the dependent velocities in C)."""
    init = {"x": 0.0, "y": 0.0, "theta0": 0.2, "theta1": 0.1, "theta2": -0.1, "x'": 1.0, "theta0'": 0.3}
    par = {"m": 1.0, "I": 0.5, "L": 1.0}
    monkeypatch.setattr(codegen, "C_FILL_FROM_LINES", 0)
    chain = examples.sleigh_chain(2)  # one instance: its numba model is compiled once, for every path
    runs = {}
    for backend in ("numba", "numpy"):
        runs[backend] = simulate(
            chain, "voronets", 2.0, init, par, backend=backend, samples=5, reduction="numeric"
        )
        assert runs[backend].status == "success"
    assert uses_c(compile_model(chain, "voronets", backend="numba", reduction="numeric"))
    for name, values in runs["numba"].coordinates.items():
        np.testing.assert_allclose(values, runs["numpy"].coordinates[name], rtol=1e-8, atol=1e-10)
    gauss = simulate(
        chain,
        "voronets",
        2.0,
        init,
        par,
        backend="numba",
        samples=5,
        reduction="numeric",
        method="gauss4",
        step=0.01,
    )
    for name, values in gauss.coordinates.items():
        np.testing.assert_allclose(values, runs["numpy"].coordinates[name], atol=1e-6)
    ens = simulate_ensemble(chain, "voronets", 2.0, [init, init], par, reduction="numeric")
    final = np.array([runs["numpy"].coordinates[name][-1] for name in ens.layout.coordinates])
    for member in ens.y:
        np.testing.assert_allclose(member[: len(final)], final, rtol=1e-8, atol=1e-10)


@needs_cc
def test_a_large_model_gets_a_c_fill_by_default() -> None:
    chain = examples.sleigh_chain(6)  # 9 coordinates: reduced numerically, a fill of ~300 lines
    compiled = compile_model(chain, "voronets", backend="numba")
    assert uses_c(compiled)
    assert not uses_c(compile_model(examples.rolling_disk(), "chaplygin", backend="numba"))


@needs_cc
def test_flags_in_chaplygin_cc_override_the_defaults(monkeypatch) -> None:
    """``CHAPLYGIN_CC="cc -O0"``: built unoptimised (a different library), the same numbers."""
    monkeypatch.setenv("CHAPLYGIN_CC", f"{_cfill.compiler()[0]} -O0")
    c, py = compile_both(examples.knife_edge, "chaplygin", monkeypatch)
    assert "-O0" in " ".join(_cfill.compiler())
    assert_same_fill(c, py, np.random.default_rng(5), states=4)


def test_no_compiler_warns_and_numba_compiles_the_python_fill(always_c, monkeypatch) -> None:
    monkeypatch.setenv("CHAPLYGIN_CC", "none")
    monkeypatch.setenv("CHAPLYGIN_MODEL_CACHE", "off")  # the warning is the compiler's: compile anew
    with pytest.warns(RuntimeWarning, match="CHAPLYGIN_CC='none' switches it off"):
        compiled = compile_model(examples.knife_edge(), "chaplygin", backend="numba")
    assert not uses_c(compiled)
    # numba compiled the Python fill (through evaluate: what it writes, the numpy module's numbers)
    assert_same_fill(
        compiled, compile_model(examples.knife_edge(), "chaplygin", backend="numpy"), np.random.default_rng(3)
    )


@pytest.mark.parametrize(
    "command, message",
    [("/nonexistent/bin/cc", "could not run"), ("false", r"failed \(exit 1\): \(no output\)")],
)
def test_a_failing_compiler_is_reported_and_nothing_is_left(
    command, message, always_c, monkeypatch, tmp_path
) -> None:
    monkeypatch.setenv("CHAPLYGIN_CC", command)
    monkeypatch.setenv("CHAPLYGIN_CACHE", str(tmp_path))
    with pytest.warns(RuntimeWarning, match=message):
        compiled = compile_model(examples.knife_edge(), "chetaev", backend="numba")
    assert not uses_c(compiled)
    assert not list(tmp_path.rglob("*.so")) and not list(tmp_path.rglob("*.c"))


def test_a_function_c_lacks_is_unavailable_not_a_crash() -> None:
    x = sp.Symbol("y[0]")
    fill = codegen._Fill(codegen._Block([sp.besselj(0, x)], [("F", 0, 0)], "c_"))
    with pytest.raises(_cfill.Unavailable, match="no translation"):
        _cfill.source(fill, [codegen._assignments(b) for b in fill.blocks()], "f")


@needs_cc
def test_a_singular_dependent_block_gives_nan_not_garbage(tmp_path) -> None:
    """``Ad·d = b`` with a zero pivot: every output built on ``d`` is NaN."""
    d0 = sp.Symbol("d[0]")
    y0 = sp.Symbol("y[0]")
    fill = codegen._Fill(
        codegen._Block([d0 + 1], [("F", 0, 0)], "c_"),
        solve=1,
        pre=codegen._Block([y0 - y0, sp.S.One], [("Ad", 0, 1), ("b", 0, 0)], "a_"),
    )
    import ctypes

    symbol, library = _cfill.build(fill, [codegen._assignments(b) for b in fill.blocks()])
    fn = getattr(ctypes.CDLL(library), symbol)
    ptr = ctypes.POINTER(ctypes.c_double)
    fn.argtypes = [ctypes.c_double, *[ptr] * 6]
    arrays = [np.zeros(1) for _ in range(6)]
    with warnings.catch_warnings():
        fn(0.0, *[a.ctypes.data_as(ptr) for a in arrays])
    assert np.isnan(arrays[3][0])  # F


@needs_cc
@pytest.mark.parametrize(
    "literal, message",
    [
        ("24336000000000000000", "integer constant is too large"),
        ("10000000000000000000", "integer constant is so large that it is unsigned"),
        ("1e400", "floating constant exceeds range"),
    ],
)
def test_a_constant_the_compiler_would_change_stops_the_build(
    literal, message, monkeypatch, tmp_path
) -> None:
    """With the kernels' flags a constant C cannot hold is an error, not a warning after which the
    library computes with another number (issue 27: 2.4336e19 became 6.0e18 and the motion was off)."""
    monkeypatch.setenv("CHAPLYGIN_CACHE", str(tmp_path))
    if "clang" in " ".join(_cfill.compiler()):  # pragma: no cover - gcc's wording
        message = ""
    source = f"double chaplygin_probe_@DIGEST@(double x) {{ return {literal} * x; }}\n"
    with pytest.raises(_cfill.Unavailable, match=message):
        _ckernel.library(source, "probe")
    assert not list(tmp_path.rglob("*.so"))


def _gallery_sources() -> tuple[str, str]:
    """One translation unit with the C ``fill`` of every gallery system's true motion (symbolic),
    one with a numerically reduced ``fill`` (its Gaussian elimination), both with the DOP853 loop."""
    from chaplygin.models import registry

    fills = []
    for k, (name, entry) in enumerate(examples.catalogue().items()):
        if name == "whipple-bicycle":  # its true motion compiles by the numeric reduction (below)
            continue
        system = entry.constructor()
        parts = codegen._parts(system.equations(registry.true_motion(system)))
        fills.append(
            _cfill.source(parts.fill, [codegen._assignments(b) for b in parts.fill.blocks()], f"fill{k}")
        )
    numeric = codegen._numeric_reduction_parts(examples.sleigh_chain(2), "voronets")
    reduced = _cfill.source(numeric.fill, [codegen._assignments(b) for b in numeric.fill.blocks()], "reduced")
    loop = _ckernel.loop_source().replace("@DIGEST@", "gallery")
    return "\n".join([*fills, loop]), reduced + loop


@needs_cc
def test_the_gallery_c_builds_without_a_diagnostic(tmp_path) -> None:
    """The generated C of every gallery system (and the loop) builds with the kernels' flags and
    -Wall -Wextra -pedantic, and the compiler says nothing (stderr is empty)."""
    for k, source in enumerate(_gallery_sources()):
        c_file = tmp_path / f"gallery{k}.c"
        c_file.write_text(source, encoding="ascii")
        run = subprocess.run(
            [
                *_cfill.compiler(),
                *_cfill.FLAGS,
                "-Wall",
                "-Wextra",
                "-pedantic",
                str(c_file),
                "-o",
                str(tmp_path / f"g{k}.so"),
                "-lm",
            ],
            capture_output=True,
            text=True,
            check=False,
        )
        assert run.returncode == 0 and not run.stderr, run.stderr
