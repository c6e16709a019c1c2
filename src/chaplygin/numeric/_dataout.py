"""Results as pandas DataFrames and xarray Datasets, and a trajectory drawn with matplotlib.

The methods ``to_pandas``, ``to_xarray`` and ``plot`` of
:class:`~chaplygin.numeric.simulate.Trajectory`, :class:`~chaplygin.numeric.ensemble.Ensemble` and
:class:`~chaplygin.apps.sweep.SweepResult` call these functions.  pandas and xarray are
optional (``pip install 'chaplygin[data]'``): they are imported here, when asked for.

The names are the same everywhere: a trajectory's columns are those of
:attr:`Trajectory.columns` (``x``, ``x'``, ``energy``, ``lambda_1`` …); one row per run of an
ensemble or a sweep is indexed by ``run`` and uses the sweep's column names (``param.m``,
``final.x``, ``final.x'``, ``t_reached``, ``energy_drift`` …).  Parameters are attributes
``param.NAME`` (numbers) of a Dataset, and ``attrs["parameters"]`` (a dict) of a DataFrame.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

import numpy as np

from chaplygin.errors import ChaplyginError

if TYPE_CHECKING:
    import pandas as pd
    import xarray as xr
    from matplotlib.axes import Axes

    from chaplygin.apps.sweep import SweepResult
    from chaplygin.numeric.ensemble import Ensemble
    from chaplygin.numeric.simulate import Trajectory

__all__ = [
    "PLOTS",
    "ensemble_dataset",
    "ensemble_frame",
    "plot_trajectory",
    "require",
    "sweep_dataset",
    "sweep_frame",
    "trajectory_dataset",
    "trajectory_frame",
]

#: what ``Trajectory.plot(what=...)`` draws
PLOTS = ("coordinates", "velocities", "invariants", "path")


def require(module: str, what: str) -> Any:
    """Import ``module`` (``"pandas"``, ``"xarray"``) or say that ``what`` needs the extra ``data``."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise ChaplyginError(
            f"{what} needs {module}, which is not installed ({exc}); pip install 'chaplygin[data]'."
        ) from None


def _kind(tr: Trajectory, name: str) -> str:
    if name in tr.coordinates:
        return "coordinate"
    if name in tr.velocities:
        return "velocity"
    if name in tr.multipliers:
        return "multiplier"
    return "invariant"


def _attributes(tr: Trajectory) -> dict[str, Any]:
    return {
        "model": tr.model,
        "form": tr.form,
        "backend": tr.backend,
        "status": tr.status,
        "message": tr.message,
        "failure": tr.failure,
        "rhs_evaluations": int(tr.rhs_evaluations),
    }


# ------------------------------------------------------------------ one trajectory
def trajectory_frame(tr: Trajectory) -> pd.DataFrame:
    """One row per sample, indexed by ``t``; the columns of :attr:`Trajectory.columns` after ``t``."""
    pd = require("pandas", "Trajectory.to_pandas()")
    names = tr.columns[1:]
    frame = pd.DataFrame(
        {name: np.asarray(tr[name], dtype=float) for name in names},
        index=pd.Index(np.asarray(tr.t, dtype=float), name="t"),
        columns=names,
    )
    frame.attrs.update(_attributes(tr), parameters=dict(tr.parameters))
    return frame


def trajectory_dataset(tr: Trajectory) -> xr.Dataset:
    """Coordinate ``t``, one variable per column (attribute ``kind``), the run's attributes."""
    xr = require("xarray", "Trajectory.to_xarray()")
    variables = {
        name: ("t", np.asarray(tr[name], dtype=float), {"kind": _kind(tr, name)}) for name in tr.columns[1:]
    }
    attrs = _attributes(tr) | {f"param.{k}": float(v) for k, v in tr.parameters.items()}
    return xr.Dataset(variables, coords={"t": np.asarray(tr.t, dtype=float)}, attrs=attrs)


# ------------------------------------------------------------------ ensembles
def _ensemble_columns(ens: Ensemble) -> dict[str, np.ndarray]:
    """One value per member, named like the sweep's columns."""
    layout = ens.layout
    columns: dict[str, np.ndarray] = {
        f"param.{k}": np.asarray(v, dtype=float) for k, v in ens.parameters.items()
    }
    if ens.y_initial is not None:
        state = layout.state
        columns.update({f"initial.{q}": ens.y_initial[:, state.index(q)] for q in layout.coordinates})
        columns.update({f"initial.{q}'": ens.velocities_initial[q + "'"] for q in layout.coordinates})
        columns.update({f"initial.{m}": ens.y_initial[:, state.index(m)] for m in layout.multipliers})
    columns["status"] = np.asarray(ens.status, dtype=object)
    columns["message"] = np.asarray(ens.messages, dtype=object)
    columns["t_reached"] = np.asarray(ens.t, dtype=float)
    columns.update({f"final.{q}": np.asarray(ens.coordinates[q], dtype=float) for q in layout.coordinates})
    columns.update(
        {f"final.{q}'": np.asarray(ens.velocities[q + "'"], dtype=float) for q in layout.coordinates}
    )
    columns.update({f"final.{m}": ens.y[:, layout.state.index(m)] for m in layout.multipliers})
    columns["energy_initial"] = np.asarray(ens.energy_initial, dtype=float)
    columns["energy_final"] = np.asarray(ens.energy, dtype=float)
    columns["energy_drift"] = np.asarray(ens.energy_drift(), dtype=float)
    columns["final.constraint_residual"] = np.asarray(ens.constraint_residual, dtype=float)
    columns["rhs_evaluations"] = np.asarray(ens.rhs_evaluations, dtype=np.int64)
    return columns


def _ensemble_attributes(ens: Ensemble) -> dict[str, Any]:
    return {
        "model": ens.model,
        "form": ens.form,
        "backend": ens.backend,
        "members": len(ens),
        "failed": int(np.count_nonzero(ens.code)),
        "wall_time": float(ens.wall_time),
    }


def ensemble_frame(ens: Ensemble) -> pd.DataFrame:
    """One row per member, indexed by ``run`` (0 … N−1): parameters, status, final state, energy."""
    pd = require("pandas", "Ensemble.to_pandas()")
    frame = pd.DataFrame(_ensemble_columns(ens), index=pd.RangeIndex(len(ens), name="run"))
    frame.attrs.update(_ensemble_attributes(ens))
    return frame


def ensemble_dataset(ens: Ensemble) -> xr.Dataset:
    """Dimension ``run``; with kept samples also ``t``, and one ``(run, t)`` variable per state entry."""
    xr = require("xarray", "Ensemble.to_xarray()")
    variables: dict[str, Any] = {name: ("run", values) for name, values in _ensemble_columns(ens).items()}
    coords: dict[str, Any] = {"run": np.arange(len(ens))}
    if ens.times is not None and ens.samples is not None:
        coords["t"] = np.asarray(ens.times, dtype=float)
        for i, name in enumerate(ens.layout.state):
            variables[name] = (("run", "t"), ens.samples[:, :, i])
    return xr.Dataset(variables, coords=coords, attrs=_ensemble_attributes(ens))


# ------------------------------------------------------------------ sweeps
def _sweep_attributes(meta: dict[str, Any]) -> dict[str, Any]:
    attrs: dict[str, Any] = {
        key: meta[key]
        for key in (
            "system",
            "source",
            "model",
            "form",
            "backend",
            "t_end",
            "samples",
            "rtol",
            "atol",
            "runs",
        )
        if key in meta
    }
    attrs.update({f"param.{k}": float(v) for k, v in meta.get("parameters", {}).items()})
    attrs.update({f"initial.{k}": float(v) for k, v in meta.get("initial", {}).items()})
    return attrs


def sweep_frame(result: SweepResult, meta: dict[str, Any]) -> pd.DataFrame:
    """The sweep's rows (:func:`chaplygin.apps.sweep.read_results`) indexed by ``run`` (the run id)."""
    require("pandas", "SweepResult.to_pandas()")
    frame = result.table().to_pandas()
    frame = frame.set_index("run_id").rename_axis("run")
    frame.attrs.update(_sweep_attributes(meta))
    return frame


def sweep_dataset(result: SweepResult, meta: dict[str, Any]) -> xr.Dataset:
    """One dimension per axis of the grid (named like the axis, its values the coordinate).

    Every other column is a variable over those dimensions; ``run`` holds the run id.  A run
    not in the output yet (an interrupted sweep) is NaN (``""`` for ``status`` and ``message``).
    """
    xr = require("xarray", "SweepResult.to_xarray()")
    grid = meta["grid"]
    shape = tuple(len(axis["values"]) for axis in grid)
    table = result.table()
    ids = table.column("run_id").to_numpy()
    dims = tuple(axis["name"] for axis in grid)
    variables: dict[str, Any] = {}
    skip = {"run_id", *(f"grid.{name}" for name in dims)}
    total = int(np.prod(shape))
    for name in table.column_names:
        if name in skip:
            continue
        values = table.column(name).to_numpy(zero_copy_only=False)
        if values.dtype.kind in "OUS":
            full = np.full(total, "", dtype=object)
        elif len(ids) == total:  # every run there: the column keeps its type (int64 counts)
            full = np.empty(total, dtype=values.dtype)
        else:
            full = np.full(total, np.nan)
        full[ids] = values
        variables[name] = (dims, full.reshape(shape))
    run = np.full(total, -1, dtype=np.int64)
    run[ids] = ids
    variables["run"] = (dims, run.reshape(shape), {"missing": -1})
    coords = {axis["name"]: np.asarray(axis["values"], dtype=float) for axis in grid}
    return xr.Dataset(variables, coords=coords, attrs=_sweep_attributes(meta))


# ------------------------------------------------------------------ plots
def path_coordinates(tr: Trajectory, path: tuple[str, str] | None) -> tuple[str, str]:
    """The pair drawn by ``plot(what="path")``: ``path`` if given, else ``("x", "y")`` if both exist."""
    names = list(tr.coordinates)
    if path is not None:
        if len(path) != 2 or any(c not in names for c in path):
            raise ChaplyginError(
                f"path={path!r}: give two coordinates of this trajectory ({', '.join(names)})."
            )
        return path[0], path[1]
    if "x" in names and "y" in names:
        return "x", "y"
    raise ChaplyginError(
        f"what='path': this trajectory has no coordinates named x and y ({', '.join(names)}); "
        "name the pair to draw, e.g. path=('a', 'b')."
    )


def plot_trajectory(
    tr: Trajectory, what: str, ax: Axes | None, path: tuple[str, str] | None, **kwargs: Any
) -> Axes:
    """See :meth:`Trajectory.plot`."""
    if what not in PLOTS:
        raise ChaplyginError(f"what={what!r}: choose one of {', '.join(map(repr, PLOTS))}.")
    pair = path_coordinates(tr, path) if what == "path" else None
    if ax is None:
        import matplotlib.pyplot as plt

        ax = plt.figure(layout="constrained").add_subplot()
    title = f"{tr.model}/{tr.form}"
    if pair is not None:
        ax.plot(tr[pair[0]], tr[pair[1]], **{"label": f"{title}", **kwargs})
        ax.plot(tr[pair[0]][:1], tr[pair[1]][:1], "ko", ms=3)
        ax.set(xlabel=pair[0], ylabel=pair[1], title=f"{title}: path")
        ax.set_aspect("equal", adjustable="datalim")
        return ax
    if what == "invariants":
        e0 = tr.energy[0] if len(tr.energy) else 0.0
        drift = np.abs(tr.energy - e0) / max(1.0, abs(e0))
        tiny = 1e-18  # a log axis shows exact zeros at 1e-18 instead of leaving them out
        e = "h" if tr.energy_column == "jacobi_integral" else "E"  # h: Jacobi's integral
        ax.plot(tr.t, drift + tiny, **{"label": f"|{e} − {e}(0)| / max(1, |{e}(0)|)", **kwargs})
        ax.plot(tr.t, tr.constraint_residual + tiny, **{"label": "constraint residual", **kwargs})
        ax.set(yscale="log", xlabel="t", title=f"{title}: invariants")
    else:
        table = tr.coordinates if what == "coordinates" else tr.velocities
        for name, values in table.items():
            ax.plot(tr.t, values, **{"label": name, **kwargs})
        ax.set(xlabel="t", title=f"{title}: {what}")
    ax.legend(fontsize="small")
    return ax
