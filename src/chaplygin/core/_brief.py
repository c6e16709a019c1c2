"""How much of an expression a summary prints: one rule for the terminal, ``str`` and reports.

A rolling body's defect or Frobenius component runs to pages; printed whole it buries the line
that carries the verdict.  Above :data:`MAX_BRIEF` characters a summary names the expression's
size and where the whole of it is kept instead.
"""

from __future__ import annotations

import sympy as sp
from sympy.physics.vector.printing import vsstrrepr

#: the longest expression a summary prints in full, in characters
MAX_BRIEF = 300


def brief(expr: sp.Expr | str, kept: str) -> str:
    """``expr`` as text, or, when longer than :data:`MAX_BRIEF`, its size and where ``kept`` it is.

    Parameters
    ----------
    expr : sympy.Expr or str
        The expression, or its text already printed.
    kept : str
        Where the whole expression can be had, e.g. ``"--format json has it"``.
    """
    text = expr if isinstance(expr, str) else vsstrrepr(expr)
    if len(text) <= MAX_BRIEF:
        return text
    return f"an expression of {len(text)} characters, not printed ({kept})"
