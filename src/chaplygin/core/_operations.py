"""The operations a :class:`~chaplygin.System` offers as methods but higher layers implement.

``system.equations(model)`` derives (the models layer) and ``system.integrability()``
analyses (the analysis layer); the description layer must not import either.  As
pandas' ``DataFrame.plot`` finds its plotting backend, each method here looks its
implementation up by module path when first called: this table is the only place where
the description layer names a higher layer, and it imports nothing from it at import
time.  (Numerics have no method: simulate with :func:`chaplygin.simulate`.)
"""

from __future__ import annotations

from importlib import import_module
from typing import Any

#: operation → (module, function)
_HOMES: dict[str, tuple[str, str]] = {
    "derive": ("chaplygin.models.derive", "derive"),
    "integrated_multipliers": ("chaplygin.models.vakonomic", "integrated_multipliers"),
    "analyze": ("chaplygin.analysis.integrability", "analyze"),
}


def operation(name: str) -> Any:
    """The function that implements operation ``name`` (a key of the table)."""
    module, function = _HOMES[name]
    return getattr(import_module(module), function)
