"""Run several models from the same initial state and show where they part.

The typical question: how far does the motion predicted by Lindelöf's
equations (or any vakonomic motion) drift from the true, Chetaev motion?
:func:`compare` simulates each model, measures the distance between the paths
of a chosen pair of coordinates (the contact point or centre, by default
``x, y``) over time, and draws matplotlib figures: paths in the plane,
coordinates over time, energy and constraint drift.

A reduced model (Chaplygin's, Voronets' equations, the vakonomic family) solves
the constraints for the dependent velocities; where that solution has a pole on
the path (a knife edge whose ``ẏ = tan φ ẋ`` meets φ = π/2) its run stops
there.  :func:`compare` then warns and simulates the multiplier form of the same
motion (``chetaev``; ``vakonomic`` for the family), which has no such pole, under
the same label; :attr:`Comparison.notes` says so.

By default (:func:`default_models`) it compares the paper's pair: the true motion with the
vakonomic motion from the same state (μ(0) = 0, ``constants="match"``), and with Lindelöf's
where it exists (a Chaplygin system).  The constants ``c_β`` go to the vakonomic models only,
and two names of one motion (``voronets`` and ``chetaev``, a model and another form of it) are
compared only with a note that their distance is integration error.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from chaplygin.errors import ChaplyginError, ChaplyginWarning
from chaplygin.models import registry
from chaplygin.numeric.simulate import (
    TIME_LIMIT,
    Degenerate,
    Trajectory,
    _atomic_write,
    simulate,
    time_span,
    vakonomic_constants,
)

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from chaplygin.core.system import System
    from chaplygin.models.registry import Model

__all__ = ["Comparison", "coincide", "compare", "default_models", "motion_notes"]

FIGURES = ("paths", "coordinates", "invariants")
#: line style and marker of each model, in order: models whose curves coincide stay visible (the
#: markers are sparse and start at a different sample for each model; earlier lines are wider)
STYLES = (("-", ""), ("--", "o"), (":", "s"), ("-.", "^"), ((0, (5, 1, 1, 1)), "D"), ((0, (1, 2)), "v"))
#: two curves coincide "to plotting precision" when they differ nowhere by more than this
#: fraction of the data's range on either axis (a fraction of a pixel on any usual figure)
COINCIDE = 1e-3


def _parse(model: str | tuple[str, str]) -> tuple[str, str, str]:
    if isinstance(model, tuple):
        name, form = model
    else:
        name, _, form = model.partition("/")
    form = form or "classic"
    return name, form, name if form == "classic" else f"{name}/{form}"


@dataclass
class Comparison:
    """Trajectories of several models from one initial state.

    Attributes
    ----------
    trajectories : dict of label → Trajectory
        One per model, labelled ``"model"`` or ``"model/form"``.
    reference : str
        The label the others are measured against (the first model).
    path : tuple of str or None
        The coordinates whose path in the plane is compared.
    notes : list of str
        What the reader must know about the runs, e.g. that a reduced model met
        a pole of its solved constraints and its multiplier form was used.
    """

    system_name: str
    trajectories: dict[str, Trajectory]
    reference: str
    path: tuple[str, str] | None
    notes: list[str] = field(default_factory=list)

    def distance(self, label: str) -> np.ndarray:
        """Distance from the reference over time: in the path's plane, else over all coordinates."""
        ref, other = self.trajectories[self.reference], self.trajectories[label]
        k = min(len(ref.t), len(other.t))
        names = self.path or tuple(ref.coordinates)
        diff = np.array([other[c][:k] - ref[c][:k] for c in names])
        return np.sqrt(np.sum(diff**2, axis=0))

    def _peak(self, label: str) -> tuple[float, float]:
        """The largest distance of ``label`` from the reference and when (NaN without samples)."""
        d = self.distance(label)
        if not len(d):
            return float("nan"), float("nan")
        k = int(np.argmax(d))
        return float(d[k]), float(self.trajectories[label].t[k])

    @property
    def energy_label(self) -> str:
        """The energy column's heading: ``"energy drift"``, ``"energy change"`` or ``"Jacobi integral
        drift"`` (:attr:`Trajectory.energy_label`)."""
        return next(iter(self.trajectories.values())).energy_label if self.trajectories else "energy drift"

    def summary(self) -> str:
        """A table: largest distance from the reference (and when), energy drift, residual."""
        what = f"path ({', '.join(self.path)})" if self.path else "coordinates"
        w = max(13, len(self.energy_label))
        lines = [
            f"{self.system_name}: models compared with {self.reference} from the same initial state",
            f"  {'model':<22} {'max distance of ' + what:>30} {'at t':>9} {self.energy_label:>{w}} {'max residual':>13}  status",
        ]
        for label, tr in self.trajectories.items():
            peak, when = self._peak(label)
            lines.append(
                f"  {label:<22} {peak:>30.6g} {when:>9.4g} "
                f"{tr.energy_drift():>{w}.3g} {np.max(tr.constraint_residual, initial=0.0):>13.3g}  {tr.status}"
            )
        lines += [f"  note: {note}" for note in self.notes]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def _repr_html_(self) -> str:
        from chaplygin import _html

        what = f"path ({', '.join(self.path)})" if self.path else "coordinates"
        rows = []
        for label, tr in self.trajectories.items():
            peak, when = self._peak(label)
            cells = (
                label,
                f"{peak:.6g}",
                f"{when:.4g}",
                f"{tr.energy_drift():.3g}",
                f"{np.max(tr.constraint_residual, initial=0.0):.3g}",
                tr.status,
            )
            rows.append([_html.escape(c) for c in cells])
        header = ["model", f"max distance of {what}", "at t", self.energy_label, "max residual", "status"]
        text = _html.heading(f"{self.system_name}: models compared with {self.reference}")
        text += _html.table(rows, header) + "".join(f"<p>note: {_html.escape(n)}</p>" for n in self.notes)
        return text + (_html.png(self.figure("paths"), alt="paths") if self.path else "")

    # ------------------------------------------------------------------ figures
    def figure(self, kind: str = "paths") -> Figure:
        """A matplotlib figure: ``"paths"``, ``"coordinates"`` or ``"invariants"``.

        ``"invariants"`` draws the energy change of every model and, below, the constraint
        residual of the models with multipliers; a reduced model (the registry's ``reduced``)
        satisfies the constraints by construction, so its residual (zero, round-off) is not
        drawn, and without a model with multipliers there is no residual panel.

        Each model has its own line style and marker (:data:`STYLES`), and a curve that
        coincides with an earlier model's to plotting precision (:data:`COINCIDE`) is labelled
        ``"lindelof (same as chaplygin)"`` in the legend of its axes, so that no model hides
        behind another.
        """
        from chaplygin.numeric._figure import Figure

        if kind not in FIGURES:
            raise ChaplyginError(f"figure kind {kind!r}: choose one of {', '.join(FIGURES)}.")
        runs = self.trajectories.items()
        if kind == "paths":
            fig = Figure(figsize=(6, 5), layout="constrained")
            ax = fig.add_subplot()
            if not self.path:
                raise ChaplyginError("no path coordinates to draw; pass path=('x', 'y') to compare().")
            px, py = self.path
            _draw(ax, [(label, tr[px], tr[py]) for label, tr in runs], legend=True)
            for _, tr in runs:
                ax.plot(tr[px][:1], tr[py][:1], "ko", ms=3)
            ax.set(xlabel=px, ylabel=py, title=f"{self.system_name}: paths")
            ax.set_aspect("equal", adjustable="datalim")
        elif kind == "coordinates":
            names = list(self.trajectories[self.reference].coordinates)
            fig = Figure(figsize=(7, 1.6 * len(names) + 0.6), layout="constrained")
            axes = fig.subplots(len(names), 1, sharex=True, squeeze=False)[:, 0]
            for k, (ax, name) in enumerate(zip(axes, names)):
                _draw(ax, [(label, tr.t, tr[name]) for label, tr in runs], legend=k == 0)
                ax.set_ylabel(name)
            axes[-1].set_xlabel("t")
            axes[0].set_title(f"{self.system_name}: coordinates")
        else:
            # a reduced model's residual is zero by construction: drawn only for the others
            exact = [label for label, tr in runs if registry.MODELS[tr.model].reduced]
            residual = len(exact) < len(self.trajectories)
            fig = Figure(figsize=(7, 5 if residual else 3), layout="constrained")
            top, *bottom = fig.subplots(2 if residual else 1, 1, sharex=True, squeeze=False)[:, 0]
            drift = [
                (
                    label,
                    tr.t,
                    np.abs(tr.energy - (e0 := tr.energy[0] if len(tr.energy) else 0.0)) / max(1.0, abs(e0))
                    + 1e-18,
                )
                for label, tr in runs
            ]
            _draw(top, drift, legend=True, log=True)
            e = "h" if "jacobi" in self.energy_label.lower() else "E"
            top.set(
                yscale="log",
                ylabel=f"|{e} − {e}(0)| / max(1, |{e}(0)|)",
                title=f"{self.system_name}: {'Jacobi integral' if e == 'h' else 'energy'}",
            )
            if residual:
                curves = [
                    (label, tr.t, None if label in exact else tr.constraint_residual + 1e-18)
                    for label, tr in runs
                ]
                _draw(bottom[0], curves, legend=False, log=True)
                bottom[0].set(yscale="log", ylabel="constraint residual", xlabel="t")
                if exact:
                    bottom[0].set_title(f"{', '.join(exact)}: 0 by construction (reduced)", fontsize="small")
            else:
                top.set_xlabel("t")
        return fig

    def save_figures(self, directory: str | Path, *, fmt: str = "svg") -> list[Path]:
        """Write every figure to ``directory`` (atomically) and return the paths."""
        out = []
        for kind in FIGURES:
            if kind == "paths" and not self.path:
                continue
            fig = self.figure(kind)
            target = Path(directory) / f"{kind}.{fmt}"
            out.append(_atomic_write(target, lambda fh, f=fig: f.savefig(fh, format=fmt), text=False))
        return out


def _span(values: list[np.ndarray]) -> float:
    """The range of ``values`` together (at least 1e-9 of their size: round-off on a constant)."""
    finite = np.concatenate([v[np.isfinite(v)] for v in values]) if values else np.empty(0)
    if not finite.size:
        return 0.0
    return max(float(np.ptp(finite)), 1e-9 * float(np.max(np.abs(finite))))


def coincide(
    a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray], spans: tuple[float, float]
) -> bool:
    """Whether curves ``a`` and ``b`` (x, y) are the same to plotting precision: as many points,
    NaN at the same ones, and nowhere apart by more than :data:`COINCIDE` of ``spans`` (x, y)."""
    if len(a[0]) != len(b[0]) or not len(a[0]):
        return False
    for u, v, span in ((a[0], b[0], spans[0]), (a[1], b[1], spans[1])):
        u, v = np.asarray(u, dtype=float), np.asarray(v, dtype=float)
        if not np.array_equal(np.isnan(u), np.isnan(v)):
            return False
        both = ~np.isnan(u)
        if np.any(np.abs(u[both] - v[both]) > COINCIDE * span):
            return False
    return True


def _draw(
    ax: Any, curves: list[tuple[str, np.ndarray, np.ndarray | None]], *, legend: bool, log: bool = False
) -> None:
    """Draw one curve per model, each in its own style; a curve that coincides with an earlier
    one is labelled ``"label (same as earlier)"``.  A legend when asked or when any coincides.
    A curve ``None`` is not drawn but keeps its model's style (and colour) for the next ones."""

    def scaled(y: np.ndarray) -> np.ndarray:  # coincidence as seen on a log axis
        y = np.asarray(y, dtype=float)
        return np.log10(np.where(y > 0, y, np.nan)) if log else y

    drawn = [(i, label, x, y) for i, (label, x, y) in enumerate(curves) if y is not None]
    spans = (
        _span([np.asarray(x, dtype=float) for _, _, x, _ in drawn]),
        _span([scaled(y) for _, _, _, y in drawn]),
    )
    any_same = False
    for i, (label, x, y) in enumerate(curves):
        if y is None:
            ax.plot([], [])  # the next model keeps its colour
            continue
        same = next(
            (other for j, other, u, v in drawn if j < i and coincide((u, scaled(v)), (x, scaled(y)), spans)),
            None,
        )
        any_same |= same is not None
        linestyle, marker = STYLES[i % len(STYLES)]
        every = max(1, len(x) // 12)
        ax.plot(
            x,
            y,
            linestyle=linestyle,
            marker=marker,
            ms=4,
            markevery=(i * every // len(curves), every),
            lw=max(1.0, 2.2 - 0.4 * i),
            label=label if same is None else f"{label} (same as {same})",
        )
    if legend or any_same:
        ax.legend(fontsize="small")


def _default_path(system: System) -> tuple[str, str] | None:
    names = [q.func.__name__ for q in system.coordinates]
    if "x" in names and "y" in names:
        return ("x", "y")
    dep = [q.func.__name__ for q in system.dependent]
    return (dep[0], dep[1]) if len(dep) >= 2 else None


def default_models(system: System) -> list[str]:
    """The paper's comparison: the true motion (Chaplygin's equations, else Voronets'), the
    vakonomic motion from the same state, and Lindelöf's equations where they exist."""
    models = [registry.true_motion(system), "vakonomic"]
    return [*models, "lindelof"] if registry.MODELS["lindelof"].obstruction(system) is None else models


def _takes_constants(model: str | Model) -> bool:
    """Whether ``model`` (a name, or the registry's entry) takes the constants c_β or μ(0)."""
    entry = registry.get(model)
    return entry.constants or entry.multipliers_in_state


def _numbers(values: Sequence[float]) -> str:
    return ", ".join(f"c_{k} = {x:.6g}" for k, x in enumerate(values, 1))


def motion_notes(
    system: System,
    models: Sequence[str | tuple[str, str]],
    t_span: tuple[float, float] | float,
    initial: Mapping[Any, float],
    parameters: Mapping[Any, float] | None = None,
    *,
    constants: Any = "match",
    multipliers: Any = None,
) -> list[str]:
    """What a reader of a comparison of ``models`` must know about the motions themselves.

    The constants c_β of the vakonomic models (what ``constants`` or ``multipliers`` give them,
    as numbers), and every set of two or more names of one motion: the true motion under any of
    its names and forms, or the vakonomic motion with the same constants (Lindelöf's is the one
    with every c_β = 0) — their distance in the table is integration error, not a difference of
    models.
    """
    entries = {_parse(m)[2]: registry.get(_parse(m)[0]) for m in models}  # each looked up once
    return _notes(system, entries, t_span, initial, parameters, constants, multipliers)


def _notes(
    system: System,
    entries: dict[str, Model],
    t_span: tuple[float, float] | float,
    initial: Mapping[Any, float],
    parameters: Mapping[Any, float] | None,
    constants: Any,
    multipliers: Any,
) -> list[str]:
    """:func:`motion_notes` of the models ``entries`` (label → the registry's entry)."""
    motions: dict[str, list[str]] = {}
    notes: list[str] = []
    c: list[float] | None = None
    if any(_takes_constants(entry) for entry in entries.values()):
        c = vakonomic_constants(system, constants, multipliers, initial, parameters, time_span(t_span)[0])
        what = (
            "from the given μ(0)"
            if multipliers is not None
            else "'match': μ(0) = 0, so it starts with the accelerations of the true motion"
            if isinstance(constants, str) and constants == "match"
            else "'zero'"
            if constants is None or (isinstance(constants, str) and constants == "zero")
            else "given"
        )
        dependent = ", ".join(q.func.__name__ for q in system.dependent)
        kept = (
            "conserved along the motion"
            if not registry.family_obstructions(system)
            else f"not conserved on {system.name}: these are their values at t = {time_span(t_span)[0]:g}"
        )
        taking = [label for label, entry in entries.items() if _takes_constants(entry)]
        notes.append(
            f"{', '.join(taking)}: {_numbers(c)} ({what}); c_β are the momenta ∂L_v/∂q̇ of the "
            f"dependent coordinates {dependent}, {kept}"
        )
    for label, entry in entries.items():
        if entry.is_true_motion:
            motion = "the true motion"
        elif entry.name == "lindelof" or (c is not None and np.allclose(c, 0.0, rtol=0.0, atol=1e-12)):
            motion = "the vakonomic motion with every c_β = 0"
        else:
            motion = "the vakonomic motion with these constants"
        motions.setdefault(motion, []).append(label)
    for motion, same in motions.items():
        if len(same) > 1:
            notes.append(
                f"{' and '.join([', '.join(same[:-1]), same[-1]])} are the same motion ({motion}): "
                "their distance in the table is integration error, not a difference of models"
            )
    return notes


#: the fallback's note where the constraints were written solved with a denominator
_SHARED_POLE = (
    "but with the constraints as written, solved with a denominator, its rows have that pole too "
    "and lose accuracy near it; written implicitly they would not"
)


#: the fallback's note for constraints nonlinear in the velocities: the multiplier model has
#: ``A = ∂f/∂q̇`` as its rows, which keep full rank where only ``∂f/∂q̇_dep`` is singular
_BRANCH_POINT = (
    "which does not solve the constraints for the dependent velocities, so their branch point "
    "does not stop it where ∂f/∂q̇ keeps full rank"
)


def _rows_have_poles(system: System) -> bool:
    """Whether a coefficient of the constraints ``A q̇ + A_0 = 0`` has a coordinate in a
    denominator (``y' = tan θ x'``: ``A = [−sin θ / cos θ, 1]``)."""
    import sympy as sp

    coordinates = system._vars.x
    return any(sp.denom(sp.together(a)).has(*coordinates) for a in [*system._A, *system._A0])


def compare(
    system: System,
    models: Sequence[str | tuple[str, str]] | None,
    t_span: tuple[float, float] | float,
    initial: Mapping[Any, float],
    parameters: Mapping[Any, float] | None = None,
    *,
    path: tuple[str, str] | None = None,
    rtol: float = 1e-10,
    atol: float = 1e-12,
    method: str = "DOP853",
    samples: int = 1001,
    backend: str = "auto",
    constants: Any = None,
    multipliers: Any = None,
    max_step: float = np.inf,
    step: float | None = None,
    reduction: str = "auto",
    progress: Callable[[float], None] | None = None,
    time_limit: float | None = TIME_LIMIT,
) -> Comparison:
    """Simulate ``models`` from one initial state and compare them with the first.

    Parameters
    ----------
    system : System
    models : sequence or None
        Model names, optionally with a form: ``["chaplygin", "lindelof/new"]``
        or ``[("chaplygin", "new")]``.  The first is the reference.  None: the paper's
        comparison (:func:`default_models`): the true motion, the vakonomic motion from the
        same state and, on a Chaplygin system, Lindelöf's.
    t_span, initial, parameters
        As for :func:`chaplygin.numeric.simulate`.
        A reduced model whose solved constraints have a pole on the path is
        replaced by its multiplier form (the ``fallback`` of its registry entry), with a
        :class:`~chaplygin.errors.ChaplyginWarning` and a note in
        :attr:`Comparison.notes`; Lindelöf's equations have none, so their run
        stops at the pole (noted too).
    path : (str, str), optional
        The coordinates whose paths are compared and drawn; by default ``x, y``
        when the system has them, else its first two dependent coordinates.
    constants : "match", "zero", sequence or mapping, optional
        The constants c_β of the vakonomic models (``vakonomic``, ``vakonomic_family``), the
        momenta ``∂L_v/∂q̇_{ε+β}`` of the dependent coordinates at the start: ``"match"`` (the
        default: μ(0) = 0, so that the vakonomic motion starts with the accelerations of the
        true one), ``"zero"`` (every c_β = 0: on a Chaplygin system, Lindelöf's motion), or one
        number per constraint (``[0.5, 1.0]``, ``{"c_1": 0.5, "c_2": 1.0}``).  On a Chaplygin
        system without forces along the dependent coordinates they are constant; elsewhere
        they fix the start only.  The other models take none.
    multipliers : sequence or mapping, optional
        μ(0) of the model ``vakonomic`` instead of the constants.
    rtol, atol, method, samples, backend, max_step, step, reduction, progress, time_limit
        Passed to :func:`chaplygin.numeric.simulate` for every model (it checks them);
        ``progress(t)`` hears each model's integration in turn.

    Returns
    -------
    Comparison
        The runs; its :attr:`Comparison.notes` give the constants used (as numbers) and say
        which labels are names of one motion (:func:`motion_notes`).
    """
    options: dict[str, Any] = {
        "rtol": rtol,
        "atol": atol,
        "method": method,
        "samples": samples,
        "backend": backend,
        "max_step": max_step,
        "step": step,
        "reduction": reduction,
        "progress": progress,
        "time_limit": time_limit,
    }
    defaulted = models is None  # (a default model whose vakonomic start is degenerate is left out)
    models = default_models(system) if models is None else models
    if not models:
        raise ChaplyginError("models: name at least one model.")
    names = [q.func.__name__ for q in system.coordinates]
    if path is not None and any(c not in names for c in path):
        raise ChaplyginError(f"path: {path} are not both coordinates of {system.name} ({', '.join(names)}).")
    parsed = [_parse(model) for model in models]
    entries = [registry.get(name, form) for name, form, _ in parsed]  # each model looked up once
    labels = [label for _, _, label in parsed]
    twice = next((label for k, label in enumerate(labels) if label in labels[:k]), None)
    if twice is not None:
        raise ChaplyginError(f"models: {twice!r} is listed twice; name each model (and form) once.")
    given = constants is not None or multipliers is not None
    if given and not any(_takes_constants(entry) for entry in entries):
        raise ChaplyginError(
            f"constants/multipliers: none of the models {', '.join(label for _, _, label in parsed)} "
            "takes them; they are for the vakonomic models 'vakonomic' and 'vakonomic_family' "
            "(Lindelöf's equations are the member with every c_β = 0)."
        )
    vakonomic = {"constants": "match" if not given else constants, "multipliers": multipliers}
    notes = _notes(system, dict(zip(labels, entries)), t_span, initial, parameters, **vakonomic)
    trajectories: dict[str, Trajectory] = {}
    for (name, form, label), entry in zip(parsed, entries):
        own = {**options, **vakonomic} if _takes_constants(entry) else options
        try:
            tr = simulate(system, name, t_span, initial, parameters, form=form, **own)
        except Degenerate as exc:
            # (nonlinear constraints: e.g. Lindelöf's T̃ of the isokinetic particle is constant)
            if not defaulted or label == labels[0]:
                raise
            note = f"{label}: left out: {exc}"
            warnings.warn(note, ChaplyginWarning, stacklevel=2)
            notes.append(note)
            continue
        if tr.failure == "pole":
            fallback = entry.fallback
            if fallback is None:
                note = (
                    f"{label} stops at {tr.message.split(';')[0]} (these equations have no multiplier form)"
                )
            else:
                note = (
                    f"{label}: {tr.message.split(';')[0]}, where the reduced equations do not hold; "
                    f"shown instead: the {fallback} model (the same motion with multipliers, "
                    + (
                        _BRANCH_POINT
                        if system.is_nonlinear
                        else _SHARED_POLE
                        if _rows_have_poles(system)
                        else "no pole"
                    )
                    + ")"
                )
                tr = simulate(system, fallback, t_span, initial, parameters, **own)
            warnings.warn(note, ChaplyginWarning, stacklevel=2)
            notes.append(note)
        notes += [note for note in tr.notes if note not in notes]  # (a coordinate solved at the start)
        if tr.holonomic_residual.size:
            notes.append(f"{label}: max holonomic residual |f| {np.max(tr.holonomic_residual):.3g}")
        trajectories[label] = tr
    return Comparison(
        system.name, trajectories, next(iter(trajectories)), path or _default_path(system), notes
    )
