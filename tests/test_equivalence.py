"""The equivalence checker on hand-written equations (the way users check derivations)."""

from __future__ import annotations

import pytest
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols

from chaplygin import ChaplyginError, equivalent, examples

t = dynamicsymbols._t
psi, theta, phi, x, y = dynamicsymbols("psi theta phi x y")
d = lambda q: q.diff(t)  # noqa: E731


@pytest.fixture(scope="module")
def sphere():
    return examples.rolling_sphere()


def lagrange(L: sp.Expr, q: sp.Expr) -> sp.Expr:
    return sp.diff(sp.diff(L, d(q)), t) - sp.diff(L, q)


def test_lindelofs_error_is_caught(sphere) -> None:
    """Constraints substituted into T before Lagrange's equations: not the true motion."""
    wrong = [lagrange(sphere.reduced_kinetic_energy, q) for q in sphere.independent]
    report = equivalent(sphere, wrong, sphere.equations("chetaev"))
    assert not report
    assert report.max_residual > 1e-2 and report.worst["acceleration"]
    assert "NOT equivalent" in str(report)


def test_hand_written_multiplier_equations(sphere) -> None:
    """The paper's (6a)-(6b) typed by hand, with λ(t): the same dynamics as Chaplygin's (15)."""
    lam1, lam2 = dynamicsymbols("lambda1 lambda2")
    T = sphere.kinetic_energy
    B = sphere.B
    eqs = [lagrange(T, q) + lam1 * B[0, k] + lam2 * B[1, k] for k, q in enumerate(sphere.independent)]
    eqs += [sp.Eq(sp.diff(sp.diff(T, d(x)), t), lam1), sp.Eq(sp.diff(sp.diff(T, d(y)), t), lam2)]
    assert equivalent(sphere, eqs, sphere.equations("chaplygin"))


def test_known_accelerations_of_the_free_sphere(sphere) -> None:
    """Constant ω in z-x-z Euler angles (free rigid body with spherical inertia)."""
    known = {
        psi.diff(t, 2): d(theta) * (d(phi) - d(psi) * sp.cos(theta)) / sp.sin(theta),
        theta.diff(t, 2): -d(phi) * d(psi) * sp.sin(theta),
        phi.diff(t, 2): d(theta) * (d(psi) - d(phi) * sp.cos(theta)) / sp.sin(theta),
    }
    assert equivalent(sphere, known, sphere.equations("chetaev"))
    known[theta.diff(t, 2)] *= 1.001
    report = equivalent(sphere, known, sphere.equations("chetaev"))
    assert not report and 1e-4 < report.max_residual < 1e-2


def test_parameters_can_be_fixed(sphere) -> None:
    report = equivalent(
        sphere, sphere.equations("chaplygin"), sphere.equations("chetaev"), parameters={"a": 2.0, "m": 3.0}
    )
    assert report.method == "numeric" and report


def test_bad_inputs(sphere) -> None:
    with pytest.raises(ChaplyginError, match="not linear"):
        equivalent(
            sphere, [psi.diff(t, 2) ** 2, theta.diff(t, 2), phi.diff(t, 2)], sphere.equations("chetaev")
        )
    with pytest.raises(ChaplyginError, match="unknown symbol"):
        equivalent(
            sphere,
            [psi.diff(t, 2) - sp.Symbol("g"), theta.diff(t, 2), phi.diff(t, 2)],
            sphere.equations("chetaev"),
        )
    with pytest.raises(ChaplyginError, match="do not determine"):
        equivalent(sphere, [psi.diff(t, 2)], sphere.equations("chetaev"))
    with pytest.raises(ChaplyginError, match="another system"):
        equivalent(sphere, examples.rolling_sphere().equations("chetaev"), sphere.equations("chetaev"))
    with pytest.raises(ChaplyginError, match="expected an Equations object"):
        equivalent(sphere, "psi'' = 0", sphere.equations("chetaev"))
