"""Differential test: every backend and every export against the model evaluated exactly.

The reference shares nothing with the code under test but the model: SymPy's mass matrix,
forcing and constraints (``eqs.mass_matrix``, ``eqs.forcing`` of :meth:`System.equations`,
``system.constraints``), lambdified by SymPy to mpmath and evaluated at 30 significant digits,
``M·x = F`` solved by mpmath's LU.  Against it:

* at random admissible states, the right-hand side of each backend (``numpy``, ``c``, ``numba``;
  ``jax`` where installed) and of each export of :func:`chaplygin.io.export.export` (the C file,
  the NumPy module), to 1e-10 relative;
* a short :func:`chaplygin.simulate` on each backend, and SciPy's DOP853 on each export's
  ``rhs``, against DOP853 at rtol 1e-13 on the exact right-hand side, to 100 local tolerances.

The systems are what made the backends disagree (issue 27, item 1): decimal numbers of 15–17
significant digits inside the equations, which become exact rationals whose numerators and
denominators run far beyond 64 bits — a rolling ellipsoid with an off-axis centre of mass and a
full inertia tensor, and random systems (``randomsystems.seeded_system``) with affine,
time-dependent constraints, one reduced model (Chaplygin's) and one with multipliers
(Chetaev's, whose state holds every velocity).  The random points take runtime parameters of
15–17 digits and magnitudes 1e-3 … 1e3; the runs, moderate ones (0.5 … 2), so that 0.05 is short
against the motion's time scale.  Each model is derived and compiled once (module-scoped
fixture).  The generated C of each (its ``fill`` and the DOP853 loop) and its exported C must
also build without a single diagnostic.  On d1d83f5 the ellipsoid's ``c`` and ``numba``
right-hand sides were 1e12 times the tolerance off, the run stopped, and gcc warned "integer
constant is too large for its type".
"""

from __future__ import annotations

import ctypes
import subprocess
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mpmath
import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp
from sympy.physics.mechanics import dynamicsymbols

import chaplygin
from chaplygin import bodies
from chaplygin.io.export import export
from chaplygin.numeric import _cfill, _ckernel
from chaplygin.numeric.codegen import _assignments, _parts, compile_model
from randomsystems import decimal, seeded_system

T = dynamicsymbols._t
DIGITS = 30
#: the right-hand sides agree with the exact one to this, relative to the largest velocity and to
#: the largest acceleration: float64 loses a few digits to M's condition (the worst seen is 2e-12)
RHS_TOL = 1e-10
#: the runs take RTOL, ATOL; the exact one 1e-13.  DOP853 keeps each step's error below
#: rtol·|y| + atol, and a run of a few steps over an interval short against the motion's time
#: scale (here |∂f/∂y|·duration < 1) adds up a few of those: RUN_TOL of them bound it with a wide
#: margin, and are 1e6 times below what the wrong constant of issue 27 did (6e-4 in 0.05 s).
RTOL, ATOL, RUN_TOL = 1e-11, 1e-12, 100.0
POINTS = 4
#: what the exported C must build with: the kernels' flags and every warning, none of them given
STRICT = ("-Wall", "-Wextra", "-pedantic")


class Exact:
    """``dy/dt`` of one model at 30 digits, for a state named as the generated code's.

    ``y`` = [coordinates, integrated velocities (``q'``), integrated multipliers (μ)]; the
    velocities a reduced model does not integrate come from the constraints, the accelerations
    (and μ') from ``M·x = F`` solved by mpmath.
    """

    def __init__(self, system: Any, model: str, form: str) -> None:
        eqs = system.equations(model, form)
        self.names = [q.func.__name__ for q in system.coordinates]
        self.n = n = len(self.names)
        q = [sp.Symbol(f"q_{k}") for k in range(n)]
        qd = [sp.Symbol(f"qd_{k}") for k in range(n)]
        plain: dict[Any, Any] = {}
        for c, s, sd in zip(system.coordinates, q, qd):
            plain[c.diff(T)] = sd  # before c: xreplace meets q'(t) before the q(t) inside it
            plain[c] = s
        unknowns = list(eqs.unknowns)
        integrated = [m for m in eqs.multipliers if m.diff(T) in unknowns]  # μ, not Chetaev's λ
        mus = [sp.Symbol(f"mu_{k}") for k in range(len(integrated))]
        plain.update(dict(zip(integrated, mus)))
        self.mu_names = [m.func.__name__ for m in integrated]
        params = [*system.parameters, *eqs.constants]
        self.parameters = tuple(p.name for p in params)
        self.dependent = [self.names.index(d.expr.func.__name__) for d in system.constraints]
        args = [T, *q, *qd, *mus, *params]

        def mp(exprs: Any) -> Callable[..., list[Any]]:
            return sp.lambdify(
                args, [sp.sympify(e).xreplace(plain) for e in exprs], modules="mpmath", cse=True
            )

        self.dim = len(unknowns)
        self.f = mp([*eqs.mass_matrix, *eqs.forcing])
        self.v = mp(list(system.constraints.values()))
        # the state entry whose derivative each unknown is: q'' of q', μ' of μ (none for λ)
        self.unknowns = [
            u.expr.func.__name__ + "'" * (u.derivative_count - 1) if isinstance(u, sp.Derivative) else ""
            for u in unknowns
        ]

    def velocities(self, t: Any, y: dict[str, Any], p: list[Any]) -> list[Any]:
        """Every velocity: ``y``'s, and the dependent ones from the constraints where ``y`` lacks them."""
        qd = [y.get(name + "'", mpmath.mpf(0)) for name in self.names]
        if any(self.names[i] + "'" not in y for i in self.dependent):
            mus = [y[m] for m in self.mu_names]
            solved = self.v(t, *(y[name] for name in self.names), *qd, *mus, *p)
            for k, i in enumerate(self.dependent):
                qd[i] = solved[k]
        return qd

    def __call__(self, t: float, state: tuple[str, ...], y: np.ndarray, p: np.ndarray) -> np.ndarray:
        """dy/dt (rounded to floats) for the state ``y`` whose entries ``state`` names and the
        parameters ``p``, both taken as the exact values of their floats."""
        with mpmath.workdps(DIGITS):
            tm = mpmath.mpf(float(t))
            values = {name: mpmath.mpf(float(v)) for name, v in zip(state, y)}
            pm = [mpmath.mpf(float(v)) for v in p]
            qd = self.velocities(tm, values, pm)
            out = self.f(
                tm, *(values[name] for name in self.names), *qd, *(values[m] for m in self.mu_names), *pm
            )
            d = self.dim
            M = mpmath.matrix([[out[i * d + j] for j in range(d)] for i in range(d)])
            x = mpmath.lu_solve(M, mpmath.matrix(out[d * d : d * d + d]))
            by_name = {name: x[i] for i, name in enumerate(self.unknowns)}
            return np.array([float(v) for v in [*qd, *(by_name[name] for name in state[self.n :])]])


@dataclass
class Point:
    """A time, an admissible state (in the layout's order) and parameters (in the layout's order)."""

    t: float
    y: np.ndarray
    p: np.ndarray


@dataclass
class Case:
    """One model of one system, its exact right-hand side, where to evaluate it, where to start a run."""

    system: Any
    model: str
    form: str
    exact: Exact
    state: tuple[str, ...]
    points: list[Point]
    start: Point
    duration: float
    built: dict[str, Any] = field(default_factory=dict)

    def reference(self, t: np.ndarray) -> np.ndarray:
        """The exact motion from ``start`` at the times ``t`` (rows): DOP853 at rtol 1e-13 on the exact
        right-hand side (integrated once, then read off its dense output)."""
        if "reference" not in self.built:
            s = self.start
            sol = solve_ivp(
                lambda t, y: self.exact(t, self.state, y, s.p),
                (s.t, s.t + self.duration),
                s.y,
                method="DOP853",
                rtol=1e-13,
                atol=1e-15,
                dense_output=True,
            )
            assert sol.success, sol.message
            self.built["reference"] = sol.sol
        return self.built["reference"](t).T

    def check_run(self, t: np.ndarray, ys: np.ndarray) -> None:
        """A run's states ``ys`` (rows) at the times ``t`` are the exact motion's, to ``RUN_TOL`` local tolerances."""
        assert t[0] == self.start.t and t[-1] == self.start.t + self.duration
        ref = self.reference(t)
        excess = np.abs(ys - ref) / (RUN_TOL * (RTOL * np.abs(ref) + ATOL))
        worst = np.unravel_index(np.argmax(excess), excess.shape)
        assert excess[worst] <= 1.0, (
            f"{self.state[worst[1]]} is {ys[worst]!r} at t = {t[worst[0]]!r}, the exact motion's {ref[worst]!r}"
        )


def _f17(rng: np.random.Generator, lo: float, hi: float) -> float:
    """A float of 17 significant digits in (lo, hi)."""
    return float(f"{rng.uniform(lo, hi):.17g}")


def _ellipsoid() -> Any:
    """A rolling ellipsoid: semi-axes, a full inertia tensor, the centre of mass (off every axis)
    and g of 17 digits (exact rationals in the equations), its mass a parameter."""
    rng = np.random.default_rng(2027)
    inertia = np.diag([_f17(rng, 0.5, 0.6), _f17(rng, 0.7, 0.8), _f17(rng, 0.9, 1.0)])
    for i, j in [(0, 1), (0, 2), (1, 2)]:
        inertia[i, j] = inertia[j, i] = _f17(rng, -0.05, 0.05)
    shape = bodies.Ellipsoid(_f17(rng, 1.2, 1.4), _f17(rng, 0.6, 0.8), _f17(rng, 0.4, 0.5))
    com = (_f17(rng, -0.05, 0.05), _f17(rng, -0.05, 0.05), _f17(rng, -0.25, -0.15))
    return bodies.rolling_body(
        shape, mass="m", inertia=inertia.tolist(), center_of_mass=com, g=_f17(rng, 9, 10)
    )


#: name → (system, model, half-width of the coordinates' range); the runs last 0.05
SYSTEMS: dict[str, Callable[[], tuple[Any, str, float]]] = {
    # cos θ = 0 is a pole of Cardan angles: θ stays within ±0.8
    "ellipsoid": lambda: (_ellipsoid(), "chaplygin", 0.8),
    # coefficients of magnitudes 1e-3 … 10 (larger ones make these polynomial systems stiff)
    "random-chaplygin": lambda: (
        seeded_system(0, floats=True, scale=(1e-3, 10.0), timed=True, chaplygin=True, forces=True).system,
        "chaplygin",
        1.5,
    ),
    "random-chetaev": lambda: (
        seeded_system(7, floats=True, scale=(1e-3, 10.0), timed=True, chaplygin=False, forces=True).system,
        "chetaev",
        1.5,
    ),
}


def _point(
    exact: Exact, state: tuple[str, ...], rng: np.random.Generator, width: float, magnitudes: tuple
) -> Point:
    """A random admissible point: random coordinates, independent velocities, multipliers and
    parameters (:func:`randomsystems.decimal` of ``magnitudes``); the dependent velocities a
    state holds from the constraints (exactly, then rounded)."""
    t = float(rng.uniform(0.0, 2.0))
    p = np.array([float(decimal(rng, *magnitudes)) for _ in exact.parameters])
    values = {name: float(rng.uniform(-width, width)) for name in exact.names}
    values.update({name + "'": float(rng.uniform(-1.0, 1.0)) for name in exact.names})
    values.update({name: float(rng.uniform(-1.0, 1.0)) for name in exact.mu_names})
    for i in exact.dependent:
        del values[exact.names[i] + "'"]
    with mpmath.workdps(DIGITS):
        exact_values = {k: mpmath.mpf(v) for k, v in values.items()}
        qd = exact.velocities(mpmath.mpf(t), exact_values, [mpmath.mpf(float(v)) for v in p])
        values.update({name + "'": float(v) for name, v in zip(exact.names, qd)})
    return Point(t, np.array([values[name] for name in state]), p)


@pytest.fixture(scope="module", params=list(SYSTEMS))
def case(request: pytest.FixtureRequest) -> Case:
    system, model, width = SYSTEMS[request.param]()
    exact = Exact(system, model, "classic")
    layout = compile_model(system, model, "classic", "numpy").layout
    assert layout.parameters == exact.parameters
    rng = np.random.default_rng(sum(map(ord, request.param)))
    points = [_point(exact, layout.state, rng, width, (1e-3, 1e3)) for _ in range(POINTS)]
    start = _point(exact, layout.state, rng, width / 2, (0.5, 2.0))
    return Case(system, model, "classic", exact, layout.state, points, start, 0.05)


def _relative_error(case: Case, got: np.ndarray, ref: np.ndarray) -> float:
    """|got − ref| relative to the largest entry, of the velocities and of the rest, the worse."""
    n = case.system.n
    parts = (slice(0, n), slice(n, None))
    return max(float(np.max(np.abs(got[s] - ref[s])) / max(np.max(np.abs(ref[s])), 1e-300)) for s in parts)


def _check_rhs(case: Case, rhs: Callable[[float, np.ndarray, np.ndarray], Any]) -> None:
    for point in case.points:
        ref = case.exact(point.t, case.state, point.y, point.p)
        got = np.asarray(rhs(point.t, point.y, point.p), dtype=float)
        assert _relative_error(case, got, ref) <= RHS_TOL, (point, got, ref)


def _compiler() -> list[str]:
    try:
        return _ckernel.compiler()
    except _ckernel.Unavailable as exc:
        pytest.skip(f"no C compiler: {exc}")
    raise AssertionError  # unreachable


def _compiled(case: Case, backend: str) -> Any:
    if backend == "jax":
        pytest.importorskip(
            "jax", reason="the jax backend is an optional extra (chaplygin[jax]), not installed"
        )
    if backend == "c":
        _compiler()
    compiled = compile_model(case.system, case.model, case.form, backend)
    assert compiled.layout.state == case.state and compiled.layout.parameters == case.exact.parameters
    return compiled


BACKENDS = ["numpy", "c", "numba", "jax"]


@pytest.mark.parametrize("backend", BACKENDS)
def test_backend_rhs_is_the_exact_rhs(case: Case, backend: str) -> None:
    _check_rhs(case, _compiled(case, backend).rhs)


@pytest.mark.parametrize("backend", BACKENDS)
def test_backend_run_is_the_exact_motion(case: Case, backend: str) -> None:
    """A short :func:`chaplygin.simulate` on each backend follows the exact motion."""
    _compiled(case, backend)
    s = case.start
    given = dict(zip(case.state, map(float, s.y)))
    for i in case.exact.dependent:  # simulate solves the constraints for them itself
        given.pop(case.exact.names[i] + "'", None)
    tr = chaplygin.simulate(
        case.system,
        case.model,
        (s.t, s.t + case.duration),
        given,
        dict(zip(case.exact.parameters, map(float, s.p))),
        form=case.form,
        rtol=RTOL,
        atol=ATOL,
        samples=3,
        backend=backend,
    )
    assert tr.status == "success", tr.message
    columns = {**tr.coordinates, **tr.velocities, **tr.multipliers}
    case.check_run(tr.t, np.array([columns[name] for name in case.state]).T)


def _exported(case: Case, to: str, tmp: Path) -> Callable[[float, np.ndarray, np.ndarray], np.ndarray]:
    """The ``rhs`` of the model exported to C (built with every warning: it must give none) or Python."""
    if to in case.built:
        return case.built[to]
    source = export(case.system, case.model, to, form=case.form)
    if to == "python":
        namespace: dict[str, Any] = {"__name__": "exported"}
        exec(compile(source, "<exported>", "exec"), namespace)
        assert tuple(namespace["STATE"]) == case.state
        assert tuple(namespace["PARAMETERS"]) == case.exact.parameters
        rhs = namespace["rhs"]
    else:
        c_file, library = tmp / "model.c", tmp / "model.so"
        c_file.write_text(source, encoding="ascii")
        run = subprocess.run(
            [*_compiler(), *_ckernel.FLAGS, *STRICT, str(c_file), "-o", str(library), "-lm"],
            capture_output=True,
            text=True,
            check=False,
        )
        assert run.returncode == 0 and not run.stderr, run.stderr
        lib = ctypes.CDLL(str(library))
        vec = np.ctypeslib.ndpointer(dtype=np.float64, flags="C_CONTIGUOUS")
        lib.rhs.argtypes, lib.rhs.restype = [ctypes.c_double, vec, vec, vec], None

        def rhs(t: float, y: np.ndarray, p: np.ndarray) -> np.ndarray:
            out = np.empty(len(case.state))
            lib.rhs(float(t), np.ascontiguousarray(y, dtype=float), np.ascontiguousarray(p, dtype=float), out)
            return out

    case.built[to] = rhs
    return rhs


@pytest.mark.parametrize("to", ["c", "python"])
def test_export_is_the_exact_model(case: Case, to: str, tmp_path: Path) -> None:
    """The exported ``rhs`` at random points, and SciPy's DOP853 on it from the start of the runs."""
    rhs = _exported(case, to, tmp_path)
    _check_rhs(case, rhs)
    s = case.start
    times = np.linspace(s.t, s.t + case.duration, 3)
    sol = solve_ivp(
        lambda t, y: rhs(t, y, s.p), times[[0, -1]], s.y, method="DOP853", rtol=RTOL, atol=ATOL, t_eval=times
    )
    assert sol.success, sol.message
    case.check_run(sol.t, sol.y.T)


def test_generated_c_builds_without_a_diagnostic(case: Case, tmp_path: Path) -> None:
    """The C of the ``c`` backend (the model's ``fill`` and the DOP853 loop; the numba backend's
    ``fill`` of a large model is the same C) builds with the kernels' flags and every warning on,
    and the compiler says nothing: no constant out of range, no implicit conversion."""
    parts = _parts(case.system.equations(case.model, case.form))
    fill = _cfill.source(parts.fill, [_assignments(b) for b in parts.fill.blocks()], "chaplygin_fill_test")
    c_file = tmp_path / "kernel.c"
    c_file.write_text(fill + _ckernel.loop_source().replace("@DIGEST@", "test"), encoding="ascii")
    run = subprocess.run(
        [*_compiler(), *_ckernel.FLAGS, *STRICT, str(c_file), "-o", str(tmp_path / "kernel.so"), "-lm"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert run.returncode == 0 and not run.stderr, run.stderr
