"""The state layout of a model and the map from its symbols to the generated code's arrays.

Shared by every code generator (:mod:`chaplygin.numeric.codegen` and
:mod:`chaplygin.numeric.jaxbackend`): the state ``y`` holds the coordinates, the integrated
velocities (all of them for a multiplier model, the independent ones for a reduced model)
and the multipliers integrated with the state; ``p`` holds the parameters, then the
constants of the model.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import sympy as sp

from chaplygin.models import registry
from chaplygin.numeric._ckernel import Layout

if TYPE_CHECKING:
    from chaplygin.models.equations import Equations

__all__ = ["state_symbols"]


def state_symbols(eqs: Equations) -> tuple[Layout, dict[sp.Symbol, sp.Expr], list[sp.Expr], int]:
    """The layout, the map from internal symbols to ``y[i]``/``p[j]``, the full velocities, k."""
    s = eqs.system
    v = s._vars
    n = s.n
    y = sp.IndexedBase("y")
    p = sp.IndexedBase("p")
    names = [q.func.__name__ for q in s.coordinates]
    to_num: dict[sp.Symbol, sp.Expr] = {x: y[i] for i, x in enumerate(v.x)}
    multiplier_model = not registry.MODELS[eqs.model].reduced
    carried = list(range(n)) if multiplier_model else list(s._ind)
    for k, i in enumerate(carried):
        to_num[v.xd[i]] = y[n + k]
    mus = list(eqs._state)
    for b, mu in enumerate(mus):
        to_num[mu] = y[n + len(carried) + b]
    params = [*s.parameters, *eqs.constants]
    for j, par in enumerate(params):
        to_num[par] = p[j]
    if multiplier_model:
        velocities = [v.xd[i] for i in range(n)]
        k = n + len(mus)  # q̈ (and μ̇) come from the solve; λ are observed
    else:
        velocities = [s._velocity_substitution.get(v.xd[i], v.xd[i]) for i in range(n)]
        k = len(carried)
    layout = Layout(
        eqs.model,
        eqs.form,
        tuple(names),
        tuple(names[i] + "'" for i in carried),
        tuple(sp.sstr(eqs._user(m)).replace("(t)", "") for m in mus),
        tuple(par.name for par in params),
        tuple(sp.sstr(eqs._user(m)).replace("(t)", "") for m in eqs._multipliers if m not in mus),
    )
    return layout, to_num, velocities, k
