"""Issue 30, the outside review's findings: each test failed on addde7f."""

from __future__ import annotations

import pytest
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols

from chaplygin import System, examples, simulate
from chaplygin.analysis.transitions import compare_models
from chaplygin.errors import SystemDefinitionError

t = sp.Symbol("t")
x, y, z, th = dynamicsymbols("x y z th")
m, k, c, b, J = sp.symbols("m k c b J", positive=True)
d = lambda q: q.diff(t)  # noqa: E731
POINT = m / 2 * (d(x) ** 2 + d(y) ** 2 + d(z) ** 2)


def test_compare_models_decides_a_root_it_cannot_normalise() -> None:
    """A sleigh whose nonlinear constraint SymPy solves by the quadratic formula: the Lindelöf
    defect under a root hung `vanishes` in its normal form (`chaplygin check` ran > 11 min); a
    50-digit value at a random point decides it is not zero."""
    T = (
        m / 2 * (d(x) ** 2 + d(y) ** 2)
        + J / 2 * d(th) ** 2
        + m * b * d(th) * (sp.cos(th) * d(y) - sp.sin(th) * d(x))
    )
    lateral = -sp.sin(th) * d(x) + sp.cos(th) * d(y)
    forward = sp.cos(th) * d(x) + sp.sin(th) * d(y)
    sleigh = System([x, y, th], T, [lateral - c * forward**2], dependent=[y], branch=0, name="sleigh")
    found = compare_models(sleigh)
    assert not found.coincide and not found.defect_vanishes
    assert all(e != 0 for e in found.defect.values())


def test_runs_stop_where_they_leave_the_branch_or_sit_on_the_singular_set() -> None:
    """Appell's weight rising (ż = +k v) reaches v = 0 at t* = v0 (1 + k²)/(g k) = 0.2548: the
    Chetaev run went on 'successfully' on the other branch (ż < 0), the vakonomic one froze at
    v ≈ 1e-8 with μ → −4e8, both reported as success."""
    s = examples.appell_weight(rising=True)
    start = {"x": 0, "y": 0, "z": 0, "x'": 0.6, "y'": 0.8}
    params = {"m": 1, "g": 9.81, "k": 0.5}
    t_star = 1.0 * (1 + 0.25) / (9.81 * 0.5)
    runs = {
        model: simulate(s, model, 1.0, start, params, samples=101, backend="numpy")
        for model in ("chetaev", "vakonomic")
    }
    for model, tr in runs.items():
        assert tr.status == "failed" and tr.failure == "branch", model
        assert t_star - 0.02 < tr.t[-1] + 0.01 and tr.t[-1] <= t_star + 0.02, (model, tr.t[-1])
        assert "x'**2 + y'**2 = 0" in tr.message
    assert "left the solved form" in runs["chetaev"].message


def test_singular_set_has_the_configuration_factors() -> None:
    """ż² = k²(x − 1)²(ẋ² + ẏ²): ∂f/∂ż = 2ż vanishes where x = 1 as well as where ẋ = ẏ = 0."""
    s = System(
        [x, y, z], POINT, [d(z) ** 2 - k**2 * (x - 1) ** 2 * (d(x) ** 2 + d(y) ** 2)], dependent=[z], branch=0
    )
    found = {sp.factor(e) for e in s.singular_set}
    assert x - 1 in found and d(x) ** 2 + d(y) ** 2 in found


@pytest.mark.parametrize(
    "constraints",
    [{d(z): k * sp.sign(d(x)) * d(x) ** 2}, [d(z) - k * sp.Abs(d(x))]],
)
def test_a_kink_in_the_velocities_is_refused(constraints) -> None:
    """abs and sign of a velocity: simulate crashed generating code for DiracDelta."""
    with pytest.raises(SystemDefinitionError, match="not differentiable where its argument vanishes"):
        System([x, y, z], POINT, constraints, dependent=None if isinstance(constraints, dict) else [z])
