"""Build the rolling system of a rigid body from its shape, mass and inertia.

Conventions (``docs/bodies.md``): space axes with ``z`` up, the plane ``z = 0``, gravity
``−g e_z``. Body axes are the shape's axes. The attitude is ``R = R_z(ψ) R_x(θ) R_3(φ) R_0``
(body → space), with ``R_3`` and the fixed ``R_0`` set by the angle convention:

* ``"cardan"``: ``R_3 = R_y``, ``R_0 = 1``; resting attitude ``R = 1`` (shape z up). Singular
  where ``cos θ = 0`` (the shape's y axis vertical).
* ``"edge"``: ``R_3 = R_y``, ``R_0 = R_x(−π/2)`` (the shape's z axis along the space y axis at
  ``ψ = θ = φ = 0``); ψ is the heading, θ the lean, φ the spin about the symmetry axis: the
  angles of :func:`chaplygin.examples.rolling_disk`. Singular where ``cos θ = 0`` (the
  symmetry axis vertical: a disk lying flat).
* ``"euler"``: ``R_3 = R_z``, ``R_0 = 1`` (z-x-z Euler angles, as
  :func:`chaplygin.examples.rolling_sphere`). Singular where ``sin θ = 0`` (shape z vertical).

Coordinates ``ψ, θ, φ`` and the horizontal position ``x, y`` of the centre of mass G. With
``u = −Rᵀ e_z`` (the downward normal in body axes), the contact point is ``P = ∇h(u)`` in body
axes and G is at height ``h(u) − u·c`` (``c``: the centre of mass from the shape's origin).
Rolling without slipping, ``v_G + ω × (P − G) = 0``, gives ``ẋ, ẏ`` (the dependent velocities)
and ``ż``; T, V and the constraints do not contain ``x, y``, so this is a Chaplygin system.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import sympy as sp

from chaplygin.bodies.shapes import Shape, positive
from chaplygin.core._symbols import TIME, function_of_time
from chaplygin.core.system import System
from chaplygin.errors import SystemDefinitionError

__all__ = ["ANGLES", "RollingBody", "rolling_body"]

#: angle conventions: (axis of the third rotation, fixed rotation R_0)
ANGLES: dict[str, tuple[int, sp.Matrix]] = {}


def _rot(axis: int, angle: sp.Expr) -> sp.Matrix:
    c, s = sp.cos(angle), sp.sin(angle)
    if axis == 0:
        return sp.Matrix([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == 1:
        return sp.Matrix([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return sp.Matrix([[c, -s, 0], [s, c, 0], [0, 0, 1]])


ANGLES.update(
    {
        "cardan": (1, sp.eye(3)),
        "edge": (1, _rot(0, -sp.pi / 2)),
        "euler": (2, sp.eye(3)),
    }
)


def _unit(k: int) -> sp.Matrix:
    e = sp.zeros(3, 1)
    e[k] = 1
    return e


def _scalar(value: Any, key: str) -> sp.Expr:
    if isinstance(value, str):
        if not value.isidentifier():
            raise SystemDefinitionError(f"{key}: {value!r} is not a symbol name.")
        return sp.Symbol(value, real=True)
    if isinstance(value, bool) or not isinstance(value, (int, float, sp.Expr)):
        raise SystemDefinitionError(f"{key}: expected a number or a SymPy expression, got {value!r}.")
    return sp.nsimplify(value) if isinstance(value, float) else sp.sympify(value, strict=True)


def _inertia(value: Any) -> sp.Matrix:
    """The central inertia tensor: three principal moments or a symmetric 3 × 3 matrix."""
    rows = value.tolist() if isinstance(value, (sp.MatrixBase, np.ndarray)) else value
    if isinstance(rows, (str, sp.Basic)) or not isinstance(rows, Sequence):
        raise SystemDefinitionError(
            "inertia: expected three principal moments (A, B, C) or a symmetric 3 x 3 tensor about the centre of mass."
        )
    rows = list(rows)
    if len(rows) == 3 and all(not isinstance(r, (Sequence, np.ndarray)) or isinstance(r, str) for r in rows):
        moments = [positive(r, f"inertia[{k}]", "a principal moment") for k, r in enumerate(rows)]
        I = sp.diag(*moments)
    elif len(rows) == 3 and all(isinstance(r, (Sequence, np.ndarray)) and len(r) == 3 for r in rows):
        I = sp.Matrix(
            [[_scalar(v, f"inertia[{i}][{j}]") for j, v in enumerate(r)] for i, r in enumerate(rows)]
        )
        for i in range(3):
            for j in range(i):
                if sp.simplify(I[i, j] - I[j, i]) != 0:
                    raise SystemDefinitionError(
                        f"inertia[{i}][{j}] = {I[i, j]} but inertia[{j}][{i}] = {I[j, i]}: an inertia tensor is symmetric."
                    )
    else:
        raise SystemDefinitionError(
            "inertia: expected three principal moments (A, B, C) or a symmetric 3 x 3 tensor about the centre of mass."
        )
    if not I.free_symbols:
        principal = np.linalg.eigvalsh(np.array(I.tolist(), dtype=float))
        if principal[0] <= 0:
            raise SystemDefinitionError(
                f"inertia: not positive definite (principal moments {np.round(principal, 12).tolist()}); a rigid body "
                "has positive principal moments."
            )
        if principal[2] > principal[0] + principal[1] + 1e-12 * principal[2]:
            raise SystemDefinitionError(
                f"inertia: the principal moments {np.round(principal, 12).tolist()} violate the triangle inequality "
                "(each must be at most the sum of the other two, as for every mass distribution)."
            )
    return I


class RollingBody(System):
    """A :class:`~chaplygin.System` built by :func:`rolling_body`, with its body kinematics.

    Attributes
    ----------
    shape : Shape
    angles : str
        ``"cardan"``, ``"edge"`` or ``"euler"`` (module docstring).
    rotation : sympy.Matrix
        ``R(ψ, θ, φ)``, body → space.
    omega_body : sympy.Matrix
        Body components of the angular velocity, linear in ``ψ̇, θ̇, φ̇``.
    contact_body : sympy.Matrix
        The contact point ``∇h(u)`` in body axes (from the shape's origin).
    center_of_mass : sympy.Matrix
        ``c``, the centre of mass from the shape's origin, body axes.
    height : sympy.Expr
        Height of the centre of mass above the plane, ``h(u) − u·c``.
    mass, gravity : sympy.Expr
    inertia : sympy.Matrix
        Central inertia tensor in body axes.
    """

    shape: Shape
    angles: str
    rotation: sp.Matrix
    omega_body: sp.Matrix
    contact_body: sp.Matrix
    center_of_mass: sp.Matrix
    height: sp.Expr
    mass: sp.Expr
    gravity: sp.Expr
    inertia: sp.Matrix


def rolling_body(
    shape: Shape,
    *,
    mass: Any,
    inertia: Any,
    center_of_mass: Sequence[Any] = (0, 0, 0),
    g: Any = None,
    name: str | None = None,
    angles: str | None = None,
) -> RollingBody:
    """A rigid body of the given shape rolling without slipping on the horizontal plane ``z = 0``.

    Parameters
    ----------
    shape : Shape
        :class:`~chaplygin.bodies.Sphere`, :class:`~chaplygin.bodies.Disk`, … in its own axes,
        which are the body axes.
    mass : number, SymPy expression or name
    inertia : three moments or a symmetric 3 × 3 tensor
        About the centre of mass, in body axes; its principal axes need not be the shape's.
    center_of_mass : three numbers or expressions
        From the shape's origin (its centre, or the paraboloid's vertex), body axes.
    g : optional
        Gravitational acceleration along ``−z`` (the positive symbol ``g`` by default).
    name : str, optional
    angles : {"cardan", "edge", "euler"}, optional
        The angle convention (module docstring); by default the shape's (``"edge"`` for
        :class:`Disk` and :class:`Torus`, else ``"cardan"``).

    Returns
    -------
    RollingBody
        A System with coordinates ``[psi, theta, phi, x, y]`` and dependent ``x, y``.

    Raises
    ------
    SystemDefinitionError
        An unknown shape or convention, a non-positive mass, an inertia tensor that is not
        symmetric, not positive definite or violates the triangle inequality, a centre of mass
        outside the body (where numeric).
    """
    if not isinstance(shape, Shape):
        raise SystemDefinitionError(
            f"shape: {shape!r} is not a shape; use Sphere, Disk, Torus, Ellipsoid, Paraboloid, Revolution or SupportFunction "
            "from chaplygin.bodies."
        )
    convention = angles or shape.default_angles
    if convention not in ANGLES:
        raise SystemDefinitionError(f"angles={convention!r}: expected one of {', '.join(map(repr, ANGLES))}.")
    m = positive(mass, "mass", "a mass")
    I = _inertia(inertia)
    gravity = sp.Symbol("g", positive=True) if g is None else positive(g, "g", "gravity")
    if (
        isinstance(center_of_mass, (str, sp.Basic))
        or not isinstance(center_of_mass, (Sequence, np.ndarray))
        or len(center_of_mass) != 3
    ):
        raise SystemDefinitionError(
            "center_of_mass: expected three coordinates (x, y, z) in the shape's axes."
        )
    c = sp.Matrix([_scalar(v, f"center_of_mass[{k}]") for k, v in enumerate(center_of_mass)])
    if not c.free_symbols:
        inside = shape.contains([float(v) for v in c])
        if inside is False:
            raise SystemDefinitionError(
                f"center_of_mass = {list(c)} lies outside the {type(shape).__name__}; give a point of the body "
                f"(relative to its {shape.reference})."
            )

    psi, theta, phi, x, y = map(function_of_time, ("psi", "theta", "phi", "x", "y"))

    def d(q: Any) -> Any:
        return q.diff(TIME)

    third, R0 = ANGLES[convention]
    R3 = _rot(third, phi)
    tilt = _rot(0, theta) * R3 * R0
    R = _rot(2, psi) * tilt
    omega = R0.T * (
        (_rot(0, theta) * R3).T * _unit(2) * d(psi) + R3.T * _unit(0) * d(theta) + _unit(third) * d(phi)
    )
    omega = omega.applyfunc(sp.expand)
    u = (-tilt.T * _unit(2)).applyfunc(sp.expand)  # downward normal in body axes; free of ψ
    P = shape.contact(u)
    arm = (P - c).applyfunc(sp.factor_terms)
    w = tilt * omega.cross(arm)  # ω × (P − G) in the heading frame
    vx, vy = sp.cos(psi) * w[0] - sp.sin(psi) * w[1], sp.sin(psi) * w[0] + sp.cos(psi) * w[1]
    vz = -w[2]
    height = shape.support(u) - (u.T * c)[0]
    T = m / 2 * (d(x) ** 2 + d(y) ** 2 + vz**2) + (omega.T * I * omega)[0] / 2
    system = RollingBody(
        [psi, theta, phi, x, y],
        T,
        {d(x): -vx, d(y): -vy},
        potential_energy=m * gravity * height,
        name=name or f"{type(shape).__name__} rolling on a plane",
    )
    system.shape, system.angles = shape, convention
    system.rotation, system.omega_body, system.contact_body = R, omega, P
    system.center_of_mass, system.height = c, height
    system.mass, system.gravity, system.inertia = m, gravity, I
    return system
