"""``check`` and ``derive`` on the rattleback through the command line (issue 18: a rolling body
goes through every command like any file): the verdicts, and a solved form too large to print
given as its linear system."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from chaplygin.apps.cli import app

runner = CliRunner()


@pytest.fixture(autouse=True)
def _own_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("CHAPLYGIN_CACHE", str(tmp_path / "cache"))


def test_check_finds_the_rolling_constraints_nonholonomic_and_the_models_different() -> None:
    result = runner.invoke(app, ["check", "example:rattleback", "--format", "json"])
    assert result.exit_code == 0, result.stderr
    doc = json.loads(result.stdout)
    integ = doc["integrability"]
    assert integ["integrable"] is False and integ["frobenius"]["holds"] is False
    assert integ["condition_28"]["holds"] is False and integ["relations"] == []
    assert doc["chaplygin_system"]["is_chaplygin"] is True
    cmp = doc["comparison"]
    assert cmp["verdict"] == "differ" and not cmp["coincide"] and not cmp["defect_vanishes"]
    assert sorted(cmp["defect"]) == ["phi", "psi", "theta"]

    text = runner.invoke(app, ["check", "example:rattleback"])
    assert text.exit_code == 0, text.stderr
    assert "not integrable (nonholonomic)" in text.stdout and "the models differ" in text.stdout
    # the pages of defect, and the thousands of characters of the failing components, are shown
    # as their leading terms and their size (the JSON and --full have them whole)
    assert max(map(len, text.stdout.splitlines())) < 520
    assert text.stdout.count("characters; --full prints it)") == 6
    whole = runner.invoke(app, ["check", "example:rattleback", "--full"])
    assert whole.exit_code == 0, whole.stderr
    for q, d in cmp["defect"].items():
        assert f"  {q}: {d}" in whole.stdout.splitlines()
    assert integ["frobenius"]["failures"][0]["value"] in whole.stdout


def test_derive_prints_the_linear_system_where_the_solved_form_is_too_large() -> None:
    result = runner.invoke(app, ["derive", "example:rattleback", "--format", "json"])
    assert result.exit_code == 0, result.stderr
    doc = json.loads(result.stdout)
    assert doc["model"] == "chaplygin" and doc["unknowns"] == ["psi''", "theta''", "phi''"]
    assert doc["accelerations"] is None
    linear = doc["linear_system"]
    assert [len(row) for row in linear["mass_matrix"]] == [3, 3, 3] and len(linear["forcing"]) == 3
    M = linear["mass_matrix"]
    assert all(M[i][j] == M[j][i] for i in range(3) for j in range(3))  # a kinetic-energy Hessian

    text = runner.invoke(app, ["derive", "example:rattleback", "--full"])  # the stored derivation
    assert text.exit_code == 0, text.stderr
    assert "M*x = F with x = (psi'', theta'', phi'')" in text.stdout
    assert f"  M[1,2] = {M[0][1]}\n" in text.stdout and f"  F[3] = {linear['forcing'][2]}" in text.stdout
    assert "Solved:" not in text.stdout
    folded = runner.invoke(app, ["derive", "example:rattleback"])  # each entry beyond a screen folded
    assert folded.exit_code == 0 and "M*x = F with x = (psi'', theta'', phi'')" in folded.stdout
    assert "  F[3] = " in folded.stdout and "--full prints it whole" in folded.stdout
    assert max(map(len, folded.stdout.splitlines())) < 3000


def test_a_small_solved_form_is_still_printed() -> None:
    result = runner.invoke(app, ["derive", "example:lindelof-problem", "--format", "json"])
    assert result.exit_code == 0, result.stderr
    doc = json.loads(result.stdout)
    assert sorted(doc["accelerations"]) == ["phi''", "psi''", "theta''"] and doc["linear_system"] is None
