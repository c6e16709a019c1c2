"""Worked examples: the seed paper's sphere and a few classic nonholonomic systems.

Each constructor returns a :class:`~chaplygin.System` built from SymPy objects;
parameters are plain symbols (mass ``m``, radius ``a`` …) that the caller may
replace with numbers by passing them as arguments.
"""

from __future__ import annotations

from collections.abc import Mapping

import sympy as sp
from sympy.physics.mechanics import dynamicsymbols

from ._symbols import TIME
from .system import System

__all__ = [
    "rolling_sphere",
    "knife_edge",
    "vertical_rolling_disk",
    "rolling_disk",
    "integrating_factor_example",
    "closed_form_example",
]

_t = TIME


def _param(value: sp.Expr | float | None, name: str) -> sp.Expr:
    if value is None:
        return sp.Symbol(name, positive=True)
    return value if isinstance(value, sp.Basic) else sp.nsimplify(value)


def rolling_sphere(
    m: sp.Expr | float | None = None,
    a: sp.Expr | float | None = None,
    *,
    forces: Mapping[str, sp.Expr] | None = None,
) -> System:
    """The paper's §4 example: a homogeneous sphere rolling on a rough horizontal plane.

    Coordinates ``ψ, θ, φ`` (Euler angles: precession, nutation, spin) and the
    centre's ``x, y``; rolling without slipping, eqs. (41)-(42)::

        ẋ = −a (φ̇ sin θ cos ψ − θ̇ sin ψ),   ẏ = −a (φ̇ sin θ sin ψ + θ̇ cos ψ)

    and the kinetic energy (47)
    ``T = ½ m (ẋ² + ẏ²) + ⅕ m a² (θ̇² + φ̇² + ψ̇² + 2 ψ̇ φ̇ cos θ)``
    (moment of inertia ``⅖ m a²`` about every axis through the centre).

    Parameters
    ----------
    m, a : optional
        Mass and radius; positive symbols ``m`` and ``a`` by default.
    forces : mapping, optional
        External generalized forces by coordinate name, e.g.
        ``{"x": F_x, "y": F_y}`` for a horizontal force on the centre. Free of
        external forces by default, as in the paper.
    """
    psi, theta, phi, x, y = dynamicsymbols("psi theta phi x y")
    m_, a_ = _param(m, "m"), _param(a, "a")
    d = lambda q: q.diff(_t)  # noqa: E731
    T = sp.Rational(1, 2) * m_ * (d(x) ** 2 + d(y) ** 2) + sp.Rational(1, 5) * m_ * a_**2 * (
        d(theta) ** 2 + d(phi) ** 2 + d(psi) ** 2 + 2 * d(psi) * d(phi) * sp.cos(theta)
    )
    constraints = {
        d(x): -a_ * (d(phi) * sp.sin(theta) * sp.cos(psi) - d(theta) * sp.sin(psi)),
        d(y): -a_ * (d(phi) * sp.sin(theta) * sp.sin(psi) + d(theta) * sp.cos(psi)),
    }
    return System(
        [psi, theta, phi, x, y],
        T,
        constraints,
        forces=dict(forces) if forces else None,
        name="Homogeneous sphere on a rough plane",
    )


def knife_edge(
    m: sp.Expr | float | None = None, J: sp.Expr | float | None = None
) -> System:
    """A knife edge (skate) on a horizontal plane: ``ẏ = ẋ tan φ``.

    Coordinates ``x, y`` (contact point) and heading ``φ``;
    ``T = ½ m (ẋ² + ẏ²) + ½ J φ̇²``.  The classic non-integrable constraint
    (Neimark & Fufaev, *Dynamics of Nonholonomic Systems*, 1972, ch. I).
    """
    x, y, phi = dynamicsymbols("x y phi")
    m_, J_ = _param(m, "m"), _param(J, "J")
    T = sp.Rational(1, 2) * m_ * (x.diff(_t) ** 2 + y.diff(_t) ** 2) + sp.Rational(1, 2) * J_ * phi.diff(_t) ** 2
    return System(
        [x, y, phi], T, [sp.sin(phi) * x.diff(_t) - sp.cos(phi) * y.diff(_t)], dependent=[y],
        name="Knife edge",
    )


def vertical_rolling_disk(
    m: sp.Expr | float | None = None,
    R: sp.Expr | float | None = None,
    I: sp.Expr | float | None = None,  # noqa: E741
    J: sp.Expr | float | None = None,
) -> System:
    """A disk rolling upright on a plane (Bloch, *Nonholonomic Mechanics and Control*, §1.4).

    Coordinates: spin ``θ``, heading ``φ``, contact point ``x, y``;
    ``T = ½ m (ẋ² + ẏ²) + ½ I θ̇² + ½ J φ̇²``, ``ẋ = R θ̇ cos φ``, ``ẏ = R θ̇ sin φ``.
    """
    theta, phi, x, y = dynamicsymbols("theta phi x y")
    m_, R_, I_, J_ = (_param(v, n) for v, n in ((m, "m"), (R, "R"), (I, "I"), (J, "J")))
    d = lambda q: q.diff(_t)  # noqa: E731
    T = sp.Rational(1, 2) * (m_ * (d(x) ** 2 + d(y) ** 2) + I_ * d(theta) ** 2 + J_ * d(phi) ** 2)
    return System(
        [theta, phi, x, y], T,
        {d(x): R_ * sp.cos(phi) * d(theta), d(y): R_ * sp.sin(phi) * d(theta)},
        name="Vertical rolling disk",
    )
