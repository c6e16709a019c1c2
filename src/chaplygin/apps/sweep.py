"""Parameter and initial-condition sweeps, on one machine or on a Dask cluster.

:func:`sweep` simulates one model of a system over the Cartesian product of
a grid of parameter and initial values (``m=0.5:2:4`` × ``theta'=0.1:1:10``),
one run per point of the grid, and keeps one row per run: the inputs, the
status and message, the final state, the energy at start and end, the energy
drift and the largest constraint residual.

By default the runs go one after another in this process, which starts at
once; only when the runs measured so far say that the rest would take longer
than :data:`AUTO_CLUSTER_SECONDS` does the sweep hand the rest to a Dask
``LocalCluster`` (``dask.distributed``) of worker processes on this machine.
A cluster is also used when asked for: ``scheduler="local"`` (or ``workers``)
for a ``LocalCluster``, or any running cluster by the address of its
scheduler.  Each worker process builds the system and compiles
the model once (the generated code lives in :func:`chaplygin.numeric.codegen.cache_dir`)
and then runs chunks of grid points.  A worker that dies (killed, out of
memory) loses nothing: the scheduler hands its tasks to the other workers.  A
run that fails (a singular mass matrix, a blow-up, an error) is a row with
status ``"failed"`` and the message; only a run that keeps killing the
workers that take it (``distributed``'s ``KilledWorker``) is recorded as
failed for that reason.

The results are a Parquet dataset: a directory (``results.parquet``) of part
files, each written to a hidden temporary file and renamed, so that a crash
in the middle of a write leaves every earlier part intact.  Finished runs are
written every ``flush_seconds`` (and whenever the sweep stops, Ctrl-C
included); ``resume=True`` reads what is there and runs only the missing run
ids.  A finished sweep is compacted into one part file, sorted by run id.
``pyarrow.parquet.read_table(path)`` (or pandas' ``read_parquet``) reads the
directory; :func:`read_results` also sorts by run id and drops the duplicates
that an interrupted compaction can leave.

Optional extra ``chaplygin[sweep]``: ``dask[distributed]`` and ``pyarrow``
(a sweep that runs in this process needs only ``pyarrow``).
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import importlib.util
import json
import math
import os
import pickle
import re
import tempfile
import threading
import time
from collections import OrderedDict, deque
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from chaplygin.errors import ChaplyginError
from chaplygin.models import registry
from chaplygin.numeric import targets
from chaplygin.numeric.simulate import TIME_LIMIT

if TYPE_CHECKING:
    import pyarrow as pa

    from chaplygin.core.system import System
    from chaplygin.io.files import SystemFile

__all__ = [
    "AUTO_CLUSTER_SECONDS",
    "SCHEMA",
    "SWEEP_BACKENDS",
    "Axis",
    "SweepOutputExists",
    "SweepResult",
    "grid_values",
    "parse_grid",
    "read_results",
    "sweep",
]

SCHEMA = "chaplygin.apps.sweep/1"
#: what ``backend=`` accepts: "auto" (the default) is what :func:`chaplygin.numeric.simulate`
#: runs: "c" where a C compiler is found, else "numpy" (:func:`~chaplygin.numeric.simulate.choose_backend`)
SWEEP_BACKENDS = ("auto", *targets.offered("sweep"))
#: what a backend compiles before the first run of a model, and about how long that takes when
#: nothing is cached (2 busy cores: the C loop and a model's fill 1-2 s, numba's about 19 s);
#: ``notice`` of :func:`sweep` is told so then, and not when the compiled model is cached
FIRST_COMPILE = {"c": ("the C kernel", 2), "numba": ("numba's code", 20)}
META_FILE = "_sweep.json"
LOCK_FILE = "_sweep.lock"
PART_PATTERN = re.compile(r"part-(\d{6,})\.parquet\Z")
MAX_RUNS = 100_000_000
MAX_MESSAGE = 2000
GRID_SYNTAX = "NAME=START:STOP:COUNT (e.g. theta=0.1:0.5:5) or NAME=V1,V2,... (e.g. m=1,2,4)"
EXTRA_HINT = "pip install 'chaplygin[sweep]' (dask[distributed] and pyarrow)"
#: A sweep given no scheduler runs in this process until the runs measured so far (the first,
#: which builds and compiles the model, left out) say that the rest would take longer than this;
#: then it hands the rest to a LocalCluster.  A LocalCluster costs seconds to tens of seconds to
#: start (worker processes that import chaplygin, derive the model and load its compiled code:
#: 5-20 s measured on 2 busy cores with the code cache warm, ~50 s seen on a busier or colder
#: machine), which only work of this order can win back, and only with more than one core.
AUTO_CLUSTER_SECONDS = 30.0

#: columns every sweep has, after the inputs (``grid.*``, ``param.*``, ``initial.*``: every
#: coordinate and every velocity, a dependent one as the constraints give it at the start)
OUTCOME_COLUMNS = ("status", "message", "t_end", "t_reached")
INVARIANT_COLUMNS = (
    "energy_initial",
    "energy_final",
    "energy_drift",
    "max_constraint_residual",
    "rhs_evaluations",
    "wall_time",
)


class SweepOutputExists(ChaplyginError):
    """The output exists and neither ``resume`` nor ``force`` was given, or it holds another sweep."""


# ====================================================================== optional dependencies
def _require(module: str) -> Any:
    """Import ``module`` (``"pyarrow.parquet"``, ``"distributed"``) or say which extra provides it."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise ChaplyginError(
            f"sweeps need {module.split('.')[0]}, which is not installed ({exc}); {EXTRA_HINT}."
        ) from None


# ====================================================================== the grid
@dataclass(frozen=True)
class Axis:
    """One swept quantity: a parameter or an initial value, and its values.

    Attributes
    ----------
    name : str
        A parameter (``"m"``), a coordinate (``"theta"``) or an independent
        velocity (``"theta'"``).
    kind : {"parameter", "initial"}
    values : tuple of float
    """

    name: str
    kind: str
    values: tuple[float, ...]

    @property
    def column(self) -> str:
        """The column of the inputs that holds this axis (``param.m``, ``initial.theta'``)."""
        return ("param." if self.kind == "parameter" else "initial.") + self.name


def grid_values(spec: str | Sequence[float] | np.ndarray, name: str = "grid") -> np.ndarray:
    """The values of one axis from ``"START:STOP:COUNT"``, ``"V1,V2,…"`` or numbers.

    ``START:STOP:COUNT`` means ``numpy.linspace(START, STOP, COUNT)``, both ends
    included.

    Raises
    ------
    ChaplyginError
        For malformed text, a count that is not a positive integer, repeated
        values, or values that are not finite numbers.
    """
    where = f"--grid {name}"
    if isinstance(spec, str):
        text = spec.strip()
        if ":" in text:
            parts = [p.strip() for p in text.split(":")]
            if len(parts) != 3:
                raise ChaplyginError(f"{where}={spec!r}: expected {GRID_SYNTAX}.")
            try:
                start, stop = float(parts[0]), float(parts[1])
            except ValueError:
                raise ChaplyginError(
                    f"{where}={spec!r}: START and STOP must be numbers; expected {GRID_SYNTAX}."
                ) from None
            try:
                count = int(parts[2])
            except ValueError:
                raise ChaplyginError(
                    f"{where}={spec!r}: COUNT must be a positive integer; expected {GRID_SYNTAX}."
                ) from None
            if not 1 <= count <= MAX_RUNS:
                raise ChaplyginError(
                    f"{where}={spec!r}: COUNT must be a positive integer (at most {MAX_RUNS}), not {count}."
                )
            if count == 1 and start != stop:
                raise ChaplyginError(
                    f"{where}={spec!r}: one value (COUNT 1) needs START = STOP; give COUNT ≥ 2."
                )
            values = np.linspace(start, stop, count)
        else:
            try:
                values = np.array([float(v) for v in text.split(",")], dtype=float)
            except ValueError:
                raise ChaplyginError(f"{where}={spec!r}: expected {GRID_SYNTAX}.") from None
    else:
        try:
            values = np.asarray(spec, dtype=float).ravel()
        except (TypeError, ValueError):
            raise ChaplyginError(f"grid {name!r}: expected numbers or a string {GRID_SYNTAX}.") from None
    if values.size == 0:
        raise ChaplyginError(f"{where}: no values; expected {GRID_SYNTAX}.")
    if not np.all(np.isfinite(values)):
        raise ChaplyginError(f"{where}: every value must be a finite number, not {values.tolist()}.")
    if len(set(values.tolist())) != values.size:  # (np.unique would import numpy.ma: 0.01 s of a warm sweep)
        raise ChaplyginError(
            f"{where}: repeated values {values.tolist()}; each point of the grid is one run."
        )
    return values


def parse_grid(text: str) -> tuple[str, np.ndarray]:
    """``"NAME=START:STOP:COUNT"`` (or ``"NAME=V1,V2,…"``) → ``(NAME, values)``.

    Raises
    ------
    ChaplyginError
        With the accepted syntax, for anything else.
    """
    name, sep, spec = text.partition("=")
    name = name.strip()
    if not sep or not name or not spec.strip():
        raise ChaplyginError(f"--grid {text!r}: expected {GRID_SYNTAX}.")
    return name, grid_values(spec, name)


# ====================================================================== the system, as workers rebuild it
@dataclass(frozen=True)
class _Recipe:
    """How a worker process rebuilds the system: an example's name, a file's text, or a pickle."""

    kind: str  # "example" | "toml" | "pickle"
    payload: Any
    source: str
    default_name: str | None
    digest: str

    def build(self) -> System:
        if self.kind == "example":
            from chaplygin import examples

            return examples.get(self.payload).constructor()
        if self.kind == "toml":
            from chaplygin.io.files import _loads

            return _loads(self.payload, self.source, self.default_name).system
        if self.kind == "pickle":
            return pickle.loads(self.payload)  # our own client's System, pickled as Dask ships objects
        raise ChaplyginError(f"{self.source}: this System lives only in the process that started the sweep.")


_SYSTEMS: OrderedDict[str, System] = OrderedDict()
_SYSTEMS_LOCK = threading.Lock()


def _system_for(recipe: _Recipe) -> System:
    """The system of ``recipe``, built once per process (its equations and compiled code with it)."""
    with _SYSTEMS_LOCK:
        system = _SYSTEMS.get(recipe.digest)
        if system is None:
            system = recipe.build()
            _SYSTEMS[recipe.digest] = system
            while len(_SYSTEMS) > 4:
                _SYSTEMS.popitem(last=False)
        _SYSTEMS.move_to_end(recipe.digest)
        return system


def _remember(recipe: _Recipe, system: System) -> None:
    with _SYSTEMS_LOCK:
        _SYSTEMS[recipe.digest] = system
        while len(_SYSTEMS) > 4:
            _SYSTEMS.popitem(last=False)


def _fingerprint(system: System) -> str:
    """A hash of what the system is (coordinates, energies, forces, constraints), stable across runs."""
    import sympy as sp

    text = sp.srepr(
        (
            system.name,
            tuple(system.coordinates),
            system.kinetic_energy,
            system.potential_energy,
            system.forces,
            system.constraints,
            *((system.holonomic,) if system.holonomic else ()),  # (f's constant is not in ḟ)
        )
    )
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _resolve(
    spec: System | SystemFile | str | os.PathLike[str],
    local: bool,
) -> tuple[System, _Recipe, dict[str, float], dict[str, float], str, SystemFile | None]:
    """``(system, recipe, default parameters, default initial state, label, the file read)`` of
    what was given (the file read: of a system file's path, else None).

    A ``System`` object travels to Dask workers as a pickle (without its derived equations); in
    a sweep that starts in this process (``local``) it is used as it is.
    """
    from chaplygin.core.system import System
    from chaplygin.io.files import SystemFile, _loads

    if isinstance(spec, SystemFile):
        recipe = _object_recipe(spec.system, spec.source, local)
        return spec.system, recipe, dict(spec.parameters), dict(spec.initial), spec.source, None
    if isinstance(spec, System):
        return spec, _object_recipe(spec, spec.name, local), {}, {}, spec.name, None
    if isinstance(spec, str) and spec.startswith("example:"):
        from chaplygin import examples

        name = spec[len("example:") :]
        entry = examples.get(name)
        recipe = _Recipe("example", name, spec, None, hashlib.sha256(spec.encode()).hexdigest())
        system = _system_for(recipe)
        return system, recipe, dict(entry.parameters), dict(entry.initial), spec, None
    if isinstance(spec, (str, os.PathLike)):
        from chaplygin.io.files import SystemFileError

        source = os.fspath(spec)
        try:
            text = _read(source)
        except OSError as exc:
            raise SystemFileError(f"cannot read the file: {exc.strerror or exc}", source=source) from None
        except UnicodeDecodeError as exc:
            raise SystemFileError(f"the file is not UTF-8 text (byte {exc.start})", source=source) from None
        loaded = _loads(text, source, Path(source).stem)  # the defaults, and errors in the file, here
        digest = hashlib.sha256(f"{source}\0{text}".encode()).hexdigest()
        recipe = _Recipe("toml", text, source, Path(source).stem, digest)
        with _SYSTEMS_LOCK:
            known = _SYSTEMS.get(digest)  # the same file again: keep its derived equations
        system = known if known is not None else loaded.system
        _remember(recipe, system)
        return system, recipe, dict(loaded.parameters), dict(loaded.initial), source, loaded
    raise ChaplyginError(
        f"sweep: expected a System, a SystemFile, a system file's path or 'example:NAME', "
        f"not {type(spec).__name__}."
    )


def _object_recipe(system: System, source: str, local: bool) -> _Recipe:
    if local:
        recipe = _Recipe("local", None, source, None, f"local-{id(system)}-{_fingerprint(system)}")
        _remember(recipe, system)
        return recipe
    clone = copy.copy(system)
    clone.__dict__["_equations"] = {}  # derived equations hold compiled code; workers derive their own
    try:
        payload = pickle.dumps(clone, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception as exc:
        raise ChaplyginError(
            f"{system.name}: this System cannot be sent to Dask workers ({type(exc).__name__}: {exc}); "
            "save it as a system file (chaplygin.dumps) and sweep the file."
        ) from None
    recipe = _Recipe("pickle", payload, source, None, hashlib.sha256(payload).hexdigest())
    _remember(recipe, system)
    return recipe


# ====================================================================== one run
@dataclass(frozen=True)
class _Plan:
    """Everything a worker needs for any run of the sweep (sent with every task)."""

    recipe: _Recipe
    model: str
    form: str
    backend: str
    t_end: float
    samples: int
    rtol: float
    atol: float
    constants: Any
    parameters: tuple[tuple[str, float], ...]
    initial: tuple[tuple[str, float], ...]
    axes: tuple[Axis, ...]
    parameter_names: tuple[str, ...]
    initial_names: tuple[str, ...]
    coordinates: tuple[str, ...]
    #: each run's ``time_limit`` (see :func:`chaplygin.numeric.simulate.simulate`)
    time_limit: float | None = 3600.0

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(len(a.values) for a in self.axes)

    @property
    def runs(self) -> int:
        return math.prod(self.shape)

    def point(self, run_id: int) -> tuple[dict[str, float], dict[str, float], list[float]]:
        """Parameters, initial values and grid values of run ``run_id`` (C order: the last axis fastest)."""
        params, initial = dict(self.parameters), dict(self.initial)
        index = np.unravel_index(run_id, self.shape)
        values = []
        for axis, i in zip(self.axes, index):
            value = axis.values[int(i)]
            (params if axis.kind == "parameter" else initial)[axis.name] = value
            values.append(value)
        return params, initial, values

    def columns(self) -> list[str]:
        return [
            "run_id",
            *(f"grid.{a.name}" for a in self.axes),
            *(f"param.{p}" for p in self.parameter_names),
            *(f"initial.{q}" for q in self.coordinates),
            *(f"initial.{q}'" for q in self.coordinates),
            *OUTCOME_COLUMNS,
            *(f"final.{q}" for q in self.coordinates),
            *(f"final.{q}'" for q in self.coordinates),
            *INVARIANT_COLUMNS,
        ]


def _inputs(plan: _Plan, run_id: int) -> tuple[dict[str, Any], dict[str, float], dict[str, float]]:
    """The input columns of run ``run_id``, and its parameters and initial values."""
    params, initial, values = plan.point(run_id)
    row: dict[str, Any] = {"run_id": run_id}
    row.update({f"grid.{a.name}": v for a, v in zip(plan.axes, values)})
    row.update({f"param.{p}": params[p] for p in plan.parameter_names})
    row.update({f"initial.{q}'": math.nan for q in plan.coordinates})  # a dependent one: from the run
    row.update({f"initial.{q}": initial[q] for q in plan.initial_names})
    return row, params, initial


def _no_outcome(plan: _Plan) -> dict[str, Any]:
    """The outcome columns of a run that produced nothing: failed, NaN everywhere."""
    nan = float("nan")
    outcome: dict[str, Any] = {"status": "failed", "message": "", "t_end": plan.t_end, "t_reached": nan}
    outcome.update({f"final.{q}": nan for q in plan.coordinates})
    outcome.update({f"final.{q}'": nan for q in plan.coordinates})
    outcome.update({c: nan for c in INVARIANT_COLUMNS})
    outcome["rhs_evaluations"] = 0
    return outcome


def _run_one(system: System | None, plan: _Plan, run_id: int) -> dict[str, Any]:
    """One row: the run's inputs and its outcome; a run that raises is a failed row, never an error.

    A system file's run is answered by its run plan where one answers it exactly as the full
    path would (:mod:`chaplygin.numeric._plan`), else by the full path on ``system`` (None:
    built from the recipe when first needed).
    """
    from chaplygin.numeric.simulate import simulate

    row, params, initial = _inputs(plan, run_id)
    outcome = _no_outcome(plan)
    start = time.perf_counter()
    try:
        options: dict[str, Any] = {
            "form": plan.form,
            "samples": plan.samples,
            "backend": plan.backend,
            "rtol": plan.rtol,
            "atol": plan.atol,
        }
        if plan.constants is not None:
            options["constants"] = plan.constants
        options["time_limit"] = plan.time_limit
        tr = _planned(plan, params, initial)
        if tr is None:
            system = system if system is not None else _system_for(plan.recipe)
            tr = simulate(system, plan.model, plan.t_end, initial, params, **options)
            if tr.success and plan.recipe.kind == "toml":
                _MADE.setdefault(plan.recipe.digest, tr)  # what a run plan is made from
    except Exception as exc:
        outcome["message"] = f"{type(exc).__name__}: {exc}"[:MAX_MESSAGE]
    else:
        outcome["status"] = "success" if tr.success else "failed"
        outcome["message"] = "" if tr.success else str(tr.message)[:MAX_MESSAGE]
        outcome["rhs_evaluations"] = int(tr.rhs_evaluations)
        if len(tr.t):
            outcome["t_reached"] = float(tr.t[-1])
            for q in plan.coordinates:
                if q + "'" not in plan.initial_names:  # a dependent velocity, from the constraints
                    row[f"initial.{q}'"] = float(tr.velocities[q + "'"][0])
                outcome[f"final.{q}"] = float(tr.coordinates[q][-1])
                outcome[f"final.{q}'"] = float(tr.velocities[q + "'"][-1])
            outcome["energy_initial"] = float(tr.energy[0])
            outcome["energy_final"] = float(tr.energy[-1])
            outcome["energy_drift"] = tr.energy_drift()
            outcome["max_constraint_residual"] = float(np.max(tr.constraint_residual))
    outcome["wall_time"] = time.perf_counter() - start
    row.update(outcome)
    return row


def _run_chunk(plan: _Plan, run_ids: Sequence[int]) -> list[dict[str, Any]]:
    """The rows of ``run_ids`` (the task each worker runs); the system is built once per process
    (a system file's only when a run plan does not answer a run)."""
    with _SYSTEMS_LOCK:
        system = _SYSTEMS.get(plan.recipe.digest)
    if system is None and plan.recipe.kind != "toml":
        system = _system_for(plan.recipe)
    return [_run_one(system, plan, int(r)) for r in run_ids]


#: a successful full-path run of each system file swept in this process (by recipe digest): the
#: run plan is made from it at the end of the sweep (:func:`_keep_warm`)
_MADE: dict[str, Any] = {}


def _planned(plan: _Plan, params: dict[str, float], initial: dict[str, float]) -> Any:
    """The run of a system file from its run plan, or None (the full path runs)."""
    if plan.recipe.kind != "toml" or plan.constants is not None:
        return None
    from chaplygin.numeric import _plan

    return _plan.run(
        plan.recipe.payload.encode("utf-8"),
        plan.model,
        plan.form,
        plan.t_end,
        plan.samples,
        plan.backend,
        "DOP853",
        None,
        None,
        params,
        initial,
        plan.rtol,
        plan.atol,
        time_limit=plan.time_limit,
        warn=False,
    )


# ====================================================================== a warm sweep of a system file
#: bumped whenever the summary a sweep keeps of a system file (:func:`_keep_warm`) changes shape
SUMMARY_FORMAT = 1


def _summary_key(raw: bytes, stem: str) -> str:
    from chaplygin.numeric import cache

    return cache.key("sweep-summary", str(SUMMARY_FORMAT), raw, stem)


class _Names:
    """What a sweep reads of a system file's System before its runs (its name and the names of
    its parameters, coordinates and velocities), from the summary a sweep of the same bytes kept:
    no SymPy."""

    def __init__(self, summary: Mapping[str, Any]) -> None:
        from chaplygin.numeric._plan import _Name

        self.name = str(summary["name"])
        self.parameters = tuple(_Name(str(p)) for p in summary["parameters"])
        self.coordinates = tuple(_Name(str(q)) for q in summary["coordinates"])
        self.independent = tuple(_Name(str(q)) for q in summary["independent"])
        self.dependent = tuple(_Name(str(q)) for q in summary["dependent"])

    def parameter(self, key: str) -> Any:
        return next(p for p in self.parameters if p.name == key)


def _read(source: str) -> str:
    """A system file's text, as a sweep reads it (at most one byte past the size limit: the
    parser refuses what is longer)."""
    from chaplygin.io._file import MAX_FILE_SIZE  # (chaplygin.io.files imports SymPy)

    with open(source, "rb") as fh:
        return fh.read(MAX_FILE_SIZE + 1).decode("utf-8")


def _warm(
    spec: Any,
    model: str | None,
    form: str,
    backend: str,
    constants: Any,
    grid: Mapping[Any, Any],
    given: Sequence[Mapping[Any, Any] | None],
) -> tuple[_Names, _Recipe, dict[str, float], dict[str, float], str, str, dict[str, Any]] | None:
    """``(names, recipe, default parameters, default initial state, label, model, summary)`` of a
    system file swept before with the same model, form and backend (its summary and run plan in
    the cache), where every name given is the file's; else None (the file is read and built)."""
    if not isinstance(spec, (str, os.PathLike)) or (isinstance(spec, str) and spec.startswith("example:")):
        return None
    if constants is not None:
        return None
    from chaplygin.numeric import _plan, cache

    source = os.fspath(spec)
    try:
        text = _read(source)
    except (OSError, UnicodeDecodeError):
        return None  # the full path says why
    raw = text.encode("utf-8")
    stem = Path(source).stem
    summary = cache.load(_summary_key(raw, stem))
    try:
        names = _Names(summary)  # type: ignore[arg-type]
        chosen = model if model is not None else str(summary["true_motion"])  # type: ignore[index]
        defaults = summary["defaults"]  # type: ignore[index]
        base_params = {str(k): float(v) for k, v in defaults["parameters"].items()}
        base_initial = {str(k): float(v) for k, v in defaults["initial"].items()}
    except (KeyError, TypeError, ValueError, AttributeError):
        return None
    if chosen not in _plan.REDUCED or _plan.plan(raw, chosen, form, backend) is None:
        return None
    known = {p.name for p in names.parameters} | {q.name for q in names.coordinates}
    known |= {q.name + "'" for q in names.independent}
    keys = [*grid, *(k for values in given for k in (values or {}))]
    if not all(isinstance(k, str) and k.strip() == k and k in known for k in keys):
        return None  # a symbol, or a name the full path explains
    digest = hashlib.sha256(f"{source}\0{text}".encode()).hexdigest()
    recipe = _Recipe("toml", text, source, stem, digest)
    return names, recipe, base_params, base_initial, source, chosen, summary  # type: ignore[return-value]


def _keep_warm(recipe: _Recipe, system: System, model: str, form: str, backend: str, loaded: Any) -> None:
    """After a sweep of a system file: the run plan of ``model`` (from a successful run of the
    sweep) and a summary of the file's names, so that the next sweep of the same bytes runs
    without SymPy (:func:`_warm`)."""
    tr = _MADE.pop(recipe.digest, None)
    if recipe.kind != "toml" or loaded is None:
        return
    from chaplygin.numeric import _plan, cache

    raw = recipe.payload.encode("utf-8")
    if tr is not None and _plan.plan(raw, model, form, backend) is None:
        _plan.remember(raw, model, form, loaded, tr)
    key = _summary_key(raw, str(recipe.default_name))
    if _plan.plan(raw, model, form, backend) is None or cache.load(key) is not None:
        return  # (a sweep whose runs a plan answered: the plan is there)
    summary = {
        "name": system.name,
        "fingerprint": _fingerprint(system),
        "true_motion": registry.true_motion(system),
        "parameters": [p.name for p in system.parameters],
        "coordinates": [q.func.__name__ for q in system.coordinates],
        "independent": [q.func.__name__ for q in system.independent],
        "dependent": [q.func.__name__ for q in system.dependent],
        "defaults": {"parameters": dict(loaded.parameters), "initial": dict(loaded.initial)},
    }
    try:
        cache.store(key, json.loads(json.dumps(summary)))
    except (TypeError, ValueError):
        pass


def _worker_version() -> str:
    from chaplygin._version import __version__

    return __version__


# ====================================================================== the dataset on disk
def _schema(plan: _Plan, meta: dict[str, Any]) -> pa.Schema:
    import pyarrow as pa

    fields = []
    for name in plan.columns():
        if name == "run_id" or name == "rhs_evaluations":
            fields.append(pa.field(name, pa.int64()))
        elif name in ("status", "message"):
            fields.append(pa.field(name, pa.string()))
        else:
            fields.append(pa.field(name, pa.float64()))
    return pa.schema(fields, metadata={b"chaplygin.apps.sweep": json.dumps(meta).encode("utf-8")})


def _fsync_dir(directory: Path) -> None:
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:  # pragma: no cover - e.g. Windows
        return
    try:
        os.fsync(fd)
    except OSError:  # pragma: no cover
        pass
    finally:
        os.close(fd)


def _atomic_bytes(path: Path, write: Callable[[Any], Any]) -> None:
    """Write through a hidden temporary file in the same folder, fsync it, then rename it over ``path``."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    _fsync_dir(path.parent)


def _parts(directory: Path) -> list[tuple[int, Path]]:
    found = []
    for p in directory.iterdir():
        m = PART_PATTERN.match(p.name)
        if m and p.is_file():
            found.append((int(m.group(1)), p))
    return sorted(found)


def _column(values: list[Any], kind: pa.DataType) -> pa.Array:
    """``values`` (numbers, or strings for a string column) as an Arrow array of type ``kind``,
    built from its buffers: ``pyarrow.array`` imports pandas (0.2 s) to ask whether they are
    pandas objects."""
    import pyarrow as pa

    if kind == pa.string():
        data = [str(v).encode("utf-8") for v in values]
        offsets = np.zeros(len(data) + 1, dtype=np.int64)
        np.cumsum([len(d) for d in data], out=offsets[1:])
        if offsets[-1] >= 2**31:  # (beyond a string column's 32-bit offsets: pyarrow.compute casts)
            buffers = [None, pa.py_buffer(offsets), pa.py_buffer(b"".join(data))]
            return pa.Array.from_buffers(pa.large_string(), len(data), buffers).cast(pa.string())
        buffers = [None, pa.py_buffer(offsets.astype(np.int32)), pa.py_buffer(b"".join(data))]
        return pa.Array.from_buffers(pa.string(), len(data), buffers)
    array = np.ascontiguousarray(values, dtype=np.int64 if kind == pa.int64() else np.float64)
    return pa.Array.from_buffers(kind, len(array), [None, pa.py_buffer(array)])


def _read_part(path: Path, columns: list[str] | None = None) -> pa.Table:
    pq = _require("pyarrow.parquet")
    try:
        return pq.read_table(path, columns=columns)
    except Exception as exc:
        raise ChaplyginError(
            f"{path}: cannot read this part of the sweep ({type(exc).__name__}: {exc}); move it "
            "away and resume: its runs will run again."
        ) from None


def _unique_sorted(table: pa.Table) -> pa.Table:
    ids = table.column("run_id").to_numpy()
    if len(ids) < 2 or np.all(np.diff(ids) > 0):
        return table
    order = np.argsort(ids, kind="stable")
    _, first = np.unique(ids[order], return_index=True)  # duplicates: rows of one run, equal
    return table.take(order[first])


def _meta(directory: Path) -> dict[str, Any]:
    """The sweep's description, ``directory / META_FILE``."""
    return json.loads((directory / META_FILE).read_text(encoding="utf-8"))


def read_results(path: str | os.PathLike[str], columns: Sequence[str] | None = None) -> pa.Table:
    """The rows of a sweep (finished or not) as a ``pyarrow.Table``, sorted by ``run_id``.

    Parameters
    ----------
    path : path
        The sweep's output (a directory of Parquet part files).
    columns : sequence of str, optional
        Only these columns (``run_id`` is always read).

    Returns
    -------
    pyarrow.Table
        One row per finished run; ``table.to_pandas()`` with pandas installed,
        ``table.column("energy_drift").to_numpy()`` without.
    """
    import pyarrow as pa

    _require("pyarrow.parquet")
    directory = Path(path)
    if not directory.is_dir() or not (directory / META_FILE).exists():
        raise ChaplyginError(f"{directory}: not a chaplygin sweep (no {META_FILE} in a directory there).")
    wanted = None if columns is None else ["run_id", *[c for c in columns if c != "run_id"]]
    tables = [_read_part(p, wanted) for _, p in _parts(directory)]
    if not tables:
        meta = _meta(directory)
        schema = pa.schema(
            [
                pa.field(
                    c,
                    pa.int64()
                    if c in ("run_id", "rhs_evaluations")
                    else pa.string()
                    if c in ("status", "message")
                    else pa.float64(),
                )
                for c in meta["columns"]
                if wanted is None or c in wanted
            ]
        )
        return schema.empty_table()
    return _unique_sorted(pa.concat_tables(tables))


class _Writer:
    """Buffers finished rows and writes them as new part files, atomically.

    Rows are written when ``flush_seconds`` have passed since the last write: at the next
    :meth:`add`, or by a background thread when no run finishes for a while (so that a row
    never waits in memory for the next run).  :meth:`close` writes what is left.
    """

    def __init__(self, directory: Path, schema: pa.Schema, flush_seconds: float, next_part: int) -> None:
        self.directory = directory
        self.schema = schema
        self.flush_seconds = max(0.0, float(flush_seconds))
        self.next_part = next_part
        self.rows: list[dict[str, Any]] = []
        self.last = time.monotonic()
        self.written = 0
        self.failed = 0
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._tick, name="chaplygin-sweep-writer", daemon=True)
        self._thread.start()

    def _tick(self) -> None:
        while not self._stop.wait(max(0.05, self.flush_seconds)):
            try:
                with self._lock:
                    if self.rows and time.monotonic() - self.last >= self.flush_seconds:
                        self._flush()
            except BaseException as exc:
                self._error = exc
                return

    def _raise(self) -> None:
        if self._error is not None:
            error, self._error = self._error, None
            raise error

    def add(self, rows: list[dict[str, Any]]) -> None:
        self._raise()
        with self._lock:
            self.rows.extend(rows)
            self.failed += sum(1 for r in rows if r["status"] != "success")
            if len(self.rows) >= 10_000 or time.monotonic() - self.last >= self.flush_seconds:
                self._flush()

    def close(self) -> None:
        """Stop the background thread and write every row still in memory."""
        self._stop.set()
        self._thread.join()
        with self._lock:
            self._flush()
        self._raise()

    def _flush(self) -> None:
        self.last = time.monotonic()
        if not self.rows:
            return
        import pyarrow as pa

        pq = _require("pyarrow.parquet")
        rows = sorted(self.rows, key=lambda r: r["run_id"])
        columns = [_column([r[f.name] for r in rows], f.type) for f in self.schema]
        table = pa.Table.from_arrays(columns, schema=self.schema)
        path = self.directory / f"part-{self.next_part:06d}.parquet"
        _atomic_bytes(path, lambda fh: pq.write_table(table, fh))
        self.next_part += 1
        self.written += len(rows)
        self.rows = []

    def compact(self) -> None:
        """Merge every part into one, sorted by run id (the old parts are removed after the rename)."""
        pq = _require("pyarrow.parquet")
        parts = _parts(self.directory)
        if len(parts) <= 1:
            return
        table = read_results(self.directory).replace_schema_metadata(self.schema.metadata)
        path = self.directory / f"part-{self.next_part:06d}.parquet"
        _atomic_bytes(path, lambda fh: pq.write_table(table, fh))
        self.next_part += 1
        for _, old in parts:
            old.unlink()
        _fsync_dir(self.directory)


@contextmanager
def _locked(directory: Path) -> Iterator[None]:
    """An exclusive lock on the sweep's directory, so that two sweeps never write to one output."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows: no lock
        yield
        return
    fh = open(directory / LOCK_FILE, "a+b")
    try:
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise ChaplyginError(
                f"{directory}: another sweep is writing there now; wait for it to end."
            ) from None
        yield
    finally:
        fh.close()


def _prepare_output(directory: Path, meta: dict[str, Any], resume: bool, force: bool) -> str:
    """Check the output: ``"new"``, ``"resume"`` (an earlier sweep, same settings) or ``"replace"``."""
    from chaplygin.numeric.simulate import check_writable

    check_writable(directory, folder=True)  # (it, or the folder above that will hold it)
    if directory.exists() and not directory.is_dir():
        if not force:
            raise SweepOutputExists(f"{directory} already exists (a file); pass force=True to replace it.")
        directory.unlink()
    elif directory.is_dir() and any(p.name != LOCK_FILE for p in directory.iterdir()):
        if not (directory / META_FILE).is_file():
            raise SweepOutputExists(
                f"{directory} is a directory that is not a chaplygin sweep (no {META_FILE}); "
                "give another --out."
            )
        if resume:
            try:
                old = _meta(directory)
            except (OSError, ValueError) as exc:
                raise ChaplyginError(f"{directory / META_FILE}: cannot read it ({exc}).") from None
            differences = _differences(old, meta)
            if differences:
                raise SweepOutputExists(
                    f"{directory} holds a different sweep ({'; '.join(differences)}); resume it with "
                    "the same settings, or give another out= path (or force=True to replace it)."
                )
            return "resume"
        if not force:
            raise SweepOutputExists(
                f"{directory} already holds a chaplygin sweep; pass resume=True to finish it or "
                "force=True to replace it."
            )
        return "replace"
    directory.mkdir(parents=True, exist_ok=True)
    return "new"


def _clear(directory: Path) -> None:
    """Remove a sweep's files (``force``), under its lock; anything else there stays."""
    for p in directory.iterdir():
        if (
            p.name == META_FILE
            or PART_PATTERN.match(p.name)
            or (p.name.startswith(".") and p.name.endswith(".tmp"))
        ):
            p.unlink()


_FINGERPRINT_KEYS = (
    "system",
    "fingerprint",
    "model",
    "form",
    "backend",
    "t_end",
    "samples",
    "rtol",
    "atol",
    "constants",
    "grid",
    "parameters",
    "initial",
    "columns",
)


def _differences(old: dict[str, Any], new: dict[str, Any]) -> list[str]:
    if old.get("schema") != SCHEMA:
        return [f"schema {old.get('schema')!r}, not {SCHEMA!r}"]
    out = []
    for key in _FINGERPRINT_KEYS:
        if old.get(key) != new.get(key):
            if key in ("grid", "parameters", "initial", "columns", "fingerprint", "constants"):
                out.append(f"its {key} differ" if key != "fingerprint" else "the system differs")
            else:
                out.append(f"{key} {old.get(key)!r} there, {new.get(key)!r} now")
    return out


# ====================================================================== the sweep
@dataclass
class SweepResult:
    """What :func:`sweep` did.

    Attributes
    ----------
    path : Path
        The results (a Parquet dataset directory).
    runs : int
        Runs in the grid.
    ran : int
        Runs done by this call.
    resumed : int
        Runs already in the output before this call (``resume=True``).
    failed : int
        Rows with status ``"failed"`` in the whole output.
    seconds : float
        Wall time of this call.
    where : str
        Where the runs of this call ran: ``"in this process"``, ``"on a LocalCluster of 2
        worker processes"``, ``"on the Dask cluster at tcp://…"``, or ``"3 in this process,
        then 97 on a LocalCluster …"``; ``""`` when nothing ran.
    model : str
        The model simulated (the true motion when none was asked for).
    backend : str
        The backend the runs used (``"c"`` or ``"numpy"`` for ``"auto"``).
    """

    path: Path
    runs: int
    ran: int
    resumed: int
    failed: int
    seconds: float
    where: str = ""
    model: str = ""
    backend: str = ""

    def table(self, columns: Sequence[str] | None = None) -> pa.Table:
        """The rows (see :func:`read_results`)."""
        return read_results(self.path, columns)

    def summary(self) -> str:
        """One line: runs done now and before, failures, the time and where the runs ran, the output."""
        before = f", {self.resumed} already there" if self.resumed else ""
        where = f" {self.where}" if self.where else ""
        return (
            f"{self.runs} runs: {self.ran} run now{before}; {self.failed} failed; "
            f"{self.seconds:.3g} s{where} -> {self.path}"
        )

    def __repr__(self) -> str:
        return f"<SweepResult {self.summary()}>"

    def to_pandas(self) -> Any:
        """The rows (:meth:`table`) as a ``pandas.DataFrame`` indexed by ``run`` (the run id).

        ``attrs``: the sweep's ``system``, ``model``, ``form``, ``backend``, ``t_end``, … and its
        fixed parameters and initial values as ``param.NAME``, ``initial.NAME``.  Needs pandas
        (``pip install 'chaplygin[data]'``).
        """
        from chaplygin.numeric._dataout import sweep_frame

        return sweep_frame(self, _meta(self.path))

    def to_xarray(self) -> Any:
        """The rows as an ``xarray.Dataset`` on the grid: one dimension per axis.

        Each axis (``m``, ``theta'``) is a dimension whose coordinate is its values; every
        other column is a variable over them, and ``run`` the run id (-1 where a run is not in
        the output yet, whose values are NaN, or ``""`` for ``status``, ``message``).  The
        attributes are those of :meth:`to_pandas`.  Needs xarray
        (``pip install 'chaplygin[data]'``).
        """
        from chaplygin.numeric._dataout import sweep_dataset

        return sweep_dataset(self, _meta(self.path))


def _axes(system: System, grid: Mapping[str, Any]) -> tuple[Axis, ...]:
    params = [p.name for p in system.parameters]
    coords = [q.func.__name__ for q in system.coordinates]
    independent = [q.func.__name__ + "'" for q in system.independent]
    dependent = [q.func.__name__ + "'" for q in system.dependent]
    accepted = (
        f"parameters {', '.join(params) or 'none'}; coordinates {', '.join(coords)}; "
        f"independent velocities {', '.join(independent) or 'none'}"
    )
    axes: list[Axis] = []
    if not grid:
        raise ChaplyginError(f"grid: nothing to sweep; give at least one --grid {GRID_SYNTAX}.")
    for raw, spec in grid.items():
        name = str(raw).strip()
        if name in params:
            kind = "parameter"
        elif name in coords or name in independent:
            kind = "initial"
        elif name in dependent:
            raise ChaplyginError(
                f"--grid {name}: the velocity of a dependent coordinate follows from the constraints; "
                f"sweep one of: {accepted}."
            )
        else:
            raise ChaplyginError(f"--grid {name}: not a name of {system.name}; sweep one of: {accepted}.")
        if any(a.name == name for a in axes):
            raise ChaplyginError(f"--grid {name}: given twice; each name is one axis of the grid.")
        axes.append(Axis(name, kind, tuple(float(v) for v in grid_values(spec, name))))
    return tuple(axes)


def _names(system: System, values: Mapping[Any, Any] | None, what: str) -> dict[str, float]:
    from chaplygin.numeric.simulate import _lookup

    out: dict[str, float] = {}
    coords = [q.func.__name__ for q in system.coordinates]
    for key, value in (values or {}).items():
        if isinstance(system, _Names):  # (a warm sweep: every name checked, see _warm)
            name = str(key).strip()
        elif what == "parameters":
            name = system.parameter(key).name
        else:
            kind, i = _lookup(system, key)
            name = coords[i] + ("'" if kind == "v" else "")
        number = float(value)
        if not math.isfinite(number):
            raise ChaplyginError(f"{what}: {name} = {number} is not a finite number.")
        out[name] = number
    return out


def _client(scheduler: Any, workers: int | None) -> tuple[Any, list[Any]]:
    """A distributed Client, and what this call started (closed at the end)."""
    distributed = _require("distributed")
    if isinstance(scheduler, distributed.Client):
        return scheduler, []
    if scheduler is None or (isinstance(scheduler, str) and scheduler.strip() == "local"):
        import logging

        n = workers or os.cpu_count() or 1
        # no fixed dashboard port (another cluster may hold 8787); the workers' restarts after a
        # crash are expected, not errors to print
        cluster = distributed.LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0",
            silence_logs=logging.CRITICAL,
        )
        try:
            client = distributed.Client(cluster)
        except BaseException:
            cluster.close()
            raise
        return client, [client, cluster]
    if hasattr(scheduler, "scheduler_address"):
        client = distributed.Client(scheduler)
        return client, [client]
    if isinstance(scheduler, str):
        try:
            client = distributed.Client(scheduler)  # timeout: dask's distributed.comm.timeouts.connect
        except (OSError, TimeoutError, ValueError) as exc:
            raise ChaplyginError(
                f"scheduler={scheduler!r}: cannot reach a Dask scheduler there ({exc}); give the "
                "address the scheduler prints (tcp://HOST:8786), 'local' for a LocalCluster, 'serial' for "
                "this process, or none."
            ) from None
        return client, [client]
    raise ChaplyginError(
        f"scheduler: expected None, 'serial', 'local', a scheduler address or a distributed.Client, "
        f"not {type(scheduler).__name__}."
    )


def _check_workers(client: Any) -> None:
    from chaplygin._version import __version__

    try:
        versions = client.run(_worker_version)
    except Exception as exc:
        raise ChaplyginError(
            f"the Dask workers cannot run chaplygin ({type(exc).__name__}: {exc}); install "
            f"chaplygin {__version__} in the workers' environment."
        ) from None
    wrong = {addr: v for addr, v in versions.items() if v != __version__}
    if wrong:
        listed = ", ".join(f"{a}: {v}" for a, v in sorted(wrong.items())[:5])
        raise ChaplyginError(f"the Dask workers run another chaplygin ({listed}); this is {__version__}.")


def sweep(
    system: System | SystemFile | str | os.PathLike[str],
    grid: Mapping[str, str | Sequence[float] | np.ndarray],
    *,
    t_end: float,
    out: str | os.PathLike[str],
    model: str | None = None,
    form: str = "classic",
    parameters: Mapping[Any, float] | None = None,
    initial: Mapping[Any, float] | None = None,
    scheduler: Any = None,
    workers: int | None = None,
    resume: bool = False,
    force: bool = False,
    backend: str = "auto",
    samples: int = 201,
    rtol: float = 1e-10,
    atol: float = 1e-12,
    constants: Any = None,
    chunk_size: int | None = None,
    flush_seconds: float = 2.0,
    retries: int = 2,
    compact: bool = True,
    progress: Callable[[int, int], None] | None = None,
    time_limit: float | None = TIME_LIMIT,
    notice: Callable[[str], None] | None = None,
) -> SweepResult:
    """Simulate ``model`` at every point of ``grid``; one row per run in a Parquet dataset.

    Parameters
    ----------
    system : System, SystemFile, path or "example:NAME"
        What to simulate.  A file or a :class:`~chaplygin.io.files.SystemFile`
        brings default parameters and an initial state.
    grid : mapping of name → values
        Each key a parameter (``"m"``), a coordinate (``"theta"``) or an
        independent velocity (``"theta'"``); each value ``"START:STOP:COUNT"``
        (``numpy.linspace``), ``"V1,V2,…"`` or a sequence of numbers.  The runs
        are the Cartesian product, numbered in C order (the last axis varies
        fastest): the run id is the point's index, the same in every sweep
        with the same grid.
    t_end : float
        Every run goes from ``t = 0`` to ``t_end``.
    out : path
        The output directory (``results.parquet``).
    model : str, optional
        The model to simulate; default: the true motion, as the command line's ``simulate``
        (:func:`chaplygin.models.registry.true_motion`: Chaplygin's equations for a Chaplygin
        system, else Voronets').
    form, constants :
        As for :func:`chaplygin.numeric.simulate`.
    parameters, initial : mapping, optional
        Fixed values over the file's (or example's) defaults; a ``System``
        given directly needs every parameter and initial value here or in the grid.
    scheduler : None, "serial", "local", address, or distributed.Client
        ``None``: in this process, handing the rest to a ``LocalCluster`` only
        when the runs measured so far say that it would take longer than
        :data:`AUTO_CLUSTER_SECONDS` (and the machine has more than one core).
        ``"serial"``: in this process, without Dask.  ``"local"``: a
        ``LocalCluster`` of ``workers`` processes (one per core by default),
        closed at the end.  An address (``"tcp://host:8786"``): that running
        cluster (its workers need chaplygin installed).
        :attr:`SweepResult.where` says which ran the runs.
    workers : int, optional
        Worker processes of the LocalCluster; with ``scheduler=None``, giving
        it asks for a LocalCluster from the start.
    resume : bool
        Continue the sweep in ``out``: run only the run ids that are not there
        (the settings must be the same).  Without it an existing ``out`` is
        refused, unless ``force``.
    force : bool
        Replace an existing sweep (or file) at ``out``.
    backend : {"auto", "c", "numba", "numpy"}
        Generated code of each run, as for :func:`chaplygin.numeric.simulate`: ``"auto"`` (the
        default) is ``"c"`` (the model and the DOP853 loop in C, built in a second or two and
        cached on disk) where a C compiler is found, else ``"numpy"`` (no compile step);
        ``"numba"`` compiles for about 20 s the first time.  The sweep records the one chosen.
    samples : int
        Samples per run, over which the energy drift and the constraint
        residual are measured.
    rtol, atol : float
        Integrator tolerances.
    chunk_size : int, optional
        Runs per Dask task (default: about four tasks per worker thread, at
        most 64 runs each).
    flush_seconds : float
        Finished runs are written at least this often (and when the sweep
        stops); after a hard kill of this process at most that much work runs again.
    retries : int
        Retries of a task that raises (Dask's ``retries``); a task lost with
        a dead worker is rescheduled by Dask itself.
    compact : bool
        Merge the part files into one when the sweep is complete.
    progress : callable(done, total), optional
        Called as runs finish (``done`` counts the resumed ones too).
    time_limit : float or None
        Seconds (default one hour; None: no limit).  Each run is limited as by
        :func:`chaplygin.numeric.simulate.simulate` (a run estimated to take longer is a failed
        row), and a sweep in this process whose first runs say that the rest would take longer
        (over the cores a LocalCluster would use) stops with a :class:`ChaplyginError` that gives
        the estimate; the runs done are kept (``resume=True`` goes on).
    notice : callable(str), optional
        Told, before the runs start, about a long first step: ``"compiling the C kernel for
        NAME (first run, about 2 s; cached afterwards)"`` where the compiled model is not in
        the disk cache yet (the command line prints it on stderr).

    Returns
    -------
    SweepResult

    Raises
    ------
    ChaplyginError
        For a bad grid or setting, an output that exists (:class:`SweepOutputExists`),
        a missing optional dependency, or workers that cannot run chaplygin.
    """
    started = time.perf_counter()
    wrong = _out_problem(out)
    if wrong is not None:
        raise ChaplyginError(f"out={os.fspath(out)!r}: {wrong}")
    _require("pyarrow.parquet")
    runner = _runner(scheduler, workers)
    if runner == "cluster":
        _require("distributed")
    if backend not in SWEEP_BACKENDS:
        raise ChaplyginError(
            f"backend {backend!r}: sweeps run on {', '.join(map(repr, SWEEP_BACKENDS))} "
            "(on a GPU use chaplygin.numeric.ensemble.simulate_ensemble, backend='cuda' or 'jax')."
        )
    t_end = float(t_end)
    if not (math.isfinite(t_end) and t_end > 0):
        raise ChaplyginError(f"t_end = {t_end:g}: the end time must be a positive number.")
    if samples < 2:
        raise ChaplyginError(f"samples = {samples}: at least 2 (the start and the end).")
    if chunk_size is not None and chunk_size < 1:
        raise ChaplyginError(f"chunk_size = {chunk_size}: at least 1 run per task.")
    if workers is not None and workers < 1:
        raise ChaplyginError(f"workers = {workers}: at least 1.")
    if resume and force:
        raise ChaplyginError(
            "resume and force exclude each other: resume keeps the runs there, force deletes them."
        )

    from chaplygin.numeric.simulate import choose_backend

    backend = choose_backend(backend)
    # a system file swept before with this model: its names and run plan answer without SymPy
    warm = _warm(system, model, form, backend, constants, grid, (parameters, initial))
    loaded: SystemFile | None = None
    summary: dict[str, Any] = {}
    if warm is not None:
        names, recipe, base_params, base_initial, label, model, summary = warm
        sys_: Any = names
    else:
        sys_, recipe, base_params, base_initial, label, loaded = _resolve(system, runner != "cluster")
    if model is None:
        model = registry.true_motion(sys_)  # as simulate on the command line
    params = {**_names(sys_, base_params, "parameters"), **_names(sys_, parameters, "parameters")}
    start = {**_names(sys_, base_initial, "initial"), **_names(sys_, initial, "initial")}
    axes = _axes(sys_, grid)
    fixed_by_user = set(_names(sys_, parameters, "parameters")) | set(_names(sys_, initial, "initial"))
    clash = [a.name for a in axes if a.name in fixed_by_user]
    if clash:
        raise ChaplyginError(
            f"--grid {clash[0]}: also given a fixed value (--param/--initial); give one or the other."
        )
    for a in axes:
        (params if a.kind == "parameter" else start).pop(a.name, None)
    parameter_names = tuple(p.name for p in sys_.parameters)
    coords = tuple(q.func.__name__ for q in sys_.coordinates)
    initial_names = coords + tuple(q.func.__name__ + "'" for q in sys_.independent)
    swept = {a.name for a in axes}
    missing = [p for p in parameter_names if p not in params and p not in swept]
    missing += [q for q in initial_names if q not in start and q not in swept]
    if missing:
        raise ChaplyginError(
            f"no value for {', '.join(missing)}: give each a value (parameters=, initial=) "
            "or sweep it (grid=)."
        )
    unknown = [q for q in start if q not in initial_names]
    if unknown:
        raise ChaplyginError(
            f"initial: {', '.join(unknown)} follow from the constraints; give coordinates and the "
            f"independent velocities ({', '.join(initial_names)})."
        )
    # a model that does not apply fails here, before any run; one compiled before (in the disk
    # cache) applies, and its runs load it without deriving (the family is derived with its
    # constants, in the runs); a warm sweep's run plan was made by a run of the model
    if warm is None and not registry.get(model).constants:
        from chaplygin.numeric.codegen import is_compiled

        if not is_compiled(sys_, model, form, backend):
            sys_.equations(model, form)

    plan = _Plan(
        recipe,
        model,
        form,
        backend,
        t_end,
        int(samples),
        float(rtol),
        float(atol),
        constants,
        tuple(sorted(params.items())),
        tuple(sorted(start.items())),
        axes,
        parameter_names,
        initial_names,
        coords,
        time_limit,
    )
    total = plan.runs
    if total > MAX_RUNS:
        raise ChaplyginError(f"grid: {total} runs; at most {MAX_RUNS} in one sweep (split it).")
    from chaplygin._version import __version__

    meta = json.loads(
        json.dumps(
            {
                "schema": SCHEMA,
                "chaplygin": __version__,
                "system": sys_.name,
                "source": label,
                "fingerprint": summary["fingerprint"] if warm is not None else _fingerprint(sys_),
                "model": model,
                "form": form,
                "backend": backend,
                "t_end": t_end,
                "samples": int(samples),
                "rtol": float(rtol),
                "atol": float(atol),
                "constants": constants,
                "runs": total,
                "grid": [{"name": a.name, "kind": a.kind, "values": list(a.values)} for a in axes],
                "parameters": dict(plan.parameters),
                "initial": dict(plan.initial),
                "columns": plan.columns(),
            }
        )
    )
    directory = Path(out)
    mode = _prepare_output(directory, meta, resume, force)
    with _locked(directory):
        if mode == "replace":
            _clear(directory)
        if mode != "resume":
            text = json.dumps(meta, indent=2) + "\n"
            _atomic_bytes(directory / META_FILE, lambda fh: fh.write(text.encode("utf-8")))
        for leftover in directory.glob(".*.tmp"):  # a write cut short: never part of the results
            leftover.unlink()
        parts = _parts(directory)
        done = np.zeros(total, dtype=bool)
        failed_before = 0
        for _, path in parts:
            table = _read_part(path, ["run_id", "status"])
            ids = table.column("run_id").to_numpy()
            failed = np.asarray(table.column("status").to_pylist(), dtype=object) != "success"
            keep = (ids >= 0) & (ids < total)
            ids, failed = ids[keep], failed[keep]
            ids, first = np.unique(ids, return_index=True)
            fresh = ~done[ids]
            failed_before += int(np.count_nonzero(failed[first][fresh]))
            done[ids] = True
        todo = np.flatnonzero(~done)
        resumed = total - len(todo)
        if notice is not None and len(todo) and warm is None:
            words = _first_compile(sys_, plan)
            if words is not None:
                notice(words)
        report = (lambda n: progress(n, total)) if progress is not None else (lambda n: None)
        writer = _Writer(directory, _schema(plan, meta), flush_seconds, (parts[-1][0] + 1) if parts else 0)
        where = ""
        try:
            report(resumed)
            if runner == "cluster" and len(todo):
                where = _distributed(
                    plan, todo, writer, resumed, report, scheduler, workers, chunk_size, retries
                )
            elif len(todo):
                if warm is None:
                    _remember(recipe, sys_)
                here = _serial(
                    plan,
                    todo,
                    writer,
                    resumed,
                    report,
                    watch=runner == "auto" and _can_cluster(),
                    limit=time_limit,
                )
                where = "in this process"
                if here < len(todo):  # the rest would take long: a LocalCluster
                    travelling = _travelling(plan, sys_)
                    rest = todo[here:]
                    if travelling is None:
                        _serial(plan, rest, writer, resumed + here, report, watch=False)
                    else:
                        there = _distributed(
                            travelling,
                            rest,
                            writer,
                            resumed + here,
                            report,
                            None,
                            workers,
                            chunk_size,
                            retries,
                        )
                        where = f"{here} in this process, then {len(rest)} {there}"
        finally:
            writer.close()
        if compact:
            writer.compact()
    if warm is None:
        with suppress(ChaplyginError, OSError):
            _keep_warm(recipe, sys_, model, form, backend, loaded)
    return SweepResult(
        directory,
        total,
        writer.written,
        resumed,
        failed_before + writer.failed,
        time.perf_counter() - started,
        where,
        model,
        backend,
    )


def _first_compile(system: System, plan: _Plan) -> str | None:
    """Words for a first compile of the sweep's model (:data:`FIRST_COMPILE`), or None: cached,
    nothing to compile, or constants of each run's own (``"match"``)."""
    if plan.backend not in FIRST_COMPILE:
        return None
    from chaplygin.numeric.codegen import is_compiled
    from chaplygin.numeric.simulate import _vakonomic_setup

    try:
        constants, _ = _vakonomic_setup(system, registry.get(plan.model), plan.constants, None)
    except ChaplyginError:  # each run says what is wrong
        return None
    if isinstance(constants, str) or is_compiled(
        system, plan.model, plan.form, plan.backend, constants=constants
    ):
        return None
    what, seconds = FIRST_COMPILE[plan.backend]
    return f"compiling {what} for {system.name} (first run, about {seconds} s; cached afterwards)"


#: the names a sweep's output may have: a Parquet dataset is a folder, ``results.parquet`` or ``results``
OUT_SUFFIXES = (".parquet", "")


def _out_problem(out: str | os.PathLike[str]) -> str | None:
    """Why ``out`` cannot hold a sweep, by its name (``x.csv`` says another format), or None.

    A sweep writes a Parquet dataset, a folder: its name ends in ``.parquet`` or has no suffix
    (:data:`OUT_SUFFIXES`); an existing folder of any name is taken as it is.
    """
    path = Path(out)
    if path.suffix.lower() in OUT_SUFFIXES or path.is_dir():
        return None
    return (
        f"a sweep writes a Parquet dataset (a folder of part files that survives a crash and can "
        f"be resumed), not a {path.suffix} file; name it {path.stem}.parquet, or {path.stem} "
        f"without a suffix; pandas.read_parquet('{path.stem}.parquet').to_csv('{path.name}') "
        "then gives CSV."
    )


def _runner(scheduler: Any, workers: int | None) -> str:
    """``"auto"`` (no scheduler, no workers), ``"serial"``, or ``"cluster"`` (asked for)."""
    if scheduler is None:
        return "auto" if workers is None else "cluster"
    if isinstance(scheduler, str) and scheduler.strip() == "serial":
        return "serial"
    return "cluster"


def _cores() -> int:
    """CPU cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not on Linux
        return os.cpu_count() or 1


def _can_cluster() -> bool:
    """Whether a LocalCluster could help: more than one core, and dask.distributed installed."""
    return _cores() > 1 and importlib.util.find_spec("distributed") is not None


def _travelling(plan: _Plan, system: System) -> _Plan | None:
    """``plan`` with a recipe that worker processes can build (None if the system cannot travel)."""
    if plan.recipe.kind != "local":
        return plan
    try:
        return dataclasses.replace(plan, recipe=_object_recipe(system, plan.recipe.source, False))
    except ChaplyginError:
        return None


def _serial(
    plan: _Plan,
    todo: np.ndarray,
    writer: _Writer,
    resumed: int,
    report: Callable[[int], None],
    *,
    watch: bool,
    limit: float | None = None,
) -> int:
    """Run ``todo`` in this process; the number run.

    With ``watch``, stop early once the runs so far (the first, which builds and compiles the
    model, left out) say that the rest would take longer than :data:`AUTO_CLUSTER_SECONDS`.
    With ``limit``, the first run measured estimates the rest, spread over the cores where
    ``watch`` may hand it to a LocalCluster; more than ``limit`` seconds stops the sweep with a
    :class:`ChaplyginError` that says so.
    """
    took: list[float] = []
    for count, run_id in enumerate(todo, 1):
        start = time.perf_counter()
        writer.add(_run_chunk(plan, [int(run_id)]))
        took.append(time.perf_counter() - start)
        report(resumed + count)
        left = len(todo) - count
        if limit is not None and left and len(took) > 1:
            rest = sum(took[1:]) / (len(took) - 1) * left / (_cores() if watch else 1)
            if rest > limit:
                from chaplygin.numeric.simulate import duration

                raise ChaplyginError(
                    f"{plan.runs} runs: the {left} left would take about {duration(rest)} (at "
                    f"{sum(took[1:]) / (len(took) - 1):.3g} s a run{f' on {_cores()} cores' if watch else ''}), "
                    f"beyond the limit of {duration(limit)}; the {count} runs done are kept: pass "
                    "time_limit=None with resume=True to finish, or sweep fewer points."
                )
            limit = None  # estimated once
        if watch and left and len(took) > 1 and sum(took[1:]) / (len(took) - 1) * left > AUTO_CLUSTER_SECONDS:
            return count
    return len(todo)


def _chunks(todo: np.ndarray, size: int) -> Iterator[list[int]]:
    for i in range(0, len(todo), size):
        yield [int(r) for r in todo[i : i + size]]


def _distributed(
    plan: _Plan,
    todo: np.ndarray,
    writer: _Writer,
    resumed: int,
    report: Callable[[int], None],
    scheduler: Any,
    workers: int | None,
    chunk_size: int | None,
    retries: int,
) -> str:
    """Run the chunks of ``todo`` on Dask, a window of tasks at a time, writing rows as they come;
    where they ran (``"on a LocalCluster of 2 worker processes"``).

    A task lost with a dead worker is rescheduled by Dask.  A chunk whose task kept killing its
    workers (``KilledWorker``) is split: its runs become *suspects*, run one task at a time, so
    that only the run that kills its worker is recorded as failed for that reason.
    """
    distributed = _require("distributed")
    client, owned = _client(scheduler, workers)
    pending: dict[Any, tuple[list[int], bool]] = {}  # future -> (run ids, a suspect?)
    suspects: deque[int] = deque()
    try:
        _check_workers(client)
        nthreads = client.nthreads()
        count = f"{len(nthreads)} worker process{'' if len(nthreads) == 1 else 'es'}"
        where = (
            f"on a LocalCluster of {count}"
            if any(isinstance(x, distributed.LocalCluster) for x in owned)
            else f"on the Dask cluster at {client.scheduler.address} ({count})"
        )
        threads = max(1, sum(nthreads.values()))
        size = chunk_size or max(1, min(64, math.ceil(len(todo) / (4 * threads))))
        window = max(8, 4 * threads)
        chunks = _chunks(todo, size)

        def submit(run_ids: list[int], suspect: bool = False) -> Any:
            future = client.submit(_run_chunk, plan, run_ids, pure=False, retries=retries)
            pending[future] = (run_ids, suspect)
            return future

        queue = distributed.as_completed([submit(c) for _, c in zip(range(window), chunks)])
        done = resumed
        for future in queue:
            run_ids, _ = pending.pop(future)
            rows: list[dict[str, Any]] = []
            if future.status not in ("finished", "cancelled", "error"):
                # done, then lost with a killed worker before it was read: Dask computes it again
                distributed.wait(future)
            if future.status == "finished":
                rows = future.result()
            elif future.status == "cancelled":
                raise ChaplyginError(
                    "the Dask scheduler cancelled the sweep's tasks (was it shut down?); the runs "
                    "finished so far are saved: resume when the cluster is back."
                )
            else:
                exc = future.exception()
                if not isinstance(exc, distributed.KilledWorker):
                    raise ChaplyginError(
                        f"a Dask task failed outside the runs ({type(exc).__name__}: {exc}); the runs "
                        "finished so far are saved: fix the cluster and resume."
                    ) from exc
                if len(run_ids) > 1:
                    suspects.extend(run_ids)
                else:
                    rows = [_killer_row(plan, run_ids[0], exc)]
            future.release()
            if rows:
                writer.add(rows)
                done += len(rows)
                report(done)
            if suspects and not any(suspect for _, suspect in pending.values()):
                queue.add(submit([suspects.popleft()], suspect=True))
            while len(pending) < window:
                chunk = next(chunks, None)
                if chunk is None:
                    break
                queue.add(submit(chunk))
        return where
    finally:
        if pending:
            with suppress(Exception):  # the cluster may already be gone
                client.cancel(list(pending))
        for thing in owned:
            with suppress(Exception):  # closing is best effort
                thing.close()


def _killer_row(plan: _Plan, run_id: int, exc: BaseException) -> dict[str, Any]:
    """The row of a run whose task killed every worker process that took it."""
    row, _, _ = _inputs(plan, run_id)
    row.update(_no_outcome(plan))
    row["message"] = (
        f"the worker processes running it died ({type(exc).__name__}: {exc}): a crash, or out of memory"
    )[:MAX_MESSAGE]
    return row
