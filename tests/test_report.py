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
  const out = {
    element: maths.length ? maths[0].constructor.name : null,
    math: maths.map(box),
    fractions: [...document.querySelectorAll('mfrac')].map(box),
    symbols: [...document.querySelectorAll('#system p math')].slice(0, 5).map(box),
    svg: svgs.map(box),
    svgPaths: svgs.map(s => s.querySelectorAll('path').length),
  };
  const pre = document.createElement('pre');
  pre.id = 'measurements';
  pre.textContent = JSON.stringify(out);
  document.body.appendChild(pre);
})();
</script>"""


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


def test_report_renders_in_chromium(sphere_report: Path, tmp_path: Path) -> None:
    binary = chromium()
    probe = tmp_path / "probe.html"
    probe.write_text(
        sphere_report.read_text(encoding="utf-8").replace("</body>", MEASURE + "</body>"), encoding="utf-8"
    )
    dom = run_chromium(binary, tmp_path / "profile", "--dump-dom", probe.as_uri())
    found = re.search(r'<pre id="measurements">(.*?)</pre>', dom.stdout, re.S)
    assert found, f"no measurements in Chromium's DOM dump: {dom.stderr[-2000:]}"
    m = json.loads(html.unescape(found.group(1)))
    assert m["element"] == "MathMLElement"  # parsed as MathML, not unknown tags
    sizes = np.array(m["math"])
    assert len(sizes) > 100 and np.all(sizes[:, 0] > 0) and np.all(sizes[:, 1] > 0)
    line = np.median(np.array(m["symbols"])[:, 1])
    fractions = np.array(m["fractions"])
    assert len(fractions) > 20 and np.median(fractions[:, 1]) > 1.4 * line  # stacked, laid out
    figures = np.array(m["svg"])
    assert figures.shape == (3, 2) and np.all(figures > 200)
    assert min(m["svgPaths"]) > 10

    shot = tmp_path / "shot.png"
    run_chromium(
        binary,
        tmp_path / "profile",
        "--window-size=1200,2400",
        f"--screenshot={shot}",
        sphere_report.as_uri(),
    )
    assert shot.exists()
    import matplotlib.image

    pixels = matplotlib.image.imread(shot)[..., :3]
    dark = np.mean(pixels < 0.5)
    assert 0.005 < dark < 0.5 and pixels.std() > 0.05  # text and equations drawn, not blank
