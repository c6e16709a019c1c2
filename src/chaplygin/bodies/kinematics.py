"""From a rotation and an angular velocity to a rolling body's state, and back along a motion."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np
import sympy as sp

from chaplygin.bodies.builder import ANGLES, RollingBody
from chaplygin.core._symbols import TIME
from chaplygin.errors import InputError

__all__ = ["Motion", "initial_state", "motion"]


class Motion(NamedTuple):
    """A rolling body's motion over the samples of a trajectory.

    Attributes
    ----------
    t : ndarray (k,)
    R : ndarray (k, 3, 3)
        Rotation body → space.
    omega : ndarray (k, 3)
        Angular velocity, body components.
    centre : ndarray (k, 3)
        Centre of mass in space.
    contact : ndarray (k, 3)
        Contact point in space (on the plane: its z is 0 up to round-off).
    """

    t: np.ndarray
    R: np.ndarray
    omega: np.ndarray
    centre: np.ndarray
    contact: np.ndarray


def _require_body(system: Any) -> RollingBody:
    if not isinstance(system, RollingBody):
        raise InputError(
            f"system: {system!r} was not built by chaplygin.bodies.rolling_body; initial_state and motion need its body kinematics."
        )
    return system


def _angles_of(convention: str, R: np.ndarray) -> tuple[float, float, float]:
    """ψ, θ, φ with ``R = R_z(ψ) R_x(θ) R_3(φ) R_0`` (the branch with |θ| ≤ π/2, or θ ∈ [0, π] for Euler)."""
    third, R0 = ANGLES[convention]
    M = R @ np.array(R0.T.tolist(), dtype=float)
    if third == 1:  # R_z(ψ) R_x(θ) R_y(φ)
        s = M[2, 1]
        if abs(s) > 1 - 1e-12:
            raise InputError(
                f"R: this attitude is the singularity of the {convention!r} angles (cos θ = 0); choose another convention."
            )
        return float(np.arctan2(-M[0, 1], M[1, 1])), float(np.arcsin(s)), float(np.arctan2(-M[2, 0], M[2, 2]))
    c = M[2, 2]
    if abs(c) > 1 - 1e-12:
        raise InputError(
            "R: this attitude is the singularity of the 'euler' angles (sin θ = 0); choose another convention."
        )
    return float(np.arctan2(M[0, 2], -M[1, 2])), float(np.arccos(c)), float(np.arctan2(M[2, 0], M[2, 1]))


def _numbers(
    system: RollingBody, parameters: Mapping[Any, float] | None, where: str
) -> dict[sp.Symbol, float]:
    given = {str(k): v for k, v in (parameters or {}).items()}
    missing = [p.name for p in system.parameters if p.name not in given]
    if missing:
        raise InputError(f"{where}: no value for the parameter(s) {', '.join(missing)}.")
    return {p: float(given[p.name]) for p in system.parameters}


def _rotation_check(R: Any) -> np.ndarray:
    try:
        M = np.asarray(R, dtype=float)
    except (TypeError, ValueError):
        raise InputError("R: expected a 3 x 3 rotation matrix (body -> space).") from None
    if M.shape != (3, 3) or not np.all(np.isfinite(M)):
        raise InputError("R: expected a finite 3 x 3 rotation matrix (body -> space).")
    if np.max(np.abs(M.T @ M - np.eye(3))) > 1e-9 or np.linalg.det(M) < 0:
        raise InputError("R: not a rotation matrix (needs R^T R = 1 and det R = +1).")
    return M


def initial_state(
    system: RollingBody,
    *,
    R: Any,
    omega: Sequence[float],
    position: Sequence[float] = (0.0, 0.0),
) -> dict[str, float]:
    """An initial state for ``system.simulate``: attitude, angular velocity and position.

    Parameters
    ----------
    system : RollingBody
        Built by :func:`rolling_body`.
    R : 3 × 3 array
        Rotation body → space.
    omega : three numbers
        Angular velocity, **body** components.
    position : two numbers
        Horizontal position ``(x, y)`` of the centre of mass.

    Returns
    -------
    dict
        ``{"psi": …, "theta": …, "phi": …, "x": …, "y": …, "psi'": …, "theta'": …, "phi'": …}``;
        the dependent velocities ``x', y'`` follow from the constraints in ``simulate``.
    """
    body = _require_body(system)
    M = _rotation_check(R)
    w = np.asarray(omega, dtype=float).reshape(-1)
    if w.shape != (3,) or not np.all(np.isfinite(w)):
        raise InputError("omega: expected three finite numbers (body components of the angular velocity).")
    pos = np.asarray(position, dtype=float).reshape(-1)
    if pos.shape != (2,) or not np.all(np.isfinite(pos)):
        raise InputError("position: expected two finite numbers (x, y of the centre of mass).")
    psi, theta, phi = _angles_of(body.angles, M)
    q = body.coordinates[:3]
    rates = [qi.diff(TIME) for qi in q]
    J = body.omega_body.jacobian(rates)
    Jn = np.array(sp.lambdify(q, J, "numpy")(psi, theta, phi), dtype=float)
    qd = np.linalg.solve(Jn, w)
    return {
        "psi": psi,
        "theta": theta,
        "phi": phi,
        "x": float(pos[0]),
        "y": float(pos[1]),
        "psi'": float(qd[0]),
        "theta'": float(qd[1]),
        "phi'": float(qd[2]),
    }


def motion(system: RollingBody, trajectory: Any, parameters: Mapping[Any, float] | None = None) -> Motion:
    """Rotation, body angular velocity, centre of mass and contact point at every sample.

    Parameters
    ----------
    system : RollingBody
    trajectory : Trajectory
        From ``chaplygin.simulate(system, ...)``; its parameters are used unless ``parameters`` is given.
    parameters : mapping, optional

    Returns
    -------
    Motion
    """
    body = _require_body(system)
    values = _numbers(
        body, parameters if parameters is not None else getattr(trajectory, "parameters", None), "parameters"
    )
    q = body.coordinates[:3]
    qd = [qi.diff(TIME) for qi in q]
    sym = sp.symbols("_q1:4 _qd1:4")
    sub = dict(zip([*qd, *q], [*sym[3:], *sym[:3]]))
    args = [*sym, *values]

    def compile_(expr: sp.Matrix) -> Any:
        return sp.lambdify(args, expr.subs(sub), "numpy")

    try:
        cols = [
            np.asarray(trajectory[name], dtype=float)
            for name in ("psi", "theta", "phi", "psi'", "theta'", "phi'", "x", "y")
        ]
    except (KeyError, TypeError):
        raise InputError(
            "trajectory: expected a Trajectory of this system (columns psi, theta, phi, their rates, x, y)."
        ) from None
    k = cols[0].size
    pvals = list(values.values())
    R = np.empty((k, 3, 3))
    omega = np.empty((k, 3))
    contact = np.empty((k, 3))
    centre = np.empty((k, 3))
    fR, fw = compile_(body.rotation), compile_(body.omega_body)
    fP, fh = compile_(body.contact_body - body.center_of_mass), compile_(sp.Matrix([body.height]))
    for i in range(k):
        a = [c[i] for c in cols[:6]] + pvals
        R[i] = np.asarray(fR(*a), dtype=float)
        omega[i] = np.asarray(fw(*a), dtype=float).reshape(3)
        centre[i] = (cols[6][i], cols[7][i], float(np.asarray(fh(*a)).reshape(-1)[0]))
        contact[i] = centre[i] + R[i] @ np.asarray(fP(*a), dtype=float).reshape(3)
    return Motion(np.asarray(getattr(trajectory, "t", np.arange(k)), dtype=float), R, omega, centre, contact)
