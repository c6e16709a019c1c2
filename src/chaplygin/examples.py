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


def rolling_disk(
    m: sp.Expr | float | None = None,
    r: sp.Expr | float | None = None,
    A: sp.Expr | float | None = None,
    C: sp.Expr | float | None = None,
    g: sp.Expr | float | None = None,
) -> System:
    """A thin disk rolling without slipping on a horizontal plane under gravity.

    The disk has mass ``m``, radius ``r`` and axisymmetric central inertia:
    ``A`` about any diameter, ``C`` about the symmetry axis (a uniform thin disk
    has ``A = m r²/4``, ``C = m r²/2``).  Gravity ``g`` acts along ``−z``.

    Conventions (the frame sequence of the rolling-disc example of
    ``sympy.physics.mechanics``): from the inertial frame ``N`` (``z`` up), turn
    by the heading ``ψ`` about ``N.z`` (frame ``Y``), lean by ``θ`` about ``Y.x``
    (frame ``L``; ``θ = 0`` is upright), spin by ``φ`` about the symmetry axis ``L.y`` (the disk).  The
    contact point is ``(x, y, 0)`` and the centre is ``r L.z`` above it, at height
    ``r cos θ``.  Angular velocity of the disk, in ``L``::

        ω = θ̇ L.x + (φ̇ + ψ̇ sin θ) L.y + ψ̇ cos θ L.z

    Rolling without slipping (the material point of the disk at the contact has
    zero velocity) makes the contact point move along the disk's horizontal
    diameter ``L.x = Y.x``::

        ẋ = r φ̇ cos ψ,   ẏ = r φ̇ sin ψ

    The kinetic energy is written unconstrained, for the centre
    ``(x + r sin θ sin ψ, y − r sin θ cos ψ, r cos θ)``::

        T = ½ m |v_G|² + ½ A (θ̇² + ψ̇² cos² θ) + ½ C (φ̇ + ψ̇ sin θ)²,
        v_G = (ẋ + r (θ̇ cos θ sin ψ + ψ̇ sin θ cos ψ),
               ẏ − r (θ̇ cos θ cos ψ − ψ̇ sin θ sin ψ),
               −r θ̇ sin θ)

    and ``V = m g r cos θ``.  T, V and the constraints are free of ``x, y``:
    this is a Chaplygin system, with non-integrable constraints.

    Parameters
    ----------
    m, r, A, C, g : optional
        Mass, radius, moments of inertia about a diameter and about the axis,
        and the gravitational acceleration; positive symbols of the same names
        by default.

    Returns
    -------
    System
        Coordinates ``[psi, theta, phi, x, y]``; dependent ``x, y``.

    References
    ----------
    Ju. I. Neimark and N. A. Fufaev, *Dynamics of Nonholonomic Systems*,
    AMS Translations of Mathematical Monographs 33, 1972 (the rolling disk is
    their recurring example).  O. M. O'Reilly, "The dynamics of rolling disks and
    sliding disks", *Nonlinear Dynamics* 10 (1996), 287–305.
    """
    psi, theta, phi, x, y = dynamicsymbols("psi theta phi x y")
    m_, r_, A_, C_, g_ = (
        _param(v, n) for v, n in ((m, "m"), (r, "r"), (A, "A"), (C, "C"), (g, "g"))
    )
    d = lambda q: q.diff(_t)  # noqa: E731
    s, c = sp.sin, sp.cos
    vg_x = d(x) + r_ * (d(theta) * c(theta) * s(psi) + d(psi) * s(theta) * c(psi))
    vg_y = d(y) - r_ * (d(theta) * c(theta) * c(psi) - d(psi) * s(theta) * s(psi))
    vg_z = -r_ * d(theta) * s(theta)
    T = (
        sp.Rational(1, 2) * m_ * (vg_x**2 + vg_y**2 + vg_z**2)
        + sp.Rational(1, 2) * A_ * (d(theta) ** 2 + d(psi) ** 2 * c(theta) ** 2)
        + sp.Rational(1, 2) * C_ * (d(phi) + d(psi) * s(theta)) ** 2
    )
    constraints = {
        d(x): r_ * d(phi) * c(psi),
        d(y): r_ * d(phi) * s(psi),
    }
    return System(
        [psi, theta, phi, x, y],
        T,
        constraints,
        potential_energy=m_ * g_ * r_ * c(theta),
        name="Disk rolling on a horizontal plane",
    )
