"""The paper's transitions between the two models, and a classifier for hand-derived equations.

For a Chaplygin system, Chaplygin's equations (15) and Lindelöf's (22) differ
by the **Lindelöf defect**::

    (15) − (22) = Σ_β (∂T/∂q̇_{ε+β})~ W_βσ ,   W_βσ = Σ_γ (∂B_βγ/∂q_σ − ∂B_βσ/∂q_γ) q̇_γ (+ affine terms)

All models coincide (Chetaev ≡ Lindelöf ≡ vakonomic with c = 0) when every
``W_βσ`` vanishes — condition (28) for homogeneous scleronomic constraints.  The
defect can vanish although (28) fails (the vertical rolling disk): then
Lindelöf's equations happen to give the true motion.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import partial
from typing import TYPE_CHECKING, Any

import numpy as np
import sympy as sp
from sympy.physics.vector.printing import vlatex, vsstrrepr

from chaplygin import _html
from chaplygin.analysis.equivalence import EquationsLike, Inconsistent, _Linear, _States, where
from chaplygin.analysis.integrability import SHOWN_OPS
from chaplygin.analysis.integrability import shown as readable
from chaplygin.core import _fold
from chaplygin.core._brief import brief
from chaplygin.core._sampling import vanishes
from chaplygin.errors import ChaplyginError, ModelError
from chaplygin.models import registry
from chaplygin.models.reduced import Reduction, bracket_terms, lindelof_defect
from chaplygin.models.vakonomic import family_obstructions

if TYPE_CHECKING:
    from chaplygin.core.system import System

__all__ = ["Classification", "ModelComparison", "classify", "compare_models"]


@dataclass
class ModelComparison:
    """How the Chetaev and vakonomic models relate for one system.

    Attributes
    ----------
    coincide : bool
        Every ``W_βσ`` vanishes (condition (28) and, for affine or rheonomic
        constraints, its time terms): Chetaev ≡ Lindelöf ≡ vakonomic(c = 0).
    condition_28 : bool or None
        Condition (28) with, for affine or time-dependent constraints, its dt
        terms ``∂B_βσ/∂t − ∂B_β0/∂q_σ`` (as in ``integrability()``): for the
        Chaplygin systems compared here the same as ``coincide``, and true
        exactly when the constraints are integrable; None for constraints
        nonlinear in the velocities (it is a test of linear ones).
    defect : dict
        The Lindelöf defect, (15) minus (22), by independent coordinate.
    defect_vanishes : bool
        The defect is identically zero: Lindelöf's equations are right here.
    nonlinear : bool
        The constraints are nonlinear in the velocities: the reduced true motion is then
        Novoselov's equations, and ``W_βσ`` contains accelerations.
    lindelof_obstruction : str or None
        Why Lindelöf's equations do not apply (nonlinear constraints whose ``T̃`` is degenerate
        in the independent velocities); then there is no defect (``defect`` is empty).
    """

    system_name: str
    coincide: bool
    condition_28: bool | None
    defect: dict[sp.Expr, sp.Expr]
    defect_vanishes: bool
    nonlinear: bool = False
    lindelof_obstruction: str | None = None

    @property
    def verdict(self) -> str:
        """``"coincide"``, ``"lindelof_right_here"``, ``"differ"`` or ``"no_lindelof"``."""
        if self.lindelof_obstruction is not None:
            return "no_lindelof"
        if self.coincide:
            return "coincide"
        return "lindelof_right_here" if self.defect_vanishes else "differ"

    def __str__(self) -> str:
        true = "Novoselov's equations" if self.nonlinear else "Chaplygin's equations (15)"
        head = {
            "coincide": f"the models coincide: {'Novoselov' if self.nonlinear else 'Chaplygin'} ≡ Lindelöf ≡ every vakonomic motion "
            "(any c), since the brackets W_βσ vanish" + ("." if self.nonlinear else " (condition (28))."),
            "lindelof_right_here": (
                "the brackets W_βσ do not vanish" if self.nonlinear else "condition (28) fails"
            )
            + ", but the Lindelöf defect vanishes: Lindelöf's equations happen to be right here.",
            "differ": f"the models differ: {true} = Lindelöf's (22) + the defect below.",
            "no_lindelof": f"Lindelöf's equations do not apply ({self.lindelof_obstruction}); "
            f"compare {true} with the vakonomic family (vakonomic_family, with its constants) instead.",
        }[self.verdict]
        lines = [f"{self.system_name}: {head}"]
        if self.verdict == "differ":
            kept = "the comparison's .defect holds it"
            lines += [f"  {vsstrrepr(q)}: {brief(d, kept)}" for q, d in self.defect.items()]
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        rows = [
            (_html.math(vlatex(q)), _fold.html_math(d, escape=_html.escape)) for q, d in self.defect.items()
        ]
        text = _html.heading(str(self).splitlines()[0])
        if self.verdict == "differ":
            text += _html.table(rows, ["coordinate", "Lindelöf defect (15) − (22)"])
        return text


def _require_family(system: System) -> None:
    problems = family_obstructions(system)
    if problems:
        raise ModelError(
            f"{system.name} has no Lindelöf equations or reduced vakonomic family ("
            + "; ".join(problems)
            + "); compare the multiplier forms instead, with models=['chetaev', 'vakonomic']."
        )


def _shown(defect: sp.Expr, nonlinear: bool) -> sp.Expr:
    """A defect as printed: :func:`readable`; for nonlinear constraints also cancelled where that
    is shorter (the normal form keeps a square root's square as an unexpanded factor)."""
    out = readable(defect)
    if nonlinear and sp.count_ops(out) <= SHOWN_OPS:
        cancelled = sp.factor_terms(sp.cancel(out))
        if sp.count_ops(cancelled) < sp.count_ops(out):
            return cancelled
    return out


def compare_models(system: System) -> ModelComparison:
    """Which models coincide for ``system``, and the Lindelöf defect (15) − (22)."""
    _require_family(system)
    W = bracket_terms(system)
    coincide = all(vanishes(w) for row in W for w in row)
    obstruction = registry.get("lindelof").obstruction(system)
    if obstruction is not None:  # no Lindelöf equations: no defect against them
        return ModelComparison(system.name, coincide, None, {}, False, True, obstruction)
    defect = lindelof_defect(system, Reduction(system))
    zero = [vanishes(d) for d in defect]
    shown = {
        system.independent[k]: system.to_user(sp.S.Zero if z else _shown(d, system.is_nonlinear))
        for k, (d, z) in enumerate(zip(defect, zero))
    }
    if system.is_nonlinear:
        return ModelComparison(system.name, coincide, None, shown, all(zero), nonlinear=True)
    return ModelComparison(system.name, coincide, coincide, shown, all(zero))


@dataclass
class Classification:
    """Which model a set of equations belongs to (see :func:`classify`).

    Attributes
    ----------
    verdict : str
        ``"chetaev"`` (the true, nonholonomic motion), ``"lindelof"``
        (constraints substituted into T: Lindelöf's equations (22)),
        ``"vakonomic"`` (a member of the reduced vakonomic family, constants in
        :attr:`constants`) or ``"none"``.
    constants : dict
        ``c_β`` of the vakonomic member (empty otherwise).
    residuals : dict
        Largest relative difference from each candidate model.
    samples : int
        Number of admissible states evaluated.
    checked : dict
        Where they were drawn: a range for each coordinate (angles around the
        circle, other coordinates with both signs), t, the velocities and the
        parameters.
    """

    verdict: str
    constants: dict[str, float] = field(default_factory=dict)
    residuals: dict[str, float] = field(default_factory=dict)
    note: str = ""
    samples: int = 0
    checked: dict[str, str] = field(default_factory=dict)

    def __str__(self) -> str:
        text = {
            "chetaev": "the true (Chetaev) motion",
            "lindelof": "Lindelöf's equations (22): the constraints were substituted into T "
            "before Lagrange's equations (vakonomic motion with c = 0), not the true motion",
            "vakonomic": "a vakonomic motion with "
            + ", ".join(f"{k} = {v:.6g}" for k, v in self.constants.items()),
            "none": "none of the models (Chetaev, Lindelöf, vakonomic family)",
        }[self.verdict]
        residuals = ", ".join(f"{k}: {v:.2g}" for k, v in self.residuals.items())
        sampled = f"; {self.samples} states, sampled {where(self.checked)}" if self.checked else ""
        return f"{text}{'; ' + self.note if self.note else ''} (relative differences: {residuals}{sampled})"

    def _repr_html_(self) -> str:
        rows = [(_html.escape(k), f"{v:.2g}") for k, v in self.residuals.items()]
        if self.checked:
            rows.append(("sampled", _html.escape(f"{self.samples} states, {where(self.checked)}")))
        return (
            _html.heading(f"Classification: {self.verdict}")
            + f"<p>{_html.escape(str(self))}</p>"
            + _html.table(rows, ["candidate model", "relative difference"])
        )


def classify(
    system: System,
    equations: EquationsLike,
    *,
    parameters: Mapping[Any, float] | None = None,
    samples: int = 16,
    tolerance: float = 1e-8,
    seed: int = 0,
) -> Classification:
    """Say which model ``equations`` describe: Chetaev, Lindelöf, a vakonomic member, or none.

    The equations (as accepted by :func:`~chaplygin.equivalent`) are evaluated
    at random admissible states beside the Chetaev accelerations and, for
    Chaplygin systems, the reduced vakonomic family, which is affine in the
    constants ``c_β``; the constants that fit best are found by least squares.
    """
    user = _Linear(system, equations, "equations")
    if user.extra_state:
        raise ChaplyginError(
            "equations: they carry state multipliers (a multiplier appears differentiated); "
            "eliminate them first, or compare with chaplygin.equivalent(..., multipliers=...)."
        )
    reps = [user, _Linear(system, system.equations("chetaev"), "chetaev")]
    family = None
    if not family_obstructions(system):
        family = _Linear(system, system.equations("vakonomic_family"), "vakonomic family")
        reps.append(family)
    states = _States(system, reps, parameters=parameters, multipliers=None, seed=seed)
    consts = family.constants if family else []
    # the family's accelerations are affine in c unless c multiplies accelerations (W_βσ of
    # constraints nonlinear in the velocities): then c is fitted to its equations' residuals
    curved = family is not None and any(e.has(*consts) for e in family.M)
    fitted: list[tuple[dict[sp.Symbol, float], np.ndarray, np.ndarray]] = []
    rows, rhs, diffs_true, diffs_lindelof, used = [], [], [], [], 0
    contradiction = 0.0  # the largest mismatch where the equations have no solution
    for _ in range(20 * samples):
        if used == samples:
            break
        _, values = states.draw()
        try:
            a_user = user.accelerations(values)
        except Inconsistent as exc:  # they contradict the constraints here: no model's equations
            contradiction, used = max(contradiction, exc.mismatch), used + 1
            continue
        a_true = reps[1].accelerations(values)
        if a_user is None or a_true is None:
            continue
        scale = np.maximum(1.0, np.abs(a_user))  # every residual is relative to this
        diffs_true.append(np.max(np.abs(a_user - a_true) / scale))
        if curved:
            assert family is not None
            values.update({c: 0.0 for c in consts})
            row, r0 = _residual_columns(family, consts, values, a_user)
            rows.append(row)
            rhs.append(-r0)
            fitted.append((dict(values), a_user, scale))
            try:
                a_l = family.accelerations(values)
            except ChaplyginError:  # Lindelöf's equations (c = 0) do not determine them here
                a_l = None
            diffs_lindelof.append(np.inf if a_l is None else np.max(np.abs(a_user - a_l) / scale))
        elif family is not None:
            values.update({c: 0.0 for c in consts})
            a_l = family.accelerations(values)
            if a_l is None:
                continue
            diffs_lindelof.append(np.max(np.abs(a_user - a_l) / scale))
            columns = []
            for c in consts:
                values[c] = 1.0
                columns.append(family.accelerations(values) - a_l)
                values[c] = 0.0
            rows.append(np.array(columns).T / scale[:, None])
            rhs.append((a_user - a_l) / scale)
        used += 1
    if used == 0:
        raise ChaplyginError("no random admissible state gave finite values for the equations.")
    residuals = {"chetaev": float(max(diffs_true, default=contradiction))}
    note = ""
    if family is not None:
        residuals["lindelof"] = float(max(diffs_lindelof, default=contradiction))
        c = np.zeros(len(consts))
        if rows:
            G, y = np.vstack(rows), np.concatenate(rhs)
            c, *_ = np.linalg.lstsq(G, y, rcond=None)
            residuals["vakonomic_family"] = (
                _member_residual(family, consts, c, fitted) if curved else float(np.max(np.abs(G @ c - y)))
            )
        else:
            residuals["vakonomic_family"] = contradiction
    else:
        note = "the vakonomic family does not reduce for this system, so only Chetaev was tried"
    residuals = {k: max(v, contradiction) for k, v in residuals.items()}
    if residuals.get("lindelof") == np.inf:
        note = "Lindelöf's equations do not determine the accelerations here"
    if contradiction:
        note = "the equations contradict the constraints at some admissible states"
    made = partial(Classification, samples=used, checked=states.sampler.where())
    if residuals["chetaev"] <= tolerance:
        if residuals.get("lindelof", 1.0) <= tolerance:
            note = "Lindelöf's equations happen to coincide with the true motion here"
        return made("chetaev", residuals=residuals, note=note)
    if residuals.get("lindelof", 1.0) <= tolerance:
        return made("lindelof", residuals=residuals, note=note)
    if residuals.get("vakonomic_family", 1.0) <= tolerance:
        constants = {s.name: float(v) for s, v in zip(consts, c)}
        return made("vakonomic", constants, residuals, note)
    return made("none", residuals=residuals, note=note)


def _residual_columns(
    family: _Linear, consts: list[sp.Symbol], values: dict[sp.Symbol, float], accelerations: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The family's equations ``M(c)·a − F(c)`` at ``accelerations``, affine in the constants:
    the columns of each ``c_β`` and the part free of them (``values`` has every c at 0)."""

    def residual() -> np.ndarray:
        M, F = family._f(*(values[a] for a in family.args))
        x = np.zeros(len(family.unknowns))
        x[family.independent] = accelerations
        return np.atleast_2d(np.asarray(M, dtype=float)) @ x - np.asarray(F, dtype=float).reshape(-1)

    r0 = residual()
    columns = []
    for c in consts:
        values[c] = 1.0
        columns.append(residual() - r0)
        values[c] = 0.0
    return np.array(columns).T, r0


def _member_residual(
    family: _Linear,
    consts: list[sp.Symbol],
    c: np.ndarray,
    fitted: list[tuple[dict[sp.Symbol, float], np.ndarray, np.ndarray]],
) -> float:
    """Largest relative difference between the accelerations and the family member ``c``."""
    worst = 0.0
    for values, accelerations, scale in fitted:
        values.update(zip(consts, c.tolist()))
        try:
            member = family.accelerations(values)
        except ChaplyginError:
            return float(np.inf)
        if member is not None:
            worst = max(worst, float(np.max(np.abs(member - accelerations) / scale)))
    return worst
