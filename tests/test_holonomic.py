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
from chaplygin.errors import ModelError, SystemDefinitionError
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


def test_a_relation_given_as_a_velocity_constraint_is_pointed_to_holonomic() -> None:
    with pytest.raises(SystemDefinitionError, match=r"goes in holonomic=\{coordinate it fixes: f\}"):
        System([x, y], (d(x) ** 2 + d(y) ** 2) / 2, [x**2 + y**2 - 1], dependent=[y])


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


# ------------------------------------------------------------------ simulate
def pendulum_xy() -> System:
    T = m / 2 * (d(x) ** 2 + d(y) ** 2)
    return System([x, y], T, [], potential_energy=m * g * y, holonomic={y: x**2 + y**2 - l**2})


def test_pendulum_in_x_y_moves_as_the_pendulum_in_its_angle() -> None:
    """Started at y = -0.5 (a guess), y is solved to -l cos θ0 by Newton, told in the notes, and
    x(t) follows l sin θ(t) of the same pendulum written in its angle (an independent run)."""
    import chaplygin

    params = {"m": 1.0, "g": 9.81, "l": 0.8}
    th0, rate0 = 0.9, 0.4
    start = {x: 0.8 * np.sin(th0), y: -0.5, d(x): 0.8 * np.cos(th0) * rate0}
    tr = chaplygin.simulate(pendulum_xy(), "chetaev", 3.0, start, params, samples=61, backend="numpy")
    angle = System([th], m * l**2 / 2 * d(th) ** 2, [], potential_energy=-m * g * l * sp.cos(th))
    ref = chaplygin.simulate(
        angle, "chetaev", 3.0, {th: th0, d(th): rate0}, params, samples=61, backend="numpy"
    )
    assert tr.coordinates["y"][0] == pytest.approx(-0.8 * np.cos(th0), rel=1e-12)
    assert tr.notes == [
        f"y solved from the holonomic constraint at the start: -0.5 → {-0.8 * np.cos(th0):.12g}"
    ]
    assert np.max(np.abs(tr.coordinates["x"] - 0.8 * np.sin(ref.coordinates["theta"]))) < 1e-7
    assert np.max(np.abs(tr.coordinates["y"] + 0.8 * np.cos(ref.coordinates["theta"]))) < 1e-7
    assert tr.holonomic_residual.shape == tr.t.shape
    assert 0 < np.max(tr.holonomic_residual) < 1e-7
    assert "holonomic_residual" in tr.columns and "max holonomic residual" in tr._repr_html_()
    assert ref.holonomic_residual.size == 0 and "holonomic_residual" not in ref.columns


def test_a_start_on_the_relation_is_kept_and_bad_starts_are_refused() -> None:
    import chaplygin
    from chaplygin.errors import InputError

    params = {"m": 1.0, "g": 9.81, "l": 0.8}
    on = {x: 0.0, y: -0.8, d(x): 0.1}
    tr = chaplygin.simulate(pendulum_xy(), "vakonomic", 0.5, on, params, samples=11, backend="numpy")
    assert tr.notes == [] and tr.coordinates["y"][0] == -0.8
    with pytest.raises(InputError, match=r"no solution for y near the given y = -0.5"):
        chaplygin.simulate(pendulum_xy(), "chetaev", 0.5, {**on, x: 2.0, y: -0.5}, params, backend="numpy")
    with pytest.raises(InputError, match=r"do not fix y at y = 0: ∂f/∂q_dep is singular there"):
        chaplygin.simulate(pendulum_xy(), "chetaev", 0.5, {**on, x: 0.8, y: 0.0}, params, backend="numpy")


def test_ensemble_members_start_on_the_relation() -> None:
    from chaplygin.numeric.ensemble import simulate_ensemble

    params = {"m": 1.0, "g": 9.81, "l": 0.8}
    starts = [{x: 0.3, y: -0.5, d(x): 0.1}, {x: -0.2, y: -0.9, d(x): 0.0}]
    ens = simulate_ensemble(pendulum_xy(), "chetaev", 0.2, starts, params, backend="c")
    assert ens.y_initial[:, 1] == pytest.approx(-np.sqrt(0.64 - np.array([0.3, -0.2]) ** 2), rel=1e-12)
    # the changes are told and the relation is monitored at the end (they were neither)
    assert len(ens.notes) == 1 and ens.notes[0].startswith("2 member(s) solved from the holonomic")
    assert "member 0: y" in ens.notes[0]
    final = ens.coordinates["x"] ** 2 + ens.coordinates["y"] ** 2 - 0.64  # x² + y² = l², by hand
    assert ens.holonomic_residual == pytest.approx(np.abs(final), abs=1e-15)
    assert np.all(ens.holonomic_residual < 1e-7) and "final holonomic residual" in ens._repr_html_()


# ------------------------------------------------------------------ system files and the command line
KNIFE_TOML = """
name = "Knife edge on a wavy surface"
coordinates = ["x", "y", "phi", "z"]

[parameters]
m = 1.0
J = 0.5
a = 0.3
g = 9.81

[energy]
T = "m/2*(x'^2 + y'^2 + z'^2) + J/2*phi'^2"
V = "m*g*z"

[constraints]
{constraints}

[holonomic]
z = "z - a*sin(x)"

[initial]
x = 0.2
phi = 0.3
"x'" = 1.0
"phi'" = 0.2
"""
SOLVED = '"y\'" = "tan(phi)*x\'"'
IMPLICIT = 'implicit = ["sin(phi)*x\' - cos(phi)*y\'"]\ndependent = ["y"]'


@pytest.mark.parametrize("constraints", [SOLVED, IMPLICIT])
def test_a_file_with_holonomic_constraints_round_trips(constraints: str) -> None:
    from chaplygin.io.files import dumps, loads

    loaded = loads(KNIFE_TOML.format(constraints=constraints))
    s = loaded.system
    assert {str(k): str(f) for k, f in s.holonomic.items()} == {"z(t)": "-a*sin(x(t)) + z(t)"}
    assert s.velocity_g == 1
    text = dumps(s, loaded.parameters, loaded.initial)
    assert '[holonomic]\nz = "-a*sin(x) + z"' in text
    back = loads(text).system
    assert (back.holonomic, back.constraint_form, back.dependent) == (s.holonomic, s.constraint_form, (y, z))
    assert sp.simplify(back.A - s.A) == sp.zeros(2, 4)


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ('w = "z"', '[holonomic] w: "w" is not a coordinate'),
        ('"z\'" = "z"', "(write the coordinate, z, not its velocity)"),
        ('z = "z - "', "[holonomic] z"),
        ('y = "y - x"', "holonomic[y]: y is a dependent coordinate of the velocity constraints"),
        ('z = "x - a"', "holonomic[z] = -a + x does not depend on z"),
    ],
)
def test_bad_holonomic_tables_are_named(table: str, message: str) -> None:
    from chaplygin.io.files import SystemFileError, loads

    text = KNIFE_TOML.format(constraints=SOLVED).replace('z = "z - a*sin(x)"', table)
    with pytest.raises(SystemFileError) as err:
        loads(text)
    assert message in str(err.value)


def test_the_command_line_derives_simulates_and_compares_such_a_file(tmp_path) -> None:
    from typer.testing import CliRunner

    from chaplygin.apps.cli import app

    path = tmp_path / "knife.toml"
    path.write_text(KNIFE_TOML.format(constraints=SOLVED))
    runner = CliRunner()
    out = runner.invoke(app, ["derive", str(path), "--model", "chetaev"])
    assert out.exit_code == 0, out.output
    assert out.output.splitlines()[1] == "holonomic: -a*sin(x) + z = 0 (fixes z)"
    out = runner.invoke(app, ["check", str(path)])
    assert "Holonomic: -a*sin(x) + z = 0 (fixes z; its time derivative is constraint 2)" in out.output
    out = runner.invoke(
        app, ["simulate", str(path), "-t", "0.5", "-o", str(tmp_path / "run.csv"), "--backend", "numpy"]
    )
    assert out.exit_code == 0, out.output
    assert "max holonomic residual" in out.output
    assert "note: z solved from the holonomic constraint at the start: 0 → 0.0596007992385" in out.output
    header = (tmp_path / "run.csv").read_text().splitlines()[0]
    assert header.endswith("constraint_residual,holonomic_residual")
    out = runner.invoke(
        app, ["compare", str(path), "-t", "0.5", "--models", "chetaev,vakonomic", "--backend", "numpy"]
    )
    assert out.exit_code == 0, out.output
    assert "note: chetaev: max holonomic residual |f|" in out.output


# ------------------------------------------------------------------ from_mechanics
def test_from_mechanics_takes_relations_as_expressions_or_a_vector_component() -> None:
    """A particle on the surface z = a sin(x): the relation as an expression and as the vector
    from the surface point below it give the System written by hand."""
    from sympy.physics.mechanics import Particle, Point, ReferenceFrame

    from chaplygin import from_mechanics

    N = ReferenceFrame("N")
    O = Point("O")
    P = O.locatenew("P", x * N.x + y * N.y + z * N.z)
    S = O.locatenew("S", x * N.x + y * N.y + a * sp.sin(x) * N.z)
    P.set_vel(N, P.pos_from(O).dt(N))
    body = Particle("p", P, m)
    body.potential_energy = m * g * z
    by_hand = System(
        [x, y, z],
        m / 2 * (d(x) ** 2 + d(y) ** 2 + d(z) ** 2),
        [],
        potential_energy=m * g * z,
        holonomic={z: z - a * sp.sin(x)},
    )
    for relation in (z - a * sp.sin(x), P.pos_from(S)):
        s = from_mechanics(N, [x, y, z], [body], [], dependent=[], holonomic={z: relation})
        assert s.holonomic == {z: z - a * sp.sin(x)}
        assert (s.A, s.A0, s.dependent) == (by_hand.A, by_hand.A0, by_hand.dependent)
        assert sp.simplify(s.kinetic_energy - by_hand.kinetic_energy) == 0
    with pytest.raises(SystemDefinitionError, match=r"holonomic\[z\]: the vector has 2 non-vanishing"):
        from_mechanics(N, [x, y, z], [body], [], dependent=[], holonomic={z: P.pos_from(O) - x * N.x})


# ------------------------------------------------------------------ finite relations as holonomic constraints
def test_an_integrable_constraint_becomes_its_finite_relation() -> None:
    """y' = x x' (form B) integrates to y - x²/2 = c: the new system has that relation (c a new
    parameter, or the value given), no velocity constraint, and the same Chetaev motion."""
    T = m / 2 * (d(x) ** 2 + d(y) ** 2 + d(z) ** 2)
    s = System([x, y, z], T, {d(y): x * d(x)}, potential_energy=g * z * y)
    report = s.integrability()
    new = report.holonomic_system()
    c_1 = sp.Symbol("c_1")
    assert sp.simplify(new.holonomic[y] - (y - x**2 / 2 - c_1)) == 0
    assert (new.velocity_g, new.g, new.dependent, new.A) == (0, 1, (y,), s.A)
    assert sp.simplify(report.holonomic_system({"y": 2}).holonomic[y] - (y - x**2 / 2 - 2)) == 0
    rng = np.random.default_rng(5)
    v = {p: sp.Float(rng.uniform(0.5, 1.5)) for p in (m, g)}
    v.update({t: 0, x: 0.3, y: 0.7, z: -0.2, d(x): 0.4, d(z): -0.6, d(y): 0.3 * 0.4})
    want, got = solution(s.equations("chetaev"), v), solution(new.equations("chetaev"), v)
    assert all(got[q.diff(t, 2)] == pytest.approx(want[q.diff(t, 2)], rel=1e-12) for q in (x, y, z))


def test_an_integrating_factor_relation_and_the_refusals() -> None:
    T = m / 2 * (d(x) ** 2 + d(y) ** 2)
    s = System([x, y], T, [y * d(x) - x * d(y)], dependent=[y])
    new = s.integrability().holonomic_system([0.5])
    f = new.holonomic[y]
    assert f == x / y - sp.Float(0.5)  # (an integrating factor 1/y²: ḟ ∝ the constraint)
    assert not sp.simplify((f.diff(x) * d(x) + f.diff(y) * d(y)) / (y * d(x) - x * d(y))).has(d(x), d(y))
    with pytest.raises(ModelError, match=r"not integrable \(Frobenius: \[X_x, X_phi\] along ∂y"):
        knife_eliminated("B").integrability().holonomic_system()
    steep = System([x, y], T, {d(y): x**x * d(x)})
    with pytest.raises(ModelError, match="no finite relation f\\(q, t\\) = c was found"):
        steep.integrability().holonomic_system()
    with pytest.raises(ModelError, match=r"constants: 2 value\(s\) given for 1 relation"):
        s.integrability().holonomic_system([1, 2])


def test_with_holonomic_adds_relations_to_a_system() -> None:
    knife = knife_eliminated("A")
    T = knife.kinetic_energy.subs(a, 0) + m / 2 * d(z) ** 2
    flat = System([x, y, phi, z], T, **knife_constraint("A"), potential_energy=m * g * z)
    added = flat.with_holonomic({z: z - a * sp.sin(x)})
    direct = knife_on_surface("A")
    assert (added.holonomic, added.dependent, added.A, added.A0) == (
        direct.holonomic,
        direct.dependent,
        direct.A,
        direct.A0,
    )
    assert added.with_holonomic({}, keep_constraints=False).velocity_g == 0


def test_the_report_shows_the_relations_and_a_simulated_system_still_pickles() -> None:
    import copy
    import pickle

    import chaplygin
    from chaplygin.apps.report import _source, _system_section
    from chaplygin.apps.sweep import _fingerprint

    s = pendulum_xy()
    start = {x: 0.1, y: -0.7, d(x): 0.0}
    chaplygin.simulate(s, "chetaev", 0.1, start, {"m": 1, "g": 1, "l": 0.8}, backend="numpy")
    clone = copy.copy(s)
    clone.__dict__["_equations"] = {}  # (as a sweep sends a System to its workers)
    assert pickle.loads(pickle.dumps(clone)).holonomic == s.holonomic
    html = _system_section(_source(s, None, None))
    assert "Holonomic constraints (1; their time derivatives are the last constraints above)" in html
    shifted = System(
        [x, y], s.kinetic_energy, [], potential_energy=m * g * y, holonomic={y: x**2 + y**2 - l**2 - 1}
    )
    assert _fingerprint(s) != _fingerprint(shifted)  # (the same derivative ḟ)


def test_a_relation_written_with_angle_sums_is_printed_with_them() -> None:
    s = System([x, y, z], (d(x) ** 2 + d(y) ** 2 + d(z) ** 2) / 2, [], holonomic={z: z - sp.sin(x + y)})
    text = str(s.equations("chetaev"))
    assert "-cos(x + y)*x' - cos(x + y)*y' + z' = 0" in text and "sin(x)*sin(y)" not in text
