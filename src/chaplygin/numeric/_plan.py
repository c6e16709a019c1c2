"""Warm runs of a system file without SymPy: run plans.

A run of a system file spends half a second importing SymPy and building the
system before it integrates for a few milliseconds.  So after a run of a file
(``chaplygin simulate FILE`` or ``chaplygin.simulate(chaplygin.load(FILE), …)``,
:func:`simulate_file`) a *run plan* is stored in the derivation cache
(:mod:`chaplygin.numeric.cache`: JSON, keyed by the system file's bytes or the
example's name, the model, form, backend and library version, verified on
read): the model's layout, its generated code (source, not code: the C
``fill`` built into the kernel cache, :mod:`chaplygin.numeric._ckernel`, or the
generated Python module of the ``numpy`` and ``numba`` backends, which the code
cache and numba's own cache keep compiled), and the file's default parameters
and initial state.  The next run of the same system, model and backend loads
the compiled code (or builds it from the stored source) and integrates
without importing SymPy (nor SciPy or numba, with the ``c`` backend).

A plan answers only what it can answer exactly as the full path would: DOP853,
no constants, no holonomic constraints (their coordinates are solved at the start
and their residual monitored: the full path), no constraints nonlinear in the
velocities (their start and watch need SymPy), overrides naming known
parameters, coordinates or velocities.  A multiplier model (``chetaev``,
constraints linear in the velocities) is planned only by a run from the file's
own parameters and coordinates, keeps that start (the dependent velocities
solved from the constraints) and answers it only.  A reduced model
(``chaplygin``, ``voronets``, ``lindelof``, whose state is the coordinates and
the independent velocities, taken as given) is planned by any run that
succeeded, and answers other velocities (a given dependent one checked against
the constraints: the kernel's velocities) and, where the full path's start
checks (the constraints solvable for the dependent velocities, a positive
definite, well-conditioned reduced mass matrix) pass by a wide margin
(:func:`_clearly_admissible`), other coordinates and parameters; its run is
judged along the way by the full path's own watch
(:func:`chaplygin.numeric.simulate._watch`: poles of the solved constraints at
and between the samples, the reduced mass matrix's definiteness, velocities gone
non-finite), run on :class:`Watched`, what the watch reads of the system, kept
in the plan with generated NumPy modules of the pole functions and the mass
matrix.  Anything else, a disagreement included, returns ``None`` and the full
path runs (and reports the error).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from chaplygin.models import registry
from chaplygin.numeric import _modelcache, cache, targets

if TYPE_CHECKING:
    from chaplygin.numeric.simulate import Trajectory

__all__ = ["LoadedFile", "key", "plan", "remember", "run", "simulate_file"]

#: the reduced models without constants, whose state a plan builds from the given numbers alone
REDUCED = tuple(m.name for m in registry.MODELS.values() if m.reduced and not m.constants)
#: the multiplier models whose state is the coordinates and velocities (a plan keeps its start)
MULTIPLIER = tuple(
    m.name
    for m in registry.MODELS.values()
    if not m.reduced and not m.constants and not m.multipliers_in_state
)
#: the backends whose runs a plan answers
PLANNED = ("c", "numpy", "numba")
#: what the command line asks for when no --model is given: the true motion (Chaplygin's
#: equations for a Chaplygin system, else Voronets'), which the plan then names
TRUE_MOTION = "true-motion"
#: bumped whenever the plan's (or the file summary's) shape changes
FORMAT = 8
#: what a plan keeps of the file it was made from (:func:`summary_key`): every field of a
#: :class:`~chaplygin.io.files.SystemFile` but the SymPy ones
SUMMARY = ("parameters", "initial", "name", "defaulted", "body")


class LoadedFile:
    """What :func:`chaplygin.numeric.simulate.simulate` runs from a file's defaults and plans
    (:class:`chaplygin.io.files.SystemFile` derives from it; told apart without importing SymPy).

    A subclass gives ``system``, ``parameters``, ``initial`` and ``defaulted`` (as
    :class:`~chaplygin.io.files.SystemFile` does) and ``definition``: the bytes a plan is keyed
    by (the file's), or None (no plan).
    """

    system: Any
    parameters: dict[str, float]
    initial: dict[str, float]
    defaulted: tuple[str, ...]
    definition: bytes | None = None


def summary_key(definition: bytes, stem: str) -> str:
    """The cache key of the summary of the file of bytes ``definition`` named ``stem`` (the
    name it takes without ``name = …``), stored with a plan made from it: the file was read and
    validated, and :func:`chaplygin.load` of the same bytes returns it without reading them again."""
    return cache.key("system file", str(FORMAT), definition, stem)


def key(definition: bytes, model: str, form: str, backend: str) -> str:
    """The cache key of the plan for ``model``/``form`` of the system ``definition`` on ``backend``."""
    from chaplygin.numeric import targets

    built = (targets.get(backend).toolchain() or "") if backend in targets.TARGETS else ""
    return cache.key("simulate-plan", str(FORMAT), definition, model, form, backend, built)


def applies(backend: str, model: str, method: str, constants: Any, step: Any) -> bool:
    """Whether a plan could answer this run (before looking for one)."""
    from chaplygin.numeric.simulate import choose_backend

    return (
        model in (*REDUCED, *MULTIPLIER, TRUE_MOTION)
        and method == "DOP853"
        and constants is None
        and step is None
        and choose_backend(backend, method) in PLANNED
    )


def remember(definition: bytes | None, asked: str, form: str, loaded: Any, tr: Trajectory) -> None:
    """Store the plan of a finished run (a no-op for anything a plan cannot answer).

    ``asked`` is the model as the command line asked for it (:data:`TRUE_MOTION` for none);
    only a run that succeeded makes a plan, and of a multiplier model only one from the file's
    own parameters and coordinates, so the checks of its start passed there.
    """
    if definition is None or tr.backend not in PLANNED or not tr.success or not len(tr.t):
        return
    if not _modelcache.enabled():  # $CHAPLYGIN_MODEL_CACHE=off: every process derives anew
        return
    system = loaded.system
    reduced = tr.model in REDUCED
    if system.is_nonlinear or (not reduced and tr.model not in MULTIPLIER):
        return  # (nonlinear constraints: the start and the watch need SymPy)
    if getattr(system, "holonomic", None):  # its start is solved and its residual monitored
        return
    defaults = {k: float(v) for k, v in (loaded.initial or {}).items()}
    started = {c: float(tr.coordinates[c][0]) for c in tr.coordinates}
    if not reduced:  # the start kept: every velocity, the dependent ones solved from the constraints
        started |= {v: float(tr.velocities[v][0]) for v in tr.velocities}
    if not reduced and (
        tr.parameters != loaded.parameters
        or any(started[k] != v for k, v in defaults.items() if k in started)
    ):
        return  # a run from other numbers: its checks say nothing of the file's
    from pathlib import Path

    from chaplygin.numeric.codegen import compile_model

    # the run's model (cached on the system)
    compiled = compile_model(system, tr.model, form, tr.backend)
    layout, code = compiled.layout, targets.get(tr.backend).code(compiled)
    if code is None:
        return
    watch = _watch_of(system) if reduced else None
    if reduced and watch is None:
        return  # pole functions not printable as a module: the watch needs SymPy
    value = {
        "watch": watch,
        "layout": {
            f: list(getattr(layout, f))
            for f in ("coordinates", "velocities", "multipliers", "parameters", "reactions")
        }
        | {"model": layout.model, "form": layout.form},
        **code,
        "g": system.g,
        "energy_conserved": tr.energy_conserved,
        "energy_column": tr.energy_column,
        "parameters": {k: float(v) for k, v in (loaded.parameters or {}).items()},
        "initial": defaults,
        "defaulted": list(getattr(loaded, "defaulted", ())),
        "start": None if reduced else [started[c] for c in layout.coordinates + layout.velocities],
        # the parameters and coordinates whose start the full path checked
        "checked": {
            "parameters": {k: float(v) for k, v in tr.parameters.items()},
            "coordinates": {c: started[c] for c in layout.coordinates},
        },
    }
    cache.store(key(definition, asked, form, tr.backend), value)
    if getattr(loaded, "definition", None) == definition:  # a file read by chaplygin.load
        try:
            summary = {k: getattr(loaded, k) for k in SUMMARY}
            cache.store(summary_key(definition, Path(loaded.source).stem), summary)
        except (TypeError, ValueError):  # a [body] value that JSON does not hold: no summary
            pass


def _watch_of(system: Any) -> dict[str, Any] | None:
    """What :class:`Watched` needs of ``system`` (JSON), or None where the pole functions are
    not a module (lambdified: the watch needs SymPy)."""
    from chaplygin.numeric import _modelcache
    from chaplygin.numeric.simulate import POLE_FORMAT, _pole_source, monitor

    if system.g:
        found = _modelcache.load_source(_modelcache.source_key(system, "pole-functions", POLE_FORMAT))
        made = (
            (found["source"], found["factors"], found["watch"]) if found is not None else _pole_source(system)
        )
        if made is None:
            return None
    else:
        made = ("def poles():\n    return []\n", 0, "none")
    watched = monitor(system)
    return {
        "poles": made[0],
        "factors": int(made[1]),
        "watch": str(made[2]),
        "coordinates": [c.func.__name__ for c in system.coordinates],
        "parameters": [par.name for par in system.parameters],
        "dep": list(system._dep),
        "ind": list(system._ind),
        "conserves_energy": bool(watched.conserved),
        "quadratic": watched.column == "energy",
        "mass": _mass_source(system),
    }


#: the largest mass matrix (in expression nodes) a plan keeps as a module: the rattleback's has
#: 3,220 (printed in 0.07 s), the Whipple bicycle's 42,350 (1.3 s)
MASS_NODES = 20_000


def _mass_source(system: Any) -> str | None:
    """A module whose ``mass(t, q…, parameters…)`` is the mass matrix ``∂²T/∂q̇²`` (rows), or None
    where it depends on the velocities or is not printable as NumPy code."""
    import sympy as sp

    from chaplygin.core._symbols import TIME
    from chaplygin.numeric.simulate import numpy_lines

    if sum(1 for e in system._M for _ in sp.preorder_traversal(e)) > MASS_NODES:
        return None  # (printing it would add seconds to the run that makes the plan)
    printed = numpy_lines([TIME, *system._vars.x, *system.parameters], list(system._M))
    if printed is None:
        return None
    names, body = printed
    n = system.n
    rows = ["[" + ", ".join(body[i * n : (i + 1) * n]) + "]" for i in range(n)]
    return (
        '"""Generated by chaplygin (a run plan\'s mass matrix)."""\n\nimport numpy\n\n\n'
        f"def mass({', '.join(names)}):\n"
        "    return [\n" + "".join(f"        {row},\n" for row in rows) + "    ]\n"
    )


class _Name:
    """A coordinate or parameter as the watch reads it: ``.name``, ``.func.__name__``."""

    def __init__(self, name: str) -> None:
        self.name = self.__name__ = name
        self.func = self


class Watched:
    """What the full path's watch of a run (:func:`chaplygin.numeric.simulate._watch`,
    :func:`~chaplygin.numeric.simulate._pole_between_samples`) reads of a
    :class:`~chaplygin.System` without nonlinear or holonomic constraints, from a plan's
    ``watch`` (:func:`_watch_of`): its sizes, coordinates, parameters, which velocities are
    dependent, how its energy column reads, and the pole functions' generated module."""

    is_nonlinear = False
    _holonomic = ()

    def __init__(self, watch: Mapping[str, Any]) -> None:
        self.coordinates = tuple(_Name(str(c)) for c in watch["coordinates"])
        self.parameters = tuple(_Name(str(p)) for p in watch["parameters"])
        self._dep = tuple(int(i) for i in watch["dep"])
        self._ind = tuple(int(i) for i in watch["ind"])
        self.n, self.g = len(self.coordinates), len(self._dep)
        self.conserves_energy = bool(watch["conserves_energy"])
        self._quadratic_T = bool(watch["quadratic"])  # (System._quadratic_T, as the watch reads it)
        poles = cache.import_source(str(watch["poles"]), "poles").poles
        self.__dict__["_pole_functions"] = (poles, int(watch["factors"]), str(watch["watch"]))
        self.mass = cache.import_source(str(watch["mass"]), "mass").mass if watch["mass"] else None


#: how far inside the full path's limits (:func:`chaplygin.numeric.simulate._check_mass`'s condition
#: number, :func:`~chaplygin.numeric.simulate._solvable`'s smallest singular value) a start must lie
#: for a plan to answer it: NumPy's numbers and the full path's differ in the last digits
MARGIN = 100.0


def _clearly_admissible(system: Watched, q: list[float], values: Mapping[str, float]) -> bool:
    """Whether the full path's start checks (:func:`chaplygin.numeric.simulate.initial_state`: the
    constraints solvable for the dependent velocities; ``_check_mass``: a positive definite,
    well-conditioned reduced mass matrix) pass at coordinates ``q`` and parameters ``values`` by
    a wide :data:`MARGIN` (else the full path decides, and says why)."""
    from chaplygin.numeric.simulate import MAX_CONDITION, _solvable

    if system.mass is None:
        return False
    numbers = [values[par.name] for par in system.parameters]
    with np.errstate(all="ignore"):
        m = np.array(system.mass(0.0, *q, *numbers), dtype=float)
        c = np.eye(system.n)[:, list(system._ind)]
        if system.g:
            poles = system.__dict__["_pole_functions"][0]
            values_ = [np.asarray(v, dtype=float) for v in poles(0.0, *q, *numbers)]
            a = np.array(values_[: system.g * system.n], dtype=float).reshape(system.g, system.n)
            factors = np.array(values_[system.g * system.n :], dtype=float)
            if not np.all(np.abs(factors) > 1e-12):
                return False  # (a factor of a denominator of [A | A_0] near 0: a pole near)
            dep, ind = list(system._dep), list(system._ind)
            if not _solvable(a, dep, MARGIN * 1e-10):
                return False
            c[dep] = -np.linalg.solve(a[:, dep], a[:, ind])
        if not (np.all(np.isfinite(m)) and np.all(np.isfinite(c))):
            return False
        reduced = c.T @ m @ c
        w = np.linalg.eigvalsh((reduced + reduced.T) / 2)
    return bool(len(w) and w[0] > MARGIN * np.max(np.abs(w)) / MAX_CONDITION)


def warn_defaulted(defaulted: Any, given: Mapping[str, float]) -> None:
    """Warn about the velocities that neither the file's [initial] nor --initial gave (they are 0)."""
    missing = [k for k in defaulted if k.endswith("'") and k not in given]
    if missing:
        import warnings

        from chaplygin.errors import ChaplyginWarning

        warnings.warn(
            f"initial: {', '.join(missing)} {'is' if len(missing) == 1 else 'are'} given neither in "
            f"[initial] nor by --initial; {'it is' if len(missing) == 1 else 'they are'} 0.",
            ChaplyginWarning,
            stacklevel=3,
        )


def plan(definition: bytes, model: str, form: str, backend: str) -> dict[str, Any] | None:
    """The stored plan, or None (always, where ``$CHAPLYGIN_MODEL_CACHE`` is off)."""
    if not _modelcache.enabled():
        return None
    value = cache.load(key(definition, model, form, backend))
    return value if isinstance(value, dict) else None


def run(
    definition: bytes | None,
    model: str,
    form: str,
    t_end: float,
    samples: int,
    backend: str,
    method: str,
    constants: Any,
    step: Any,
    params: Mapping[str, float],
    initial: Mapping[str, float],
    rtol: float = 1e-10,
    atol: float = 1e-12,
    progress: Callable[[float], None] | None = None,
    time_limit: float | None = None,
    warn: bool = True,
) -> Trajectory | None:
    """The run from a stored plan, or None where the full path must run.

    ``progress`` is told the time the integration reaches, and ``time_limit`` is applied, as by
    :func:`chaplygin.numeric.simulate.simulate`; ``warn``: warn of the velocities that neither the
    file nor ``initial`` gave, as the command line does (:func:`warn_defaulted`).

    ``params`` and ``initial`` are the command line's overrides (by name).  The
    full path checks the start (a positive definite, well-conditioned mass
    matrix; no pole of the solved constraints); the plan was made by a run that
    passed those checks, so it answers runs from that start's parameters and
    coordinates (a reduced model's velocities may differ), and a reduced model's
    runs from others where the checks pass by a wide margin; every number
    finite, ``samples`` within the full path's limits.
    """
    from chaplygin.numeric.simulate import MAX_SAMPLES, choose_backend

    if (
        definition is None
        or not 0 < t_end < np.inf
        or not 2 <= samples <= MAX_SAMPLES
        or not applies(backend, model, method, constants, step)
    ):
        return None
    chosen = choose_backend(backend, method)
    found = plan(definition, model, form, chosen)
    if found is None:
        return None
    try:
        return _run(found, chosen, t_end, samples, params, initial, rtol, atol, progress, time_limit, warn)
    except (AttributeError, KeyError, TypeError, ValueError):  # a plan of another shape: the full path
        return None


def _run(
    found: dict[str, Any],
    backend: str,
    t_end: float,
    samples: int,
    params: Mapping[str, float],
    initial: Mapping[str, float],
    rtol: float,
    atol: float,
    progress: Callable[[float], None] | None = None,
    time_limit: float | None = None,
    warn: bool = True,
) -> Trajectory | None:
    from chaplygin.numeric._ckernel import Layout
    from chaplygin.numeric.simulate import _pole_between_samples, _watch, integrate, sign_fixed

    lay = found["layout"]
    layout = Layout(
        lay["model"],
        lay["form"],
        *(tuple(lay[f]) for f in ("coordinates", "velocities", "multipliers", "parameters", "reactions")),
    )
    values = {**found["parameters"], **params}
    state = {**found["initial"], **initial}
    if set(values) != set(layout.parameters) or not all(np.isfinite(v) for v in values.values()):
        return None  # an unknown name, or a number the full path refuses
    if not all(np.isfinite(v) for v in state.values()):
        return None
    every = set(layout.coordinates) | {c + "'" for c in layout.coordinates}
    start = found["start"]
    # a reduced model's run is watched as the full path watches it (System's stand-in)
    system: Any = Watched(found["watch"]) if start is None else None
    if system is not None and (system.n, system.g) != (len(layout.coordinates), int(found["g"])):
        return None
    checked = found["checked"]
    moved = values != checked["parameters"] or any(
        state.get(name) != checked["coordinates"][name] for name in layout.coordinates
    )
    if moved and (
        system is None
        or not set(layout.coordinates) <= set(state)
        or not _clearly_admissible(system, [state[c] for c in layout.coordinates], values)
    ):
        return None  # another configuration or parameter: the full path's start checks decide
    if start is not None and state != found["initial"]:
        return None  # a multiplier model's plan answers the start it kept, and no other
    if not set(state) <= every or (
        start is None and not set(layout.coordinates) | set(layout.velocities) <= set(state)
    ):
        return None
    compiled = _compiled(found, layout, backend)
    if compiled is None:
        return None
    names = layout.coordinates + layout.velocities
    y0 = np.array(start if start is not None else [state[name] for name in names], dtype=float)
    if len(y0) != len(names):
        return None
    p = np.array([values[name] for name in layout.parameters], dtype=float)
    velocities = compiled.observe(0.0, y0, p)[-len(layout.coordinates) :]
    for name, implied in zip(layout.coordinates, velocities):
        given = state.get(name + "'")
        if not np.isfinite(implied) or (
            given is not None and abs(given - implied) > 1e-9 * max(1.0, abs(implied))
        ):
            return None  # a dependent velocity that violates the constraints: the full path's error
    if warn:  # as the command line's full path does (chaplygin.apps.cli._numbers)
        warn_defaulted(found["defaulted"], initial)
    options: dict[str, Any] = {"rtol": rtol, "atol": atol, "method": "DOP853", "max_step": np.inf}
    span = (0.0, float(t_end))
    tr = integrate(
        compiled,
        span,
        y0,
        p,
        dict(values),
        samples=samples,
        g=int(found["g"]),
        progress=progress,
        time_limit=time_limit,
        **options,
    )
    if system is not None:  # a reduced model: judged as the full path judges it
        pole = None
        if system.g and not sign_fixed(system):
            pole = _pole_between_samples(system, compiled, tr, span, samples, y0, p, dict(values), **options)
        notes = tr.notes
        tr = _watch(system, tr, dict(values), reduced=True, compiled=compiled, p=p, pole=pole)
        tr.notes = notes
        return tr
    if start is not None and not (tr.success and all(np.all(np.isfinite(v)) for v in tr.velocities.values())):
        return (
            None  # the full path says why a multiplier run failed, and cuts it where a velocity is not finite
        )
    tr.energy_conserved = bool(found["energy_conserved"])
    tr.energy_column = str(found["energy_column"])
    return tr


def _compiled(found: dict[str, Any], layout: Any, backend: str) -> Any:
    """The plan's compiled model on ``backend`` (built from its stored source where needed), or
    None; the model that integrates DOP853 (numba's: the module with the loop)."""
    target = targets.get(backend)
    compiled = target.restore(found, layout)
    return None if compiled is None else target.looped(compiled, "DOP853")


def simulate_file(
    loaded: LoadedFile,
    model: str,
    t_span: tuple[float, float] | float,
    initial: Mapping[Any, float] | None,
    parameters: Mapping[Any, float] | None,
    options: dict[str, Any],
) -> Trajectory:
    """:func:`chaplygin.numeric.simulate.simulate` of a loaded file (``options``: its keyword
    arguments): ``initial`` and ``parameters`` override the file's ``[initial]`` and
    ``[parameters]``; a stored plan answers without building the system (no SymPy), else the
    full path runs on ``loaded.system`` and, where it can, leaves a plan for the next run."""
    from chaplygin.numeric.simulate import METHODS, _check_options, check_time_limit, simulate, time_span

    # the numbers of the run: the file's, as they are now, and the ones given over them
    start, numbers = {**loaded.initial, **(initial or {})}, {**loaded.parameters, **(parameters or {})}
    t0, t1 = time_span(t_span)
    _check_options(t0, t1, options["samples"], options["rtol"], options["atol"], options["max_step"])
    plain = (
        loaded.definition is not None
        and t0 == 0.0
        and options["multipliers"] is None
        and options["max_step"] == np.inf
        and options["reduction"] == "auto"
        and options["method"] in METHODS
        and all(isinstance(k, str) and isinstance(v, (int, float)) for k, v in (start | numbers).items())
    )
    if plain:
        found = run(
            loaded.definition,
            model,
            options["form"],
            t1,
            options["samples"],
            options["backend"],
            options["method"],
            options["constants"],
            options["step"],
            {k.strip(): float(v) for k, v in numbers.items()},
            {k.strip(): float(v) for k, v in start.items()},
            options["rtol"],
            options["atol"],
            options["progress"],
            check_time_limit(options["time_limit"]),
            warn=False,
        )
        if found is not None:
            return found
    system = loaded.system
    tr = simulate(system, model, t_span, start, numbers, **options)
    definition = loaded.definition
    if plain and definition is not None and plan(definition, model, options["form"], tr.backend) is None:
        remember(definition, model, options["form"], loaded, tr)  # (once, not at every run)
    return tr
