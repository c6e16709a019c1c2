"""chaplygin: equations of motion of nonholonomic systems, in both models of constrained motion."""

from __future__ import annotations

from . import examples
from .equations import Equations
from .compare import Comparison, compare
from .equivalence import EquivalenceReport, equivalent
from .files import SystemFile, SystemFileError, dumps, load, loads
from .mechanics import from_mechanics
from .simulate import Trajectory
from .integrability import IntegrabilityReport
from .errors import ChaplyginError, ModelError, SystemDefinitionError
from .system import System
from .transitions import Classification, ModelComparison, classify, compare_models

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
