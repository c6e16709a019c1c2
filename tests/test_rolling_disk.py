"""The rolling disk of ``chaplygin.examples.rolling_disk`` against independent oracles.

Nothing here is computed by chaplygin except the quantities under test:

* the kinetic energy, the potential and the no-slip constraints are rebuilt with
  ``sympy.physics.mechanics`` (frames, points, a rigid body, the velocity of the
  disk's material point at the contact);
* the dynamics are derived a second time with ``KanesMethod`` (dependent speeds,
  velocity constraints) and compared at random admissible states;
* energy conservation uses the mechanics kinetic energy.

Conventions (see the docstring of ``rolling_disk``): N --ψ about N.z--> Y --θ about
Y.x--> L --φ about L.y--> disk; contact point (x, y, 0), centre at contact + r L.z.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from sympy.physics.mechanics import (
    KanesMethod,
    Point,
    ReferenceFrame,
    RigidBody,
    dynamicsymbols,
    inertia,
)

from chaplygin import examples

t = dynamicsymbols._t
SAMPLES = 12
RTOL = 1e-9


# --------------------------------------------------------------------------- oracle
class Mechanics:
    """The rolling disk built with sympy.physics.mechanics, with its own symbols."""

    def __init__(self) -> None:
        self.q = dynamicsymbols("psi theta phi x y")  # same names: same dynamicsymbols
        self.qd = [qi.diff(t) for qi in self.q]
        self.qdd = [qi.diff(t, 2) for qi in self.q]
        psi, theta, phi, x, y = self.q
        self.params = sp.symbols("m r A C g", positive=True)
        m, r, A, C, g = self.params

        N = ReferenceFrame("N")
        Y = N.orientnew("Y", "Axis", [psi, N.z])
        L = Y.orientnew("L", "Axis", [theta, Y.x])
        D = L.orientnew("D", "Axis", [phi, L.y])
        origin = Point("O")
        origin.set_vel(N, 0)
        contact = origin.locatenew("P", x * N.x + y * N.y)
        centre = contact.locatenew("G", r * L.z)
        centre.set_vel(N, centre.pos_from(origin).dt(N))
        disk = RigidBody("disk", centre, D, m, (inertia(L, A, C, A), centre))
        self.N, self.centre, self.disk = N, centre, disk

        self.T = disk.kinetic_energy(N)  # unconstrained: x', y' free
        self.V = m * g * centre.pos_from(origin).dot(N.z)
        # no slip: the material point of the disk at the contact has zero velocity
        slip = centre.vel(N) + D.ang_vel_in(N).cross(contact.pos_from(centre))
        self.slip = [slip.dot(N.x), slip.dot(N.y), slip.dot(N.z)]
        sol = sp.solve(self.slip[:2], [x.diff(t), y.diff(t)], dict=True)
        assert len(sol) == 1
        self.constraints = sol[0]  # {x': ..., y': ...}
        self.T_reduced = self.T.subs(self.constraints)

        # plain symbols for numerics: q, q', q'' -> Q, U, W
        self.Q = sp.symbols("Q0:5")
        self.U = sp.symbols("U0:5")
        self.W = sp.symbols("W0:5")
        self._plain = {}
        for f, s0, s1, s2 in zip(self.q, self.Q, self.U, self.W):
            self._plain[f.diff(t, 2)] = s2
            self._plain[f.diff(t)] = s1
            self._plain[f] = s0

    def plain(self, expr):
        return expr.xreplace(self._plain)

    def lambdify(self, expr, extra=()):
        return sp.lambdify([*self.Q, *self.U, *extra, *self.params], self.plain(expr), "numpy", cse=True)

    def kanes_method(self):
        """KanesMethod with u_i = q_i'; u4, u5 (x', y') dependent through the no-slip constraints."""
        u = dynamicsymbols("u1:6")
        to_u = dict(zip(self.qd, u))
        kd = [qd - ui for qd, ui in zip(self.qd, u)]
        vc = [sp.expand(c.xreplace(to_u)) for c in self.slip[:2]]
        km = KanesMethod(
            self.N, q_ind=self.q, u_ind=u[:3], kd_eqs=kd, u_dependent=u[3:], velocity_constraints=vc
        )
        m, g = self.params[0], self.params[4]
        km.kanes_equations([self.disk], [(self.centre, -m * g * self.N.z)])
        # u_i = q_i': the state of the full system (q, u) maps onto (q, q')
        back = dict(zip(u, self.U))
        M = self.plain(km.mass_matrix_full).xreplace(back)
        F = self.plain(km.forcing_full).xreplace(back)
        return sp.lambdify([*self.Q, *self.U, *self.params], [M, F], "numpy", cse=True)


@pytest.fixture(scope="module")
def mech() -> Mechanics:
    return Mechanics()


@pytest.fixture(scope="module")
def disk():
    return examples.rolling_disk()


@pytest.fixture(scope="module")
def states(mech):
    """Random admissible states (q, q', parameters); q' of x, y from the mechanics constraints."""
    rng = np.random.default_rng(1996)
    dep = [mech.lambdify(mech.constraints[qd]) for qd in mech.qd[3:]]
    out = []
    for _ in range(SAMPLES):
        q = np.array(
            [
                rng.uniform(-np.pi, np.pi),
                rng.uniform(-1.2, 1.2),
                rng.uniform(-np.pi, np.pi),
                *rng.uniform(-2, 2, size=2),
            ]
        )
        qd = np.concatenate([rng.uniform(-2, 2, size=3), [0.0, 0.0]])
        p = np.array(
            [
                rng.uniform(0.5, 2.0),
                rng.uniform(0.3, 1.5),
                rng.uniform(0.1, 2.0),
                rng.uniform(0.1, 2.0),
                rng.uniform(5.0, 15.0),
            ]
        )
        qd[3:] = [f(*q, *qd, *p) for f in dep]
        out.append((q, qd, p))
    return out


@pytest.fixture(scope="module")
def kane(mech, states):
    """KanesMethod accelerations q'' at every sampled state."""
    f = mech.kanes_method()
    out = []
    for q, qd, p in states:
        M, F = f(*q, *qd, *p)
        x = np.linalg.solve(np.asarray(M, float), np.asarray(F, float).ravel())
        np.testing.assert_allclose(x[:5], qd, rtol=1e-12, atol=1e-12)  # q' = u
        out.append(x[5:])
    return out


def user_params(disk, mech):
    """Map the example's parameter symbols onto the oracle's (same names, checked)."""
    names = [p.name for p in mech.params]
    assert sorted(p.name for p in disk.parameters) == sorted(names)
    return {disk.parameter(n): p for n, p in zip(names, mech.params)}


def assert_close(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    scale = max(1.0, float(np.max(np.abs(a))), float(np.max(np.abs(b))))
    np.testing.assert_allclose(a, b, rtol=RTOL, atol=RTOL * scale)


def solve_linear(disk, mech, eqs, states):
    """Solve the model's own M·x = F numerically at every state; returns the solutions
    and the model's unknowns (user symbols), in the order of ``eqs.unknowns``."""
    sub = user_params(disk, mech)
    f = sp.lambdify(
        [*mech.Q, *mech.U, *mech.params],
        [mech.plain(eqs.mass_matrix.xreplace(sub)), mech.plain(eqs.forcing.xreplace(sub))],
        "numpy",
        cse=True,
    )
    out = []
    for q, qd, p in states:
        M, F = f(*q, *qd, *p)
        out.append(np.linalg.solve(np.asarray(M, float), np.asarray(F, float).ravel()))
    return np.array(out), list(eqs.unknowns)


def pick(solutions, unknowns, wanted):
    index = {u: k for k, u in enumerate(unknowns)}
    return solutions[:, [index[w] for w in wanted]]


@pytest.fixture(scope="module")
def chetaev_numeric(disk, mech, states):
    """The n + g multiplier equations (6)/(35) of chaplygin, solved numerically."""
    eqs = disk.equations("chetaev")
    sol, unknowns = solve_linear(disk, mech, eqs, states)
    return pick(sol, unknowns, mech.qdd), pick(sol, unknowns, eqs.multipliers)


def dependent_accelerations(mech):
    """x'', y'' from the mechanics constraints differentiated in time (oracle), as
    functions of (q, q', ψ'', θ'', φ'', parameters)."""
    return [mech.lambdify(sp.diff(mech.constraints[qd], t), extra=mech.W[:3]) for qd in mech.qd[3:]]


# --------------------------------------------------------------------------- (a) model
def test_definition(disk, mech):
    assert [q.func.__name__ for q in disk.coordinates] == ["psi", "theta", "phi", "x", "y"]
    assert list(disk.coordinates) == list(mech.q)
    assert disk.dependent == tuple(mech.q[3:])
    assert disk.is_chaplygin, disk.chaplygin_obstructions
    user_params(disk, mech)


def test_kinetic_energy_unconstrained(disk, mech):
    sub = user_params(disk, mech)
    diff = disk.kinetic_energy.xreplace(sub) - mech.T
    assert sp.simplify(sp.expand(diff)) == 0


def test_kinetic_energy_on_constraints(disk, mech):
    sub = user_params(disk, mech)
    diff = disk.reduced_kinetic_energy.xreplace(sub) - mech.T_reduced
    assert sp.simplify(sp.expand(diff)) == 0


def test_potential_energy(disk, mech):
    sub = user_params(disk, mech)
    assert sp.simplify(disk.potential_energy.xreplace(sub) - mech.V) == 0


def test_constraints_are_no_slip(disk, mech):
    sub = user_params(disk, mech)
    assert sp.simplify(mech.slip[2]) == 0  # the contact stays on the plane identically
    got = {k: v.xreplace(sub) for k, v in disk.constraints.items()}
    assert set(got) == set(mech.constraints)
    for qd, expr in mech.constraints.items():
        assert sp.simplify(got[qd] - expr) == 0
    # form A, as the vanishing of the slip velocity itself
    for row, slip in zip(disk.implicit_constraints, mech.slip[:2]):
        assert sp.simplify(sp.expand(row.xreplace(sub) - slip)) == 0


def test_constraints_nonholonomic(disk, mech):
    """Independent Frobenius test: [X_psi, X_phi] leaves the constraint distribution."""
    Q = mech.Q
    X = {}
    for k in range(3):  # X_k = ∂_k + Σ_β B_βk ∂_{dep β}
        vec = [sp.S.Zero] * 5
        vec[k] = sp.S.One
        for b, qd in enumerate(mech.qd[3:]):
            vec[3 + b] = mech.plain(sp.diff(mech.constraints[qd], mech.qd[k]))
        X[k] = sp.Matrix(vec)

    def bracket(a, b):
        return b.jacobian(Q) * a - a.jacobian(Q) * b

    br = bracket(X[0], X[2]).applyfunc(sp.simplify)
    assert br[:3, 0] == sp.zeros(3, 1) and br[3:, 0] != sp.zeros(2, 1)
    assert disk.integrability().integrable is False


def test_numbers_for_parameters():
    s = examples.rolling_disk(m=2, r=0.5, A=sp.Rational(1, 8), C=0.25, g=9.81)
    assert s.parameters == ()
    assert s.is_chaplygin


# --------------------------------------------------------------------------- (b) dynamics
def test_chetaev_matches_kane(chetaev_numeric, kane):
    """The multiplier equations, solved numerically, against KanesMethod: all five q''."""
    for g_, k_ in zip(chetaev_numeric[0], kane):
        assert_close(g_, k_)


def friction(mech):
    """m a_G · N.x, m a_G · N.y as functions of (q, q', q'', parameters)."""
    m = mech.params[0]
    acc = mech.centre.acc(mech.N)
    return [mech.lambdify(m * acc.dot(e), extra=mech.W) for e in (mech.N.x, mech.N.y)]


def test_chetaev_multipliers_are_friction(mech, states, kane, chetaev_numeric):
    """λ_β is the horizontal contact force (R_x = λ_1, R_y = λ_2 with A_{β,dep β} = 1, and
    E_s(T) = Q_s + R_s): Newton's law for the centre gives it as m a_G · N.x, m a_G · N.y."""
    force = friction(mech)
    for (q, qd, p), k_, lam in zip(states, kane, chetaev_numeric[1]):
        assert_close(lam, [fn(*q, *qd, *k_, *p) for fn in force])


def test_chetaev_accelerations_match_kane(disk, mech, states, kane):
    """The symbolic solution ``.accelerations`` of the Chetaev model: q'' and λ."""
    eqs = disk.equations("chetaev")
    acc = eqs.accelerations
    assert set(acc) == {*mech.qdd, *eqs.multipliers}
    sub = user_params(disk, mech)
    fq = [mech.lambdify(acc[a].xreplace(sub)) for a in mech.qdd]
    fl = [mech.lambdify(acc[lm].xreplace(sub)) for lm in eqs.multipliers]
    force = friction(mech)
    for (q, qd, p), k_ in zip(states, kane):
        assert_close([fn(*q, *qd, *p) for fn in fq], k_)
        assert_close([fn(*q, *qd, *p) for fn in fl], [fn(*q, *qd, *k_, *p) for fn in force])


@pytest.mark.parametrize("form", ["classic", "new"])
def test_chaplygin_linear_system_matches_kane(disk, mech, states, kane, form):
    """Chaplygin's equations (15) / the new form (40): their M·x = F solved numerically."""
    sol, unknowns = solve_linear(disk, mech, disk.equations("chaplygin", form=form), states)
    assert set(unknowns) == set(mech.qdd[:3])
    for g_, k_ in zip(pick(sol, unknowns, mech.qdd[:3]), kane):
        assert_close(g_, k_[:3])


@pytest.fixture(scope="module")
def chaplygin_accelerations(disk, mech):
    """The symbolic solved accelerations of Chaplygin's equations (15), as numeric functions."""
    acc = disk.equations("chaplygin").accelerations
    assert set(acc) == set(mech.qdd[:3])
    sub = user_params(disk, mech)
    return [mech.lambdify(acc[a].xreplace(sub)) for a in mech.qdd[:3]]


def test_chaplygin_accelerations_match_kane(mech, states, kane, chaplygin_accelerations):
    dep = dependent_accelerations(mech)
    for (q, qd, p), k_ in zip(states, kane):
        ind = [f(*q, *qd, *p) for f in chaplygin_accelerations]
        full = ind + [f(*q, *qd, *ind, *p) for f in dep]
        assert_close(full, k_)


def test_upright_rolling_is_steady(mech, chaplygin_accelerations):
    """Known physics: an upright disk rolling straight at constant speed keeps doing so."""
    q = [0.3, 0.0, 0.1, 0.2, -0.4]
    qd = [0.0, 0.0, 2.0, 0.0, 0.0]
    p = [1.0, 0.5, 0.3, 0.6, 9.81]
    qd[3], qd[4] = 0.5 * 2.0 * np.cos(0.3), 0.5 * 2.0 * np.sin(0.3)
    assert np.allclose([f(*q, *qd, *p) for f in chaplygin_accelerations], 0.0, atol=1e-12)


# --------------------------------------------------------------------------- (c) energy
def test_energy_is_conserved(mech, states, chaplygin_accelerations):
    """d/dt (T + V) = 0 along Chaplygin's accelerations (T from sympy.physics.mechanics)."""
    E = mech.plain(mech.T_reduced + mech.V)  # T̃ + V: a function of q and the independent q'
    dE = sum(sp.diff(E, Q) * U for Q, U in zip(mech.Q, mech.U)) + sum(
        sp.diff(E, U) * W for U, W in zip(mech.U[:3], mech.W[:3])
    )
    f = sp.lambdify([*mech.Q, *mech.U, *mech.W[:3], *mech.params], dE, "numpy", cse=True)
    terms = sp.lambdify(
        [*mech.Q, *mech.U, *mech.W[:3], *mech.params],
        [sp.diff(E, U) * W for U, W in zip(mech.U[:3], mech.W[:3])],
        "numpy",
        cse=True,
    )
    for q, qd, p in states:
        acc = [fa(*q, *qd, *p) for fa in chaplygin_accelerations]
        scale = max(1.0, *np.abs(terms(*q, *qd, *acc, *p)))
        assert abs(f(*q, *qd, *acc, *p)) <= RTOL * scale
