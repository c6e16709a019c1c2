"""Rolling rigid bodies built from their shape (issue 18).

``rolling_body(shape, mass=…, inertia=…, center_of_mass=…)`` writes the kinetic and potential
energy and the rolling constraints of a convex body on a horizontal plane and returns a
:class:`~chaplygin.System` (a :class:`RollingBody`); ``initial_state`` and ``motion`` convert
between rotations/angular velocities and its coordinates. See ``docs/bodies.md``.
"""

from __future__ import annotations

from chaplygin.bodies.builder import RollingBody, rolling_body
from chaplygin.bodies.kinematics import Motion, initial_state, motion
from chaplygin.bodies.shapes import (
    Disk,
    Ellipsoid,
    Paraboloid,
    Revolution,
    Shape,
    Sphere,
    SupportFunction,
    Torus,
)

__all__ = [
    "Disk",
    "Ellipsoid",
    "Motion",
    "Paraboloid",
    "Revolution",
    "RollingBody",
    "Shape",
    "Sphere",
    "SupportFunction",
    "Torus",
    "initial_state",
    "motion",
    "rolling_body",
]
