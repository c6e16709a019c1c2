"""System files with a [body] table: a rolling body built by chaplygin.bodies.rolling_body."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols
from typer.testing import CliRunner

import chaplygin
from chaplygin import examples
from chaplygin.apps.cli import app
from chaplygin.bodies import Disk, Sphere, rolling_body
from chaplygin.io.files import SystemFileError, loads

runner = CliRunner()
T_ = dynamicsymbols._t

ROUTH = """
name = "Routh's sphere"

[body]
shape = "sphere"
radius = "r"
mass = "m"
inertia = ["A", "A", "C"]
center_of_mass = [0, 0, "-e"]
angles = "euler"

[parameters]
r = 1.0
m = 1.0
A = 0.4
C = 0.5
e = 0.1
g = 9.81

[initial]
theta = 0.5
"phi'" = 3.0
"psi'" = 0.2
"""

DISK = """
name = "Disk"

[body]
shape = "disk"
radius = "r"
mass = "m"
inertia = [["A", 0, 0], [0, "A", 0], [0, 0, "2*A"]]
g = 1

[parameters]
r = 1.0
m = 1.0
A = 0.25

[initial]
theta = 0.1
"phi'" = 5.0
"""


def positive(expr: Any) -> Any:
    """``expr`` with the file's real parameter symbols replaced by positive ones of the same name."""
    return expr.xreplace(
        {
            s: sp.Symbol(s.name, positive=True)
            for s in expr.free_symbols
            if isinstance(s, sp.Symbol) and s != T_
        }
    )


def same_dynamics(reference: chaplygin.System, loaded: chaplygin.System) -> None:
    """Same constraints, same kinetic and potential energy and equivalent reduced equations."""
    assert loaded.coordinates == reference.coordinates
    for vel, rhs in reference.constraints.items():
        assert sp.simplify(positive(loaded.constraints[vel]) - rhs) == 0
    assert sp.simplify(positive(loaded.kinetic_energy) - reference.kinetic_energy) == 0
    equations = [positive(e) for e in loaded.equations("chaplygin").equations]
    report = chaplygin.equivalent(reference, reference.equations("chaplygin"), equations)
    assert report, report


def test_sphere_file_is_rolling_body() -> None:
    loaded = loads(ROUTH)
    r, m, A, C, e = sp.symbols("r m A C e", positive=True)
    direct = rolling_body(Sphere(r), mass=m, inertia=[A, A, C], center_of_mass=(0, 0, -e), angles="euler")
    assert sp.simplify(positive(loaded.system.potential_energy) - direct.potential_energy) == 0
    same_dynamics(direct, loaded.system)
    assert loaded.parameters == {"r": 1.0, "m": 1.0, "A": 0.4, "C": 0.5, "e": 0.1, "g": 9.81}
    assert loaded.initial["theta"] == 0.5 and loaded.initial["x"] == 0.0 and "x'" not in loaded.initial


def test_homogeneous_sphere_file_is_the_papers_sphere() -> None:
    loaded = loads("""
        [body]
        shape = "sphere"
        radius = "a"
        mass = "m"
        inertia = ["2*m*a^2/5", "2*m*a^2/5", "2*m*a^2/5"]
        angles = "euler"
        [parameters]
        a = 1.0
        m = 2.0
        g = 9.81
    """)
    same_dynamics(examples.rolling_sphere(), loaded.system)


def test_disk_file_is_rolling_body() -> None:
    loaded = loads(DISK)
    r, m, A = sp.symbols("r m A", positive=True)
    direct = rolling_body(Disk(r), mass=m, inertia=[A, A, 2 * A], g=1)
    assert loaded.system.angles == "edge"  # the disk's default convention
    same_dynamics(direct, loaded.system)


def test_body_file_round_trips() -> None:
    loaded = loads(ROUTH)
    again = loads(loaded.dumps())
    assert again.body == loaded.body and again.parameters == loaded.parameters
    assert again.initial == loaded.initial and again.name == loaded.name
    assert again.system.kinetic_energy == loaded.system.kinetic_energy
    assert again.system.constraints == loaded.system.constraints


@pytest.mark.parametrize(
    "command", [["check"], ["derive"], ["simulate", "-t", "0.5", "-n", "5", "-b", "numpy"]]
)
def test_cli_accepts_a_body_file(command: list[str], tmp_path: Path) -> None:
    path = tmp_path / "routh.toml"
    path.write_text(ROUTH, encoding="utf-8")
    out = ["-o", str(tmp_path / "run.csv")] if command[0] == "simulate" else []
    result = runner.invoke(app, [command[0], str(path), *command[1:], *out])
    assert result.exit_code == 0, result.output
    if command[0] == "simulate":
        assert len((tmp_path / "run.csv").read_text().splitlines()) == 6  # header + 5 samples


def body(**changes: Any) -> str:
    """ROUTH with [body] keys changed (None removes one); values are TOML text."""
    table = {
        "shape": '"sphere"',
        "radius": '"r"',
        "mass": '"m"',
        "inertia": '["A", "A", "C"]',
        "center_of_mass": '[0, 0, "-e"]',
        "angles": '"euler"',
    }
    table.update(changes)
    lines = [f"{k} = {v}" for k, v in table.items() if v is not None]
    params = "r = 1.0\nm = 1.0\nA = 0.4\nC = 0.5\ne = 0.1\ng = 9.81"
    return "[body]\n" + "\n".join(lines) + "\n[parameters]\n" + params + "\n"


BAD = [
    (body(shape='"cube"'), "[body] shape", '"sphere" | "disk" | "torus"'),
    (body(shape=None), "[body] shape", "ellipsoid"),
    (body(radius=None), "radius is missing", "radius"),
    (body(shape='"torus"'), "[body] radius", "torus has the keys R, r"),
    (body(radius="-1", center_of_mass=None), "[body] radius", "> 0"),
    (body(radius='"-r"', center_of_mass=None), "[body] radius", "with the values of [parameters]"),
    (body(mass="0"), "[body] mass", "> 0"),
    (body(inertia="[1, 2, 0]"), "[body] inertia[2]", "> 0"),
    (body(inertia="[1, 1, 3]"), "[body] inertia", "triangle inequality"),
    (body(inertia='["A", "A", "3*A"]'), "[body] inertia", "triangle inequality"),
    (body(inertia="[[1, 2, 0], [2, 1, 0], [0, 0, 1]]"), "[body] inertia", "positive definite"),
    (body(inertia="[[1, 0.1, 0], [0, 1, 0], [0, 0, 1]]"), "[body] inertia[1][0]", "symmetric"),
    (body(inertia='["A", "A"]'), "[body] inertia", "three principal moments"),
    (body(center_of_mass="[0, 0, 2]"), "[body] center_of_mass", "outside"),
    (body(center_of_mass='[0, 0, "-20*e"]'), "[body] center_of_mass", "outside"),
    (body(angles='"zyz"'), "[body] angles", '"cardan", "edge", "euler"'),
    (body(colour='"red"'), "[body] colour", "mass, inertia"),
    (body(mass='"m*x"'), "[body] mass", "x"),  # a coordinate is not a parameter
    (body(mass='"__import__(1)"'), "[body] mass", ""),
    ('coordinates = ["x"]\n' + body(), "coordinates", "[body]"),
    (body().replace("[parameters]", '[energy]\nT = "1"\n[parameters]'), "energy", "[body]"),
    (body().replace("g = 9.81", ""), "[body] g", "g = 9.81"),
    (body().replace("g = 9.81", "g = 9.81\nk = 2.0"), "[parameters] k", "[body]"),
]


@pytest.mark.parametrize(("text", "key", "allowed"), BAD)
def test_bad_body_is_refused_naming_the_key(text: str, key: str, allowed: str) -> None:
    with pytest.raises(SystemFileError) as info:
        loads(text)
    message = str(info.value)
    assert key in message and allowed in message, message


@pytest.mark.parametrize(("text", "key", "allowed"), BAD[:3] + BAD[8:9] + BAD[13:14])
def test_cli_refuses_a_bad_body_with_exit_1(text: str, key: str, allowed: str, tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text, encoding="utf-8")
    result = runner.invoke(app, ["check", str(path)])
    assert result.exit_code == 1 and key in result.stderr and "Traceback" not in result.stderr, result.output
