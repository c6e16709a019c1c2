"""Holonomic constraints ``f(q, t) = 0`` beside the velocity constraints (issue 29, item 1).

Ground truth: a closed form (the pendulum), the same systems with the holonomic coordinate
eliminated by hand (substituted into T and U, derived independently), and the Chetaev model
for the vakonomic one (a holonomic constraint acts in both alike: its multiplier enters only
through μ̇, since ∂ḟ/∂q_s = d/dt ∂f/∂q_s).
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols

from chaplygin import System
from chaplygin.errors import SystemDefinitionError
from chaplygin.numeric._modelcache import definition
from randomsystems import matrix, t

x, y, z, phi, th = dynamicsymbols("x y z phi theta")
m, g, J, a, l, w, c = sp.symbols("m g J a l omega c", positive=True)


def d(q: sp.Expr) -> sp.Expr:
    return q.diff(t)


def solution(eqs, values: dict) -> dict:
    """``M·x = F`` of ``eqs`` solved with NumPy at ``values`` (unknowns → numbers)."""
    sol = np.linalg.solve(matrix(eqs.mass_matrix, values), matrix(eqs.forcing, values)[:, 0])
    return dict(zip(eqs.unknowns, sol))


def knife_constraint(form: str) -> dict:
    """The knife edge's constraint in form B (ẏ = tan φ ẋ) or A (sin φ ẋ − cos φ ẏ = 0)."""
    if form == "B":
        return {"constraints": {d(y): sp.tan(phi) * d(x)}}
    return {"constraints": [sp.sin(phi) * d(x) - sp.cos(phi) * d(y)], "dependent": [y]}


def knife_on_surface(form: str) -> System:
    """A knife edge (x, y, heading phi) on the surface z = a sin(x) under gravity."""
    T = m / 2 * (d(x) ** 2 + d(y) ** 2 + d(z) ** 2) + J / 2 * d(phi) ** 2
    return System(
        [x, y, phi, z],
        T,
        **knife_constraint(form),
        potential_energy=m * g * z,
        holonomic={z: z - a * sp.sin(x)},
    )


def knife_eliminated(form: str) -> System:
    """The same knife edge with z = a sin(x) substituted by hand."""
    zdot = a * sp.cos(x) * d(x)
    T = m / 2 * (d(x) ** 2 + d(y) ** 2 + zdot**2) + J / 2 * d(phi) ** 2
    return System([x, y, phi], T, **knife_constraint(form), potential_energy=m * g * a * sp.sin(x))


def knife_state(rng: np.random.Generator) -> dict:
    """A random admissible state of the knife edge: on the surface, velocities that satisfy both."""
    v = {p: sp.Float(rng.uniform(0.5, 1.5)) for p in (m, g, J, a)}
    v[t] = sp.Float(rng.uniform(0, 1))
    for q in (x, y, phi):
        v[q] = sp.Float(rng.uniform(-1.2, 1.2))
    v[z] = v[a] * sp.sin(v[x])
    v[d(x)], v[d(phi)] = (sp.Float(rng.uniform(-1, 1)) for _ in range(2))
    v[d(y)] = sp.tan(v[phi]) * v[d(x)]
    v[d(z)] = v[a] * sp.cos(v[x]) * v[d(x)]
    return v


# ------------------------------------------------------------------ the definition
@pytest.mark.parametrize(
    ("holonomic", "message"),
    [
        ({d(z): z}, "holonomic: z' is not one of the coordinates"),
        ({sp.Symbol("r"): z}, "holonomic: r is not one of the coordinates"),
        ({y: y - x}, "holonomic[y]: y is a dependent coordinate of the velocity constraints"),
        ({z: z - d(x)}, "holonomic[z] = z - x' contains velocities"),
        ({z: x**2 - a}, "holonomic[z] = -a + x**2 does not depend on z"),
        ({z: "z - a*sin(x)"}, "holonomic[z]: got the string 'z - a*sin(x)'"),
        ([z - x], "holonomic: expected a mapping {coordinate: f(q, t)}"),
    ],
)
def test_bad_relations_are_named(holonomic: object, message: str) -> None:
    T = m / 2 * (d(x) ** 2 + d(y) ** 2 + d(z) ** 2)
    with pytest.raises(SystemDefinitionError) as err:
        System([x, y, z], T, {d(y): x * d(x)}, holonomic=holonomic)  # type: ignore[arg-type]
    assert message in str(err.value)


def test_relations_are_the_last_velocity_constraints() -> None:
    """ḟ = Σ ∂f/∂q_s q̇_s + ∂f/∂t is the last row of A/A_0, its coordinate the last dependent,
    in form A and in form B; a parameter only f contains is a parameter."""
    f = z - a * sp.sin(x - w * t) - c
    T = m / 2 * (d(x) ** 2 + d(y) ** 2 + d(z) ** 2)
    for cons, dep in (({d(y): x * d(x)}, None), ([d(y) - x * d(x)], [y])):
        s = System([x, y, z], T, cons, dependent=dep, holonomic={z: sp.Eq(z, a * sp.sin(x - w * t) + c)})
        assert (s.g, s.velocity_g, s.dependent, s.independent) == (2, 1, (y, z), (x,))
        assert s.holonomic == {z: f}
        assert s._holonomic == ((2, f.xreplace(s._to_sym)),)
        assert sp.simplify(s.A.row(1) - sp.Matrix([[-a * sp.cos(x - w * t), 0, 1]])) == sp.zeros(1, 3)
        assert sp.simplify(s.A0[1] - a * w * sp.cos(x - w * t)) == 0
        assert c in s.parameters  # (in f only: its derivative has no c)
        assert (
            sp.simplify(s.constraints[d(z)] - (a * sp.cos(x - w * t) * d(x) - a * w * sp.cos(x - w * t))) == 0
        )
    alone = System([x, z], m / 2 * (d(x) ** 2 + d(z) ** 2), [], holonomic={"z": z - x**2})
    assert (alone.g, alone.dependent, alone.constraint_form) == (1, (z,), "A")


def test_every_description_shows_the_relations() -> None:
    s = knife_on_surface("B")
    assert "z: -a*sin(x) + z = 0" in repr(s)
    assert "holonomic constraints" in s._repr_html_()
    other = System(
        [x, y, phi, z],
        s.kinetic_energy,
        {d(y): sp.tan(phi) * d(x)},
        potential_energy=m * g * z,
        holonomic={z: z - a * sp.cos(x)},
    )
    assert definition(s) != definition(other)  # compiled models are not shared
    assert definition(s) == definition(knife_on_surface("B"))


def test_float_relations_are_exact_inside() -> None:
    s = System([x, z], m / 2 * (d(x) ** 2 + d(z) ** 2), [], holonomic={z: z - 0.1 * x})
    assert s._holonomic[0][1].xreplace(s._to_fun) == z - x / 10
    assert s.A == sp.Matrix([[-0.1, 1]])


# ------------------------------------------------------------------ the models
def test_chetaev_pendulum_against_its_closed_form() -> None:
    """A pendulum written in (x, y) with x² + y² − l² = 0 moves as θ̈ = −(g/l) sin θ."""
    s = System(
        [x, y],
        m / 2 * (d(x) ** 2 + d(y) ** 2),
        [],
        potential_energy=m * g * y,
        holonomic={y: x**2 + y**2 - l**2},
    )
    eqs = s.equations("chetaev")
    rng = np.random.default_rng(1)
    for _ in range(4):
        ang, rate = rng.uniform(-1.2, 1.2), rng.uniform(-2, 2)
        vals = {m: 1.3, g: 9.81, l: 0.7}
        acc = -vals[g] / vals[l] * np.sin(ang)
        v = {sp.Symbol(k.name, positive=True): sp.Float(val) for k, val in vals.items()}
        v.update({t: sp.Float(0), x: l * sp.sin(ang), y: -l * sp.cos(ang)})
        v.update({d(x): l * sp.cos(ang) * rate, d(y): l * sp.sin(ang) * rate})
        v = {k: sp.Float(sp.sympify(e).xreplace({l: vals[l]})) for k, e in v.items()}
        got = solution(eqs, v)
        L = vals[l]
        assert got[x.diff(t, 2)] == pytest.approx(L * np.cos(ang) * acc - L * np.sin(ang) * rate**2)
        assert got[y.diff(t, 2)] == pytest.approx(L * np.sin(ang) * acc + L * np.cos(ang) * rate**2)


def test_vakonomic_equals_chetaev_with_only_holonomic_constraints() -> None:
    """Random admissible states, random μ: the vakonomic accelerations are Chetaev's
    (a rheonomic relation and a kinetic energy with a velocity product)."""
    T = m / 2 * (d(x) ** 2 + d(y) ** 2 + d(z) ** 2) + a * x * d(x) * d(y)
    s = System([x, y, z], T, [], potential_energy=g * z, holonomic={z: z - a * sp.sin(x) * sp.cos(y - w * t)})
    chetaev, vakonomic = s.equations("chetaev"), s.equations("vakonomic")
    rng = np.random.default_rng(2)
    for _ in range(4):
        v = {p: sp.Float(rng.uniform(0.5, 1.5)) for p in s.parameters}
        v.update({t: sp.Float(rng.uniform(0, 1)), **{q: sp.Float(rng.uniform(-1, 1)) for q in (x, y, z)}})
        v.update({d(q): sp.Float(rng.uniform(-1, 1)) for q in (x, y)})
        v[d(z)] = s.constraints[d(z)].xreplace(v)
        v.update({mu: sp.Float(rng.uniform(-3, 3)) for mu in vakonomic.multipliers})
        want, got = solution(chetaev, v), solution(vakonomic, v)
        for q in (x, y, z):
            assert got[q.diff(t, 2)] == pytest.approx(want[q.diff(t, 2)], rel=1e-10, abs=1e-12)


@pytest.mark.parametrize("form", ["A", "B"])
def test_mixed_system_moves_as_the_one_eliminated_by_hand(form: str) -> None:
    """The knife edge on z = a sin(x): Chetaev and vakonomic accelerations (and μ̇ of the
    rolling constraint) equal those of the knife edge with z substituted, at random admissible
    states with random μ; the multiplier of the relation does not enter."""
    full, eliminated = knife_on_surface(form), knife_eliminated(form)
    rng = np.random.default_rng(3)
    for model in ("chetaev", "vakonomic"):
        eqs_full, eqs_elim = full.equations(model), eliminated.equations(model)
        for _ in range(3):
            v = knife_state(rng)
            mus = [sp.Float(rng.uniform(-3, 3)) for _ in range(2)]
            v.update(zip(eqs_full.multipliers, mus))
            v.update(zip(eqs_elim.multipliers, mus[:1]))
            got, want = solution(eqs_full, v), solution(eqs_elim, v)
            for q in (x, y, phi):
                assert got[q.diff(t, 2)] == pytest.approx(want[q.diff(t, 2)], rel=1e-10, abs=1e-12)
            if model == "vakonomic":
                rate_full, rate_elim = eqs_full.unknowns[4], eqs_elim.unknowns[3]
                assert got[rate_full] == pytest.approx(want[rate_elim], rel=1e-10, abs=1e-12)


def test_every_model_derives_with_a_relation() -> None:
    """A Chaplygin system with a relation (z = a sin(x), no gravity): the reduced models match
    the Chetaev multiplier model, and Lindelöf's equations are those of the eliminated system."""
    T = m / 2 * (d(x) ** 2 + d(y) ** 2 + d(z) ** 2) + J / 2 * d(phi) ** 2
    s = System([x, y, phi, z], T, {d(y): sp.tan(phi) * d(x)}, holonomic={z: z - a * sp.sin(x)})
    zdot = a * sp.cos(x) * d(x)
    T_elim = m / 2 * (d(x) ** 2 + d(y) ** 2 + zdot**2) + J / 2 * d(phi) ** 2
    eliminated = System([x, y, phi], T_elim, {d(y): sp.tan(phi) * d(x)})
    assert s.is_chaplygin
    rng = np.random.default_rng(4)
    v = knife_state(rng)
    truth = solution(s.equations("chetaev"), v)
    for model in ("chaplygin", "voronets", "lindelof", "vakonomic_family"):
        for form in ("classic", "new"):
            constants = [0.7, 5] if model == "vakonomic_family" else None
            got = solution(s.equations(model, form, constants=constants), v)
            assert set(got) == {x.diff(t, 2), phi.diff(t, 2)}
            if model in ("chaplygin", "voronets"):
                for acc, value in got.items():
                    assert value == pytest.approx(truth[acc], rel=1e-10), (model, form)
            if model == "lindelof":
                want = solution(eliminated.equations("lindelof", form), v)
                for acc, value in got.items():
                    assert value == pytest.approx(want[acc], rel=1e-10), form
            if model == "vakonomic_family":  # the relation's constant c_2 does not enter
                want = solution(s.equations(model, form, constants=[0.7, -3]), v)
                elim = solution(eliminated.equations(model, form, constants=[0.7]), v)
                for acc, value in got.items():
                    assert value == pytest.approx(want[acc], rel=1e-10) == elim[acc], form
