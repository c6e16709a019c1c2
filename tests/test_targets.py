"""The code targets (:mod:`chaplygin.numeric.targets`): one module each behind one interface,
found by name in one table, imported when first asked for; a fifth is one module and one row."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from chaplygin import ChaplyginError, examples
from chaplygin.numeric import codegen, ensemble, simulate, targets


def test_every_row_is_a_module_with_its_target() -> None:
    """Each row's module defines TARGET, a Target of the row's name; the entry points take the
    backends they took before the table (the table is where they come from now)."""
    for name in targets.TARGETS:
        target = targets.get(name)
        assert isinstance(target, targets.Target) and target.name == name
    assert simulate.BACKENDS == ("auto", "numpy", "numba", "c", "jax")
    assert set(codegen.BACKENDS) == {"numpy", "numba", "jax", "c"}
    assert set(ensemble.ENSEMBLE_BACKENDS) == {"auto", "c", "numba", "jax", "cuda"}
    with pytest.raises(ChaplyginError, match="unknown backend 'fortran'; the backends are 'numpy'"):
        targets.get("fortran")


def test_a_target_of_another_entry_point_is_named_as_such() -> None:
    """backend='cuda' (ensembles only) given to simulate or compile_model: the message says where
    it serves and what the entry point takes, not that 'cuda' is unknown."""
    for call, entry in (
        (lambda: simulate.choose_backend("cuda"), "simulate"),
        (lambda: codegen._check_backend("cuda"), "compile_model"),
    ):
        with pytest.raises(
            ChaplyginError,
            match=f"backend 'cuda' serves simulate_ensemble, not {entry}; {entry}'s backends are",
        ):
            call()
    with pytest.raises(ChaplyginError, match="unknown backend 'fortran'; the backends are 'auto', 'numpy'"):
        simulate.choose_backend("fortran")


def test_a_target_is_imported_when_first_asked_for() -> None:
    """Choosing a backend imports its target's module only: no other target, and none of numba,
    JAX or CuPy (which the C target does not use)."""
    script = (
        "import sys\n"
        "from chaplygin.numeric.simulate import choose_backend\n"
        "from chaplygin.numeric import targets\n"
        "assert choose_backend('auto') == ('c' if targets.get('c').unavailable() is None else 'numpy')\n"
        "print(sorted(m for m in sys.modules if m.startswith('chaplygin.numeric.targets.')))\n"
        "print(sorted({m.split('.')[0] for m in sys.modules} & {'numba', 'jax', 'cupy', 'sympy'}))\n"
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    assert out.stdout.split("\n")[:2] == ["['chaplygin.numeric.targets.c']", "[]"]


def test_a_fifth_target_is_one_module_and_one_row(monkeypatch) -> None:
    """A target added as docs/architecture.md says (tests/fifth_target.py and a row of the table)
    compiles and runs a knife edge through simulate(): the entry point calls it, and the run
    is the closed form (φ̇ = ω and the speed v constant: x = v/ω (sin φ − sin φ₀),
    y = −v/ω (cos φ − cos φ₀)) to the tolerance."""
    import fifth_target

    monkeypatch.setenv("CHAPLYGIN_MODEL_CACHE", "off")  # built here, not loaded from an earlier run
    monkeypatch.setitem(
        targets.TARGETS, "traced", targets.Row("fifth_target", compile=True, simulate=True, ensemble=False)
    )
    fifth_target.TARGET.calls.clear()
    knife = examples.knife_edge()
    phi0, omega, v = 0.3, 0.5, 1.5
    start = {"x": 0.0, "y": 0.0, "phi": phi0, "x'": v * np.cos(phi0), "phi'": omega}
    run = simulate.simulate(
        knife, "chaplygin", 2.0, start, {"m": 1.0, "J": 0.5}, samples=21, backend="traced"
    )
    assert run.backend == "traced" and run.success
    calls = fifth_target.TARGET.calls  # (integrated again between samples: the knife edge has a pole)
    assert calls[:3] == ["build", "integrate", "observe_run"] and set(calls) == set(calls[:3])
    phi = phi0 + omega * run.t
    assert np.max(np.abs(run["phi"] - phi)) < 1e-9
    assert np.max(np.abs(run["x"] - v / omega * (np.sin(phi) - np.sin(phi0)))) < 1e-9
    assert np.max(np.abs(run["y"] + v / omega * (np.cos(phi) - np.cos(phi0)))) < 1e-9
    with pytest.raises(ChaplyginError, match="ensembles run on 'auto', 'numba', 'c', 'jax', 'cuda'"):
        ensemble.simulate_ensemble(knife, "chaplygin", 1.0, [start], {"m": 1.0, "J": 0.5}, backend="traced")


def test_the_model_is_looked_up_by_name_once_per_entry_point(monkeypatch) -> None:
    """simulate(), simulate_ensemble() and compare() resolve each model's name into the registry's
    entry at the front door and hand the entry down (on 4672eb7 a compiled knife edge's simulate
    looked 'chaplygin' up 4 times, its ensemble 5 times, compare of two models 16 times: again in
    _vakonomic_setup, _model_key, reduces_numerically, _states, motion_notes, _takes_constants)."""
    from chaplygin import compare
    from chaplygin.models import registry
    from chaplygin.numeric._ckernel import Unavailable, compiler

    knife, params = examples.knife_edge(), {"m": 1.0, "J": 0.5}
    start = {"x": 0.0, "y": 0.0, "phi": 0.3, "x'": 1.0, "phi'": 0.2}
    backend = "numpy"
    try:
        compiler()
        backend = "c"  # (ensembles run on the compiled loops)
    except Unavailable:  # pragma: no cover - every CI machine has a C compiler
        pytest.skip("no C compiler for the ensemble")
    for model in ("chaplygin", "chetaev"):  # compiled and derived before counting
        simulate.simulate(knife, model, 0.5, start, params, samples=3, backend=backend)
    names: list[str] = []
    get = registry.get

    def counted(name, *args, **kwargs):
        if isinstance(name, str):
            names.append(name)
        return get(name, *args, **kwargs)

    monkeypatch.setattr(registry, "get", counted)
    simulate.simulate(knife, "chaplygin", 0.5, start, params, samples=3, backend=backend)
    assert names == ["chaplygin"]
    names.clear()
    ensemble.simulate_ensemble(knife, "chaplygin", 0.5, [start, start], params, backend=backend)
    assert names == ["chaplygin"]
    names.clear()
    compare(knife, ["chaplygin", "chetaev"], 0.5, start, params, samples=3, backend=backend)
    assert names == ["chaplygin", "chetaev", "chaplygin", "chetaev"]  # compare's, then simulate's
