"""The rolling bodies of the catalogue: ``lindelof-problem``, ``routh-sphere`` and ``rattleback``.

Each entry runs through the command line (``derive``, ``simulate``) and through
``chaplygin.simulate``, and is checked against something the code under test does not produce:
``rolling_body`` called here with the documented parameters (identity), the hand-written rolling
disk of the gallery, energy conservation, Jellett's integral (Gray & Nickel 2000), the
rattleback's reversal for one sense of spin only and the mirror symmetry that swaps the senses
(Kane & Levinson 1982; Garcia & Hubbard 1988).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from typer.testing import CliRunner

import chaplygin
from chaplygin import examples, simulate
from chaplygin.apps.cli import app
from chaplygin.bodies import Disk, Ellipsoid, Sphere, Torus, initial_state, motion, rolling_body
from randomsystems import number

runner = CliRunner()
BODIES = ["lindelof-problem", "routh-sphere", "rattleback"]

#: Kane & Levinson (1982), z up (their z points down: a half turn about x flips the sign of D);
#: moments per unit mass.
KANE_LEVINSON = {
    "a": 0.2,
    "b": 0.03,
    "c": 0.02,
    "h": 0.01,
    "m": 1.0,
    "A": 2e-4,
    "B": 1.6e-3,
    "C": 1.7e-3,
    "D": 2e-5,
    "g": 9.81,
}

#: (documented parameters, the body rolling_body builds from them), as the gallery pages state them
DOCUMENTED: dict[str, tuple[dict[str, float], Callable[[dict], chaplygin.System]]] = {
    # a uniform thin disk of unit mass and radius: A = m r²/4, C = m r²/2
    "lindelof-problem": (
        {"m": 1.0, "r": 1.0, "A": 0.25, "C": 0.5, "g": 9.81},
        lambda p: rolling_body(Disk(p["r"]), mass=p["m"], inertia=[p["A"], p["A"], p["C"]], g=p["g"]),
    ),
    "routh-sphere": (
        {"r": 1.0, "a": 0.3, "m": 1.0, "A": 0.4, "C": 0.6, "g": 9.81},
        lambda p: rolling_body(
            Sphere(p["r"]),
            mass=p["m"],
            inertia=[p["A"], p["A"], p["C"]],
            center_of_mass=(0, 0, -p["a"]),
            g=p["g"],
        ),
    ),
    "rattleback": (
        KANE_LEVINSON,
        lambda p: rolling_body(
            Ellipsoid(p["a"], p["b"], p["c"]),
            mass=p["m"],
            inertia=[
                [p["m"] * p["A"], p["m"] * p["D"], 0],
                [p["m"] * p["D"], p["m"] * p["B"], 0],
                [0, 0, p["m"] * p["C"]],
            ],
            center_of_mass=(0, 0, -p["h"]),
            g=p["g"],
        ),
    ),
}


def rot(axis: str, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return {
        "x": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
        "y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
    }[axis]


def _at_random_states(expr: sp.Expr, system: chaplygin.System, rng: np.random.Generator) -> np.ndarray:
    """``expr`` at random values of the coordinates and velocities (no parameters left), in
    floats (randomsystems.numbers: SymPy's subs + lambdify of the rattleback's T took a second)."""
    qs = list(system.coordinates)
    state = qs + [q.diff() for q in qs]
    return np.array(
        [number(expr, dict(zip(state, rng.uniform(-0.7, 0.7, size=len(state))))) for _ in range(5)]
    )


# ---------------------------------------------------------------- identity
@pytest.mark.parametrize("name", BODIES)
def test_entry_is_rolling_body_of_the_documented_parameters(name: str) -> None:
    """The catalogue's symbolic body with its default parameters is what rolling_body builds
    from the numbers the gallery page documents: same T, V and constraints."""
    entry = examples.get(name)
    documented, build = DOCUMENTED[name]
    assert entry.parameters == documented
    mine, theirs = entry.system(), build(documented)
    assert [q.name for q in mine.coordinates] == [q.name for q in theirs.coordinates]
    assert [q.name for q in mine.dependent] == ["x", "y"] and mine.is_chaplygin
    values = {p: sp.nsimplify(documented[p.name]) for p in mine.parameters}
    pairs = [
        (mine.kinetic_energy, theirs.kinetic_energy),
        (mine.potential_energy, theirs.potential_energy),
        *((mine.constraints[v], theirs.constraints[v]) for v in theirs.constraints),
    ]
    rng = np.random.default_rng(18)
    for ours, reference in pairs:
        difference = _at_random_states(ours.xreplace(values) - reference, mine, rng)
        scale = 1 + np.max(np.abs(_at_random_states(reference, mine, rng)))
        assert np.max(np.abs(difference)) < 1e-12 * scale


@pytest.mark.parametrize("name", ["routh-sphere", "rattleback"])
def test_default_state_is_the_documented_physical_state(name: str) -> None:
    """The entries' states, written as angles and rates, are the tilts and body angular
    velocities the descriptions and pages state."""
    entry = examples.get(name)
    R, omega = {
        "routh-sphere": (rot("x", 0.5), [1.0, -0.5, 4.0]),
        "rattleback": (rot("x", 0.01) @ rot("y", 0.01), [0.0, 0.0, 5.0]),
    }[name]
    start = initial_state(entry.system(), R=R, omega=omega)
    assert set(start) == set(entry.initial)
    for key, value in start.items():
        assert entry.initial[key] == pytest.approx(value, rel=1e-12, abs=1e-15), key


# ---------------------------------------------------------------- the command line
@pytest.mark.parametrize("name", BODIES)
def test_derive_and_simulate_through_the_cli(name: str, tmp_path: Path) -> None:
    entry = examples.get(name)
    # The solved accelerations of the sphere and the ellipsoid run to 10⁵–10⁶ operations, and
    # SymPy's printer needs most of a minute for the ellipsoid's: the disk alone solves them here.
    solve = name == "lindelof-problem"
    derived = runner.invoke(
        app, ["derive", f"example:{name}", "--format", "json", *(() if solve else ("--no-accelerations",))]
    )
    assert derived.exit_code == 0, derived.stderr
    doc = json.loads(derived.stdout)
    assert doc["model"] == "chaplygin" and doc["coordinates"] == ["psi", "theta", "phi", "x", "y"]
    assert doc["dependent"] == ["x", "y"] and sorted(doc["parameters"]) == sorted(entry.parameters)
    assert doc["unknowns"] == ["psi''", "theta''", "phi''"] and len(doc["equations"]) == 3
    if solve:
        assert sorted(doc["accelerations"]) == ["phi''", "psi''", "theta''"]
    out = tmp_path / f"{name}.csv"
    result = runner.invoke(
        app, ["simulate", f"example:{name}", "-t", "0.5", "--samples", "11", "--out", str(out)]
    )
    assert result.exit_code == 0, result.stderr
    assert "success" in result.stdout
    data = np.genfromtxt(out, delimiter=",", names=True)
    assert data["t"][-1] == pytest.approx(0.5) and data["theta"][0] == entry.initial["theta"]
    energy = data["energy"]
    assert np.ptp(energy) <= 1e-9 * np.max(np.abs(energy))  # rolling does no work: T + V is constant


# ---------------------------------------------------------------- Lindelöf's problem
def test_lindelof_problem_is_the_gallery_disk_in_both_models() -> None:
    """Chaplygin's and Lindelöf's equations of the built disk are those of the hand-written
    rolling disk (Neimark & Fufaev; its x, y are the contact point, the entry's the centre:
    the reduced equations in ψ, θ, φ do not see the difference)."""
    built, disk = examples.lindelof_problem(), examples.rolling_disk()
    for model in ("chaplygin", "lindelof"):
        report = chaplygin.equivalent(disk, disk.equations(model), list(built.equations(model).equations))
        assert report, (model, report)


@pytest.mark.parametrize("name", BODIES)
def test_true_and_lindelof_motions_conserve_energy_and_part(name: str) -> None:
    """From each entry's default state both models conserve T + V (the reactions of the true
    motion do no work; T + V is the Jacobi integral of Lindelöf's Lagrangian T̃ − V), and the
    lean angles part: Lindelöf's equations are not the rolling motion of any of these bodies."""
    entry = examples.get(name)
    system = entry.system()
    runs = {
        m: simulate(system, m, 20.0, entry.initial, entry.parameters, samples=201)
        for m in ("chaplygin", "lindelof")
    }
    for model, run in runs.items():
        assert run.success and run.energy_drift() <= 1e-9, model
    assert np.max(np.abs(runs["chaplygin"]["theta"] - runs["lindelof"]["theta"])) > 0.1


# ---------------------------------------------------------------- Routh's sphere
def test_routh_sphere_default_state_keeps_jellett_integral() -> None:
    """Jellett's integral (I ω)·s, s = r γ − a e₃ from the contact point to the centre of mass
    (Gray & Nickel 2000), and the energy along the entry's default motion."""
    entry = examples.get("routh-sphere")
    system, p = entry.system(), entry.parameters
    run = simulate(system, "chaplygin", 10.0, entry.initial, p, samples=201)
    assert run.success and run.energy_drift() <= 1e-9
    mo = motion(system, run)
    s = p["r"] * mo.R[:, 2, :] - np.array([0.0, 0.0, p["a"]])
    jellett = np.einsum("ki,ki->k", mo.omega * [p["A"], p["A"], p["C"]], s)
    assert np.ptp(jellett) < 1e-8 * np.max(np.abs(jellett))
    assert np.ptp(mo.omega[:, 2]) > 1e-3  # the spin alone is not conserved: the test can fail


# ---------------------------------------------------------------- the rattleback
def _vertical_spin(system: chaplygin.System, start: dict, parameters: dict, t_end: float) -> tuple:
    run = simulate(system, "chaplygin", t_end, start, parameters, samples=int(40 * t_end) + 1)
    assert run.success and run.energy_drift() <= 1e-9  # no friction: the energy is conserved
    mo = motion(system, run)
    return run.t, np.einsum("kij,kj->ki", mo.R, mo.omega)[:, 2]


def test_rattleback_reverses_for_one_sense_only() -> None:
    """Spun with n D > 0 (the default, counter-clockwise) it reverses within 4 s; spun the other
    way from the same tilt it keeps its sense for 6 s (Kane & Levinson 1982)."""
    entry = examples.get("rattleback")
    system, p = entry.system(), entry.parameters
    t, wz = _vertical_spin(system, entry.initial, p, 4.0)
    assert wz[0] == pytest.approx(5.0, rel=1e-3) and np.min(wz) < -1.0
    assert t[np.argmax(wz < 0)] < 3.5
    other = initial_state(system, R=rot("x", 0.01) @ rot("y", 0.01), omega=[0.0, 0.0, -5.0])
    _, wz = _vertical_spin(system, other, p, 6.0)
    assert np.all(wz < -2.0)


def test_rattleback_mirror_image_reverses_the_other_way() -> None:
    """The mirror image y → −y of the rattleback has −D; the mirror image of the default motion
    (tilt R_x(−0.01) R_y(0.01), ω = −S ω for the pseudovector ω) is a motion of it, with the
    vertical spin of the original negated: the sense that reverses is fixed by the sign of n D."""
    entry = examples.get("rattleback")
    system, p = entry.system(), entry.parameters
    t, wz = _vertical_spin(system, entry.initial, p, 4.0)
    mirrored = initial_state(system, R=rot("x", -0.01) @ rot("y", 0.01), omega=[0.0, 0.0, -5.0])
    _, wz_mirror = _vertical_spin(system, mirrored, dict(p, D=-p["D"]), 4.0)
    np.testing.assert_allclose(wz_mirror, -wz, atol=1e-6)
    assert np.min(-wz_mirror) < -1.0  # it did reverse (clockwise to counter-clockwise)


# ---------------------------------------------------------------- as a system file
def test_a_built_body_is_written_as_its_body_table() -> None:
    """``dumps`` writes a body built by ``rolling_body`` as a ``[body]`` table: reading it back
    builds the same T, V and constraints, and writing that again gives the same text."""
    from chaplygin.io.files import dumps, loads

    tenth = sp.Rational(1, 10)
    body = rolling_body(
        Torus(1, sp.Rational(1, 4)),
        mass=2,
        inertia=[[3, tenth, 0], [tenth, 2, 0], [0, 0, 4]],
        center_of_mass=(tenth, 0, 0),
        g=sp.Symbol("g", positive=True),
    )
    start = {
        "psi": 0.1,
        "theta": 0.3,
        "phi": 0.0,
        "x": 0.0,
        "y": 0.0,
        "psi'": 1.0,
        "theta'": 0.0,
        "phi'": 2.0,
    }
    text = dumps(body, {"g": 9.81}, start)
    assert "[body]" in text and "[energy]" not in text and 'shape = "torus"' in text
    loaded = loads(text)
    assert loaded.dumps() == text
    rng = np.random.default_rng(7)
    g = {loaded.system.parameter("g"): body.gravity}
    pairs = [
        (loaded.system.kinetic_energy, body.kinetic_energy),
        (loaded.system.potential_energy.xreplace(g), body.potential_energy),
        *((loaded.system.constraints[v], body.constraints[v]) for v in body.constraints),
    ]
    for theirs, ours in pairs:
        assert np.max(np.abs(_at_random_states(theirs - ours, body, rng))) < 1e-12
