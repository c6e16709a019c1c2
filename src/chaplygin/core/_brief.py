"""How much of an expression a summary prints: one rule for the terminal, ``str`` and reports.

A rolling body's defect or Frobenius component runs to pages; printed whole it buries the line
that carries the verdict.  Above :data:`MAX_BRIEF` characters a one-line mention shows the
expression's leading structure (:func:`chaplygin.core._fold.abbreviated`, the summary every
display folds a long expression into), its size and where the whole of it is kept instead.
"""

from __future__ import annotations

from collections.abc import Callable

import sympy as sp

from chaplygin.core._symbols import vsstrrepr

#: the longest expression a summary prints in full, in characters
MAX_BRIEF = 300


def brief(expr: sp.Expr | str, kept: str, printer: Callable[[sp.Basic], str] = vsstrrepr) -> str:
    """``expr`` as text, or, when longer than :data:`MAX_BRIEF`, its leading structure, its size
    and where ``kept`` it is.

    Parameters
    ----------
    expr : sympy.Expr or str
        The expression, or its text already printed (then only its size is told).
    kept : str
        Where the whole expression can be had, e.g. ``"--format json has it"``.
    printer : callable
        How the expression is printed (``vsstrrepr`` as ``str`` does, or the file syntax).
    """
    text = expr if isinstance(expr, str) else printer(expr)
    if len(text) <= MAX_BRIEF:
        return text
    if isinstance(expr, str):
        return f"an expression of {len(text)} characters, not printed ({kept})"
    from chaplygin.core._fold import abbreviated

    return f"{abbreviated(expr, printer)} ({len(text)} characters; {kept})"
