"""The HTML report: contents, self-containedness, the paper's table, and rendering in Chromium."""

from __future__ import annotations

import html
import json
import os
import re
import shutil
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols

from chaplygin import System, examples
from chaplygin.apps.report import (
    VERDICTS,
    PaperLine,
    is_paper_sphere,
    mathml,
    mathml_pieces,
    paper_table,
    render_report,
    write_report,
)

t = dynamicsymbols._t
SPHERE_START = {
    "psi": 0.3,
    "theta": 1.0,
    "phi": 0.1,
    "x": 0.0,
    "y": 0.0,
    "psi'": 0.5,
    "theta'": 0.4,
    "phi'": -0.7,
}


@pytest.fixture(scope="module")
def sphere_report(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("report") / "sphere.html"
    stages: list[str] = []
    write_report(
        examples.rolling_sphere(),
        path,
        parameters={"m": 1.0, "a": 1.0},
        initial=SPHERE_START,
        t_end=5.0,
        samples=101,
        progress=stages.append,
    )
    assert stages == ["system", "integrability", "equations", "simulation", "figures", "paper"]
    return path


@pytest.fixture(scope="module")
def table():
    return paper_table()


#: A sled carrying a point mass ``mp`` (a multi-letter parameter) at an angle ``alpha`` given
#: as ``"pi/6"``, with a damping moment in [forces].
DAMPED_SLED = """
name = "Damped sled"
coordinates = ["x", "y", "phi"]

[parameters]
m = 1.0
mp = 0.5
l = 0.3
J = 0.2
alpha = "pi/6"

[energy]
T = "(m + mp)/2*(x'^2 + y'^2) + (J + mp*l^2*sin(2*alpha))/2*phi'^2"

[forces]
phi = "-0.1*phi'"

[constraints]
"y'" = "tan(phi)*x'"

[initial]
phi = 0.3
"x'" = 1.0
"phi'" = 0.5
"""


@pytest.fixture(scope="module")
def sled_file():
    from chaplygin.io import files

    return files.loads(DAMPED_SLED)


@pytest.fixture(scope="module")
def sled_comparison(sled_file):
    from chaplygin import compare

    return compare(
        sled_file.system,
        ["chaplygin", "chetaev"],  # reduced, and with multipliers
        2.0,
        sled_file.initial,
        sled_file.parameters,
        samples=41,
        backend="numpy",
    )


@pytest.fixture(scope="module")
def sled_report(sled_file, sled_comparison, tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("report") / "sled.html"
    return write_report(sled_file, path, comparison=sled_comparison)


# ---------------------------------------------------------------- MathML
def test_mathml_prints_dots_and_is_well_formed() -> None:
    theta, x = dynamicsymbols("theta x")
    markup = mathml(sp.Eq(theta.diff(t, 2) + sp.sin(theta) * x.diff(t) ** 2, 0), display="block")
    root = ET.fromstring(markup)  # valid XML: no named entities left
    assert root.tag.endswith("math") and root.get("display") == "block"
    assert "<mover><mi>&#952;</mi><mo>&#168;</mo></mover>" in markup  # θ̈
    assert "<mover><mi>x</mi><mo>&#729;</mo></mover>" in markup  # ẋ
    assert "(t)" not in markup and "&dd;" not in markup
    assert "<mo>\u2212</mo>" in mathml(-x + 1)


def test_multi_letter_names_are_one_word_set_apart_in_products() -> None:
    """``mp`` is one upright name, not the product m·p, and a thin space keeps it (and a
    function) apart from its neighbours: ``l² mp sin(2α)``, not ``l²mpsin(2α)``."""
    mp, l, alpha, m, p = sp.symbols("mp l alpha m p")
    markup = mathml(l**2 * mp * sp.sin(2 * alpha))
    ET.fromstring(markup)
    assert markup.count("<mi>mp</mi>") == 1 and "<mi>m</mi><mo>\u2062</mo><mi>p</mi>" not in markup
    space = '<mo>\u2062</mo><mspace width="0.1667em"/>'
    assert f"{space}<mi>mp</mi>{space}<mrow><mi>sin</mi>" in markup
    assert "<mi>&#945;</mi>" in markup and "alpha" not in markup  # Greek names stay letters
    assert "mspace" not in mathml(m * p)  # single letters: an ordinary product


def test_long_formulas_are_cut_between_terms() -> None:
    x, y, a = dynamicsymbols("x y a")
    c = sp.Symbol("c")
    expr = sp.Eq(x.diff(t, 2) - c * (x + y.diff(t)) / 5, a - 1, evaluate=False)
    pieces = mathml_pieces(expr)
    for piece in pieces:
        ET.fromstring(piece)  # each one well-formed <math>
    texts = ["".join(ET.fromstring(p).itertext()) for p in pieces]
    # the sum leaves the fraction (c/5)(x + ẏ) and is cut inside its parentheses
    assert texts == ["\u2212c5\u2062(x", "+y\u02d9)", "+x\u00a8", "=a", "\u22121"]
    # binary spacing for the operator a piece begins with; a sign stays a sign
    assert all('<mo form="infix">' in p for p in pieces[1:]) and "infix" not in pieces[0]
    assert '<mrow><mo form="prefix">\u2212</mo><mfrac><mi>c</mi><mn>5</mn></mfrac>' in pieces[0]
    assert all('displaystyle="true"' in p for p in pieces)


# ---------------------------------------------------------------- contents
def test_report_sections_and_self_containedness(sphere_report: Path) -> None:
    text = sphere_report.read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>")
    for section in ("system", "integrability", "models", "equations", "simulation", "paper"):
        assert f'<section id="{section}">' in text
    for title in ("eq. (6)/(35)", "eq. (15)", "eq. (40)", "eqs. (17)-(18)", "eq. (22)", "eq. (39)"):
        assert title in text
    assert "Implicit, form A" in text and "solved, form B" in text
    assert text.count("<svg") == 3 and text.count("<math") > 100
    assert "not integrable (nonholonomic)" in text and "<code>differ</code>" in text
    # one file, nothing fetched: no scripts, links, images or remote references
    assert not re.search(r"<(script|link|img|iframe|object|embed)\b", text, re.I)
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:|//)""", text, re.I)
    assert not re.search(r"url\((?!#)", text) and "@import" not in text  # url(#id): in-file only


def test_report_of_a_system_without_numbers_and_of_a_voronets_system(tmp_path: Path) -> None:
    knife = render_report(examples.knife_edge())
    assert "Not simulated" in knife and "<svg" not in knife and 'id="paper"' not in knife
    x, y, z = dynamicsymbols("x y z")
    voronets = System(
        [x, y, z],
        (x.diff(t) ** 2 + y.diff(t) ** 2 + z.diff(t) ** 2) / 2,
        {z.diff(t): z * y.diff(t)},
        name="Voronets test",
    )
    text = render_report(
        voronets, parameters={}, initial={"x": 0, "y": 0, "z": 1, "x'": 1, "y'": 0.5}, t_end=1.0, samples=11
    )
    assert "Voronets' equations" in text and "Chaplygin's equations, eq. (15)" not in text
    assert "No Lindelöf comparison" in text and text.count("<svg") == 3


def test_report_keeps_values_given_exactly(sled_file, sled_comparison) -> None:
    assert sled_file.exact == {"alpha": sp.pi / 6}
    assert sled_file.parameters["alpha"] == pytest.approx(np.pi / 6, rel=1e-15)
    text = render_report(sled_file, comparison=sled_comparison)
    row = re.search(r"<tr><td><math[^>]*><mi>&#945;</mi></math></td>(.*?)</tr>", text).group(1)
    assert "<mfrac><mi>\u03c0</mi><mn>6</mn></mfrac>" in row and "0.52" not in row  # π/6
    assert "0.5235987756" not in text
    # a number given on top of the file's is shown as the number it is
    override = render_report(sled_file, comparison=sled_comparison, parameters={"alpha": 0.25})
    row = re.search(r"<tr><td><math[^>]*><mi>&#945;</mi></math></td>(.*?)</tr>", override).group(1)
    assert "0.25" in row and "\u03c0" not in row


def test_energy_note_knows_non_potential_forces(sphere_report: Path, sled_report: Path) -> None:
    conservative = sphere_report.read_text(encoding="utf-8")
    assert "<th>energy drift</th>" in conservative and "E is an invariant here" in conservative
    damped = sled_report.read_text(encoding="utf-8")
    assert "invariant here" not in damped.replace("not an invariant here", "")
    assert "<th>energy change</th>" in damped and "<th>energy drift</th>" not in damped
    forces = re.search(r"The non-potential forces \((.*?)\) do work", damped)
    assert forces and ET.fromstring(forces.group(1)).findtext(".//{*}mi") == "Q"  # Q_φ, typeset
    assert "changes by their work" in damped


def _axes(figure_html: str) -> int:
    return len(re.findall(r'<g id="axes_\d+">', figure_html))


def test_no_residual_plot_for_models_that_satisfy_the_constraints_by_construction(
    sphere_report: Path, sled_report: Path, sled_comparison
) -> None:
    # the sphere's default models (chaplygin, lindelof) are both reduced: no residual panel
    sphere = sphere_report.read_text(encoding="utf-8")
    invariants = sphere.split('id="figure-invariants"')[1].split("</div>")[0]
    assert _axes(invariants) == 1
    cell = '<td class="note" colspan="2">0 by construction (reduced)</td>'
    assert sphere.count(cell) == 2 and "chaplygin, lindelof: they" in sphere
    # chaplygin beside chetaev: a residual panel with chetaev's curve only, in chetaev's colour
    fig = sled_comparison.figure("invariants")
    top, bottom = fig.axes
    drawn = [line for line in bottom.lines if len(line.get_xdata())]
    assert len(drawn) == 1 and drawn[0].get_color() == top.lines[1].get_color()
    assert "chaplygin: 0 by construction" in bottom.get_title()
    sled = sled_report.read_text(encoding="utf-8")
    assert _axes(sled.split('id="figure-invariants"')[1].split("</div>")[0]) == 2
    assert sled.count(cell) == 1


def test_is_paper_sphere() -> None:
    assert is_paper_sphere(examples.rolling_sphere())
    assert is_paper_sphere(examples.rolling_sphere(forces={"x": sp.Symbol("V_1")}))
    assert not is_paper_sphere(examples.knife_edge())
    from chaplygin.io import files

    from_file = files.loads(files.dumps(examples.rolling_sphere(), {"m": 2.0, "a": 0.5}))
    assert is_paper_sphere(from_file.system)  # real, not positive, symbols: still the sphere
    assert not is_paper_sphere(examples.rolling_disk())


# ---------------------------------------------------------------- the paper's (49)-(62)
def test_paper_table_verdicts(table) -> None:
    verdicts = {line.number: line.verdict for line in table.lines}
    assert list(verdicts) == [f"({k})" for k in range(49, 63)]
    assert verdicts.pop("(57)") == "agree"  # the two products cancel as printed
    assert set(verdicts.values()) == {"transcription error"}
    assert table.counts() == {"agree": 1, "transcription error": 13, "differs in substance": 0}
    for line in table.lines:
        assert line.repairs, line.number  # every restoration is spelled out


def test_paper_table_sets_are_classified(table) -> None:
    sets = {(label, reading): verdict for label, reading, verdict in table.sets}
    assert sets[("(52)-(54)", "restored")].startswith("Lindelöf's equations (22)")
    assert sets[("(60)-(62)", "restored")].startswith("the true (Chetaev) motion")
    assert sets[("(52)-(54)", "printed")].startswith("not equations of motion")


def test_the_sign_restored_in_50_is_the_papers_own(table) -> None:
    """(61) = (53) + (58): holds for the restored lines, fails with the printed sign of (50)/(53)."""
    line = {entry.number: entry for entry in table.lines}
    restored = line["(61)"].restored - line["(53)"].restored - line["(58)"].restored
    assert sp.simplify(restored) == 0
    theta, phi = examples.rolling_sphere().coordinates[1:3]
    m, a = sp.symbols("m a", positive=True)
    misprinted = line["(53)"].restored + 2 * m * a**2 * phi.diff(t) ** 2 * sp.sin(theta) * sp.cos(theta)
    assert sp.simplify(line["(61)"].restored - misprinted - line["(58)"].restored) != 0


def test_judge_tells_the_three_verdicts_apart() -> None:
    q = dynamicsymbols("q")
    derived = q.diff(t, 2) + sp.sin(q)
    assert PaperLine("(1)", "", "", derived, None, [], derived).judge() == VERDICTS[0]
    lost_dot = PaperLine("(2)", "", "", q.diff(t) + sp.sin(q), derived, ["dot lost"], derived)
    assert lost_dot.judge() == VERDICTS[1]
    wrong = PaperLine("(3)", "", "", q.diff(t) - sp.sin(q), q.diff(t, 2) - sp.sin(q), ["dot lost"], derived)
    assert wrong.judge() == VERDICTS[2]


def test_paper_table_in_the_report(sphere_report: Path) -> None:
    text = sphere_report.read_text(encoding="utf-8")
    rows = re.findall(r'<tr id="paper-(\d+)">', text)
    assert rows == [str(k) for k in range(49, 63)]
    assert text.count('class="verdict transcription"') == 13 and text.count('class="verdict agree"') == 1
    assert r"\dot{\sin}" in text  # the OCR text is shown as it stands


# ---------------------------------------------------------------- rendering in headless Chromium
CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
    "--hide-scrollbars",
]

MEASURE = """<script>
(() => {
  const box = e => { const r = e.getBoundingClientRect(); return [r.width, r.height]; };
  const maths = [...document.querySelectorAll('math')];
  const svgs = [...document.querySelectorAll('.figure svg')];
  const scrolls = (axis, e) => ['auto', 'scroll'].includes(getComputedStyle(e)['overflow' + axis]);
  const all = [...document.querySelectorAll('body *')];
  // a formula sticking out of the block that holds it (a cell, a paragraph, a formula's row)
  const outside = maths.filter(m => {
    const r = m.getBoundingClientRect();
    const c = m.parentElement.closest('div, td, p, li').getBoundingClientRect();
    return r.left < c.left - 0.5 || r.right > c.right + 0.5;
  });
  // the gap after each name "mp" to the next identifier of its formula
  const gaps = [];
  for (const m of maths) {
    const ids = [...m.querySelectorAll('mi')];
    ids.forEach((mi, k) => {
      if (mi.textContent === 'mp' && k + 1 < ids.length)
        gaps.push(ids[k + 1].getBoundingClientRect().left - mi.getBoundingClientRect().right);
    });
  }
  const out = {
    element: maths.length ? maths[0].constructor.name : null,
    math: maths.map(box),
    fractions: [...document.querySelectorAll('mfrac')].map(box),
    symbols: [...document.querySelectorAll('#system p math')].slice(0, 5).map(box),
    svg: svgs.map(box),
    svgPaths: svgs.map(s => s.querySelectorAll('path').length),
    scrollX: all.filter(e => scrolls('X', e) && e.scrollWidth > e.clientWidth).map(e => e.outerHTML.slice(0, 300)),
    scrollY: all.filter(e => scrolls('Y', e) && e.scrollHeight > e.clientHeight).map(e => e.outerHTML.slice(0, 300)),
    outside: outside.map(m => m.outerHTML.slice(0, 300)),
    page: [document.documentElement.scrollWidth, document.documentElement.clientWidth],
    wrapped: [...document.querySelectorAll('.eq')].filter(e => e.getBoundingClientRect().height > 70).length,
    gaps: gaps,
  };
  const pre = document.createElement('pre');
  pre.id = 'measurements';
  pre.textContent = JSON.stringify(out);
  document.body.appendChild(pre);
})();
</script>"""

#: The browser window of the rendering tests (a laptop's page width)
WINDOW = "--window-size=1000,2000"


def chromium() -> str:
    found = shutil.which("chromium") or shutil.which("chromium-browser")
    if found is None:
        if os.environ.get("CHAPLYGIN_REQUIRE_CHROMIUM"):
            pytest.fail(
                "CHAPLYGIN_REQUIRE_CHROMIUM is set but chromium is not installed "
                "(apt-get install chromium): the report's rendering cannot be checked"
            )
        pytest.skip(
            "chromium is not installed (apt-get install chromium): "
            "the report's rendering in a browser is not checked"
        )
    return found


def run_chromium(binary: str, profile: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [binary, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", *args],
        capture_output=True,
        text=True,
        timeout=120,
    )


def measure(binary: str, report: Path, tmp_path: Path) -> dict:
    """Boxes of the report as Chromium lays it out in :data:`WINDOW` (see :data:`MEASURE`)."""
    probe = tmp_path / "probe.html"
    probe.write_text(
        report.read_text(encoding="utf-8").replace("</body>", MEASURE + "</body>"), encoding="utf-8"
    )
    dom = run_chromium(binary, tmp_path / "profile", WINDOW, "--dump-dom", probe.as_uri())
    found = re.search(r'<pre id="measurements">(.*?)</pre>', dom.stdout, re.S)
    assert found, f"no measurements in Chromium's DOM dump: {dom.stderr[-2000:]}"
    return json.loads(html.unescape(found.group(1)))


def test_report_renders_in_chromium(sphere_report: Path, tmp_path: Path) -> None:
    binary = chromium()
    m = measure(binary, sphere_report, tmp_path)
    assert m["element"] == "MathMLElement"  # parsed as MathML, not unknown tags
    sizes = np.array(m["math"])
    assert len(sizes) > 100 and np.all(sizes[:, 0] > 0) and np.all(sizes[:, 1] > 0)
    line = np.median(np.array(m["symbols"])[:, 1])
    fractions = np.array(m["fractions"])
    assert len(fractions) > 20 and np.median(fractions[:, 1]) > 1.4 * line  # stacked, laid out
    figures = np.array(m["svg"])
    assert figures.shape == (3, 2) and np.all(figures > 200)
    assert min(m["svgPaths"]) > 10
    # no formula scrolls or sticks out of its block: the long ones wrap between terms (the
    # vakonomic family and the paper's table have some), none is wider than the page here
    assert m["scrollX"] == [] and m["scrollY"] == [] and m["outside"] == []
    assert m["page"][0] <= m["page"][1] and m["wrapped"] >= 3

    shot = tmp_path / "shot.png"
    run_chromium(binary, tmp_path / "profile", WINDOW, f"--screenshot={shot}", sphere_report.as_uri())
    assert shot.exists()
    import matplotlib.image

    pixels = matplotlib.image.imread(shot)[..., :3]
    dark = np.mean(pixels < 0.5)
    assert 0.005 < dark < 0.5 and pixels.std() > 0.05  # text and equations drawn, not blank


def test_multi_letter_name_is_set_apart_in_chromium(sled_report: Path, tmp_path: Path) -> None:
    """``l² mp sin(2α)``: a visible space after ``mp`` wherever a name follows it."""
    m = measure(chromium(), sled_report, tmp_path)
    assert len(m["gaps"]) >= 5 and min(m["gaps"]) > 2.0  # px: a thin space (1/6 em) is about 3
    assert m["scrollX"] == [] and m["scrollY"] == [] and m["outside"] == []
