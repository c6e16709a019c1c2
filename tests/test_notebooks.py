"""The tutorial notebooks of docs/notebooks run from top to bottom without an error.

They are stored without outputs; each is executed here in a copy of its folder (so that the files
it writes stay out of the repository), by a kernel on this interpreter.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
FOLDER = ROOT / "docs" / "notebooks"
NOTEBOOKS = sorted(FOLDER.glob("*.ipynb"))


def test_the_tutorials_are_there() -> None:
    assert [p.name for p in NOTEBOOKS] == ["own-system.ipynb", "rolling-sphere.ipynb"]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_stored_without_outputs(path: Path) -> None:
    import nbformat  # in the tests, not at collection: nbformat and nbclient take seconds to import

    nb = nbformat.read(path, as_version=4)
    nbformat.validate(nb)
    dirty = [
        k
        for k, cell in enumerate(nb.cells)
        if cell.cell_type == "code" and (cell.outputs or cell.execution_count)
    ]
    assert not dirty, f"{path.name}: cells {dirty} have outputs; clear them before committing"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_runs(path: Path, tmp_path: Path) -> None:
    work = tmp_path / "notebooks"
    shutil.copytree(FOLDER, work)
    import nbclient
    import nbformat

    nb = nbformat.read(work / path.name, as_version=4)
    # the "python3" kernel: ipykernel's, started with sys.executable (jupyter_client puts this
    # interpreter in place of the spec's "python"), so the notebooks see this venv's chaplygin
    client = nbclient.NotebookClient(
        nb, kernel_name="python3", timeout=600, resources={"metadata": {"path": str(work)}}
    )
    client.execute()  # raises CellExecutionError, with the cell and its traceback, on any error
    errors = [
        out
        for cell in nb.cells
        if cell.cell_type == "code"
        for out in cell.outputs
        if out.output_type == "error"
    ]
    assert not errors
    # every figure shows itself (no %matplotlib inline in the notebooks): a PNG, never only
    # matplotlib's "<Figure size 700x860 with 5 Axes>"
    shown = [out.get("data", {}) for cell in nb.cells if cell.cell_type == "code" for out in cell.outputs]
    assert not any(d.get("text/plain", "").startswith("<Figure size") and "image/png" not in d for d in shown)
    assert sum("image/png" in d for d in shown) >= 2
    if path.name == "own-system.ipynb":
        report = (work / "cart-report.html").read_text(encoding="utf-8")
        assert report.startswith("<!DOCTYPE html>") and "Cart with a fixed rear axle" in report
