"""Call a model's ``fill`` through its C address, from numba (the shared DOP853 loop).

The numba DOP853 loop of :mod:`chaplygin.numeric._loop` is compiled once per
installation, so it cannot name a model's ``fill``: it receives the address of
a C-callable one, ``int fill(double t, double *y, double *p, double *M,
double *F, double *V, double *O)`` returning 0, or 3 when it raised (a
``numba.cfunc`` around the generated ``fill``), inside a *model tuple*
``(address, DIM, N, N_OBSERVED)``.  :func:`call_fill` is the numba intrinsic
that turns the address into that function pointer and calls it with the
arrays' data pointers.  The arrays must be C-contiguous float64 arrays (the
loop's own work arrays always are); anything else is a typing error at
compile time, never a wrong pointer.

This module imports numba and is imported only by the generated loop module.
"""

from __future__ import annotations

from typing import Any

from llvmlite import ir
from numba import types
from numba.extending import intrinsic

__all__ = ["call_fill"]


def _float_arrays(arrays: tuple[Any, ...]) -> bool:
    return all(isinstance(a, types.Array) and a.dtype == types.float64 and a.layout == "C" for a in arrays)


@intrinsic
def call_fill(typingctx: Any, model: Any, t: Any, y: Any, p: Any, M: Any, F: Any, V: Any, O: Any) -> Any:  # noqa: E741
    """``fill(t, y, p, M, F, V, O)`` at the address ``model[0]``; its int32 status (0, or 3)."""
    arrays = (y, p, M, F, V, O)
    if not (
        isinstance(model, types.UniTuple)
        and isinstance(model.dtype, types.Integer)
        and isinstance(t, (types.Float, types.Integer))
        and _float_arrays(arrays)
    ):
        return None  # numba reports the argument types that do not fit
    signature = types.int32(model, t, *arrays)

    def codegen(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        double = ir.DoubleType()
        function = ir.FunctionType(ir.IntType(32), [double] + [double.as_pointer()] * 6)
        address = builder.extract_value(args[0], 0)
        pointer = builder.inttoptr(address, function.as_pointer())
        time = context.cast(builder, args[1], sig.args[1], types.float64)
        data = [
            context.make_array(ty)(context, builder, value).data for ty, value in zip(sig.args[2:], args[2:])
        ]
        return builder.call(pointer, [time, *data])

    return signature, codegen
