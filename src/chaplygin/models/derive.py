"""Derive the equations of any model of the registry (the work behind ``System.equations``)."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from chaplygin.errors import ModelError
from chaplygin.models import registry
from chaplygin.models.chetaev import chetaev_equations
from chaplygin.models.reduced import reduced_equations
from chaplygin.models.vakonomic import vakonomic_equations, vakonomic_family

if TYPE_CHECKING:
    from chaplygin.core.system import System
    from chaplygin.models.equations import Equations

__all__ = ["derive"]

#: the builder of each kind of model (the ``builder`` column of the registry)
_BUILDERS: dict[str, Callable[[System, registry.Model, str, Any], Equations]] = {
    "chetaev": lambda system, model, form, constants: chetaev_equations(system),
    "vakonomic": lambda system, model, form, constants: vakonomic_equations(system),
    "reduced": lambda system, model, form, constants: reduced_equations(system, model.name, form),
    "family": lambda system, model, form, constants: vakonomic_family(system, model.name, form, constants),
}


def derive(system: System, model: str, form: str = "classic", constants: Any = None) -> Equations:
    """Derive the equations of ``model`` in ``form``.

    Parameters
    ----------
    system : System
    model : str
        A model of :data:`chaplygin.models.registry.MODELS`.
    form : {"classic", "new"}
    constants : optional
        The constants ``c_β`` (models that take them).

    Raises
    ------
    ModelError
        Unknown model or form, constants given to a model without them, or a model
        whose requirements the system does not meet (e.g. Chaplygin's equations for a
        system that is not a Chaplygin system).
    """
    entry = registry.get(model, form, constants=constants)
    if entry.requires_chaplygin and not system.is_chaplygin:
        raise ModelError(
            f"{system.name} is not a Chaplygin system ("
            + "; ".join(system.chaplygin_obstructions)
            + f"), so the {entry.name!r} model (Chaplygin's equations (15)) does not apply. Use model='voronets', "
            "which allows T, U and B to depend on the dependent coordinates."
        )
    if entry.family and not entry.constants and system.is_nonlinear and system._lindelof_degenerate:
        raise ModelError(
            f"the {entry.name!r} model does not apply to {system.name}: "
            + "; ".join(system._lindelof_degenerate)
            + ". The vakonomic motions are the family with constants c ≠ 0 (model='vakonomic_family') "
            "or the multiplier form (model='vakonomic')."
        )
    return _BUILDERS[entry.builder](system, entry, form, constants)
