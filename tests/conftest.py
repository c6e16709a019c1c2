"""Test-suite set-up: reproducible Hypothesis runs, numba's cache per xdist worker, xdist scheduling.

``make test`` runs the suite on all cores with pytest-xdist (``-n auto``, scheduled below); a
plain ``python -m pytest tests/test_x.py`` runs serially, with the same settings.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, settings

sys.path.insert(0, str(Path(__file__).parent))

# ---------------------------------------------------------------- Hypothesis
# "ci" (the default): the same examples on every run and every machine (derandomize=True, which
# also turns Hypothesis' example database off), so a CI result can be reproduced anywhere.
# HYPOTHESIS_PROFILE=thorough explores: 200 fresh random examples a test, failures remembered.
settings.register_profile(
    "ci",
    deadline=None,
    max_examples=12,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
settings.register_profile("thorough", parent=settings.get_profile("ci"), max_examples=200, derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

# ---------------------------------------------------------------- caches
# chaplygin's cache ($CHAPLYGIN_CACHE, else the user's cache directory: generated modules, C
# libraries, derivations) is shared by all xdist workers, their subprocesses and later runs, as in
# normal use: every file in it is content-addressed, verified or compared on reading, and written
# atomically (a temporary file, then a rename). Point CHAPLYGIN_CACHE at an empty directory for a
# cold run. numba's cache of compiled functions is not race-free between processes (two processes
# compiling different signatures of one function at once can both take data file 1, and the index
# then maps a signature to the other's code), so each xdist worker keeps its own, beside
# chaplygin's; set before anything imports numba, which reads NUMBA_CACHE_DIR once.
_WORKER = os.environ.get("PYTEST_XDIST_WORKER")
if _WORKER and "NUMBA_CACHE_DIR" not in os.environ:
    from chaplygin.numeric.cache import cache_dir  # imports neither numba nor SymPy

    os.environ["NUMBA_CACHE_DIR"] = str(cache_dir() / "numba-test-workers" / _WORKER)


# ---------------------------------------------------------------- xdist scheduling
#: modules whose tests share no costly fixture or compiled model: xdist spreads their tests over
#: the workers; every other module goes to one worker as a whole, so that its module-scoped
#: fixtures, and the models its tests compile, are built once
SPREAD = {
    "test_cache.py",
    "test_cfill.py",
    "test_docs.py",
    "test_files.py",
    "test_integrability.py",
    "test_mechanics.py",
    "test_models_property.py",
    "test_native.py",
    "test_parser.py",
    "test_scale.py",
    "test_validation.py",
}
#: the longest modules, started first so that no worker is left running one at the end
FIRST = (
    "test_symmetric.py",
    "test_backends.py",
    "test_sweep.py",
    "test_vakonomic.py",
    "test_gallery.py",
    "test_rolling_disk.py",
    "test_cli.py",
    "test_models_property.py",
    "test_nonlinear_models.py",
    "test_cfill.py",
    "test_docs.py",
)


def pytest_xdist_make_scheduler(config: pytest.Config, log: object) -> object | None:
    """Under ``-n``: whole modules, or single tests of the SPREAD modules, in FIRST's order.

    (pytest-xdist's own ``--dist loadgroup`` cannot group here: it renames ``item._nodeid``,
    which pytest 9 no longer reads.)  ``--dist each``/``worksteal`` keep xdist's scheduling.
    """
    if config.getvalue("dist") not in ("load", "loadscope", "loadfile", "loadgroup"):
        return None
    from xdist.scheduler import LoadScopeScheduling

    class ModuleScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            module = nodeid.split("::", 1)[0]
            return nodeid if module.rsplit("/", 1)[-1] in SPREAD else module

    config.option.loadscopereorder = False  # keep the collection order below, not xdist's by size
    return ModuleScheduling(config, log)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Under xdist, FIRST's modules first (the other modules keep their order)."""
    if hasattr(config, "workerinput"):  # an xdist worker: under xdist only the workers collect
        rank = {name: k for k, name in enumerate(FIRST)}
        items.sort(key=lambda item: rank.get(item.path.name, len(FIRST)))


@pytest.fixture(scope="module")
def failing() -> Any:
    """A system that fails in two ways (test_backends, test_pyloop): ẍ = k ẋ² blows up at
    t = 1/(k ẋ(0)), and the mass of y drops to exactly 0 at t = a."""
    import sympy as sp
    from sympy.physics.mechanics import dynamicsymbols

    from chaplygin import System
    from chaplygin.core._symbols import TIME

    x, y, z = dynamicsymbols("x y z")
    a, k = sp.symbols("a k", positive=True)
    mass_y = sp.Piecewise((1, TIME < a), (0, True))
    T = sp.Rational(1, 2) * x.diff(TIME) ** 2 + sp.Rational(1, 2) * mass_y * y.diff(TIME) ** 2
    return System(
        [x, y, z], T, {z.diff(TIME): y.diff(TIME)}, forces={x: k * x.diff(TIME) ** 2}, name="failing"
    )
