"""The command line's polish (issue 19, item 4): the models explained in --help and by
`chaplygin models`; `derive --format pretty`; no `<bool>` after a flag; lists wrapped to the
terminal; CSV numbers that read back exactly; integration progress as t / t_end; messages that
name q, q', q'' as the files do, never SymPy's `Derivative(q(t), (t, 2))`."""

from __future__ import annotations

import re
from pathlib import Path

import click
import numpy as np
import pytest
import sympy as sp
import typer
from sympy.physics.mechanics import dynamicsymbols
from typer.testing import CliRunner

import chaplygin
from chaplygin import ChaplyginError, System, examples
from chaplygin.apps.cli import app
from chaplygin.numeric._ckernel import Unavailable, compiler

runner = CliRunner()
T_ = dynamicsymbols._t

try:
    compiler()
    LOOPS = ["numba", "c"]
except Unavailable:  # pragma: no cover - every CI machine has a C compiler
    LOOPS = ["numba"]


def run(*args: str, **kwargs):
    return runner.invoke(app, [str(a) for a in args], **kwargs)


def words(text: str) -> str:
    """``text`` with every run of white space (a wrapped line, a table's padding) one space."""
    return " ".join(text.split())


def every_command() -> list[list[str]]:
    """The argument lists of every command and group, ``[]`` for ``chaplygin`` itself."""
    found: list[list[str]] = []

    def walk(command: click.Command, path: list[str]) -> None:
        found.append(path)
        for name, sub in getattr(command, "commands", {}).items():
            walk(sub, [*path, name])

    walk(typer.main.get_command(app), [])
    return found


# ---------------------------------------------------------------- derive --format pretty
def test_derive_pretty_prints_unicode_as_demo_does() -> None:
    result = run("derive", "example:knife-edge", "--model", "chaplygin", "--format", "pretty")
    assert result.exit_code == 0, result.output
    out = result.stdout
    assert out.startswith("Chaplygin's equations, eq. (15) - Knife edge\n")
    assert "\N{GREEK SMALL LETTER PHI}\N{COMBINING DIAERESIS}" in out  # φ with two dots
    assert "x\N{COMBINING DIAERESIS}" in out and "cos(\N{GREEK SMALL LETTER PHI})" in out
    assert "phi''" not in out and "**" not in out and "Derivative" not in out
    assert "\nSolved:\n" in out
    # the equations exactly as `chaplygin demo` prints a system's equations (Equations.pretty)
    demo_style = examples.get("knife-edge").constructor().equations("chaplygin").pretty()
    assert out.split("\nSolved:\n")[0].rstrip() == demo_style.rstrip()
    text = run("derive", "example:knife-edge", "--model", "chaplygin").stdout
    assert "phi''" in text and "φ" not in text  # -f text stays the file syntax


# ---------------------------------------------------------------- CSV numbers
def test_csv_numbers_are_the_shortest_round_trip(tmp_path: Path) -> None:
    entry = examples.get("knife-edge")
    start = {**entry.initial, "x'": 0.3}
    tr = chaplygin.simulate(entry.constructor(), "chaplygin", 1.0, start, entry.parameters, samples=11)
    path = tr.to_csv(tmp_path / "knife.csv")
    lines = path.read_text().splitlines()
    assert lines[0] == ",".join(tr.columns)
    back = np.loadtxt(path, delimiter=",", skiprows=1)
    assert np.array_equal(back, tr.table())  # every float bit for bit
    first = dict(zip(lines[0].split(","), lines[1].split(",")))
    assert first["x'"] == "0.3" and first["t"] == "0.0"
    assert "0.29999999999999999" not in path.read_text()
    for line in lines[1:]:
        for field in line.split(","):
            assert repr(float(field)) == field  # the shortest text of that float


def test_simulate_command_writes_shortest_numbers(tmp_path: Path) -> None:
    out = tmp_path / "run.csv"
    args = ["simulate", "example:knife-edge", "-m", "chaplygin", "-t", "1", "-n", "11", "-o", out]
    assert run(*args, "--initial", "x'=0.3").exit_code == 0
    header, first = out.read_text().splitlines()[:2]
    assert dict(zip(header.split(","), first.split(",")))["x'"] == "0.3"


# ---------------------------------------------------------------- no SymPy internals in messages
SYMPY_INTERNALS = re.compile(r"Derivative\(|\(t\)|Dummy|Symbol\(|_dd\b|\b_[a-z]")


def message(call) -> str:
    with pytest.raises(ChaplyginError) as caught:
        call()
    text = str(caught.value)
    assert not SYMPY_INTERNALS.search(text), text
    return text


@pytest.fixture
def knife() -> tuple[System, tuple[sp.Expr, ...], tuple[sp.Symbol, ...]]:
    x, y, phi = dynamicsymbols("x y phi")
    m, J = sp.symbols("m J", positive=True)
    system = System(
        coordinates=[x, y, phi],
        kinetic_energy=m / 2 * (x.diff(T_) ** 2 + y.diff(T_) ** 2) + J / 2 * phi.diff(T_) ** 2,
        constraints={y.diff(T_): sp.tan(phi) * x.diff(T_)},
    )
    return system, (x, y, phi), (m, J)


def test_do_not_determine_names_the_accelerations_as_files_do(knife) -> None:
    system, (x, _, phi), (m, _) = knife
    chap = system.equations("chaplygin")
    text = message(lambda: chaplygin.equivalent(system, [m * x.diff(T_, 2)], chap))
    assert "do not determine phi''" in text
    text = message(lambda: chaplygin.classify(system, [m * x.diff(T_, 2)]))
    assert "phi''" in text
    same = [x.diff(T_, 2) + phi.diff(T_, 2)] * 2
    text = message(lambda: chaplygin.equivalent(system, same, chap))
    assert "do not determine all of x'', phi''" in text


def test_other_messages_name_expressions_in_the_file_syntax(knife) -> None:
    system, (x, _, phi), (m, J) = knife
    chap = system.equations("chaplygin")
    assert "x'''" in message(lambda: chaplygin.equivalent(system, [x.diff(T_, 3), phi.diff(T_, 2)], chap))
    numbers = {"m": 1.0, "J": 1.0}
    assert "x''" in message(
        lambda: chaplygin.simulate(system, "chaplygin", 1.0, {x.diff(T_, 2): 1.0}, numbers)
    )
    free = {"coordinates": [x, phi], "constraints": {}}
    T = m / 2 * x.diff(T_) ** 2
    assert "x''" in message(lambda: System(**free, kinetic_energy=T + m * x.diff(T_, 2)))
    assert "forces[phi]" in message(lambda: System(**free, kinetic_energy=T, forces={phi: "J"}))
    assert "phi is not a parameter" in message(lambda: system.parameter(phi))
    state = {x: "a", "y": 0.0, "phi": 0.0, "x'": 1.0, "phi'": 0.0}
    assert "x = 'a' is not a number" in message(
        lambda: chaplygin.simulate_ensemble(system, "chaplygin", 1.0, [state], numbers)
    )
