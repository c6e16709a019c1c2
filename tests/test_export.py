"""chaplygin.io.export: the exported C file and Python module compute the model's own equations.

The reference is independent of the code generator: the solved accelerations of
:attr:`Equations.accelerations` (chaplygin's exact solution of ``M·x = F``) and the constraints
of :attr:`System.constraints`, evaluated with SymPy's ``lambdify`` at random states that
satisfy the constraints.  The Jacobians are checked against central differences of the
exported right-hand side itself.
"""

from __future__ import annotations

import ctypes
import subprocess
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols

from chaplygin import ChaplyginError, examples
from chaplygin.io.export import export

T = dynamicsymbols._t
RNG_SEED = 20240601

#: (system, model, form): every model on a Chaplygin system, and the non-Chaplygin rolling disk
CASES = [
    ("knife_edge", "chetaev", "classic"),
    ("knife_edge", "chaplygin", "classic"),
    ("knife_edge", "vakonomic", "classic"),
    ("knife_edge", "vakonomic_family", "classic"),
    ("rolling_sphere", "chaplygin", "new"),
    ("rolling_sphere", "lindelof", "classic"),
    ("rolling_disk", "chetaev", "classic"),
    ("rolling_disk", "voronets", "classic"),
    # constraints nonlinear in the velocities (issue 30): Appell's weight, ż² = k²(ẋ² + ẏ²)
    ("appell_weight", "chetaev", "classic"),
    ("appell_weight", "voronets", "classic"),
    ("appell_weight", "voronets", "new"),
    ("appell_weight", "vakonomic", "classic"),
]

_SYSTEMS: dict[str, Any] = {}


def _system(name: str) -> Any:
    if name not in _SYSTEMS:
        _SYSTEMS[name] = getattr(examples, name)()
    return _SYSTEMS[name]


class Reference:
    """The model's velocities and solved accelerations as NumPy functions of plain symbols."""

    def __init__(self, system: Any, model: str, form: str) -> None:
        eqs = system.equations(model, form)
        self.system, self.eqs = system, eqs
        self.names = [q.func.__name__ for q in system.coordinates]
        q = [sp.Symbol(n) for n in self.names]
        qd = [sp.Symbol(n + "'") for n in self.names]
        acc = eqs.accelerations
        integrated = [m for m in eqs.multipliers if m.diff(T) in acc]  # μ, not Chetaev's λ
        mus = [sp.Symbol(m.func.__name__) for m in integrated]
        params = [*system.parameters, *eqs.constants]
        plain: dict[Any, Any] = {}
        for c, s, sd in zip(system.coordinates, q, qd):
            plain[c.diff(T)] = sd
            plain[c] = s
        plain.update({m: s for m, s in zip(integrated, mus)})
        self.keys = list(acc)
        args = [T, *q, *qd, *mus, *params]
        self.acc = sp.lambdify(args, [e.subs(plain) for e in acc.values()], modules="numpy")
        dep = list(system.constraints)
        self.dependent = [self.names.index(d.expr.func.__name__) for d in dep]
        self.velocity = sp.lambdify(args, [system.constraints[d].subs(plain) for d in dep], modules="numpy")
        self.parameters = [p.name for p in params]
        self.mus = len(mus)

    def state(self, rng: np.random.Generator) -> tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """A random time, coordinates, velocities satisfying the constraints, multipliers, parameters."""
        n = len(self.names)
        t = float(rng.uniform(0.0, 1.0))
        q = rng.uniform(0.2, 1.2, n)  # away from the poles at 0 and π/2 of the examples
        qd = rng.uniform(-1.0, 1.0, n)
        mu = rng.uniform(-1.0, 1.0, self.mus)
        p = rng.uniform(0.5, 2.0, len(self.parameters))
        if self.dependent:
            qd[self.dependent] = self.velocity(t, *q, *qd, *mu, *p)
        return t, q, qd, mu, p

    def derivative(
        self,
        t: float,
        q: np.ndarray,
        qd: np.ndarray,
        mu: np.ndarray,
        p: np.ndarray,
        layout_state: tuple[str, ...],
    ) -> np.ndarray:
        """dy/dt in the exported layout: velocities, then q'' of the integrated velocities, then μ'."""
        values = dict(zip(self.keys, self.acc(t, *q, *qd, *mu, *p)))
        by_name = {}
        for key, value in values.items():
            if isinstance(key, sp.Derivative) and key.derivative_count == 2:
                by_name[key.expr.func.__name__ + "'"] = value  # q'' is d/dt of the state entry q'
            elif isinstance(key, sp.Derivative):
                by_name[key.expr.func.__name__] = value  # μ' is d/dt of μ
        n = len(self.names)
        return np.array([*qd, *(by_name[name] for name in layout_state[n:])], dtype=float)


def _layout_state(source: str) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """STATE and PARAMETERS of an exported Python module."""
    namespace: dict[str, Any] = {}
    exec(compile(source, "<exported>", "exec"), namespace)
    return namespace["STATE"], namespace["PARAMETERS"]


def _python_module(source: str) -> dict[str, Any]:
    namespace: dict[str, Any] = {"__name__": "exported"}
    exec(compile(source, "<exported>", "exec"), namespace)
    return namespace


def _c_compiler() -> list[str]:
    from chaplygin.numeric._ckernel import Unavailable, compiler

    try:
        return compiler()
    except Unavailable as exc:
        pytest.skip(f"no C compiler: {exc}")
    raise AssertionError  # unreachable


def _c_functions(source: str, tmp: Path, ny: int, jacobian: bool) -> tuple[Callable[..., np.ndarray], ...]:
    """Compile ``source`` with the system's compiler, warnings as errors; rhs and jacobian via ctypes."""
    cc = _c_compiler()
    c_file, library = tmp / "model.c", tmp / "model.so"
    c_file.write_text(source, encoding="ascii")  # the exported C is plain ASCII
    run = subprocess.run(
        [
            *cc,
            "-std=c99",
            "-Wall",
            "-Wextra",
            "-pedantic",
            "-Werror",
            "-O1",
            "-fPIC",
            "-shared",
            str(c_file),
            "-o",
            str(library),
            "-lm",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    lib = ctypes.CDLL(str(library))
    vec = np.ctypeslib.ndpointer(dtype=np.float64, flags="C_CONTIGUOUS")
    lib.rhs.argtypes = [ctypes.c_double, vec, vec, vec]
    lib.rhs.restype = None

    def rhs(t: float, y: np.ndarray, p: np.ndarray) -> np.ndarray:
        out = np.empty(ny)
        lib.rhs(t, np.ascontiguousarray(y, dtype=float), np.ascontiguousarray(p, dtype=float), out)
        return out

    if not jacobian:
        return (rhs,)
    lib.jacobian.argtypes = [ctypes.c_double, vec, vec, vec]
    lib.jacobian.restype = None

    def jac(t: float, y: np.ndarray, p: np.ndarray) -> np.ndarray:
        out = np.empty(ny * ny)
        lib.jacobian(t, np.ascontiguousarray(y, dtype=float), np.ascontiguousarray(p, dtype=float), out)
        return out.reshape(ny, ny)

    return rhs, jac


def _check(
    rhs: Callable[..., np.ndarray], jac: Callable[..., np.ndarray], ref: Reference, state: tuple[str, ...]
) -> None:
    rng = np.random.default_rng(RNG_SEED)
    n = len(ref.names)
    for _ in range(5):
        t, q, qd, mu, p = ref.state(rng)
        # the exported y: every coordinate, the velocities the model integrates, then μ
        y = np.array([*q, *(qd[ref.names.index(v[:-1])] for v in state[n : len(state) - ref.mus]), *mu])
        expected = ref.derivative(t, q, qd, mu, p, state)
        np.testing.assert_allclose(rhs(t, y, p), expected, rtol=1e-10, atol=1e-10)
        J = jac(t, y, p)
        fd = np.empty_like(J)
        for j in range(len(y)):
            h = 1e-6 * (1.0 + abs(y[j]))
            up, down = y.copy(), y.copy()
            up[j] += h
            down[j] -= h
            fd[:, j] = (rhs(t, up, p) - rhs(t, down, p)) / (2 * h)
        np.testing.assert_allclose(J, fd, rtol=1e-6, atol=1e-6 * max(1.0, np.max(np.abs(fd))))


@pytest.mark.parametrize(("system", "model", "form"), CASES)
def test_python_export_computes_the_equations(system: str, model: str, form: str) -> None:
    s = _system(system)
    ref = Reference(s, model, form)
    module = _python_module(export(s, model, "python", form=form, jacobian=True))
    assert list(module["PARAMETERS"]) == ref.parameters
    _check(module["rhs"], module["jacobian"], ref, module["STATE"])


@pytest.mark.parametrize(("system", "model", "form"), CASES)
def test_c_export_computes_the_equations(system: str, model: str, form: str, tmp_path: Path) -> None:
    s = _system(system)
    ref = Reference(s, model, form)
    state, parameters = _layout_state(export(s, model, "python", form=form))
    assert list(parameters) == ref.parameters
    source = export(s, model, "c", form=form, jacobian=True)
    assert source.isascii()
    rhs, jac = _c_functions(source, tmp_path, len(state), jacobian=True)
    _check(rhs, jac, ref, state)


def test_header_documents_the_layout() -> None:
    knife = _system("knife_edge")
    source = export(knife, "chaplygin", "c")
    for line in (
        "y[0]  x     coordinate",
        "y[3]  x'    velocity",
        "y[4]  phi'  velocity",
        "p[0]  J",
        "p[1]  m",
        "Units: none",
        "dependent velocities (y')",
    ):
        assert line in source, line
    assert "jacobian" not in source  # only when asked
    family = export(knife, "vakonomic_family", "python")
    assert "p[2]  c_1  (constant c of the vakonomic family)" in family
    multipliers = export(knife, "vakonomic", "python")
    assert "y[6]  mu_1  vakonomic multiplier" in multipliers


def test_prefix_names_the_functions(tmp_path: Path) -> None:
    knife = _system("knife_edge")
    source = export(knife, "chetaev", "c", prefix="knife_", jacobian=True)
    assert "void knife_rhs(" in source and "void knife_jacobian(" in source
    module = _python_module(export(knife, "chetaev", "python", prefix="knife_"))
    assert callable(module["knife_rhs"]) and "rhs" not in module


def test_python_module_refuses_a_wrong_state() -> None:
    module = _python_module(export(_system("knife_edge"), "chaplygin", "python"))
    with pytest.raises(ValueError, match="expected y of 5 and p of 2 numbers"):
        module["rhs"](0.0, [0.0, 0.0, 0.1], [1.0, 1.0])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"to": "fortran"}, "to='fortran': export writes 'c' or 'python'"),
        ({"to": "c", "prefix": "2x"}, "prefix='2x': give letters, digits and '_'"),
        ({"to": "c", "prefix": "a b"}, "prefix='a b'"),
    ],
)
def test_bad_options_are_refused(kwargs: dict[str, Any], message: str) -> None:
    with pytest.raises(ChaplyginError, match=message.replace("(", r"\(").replace(")", r"\)")):
        export(_system("knife_edge"), "chaplygin", **kwargs)


def test_unknown_model_is_refused() -> None:
    with pytest.raises(ChaplyginError, match="unknown model 'newton'"):
        export(_system("knife_edge"), "newton")


def test_command_line_writes_and_prints(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from chaplygin.apps.cli import app

    runner = CliRunner()
    out = tmp_path / "deep" / "knife.py"
    args = [
        "export",
        "example:knife-edge",
        "--model",
        "chetaev",
        "--to",
        "python",
        "--jacobian",
        "-o",
        str(out),
    ]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    assert "rhs and jacobian of chetaev/classic" in result.stdout
    module = _python_module(out.read_text(encoding="utf-8"))
    assert module["STATE"] == ("x", "y", "phi", "x'", "y'", "phi'") and callable(module["jacobian"])
    again = runner.invoke(app, args)
    assert again.exit_code == 1 and "pass --force" in again.stderr
    assert runner.invoke(app, [*args, "--force"]).exit_code == 0
    printed = runner.invoke(app, ["export", "example:knife-edge", "--to", "c"])  # the true motion
    assert printed.exit_code == 0 and printed.stdout.startswith("/*")
    assert "chaplygin/classic equations of Knife edge" in printed.stdout
    assert runner.invoke(app, ["export", "example:knife-edge", "--to", "fortran"]).exit_code == 2
    assert runner.invoke(app, ["export", "example:knife-edge", "--to", "c", "--prefix", "1x"]).exit_code == 2
