"""Rich displays for Jupyter: every ``_repr_html_`` is well-formed HTML, shows what it is about,
escapes user text, and the runs carry their plot as an embedded PNG."""

from __future__ import annotations

import base64
import re
from html.parser import HTMLParser

import pytest
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols

from chaplygin import System, classify, compare, compare_models, equivalent, examples, simulate
from chaplygin._html import escape, latex_text, png, table

KNIFE_START = {"x": 0.0, "y": 0.0, "phi": 0.3, "x'": 1.0, "phi'": 0.2}
KNIFE_PARAMETERS = {"m": 1.0, "J": 0.5}
HOSTILE = "<script>alert(1)</script>"
VOID = {"br", "img"}
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


class _Checker(HTMLParser):
    """Collects the text and checks that every element is closed, in order."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.open: list[str] = []
        self.tags: list[str] = []
        self.text: list[str] = []
        self.images: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append(tag)
        if tag == "img":
            self.images.append(dict(attrs)["src"] or "")
        if tag not in VOID:
            self.open.append(tag)

    def handle_startendtag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.handle_starttag(tag, attrs)

    def handle_endtag(self, tag: str) -> None:
        assert self.open and self.open[-1] == tag, f"</{tag}> closes {self.open[-1:] or 'nothing'}"
        self.open.pop()

    def handle_data(self, data: str) -> None:
        self.text.append(data)


def parse(markup: str) -> _Checker:
    """Parse ``markup``; fail on a stray or unclosed tag."""
    checker = _Checker()
    checker.feed(markup)
    checker.close()
    assert not checker.open, f"unclosed: {checker.open}"
    return checker


def text_of(markup: str) -> str:
    return "".join(parse(markup).text)


def png_bytes(markup: str) -> bytes:
    images = parse(markup).images
    assert len(images) == 1 and images[0].startswith("data:image/png;base64,")
    return base64.b64decode(images[0].split(",", 1)[1], validate=True)


@pytest.fixture(scope="module")
def knife() -> System:
    return examples.knife_edge()


# ---------------------------------------------------------------- the helper
def test_helper_escapes_text_and_latex() -> None:
    assert escape(HOSTILE) == "&lt;script&gt;alert(1)&lt;/script&gt;"
    assert (
        table([["<b>1</b>"]], ["a<b"]) == "<table><tr><th>a&lt;b</th></tr><tr><td><b>1</b></td></tr></table>"
    )
    assert latex_text("a_b {c} 50% $x$ \\") == r"\text{a\_b \{c\} 50\% \$x\$ \textbackslash{}}"


def test_png_closes_a_pyplot_figure() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure()
    fig.add_subplot().plot([0, 1], [1, 0])
    markup = png(fig, alt="a <line>")
    assert not plt.fignum_exists(fig.number) and "alt='a &lt;line&gt;'" in markup
    assert png_bytes(markup).startswith(PNG_MAGIC)


# ---------------------------------------------------------------- symbolic objects
def test_system(knife: System) -> None:
    markup = knife._repr_html_()
    text = text_of(markup)
    assert "System Knife edge" in text and "kinetic energy" in text
    assert "$x$, $y$, $\\phi$" in text  # the coordinates
    assert "dependent" in text and "$J$, $m$" in text  # the parameters
    assert "\\dot{y} =" in text  # the constraint, form B


def test_hostile_names_are_escaped() -> None:
    q = dynamicsymbols("q1 q2")
    k = sp.Symbol("k")
    system = System(
        q, k * (q[0].diff() ** 2 + q[1].diff() ** 2) / 2, {q[1].diff(): q[0] * q[0].diff()}, name=HOSTILE
    )
    for markup in (
        system._repr_html_(),
        system.equations("chetaev")._repr_html_(),
        system.integrability()._repr_html_(),
        compare_models(system)._repr_html_(),
    ):
        assert "<script" not in markup
        checker = parse(markup)
        assert "script" not in checker.tags and HOSTILE in "".join(checker.text)


def test_equations_carry_their_title(knife: System) -> None:
    eqs = knife.equations("chaplygin")
    assert f"{eqs.title} - Knife edge" in text_of(eqs._repr_html_())
    assert r"\begin{aligned}" in text_of(eqs._repr_html_())
    latex = eqs._repr_latex_()
    assert latex.startswith("$") and latex.endswith("$")
    assert r"\text{Chaplygin's equations, eq. (15) - Knife edge}" in latex and eqs.latex() in latex


def test_integrability(knife: System) -> None:
    text = text_of(knife.integrability()._repr_html_())
    assert "Constraints of Knife edge: not integrable" in text
    assert all(name in text for name in ("(28)", "(33)", "Frobenius", "fails"))


def test_model_comparison_and_classification(knife: System) -> None:
    text = text_of(compare_models(knife)._repr_html_())
    assert "Knife edge: the models differ" in text and "Lindelöf defect" in text and "$x$" in text
    text = text_of(classify(knife, knife.equations("lindelof"))._repr_html_())
    assert "Classification: lindelof" in text and "chetaev" in text


def test_equivalence_report(knife: System) -> None:
    text = text_of(equivalent(knife, knife.equations("chaplygin"), knife.equations("lindelof"))._repr_html_())
    assert "NOT equivalent" in text and "numeric" in text
    text = text_of(equivalent(knife, knife.equations("chaplygin"), knife.equations("chetaev"))._repr_html_())
    assert re.search(r"verdict\s*equivalent", text) and "symbolic" in text


# ---------------------------------------------------------------- runs
def test_trajectory(knife: System) -> None:
    run = simulate(knife, "chaplygin", 2.0, KNIFE_START, KNIFE_PARAMETERS, samples=51, backend="numpy")
    markup = run._repr_html_()
    text = text_of(markup)
    for expected in (
        "chaplygin/classic",
        "numpy",
        "success",
        "0 … 2",
        "51",
        "max energy drift",
        "max constraint residual",
    ):
        assert expected in text
    assert png_bytes(markup).startswith(PNG_MAGIC)


def test_comparison() -> None:
    sphere = examples.rolling_sphere()
    start = {
        "psi": 0.3,
        "theta": 1.0,
        "phi": 0.1,
        "x": 0.0,
        "y": 0.0,
        "psi'": 0.5,
        "theta'": 0.2,
        "phi'": 0.4,
    }
    result = compare(
        sphere, ["chaplygin", "lindelof"], 2.0, start, {"m": 1.0, "a": 1.0}, samples=41, backend="numpy"
    )
    markup = result._repr_html_()
    text = text_of(markup)
    assert "models compared with chaplygin" in text and "lindelof" in text
    assert "max distance of path (x, y)" in text
    assert png_bytes(markup).startswith(PNG_MAGIC)


def test_ensemble(knife: System) -> None:
    from chaplygin import simulate_ensemble

    starts = [{**KNIFE_START, "x'": v} for v in (0.5, 1.0, 1.5)]
    ens = simulate_ensemble(knife, "chaplygin", 1.0, starts, KNIFE_PARAMETERS, backend="numba")
    text = text_of(ens._repr_html_())
    assert "Ensemble" in text and "chaplygin/classic" in text and "members3" in text.replace(" ", "")
    assert "failed0" in text.replace(" ", "") and "(median)" in text and "(max)" in text


def test_system_file_keeps_symbolic_values(tmp_path) -> None:
    from chaplygin import load

    path = tmp_path / "pendulum.toml"
    path.write_text(
        'name = "Knife <b>"\ncoordinates = ["x", "y", "phi"]\n[parameters]\nm = 1.0\nJ = "pi/6"\n'
        "[energy]\nT = \"m/2*(x'^2 + y'^2) + J/2*phi'^2\"\n"
        '[constraints]\n"y\'" = "tan(phi)*x\'"\n[initial]\nphi = 0.25\n"x\'" = 1.0\n',
        encoding="utf-8",
    )
    markup = load(path)._repr_html_()
    text = text_of(markup)  # well-formed, the name escaped
    assert "Knife <b>" in text and "<b>" not in markup.replace("&lt;b&gt;", "")
    assert r"\frac{\pi}{6}" in text and "0.523" not in text  # J as written, not as a float
    assert "parameters" in text and "initial state" in text and "0.25" in text
