"""Warm runs of ``chaplygin simulate`` without SymPy: run plans.

A run of ``chaplygin simulate`` spends half a second importing SymPy and
building the system before it integrates for a few milliseconds.  So after a
run the command line stores a *run plan* in the derivation cache
(:mod:`chaplygin.numeric.cache`: JSON, keyed by the system file's bytes or the
example's name, the model, form, backend and library version, verified on
read): the model's layout, its generated code (source, not code: the C
``fill`` built into the kernel cache, :mod:`chaplygin.numeric._ckernel`, or the
generated Python module of the ``numpy`` and ``numba`` backends, which the code
cache and numba's own cache keep compiled), and the file's default parameters
and initial state.  The next run of the same system, model and backend loads
the compiled code (or builds it from the stored source) and integrates
without importing SymPy (nor SciPy or numba, with the ``c`` backend).

A plan answers only what it can answer exactly as the full path would: a
reduced model (``chaplygin``, ``voronets``, ``lindelof``, whose state is the
coordinates and the independent velocities, taken as given), DOP853, no
constants, no holonomic constraints (their coordinates are solved at the start and their
residual monitored: the full path), overrides naming known parameters, coordinates or velocities.  A
given dependent velocity is checked against the constraints (the kernel's
velocities); anything else, a disagreement included, returns ``None`` and the
full path runs (and reports the error).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from chaplygin.models import registry
from chaplygin.numeric import cache

if TYPE_CHECKING:
    from chaplygin.numeric.simulate import Trajectory

__all__ = ["key", "plan", "remember", "run"]

#: the reduced models without constants, whose state a plan builds from the given numbers alone
REDUCED = tuple(m.name for m in registry.MODELS.values() if m.reduced and not m.constants)
#: the backends whose runs a plan answers
PLANNED = ("c", "numpy", "numba")
#: what the command line asks for when no --model is given: the true motion (Chaplygin's
#: equations for a Chaplygin system, else Voronets'), which the plan then names
TRUE_MOTION = "true-motion"
#: bumped whenever the plan's shape changes
FORMAT = 5


def key(definition: bytes, model: str, form: str, backend: str) -> str:
    """The cache key of the plan for ``model``/``form`` of the system ``definition`` on ``backend``."""
    from chaplygin.numeric._ckernel import FLAGS, compiler

    built = "\0".join([*compiler(), *FLAGS]) if backend == "c" else ""
    return cache.key("simulate-plan", str(FORMAT), definition, model, form, backend, built)


def applies(backend: str, model: str, method: str, constants: Any, step: Any) -> bool:
    """Whether a plan could answer this run (before looking for one)."""
    from chaplygin.numeric.simulate import choose_backend

    return (
        model in (*REDUCED, TRUE_MOTION)
        and method == "DOP853"
        and constants is None
        and step is None
        and choose_backend(backend, method) in PLANNED
    )


def remember(definition: bytes | None, asked: str, form: str, loaded: Any, tr: Trajectory) -> None:
    """Store the plan of a finished ``c``-backend run (a no-op for anything a plan cannot answer).

    ``asked`` is the model as the command line asked for it (:data:`TRUE_MOTION` for none);
    only a run that succeeded makes a plan, so the checks of its start passed.
    """
    if definition is None or tr.backend not in PLANNED or tr.model not in REDUCED or not tr.success:
        return
    if getattr(loaded.system, "holonomic", None):  # its start is solved and its residual monitored
        return
    from pathlib import Path

    from chaplygin.numeric.codegen import compile_model

    # the run's model (cached on the system)
    compiled = compile_model(loaded.system, tr.model, form, tr.backend)
    kernel, layout = compiled.module, compiled.layout
    system = loaded.system
    if tr.backend == "c":
        code = {"fill": kernel.fill_source, "dim": kernel.DIM, "n": kernel.N, "k": kernel.K}
        code |= {"n_observed": kernel.N_OBSERVED, "n_react": kernel.n_react}
    else:
        code = {"module": Path(kernel.__file__).read_text(encoding="utf-8")}
    value = {
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
        "initial": {k: float(v) for k, v in (loaded.initial or {}).items()},
        "defaulted": list(getattr(loaded, "defaulted", ())),
    }
    cache.store(key(definition, asked, form, tr.backend), value)


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
    """The stored plan, or None."""
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
) -> Trajectory | None:
    """The run from a stored plan, or None where the full path must run.

    ``progress`` is told the time the integration reaches, and ``time_limit`` is applied, as by
    :func:`chaplygin.numeric.simulate.simulate`.

    ``params`` and ``initial`` are the command line's overrides (by name).  The
    full path checks the start (a positive definite, well-conditioned mass
    matrix; no pole of the solved constraints); the plan was made by a run that
    passed those checks, so it answers only runs whose mass matrix and
    constraints are the same: the same parameters and coordinates (velocities
    may differ), every number finite, ``samples`` within the full path's limits.
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
        return _run(found, chosen, t_end, samples, params, initial, rtol, atol, progress, time_limit)
    except (KeyError, TypeError, ValueError):  # a plan of an unexpected shape: the full path decides
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
) -> Trajectory | None:
    from chaplygin.numeric._ckernel import Layout
    from chaplygin.numeric.simulate import integrate

    lay = found["layout"]
    layout = Layout(
        lay["model"],
        lay["form"],
        *(tuple(lay[f]) for f in ("coordinates", "velocities", "multipliers", "parameters", "reactions")),
    )
    values = {**found["parameters"], **params}
    state = {**found["initial"], **initial}
    if set(values) != set(layout.parameters) or values != found["parameters"]:
        return None  # another parameter value (or an unknown name): the full path checks it
    if any(name in initial and initial[name] != found["initial"].get(name) for name in layout.coordinates):
        return None  # another configuration: the full path checks the mass matrix there
    if not all(np.isfinite(v) for v in state.values()):
        return None
    every = set(layout.coordinates) | {c + "'" for c in layout.coordinates}
    if not set(state) <= every or not set(layout.coordinates) | set(layout.velocities) <= set(state):
        return None
    compiled = _compiled(found, layout, backend)
    if compiled is None:
        return None
    y0 = np.array([state[name] for name in layout.coordinates + layout.velocities], dtype=float)
    p = np.array([values[name] for name in layout.parameters], dtype=float)
    velocities = compiled.observe(0.0, y0, p)[-len(layout.coordinates) :]
    for name, implied in zip(layout.coordinates, velocities):
        given = state.get(name + "'")
        if not np.isfinite(implied) or (
            given is not None and abs(given - implied) > 1e-9 * max(1.0, abs(implied))
        ):
            return None  # a dependent velocity that violates the constraints: the full path's error
    warn_defaulted(found["defaulted"], initial)  # as the full path does (chaplygin.apps.cli._numbers)
    tr = integrate(
        compiled,
        (0.0, float(t_end)),
        y0,
        p,
        dict(values),
        rtol=rtol,
        atol=atol,
        method="DOP853",
        samples=samples,
        max_step=np.inf,
        g=int(found["g"]),
        progress=progress,
        time_limit=time_limit,
    )
    tr.energy_conserved = bool(found["energy_conserved"])
    tr.energy_column = str(found["energy_column"])
    return tr


def _compiled(found: dict[str, Any], layout: Any, backend: str) -> Any:
    """The plan's compiled model on ``backend`` (built from its stored source where needed), or None."""
    from chaplygin.numeric._ckernel import CKernel, CompiledModel, Unavailable

    if backend == "c":
        try:
            kernel = CKernel(
                found["fill"],
                *(int(found[k]) for k in ("dim", "n", "k", "n_observed", "n_react")),
            )
        except Unavailable:
            return None
        return CompiledModel(layout, kernel, "c")
    module = cache.import_source(str(found["module"]), backend)
    compiled = CompiledModel(layout, module, backend)
    if backend == "numba":  # the module with the DOP853 loop, as the run integrates it
        from chaplygin.numeric._loop import loop_model

        compiled = loop_model(compiled)
    return compiled
