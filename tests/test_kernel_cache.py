"""The kernel cache, the run plans and ``backend="auto"``, across real processes.

Each check runs fresh Python processes on a private cache folder
(``$CHAPLYGIN_CACHE``) and looks at what they did — libraries built or
loaded (``chaplygin.numeric._ckernel.STATS``), whether SymPy was imported — never at
how long they took.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import chaplygin
from chaplygin import examples
from chaplygin.numeric import _ckernel
from chaplygin.numeric._ckernel import Unavailable, compiler
from chaplygin.numeric.simulate import SYMMETRIC_METHODS, choose_backend, simulate
from chaplygin.numeric.symmetric import METHODS
from subprocesses import SRC, run_json

try:
    compiler()
    HAVE_CC = True
except Unavailable:  # pragma: no cover - every CI machine has a C compiler
    HAVE_CC = False

needs_cc = pytest.mark.skipif(not HAVE_CC, reason="no C compiler")
RUN = ["simulate", "example:rolling-disk", "-m", "chaplygin", "-t", "2", "-n", "21"]

# The processes below exercise the kernel cache, so the loop library that an installation built
# into the package (setup.py) is hidden from them (PACKAGED_DIR names another folder: an empty one,
# or one a test fills), and they build the loop as an installation without one does.
PACKAGED = """
import os, pathlib
from chaplygin.numeric import _ckernel
_ckernel.PACKAGED = pathlib.Path(os.environ.get("PACKAGED_DIR", "/nonexistent"))
"""
# a process that runs the command line, then reports what it built and imported
CLI = (
    PACKAGED
    + """
import json, sys
from chaplygin.numeric import _ckernel
from chaplygin.apps.cli import main
code = main(sys.argv[1:])
print(json.dumps({"code": code, "stats": _ckernel.STATS, "sympy": "sympy" in sys.modules}))
"""
)
# a process that compiles the rolling disk's Chaplygin model for the c backend
COMPILE = (
    PACKAGED
    + """
import json
from chaplygin.numeric import _ckernel
from chaplygin import examples
from chaplygin.numeric.codegen import compile_model
model = compile_model(examples.rolling_disk(), "chaplygin", "classic", "c")
print(json.dumps({"stats": _ckernel.STATS, "file": model.module.__file__}))
"""
)


@needs_cc
def test_second_process_loads_the_compiled_kernel(tmp_path):
    first = run_json(COMPILE, [], tmp_path)
    assert first["stats"]["built"] == 2  # the DOP853 loop and this model's fill
    second = run_json(COMPILE, [], tmp_path)
    assert second["stats"] == {"built": 0, "loaded": 2, "discarded": 0}
    assert second["file"] == first["file"]


# a process that records, as the rolling disk's Chaplygin equations are derived for the c
# backend, whether the C compiler is already building the DOP853 loop beside it
BESIDE = (
    PACKAGED
    + """
import json, threading
from chaplygin import examples
from chaplygin.core.system import System
from chaplygin.numeric import _ckernel
from chaplygin.numeric.codegen import compile_model
seen = []
derive = System.equations
def watched(self, *args, **kwargs):
    seen.append(sorted(t.name for t in threading.enumerate()))
    return derive(self, *args, **kwargs)
System.equations = watched
compile_model(examples.rolling_disk(), "chaplygin", "classic", "c")
loops = sorted(p.name for p in _ckernel.kernel_dir().glob("dop853_*.so"))
print(json.dumps({"seen": seen, "stats": _ckernel.STATS, "loops": loops}))
"""
)


@needs_cc
def test_the_loop_library_is_built_while_the_model_is_derived(tmp_path):
    # the C compiler's ~0.2 s for the DOP853 loop (once per kernel cache) overlap the derivation
    first = run_json(BESIDE, [], tmp_path)
    assert "chaplygin-loop-build" in first["seen"][0]
    assert first["stats"]["built"] == 2 and len(first["loops"]) == 1
    # with the loop in the cache nothing is started beside the derivation
    second = run_json(BESIDE.replace("rolling_disk()", "rolling_sphere()"), [], tmp_path)
    assert second["seen"] and "chaplygin-loop-build" not in second["seen"][0]
    assert second["stats"] == {"built": 1, "loaded": 1, "discarded": 0}


# the same, with the loop's build held until the model's fill is in the kernel cache (at most
# 10 s): the order in which the two libraries were finished
HELD = (
    PACKAGED
    + """
import json, threading, time
from chaplygin import examples
from chaplygin.numeric import _ckernel
from chaplygin.numeric.codegen import compile_model
finished, build = [], _ckernel._compile
def held(source, cmd, directory, so, record, digest):
    if so.name.startswith("dop853_"):
        deadline = time.monotonic() + 10
        while not any(directory.glob("fill_*.so")) and time.monotonic() < deadline:
            time.sleep(0.01)
    build(source, cmd, directory, so, record, digest)
    finished.append(so.name.split("_")[0])
_ckernel._compile = held
compile_model(examples.rolling_disk(), "chaplygin", "classic", "c")
print(json.dumps({"finished": finished, "stats": _ckernel.STATS}))
"""
)


@needs_cc
def test_the_fill_is_compiled_while_the_loop_library_is_still_building(tmp_path):
    # the model's fill does not wait for the loop library built beside it: the compilers run at once
    first = run_json(HELD, [], tmp_path)
    assert first["finished"] == ["fill", "dop853"]
    assert first["stats"] == {"built": 2, "loaded": 2, "discarded": 0}  # both then loaded from the cache


@needs_cc
@pytest.mark.parametrize("damage", ["library", "record"])
def test_a_corrupt_kernel_is_discarded_and_rebuilt(tmp_path, damage):
    first = run_json(COMPILE, [], tmp_path)
    library = Path(first["file"])
    target = library if damage == "library" else library.with_suffix(".json")
    target.write_bytes(target.read_bytes()[:200] + b"garbage")
    again = run_json(COMPILE, [], tmp_path)
    assert again["stats"] == {"built": 1, "loaded": 1, "discarded": 1}
    assert again["file"] == first["file"]
    assert run_json(COMPILE, [], tmp_path)["stats"]["built"] == 0  # and the rebuilt one is reused


@needs_cc
def test_the_loop_library_built_at_install_is_used(tmp_path):
    # setup.py's build, into a package folder of its own: a first run builds only the model's fill
    package = tmp_path / "package"
    _ckernel.install_loop(package / "_dop853_loop.cpython-test.so")
    a, b = tmp_path / "a.npz", tmp_path / "b.npz"
    used = run_json(CLI, [*RUN, "-o", str(a)], tmp_path / "one", PACKAGED_DIR=str(package))
    assert used["code"] == 0 and used["stats"] == {"built": 1, "loaded": 0, "discarded": 0}
    assert not list((tmp_path / "one" / "kernels").glob("dop853_*"))
    # the same numbers as the loop the kernel cache builds
    cached = run_json(CLI, [*RUN, "-o", str(b)], tmp_path / "two")
    assert (
        cached["stats"]["built"] == 2 and len(list((tmp_path / "two" / "kernels").glob("dop853_*.so"))) == 1
    )
    x, y = np.load(a), np.load(b)
    assert x.files == y.files and all(np.array_equal(x[k], y[k]) for k in x.files)


@needs_cc
@pytest.mark.parametrize("kind", ["another source", "not a library", "truncated"])
def test_a_packaged_loop_library_of_another_build_is_ignored(tmp_path, monkeypatch, kind):
    # an installation of other sources (an edited checkout), or a damaged file (which the loader
    # could crash on: a truncated library gave SIGBUS): the kernel cache builds this run's loop
    package = tmp_path / "package"
    library = package / "_dop853_loop.so"
    if kind == "another source":
        source = _ckernel.loop_source()
        monkeypatch.setattr(_ckernel, "loop_source", lambda: source + "\n/* another */\n")
        _ckernel.install_loop(library)
    elif kind == "truncated":
        _ckernel.install_loop(library)
        library.write_bytes(library.read_bytes()[:10000])
    else:
        package.mkdir()
        library.write_bytes(b"\x7fELF not a library")
    run = run_json(CLI, [*RUN, "-o", str(tmp_path / "a.npz")], tmp_path / "cache", PACKAGED_DIR=str(package))
    assert run["code"] == 0 and run["stats"]["built"] == 2
    assert len(list((tmp_path / "cache" / "kernels").glob("dop853_*.so"))) == 1


@needs_cc
def test_warm_command_line_run_needs_no_sympy_and_no_compiler(tmp_path):
    out = [str(tmp_path / "a.npz"), str(tmp_path / "b.npz"), str(tmp_path / "c.npz")]
    cold = run_json(CLI, [*RUN, "-o", out[0]], tmp_path / "cache")
    assert cold["code"] == 0 and cold["sympy"] and cold["stats"]["built"] == 2
    assert "chaplygin [auto: c]: success" in cold["stdout"]
    warm = run_json(CLI, [*RUN, "-o", out[1]], tmp_path / "cache")
    assert warm["code"] == 0 and not warm["sympy"]
    assert warm["stats"] == {"built": 0, "loaded": 2, "discarded": 0}
    assert warm["stdout"].replace(out[1], out[0]) == cold["stdout"]
    a, b = np.load(out[0]), np.load(out[1])
    assert a.files == b.files and all(np.array_equal(a[k], b[k]) for k in a.files)
    # another independent velocity is applied from the plan, and so are another configuration
    # or parameter where the plan's start checks pass by a wide margin; a start the full path
    # refuses (here a kinetic energy not positive definite) and a dependent velocity that
    # violates the constraints take the full path, which reports them
    faster = run_json(CLI, [*RUN, "-o", out[2], "-i", "phi'=7"], tmp_path / "cache")
    assert faster["code"] == 0 and not faster["sympy"]
    assert abs(float(np.load(out[2])["phi'"][0]) - 7) < 1e-15
    for override in (["-i", "theta=0.2"], ["-p", "m=2"]):
        moved = run_json(CLI, [*RUN, "-o", out[2], "--force", *override], tmp_path / "cache")
        assert moved["code"] == 0 and not moved["sympy"], override

    def full_path(out: str, *override: str) -> subprocess.CompletedProcess:
        return subprocess.run(
            [sys.executable, "-m", "chaplygin", *RUN, "-o", str(tmp_path / out), *override],
            capture_output=True,
            text=True,
            timeout=600,
            check=False,
            env={**os.environ, "CHAPLYGIN_CACHE": str(tmp_path / "cache"), "PYTHONPATH": SRC},
        )

    refused = full_path("e.npz", "-p", "m=-1")
    assert refused.returncode == 1 and "not positive definite at the initial state" in refused.stderr
    bad = full_path("d.npz", "-i", "x'=5")
    assert bad.returncode == 1 and "violates the constraints" in bad.stderr


@pytest.mark.parametrize(
    ("backend", "env"),
    [("numpy", {}), ("auto", {"CHAPLYGIN_CC": "none"}), ("numba", {})],
)
def test_warm_runs_of_the_python_backends_need_no_sympy(tmp_path, backend, env):
    """The numpy and numba backends have run plans too (auto without a C compiler is numpy)."""
    cache, out = tmp_path / "cache", [str(tmp_path / f"{k}.npz") for k in "abc"]
    args = [*RUN, "-b", backend]
    cold = run_json(CLI, [*args, "-o", out[0]], cache, **env)
    warm = run_json(CLI, [*args, "-o", out[1]], cache, **env)
    assert cold["code"] == warm["code"] == 0 and cold["sympy"] and not warm["sympy"]
    assert warm["stdout"].replace(out[1], out[0]) == cold["stdout"]
    a, b = np.load(out[0]), np.load(out[1])
    assert a.files == b.files and all(np.array_equal(a[k], b[k]) for k in a.files)
    # a plan is kept per backend: the c backend's run does not answer from this one
    if HAVE_CC and backend != "auto":
        other = run_json(CLI, [*RUN, "-b", "c", "-o", out[2]], cache)
        assert other["code"] == 0 and other["sympy"] and "chaplygin [c]" in other["stdout"]


@needs_cc
def test_a_corrupt_run_plan_is_ignored_and_replaced(tmp_path):
    cache = tmp_path / "cache"
    run_json(CLI, [*RUN, "-o", str(tmp_path / "a.npz")], cache)
    # (the run plan: the other entries are the compiled model and the pole functions)
    (plan,) = [
        p for p in (cache / "derivations").glob("*.json") if '"defaulted"' in p.read_text(encoding="utf-8")
    ]
    plan.write_text(plan.read_text(encoding="utf-8").replace('"fill"', '"fil"'), encoding="utf-8")
    again = run_json(CLI, [*RUN, "-o", str(tmp_path / "b.npz")], cache)
    assert again["code"] == 0 and again["sympy"]  # the full path ran
    assert not run_json(CLI, [*RUN, "-o", str(tmp_path / "c.npz")], cache)["sympy"]  # and stored a good plan


def test_auto_says_which_backend_ran(tmp_path):
    without = run_json(CLI, [*RUN, "-o", str(tmp_path / "a.npz")], tmp_path, CHAPLYGIN_CC="none")
    assert "chaplygin [auto: numpy]: success" in without["stdout"]
    forced = run_json(CLI, [*RUN, "-o", str(tmp_path / "b.npz"), "-b", "numpy"], tmp_path)
    assert "chaplygin [numpy]: success" in forced["stdout"]
    if HAVE_CC:
        c = run_json(CLI, [*RUN, "-o", str(tmp_path / "c.npz"), "-b", "c"], tmp_path)
        assert "chaplygin [c]: success" in c["stdout"]
        a, b = np.load(tmp_path / "b.npz"), np.load(tmp_path / "c.npz")
        assert max(float(np.max(np.abs(a[k] - b[k]))) for k in a.files) < 1e-8


def test_auto_says_why_it_integrated_in_numpy(tmp_path):
    # a C compiler that is there but fails: "auto" takes the numpy backend, and says why
    run = run_json(CLI, [*RUN, "-o", str(tmp_path / "a.npz")], tmp_path, CHAPLYGIN_CC="false")
    assert "chaplygin [auto: numpy]: success" in run["stdout"]
    assert (
        "note: integrated by the numpy backend: backend 'c' cannot be used: the C compiler 'false'"
        in run["stdout"]
    )


def test_auto_in_the_api():
    disk = examples.rolling_disk()
    start = {
        "psi": 0.0,
        "theta": 0.3,
        "phi": 0.0,
        "x": 0.0,
        "y": 0.0,
        "psi'": 2.0,
        "theta'": 0.0,
        "phi'": 5.0,
    }
    params = {"m": 1.0, "r": 0.5, "A": 0.0625, "C": 0.125, "g": 9.81}
    tr = simulate(disk, "chaplygin", 1.0, start, params, samples=11)
    assert tr.backend == ("c" if HAVE_CC else "numpy") and tr.success
    assert choose_backend("auto", "RK45") == "numpy" and choose_backend("numba", "DOP853") == "numba"
    assert (
        simulate(disk, "chaplygin", 1.0, start, params, samples=11, method="midpoint", step=0.1).backend
        == "numpy"
    )
    with pytest.raises(chaplygin.ChaplyginError, match="unknown backend 'fortran'"):
        simulate(disk, "chaplygin", 1.0, start, params, backend="fortran")


def test_generated_source_is_the_same_in_every_process(tmp_path):
    """numba's on-disk cache is keyed by the generated file: it must not change between processes."""
    script = """
import hashlib, json
from chaplygin import examples
from chaplygin.numeric.codegen import _source
eqs = examples.rolling_disk().equations("chaplygin")
print(json.dumps({"digest": hashlib.sha256(_source(eqs, "numba")[1].encode()).hexdigest()}))
"""
    digests = {run_json(script, [], tmp_path, PYTHONHASHSEED=str(seed))["digest"] for seed in (1, 2, 3)}
    assert len(digests) == 1


def test_symmetric_methods_are_named_alike():
    assert SYMMETRIC_METHODS == tuple(METHODS)


# a process that integrates one example's model with the numba loop, then reports what numba
# compiled (cache misses) and loaded (cache hits) for the shared loop and for the model's fill
LOOP = """
import json, sys
import numpy as np
from numba.core.registry import CPUDispatcher
from chaplygin import examples
from chaplygin.numeric import _loop
from chaplygin.numeric.codegen import compile_model
system = getattr(examples, sys.argv[1])()
model = _loop.loop_model(compile_model(system, "chaplygin", backend="numba"))
y0 = np.full(len(model.layout.state), 0.1)
p = np.ones(len(model.layout.parameters))
run = _loop.integrate_dop853(model, (0.0, 0.1), y0, p, np.array([0.1]))
kernels = [f for f in vars(_loop.shared()).values() if isinstance(f, CPUDispatcher)]
print(json.dumps({
    "status": run.status,
    "loop_misses": sum(sum(f.stats.cache_misses.values()) for f in kernels),
    "loop_hits": sum(sum(f.stats.cache_hits.values()) for f in kernels),
    "fill_hits": model.module.fill_c.cache_hits,
    "loop_file": _loop.shared().__file__,
}))
"""


def test_the_numba_loop_is_compiled_once_for_every_model(tmp_path):
    """A second model, in a fresh process, compiles only its own fill: the loop is loaded."""
    numba_cache = {"NUMBA_CACHE_DIR": str(tmp_path / "numba")}  # this test's own, cold
    first = run_json(LOOP, ["rolling_disk"], tmp_path / "cache", **numba_cache)
    second = run_json(LOOP, ["knife_edge"], tmp_path / "cache", **numba_cache)
    assert first["status"] == second["status"] == "success"
    assert first["loop_misses"] > 0 and first["fill_hits"] == 0  # cold: the loop was compiled
    assert second["loop_file"] == first["loop_file"]
    assert second["loop_misses"] == 0 and second["loop_hits"] > 0  # loaded, not compiled
    assert second["fill_hits"] == 0  # a model never seen: its fill was compiled
    again = run_json(LOOP, ["knife_edge"], tmp_path / "cache", **numba_cache)
    assert again["loop_misses"] == 0 and again["fill_hits"] == 1  # and then loaded too
