"""The ``numpy`` target: the generated Python module run as it is, no build step.

A trajectory with DOP853 steps the generated ``rhs_list`` (on lists of floats) in plain
Python (:mod:`chaplygin.numeric._pyloop`); the other methods are SciPy's.  Its code is
:func:`chaplygin.numeric.codegen._module`, imported from the code cache.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from chaplygin.numeric.targets import Target

if TYPE_CHECKING:
    from collections.abc import Callable

    import numpy as np

    from chaplygin.numeric._ckernel import CompiledModel


class NumPy(Target):
    """The generated Python module, run by the interpreter."""

    name = "numpy"
    symmetric = True

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
        if method == "DOP853" and hasattr(compiled.module, "rhs_list"):
            # the generated code on lists, stepped in plain Python: no SciPy at all
            from chaplygin.numeric.simulate import _list_attempt

            return _list_attempt(compiled, t1, p, rtol, atol, told)
        return super().attempt(compiled, t1, p, rtol, atol, method, told)


TARGET = NumPy()
