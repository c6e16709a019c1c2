"""Compiled models on disk: a second process that simulates an equal system derives nothing.

:func:`chaplygin.numeric.codegen.compile_model` keeps what it builds in memory, per
:class:`~chaplygin.System` object, so a new process derived the equations and generated
their code again (on the symbolic rattleback 0.4 s and 0.3 s) before finding the compiled C
by the digest of that code.  So every model it builds is also stored in the derivation cache
(:mod:`chaplygin.numeric.cache`: JSON, written atomically, verified on read, a damaged entry
is a miss): its :class:`~chaplygin.numeric.codegen.Layout` and its generated source (the C
``fill`` of the ``c`` backend, the Python module of the ``numpy`` and ``numba`` backends);
and so are the pole functions of :func:`chaplygin.numeric.simulate.simulate`'s checks and the
linearisations of :mod:`chaplygin.numeric.linearization` (:func:`load_source`).  Nothing from the cache is run but source the library generated and
stored itself, after its SHA-256 checked, as :mod:`chaplygin.numeric._plan`'s run plans do.

The key (:func:`model_key`) is the SHA-256 of the system's definition (:func:`definition`:
the coordinates, T, the force function U, the generalized forces, the constraints as given
and which coordinates are dependent — not the name), the model, form, backend, the
constants of a vakonomic family, the reduction asked for, the code format and
:func:`chaplygin.numeric.cache.key`'s library version and source digest.  A definition that
holds something whose identity is not its printed form (a ``Dummy``, a class from outside
SymPy) has no key and is never cached.

``CHAPLYGIN_MODEL_CACHE=off`` (or ``0``, ``no``, ``false``) switches the disk cache off:
every process derives anew (the in-memory cache per ``System`` is unaffected).
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from chaplygin.numeric import cache, targets

if TYPE_CHECKING:
    from chaplygin.core.system import System
    from chaplygin.numeric._ckernel import CompiledModel

__all__ = ["ENVIRONMENT", "definition", "enabled", "load_model", "load_source", "store_model", "store_source"]

#: bumped whenever the shape of an entry changes
FORMAT = 1
#: the environment variable that switches the disk cache of compiled models off
ENVIRONMENT = "CHAPLYGIN_MODEL_CACHE"


def enabled() -> bool:
    """Whether compiled models are read from and written to disk (``$CHAPLYGIN_MODEL_CACHE``)."""
    return os.environ.get(ENVIRONMENT, "").strip().lower() not in ("off", "0", "no", "false", "none")


# ------------------------------------------------------------------ the system's definition
def definition(system: System) -> str | None:
    """The SHA-256 (hex) of what ``system`` was defined from; None where it cannot be keyed.

    The coordinates (names and assumptions), the kinetic energy, the force function, the
    generalized forces by coordinate, the constraint form, the dependent coordinates, the
    constraints and the holonomic relations as given, the branch chosen of implicit constraints
    nonlinear in the velocities, as a table of nodes (each subexpression once, in the order first
    met; a symbol by its name and assumptions).  SymPy orders the arguments of a sum or a
    product canonically, so an equal definition gives the same digest in every process.
    Computed once per system.
    """
    memo = system.__dict__.get("_definition_digest", "")
    if memo != "":
        return memo
    import sympy as sp

    given = system.__dict__.get("_given_constraints")  # (absent from a System pickled by an older version)
    forces = [system.forces.get(q, sp.S.Zero) for q in system.coordinates]
    relations = list(system.__dict__.get("holonomic", {}).values())  # f(q, t) = 0, as given
    exprs = [*system.coordinates, system.kinetic_energy, system.force_function, *forces, *(given or ())]
    nodes = None if given is None else _nodes([*exprs, *relations])
    digest = None
    if nodes is not None:
        head = [system.constraint_form, list(system._dep), len(system.coordinates), len(forces)]
        head += [len(relations)] if relations else []  # (keys of systems without them unchanged)
        # which solution of implicit constraints nonlinear in the velocities (issue 30)
        head += [["branch", system._branch]] if getattr(system, "_branch", None) is not None else []
        text = json.dumps([head, nodes], separators=(",", ":"), ensure_ascii=True)
        digest = hashlib.sha256(text.encode()).hexdigest()
    system.__dict__["_definition_digest"] = digest
    return digest


def _nodes(exprs: list[Any]) -> list[Any] | None:
    """``exprs`` as a table of nodes (see :func:`definition`); None if one cannot be named."""
    import sympy as sp
    from sympy.core.function import AppliedUndef

    nodes: list[Any] = []
    index: dict[Any, int] = {}

    def visit(e: Any) -> int:
        kind = type(e)
        i = index.get((kind, e))  # (by type too: 1 and 1.0 may compare equal)
        if i is not None:
            return i
        if isinstance(e, AppliedUndef):  # a coordinate q(t): an undefined function, by name
            kwargs = sorted(getattr(e.func, "_kwargs", {}).items())
            node: list[Any] = ["Function", e.func.__name__, repr(kwargs), *[visit(a) for a in e.args]]
        elif not isinstance(e, sp.Basic) or not kind.__module__.startswith("sympy."):
            raise TypeError(kind.__name__)  # a user's class: its meaning is not in its name
        elif isinstance(e, sp.Symbol):
            if kind is not sp.Symbol:  # Dummy, Wild: an identity beyond the name
                raise TypeError(kind.__name__)
            node = ["Symbol", e.name, sorted(e._assumptions_orig.items())]
        elif isinstance(e, sp.Rational):
            node = ["Rational", str(e.p), str(e.q)]
        elif isinstance(e, sp.Float):
            node = ["Float", repr(e._mpf_), e._prec]
        elif not e.args:  # a constant (pi, E, I, oo …)
            node = [kind.__name__, sp.srepr(e)]
        else:
            node = [f"{kind.__module__}.{kind.__qualname__}", *[visit(a) for a in e.args]]
        nodes.append(node)
        index[kind, e] = len(nodes) - 1
        return len(nodes) - 1

    try:
        roots = [visit(e) for e in exprs]
    except (TypeError, RecursionError):
        return None
    return [nodes, roots]


# ------------------------------------------------------------------ compiled models
def model_key(
    system: System, model: str, form: str, backend: str, constants: Any, variant: str, code_format: int
) -> str | None:
    """The key of a compiled model; None where there is none (switched off, not keyable).

    ``variant`` names the choices of the code generator that the rest does not fix (the
    reduction, the size from which numba's ``fill`` is C).  What builds the target's code
    (:meth:`~chaplygin.numeric.targets.Target.toolchain`: the C compiler of the ``c`` and
    ``numba`` targets) is part of the key; a target without one (jax: traced functions, not
    source) has no key.
    """
    built = targets.get(backend).toolchain() if enabled() else None
    if built is None:
        return None
    given = _constants(constants)
    digest = definition(system)
    if given is None or digest is None:
        return None
    parts = ("compiled-model", str(FORMAT), str(code_format), digest, model, form, backend)
    return cache.key(*parts, given, variant, built)


def _constants(constants: Any) -> str | None:
    """The constants of a vakonomic family as text; None for what has no exact text here."""
    if constants is None:
        return "none"
    if isinstance(constants, Mapping):
        items = list(constants.items())
    elif isinstance(constants, (list, tuple)):
        items = list(enumerate(constants))
    else:
        return None
    out = []
    for k, value in items:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not isinstance(k, (int, str)):
            return None
        out.append(f"{k!r}={float(value).hex()}")
    return ",".join(out)


#: the models loaded or stored by this process, by key (a key names what a model is, so an
#: equal system's is the same; kept here, not on the System, which stays picklable)
_LOADED: dict[str, CompiledModel] = {}


def load_model(key: str | None) -> CompiledModel | None:
    """The compiled model stored under ``key`` (loaded once per process), or None."""
    if key is None:
        return None
    if key in _LOADED:
        return _LOADED[key]
    value = cache.load(key)
    if not isinstance(value, dict):
        return None
    try:
        compiled = _build(value)
    except (KeyError, TypeError, ValueError, ImportError):  # an unexpected shape: derive anew
        return None
    if compiled is not None:
        _LOADED[key] = compiled
    return compiled


def _build(value: dict[str, Any]) -> CompiledModel | None:
    from chaplygin.numeric._ckernel import Layout

    lay = value["layout"]
    fields = ("coordinates", "velocities", "multipliers", "parameters", "reactions")
    layout = Layout(str(lay["model"]), str(lay["form"]), *(tuple(map(str, lay[f])) for f in fields))
    backend = value["backend"]
    if backend not in targets.TARGETS:
        return None
    return targets.get(backend).restore(value, layout)


def store_model(key: str | None, compiled: CompiledModel) -> None:
    """Store ``compiled`` under ``key`` (nothing where ``key`` is None or it is not source)."""
    if key is None:
        return
    code = targets.get(compiled.backend).code(compiled)
    if code is None:
        return
    layout = compiled.layout
    value: dict[str, Any] = {
        "layout": {
            f: list(getattr(layout, f))
            for f in ("coordinates", "velocities", "multipliers", "parameters", "reactions")
        }
        | {"model": layout.model, "form": layout.form},
        "backend": compiled.backend,
    }
    cache.store(key, value | code)
    _LOADED[key] = compiled


# ------------------------------------------------------------------ other generated source
def source_key(system: System, what: str, code_format: int) -> str | None:
    """The key of generated source ``what`` (e.g. ``"pole-functions"``) of ``system``; None if none."""
    digest = definition(system) if enabled() else None
    return None if digest is None else cache.key(what, str(FORMAT), str(code_format), digest)


def load_source(key: str | None) -> dict[str, Any] | None:
    """The stored ``{"source": module source, **metadata}`` under ``key``, or None."""
    value = cache.load(key) if key is not None else None
    return value if isinstance(value, dict) and isinstance(value.get("source"), str) else None


def store_source(key: str | None, source: str, **metadata: Any) -> None:
    """Store generated module ``source`` (and JSON ``metadata``) under ``key`` (None: nothing)."""
    if key is not None:
        cache.store(key, {"source": source, **metadata})
