"""Test-suite set-up: reproducible Hypothesis runs, numba's cache per xdist worker, xdist groups.

``make test`` runs the suite on all cores with pytest-xdist (``-n auto --dist loadgroup``); a
plain ``python -m pytest tests/test_x.py`` runs serially, with the same settings.
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
from pathlib import Path

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
settings.register_profile(
    "thorough", parent=settings.get_profile("ci"), max_examples=200, derandomize=False
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

# ---------------------------------------------------------------- caches
# The run's own cache (generated modules, C libraries, derivations), unless CHAPLYGIN_CACHE names
# one: a fresh directory made by the first process (plain pytest, or xdist's controller, whose
# workers and their subprocesses inherit it) and removed at the end. So no run depends on, or
# fills, the user's cache. All xdist workers share it: every file in it is content-addressed and
# written atomically (a temporary file, then a rename). numba's cache of compiled functions is not
# race-free between processes (two processes compiling different signatures of one function at
# once can number their data files alike), so each worker keeps its own, inside the run's cache;
# set before anything imports numba, which reads NUMBA_CACHE_DIR once.
_RUN_CACHE: str | None = None
if not os.environ.get("CHAPLYGIN_CACHE"):
    _RUN_CACHE = os.environ["CHAPLYGIN_CACHE"] = tempfile.mkdtemp(prefix="chaplygin-tests-")
_WORKER = os.environ.get("PYTEST_XDIST_WORKER")
if _WORKER and "NUMBA_CACHE_DIR" not in os.environ:
    os.environ["NUMBA_CACHE_DIR"] = os.path.join(os.environ["CHAPLYGIN_CACHE"], "numba", _WORKER)


def pytest_unconfigure(config: pytest.Config) -> None:
    if _RUN_CACHE is not None:
        shutil.rmtree(_RUN_CACHE, ignore_errors=True)


# ---------------------------------------------------------------- xdist scheduling
#: modules whose tests share no costly fixture or compiled model: xdist spreads their tests over
#: the workers; every other module goes to one worker as a whole, so that its module-scoped
#: fixtures, and the models its tests compile, are built once
SPREAD = {
    "test_cache.py", "test_cfill.py", "test_docs.py", "test_files.py", "test_integrability.py",
    "test_mechanics.py", "test_models_property.py", "test_native.py", "test_parser.py",
    "test_scale.py", "test_validation.py",
}
#: the longest modules, started first so that no worker is left running one at the end
FIRST = ("test_symmetric.py", "test_backends.py", "test_sweep.py", "test_vakonomic.py",
         "test_gallery.py", "test_rolling_disk.py", "test_cli.py", "test_models_property.py",
         "test_cfill.py", "test_docs.py")


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
