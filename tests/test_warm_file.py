"""A run of a system file imports only what it uses (issue 31).

No ``sympy.physics`` (its mechanics and units, 0.15 s) unless the user asks for it.  And
``chaplygin.load(FILE)`` of bytes run before returns the file from the summary its run plan
keeps, without building the system; ``chaplygin.simulate(f, model, t)`` runs the plan
(:mod:`chaplygin.numeric._plan`) and must give what the full path gives.  Whether the system was
built is read off the loaded file (``"system" in vars(f)``); whether SymPy or
``sympy.physics`` were imported, off ``sys.modules`` of a fresh process.  Nothing is timed.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import chaplygin
from chaplygin.errors import ChaplyginError
from chaplygin.io.files import SystemFileError, loads
from chaplygin.numeric import cache
from subprocesses import run_json

# the snakeboard: implicit constraints, solved for x', y' (benchmarks/systems)
SNAKEBOARD = """\
name = "Snakeboard with a steering spring"
coordinates = ["x", "y", "theta", "psi", "phi"]
[parameters]
m = 1.0
l = 0.5
J = 0.1
Jr = 0.05
[energy]
T = "m/2*(x'^2 + y'^2) + J/2*theta'^2 + Jr/2*psi'^2 + Jr*theta'*psi' + phi'^2/2"
V = "50*(phi - 1/2)^2"
[constraints]
implicit = [
  "-sin(theta + phi)*x' + cos(theta + phi)*y' - l*cos(phi)*theta'",
  "-sin(theta - phi)*x' + cos(theta - phi)*y' + l*cos(phi)*theta'",
]
dependent = ["x", "y"]
[initial]
phi = 0.3
"theta'" = 0.2
"psi'" = 1.0
"""
RUN = {"samples": 11}

# a process that loads the file, runs it from the Python API and says what it imported
SCRIPT = """
import json, sys
import chaplygin
f = chaplygin.load(sys.argv[1])
lazy = "system" not in vars(f)
if sys.argv[2] == "file":
    tr = chaplygin.simulate(f, "chetaev", 2.0, samples=11)
else:
    tr = chaplygin.simulate(f.system, "chetaev", 2.0, f.initial, f.parameters, samples=11)
print(json.dumps({
    "lazy": lazy,
    "imported": {m: m in sys.modules for m in ("sympy", "sympy.physics.mechanics", "sympy.physics.units")},
    "columns": {k: tr[k].tolist() for k in tr.columns},
}))
"""
# a process that runs the command line on the file, then says what it imported
CLI = """
import json, sys
from chaplygin.apps.cli import main
codes = [main(["derive", sys.argv[1], "-m", "chetaev"]),
         main(["simulate", sys.argv[1], "-m", "chetaev", "-t", "1", "-n", "11", "-o", sys.argv[2]])]
print(json.dumps({"codes": codes, "mechanics": "sympy.physics.mechanics" in sys.modules}))
"""


@pytest.fixture
def snakeboard(tmp_path, monkeypatch):
    monkeypatch.setenv("CHAPLYGIN_CACHE", str(tmp_path / "cache"))  # cold: no plan, no summary
    path = tmp_path / "snakeboard.toml"
    path.write_text(SNAKEBOARD, encoding="utf-8")
    return path


def same(a: chaplygin.Trajectory, b: chaplygin.Trajectory) -> bool:
    """Every column, the status and the labels of two runs equal, bit for bit."""
    columns = a.columns == b.columns and all(np.array_equal(a[k], b[k]) for k in a.columns)
    labels = (
        "status",
        "message",
        "failure",
        "model",
        "backend",
        "energy_column",
        "energy_conserved",
        "notes",
    )
    return columns and all(getattr(a, k) == getattr(b, k) for k in labels)


def test_a_file_without_a_body_imports_no_mechanics(tmp_path, snakeboard):
    """sympy.physics.mechanics (and units) only when the user asks: not to load and run a file
    written with coordinates, nor to derive and simulate it from the command line."""
    run = run_json(SCRIPT, [str(snakeboard), "system"], tmp_path / "cache")
    assert run["imported"] == {
        "sympy": True,
        "sympy.physics.mechanics": False,
        "sympy.physics.units": False,
    }
    cli = run_json(CLI, [str(snakeboard), str(tmp_path / "out.csv")], tmp_path / "cli-cache")
    assert cli == {"codes": [0, 0], "mechanics": False, "stdout": cli["stdout"]}


def test_a_warm_run_of_a_loaded_file_imports_no_sympy(tmp_path, snakeboard):
    cold = run_json(SCRIPT, [str(snakeboard), "file"], tmp_path / "cache")
    warm = run_json(SCRIPT, [str(snakeboard), "file"], tmp_path / "cache")
    assert not cold["lazy"] and cold["imported"]["sympy"]
    assert warm["lazy"] and not any(warm["imported"].values())
    assert warm["columns"] == cold["columns"]  # the floats of both, as JSON writes them exactly
    # the full path from the System, the route a SymPy user writes, gives the same motion
    f = chaplygin.load(snakeboard)
    tr = chaplygin.simulate(f.system, "chetaev", 2.0, f.initial, f.parameters, **RUN)
    assert json.loads(json.dumps({k: tr[k].tolist() for k in tr.columns})) == cold["columns"]


def test_the_plan_answers_what_the_full_path_would(snakeboard):
    """A file's [initial] and [parameters] are defaults that explicit arguments override; the plan
    answers exactly the runs the full path would run the same (anything else takes the full
    path: the system is built)."""
    first = chaplygin.load(snakeboard)
    assert "system" in vars(first)  # no plan yet: read and validated as always
    system, initial, parameters = first.system, first.initial, first.parameters
    tr = chaplygin.simulate(first, "chetaev", 2.0, **RUN)
    assert same(tr, chaplygin.simulate(system, "chetaev", 2.0, initial, parameters, **RUN))

    def warm(model: str, *args: dict) -> tuple[chaplygin.Trajectory, bool]:
        f = chaplygin.load(snakeboard)
        assert "system" not in vars(f) and f.parameters == parameters and f.initial == initial
        tr = chaplygin.simulate(f, model, 2.0, *args, **RUN)
        return tr, "system" in vars(f)

    planned, built = warm("chetaev")
    assert same(planned, tr) and not built
    # another start or parameter: a multiplier model's plan answers only the start it kept
    for override in ({"phi": 0.2}, {"psi'": 2.0}):
        other, built = warm("chetaev", override)
        assert built and same(
            other, chaplygin.simulate(system, "chetaev", 2.0, {**initial, **override}, parameters, **RUN)
        ), override
    moved = chaplygin.load(snakeboard)
    moved.initial["phi"] = 0.2  # the file's numbers as they are at the run
    expected = chaplygin.simulate(system, "chetaev", 2.0, {**initial, "phi": 0.2}, parameters, **RUN)
    assert same(chaplygin.simulate(moved, "chetaev", 2.0, **RUN), expected) and "system" in vars(moved)
    other, built = warm("chetaev", {}, {"m": 2.0})
    assert built and same(
        other, chaplygin.simulate(system, "chetaev", 2.0, initial, {**parameters, "m": 2.0}, **RUN)
    )
    # a reduced model's plan takes other velocities (its state), and another configuration or
    # parameter where its start checks pass by a wide margin; near a pole (det = -sin 2 phi) the
    # full path decides
    chaplygin.simulate(chaplygin.load(snakeboard), "chaplygin", 2.0, **RUN)
    for override, numbers, planned in (
        ({"psi'": 2.0}, {}, True),
        ({"phi": 0.2}, {}, True),
        ({}, {"m": 2.0}, True),
        ({"phi": 1e-5, "theta'": 0.0}, {}, False),  # (condition number 5e10: within 100x of the limit)
    ):
        other, built = warm("chaplygin", override, numbers)
        assert built is not planned and same(
            other,
            chaplygin.simulate(
                system, "chaplygin", 2.0, {**initial, **override}, {**parameters, **numbers}, **RUN
            ),
        ), override


@pytest.mark.parametrize("broken", ["non-finite", "pole"])
def test_a_run_the_full_path_would_judge_takes_the_full_path(snakeboard, monkeypatch, broken):
    """A multiplier model's plan does not judge a run that failed or went non-finite: the full
    path's watch (its cut, its message, its failure label) decides, so both routes agree."""
    from chaplygin.numeric import simulate as module

    chaplygin.simulate(chaplygin.load(snakeboard), "chetaev", 2.0, **RUN)  # the plan
    integrate = module.integrate

    def breaking(*args, **kwargs):  # what a run that meets trouble at its 6th sample returns
        tr = integrate(*args, **kwargs)
        if broken == "non-finite":
            tr.velocities["x'"][5:] = np.nan
        else:  # the compiled loop's own report of a singular step (its code 9)
            tr.status, tr.message = "failed", "a pole at t = 1: the mass matrix is singular"
        return tr

    monkeypatch.setattr(module, "integrate", breaking)
    f = chaplygin.load(snakeboard)
    tr = chaplygin.simulate(f, "chetaev", 2.0, **RUN)
    assert "system" in vars(f) and tr.status == "failed"
    assert tr.failure == "pole" and len(tr.t) == (11 if broken == "pole" else 5)  # (cut at the 6th)
    assert same(tr, chaplygin.simulate(f.system, "chetaev", 2.0, f.initial, f.parameters, **RUN))


def test_a_file_from_its_summary_is_the_file(snakeboard):
    eager = chaplygin.load(snakeboard)
    chaplygin.simulate(eager, "chetaev", 1.0, **RUN)  # the plan, and the file's summary
    lazy = chaplygin.load(snakeboard)
    assert "system" not in vars(lazy)
    assert (lazy.name, lazy.source, lazy.defaulted, lazy.body) == (
        eager.name,
        eager.source,
        eager.defaulted,
        eager.body,
    )
    assert list(lazy.initial.items()) == list(eager.initial.items())  # in the file's order
    assert list(lazy.parameters.items()) == list(eager.parameters.items())
    assert lazy.dumps() == eager.dumps() and lazy.exact == eager.exact  # the system, built on use
    assert lazy.system.kinetic_energy == eager.system.kinetic_energy and lazy.system.A == eager.system.A


def test_changed_bytes_are_read_and_refused_as_before(snakeboard):
    chaplygin.simulate(chaplygin.load(snakeboard), "chetaev", 1.0, **RUN)
    bad = SNAKEBOARD.replace("J = 0.1", "J = 0.1\nK = 2.0")  # an unused parameter
    snakeboard.write_text(bad, encoding="utf-8")
    with pytest.raises(SystemFileError) as raised:
        chaplygin.load(snakeboard)
    with pytest.raises(SystemFileError) as expected:
        loads(bad, source=str(snakeboard))
    assert str(raised.value) == str(expected.value) and "K is not used" in str(raised.value)


def test_a_summary_of_another_shape_is_ignored(snakeboard):
    from chaplygin.numeric import _plan

    raw = snakeboard.read_bytes()
    cache.store(_plan.summary_key(raw, "snakeboard"), {"name": 1})
    assert "system" in vars(chaplygin.load(snakeboard))  # read as if there were none


def test_a_system_needs_an_initial_state(snakeboard):
    f = chaplygin.load(snakeboard)
    with pytest.raises(ChaplyginError, match="initial: no initial state"):
        chaplygin.simulate(f.system, "chetaev", 1.0)


# a reduced mass matrix that runs out: with z' = x' it is diag(3 - y, 1) in (x', y'), and a start
# with x' = 0 keeps x' = 0 (d/dt((3 - y) x') = 0) while y = y'·t passes 3 at t = 3/y'
RUNNING_OUT = """\
name = "A mass that runs out"
coordinates = ["x", "y", "z"]
[energy]
T = "((2 - y)*x'^2 + y'^2 + z'^2)/2"
[constraints]
"z'" = "x'"
[initial]
x = 0.0
y = 0.0
z = 0.0
"x'" = 0.0
"y'" = 0.0
"""
# a process that runs a file from the Python API and the command line, with overrides
OVERRIDDEN = """
import json, sys
from pathlib import Path
import chaplygin
from chaplygin.apps.cli import main
path, model, backend, out = sys.argv[1:5]
given = json.loads(sys.argv[5])
f = chaplygin.load(path)
tr = chaplygin.simulate(f, model, 4.0, given, samples=11, backend=backend)
flags = [a for k, v in given.items() for a in ("--initial", f"{k}={v}")]
code = main(["simulate", path, "-m", model, "-t", "4", "-n", "11", "-b", backend, "-o", out, *flags])
print(json.dumps({
    "lazy": "system" not in vars(f),
    "sympy": "sympy" in sys.modules,
    "columns": {k: tr[k].tolist() for k in tr.columns},
    "labels": [tr.status, tr.failure, tr.message],
    "code": code,
    "csv": Path(out).read_text(encoding="utf-8"),
}))
"""


@pytest.mark.parametrize(
    ("text", "model", "backend", "given", "failure", "cut"),
    [  # the snakeboard's solved constraints have a pole where sin(2 phi) = 0: phi' = -10 swings phi past 0
        (SNAKEBOARD, "chaplygin", "c", {"phi'": -10.0}, "pole", 1),
        (RUNNING_OUT, "voronets", "numpy", {"y'": 1.0}, "mass", 8),
    ],
)
def test_a_warm_reduced_run_is_judged_as_the_full_path(
    tmp_path, monkeypatch, text, model, backend, given, failure, cut
):
    """A reduced model's plan answers other velocities: a warm run (no SymPy) that meets a pole of
    the solved constraints or a mass matrix losing definiteness stops where the full path stops,
    with its columns, status, failure and message, from the Python API and the command line
    (before, both integrated through and reported success)."""
    monkeypatch.setenv("CHAPLYGIN_CACHE", str(tmp_path / "cache"))
    path = tmp_path / "system.toml"
    path.write_text(text, encoding="utf-8")
    f = chaplygin.load(path)
    chaplygin.simulate(f, model, 4.0, samples=11, backend=backend)  # the plan, from the file's numbers
    expected = chaplygin.simulate(
        f.system, model, 4.0, {**f.initial, **given}, f.parameters, samples=11, backend=backend
    )
    assert (expected.status, expected.failure, len(expected.t)) == ("failed", failure, cut)
    out = tmp_path / "out.csv"
    warm = run_json(OVERRIDDEN, [str(path), model, backend, str(out), json.dumps(given)], tmp_path / "cache")
    assert warm["lazy"] and not warm["sympy"]
    assert warm["columns"] == json.loads(json.dumps({k: expected[k].tolist() for k in expected.columns}))
    assert warm["labels"] == [expected.status, expected.failure, expected.message]
    expected.to_csv(tmp_path / "expected.csv")
    assert warm["code"] == 3 and warm["csv"] == (tmp_path / "expected.csv").read_text(encoding="utf-8")


def test_a_start_on_a_pole_is_refused_warm_as_cold(snakeboard):
    """phi = 0 is a pole of the snakeboard's solved constraints: the plan does not answer another
    configuration, and the full path refuses it with its message."""
    f = chaplygin.load(snakeboard)
    chaplygin.simulate(f, "chaplygin", 2.0, **RUN)  # the plan
    with pytest.raises(ChaplyginError) as cold:
        chaplygin.simulate(f.system, "chaplygin", 2.0, {**f.initial, "phi": 0.0}, f.parameters, **RUN)
    with pytest.raises(ChaplyginError) as warm:
        chaplygin.simulate(chaplygin.load(snakeboard), "chaplygin", 2.0, {"phi": 0.0}, **RUN)
    assert str(warm.value) == str(cold.value) and "pole of the solved constraints" in str(cold.value)
