"""Private numeric sampling: random admissible states of a system.

Used for checks that are cheaper numerically than symbolically (is a matrix
singular *everywhere*?) and by the equivalence checker.  Nothing in the
symbolic model depends on this module.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import sympy as sp
from sympy.functions.elementary.trigonometric import TrigonometricFunction

from chaplygin.core._symbols import TIME
from chaplygin.errors import SystemDefinitionError

if TYPE_CHECKING:
    from chaplygin.core.system import System

#: where :func:`vanishes` samples every symbol (an analytic expression zero on an open box is zero)
COORDINATE_RANGE = (0.3, 1.3)
#: where it samples an expression that is not analytic (``Abs``, ``sign``, ...): each sign and
#: magnitude, around the circle and beyond; symbols assumed positive stay positive
WIDE_RANGE = (-5.0, 5.0)
#: functions that can vanish on an open box and not elsewhere
NOT_ANALYTIC = (
    sp.Abs,
    sp.sign,
    sp.Piecewise,
    sp.Heaviside,
    sp.floor,
    sp.ceiling,
    sp.Min,
    sp.Max,
    sp.re,
    sp.im,
)
#: where :class:`StateSampler` draws an angle (a coordinate or t inside sin, cos, tan, ...)
ANGLE_RANGE = (-np.pi, np.pi)
#: magnitudes of the other coordinates and of t, log-uniform, each sign equally likely
LENGTH_MAGNITUDES = (0.1, 10.0)
VELOCITY_RANGE = (-1.0, 1.0)
#: for constraints nonlinear in the velocities real nowhere in VELOCITY_RANGE: the factors
#: (log-uniform) of the later draws
WIDE_VELOCITIES = (1.0, 1e3)
PARAMETER_RANGE = (0.5, 1.5)
#: a state whose B or B_0 has an entry beyond this is too near a pole of the constraints
POLE = 1e6


def compile_function(exprs: Any, args: Sequence[sp.Symbol]) -> Callable[..., Any]:
    """``lambdify`` with common-subexpression elimination, NumPy semantics."""
    return sp.lambdify(list(args), exprs, modules="numpy", cse=True)


def parameter_values(
    system: System, rng: np.random.Generator, given: Mapping[Any, float] | None = None
) -> dict[sp.Symbol, float]:
    """Random positive values for every parameter, overridden by ``given``."""
    values = {p: float(rng.uniform(*PARAMETER_RANGE)) for p in system.parameters}
    for key, value in (given or {}).items():
        values[system.parameter(key)] = float(value)
    return values


def angles(exprs: Iterable[Any], symbols: Iterable[sp.Symbol]) -> set[sp.Symbol]:
    """Those of ``symbols`` that appear inside a trigonometric function in ``exprs``."""
    wanted, found = set(symbols), set()
    seen: set[sp.Basic] = set()
    stack = [e for e in exprs if isinstance(e, sp.Basic)]
    while stack:
        node = stack.pop()
        if node in seen or not node.args:
            continue
        seen.add(node)
        if isinstance(node, TrigonometricFunction):
            found |= node.free_symbols & wanted
        else:
            stack.extend(node.args)
    return found


class StateSampler:
    """Draws random states ``(t, q, q̇)`` that satisfy the velocity constraints.

    Every coordinate is sampled over its whole range: an angle (a coordinate
    that appears inside a trigonometric function of the system or of
    ``expressions``) around the whole circle, :data:`ANGLE_RANGE`; any other
    coordinate, and t, with either sign and magnitudes log-uniform in
    :data:`LENGTH_MAGNITUDES`.  States where the constraints are not finite or
    near a pole (an entry of B or B_0 beyond :data:`POLE`) are drawn again.
    :meth:`where` says where the states were drawn.
    """

    def __init__(
        self, system: System, parameters: Mapping[sp.Symbol, float], expressions: Iterable[Any] = ()
    ) -> None:
        self.system = system
        self.parameters = dict(parameters)
        v = system._vars
        # (constraints nonlinear in the velocities: B and B_0 depend on the independent velocities)
        b_args = [TIME, *v.x, *(v.xd[i] for i in system._ind if system.is_nonlinear), *self.parameters]
        self._b = compile_function(system._B, b_args)
        self._b0 = compile_function(system._B0, b_args)
        self.angles = angles([*system._B, *system._B0, *system._A, *system._A0, *expressions], [TIME, *v.x])

    def _coordinate(self, symbol: sp.Symbol, rng: np.random.Generator) -> float:
        if symbol in self.angles:
            return float(rng.uniform(*ANGLE_RANGE))
        low, high = np.log10(LENGTH_MAGNITUDES)
        return float(rng.choice((-1.0, 1.0)) * 10 ** rng.uniform(low, high))

    def where(self) -> dict[str, str]:
        """Where :meth:`draw` samples: a range for each coordinate, t, the velocities, the parameters."""
        s = self.system
        length = f"±[{LENGTH_MAGNITUDES[0]:g}, {LENGTH_MAGNITUDES[1]:g}]"
        out = {}
        for q, x in [("t", TIME), *((c.func.__name__, x) for c, x in zip(s.coordinates, s._vars.x))]:
            out[q] = "(-π, π)" if x in self.angles else length
        out["velocities"] = f"({VELOCITY_RANGE[0]:g}, {VELOCITY_RANGE[1]:g})"
        out["parameters"] = f"({PARAMETER_RANGE[0]:g}, {PARAMETER_RANGE[1]:g}) unless given"
        return out

    def draw(self, rng: np.random.Generator) -> dict[sp.Symbol, float]:
        """One random admissible state as a map from internal symbols to numbers."""
        s, v = self.system, self.system._vars
        for attempt in range(100):
            t = self._coordinate(TIME, rng)
            q = np.array([self._coordinate(x, rng) for x in v.x])
            qd = np.zeros(s.n)
            qd[list(s._ind)] = rng.uniform(*VELOCITY_RANGE, size=len(s._ind))
            if s.is_nonlinear and attempt >= 50:  # constraints real only for larger velocities
                low, high = np.log10(WIDE_VELOCITIES)
                qd[list(s._ind)] *= 10 ** rng.uniform(low, high, size=len(s._ind))
            if not s.g:
                break
            velocities: Any = qd[list(s._ind)] if s.is_nonlinear else []
            args = (t, *q, *velocities, *self.parameters.values())
            with np.errstate(all="ignore"):  # (a root of a negative number, off the constraints' domain: NaN)
                b = np.asarray(self._b(*args), dtype=complex).reshape(s.g, len(s._ind))
                b0 = np.asarray(self._b0(*args), dtype=complex).reshape(s.g)
            real = np.all(b.imag == 0) and np.all(b0.imag == 0)
            b, b0 = b.real, b0.real
            qd[list(s._dep)] = b @ qd[list(s._ind)] + b0
            if real and np.all(np.abs(b) <= POLE) and np.all(np.abs(b0) <= POLE):
                break
        else:
            if s.is_nonlinear and not np.all(np.isfinite(qd)):
                raise SystemDefinitionError(
                    f"constraints: {s.name} has no admissible state at 100 random ones (independent "
                    f"velocities in {VELOCITY_RANGE}, then up to {WIDE_VELOCITIES[1]:g} times that): the "
                    "solved constraints are not real, or not finite, there."
                )
        state: dict[sp.Symbol, float] = {TIME: t}
        state.update(zip(v.x, q.tolist()))
        state.update(zip(v.xd, qd.tolist()))
        state.update(self.parameters)
        return state


def vanishes(expr: sp.Expr, *, samples: int = 8, seed: int = 28) -> bool:
    """Decide whether ``expr`` is identically zero.

    Numbers first: ``expr`` is evaluated at random points of every free symbol
    in interval arithmetic (:func:`_interval_signs`), so a value whose interval
    excludes zero proves the expression non-zero — certainly, whatever the
    round-off — in milliseconds, however large the expression.  When every
    sample is zero to within a tiny fraction of the magnitudes met on the way,
    the expression is taken as zero: a non-zero analytic expression vanishes at
    random points with probability nil, and these samples are far finer than
    the floating-point test below.  When the numbers decide nothing (a
    function without an interval version, a complex or undefined value), the
    exact path decides: cheap symbolic normalisation, then floating-point
    samples (a single clearly non-zero value settles it), and only when no
    sample is finite a full ``simplify``.  An expression with a function that
    is not analytic (:data:`NOT_ANALYTIC`: ``|cos φ| − cos φ`` is zero for
    |φ| < π/2 only) is sampled four times as often over :data:`WIDE_RANGE`.
    """
    if expr == 0:
        return True
    if expr.has(*NOT_ANALYTIC):
        samples *= 4
    verdict = _interval_signs(expr, samples, seed)
    if verdict is not None:
        return verdict
    # (before the normal form, which may not finish: roots; not with Floats, whose rounding shows)
    if not expr.atoms(sp.Float) and _clearly_nonzero(expr, seed):
        return False
    expr = sp.cancel(sp.expand(expr))
    if expr == 0:
        return True
    symbols = sorted(expr.free_symbols, key=str)
    rng = np.random.default_rng(seed)
    f = compile_function(expr, symbols)
    finite = 0
    for _ in range(samples):
        try:
            with np.errstate(all="ignore"):
                value = complex(f(*_point(expr, symbols, rng)))
        except NameError:  # a function NumPy does not have (LambertW): no floating-point samples
            break
        if np.isfinite(value):
            if abs(value) > 1e-9:
                return False
            finite += 1
    return finite > 0 or sp.simplify(expr) == 0


def _clearly_nonzero(expr: sp.Expr, seed: int, points: int = 3) -> bool:
    """Whether ``expr`` is far from zero at one of a few random points, evaluated with 50 digits
    (a value beyond 1e-20 is no round-off of a zero): complex values (a root of a negative) count."""
    symbols = sorted(expr.free_symbols, key=str)
    rng = np.random.default_rng(seed)
    for _ in range(points):
        values = {x: sp.Float(float(val), 50) for x, val in zip(symbols, _point(expr, symbols, rng))}
        try:  # (functions of t, as users write them, have no value at a number: nothing decided)
            value = expr.xreplace(values).evalf(50)
        except (ValueError, TypeError):
            return False
        if value.is_number and value.is_finite is not False and not value.has(sp.nan, sp.zoo):
            if abs(complex(value)) > 1e-20:
                return True
    return False


#: bits of the interval arithmetic in :func:`_interval_signs` (quadruple precision)
_PRECISION = 113
#: values proved non-zero but this small are left to the floating-point test (its zero)
_SMALL = 1e-9
#: a sample counts as zero when its interval lies within this fraction of the largest magnitude met
_ZERO = 1e-12


class _Undecided(Exception):
    """An interval evaluation that says nothing (a complex value, an unknown function)."""


def _interval_signs(expr: sp.Expr, samples: int, seed: int) -> bool | None:
    """``False`` when a sample proves ``expr`` non-zero, ``True`` when every sample is zero, else None.

    Each sample evaluates ``expr`` at a random point (the floats drawn are exact
    binary numbers) in outward-rounded interval arithmetic at
    :data:`_PRECISION` bits: an interval that excludes zero is a proof.  Only
    values beyond :data:`_SMALL` count, the threshold of the floating-point
    test, which decides the others as it always has (a Float left over from
    cancelled Floats, ``5.6e-17·x``, is zero there).  A
    sample is zero when its interval contains zero and is narrower than
    :data:`_ZERO` times the largest magnitude of any subexpression — the
    round-off of an exact zero, and for a non-zero expression a value at a
    random point some 10⁻¹² below its own terms, which the samples do not all
    hit.  A Float is an interval of two units in its last place: a difference
    made only of rounding is never taken for a proof.
    """
    import mpmath

    ctx = type(mpmath.iv)()  # a private context: its precision is no one else's
    ctx.prec = _PRECISION
    nodes = _postorder(expr)
    symbols = sorted(expr.free_symbols, key=str)
    rng = np.random.default_rng(seed)
    zeros = 0
    for _ in range(samples):
        point = _point(expr, symbols, rng)
        values: dict[sp.Basic, Any] = {x: ctx.mpf(float(p)) for x, p in zip(symbols, point)}
        try:
            scale = 1.0
            for node in nodes:
                if node not in values:
                    value = _interval(ctx, node, values)
                    values[node] = value
                    scale = max(scale, abs(float(value.a)), abs(float(value.b)))
            value = values[expr]
        except (_Undecided, ZeroDivisionError, ValueError, ArithmeticError):
            return None
        low, high = float(value.a), float(value.b)
        if low > _SMALL or high < -_SMALL:
            return False
        if low > 0 or high < 0:  # non-zero, but no larger than the floating-point test's zeros
            return None
        if not (np.isfinite(scale) and max(-low, high) <= _ZERO * scale):
            return None
        zeros += 1
    return zeros > 0


def _point(expr: sp.Expr, symbols: Sequence[sp.Symbol], rng: np.random.Generator) -> np.ndarray:
    """A random point for :func:`vanishes`: in :data:`COORDINATE_RANGE` where ``expr`` is
    analytic (zero on an open box is zero everywhere), else in :data:`WIDE_RANGE` (Abs, sign, ...
    can vanish on a box and not elsewhere), keeping symbols assumed positive positive."""
    if not expr.has(*NOT_ANALYTIC):
        return rng.uniform(*COORDINATE_RANGE, size=len(symbols))
    point = rng.uniform(*WIDE_RANGE, size=len(symbols))
    positive = np.array([bool(x.is_nonnegative) for x in symbols], dtype=bool)
    return np.where(positive, np.abs(point), point)


def _postorder(expr: sp.Basic) -> list[sp.Basic]:
    """The distinct subexpressions of ``expr``, each after its arguments (shared ones once)."""
    order: list[sp.Basic] = []
    seen: set[sp.Basic] = set()
    stack: list[tuple[sp.Basic, bool]] = [(expr, False)]
    while stack:
        node, ready = stack.pop()
        if ready:
            order.append(node)
        elif node not in seen:
            seen.add(node)
            stack.append((node, True))
            stack.extend((a, False) for a in node.args)
    return order


def _interval(ctx: Any, node: sp.Basic, values: dict[sp.Basic, Any]) -> Any:
    """The interval of ``node`` from the intervals of its arguments (already in ``values``)."""
    import mpmath

    if node.is_Rational:
        return ctx.mpf(int(node.p)) / int(node.q)
    if node.is_Float:  # a rounded number: give it two units in its last place either way
        value = ctx.mpf(mpmath.mpf(node._mpf_))
        return value + abs(value) * ctx.mpf([-1, 1]) * ctx.mpf(2) ** (2 - node._prec)
    if node is sp.pi:
        return ctx.pi
    if node is sp.E:
        return ctx.e
    args = [values[a] for a in node.args] if node.args else []
    if node.is_Add:
        out = args[0]
        for a in args[1:]:
            out = out + a
        return out
    if node.is_Mul:
        out = args[0]
        for a in args[1:]:
            out = out * a
        return out
    if node.is_Pow and node.exp.is_Integer:
        return args[0] ** int(node.exp)
    if node.is_Pow and node.exp.is_Rational and args[0].a > 0:
        if node.exp == sp.S.Half:
            return ctx.sqrt(args[0])
        return ctx.exp(ctx.log(args[0]) * args[1])
    functions = {sp.sin: ctx.sin, sp.cos: ctx.cos, sp.exp: ctx.exp}
    if type(node) in functions:
        return functions[type(node)](args[0])
    if isinstance(node, sp.Abs):
        return abs(args[0])
    raise _Undecided(node)
