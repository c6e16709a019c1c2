"""Exceptions raised by chaplygin.

Every error a user can provoke with bad input is a :class:`ChaplyginError`
whose message names the offending item and says what would be accepted.
"""

from __future__ import annotations

__all__ = ["ChaplyginError", "ChaplyginWarning", "InputError", "ModelError", "SystemDefinitionError"]


class ChaplyginError(Exception):
    """Base class of every error raised on purpose by chaplygin."""


class SystemDefinitionError(ChaplyginError, ValueError):
    """The description of a mechanical system is invalid."""


class ModelError(ChaplyginError, ValueError):
    """A model or form was asked for that does not apply to the system."""


class InputError(ChaplyginError, ValueError):
    """A simulation input is invalid or physically meaningless (a negative mass, ``t_end = inf``,
    a start on a pole of the solved constraints, …)."""


class ChaplyginWarning(UserWarning):
    """Something the user should know that does not stop the work (a fallback, a default used)."""
