"""Cases shared by test modules: the rolling disk's and the knife edge's parameters and starts,
and the skip of a module that needs a C compiler."""

from __future__ import annotations

import pytest

from chaplygin.numeric._ckernel import Unavailable, compiler

DISK_P = {"m": 1.0, "r": 0.5, "A": 0.0625, "C": 0.125, "g": 9.81}
DISK_0 = {"psi": 0.0, "theta": 0.3, "phi": 0.0, "x": 0.0, "y": 0.0, "psi'": 2.0, "theta'": 0.0, "phi'": 5.0}
KNIFE_P = {"m": 1.0, "J": 0.5}
KNIFE_0 = [
    {"x": 0.0, "y": 0.0, "phi": 1.2, "x'": 1.0, "phi'": 1.0},  # φ = π/2 at t = π/2 − 1.2 ≈ 0.371
    {"x": 0.0, "y": 0.0, "phi": 0.1, "x'": 1.0, "phi'": 0.2},  # φ ≤ 0.3: never
]


def require_c_compiler() -> None:
    """Skip the calling test module (at its import) where no C compiler is found."""
    try:
        compiler()
    except Unavailable as exc:  # pragma: no cover - every CI machine has a C compiler
        pytest.skip(f"no C compiler: {exc}", allow_module_level=True)
