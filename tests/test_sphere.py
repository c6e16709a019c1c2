"""The seed paper's §4 example: a homogeneous sphere rolling on a rough horizontal plane.

Expected values are typed from the paper (eqs. (43), (48)) and from known physics,
never produced by chaplygin.
"""

from __future__ import annotations

import pytest
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols

from chaplygin import equivalent, examples

t = dynamicsymbols._t
psi, theta, phi, x, y = dynamicsymbols("psi theta phi x y")
m, a = sp.symbols("m a", positive=True)
d = lambda q: q.diff(t)  # noqa: E731


@pytest.fixture(scope="module")
def sphere():
    return examples.rolling_sphere()


def test_constraint_coefficients_are_eq_43(sphere) -> None:
    assert sphere.independent == (psi, theta, phi)
    assert sphere.dependent == (x, y)
    expected = sp.Matrix(
        [
            [0, a * sp.sin(psi), -a * sp.sin(theta) * sp.cos(psi)],
            [0, -a * sp.cos(psi), -a * sp.sin(theta) * sp.sin(psi)],
        ]
    )
    assert sp.simplify(sphere.B - expected) == sp.zeros(2, 3)
    assert sphere.B0 == sp.zeros(2, 1)
    assert sphere.is_chaplygin and not sphere.is_affine and sphere.is_scleronomic


def test_reduced_kinetic_energy_is_eq_48(sphere) -> None:
    eq48 = (
        m
        * a**2
        / 2
        * (
            sp.Rational(7, 5) * d(theta) ** 2
            + d(phi) ** 2 * sp.sin(theta) ** 2
            + sp.Rational(2, 5) * (d(phi) ** 2 + d(psi) ** 2 + 2 * d(psi) * d(phi) * sp.cos(theta))
        )
    )
    assert sp.simplify(sphere.reduced_kinetic_energy - eq48) == 0


@pytest.mark.parametrize("form", ["classic", "new"])
def test_chaplygin_forms_agree_with_chetaev(sphere, form: str) -> None:
    chaplygin = sphere.equations("chaplygin", form)
    chetaev = sphere.equations("chetaev")
    assert equivalent(sphere, chaplygin, chetaev)
    numeric = equivalent(sphere, chaplygin, chetaev, symbolic=False)
    assert numeric.method == "numeric" and numeric.max_residual < 1e-12


def angular_velocity():
    """Space components of ω for z-x-z Euler angles (ψ precession, θ nutation, φ spin)."""
    return sp.Matrix(
        [
            d(theta) * sp.cos(psi) + d(phi) * sp.sin(theta) * sp.sin(psi),
            d(theta) * sp.sin(psi) - d(phi) * sp.sin(theta) * sp.cos(psi),
            d(psi) + d(phi) * sp.cos(theta),
        ]
    )


def test_rolling_constraint_is_v_equals_omega_cross_r() -> None:
    """Contact point at rest: v_centre = ω × (a e_z) = a (ω_y, −ω_x, 0)."""
    w = angular_velocity()
    sphere = examples.rolling_sphere()
    assert sp.simplify(sphere.constraints[d(x)] - a * w[1]) == 0
    assert sp.simplify(sphere.constraints[d(y)] + a * w[0]) == 0


@pytest.mark.parametrize(
    "model,form",
    [("chetaev", "classic"), ("chaplygin", "classic"), ("chaplygin", "new"), ("voronets", "classic")],
)
def test_angular_velocity_is_constant(sphere, model: str, form: str) -> None:
    """A free homogeneous sphere rolling on a plane keeps ω constant (Routh 1905, §243)."""
    acc = sphere.equations(model, form).accelerations
    w_dot = angular_velocity().diff(t).xreplace(acc)
    assert sp.simplify(w_dot) == sp.zeros(3, 1)


def test_centre_moves_uniformly_and_reactions_vanish(sphere) -> None:
    acc = sphere.equations("chetaev").accelerations
    assert sp.simplify(acc[x.diff(t, 2)]) == 0
    assert sp.simplify(acc[y.diff(t, 2)]) == 0
    lam = sphere.equations("chetaev").multipliers
    assert all(sp.simplify(acc[l]) == 0 for l in lam)


def test_horizontal_force_accelerates_centre_by_five_sevenths() -> None:
    """Force F on the centre of a rolling sphere: ẍ = F / (m + I/a²) = 5F/(7m)."""
    F = sp.Symbol("F")
    pushed = examples.rolling_sphere(forces={"x": F})
    acc = pushed.equations("chetaev").accelerations
    assert sp.simplify(acc[x.diff(t, 2)] - 5 * F / (7 * m)) == 0
    assert sp.simplify(acc[y.diff(t, 2)]) == 0
    for form in ("classic", "new"):
        assert equivalent(pushed, pushed.equations("chaplygin", form), pushed.equations("chetaev"))


def test_constraint_forces_and_virtual_work(sphere) -> None:
    eqs = sphere.equations("chetaev")
    l1, l2 = eqs.multipliers
    R = eqs.constraint_forces()
    assert R[x] == l1 and R[y] == l2
    assert sp.simplify(R[theta] - (-a * sp.sin(psi) * l1 + a * sp.cos(psi) * l2)) == 0
    assert eqs.virtual_work() == 0  # eq. (9) under Chetaev's condition (4)
    assert eqs.virtual_work(chetaev_condition=False) != 0


def test_equations_print(sphere) -> None:
    text = str(sphere.equations("chaplygin"))
    assert "eq. (15)" in text and "theta''" in text
    assert "eq. (40)" in sphere.equations("chaplygin", "new").pretty()
    assert sphere.equations("chetaev")._repr_latex_().startswith("$")
