"""``fill`` as C, compiled by the system's C compiler, for the numba backend's large models.

numba compiles straight-line code slowly: its type inference and lowering run
in Python for every statement, and the generated ``fill`` of a chain of 17
sleighs (2,400 lines) takes it about a minute, while a C compiler builds the
same function in under two seconds.  So from :data:`chaplygin.numeric.codegen.C_FILL_FROM_LINES`
lines on, the numba backend prints ``fill`` as C (:mod:`chaplygin.numeric._printing`,
the same common subexpressions), builds a shared library in the code cache,
and its generated module calls it through ``numba.types.ExternalFunction``:
a call by symbol name, which numba caches like any other function (the module
loads the library with ``llvmlite.binding.load_library_permanently`` before
anything is compiled or loaded from numba's cache).  The rest of the module —
``evaluate``, ``rhs``, ``observe`` and the compiled integrators appended to it
— is unchanged.

The compiler is ``$CHAPLYGIN_CC`` (a command, whose own flags come after
:data:`FLAGS` and so override them, e.g. ``"gcc -O0"``; ``none`` switches this
path off), else ``$CC``, else the first of ``cc``, ``gcc``, ``clang`` on
``PATH`` (POSIX only).  Where there is none, or it fails, or the model uses a function
that C's ``math.h`` does not have, :class:`Unavailable` says why and numba
compiles the Python ``fill`` as before.  Libraries are kept in the kernel cache
of :mod:`chaplygin.numeric._ckernel`: keyed by a hash of their C source and the
compiler command, built in a temporary directory, moved into place atomically
and verified (SHA-256 of their bytes) when loaded.  The ``c`` backend uses the
same libraries through :mod:`ctypes`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from sympy.printing.codeprinter import PrintMethodNotImplementedError

from chaplygin.numeric import _ckernel
from chaplygin.numeric._ckernel import FLAGS, Unavailable, compiler
from chaplygin.numeric._printing import code

if TYPE_CHECKING:
    from chaplygin.numeric.codegen import Target, _Fill

__all__ = ["FLAGS", "Unavailable", "body", "build", "compiler", "numba_fill", "source"]

_SOLVE = """
/* x = A^-1 b by Gaussian elimination with partial pivoting (A and b are overwritten);
   a singular A gives NaN, which the integrators report as a non-finite derivative. */
static void chaplygin_solve(int n, double *A, double *b, double *x)
{
    for (int c = 0; c < n; ++c) {
        int piv = c;
        for (int r = c + 1; r < n; ++r)
            if (fabs(A[r * n + c]) > fabs(A[piv * n + c])) piv = r;
        if (A[piv * n + c] == 0.0) {
            for (int i = 0; i < n; ++i) x[i] = NAN;
            return;
        }
        if (piv != c) {
            for (int j = 0; j < n; ++j) {
                double tmp = A[c * n + j]; A[c * n + j] = A[piv * n + j]; A[piv * n + j] = tmp;
            }
            double tmp = b[c]; b[c] = b[piv]; b[piv] = tmp;
        }
        for (int r = c + 1; r < n; ++r) {
            double f = A[r * n + c] / A[c * n + c];
            for (int j = c; j < n; ++j) A[r * n + j] -= f * A[c * n + j];
            b[r] -= f * b[c];
        }
    }
    for (int c = n - 1; c >= 0; --c) {
        double acc = b[c];
        for (int j = c + 1; j < n; ++j) acc -= A[c * n + j] * x[j];
        x[c] = acc / A[c * n + c];
    }
}
"""


def body(fill: _Fill, assigned: list[tuple[list, list[tuple[Target, Any]]]]) -> list[str]:
    """The statements of ``fill``'s C function (indented lines; also used by :mod:`chaplygin.io.export`).

    ``assigned`` is :func:`chaplygin.numeric.codegen._assignments` of each of
    ``fill.blocks()``.  Raises :class:`Unavailable` for a function C lacks.
    """
    lines = ["    (void)t; (void)y; (void)p;  /* a model need not use each */"]
    if fill.solve:
        g = fill.solve
        lines += [
            f"    double Ad[{g * g}] = {{0.0}};",
            f"    double b[{g}] = {{0.0}};",
            f"    double d[{g}];",
        ]
    try:
        for block, (replacements, stores) in zip(fill.blocks(), assigned):
            lines += [f"    const double {sym} = {code(e, 'c')};" for sym, e in replacements]
            lines += [f"    {name}[{i}] = {code(e, 'c')};" for (name, i, _), e in stores]
            if block is fill.pre:
                lines.append(f"    chaplygin_solve({fill.solve}, Ad, b, d);")
    except PrintMethodNotImplementedError as exc:
        raise Unavailable(f"C has no translation of a function in this model ({exc})") from None
    return lines


def source(fill: _Fill, assigned: list[tuple[list, list[tuple[Target, Any]]]], symbol: str) -> str:
    """The C translation unit defining ``void symbol(t, y, p, M, F, V, O)``.

    ``assigned`` is :func:`chaplygin.numeric.codegen._assignments` of each of
    ``fill.blocks()``.  Raises :class:`Unavailable` for a function C lacks.
    """
    statements = body(fill, assigned)
    signature = (
        f"void {symbol}(double t, const double *y, const double *p, "
        "double *M, double *F, double *V, double *O)"
    )
    return "\n".join(
        [
            "/* Generated by chaplygin: fill(t, y, p, M, F, V, O) of one model (see chaplygin.numeric.codegen). */",
            "#include <math.h>",
            _SOLVE if fill.solve else "",
            f"{signature}\n{{",
            *statements,
            "}",
            "",
        ]
    )


def build(fill: _Fill, assigned: list[tuple[list, list[tuple[Target, Any]]]]) -> tuple[str, str]:
    """Compile ``fill`` into the kernel cache (:func:`chaplygin.numeric._ckernel.library`); ``(symbol, library path)``.

    Raises :class:`Unavailable` when there is no compiler or it fails.
    """
    digest, library = _ckernel.library(source(fill, assigned, "chaplygin_fill_@DIGEST@"), "fill")
    return f"chaplygin_fill_{digest}", str(library)


def numba_fill(symbol: str, library: str) -> str:
    """Module source defining a jitted ``fill`` that calls ``symbol`` in ``library``."""
    return f'''from llvmlite import binding as _llvm
from numba import types as _nbt

_llvm.load_library_permanently({library!r})
_PTR = _nbt.CPointer(_nbt.float64)
_c_fill = _nbt.ExternalFunction({symbol!r}, _nbt.void(_nbt.float64, _PTR, _PTR, _PTR, _PTR, _PTR, _PTR))


@_jit
def fill(t, y, p, M, F, V, O):
    """M, F, V, O at (t, y, p), computed by the compiled C function {symbol}."""
    yc = np.ascontiguousarray(y)
    pc = np.ascontiguousarray(p)
    _c_fill(float(t), yc.ctypes, pc.ctypes, M.ctypes, F.ctypes, V.ctypes, O.ctypes)
'''
