"""``chaplygin stability``: a steady motion's eigenvalues and verdict on the command line (issue 29, item 3).

The expected eigenvalues are closed forms, not chaplygin's own output:

* the Chaplygin sleigh moving straight at speed ``v₀``: ``λ = −m a v₀/(I + m a²)`` besides two
  zeros (Bloch 2003, §1.7);
* the upright rolling disk spinning at ``ω``: ``λ² = [m g r − C (C + m r²) ω²/A]/(A + m r²)``
  (Routh 1905, art. 244; McDonald 2000, §2.5), and Lindelöf's disk (the constraints substituted
  into T): ``λ² = [A m g r − (C + m r²)² ω²]/(A (A + m r²))`` (docs/gallery/rolling-disk.md);
* the steady turning of the disk: ``A Ω² sin θ cos θ − (C + m r²) s Ω cos θ − m g r sin θ = 0``
  with ``s = φ' + Ω sin θ`` (O'Reilly 1996; McDonald 2000, §2.2).

On 95d57e3 there is no ``stability`` command: every test here fails (exit status 2).
"""

from __future__ import annotations

import _thread
import csv
import io
import json
import threading
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from typer.testing import CliRunner

import chaplygin
from chaplygin.apps import _steady
from chaplygin.apps.cli import app
from chaplygin.errors import ChaplyginError

runner = CliRunner()
SLEIGH = {"m": 2.0, "I": 0.7, "a": 0.4}
COIN = {"m": 1.0, "r": 1.0, "A": 0.25, "C": 0.5, "g": 9.81}  # example:rolling-disk's numbers
DISK = "example:rolling-disk"


def run(*args: object) -> object:
    return runner.invoke(app, ["stability", *(str(a) for a in args)])


def upright(omega: float, lindelof: bool = False) -> complex:
    """The upright disk's nonzero eigenvalue with the largest real part (then imaginary part)."""
    m, r, A, C, g = (COIN[k] for k in ("m", "r", "A", "C", "g"))
    if lindelof:
        square = (A * m * g * r - (C + m * r**2) ** 2 * omega**2) / (A * (A + m * r**2))
    else:
        square = (m * g * r - C * (C + m * r**2) * omega**2 / A) / (A + m * r**2)
    return complex(np.sqrt(square)) if square > 0 else 1j * np.sqrt(-square)


def coin_values(*symbols: sp.Symbol) -> dict[sp.Symbol, float]:
    return dict(zip(symbols, (COIN[k] for k in ("m", "r", "A", "C", "g"))))


def nonzero(pairs: list[list[float]], tol: float = 1e-9) -> np.ndarray:
    values = np.array([complex(re, im) for re, im in pairs])
    return np.sort_complex(values[np.abs(values) > tol])


def printed(stdout: str, model: str) -> list[str]:
    """The eigenvalues printed in the block of ``model``."""
    block = stdout.split(f"\n{model} (")[1]
    line = next(line for line in block.splitlines() if line.startswith("  eigenvalues: "))
    return line.removeprefix("  eigenvalues: ").split(", ")


# ---------------------------------------------------------------- against the closed forms
@pytest.mark.parametrize("v0", [1.5, -0.8])
def test_sleigh_eigenvalue_is_the_closed_form(v0: float) -> None:
    params = [a for k, v in SLEIGH.items() for a in ("-p", f"{k}={v}")]
    result = run("example:chaplygin-sleigh", "--at", f"theta=0, x'={v0}", *params)
    assert result.exit_code == 0, result.output
    expected = -SLEIGH["m"] * SLEIGH["a"] * v0 / (SLEIGH["I"] + SLEIGH["m"] * SLEIGH["a"] ** 2)
    assert sorted(printed(result.stdout, "chaplygin")) == sorted([f"{expected:.6g}", "0", "0"])
    assert "(theta' = 0 by default" in result.stdout  # theta stays constant
    assert "2 zero eigenvalues: from the family of steady motions" in result.stdout
    kind = "asymptotically stable" if v0 > 0 else "unstable"  # stable when the mass centre leads
    assert f"chaplygin (the true motion): {kind}\n" in result.stdout
    doc = json.loads(
        run("example:chaplygin-sleigh", "--at", f"theta=0, x'={v0}", *params, "-f", "json").stdout
    )
    np.testing.assert_allclose(nonzero(doc["models"][0]["eigenvalues"]), [expected], rtol=1e-12)


def test_upright_disk_both_sides_of_the_threshold_in_two_models() -> None:
    """Below and above sqrt(g/(3r)) = 1.81, and Lindelöf's disk beside the true one."""
    for omega in (1.5, 2.5):
        result = run(DISK, "--at", f"theta=0, psi'=0, phi'={omega}", "--model", "chaplygin,lindelof,chetaev")
        assert result.exit_code == 0, result.output
        true, lindelof = upright(omega), upright(omega, lindelof=True)
        for model, lam in (("chaplygin", true), ("chetaev", true), ("lindelof", lindelof)):
            text = f"0 + {lam.imag:.6g}i" if lam.imag else f"{lam.real:.6g}"
            assert printed(result.stdout, model)[0] == text, (model, omega)
        assert "side by side (the largest real part, the named zero eigenvalues set aside):" in result.stdout
    doc = json.loads(
        run(DISK, "--at", "theta=0, psi'=0, phi'=1.5", "-m", "chaplygin,lindelof", "-f", "json").stdout
    )
    rows = {row["model"]: row for row in doc["models"]}
    np.testing.assert_allclose(
        nonzero(rows["chaplygin"]["eigenvalues"]), [-upright(1.5), upright(1.5)], rtol=1e-10
    )
    np.testing.assert_allclose(
        nonzero(rows["lindelof"]["eigenvalues"]),
        np.sort_complex([upright(1.5, True), -upright(1.5, True)]),
        rtol=1e-10,
    )
    assert (rows["chaplygin"]["kind"], rows["lindelof"]["kind"]) == ("unstable", "linearly stable")
    assert rows["chaplygin"]["stable"] is False and rows["lindelof"]["motion"] == "vakonomic"


def test_vakonomic_row_takes_its_multipliers_from_at() -> None:
    """One --at for every model: the names a model's state lacks (mu_1 for chaplygin) are left out."""
    at = "theta=0, psi'=0, phi'=2.5, psi=0, mu_1=-2.5, mu_2=0"  # Lindelöf's member: mu_1 = -m r w
    result = run(DISK, "--at", at, "--model", "chaplygin,vakonomic", "-f", "json")
    assert result.exit_code == 0, result.output
    rows = {row["model"]: row for row in json.loads(result.stdout)["models"]}
    lam = upright(2.5, lindelof=True)
    np.testing.assert_allclose(nonzero(rows["vakonomic"]["eigenvalues"]), [np.conj(lam), lam], rtol=1e-9)
    assert "mu_1" in rows["vakonomic"]["point"] and "mu_1" not in rows["chaplygin"]["point"]


def test_find_gives_the_classical_turning_relation() -> None:
    result = run(DISK, "--at", "theta=0.3, psi'=2, phi'=0", "--find", "--fixed", "theta,psi'", "-f", "json")
    assert result.exit_code == 0, result.output
    row = json.loads(result.stdout)["models"][0]
    assert row["found"]["fixed"] == ["theta", "psi'"] and row["found"]["family_dimension"] == 2
    theta, om, phid = row["point"]["theta"], row["point"]["psi'"], row["point"]["phi'"]
    m, r, A, C, g = (COIN[k] for k in ("m", "r", "A", "C", "g"))
    s = phid + om * np.sin(theta)
    relation = A * om**2 * np.sin(theta) * np.cos(theta) - (C + m * r**2) * s * om * np.cos(theta)
    assert relation - m * g * r * np.sin(theta) == pytest.approx(0.0, abs=1e-10)
    assert (theta, om) == (0.3, 2.0)


# ---------------------------------------------------------------- root locus, files, JSON
def test_root_locus_table_csv_json_and_figure(tmp_path: Path) -> None:
    out, plot = tmp_path / "locus.csv", tmp_path / "locus.png"
    args = [DISK, "--at", "theta=0, psi'=0", "--vary", "phi'=1:3:5", "-m", "chaplygin,lindelof"]
    result = run(*args, "--out", out, "--plot", plot)
    assert result.exit_code == 0, result.output
    assert f"wrote {out}" in result.stdout and f"wrote {plot}" in result.stdout
    assert plot.read_bytes().startswith(b"\x89PNG")
    rows = list(csv.DictReader(io.StringIO(out.read_text())))
    assert [r["model"] for r in rows] == ["chaplygin"] * 5 + ["lindelof"] * 5
    for r in rows:
        omega = float(r["phi'"])
        lam = upright(omega, lindelof=r["model"] == "lindelof")
        first = complex(float(r["re_1"]), float(r["im_1"]))
        assert first == pytest.approx(lam, rel=1e-10), (r["model"], omega)
    assert "  phi' = 1.5        unstable" in result.stdout.split("root locus of lindelof")[0]
    # JSON: the document printed is the one written, and reads back to the same numbers
    doc_path = tmp_path / "locus.json"
    printed_doc = json.loads(run(*args, "--out", doc_path, "-f", "json").stdout.split("\nwrote ")[0])
    written = json.loads(doc_path.read_text())
    assert printed_doc == written and written["schema"] == "chaplygin.stability/1"
    locus = written["locus"]["lindelof"]
    assert locus["parameter"] == "phi'" and locus["values"] == [1.0, 1.5, 2.0, 2.5, 3.0]
    back = [complex(*pair) for pair in locus["eigenvalues"][3]]
    assert back[0] == pytest.approx(upright(2.5, lindelof=True), rel=1e-10)
    assert written["at"] == {"theta": 0.0, "psi'": 0.0} and written["models"] == []


def test_outputs_are_refused_before_the_work_and_forced(tmp_path: Path, monkeypatch) -> None:
    out = tmp_path / "r.json"
    out.write_text("keep", encoding="utf-8")
    called = []
    monkeypatch.setattr(_steady, "assess", lambda *a, **k: called.append(a))
    refused = run(DISK, "--at", "theta=0, psi'=0, phi'=2.5", "--out", out)
    assert refused.exit_code == 1 and "already exists; pass --force to overwrite" in refused.stderr
    assert out.read_text() == "keep" and not called
    monkeypatch.undo()
    forced = run(DISK, "--at", "theta=0, psi'=0, phi'=2.5", "--out", out, "--force")
    assert forced.exit_code == 0, forced.output
    assert json.loads(out.read_text())["models"][0]["kind"] == "linearly stable"
    assert list(tmp_path.iterdir()) == [out]  # no temporary file left


def test_conditions_are_the_published_threshold() -> None:
    result = run(
        DISK, "--at", "theta=0, psi'=0, phi'=w", "--conditions", "-m", "chaplygin,lindelof", "-f", "json"
    )
    assert result.exit_code == 0, result.output
    found = json.loads(result.stdout)["conditions"]
    w, lam, s = sp.symbols("w lam s")
    m, r, A, C, g = sp.symbols("m r A C g")
    names = {"lam": lam, "w": w, "m": m, "r": r, "A": A, "C": C, "g": g}
    thresholds = {
        "chaplygin": m * g * r * A / (C * (C + m * r**2)),
        "lindelof": m * g * r * A / (C + m * r**2) ** 2,
    }
    for model, threshold in thresholds.items():
        assert found[model]["zero_roots"] == 2 and found[model]["route"] == "even"
        assert found[model]["from"] == model
        reduced = sp.sympify(found[model]["reduced"], locals=names).subs(lam**2, s)
        (square,) = sp.solve(reduced, s)  # the nonzero λ² of the upright disk
        assert sp.simplify(square.subs(w, sp.sqrt(threshold))) == 0, model  # zero at the threshold
        assert square.subs({**coin_values(m, r, A, C, g), w: 2.5}) == pytest.approx(
            upright(2.5, lindelof=model == "lindelof") ** 2, rel=1e-12
        )
    text = run(DISK, "--at", "theta=0, psi'=0, phi'=w", "--conditions").stdout
    assert (
        "stability conditions of chaplygin (the true motion):" in text
        and "zero roots factored out: 2" in text
    )


# ---------------------------------------------------------------- every error path
def _toml_with_time(tmp_path: Path) -> Path:
    text = runner.invoke(app, ["examples", "show", "chaplygin-sleigh"]).stdout
    path = tmp_path / "forced.toml"
    path.write_text(text.replace('T = "', 'V = "m*sin(t)*x"\nT = "', 1), encoding="utf-8")
    return path


@pytest.mark.parametrize(
    "args, status, words",
    [
        (
            ["--at", "theta=0, psi'=0, foo=2"],
            1,
            ["'foo' is not a coordinate, velocity or multiplier", "the names are psi, theta"],
        ),
        (["--at", "theta=0, phi'=2.5"], 1, ["no value for psi'", "given by theta, psi', theta', phi'"]),
        (["--at", "theta=0, psi'=0, phi'=2.5", "-m", "vakonomic"], 1, ["no value for psi, mu_1, mu_2"]),
        (["--at", "theta=0.3, psi'=2, phi'=0"], 1, ["not a steady motion of the chaplygin model", "--find"]),
        (["--at", "theta=0, psi'=0, phi'=x"], 2, ["phi'='x' is not a number", "NAME=NUMBER"]),
        (["--at", "theta=0 psi'=0"], 2, ["is not a number"]),
        (["--at", "theta=0, theta=1"], 2, ["theta is given twice"]),
        (["--at", "theta=nan, psi'=0"], 2, ["not a finite number"]),
        (["--at", "theta=0, psi'=0", "--vary", "phi'=0:5:0"], 2, ["COUNT must be a positive integer"]),
        (["--at", "theta=0, psi'=0", "--vary", "phi'=5:1:1"], 2, ["COUNT ≥ 2"]),
        (["--at", "theta=0, psi'=0", "--vary", "phi'=1,1"], 2, ["repeated values"]),
        (["--at", "theta=0, psi'=0", "--vary", "phi'=1:inf:3"], 2, ["finite"]),
        (["--at", "theta=0, psi'=0", "--vary", "phi'"], 2, ["NAME=START:STOP:COUNT"]),
        (
            ["--at", "theta=0, psi'=0", "--vary", "zz=0:1:3"],
            1,
            ["'zz' is neither a parameter", "(m, r, A, C, g)"],
        ),
        (
            ["--at", "theta=0, phi'=1", "--vary", "psi=0:1:3"],
            1,
            ["'psi' is not a reduced variable of the chaplygin model"],
        ),
        (["--at", "theta=0, psi'=0, phi'=2", "--fixed", "theta"], 2, ["--fixed goes with --find"]),
        (
            ["--at", "theta=0.3, psi'=2, phi'=0", "--find", "--fixed", "zz"],
            1,
            ["--fixed: 'zz' is not a reduced variable"],
        ),
        (["--at", "theta=0, psi'=0, phi'=2", "--plot", "x.png"], 2, ["give --vary"]),
        (
            ["--at", "theta=0, psi'=0, phi'=2", "--vary", "phi'=1:2:3", "--plot", "x.gif"],
            2,
            [".png, .svg or .pdf"],
        ),
        (["--at", "theta=0, psi'=0, phi'=2", "--out", "x.txt"], 2, [".json or .csv"]),
        (["--at", "theta=0, psi'=0, phi'=2", "--out", "x.csv"], 2, ["give --vary"]),
        (["--at", "theta=0, psi'=0, phi'=2", "-m", "newton"], 2, ["'newton' is not a model"]),
        (["--at", "theta=0, psi'=0, phi'=2", "-m", "chetaev,chetaev"], 2, ["chetaev is listed twice"]),
        (
            ["--at", "theta=0, psi'=0, phi'=2", "-p", "q=1"],
            1,
            ["--param: 'q' is not a parameter", "A, C, g, m, r"],
        ),
        (["--at", "theta=0, psi'=0, phi'=w", "--conditions", "--vary", "phi'=1:2:3"], 2, ["needs numbers"]),
        (["--at", "theta=0, psi'=0, phi'=m", "--conditions"], 1, ["m is a parameter"]),
    ],
)
def test_bad_input_is_one_clear_line(args: list[str], status: int, words: list[str], tmp_path: Path) -> None:
    result = run(DISK, *args)
    assert result.exit_code == status, result.output
    message = " ".join(result.stderr.replace("│", " ").split())
    for word in words:
        assert word in message, (word, message)
    if status == 1:
        assert result.stderr.startswith("error: ") and result.stderr.count("\n") == 1
    assert "Traceback" not in result.output
    assert list(tmp_path.iterdir()) == []


def test_a_system_with_explicit_time_is_refused(tmp_path: Path) -> None:
    result = run(_toml_with_time(tmp_path), "--at", "theta=0, x'=1")
    assert result.exit_code == 1
    assert "depend explicitly on the time t" in result.stderr and "autonomous systems only" in result.stderr


# ---------------------------------------------------------------- Ctrl-C and the time limit
def test_ctrl_c_stops_the_symbolic_work_at_once() -> None:
    """SymPy runs in a worker thread; the main thread waits in steps of 0.1 s and so hears Ctrl-C
    (here ``interrupt_main``) although the work never ends by itself."""
    release = threading.Event()
    threading.Timer(0.3, _thread.interrupt_main).start()
    try:
        with pytest.raises(KeyboardInterrupt):
            _steady._within(release.wait, None, "the work")
    finally:
        release.set()


def test_time_limit_of_the_conditions(monkeypatch) -> None:
    release = threading.Event()
    monkeypatch.setattr(chaplygin, "stability_conditions", lambda *a, **k: release.wait(), raising=False)
    try:
        result = run(DISK, "--at", "theta=0, psi'=0, phi'=w", "--conditions", "--time-limit", "0.3")
    finally:
        release.set()
    assert result.exit_code == 1
    assert "the symbolic conditions took longer than 0.3 s (--time-limit)" in result.stderr


def test_interrupted_run_leaves_no_output(tmp_path: Path, monkeypatch) -> None:
    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(chaplygin, "root_locus", interrupted, raising=False)
    out = tmp_path / "locus.csv"
    result = run(DISK, "--at", "theta=0, psi'=0", "--vary", "phi'=1:2:3", "--out", out)
    assert result.exit_code == 130 and "interrupted: no output was left half-written." in result.stderr
    assert list(tmp_path.iterdir()) == []


def test_parse_at_never_evaluates() -> None:
    assert _steady.parse_at("theta=0, phi'=2.5") == {"theta": 0.0, "phi'": 2.5}
    assert _steady.parse_at("phi'=w", symbols=True) == {"phi'": "w"}
    for text in ("phi'=__import__('os')", "phi'=1+1", "phi'=w"):
        with pytest.raises(ChaplyginError, match="is not a number"):
            _steady.parse_at(text)


# ---------------------------------------------------------------- the report's section
def test_report_section_has_the_eigenvalues_verdicts_and_root_locus(tmp_path: Path) -> None:
    page = tmp_path / "disk.html"
    args = ["report", DISK, "-o", page, "-t", "0.5", "-n", "11", "--at", "theta=0, psi'=0, phi'=1.5"]
    result = runner.invoke(app, [str(a) for a in [*args, "--vary", "phi'=1:2:3"]])
    assert result.exit_code == 0, result.output
    html = page.read_text(encoding="utf-8")
    section = html.split('<section id="stability"><h2>Steady motion and stability</h2>')[1].split(
        "</section>"
    )[0]
    assert '<a href="#stability">stability</a>' in html
    true, lindelof = upright(1.5), upright(1.5, lindelof=True)  # unstable, and stable: both models
    assert f'<td class="num">{true.real:.6g}<br>0<br>0<br>{-true.real:.6g}</td>' in section
    assert f"0 + {lindelof.imag:.6g}i" in section
    assert '<span class="verdict fails">unstable</span>' in section
    assert '<span class="verdict holds">linearly stable</span>' in section
    assert section.count("<svg") == 1 and 'id="figure-locus"' in section
    assert f"0 + {upright(2.0).imag:.5g}i" in section  # the locus's numbers at phi' = 2
    plain = runner.invoke(
        app, [str(a) for a in ["report", DISK, "-o", tmp_path / "p.html", "-t", "0.5", "-n", "11"]]
    )
    assert plain.exit_code == 0 and 'id="stability"' not in (tmp_path / "p.html").read_text(encoding="utf-8")


def test_report_refuses_stability_options_without_at(tmp_path: Path) -> None:
    result = runner.invoke(app, ["report", DISK, "-o", str(tmp_path / "r.html"), "--vary", "phi'=1:2:3"])
    assert result.exit_code == 2 and "--vary goes with --at" in " ".join(
        result.stderr.replace("│", " ").split()
    )
    bad = runner.invoke(app, ["report", DISK, "-o", str(tmp_path / "r.html"), "--at", "theta=0, phi'=1"])
    assert bad.exit_code == 1 and "no value for psi'" in bad.stderr
    assert list(tmp_path.iterdir()) == []


def test_a_system_that_is_not_chaplygins_defaults_to_the_chetaev_model(tmp_path: Path) -> None:
    """A pendulum in (x, y) with x² + y² = 4 (y appears in T and U: not a Chaplygin system). The
    default model was Voronets', whose symbolic equations kept the Whipple bicycle busy for more
    than ten minutes; the true motion is now linearised through the Chetaev model. Hanging at rest:
    λ = ±i √(g/L) (a pendulum of length L = 2)."""
    path = tmp_path / "pendulum.toml"
    path.write_text(
        'name = "Cartesian pendulum"\ncoordinates = ["x", "y"]\nparameters = { m = 0.5, g = 9.81 }\n'
        '[energy]\nT = "m/2*(x\'^2 + y\'^2)"\nV = "m*g*y"\n[holonomic]\ny = "x^2 + y^2 - 4"\n',
        encoding="utf-8",
    )
    result = run(path, "--at", "x=0, y=-2", "--format", "json")
    assert result.exit_code == 0, result.output
    [row] = json.loads(result.stdout)["models"]
    assert row["model"] == "chetaev" and row["kind"] == "linearly stable"
    np.testing.assert_allclose(
        sorted(im for _, im in row["eigenvalues"]), [-np.sqrt(9.81 / 2), np.sqrt(9.81 / 2)]
    )
