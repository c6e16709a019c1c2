"""The command line names command-line options in its messages, the Python API keyword arguments
(issue 28, item 5).

On main a11bdc0 ``chaplygin derive example:sleigh-chain --model chaplygin`` said ``Use
model='voronets'``, ``check`` said ``compare … model='chetaev' and model='vakonomic'``, and the
time-limit refusals named both ``time_limit=None`` and ``--time-limit 0`` (a sweep's also
``resume=True (--resume)``), in Python and on the command line alike.  Each path here runs the
command and checks that no ``name='value'`` (``name=None``, ``name=True``, ``name=[…]``) hint is
left, and that the option the hint meant is named; the Python API keeps its own syntax.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

import chaplygin
from chaplygin import examples
from chaplygin.apps import cli
from chaplygin.apps._wording import cli_wording
from chaplygin.errors import ChaplyginError, InputError
from chaplygin.numeric import simulate as numeric_simulate

runner = CliRunner()
#: a Python keyword hint, written independently of the code under test
PYTHON = re.compile(r"\b[a-z_]+ ?= ?('[^']*'|\"[^\"]*\"|None\b|True\b|False\b|\[)")
DISK = examples.get("rolling-disk")


@pytest.fixture(autouse=True)
def quick_estimates(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(numeric_simulate, "ESTIMATE_AFTER", 0.05)
    monkeypatch.setattr(numeric_simulate, "PROGRESS_EVERY", 0.02)


def said(*args: str, code: int = 1) -> str:
    """What ``chaplygin ARGS`` printed (stdout and stderr), checked free of Python hints."""
    result = runner.invoke(cli.app, list(args))
    assert result.exit_code == code, (result.exit_code, result.output, result.stderr)
    text = result.stdout + result.stderr
    assert not PYTHON.search(text), text
    assert "time_limit" not in text and "multipliers=" not in text, text
    return " ".join(text.split())  # rich may wrap


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["derive", "example:sleigh-chain", "--model", "chaplygin"], "Use --model voronets, which"),
        (
            ["derive", "example:sleigh-chain", "--model", "lindelof"],
            "use --model vakonomic (the multiplier form)",
        ),
        (
            ["simulate", "example:sleigh-chain", "--model", "vakonomic", "--constants", "1,1", "-t", "1"],
            "Invalid value for --constants",
        ),
    ],
)
def test_errors_name_the_option(tmp_path: Path, args: list[str], option: str) -> None:
    code = 1
    if args[0] == "simulate":  # a value the option refuses: a usage error
        args, code = [*args, "-o", str(tmp_path / "v.csv")], 2
    assert option in " ".join(said(*args, code=code).split())


def test_check_names_the_option_in_text_and_json() -> None:
    assert "compare the multiplier forms instead, with --models chetaev,vakonomic." in said(
        "check", "example:sleigh-chain", code=0
    )
    doc = json.loads(runner.invoke(cli.app, ["check", "example:sleigh-chain", "--format", "json"]).stdout)
    assert doc["comparison_unavailable"].endswith("with --models chetaev,vakonomic.")


def test_the_time_limit_refusals_name_one_form_each(tmp_path: Path) -> None:
    from chaplygin.apps.sweep import sweep

    # simulate: only --time-limit 0 on the command line, only time_limit=None in Python
    args = ["simulate", "example:rolling-disk", "-t", "1e300", "-o", str(tmp_path / "r.csv")]
    text = said(*args, "--time-limit", "60", "--backend", "numpy")
    assert (
        text.startswith("error: --t-end 1e+300: too long to run")
        and "--time-limit 0 to run it anyway" in text
    )
    assert "ask for a shorter time, or pass --time-limit 0" in text  # (was "… or, beyond the limit …")
    with pytest.raises(InputError, match=r"ask for a shorter time, or pass time_limit=None to run") as caught:
        chaplygin.simulate(
            DISK.constructor(),
            "voronets",
            1e300,
            DISK.initial,
            DISK.parameters,
            backend="numpy",
            time_limit=60,
        )
    assert "--" not in str(caught.value)
    # a sweep: --time-limit 0 with --resume; time_limit=None with resume=True
    grid = ["--grid", "x'=0.1:1:50", "--grid", "phi'=0.1:1:50"]
    out = tmp_path / "s.parquet"
    common = [
        "-t",
        "1",
        "-o",
        str(out),
        "--model",
        "chaplygin",
        "-b",
        "numpy",
        "-n",
        "11",
        "--scheduler",
        "serial",
    ]
    text = said("sweep", "example:knife-edge", *grid, *common, "--time-limit", "0.01")
    assert "beyond the limit of 0.01 s; the 2 runs done are kept: pass --time-limit 0 with --resume" in text
    with pytest.raises(ChaplyginError, match="pass time_limit=None with resume=True to finish") as refused:
        sweep("example:knife-edge", {"x'": "0.1:1:50", "phi'": "0.1:1:50"}, t_end=1.0, out=tmp_path / "p",
              model="chaplygin", backend="numpy", samples=11, scheduler="serial", time_limit=0.01)  # fmt: skip
    assert "--" not in str(refused.value)


def test_a_sweep_names_the_options_on_the_command_line_and_keywords_in_python(tmp_path: Path) -> None:
    pytest.importorskip("pyarrow")
    from chaplygin.apps.sweep import sweep

    held = tmp_path / "held.parquet"
    held.mkdir()
    (held / "_sweep.json").write_text("{}")
    common = ["example:knife-edge", "--grid", "x'=0.1,0.2", "-b", "numpy", "-n", "3"]
    text = said("sweep", *common, "-t", "1", "-o", str(held))
    assert "already holds a chaplygin sweep; pass --resume to finish it or --force to replace it." in text
    assert said("sweep", *common, "-t", "-1", "-o", str(tmp_path / "new")).startswith(
        "error: --t-end -1: the end time must be a positive number."
    )
    with pytest.raises(ChaplyginError, match="pass resume=True to finish it or force=True to replace it"):
        sweep("example:knife-edge", {"x'": [0.1, 0.2]}, t_end=1.0, out=held, backend="numpy", samples=3)
    with pytest.raises(ChaplyginError, match="t_end = -1: the end time must be a positive number"):
        sweep("example:knife-edge", {"x'": [0.1, 0.2]}, t_end=-1.0, out=tmp_path / "new", samples=3)


@pytest.mark.parametrize(
    ("python", "command_line"),
    [
        ("Use model='voronets', which", "Use --model voronets, which"),
        ("pass time_limit=None with resume=True to finish", "pass --time-limit 0 with --resume to finish"),
        ("t_end = 1e+300: too long", "--t-end 1e+300: too long"),
        ("export to='python' instead.", "export --to python instead."),
        ("with models=['chetaev', 'vakonomic'].", "with --models chetaev,vakonomic."),
        ("(e.g. step=0.01), not 0", "(e.g. --step 0.01), not 0"),
        (
            "give constants='match' (or the initial multipliers themselves, multipliers=[...]).",
            "give --constants match.",
        ),
        # not the API's keywords: left as they are
        ("expected NAME=NUMBER, e.g. m=1.5", "expected NAME=NUMBER, e.g. m=1.5"),
        ("--grid theta=0.1:0.5:5", "--grid theta=0.1:0.5:5"),
    ],
)
def test_the_wording(python: str, command_line: str) -> None:
    assert cli_wording(python) == command_line


def test_compare_names_the_end_time_option_and_refuses_a_model_twice() -> None:
    """Review of issue 28: ``compare -t -1`` said ``t_span: the end time …`` (Python's name), and
    ``--models chetaev,chetaev`` silently gave one row."""
    assert "--t-end -1 must be after the start 0." in said("compare", "example:knife-edge", "-t", "-1")
    twice = said("compare", "example:knife-edge", "--models", "chetaev,chetaev", "-t", "1", code=2)
    assert "chetaev is listed twice" in twice
    with pytest.raises(ChaplyginError, match="'chetaev' is listed twice"):
        chaplygin.compare(examples.knife_edge(), ["chetaev", "chetaev"], 1.0, {})
