"""Look, don't read: a rolling body drawn in 3-D along its motion, the models side by side.

For a system built by :func:`chaplygin.bodies.rolling_body`, :func:`show_rolling` draws a
matplotlib figure and :func:`body_views` an HTML fragment (inline SVG, no script, nothing
fetched): on top, the contact paths of every run seen from above; below, one row of 3-D views
per time, one column per run (the true motion and Lindelöf's, say), each showing

* the body's surface, shaded, painted with a body-fixed checker of its eight octants (one of
  them, ``x, y, z ≥ 0`` from the centre of its bounding box, in gold) so that its rotation shows;
* its shadow straight down, the plane's grid (fixed in space: the camera follows the body);
* the contact path so far, and the other runs' contact paths so far, thin and grey.

The surface is sampled as the shape's own formula for the contact point, ``∇h(n)``
(:mod:`chaplygin.bodies.shapes`), over a grid of unit normals ``n``, spaced evenly along the
surface; flat faces (a disk's, the top of a rounded disk) are closed by fans. The body is
convex, so hidden faces are exactly those whose normal points away from the camera
(orthographic, fixed oblique direction), and the body hides the plane behind it.
"""

from __future__ import annotations

import html
import io
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import sympy as sp

from chaplygin.bodies import Motion, Paraboloid, RollingBody, Shape, motion
from chaplygin.errors import InputError
from chaplygin.models import registry

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from chaplygin.numeric._figure import Figure
    from chaplygin.numeric.simulate import Trajectory

__all__ = ["Mesh", "Scene", "body_section", "body_views", "scenes", "show_rolling", "surface"]

#: the camera: azimuth and elevation (degrees) of the direction it looks from
AZIMUTH, ELEVATION = -58.0, 26.0
#: per run, in order: the body's dark and pale checker colours (the dark one draws its path); the
#: runs' colours have the same lightness, so that their views differ in hue only
PALETTE = (("#2f6db3", "#b9d2ee"), ("#c2452d", "#f2c3b5"), ("#3f8f3f", "#c4e3c0"), ("#7b4fa8", "#ddc9ee"))
ACCENT = "#e8b10e"
GROUND = "#f4f1ea"


@dataclass(frozen=True)
class Mesh:
    """A closed polygon mesh of a shape's surface in body axes (from the shape's origin).

    Attributes
    ----------
    points : ndarray (N, 3)
    faces : list of int arrays
        Vertex indices of each polygon (quads, and triangle fans closing the poles).
    normals : ndarray (F, 3)
        Outward unit normal of each face.
    paint : ndarray (F,) of int
        0 or 1: the checker of the body's octants about :attr:`centre`; 2: the octant
        ``x, y, z ≥ 0`` (the marker).
    centre : ndarray (3,)
        Centre of the bounding box.
    radius : float
        Largest distance of a vertex from ``centre``.
    """

    points: np.ndarray
    faces: list[np.ndarray]
    normals: np.ndarray
    paint: np.ndarray
    centre: np.ndarray
    radius: float

    @property
    def marker(self) -> np.ndarray:
        """Body-axes centroid of the marker (gold) faces."""
        return np.mean(
            [self.points[f].mean(axis=0) for f, p in zip(self.faces, self.paint) if p == 2], axis=0
        )


def _values(system: RollingBody, parameters: Mapping[Any, float]) -> dict[sp.Symbol, float]:
    given = {str(k): v for k, v in parameters.items()}
    missing = [p.name for p in system.parameters if p.name not in given]
    if missing:
        raise InputError(f"parameters: no value for {', '.join(missing)}, needed to draw {system.name}.")
    return {p: float(given[p.name]) for p in system.parameters}


def _normals(alpha: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """Unit normals at angle ``alpha`` from the downward axis −z and longitude ``beta``."""
    s = np.sin(alpha)
    return np.stack(np.broadcast_arrays(s * np.cos(beta), s * np.sin(beta), -np.cos(alpha)), axis=-1)


def _even(values: np.ndarray, steps: np.ndarray, count: int) -> np.ndarray:
    """``count`` values spaced evenly in ``steps`` (lengths between successive ``values``), half
    the weight on length, half on ``values`` themselves: no part of the surface is left coarse."""
    total = steps.sum()
    weight = (steps / total if total > 0 else 0.0) + 1.0 / len(steps)
    s = np.concatenate([[0.0], np.cumsum(weight)])
    return np.interp(np.linspace(0.0, s[-1], count), s, values)


def surface(
    shape: Shape,
    values: Mapping[sp.Symbol, float] | None = None,
    *,
    center_of_mass: Sequence[float] | np.ndarray = (0.0, 0.0, 0.0),
    rings: int = 15,
    meridians: int = 28,
) -> Mesh:
    """Sample a shape's surface as ``∇h(n)`` over unit normals ``n``: a :class:`Mesh`.

    Parameters
    ----------
    shape : Shape
    values : mapping, optional
        Numbers for the symbols of the shape's lengths.
    center_of_mass : three numbers
        Only for a paraboloid (an unbounded cap): its lid is drawn above the centre of mass.
    rings, meridians : int
        Rings of normals from the bottom pole to the top, and meridians around the z axis;
        both are spaced evenly along the surface (from a fine grid) and in angle.

    Returns
    -------
    Mesh
    """
    n1, n2, n3 = sp.symbols("_n1:4", real=True)
    exprs = [
        sp.sympify(e, strict=True).xreplace(dict(values or {}))
        for e in shape.contact(sp.Matrix([n1, n2, n3]))
    ]
    loose = set().union(*(e.free_symbols for e in exprs)) - {n1, n2, n3}
    if loose:
        raise InputError(f"shape: no value for {', '.join(sorted(map(str, loose)))}, needed to draw it.")
    fns = [sp.lambdify((n1, n2, n3), e, "numpy") for e in exprs]

    def contact(n: np.ndarray) -> np.ndarray:
        cols = [
            np.broadcast_to(np.asarray(f(n[..., 0], n[..., 1], n[..., 2]), dtype=float), n.shape[:-1])
            for f in fns
        ]
        return np.stack(cols, axis=-1)

    lower = isinstance(shape, Paraboloid) or shape._directions_half()
    eps = 1e-3
    alpha = np.linspace(eps, np.pi / 2 - 0.02 if lower else np.pi - eps, 361)
    beta = np.linspace(0.0, 2 * np.pi, 721)
    fine = contact(_normals(alpha[:, None], beta[None, :-1]))
    if not np.all(np.isfinite(fine)):
        raise InputError(
            f"shape: {shape!r} has no finite contact point for some normals; it cannot be drawn."
        )
    if lower:  # an unbounded cap: a lid at a height that shows its curvature and holds the centre of mass
        bottom = fine[..., 2].min()
        reach = np.max(np.hypot(fine[180, :, 0], fine[180, :, 1]))  # the ring at 45°
        lid = bottom + max(reach / 2, 1.5 * (float(center_of_mass[2]) - bottom))
        top = fine[..., 2].max(axis=1)
        cut = max(2, int(np.searchsorted(top, lid)) + 1)
        alpha, fine = alpha[:cut], fine[:cut]
    ring_steps = np.linalg.norm(np.diff(fine, axis=0), axis=2).max(axis=1)  # the longest chord
    wrapped = np.concatenate([fine, fine[:, :1]], axis=1)
    meridian_steps = np.linalg.norm(np.diff(wrapped, axis=1), axis=2).max(axis=0)
    a = _even(alpha, ring_steps, rings)
    b = _even(beta, meridian_steps, meridians + 1)[:-1]
    n = _normals(a[:, None], b[None, :])
    grid = contact(n)
    index = np.arange(rings * meridians).reshape(rings, meridians)
    faces: list[np.ndarray] = []
    normals: list[np.ndarray] = []
    for i in range(rings - 1):
        for j in range(meridians):
            k = (j + 1) % meridians
            faces.append(np.array([index[i, j], index[i, k], index[i + 1, k], index[i + 1, j]]))
            m = n[i, j] + n[i, k] + n[i + 1, k] + n[i + 1, j]
            normals.append(m / np.linalg.norm(m))
    for ring, pole in ((0, (0.0, 0.0, -1.0)), (rings - 1, (0.0, 0.0, 1.0))):  # fans close both ends
        apex = rings * meridians + (0 if ring == 0 else 1)
        for j in range(meridians):
            faces.append(np.array([apex, index[ring, j], index[ring, (j + 1) % meridians]]))
            normals.append(np.array(pole))
    pts = np.vstack([grid.reshape(-1, 3), grid[0].mean(axis=0), grid[-1].mean(axis=0)])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre, size = (lo + hi) / 2, float(np.max(hi - lo))
    keep = [_area(pts[f]) > 1e-10 * size**2 for f in faces]  # a disk's rim quads have none
    faces = [f for f, k in zip(faces, keep) if k]
    normal_arr = np.array([v for v, k in zip(normals, keep) if k])
    offset = np.array([pts[f].mean(axis=0) for f in faces]) - centre
    positive = offset >= -1e-9 * size
    paint = positive.sum(axis=1) % 2
    paint[positive.all(axis=1)] = 2
    radius = float(np.max(np.linalg.norm(pts - centre, axis=1)))
    return Mesh(pts, faces, normal_arr, paint, centre, radius)


def _area(p: np.ndarray) -> float:
    return float(np.linalg.norm(sum(np.cross(p[i], p[(i + 1) % len(p)]) for i in range(len(p)))) / 2)


@dataclass(frozen=True)
class Scene:
    """One run at one time, in space coordinates: what one 3-D view draws.

    Attributes
    ----------
    label : str
        The run's label (its model).
    t : float
        The sample's time.
    index : int
        The sample's index in the run.
    faces : list of (m, 3) arrays
        The body's polygons that face the camera.
    colors : ndarray (F, 3)
        Their shaded colours (RGB in [0, 1]).
    paint : ndarray (F,)
        Their paint (:attr:`Mesh.paint`).
    path : ndarray (k, 3)
        The contact points so far (samples 0 … ``index``).
    centre : ndarray (3,)
        The centre of the body's bounding box in space (the view is centred on it).
    marker : ndarray (3,)
        The marker's centroid (:attr:`Mesh.marker`) in space.
    shadow : ndarray (s, 3)
        The body's shadow straight down on the plane (a convex polygon).
    ended : bool
        The run stopped before this time (the last sample is shown).
    """

    label: str
    t: float
    index: int
    faces: list[np.ndarray]
    colors: np.ndarray
    paint: np.ndarray
    path: np.ndarray
    centre: np.ndarray
    marker: np.ndarray
    shadow: np.ndarray
    ended: bool


def _camera() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit vectors: towards the camera, screen right, screen up."""
    az, el = np.radians(AZIMUTH), np.radians(ELEVATION)
    toward = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    right = np.array([-np.sin(az), np.cos(az), 0.0])
    return toward, right, np.cross(toward, right)


def _rgb(color: str) -> np.ndarray:
    return np.array([int(color[k : k + 2], 16) / 255 for k in (1, 3, 5)])


def _runs(trajectories: Any) -> dict[str, Trajectory]:
    runs = getattr(trajectories, "trajectories", trajectories)  # a Comparison
    if isinstance(runs, Mapping):
        out = {str(k): v for k, v in runs.items()}
    elif hasattr(runs, "t") and hasattr(runs, "coordinates"):
        out = {"run": runs}
    else:
        raise InputError(
            f"trajectories: expected a Trajectory, a mapping label -> Trajectory or a Comparison, got {type(trajectories).__name__}."
        )
    if not out:
        raise InputError("trajectories: no run to draw.")
    for label, run in out.items():
        if len(getattr(run, "t", ())) == 0:
            raise InputError(f"trajectories[{label!r}]: the run has no samples.")
    return out


def _shadow(points: np.ndarray) -> np.ndarray:
    from scipy.spatial import ConvexHull

    xy = points[:, :2]
    hull = ConvexHull(xy)
    return np.column_stack([xy[hull.vertices], np.zeros(len(hull.vertices))])


def scenes(
    system: RollingBody,
    trajectories: Any,
    *,
    snapshots: int = 6,
    parameters: Mapping[Any, float] | None = None,
) -> tuple[Mesh, list[float], list[list[Scene]]]:
    """The 3-D views of :func:`show_rolling` as data: one row per time, one column per run.

    Parameters
    ----------
    system : RollingBody
        Built by :func:`chaplygin.bodies.rolling_body`.
    trajectories : Trajectory, mapping label → Trajectory, or Comparison
        Runs of ``system`` (from ``chaplygin.simulate`` or ``chaplygin.compare``).
    snapshots : int
        Number of times, evenly spread from the start to the end of the longest run; each
        run shows its nearest sample.
    parameters : mapping, optional
        Numbers for the system's parameters (default: the first run's).

    Returns
    -------
    mesh, times, rows
        The body's mesh, the times and ``rows[i][j]``, the :class:`Scene` of run ``j`` at
        time ``i``.
    """
    if not isinstance(system, RollingBody):
        raise InputError(
            f"system: {getattr(system, 'name', system)!r} was not built by chaplygin.bodies.rolling_body; "
            "only a rolling body can be drawn."
        )
    if isinstance(snapshots, bool) or not isinstance(snapshots, int) or snapshots < 1:
        raise InputError(f"snapshots: expected a positive whole number, got {snapshots!r}.")
    runs = _runs(trajectories)
    values = _values(system, parameters if parameters is not None else next(iter(runs.values())).parameters)
    c = np.array([float(v) for v in system.center_of_mass.xreplace(values)])
    mesh = surface(system.shape, values, center_of_mass=c)
    motions: dict[str, Motion] = {
        label: motion(system, run, {p.name: v for p, v in values.items()}) for label, run in runs.items()
    }
    start = min(float(m.t[0]) for m in motions.values())
    end = max(float(m.t[-1]) for m in motions.values())
    times = list(np.linspace(start, end, snapshots)) if snapshots > 1 else [end]
    toward, right, up = _camera()
    light = toward + 0.7 * up - 0.4 * right
    light /= np.linalg.norm(light)
    rows = []
    for t in times:
        row = []
        for j, (label, mo) in enumerate(motions.items()):
            k = int(np.argmin(np.abs(mo.t - t)))
            ended = t > mo.t[-1] + 1e-9 * max(1.0, abs(end))
            R, G = mo.R[k], mo.centre[k]
            space = G + (mesh.points - c) @ R.T
            normals = mesh.normals @ R.T
            seen = normals @ toward > 1e-9
            dark, pale = (_rgb(h) for h in PALETTE[j % len(PALETTE)])
            base = np.where(
                mesh.paint[:, None] == 2, _rgb(ACCENT), np.where(mesh.paint[:, None] == 1, dark, pale)
            )
            shade = 0.45 + 0.55 * np.clip(normals @ light, 0.0, 1.0)
            row.append(
                Scene(
                    label,
                    float(mo.t[k]),
                    k,
                    [space[f] for f, s in zip(mesh.faces, seen) if s],
                    (base * shade[:, None])[seen],
                    mesh.paint[seen],
                    mo.contact[: k + 1],
                    G + R @ (mesh.centre - c),
                    G + R @ (mesh.marker - c),
                    _shadow(space),
                    bool(ended),
                )
            )
        rows.append(row)
    return mesh, [float(t) for t in times], rows


def _title(label: str) -> str:
    name = label.partition("/")[0]
    model = registry.MODELS.get(name)
    if model is None:
        return label
    if model.motion == "true":
        return f"{label}: the true motion"
    return f"{label}: Lindelöf's equations" if name == "lindelof" else f"{label}: vakonomic motion"


def _nice(step: float) -> float:
    e = 10 ** np.floor(np.log10(step))
    return float(min((m * e for m in (1, 2, 5, 10) if m * e >= step), default=10 * e))


def _draw_scene(
    ax: Axes, scene: Scene, others: Sequence[Scene], half: tuple[float, float], color: str
) -> None:
    from matplotlib.collections import LineCollection, PolyCollection

    _, right, up = _camera()
    S = np.array([right, up])

    def screen(p: np.ndarray) -> np.ndarray:
        return np.asarray(p) @ S.T

    cx, cy = screen(scene.centre)
    hx, hy = half
    ax.set_xlim(cx - hx, cx + hx)
    ax.set_ylim(cy - hy, cy + hy)
    ax.set_aspect("equal")
    ax.set_facecolor(GROUND)
    ax.set_xticks([])
    ax.set_yticks([])
    # the plane's grid, fixed in space: the window's corners taken back to z = 0
    corners = np.array([[cx + sx * hx, cy + sy * hy] for sx in (-1, 1) for sy in (-1, 1)])
    plane = np.linalg.solve(S[:, :2], corners.T).T  # (a, b) = S (x, y, 0)
    lo, hi = plane.min(axis=0), plane.max(axis=0)
    step = _nice(hx / 2.5)
    lines = []
    for axis in (0, 1):
        for v in np.arange(np.floor(lo[axis] / step), np.ceil(hi[axis] / step) + 1) * step:
            a, b = np.zeros(3), np.zeros(3)
            a[axis] = b[axis] = v
            a[1 - axis], b[1 - axis] = lo[1 - axis], hi[1 - axis]
            lines.append(screen(np.array([a, b])))
    ax.add_collection(LineCollection(lines, colors="#d9d3c4", linewidths=0.6, zorder=0))
    ax.fill(*screen(scene.shadow).T, color="#000000", alpha=0.13, lw=0, zorder=1)
    for other in others:
        if len(other.path) > 1:
            ax.plot(*screen(other.path).T, color="#8a8a8a", lw=0.8, ls=(0, (3, 2)), zorder=2)
    path = screen(scene.path)
    ax.plot(*path.T, color=color, lw=1.6, zorder=3)
    ax.plot(*path[0], "o", color=color, ms=3, zorder=3)
    ax.plot(*path[-1], "o", color="#1b1b1b", ms=2.5, zorder=3)
    polys = [screen(f) for f in scene.faces]
    ax.add_collection(
        PolyCollection(
            polys, facecolors=scene.colors, edgecolors=scene.colors, linewidths=0.3, zorder=4, clip_on=False
        )  # the window holds the body
    )
    text = f"t = {scene.t:.3g}" + (" (run ended)" if scene.ended else "")
    ax.text(0.03, 0.95, text, transform=ax.transAxes, va="top", fontsize=8, color="#333333")


def _figure(system: RollingBody, mesh: Mesh, times: list[float], rows: list[list[Scene]]) -> Figure:
    from chaplygin.numeric._figure import Figure

    ncol = len(rows[0])
    cell_w, cell_h, top_h = 4.2, 2.9, 3.0
    fig = Figure(figsize=(cell_w * ncol, top_h + cell_h * len(rows)), layout="constrained")
    grid = fig.add_gridspec(1 + len(rows), ncol, height_ratios=[top_h] + [cell_h] * len(rows))
    # the whole contact paths from above, the snapshots numbered
    over = fig.add_subplot(grid[0, :])
    for j in range(ncol):
        color = PALETTE[j % len(PALETTE)][0]
        last = rows[-1][j]
        over.plot(last.path[:, 0], last.path[:, 1], color=color, lw=1.6, label=_title(last.label))
        over.plot(*last.path[0, :2], "o", color=color, ms=3)
        for i, row in enumerate(rows):
            p = row[j].path[-1]
            over.annotate(
                str(i + 1),
                p[:2],
                fontsize=7,
                color=color,
                ha="center",
                va="center",
                bbox={"boxstyle": "circle,pad=0.15", "fc": "white", "ec": color, "lw": 0.6},
            )
    over.set_aspect("equal", adjustable="datalim")
    over.set_xlabel("x", fontsize=8, labelpad=1)
    over.set_ylabel("y", fontsize=8, labelpad=1)
    over.tick_params(labelsize=7)
    over.legend(fontsize=8, loc="best")
    over.set_title(f"{system.name}: contact paths seen from above; numbers: the views below", fontsize=9)
    # the 3-D views: one scale for all, the body and a margin
    half_w = 1.9 * mesh.radius
    half = (half_w, half_w * cell_h / cell_w)
    for i, row in enumerate(rows):
        for j, scene in enumerate(row):
            ax = fig.add_subplot(grid[1 + i, j], gid=f"bodyview-{i + 1}-{j + 1}")
            _draw_scene(ax, scene, [s for s in row if s is not scene], half, PALETTE[j % len(PALETTE)][0])
            if j == 0:
                ax.text(-0.012, 0.5, str(i + 1), transform=ax.transAxes, ha="right", va="center", fontsize=8)
            if i == 0:
                ax.set_title(_title(scene.label), fontsize=9)
    return fig


def show_rolling(
    system: RollingBody,
    trajectories: Any,
    *,
    snapshots: int = 6,
    parameters: Mapping[Any, float] | None = None,
) -> Figure:
    """A matplotlib figure of the body rolling: its contact paths, then 3-D views over time.

    Parameters
    ----------
    system : RollingBody
        Built by :func:`chaplygin.bodies.rolling_body`.
    trajectories : Trajectory, mapping label → Trajectory, or Comparison
        The runs to show side by side, e.g. ``chaplygin.compare(system, ["chaplygin",
        "lindelof"], …)``: the true motion and Lindelöf's from the same initial state.
    snapshots : int
        Rows of views, at times evenly spread over the runs.
    parameters : mapping, optional
        Numbers for the system's parameters (default: the first run's).

    Returns
    -------
    matplotlib.figure.Figure
        Not managed by pyplot; Jupyter shows it, ``fig.savefig`` writes it.
    """
    mesh, times, rows = scenes(system, trajectories, snapshots=snapshots, parameters=parameters)
    return _figure(system, mesh, times, rows)


def _svg(fig: Figure) -> str:
    """Inline ``<svg>`` markup: no prolog, no metadata, deterministic ids."""
    import matplotlib

    buf = io.StringIO()
    with matplotlib.rc_context({"svg.hashsalt": "chaplygin-body", "svg.fonttype": "path"}):
        fig.savefig(buf, format="svg", metadata={"Date": None})
    text = buf.getvalue()
    text = re.sub(r"\s*<metadata>.*?</metadata>", "", text[text.find("<svg") :], flags=re.S)
    # two decimals of a point are plenty: a third of the size
    return re.sub(r' d="[^"]*"', lambda m: re.sub(r"(\.\d\d)\d+", r"\1", m.group(0)), text)


def body_views(
    system: RollingBody,
    trajectories: Any,
    *,
    snapshots: int = 6,
    parameters: Mapping[Any, float] | None = None,
) -> str:
    """:func:`show_rolling` as an HTML fragment: a ``<figure>`` holding inline SVG and a caption.

    Self-contained: no script, no image file, nothing fetched when it is viewed.
    """
    fig = show_rolling(system, trajectories, snapshots=snapshots, parameters=parameters)
    caption = (
        "Each row is one time, each column one run from the same initial state; the camera follows "
        "the body (the plane's grid is fixed in space). The body is painted with a checker of its "
        "octants, one of them gold, so that its turning shows; the solid line is its contact path so "
        "far, the dashed grey line the other runs' paths so far."
    )
    return (
        f'<figure class="figure bodyview" id="figure-body">{_svg(fig)}'
        f'<figcaption class="note">{html.escape(caption)}</figcaption></figure>'
    )


def body_section(system: Any, comparison: Any) -> str:
    """The report's section "The body rolling", or ``""`` when ``system`` is not a rolling body
    or nothing was simulated."""
    if not isinstance(system, RollingBody) or comparison is None:
        return ""
    try:
        views = body_views(system, comparison)
    except InputError as exc:
        views = f'<p class="note">Not drawn: {html.escape(str(exc))}</p>'
    return f'<section id="body"><h2>The body rolling</h2>\n{views}\n</section>'
