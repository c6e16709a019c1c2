"""Bad input gets a clear error that names the offending item."""

from __future__ import annotations

from pathlib import Path

import pytest
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols

from chaplygin import ModelError, System, SystemDefinitionError, examples, simulate

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
    """Constraints nonlinear in the velocities are read (issue 30); their solved form is the branch
    chosen, and one with several solutions for the dependent velocities needs the choice."""
    assert System([x, y, z], T, {d(z): d(x) ** 2}).is_nonlinear
    assert System([x, y, z], T, [d(z) - d(x) * d(y)], dependent=[z]).constraints == {d(z): d(x) * d(y)}
    msg = error([x, y, z], T, [d(z) ** 2 - d(x) ** 2], dependent=[z])
    assert "2 solutions for z'" in msg and "branch=0: z' = -x'" in msg and "branch=1: z' = x'" in msg


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


# ------------------------------------------------------------------ simulation inputs
KNIFE_P = {"m": 1.0, "J": 0.5}
KNIFE_0 = {"x": 0.0, "y": 0.0, "phi": 0.3, "x'": 1.0, "phi'": 0.2}


@pytest.fixture(scope="module")
def knife() -> System:
    return examples.knife_edge()


def refused(
    system: System, *, model: str = "chaplygin", t_end: float = 0.1, initial=None, parameters=None, **options
) -> str:
    """The InputError message of a simulation that must not start (nothing is integrated)."""
    from chaplygin import InputError

    with pytest.raises(InputError) as info:
        simulate(system, model, t_end, initial or KNIFE_0, parameters or KNIFE_P, samples=3, **options)
    return str(info.value)


@pytest.mark.parametrize("model", ["chaplygin", "chetaev"])
def test_negative_and_zero_inertia_are_refused(knife: System, model: str) -> None:
    msg = refused(knife, model=model, parameters={"m": -1.0, "J": 0.5})
    assert "not positive definite" in msg and "negative along x'" in msg and "m = -1" in msg
    msg = refused(knife, model=model, parameters={"m": 1.0, "J": 0.0})
    assert "singular" in msg and "along phi'" in msg and "J = 0" in msg


def test_ill_conditioned_mass_matrix_is_refused(knife: System) -> None:
    msg = refused(knife, parameters={"m": 1.0, "J": 1e-14})
    assert "condition number" in msg and "phi'" in msg
    # a large but honest ratio of inertias runs
    assert simulate(knife, "chaplygin", 0.1, KNIFE_0, {"m": 1.0, "J": 1e-6}, samples=3).success


@pytest.mark.parametrize("constraint", ["implicit", "solved"])
def test_start_on_a_pole_of_the_solved_constraints_is_refused(knife: System, constraint: str) -> None:
    import math

    if constraint == "solved":  # ẏ = tan φ ẋ as given by a user (form B)
        phi = dynamicsymbols("phi")
        m, J = sp.symbols("m J", positive=True)
        knife = System(
            [x, y, phi], m / 2 * (d(x) ** 2 + d(y) ** 2) + J / 2 * d(phi) ** 2, {d(y): sp.tan(phi) * d(x)}
        )
    msg = refused(knife, initial={**KNIFE_0, "phi": math.pi / 2})
    assert "pole of the solved constraints" in msg and "y'" in msg and "phi = 1.5708" in msg


@pytest.mark.parametrize(
    "key,value,named",
    [
        ("J", float("nan"), "parameters: J = nan"),
        ("m", float("inf"), "parameters: m = inf"),
    ],
)
def test_non_finite_parameters_are_refused(knife: System, key: str, value: float, named: str) -> None:
    assert named in refused(knife, parameters={**KNIFE_P, key: value})


@pytest.mark.parametrize("key", ["phi", "x'"])
def test_non_finite_initial_values_are_refused(knife: System, key: str) -> None:
    assert f"initial: {key} = inf is not finite" in refused(knife, initial={**KNIFE_0, key: float("inf")})


@pytest.mark.parametrize(
    "options,named",
    [
        ({"t_end": float("inf")}, "the end time = inf"),
        ({"t_end": float("nan")}, "the end time = nan"),
        ({"t_end": -1.0}, "must be after the start"),
        ({"samples": 1}, "samples = 1"),
        ({"samples": 10**7}, "samples = 10000000"),
        ({"samples": 2.5}, "samples = 2.5"),
        ({"rtol": 0.0}, "rtol = 0.0"),
        ({"rtol": float("nan")}, "rtol = nan"),
        ({"atol": -1.0}, "atol = -1.0"),
        ({"max_step": 0.0}, "max_step = 0.0"),
    ],
)
def test_run_options_are_checked(knife: System, options: dict, named: str) -> None:
    from chaplygin import InputError

    options = {"samples": 3, **options}
    t_end = options.pop("t_end", 0.1)
    with pytest.raises(InputError) as info:
        simulate(knife, "chaplygin", t_end, KNIFE_0, KNIFE_P, **options)
    assert named in str(info.value)


def test_a_parameter_that_makes_a_denominator_vanish_is_named(tmp_path: Path) -> None:
    """Review of issue 28: ``compare car_trailer.toml -p L=0`` said 'unexpected TypeError: Cannot
    convert complex to float' (1/L at the initial state); it names the state and the values now."""
    from typer.testing import CliRunner

    from chaplygin.apps import cli

    car = Path(__file__).resolve().parent.parent / "benchmarks" / "systems" / "car_trailer.toml"
    result = CliRunner().invoke(cli.app, ["compare", str(car), "-t", "1", "-p", "L=0"])
    assert result.exit_code == 1, result.output
    text = " ".join((result.stdout + result.stderr).split())
    assert "not finite at the initial state" in text and "L = 0" in text and "unexpected" not in text


def test_a_solved_constraint_that_is_not_an_expression_is_named_in_the_message() -> None:
    """The message names the constraint by its velocity as a system file writes it (the name is
    made only for a message: a valid system never prints one)."""
    x, y = dynamicsymbols("x y")
    tt = dynamicsymbols._t
    with pytest.raises(SystemDefinitionError, match=r"constraints\[y'\]: got the string \"x'\""):
        System([x, y], (x.diff(tt) ** 2 + y.diff(tt) ** 2) / 2, {y.diff(tt): "x'"})
