"""The SymEngine path: Chetaev matrices, constraint splitting, the T check and the code printers.

Each is checked against an independent computation: the SymPy derivation of
the same system evaluated by ``randomsystems``' own ``xreplace`` + ``evalf``
oracle, SymPy's ``linear_coefficients``/``Poly``, and SymEngine's numerical
evaluation of the expressions the printers print.
"""

from __future__ import annotations

import math
import shutil
import subprocess

import numpy as np
import pytest
import symengine as se
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st
from sympy.physics.mechanics import dynamicsymbols
from sympy.printing.codeprinter import PrintMethodNotImplementedError

from chaplygin import System, examples
from chaplygin.core._native import chetaev_matrices, is_quadratic, linear_split, momenta
from chaplygin.core._symbols import linear_coefficients
from chaplygin.numeric._printing import code
from randomsystems import Spec, matrix, random_state, systems

t = dynamicsymbols._t


def _numbers(system: System, values: dict) -> dict:
    """``values`` (user symbols) for SymEngine's internal symbols; parameters by name."""
    nat = system._native
    out = {nat.t: float(values[t])}
    for q, x, xd in zip(system.coordinates, nat.x, nat.xd):
        out[x] = float(values[q])
        out[xd] = float(values[q.diff(t)])
    out.update({se.Symbol(p.name): float(values[p]) for p in system.parameters})
    return out


def _evaluate(exprs: list, numbers: dict) -> np.ndarray:
    return np.array([float(se.sympify(e).subs(numbers)) for e in exprs])


@given(spec=systems(), seed=st.integers(0, 2**32 - 1))
@settings(max_examples=15, deadline=None)
def test_chetaev_matrices_equal_the_sympy_derivation(spec: Spec, seed: int) -> None:
    """Form A and B, affine, time-dependent, with forces: (M, F) of eq. (6) agree at random states."""
    system = spec.system
    assert system._native is not None
    M, F = chetaev_matrices(system._native)
    eqs = system.equations("chetaev")
    values = random_state(system, np.random.default_rng(seed))
    numbers = _numbers(system, values)
    dim = system.n + system.g
    np.testing.assert_allclose(
        _evaluate([e for row in M for e in row], numbers).reshape(dim, dim),
        matrix(eqs.mass_matrix, values),
        rtol=1e-10,
        atol=1e-10,
    )
    np.testing.assert_allclose(
        _evaluate(F, numbers), matrix(eqs.forcing, values)[:, 0], rtol=1e-10, atol=1e-10
    )


@given(spec=systems())
@settings(max_examples=15, deadline=None)
def test_constraints_read_in_symengine_equal_sympys_split(spec: Spec) -> None:
    """A and A_0 (converted lazily from SymEngine in form A) equal SymPy's split of the same constraints."""
    system = spec.system
    phi = system._A * sp.Matrix(system._vars.xd) + system._A0
    for b in range(system.g):
        coeffs, rest = linear_coefficients(sp.expand(phi[b]), list(system._vars.xd))
        assert all(sp.expand(c - a) == 0 for c, a in zip(coeffs, system._A.row(b)))
        assert sp.expand(rest - system._A0[b]) == 0
    if system.constraint_form == "A":
        assert "_native_A" in system.__dict__


def test_a_form_a_chain_keeps_its_symbols_assumptions() -> None:
    chain = examples.sleigh_chain(3)
    assert "_A" not in chain.__dict__  # A is converted to SymPy only when SymPy needs it
    assert [p.name for p in chain.parameters] == ["I", "L", "m"]
    assert all(p.is_positive for p in chain.parameters)
    assert all(p.is_positive for p in chain._A.free_symbols & set(chain.parameters))
    assert chain._A.free_symbols & set(chain.parameters) == {chain.parameter("L")}


def test_linear_split_refuses_what_is_not_affine() -> None:
    x, v, w = se.symbols("x v w")
    coeffs, rest = linear_split(se.sin(x) * v + (v + 1) * (w - 2) - v * w, [v, w])
    assert se.expand(coeffs[0] - (se.sin(x) - 2)) == 0 and coeffs[1] == 1 and rest == -2
    assert linear_split(v * w + x, [v, w]) is None
    assert linear_split(se.cos(v), [v, w]) is None


def test_is_quadratic_against_poly() -> None:
    x, v, w, m = se.symbols("x v w m")

    def quadratic(T: se.Basic) -> tuple[bool, bool] | None:
        return is_quadratic(T, [v, w], *momenta(T, [v, w]))

    assert quadratic(m * v**2 / 2 + se.sin(x) * v * w + x * w) == (True, True)
    assert quadratic((v + se.cos(x) * w) ** 2 / (1 + x**2)) == (True, True)
    assert quadratic(x * v + 3) == (True, False)
    assert quadratic(se.Integer(0)) == (True, False)
    # not shown: SymPy's Poly decides (and refuses these, see test_validation)
    assert quadratic(v**3 + w**2) is None
    assert quadratic(se.sqrt(1 + v**2)) is None


# ------------------------------------------------------------------ printers
X, Y, Z = se.symbols("x y z")
POINT = {X: 1.7, Y: 1.3, Z: 0.4}
CASES = [
    se.sin(X) ** 2 * Y / 3,
    -X * Y / (Z + 1),
    X**-2,
    -(X**2),
    (X + Y) ** -3,
    se.sqrt(X) / Y,
    1 / se.sqrt(X * Y),
    (X - Y) ** se.Rational(1, 3),
    -se.Rational(3, 7) * X + Y - Z,
    se.exp(X * Y) - se.pi * X,
    se.atan2(X, Y) * se.Abs(Z),
    X**Y,
    -(X + Y) * (Z - X),
    se.RealDouble(-0.1) * X + se.RealDouble(1 / 3),
    se.Max(X, Y) - se.Min(X, Z),
    se.E ** (-X),
    2 / (X * Y),
    -2 / (X * Y**2),
    X * Y**-1 * Z**-2,
    se.cosh(X) / se.tanh(Y),
    se.Integer(-3),
    (X**2) ** Y,
    X ** (Y**2),
    -(X**-1),
    se.Rational(-1, 2) * X**2,
    -((X * Y) ** Z),
    1 / (X + Y) - 1 / (X - Y),
    se.floor(3 * X),
    se.RealDouble(0.1) * se.RealDouble(3.0) ** X,
]


def _operands() -> st.SearchStrategy:
    leaves = st.sampled_from([X, Y, Z, se.Integer(2), se.Integer(-3), se.Rational(2, 7), se.RealDouble(0.3)])

    def grow(children: st.SearchStrategy) -> st.SearchStrategy:
        pairs = st.tuples(children, children)
        return st.one_of(
            pairs.map(lambda ab: ab[0] + ab[1]),
            pairs.map(lambda ab: ab[0] - ab[1]),
            pairs.map(lambda ab: ab[0] * ab[1]),
            pairs.map(lambda ab: ab[0] / (ab[1] ** 2 + 1)),
            st.tuples(children, st.integers(-3, 3)).map(lambda ab: (ab[0] ** 2 + 1) ** ab[1]),
            children.map(se.sin),
            children.map(se.cos),
            children.map(lambda a: se.sqrt(a**2 + 1)),
            children.map(lambda a: -a),
            children.map(lambda a: se.exp(a / (a**2 + 1))),
        )

    return st.recursive(leaves, grow, max_leaves=12)


def _python(expr: se.Basic) -> float:
    return eval(code(expr, "python"), {"math": math, "x": POINT[X], "y": POINT[Y], "z": POINT[Z]})


def _close(got: float, expected: float) -> bool:
    return abs(got - expected) <= 1e-12 * max(1.0, abs(expected))


@pytest.mark.parametrize("expr", CASES, ids=str)
def test_python_printer(expr: se.Basic) -> None:
    assert _close(_python(expr), float(expr.subs(POINT)))


@given(expr=_operands())
@settings(max_examples=200, deadline=None)
def test_python_printer_on_random_expressions(expr: se.Basic) -> None:
    assert _close(_python(expr), float(expr.subs(POINT)))


def test_printer_falls_back_to_sympy() -> None:
    """A function these printers do not know is printed by SymPy's printers (as before them)."""
    x = sp.Symbol("x")
    assert code(se.sympify(sp.erf(x)), "python") == "math.erf(x)"
    assert code(se.sympify(sp.erf(x)), "c") == "erf(x)"
    with pytest.raises(PrintMethodNotImplementedError, match="besselj"):
        code(se.sympify(sp.besselj(0, x)), "c")


_CC = shutil.which("cc") or shutil.which("gcc")


@pytest.mark.skipif(_CC is None, reason="no C compiler")
@given(extra=st.lists(_operands(), min_size=20, max_size=20))
@settings(max_examples=5, deadline=None)
def test_c_printer(extra: list) -> None:
    import ctypes
    import tempfile
    from pathlib import Path

    exprs = CASES + extra
    lines = ["#include <math.h>"]
    lines += [
        f"double f{k}(double x, double y, double z) {{ return {code(e, 'c')}; }}" for k, e in enumerate(exprs)
    ]
    with tempfile.TemporaryDirectory() as tmp:
        source, library = Path(tmp) / "f.c", Path(tmp) / "f.so"
        source.write_text("\n".join(lines))
        subprocess.run(
            [_CC, "-std=c99", "-O2", "-fPIC", "-shared", str(source), "-o", str(library), "-lm"], check=True
        )
        lib = ctypes.CDLL(str(library))
        for k, e in enumerate(exprs):
            f = getattr(lib, f"f{k}")
            f.restype, f.argtypes = ctypes.c_double, [ctypes.c_double] * 3
            assert _close(f(POINT[X], POINT[Y], POINT[Z]), float(e.subs(POINT))), (e, code(e, "c"))


#: exact numbers as derivations from decimal inputs make them (issue 27): beyond 2**53, 2**63 and
#: 2**64, numerators and denominators beyond 64 bits, and a quotient of two numbers beyond doubles
HUGE = [
    se.Integer(2**53 + 1),
    se.Integer(7056000000000000000),
    se.Integer(10000000000000000000),
    se.Integer(-24336000000000000000),
    se.Integer(3**100),
    se.Rational(6487556168626515477, 10**19),
    se.Rational(-17, 10**34),
    se.Rational(10**400 + 1, 10**399),
    se.Rational(2**53 + 1, 3),
    se.Rational(1, 3),
]


def test_exact_numbers_print_as_their_nearest_double() -> None:
    """Every printer (SymEngine's and SymPy's, Python and C) prints an exact number so that Python,
    numba and C compute with its correctly rounded double (Python's ``float(Fraction)``), not an
    integer literal C truncates to 64 bits (only warning) and numba refuses; and C builds them with
    the kernels' flags and every warning on, saying nothing."""
    import ctypes
    import tempfile
    from fractions import Fraction
    from pathlib import Path

    import numba

    from chaplygin.numeric._ckernel import FLAGS, compiler

    x = se.Symbol("x")
    exprs = [n * x for n in HUGE] + [n._sympy_() * sp.Symbol("x") for n in HUGE]
    expected = [float(Fraction(int(n.p), int(n.q))) for n in HUGE] * 2
    python = [code(e, "python") for e in exprs]
    assert [eval(text, {"math": math, "x": 1.0}) for text in python] == expected
    jitted = numba.njit(eval(f"lambda x: ({', '.join(python)},)", {"math": math}))
    assert list(jitted(1.0)) == expected
    lines = ["#include <math.h>"]
    lines += [f"double f{k}(double x) {{ return {code(e, 'c')}; }}" for k, e in enumerate(exprs)]
    with tempfile.TemporaryDirectory() as tmp:
        source, library = Path(tmp) / "f.c", Path(tmp) / "f.so"
        source.write_text("\n".join(lines) + "\n")
        run = subprocess.run(
            [*compiler(), *FLAGS, "-Wall", "-Wextra", "-pedantic", str(source), "-o", str(library), "-lm"],
            capture_output=True,
            text=True,
            check=False,
        )
        assert run.returncode == 0 and not run.stderr, run.stderr
        lib = ctypes.CDLL(str(library))
        for k, value in enumerate(expected):
            f = getattr(lib, f"f{k}")
            f.restype, f.argtypes = ctypes.c_double, [ctypes.c_double]
            assert f(1.0) == value, (exprs[k], code(exprs[k], "c"))


def test_a_number_beyond_doubles_is_refused_by_name() -> None:
    """10^400 has no double: printing it is an error that says so, not ``inf`` in the code."""
    from chaplygin.errors import ChaplyginError

    for language in ("python", "c"):
        with pytest.raises(ChaplyginError, match=r"10\^400.*beyond the range of double"):
            code(se.Integer(10**400) * se.Symbol("x"), language)
        with pytest.raises(ChaplyginError, match=r"10\^400.*beyond the range of double"):
            code(sp.Integer(10**400) * sp.Symbol("x"), language)


def test_abs_of_a_coordinate_differentiates_to_sign_and_compiles() -> None:
    """|x| in T and V (SymPy's path: SymEngine cannot differentiate Abs): d|x|/dx = sign(x), not
    unevaluated derivatives of re(x) and im(x), so every compiled path agrees: both reductions in
    plain Python, and each through another printer (numba's, and C's, which the numeric reduction
    is cheap to build with: numba would spend seconds compiling its ``np.linalg.solve``)."""
    from chaplygin.numeric.codegen import compile_model

    x, y, th = dynamicsymbols("x y theta")
    m, J, k = sp.symbols("m J k", positive=True)
    T = m / 2 * (x.diff(t) ** 2 + y.diff(t) ** 2) + (J / 2 + 1 + sp.Abs(x)) * th.diff(t) ** 2
    system = System(
        [x, y, th],
        T,
        [k * (sp.sin(th) * x.diff(t) - sp.cos(th) * y.diff(t))],
        dependent=[y],
        potential_energy=k * sp.Abs(th),
    )
    assert system._native is None  # SymPy derives it
    F = system.equations("chetaev").forcing
    # by hand: F_x = ∂T/∂x = sign(x) θ̇², F_θ = −∂V/∂θ − d/dt(∂T/∂θ̇)|_{θ̈=0} = −k sign(θ) − 2 sign(x) ẋ θ̇
    assert sp.simplify(F[0] - sp.sign(x) * th.diff(t) ** 2) == 0
    assert sp.simplify(F[2] + k * sp.sign(th) + 2 * sp.sign(x) * x.diff(t) * th.diff(t)) == 0
    state, p = np.array([0.3, 0.2, -0.5, 1.0, 0.4]), np.array([1.3, 1.1, 0.7])
    rhs = [
        compile_model(system, "voronets", backend=backend, reduction=reduction).rhs(0.0, state, p)
        for backend, reduction in (
            ("numpy", "numeric"),
            ("numpy", "symbolic"),
            ("numba", "symbolic"),
            ("c", "numeric"),
        )
    ]
    assert np.all(np.isfinite(rhs))
    np.testing.assert_allclose(rhs, [rhs[0]] * 4, rtol=1e-12)


def test_the_code_generator_does_not_convert_the_reduced_forcing_again(monkeypatch) -> None:
    """Chaplygin's equations of the rolling disk: F reaches the code generator in SymEngine, summed
    there from the terms the derivation computed in it (none converted a second time), and it is
    the SymPy F (the difference simplifies to 0)."""
    from chaplygin.core import _fast
    from chaplygin.numeric import codegen

    system = examples.rolling_disk()
    eqs = system.equations("chaplygin")
    seen: list[sp.Basic] = []
    convert = _fast._to_symengine
    monkeypatch.setattr(
        _fast, "_to_symengine", lambda e: (isinstance(e, sp.Basic) and seen.append(e), convert(e))[1]
    )
    codegen._parts(eqs)
    assert not set(eqs._F) & set(seen), "the code generator converted F"
    assert eqs._native_F is not None
    for f, e in zip(eqs._F, eqs._native_F):
        by_name = {sp.Symbol(x.name): x for x in f.free_symbols if isinstance(x, sp.Symbol)}
        assert sp.simplify(_fast.to_sympy(e).xreplace(by_name) - f) == 0  # (assumptions by name)


def test_a_homogeneous_kinetic_energy_is_known_from_symengine() -> None:
    """The rattleback's T is a quadratic form in the velocities: the System says so from
    SymEngine when it checks T (the monitor's SymPy check, E = T − U or Jacobi's integral, took
    0.06 s of its cold build); a particle in a rotating frame (T₁, T₀ parts) is left to the
    monitor, which names Jacobi's integral."""
    from chaplygin.numeric.simulate import monitor

    body = examples.rattleback()
    assert body.__dict__.get("_quadratic_T") is True
    assert monitor(body).column == "energy"
    x, y = dynamicsymbols("x y")
    m, w = sp.symbols("m Omega", positive=True)
    T = m / 2 * ((x.diff(t) - w * y) ** 2 + (y.diff(t) + w * x) ** 2)
    rotating = System([x, y], T, {})
    assert "_quadratic_T" not in rotating.__dict__
    assert monitor(rotating).column == "jacobi_integral"


def test_shown_nonzero_never_takes_an_identity_for_a_nonzero_value() -> None:
    """An expression that vanishes identically (the trigonometric identity, a cancelling
    polynomial, (√a)² − a, a difference of large equal sums) is never shown nonzero; values that
    are not 0, however small or near a cancellation, are; a pole is not shown."""
    from chaplygin.core._fast import shown_nonzero

    x, y, a = se.symbols("x y a")
    big = sum((se.sin(k * x) * se.cos(y) ** k / (k + a) for k in range(1, 40)), se.Integer(0))
    zero = [
        se.sin(x) ** 2 + se.cos(x) ** 2 - 1,
        (x + y) ** 3 - x**3 - 3 * x**2 * y - 3 * x * y**2 - y**3,
        se.sqrt(a) ** 2 - a,
        se.expand(big * (x - y)) - big * x + big * y,
        se.sin(x + y) - se.sin(x) * se.cos(y) - se.cos(x) * se.sin(y),
    ]
    assert shown_nonzero(zero) == [False] * len(zero)
    nonzero = [x, se.Integer(10) ** -12 * x, se.sin(x) ** 2 + se.cos(x) ** 2 - 1 + y / 10**6, big]
    assert shown_nonzero(nonzero) == [True] * len(nonzero)
    assert shown_nonzero([1 / (x - x)]) == [False]
    # with a floating coefficient (a numeric parameter) and through exp, log and roots alike
    c = se.RealDouble(0.37)
    zero = [
        c * (se.sin(x) ** 2 + se.cos(x) ** 2 - 1),
        c * se.sqrt(a) ** 2 - c * a,
        se.exp(x) * se.exp(-x) - 1,
        se.log(x * y) - se.log(x) - se.log(y),
        (se.sqrt(x) * se.sqrt(y)) ** 2 - x * y,
    ]
    assert shown_nonzero(zero) == [False] * len(zero)
    nonzero = [c * x, c * (se.sin(x) ** 2 + se.cos(x) ** 2) - c + se.Integer(10) ** -9 * y, se.pi * x - 3 * x]
    assert shown_nonzero(nonzero) == [True] * len(nonzero)


def test_a_result_handed_back_to_symengine_is_not_converted_again(monkeypatch) -> None:
    """The gradient's entries, handed to ``jacobian`` (as the derivation hands the momenta to the
    mass matrix), are taken as the SymEngine values they were made from: none is converted a
    second time; the Hessian is SymPy's own ``diff`` (simplified difference 0), its symbol ``a``
    the positive one given."""
    from chaplygin.core import _fast

    a, (x, y) = sp.Symbol("a", positive=True), sp.symbols("x y")
    f = a * sp.sin(x * y) ** 2 + sp.sqrt(a) * x**3 * y / (1 + a * y**2)
    g = _fast.gradient(f, [x, y])
    seen: list[sp.Basic] = []
    convert = _fast._to_symengine
    monkeypatch.setattr(_fast, "_to_symengine", lambda e: (seen.append(e), convert(e))[1])
    H = _fast.jacobian(g, [x, y])
    assert not set(g) & set(seen), "jacobian converted the gradient again"
    for i, u in enumerate((x, y)):
        for j, v in enumerate((x, y)):
            assert sp.simplify(H[i, j] - sp.diff(f, u, v)) == 0
    assert a in H.free_symbols and sp.Symbol("a") not in H.free_symbols


def test_same_named_symbols_with_other_assumptions_keep_their_own() -> None:
    """A positive ``a`` and a plain ``a`` in one session (two systems, a body file's positive
    r beside a plain r): each result, and each result of a result, has its own symbol back."""
    from chaplygin.core import _fast

    x = sp.Symbol("x")
    for a, other in (
        (sp.Symbol("a", positive=True), sp.Symbol("a")),
        (sp.Symbol("a"), sp.Symbol("a", positive=True)),
    ):
        g = _fast.gradient(a * x**3 + sp.cos(a * x), [x])
        H = _fast.jacobian(g, [x])
        for e in (g[0], H[0]):
            assert a in e.free_symbols and other not in e.free_symbols
        assert sp.simplify(H[0] - (6 * a * x - a**2 * sp.cos(a * x))) == 0


def test_symbols_come_back_with_their_assumptions_without_a_sympy_substitution(monkeypatch) -> None:
    """SymEngine drops assumptions; the way back gives the positive ``a`` and ``b`` (and the plain
    ``x``) as they were given, built so at once: no SymPy ``xreplace`` pass rebuilding every node
    above them. The values are SymPy's own derivatives (simplified difference 0)."""
    from chaplygin.core import _fast

    a, b, x = sp.Symbol("a", positive=True), sp.Symbol("b", positive=True), sp.Symbol("x")
    f = a * b**2 * sp.sin(x) / sp.sqrt(a**2 + b**2 * x**2) + b * x**3
    monkeypatch.setattr(sp.Basic, "xreplace", lambda *args, **kwargs: pytest.fail("xreplace called"))
    (df,) = _fast.gradient(f, [x])
    (d2f,) = _fast.jacobian([df], [x])
    monkeypatch.undo()
    for e, expected in ((df, f.diff(x)), (d2f, f.diff(x, 2))):
        assert e.free_symbols == {a, b, x}
        assert sp.simplify(e - expected) == 0


def test_the_compiled_reduced_model_leaves_sympys_forcing_uncomputed() -> None:
    """Chaplygin's equations of the rolling disk compiled from the derivation's SymEngine F: the
    SymPy F (an xreplace of the whole residuals, and the exact zero test) is computed only when
    asked for, and then ``M⁻¹F`` at a state is the compiled right-hand side's acceleration."""
    from chaplygin.numeric.codegen import compile_equations

    system = examples.rolling_disk()
    eqs = system.equations("chaplygin")
    model = compile_equations(eqs, "numpy")
    assert "_F" not in eqs.__dict__, "the SymPy forcing was computed for the compiled model"
    values = dict(zip(system.parameters, (1.3, 0.7, 9.81, 0.4, 0.9)))  # A, C, g, m, r
    assert model.layout.parameters == tuple(str(s) for s in system.parameters)
    v, n = system._vars, system.n
    y = np.array([0.3, 0.4, 0.2, 0.1, -0.2, 1.1, -0.6, 0.8])  # ψ, θ, φ, x, y, ψ', θ', φ'
    state = dict(zip(v.x, y[:n])) | dict(zip([v.xd[i] for i in system._ind], y[n:])) | values
    M = np.array(eqs._M.xreplace(state).evalf(), dtype=float)
    F = np.array(eqs._F.xreplace(state).evalf(), dtype=float).ravel()
    rhs = model.rhs(0.0, y, np.array(list(values.values())))
    np.testing.assert_allclose(rhs[n:], np.linalg.solve(M, F), rtol=1e-12)


def test_a_derivation_converts_no_expression_twice(monkeypatch) -> None:
    """Chaplygin's equations of the rolling disk: each SymPy expression is converted to SymEngine
    at most once (D_σ differentiates each entry of B once per independent coordinate, and each
    step takes the one before's results), and the equations are those derived without the
    memory of conversions (printed alike: each system has its own internal symbols)."""
    from chaplygin.core import _fast

    with monkeypatch.context() as m:  # nothing remembered: every expression converted afresh
        m.setattr(_fast, "_remember", lambda *args: None, raising=False)
        m.setattr(_fast, "_MADE", {}, raising=False)
        reference = examples.rolling_disk().equations("chaplygin")._residuals
    seen: list[sp.Basic] = []
    convert = _fast._to_symengine
    monkeypatch.setattr(_fast, "_to_symengine", lambda e: (seen.append(e), convert(e))[1])
    monkeypatch.setattr(_fast, "_MADE", {}, raising=False)
    residuals = examples.rolling_disk().equations("chaplygin")._residuals
    compound = [e for e in seen if isinstance(e, sp.Basic) and not e.is_Atom]
    assert len({id(e) for e in compound}) == len(compound), "an expression was converted twice"
    assert [str(r) for r in residuals] == [str(r) for r in reference]


def test_solved_constraints_are_split_without_factoring(monkeypatch) -> None:
    """Constraints given solved (form B, a rolling body's ``ẋ = …, ẏ = …``): their coefficients
    go to B and B_0 in normal form at once, without ``factor_terms`` first (a third of the
    rattleback's System); B is ``∂(ẋ_dep)/∂(ẋ_ind)`` by SymPy's own ``diff``, B_0 the rest."""
    from chaplygin.core import _symbols

    x, y, th, ph = dynamicsymbols("x y theta phi")
    a, b = sp.symbols("a b", positive=True)
    vx = a * sp.cos(th) * ph.diff(t) / sp.sqrt(a**2 * sp.sin(th) ** 2 + b**2) + b * sp.sin(t) * th.diff(t)
    vy = (a * sp.sin(th) + b) * ph.diff(t) * sp.cos(th) + sp.cos(th) ** 2 * th.diff(t) + a * b * sp.cos(t)
    T = (x.diff(t) ** 2 + y.diff(t) ** 2 + th.diff(t) ** 2 + ph.diff(t) ** 2) / 2
    monkeypatch.setattr(
        _symbols.sp, "factor_terms", lambda *args, **kwargs: pytest.fail("factor_terms called")
    )
    system = System([x, y, th, ph], T, {x.diff(t): vx, y.diff(t): vy})
    monkeypatch.undo()
    to_fun = system._to_fun
    speeds = [th.diff(t), ph.diff(t)]
    for row, v in enumerate((vx, vy)):
        for col, s in enumerate(speeds):
            assert sp.simplify(system._B[row, col].xreplace(to_fun) - v.diff(s)) == 0
        assert sp.simplify(system._B0[row].xreplace(to_fun) - v.xreplace({s: 0 for s in speeds})) == 0


def test_cse_keeps_a_shared_condition_in_its_piecewise() -> None:
    # SymEngine's elimination makes a condition two Piecewise share a temporary and each
    # condition "x0 == True": printed as C, a number compared with C99's undeclared `true`
    from symengine.lib.symengine_wrapper import Boolean

    from chaplygin.core._fast import cse

    t, a, y = se.symbols("t a y")
    step = se.Piecewise((1, t < a), (0, True))
    exprs = [step * y, se.Piecewise((y**2, t < a), (0, True)) + step]
    pairs, reduced = cse(exprs)
    assert not any(isinstance(v, Boolean) for _, v in pairs)
    assert "True ==" not in str(reduced) and "== True" not in str(reduced)
    values = {t: 0.5, a: 1.25, y: 3.0}
    for later in (values, {**values, t: 2.0}):
        subs = dict(later)
        for s, v in pairs:
            subs[s] = v.subs(subs)
        assert [float(r.subs(subs)) for r in reduced] == [float(e.subs(later)) for e in exprs]
