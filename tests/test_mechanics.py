"""Interop: systems built from sympy.physics.mechanics objects equal the hand-written ones."""

from __future__ import annotations

import pytest
import sympy as sp
from sympy.physics.mechanics import (
    Particle,
    Point,
    ReferenceFrame,
    RigidBody,
    dynamicsymbols,
    inertia,
)

from chaplygin import SystemDefinitionError, equivalent, examples
from chaplygin.io.mechanics import from_mechanics
from test_rolling_disk import Mechanics

t = dynamicsymbols._t


def mechanics_disk(gravity_as_load: bool):
    """The rolling disk of the KanesMethod oracle (tests/test_rolling_disk.py), through from_mechanics."""
    disk = Mechanics()
    m, r, _, _, g = disk.params
    psi, theta, phi, x, y = disk.q
    kwargs = (
        {"loads": [(disk.centre, -m * g * disk.N.z)]}
        if gravity_as_load
        else {"potential_energy": m * g * r * sp.cos(theta)}
    )
    # its slip velocity, all three components: the vertical one vanishes and is dropped
    return from_mechanics(
        disk.N, disk.q, [disk.disk], disk.slip, dependent=[x, y], name="mechanics disk", **kwargs
    )


@pytest.mark.parametrize("gravity_as_load", [False, True])
def test_rolling_disk_from_mechanics(gravity_as_load: bool) -> None:
    built = mechanics_disk(gravity_as_load)
    assert built.g == 2 and built.is_chaplygin  # the vertical slip component vanished
    reference = examples.rolling_disk()
    assert sp.simplify(built.kinetic_energy - reference.kinetic_energy) == 0
    # same dynamics: evaluate the built system's equations in the reference system
    eqs = built.equations("chetaev").residuals[: built.n]
    assert equivalent(reference, eqs, reference.equations("chaplygin"), symbolic=False)


def test_from_mechanics_keeps_the_bodies_expressions() -> None:
    """T and the constraints go to System as the bodies give them: System reads them through
    SymEngine, and SymPy's expand of them was most of from_mechanics' time (the Whipple
    bicycle: 5.8 s → 1.0 s to build); the derived equations are the same (the test above)."""
    disk = Mechanics()
    built = mechanics_disk(False)
    assert built.kinetic_energy == disk.disk.kinetic_energy(disk.N)
    assert built.kinetic_energy != sp.expand(built.kinetic_energy)
    assert built._given_constraints == tuple(disk.slip[:2])  # the vertical one vanishes


def test_knife_edge_from_mechanics() -> None:
    x, y, phi = q = dynamicsymbols("x y phi")
    m, J = sp.symbols("m J", positive=True)
    N = ReferenceFrame("N")
    B = N.orientnew("B", "Axis", [phi, N.z])
    O = Point("O")
    P = O.locatenew("P", x * N.x + y * N.y)
    P.set_vel(N, P.pos_from(O).dt(N))
    blade = RigidBody("blade", P, B, m, (inertia(B, 0, 0, J), P))
    built = from_mechanics(N, q, [blade], [P.vel(N).dot(B.y)], dependent=[y])
    reference = examples.knife_edge()
    assert equivalent(
        reference,
        built.equations("chetaev").residuals[:3],
        reference.equations("chetaev"),
        symbolic=False,
    )


def test_errors() -> None:
    x, y = q = dynamicsymbols("x y")
    N = ReferenceFrame("N")
    P = Point("P")
    P.set_vel(N, x.diff(t) * N.x + y.diff(t) * N.y)
    ball = Particle("ball", P, sp.Symbol("m"))
    with pytest.raises(SystemDefinitionError, match="2 non-vanishing constraint component"):
        from_mechanics(N, q, [ball], [P.vel(N)], dependent=[y])
    with pytest.raises(SystemDefinitionError, match="not a RigidBody or Particle"):
        from_mechanics(N, q, [P], [y.diff(t)], dependent=[y])
    with pytest.raises(SystemDefinitionError, match="loads\\[0\\]"):
        from_mechanics(N, q, [ball], [y.diff(t)], dependent=[y], loads=[(P, 1)])
