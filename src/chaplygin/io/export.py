"""A model's equations of motion as standalone code: a C file or a plain Python module.

:func:`export` writes the first-order right-hand side ``ẏ = f(t, y, p)`` of one
model (and, on request, its Jacobian ``∂f/∂y``) as source that needs nothing
from chaplygin: C99 with ``math.h`` only, or Python with ``math`` and NumPy
only.  The state ``y`` and the parameters ``p`` are in the order of
:class:`chaplygin.numeric.codegen.Layout` (all coordinates, the velocities the model
integrates, the vakonomic multipliers μ; the system's parameters sorted by
name, then the constants ``c_β`` of a vakonomic family), and the header
comment of the generated file lists them entry by entry.

The code is the one :mod:`chaplygin.numeric.codegen` generates for simulation, from the
same ``M·x = F`` and printed by the same printers (:mod:`chaplygin.numeric._printing`,
:func:`chaplygin.numeric._cfill.body`): ``f`` fills ``M`` and ``F``, solves ``M·x = F``
by Gaussian elimination with partial pivoting and returns the velocities and
the first ``K`` entries of ``x``.  The Jacobian is exact, not differenced:
differentiating ``M·x = F`` gives ``M·∂x/∂y_j = ∂(F − M·X)/∂y_j`` at ``X = x``,
whose right-hand sides are generated symbolically (SymEngine's derivatives)
and solved with the same ``M``.  Export always uses the symbolically derived
equations (:meth:`System.equations`), never the numerical reduction that
:func:`chaplygin.numeric.codegen.compile_model` uses for large systems.
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING

from chaplygin.errors import ChaplyginError
from chaplygin.models import registry
from chaplygin.numeric import _cfill

if TYPE_CHECKING:
    from chaplygin.core.system import System
    from chaplygin.models.equations import Equations
    from chaplygin.numeric.codegen import Layout, _Block

__all__ = ["TARGETS", "export"]

#: what ``to=`` accepts
TARGETS = ("c", "python")
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


def export(
    system: System,
    model: str,
    to: str = "c",
    *,
    form: str = "classic",
    jacobian: bool = False,
    prefix: str = "",
) -> str:
    """The source of a standalone ``rhs(t, y, p)`` (and ``jacobian``) for one model.

    Parameters
    ----------
    system : System
    model : str
        Any model of :meth:`System.equations` (``"chetaev"``, ``"chaplygin"``, …).
    to : {"c", "python"}
        ``"c"``: one C99 file defining
        ``void rhs(double t, const double *y, const double *p, double *dydt)``
        and, with ``jacobian``,
        ``void jacobian(double t, const double *y, const double *p, double *J)``
        (``J`` row-major, ``J[i*NY + j] = ∂f_i/∂y_j``); everything else in the
        file is ``static``.  ``"python"``: a module with ``rhs(t, y, p)``
        returning an array of ``NY`` numbers and ``jacobian(t, y, p)`` an
        ``NY × NY`` array, and the constants ``NY``, ``NP``, ``STATE``,
        ``PARAMETERS``.
    form : {"classic", "new"}
        The form of a reduced model.
    jacobian : bool
        Also generate ``jacobian``.
    prefix : str
        Put before the names ``rhs`` and ``jacobian`` (``"sphere_"`` gives
        ``sphere_rhs``), so that several models can be linked into one program;
        letters, digits and ``_``, not starting with a digit.

    Returns
    -------
    str
        The file's text.  Its header comment documents the argument order: the
        entries of ``y`` and ``p``, by index and name.

    Raises
    ------
    ChaplyginError
        For a ``to`` or ``prefix`` that is not accepted, a model or form that
        does not apply to ``system``, or (C) a function C's ``math.h`` lacks.
    """
    if to not in TARGETS:
        raise ChaplyginError(f"to={to!r}: export writes {' or '.join(map(repr, TARGETS))}.")
    if prefix and not _IDENTIFIER.match(prefix):
        raise ChaplyginError(
            f"prefix={prefix!r}: give letters, digits and '_' (not starting with a digit), e.g. 'sphere_'."
        )
    eqs = system.equations(model, form)
    layout, main, derivatives, dim, k = _blocks(eqs, jacobian)
    if to == "c":
        return _c_source(eqs, layout, main, derivatives, dim, k, prefix)
    return _python_source(eqs, layout, main, derivatives, dim, k, prefix)


# ------------------------------------------------------------------ what is computed
def _blocks(eqs: Equations, jacobian: bool) -> tuple[Layout, _Block, _Block | None, int, int]:
    """The layout; the block filling ``M`` (row-major), ``F`` and the velocities ``V``; with
    ``jacobian``, the block filling ``R[j, r] = ∂(F − M·x)_r/∂y_j`` and ``dV[j, i] = ∂V_i/∂y_j``
    (``x`` given); ``M``'s size; ``K``, the entries of ``x`` that are derivatives of ``y``."""
    import sympy as sp

    from chaplygin.core._fast import jacobian as differentiate
    from chaplygin.numeric._layout import state_symbols
    from chaplygin.numeric.codegen import _at, _Block, _plain

    layout, to_num, velocities, k = state_symbols(eqs)
    plain = _plain(to_num)
    n, dim = eqs.system.n, eqs._M.shape[0]
    M, F = list(eqs._M), list(eqs._F)
    targets = (
        [("M", i, dim) for i in range(dim * dim)]
        + [("F", i, 0) for i in range(dim)]
        + [("V", i, 0) for i in range(n)]
    )
    main = _Block(_at([*M, *F, *velocities], plain), targets, "c_", skip_zero=dim * dim)
    if not jacobian:
        return layout, main, None, dim, k
    y = sp.IndexedBase("y")
    state = sorted((value.indices[0], symbol) for symbol, value in to_num.items() if value.base == y)
    variables = [symbol for _, symbol in state]
    x = [sp.Symbol(f"x[{c}]") for c in range(dim)]
    residual = [F[r] - sum((M[r * dim + c] * x[c] for c in range(dim)), sp.S.Zero) for r in range(dim)]
    d = differentiate([*residual, *velocities], variables)  # rows: residual then V; columns: y_j
    size = len(variables)
    exprs = [d[r, j] for j in range(size) for r in range(dim)] + [
        d[dim + i, j] for j in range(size) for i in range(n)
    ]
    targets = [("R", j * dim + r, dim) for j in range(size) for r in range(dim)] + [
        ("dV", j * n + i, n) for j in range(size) for i in range(n)
    ]
    return layout, main, _Block(_at(exprs, plain), targets, "d_", skip_zero=len(targets)), dim, k


def _header(
    eqs: Equations, layout: Layout, jacobian: bool, language: str, prefix: str, name: str
) -> list[str]:
    """The lines of the generated file's header comment: what it computes, the layout of ``y`` and ``p``
    (``name``: the system's name, made safe for the comment by the caller)."""
    from chaplygin._version import __version__

    s = eqs.system
    ny, n_mu = len(layout.state), len(layout.multipliers)
    c = language == "c"
    lines = [
        f"Generated by chaplygin {__version__} from the {layout.model}/{layout.form} equations of {name}:",
        f"{eqs.title}.",
        "",
        "The first-order right-hand side dy/dt = f(t, y, p):",
        (
            f"    void {prefix}rhs(double t, const double *y, const double *p, double *dydt);"
            if c
            else f"    {prefix}rhs(t, y, p) -> ndarray of NY numbers"
        ),
        "dydt[i] is the time derivative of y[i].",
    ]
    if jacobian:
        lines += [
            "Its Jacobian df/dy, exact (not differenced):",
            (
                f"    void {prefix}jacobian(double t, const double *y, const double *p, double *J);"
                if c
                else f"    {prefix}jacobian(t, y, p) -> ndarray NY x NY"
            ),
            "J[i*NY + j] = df_i/dy_j (row-major)." if c else "J[i, j] = df_i/dy_j.",
        ]
    lines += ["", f"y, NY = {ny} numbers, in this order:"]
    kinds = (
        ["coordinate"] * len(layout.coordinates)
        + ["velocity"] * len(layout.velocities)
        + ["vakonomic multiplier mu (integrated)"] * n_mu
    )
    width = max(len(name) for name in layout.state)
    lines += [
        f"    y[{i}]{' ' * (len(str(ny)) - len(str(i)))}  {name:<{width}}  {kind}"
        for i, (name, kind) in enumerate(zip(layout.state, kinds))
    ]
    n_par = len(layout.parameters)
    lines += [
        "",
        f"p, NP = {n_par} numbers, in this order:" if n_par else "p: no parameters (pass any pointer).",
    ]
    constants = {str(c_) for c_ in eqs.constants}
    lines += [
        f"    p[{j}]  {name}" + ("  (constant c of the vakonomic family)" if name in constants else "")
        for j, name in enumerate(layout.parameters)
    ]
    dependent = [q.func.__name__ for q in s.dependent]
    if not registry.get(layout.model).reduced:  # the multiplier models integrate every velocity
        lines += [
            "",
            "y holds every velocity; the constraints hold along a motion only if the initial",
            "state satisfies them (f imposes them at the level of accelerations).",
        ]
        if layout.reactions:
            lines.append(
                f"The multipliers {', '.join(layout.reactions)} are solved for inside f; they are not in y."
            )
    elif dependent:
        velocities = ", ".join(q + "'" for q in dependent)
        lines += [
            "",
            f"Not in y: the dependent velocities ({velocities}); f computes them from the constraints.",
        ]
    lines += [
        "",
        "Units: none. f is what the equations say; give every number in one consistent system of units.",
        "A singular mass matrix gives " + ("NaN in the result." if c else "numpy.linalg.LinAlgError."),
    ]
    return lines


# ------------------------------------------------------------------ C
def _comment_safe(text: str) -> str:
    """``text`` in printable ASCII that cannot end a C comment."""
    out = "".join(ch if 32 <= ord(ch) < 127 else f"<U+{ord(ch):04X}>" for ch in text)
    return out.replace("*/", "* /")


def _c_source(
    eqs: Equations, layout: Layout, main: _Block, derivatives: _Block | None, dim: int, k: int, prefix: str
) -> str:
    from chaplygin.numeric.codegen import _assignments, _Fill

    n, ny = eqs.system.n, len(layout.state)

    def statements(block: _Block) -> list[str]:
        try:
            return _cfill.body(_Fill(block), [_assignments(block)])
        except _cfill.Unavailable as exc:
            raise ChaplyginError(f"export to C: {exc}; export to='python' instead.") from None

    header = _header(eqs, layout, derivatives is not None, "c", prefix, eqs.system.name)
    parts = [
        "/*",
        *(f" * {_comment_safe(line)}".rstrip() for line in header),
        " */",
        "#include <math.h>",
        _cfill._SOLVE,
        "/* M (row-major), F and the velocities V at (t, y, p): M x = F gives the accelerations. */",
        "static void chaplygin_fill(double t, const double *y, const double *p, double *M, double *F, double *V)",
        "{",
        *statements(main),
        "}",
        "",
        f"void {prefix}rhs(double t, const double *y, const double *p, double *dydt)",
        "{",
        f"    double M[{dim * dim}] = {{0.0}}, F[{dim}], V[{n}], x[{dim}];",
        "    chaplygin_fill(t, y, p, M, F, V);",
        f"    chaplygin_solve({dim}, M, F, x);",
        f"    for (int i = 0; i < {n}; ++i) dydt[i] = V[i];",
        f"    for (int i = 0; i < {k}; ++i) dydt[{n} + i] = x[i];",
        "}",
        "",
    ]
    if derivatives is not None:
        parts += [
            "/* R[j*DIM + r] = d(F - M X)_r/dy_j at X = x, and dV[j*N + i] = dV_i/dy_j. */",
            (
                "static void chaplygin_dfill(double t, const double *y, const double *p, const double *x, "
                "double *R, double *dV)"
            ),
            "{",
            "    (void)x;",
            *statements(derivatives),
            "}",
            "",
            f"void {prefix}jacobian(double t, const double *y, const double *p, double *J)",
            "{",
            f"    double M[{dim * dim}] = {{0.0}}, F[{dim}], V[{n}], x[{dim}], A[{dim * dim}], b[{dim}], dx[{dim}];",
            f"    double R[{ny * dim}] = {{0.0}}, dV[{ny * n}] = {{0.0}};",
            "    chaplygin_fill(t, y, p, M, F, V);",
            f"    for (int i = 0; i < {dim * dim}; ++i) A[i] = M[i];",
            f"    chaplygin_solve({dim}, A, F, x);",
            "    chaplygin_dfill(t, y, p, x, R, dV);",
            f"    for (int j = 0; j < {ny}; ++j) {{",
            f"        for (int i = 0; i < {n}; ++i) J[i * {ny} + j] = dV[j * {n} + i];",
            f"        for (int i = 0; i < {dim * dim}; ++i) A[i] = M[i];",
            f"        for (int r = 0; r < {dim}; ++r) b[r] = R[j * {dim} + r];",
            f"        chaplygin_solve({dim}, A, b, dx);  /* M dx/dy_j = R_j */",
            f"        for (int i = 0; i < {k}; ++i) J[({n} + i) * {ny} + j] = dx[i];",
            "    }",
            "}",
            "",
        ]
    return "\n".join(parts)


# ------------------------------------------------------------------ Python
def _python_source(
    eqs: Equations, layout: Layout, main: _Block, derivatives: _Block | None, dim: int, k: int, prefix: str
) -> str:
    from chaplygin.numeric.codegen import _assignments, _docstring_safe, _Fill, _python_body

    n, ny = eqs.system.n, len(layout.state)
    # the system's name is the only free text in the header (the rest: identifiers, fixed titles)
    doc = "\n".join(
        _header(eqs, layout, derivatives is not None, "python", prefix, _docstring_safe(eqs.system.name))
    )
    check = """    y = np.asarray(y, dtype=float)
    p = np.asarray(p, dtype=float)
    if y.shape != (NY,) or p.shape != (NP,):
        raise ValueError(f"expected y of {NY} and p of {NP} numbers (see this module's docstring), "
                         f"not shapes {y.shape} and {p.shape}")
"""
    body = "\n".join(_python_body(_Fill(main), [_assignments(main)]))
    source = f'''"""{doc}
"""

import math

import numpy as np

NY = {ny}
NP = {len(layout.parameters)}
STATE = {tuple(layout.state)!r}
PARAMETERS = {tuple(layout.parameters)!r}
_N = {n}  # coordinates (the first entries of y and of dy/dt)
_K = {k}  # entries of the solution x of M x = F that are dy/dt after the first _N
_DIM = {dim}  # size of M


def _fill(t, y, p, M, F, V):
    """M, F and the velocities V at (t, y, p): M x = F gives the accelerations."""
{body}


def {prefix}rhs(t, y, p):
    """dy/dt at (t, y, p): the velocities, then the first _K entries of x solving M x = F."""
{check}    M = np.zeros((_DIM, _DIM))
    F = np.zeros(_DIM)
    V = np.zeros(_N)
    _fill(t, y, p, M, F, V)
    x = np.linalg.solve(M, F)
    return np.concatenate((V, x[:_K]))
'''
    if derivatives is not None:
        dbody = "\n".join(_python_body(_Fill(derivatives), [_assignments(derivatives)]))
        source += f'''

def _dfill(t, y, p, x, R, dV):
    """R[j, r] = d(F - M X)_r/dy_j at X = x, and dV[j, i] = dV_i/dy_j."""
{dbody}


def {prefix}jacobian(t, y, p):
    """df/dy at (t, y, p): J[i, j] = df_i/dy_j (M dx/dy_j = d(F - M X)/dy_j at X = x)."""
{check}    M = np.zeros((_DIM, _DIM))
    F = np.zeros(_DIM)
    V = np.zeros(_N)
    _fill(t, y, p, M, F, V)
    x = np.linalg.solve(M, F)
    R = np.zeros((NY, _DIM))
    dV = np.zeros((NY, _N))
    _dfill(t, y, p, x, R, dV)
    J = np.empty((NY, NY))
    J[:_N, :] = dV.T
    J[_N:, :] = np.linalg.solve(M, R.T)[:_K, :]
    return J
'''
    return source
