"""The ``cuda`` target: ensembles on an NVIDIA GPU, one thread per member, in a kernel built
from the ``c`` target's model (its C ``fill`` and the C DOP853 loop; :mod:`chaplygin.numeric._cuda`,
NVRTC through CuPy, optional extra ``chaplygin[cuda]``).

CuPy is imported when the device is looked for, never before.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from chaplygin.numeric.targets import Target, get

if TYPE_CHECKING:
    import numpy as np

    from chaplygin.core.system import System
    from chaplygin.models.registry import Model
    from chaplygin.numeric._ckernel import CompiledModel


class Cuda(Target):
    """The C target's model with the GPU kernel built from it."""

    name = "cuda"
    observes_start = True
    one_parameter_row = True

    def unavailable(self) -> str | None:
        from chaplygin.numeric import _cuda

        return _cuda.device_problem()

    def compile_model(
        self, system: System, model: Model, form: str, constants: Any, reduction: str
    ) -> CompiledModel:
        from chaplygin.numeric import _cuda
        from chaplygin.numeric.codegen import BackendUnavailable

        problem = self.unavailable()
        if problem is not None:
            raise BackendUnavailable(f"backend 'cuda' cannot be used: {problem}; {_cuda.INSTALL}.")
        try:
            c = get("c").compile_model(system, model, form, constants, reduction)
        except BackendUnavailable as exc:
            raise BackendUnavailable(f"backend 'cuda' builds on the C backend: {exc}") from None
        cuda = _cuda.CudaModel(c)
        cuda.device  # noqa: B018  # NVRTC compiles here, before any member is prepared
        return cuda

    def toolchain(self) -> str | None:
        return None  # the C target's model is stored; the GPU kernel is built from it

    def observe_members(
        self, compiled: CompiledModel, t: np.ndarray, Y: np.ndarray, P: np.ndarray
    ) -> np.ndarray:
        return compiled.device.observe(t, Y, P)  # type: ignore[attr-defined]  # a CudaModel

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
        return compiled.device.run(  # type: ignore[attr-defined]  # a CudaModel
            t_span, Y0, P, times=times, rtol=rtol, atol=atol, max_step=max_step, max_steps=max_steps
        )


TARGET = Cuda()
