"""The one table of models: every model, its forms and titles, and what it needs.

Every other module asks this table about a model — which forms it has, whether it is
the true (Chetaev) motion or a vakonomic one, reduced or with multipliers, what it
requires of the system, which multiplier model checks it — and none re-tests model
names.  A new model is one new row here and one builder in
:mod:`chaplygin.models.derive`.

The table is plain data (no SymPy), so the command line can list models without
importing the symbolic machinery.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

from chaplygin.errors import ModelError

if TYPE_CHECKING:
    from chaplygin.core.system import System

__all__ = ["FORMS", "MODELS", "Model", "family_obstructions", "get", "names", "true_motion"]

FORMS = ("classic", "new")

Motion = Literal["true", "vakonomic"]
Builder = Literal["chetaev", "vakonomic", "reduced", "family"]


@dataclass(frozen=True)
class Model:
    """One model of constrained motion.

    Attributes
    ----------
    name : str
        The name used everywhere (``system.equations(name)``, ``--model name``).
    titles : dict
        A title per form; the keys are the model's forms, ``"classic"`` first.
    motion : {"true", "vakonomic"}
        The true (Chetaev, Lagrange–d'Alembert) motion or a vakonomic one.
    reduced : bool
        Multipliers eliminated: the state is the coordinates and the independent
        velocities.  ``False``: the n + g equations with multipliers, state all
        velocities (and, for ``"vakonomic"``, the multipliers μ).
    builder : {"chetaev", "vakonomic", "reduced", "family"}
        How it is derived (see :func:`chaplygin.models.derive.derive`).
    requires_chaplygin : bool
        Only for Chaplygin systems (T, U and B free of the dependent coordinates).
    family : bool
        Needs the conditions of the reduced vakonomic family (a Chaplygin system
        with homogeneous constraints, eq. (18b) integrable).
    constants : bool
        Takes the constants ``c_β`` of the vakonomic family.
    multipliers_in_state : bool
        The multipliers are integrated with the state (the vakonomic model, (18)).
    checked_by : str or None
        The multiplier model of the same motion: the reference a reduced model
        must agree with.
    fallback : str or None
        The multiplier model that :func:`chaplygin.compare` shows instead where the
        solved constraints of this reduced model have a pole on the path.
    glossary : str
        One line for ``--help`` and ``chaplygin models``.
    """

    name: str
    titles: dict[str, str]
    motion: Motion
    reduced: bool
    builder: Builder
    glossary: str
    requires_chaplygin: bool = False
    family: bool = False
    constants: bool = False
    multipliers_in_state: bool = False
    checked_by: str | None = None
    fallback: str | None = None
    nonlinear_titles: dict[str, str] | None = None

    @property
    def forms(self) -> tuple[str, ...]:
        """The forms this model has (``"classic"`` first)."""
        return tuple(self.titles)

    @property
    def is_true_motion(self) -> bool:
        """The Chetaev (true, Lagrange–d'Alembert) motion."""
        return self.motion == "true"

    def title(self, form: str = "classic", *, nonlinear: bool = False) -> str:
        """The title of one form (``nonlinear``: for constraints nonlinear in the velocities)."""
        return (self.nonlinear_titles or self.titles)[form] if nonlinear else self.titles[form]

    def obstruction(self, system: System) -> str | None:
        """Why this model does not apply to ``system``, or ``None`` when it does."""
        if self.requires_chaplygin and not system.is_chaplygin:
            return "not a Chaplygin system: " + "; ".join(system.chaplygin_obstructions)
        found = family_obstructions(system) if self.family else []
        if self.family and not self.constants and not found and system.is_nonlinear:
            found += system._lindelof_degenerate  # (linear constraints: T̃'s Hessian is CᵀMC, regular)
        return "; ".join(found) if found else None


def family_obstructions(system: System) -> list[str]:
    """Why the vakonomic multipliers do not integrate to ``μ_β = c_β − ∂T/∂q̇_{ε+β}``."""
    out = list(system.chaplygin_obstructions)
    forced = [system.coordinates[i].func.__name__ for i in system._dep if system._Qnp[i] != 0]
    if forced:
        out.append(f"non-potential forces act along the dependent coordinate(s) {', '.join(forced)}")
    return out


MODELS: dict[str, Model] = {
    m.name: m
    for m in (
        Model(
            "chetaev",
            {"classic": "Chetaev model: Lagrange-d'Alembert equations with multipliers, eq. (6)/(35)"},
            motion="true",
            reduced=False,
            builder="chetaev",
            glossary="true (rolling) motion: n + g Lagrange–d'Alembert equations with multipliers λ",
        ),
        Model(
            "chaplygin",
            {
                "classic": "Chaplygin's equations, eq. (15)",
                "new": "Chaplygin's equations in the paper's new form, eq. (40)",
            },
            motion="true",
            reduced=True,
            builder="reduced",
            requires_chaplygin=True,
            checked_by="chetaev",
            fallback="chetaev",
            nonlinear_titles={
                "classic": "Novoselov's equations (Chaplygin's (15) for nonlinear constraints)",
                "new": "Novoselov's equations in the paper's new form, eq. (40)",
            },
            glossary="true motion reduced to the independent velocities, for Chaplygin systems",
        ),
        Model(
            "voronets",
            {
                "classic": "Voronets' equations",
                "new": "Voronets' equations in the unreduced form of eq. (40), generalised",
            },
            motion="true",
            reduced=True,
            builder="reduced",
            checked_by="chetaev",
            fallback="chetaev",
            nonlinear_titles={
                "classic": "Novoselov's equations (Voronets' form, nonlinear constraints)",
                "new": "Novoselov's equations in the unreduced form of eq. (40)",
            },
            glossary="true motion reduced; T, U and the constraints may depend on every coordinate",
        ),
        Model(
            "vakonomic",
            {"classic": "Vakonomic model: equations with multipliers μ, eqs. (17)-(18)"},
            motion="vakonomic",
            reduced=False,
            builder="vakonomic",
            multipliers_in_state=True,
            glossary="variational motion: n + g equations with multipliers μ integrated with the state",
        ),
        Model(
            "lindelof",
            {
                "classic": "Lindelöf's equations (vakonomic, c = 0), eq. (22)",
                "new": "Lindelöf's equations in the paper's new form, eq. (39)",
            },
            motion="vakonomic",
            reduced=True,
            builder="family",
            family=True,
            checked_by="vakonomic",
            glossary="the constraints substituted into T (Lindelöf's error): the vakonomic motion with c = 0",
        ),
        Model(
            "vakonomic_family",
            {
                "classic": "Reduced vakonomic family with constants c (c = 0: eq. (22))",
                "new": "Reduced vakonomic family in the form of eq. (39) with constants c",
            },
            motion="vakonomic",
            reduced=True,
            builder="family",
            family=True,
            constants=True,
            checked_by="vakonomic",
            fallback="vakonomic",
            glossary="the vakonomic motions with constants c_β, reduced",
        ),
    )
}


def names() -> tuple[str, ...]:
    """Every model name, in the table's order."""
    return tuple(MODELS)


def get(name: Any, form: str | None = None, *, constants: Any = None) -> Model:
    """The model called ``name``; a :class:`ModelError` naming what exists otherwise.

    With ``form``, the form is checked too; with ``constants``, that the model takes them.
    ``name`` may be a :class:`Model` already (resolved by an entry point): it is checked in
    the same way and returned, with no look-up by name.
    """
    model = name if isinstance(name, Model) else MODELS.get(name) if isinstance(name, str) else None
    if model is None:
        raise ModelError(f"unknown model {name!r}; the models are {', '.join(repr(m) for m in MODELS)}.")
    if form is not None and form not in model.titles:
        raise ModelError(
            f"model {model.name!r} has no form {form!r}; its forms are {', '.join(repr(f) for f in model.forms)}."
        )
    if constants is not None and not model.constants:
        with_constants = [m.name for m in MODELS.values() if m.constants]
        raise ModelError(
            f"constants c_β belong to model {' or '.join(map(repr, with_constants))}, not to {model.name!r}."
        )
    return model


def true_motion(system: System) -> str:
    """The reduced model of the true motion: Chaplygin's equations where they apply, else Voronets'."""
    return "chaplygin" if MODELS["chaplygin"].obstruction(system) is None else "voronets"
