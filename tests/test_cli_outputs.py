"""Outputs are checked before the work, and one exit status says "written, but a run stopped early".

On main d1d83f5 an unwritable ``--out`` was found only after the simulation or comparison, with a
message naming a hidden temporary file; and ``compare`` exited 1 where ``report`` exited 0 for the
same run that met a pole (``simulate`` 1, ``sweep`` 0).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from chaplygin.apps import cli
from unwritable import WAYS, unwritable

runner = CliRunner()

#: each command with an output, its output option's value (under ``{bad}``), and the function
#: that would do its work (which must not be called when the output cannot be written)
COMMANDS = {
    "simulate": (
        ["simulate", "example:knife-edge", "-t", "1", "-o", "{bad}/k.csv"],
        "chaplygin.numeric._plan.run",
    ),
    "compare": (
        ["compare", "example:knife-edge", "-t", "1", "-o", "{bad}/cmp"],
        "chaplygin.numeric.comparison.compare",
    ),
    "report": (
        ["report", "example:knife-edge", "-t", "1", "-o", "{bad}/r.html"],
        "chaplygin.apps.report.render_report",
    ),
    "export": (
        ["export", "example:knife-edge", "--to", "c", "-o", "{bad}/k.c"],
        "chaplygin.io.export.export",
    ),
    "sweep": (
        [
            "sweep",
            "example:knife-edge",
            "-m",
            "chaplygin",
            "-g",
            "x'=0.5,1",
            "-t",
            "1",
            "-b",
            "numpy",
            "-o",
            "{bad}/s.parquet",
        ],
        "chaplygin.apps.sweep.sweep",
    ),
    "demo": (["demo", "-o", "{bad}/demo.html"], "chaplygin.numeric.comparison.compare"),
    "stability": (
        ["stability", "example:rolling-disk", "--at", "theta=0, psi'=0, phi'=2.5", "-o", "{bad}/s.json"],
        "chaplygin.apps._steady.assess",
    ),
}


@pytest.mark.parametrize("how", WAYS)
@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_an_unwritable_output_is_refused_before_the_work(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, command: str, how: str
) -> None:
    args, work = COMMANDS[command]
    bad = unwritable(tmp_path, how)
    called: list[str] = []
    module, name = work.rsplit(".", 1)
    monkeypatch.setattr(f"{module}.{name}", lambda *a, **k: called.append(name))
    argv = [a.replace("{bad}", str(bad)) for a in args]
    result = runner.invoke(cli.app, argv)
    assert result.exit_code == 1, result.output
    given = argv[argv.index("-o") + 1]
    assert result.stderr.startswith(f"error: {given}: cannot be written there"), result.stderr
    assert ".tmp" not in result.stderr  # the path given, not a hidden temporary file
    assert called == []  # refused before the work


def test_a_read_only_folder_is_named_by_trajectory_writes(tmp_path: Path) -> None:
    """``Trajectory.to_csv`` (the Python API) names the file asked for, not its temporary file."""
    import chaplygin
    from chaplygin import examples

    bad = unwritable(tmp_path, "read-only folder")
    entry = examples.get("knife-edge")
    tr = chaplygin.simulate(entry.constructor(), "chaplygin", 0.1, entry.initial, entry.parameters, samples=3)
    with pytest.raises(PermissionError) as caught:
        tr.to_csv(bad / "k.csv")
    assert caught.value.filename == str(bad / "k.csv")


# ---------------------------------------------------------------- exit status 3: a run stopped early
POLE = ["example:knife-edge", "--initial", "phi'=1", "-t", "3", "-n", "31"]  # Lindelöf: a pole at t ≈ 1.55


def test_every_command_that_simulates_says_a_run_stopped_early_with_status_3(tmp_path: Path) -> None:
    """The same run, meeting a pole, in simulate, compare, report and sweep: outputs written, exit 3,
    a ``stopped early:`` line naming the model and why."""
    sim = runner.invoke(cli.app, ["simulate", *POLE, "-m", "lindelof", "-o", str(tmp_path / "s.csv")])
    cmp = runner.invoke(cli.app, ["compare", *POLE, "-o", str(tmp_path / "cmp")])
    rep = runner.invoke(cli.app, ["report", *POLE, "-o", str(tmp_path / "r.html")])
    swp = runner.invoke(
        cli.app,
        ["sweep", *POLE, "-m", "lindelof", "-g", "x'=1", "-b", "numpy", "-o", str(tmp_path / "s.parquet")],
    )
    for result in (sim, cmp, rep, swp):
        assert result.exit_code == cli.STOPPED_EARLY == 3, result.output
        assert "stopped early:" in result.stderr and "error:" not in result.stderr
    for result in (sim, cmp, rep):
        assert (
            "stopped early: lindelof: a pole of the solved constraints between t = 1.5 and 1.6"
            in result.stderr
        )
    assert len((tmp_path / "s.csv").read_text().splitlines()) == 1 + 16  # samples t = 0 … 1.5
    summary = json.loads((tmp_path / "cmp" / "summary.json").read_text())
    assert summary["models"]["lindelof"]["status"] == "failed"
    assert "<html" in (tmp_path / "r.html").read_text()
    from chaplygin.apps.sweep import read_results

    assert read_results(tmp_path / "s.parquet", ["status"]).column("status").to_pylist() == ["failed"]


def test_compare_says_each_pole_once_in_the_summary_and_once_in_its_stopped_early_line(
    tmp_path: Path,
) -> None:
    """The note of a run that stopped at a pole is in the summary printed on stdout, and in the
    exit-3 line on stderr (1300154 repeated it as a 'warning:' line too); the warning that another
    model is shown instead of the true motion's stays, once."""
    result = runner.invoke(cli.app, ["compare", *POLE, "-o", str(tmp_path / "cmp")])
    assert result.exit_code == 3
    assert "note: lindelof stops at a pole" in result.stdout
    assert result.stderr.count("stopped early: lindelof: a pole") == 1
    assert "lindelof stops at" not in result.stderr, result.stderr  # (the note's own words)
    assert result.stderr.count("warning: chaplygin: a pole") == 1, result.stderr


def test_a_run_that_reaches_the_end_exits_0(tmp_path: Path) -> None:
    result = runner.invoke(
        cli.app, ["compare", "example:knife-edge", "-t", "1", "-n", "11", "-o", str(tmp_path)]
    )
    assert result.exit_code == 0 and "stopped early" not in result.stderr
