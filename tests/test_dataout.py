"""Data out: to_pandas / to_xarray of trajectories, ensembles and sweeps; Trajectory.plot; the
comparison figures that keep coincident models visible."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np
import pandas as pd  # the extra chaplygin[data], part of the test extra
import pytest
import xarray as xr
from matplotlib.figure import Figure

from chaplygin import ChaplyginError, compare, examples, simulate
from chaplygin.numeric.codegen import Layout
from chaplygin.numeric.comparison import COINCIDE, coincide
from chaplygin.numeric.ensemble import Ensemble
from chaplygin.numeric.simulate import Trajectory

matplotlib.use("Agg")

KNIFE_START = {"x": 0.0, "y": 0.0, "phi": 0.3, "x'": 1.0, "phi'": 0.2}
KNIFE_PARAMETERS = {"m": 1.0, "J": 0.5}


@pytest.fixture(scope="module")
def knife() -> Any:
    return examples.knife_edge()


@pytest.fixture(scope="module")
def run(knife: Any) -> Trajectory:
    """A Chetaev run: coordinates, velocities, invariants and a multiplier λ."""
    return simulate(knife, "chetaev", 1.0, KNIFE_START, KNIFE_PARAMETERS, samples=11, backend="numpy")


def _axes() -> Any:
    return Figure().add_subplot()


# ------------------------------------------------------------------ Trajectory
def test_trajectory_to_pandas(run: Trajectory) -> None:
    frame = run.to_pandas()
    assert isinstance(frame, pd.DataFrame) and frame.index.name == "t"
    np.testing.assert_array_equal(frame.index.to_numpy(), run.t)
    assert list(frame.columns) == [
        "x",
        "y",
        "phi",
        "x'",
        "y'",
        "phi'",
        "energy",
        "constraint_residual",
        "lambda_1",
    ]
    assert list(frame.columns) == run.columns[1:]  # the names of table() and to_csv()
    for name in frame.columns:
        np.testing.assert_array_equal(frame[name].to_numpy(), run[name])
    assert frame.attrs["model"] == "chetaev" and frame.attrs["status"] == "success"
    assert frame.attrs["parameters"] == {"m": 1.0, "J": 0.5}
    assert frame.attrs["message"] == run.message


def test_trajectory_to_xarray(run: Trajectory, tmp_path: Path) -> None:
    ds = run.to_xarray()
    assert isinstance(ds, xr.Dataset) and list(ds.coords) == ["t"] and ds.sizes == {"t": 11}
    assert list(ds.data_vars) == run.columns[1:]
    np.testing.assert_array_equal(ds["phi'"].to_numpy(), run["phi'"])
    assert ds["x"].attrs["kind"] == "coordinate" and ds["x'"].attrs["kind"] == "velocity"
    assert ds["energy"].attrs["kind"] == "invariant" and ds["lambda_1"].attrs["kind"] == "multiplier"
    assert ds.attrs["model"] == "chetaev" and ds.attrs["status"] == "success"
    assert ds.attrs["param.m"] == 1.0 and ds.attrs["param.J"] == 0.5
    # every attribute is one a netCDF file holds: the Dataset round-trips through one
    path = tmp_path / "run.nc"
    ds.to_netcdf(path, engine="scipy")
    with xr.open_dataset(path, engine="scipy") as back:
        assert back.attrs["message"] == run.message and float(back.attrs["param.J"]) == 0.5
        np.testing.assert_array_equal(back["lambda_1"].to_numpy(), run["lambda_1"])


def test_missing_pandas_or_xarray_says_which_extra(run: Trajectory, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "pandas", None)  # import pandas raises ImportError
    monkeypatch.setitem(sys.modules, "xarray", None)
    with pytest.raises(ChaplyginError, match=r"to_pandas\(\) needs pandas.*pip install 'chaplygin\[data\]'"):
        run.to_pandas()
    with pytest.raises(ChaplyginError, match=r"to_xarray\(\) needs xarray.*pip install 'chaplygin\[data\]'"):
        run.to_xarray()


# ------------------------------------------------------------------ plots
@pytest.mark.parametrize(
    ("what", "labels"),
    [
        ("coordinates", ["x", "y", "phi"]),
        ("velocities", ["x'", "y'", "phi'"]),
        ("invariants", ["|E − E(0)| / max(1, |E(0)|)", "constraint residual"]),
    ],
)
def test_plot_against_time(run: Trajectory, what: str, labels: list[str]) -> None:
    ax = _axes()
    assert run.plot(what, ax=ax, lw=0.5) is ax
    lines = ax.get_lines()
    assert [line.get_label() for line in lines] == labels
    assert all(line.get_linewidth() == 0.5 for line in lines)
    np.testing.assert_array_equal(lines[0].get_xdata(), run.t)
    if what != "invariants":
        np.testing.assert_array_equal(lines[-1].get_ydata(), run[labels[-1]])
    else:
        assert ax.get_yscale() == "log"


def test_plot_path_draws_y_against_x(run: Trajectory) -> None:
    ax = run.plot("path", ax=_axes())
    line = ax.get_lines()[0]
    np.testing.assert_array_equal(line.get_xdata(), run["x"])
    np.testing.assert_array_equal(line.get_ydata(), run["y"])
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x", "y")
    other = run.plot("path", ax=_axes(), path=("phi", "x"))
    np.testing.assert_array_equal(other.get_lines()[0].get_xdata(), run["phi"])


def test_plot_path_without_x_and_y_needs_the_pair() -> None:
    t = np.linspace(0.0, 1.0, 3)
    tr = Trajectory(
        "chetaev",
        "classic",
        "numpy",
        t,
        {"a": t, "b": 2 * t},
        {"a'": t, "b'": t},
        {},
        np.zeros(3),
        np.zeros(3),
    )
    with pytest.raises(ChaplyginError, match=r"no coordinates named x and y \(a, b\).*path=\('a', 'b'\)"):
        tr.plot("path", ax=_axes())
    with pytest.raises(
        ChaplyginError, match=r"path=\('a', 'c'\): give two coordinates of this trajectory \(a, b\)"
    ):
        tr.plot("path", ax=_axes(), path=("a", "c"))
    np.testing.assert_array_equal(
        tr.plot("path", ax=_axes(), path=("a", "b")).get_lines()[0].get_ydata(), 2 * t
    )
    with pytest.raises(ChaplyginError, match="what='speed': choose one of 'coordinates'"):
        tr.plot("speed")


def test_plot_without_axes_makes_a_pyplot_figure(run: Trajectory) -> None:
    import matplotlib.pyplot as plt

    ax = run.plot()
    try:
        assert ax.figure in [plt.figure(n) for n in plt.get_fignums()]
    finally:
        plt.close(ax.figure)


# ------------------------------------------------------------------ comparison figures
def test_coincide_is_plotting_precision() -> None:
    x = np.linspace(0.0, 1.0, 50)
    y = np.sin(3 * x)
    spans = (1.0, float(np.ptp(y)))
    assert coincide((x, y), (x, y + 0.5 * COINCIDE * spans[1]), spans)
    assert not coincide((x, y), (x, y + 2 * COINCIDE * spans[1]), spans)
    assert not coincide((x, y), (x[:-1], y[:-1]), spans)  # a run that stopped early


def test_coincident_models_stay_visible() -> None:
    """Lindelöf's equations are right for the vertical rolling disk: its curves are the true ones."""
    disk = examples.vertical_rolling_disk()
    entry = examples.get("vertical-rolling-disk")
    result = compare(
        disk, ["chaplygin", "lindelof"], 2.0, entry.initial, entry.parameters, samples=41, backend="numpy"
    )
    fig = result.figure("paths")
    ax = fig.axes[0]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["chaplygin", "lindelof (same as chaplygin)"]
    first, second = ax.get_lines()[0], ax.get_lines()[1]
    assert (first.get_linestyle(), first.get_marker()) != (second.get_linestyle(), second.get_marker())


def test_models_that_differ_are_not_called_the_same(knife: Any) -> None:
    result = compare(
        knife, ["chaplygin", "lindelof"], 1.0, KNIFE_START, KNIFE_PARAMETERS, samples=21, backend="numpy"
    )
    assert np.max(result.distance("lindelof")) > 1e-2  # visibly apart
    labels = [t.get_text() for t in result.figure("paths").axes[0].get_legend().get_texts()]
    assert labels == ["chaplygin", "lindelof"]


# ------------------------------------------------------------------ ensembles
def _ensemble() -> Ensemble:
    """Three members of a made-up vakonomic run (state x, y, x', y', mu_1), samples kept at 3 times."""
    layout = Layout("vakonomic", "classic", ("x", "y"), ("x'", "y'"), ("mu_1",), ("m",))
    y = np.array([[1.0, 2.0, 0.1, 0.2, 5.0], [3.0, 4.0, 0.3, 0.4, 6.0], [5.0, 6.0, 0.5, 0.6, 7.0]])
    samples = np.arange(3 * 3 * 5, dtype=float).reshape(3, 3, 5)
    samples[2, 2] = np.nan  # member 2 failed before the last time
    return Ensemble(
        "vakonomic",
        "classic",
        "numba",
        layout,
        np.array([1.0, 1.0, 0.7]),
        y,
        {"x": y[:, 0], "y": y[:, 1]},
        {"x'": y[:, 2], "y'": y[:, 3]},
        np.array([1.5, 2.5, 3.5]),
        np.array([1.0, 2.0, 4.0]),
        np.array([0.0, 1e-12, 1e-3]),
        np.array([0, 0, 2]),
        np.array([40, 41, 99]),
        times=np.array([0.0, 0.5, 1.0]),
        samples=samples,
        wall_time=0.25,
        parameters={"m": np.array([1.0, 2.0, 3.0])},
    )


def test_ensemble_to_pandas() -> None:
    ens = _ensemble()
    frame = ens.to_pandas()
    assert frame.index.name == "run" and list(frame.index) == [0, 1, 2]
    assert list(frame["param.m"]) == [1.0, 2.0, 3.0]
    assert list(frame["status"]) == ["success", "success", "failed"]
    assert frame["message"][2].startswith("stopped at t = 0.7")
    assert list(frame["final.y'"]) == [0.2, 0.4, 0.6] and list(frame["final.mu_1"]) == [5.0, 6.0, 7.0]
    assert list(frame["t_reached"]) == [1.0, 1.0, 0.7]
    assert list(frame["energy_initial"]) == [1.0, 2.0, 4.0] and list(frame["energy_final"]) == [1.5, 2.5, 3.5]
    np.testing.assert_allclose(frame["energy_drift"], [0.5, 0.25, 0.125])
    assert list(frame["final.constraint_residual"]) == [0.0, 1e-12, 1e-3]
    assert list(frame["rhs_evaluations"]) == [40, 41, 99]
    assert frame.attrs["model"] == "vakonomic" and frame.attrs["members"] == 3 and frame.attrs["failed"] == 1


def test_ensemble_to_xarray() -> None:
    ens = _ensemble()
    ds = ens.to_xarray()
    assert ds.sizes == {"run": 3, "t": 3}
    np.testing.assert_array_equal(ds["t"], [0.0, 0.5, 1.0])
    assert ds["mu_1"].dims == ("run", "t")
    np.testing.assert_array_equal(ds["mu_1"].sel(run=1).to_numpy(), [19.0, 24.0, 29.0])  # samples[1, :, 4]
    assert np.isnan(ds["x"].sel(run=2, t=1.0))
    assert list(ds["final.x"].to_numpy()) == [1.0, 3.0, 5.0]
    assert ds.attrs["backend"] == "numba"
    final_only = Ensemble(**{**ens.__dict__, "times": None, "samples": None}).to_xarray()
    assert final_only.sizes == {"run": 3} and "x" not in final_only


# ------------------------------------------------------------------ sweeps
def test_sweep_to_pandas_and_xarray(knife: Any, tmp_path: Path) -> None:
    pytest.importorskip("pyarrow")
    from chaplygin.apps.sweep import sweep

    start = {k: v for k, v in KNIFE_START.items() if k != "x'"}
    result = sweep(
        knife,
        {"m": [1.0, 2.0], "x'": [0.5, 1.0, 2.0]},
        model="chaplygin",
        t_end=0.5,
        parameters={"J": 0.5},
        initial=start,
        out=tmp_path / "knife.parquet",
        backend="numpy",
        samples=3,
        scheduler="serial",
    )
    frame = result.to_pandas()
    assert frame.index.name == "run" and list(frame.index) == list(range(6))
    assert list(frame["grid.x'"]) == [0.5, 1.0, 2.0, 0.5, 1.0, 2.0]  # C order: the last axis fastest
    assert frame.attrs["model"] == "chaplygin" and frame.attrs["param.J"] == 0.5
    ds = result.to_xarray()
    assert dict(ds.sizes) == {"m": 2, "x'": 3}
    np.testing.assert_array_equal(ds["x'"], [0.5, 1.0, 2.0])
    assert int(ds["run"].sel(m=2.0, **{"x'": 1.0})) == 4
    cell = ds.sel(m=2.0, **{"x'": 1.0})
    assert float(cell["final.x"]) == frame.loc[4, "final.x"] and str(cell["status"].item()) == "success"
    assert ds["rhs_evaluations"].dtype == np.int64  # every run there: counts stay integers
    # the knife edge keeps its speed (see its gallery page): |v(t_end)| = |v(0)| at every grid point
    speed = np.hypot(ds["final.x'"], ds["final.y'"])
    initial = np.hypot(ds["x'"], ds["x'"] * np.tan(0.3))
    np.testing.assert_allclose(speed, initial.broadcast_like(speed), rtol=1e-8)
