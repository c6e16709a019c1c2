"""A fifth code target for tests/test_targets.py, written as docs/architecture.md says: one
module with a :class:`~chaplygin.numeric.targets.Target` named ``TARGET``.  It is the
generated Python module stepped by SciPy (the interface's defaults), and it records what the
entry points ask of it."""

from __future__ import annotations

from typing import Any

from chaplygin.numeric.targets import Target


class Traced(Target):
    """The defaults, each call recorded in :attr:`calls`."""

    name = "traced"
    ensemble_methods = ()

    def __init__(self) -> None:
        self.calls: list[str] = []

    def build(self, parts: Any) -> Any:
        self.calls.append("build")
        return super().build(parts)

    def integrate(self, compiled: Any, *args: Any, **kwargs: Any) -> Any:
        self.calls.append("integrate")
        return super().integrate(compiled, *args, **kwargs)

    def observe_run(self, compiled: Any, *args: Any) -> Any:
        self.calls.append("observe_run")
        return super().observe_run(compiled, *args)


TARGET = Traced()
