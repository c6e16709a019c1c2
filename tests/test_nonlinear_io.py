"""Constraints nonlinear in the velocities (issue 30) in system files, the CLI, the report and the
analysis: the branch kept through a round trip, errors that name the key, integrability that
does not apply Frobenius to them, check/derive/report/compare on a file written here, and
classify/equivalent against equations derived by hand.

The two systems are written here, not taken from the gallery: the isokinetic particle
(ẋ² + ẏ² = v² under gravity; by hand, with x the dependent coordinate and ẋ = √(v² − ẏ²) > 0,
Novoselov's equation is m v² ÿ/(v² − ẏ²) + m g = 0, ÿ = −g (v² − ẏ²)/v², the "grim reaper";
its reduced vakonomic family is c v² ÿ = −m g (v² − ẏ²)^{3/2}, the catenaries
y'' = −(m g/c) √(1 + y'²) in x) and Appell's weight (ż = k √(ẋ² + ẏ²), homogeneous of degree 1).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols
from typer.testing import CliRunner

from chaplygin import equivalent
from chaplygin.analysis.transitions import classify, compare_models
from chaplygin.apps.cli import app
from chaplygin.errors import ModelError
from chaplygin.io.files import SystemFileError, loads

t = dynamicsymbols._t
runner = CliRunner()

ISOKINETIC = """\
name = "Isokinetic particle"
coordinates = ["x", "y"]

[parameters]
m = 1.0
g = 9.81
v = 1.0

[energy]
T = "m/2*(x'^2 + y'^2)"
V = "m*g*y"

[constraints]
implicit = ["x'^2 + y'^2 - v^2"]
dependent = ["x"]
branch = 1

[initial]
"y'" = 0.3
"""

APPELL = """\
name = "Appell's weight"
coordinates = ["x", "y", "z"]

[parameters]
m = 1.0
g = 9.81
k = 0.5

[energy]
T = "m/2*(x'^2 + y'^2 + z'^2)"
V = "m*g*z"

[constraints]
"z'" = "k*sqrt(x'^2 + y'^2)"

[initial]
"x'" = 1.0
"y'" = 0.5
"""


def run(*args: str):
    return runner.invoke(app, list(args))


@pytest.fixture
def files(tmp_path: Path) -> dict[str, Path]:
    out = {}
    for name, text in (("iso", ISOKINETIC), ("appell", APPELL)):
        out[name] = tmp_path / f"{name}.toml"
        out[name].write_text(text, encoding="utf-8")
    return out


def _symbols(system):
    return {p.name: p for p in system.parameters}


# ---------------------------------------------------------------- files
def test_implicit_constraints_with_a_branch_round_trip() -> None:
    sf = loads(ISOKINETIC)
    s = sf.system
    x, y = s.coordinates
    v = _symbols(s)["v"]
    assert s.is_nonlinear and s._branch == 1
    # branch 1 of x'^2 + y'^2 = v^2 is the positive root (by hand)
    assert sp.simplify(s.constraints[x.diff(t)] - sp.sqrt(v**2 - y.diff(t) ** 2)) == 0
    text = sf.dumps()
    assert "branch = 1" in text and 'dependent = ["x"]' in text
    back = loads(text)
    assert back.system._branch == 1 and back.system.constraints == s.constraints
    assert back.initial == sf.initial == {"x": 0.0, "y": 0.0, "y'": 0.3}
    # the other branch is the negative root
    other = loads(ISOKINETIC.replace("branch = 1", "branch = 0")).system
    assert sp.simplify(other.constraints[x.diff(t)] + sp.sqrt(v**2 - y.diff(t) ** 2)) == 0


def test_solved_nonlinear_constraints_round_trip() -> None:
    sf = loads(APPELL)
    x, y, z = sf.system.coordinates
    k = _symbols(sf.system)["k"]
    assert sf.system.constraints == {z.diff(t): k * sp.sqrt(x.diff(t) ** 2 + y.diff(t) ** 2)}
    text = sf.dumps()
    assert "branch" not in text and '"z\'" = "k*sqrt(x\'^2 + y\'^2)"' in text
    assert loads(text).system.constraints == sf.system.constraints


IMPLICIT = 'implicit = ["x\'^2 + y\'^2 - v^2"]\ndependent = ["x"]\n'


@pytest.mark.parametrize(
    ("old", "new", "head", "shown"),
    [
        (
            "branch = 1\n",
            "",
            "[constraints] implicit: the implicit constraints have 2 solutions",
            "branch=1: x' = sqrt(v**2 - y'**2)",
        ),
        (
            "branch = 1",
            "branch = 5",
            "[constraints] branch: expected an integer from 0 to 1, got 5",
            "    branch = 5",
        ),
        (
            "branch = 1",
            'branch = "1"',
            "[constraints] branch: branch must be a whole number",
            "branch = K picks one",
        ),
        (
            "branch = 1",
            "branch = -1",
            "[constraints] branch: branch must be a whole number",
            "branch = K picks one",
        ),
        (
            IMPLICIT + "branch = 1",
            '"x\'" = "sqrt(v^2 - y\'^2)"\nbranch = 0',
            "[constraints] branch: branch chooses a solution of implicit",
            "Remove branch",
        ),
        (
            "x'^2 + y'^2 - v^2",
            "x' - v*y'",
            "[constraints] branch: the constraints are linear in the velocities",
            "    branch = 1",
        ),
        (
            IMPLICIT + "branch = 1",
            IMPLICIT.replace("x'^2 + y'^2 - v^2", "(x' - v*y')^2"),
            "[constraints] implicit (item 1): ∂f/∂(x') is singular",
            "    (x' - v*y')^2",
        ),
        (
            "x'^2 + y'^2 - v^2",
            "x'^2 + y'^2 - v^2/100",
            "[constraints] implicit: no real value of x' at the initial state (y' = 0.3)",
            "or another branch",
        ),
        (
            '"y\'" = 0.3',
            '"y\'" = 2.0',
            "[constraints] implicit: no real value of x' at the initial state (y' = 2)",
            "x' = sqrt(v**2 - y'**2) = 0+1.73205i",
        ),
        (
            IMPLICIT + "branch = 1",
            IMPLICIT.replace("x'^2 + y'^2 - v^2", "x'^5 + x' + y'^7 + exp(x')"),
            "[constraints] implicit: SymPy cannot solve the implicit constraints for x'",
            "Give them solved instead",
        ),
        (
            "[initial]",
            '[holonomic]\ny = "y - x"\n\n[initial]',
            "[holonomic]: holonomic constraints beside constraints nonlinear",
            "[holonomic] gives relations",
        ),
    ],
)
def test_errors_of_nonlinear_constraints_name_the_key(old: str, new: str, head: str, shown: str) -> None:
    assert old in ISOKINETIC
    text = ISOKINETIC.replace(old, new)
    with pytest.raises(SystemFileError) as err:
        loads(text, source="iso.toml")
    message = str(err.value)
    assert message.startswith(f"iso.toml: {head}"), message
    assert shown in message, message
    assert "Traceback" not in message


# ---------------------------------------------------------------- analysis
def test_integrability_does_not_apply_frobenius_to_nonlinear_constraints() -> None:
    report = loads(APPELL).system.integrability()
    assert report.integrable is False
    assert [c.holds for c in (report.condition_28, report.condition_33, report.frobenius)] == [None] * 3
    assert report.verdict.startswith("not integrable (nonholonomic): the constraints are nonlinear")
    assert "Frobenius: not applicable" in str(report)
    with pytest.raises(ModelError, match="not integrable: the constraints are nonlinear in the velocities"):
        report.holonomic_system()


def test_a_branch_linear_in_the_velocities_is_tested_as_linear() -> None:
    # z'^2 = x'^2: branch 1 is z' = x', integrable, z - x constant (by hand)
    text = """
coordinates = ["x", "z"]
[parameters]
m = 1.0
[energy]
T = "m/2*(x'^2 + z'^2)"
[constraints]
implicit = ["z'^2 - x'^2"]
dependent = ["z"]
branch = 1
[initial]
"x'" = 1.0
"""
    s = loads(text).system
    x, z = s.coordinates
    assert s.constraints == {z.diff(t): x.diff(t)}
    report = s.integrability()
    assert report.integrable and report.frobenius.holds is True
    assert "on the branch chosen they are linear, z' = x'" in report.verdict
    (relation,) = report.relations
    assert sp.expand(relation - (z - x)) == 0 or sp.expand(relation + (z - x)) == 0


def test_classify_and_equivalent_against_hand_derived_equations() -> None:
    s = loads(ISOKINETIC).system
    x, y = s.coordinates
    p = _symbols(s)
    g, m, v = p["g"], p["m"], p["v"]
    yd, ydd = y.diff(t), y.diff(t, 2)
    reaper = {ydd: -g * (v**2 - yd**2) / v**2}  # the true (Chetaev) motion, by hand
    assert equivalent(s, reaper, s.equations("chetaev"), symbolic=False)
    assert equivalent(s, s.equations("chaplygin"), s.equations("chetaev"))
    assert classify(s, reaper).verdict == "chetaev"
    # a catenary of the vakonomic family, by hand: c v^2 y'' = -m g (v^2 - y'^2)^(3/2), c = 0.7
    catenary = {ydd: -m * g * (v**2 - yd**2) ** sp.Rational(3, 2) / (sp.Rational(7, 10) * v**2)}
    found = classify(s, catenary)
    assert found.verdict == "vakonomic" and found.constants == {"c_1": pytest.approx(0.7, rel=1e-9)}
    # Lindelöf's equations (T̃ = m v²/2 is constant) contain no acceleration here
    assert found.residuals["lindelof"] == float("inf") and "Lindelöf's equations do not" in found.note
    assert classify(s, {ydd: -g}).verdict == "none"
    # no Lindelöf equations (T̃ degenerate), so no defect against them (tests/test_nonlinear_review.py)
    comparison = compare_models(s)
    assert comparison.verdict == "no_lindelof" and comparison.condition_28 is None and not comparison.defect


# ---------------------------------------------------------------- the command line
def test_check_says_nonlinear_branch_singular_set_and_work(files: dict[str, Path]) -> None:
    doc = json.loads(run("check", str(files["iso"]), "--format", "json").stdout)
    assert doc["nonlinear"] is True and doc["branch"] == 1 and doc["homogeneous"] is False
    assert doc["solved"] == {"x'": "sqrt(v**2 - y'**2)"}
    assert doc["singular_set"] == ["v**2 - y'**2"]
    assert doc["integrability"]["integrable"] is False
    assert doc["integrability"]["frobenius"]["holds"] is None
    assert doc["comparison"]["verdict"] == "no_lindelof" and doc["comparison"]["condition_28"] is None
    assert doc["comparison"]["defect"] == {} and "degenerate" in doc["comparison"]["lindelof_obstruction"]
    text = run("check", str(files["iso"]))
    assert text.exit_code == 0
    assert (
        "Nonlinear in the velocities: x' = sqrt(v**2 - y'**2) (branch 1 of the implicit constraints); "
        "not homogeneous of degree 1 in the velocities: the constraint forces do work" in text.stdout
    )
    assert "Singular (no smooth solution for the dependent velocities) where v**2 - y'**2 = 0." in text.stdout
    assert "Constraints: not integrable (nonholonomic): the constraints are nonlinear" in text.stdout
    appell = run("check", str(files["appell"]))
    assert "homogeneous of degree 1 in the velocities: the constraint forces do no work" in appell.stdout
    linear = json.loads(run("check", "example:knife-edge", "--format", "json").stdout)
    assert linear["nonlinear"] is False and "branch" not in linear


def test_derive_prints_novoselovs_equations_tidy(files: dict[str, Path]) -> None:
    out = run("derive", str(files["iso"]), "--model", "chaplygin")
    assert out.exit_code == 0
    lines = out.stdout.splitlines()
    assert lines[0].startswith("Novoselov's equations")
    # by hand: m v² ÿ = −m g (v² − ẏ²)
    assert lines[1].strip() == "m*v**2*y'' = -g*m*(v**2 - y'**2)"
    assert "y'' = -g*(v**2 - y'**2)/v**2" in out.stdout


def test_report_says_the_constraints_are_nonlinear_and_do_work(
    files: dict[str, Path], tmp_path: Path
) -> None:
    out = tmp_path / "iso.html"
    args = ["report", str(files["iso"]), "-m", "chetaev", "-o", str(out), "-t", "0.5", "-n", "11"]
    result = run(*args)
    assert result.exit_code == 0, result.output
    page = out.read_text(encoding="utf-8")
    assert "<b>nonlinear in the velocities</b>, branch 1 of the implicit constraints" in page
    assert "so the constraint forces <b>do work</b> along the motion: their power" in page
    power = page.split("their power")[1].split("</math>")[0]  # the Chetaev power 2 v² λ₁
    assert "<msub><mi>&#955;</mi><mi>1</mi></msub>" in power and "<mi>v</mi><mn>2</mn>" in power
    assert "the constraints are nonlinear in the velocities" in page  # the integrability verdict
    assert "Novoselov's equations" in page
    # no Lindelöf equations here, so no defect against them (on addde7f: "the models differ")
    assert "Verdict: <code>no_lindelof</code>" in page and "Lindelöf defect" not in page
    # the residual legend names the constraint functions (on addde7f: "max_β |Σ A_βs q̇_s + A_β0|")
    assert "Constraint residual: max_β |f_β|" in page
    out2 = tmp_path / "appell.html"
    result = run("report", str(files["appell"]), "-o", str(out2), "-t", "0.2", "-n", "11")
    assert result.exit_code == 0, result.output
    assert "so the constraint forces do no work" in out2.read_text(encoding="utf-8")


def test_compare_on_a_nonlinear_file(files: dict[str, Path]) -> None:
    # Appell's example: the vakonomic motion is the true one (Appell 1911; issue 30)
    result = run("compare", str(files["appell"]), "-t", "0.2", "-n", "11")
    assert result.exit_code == 0, result.output
    rows = {line.split()[0]: line.split() for line in result.stdout.splitlines()[2:4]}
    assert set(rows) == {"voronets", "vakonomic"}
    assert float(rows["vakonomic"][1]) < 1e-8


def test_solved_accelerations_use_that_a_root_squared_is_its_radicand(files: dict[str, Path]) -> None:
    # Appell (1911): the speed falls at g k/(1 + k²) along the path, z'' = -g k²/(1 + k²);
    # before (√b)² = b was applied, x'' was a fraction of 16 terms over 15 that did not cancel
    out = run("derive", str(files["appell"]), "--model", "chetaev")
    assert out.exit_code == 0
    solved = out.stdout.split("Solved:")[1].splitlines()
    assert [line.strip() for line in solved[1:5]] == [
        "x'' = -g*k*x'/((k**2 + 1)*sqrt(x'**2 + y'**2))",
        "y'' = -g*k*y'/((k**2 + 1)*sqrt(x'**2 + y'**2))",
        "z'' = -g*k**2/(k**2 + 1)",
        "lambda_1 = g*m/(k**2 + 1)",
    ]
    voronets = run("derive", str(files["appell"]), "--model", "voronets").stdout
    assert "x'' = -g*k*x'/((k**2 + 1)*sqrt(x'**2 + y'**2))" in voronets
