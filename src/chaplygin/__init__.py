"""chaplygin: equations of motion of nonholonomic systems, in both models of constrained motion.

The package is built in layers, each a folder that imports only the layers below it
(``docs/architecture.md``): ``core`` (the system description) → ``models`` (the
registry and the derivations) → ``analysis`` → ``numeric`` (code generation and
simulation) → ``io`` (files) → ``examples`` (the gallery) → ``apps`` (command line,
sweeps, reports).  This module is the front door: it re-exports the public names.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

from chaplygin._version import __version__

if TYPE_CHECKING:
    from chaplygin import examples
    from chaplygin.analysis.equivalence import EquivalenceReport, equivalent
    from chaplygin.analysis.integrability import IntegrabilityReport
    from chaplygin.analysis.transitions import (
        Classification,
        ModelComparison,
        classify,
        compare_models,
    )
    from chaplygin.apps.bodyview import show_rolling
    from chaplygin.bodies import (
        Disk,
        Ellipsoid,
        Paraboloid,
        Revolution,
        Sphere,
        SupportFunction,
        Torus,
        initial_state,
        motion,
        rolling_body,
    )
    from chaplygin.core.system import System
    from chaplygin.errors import (
        ChaplyginError,
        ChaplyginWarning,
        InputError,
        ModelError,
        SystemDefinitionError,
    )
    from chaplygin.io.files import SystemFile, SystemFileError, dumps, load, loads
    from chaplygin.io.mechanics import from_mechanics
    from chaplygin.models.equations import Equations
    from chaplygin.numeric.comparison import Comparison, compare
    from chaplygin.numeric.ensemble import Ensemble, simulate_ensemble
    from chaplygin.numeric.linearization import Linearization, linearize
    from chaplygin.numeric.simulate import Trajectory, simulate
    from chaplygin.numeric.stability import (
        RootLocus,
        Stability,
        SteadyMotion,
        root_locus,
        stability,
        stability_conditions,
        steady_motions,
    )

#: where each public name lives; imported on first use, so that ``import chaplygin``
#: (and the command line, whose cached answers need no SymPy) starts fast
_HOME = {
    "examples": "chaplygin.examples",
    "System": "chaplygin.core.system",
    **{
        name: "chaplygin.bodies"
        for name in (
            "Sphere",
            "Disk",
            "Torus",
            "Ellipsoid",
            "Paraboloid",
            "Revolution",
            "SupportFunction",
            "rolling_body",
            "initial_state",
            "motion",
        )
    },
    "Equations": "chaplygin.models.equations",
    "IntegrabilityReport": "chaplygin.analysis.integrability",
    "EquivalenceReport": "chaplygin.analysis.equivalence",
    "equivalent": "chaplygin.analysis.equivalence",
    "Classification": "chaplygin.analysis.transitions",
    "ModelComparison": "chaplygin.analysis.transitions",
    "classify": "chaplygin.analysis.transitions",
    "compare_models": "chaplygin.analysis.transitions",
    "simulate": "chaplygin.numeric.simulate",
    "Trajectory": "chaplygin.numeric.simulate",
    "simulate_ensemble": "chaplygin.numeric.ensemble",
    "Ensemble": "chaplygin.numeric.ensemble",
    "compare": "chaplygin.numeric.comparison",
    "Comparison": "chaplygin.numeric.comparison",
    "Linearization": "chaplygin.numeric.linearization",
    "linearize": "chaplygin.numeric.linearization",
    **{
        name: "chaplygin.numeric.stability"
        for name in (
            "RootLocus",
            "Stability",
            "SteadyMotion",
            "root_locus",
            "stability",
            "stability_conditions",
            "steady_motions",
        )
    },
    "from_mechanics": "chaplygin.io.mechanics",
    "show_rolling": "chaplygin.apps.bodyview",
    "SystemFile": "chaplygin.io._file",
    "SystemFileError": "chaplygin.io.files",
    "dumps": "chaplygin.io.files",
    "load": "chaplygin.io._file",
    "loads": "chaplygin.io.files",
    **{
        name: "chaplygin.errors"
        for name in (
            "ChaplyginError",
            "ChaplyginWarning",
            "InputError",
            "ModelError",
            "SystemDefinitionError",
        )
    },
}


def __getattr__(name: str) -> Any:
    if name not in _HOME:
        raise AttributeError(f"module 'chaplygin' has no attribute {name!r}")
    module = import_module(_HOME[name])
    value = module if module.__name__ == f"chaplygin.{name}" else getattr(module, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_HOME])


__all__ = [
    "ChaplyginError",
    "ChaplyginWarning",
    "Classification",
    "Comparison",
    "Disk",
    "Ellipsoid",
    "Ensemble",
    "Equations",
    "EquivalenceReport",
    "InputError",
    "IntegrabilityReport",
    "Linearization",
    "ModelComparison",
    "ModelError",
    "Paraboloid",
    "Revolution",
    "RootLocus",
    "Sphere",
    "Stability",
    "SteadyMotion",
    "SupportFunction",
    "System",
    "SystemDefinitionError",
    "SystemFile",
    "SystemFileError",
    "Torus",
    "Trajectory",
    "__version__",
    "classify",
    "compare",
    "compare_models",
    "dumps",
    "equivalent",
    "examples",
    "from_mechanics",
    "initial_state",
    "linearize",
    "load",
    "loads",
    "motion",
    "rolling_body",
    "root_locus",
    "show_rolling",
    "simulate",
    "simulate_ensemble",
    "stability",
    "stability_conditions",
    "steady_motions",
]
