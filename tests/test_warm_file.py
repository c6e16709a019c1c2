"""A run of a system file imports only what it uses (issue 31): no ``sympy.physics`` (its
mechanics and units, 0.15 s) unless the user asks for it.  Read off ``sys.modules`` of a fresh
process; nothing is timed.
"""

from __future__ import annotations

import pytest

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
tr = chaplygin.simulate(f.system, "chetaev", 2.0, f.initial, f.parameters, samples=11)
print(json.dumps({
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


def test_a_file_without_a_body_imports_no_mechanics(tmp_path, snakeboard):
    """sympy.physics.mechanics (and units) only when the user asks: not to load and run a file
    written with coordinates, nor to derive and simulate it from the command line."""
    run = run_json(SCRIPT, [str(snakeboard)], tmp_path / "cache")
    assert run["imported"] == {
        "sympy": True,
        "sympy.physics.mechanics": False,
        "sympy.physics.units": False,
    }
    cli = run_json(CLI, [str(snakeboard), str(tmp_path / "out.csv")], tmp_path / "cli-cache")
    assert cli == {"codes": [0, 0], "mechanics": False, "stdout": cli["stdout"]}
