"""The ``c`` target: the model's ``fill`` printed as C (:mod:`chaplygin.numeric._cfill`),
built by the system's C compiler and integrated by the DOP853 loop in C
(:mod:`chaplygin.numeric._ckernel`): one trajectory, or an ensemble on every core.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from chaplygin.numeric.targets import LoopTarget, c_toolchain

if TYPE_CHECKING:
    import numpy as np

    from chaplygin.numeric._ckernel import CompiledModel, Layout
    from chaplygin.numeric.codegen import _Parts

#: what :meth:`C.code` stores beside ``fill``'s source: the kernel's sizes, in CKernel's order
SIZES = ("dim", "n", "k", "n_observed", "n_react")


class C(LoopTarget):
    """Generated C with the C DOP853 loop."""

    name = "c"

    def unavailable(self) -> str | None:
        from chaplygin.numeric._ckernel import Unavailable, compiler

        try:
            compiler()
        except Unavailable as exc:
            return str(exc)
        return None

    def prepare(self) -> None:
        from chaplygin.numeric.codegen import _build_loop_beside

        _build_loop_beside()

    def build(self, parts: _Parts) -> CompiledModel:
        from chaplygin.numeric import _cfill
        from chaplygin.numeric._ckernel import CKernel, CompiledModel, library
        from chaplygin.numeric.codegen import _BESIDE, BackendUnavailable, _assignments

        s, layout = parts.system, parts.layout
        try:
            source = _cfill.source(
                parts.fill, [_assignments(b) for b in parts.fill.blocks()], "chaplygin_fill_@DIGEST@"
            )
            if any(t.is_alive() for t in _BESIDE):  # the loop library, built beside the derivation:
                library(source, "fill")  # the fill is compiled meanwhile (CKernel then loads it)
            for thread in _BESIDE:
                thread.join()
            kernel = CKernel(
                source,
                parts.dim,
                s.n,
                parts.k,
                1 + s.g + len(layout.reactions) + s.n,
                len(layout.reactions),
            )
        except _cfill.Unavailable as exc:
            raise BackendUnavailable(f"backend 'c' cannot be used: {exc}") from None
        return CompiledModel(layout, kernel, "c")

    def toolchain(self) -> str | None:
        return c_toolchain()

    def code(self, compiled: CompiledModel) -> dict[str, Any] | None:
        kernel = compiled.module
        sizes = (kernel.DIM, kernel.N, kernel.K, kernel.N_OBSERVED, kernel.n_react)
        return {"fill": kernel.fill_source, **dict(zip(SIZES, sizes))}

    def restore(self, stored: dict[str, Any], layout: Layout) -> CompiledModel | None:
        from chaplygin.numeric._ckernel import CKernel, CompiledModel, Unavailable

        try:
            kernel = CKernel(str(stored["fill"]), *(int(stored[k]) for k in SIZES))
        except Unavailable:
            return None
        return CompiledModel(layout, kernel, "c")

    def observe_run(
        self, compiled: CompiledModel, times: np.ndarray, ys: np.ndarray, p: np.ndarray
    ) -> np.ndarray:
        return compiled.module.observe_many(times, ys, p)  # every sample in one call

    def observe_members(
        self, compiled: CompiledModel, t: np.ndarray, Y: np.ndarray, P: np.ndarray
    ) -> np.ndarray:
        import numpy as np

        if not len(t):
            return super().observe_members(compiled, t, Y, P)
        observe_many = compiled.module.observe_many  # many states, one p
        # one call per distinct parameter vector (one for an ensemble over initial states only)
        if np.array_equal(P, np.broadcast_to(P[0], P.shape)):  # (np.unique's row sort costs 30 times more)
            return np.asarray(observe_many(t, Y, P[0]))
        distinct, inverse = np.unique(P, axis=0, return_inverse=True)
        if len(distinct) <= max(1, len(t) // 4):
            order = np.argsort(inverse.ravel(), kind="stable")
            ends = np.cumsum(np.bincount(inverse.ravel(), minlength=len(distinct)))
            rows = np.empty((len(t), compiled.n_observed))
            for k, members in enumerate(np.split(order, ends[:-1])):
                rows[members] = observe_many(t[members], Y[members], distinct[k])
            return rows
        return super().observe_members(compiled, t, Y, P)


TARGET = C()
