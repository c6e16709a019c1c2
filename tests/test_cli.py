"""The command line: every command, exit statuses, --force, atomic writes, JSON schemas, quiet pipes."""

from __future__ import annotations

import io
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from rich.console import Console
from sympy.parsing.sympy_parser import parse_expr
from sympy.physics.mechanics import dynamicsymbols
from typer.testing import CliRunner

import chaplygin
from chaplygin import examples
from chaplygin.apps import cli
from chaplygin.apps.cli import app

runner = CliRunner()
T_ = dynamicsymbols._t
EXAMPLES = ("rolling-sphere", "knife-edge", "vertical-rolling-disk", "rolling-disk")

# A system that is not a Chaplygin system: the constraint coefficient depends on z (dependent).
VORONETS_TOML = """
name = "Voronets test system"
coordinates = ["x", "y", "z"]

[parameters]
m = 1.0

[energy]
T = "m/2*(x'^2 + y'^2 + z'^2)"

[constraints]
"z'" = "z*y'"

[initial]
x = 0.0
y = 0.0
z = 1.0
"x'" = 1.0
"y'" = 0.5
"""


def run(*args: str, **kwargs):
    return runner.invoke(app, list(args), **kwargs)


def no_traceback(result) -> None:
    assert "Traceback" not in result.output and "Traceback" not in (result.stderr or "")


@pytest.fixture
def voronets_file(tmp_path: Path) -> Path:
    path = tmp_path / "voronets.toml"
    path.write_text(VORONETS_TOML, encoding="utf-8")
    return path


# ---------------------------------------------------------------- usage: exit status 2
@pytest.mark.parametrize(
    "args",
    [
        [],  # no command
        ["bogus-command"],
        ["derive", "example:knife-edge", "--form", "newest"],  # not a form
        ["derive", "example:knife-edge", "--model", "newton"],  # not a model
        ["derive", "example:knife-edge", "--model", "chetaev", "--format", "xml"],
        ["simulate", "example:knife-edge", "--model", "chaplygin", "--t-end", "1", "--out", "run.txt"],
        [
            "simulate",
            "example:knife-edge",
            "--model",
            "chaplygin",
            "--t-end",
            "1",
            "--out",
            "r.csv",
            "--param",
            "m",
        ],  # not NAME=NUMBER
        [
            "simulate",
            "example:knife-edge",
            "--model",
            "chaplygin",
            "--t-end",
            "1",
            "--out",
            "r.csv",
            "--samples",
            "1",
        ],
        ["compare", "example:knife-edge", "--t-end", "1", "--out", "d", "--models", "chaplygin,newton"],
        ["examples", "show", "no-such-example"],
        ["check", "example:knife-edge", "--unknown-option"],
    ],
)
def test_wrong_usage_exits_2(args: list[str], tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    result = run(*args)
    assert result.exit_code == 2, result.output
    no_traceback(result)
    assert not list(tmp_path.iterdir())  # nothing written


def test_help() -> None:
    result = run("--help")
    assert result.exit_code == 0
    for command in ("derive", "check", "simulate", "compare", "report", "demo", "examples"):
        assert command in result.output


# ---------------------------------------------------------------- failures: exit status 1
def test_bad_inputs_exit_1_with_a_message(tmp_path: Path, voronets_file: Path) -> None:
    missing = run("derive", str(tmp_path / "nowhere.toml"), "--model", "chetaev")
    assert missing.exit_code == 1 and "nowhere.toml" in missing.stderr
    unknown = run("check", "example:no-such-example")
    assert unknown.exit_code == 1 and "knife-edge" in unknown.stderr  # lists the examples
    bad = tmp_path / "bad.toml"
    bad.write_text('coordinates = ["x"\n[energy]\nT = "x\'^2"\n', encoding="utf-8")
    broken = run("check", str(bad))
    assert broken.exit_code == 1 and broken.stderr.startswith("error:")
    not_chaplygin = run("derive", str(voronets_file), "--model", "chaplygin")
    assert not_chaplygin.exit_code == 1 and "not a Chaplygin system" in not_chaplygin.stderr
    for result in (missing, unknown, broken, not_chaplygin):
        no_traceback(result)
        assert result.stdout == ""


def test_unexpected_errors_are_reported_without_traceback(monkeypatch) -> None:
    def boom(*args, **kwargs):
        raise RuntimeError("something nobody foresaw")

    monkeypatch.setattr(chaplygin.System, "integrability", boom)
    result = run("check", "example:knife-edge")
    assert result.exit_code == 1
    assert "unexpected RuntimeError: something nobody foresaw" in result.stderr
    no_traceback(result)


# ---------------------------------------------------------------- derive
def parse_file_syntax(text: str, system: chaplygin.System) -> sp.Expr:
    """Read an expression of the file syntax back (test-side; the library never parses this way)."""
    names = {q.func.__name__: q for q in system.coordinates}
    local: dict[str, object] = {p.name: p for p in system.parameters}
    for name, q in names.items():
        local[name] = q
        local[f"{name}__d"] = q.diff(T_)
        local[f"{name}__dd"] = q.diff(T_, 2)
    text = re.sub(r"([A-Za-z_]\w*)''", r"\1__dd", text)
    text = re.sub(r"([A-Za-z_]\w*)'", r"\1__d", text)
    local["t"] = T_
    return parse_expr(text, local_dict=local)


@pytest.mark.parametrize("name", ["knife-edge", "rolling-sphere"])
def test_derive_json_schema_and_file_syntax(name: str) -> None:
    result = run("derive", f"example:{name}", "--model", "chaplygin", "--format", "json")
    assert result.exit_code == 0, result.stderr
    doc = json.loads(result.stdout)
    assert set(doc) == {
        "schema",
        "system",
        "model",
        "form",
        "title",
        "coordinates",
        "independent",
        "dependent",
        "parameters",
        "constraints",
        "unknowns",
        "multipliers",
        "constants",
        "equations",
        "accelerations",
        "linear_system",
    }
    assert doc["schema"] == "chaplygin.derive/2" and doc["model"] == "chaplygin"
    assert doc["linear_system"] is None and doc["accelerations"]  # small enough to print solved
    system = examples.get(name).constructor()
    assert doc["coordinates"] == [q.func.__name__ for q in system.coordinates]
    assert doc["unknowns"] == [f"{q.func.__name__}''" for q in system.independent]
    text = json.dumps(doc)
    assert "Derivative" not in text and "(t)" not in text
    # the strings are the file syntax: read back, they are chaplygin's expressions
    eqs = system.equations("chaplygin")
    for sides, eq in zip(doc["equations"], eqs.equations):
        assert sp.simplify(parse_file_syntax(sides["lhs"], system) - eq.lhs) == 0
        assert sp.simplify(parse_file_syntax(sides["rhs"], system) - eq.rhs) == 0
    for key, value in doc["accelerations"].items():
        acc = parse_file_syntax(key, system)
        assert sp.simplify(parse_file_syntax(value, system) - eqs.accelerations[acc]) == 0
    for key, value in doc["constraints"].items():
        assert (
            sp.simplify(parse_file_syntax(value, system) - system.constraints[parse_file_syntax(key, system)])
            == 0
        )


def test_derive_text_latex_and_multipliers() -> None:
    text = run("derive", "example:knife-edge", "--model", "chetaev")
    assert text.exit_code == 0
    assert "Chetaev model" in text.stdout and "x'' = " in text.stdout and "lambda_1 = " in text.stdout
    latex = run("derive", "example:knife-edge", "--model", "lindelof", "--form", "new", "--format", "latex")
    assert latex.exit_code == 0 and r"\begin{aligned}" in latex.stdout and r"\ddot{x}" in latex.stdout
    bare = run(
        "derive", "example:knife-edge", "--model", "vakonomic", "--format", "json", "--no-accelerations"
    )
    doc = json.loads(bare.stdout)
    assert doc["accelerations"] is None and doc["multipliers"] == ["mu_1"]
    assert any("mu_1'" in e["lhs"] for e in doc["equations"])


def test_derive_defaults_to_the_true_motion() -> None:
    for name, title in (("knife-edge", "Chaplygin's equations"), ("turntable-ball", "Voronets' equations")):
        doc = json.loads(run("derive", f"example:{name}", "-f", "json").stdout)
        assert doc["title"].startswith(title), name


def test_derive_simplify_gives_the_same_accelerations() -> None:
    """--simplify is a display option: the solved accelerations are the same functions."""
    from chaplygin.io.parser import Names, parse_expression

    docs = [
        json.loads(run("derive", "example:knife-edge", "-m", "chetaev", "-f", "json", *extra).stdout)
        for extra in ((), ("--simplify",))
    ]
    assert docs[0]["accelerations"].keys() == docs[1]["accelerations"].keys()
    names = Names.build(parameters=docs[0]["parameters"] + ["lambda_1"], coordinates=docs[0]["coordinates"])
    point = {
        sp.Symbol(p, real=True): 0.7 + i / 10 for i, p in enumerate(docs[0]["parameters"] + ["lambda_1"])
    }
    t = dynamicsymbols._t
    for q, v in zip(dynamicsymbols(docs[0]["coordinates"]), (0.3, -0.4, 0.5)):
        point[q.diff(t)] = v + 1
        point[q] = v
    for key in docs[0]["accelerations"]:
        plain, simple = (parse_expression(d["accelerations"][key], names) for d in docs)
        assert float(plain.xreplace(point)) == pytest.approx(float(simple.xreplace(point)), rel=1e-12)


# ---------------------------------------------------------------- check
def test_check_json_and_text() -> None:
    sphere = json.loads(run("check", "example:rolling-sphere", "--format", "json").stdout)
    assert sphere["schema"] == "chaplygin.check/1"
    assert sphere["integrability"]["integrable"] is False
    assert sphere["integrability"]["condition_28"]["holds"] is False
    assert sphere["chaplygin_system"] == {"is_chaplygin": True, "obstructions": []}
    assert sphere["comparison"]["verdict"] == "differ"
    assert set(sphere["comparison"]["defect"]) == {"psi", "theta", "phi"}
    assert "lindelof/classic" in sphere["models"]["applicable"]
    disk = json.loads(run("check", "example:vertical-rolling-disk", "--format", "json").stdout)
    assert disk["comparison"]["verdict"] == "lindelof_right_here"
    text = run("check", "example:rolling-sphere")
    assert text.exit_code == 0
    assert "not integrable" in text.stdout and "the models differ" in text.stdout


def test_check_of_a_voronets_system(voronets_file: Path) -> None:
    doc = json.loads(run("check", str(voronets_file), "--format", "json").stdout)
    assert doc["chaplygin_system"]["is_chaplygin"] is False
    assert doc["comparison"] is None and "vakonomic" in doc["comparison_unavailable"]
    assert "chaplygin" in doc["models"]["not_applicable"]


# ---------------------------------------------------------------- simulate, --force, atomic writes
def test_simulate_csv_and_npz(tmp_path: Path) -> None:
    csv, npz = tmp_path / "knife.csv", tmp_path / "sub" / "knife.npz"
    result = run(
        "simulate",
        "example:knife-edge",
        "--model",
        "chaplygin",
        "--t-end",
        "2",
        "--samples",
        "21",
        "--out",
        str(csv),
    )
    assert result.exit_code == 0, result.stderr
    assert str(csv) in result.stdout and "success" in result.stdout
    header = csv.read_text().splitlines()[0].split(",")
    assert header[:4] == ["t", "x", "y", "phi"] and "energy" in header
    assert len(csv.read_text().splitlines()) == 22
    result = run(
        "simulate",
        "example:knife-edge",
        "--model",
        "chetaev",
        "--t-end",
        "2",
        "--samples",
        "21",
        "--out",
        str(npz),
        "--param",
        "m=2",
        "--initial",
        "phi'=1",
    )
    assert result.exit_code == 0, result.stderr
    data = np.load(npz)
    assert data["phi'"][0] == 1.0 and "lambda_1" in data.files


def test_existing_output_needs_force(tmp_path: Path) -> None:
    out = tmp_path / "run.csv"
    out.write_text("precious\n")
    args = [
        "simulate",
        "example:knife-edge",
        "--model",
        "chaplygin",
        "--t-end",
        "1",
        "--samples",
        "5",
        "--out",
        str(out),
    ]
    refused = run(*args)
    assert refused.exit_code == 1 and "--force" in refused.stderr
    assert out.read_text() == "precious\n"
    forced = run(*args, "--force")
    assert forced.exit_code == 0 and out.read_text().startswith("t,")


def test_interrupted_write_leaves_the_previous_file(tmp_path: Path, monkeypatch) -> None:
    out = tmp_path / "run.csv"
    out.write_text("previous run\n")

    class HalfThenInterrupt:  # the table: one row is written, then Ctrl-C
        def tolist(self):
            yield [0.0, 1.0]
            raise KeyboardInterrupt

    from chaplygin.numeric.simulate import Trajectory

    monkeypatch.setattr(Trajectory, "table", lambda self: HalfThenInterrupt())
    result = run(
        "simulate",
        "example:knife-edge",
        "--model",
        "chaplygin",
        "--t-end",
        "1",
        "--samples",
        "5",
        "--out",
        str(out),
        "--force",
    )
    assert result.exit_code != 0
    assert out.read_text() == "previous run\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.csv"]  # no temporary left


def test_interrupted_report_leaves_the_previous_file(tmp_path: Path, monkeypatch) -> None:
    from chaplygin.apps import report

    out = tmp_path / "r.html"
    out.write_text("<p>old report</p>")
    monkeypatch.setattr(report, "render_report", lambda *a, **k: "<p>new</p>" * 50_000)
    real_fdopen = os.fdopen

    class Dies:
        def __init__(self, fh):
            self.fh = fh

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.fh.close()

        def write(self, data):
            self.fh.write(data)
            raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fdopen", lambda fd, mode="r", *a, **k: Dies(real_fdopen(fd, mode, *a, **k)))
    result = run("report", "example:knife-edge", "--out", str(out), "--force")
    assert result.exit_code == 1 and "No space left" in result.stderr
    no_traceback(result)
    assert out.read_text() == "<p>old report</p>"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.html"]


def test_a_failed_run_is_written_and_exits_3(tmp_path: Path, monkeypatch) -> None:
    from chaplygin.numeric.simulate import Trajectory

    def failing(system, model, t_span, initial, parameters=None, **options):
        z = np.zeros(1)
        return Trajectory(
            model,
            "classic",
            "numpy",
            z,
            {"x": z},
            {"x'": z},
            {},
            z,
            z,
            status="failed",
            message="the solution blew up at t = 0.5",
        )

    monkeypatch.setattr("chaplygin.numeric.simulate.simulate", failing)
    monkeypatch.setenv("CHAPLYGIN_CACHE", str(tmp_path / "cache"))  # no run plan answers without System
    out = tmp_path / "run.csv"
    result = run("simulate", "example:knife-edge", "--model", "chaplygin", "--t-end", "1", "--out", str(out))
    assert result.exit_code == 3 and "stopped early: chaplygin: the solution blew up" in result.stderr
    assert out.exists()


# ---------------------------------------------------------------- compare, report
def test_compare_writes_summary_trajectories_and_figures(tmp_path: Path) -> None:
    out = tmp_path / "cmp"
    args = [
        "compare",
        "example:knife-edge",
        "--models",
        "chaplygin,lindelof,chetaev",
        "--t-end",
        "1",
        "--samples",
        "31",
        "--out",
        str(out),
    ]
    result = run(*args)
    assert result.exit_code == 0, result.stderr
    names = sorted(p.name for p in out.iterdir())
    assert names == sorted(
        [
            "summary.txt",
            "summary.json",
            "chaplygin.csv",
            "lindelof.csv",
            "chetaev.csv",
            "paths.svg",
            "coordinates.svg",
            "invariants.svg",
        ]
    )
    doc = json.loads((out / "summary.json").read_text())
    assert doc["schema"] == "chaplygin.compare/1" and doc["reference"] == "chaplygin"
    assert doc["path"] == ["x", "y"]
    assert doc["models"]["chetaev"]["max_distance"] < 1e-6 < doc["models"]["lindelof"]["max_distance"]
    assert "lindelof" in result.stdout and "max distance" in result.stdout
    again = run(*args)
    assert again.exit_code == 1 and "--force" in again.stderr
    assert run(*args, "--force").exit_code == 0


def test_report_command(tmp_path: Path) -> None:
    out = tmp_path / "knife.html"
    args = ["report", "example:knife-edge", "--out", str(out), "--t-end", "1", "--samples", "21"]
    result = run(*args)
    assert result.exit_code == 0, result.stderr
    html = out.read_text(encoding="utf-8")
    assert html.count("<math") > 10 and html.count("<svg") == 3
    assert 'id="paper"' not in html  # the paper's table is for the sphere only
    assert run(*args).exit_code == 1 and out.read_text(encoding="utf-8") == html


# ---------------------------------------------------------------- demo
@pytest.fixture(scope="module")
def demo_run(tmp_path_factory):
    where = tmp_path_factory.mktemp("demo")
    cwd = os.getcwd()
    os.chdir(where)
    try:
        result = run("demo", "--t-end", "10")
    finally:
        os.chdir(cwd)
    return where, result


def test_demo(demo_run) -> None:
    where, result = demo_run
    assert result.exit_code == 0, result.stderr
    text = result.stdout
    assert "not integrable" in text and "the models differ" in text
    assert "Chaplygin (15) = new form (40) = Chetaev multipliers (6): yes" in text
    assert re.search(r"Lindelöf's centre drifts from the true path: \d", text)
    assert "1 agree, 13 differ by a transcription error, 0 differ in substance" in text
    report = where / "demo" / "report.html"
    assert report.exists() and cli._is_demo_report(report)


def test_demo_replaces_only_its_own_report(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "demo").mkdir()
    foreign = tmp_path / "demo" / "report.html"
    foreign.write_text("<p>somebody's notes</p>")
    result = run("demo")
    assert result.exit_code == 1 and "not a chaplygin demo report" in result.stderr
    assert foreign.read_text() == "<p>somebody's notes</p>"


# ---------------------------------------------------------------- examples
def test_examples_list_and_show(tmp_path: Path) -> None:
    from chaplygin.io import files

    listing = run("examples", "list")
    assert listing.exit_code == 0
    for name in EXAMPLES:
        assert name in listing.stdout
    shown = run("examples", "show", "knife-edge")
    assert shown.exit_code == 0
    loaded = files.loads(shown.stdout)
    reference = examples.get("knife-edge").constructor()
    assert [q.func.__name__ for q in loaded.system.coordinates] == ["x", "y", "phi"]
    rename = {p: reference.parameter(p.name) for p in loaded.system.parameters}
    assert sp.simplify(loaded.system.kinetic_energy.xreplace(rename) - reference.kinetic_energy) == 0
    # the printed file is a valid FILE for every command
    path = tmp_path / "knife.toml"
    path.write_text(shown.stdout, encoding="utf-8")
    assert run("check", str(path)).exit_code == 0


# ---------------------------------------------------------------- progress: terminal vs pipe
def test_quiet_when_piped() -> None:
    result = run("derive", "example:rolling-sphere", "--model", "chaplygin")
    assert result.exit_code == 0
    assert "\x1b[" not in result.output  # no escape codes, no progress bar
    assert result.stderr == ""
    assert not any(ch in result.output for ch in "━⠋⠙⠹")


def test_progress_on_a_terminal(monkeypatch) -> None:
    screen = io.StringIO()
    terminal = Console(file=screen, force_terminal=True, width=100)
    monkeypatch.setattr(cli, "_stderr", lambda: terminal)
    with cli._Steps(2, "working") as steps:
        steps.step("deriving the chaplygin equations")
        steps.step("solving for the accelerations")
    assert "deriving the chaplygin equations" in screen.getvalue() or "solving" in screen.getvalue()
    quiet = io.StringIO()
    monkeypatch.setattr(cli, "_stderr", lambda: Console(file=quiet))
    with cli._Steps(2, "working") as steps:
        steps.step("deriving")
    assert quiet.getvalue() == ""


def test_python_m_chaplygin() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "chaplygin", "examples", "list"], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0 and "rolling-sphere" in result.stdout
    usage = subprocess.run(
        [sys.executable, "-m", "chaplygin", "derive"], capture_output=True, text=True, timeout=120
    )
    assert usage.returncode == 2


# ---------------------------------------------------------------- meaningless input: refused, exit 1
KNIFE = ["simulate", "example:knife-edge", "--samples", "5"]


@pytest.mark.parametrize(
    "args,named",
    [
        (["--t-end", "1", "--param", "m=-1"], "m = -1"),  # negative mass
        (["--t-end", "1", "--param", "J=0"], "J = 0"),  # no inertia
        (["--t-end", "1", "--param", "J=nan"], "J = nan"),
        (["--t-end", "1", "--initial", "phi=1.5707963267948966"], "pole of the solved constraints"),
        (["--t-end", "1", "--initial", "x'=inf"], "x' = inf"),
        (["--t-end", "inf"], "--t-end = inf"),
        (["--t-end", "-1"], "must be after the start"),
        (["--t-end", "1", "--samples", "10000000"], "--samples 10000000"),  # (Python: samples = 10000000)
    ],
)
def test_meaningless_input_exits_1_and_writes_nothing(tmp_path: Path, args: list[str], named: str) -> None:
    out = tmp_path / "run.csv"
    result = run(*KNIFE, *args, "--out", str(out))
    assert result.exit_code == 1, result.output
    assert result.stderr.startswith("error:") and named in result.stderr, result.stderr
    assert "RuntimeWarning" not in result.stderr
    no_traceback(result)
    assert not out.exists()


@pytest.mark.parametrize("option", ["--rtol", "--atol"])
@pytest.mark.parametrize("value", ["0", "-1e-9", "inf", "nan"])
def test_tolerances_must_be_positive_and_finite(tmp_path: Path, option: str, value: str) -> None:
    result = run(*KNIFE, "--t-end", "1", option, value, "--out", str(tmp_path / "r.csv"))
    assert result.exit_code == 2 and "positive finite tolerance" in result.output
    assert not list(tmp_path.iterdir())


def test_tolerances_reach_the_integrator(tmp_path: Path) -> None:
    """Loose tolerances give a visibly larger constraint drift of the multiplier model."""

    def residual(*tolerances: str) -> float:
        result = run(
            *KNIFE,
            "--model",
            "chetaev",
            "--t-end",
            "2",
            "--initial",
            "phi'=1",
            "--force",
            "--out",
            str(tmp_path / "r.csv"),
            *tolerances,
        )
        assert result.exit_code == 0, result.stderr
        return float(re.search(r"max constraint residual ([0-9.e+-]+)", result.stdout).group(1))

    assert residual("--rtol", "1e-3", "--atol", "1e-3") > 1e3 * residual()


def test_model_defaults_to_the_true_motion(tmp_path: Path, voronets_file: Path) -> None:
    chaplygin_system = run(*KNIFE, "--t-end", "1", "--out", str(tmp_path / "a.csv"))
    assert chaplygin_system.exit_code == 0 and chaplygin_system.stdout.startswith("chaplygin [")
    other = run(
        "simulate", str(voronets_file), "--t-end", "0.5", "--samples", "5", "--out", str(tmp_path / "b.csv")
    )
    assert other.exit_code == 0 and other.stdout.startswith("voronets ["), other.stderr


def test_missing_initial_velocity_is_a_warning(tmp_path: Path, voronets_file: Path) -> None:
    text = voronets_file.read_text().replace('"y\'" = 0.5\n', "")
    no_velocity = tmp_path / "v.toml"
    no_velocity.write_text(text, encoding="utf-8")
    result = run(
        "simulate", str(no_velocity), "--t-end", "0.5", "--samples", "5", "--out", str(tmp_path / "v.csv")
    )
    assert result.exit_code == 0
    assert "warning: initial: y' is given neither in [initial] nor by --initial; it is 0." in result.stderr
    given = run(
        "simulate",
        str(no_velocity),
        "--t-end",
        "0.5",
        "--samples",
        "5",
        "--out",
        str(tmp_path / "w.csv"),
        "--initial",
        "y'=0.5",
    )
    assert given.exit_code == 0 and "warning" not in given.stderr


def test_created_folders_are_said(tmp_path: Path) -> None:
    out = tmp_path / "new" / "deeper" / "run.csv"
    result = run(*KNIFE, "--t-end", "1", "--out", str(out))
    assert result.exit_code == 0 and out.exists()
    assert (
        f"created the folder {tmp_path / 'new' / 'deeper'} (and 1 above it): it did not exist"
        in result.stdout
    )
    again = run(*KNIFE, "--t-end", "1", "--out", str(out), "--force")
    assert again.exit_code == 0 and "it did not exist" not in again.stdout


def test_compare_at_a_pole_warns_and_notes_the_fallback(tmp_path: Path) -> None:
    result = run(
        "compare",
        "example:knife-edge",
        "--t-end",
        "1",
        "--samples",
        "21",
        "--models",
        "chaplygin,chetaev",
        "--out",
        str(tmp_path / "cmp"),
        "--initial",
        "phi=1.2",
        "--initial",
        "phi'=1",
    )
    assert result.exit_code == 0, result.stderr
    assert "warning: chaplygin: a pole of the solved constraints" in result.stderr
    assert "note: chaplygin" in result.stdout and "chetaev model" in result.stdout
    doc = json.loads((tmp_path / "cmp" / "summary.json").read_text())
    assert doc["models"]["chaplygin"]["status"] == "success" and len(doc["notes"]) == 2
    assert doc["notes"][0].startswith("chaplygin and chetaev are the same motion")  # (two names of it)


def test_version() -> None:
    result = run("--version")
    assert result.exit_code == 0 and result.stdout.strip() == f"chaplygin {chaplygin.__version__}"
