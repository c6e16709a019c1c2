"""Every expression handed out as ``Equations.accelerations``, evaluated in float64 as a user would.

A user takes ``system.equations(model, form).accelerations`` and ``sympy.lambdify``-s it with
NumPy.  Exactness of the expressions is checked elsewhere (test_models_property: every form
against the multiplier system); here the question is whether the *printed form* can be evaluated
in double precision.  Ground truth: the same expressions at 50 significant digits (mpmath, a tree
walk that shares no code with ``lambdify``), with the same double inputs.

The norm is Skeel's componentwise bound of the linear system ``M·x = F`` the accelerations solve,
``s = |M⁻¹| (|F| + |M|·|x|)`` (M, F at 50 digits): what perturbing every entry of ``M`` and ``F``
by one unit in its last place may change in each unknown, whatever form ``x`` is printed in.  A
component is accurate when its error is within ``TOL·(s_i + 10⁻⁶·max s)`` (the floor is for
unknowns that vanish identically).  Before the fix of issue 27 (common factors of the
denominators left uncancelled in the new forms), the snakeboard's ``chaplygin/new`` θ̈ was off by
130 % at φ = 0.05; the gallery and the random systems passed, away from such poles.
"""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st
from sympy.physics.mechanics import dynamicsymbols

from chaplygin import System, examples
from chaplygin.models.equations import Equations
from chaplygin.models.registry import MODELS
from randomsystems import Spec, seeded_system, systems, t

TOL = 1e-10
DPS = 50

_MP_FUNCTIONS = {
    sp.sin: mpmath.sin,
    sp.cos: mpmath.cos,
    sp.tan: mpmath.tan,
    sp.exp: mpmath.exp,
    sp.log: mpmath.log,
    sp.sqrt: mpmath.sqrt,
    sp.sinh: mpmath.sinh,
    sp.cosh: mpmath.cosh,
    sp.tanh: mpmath.tanh,
    sp.atan: mpmath.atan,
}


def exact(exprs: list[sp.Expr], values: dict[sp.Expr, float]) -> list[mpmath.mpf]:
    """Each of ``exprs`` at ``values`` with 50 significant digits (mpmath, memoised tree walk).

    A node that is a key of ``values`` takes its (double) value exactly; Rationals are exact,
    Floats keep their binary value; anything else goes through SymPy's ``evalf``.
    """
    with mpmath.workdps(DPS):
        memo: dict[sp.Expr, mpmath.mpf] = {k: mpmath.mpf(v) for k, v in values.items()}

        def value(e: sp.Expr) -> mpmath.mpf:
            if e in memo:
                return memo[e]
            if e.is_Rational:
                out = mpmath.mpf(int(e.p)) / int(e.q)
            elif e.is_Float:
                out = mpmath.mpf(e._mpf_)
            elif e.is_Add:
                out = mpmath.fsum(value(a) for a in e.args)
            elif e.is_Mul:
                out = mpmath.fprod(value(a) for a in e.args)
            elif e.is_Pow:
                base, exp = value(e.base), e.exp
                out = base ** int(exp) if exp.is_Integer else base ** value(exp)
            elif e.func in _MP_FUNCTIONS:
                out = _MP_FUNCTIONS[e.func](*(value(a) for a in e.args))
            else:
                hi = {k: sp.Float(v, DPS) for k, v in values.items()}
                out = mpmath.mpf(sp.N(e.xreplace(hi), DPS))
            memo[e] = out
            return out

        return [value(sp.sympify(e)) for e in exprs]


def applicable(system: System) -> list[tuple[str, str]]:
    """Every (model, form) of the registry that applies to ``system``."""
    return [
        (name, form)
        for name, model in MODELS.items()
        if model.obstruction(system) is None
        for form in model.forms
    ]


def random_inputs(
    system: System, eq: Equations, rng: np.random.Generator, coordinates: tuple[float, float]
) -> dict[sp.Expr, float]:
    """Doubles for t, the parameters (and constants c_β) — 17 significant digits, magnitudes
    10⁻² … 10² —, the coordinates, the independent velocities and the state multipliers; the
    dependent velocities from the constraints (at 50 digits, then rounded: an admissible state)."""
    vals: dict[sp.Expr, float] = {t: float(rng.uniform(0.2, 1.2))}
    vals.update({p: float(10 ** rng.uniform(-2, 2)) for p in [*system.parameters, *eq.constants]})
    vals.update({q: float(rng.uniform(*coordinates)) for q in system.coordinates})
    vals.update({q.diff(t): float(rng.uniform(-1, 1)) for q in system.independent})
    if eq.model == "vakonomic":
        vals.update({mu: float(rng.uniform(-1, 1)) for mu in eq.multipliers})
    return admissible(system, vals)


def admissible(system: System, vals: dict[sp.Expr, float]) -> dict[sp.Expr, float]:
    """``vals`` with the dependent velocities from the constraints."""
    rhs = list(system.constraints.values())
    for vel, v in zip(system.constraints, exact(rhs, vals)):
        vals[vel] = float(v)
    return vals


def float_errors(eq: Equations, vals: dict[sp.Expr, float]) -> np.ndarray:
    """Error of each lambdified (float64) acceleration against its 50-digit value, in units of
    the Skeel bound of ``M·x = F`` (see the module docstring)."""
    acc = eq.accelerations
    exprs = list(acc.values())
    args = list(vals)
    got = np.array(sp.lambdify(args, exprs, "numpy")(*vals.values()), dtype=float)
    n = len(eq.unknowns)
    with mpmath.workdps(DPS):
        truth = exact(exprs, vals)
        entries = exact([*eq.mass_matrix, *eq.forcing], vals)
        M = mpmath.matrix([entries[i * n : (i + 1) * n] for i in range(n)])
        F = mpmath.matrix(entries[n * n :])
        Mi = M**-1
        x = Mi * F
        absolute = lambda m: m.apply(abs)  # noqa: E731
        bound = absolute(Mi) * (absolute(F) + absolute(M) * absolute(x))
        order = {u: i for i, u in enumerate(eq.unknowns)}
        scale = np.array([float(bound[order[k]]) for k in acc])
        # the expressions are the solution of M·x = F: a wrong oracle would pass anything.  Exactly,
        # but with Float parameters: there the solution's numbers are computed exactly from the
        # decimals the input's Floats were written as (17.9·44.8 is 801.92), then rounded once,
        # a change of the order of float64's own rounding of the same expression
        solution = [x[order[k]] for k in acc]
        slack = TOL if _has_floats(eq) else 1e-20
        assert all(abs(a - b) <= slack * (s + 1) for a, b, s in zip(truth, solution, scale)), (
            eq,
            truth,
            solution,
        )
        truth_f = np.array([float(v) for v in truth])
    floor = max(1e-6 * float(scale.max(initial=0.0)), 1e-300)
    return np.abs(got - truth_f) / (scale + floor)


def _has_floats(eq: Equations) -> bool:
    """Whether the system was written with Float numbers (they show in ``M`` or ``F``)."""
    return any(e.has(sp.Float) for e in [*eq.mass_matrix, *eq.forcing])


def assert_accurate(
    system: System, model: str, form: str, rng: np.random.Generator, coordinates: tuple[float, float]
) -> None:
    eq = system.equations(model, form)
    vals = random_inputs(system, eq, rng, coordinates)
    err = float_errors(eq, vals)
    assert err.max(initial=0.0) <= TOL, (system.name, model, form, err, {str(k): v for k, v in vals.items()})


# ---------------------------------------------------------------- a snakeboard, as a user writes it
x, y, theta, psi, phi = dynamicsymbols("x y theta psi phi")


SNAKEBOARD_PARAMETERS = sp.symbols("m J J_0 J_1 r", positive=True)


def snakeboard(values: tuple[float, ...] | None = None) -> System:
    """The snakeboard (Bloch, *Nonholonomic Mechanics and Control*, §1.11; Ostrowski): a board at
    (x, y) with heading θ, a rotor ψ at its centre, wheel axles at ±r along the board turned by
    ±φ; no slip sideways at either axle.  x, y dependent: the split is singular at φ = 0
    (parallel wheels), so every form carries the factor sin 2φ = 0 in its denominators.
    ``values``: m, J, J₀, J₁, r as Floats written into T and the constraints (as a user writes
    numbers), else symbols."""
    m, J, J0, J1, r = SNAKEBOARD_PARAMETERS if values is None else [sp.Float(v) for v in values]
    d = lambda q: q.diff(t)  # noqa: E731
    T = (
        m / 2 * (d(x) ** 2 + d(y) ** 2)
        + J / 2 * d(theta) ** 2
        + J0 / 2 * (d(theta) + d(psi)) ** 2
        + J1 / 2 * ((d(theta) + d(phi)) ** 2 + (d(theta) - d(phi)) ** 2)
    )
    wheels = [
        -sp.sin(theta + phi) * d(x) + sp.cos(theta + phi) * d(y) + r * sp.cos(phi) * d(theta),
        -sp.sin(theta - phi) * d(x) + sp.cos(theta - phi) * d(y) - r * sp.cos(phi) * d(theta),
    ]
    name = "snakeboard" if values is None else "snakeboard, float parameters"
    return System([x, y, theta, psi, phi], T, wheels, dependent=[x, y], name=name)


def snakeboard_state(system: System, eq: Equations, rng: np.random.Generator, angle: float) -> dict:
    """A regular motion near parallel wheels: φ = ``angle``, θ̇ ∝ tan φ (finite ẋ, ẏ)."""
    vals = random_inputs(system, eq, rng, coordinates=(0.2, 1.2))
    vals[phi] = angle
    vals[theta.diff(t)] = float(0.8 * math.tan(angle) * rng.uniform(0.5, 1.5))
    return admissible(system, vals)


@pytest.fixture(scope="module")
def board() -> System:
    return snakeboard()


def test_snakeboard_new_form_is_accurate_near_parallel_wheels(board: System) -> None:
    """Issue 27 (2): chaplygin/new's θ̈ lambdified in float64 was 1.108 against the exact 0.4799
    at φ = 0.05 (m = 2.3, J = 0.31, J₀ = 0.12, J₁ = 0.05, r = 0.4): numerator and denominator
    shared sin 2φ-type factors of the denominators, rewritten by sin² + cos² = 1 past
    recognition, and both vanished together in a 100,000-character expression."""
    eq = board.equations("chaplygin", "new")
    pars = dict(zip(sp.symbols("m J J_0 J_1 r", positive=True), (2.3, 0.31, 0.12, 0.05, 0.4)))
    for angle in (0.05, 0.07, 0.1):
        vals = {t: 0.0, x: 0.1, y: 0.2, theta: 0.7, psi: 0.3, phi: angle, **pars}
        vals.update({theta.diff(t): 0.8 * math.tan(angle), psi.diff(t): -0.4, phi.diff(t): 0.6})
        vals = admissible(board, vals)
        exprs = list(eq.accelerations.values())
        got = np.array(sp.lambdify(list(vals), exprs, "numpy")(*vals.values()), dtype=float)
        truth = np.array([float(v) for v in exact(exprs, vals)])
        assert np.max(np.abs(got - truth)) <= TOL * np.max(np.abs(truth)), (angle, got, truth)
    assert sum(len(str(e)) for e in eq.accelerations.values()) < 20_000  # 100,238 characters before


@pytest.mark.parametrize("model,form", applicable(snakeboard()))
def test_snakeboard_every_form_near_parallel_wheels(board: System, model: str, form: str) -> None:
    rng = np.random.default_rng(27)
    eq = board.equations(model, form)
    for angle in (0.05, 0.1):
        vals = snakeboard_state(board, eq, rng, angle)
        err = float_errors(eq, vals)
        assert err.max() <= TOL, (model, form, angle, err)


@pytest.mark.parametrize("model", ["chaplygin", "voronets"])
def test_snakeboard_classic_form_vanishing_forcing(board: System, model: str) -> None:
    """A heavy, long board (m ≈ 18, r ≈ 45, ẋ ≈ 32): the classic form's φ̈ is 0 exactly, but its
    forcing, too large for the expanded solve, was printed as 2,300 characters of terms that cancel
    only exactly, and ``lambdify`` gave φ̈ = −4·10⁻⁸ beside θ̈ = −0.92."""
    eq = board.equations(model, "classic")
    names = sp.symbols("m J J_0 J_1 r", positive=True)
    pars = (
        17.909396718478327,
        0.11999049779393503,
        0.014584585665958869,
        0.011644223751767876,
        44.7736303184423,
    )
    vals = {t: 0.84, x: 0.81, y: 0.93, theta: 0.7436249914654229, psi: 1.1350724237877683, phi: 0.01}
    vals.update(dict(zip(names, pars)))
    vals.update(
        {
            theta.diff(t): 0.009837571492675458,
            psi.diff(t): 0.7148085531751387,
            phi.diff(t): -0.9328288493890713,
        }
    )
    err = float_errors(eq, admissible(board, vals))
    assert err.max() <= TOL, err


#: the outside reviewer's board (review of 1300154, defect 2): m, J, J₀, J₁, r
REVIEWED = (17.9, 270.0, 3.1e-3, 1.3e-5, 44.8)


@pytest.fixture(scope="module")
def float_board() -> System:
    return snakeboard(REVIEWED)


@pytest.mark.parametrize("model,form", applicable(snakeboard(REVIEWED)))
def test_snakeboard_float_parameters_every_form(float_board: System, model: str, form: str) -> None:
    """Review defect 2: with m, J, J₀, J₁, r written into the System as Floats, the classic
    forms' φ̈ (0 exactly) came out −69.5 beside θ̈ = −1080 at the reviewer's state (φ = 0.001):
    each Float, its negative, 1.0 and 2.0 were independent kernels of the exact solve, nothing
    cancelled, and the nested fallback printed a forcing that vanishes only exactly.  Every
    model and form, at that state and near parallel wheels."""
    eq = float_board.equations(model, form)
    rng = np.random.default_rng(2)
    vals = random_inputs(float_board, eq, rng, coordinates=(0.2, 1.2))  # t, x, y, c_β, μ_β
    vals.update({theta: 1.5773129029984254, psi: 1.7384858247705797, phi: 0.001})
    vals.update(
        {
            theta.diff(t): -0.584852088633586,
            psi.diff(t): 1.9239062922885064,
            phi.diff(t): 1.847603751592903,
        }
    )
    states = [admissible(float_board, vals), snakeboard_state(float_board, eq, rng, 0.05)]
    for vals in states:
        err = float_errors(eq, vals)
        assert err.max() <= TOL, (model, form, vals[phi], err)


@pytest.mark.parametrize("model", ["chaplygin", "voronets"])
def test_snakeboard_classic_forcing_that_vanishes_is_zero(
    board: System, float_board: System, model: str
) -> None:
    """Review defect 2, the simulation: the compiled right-hand sides solve ``M·x = F`` in float64,
    and the classic forms' φ row of F (0 exactly: 2J₁φ̈ = 0) was a nested sum that cancels only
    exactly — ``simulate(form="classic")`` took 8 s (symbolic parameters) and ended with
    φ̇ = 3·10⁻⁸ from φ̇ = 0, t = 0.01.  Now 0 in float64, with the mass matrix's row 2J₁φ̈."""
    vals = {t: 0.3, x: 0.1, y: 0.2, theta: 1.5773129029984254, psi: 1.7384858247705797, phi: 0.001}
    vals.update({theta.diff(t): -0.584852088633586, psi.diff(t): 1.9239062922885064, phi.diff(t): 1.85})
    for system, pars in ((board, dict(zip(SNAKEBOARD_PARAMETERS, REVIEWED))), (float_board, {})):
        eq = system.equations(model, "classic")
        state = admissible(system, {**vals, **pars})
        row = list(eq.unknowns).index(phi.diff(t, 2))
        assert abs(exact([eq.forcing[row]], state)[0]) < 1e-30  # the premise: 0 (to 50 digits)
        got = sp.lambdify(list(state), eq.forcing[row], "numpy")(*state.values())
        assert got == 0.0, (system.name, got)


# ---------------------------------------------------------------- the gallery
GALLERY = {
    "knife edge": lambda: examples.knife_edge(),
    "knife edge, float parameters": lambda: examples.knife_edge(m=0.1234567890123456, J=37.21490017536941),
    "Chaplygin sleigh": lambda: examples.chaplygin_sleigh(),
    "rolling disk": lambda: examples.rolling_disk(),
    "rolling disk, float parameters": lambda: examples.rolling_disk(
        m=1.7000000000000002, r=0.30000000000000004, A=0.0038250000000000003, C=0.07650000000000001, g=9.81
    ),
    "turntable ball (affine)": lambda: examples.turntable_ball(),
    "differential drive": lambda: examples.differential_drive(),
    "contact oscillator": lambda: examples.contact_oscillator(),
    # sp.Float arguments stay Floats in the System (Python floats are made rationals)
    "Chaplygin sleigh, Float parameters": lambda: examples.chaplygin_sleigh(*floats(2.7, 0.0834, 0.31)),
    "differential drive, Float parameters": lambda: examples.differential_drive(
        *floats(4.1, 0.27, 3.6e-3, 0.05, 0.18)
    ),
    "rolling disk, Float parameters": lambda: examples.rolling_disk(*floats(1.7, 0.3, 0.038, 0.077, 9.81)),
}


def floats(*values: float) -> list[sp.Float]:
    return [sp.Float(v) for v in values]


@pytest.mark.parametrize("name", list(GALLERY))
def test_gallery_accelerations_in_float64(name: str) -> None:
    system = GALLERY[name]()
    rng = np.random.default_rng(2)
    for model, form in applicable(system):
        assert_accurate(system, model, form, rng, coordinates=(-3.0, 3.0))


# ---------------------------------------------------------------- random systems
@settings(max_examples=6)
@given(spec=systems().filter(lambda spec: spec.system.n <= 3), seed=st.integers(0, 2**32 - 1))
def test_random_systems_accelerations_in_float64(spec: Spec, seed: int) -> None:
    """Random T, constraints (form A or B, affine, time-dependent), forces; every model and form.

    Up to 3 coordinates: a 4-coordinate system's nested solutions (300,000 characters) take 2 s
    each to evaluate at 50 digits."""
    rng = np.random.default_rng(seed)
    for model, form in applicable(spec.system):
        assert_accurate(spec.system, model, form, rng, coordinates=(-1.5, 1.5))


@pytest.mark.parametrize("seed", [11])
def test_random_systems_written_with_floats(seed: int) -> None:
    """Seeded random systems with coefficients of 15–17 significant digits, written into the
    System as Floats, the parameter too (:func:`with_floats`): every model and form.  (Seed 19,
    3 coordinates, took 88 s to derive and check before Floats were read as decimals, 3.9 s now.)"""
    system = seeded_system(seed, floats=True).system
    system = with_floats(system, {p: 3.7 for p in system.parameters})
    rng = np.random.default_rng(seed)
    for model, form in applicable(system):
        assert_accurate(system, model, form, rng, coordinates=(-1.5, 1.5))


def with_floats(system: System, values: dict[sp.Symbol, float]) -> System:
    """``system`` with ``values`` written into it as Floats, and its other numbers but the integers
    as Floats too (½ as 0.5): as a user writes a system with float literals."""

    def put(e: sp.Expr) -> sp.Expr:
        numbers = {r: sp.Float(r) for r in e.atoms(sp.Rational) if not r.is_Integer}
        return e.xreplace({**numbers, **{p: sp.Float(v) for p, v in values.items()}})

    constraints: dict | list = (
        {v: put(e) for v, e in system.constraints.items()}
        if system.constraint_form == "B"
        else [put(e) for e in system.implicit_constraints]
    )
    return System(
        system.coordinates,
        put(system.kinetic_energy),
        constraints,
        dependent=system.dependent,
        force_function=put(system.force_function),
        forces={q: put(f) for q, f in system.forces.items()},
        name=f"{system.name}, Float parameters",
    )
