"""Gallery systems against their known physics (sources in the constructors' docstrings)."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols

from chaplygin import compare_models, examples

t = dynamicsymbols._t


def test_chaplygin_sleigh_reduced_dynamics() -> None:
    """v̇ = a ω², ω̇ = −m a v ω / (I + m a²) (Bloch 2003, §1.7)."""
    s = examples.chaplygin_sleigh()
    x, y, th = s.coordinates
    m, I, a = s.parameter("m"), s.parameter("I"), s.parameter("a")
    acc = s.equations("chetaev").accelerations
    v = x.diff(t) * sp.cos(th) + y.diff(t) * sp.sin(th)
    w = th.diff(t)
    assert sp.simplify((v.diff(t).xreplace(acc) - a * w**2).xreplace(s.constraints)) == 0
    assert sp.simplify((acc[th.diff(t, 2)] + m * a * v * w / (I + m * a**2)).xreplace(s.constraints)) == 0
    assert not s.integrability().integrable


def test_sleigh_settles_to_straight_motion() -> None:
    """The sleigh's turning rate dies out and its speed tends to sqrt(2E/m) (Bloch 2003, §1.7)."""
    s = examples.chaplygin_sleigh(m=1, I=1, a=1)
    # a gentle start keeps the heading away from θ = π/2, the pole of the split ẏ = tan θ ẋ
    tr = s.simulate("chaplygin", 60.0, {"x": 0, "y": 0, "theta": 0, "x'": 1.0, "theta'": 0.3}, samples=61)
    assert tr.success and tr.energy_drift() < 1e-9
    assert abs(tr["theta'"][-1]) < 1e-3
    speed = np.hypot(tr["x'"][-1], tr["y'"][-1])
    assert speed == pytest.approx(np.sqrt(2 * tr.energy[0]), rel=1e-4)


def test_turntable_ball_centre_velocity_rotates_at_two_sevenths_omega() -> None:
    """ẍ = −(2/7)Ω ẏ, ÿ = (2/7)Ω ẋ: the centre circles with angular frequency 2Ω/7 (Pars 1965, §8.6)."""
    s = examples.turntable_ball()
    assert s.is_affine and not s.is_chaplygin
    X, Y = s.dependent
    W = s.parameter("Omega")
    acc = s.equations("chetaev").accelerations
    assert sp.simplify(acc[X.diff(t, 2)].xreplace(s.constraints) + sp.Rational(2, 7) * W * s.constraints[Y.diff(t)]) == 0
    assert sp.simplify(acc[Y.diff(t, 2)].xreplace(s.constraints) - sp.Rational(2, 7) * W * s.constraints[X.diff(t)]) == 0


def test_heisenberg_true_lines_and_vakonomic_circles() -> None:
    """Chetaev: straight lines; vakonomic: ẍ = −c ẏ, ÿ = c ẋ, circles (sub-Riemannian geodesics;
    Bloch 2003, §7.3; Montgomery 2002)."""
    s = examples.heisenberg()
    x, y, z = s.coordinates
    true = s.equations("chetaev").accelerations
    assert true[x.diff(t, 2)] == 0 and true[y.diff(t, 2)] == 0
    fam = s.equations("vakonomic_family").accelerations
    (c,) = s.equations("vakonomic_family").constants
    assert sp.simplify(fam[x.diff(t, 2)] + c * y.diff(t)) == 0
    assert sp.simplify(fam[y.diff(t, 2)] - c * x.diff(t)) == 0
    # T does not depend on ż, so the Lindelöf defect vanishes: c = 0 gives the true lines too,
    # and only the members c ≠ 0 of the vakonomic family bend into circles
    assert compare_models(s).verdict == "lindelof_right_here"


def test_contact_oscillator_conserves_energy() -> None:
    """ẋ + y ż = 0 with H = ½|v|² + ½|q|² + ½ε x² z² (McLachlan & Perlmutter 2006)."""
    s = examples.contact_oscillator(eps=sp.Rational(1, 100))
    assert not s.integrability().integrable
    tr = s.simulate("voronets", 100.0, {"x": 0.0, "y": 1.0, "z": 0.5, "y'": 0.2, "z'": 0.4}, samples=101)
    assert tr.success and tr.energy_drift() < 1e-9 and np.max(tr.constraint_residual) < 1e-9


def test_differential_drive_wheels_spin_freely() -> None:
    """Without torques and with the centre of mass on the axle, each wheel keeps its speed."""
    s = examples.differential_drive()
    acc = s.equations("voronets").accelerations
    assert set(acc.values()) == {0}


def test_chaplygin_ball_conserves_contact_angular_momentum() -> None:
    """K = Iω + m a² γ × (ω × γ) is constant in space (Chaplygin 1903; Borisov & Mamaev 2002)."""
    s = examples.chaplygin_ball(m=1, a=1, A=sp.Rational(3, 10), B=sp.Rational(4, 10), C=sp.Rational(5, 10))
    start = {"psi": 0.2, "theta": 1.1, "phi": 0.3, "x": 0, "y": 0, "psi'": 0.4, "theta'": -0.3, "phi'": 0.8}
    tr = s.simulate("chaplygin", 20.0, start, samples=41)
    assert tr.success and tr.energy_drift() < 1e-9
    K = contact_momentum(tr, inertia=np.diag([0.3, 0.4, 0.5]), m=1.0, a=1.0)
    assert np.max(np.abs(K - K[0])) < 1e-8


def rotation(psi: float, theta: float, phi: float) -> np.ndarray:
    """Body → space for z-x-z Euler angles: Rz(ψ) Rx(θ) Rz(φ)."""
    def rz(u: float) -> np.ndarray:
        return np.array([[np.cos(u), -np.sin(u), 0], [np.sin(u), np.cos(u), 0], [0, 0, 1]])
    rx = np.array([[1, 0, 0], [0, np.cos(theta), -np.sin(theta)], [0, np.sin(theta), np.cos(theta)]])
    return rz(psi) @ rx @ rz(phi)


def contact_momentum(tr, inertia: np.ndarray, m: float, a: float) -> np.ndarray:
    out = []
    for k in range(len(tr.t)):
        psi, theta, phi = tr["psi"][k], tr["theta"][k], tr["phi"][k]
        dpsi, dtheta, dphi = tr["psi'"][k], tr["theta'"][k], tr["phi'"][k]
        w = np.array([dtheta * np.cos(psi) + dphi * np.sin(theta) * np.sin(psi),
                      dtheta * np.sin(psi) - dphi * np.sin(theta) * np.cos(psi),
                      dpsi + dphi * np.cos(theta)])
        R = rotation(psi, theta, phi)
        gamma = np.array([0.0, 0.0, 1.0])
        out.append(R @ inertia @ R.T @ w + m * a**2 * (w - w.dot(gamma) * gamma))
    return np.array(out)


@pytest.mark.parametrize("n", [1, 2])
def test_sleigh_chain_scales_and_conserves_energy(n: int) -> None:
    s = examples.sleigh_chain(n)
    assert s.n == n + 3 and s.g == n + 1 and s.epsilon == 2
    params = {"m": 1.0, "I": 0.5, "L": 1.0}
    start = {"x": 0.0, "y": 0.0, **{f"theta{i}": 0.1 * i for i in range(n + 1)}, "x'": 1.0, "theta0'": 0.05}
    # the lead heading stays far from θ0 = π/2, the pole of the split ẏ = tan θ0 ẋ
    tr = s.simulate("voronets", 10.0, start, params, samples=21)
    assert tr.success and tr.energy_drift() < 1e-9
