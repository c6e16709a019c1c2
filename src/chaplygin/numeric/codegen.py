"""Numerical code generated from a model's ``M·x = F`` with a fixed argument order.

Every generated function takes ``(t, y, p)``:

* ``t`` — time;
* ``y`` — the state, in the order given by :class:`Layout`:
  all coordinates ``q_1 … q_n`` in the system's order, then the velocities the
  model integrates (the independent ones ``q̇_σ`` for reduced models, all of
  them for the multiplier models), then the multipliers ``μ_β`` (vakonomic
  multiplier model only);
* ``p`` — the parameter values in :attr:`Layout.parameters` order: the
  system's parameters (sorted by name), then the constants ``c_β`` of a
  vakonomic family.

The symbolic model stays free of numerics: this module only reads an
:class:`~chaplygin.Equations` object's mass matrix, forcing and kinematics
(or, for the numerically reduced models, the Chetaev matrices derived in
SymEngine by :mod:`chaplygin.core._native`), writes one Python module (plain
``math`` code with common subexpressions eliminated, printed by
:mod:`chaplygin.numeric._printing`) to the cache directory, and imports it.  The ``numpy`` backend
runs that module as it is; the ``numba`` backend compiles the same functions
with ``numba.njit``, except that a large ``fill`` is printed as C and built by
the system's C compiler (:mod:`chaplygin.numeric._cfill`), which numba then calls.  Generated modules are written atomically and keyed by a
hash of their source, so they are never half-written and are shared between
runs.
"""

from __future__ import annotations

import heapq
import inspect
import itertools
import threading
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import sympy as sp

from chaplygin.core._fast import cse, native, to_sympy
from chaplygin.core._native import chetaev_matrices
from chaplygin.core._symbols import TIME
from chaplygin.errors import ChaplyginError, ModelError
from chaplygin.models import registry
from chaplygin.numeric import _cfill, _modelcache, targets
from chaplygin.numeric._ckernel import CompiledModel, Layout
from chaplygin.numeric._layout import state_symbols
from chaplygin.numeric._loop import _k_pivot, _k_solve
from chaplygin.numeric._printing import code
from chaplygin.numeric.cache import cache_dir

if TYPE_CHECKING:
    from chaplygin.core.system import System
    from chaplygin.models.equations import Equations
    from chaplygin.models.registry import Model

__all__ = [
    "BACKENDS",
    "REDUCTIONS",
    "CompiledModel",
    "Layout",
    "cache_dir",
    "compile_equations",
    "compile_model",
    "model_blocks",
    "reduces_numerically",
]

#: what ``compile_model(backend=…)`` accepts: the targets that compile models (:mod:`chaplygin.numeric.targets`)
BACKENDS = targets.offered("compile")
#: bumped whenever the generated code changes shape, so that no stale cache is reused
CODE_FORMAT = 8


def _docstring_safe(text: str) -> str:
    """``text`` escaped so that it cannot end or escape the generated module's docstring."""
    return text.encode("unicode_escape").decode("ascii").replace('"', "\\x22")


def _version() -> str:
    from chaplygin._version import __version__

    return __version__


#: where ``fill`` stores one value: array name, flat (row-major) index, row width (0: 1-D)
Target = tuple[str, int, int]


@dataclass(frozen=True)
class _Block:
    """Assignments ``target = expr``, whose common subexpressions are named ``prefix0, …``.

    The first ``skip_zero`` targets (arrays zeroed before ``fill``) are left out
    where their expression is 0.
    """

    exprs: list[Any]  # SymEngine or SymPy
    targets: list[Target]
    prefix: str
    skip_zero: int = 0


@dataclass(frozen=True)
class _Fill:
    """What ``fill(t, y, p, M, F, V, O)`` computes, in no particular language.

    With ``solve = g > 0`` it first fills ``Ad`` (g × g) and ``b`` from
    ``pre`` and solves ``Ad·d = b`` (the numerically reduced models), then
    evaluates ``main``.  :func:`_python_body` and :mod:`chaplygin.numeric._cfill` print it.
    """

    main: _Block
    solve: int = 0
    pre: _Block | None = None

    def blocks(self) -> list[_Block]:
        return [self.pre, self.main] if self.pre is not None else [self.main]


def _canonical(
    replacements: list[tuple[Any, Any]], reduced: list[Any], prefix: str
) -> tuple[list[tuple[Any, Any]], list[Any]]:
    """``cse``'s result renamed and ordered in a way that does not depend on the process.

    SymEngine's ``cse`` finds the same subexpressions in every process but
    numbers them in an order that varies from run to run (it follows memory
    addresses), so the generated source — and every cache keyed by its hash,
    numba's included — changed with each process.  Here each subexpression is
    named once all those it uses are named, the smallest printed form first.
    """
    names = [s for s, _ in replacements]
    index = {s: k for k, s in enumerate(names)}
    deps = [[index[x] for x in e.free_symbols if x in index] for _, e in replacements]
    users: list[list[int]] = [[] for _ in names]
    for k, used in enumerate(deps):
        for j in used:
            users[j].append(k)
    waiting = [len(used) for used in deps]
    rename: dict[Any, Any] = {}
    renamed: dict[int, Any] = {}
    ready: list[tuple[str, int]] = []

    def push(k: int) -> None:
        e = replacements[k][1]
        renamed[k] = e.xreplace({names[j]: rename[names[j]] for j in deps[k]}) if deps[k] else e
        heapq.heappush(ready, (str(renamed[k]), k))

    for k in range(len(names)):
        if not waiting[k]:
            push(k)
    order: list[int] = []
    while ready:
        _, k = heapq.heappop(ready)
        rename[names[k]] = type(names[k])(f"{prefix}{len(order)}")
        order.append(k)
        for u in users[k]:
            waiting[u] -= 1
            if not waiting[u]:
                push(u)
    out = [e.xreplace({s: rename[s] for s in e.free_symbols if s in rename}) for e in reduced]
    return [(rename[names[k]], renamed[k]) for k in order], out


def _assignments(block: _Block) -> tuple[list[tuple[Any, Any]], list[tuple[Target, Any]]]:
    """The block's common subexpressions and its (target, expression) pairs still to store."""
    replacements, reduced = _canonical(*cse(block.exprs, block.prefix), block.prefix)
    stores = [
        (target, e)
        for i, (target, e) in enumerate(zip(block.targets, reduced))
        if i >= block.skip_zero or e != 0
    ]
    return replacements, stores


def _python_body(
    fill: _Fill, assigned: list[tuple[list, list[tuple[Target, Any]]]], lists: bool = False
) -> list[str]:
    """``fill``'s body as Python lines (``math`` calls; run by numpy, compiled by numba).

    ``assigned``: :func:`_assignments` of each of ``fill.blocks()``.  With ``lists``
    the arrays are Python lists (``M[i][j]``; ``y`` and ``p`` lists of floats too):
    what the ``numpy`` backend runs, as indexing a list costs a fraction of
    indexing an array from Python.
    """
    g = fill.solve
    out: list[str] = []
    if g:
        out += (
            [f"    Ad = [[0.0] * {g} for _ in range({g})]", f"    b = [0.0] * {g}"]
            if lists
            else [f"    Ad = np.zeros(({g}, {g}))", f"    b = np.zeros({g})"]
        )
    for block, (replacements, stores) in zip(fill.blocks(), assigned):
        out += [f"    {sym} = {code(e, 'python')}" for sym, e in replacements]
        out += [
            f"    {name}[{(f'{i // w}][{i % w}' if lists else f'{i // w}, {i % w}') if w else i}] = "
            + code(e, "python")
            for (name, i, w), e in stores
        ]
        if block is fill.pre:
            out.append(f"    d = {'_lsolve' if lists else 'np.linalg.solve'}(Ad, b)")
    return out or ["    pass"]


def _targets(dim: int, n: int, g: int) -> list[Target]:
    """Where ``fill`` stores M (row-major), F, the velocities, energy and residuals."""
    return (
        [("M", i, dim) for i in range(dim * dim)]
        + [("F", i, 0) for i in range(dim)]
        + [("V", i, 0) for i in range(n)]
        + [("O", i, 0) for i in range(1 + g)]
    )


def _plain(to_num: dict[sp.Symbol, sp.Expr]) -> dict[sp.Symbol, sp.Expr]:
    """``y[i]``, ``p[j]`` as symbols of those names (printed as they are) for SymEngine's cse."""
    return {k: sp.Symbol(f"{v.base}[{v.indices[0]}]") for k, v in to_num.items()} | {TIME: sp.Symbol("t")}


def _common(items: list[Any]) -> list[Any]:
    """``items`` (SymPy or SymEngine) all as SymEngine expressions, or all as SymPy's if SymEngine cannot."""
    fast = native(items)
    return fast if fast is not None else [to_sympy(e) for e in items]


def _at(exprs: list[Any], plain: dict[sp.Symbol, sp.Expr]) -> list[Any]:
    """``exprs`` with ``plain``'s symbols substituted (see :func:`_common`)."""
    items = _common([*exprs, *plain, *plain.values()])
    k, m = len(exprs), len(plain)
    rule = dict(zip(items[k : k + m], items[k + m :]))
    return [e.xreplace(rule) for e in items[:k]]


def _kinematics(s: System) -> tuple[Any, list[list[Any]], list[Any], list[Any]]:
    """The monitored quantity (:func:`monitored`), the rows of ``A``, ``A_0`` and ``q̇``
    (SymEngine's where it has them)."""
    nat = s._native
    if nat is not None:
        return monitored(s, nat.T, nat.U, nat.xd), nat.A, nat.A0, nat.xd
    return monitored(s, s._T, s._U, s._vars.xd), s._A.tolist(), list(s._A0), list(s._vars.xd)


def monitored(s: System, T: Any, U: Any, xd: Any) -> Any:
    """What the ``energy`` observable computes (:func:`chaplygin.numeric.simulate.monitor`):
    ``T − U``, or Jacobi's integral ``Σ q̇ ∂T/∂q̇ − T − U`` where T is not quadratic in ``q̇``."""
    from chaplygin.numeric.simulate import monitor

    if monitor(s).column == "jacobi_integral":
        return sum((v * T.diff(v) for v in xd), 0) - T - U
    return T - U


def _main_block(
    s: System, M: list[Any], F: list[Any], velocities: list[Any], plain: dict[sp.Symbol, sp.Expr]
) -> _Block:
    """``M`` (flat, row-major), ``F``, the full velocities, energy and constraint residuals at ``plain``'s symbols."""
    energy, A, A0, xd = _kinematics(s)
    dim, n, g = len(F), s.n, s.g
    items = _common([*M, *F, *velocities, energy, *(a for row in A for a in row), *A0, *xd])
    cut = np.cumsum([0, dim * dim, dim, n, 1, g * n, g])
    M, F, velocities, (energy,), A, A0, xd = (items[i:j] for i, j in zip(cut, [*cut[1:], None]))
    full = dict(zip(xd, velocities))
    energy = energy.xreplace(full)
    # f = A q̇ + A_0 at the full velocities (A and A_0 hold q̇ where f is nonlinear in it)
    residual = [sum((A[b * n + j] * xd[j] for j in range(n)), A0[b]).xreplace(full) for b in range(g)]
    exprs = _at([*M, *F, *velocities, energy, *residual], plain)
    return _Block(exprs, _targets(dim, n, g), "c_", skip_zero=dim * dim)


def _off_the_kink(e: sp.Expr) -> sp.Expr:
    """A Jacobian's entry with ``DiracDelta(u)``, the derivative of ``sign(u)``, as what it is off
    ``u = 0``, zero, and NaN on it (where the Jacobian does not exist)."""
    if not e.has(sp.DiracDelta):
        return e
    return e.replace(sp.DiracDelta, lambda u, *order: sp.Piecewise((sp.nan, sp.Eq(u, 0)), (0, True)))


def model_blocks(eqs: Equations, jacobian: bool) -> tuple[Layout, _Block, _Block | None, int, int]:
    """The layout; the block filling ``M`` (row-major), ``F`` and the velocities ``V``; with
    ``jacobian``, the block filling ``R[j, r] = ∂(F − M·x)_r/∂y_j`` and ``dV[j, i] = ∂V_i/∂y_j``
    (``x`` given: the solution of ``M·x = F``, so that ``M·∂x/∂y_j = R[j]``); ``M``'s size; ``K``,
    the entries of ``x`` that are derivatives of ``y``.  What :func:`chaplygin.io.export.export`
    prints and :mod:`chaplygin.numeric.linearization` evaluates."""
    from chaplygin.core._fast import jacobian as differentiate

    layout, to_num, velocities, k = state_symbols(eqs)
    plain = _plain(to_num)
    n, dim = eqs.system.n, eqs._M.shape[0]
    y = sp.IndexedBase("y")
    state = sorted((value.indices[0], symbol) for symbol, value in to_num.items() if value.base == y)
    variables = [symbol for _, symbol in state]
    x = [sp.Symbol(f"x[{c}]") for c in range(dim)]
    size = len(variables)
    # converted to SymEngine once and differentiated there (SymPy's only where SymEngine cannot)
    fast = native([*eqs._M, *eqs._F, *velocities, *variables, *x]) if jacobian else None
    items = fast if fast is not None else [*eqs._M, *eqs._F, *velocities, *variables, *x]
    cut = np.cumsum([0, dim * dim, dim, n, size, dim])
    M, F, V, y_k, x = (items[i:j] for i, j in itertools.pairwise(cut))
    targets = (
        [("M", i, dim) for i in range(dim * dim)]
        + [("F", i, 0) for i in range(dim)]
        + [("V", i, 0) for i in range(n)]
    )
    main = _Block(_at([*M, *F, *V], plain), targets, "c_", skip_zero=dim * dim)
    if not jacobian:
        return layout, main, None, dim, k
    residual = [F[r] - sum((M[r * dim + c] * x[c] for c in range(dim)), 0) for r in range(dim)]
    if fast is not None:
        exprs = [residual[r].diff(y_k[j]) for j in range(size) for r in range(dim)]
        exprs += [V[i].diff(y_k[j]) for j in range(size) for i in range(n)]
    else:
        d = differentiate([*residual, *V], variables).applyfunc(_off_the_kink)  # rows: residual, V
        exprs = [d[r, j] for j in range(size) for r in range(dim)]
        exprs += [d[dim + i, j] for j in range(size) for i in range(n)]
    targets = [("R", j * dim + r, dim) for j in range(size) for r in range(dim)] + [
        ("dV", j * n + i, n) for j in range(size) for i in range(n)
    ]
    return layout, main, _Block(_at(exprs, plain), targets, "d_", skip_zero=len(targets)), dim, k


@dataclass(frozen=True)
class _Parts:
    """What a model's generated code is made of: its layout, ``fill``, ``M``'s size, ``K``."""

    system: System
    layout: Layout
    fill: _Fill
    dim: int
    k: int


def _source(eqs: Equations, backend: str) -> tuple[Layout, str]:
    """The layout and the generated Python module of ``eqs`` (numpy or numba)."""
    parts = _parts(eqs)
    return parts.layout, _module(parts.system, parts.layout, parts.fill, parts.dim, parts.k, backend)


def _parts(eqs: Equations) -> _Parts:
    layout, to_num, velocities, k = state_symbols(eqs)
    F = list(eqs._F) if eqs._native_F is None else eqs._native_F
    fill = _Fill(_main_block(eqs.system, list(eqs._M), F, velocities, _plain(to_num)))
    return _Parts(eqs.system, layout, fill, eqs._M.shape[0], k)


def _numeric_reduction_parts(s: System, model: str) -> _Parts:
    """A reduced model (Chaplygin's or Voronets' equations) computed from the Chetaev model.

    The state is that of the reduced model (coordinates, independent
    velocities); ``fill`` solves the constraints ``A_dep q̇_dep = −(A_ind q̇_σ + A_0)``
    numerically (for constraints nonlinear in the velocities it takes their solved form
    ``q̇_dep = φ(q, q̇_σ, t)``, the branch chosen), then fills the multiplier system (6) with
    its unknowns ordered ``[q̈_σ, q̈_dep, λ]``, whose leading ε entries are the reduced model's
    accelerations at that (admissible) state.  No symbolic ``B`` is needed, so
    systems far too large for a symbolic elimination compile in seconds.  The
    Chetaev matrices are derived in SymEngine (:mod:`chaplygin.core._native`) where
    it can represent the system, else taken from :meth:`System.equations`.
    """
    v, n, g, ind, dep = s._vars, s.n, s.g, list(s._ind), list(s._dep)
    names = [q.func.__name__ for q in s.coordinates]
    layout = Layout(
        model,
        "numeric",
        tuple(names),
        tuple(names[i] + "'" for i in ind),
        (),
        tuple(par.name for par in s.parameters),
    )
    y, p = sp.IndexedBase("y"), sp.IndexedBase("p")
    to_num: dict[sp.Symbol, sp.Expr] = {x: y[i] for i, x in enumerate(v.x)}
    to_num.update({v.xd[i]: y[n + k] for k, i in enumerate(ind)})
    to_num.update({par: p[j] for j, par in enumerate(s.parameters)})
    plain = _plain(to_num)
    if s._native is not None:
        rows, F = chetaev_matrices(s._native)
    else:
        eqs = s.equations("chetaev")
        rows, F = eqs._M.tolist(), list(eqs._F)
    _, A, A0, xd = _kinematics(s)
    if s.is_nonlinear:  # q̇_dep = φ(q, q̇_σ, t), the branch chosen: no linear solve
        plain.update({v.xd[i]: v.xd[i].xreplace(s._velocity_substitution).xreplace(plain) for i in dep})
        M = [row[j] for row in rows for j in [*ind, *dep, *range(n, n + g)]]
        return _Parts(s, layout, _Fill(_main_block(s, M, F, list(xd), plain)), n + g, len(ind))
    a_dep = [A[b][j] for b in range(g) for j in dep]
    rhs = [-(sum((A[b][i] * xd[i] for i in ind), 0) + A0[b]) for b in range(g)]
    pre = _Block(
        _at([*a_dep, *rhs], plain),
        [("Ad", i, g) for i in range(g * g)] + [("b", i, 0) for i in range(g)],
        "a_",
        skip_zero=g * g,
    )
    plain.update({v.xd[i]: sp.Symbol(f"d[{k}]") for k, i in enumerate(dep)})
    M = [row[j] for row in rows for j in [*ind, *dep, *range(n, n + g)]]
    fill = _Fill(_main_block(s, M, F, list(xd), plain), solve=g, pre=pre)
    return _Parts(s, layout, fill, n + g, len(ind))


def _fill_source(fill: _Fill, backend: str) -> str:
    """``fill``'s definition: Python (numpy; numba for small models) or a call into generated C."""
    assigned = [_assignments(block) for block in fill.blocks()]
    if backend == "numba" and sum(len(r) + len(st) for r, st in assigned) >= C_FILL_FROM_LINES:
        try:
            return _cfill.numba_fill(*_cfill.build(fill, assigned))
        except _cfill.Unavailable as exc:
            warnings.warn(
                f"chaplygin: numba compiles this model's large fill itself, which can take minutes, "
                f"because generated C is not available: {exc}",
                RuntimeWarning,
                stacklevel=4,
            )
    if backend == "numpy":
        return _LIST_FILL + "\n".join(_python_body(fill, assigned, lists=True)) + "\n"
    deco = "@_jit\n" if backend == "numba" else ""
    return f"{deco}def fill(t, y, p, M, F, V, O):\n" + "\n".join(_python_body(fill, assigned)) + "\n"


#: the numpy backend's ``fill`` (arrays, as everywhere) on top of ``_fill`` (lists), its
#: list solver and its ``rhs``: no array is indexed from Python in a right-hand side
_LIST_FILL = '''def fill(t, y, p, M, F, V, O):
    m, f, v, o = _lists()
    _fill_floats(t, _floats(y), _floats(p), m, f, v, o)
    M[:, :] = m
    F[:] = f
    V[:] = v
    O[:] = o


def _floats(a):
    return a.tolist() if type(a) is np.ndarray else [float(x) for x in a]


def _lsolve(M, b):
    """``M⁻¹b`` for lists (``M`` and ``b`` are overwritten): partial pivoting, as LAPACK's gesv."""
    n = len(b)
    if n > 8:
        return np.linalg.solve(np.array(M), np.array(b)).tolist()
    for c in range(n):
        piv, big = c, abs(M[c][c])
        for r in range(c + 1, n):
            if abs(M[r][c]) > big:
                piv, big = r, abs(M[r][c])
        if big == 0.0:
            raise np.linalg.LinAlgError("Matrix is singular.")
        if piv != c:
            M[c], M[piv], b[c], b[piv] = M[piv], M[c], b[piv], b[c]
        row, pivot = M[c], M[c][c]
        for r in range(c + 1, n):
            other = M[r]
            factor = other[c] / pivot
            if factor:
                for j in range(c + 1, n):
                    other[j] -= factor * row[j]
                b[r] -= factor * b[c]
    for c in range(n - 1, -1, -1):
        row, acc = M[c], b[c]
        for j in range(c + 1, n):
            acc -= row[j] * b[j]
        b[c] = acc / row[c]
    return b


def rhs_list(t, y, p):
    """dy/dt for ``y`` and ``p`` given as lists of floats, as a new list: what the numpy
    backend's DOP853 stepper (chaplygin.numeric._pyloop) calls, with no array in a step."""
    m, f, v, o = _lists()
    _fill_floats(t, y, p, m, f, v, o)
    return v + _msolve(m, f)[:K]


def _rhs(t, y, p):
    """The numpy backend's ``rhs``: lists all the way, one array at the end."""
    return np.array(rhs_list(t, _floats(y), _floats(p)))


def _fill_floats(t, y, p, m, f, v, o):
    """``_fill`` on lists of Python floats; where one overflows (``**``, ``exp``), again on
    NumPy's scalars, which give ``inf`` as the arrays of the other backends do."""
    try:
        _fill(t, y, p, m, f, v, o)
    except OverflowError:
        _fill(t, list(np.asarray(y, dtype=float)), list(np.asarray(p, dtype=float)), m, f, v, o)


def _fill(t, y, p, M, F, V, O):
'''


def _solver_source(jit: bool) -> str:
    """``_k_pivot``, ``_k_solve`` and, for numba, ``_solve``: ``M⁻¹F`` without numba's LAPACK binding.

    numba compiles ``np.linalg.solve`` in about 4 s for every generated module;
    Gaussian elimination with partial pivoting (what LAPACK's ``gesv`` does)
    compiles in a fraction of that and is as fast at these sizes.
    """
    deco = "@_jit\n" if jit else ""
    source = "\n\n".join(deco + inspect.getsource(fn) for fn in (_k_pivot, _k_solve))
    if jit:
        source += '''

@_jit
def _solve(M, F):
    """M⁻¹F (M and F are overwritten); LinAlgError for a singular M, as numpy.linalg.solve."""
    if _k_solve(M, F) != 0:
        raise np.linalg.LinAlgError("Matrix is singular.")
    return F
'''
    return source


#: the largest ``DIM`` whose ``M⁻¹F`` the numpy backend writes out (:func:`_unrolled_solve`)
UNROLL_SOLVE = 8


def _unrolled_solve(n: int) -> str:
    """``_msolve(M, b)``: the list solver ``_lsolve`` written out for an ``n × n`` ``M`` on local
    variables (the same pivots and the same arithmetic, in a fifth of the time for n = 3)."""
    a = [[f"a{i}_{j}" for j in range(n)] for i in range(n)]
    b = [f"b{i}" for i in range(n)]
    comma = "," if n == 1 else ""
    lines = [
        "def _msolve(M, b):",
        '    """``M⁻¹b`` for this module\'s DIM × DIM ``M`` (lists, left as they are): ``_lsolve`` written out."""',
        *(f"    {', '.join(a[i])}{comma} = M[{i}]" for i in range(n)),
        f"    {', '.join(b)}{comma} = b",
    ]
    for c in range(n):
        lines.append(f"    big, piv = abs({a[c][c]}), {c}")
        for r in range(c + 1, n):
            lines += [f"    if abs({a[r][c]}) > big:", f"        big, piv = abs({a[r][c]}), {r}"]
        lines += ["    if big == 0.0:", '        raise np.linalg.LinAlgError("Matrix is singular.")']
        for r in range(c + 1, n):
            pivot_row, other = [*a[c][c:], b[c]], [*a[r][c:], b[r]]
            lines.append(f"    {'if' if r == c + 1 else 'elif'} piv == {r}:")
            lines.append(f"        {', '.join(pivot_row + other)} = {', '.join(other + pivot_row)}")
        for r in range(c + 1, n):
            lines += [f"    factor = {a[r][c]} / {a[c][c]}", "    if factor:"]
            lines += [f"        {a[r][j]} -= factor * {a[c][j]}" for j in range(c + 1, n)]
            lines.append(f"        {b[r]} -= factor * {b[c]}")
    for c in range(n - 1, -1, -1):
        terms = "".join(f" - {a[c][j]} * {b[j]}" for j in range(c + 1, n))
        lines.append(f"    {b[c]} = ({b[c]}{terms}) / {a[c][c]}")
    lines.append(f"    return [{', '.join(b)}]")
    return "\n".join(lines) + "\n"


def _rhs_source(jit: bool, dim: int) -> str:
    """``rhs``: numba's on arrays; the numpy backend's is ``_rhs`` (on lists, see :data:`_LIST_FILL`),
    with its helpers written out for ``dim``: ``_lists`` (fresh zeroed lists) and ``_msolve``."""
    if not jit:
        small = dim <= UNROLL_SOLVE  # M's rows written out as literals: half the time of [0.0] * DIM
        row = f"[{', '.join(['0.0'] * dim)}]" if small else "[0.0] * DIM"
        zeros = f"[{', '.join([row] * dim)}]" if small else "[[0.0] * DIM for _ in range(DIM)]"
        solver = _unrolled_solve(dim) if 1 <= dim <= UNROLL_SOLVE else "_msolve = _lsolve\n"
        return (
            "def _lists():\n"
            '    """Zeroed M, F, V, O as lists."""\n'
            f"    return {zeros}, {row}, [0.0] * N, [0.0] * N_OBSERVED\n\n\n"
            f"{solver}\n\n"
            "rhs = _rhs  # dy/dt = [velocities of q, solve(M, F)[:K]]\n"
        )
    return '''@_jit
def rhs(t, y, p):
    """dy/dt = [velocities of q, solve(M, F)[:K]]."""
    M, F, V, O = evaluate(t, y, p)
    x = _solve(M, F)
    dy = np.empty(N + K)
    for i in range(N):  # loops, not slices: numba compiles them much faster
        dy[i] = V[i]
    for i in range(K):
        dy[N + i] = x[i]
    return dy
'''


def _module(s: System, layout: Layout, fill: _Fill, dim: int, k: int, backend: str) -> str:
    """The generated module: ``fill`` and the functions built on it."""
    jit = backend == "numba"
    solve = "_solve" if jit else "np.linalg.solve"
    n_reactions = len(layout.reactions)
    n_observed = 1 + s.g + n_reactions + s.n
    deco = "@_jit\n" if jit else ""
    header = (
        '"""Generated by chaplygin {version} (code format {fmt}) from the {model}/{form} '
        "equations of {name}.\n\n"
        "Every function takes (t, y, p):\n"
        "    y = [{state}]\n"
        "    p = [{params}]\n"
        "observe() returns [energy, constraint residuals ({g}), computed multipliers "
        "({reactions}), velocities ({n})].\n"
        '"""\n'
    ).format(
        version=_version(),
        fmt=CODE_FORMAT,
        model=layout.model,
        form=layout.form,
        name=_docstring_safe(s.name),
        state=", ".join(layout.state),
        params=", ".join(layout.parameters),
        g=s.g,
        reactions=", ".join(layout.reactions) or "none",
        n=s.n,
    )
    jit_line = "from numba import njit\n_jit = njit(cache=True, fastmath=False)\n" if jit else ""
    return f'''{header}
import math

import numpy as np
{jit_line}
DIM = {dim}
N = {s.n}
K = {k}
N_OBSERVED = {n_observed}


{_fill_source(fill, backend)}

{_solver_source(jit)}

{deco}def evaluate(t, y, p):
    """Fresh arrays M, F, V, O filled at (t, y, p)."""
    M = np.zeros((DIM, DIM))
    F = np.zeros(DIM)
    V = np.zeros(N)
    O = np.zeros(N_OBSERVED)
    fill(t, y, p, M, F, V, O)
    return M, F, V, O


{_rhs_source(jit, dim)}


{deco}def observe(t, y, p):
    """[energy, residuals, computed multipliers, velocities]."""
    M, F, V, O = evaluate(t, y, p)
    if N_OBSERVED - 1 - {s.g} - N > 0:
        x = {solve}(M, F)
        for i in range({n_reactions}):
            O[1 + {s.g} + i] = x[DIM - {n_reactions} + i]
    for i in range(N):
        O[N_OBSERVED - N + i] = V[i]
    return O
'''


class BackendUnavailable(ChaplyginError):
    """The backend asked for cannot run here (no C compiler, or a function C lacks)."""


def compile_equations(eqs: Equations, backend: str = "numpy") -> CompiledModel:
    """Generate and load the numerical functions of ``eqs`` for ``backend``.

    Parameters
    ----------
    eqs : Equations
        Any model's equations (reduced or with multipliers).
    backend : {"numpy", "numba", "jax", "c"}
        ``"numpy"``: plain Python/NumPy, no compile step.  ``"numba"``: the
        same code compiled with ``numba.njit`` (microseconds per call; the
        first call compiles, later runs load from numba's cache).  ``"c"``:
        ``fill`` as C built by the system's C compiler, with a DOP853 loop in C
        (:mod:`chaplygin.numeric._ckernel`; raises :class:`ChaplyginError` without a
        compiler).  ``"jax"``:
        the same expressions as JAX functions (optional extra
        ``chaplygin[jax]``; see :mod:`chaplygin.numeric.jaxbackend`).
    """
    _check_backend(backend)
    _no_impulse(eqs)
    cache = eqs.__dict__.setdefault("_compiled", {})  # one compilation per equations and backend
    if backend not in cache:
        cache[backend] = targets.get(backend).compile(eqs)
    return cache[backend]


def kink_arguments(system: System) -> list[sp.Expr]:
    """The arguments of the ``abs`` and ``sign`` in the system's T, U, forces and constraints
    (internal symbols, in a fixed order): where one is 0 the equations have a kink or a jump."""
    if "_kink_arguments" not in system.__dict__:
        exprs = [system._T, system._U, *system._Qnp, *system._A, *system._A0]
        found = {a.args[0] for e in exprs for a in e.atoms(sp.Abs, sp.sign)}
        system.__dict__["_kink_arguments"] = sorted(found, key=sp.default_sort_key)
    return system.__dict__["_kink_arguments"]


def _no_impulse(eqs: Equations) -> None:
    """Refuse equations holding ``DiracDelta`` (an impulse: :func:`~chaplygin.numeric._printing.impulse_message`),
    naming its arguments as the system's file would."""
    from chaplygin.core._symbols import describe
    from chaplygin.numeric._printing import impulse_message

    if not kink_arguments(eqs.system):
        return  # (nothing to differentiate into DiracDelta; nor is SymPy's F computed, if it is not yet)
    found = {d.args[0] for e in [*eqs._M, *eqs._F] if isinstance(e, sp.Basic) for d in e.atoms(sp.DiracDelta)}
    if found:
        raise ModelError(impulse_message(sorted(describe(eqs.system.to_user(u)) for u in found)))


def _check_backend(backend: str) -> None:
    targets.require(backend, "compile", auto=False)  # (the table as it is now: BACKENDS is it at import)


#: the numba backend builds ``fill`` with a C compiler from this many generated lines on
#: (numba needs ~20 ms a line, a C compiler ~1 ms; see :mod:`chaplygin.numeric._cfill`)
C_FILL_FROM_LINES = 200

#: ``reduction="auto"`` reduces numerically from this many coordinates on: from nothing to a
#: right-hand side it is the faster route from 5 coordinates on, whatever the constraints (a
#: chain of 7–8 coordinates with 3 knife edges: 0.41–0.49 s against 1.24–1.48 s symbolic and
#: Kane's 0.60–0.80 s; ``benchmarks/scaling.py --crossover``); the 5-coordinate systems keep
#: their compact symbolic equations, whose right-hand side long runs call millions of times
NUMERIC_REDUCTION_FROM = 6
#: ... or from this many constraints on (the Whipple bicycle: 8 coordinates, 5 constraints,
#: whose symbolic Voronets equations did not finish in 10 minutes and 19 GB)
NUMERIC_REDUCTION_FROM_CONSTRAINTS = 4
REDUCTIONS = ("auto", "symbolic", "numeric")


def compile_model(
    system: System,
    model: str | Model,
    form: str = "classic",
    backend: str = "numpy",
    *,
    constants: Any = None,
    reduction: str = "auto",
) -> CompiledModel:
    """Compile one model of ``system``, deriving what it needs.

    Parameters
    ----------
    model : str or Model
        The model's name, or its entry of the registry (:func:`chaplygin.models.registry.get`),
        which an entry point resolved once.
    reduction : {"auto", "symbolic", "numeric"}
        How Chaplygin's and Voronets' equations are computed.  ``"symbolic"``
        compiles the derived equations (15)/(40); ``"numeric"`` compiles the
        Chetaev model (6) and eliminates the dependent velocities, accelerations
        and multipliers numerically at each call (:func:`_numeric_reduction_source`):
        the same accelerations at every admissible state, without the symbolic
        elimination whose size grows fast with the number of constraints.
        ``"auto"`` chooses ``"numeric"`` from :data:`NUMERIC_REDUCTION_FROM`
        coordinates or :data:`NUMERIC_REDUCTION_FROM_CONSTRAINTS` constraints on (never for
        the ``jax`` backend).  Other models ignore it.

    Notes
    -----
    What is compiled is also stored on disk (:mod:`chaplygin.numeric._modelcache`), so another
    process that compiles the same model of an equal system loads it and derives nothing.
    """
    key, numeric, entry = _model_key(system, model, form, backend, constants, reduction)
    found = _modelcache.load_model(key)
    if found is None:
        found = _compile_model(system, entry, form, backend, constants, numeric)
        _modelcache.store_model(key, found)
    return found


def is_compiled(
    system: System,
    model: str | Model,
    form: str = "classic",
    backend: str = "numpy",
    *,
    constants: Any = None,
    reduction: str = "auto",
) -> bool:
    """Whether :func:`compile_model` would load this model from the disk cache (derive and
    compile nothing); False where the cache is off or cannot hold it."""
    key, _, _ = _model_key(system, model, form, backend, constants, reduction)
    return _modelcache.load_model(key) is not None


def reduces_numerically(
    system: System, model: str | Model, form: str = "classic", backend: str = "auto", reduction: str = "auto"
) -> bool:
    """Whether :func:`compile_model` compiles ``model`` by the numeric reduction, from the
    Chetaev matrices, so that the model's symbolic equations are never needed to run it."""
    entry = registry.get(model, form)
    return (
        entry.reduced
        and entry.is_true_motion
        and (backend not in targets.TARGETS or targets.get(backend).numeric_reduction)  # ("auto" too)
        and (
            reduction == "numeric"
            or (
                reduction == "auto"
                and (system.n >= NUMERIC_REDUCTION_FROM or system.g >= NUMERIC_REDUCTION_FROM_CONSTRAINTS)
            )
        )
    )


def _model_key(
    system: System, model: str | Model, form: str, backend: str, constants: Any, reduction: str
) -> tuple[str | None, bool, Model]:
    """The disk-cache key of a compiled model (None: not cached), whether it is the numeric
    reduction, and the model's entry; an unknown model, form, backend or reduction is refused here."""
    if reduction not in REDUCTIONS:
        raise ChaplyginError(f"reduction {reduction!r} is not one of {', '.join(map(repr, REDUCTIONS))}.")
    entry = registry.get(model, form)  # refuses an unknown model or form before anything is looked up
    _check_backend(backend)
    numeric = reduces_numerically(system, entry, form, backend, reduction)
    variant = f"numeric reduction {numeric}, C fill from {C_FILL_FROM_LINES} lines"
    key = _modelcache.model_key(system, entry.name, form, backend, constants, variant, CODE_FORMAT)
    return key, numeric, entry


def _compile_model(
    system: System, entry: Model, form: str, backend: str, constants: Any, numeric: bool
) -> CompiledModel:
    """:func:`compile_model` without the disk cache: derive (once per system) and generate."""
    model = entry.name
    target = targets.get(backend)
    target.prepare()
    if not numeric:
        kwargs = {} if constants is None else {"constants": constants}
        return compile_equations(system.equations(model, form, **kwargs), backend)
    if entry.obstruction(system):
        system.equations(model, form)  # raises the error that explains why
    cache = system.__dict__.setdefault("_compiled_numeric", {})
    key = (backend, model)
    if key not in cache:
        cache[key] = target.build(_numeric_reduction_parts(system, model))
    return cache[key]


#: the thread building the C loop library while the model is derived (:func:`_build_loop_beside`)
_BESIDE: list[threading.Thread] = []


def _build_loop_beside() -> None:
    """Start building the C loop library (once per kernel cache where the installation did not
    build it, ~0.2 s of the C compiler) in
    a thread, so that the compiler runs while this process derives and generates the model;
    the C target's build (:meth:`chaplygin.numeric.targets.c.C.build`) waits for it before it loads the loop.  Nothing is started where the
    loop is loaded, being built or in the cache already (a library of another source there is
    built by the load as before); a failure is left to the load, which raises it again."""
    from chaplygin.numeric import _ckernel

    if _ckernel._LOOP or any(t.is_alive() for t in _BESIDE):
        return
    try:
        if next(_ckernel.kernel_dir().glob("dop853_*.so"), None) is not None:
            return
        if _ckernel.packaged_loop() is not None:  # built when the package was installed
            return
    except (OSError, _ckernel.Unavailable):
        return

    def build() -> None:
        try:
            _ckernel.library(_ckernel.loop_source(), "dop853")
        except Exception:  # the main thread's load raises it again, with its context
            pass

    _BESIDE[:] = [threading.Thread(target=build, name="chaplygin-loop-build")]
    _BESIDE[0].start()


def parameter_vector(layout: Layout, values: dict[str, float]) -> np.ndarray:
    """``p`` in layout order from a name → value map (every name must be present)."""
    return np.array([float(values[name]) for name in layout.parameters], dtype=float)
