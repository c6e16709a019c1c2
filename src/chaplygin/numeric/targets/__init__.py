"""The code targets: one module each, behind one interface (:class:`Target`), found by name in
one table (:data:`TARGETS`).

A target turns a model's generated parts into something that runs (a generated Python module,
numba's compilation of it, a C kernel, JAX functions, a GPU kernel) and integrates with it:
one trajectory for :func:`~chaplygin.numeric.simulate.simulate`, many for
:func:`~chaplygin.numeric.ensemble.simulate_ensemble`.  The entry points never test a backend's
name: they ask :func:`get` for its target and call it.

=========  ==========================================  =============================================
target     module                                      implementation
=========  ==========================================  =============================================
``numpy``  :mod:`chaplygin.numeric.targets.numpy`      the generated module as it is; DOP853 on lists
                                                       (:mod:`~chaplygin.numeric._pyloop`)
``numba``  :mod:`chaplygin.numeric.targets.numba`      the module compiled by numba; the numba
                                                       DOP853 loop (:mod:`~chaplygin.numeric._loop`,
                                                       :mod:`~chaplygin.numeric._fnptr`,
                                                       :mod:`~chaplygin.numeric._cfill`)
``c``      :mod:`chaplygin.numeric.targets.c`          ``fill`` in C with the C DOP853 loop
                                                       (:mod:`~chaplygin.numeric._ckernel`,
                                                       :mod:`~chaplygin.numeric._cfill`)
``jax``    :mod:`chaplygin.numeric.targets.jax`        JAX functions, diffrax
                                                       (:mod:`~chaplygin.numeric.jaxbackend`)
``cuda``   :mod:`chaplygin.numeric.targets.cuda`       the C loop as a GPU kernel
                                                       (:mod:`~chaplygin.numeric._cuda`)
=========  ==========================================  =============================================

The table names each module, which is imported the first time its target is asked for: a run
on the C target imports neither numba nor JAX nor CuPy.  Targets do not import each other (an
import-linter contract); what two of them share is here (:class:`Target`'s defaults).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any, NamedTuple

from chaplygin.errors import ChaplyginError

if TYPE_CHECKING:
    from collections.abc import Callable

    import numpy as np

    from chaplygin.core.system import System
    from chaplygin.models.equations import Equations
    from chaplygin.models.registry import Model
    from chaplygin.numeric._ckernel import CompiledModel, Layout
    from chaplygin.numeric.codegen import _Parts

__all__ = ["TARGETS", "Row", "Target", "c_toolchain", "get", "offered", "require"]


class Row(NamedTuple):
    """One row of :data:`TARGETS`: the target's module and the entry points that offer it."""

    module: str
    #: ``compile_model(backend=…)`` and ``compile_equations`` build it
    compile: bool
    #: ``simulate(backend=…)`` runs one trajectory on it
    simulate: bool
    #: ``simulate_ensemble(backend=…)`` runs ensembles on it
    ensemble: bool
    #: sweeps (``chaplygin sweep``, :func:`chaplygin.apps.sweep.sweep`) run on it: one trajectory
    #: per run, in worker processes that take the compiled model from the disk cache
    sweep: bool = False


#: every target, by the name ``backend=`` gives it
TARGETS: dict[str, Row] = {
    "numpy": Row("chaplygin.numeric.targets.numpy", compile=True, simulate=True, ensemble=False, sweep=True),
    "numba": Row("chaplygin.numeric.targets.numba", compile=True, simulate=True, ensemble=True, sweep=True),
    "c": Row("chaplygin.numeric.targets.c", compile=True, simulate=True, ensemble=True, sweep=True),
    "jax": Row("chaplygin.numeric.targets.jax", compile=True, simulate=True, ensemble=True),
    "cuda": Row("chaplygin.numeric.targets.cuda", compile=False, simulate=False, ensemble=True),
}

_LOADED: dict[str, Target] = {}


def get(name: str) -> Target:
    """The target named ``name`` (its module imported on first use)."""
    if name not in _LOADED:
        if name not in TARGETS:
            raise ChaplyginError(
                f"unknown backend {name!r}; the backends are {', '.join(map(repr, TARGETS))}."
            )
        _LOADED[name] = importlib.import_module(TARGETS[name].module).TARGET
    return _LOADED[name]


#: the entry points of :class:`Row`'s fields, as a user calls them
_ENTRY = {
    "compile": "compile_model",
    "simulate": "simulate",
    "ensemble": "simulate_ensemble",
    "sweep": "sweeps",
}


def require(name: str, entry: str, *, auto: bool = True) -> None:
    """Refuse ``name`` unless the entry point ``entry`` (a field of :class:`Row`) offers it
    (``"auto"`` too where ``auto``): an unknown name, or a target that serves other entry points,
    which the message names."""
    names = (("auto",) if auto else ()) + offered(entry)
    if name in names:
        return
    if name in TARGETS:
        serves = [_ENTRY[e] for e in _ENTRY if getattr(TARGETS[name], e)]
        raise ChaplyginError(
            f"backend {name!r} serves {' and '.join(serves) or 'no entry point'}, not {_ENTRY[entry]}; "
            f"{_ENTRY[entry]}'s backends are {', '.join(map(repr, names))}."
        )
    raise ChaplyginError(f"unknown backend {name!r}; the backends are {', '.join(map(repr, names))}.")


def c_toolchain() -> str | None:
    """The C compiler's command and flags as text, for the keys of what the targets that build C
    store (:meth:`Target.toolchain`); None where no C compiler is found."""
    from chaplygin.numeric._ckernel import FLAGS, Unavailable, compiler

    try:
        return "\0".join([*compiler(), *FLAGS])
    except Unavailable:
        return None


def offered(entry: str) -> tuple[str, ...]:
    """The targets that the entry point ``entry`` (a field of :class:`Row`) offers, in table order."""
    return tuple(name for name, row in TARGETS.items() if getattr(row, entry))


class Target:
    """What the entry points need of a code target.  A target module defines a subclass and one
    instance of it, ``TARGET``; the defaults here are those of the generated Python module
    stepped by SciPy."""

    #: the name ``backend=`` gives it (a key of :data:`TARGETS`)
    name: str = ""
    #: whether :func:`~chaplygin.numeric.codegen.compile_model` may compile a reduced model by
    #: the numeric reduction (from the Chetaev matrices) for it
    numeric_reduction: bool = True
    #: the methods its ensembles integrate with
    ensemble_methods: tuple[str, ...] = ("DOP853",)
    #: whether an ensemble's duration is estimated beforehand from its first member (the CPU loops)
    paced: bool = False
    #: whether :meth:`ensemble` also returns ``observed0``, ``observe`` at every member's start
    #: (the GPU: from the states already on the device, in the same pass)
    observes_start: bool = False
    #: whether parameters given as numbers may reach :meth:`ensemble` as one row seen by every
    #: member (a read-only view: the GPU uploads the row, not the matrix; numba would compile the
    #: CPU loop again for read-only arrays, some 4 s)
    one_parameter_row: bool = False
    #: whether the symmetric fixed-step methods (:mod:`~chaplygin.numeric.symmetric`) run on it
    symmetric: bool = False
    #: how :meth:`build` prints the generated Python module (:func:`~chaplygin.numeric.codegen._module`):
    #: ``"numpy"`` (plain Python on lists) or ``"numba"`` (on arrays, for ``numba.njit``)
    flavour: str = "numpy"

    def unavailable(self) -> str | None:
        """Why this target cannot run here (None: it can)."""
        return None

    def prepare(self) -> None:
        """Start what the target needs before a model is derived (called by ``compile_model``)."""

    def compile(self, eqs: Equations) -> CompiledModel:
        """The compiled model of ``eqs``."""
        from chaplygin.numeric.codegen import _parts

        return self.build(_parts(eqs))

    def build(self, parts: _Parts) -> CompiledModel:
        """The compiled model of generated ``parts`` (:func:`~chaplygin.numeric.codegen._parts`):
        here the generated Python module (:func:`~chaplygin.numeric.codegen._module`) imported."""
        from chaplygin.numeric._ckernel import CompiledModel
        from chaplygin.numeric.cache import import_source
        from chaplygin.numeric.codegen import _module

        source = _module(parts.system, parts.layout, parts.fill, parts.dim, parts.k, self.flavour)
        return CompiledModel(parts.layout, import_source(source, self.name), self.name)

    def compile_model(
        self, system: System, model: Model, form: str, constants: Any, reduction: str
    ) -> CompiledModel:
        """:func:`~chaplygin.numeric.codegen.compile_model` for this target (``model``: the
        registry's entry, resolved by the entry point)."""
        from chaplygin.numeric.codegen import compile_model

        return compile_model(system, model, form, self.name, constants=constants, reduction=reduction)

    # ---------------------------------------------------------------- the disk cache
    def toolchain(self) -> str | None:
        """What builds this target's code, as text for the disk cache's keys ("": nothing; None:
        nothing is stored, as the code cannot be built here or is not kept on disk)."""
        return ""

    def code(self, compiled: CompiledModel) -> dict[str, Any] | None:
        """The code of ``compiled`` that the disk cache and run plans store beside its layout
        (None: nothing): here the generated module's source."""
        from pathlib import Path

        return {"module": Path(compiled.module.__file__).read_text(encoding="utf-8")}

    def restore(self, stored: dict[str, Any], layout: Layout) -> CompiledModel | None:
        """The compiled model from :meth:`code`'s ``stored`` (None: it cannot be rebuilt here)."""
        from chaplygin.numeric._ckernel import CompiledModel
        from chaplygin.numeric.cache import import_source

        return CompiledModel(layout, import_source(str(stored["module"]), self.name), self.name)

    # ---------------------------------------------------------------- one trajectory
    def looped(self, compiled: CompiledModel, method: str) -> CompiledModel:
        """The model that integrates ``method`` (``compiled`` itself but for numba's loop)."""
        return compiled

    def attempt(
        self,
        compiled: CompiledModel,
        t1: float,
        p: np.ndarray,
        rtol: float,
        atol: Any,
        method: str,
        told: Any,
    ) -> Callable[..., Any]:
        """One attempt of :func:`~chaplygin.numeric.simulate._pinned`: SciPy's ``method``."""
        from chaplygin.numeric.simulate import _scipy_attempt

        return _scipy_attempt(compiled, t1, p, rtol, atol, method, told)

    def integrate(
        self,
        compiled: CompiledModel,
        t_span: tuple[float, float],
        y0: np.ndarray,
        p: np.ndarray,
        times: np.ndarray,
        *,
        rtol: float,
        atol: Any,
        method: str,
        max_step: float,
        progress: Callable[[float], None] | None,
        time_limit: float | None,
    ) -> tuple[CompiledModel, np.ndarray, np.ndarray, str, str, int]:
        """One trajectory sampled at ``times``: ``(model, t, y, status, message, n_rhs)``, the
        model being the one that integrated (see :func:`~chaplygin.numeric.simulate.integrate`)."""
        import numpy as np

        from chaplygin.numeric.simulate import _budget, _pinned

        told = _budget(progress, t_span[1], time_limit)  # (the last call below: not checked)
        compiled = self.looped(compiled, method)
        attempt = self.attempt(compiled, t_span[1], p, rtol, atol, method, told)
        ts, ys, message, n_rhs = _pinned(attempt, t_span[0], np.asarray(y0, dtype=float), times, max_step)
        if progress is not None:
            progress(float(ts[-1]) if len(ts) else t_span[0])
        status = "failed" if message else "success"
        return compiled, ts, ys, status, message or f"reached t = {t_span[1]:g}", n_rhs

    def observe_run(
        self, compiled: CompiledModel, times: np.ndarray, ys: np.ndarray, p: np.ndarray
    ) -> np.ndarray:
        """``observe`` at every sample of one run (one row each)."""
        import numpy as np

        return np.array([compiled.observe(t, y, p) for t, y in zip(times, ys)]).reshape(
            len(times), compiled.n_observed
        )

    # ---------------------------------------------------------------- ensembles
    def observe_members(
        self, compiled: CompiledModel, t: np.ndarray, Y: np.ndarray, P: np.ndarray
    ) -> np.ndarray:
        """``observe`` of every member (row ``k``: ``t[k]``, ``Y[k]``, ``P[k]``)."""
        import numpy as np

        observe = compiled.module.observe
        return np.array([observe(ti, yi, pi) for ti, yi, pi in zip(t, Y, P)]).reshape(len(t), -1)

    def ensemble(
        self,
        compiled: CompiledModel,
        t_span: tuple[float, float],
        Y0: np.ndarray,
        P: np.ndarray,
        *,
        times: np.ndarray | None,
        rtol: float,
        atol: Any,
        method: str,
        max_step: float,
        max_steps: int,
        threads: int | None,
    ) -> dict[str, np.ndarray]:
        """Every member integrated (the arrays of :func:`~chaplygin.numeric._loop.ensemble_dop853`)."""
        raise ChaplyginError(f"backend {self.name!r} runs no ensembles.")


class LoopTarget(Target):
    """A target with the compiled DOP853 loop (numba's or C's): one trajectory and ensembles on
    every core, with the same steps and status codes."""

    paced = True

    def attempt(
        self,
        compiled: CompiledModel,
        t1: float,
        p: np.ndarray,
        rtol: float,
        atol: Any,
        method: str,
        told: Any,
    ) -> Callable[..., Any]:
        if method != "DOP853":
            return super().attempt(compiled, t1, p, rtol, atol, method, told)
        from chaplygin.numeric.simulate import _loop_attempt

        return _loop_attempt(compiled, t1, p, rtol, atol, told)

    def ensemble(
        self,
        compiled: CompiledModel,
        t_span: tuple[float, float],
        Y0: np.ndarray,
        P: np.ndarray,
        *,
        times: np.ndarray | None,
        rtol: float,
        atol: Any,
        method: str,
        max_step: float,
        max_steps: int,
        threads: int | None,
    ) -> dict[str, np.ndarray]:
        from chaplygin.numeric._loop import ensemble_dop853

        return ensemble_dop853(
            compiled,
            t_span,
            Y0,
            P,
            times=times,
            rtol=rtol,
            atol=atol,
            max_step=max_step,
            max_steps=max_steps,
            threads=threads,
        )
