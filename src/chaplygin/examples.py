"""Worked examples: the seed paper's sphere and a few classic nonholonomic systems.

Each constructor returns a :class:`~chaplygin.System` built from SymPy objects;
parameters are plain symbols (mass ``m``, radius ``a`` …) that the caller may
replace with numbers by passing them as arguments.

:func:`catalogue` lists them by name (``rolling-sphere``, ``knife-edge``,
``vertical-rolling-disk``, ``rolling-disk``, ``chaplygin-sleigh``,
``turntable-ball``, ``chaplygin-ball``, ``heisenberg``, ``contact-oscillator``,
``differential-drive``, ``sleigh-chain``, ``whipple-bicycle``, the rigid bodies built by
:mod:`chaplygin.bodies`: ``lindelof-problem``, ``routh-sphere``, ``rattleback``, and two
constraints nonlinear in the velocities: ``appell-weight``, ``isokinetic-particle``)
with a description, default
parameter values and an initial state; :func:`get` looks one up.  Each has a
page in the documentation's gallery (``docs/gallery/<name>.md``) with what is
known about it and the sources.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Callable, Mapping
from typing import NamedTuple

import sympy as sp
from sympy.physics.mechanics import Point, ReferenceFrame, RigidBody, dynamicsymbols, inertia

from chaplygin.bodies import Disk, Ellipsoid, RollingBody, Sphere, rolling_body
from chaplygin.core._symbols import TIME
from chaplygin.core.system import System
from chaplygin.errors import ChaplyginError
from chaplygin.io.mechanics import from_mechanics

__all__ = [
    "WHIPPLE_BENCHMARK",
    "ExampleEntry",
    "appell_weight",
    "catalogue",
    "chaplygin_ball",
    "chaplygin_sleigh",
    "contact_oscillator",
    "differential_drive",
    "get",
    "heisenberg",
    "isokinetic_particle",
    "knife_edge",
    "lindelof_problem",
    "rattleback",
    "rolling_disk",
    "rolling_sphere",
    "routh_sphere",
    "sleigh_chain",
    "turntable_ball",
    "vertical_rolling_disk",
    "whipple_bicycle",
    "whipple_pitch_relation",
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


def knife_edge(m: sp.Expr | float | None = None, J: sp.Expr | float | None = None) -> System:
    """A knife edge (skate) on a horizontal plane: ``ẏ = ẋ tan φ``.

    Coordinates ``x, y`` (contact point) and heading ``φ``;
    ``T = ½ m (ẋ² + ẏ²) + ½ J φ̇²``.  The classic non-integrable constraint
    (Neimark & Fufaev, *Dynamics of Nonholonomic Systems*, 1972).  See
    ``docs/gallery/knife-edge.md``.
    """
    x, y, phi = dynamicsymbols("x y phi")
    m_, J_ = _param(m, "m"), _param(J, "J")
    T = (
        sp.Rational(1, 2) * m_ * (x.diff(_t) ** 2 + y.diff(_t) ** 2)
        + sp.Rational(1, 2) * J_ * phi.diff(_t) ** 2
    )
    return System(
        [x, y, phi],
        T,
        [sp.sin(phi) * x.diff(_t) - sp.cos(phi) * y.diff(_t)],
        dependent=[y],
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
    See ``docs/gallery/vertical-rolling-disk.md``.
    """
    theta, phi, x, y = dynamicsymbols("theta phi x y")
    m_, R_, I_, J_ = (_param(v, n) for v, n in ((m, "m"), (R, "R"), (I, "I"), (J, "J")))
    d = lambda q: q.diff(_t)  # noqa: E731
    T = sp.Rational(1, 2) * (m_ * (d(x) ** 2 + d(y) ** 2) + I_ * d(theta) ** 2 + J_ * d(phi) ** 2)
    return System(
        [theta, phi, x, y],
        T,
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
    this is a Chaplygin system, with non-integrable constraints.  A coin, a hoop
    or any body of revolution rolling on a circular edge centred at its centre
    of mass (Lindelöf's problem); steady motions and their stability are on
    ``docs/gallery/rolling-disk.md``.

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
    sliding disks", *Nonlinear Dynamics* 10 (1996), 287–305.  E. J. Routh, *The
    Advanced Part of a Treatise on the Dynamics of a System of Rigid Bodies*,
    1905, art. 244.
    """
    psi, theta, phi, x, y = dynamicsymbols("psi theta phi x y")
    m_, r_, A_, C_, g_ = (_param(v, n) for v, n in ((m, "m"), (r, "r"), (A, "A"), (C, "C"), (g, "g")))
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


# ---------------------------------------------------------------------- gallery
def _d(q: sp.Expr) -> sp.Expr:
    return q.diff(_t)


def _space_omega(psi: sp.Expr, theta: sp.Expr, phi: sp.Expr) -> sp.Matrix:
    """Space components of the angular velocity for z-x-z Euler angles (ψ, θ, φ)."""
    return sp.Matrix(
        [
            _d(theta) * sp.cos(psi) + _d(phi) * sp.sin(theta) * sp.sin(psi),
            _d(theta) * sp.sin(psi) - _d(phi) * sp.sin(theta) * sp.cos(psi),
            _d(psi) + _d(phi) * sp.cos(theta),
        ]
    )


def chaplygin_sleigh(
    m: sp.Expr | float | None = None,
    I: sp.Expr | float | None = None,  # noqa: E741
    a: sp.Expr | float | None = None,
) -> System:
    """The Chaplygin sleigh: a body on a knife edge at (x, y), centre of mass a ahead of it.

    ``T = ½ m (ẋ² + ẏ²) + m a θ̇ (−ẋ sin θ + ẏ cos θ) + ½ (I + m a²) θ̇²`` with the
    knife-edge constraint ``−ẋ sin θ + ẏ cos θ = 0`` (dependent ``y``; the split
    ``ẏ = tan θ ẋ`` has a pole at ``θ = ±π/2``).  With the forward speed v and
    ω = θ̇: ``v̇ = a ω²``, ``ω̇ = −m a v ω / (I + m a²)``; the sleigh ends up
    moving straight.  See ``docs/gallery/chaplygin-sleigh.md``.

    Parameters
    ----------
    m, I, a : optional
        Mass, moment of inertia about the centre of mass, distance of the
        centre of mass ahead of the knife edge; positive symbols by default.

    References
    ----------
    S. A. Chaplygin, "On the theory of motion of nonholonomic systems. The
    theorem on the reducing multiplier", *Mat. Sbornik* 28(2), 1911 (English:
    *Regular and Chaotic Dynamics* 13(4), 2008, 369–376).  A. M. Bloch,
    *Nonholonomic Mechanics and Control*, Springer, 2003, §1.7.
    """
    x, y, th = dynamicsymbols("x y theta")
    m_, I_, a_ = _param(m, "m"), _param(I, "I"), _param(a, "a")
    T = m_ / 2 * (_d(x) ** 2 + _d(y) ** 2) + m_ * a_ * _d(th) * (-_d(x) * sp.sin(th) + _d(y) * sp.cos(th))
    T += (I_ + m_ * a_**2) / 2 * _d(th) ** 2
    return System(
        [x, y, th], T, [-sp.sin(th) * _d(x) + sp.cos(th) * _d(y)], dependent=[y], name="Chaplygin sleigh"
    )


def turntable_ball(
    m: sp.Expr | float | None = None,
    a: sp.Expr | float | None = None,
    Omega: sp.Expr | float | None = None,
) -> System:
    """A homogeneous ball rolling on a turntable spinning at the constant rate Ω.

    Euler angles ``ψ, θ, φ`` (z-x-z, as :func:`rolling_sphere`) and the centre
    ``x, y``; ``T = ½ m (ẋ² + ẏ²) + ⅕ m a² |ω|²``.  The contact point moves with
    the table: ``ẋ = a ω_y − Ω y``, ``ẏ = −a ω_x + Ω x`` (affine constraints whose
    B_0 depends on the dependent x, y: Voronets' case, no Lindelöf equations).
    The centre moves on a circle with angular frequency 2Ω/7; the energy is not
    conserved, ``E − Ω L_z`` is.  See ``docs/gallery/turntable-ball.md``.

    Parameters
    ----------
    m, a, Omega : optional
        Mass and radius of the ball, rate of the table; positive symbols by default.

    References
    ----------
    K. Weltner, "Stable circular orbits of freely moving balls on rotating
    discs", *Am. J. Phys.* 47, 1979, 984–986.  W. Weckesser, "A ball rolling on
    a freely spinning turntable", *Am. J. Phys.* 65, 1997, 736–738.  F. Fassò
    and N. Sansonetto, "Conservation of 'moving' energy in nonholonomic systems
    with affine constraints and integrability of spheres on rotating surfaces",
    *J. Nonlinear Sci.* 26, 2016, 519–544.
    """
    psi, theta, phi, x, y = dynamicsymbols("psi theta phi x y")
    m_, a_, W = _param(m, "m"), _param(a, "a"), _param(Omega, "Omega")
    w = _space_omega(psi, theta, phi)
    T = m_ / 2 * (_d(x) ** 2 + _d(y) ** 2) + sp.Rational(1, 5) * m_ * a_**2 * sp.trigsimp(sp.expand(w.dot(w)))
    return System(
        [psi, theta, phi, x, y],
        T,
        {_d(x): a_ * w[1] - W * y, _d(y): -a_ * w[0] + W * x},
        name="Ball on a rotating turntable",
    )


def chaplygin_ball(
    m: sp.Expr | float | None = None,
    a: sp.Expr | float | None = None,
    A: sp.Expr | float | None = None,
    B: sp.Expr | float | None = None,
    C: sp.Expr | float | None = None,
) -> System:
    """Chaplygin's ball: centre of mass at the geometric centre, principal moments A, B, C.

    Euler angles ``ψ, θ, φ`` (z-x-z) and the centre ``x, y``; rolls on a plane
    with the paper's sphere's constraints.  The energy and the angular momentum
    about the contact point, ``I ω + m a² (ω − ω_z e_z)``, are constant.  See
    ``docs/gallery/chaplygin-ball.md``.

    Parameters
    ----------
    m, a, A, B, C : optional
        Mass, radius, principal central moments of inertia; positive symbols by default.

    References
    ----------
    S. A. Chaplygin, "On a ball's rolling on a horizontal plane", *Mat.
    Sbornik* 24, 1903, 139–168 (English: *Regular and Chaotic Dynamics* 7(2),
    2002, 131–148).  A. V. Borisov and I. S. Mamaev, "Rolling of a rigid body on
    plane and sphere. Hierarchy of dynamics", *Regular and Chaotic Dynamics*
    7(2), 2002, 177–200.
    """
    psi, theta, phi, x, y = dynamicsymbols("psi theta phi x y")
    m_, a_, A_, B_, C_ = (_param(v, n) for v, n in ((m, "m"), (a, "a"), (A, "A"), (B, "B"), (C, "C")))
    body = sp.Matrix(
        [
            _d(psi) * sp.sin(theta) * sp.sin(phi) + _d(theta) * sp.cos(phi),
            _d(psi) * sp.sin(theta) * sp.cos(phi) - _d(theta) * sp.sin(phi),
            _d(psi) * sp.cos(theta) + _d(phi),
        ]
    )
    T = m_ / 2 * (_d(x) ** 2 + _d(y) ** 2) + (A_ * body[0] ** 2 + B_ * body[1] ** 2 + C_ * body[2] ** 2) / 2
    w = _space_omega(psi, theta, phi)
    return System([psi, theta, phi, x, y], T, {_d(x): a_ * w[1], _d(y): -a_ * w[0]}, name="Chaplygin ball")


def heisenberg() -> System:
    """The Heisenberg (Brockett) system: ``ż = (x ẏ − y ẋ)/2``, ``T = ½ (ẋ² + ẏ²)``.

    True motions are straight lines; vakonomic motions are circles, the
    sub-Riemannian geodesics, along which ``z`` gains the enclosed area.  See
    ``docs/gallery/heisenberg.md``.

    References
    ----------
    R. W. Brockett, "Control theory and singular Riemannian geometry", in
    *New Directions in Applied Mathematics*, Springer, 1981, 11–27.
    R. Montgomery, *A Tour of Subriemannian Geometries, Their Geodesics and
    Applications*, AMS, 2002, ch. 1.
    """
    x, y, z = dynamicsymbols("x y z")
    return System(
        [x, y, z],
        (_d(x) ** 2 + _d(y) ** 2) / 2,
        {_d(z): (x * _d(y) - y * _d(x)) / 2},
        name="Heisenberg system",
    )


def contact_oscillator(eps: sp.Expr | float | None = None) -> System:
    """The contact oscillator ``ẋ + y ż = 0``, ``H = ½|v|² + ½|q|² + ½ ε x² z²``.

    Dependent ``x``; the potential depends on it, so this is a Voronets system
    (no Lindelöf equations).  ``y`` is a harmonic oscillator for every ε.  See
    ``docs/gallery/contact-oscillator.md``.

    Parameters
    ----------
    eps : optional
        The coupling ε, parameter ``epsilon``; a positive symbol by default.

    References
    ----------
    R. I. McLachlan and M. Perlmutter, "Integrators for nonholonomic
    mechanical systems", *J. Nonlinear Sci.* 16, 2006, 283–328 (nonholonomic
    test problems for integrators).
    """
    x, y, z = dynamicsymbols("x y z")
    e = _param(eps, "epsilon")
    return System(
        [x, y, z],
        (_d(x) ** 2 + _d(y) ** 2 + _d(z) ** 2) / 2,
        {_d(x): -y * _d(z)},
        potential_energy=(x**2 + y**2 + z**2) / 2 + e * x**2 * z**2 / 2,
        name="Contact oscillator",
    )


def differential_drive(
    m: sp.Expr | float | None = None,
    I: sp.Expr | float | None = None,  # noqa: E741
    J: sp.Expr | float | None = None,
    r: sp.Expr | float | None = None,
    b: sp.Expr | float | None = None,
) -> System:
    """A differential-drive robot: wheels of radius r at ±b on an axle through the centre of mass.

    Coordinates x, y, θ and the wheel angles φ_L, φ_R (dependent ``x, y, θ``);
    ``ẋ = v cos θ``, ``ẏ = v sin θ``, ``θ̇ = ω`` with ``v = r (φ̇_R + φ̇_L)/2``,
    ``ω = r (φ̇_R − φ̇_L)/(2b)``; ``T = ½ m (ẋ² + ẏ²) + ½ I θ̇² + ½ J (φ̇_L² + φ̇_R²)``.
    Free of torques, the wheels keep their speeds.  See
    ``docs/gallery/differential-drive.md``.

    Parameters
    ----------
    m, I, J, r, b : optional
        Mass, moment of inertia about the vertical, each wheel's moment of
        inertia about the axle, wheel radius, half the track; positive symbols
        by default.

    References
    ----------
    R. Siegwart and I. R. Nourbakhsh, *Introduction to Autonomous Mobile
    Robots*, MIT Press, 2004, ch. 3 (mobile robot kinematics).
    """
    x, y, th, pl, pr = dynamicsymbols("x y theta phi_L phi_R")
    m_, I_, J_, r_, b_ = (_param(v, n) for v, n in ((m, "m"), (I, "I"), (J, "J"), (r, "r"), (b, "b")))
    v, w = r_ / 2 * (_d(pr) + _d(pl)), r_ / (2 * b_) * (_d(pr) - _d(pl))
    T = m_ / 2 * (_d(x) ** 2 + _d(y) ** 2) + I_ / 2 * _d(th) ** 2 + J_ / 2 * (_d(pl) ** 2 + _d(pr) ** 2)
    return System(
        [x, y, th, pl, pr],
        T,
        {_d(x): v * sp.cos(th), _d(y): v * sp.sin(th), _d(th): w},
        name="Differential-drive robot",
    )


def sleigh_chain(
    n: int,
    m: sp.Expr | float | None = None,
    I: sp.Expr | float | None = None,  # noqa: E741
    L: sp.Expr | float | None = None,
) -> System:
    """A knife-edge sleigh at (x, y) pulling ``n`` sleighs, each hitched at distance L behind the last.

    Body ``i`` has heading ``θ_i`` and its knife edge at
    ``p_i = (x, y) − L Σ_{j=1..i} (cos θ_j, sin θ_j)``, hitched to the knife
    edge of body ``i − 1``; every body has mass m at its knife edge and moment
    of inertia I about it, and its knife edge forbids sideways motion::

        T = Σ_i [½ m |ṗ_i|² + ½ I θ̇_i²],
        −sin θ_i ẋ + cos θ_i ẏ − L Σ_{j=1..i} θ̇_j cos(θ_j − θ_i) = 0   (i = 0 … n)

    n + 3 coordinates ``x, y, θ_0 … θ_n`` and n + 1 constraints (dependent
    ``y, θ_1 … θ_n``): the scalable system for benchmarks.  Its kinematics are
    those of the standard N-trailer (D. Tilbury, R. M. Murray and S. S. Sastry,
    "Trajectory generation for the N-trailer problem using Goursat normal
    form", *IEEE Trans. Automatic Control* 40(5), 1995, 802–819).

    Raises
    ------
    ValueError
        If ``n`` is not a non-negative integer.
    """
    if not isinstance(n, int) or n < 0:
        raise ValueError(f"sleigh_chain: n must be a non-negative integer, got {n!r}.")
    x, y = dynamicsymbols("x y")
    th = list(dynamicsymbols(f"theta0:{n + 1}"))
    m_, I_, L_ = _param(m, "m"), _param(I, "I"), _param(L, "L")
    # T summed body by body (the docstring's form), written out term by term: body i
    # contributes to θ_j's terms for every j ≤ i, so the coefficients count those bodies
    dx, dy, dth = _d(x), _d(y), [_d(tj) for tj in th]
    # (already expanded: SymPy's expand of the sum costs more than building it; each
    # cos(θ_j − θ_k) is built once, as SymPy's evaluation of it is the costly part)
    cos = {(j, k): sp.cos(th[j] - th[k]) for k in range(1, n + 1) for j in range(1, k + 1)}
    terms = [m_ * (n + 1) / 2 * dx**2, m_ * (n + 1) / 2 * dy**2, *(I_ / 2 * w**2 for w in dth)]
    for j in range(1, n + 1):
        terms.append(m_ * L_ * (n + 1 - j) * dth[j] * dx * sp.sin(th[j]))
        terms.append(-m_ * L_ * (n + 1 - j) * dth[j] * dy * sp.cos(th[j]))
        terms.append(m_ * L_**2 * (n + 1 - j) / 2 * dth[j] ** 2)
        for k in range(j + 1, n + 1):
            terms.append(m_ * L_**2 * (n + 1 - k) * dth[j] * dth[k] * cos[j, k])
    T = sp.Add(*terms)
    cons = [
        -sp.sin(ti) * dx + sp.cos(ti) * dy - L_ * sp.Add(*(dth[j] * cos[j, i] for j in range(1, i + 1)))
        for i, ti in enumerate(th)
    ]
    return System([x, y, *th], T, cons, dependent=[y, *th[1:]], name=f"Chain of {n + 1} sleighs")


def _sleigh_chain_2() -> System:
    """``sleigh_chain(2)``: a lead sleigh pulling two sleighs (the catalogue's ``sleigh-chain``)."""
    return sleigh_chain(2)


# ---------------------------------------------------------------- rigid bodies from their shape
def lindelof_problem(
    m: sp.Expr | float | None = None,
    r: sp.Expr | float | None = None,
    A: sp.Expr | float | None = None,
    C: sp.Expr | float | None = None,
    g: sp.Expr | float | None = None,
) -> RollingBody:
    """Lindelöf's body of revolution, built from its shape: ``rolling_body(Disk(r), mass=m, inertia=[A, A, C], g=g)``.

    A thin disk (or hoop) of mass ``m`` and radius ``r``, central moments ``A`` about a diameter
    and ``C`` about the axis, rolling without slipping on a horizontal plane under gravity.
    The ``"edge"`` angles of :func:`chaplygin.bodies.rolling_body`: heading ``ψ``, lean ``θ``
    (0 upright; singular where the disk lies flat), spin ``φ``; ``x, y`` are the centre of mass
    (the centre). The same dynamics as :func:`rolling_disk`, whose ``x, y`` are the contact
    point, and a :class:`~chaplygin.bodies.RollingBody`, so :func:`chaplygin.bodies.motion`
    works on its runs. Lindelöf (1895) substituted the rolling constraints into T for this body;
    Chaplygin (1897) showed that this gives a different motion. See
    ``docs/gallery/lindelof-problem.md``.

    Parameters
    ----------
    m, r, A, C, g : optional
        Mass, radius, moments of inertia about a diameter and about the axis, gravity;
        positive symbols of the same names by default.

    References
    ----------
    E. Lindelöf, "Sur le mouvement d'un corps de révolution roulant sur un plan horizontal",
    *Acta Societatis Scientiarum Fennicae* 20(10), 1895.  S. A. Chaplygin, "On a motion of a
    heavy body of revolution on a horizontal plane", 1897 (English: *Regular and Chaotic
    Dynamics* 7(2), 2002, 119–130).
    """
    m_, r_, A_, C_, g_ = (_param(v, n) for v, n in ((m, "m"), (r, "r"), (A, "A"), (C, "C"), (g, "g")))
    return rolling_body(
        Disk(r_), mass=m_, inertia=[A_, A_, C_], g=g_, name="Lindelöf's body of revolution (a disk)"
    )


def routh_sphere(
    r: sp.Expr | float | None = None,
    a: sp.Expr | float | None = None,
    m: sp.Expr | float | None = None,
    A: sp.Expr | float | None = None,
    C: sp.Expr | float | None = None,
    g: sp.Expr | float | None = None,
) -> RollingBody:
    """Routh's sphere: a ball whose centre of mass is ``a`` below its centre on an axis of symmetry.

    ``rolling_body(Sphere(r), mass=m, inertia=[A, A, C], center_of_mass=(0, 0, −a), g=g)``:
    radius ``r``, central moments ``A, A, C``, rolling without slipping on a horizontal plane
    under gravity. Cardan angles ``ψ, θ, φ`` (rest ``R = 1`` is regular; singular where the
    shape's y axis is vertical) and the centre of mass ``x, y``. Besides the energy, Jellett's
    integral ``(I ω)·s`` and Routh's integral ``ω₃ √(A C + m A (s₁² + s₂²) + m C s₃²)`` are
    constant (``s`` from the contact point to the centre of mass, body axes). See
    ``docs/gallery/routh-sphere.md``.

    Parameters
    ----------
    r, a, m, A, C, g : optional
        Radius, offset of the centre of mass below the centre, mass, central moments about a
        diameter and about the axis, gravity; positive symbols of the same names by default.

    References
    ----------
    E. J. Routh, *The Advanced Part of a Treatise on the Dynamics of a System of Rigid
    Bodies*, 6th ed., 1905.  C. G. Gray and B. G. Nickel, "Constants of the motion for
    nonslipping tippe tops and other tops with round pegs", *Am. J. Phys.* 68(9), 2000,
    821–828.  A. V. Borisov and I. S. Mamaev, "Rolling of a rigid body on plane and sphere.
    Hierarchy of dynamics", *Regular and Chaotic Dynamics* 7(2), 2002, 177–200.
    """
    r_, a_, m_, A_, C_, g_ = (
        _param(v, n) for v, n in ((r, "r"), (a, "a"), (m, "m"), (A, "A"), (C, "C"), (g, "g"))
    )
    return rolling_body(
        Sphere(r_), mass=m_, inertia=[A_, A_, C_], center_of_mass=(0, 0, -a_), g=g_, name="Routh's sphere"
    )


def rattleback(
    a: sp.Expr | float | None = None,
    b: sp.Expr | float | None = None,
    c: sp.Expr | float | None = None,
    h: sp.Expr | float | None = None,
    m: sp.Expr | float | None = None,
    A: sp.Expr | float | None = None,
    B: sp.Expr | float | None = None,
    C: sp.Expr | float | None = None,
    D: sp.Expr | float | None = None,
    g: sp.Expr | float | None = None,
) -> RollingBody:
    """The rattleback (celt) of Kane & Levinson (1982), built from its shape.

    An ellipsoid with semi-axes ``a, b, c`` along the body's x, y, z, the centre of mass ``h``
    below its centre, central inertia ``m [[A, D, 0], [D, B, 0], [0, 0, C]]`` (``A, B, C, D``
    per unit mass: the principal axes of inertia are turned from the shape's by the product
    ``D``), rolling without slipping on a horizontal plane under gravity::

        rolling_body(Ellipsoid(a, b, c), mass=m, center_of_mass=(0, 0, −h), g=g,
                     inertia=[[m A, m D, 0], [m D, m B, 0], [0, 0, m C]])

    Cardan angles ``ψ, θ, φ`` (rest ``R = 1`` is regular) and the centre of mass ``x, y``.
    Kane & Levinson's numbers (catalogue defaults) are ``a = 0.2``, ``b = 0.03``,
    ``c = 0.02``, ``h = 0.01`` m, ``m = 1`` kg, ``A = 2·10⁻⁴``, ``B = 1.6·10⁻³``,
    ``C = 1.7·10⁻³``, ``D = −2·10⁻⁵`` m² in their axes with z down; a half turn about x brings
    z up and flips the sign of ``D``, so the default here is ``D = +2·10⁻⁵``. Spun about the
    vertical with ``n D > 0`` it rocks and reverses within a few seconds; with ``n D < 0`` it
    keeps its sense much longer. See ``docs/gallery/rattleback.md``.

    Parameters
    ----------
    a, b, c, h, m, A, B, C, g : optional
        Semi-axes, offset of the centre of mass, mass, moments per unit mass, gravity;
        positive symbols of the same names by default.
    D : optional
        Product of inertia per unit mass; a real symbol ``D`` by default.

    References
    ----------
    T. R. Kane and D. A. Levinson, "Realistic mathematical modeling of the rattleback",
    *Int. J. Non-Linear Mechanics* 17(3), 1982, 175–186.  A. Garcia and M. Hubbard, "Spin
    reversal of the rattleback: theory and experiment", *Proc. R. Soc. A* 418, 1988, 165–197.
    """
    a_, b_, c_, h_, m_, A_, B_, C_, g_ = (
        _param(v, n)
        for v, n in ((a, "a"), (b, "b"), (c, "c"), (h, "h"), (m, "m"), (A, "A"), (B, "B"), (C, "C"), (g, "g"))
    )
    D_ = sp.Symbol("D", real=True) if D is None else _param(D, "D")
    return rolling_body(
        Ellipsoid(a_, b_, c_),
        mass=m_,
        inertia=[[m_ * A_, m_ * D_, 0], [m_ * D_, m_ * B_, 0], [0, 0, m_ * C_]],
        center_of_mass=(0, 0, -h_),
        g=g_,
        name="Rattleback (Kane & Levinson 1982)",
    )


# ------------------------------------------------- constraints nonlinear in the velocities
def appell_weight(
    m: sp.Expr | float | None = None,
    g: sp.Expr | float | None = None,
    k: sp.Expr | float | None = None,
    *,
    rising: bool = False,
) -> System:
    """Appell's example, reduced to a point mass: ``ż² = k² (ẋ² + ẏ²)``, ``V = m g z``.

    Appell's weight hangs on a thread wound on the drum (radius ``a``) of a wheel (radius
    ``b``) that rolls on a horizontal plane: the weight's vertical speed is ``k = a/b`` times
    the horizontal speed of the wheel, whatever its direction. Neimark & Fufaev (ch. III)
    reduce it to a point of mass ``m`` at ``(x, y, z)`` with ``T = ½ m (ẋ² + ẏ² + ż²)``, the
    potential ``m g z`` and the constraint ``ż² − k² (ẋ² + ẏ²) = 0``, dependent ``z``: the
    first mechanical constraint nonlinear in the velocities. It has two solutions for ``ż``;
    ``branch=0``, ``ż = −k √(ẋ² + ẏ²)``, the weight falling and driving the wheel (default),
    or ``branch=1``, ``ż = +k √(ẋ² + ẏ²)``, the wheel lifting it (``rising=True``). Both are
    singular where ``ẋ² + ẏ² = 0``. The true motion runs on a straight line with
    ``v̇ = −σ g k/(1 + k²)`` (``σ = ±1`` the branch's sign). See
    ``docs/gallery/appell-weight.md``.

    Parameters
    ----------
    m, g, k : optional
        Mass, gravity, ratio ``k = a/b`` of the drum's radius to the wheel's; positive
        symbols ``m``, ``g``, ``k`` by default.
    rising : bool
        Take the branch ``ż = +k √(ẋ² + ẏ²)`` (the weight rising) instead of the falling one.

    References
    ----------
    P. Appell, "Exemple de mouvement d'un point assujetti à une liaison exprimée par une
    relation non linéaire entre les composantes de la vitesse", *C. R. Acad. Sci. Paris* 152,
    1911, 1197–1199.  Ju. I. Neimark and N. A. Fufaev, *Dynamics of Nonholonomic Systems*,
    AMS, 1972, ch. III.
    """
    x, y, z = dynamicsymbols("x y z")
    m_, g_, k_ = (_param(v, n) for v, n in ((m, "m"), (g, "g"), (k, "k")))
    return System(
        [x, y, z],
        m_ / 2 * (_d(x) ** 2 + _d(y) ** 2 + _d(z) ** 2),
        [_d(z) ** 2 - k_**2 * (_d(x) ** 2 + _d(y) ** 2)],
        dependent=[z],
        branch=1 if rising else 0,
        potential_energy=m_ * g_ * z,
        name="Appell's weight",
    )


def isokinetic_particle(
    m: sp.Expr | float | None = None,
    g: sp.Expr | float | None = None,
    v: sp.Expr | float | None = None,
) -> System:
    """A particle kept at the speed ``v`` in a uniform field: ``ẋ² + ẏ² = v²``, ``V = m g y``.

    Gauss's isokinetic thermostat (Hoover et al. 1982; Evans et al. 1983; Evans & Morriss): the constraint
    force of the Chetaev model is along the velocity and removes the work of gravity. Dependent
    ``x`` on the branch ``ẋ = +√(v² − ẏ²)`` (singular where ``ẏ² = v²``). The true motion runs
    on the grim reaper ``y = y₀ + a ln cos((x − x₀)/a)``, ``a = v²/g``; the vakonomic motions
    on catenaries. See ``docs/gallery/isokinetic-particle.md``.

    Parameters
    ----------
    m, g, v : optional
        Mass, field strength and the speed kept; positive symbols ``m``, ``g``, ``v`` by
        default.

    References
    ----------
    W. G. Hoover, A. J. C. Ladd and B. Moran, "High-strain-rate plastic flow studied via
    nonequilibrium molecular dynamics", *Phys. Rev. Lett.* 48, 1982, 1818–1820.  D. J. Evans,
    W. G. Hoover, B. H. Failor, B. Moran and A. J. C. Ladd, "Nonequilibrium molecular dynamics
    via Gauss's principle of least constraint", *Phys. Rev. A* 28, 1983, 1016–1021.
    D. J. Evans and G. P. Morriss, *Statistical Mechanics of Nonequilibrium Liquids*, Academic
    Press, 1990 (2nd ed. Cambridge University Press, 2008): Gauss's principle and the
    isokinetic thermostat.
    """
    x, y = dynamicsymbols("x y")
    m_, g_, v_ = (_param(value, n) for value, n in ((m, "m"), (g, "g"), (v, "v")))
    return System(
        [x, y],
        m_ / 2 * (_d(x) ** 2 + _d(y) ** 2),
        [_d(x) ** 2 + _d(y) ** 2 - v_**2],
        dependent=[x],
        branch=1,
        potential_energy=m_ * g_ * y,
        name="Isokinetic particle",
    )


# ---------------------------------------------------------------- the Whipple bicycle
#: Table 1 of Meijaard, Papadopoulos, Ruina & Schwab (2007): the benchmark bicycle, exact
#: (SI units; the paper's axes: x forward, y to the right, z down, origin at the rear contact).
WHIPPLE_BENCHMARK: dict[str, sp.Expr] = {
    "w": sp.Rational(102, 100),  # wheel base
    "c": sp.Rational(8, 100),  # trail
    "lam": sp.pi / 10,  # steer axis tilt (from the vertical)
    "g": sp.Rational(981, 100),
    "r_R": sp.Rational(3, 10),
    "m_R": sp.Integer(2),
    "I_Rxx": sp.Rational(603, 10000),
    "I_Ryy": sp.Rational(12, 100),
    "x_B": sp.Rational(3, 10),
    "z_B": sp.Rational(-9, 10),
    "m_B": sp.Integer(85),
    "I_Bxx": sp.Rational(92, 10),
    "I_Byy": sp.Integer(11),
    "I_Bzz": sp.Rational(28, 10),
    "I_Bxz": sp.Rational(24, 10),
    "x_H": sp.Rational(9, 10),
    "z_H": sp.Rational(-7, 10),
    "m_H": sp.Integer(4),
    "I_Hxx": sp.Rational(5892, 100000),
    "I_Hyy": sp.Rational(6, 100),
    "I_Hzz": sp.Rational(708, 100000),
    "I_Hxz": sp.Rational(-756, 100000),
    "r_F": sp.Rational(35, 100),
    "m_F": sp.Integer(3),
    "I_Fxx": sp.Rational(1405, 10000),
    "I_Fyy": sp.Rational(28, 100),
}
#: parameters that may be negative (the centres of mass lie above the ground: z < 0; products)
_WHIPPLE_REAL = ("z_B", "I_Bxz", "z_H", "I_Hxz")


class _Whipple(NamedTuple):
    """The bicycle as ``sympy.physics.mechanics`` objects (see :func:`whipple_bicycle`)."""

    frame: ReferenceFrame
    coordinates: list[sp.Expr]
    bodies: list[RigidBody]
    potential_energy: sp.Expr
    rear_contact_velocity: sp.Expr  # a Vector: the velocity of the rear wheel's point at the contact
    front_contact_velocity: sp.Expr
    pitch_relation: sp.Expr  # the height of the front contact: 0 on the ground


def _whipple_parameters(values: Mapping[str, sp.Expr | float]) -> dict[str, sp.Expr]:
    unknown = sorted(set(values) - set(WHIPPLE_BENCHMARK))
    if unknown:
        raise ChaplyginError(
            f"whipple_bicycle: unknown parameter {unknown[0]!r}; the parameters are "
            f"{', '.join(WHIPPLE_BENCHMARK)}."
        )
    out = {}
    for name in WHIPPLE_BENCHMARK:
        value = values.get(name)
        if value is None and name in _WHIPPLE_REAL:
            out[name] = sp.Symbol(name, real=True)
        else:
            out[name] = _param(value, name)
    return out


def _whipple(values: Mapping[str, sp.Expr | float]) -> _Whipple:
    """Frames, points and bodies of the benchmark bicycle (Meijaard et al. 2007, §2 and appendix A)."""
    p = _whipple_parameters(values)
    x, y, psi, phi, theta, delta, theta_R, theta_F = dynamicsymbols("x y psi phi theta delta theta_R theta_F")
    N = ReferenceFrame("N")  # z down, as in the paper
    yawed = N.orientnew("yawed", "Axis", [psi, N.z])
    rolled = yawed.orientnew("rolled", "Axis", [phi, yawed.x])
    B = rolled.orientnew("B", "Axis", [theta, rolled.y])  # rear frame: pitch from the nominal attitude
    R = B.orientnew("R", "Axis", [theta_R, B.y])
    steer_axis = B.orientnew("steer_axis", "Axis", [p["lam"], B.y])  # its z: down the steer axis
    steered = steer_axis.orientnew("steered", "Axis", [delta, steer_axis.z])
    H = steered.orientnew("H", "Axis", [-p["lam"], steered.y])  # front frame: = B at δ = 0
    F = H.orientnew("F", "Axis", [theta_F, H.y])

    origin = Point("O")
    rear_contact = origin.locatenew("P", x * N.x + y * N.y)
    rear_centre = rear_contact.locatenew("R_o", -p["r_R"] * rolled.z)
    rear_frame_mass = rear_centre.locatenew("B_o", p["x_B"] * B.x + (p["z_B"] + p["r_R"]) * B.z)
    # where the steer axis meets the ground in the nominal configuration: a point of B and of H
    axis_foot = rear_centre.locatenew("S", (p["w"] + p["c"]) * B.x + p["r_R"] * B.z)
    front_frame_mass = axis_foot.locatenew("H_o", (p["x_H"] - p["w"] - p["c"]) * H.x + p["z_H"] * H.z)
    front_centre = axis_foot.locatenew("F_o", -p["c"] * H.x - p["r_F"] * H.z)
    # the lowest point of the front wheel: from its centre, down within the wheel's plane
    tilt = N.z.dot(H.y)
    front_contact = front_centre.locatenew("Q", p["r_F"] * (N.z - tilt * H.y) / sp.sqrt(1 - tilt**2))
    origin.set_vel(N, 0)
    for point in (rear_contact, rear_centre, rear_frame_mass, front_frame_mass, front_centre):
        point.set_vel(N, point.pos_from(origin).dt(N))

    bodies = [
        RigidBody(
            "R", rear_centre, R, p["m_R"], (inertia(B, p["I_Rxx"], p["I_Ryy"], p["I_Rxx"]), rear_centre)
        ),
        RigidBody(
            "B",
            rear_frame_mass,
            B,
            p["m_B"],
            (inertia(B, p["I_Bxx"], p["I_Byy"], p["I_Bzz"], 0, 0, p["I_Bxz"]), rear_frame_mass),
        ),
        RigidBody(
            "H",
            front_frame_mass,
            H,
            p["m_H"],
            (inertia(H, p["I_Hxx"], p["I_Hyy"], p["I_Hzz"], 0, 0, p["I_Hxz"]), front_frame_mass),
        ),
        RigidBody(
            "F", front_centre, F, p["m_F"], (inertia(H, p["I_Fxx"], p["I_Fyy"], p["I_Fxx"]), front_centre)
        ),
    ]
    # gravity along +z (down): V = −g Σ m z
    V = -p["g"] * sum((b.mass * b.masscenter.pos_from(origin).dot(N.z) for b in bodies), sp.S.Zero)
    rear_slip = rear_centre.vel(N) + R.ang_vel_in(N).cross(rear_contact.pos_from(rear_centre))
    front_slip = front_centre.vel(N) + F.ang_vel_in(N).cross(front_contact.pos_from(front_centre))
    return _Whipple(
        N,
        [x, y, psi, phi, theta, delta, theta_R, theta_F],
        bodies,
        V,
        rear_slip,
        front_slip,
        front_contact.pos_from(origin).dot(N.z),
    )


def whipple_pitch_relation(**parameters: sp.Expr | float) -> sp.Expr:
    """The holonomic constraint of :func:`whipple_bicycle`: the front contact's height, ``f(φ, θ, δ) = 0``.

    The height (along the paper's downward z) of the front wheel's lowest point; the rear wheel
    touches the ground by construction. It vanishes at ``φ = θ = δ = 0`` for every value of the
    parameters, and it fixes the pitch ``θ`` once the roll ``φ`` and the steer ``δ`` are given.
    Parameters as for :func:`whipple_bicycle`.
    """
    return _whipple(parameters).pitch_relation


def whipple_bicycle(**parameters: sp.Expr | float) -> System:
    """The Whipple bicycle of the benchmark of Meijaard, Papadopoulos, Ruina & Schwab (2007).

    Four rigid bodies — the rear wheel R, the rear frame B with the rider, the front frame H
    (fork and handlebar) and the front wheel F — hinged at the wheel axles and at the steer
    axis; knife-edge wheels roll without slipping on level ground under gravity. Built the way
    a user builds it, with ``sympy.physics.mechanics`` frames, points and rigid bodies and
    :func:`~chaplygin.from_mechanics`.

    Geometry and axes are the paper's (x forward, y to the right, z down): from the inertial
    frame, yaw ``ψ`` about z, roll ``φ`` about the new x (positive: leaning right), pitch ``θ``
    of the rear frame about the new y, measured from the nominal attitude (``θ = 0`` upright and
    straight), steer ``δ`` about the steer axis (tilted back by ``lam`` from the vertical,
    positive: to the right), and the wheels' angles ``θ_R, θ_F`` relative to their frames
    (rolling forward turns them negative). ``x, y`` is the rear contact point.

    Constraints (g = 5): the horizontal velocity of each wheel's material point at its contact
    vanishes (4 rolling constraints, dependent ``x, y, ψ, θ_F``), and the front wheel touches
    the ground, the holonomic relation :func:`whipple_pitch_relation` ``f(φ, θ, δ) = 0``
    (``holonomic={θ: f}``: its time derivative is the fifth velocity constraint, and a
    simulation solves θ from it at the start). The independent coordinates are the roll
    ``φ``, the steer ``δ`` and the rear wheel's angle ``θ_R``; the rear contact moves forward at
    ``v = −r_R (θ̇_R + θ̇)`` (the wheel's angle is measured from the rear frame), ``−r_R θ̇_R`` at
    constant pitch, as in the upright straight run.

    Parameters
    ----------
    **parameters
        Values by name; a parameter not given stays a symbol (positive, except ``z_B, z_H``
        and the products of inertia ``I_Bxz, I_Hxz``, which are real). The names and the
        benchmark's values (Table 1, :data:`WHIPPLE_BENCHMARK`): wheel base ``w = 1.02``, trail
        ``c = 0.08``, steer axis tilt ``lam = π/10``, gravity ``g = 9.81``; rear wheel radius
        ``r_R = 0.3``, mass ``m_R = 2``, moments ``I_Rxx = 0.0603``, ``I_Ryy = 0.12``; rear frame
        centre of mass ``(x_B, z_B) = (0.3, −0.9)``, mass ``m_B = 85``, inertia
        ``[[I_Bxx, 0, I_Bxz], [0, I_Byy, 0], [I_Bxz, 0, I_Bzz]] = [[9.2, 0, 2.4], [0, 11, 0],
        [2.4, 0, 2.8]]``; front frame ``(x_H, z_H) = (0.9, −0.7)``, ``m_H = 4``,
        ``[[0.05892, 0, −0.00756], [0, 0.06, 0], [−0.00756, 0, 0.00708]]``; front wheel
        ``r_F = 0.35``, ``m_F = 3``, ``I_Fxx = 0.1405``, ``I_Fyy = 0.28``. Centres of mass are
        given from the rear contact in the nominal configuration, inertias about them in the
        paper's axes.

    References
    ----------
    J. P. Meijaard, J. M. Papadopoulos, A. Ruina and A. L. Schwab, "Linearized dynamics
    equations for the balance and steer of a bicycle: a benchmark and review", *Proc. R. Soc.
    A* 463, 2007, 1955–1982 (Table 1: the parameters; Table 2: the linearised equations and
    their eigenvalues). See ``docs/gallery/whipple-bicycle.md``.
    """
    bike = _whipple(parameters)
    N = bike.frame
    x, y, psi, _, theta, _, _, theta_F = bike.coordinates
    rolling = [
        bike.rear_contact_velocity.dot(N.x),
        bike.rear_contact_velocity.dot(N.y),
        bike.front_contact_velocity.dot(N.x),
        bike.front_contact_velocity.dot(N.y),
    ]
    return from_mechanics(
        N,
        bike.coordinates,
        bike.bodies,
        rolling,
        dependent=[x, y, psi, theta_F],
        holonomic={theta: bike.pitch_relation},
        potential_energy=bike.potential_energy,
        name="Whipple bicycle (Meijaard et al. 2007)",
    )


# ---------------------------------------------------------------------------- catalogue
class ExampleEntry(NamedTuple):
    """One built-in example: how to build it, what it is, and numbers to simulate it with.

    ``constructor()`` returns the symbolic :class:`~chaplygin.System`;
    ``parameters`` gives a default value to each of its parameters and
    ``initial`` a full initial state (every coordinate and every independent
    velocity, keyed ``"x"``/``"x'"``) from which every model simulates well
    over ``0 ≤ t ≤ 20``.
    """

    constructor: Callable[[], System]
    description: str
    parameters: dict[str, float]
    initial: dict[str, float]

    def system(self) -> System:
        """The symbolic system (``constructor()``)."""
        return self.constructor()

    def dumps(self) -> str:
        """The example as a system file (TOML, see :mod:`chaplygin.io.files`)."""
        from chaplygin.io.files import dumps

        return dumps(self.constructor(), self.parameters, self.initial)


_CATALOGUE: dict[str, tuple[Callable[[], System], str, dict[str, float], dict[str, float]]] = {
    "rolling-sphere": (
        rolling_sphere,
        (
            "The seed paper's §4 example: a homogeneous sphere (mass m, radius a) rolling without "
            "slipping on a rough horizontal plane; Euler angles psi, theta, phi and the centre x, y. "
            "A Chaplygin system with non-integrable constraints; the true motion and Lindelöf's "
            "differ (paper eqs. (41)-(62))."
        ),
        {"m": 1.0, "a": 1.0},
        {"psi": 0.3, "theta": 1.0, "phi": 0.1, "x": 0.0, "y": 0.0, "psi'": 0.5, "theta'": 0.4, "phi'": -0.7},
    ),
    "knife-edge": (
        knife_edge,
        (
            "A knife edge (skate) on a horizontal plane: the contact point (x, y) moves only along the "
            "blade of heading phi, sin(phi)*x' - cos(phi)*y' = 0, with y dependent (y' = tan(phi)*x', "
            "a pole at phi = ±pi/2). The true motion keeps its speed and turns at a constant rate; "
            "Lindelöf's equations instead swing phi away from 0 exponentially (rate x'*sqrt(m/J)), "
            "reaching the pole after t ≈ 25 from the default state."
        ),
        {"m": 1.0, "J": 1.0},
        {"x": 0.0, "y": 0.0, "phi": 0.0, "x'": 0.1, "phi'": 0.02},
    ),
    "vertical-rolling-disk": (
        vertical_rolling_disk,
        (
            "A disk rolling upright on a plane (Bloch, Nonholonomic Mechanics and Control, §1.4): "
            "spin theta, heading phi, contact point x, y; x' = R*cos(phi)*theta', "
            "y' = R*sin(phi)*theta'. The contact point runs round a circle."
        ),
        {"m": 1.0, "R": 1.0, "I": 0.5, "J": 0.25},
        {"theta": 0.0, "phi": 0.0, "x": 0.0, "y": 0.0, "theta'": 1.0, "phi'": 0.2},
    ),
    "rolling-disk": (
        rolling_disk,
        (
            "A thin uniform disk (A = m r²/4, C = m r²/2) rolling without slipping on a horizontal "
            "plane under gravity: heading psi, lean theta (0 upright), spin phi, contact point x, y. "
            "The default state rolls fast enough (phi' = 6) to stay up, wobbling about the upright."
        ),
        {"m": 1.0, "r": 1.0, "A": 0.25, "C": 0.5, "g": 9.81},
        {"psi": 0.0, "theta": 0.1, "phi": 0.0, "x": 0.0, "y": 0.0, "psi'": 0.0, "theta'": 0.0, "phi'": 6.0},
    ),
    "chaplygin-sleigh": (
        chaplygin_sleigh,
        (
            "The Chaplygin sleigh (Chaplygin 1911; Bloch, Nonholonomic Mechanics and Control, §1.7): "
            "a body on a knife edge at (x, y) of heading theta, its centre of mass a ahead of the "
            "edge; y' = tan(theta)*x' (a pole at theta = ±pi/2). The true motion has v' = a*w^2, "
            "w' = -m*a*v*w/(I + m*a^2) and ends in straight-line motion; Lindelöf's equations are "
            "the knife edge's with J = I + m*a^2 and swing theta away from 0 (rate x'*sqrt(m/J)), "
            "so the default state is slow enough to keep every model below the pole up to t = 20."
        ),
        {"m": 1.0, "I": 1.0, "a": 1.0},
        {"x": 0.0, "y": 0.0, "theta": 0.0, "x'": 0.1, "theta'": 0.01},
    ),
    "turntable-ball": (
        turntable_ball,
        (
            "A homogeneous ball (mass m, radius a) rolling on a turntable that turns at the constant "
            "rate Omega: affine constraints x' = a*w_y - Omega*y, y' = -a*w_x + Omega*x with Euler "
            "angles psi, theta, phi (singular at theta = 0, pi). Not a Chaplygin system (no Lindelöf "
            "equations); the centre circles at 2*Omega/7. The default ball starts carried by the "
            "table at (0.5, 0) and circles about (-1.25, 0); energy is not conserved (the table "
            "does work), but E - Omega*L_z is; the vakonomic motion from it gains energy fast."
        ),
        {"m": 1.0, "a": 1.0, "Omega": 0.5},
        {"psi": 0.0, "theta": 1.5, "phi": 0.0, "x": 0.5, "y": 0.0, "psi'": 0.2, "theta'": 0.0, "phi'": 0.0},
    ),
    "chaplygin-ball": (
        chaplygin_ball,
        (
            "Chaplygin's ball (1903): a ball of radius a whose centre of mass is its centre, with "
            "principal moments A, B, C, rolling on a rough plane (the sphere's constraints, Euler "
            "angles psi, theta, phi, singular at theta = 0, pi). The angular momentum about the "
            "contact point is conserved in the true motion, not in Lindelöf's."
        ),
        {"m": 1.0, "a": 1.0, "A": 0.3, "B": 0.4, "C": 0.5},
        {"psi": 0.2, "theta": 1.1, "phi": 0.3, "x": 0.0, "y": 0.0, "psi'": 0.4, "theta'": -0.3, "phi'": 0.8},
    ),
    "heisenberg": (
        heisenberg,
        (
            "The Heisenberg (Brockett) system: T = (x'^2 + y'^2)/2 with z' = (x*y' - y*x')/2. "
            "True motions are straight lines (and so are Lindelöf's: the defect vanishes); the other "
            "vakonomic motions are circles, the sub-Riemannian geodesics, and z gains the area "
            "they enclose."
        ),
        {},
        {"x": 1.0, "y": 0.0, "z": 0.0, "x'": 0.0, "y'": 1.0},
    ),
    "contact-oscillator": (
        contact_oscillator,
        (
            "A nonholonomic oscillator: a unit mass in R^3 with x' + y*z' = 0 (x dependent) and "
            "V = (x^2 + y^2 + z^2)/2 + epsilon*x^2*z^2/2. Not a Chaplygin system (V depends on x): "
            "Voronets' equations, no Lindelöf equations. In the true motion y is a harmonic "
            "oscillator for every epsilon; the energy is conserved."
        ),
        {"epsilon": 0.01},
        {"x": 0.0, "y": 1.0, "z": 0.5, "y'": 0.2, "z'": 0.4},
    ),
    "differential-drive": (
        differential_drive,
        (
            "A differential-drive robot: wheels of radius r at ±b on an axle through the centre of "
            "mass, wheel angles phi_L, phi_R; x' = v*cos(theta), y' = v*sin(theta), theta' = w with "
            "v = r*(phi_R' + phi_L')/2, w = r*(phi_R' - phi_L')/(2*b). Free of torques the wheels "
            "keep their speeds: the default robot drives round a circle of radius 1.5."
        ),
        {"m": 1.0, "I": 0.5, "J": 0.1, "r": 0.1, "b": 0.3},
        {"x": 0.0, "y": 0.0, "theta": 0.0, "phi_L": 0.0, "phi_R": 0.0, "phi_L'": 4.0, "phi_R'": 6.0},
    ),
    "sleigh-chain": (
        _sleigh_chain_2,
        (
            "A lead sleigh at (x, y) of heading theta0 pulling two sleighs, each hitched at the "
            "knife edge of the one ahead at distance L (sleigh_chain(2); mass m and inertia I at "
            "each knife edge): the N-trailer kinematics with dynamics. Not a Chaplygin system. "
            "In the true motion theta0' is constant; the default lead runs straight and the "
            "trailers line up behind it."
        ),
        {"m": 1.0, "I": 0.5, "L": 1.0},
        {"x": 0.0, "y": 0.0, "theta0": 0.0, "theta1": 0.2, "theta2": 0.0, "x'": 1.0, "theta0'": 0.0},
    ),
    "lindelof-problem": (
        lindelof_problem,
        (
            "Lindelöf's problem (1895): a body of revolution, here a thin disk (mass m, radius r, "
            "central moments A, A, C), built from its shape by rolling_body(Disk(r), ...), rolling "
            "without slipping on a horizontal plane under gravity; heading psi, lean theta (0 upright), "
            "spin phi and the centre x, y. Lindelöf substituted the constraints into T; Chaplygin "
            "(1897) showed that this gives another motion: from the default state (a coin leaning "
            "by 0.3 rad, turning and spinning) the two lean angles part within a second."
        ),
        {"m": 1.0, "r": 1.0, "A": 0.25, "C": 0.5, "g": 9.81},
        {"psi": 0.0, "theta": 0.3, "phi": 0.0, "x": 0.0, "y": 0.0, "psi'": 1.0, "theta'": 0.0, "phi'": 3.0},
    ),
    "routh-sphere": (
        routh_sphere,
        (
            "Routh's sphere (Routh 1905): a ball of radius r whose centre of mass lies a below its "
            "centre on an axis of symmetry (central moments A, A, C), rolling without slipping on a "
            "horizontal plane; Cardan angles psi, theta, phi and the centre of mass x, y. Energy, "
            "Jellett's and Routh's integrals are conserved. The default ball starts tilted by 0.5 "
            "rad about x with body angular velocity (1, -0.5, 4)."
        ),
        {"r": 1.0, "a": 0.3, "m": 1.0, "A": 0.4, "C": 0.6, "g": 9.81},
        # R = R_x(0.5), ω = (1, −0.5, 4) in body axes: θ' = ω₁, ψ' = ω₃/cos θ, φ' = ω₂ − ψ' sin θ
        {
            "psi": 0.0,
            "theta": 0.5,
            "phi": 0.0,
            "x": 0.0,
            "y": 0.0,
            "psi'": 4.0 / math.cos(0.5),
            "theta'": 1.0,
            "phi'": -0.5 - 4.0 * math.tan(0.5),
        },
    ),
    "rattleback": (
        rattleback,
        (
            "The rattleback of Kane & Levinson (1982): an ellipsoid (semi-axes a, b, c) with the "
            "centre of mass h below its centre and the principal axes of inertia turned from the "
            "shape's by the product D (inertia m*[[A, D, 0], [D, B, 0], [0, 0, C]], z up), rolling "
            "without slipping; Cardan angles psi, theta, phi and the centre of mass x, y. The "
            "default state, tilted by 0.01 rad about x and y and spun at 5 rad/s counter-clockwise "
            "(n*D > 0), rocks and reverses its spin at t ≈ 2.8 s; spun the other way (psi' = -5, "
            "theta' = -0.05, phi' = 0.05) it keeps its sense for much longer."
        ),
        {
            "a": 0.2,
            "b": 0.03,
            "c": 0.02,
            "h": 0.01,
            "m": 1.0,
            "A": 2e-4,
            "B": 1.6e-3,
            "C": 1.7e-3,
            "D": 2e-5,
            "g": 9.81,
        },
        # R = R_x(0.01) R_y(0.01), ω = (0, 0, 5) in body axes: ψ' = 5, θ' = 5 sin 0.01, φ' = −5 sin 0.01
        {
            "psi": 0.0,
            "theta": 0.01,
            "phi": 0.01,
            "x": 0.0,
            "y": 0.0,
            "psi'": 5.0,
            "theta'": 5.0 * math.sin(0.01),
            "phi'": -5.0 * math.sin(0.01),
        },
    ),
    "appell-weight": (
        appell_weight,
        (
            "Appell's weight (1911): a weight on a thread wound on the drum of a wheel rolling on a "
            "plane, reduced to a point mass (x, y, z) with z'^2 = k^2*(x'^2 + y'^2), k the drum's "
            "radius over the wheel's, and potential m*g*z (Neimark & Fufaev, chapter III): a "
            "constraint nonlinear in the velocities. On the branch z' = -k*sqrt(x'^2 + y'^2) the "
            "weight falls and drives the wheel (singular at x' = y' = 0). The true motion runs on a "
            "straight line with v' = g*k/(1 + k^2) and z'' = -g*k^2/(1 + k^2); the vakonomic "
            "motion is the same."
        ),
        {"m": 1.0, "g": 9.81, "k": 0.5},
        {"x": 0.0, "y": 0.0, "z": 0.0, "x'": 0.6, "y'": 0.8},
    ),
    "isokinetic-particle": (
        isokinetic_particle,
        (
            "A particle kept at the speed v in a uniform field, x'^2 + y'^2 = v^2 with potential "
            "m*g*y: Gauss's isokinetic thermostat (Hoover 1982; Evans & Morriss 1990), on the "
            "branch x' = sqrt(v^2 - y'^2) (singular at y' = ±v). The true motion runs on the grim "
            "reaper y = y0 + a*log(cos((x - x0)/a)), a = v^2/g; the vakonomic motions on "
            "catenaries y = y1 - A*cosh((x - x1)/A), A = v*c/(m*g): the models differ."
        ),
        {"m": 1.0, "g": 0.1, "v": 1.0},
        {"x": 0.0, "y": 0.0, "y'": 0.6},
    ),
    "whipple-bicycle": (
        whipple_bicycle,
        (
            "The Whipple bicycle of the benchmark of Meijaard, Papadopoulos, Ruina & Schwab (Proc. R. "
            "Soc. A 463, 2007): rear wheel, rear frame with rider, front frame and front wheel, "
            "knife-edge wheels rolling without slipping on level ground (paper's axes: z down). "
            "Rear contact x, y, yaw psi, roll phi, pitch theta (fixed by the front wheel touching the "
            "ground), steer delta, wheel angles theta_R, theta_F; Table 1's numbers. From the default "
            "state, rolling at v = -r_R*theta_R' = 5 m/s (between the weave speed 4.29 and the "
            "capsize speed 6.02 m/s: self-stable) and leaning by 0.05 rad, the lean dies away."
        ),
        {name: float(value) for name, value in WHIPPLE_BENCHMARK.items()},
        {
            "x": 0.0,
            "y": 0.0,
            "psi": 0.0,
            "phi": 0.05,
            "theta": 0.0,  # the front wheel touches the ground at delta = 0 for every roll
            "delta": 0.0,
            "theta_R": 0.0,
            "theta_F": 0.0,
            "phi'": 0.0,
            "delta'": 0.0,
            "theta_R'": -5.0 / 0.3,
        },
    ),
}


def _normalise(name: str) -> str:
    return name.strip().lower().replace("_", "-").replace(" ", "-")


def catalogue() -> dict[str, ExampleEntry]:
    """The built-in examples by name, each an :class:`ExampleEntry` (fresh copies every call)."""
    return {
        name: ExampleEntry(ctor, text, dict(params), dict(init))
        for name, (ctor, text, params, init) in _CATALOGUE.items()
    }


def get(name: str) -> ExampleEntry:
    """The example called ``name`` (``"rolling-sphere"``; ``rolling_sphere`` works too).

    Raises
    ------
    ChaplyginError
        For an unknown name, listing the examples.
    """
    entries = catalogue()
    key = _normalise(name) if isinstance(name, str) else name
    if key not in entries:
        close = difflib.get_close_matches(str(key), list(entries), n=1)
        hint = f" Did you mean {close[0]!r}?" if close else ""
        raise ChaplyginError(f"unknown example {name!r}; the examples are {', '.join(entries)}.{hint}")
    return entries[key]
