"""The ``jax`` target: the model's expressions as JAX functions, integrated by diffrax
(:mod:`chaplygin.numeric.jaxbackend`; one trajectory, or an ensemble under ``jax.vmap``).

JAX is imported when a model is compiled for it, never before (optional extra ``chaplygin[jax]``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from chaplygin.errors import ChaplyginError
from chaplygin.numeric.targets import Target

if TYPE_CHECKING:
    from collections.abc import Callable

    import numpy as np

    from chaplygin.models.equations import Equations
    from chaplygin.numeric._ckernel import CompiledModel
    from chaplygin.numeric.codegen import _Parts

#: the methods diffrax integrates with (``"DOP853"`` → ``Dopri8``; see ``jaxbackend.SOLVERS``)
METHODS = ("DOP853", "RK45", "RK23")


class Jax(Target):
    """JAX functions of the symbolic equations, stepped by diffrax."""

    name = "jax"
    numeric_reduction = False  # its functions are the symbolic equations'
    ensemble_methods = METHODS

    def compile(self, eqs: Equations) -> CompiledModel:
        from chaplygin.numeric.jaxbackend import compile_jax

        return compile_jax(eqs)

    def build(self, parts: _Parts) -> CompiledModel:
        raise ChaplyginError("backend 'jax' compiles symbolic equations, not generated parts.")

    def toolchain(self) -> str | None:
        return None  # jitted functions, compiled anew in each process

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
        if method not in METHODS:  # SciPy's, on the JAX functions
            return super().integrate(
                compiled, t_span, y0, p, times, rtol=rtol, atol=atol, method=method, max_step=max_step,
                progress=progress, time_limit=time_limit,
            )  # fmt: skip
        from chaplygin.numeric.jaxbackend import solve

        res = solve(compiled, t_span, y0, p, times, rtol=rtol, atol=atol, method=method, max_step=max_step)
        if progress is not None and len(res.t):
            progress(float(res.t[-1]))
        return compiled, res.t, res.y, res.status, res.message, res.n_rhs

    def observe_members(
        self, compiled: CompiledModel, t: np.ndarray, Y: np.ndarray, P: np.ndarray
    ) -> np.ndarray:
        import jax
        import numpy as np

        solvers = compiled._solvers  # type: ignore[attr-defined]  # jitted functions of this model
        if "observe_vmap" not in solvers:
            solvers["observe_vmap"] = jax.jit(jax.vmap(compiled.module.observe_jax))
        return np.asarray(solvers["observe_vmap"](t, Y, P))

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
        from chaplygin.numeric.jaxbackend import solve_ensemble

        return solve_ensemble(
            compiled,
            t_span,
            Y0,
            P,
            times=times,
            rtol=rtol,
            atol=atol,
            method=method,
            max_step=max_step,
            max_steps=max_steps or 1_000_000,
        )


TARGET = Jax()
