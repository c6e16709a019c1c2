"""The ``numba`` target: the generated Python module compiled by ``numba.njit``, integrated by
the shared numba DOP853 loop (:mod:`chaplygin.numeric._loop`, calling the model's ``fill``
through :mod:`chaplygin.numeric._fnptr`); a large ``fill`` is C (:mod:`chaplygin.numeric._cfill`).

numba is imported when a model is built or loaded, never before.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from chaplygin.errors import ChaplyginError
from chaplygin.numeric.targets import LoopTarget, c_toolchain

if TYPE_CHECKING:
    from chaplygin.models.equations import Equations
    from chaplygin.numeric._ckernel import CompiledModel


class Numba(LoopTarget):
    """The generated module compiled by numba; its models run in the shared numba loop."""

    name = "numba"
    flavour = "numba"
    symmetric = True

    def compile(self, eqs: Equations) -> CompiledModel:
        try:
            import numba  # noqa: F401
        except ImportError as exc:  # pragma: no cover - numba is a dependency
            raise ChaplyginError("backend 'numba' needs numba: pip install numba") from exc
        return super().compile(eqs)

    def toolchain(self) -> str | None:
        return c_toolchain() or "no C compiler"  # (the C compiler builds a large fill)

    def code(self, compiled: CompiledModel) -> dict[str, Any] | None:
        code = super().code(compiled)
        if code is not None and "load_library_permanently" in code["module"]:
            return None  # a module calling a C fill by its library's path, which the cache may lose
        return code

    def looped(self, compiled: CompiledModel, method: str) -> CompiledModel:
        if method != "DOP853":
            return compiled
        from chaplygin.numeric._loop import loop_model

        return loop_model(compiled)  # its observe is compiled (and cached) with the loop


TARGET = Numba()
