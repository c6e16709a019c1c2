"""Sweeps and ensembles that trip scripts no more (issue 28, item 5).

On main a11bdc0: ``chaplygin sweep … --out x.csv`` wrote a Parquet folder named ``x.csv``;
``Ensemble.to_pandas()`` had no columns for the members' initial values, and a sweep's rows had
none for the dependent velocities at the start.  The knife edge's constraint gives the dependent
velocity in closed form, ``y' = tan(φ) x'``: the initial columns are checked against it.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from chaplygin import examples, simulate_ensemble
from chaplygin.apps import cli
from chaplygin.errors import ChaplyginError
from chaplygin.numeric._ckernel import Unavailable, compiler

runner = CliRunner()
try:
    compiler()
    AUTO = "c"
except Unavailable:  # pragma: no cover - every CI machine has a C compiler
    AUTO = "numpy"
needs_c = pytest.mark.skipif(AUTO != "c", reason="no C compiler")
KNIFE = examples.get("knife-edge")
COORDINATES = ("x", "y", "phi")


# ------------------------------------------------------------------ --out names its format
@pytest.mark.parametrize("name", ["x.csv", "x.npz", "results.txt"])
def test_an_out_named_for_another_format_is_refused_before_any_work(tmp_path: Path, name: str) -> None:
    out = tmp_path / name
    args = ["sweep", "example:knife-edge", "--grid", "x'=0.1,0.2", "-t", "0.1", "-o", str(out)]
    result = runner.invoke(cli.app, args)
    said = " ".join(result.stderr.replace("│", " ").split())  # (rich draws a box around it)
    assert result.exit_code == 2 and "a sweep writes a Parquet dataset" in said, said
    stem = name.split(".")[0]
    assert f"name it {stem}.parquet, or {stem} without a suffix" in said
    assert not out.exists()
    from chaplygin.apps.sweep import sweep

    # Python: the same, before the system is even looked at (an unknown example is not reached)
    with pytest.raises(ChaplyginError, match=rf"out='[^']*{name}': a sweep writes a Parquet dataset"):
        sweep("example:no-such-example", {"x'": [0.1]}, t_end=0.1, out=out)
    assert not out.exists()


# ------------------------------------------------------------------ initial values in the frames
def test_an_ensemble_frame_has_the_initial_values() -> None:
    pytest.importorskip("pandas")
    phi, xdot = np.array([0.1, 0.4, -0.7]), np.array([1.0, 0.5, 2.0])
    starts = [
        {"x": 0.5 * i, "y": -1.0, "phi": p, "x'": v, "phi'": 0.3} for i, (p, v) in enumerate(zip(phi, xdot))
    ]
    ens = simulate_ensemble(KNIFE.constructor(), "chaplygin", 0.2, starts, KNIFE.parameters)
    frame = ens.to_pandas()
    columns = list(frame.columns)
    wanted = [f"initial.{q}" for q in COORDINATES] + [f"initial.{q}'" for q in COORDINATES]
    assert columns[columns.index("param.m") + 1 : columns.index("status")][-6:] == wanted
    np.testing.assert_array_equal(frame["initial.phi"], phi)
    np.testing.assert_array_equal(frame["initial.x'"], xdot)
    np.testing.assert_array_equal(frame["initial.x"], [0.0, 0.5, 1.0])
    np.testing.assert_allclose(frame["initial.y'"], np.tan(phi) * xdot, rtol=1e-13)  # y' = tan φ x'
    assert not np.allclose(frame["initial.phi"], frame["final.phi"])  # the start, not the end
    assert "initial.y'" in ens.to_xarray()


def test_a_sweep_row_has_every_initial_velocity(tmp_path: Path) -> None:
    pytest.importorskip("pyarrow")
    from chaplygin.apps.sweep import sweep

    phi = [0.1, 0.4]
    result = sweep("example:knife-edge", {"phi": phi, "x'": "0.5,2"}, t_end=0.1, out=tmp_path / "knife",
                   model="chaplygin", backend="numpy", samples=5, scheduler="serial")  # fmt: skip
    table = result.table()
    names = table.column_names
    wanted = [f"initial.{q}" for q in COORDINATES] + [f"initial.{q}'" for q in COORDINATES]
    assert names[names.index("status") - 6 : names.index("status")] == wanted
    rows = table.to_pylist()
    for row in rows:
        assert row["initial.phi"] == row["grid.phi"] and row["initial.x'"] == row["grid.x'"]
        assert row["initial.y'"] == pytest.approx(np.tan(row["grid.phi"]) * row["grid.x'"], rel=1e-13)
    assert (tmp_path / "knife" / "_sweep.json").is_file()  # a name without a suffix: a Parquet folder


# ------------------------------------------------------------------ the defaults of simulate, and C
def summary(*args: str) -> tuple[str, str]:
    """``(MODEL, BACKEND)`` of the summary line of ``chaplygin ARGS`` (``knife [auto: c]: …``)."""
    result = runner.invoke(cli.app, list(args))
    assert result.exit_code == 0, (result.output, result.stderr)
    match = re.match(r"(\S+) \[([^\]]+)\][:,]", result.stdout)
    assert match, result.stdout
    return match[1], match[2]


@pytest.mark.parametrize("example", ["knife-edge", "sleigh-chain"])
def test_a_sweep_runs_what_simulate_runs_by_default(tmp_path: Path, example: str) -> None:
    pytest.importorskip("pyarrow")
    simulated = summary(
        "simulate", f"example:{example}", "-t", "0.05", "-n", "3", "-o", str(tmp_path / "s.csv")
    )
    swept = summary("sweep", f"example:{example}", "--grid", "x'=0.5,1", "-t", "0.05", "-n", "3",
                    "-o", str(tmp_path / "s.parquet"))  # fmt: skip
    # the knife edge is a Chaplygin system, the chain of sleighs is not (docs/gallery)
    assert (
        simulated
        == swept
        == ({"knife-edge": "chaplygin", "sleigh-chain": "voronets"}[example], f"auto: {AUTO}")
    )


@needs_c
def test_a_sweep_runs_on_c(tmp_path: Path) -> None:
    pytest.importorskip("pyarrow")
    from chaplygin.apps.sweep import sweep

    # heading fixed (phi' = 0): the knife edge slides straight on, x(t) = x(0) + x' t
    result = sweep("example:knife-edge", {"x'": [0.5, 2.0]}, t_end=3.0, out=tmp_path / "c.parquet",
                   initial={"phi'": 0.0, "x": 1.0}, backend="c", samples=5)  # fmt: skip
    table = result.table()
    assert result.backend == "c" and set(table.column("status").to_pylist()) == {"success"}
    np.testing.assert_allclose(table.column("final.x").to_numpy(), [1.0 + 0.5 * 3, 1.0 + 2.0 * 3], rtol=1e-12)
    assert result.to_pandas().attrs["backend"] == "c"


@needs_c
def test_a_first_compile_is_announced_and_a_cached_one_is_not(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("pyarrow")
    from chaplygin.numeric import _modelcache

    monkeypatch.setenv("CHAPLYGIN_CACHE", str(tmp_path / "cache"))  # nothing compiled there yet
    monkeypatch.setattr(_modelcache, "_LOADED", {})  # nor in this process
    args = ["sweep", "example:knife-edge", "--grid", "x'=0.5,1", "-t", "0.05", "-n", "3", "--backend", "c"]
    first = runner.invoke(cli.app, [*args, "-o", str(tmp_path / "first")])
    assert first.exit_code == 0 and first.stderr.startswith(
        "compiling the C kernel for Knife edge (first run, about 2 s; cached afterwards)"
    ), first.stderr
    again = runner.invoke(cli.app, [*args, "-o", str(tmp_path / "again")])
    assert again.exit_code == 0 and again.stderr == ""
    numpy = runner.invoke(cli.app, [*args[:-2], "--backend", "numpy", "-o", str(tmp_path / "numpy")])
    assert numpy.exit_code == 0 and numpy.stderr == ""  # nothing to compile
