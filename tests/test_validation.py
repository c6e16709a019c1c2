"""Bad input gets a clear error that names the offending item."""

from __future__ import annotations

import pytest
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols

from chaplygin import ModelError, System, SystemDefinitionError, examples

t = dynamicsymbols._t
x, y, z = dynamicsymbols("x y z")
d = lambda q: q.diff(t)  # noqa: E731
T = (d(x) ** 2 + d(y) ** 2 + d(z) ** 2) / 2


def error(*args, **kwargs) -> str:
    with pytest.raises(SystemDefinitionError) as info:
        System(*args, **kwargs)
    return str(info.value)


def test_plain_symbol_coordinate() -> None:
    msg = error([sp.Symbol("x"), y, z], T, {d(z): d(y)})
    assert "dynamicsymbols('x')" in msg


def test_duplicate_coordinate() -> None:
    assert "x is listed more than once" in error([x, x, z], T, {d(z): d(x)})


def test_kinetic_energy_not_quadratic() -> None:
    assert "not quadratic" in error([x, y, z], T + d(x) ** 3, {d(z): d(y)})
    assert "not quadratic" in error([x, y, z], sp.sqrt(1 + d(x) ** 2), {d(z): d(y)})
    assert "no term quadratic" in error([x, y, z], x * d(y), {d(z): d(y)})


def test_string_is_refused() -> None:
    assert "string" in error([x, y, z], "x'**2", {d(z): d(y)})


def test_nonlinear_constraint() -> None:
    msg = error([x, y, z], T, {d(z): d(x) ** 2})
    assert "constraints[z']" in msg and "not linear" in msg
    assert "not linear" in error([x, y, z], T, [d(z) - d(x) * d(y)], dependent=[z])


def test_dependent_velocity_on_right_side() -> None:
    msg = error([x, y, z], T, {d(z): d(y), d(y): d(z) + d(x)})
    assert "dependent velocity" in msg


def test_form_a_needs_dependent_and_matching_counts() -> None:
    assert "dependent=[...]" in error([x, y, z], T, [d(z) - x * d(y)])
    assert "1 coordinate(s) but there are 2" in error(
        [x, y, z], T, [d(z) - x * d(y), d(x) - d(y)], dependent=[z]
    )
    assert "fewer constraints than coordinates" in error(
        [x, y], (d(x) ** 2 + d(y) ** 2) / 2, [d(x), d(y)], dependent=[x, y]
    )


def test_unknown_function_of_time() -> None:
    f = dynamicsymbols("f")
    msg = error([x, y, z], T + f * d(x) ** 2, {d(z): d(y)})
    assert "unknown function f(t)" in msg and "x, y, z" in msg


def test_second_derivative_in_input() -> None:
    assert "second or higher derivative" in error([x, y, z], T, {d(z): d(y) + x.diff(t, 2)})


def test_singular_dependent_block_suggests_other_choice() -> None:
    msg = error([x, y, z], T, [d(x) + d(y)], dependent=[z])
    assert "dependent=[z]" in msg and "dependent=[x]" in msg


def test_redundant_constraints() -> None:
    msg = error([x, y, z], T, [d(x) - d(z), 2 * d(x) - 2 * d(z)], dependent=[y, z])
    assert "not independent" in msg


def test_degenerate_reduced_mass_matrix() -> None:
    msg = error([x, y, z], d(z) ** 2 / 2, {d(z): x * d(y)})
    assert "singular" in msg and "x, y" in msg


def test_degenerate_but_admissible_heisenberg() -> None:
    """T may be degenerate in the dependent velocity: only C^T M C must be invertible."""
    s = System([x, y, z], (d(x) ** 2 + d(y) ** 2) / 2, {d(z): (x * d(y) - y * d(x)) / 2})
    assert s.epsilon == 2


def test_potential_and_force_function_together() -> None:
    assert "not both" in error([x, y, z], T, {d(z): d(y)}, potential_energy=x, force_function=y)


def test_velocity_dependent_potential() -> None:
    assert "forces={...}" in error([x, y, z], T, {d(z): d(y)}, potential_energy=d(x) ** 2)


def test_force_on_unknown_coordinate() -> None:
    msg = error([x, y, z], T, {d(z): d(y)}, forces={"w": 1})
    assert "forces: 'w' is not one of the coordinates x, y, z" in msg


def test_constraint_key_is_coordinate() -> None:
    assert "dependent velocities such as" in error([x, y, z], T, {z: d(y)})


def test_model_errors() -> None:
    s = System([x, y, z], T, {d(z): z * d(y)})
    assert not s.is_chaplygin
    with pytest.raises(ModelError, match="voronets"):
        s.equations("chaplygin")
    with pytest.raises(ModelError, match="unknown model 'lagrange'"):
        s.equations("lagrange")
    with pytest.raises(ModelError, match="no form 'new'"):
        s.equations("chetaev", "new")
    with pytest.raises(ModelError, match="equations\\('chetaev'\\)"):
        s.equations("voronets").constraint_forces()


def test_parameter_lookup() -> None:
    sphere = examples.rolling_sphere()
    assert sphere.parameter("a") == sp.Symbol("a", positive=True)
    with pytest.raises(SystemDefinitionError, match="the parameters are a, m"):
        sphere.parameter("g")
