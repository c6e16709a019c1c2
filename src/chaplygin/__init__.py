"""chaplygin: equations of motion of nonholonomic systems, in both models of constrained motion."""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from . import examples
    from .comparison import Comparison, compare
    from .equations import Equations
    from .equivalence import EquivalenceReport, equivalent
    from .errors import (
        ChaplyginError,
        ChaplyginWarning,
        InputError,
        ModelError,
        SystemDefinitionError,
    )
    from .files import SystemFile, SystemFileError, dumps, load, loads
    from .integrability import IntegrabilityReport
    from .mechanics import from_mechanics
    from .simulate import Trajectory
    from .system import System
    from .transitions import Classification, ModelComparison, classify, compare_models

#: where each public name lives; imported on first use, so that ``import chaplygin``
#: (and the command line, whose cached answers need no SymPy) starts fast
_HOME = {
    "examples": "", "Comparison": "comparison", "compare": "comparison", "Equations": "equations",
    "EquivalenceReport": "equivalence", "equivalent": "equivalence",
    "ChaplyginError": "errors", "ChaplyginWarning": "errors", "InputError": "errors", "ModelError": "errors", "SystemDefinitionError": "errors",
    "SystemFile": "files", "SystemFileError": "files", "dumps": "files", "load": "files",
    "loads": "files", "IntegrabilityReport": "integrability", "from_mechanics": "mechanics",
    "Trajectory": "simulate", "System": "system", "Classification": "transitions",
    "ModelComparison": "transitions", "classify": "transitions", "compare_models": "transitions",
}


def __getattr__(name: str) -> Any:
    if name not in _HOME:
        raise AttributeError(f"module 'chaplygin' has no attribute {name!r}")
    home = _HOME[name]
    value = import_module(f".{home or name}", __name__)
    value = value if not home else getattr(value, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_HOME])


__all__ = [
    "System",
    "Equations",
    "equivalent",
    "EquivalenceReport",
    "IntegrabilityReport",
    "compare_models",
    "ModelComparison",
    "classify",
    "Classification",
    "ChaplyginError",
    "SystemDefinitionError",
    "ModelError",
    "InputError",
    "ChaplyginWarning",
    "examples",
    "Trajectory",
    "compare",
    "from_mechanics",
    "load",
    "loads",
    "dumps",
    "SystemFile",
    "SystemFileError",
    "Comparison",
]

__version__ = "0.1.0"
