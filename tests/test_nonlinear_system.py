"""Validation of constraints nonlinear in the velocities (issue 30): what System reads, which
solution it takes, and what it refuses, each refusal a SystemDefinitionError naming the
constraint (or branch) and what would be accepted."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols

from chaplygin import System
from chaplygin.errors import SystemDefinitionError

t = dynamicsymbols._t
x, y, z, w = dynamicsymbols("x y z w")
d = lambda q: q.diff(t)  # noqa: E731
T3 = (d(x) ** 2 + d(y) ** 2 + d(z) ** 2) / 2
T4 = T3 + d(w) ** 2 / 2
k = sp.Symbol("k", positive=True)


def error(*args, **kwargs) -> str:
    with pytest.raises(SystemDefinitionError) as info:
        System(*args, **kwargs)
    return str(info.value)


# ------------------------------------------------------------------ branches
def test_several_solutions_need_a_branch_and_list_them() -> None:
    msg = error([x, y, z], T3, [d(z) ** 2 - k**2 * (d(x) ** 2 + d(y) ** 2)], dependent=[z])
    assert "2 solutions for z'" in msg and "choose one with branch=K" in msg
    assert "branch=0: z' = -k*sqrt(x'**2 + y'**2); branch=1: z' = k*sqrt(x'**2 + y'**2)." in msg
    s = System([x, y, z], T3, [d(z) ** 2 - k**2 * (d(x) ** 2 + d(y) ** 2)], dependent=[z], branch=1)
    assert s.constraints == {d(z): k * sp.sqrt(d(x) ** 2 + d(y) ** 2)} and not s.is_affine


def test_two_squared_constraints_have_the_analytic_branches() -> None:
    """Each constraint is solved in its own unknown: z' = ±(x' + y'), not ±√((x' + y')²) = ±|x' + y'|,
    which is no branch at all (a joint solve gave that: the branch matched the linear constraint
    on half the states only)."""
    f = [d(z) ** 2 - (d(x) + d(y)) ** 2, d(w) ** 2 - (d(x) - d(y)) ** 2]
    msg = error([x, y, z, w], T4, f, dependent=[z, w])
    assert "4 solutions for z', w'" in msg and "sqrt" not in msg
    s = System([x, y, z, w], T4, f, dependent=[z, w], branch=3)
    assert s.constraints == {d(z): d(x) + d(y), d(w): d(x) - d(y)}
    assert s.singular_set == [d(x) ** 2 - d(y) ** 2]  # where ∂f/∂(z', w') = 4 z' w' vanishes


def test_complex_solutions_are_not_branches() -> None:
    """z'³ = x'³ has one real solution; its two complex ones were listed as branches. Its branch
    point x' = 0 (∂f/∂z' = 3z'² = 0 there) is in the singular set though B = 1 has no pole."""
    s = System([x, y, z], T3, [d(z) ** 3 - d(x) ** 3], dependent=[z])
    assert s.constraints == {d(z): d(x)} and s.singular_set == [d(x)]


@pytest.mark.parametrize("branch", [np.int64(1), sp.Integer(1)])
def test_branch_accepts_integers_of_numpy_and_sympy(branch) -> None:
    s = System([x, y, z], T3, [d(z) ** 2 - d(x) ** 2], dependent=[z], branch=branch)
    assert s.constraints == {d(z): d(x)}


@pytest.mark.parametrize("branch", [2, -1, True, 1.0, "1"])
def test_bad_branch(branch) -> None:
    msg = error([x, y, z], T3, [d(z) ** 2 - d(x) ** 2], dependent=[z], branch=branch)
    assert msg.startswith(f"branch: expected an integer from 0 to 1, got {branch!r}")
    assert "branch=0: z' = -x'; branch=1: z' = x'" in msg


def test_branch_of_linear_or_solved_constraints() -> None:
    assert "linear in the velocities" in error([x, y, z], T3, [d(z) - d(x)], dependent=[z], branch=0)
    assert "given solved" in error([x, y, z], T3, {d(z): d(x) ** 2}, branch=0)


# ------------------------------------------------------------------ refusals
def test_roots_are_checked_real_without_generating_code(monkeypatch) -> None:
    """Whether a root in a constraint linear in the velocities is real somewhere is sampled by
    SymEngine's evaluator (no lambdify: 0.07 s of the rattleback's cold build), with the answers
    of test_a_root_real_nowhere_in_a_velocity_free_term."""
    from chaplygin.core import _sampling

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("lambdify was called")

    monkeypatch.setattr(_sampling, "compile_function", refuse)
    assert not System([x, y, z], T3, {d(z): d(x) + sp.sqrt(x - 100)}).is_nonlinear
    msg = error([x, y, z], T3, {d(z): d(x) + sp.sqrt(-(x**2) - 1)})
    assert msg.startswith("constraints[z'] = sqrt(-x**2 - 1) + x' is not real")
    msg = error([x, y, z], T3, [d(z) - d(x) + sp.sqrt(-(x**2) - 1)], dependent=[z])
    assert msg.startswith("constraints[0] = sqrt(-x**2 - 1) - x' + z' is not real")


def test_no_solution_sympy_finds() -> None:
    msg = error([x, y, z], T3, [sp.Abs(d(z)) + d(z) ** 3 - d(x)], dependent=[z])
    assert "SymPy cannot solve the implicit constraints for z'" in msg and "{z': expression" in msg


def test_no_real_solution() -> None:
    """z'² + x'² + 1 = 0 holds for no real velocities: refused, not read as z' = ±√(−x'² − 1)."""
    msg = error([x, y, z], T3, [d(z) ** 2 + d(x) ** 2 + 1], dependent=[z], branch=0)
    assert "no real solution for z'" in msg and "z' = sqrt(-x'**2 - 1)) are not real" in msg
    msg = error([x, y, z], T3, {d(z): sp.sqrt(-(d(x) ** 2) - 1)})
    assert msg.startswith("constraints[z'] = sqrt(-x'**2 - 1) is not real")
    # real only for |x'|, |y'| large: kept
    assert System([x, y, z], T3, {d(z): sp.sqrt(d(x) ** 2 + d(y) ** 2 - 100)}).is_nonlinear


def test_a_root_real_nowhere_in_a_velocity_free_term() -> None:
    """√(−x² − 1) is real nowhere: refused in a linear constraint too (solved or implicit), where
    it was read as a complex B₀; √(x − 100), real for x > 100, is kept."""
    msg = error([x, y, z], T3, {d(z): d(x) + sp.sqrt(-(x**2) - 1)})
    assert msg.startswith("constraints[z'] = sqrt(-x**2 - 1) + x' is not real")
    msg = error([x, y, z], T3, [d(z) - d(x) + sp.sqrt(-(x**2) - 1)], dependent=[z])
    assert msg.startswith("constraints[0] = sqrt(-x**2 - 1) - x' + z' is not real")
    assert not System([x, y, z], T3, {d(z): d(x) + sp.sqrt(x - 100)}).is_nonlinear


def test_a_solution_chaplygin_cannot_evaluate() -> None:
    msg = error([x, y, z], T3, [sp.exp(d(z)) + d(z) - d(x) ** 2], dependent=[z])
    assert msg.startswith("constraints: LambertW has no numerical evaluation in chaplygin")


def test_singular_block_on_the_constraint_manifold() -> None:
    msg = error([x, y, z], T3, [(d(x) - d(y)) ** 2], dependent=[x])
    assert msg.startswith("constraints[0]: ∂f/∂(x') is singular wherever the constraints hold")


def test_constraints_that_fix_no_dependent_velocity() -> None:
    msg = error([x, y, z], T3, [d(x) ** 2 + d(y) ** 2 - 1], dependent=[z])
    assert msg.startswith("constraints[0] contains none of the dependent velocities z'")
    msg = error([x, y, z], T3, [d(z) ** 2 - d(x) ** 2, x * d(x) ** 2], dependent=[z, y])
    assert msg.startswith("constraints[1] contains none of the dependent velocities z', y'")
    msg = error([x, y, z], T3, [d(z) ** 2 - d(x) ** 2, 2 * d(z) ** 2 - 2 * d(x) ** 2], dependent=[z, y])
    assert msg.startswith("constraints: ∂f/∂(z', y') is singular at every sampled state")


def test_a_velocity_free_constraint_among_nonlinear_ones() -> None:
    msg = error([x, y, z], T3, [d(z) ** 2 - d(x) ** 2, x**2 + y - 1], dependent=[z, y], branch=0)
    assert msg.startswith("constraints[1] contains no velocity: x**2 + y - 1") and "holonomic=" in msg


def test_solved_form_with_a_dependent_velocity() -> None:
    msg = error([x, y, z], T3, {d(z): d(x) ** 2 + d(z)})
    assert msg.startswith("constraints[z'] contains the dependent velocity z'")
    msg = error([x, y, z], T3, {d(z): sp.sqrt(d(x) ** 2 + d(y) ** 2), d(y): d(x) ** 2})
    assert msg.startswith("constraints[z'] contains the dependent velocity y'")


def test_solved_form_mixing_linear_and_nonlinear_rows() -> None:
    """A linear row beside a nonlinear one in the solved form (a TypeError before)."""
    s = System([x, y, z], T3, {d(z): d(x) ** 2, d(y): x * d(x) + 1})
    assert s.is_nonlinear and s.constraints == {d(z): d(x) ** 2, d(y): x * d(x) + 1}


def test_nonlinear_with_holonomic_constraints() -> None:
    msg = error([x, y, z], T3, [d(z) ** 2 - d(x) ** 2], dependent=[z], branch=1, holonomic={y: y - x})
    assert msg.startswith("holonomic: holonomic constraints beside constraints nonlinear in the velocities")


# ------------------------------------------------------------------ admissible states
def test_states_where_the_constraints_are_real_only_for_larger_velocities() -> None:
    """z' = √(x'² + y'² − 100) is real only where |(x', y')| > 10: the sampler draws larger
    velocities when those in (−1, 1) give none (it returned z' = NaN), and a constraint real
    nowhere it draws is an error, not a NaN state."""
    from chaplygin.core._sampling import StateSampler

    s = System([x, y, z], T3, {d(z): sp.sqrt(d(x) ** 2 + d(y) ** 2 - 100)})
    rng = np.random.default_rng(0)
    xd, yd, zd = (s._vars.xd[i] for i in range(3))
    for _ in range(3):
        state = StateSampler(s, {}).draw(rng)
        assert state[zd] ** 2 == pytest.approx(state[xd] ** 2 + state[yd] ** 2 - 100, rel=1e-12)
    far = System([x, y, z], T3, {d(z): d(x) ** 2 + sp.sqrt(x - 100)})  # real for x > 100 only
    with pytest.raises(SystemDefinitionError, match="has no admissible state at 100 random ones"):
        StateSampler(far, {}).draw(rng)
