"""Big results shown readably: the report typesets every equation with line breaks, the notebook
displays and ``chaplygin derive`` fold an expression beyond a screen into a summary, the whole one
a click (``<details>``) or ``--full`` away; small results print whole (:mod:`chaplygin.core._fold`)."""

from __future__ import annotations

import random
import re
import xml.etree.ElementTree as ET
from html.parser import HTMLParser
from pathlib import Path

import pytest
import sympy as sp
from typer.testing import CliRunner

import chaplygin
from chaplygin.apps.cli import app
from chaplygin.apps.report import _block
from chaplygin.core import _fold
from chaplygin.core._symbols import file_syntax

# A roller racer (two platforms on a revolute joint): Voronets' equations of 27 000 characters each.
ROLLER_RACER = '''
name = "Roller racer"
coordinates = ["x", "y", "theta", "psi"]
[parameters]
m1 = 1.0
m2 = 0.5
I1 = 0.2
I2 = 0.1
d1 = 0.6
d2 = 0.4
[energy]
T = """m1/2*(x'^2 + y'^2) + I1/2*theta'^2 + I2/2*(theta' + psi')^2
     + m2/2*((x' - d1*sin(theta)*theta' + d2*sin(theta + psi)*(theta' + psi'))^2
           + (y' + d1*cos(theta)*theta' - d2*cos(theta + psi)*(theta' + psi'))^2)"""
[constraints]
implicit = [
  "-sin(theta)*x' + cos(theta)*y'",
  "-sin(theta + psi)*(x' - d1*sin(theta)*theta') + cos(theta + psi)*(y' + d1*cos(theta)*theta') - d2*(theta' + psi')",
]
dependent = ["y", "theta"]
'''

#: the widest line (characters of text) a display may show; today's lines ran to 27 000
WIDE = 2000
#: the fold threshold in these tests: the roller racer's equations stay beyond it however they
#: are tidied (they were 10 800 symbols and operations each at main a11bdc0)
FOLD = 300


@pytest.fixture
def fold_at(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(_fold, "FOLD_NODES", FOLD)


@pytest.fixture(scope="module")
def racer_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("racer") / "roller_racer.toml"
    path.write_text(ROLLER_RACER)
    return path


@pytest.fixture(scope="module")
def racer(racer_file: Path) -> chaplygin.Equations:
    return chaplygin.load(racer_file).system.equations("voronets")


def _parsed(text: str, names: set[sp.Symbol]) -> sp.Expr:
    """Text in the file syntax read back by SymPy (the test's own reading, not chaplygin's)."""
    text = re.sub(r"(\w+)''", r"\1_dd", text)
    text = re.sub(r"(\w+)'", r"\1_d", text)
    return sp.parse_expr(text, local_dict={s.name: s for s in names})


def test_pieces_put_together_are_the_expression() -> None:
    """The lines a long expression is broken into, read back, are the expression (exactly)."""
    a, b, c, x, y = sp.symbols("a b c x y")
    rng = random.Random(3)
    atoms = [a, b, c, x, y, sp.Rational(3, 7), sp.Integer(-2)]

    def grow(depth: int) -> sp.Expr:
        if depth == 0:
            return rng.choice(atoms) * rng.choice(atoms)
        parts = [grow(depth - 1) for _ in range(3)]
        return rng.choice(
            [
                sp.Add(*parts),
                parts[0] * parts[1] - parts[2],
                parts[0] / (parts[1] + 5 * x**2 + 1),
                (parts[0] + parts[1]) ** 2 - parts[2],
                -parts[0] * (parts[1] + parts[2]) / (a**2 + 1) ** 3,
            ]
        )

    for _ in range(6):
        expr = grow(4)
        assert _fold.size(expr) > _fold.PIECE_NODES
        for width in (30, 60):  # an equation, its short "= 0" kept on the last line
            lines = _fold.lines(_fold.tokens(sp.Eq(expr, 0, evaluate=False)), width)
            assert len(lines) > 2
            text = "".join(_fold._text_token(t, file_syntax) for line in lines for t in line)
            lhs, _, rhs = text.rpartition(" = ")
            values = {s: sp.Rational(rng.randint(1, 9), rng.randint(2, 9)) for s in (a, b, c, x, y)}
            assert rhs == "0" and (_parsed(lhs, {a, b, c, x, y}) - expr).subs(values) == 0


def test_the_report_typesets_the_voronets_equations_in_lines(
    racer: chaplygin.Equations, fold_at: None
) -> None:
    """Main a11bdc0 replaced them by '[a formula of more than 4000 symbols and operations, not typeset]'."""
    voronets = "".join(_block(e) for e in racer.equations)  # as the report's section of equations
    assert "not typeset" not in voronets
    assert voronets.count("<details>") == 2  # both equations: the summary, the whole a click away
    whole = voronets[voronets.index("<details>") : voronets.index("</details>")]
    maths = re.findall(r"<math.*?</math>", whole, re.S)
    texts = ["".join(ET.fromstring(m).itertext()) for m in maths]  # each piece well-formed MathML
    assert len(maths) > 10  # cut into pieces the browser wraps between
    assert max(map(len, texts)) <= 120  # no piece wider than a line
    first = racer.equations[0]
    assert sum(map(len, texts)) > len(file_syntax(first.lhs)) / 2  # all of the equation is there


def test_a_notebook_folds_a_big_result_with_the_whole_one_a_click_away(
    racer: chaplygin.Equations, fold_at: None
) -> None:
    """Main a11bdc0 showed each of these equations as one LaTeX line of about 60 000 characters."""
    html = racer._repr_html_()
    checker = HTMLParser()
    checker.feed(html)
    assert html.count("<details>") == len(racer.equations) == 2
    summary, _, whole = html.partition("<details>")
    assert len(summary) < 3000 and "folded" in summary and "symbols and operations" in summary
    latex = whole[whole.index("$$") + 2 : whole.rindex("$$")]
    rows = latex.split(r"\\")
    assert len(rows) > _fold.size(racer.equations[0]) / 200  # broken into lines
    assert max(map(len, rows)) <= 800  # of LaTeX source: about 80 characters of text each
    # (\cos{\left(\psi \right)} is 25 characters of source for 8 of text)
    for row in rows:  # \left( and \right) are paired within a line, as MathJax and LaTeX need
        assert row.count(r"\left(") == row.count(r"\right)")
    assert latex.count("(") == latex.count(")")
    assert len(racer._repr_latex_()) < 3000  # the LaTeX display folds too
    assert len(racer.latex()) > len(file_syntax(racer.equations[0].lhs))  # latex(): the whole, for a paper
    pretty = racer.pretty()  # one line per folded equation; pretty(full=True) the whole
    assert len(pretty) < 2000 and pretty.count("pretty(full=True) prints it whole") == 2


def test_derive_folds_a_big_system_and_prints_it_whole_with_full(
    racer_file: Path, racer, fold_at: None
) -> None:
    """Main a11bdc0 printed 110 KB with lines of up to 27 000 characters, and had no --full."""
    runner = CliRunner()
    folded = runner.invoke(app, ["derive", str(racer_file), "--no-cache"])
    assert folded.exit_code == 0, folded.output
    assert len(folded.stdout) < 12_000 and max(map(len, folded.stdout.splitlines())) < WIDE
    assert folded.stdout.count("# folded: ") >= 2 and "--full prints it whole" in folded.stdout
    whole = runner.invoke(app, ["derive", str(racer_file), "--no-cache", "--full"])
    assert whole.exit_code == 0, whole.output
    lines = whole.stdout.splitlines()
    for e in racer.equations:  # every equation whole, as the file syntax prints it
        assert f"  {file_syntax(e.lhs)} = {file_syntax(e.rhs)}" in lines
    assert "folded" not in whole.stdout
    # a small system prints whole, as it always has
    small = runner.invoke(app, ["derive", "example:knife-edge", "--model", "chaplygin", "--no-cache"])
    knife = chaplygin.examples.knife_edge().equations("chaplygin")
    assert small.stdout.splitlines()[1:3] == [
        f"  {file_syntax(e.lhs)} = {file_syntax(e.rhs)}" for e in knife.equations
    ]
    assert "folded" not in small.stdout


def test_a_long_value_in_a_one_line_verdict_shows_its_leading_terms() -> None:
    """Main a11bdc0 said only 'an expression of N characters, not printed (…)'."""
    from chaplygin.core._brief import MAX_BRIEF, brief

    x, y = sp.symbols("x y")
    expr = sum(sp.Symbol(f"k{i}") * sp.sin(x) ** i * sp.cos(y) ** (i + 1) for i in range(1, 40))
    text = brief(expr, "--full prints it")
    shown, _, size = text.rpartition(" (")
    assert size == f"{len(str(expr))} characters; --full prints it)"
    assert len(shown) <= MAX_BRIEF and shown.count("…") >= 1
    first = expr.as_ordered_terms()[0]
    assert shown.startswith(str(first))  # the leading term, whole
    assert brief(x + y, "--full prints it") == "x + y"  # a short one as it is


def test_a_folded_value_in_a_notebook_table_keeps_the_whole_a_click_away(fold_at: None) -> None:
    x, y = sp.symbols("x y")
    expr = sum((x + i) ** 2 / (y + i) for i in range(1, 60))
    shown = _fold.html_math(expr, escape=str)
    summary, _, whole = shown.partition("<details>")
    assert len(summary) < 1500 and r"\dots" in summary
    assert whole.count(r"\\") > 5 and all(f"y + {i}" in whole for i in (1, 59))
    assert _fold.html_math(x + y, escape=str) == "$x + y$"  # a small one as it always was
