"""Review fixes for constraints nonlinear in the velocities (issue 30, part B): the model
comparison where Lindelöf's equations do not apply, its defect printed short, and the stability
command's pointer to the reduced vakonomic form.

The systems are written here.  The polar isokinetic particle on a spring (ṙ² + r² θ̇² = v², θ the
dependent coordinate): T̃ = m v²/2 is a constant, so Lagrange's equations on T̃ (Lindelöf's) do
not exist.  The "relativistic" particle ż² = ẋ² + ẏ² + c² (z dependent, ż = S = √(ẋ² + ẏ² + c²)):
T̃ = m (ẋ² + ẏ² + S²)/2 is regular and, by hand, with p = m S and W_x = −d/dt(ẋ/S),
the Lindelöf defect in x is p W_x = m (ẋ ẏ ÿ − (ẏ² + c²) ẍ)/S².
"""

from __future__ import annotations

from pathlib import Path

import pytest
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols
from typer.testing import CliRunner

from chaplygin.analysis.transitions import compare_models
from chaplygin.apps.cli import app
from chaplygin.io.files import SystemFileError, loads

t = dynamicsymbols._t
runner = CliRunner()

POLAR = """\
name = "Polar isokinetic spring"
coordinates = ["r", "th"]

[parameters]
m = 1.0
kk = 2.0
v = 1.0

[energy]
T = "m/2*(r'^2 + r^2*th'^2)"
V = "kk/2*r^2"

[constraints]
implicit = ["r'^2 + r^2*th'^2 - v^2"]
dependent = ["th"]
branch = 1

[initial]
r = 0.5
"""

RELATIVISTIC = """\
name = "Relativistic particle"
coordinates = ["x", "y", "z"]

[parameters]
m = 1.0
g = 9.81
c = 1.0

[energy]
T = "m/2*(x'^2 + y'^2 + z'^2)"
V = "m*g*x"

[constraints]
implicit = ["z'^2 - x'^2 - y'^2 - c^2"]
dependent = ["z"]
branch = 1
"""


@pytest.fixture
def polar(tmp_path: Path) -> Path:
    path = tmp_path / "polar.toml"
    path.write_text(POLAR, encoding="utf-8")
    return path


def test_check_says_lindelof_does_not_apply_instead_of_a_defect(polar: Path) -> None:
    # on addde7f: "the models differ: Novoselov's equations = Lindelöf's (22) + the defect below."
    comparison = compare_models(loads(POLAR).system)
    assert comparison.verdict == "no_lindelof" and comparison.defect == {}
    assert "degenerate" in (comparison.lindelof_obstruction or "")
    out = runner.invoke(app, ["check", str(polar)]).stdout
    assert "Lindelöf's equations do not apply (T̃ = m*v**2/2" in out and "degenerate" in out
    assert "the models differ" not in out and "defect" not in out
    assert "vakonomic_family" in out


def test_nonlinear_defect_is_printed_cancelled() -> None:
    s = loads(RELATIVISTIC).system
    x, y, _ = s.coordinates
    c, m = (next(p for p in s.parameters if p.name == n) for n in ("c", "m"))
    xd, yd, xdd, ydd = x.diff(t), y.diff(t), x.diff(t, 2), y.diff(t, 2)
    by_hand = m * (xd * yd * ydd - (yd**2 + c**2) * xdd) / (xd**2 + yd**2 + c**2)
    comparison = compare_models(s)
    assert comparison.verdict == "differ"
    assert sp.simplify(comparison.defect[x] - by_hand) == 0
    # on addde7f: m (ẋ² ẍ + ẋ ẏ ÿ − ẍ (ẋ² + ẏ² + c²))/(ẋ² + ẏ² + c²), the denominator left
    # unexpanded in the numerator; cancelled, the numerator is by hand's
    numer, denom = sp.fraction(comparison.defect[x])
    assert (
        not numer.has(xd**2 + yd**2 + c**2)
        and sp.expand(numer - m * (xd * yd * ydd - (yd**2 + c**2) * xdd)) == 0
    )


def test_stability_points_to_the_vakonomic_family_where_lindelof_does_not_apply(polar: Path) -> None:
    out = runner.invoke(app, ["stability", str(polar), "--at", "r=0.5", "--model", "vakonomic"])
    assert out.exit_code != 0
    # on addde7f: "the vakonomic motion's reduced form is 'lindelof' (its family at c = 0)"
    assert "reduced form is 'vakonomic_family' with its constants" in out.output
    assert "reduced form is 'lindelof'" not in out.output


def test_unsolvable_implicit_constraint_hint_names_the_dependent_velocity() -> None:
    text = POLAR.replace("r'^2 + r^2*th'^2 - v^2", "th'^5 + th' + r'^7 + exp(th')")
    with pytest.raises(SystemFileError) as err:
        loads(text, source="polar.toml")
    message = str(err.value)
    assert "SymPy cannot solve the implicit constraints for th'" in message, message
    # on addde7f: 'Give them solved instead, "x'" = "..." for each dependent velocity'
    assert 'Give them solved instead, "th\'" = "..." (the branch you mean).' in message, message
    assert '"x\'"' not in message


def test_simulate_constants_help_states_its_default_and_the_degenerate_start() -> None:
    result = runner.invoke(app, ["simulate", "--help"], env={"COLUMNS": "2000"})
    text = " ".join(result.output.split())
    # on addde7f: "match (μ(0) = 0), zero, or numbers ..." with no default and no warning
    assert "zero (the default: every c_β = 0)" in text
    assert "c = 0 is a degenerate start (the vakonomic Lagrangian is singular there): use match." in text
