"""Private numeric sampling: random admissible states of a system.

Used for checks that are cheaper numerically than symbolically (is a matrix
singular *everywhere*?) and by the equivalence checker.  Nothing in the
symbolic model depends on this module.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import sympy as sp

from chaplygin.core._symbols import TIME

if TYPE_CHECKING:
    from chaplygin.core.system import System

COORDINATE_RANGE = (0.3, 1.3)
VELOCITY_RANGE = (-1.0, 1.0)
PARAMETER_RANGE = (0.5, 1.5)


def compile_function(exprs: Any, args: Sequence[sp.Symbol]) -> Callable[..., Any]:
    """``lambdify`` with common-subexpression elimination, NumPy semantics."""
    return sp.lambdify(list(args), exprs, modules="numpy", cse=True)


def parameter_values(
    system: System, rng: np.random.Generator, given: Mapping[Any, float] | None = None
) -> dict[sp.Symbol, float]:
    """Random positive values for every parameter, overridden by ``given``."""
    values = {p: float(rng.uniform(*PARAMETER_RANGE)) for p in system.parameters}
    for key, value in (given or {}).items():
        values[system.parameter(key)] = float(value)
    return values


class StateSampler:
    """Draws random states ``(t, q, q̇)`` that satisfy the velocity constraints."""

    def __init__(self, system: System, parameters: Mapping[sp.Symbol, float]) -> None:
        self.system = system
        self.parameters = dict(parameters)
        v = system._vars
        b_args = [TIME, *v.x, *self.parameters]
        self._b = compile_function(system._B, b_args)
        self._b0 = compile_function(system._B0, b_args)

    def draw(self, rng: np.random.Generator) -> dict[sp.Symbol, float]:
        """One random admissible state as a map from internal symbols to numbers."""
        s, v = self.system, self.system._vars
        t = float(rng.uniform(*COORDINATE_RANGE))
        q = rng.uniform(*COORDINATE_RANGE, size=s.n)
        qd = np.zeros(s.n)
        qd[list(s._ind)] = rng.uniform(*VELOCITY_RANGE, size=len(s._ind))
        if s.g:
            args = (t, *q, *self.parameters.values())
            b = np.asarray(self._b(*args), dtype=float).reshape(s.g, len(s._ind))
            b0 = np.asarray(self._b0(*args), dtype=float).reshape(s.g)
            qd[list(s._dep)] = b @ qd[list(s._ind)] + b0
        state: dict[sp.Symbol, float] = {TIME: t}
        state.update(zip(v.x, q.tolist()))
        state.update(zip(v.xd, qd.tolist()))
        state.update(self.parameters)
        return state


def vanishes(expr: sp.Expr, *, samples: int = 8, seed: int = 28) -> bool:
    """Decide whether ``expr`` is identically zero.

    Cheap symbolic normalisation first; then evaluation at random points of
    every free symbol (a single clearly non-zero value settles it).  When all
    finite samples vanish the expression is taken as zero — a non-zero
    analytic expression vanishes at random points with probability nil.  Only
    when no sample is finite does a full ``simplify`` decide.
    """
    expr = sp.cancel(sp.expand(expr))
    if expr == 0:
        return True
    symbols = sorted(expr.free_symbols, key=str)
    rng = np.random.default_rng(seed)
    f = compile_function(expr, symbols)
    finite = 0
    for _ in range(samples):
        with np.errstate(all="ignore"):
            value = complex(f(*rng.uniform(*COORDINATE_RANGE, size=len(symbols))))
        if np.isfinite(value):
            if abs(value) > 1e-9:
                return False
            finite += 1
    return finite > 0 or sp.simplify(expr) == 0
