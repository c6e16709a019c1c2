"""A warm ``chaplygin sweep`` of a system file runs without SymPy (issue 31).

A sweep of a file keeps, beside the run plan of its model (:mod:`chaplygin.numeric._plan`), a
summary of the file's names; the next sweep of the same bytes, model and options reads them
instead of building the system, and each run is answered by the plan where it answers exactly
as the full path would (else by the full path, the system built then).  The rows must be the
full path's, but for ``wall_time``.  Whether SymPy was imported is read off ``sys.modules`` of
a fresh process.  Nothing is timed.
"""

from __future__ import annotations

import json

import chaplygin
from chaplygin.apps.sweep import read_results, sweep
from subprocesses import run_json
from test_warm_file import SNAKEBOARD

# a process that sweeps a file from the command line, then says what it imported
SWEEP = """
import json, sys
from pathlib import Path
from chaplygin.apps.cli import main
code = main(["sweep", sys.argv[1], *json.loads(sys.argv[2]), "-t", "2", "-n", "21", "-o", sys.argv[3]])
sympy, pandas = "sympy" in sys.modules, "pandas" in sys.modules
from chaplygin.apps.sweep import read_results
rows = [{k: v for k, v in r.items() if k != "wall_time"} for r in read_results(sys.argv[3]).to_pylist()]
meta = json.loads((Path(sys.argv[3]) / "_sweep.json").read_text(encoding="utf-8"))
print(json.dumps({"code": code, "sympy": sympy, "pandas": pandas, "rows": json.dumps(rows), "meta": meta}))
"""


def rows_of(path) -> str:
    """The rows of a sweep but their wall times, as JSON text (NaN written as NaN)."""
    return json.dumps(
        [{k: v for k, v in r.items() if k != "wall_time"} for r in read_results(path).to_pylist()]
    )


def test_a_warm_sweep_of_a_file_needs_no_sympy_and_gives_the_full_paths_rows(tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    monkeypatch.setenv("CHAPLYGIN_CACHE", str(cache))
    path = tmp_path / "snakeboard.toml"
    path.write_text(SNAKEBOARD, encoding="utf-8")
    # a parameter axis and a velocity axis; phi' = -10 swings phi through the pole at phi = 0
    grid = json.dumps(["-g", "J=0.1:0.2:2", "-g", "phi'=-10,1"])
    cold = run_json(SWEEP, [str(path), grid, str(tmp_path / "cold")], cache)
    warm = run_json(SWEEP, [str(path), grid, str(tmp_path / "warm")], cache)
    # (exit 3: a sweep with failed runs)
    assert cold["code"] == warm["code"] == 3 and cold["sympy"] and not warm["sympy"]
    assert warm["rows"] == cold["rows"] and warm["meta"] == cold["meta"]
    statuses = [(r["status"], r["message"][:37]) for r in json.loads(cold["rows"])]
    assert statuses == [("failed", "a pole of the solved constraints betw"), ("success", "")] * 2
    # a point the plan leaves to the full path (a start on the pole) beside one it answers; the
    # rows are those of a sweep of the loaded file's System
    grid = json.dumps(["-g", "phi=0,0.3"])
    mixed = run_json(SWEEP, [str(path), grid, str(tmp_path / "mixed")], cache)
    f = chaplygin.load(path)
    expected = sweep(f, {"phi": "0,0.3"}, t_end=2.0, samples=21, out=tmp_path / "expected")
    assert mixed["code"] == 3 and mixed["rows"] == rows_of(tmp_path / "expected") and expected.failed == 1
    assert "InputError: initial: the constraints cannot be solved" in json.loads(mixed["rows"])[0]["message"]
    # nor pandas (pyarrow.array imports it, 0.2 s) where no failed row is read back to be shown
    clean = run_json(SWEEP, [str(path), json.dumps(["-g", "J=0.1,0.2"]), str(tmp_path / "clean")], cache)
    assert clean["code"] == 0 and not clean["sympy"] and not clean["pandas"]
