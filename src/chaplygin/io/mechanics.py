"""Build a :class:`~chaplygin.System` from ``sympy.physics.mechanics`` objects.

Models written for ``sympy.physics.mechanics`` — reference frames, points,
rigid bodies and particles, loads — carry everything chaplygin needs: the
kinetic energy is the bodies' kinetic energy in the inertial frame, the
generalized forces come from the loads through partial velocities, and
velocity constraints may be written as mechanics vectors (e.g. "the
contact-point velocity is zero"): every non-vanishing component along the
inertial frame's axes becomes one constraint.  Holonomic constraints ``f(q, t) = 0`` are
given by the coordinate each one fixes, as an expression or as a vector with a single
non-vanishing component (a contact point's position along the normal of its surface).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import sympy as sp
from sympy.physics.mechanics import Particle, Point, ReferenceFrame, RigidBody
from sympy.physics.vector import Vector

from chaplygin.core._sampling import vanishes
from chaplygin.core._symbols import TIME, Vars
from chaplygin.core.system import System
from chaplygin.errors import SystemDefinitionError

__all__ = ["from_mechanics"]

Load = tuple[Any, Vector]


def _plain(expr: sp.Expr, vars_: Vars) -> sp.Expr:
    return expr.xreplace(vars_.to_symbols())


def _constraint_expressions(
    constraints: Sequence[Vector | sp.Expr], frame: ReferenceFrame, vars_: Vars
) -> list[sp.Expr]:
    out: list[sp.Expr] = []
    for k, c in enumerate(constraints):
        if isinstance(c, Vector):
            parts = [c.dot(axis) for axis in (frame.x, frame.y, frame.z)]
        elif isinstance(c, sp.Expr):
            parts = [c]
        else:
            raise SystemDefinitionError(
                f"constraints[{k}]: expected a mechanics Vector or a SymPy expression, got {c!r}."
            )
        # not expanded: System reads them through SymEngine (expanding the Whipple bicycle's
        # front contact velocity in SymPy took 3.8 of the 5.8 s of from_mechanics)
        out += [p for p in parts if not vanishes(_plain(p, vars_))]
    return out


def _relations(
    holonomic: Mapping[Any, Vector | sp.Expr] | None, frame: ReferenceFrame, vars_: Vars
) -> dict[Any, Any] | None:
    """``holonomic`` with each vector replaced by its one non-vanishing component along ``frame``'s axes."""
    if holonomic is None or not isinstance(holonomic, Mapping):
        return holonomic  # (System says what is wrong with it)
    out: dict[Any, Any] = {}
    for key, value in holonomic.items():
        if isinstance(value, Vector):
            parts = [sp.expand(value.dot(axis)) for axis in (frame.x, frame.y, frame.z)]
            parts = [p for p in parts if not vanishes(_plain(p, vars_))]
            if len(parts) != 1:
                name = getattr(getattr(key, "func", None), "__name__", key)
                raise SystemDefinitionError(
                    f"holonomic[{name}]: the vector has {len(parts)} non-vanishing components along "
                    f"{frame}'s axes; a holonomic constraint is one relation f = 0: give a vector with "
                    "one component (a point's position along a normal) or the expression itself."
                )
            value = parts[0]
        out[key] = value
    return out


def _generalized_forces(
    loads: Sequence[Load], frame: ReferenceFrame, coordinates: Sequence[sp.Expr]
) -> dict[sp.Expr, sp.Expr]:
    speeds = [q.diff(TIME) for q in coordinates]
    forces: dict[sp.Expr, sp.Expr] = {}
    for k, load in enumerate(loads):
        if not (isinstance(load, tuple) and len(load) == 2 and isinstance(load[1], Vector)):
            raise SystemDefinitionError(
                f"loads[{k}]: expected (Point, force vector) or (ReferenceFrame, torque vector)."
            )
        where, vector = load
        if isinstance(where, Point):
            velocity = where.vel(frame)
        elif isinstance(where, ReferenceFrame):
            velocity = where.ang_vel_in(frame)
        else:
            raise SystemDefinitionError(f"loads[{k}]: {where!r} is neither a Point nor a ReferenceFrame.")
        for q, qd in zip(coordinates, speeds):
            term = vector.dot(velocity.diff(qd, frame))
            if term != 0:
                forces[q] = sp.expand(forces.get(q, sp.S.Zero) + term)
    return forces


def from_mechanics(
    frame: ReferenceFrame,
    coordinates: Sequence[sp.Expr],
    bodies: Sequence[RigidBody | Particle],
    constraints: Sequence[Vector | sp.Expr],
    *,
    dependent: Sequence[sp.Expr],
    loads: Sequence[Load] = (),
    potential_energy: sp.Expr | None = None,
    force_function: sp.Expr | None = None,
    holonomic: Mapping[Any, Vector | sp.Expr] | None = None,
    name: str | None = None,
) -> System:
    """A :class:`System` from bodies, loads and velocity constraints of ``sympy.physics.mechanics``.

    Parameters
    ----------
    frame : ReferenceFrame
        The inertial frame.
    coordinates : sequence of dynamicsymbols
        The generalized coordinates (velocities are their time derivatives).
    bodies : sequence of RigidBody or Particle
        T is the sum of their kinetic energies in ``frame``; their
        ``potential_energy`` attributes are summed into V unless
        ``potential_energy`` or ``force_function`` is given.
    constraints : sequence of Vector or expressions
        Velocity constraints; a vector stands for its components along
        ``frame.x, frame.y, frame.z`` that do not vanish identically (a rolling
        constraint "contact-point velocity = 0" gives two).
    dependent : sequence of dynamicsymbols
        One dependent coordinate per (non-vanishing) constraint.
    loads : sequence of (Point, force) or (ReferenceFrame, torque)
        Applied loads; ``Q_s = F · ∂v_P/∂q̇_s`` and ``τ · ∂ω/∂q̇_s``.
    holonomic : mapping, optional
        Holonomic constraints ``{q_dep: f}`` with ``f(q, t) = 0``, as for
        :class:`System`; ``f`` may be a SymPy expression or a mechanics Vector
        with exactly one component along ``frame.x, frame.y, frame.z`` that does
        not vanish identically, which is then ``f``: e.g. ``P.pos_from(S)`` for a
        point P that stays on a surface and the surface's point S below it, so
        that only the normal component is left.
    """
    coords = tuple(coordinates)
    vars_ = Vars(coords)
    T = sp.S.Zero
    for k, body in enumerate(bodies):
        if not isinstance(body, (RigidBody, Particle)):
            raise SystemDefinitionError(f"bodies[{k}]: {body!r} is not a RigidBody or Particle.")
        T += body.kinetic_energy(frame)
    if potential_energy is None and force_function is None:
        V = sum((getattr(b, "potential_energy", 0) or 0 for b in bodies), sp.S.Zero)
        potential_energy = V if V != 0 else None
    exprs = _constraint_expressions(constraints, frame, vars_)
    if len(exprs) != len(dependent):
        raise SystemDefinitionError(
            f"constraints: {len(exprs)} non-vanishing constraint component(s) but "
            f"{len(dependent)} dependent coordinate(s); give one dependent coordinate per component."
        )
    forces = _generalized_forces(loads, frame, coords)
    return System(
        coords,
        T,
        exprs,
        dependent=dependent,
        potential_energy=potential_energy,
        force_function=force_function,
        forces=forces or None,
        holonomic=_relations(holonomic, frame, vars_),
        name=name,
    )
