"""Convex shapes for :func:`~chaplygin.bodies.rolling_body`, each by its support function.

A convex body ``K`` is described by its **support function** ``h(u) = max_{p∈K} p·u``
(homogeneous of degree one in ``u``). The point of ``K`` furthest in the direction ``u`` is
the gradient ``∇h(u)`` (Schneider, *Convex Bodies: The Brunn–Minkowski Theory*, 2nd ed., 2014,
§1.7). A body resting on the plane ``z = 0`` touches it where its outward normal points
down, so with ``u`` the downward vertical written in body axes the contact point is ``∇h(u)``
and the height of the reference point above the plane is ``h(u)``. Every shape here gives
``h`` and ``∇h`` in closed form; :class:`SupportFunction` takes any ``h``.

All lengths are SymPy expressions: numbers, symbols, or names (a string ``"r"`` is the
positive symbol ``r``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, TypeAlias

import numpy as np
import sympy as sp

from chaplygin.core._fast import evaluator
from chaplygin.errors import SystemDefinitionError

__all__ = [
    "Disk",
    "Ellipsoid",
    "Paraboloid",
    "Revolution",
    "Shape",
    "Sphere",
    "SupportFunction",
    "Torus",
]

#: a 3-vector: a SymPy column Matrix (sympy has no type information, so Any to mypy)
Vector: TypeAlias = Any


def positive(value: Any, key: str, what: str = "a length") -> sp.Expr:
    """A positive quantity (``what``): a number, a SymPy expression or a name; anything else is refused."""
    if isinstance(value, str):
        if not value.isidentifier():
            raise SystemDefinitionError(
                f"{key}: {value!r} is not a symbol name; give a number, a SymPy symbol or a name like 'r'."
            )
        return sp.Symbol(value, positive=True)
    if isinstance(value, bool) or not isinstance(value, (int, float, sp.Expr)):
        raise SystemDefinitionError(
            f"{key}: expected a positive number or a SymPy expression, got {value!r}."
        )
    expr = sp.nsimplify(value) if isinstance(value, float) else sp.sympify(value, strict=True)
    if expr.free_symbols:
        if expr.is_positive is False:
            raise SystemDefinitionError(f"{key} = {expr} is not positive; {what} must be > 0.")
        return expr
    if not (expr.is_real and expr.is_finite) or expr <= 0:
        raise SystemDefinitionError(f"{key} = {expr}: {what} must be a finite number > 0.")
    return expr


def norm(v: Sequence[sp.Expr]) -> sp.Expr:
    """``|v|`` without a square root where ``v·v`` simplifies to 1 or to a square ``f²``.

    For a square the positive root is taken to be ``f`` itself: right near the resting
    attitude of the angle conventions of :mod:`chaplygin.bodies.builder` (for example
    ``cos θ`` for a disk on its rim, ``|θ| < π/2``); the expressions are singular where
    ``f = 0``.
    """
    s = sp.trigsimp(sp.expand(sum(c**2 for c in v)))
    if s == 1:
        return sp.S.One
    base, exp = s.as_base_exp()
    if exp == 2:
        return base
    return sp.sqrt(s)


class Shape:
    """A convex shape in its own axes: support function, contact point and a few checks."""

    #: the angle convention that is regular at the usual resting attitude
    default_angles: str = "cardan"
    #: what the shape's origin is (the body's reference point)
    reference: str = "centre"

    def support(self, u: Vector) -> sp.Expr:
        """``h(u)`` for a unit vector ``u`` in shape axes."""
        raise NotImplementedError

    def contact(self, u: Vector) -> Vector:
        """``∇h(u)``: the point of the surface whose outward normal is the unit vector ``u``."""
        raise NotImplementedError

    def contains(self, point: Sequence[float]) -> bool | None:
        """Whether a numeric point lies in the body (``None`` where it cannot be decided)."""
        h = self._numeric_support()
        if h is None:
            return None
        p = np.asarray(point, dtype=float)
        return bool(all(h(u) >= u @ p - 1e-12 for u in _directions(self._directions_half())))

    def _directions_half(self) -> bool:
        return False

    def _numeric_support(self) -> Callable[[np.ndarray], float] | None:
        a, b, c = sp.symbols("_u1:4", real=True)
        expr = self.support(sp.Matrix([a, b, c]))
        if expr.free_symbols - {a, b, c}:
            return None
        fast = evaluator([a, b, c], [expr], real=True)  # SymEngine's: cheap to build, imports nothing
        if fast is not None:
            return lambda u: float(fast(u)[0])
        f = sp.lambdify((a, b, c), expr, "numpy")
        return lambda u: float(f(*u))

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v}" for k, v in vars(self).items() if not k.startswith("_"))
        return f"{type(self).__name__}({args})"


def _directions(lower_only: bool = False, count: int = 400) -> np.ndarray:
    """Nearly uniform unit vectors (a Fibonacci lattice), optionally only with u_z < 0."""
    k = np.arange(count) + 0.5
    z = 1 - 2 * k / count
    if lower_only:
        z = -np.abs(z)
    phi = np.pi * (1 + 5**0.5) * k
    r = np.sqrt(1 - z**2)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


class Sphere(Shape):
    """A sphere of radius ``radius`` about its centre: ``h(u) = r |u|``, contact ``r u``."""

    def __init__(self, radius: Any) -> None:
        self.radius = positive(radius, "radius")

    def support(self, u: Vector) -> sp.Expr:
        return self.radius * norm(u)

    def contact(self, u: Vector) -> Vector:
        return self.radius * u / norm(u)


class Disk(Shape):
    """A thin disk (or hoop) of radius ``radius`` in the xy-plane, symmetry axis z.

    ``h(u) = r |u_⊥|`` with ``u_⊥ = (u_x, u_y)``; contact ``r (u_x, u_y, 0)/|u_⊥|``, undefined
    where the disk lies flat (``u_⊥ = 0``).
    """

    default_angles = "edge"

    def __init__(self, radius: Any) -> None:
        self.radius = positive(radius, "radius")

    def support(self, u: Vector) -> sp.Expr:
        return self.radius * norm(u[:2])

    def contact(self, u: Vector) -> Vector:
        return self.radius * sp.Matrix([u[0], u[1], 0]) / norm(u[:2])

    def contains(self, point: Sequence[float]) -> bool | None:
        if not self.radius.is_number:
            return None
        x, y, z = (float(c) for c in point)
        return abs(z) < 1e-12 and x * x + y * y <= float(self.radius) ** 2 + 1e-12


class Torus(Shape):
    """A disk with a rounded rim: the convex hull of a torus, centre circle radius ``R`` in the
    xy-plane, tube radius ``r`` (the Minkowski sum of a disk of radius R and a ball of radius r).

    ``h(u) = R |u_⊥| + r |u|``; contact ``R u_⊥/|u_⊥| + r u``.
    """

    default_angles = "edge"

    def __init__(self, R: Any, r: Any) -> None:
        self.R = positive(R, "R")
        self.r = positive(r, "r")

    def support(self, u: Vector) -> sp.Expr:
        return self.R * norm(u[:2]) + self.r * norm(u)

    def contact(self, u: Vector) -> Vector:
        return self.R * sp.Matrix([u[0], u[1], 0]) / norm(u[:2]) + self.r * u / norm(u)


class Ellipsoid(Shape):
    """The ellipsoid ``x²/a² + y²/b² + z²/c² ≤ 1``: ``h(u) = √(a²u_x² + b²u_y² + c²u_z²)``,
    contact ``(a²u_x, b²u_y, c²u_z)/h``."""

    def __init__(self, a: Any, b: Any, c: Any) -> None:
        self.a, self.b, self.c = positive(a, "a"), positive(b, "b"), positive(c, "c")

    def support(self, u: Vector) -> sp.Expr:
        return sp.sqrt(self.a**2 * u[0] ** 2 + self.b**2 * u[1] ** 2 + self.c**2 * u[2] ** 2)

    def contact(self, u: Vector) -> Vector:
        return sp.Matrix([self.a**2 * u[0], self.b**2 * u[1], self.c**2 * u[2]]) / self.support(u)


class Paraboloid(Shape):
    """The cap ``z ≥ x²/2ρ₁ + y²/2ρ₂`` about its vertex (the origin; ρ₁, ρ₂ are the radii of
    curvature there). Defined for downward normals ``u_z < 0``:
    ``h(u) = −(ρ₁u_x² + ρ₂u_y²)/(2u_z)``, contact ``(−ρ₁u_x/u_z, −ρ₂u_y/u_z, (ρ₁u_x² + ρ₂u_y²)/(2u_z²))``.
    """

    reference = "vertex"

    def __init__(self, rho1: Any, rho2: Any) -> None:
        self.rho1, self.rho2 = positive(rho1, "rho1"), positive(rho2, "rho2")

    def support(self, u: Vector) -> sp.Expr:
        return -(self.rho1 * u[0] ** 2 + self.rho2 * u[1] ** 2) / (2 * u[2])

    def contact(self, u: Vector) -> Vector:
        return sp.Matrix(
            [
                -self.rho1 * u[0] / u[2],
                -self.rho2 * u[1] / u[2],
                (self.rho1 * u[0] ** 2 + self.rho2 * u[1] ** 2) / (2 * u[2] ** 2),
            ]
        )

    def contains(self, point: Sequence[float]) -> bool | None:
        if not (self.rho1.is_number and self.rho2.is_number):
            return None
        x, y, z = (float(c) for c in point)
        return z >= x * x / (2 * float(self.rho1)) + y * y / (2 * float(self.rho2)) - 1e-12


class Revolution(Shape):
    """A convex body of revolution about the z axis, by the support function of its meridian.

    ``profile`` is a function ``p(α)`` (a Python callable taking and returning SymPy
    expressions, or a ``sympy.Lambda``): the distance from the origin (on the axis) to the
    tangent plane whose outward normal makes the angle ``α`` with the downward axis ``−z``
    (``α = 0``: the bottom pole, ``α = π``: the top). This is how Chaplygin (1897) and Routh
    (1905) describe the body: ``p`` is the height of the origin above the plane when
    the axis is tilted by ``α``. The meridian point that touches is

        ρ = p sin α + p′ cos α,     z = −p cos α + p′ sin α ,

    and the meridian is convex where its radius of curvature ``p + p″`` is ≥ 0 (checked on
    ``[0, π]`` when ``p`` is numeric). Examples: a sphere ``p = r``; a disk of radius R,
    ``p = R sin α``; a rounded disk (:class:`Torus`), ``p = R sin α + r``; a spheroid with
    semi-axes a (equatorial) and c, ``p = √(a² sin² α + c² cos² α)``.
    """

    def __init__(self, profile: Callable[[sp.Expr], Any] | sp.Lambda) -> None:
        if not callable(profile):
            raise SystemDefinitionError(
                "profile: expected a function p(alpha) (a Python callable or sympy.Lambda) giving the "
                "distance from the origin to the tangent plane at normal angle alpha from the downward axis."
            )
        alpha = sp.Dummy("alpha", real=True)
        try:
            p = sp.sympify(profile(alpha), strict=True)
        except (TypeError, ValueError, sp.SympifyError) as exc:
            raise SystemDefinitionError(
                f"profile: calling it with a SymPy symbol failed ({exc}); it must accept and return SymPy expressions."
            ) from None
        if not isinstance(p, sp.Expr):
            raise SystemDefinitionError(f"profile: p(alpha) = {p!r} is not a SymPy expression.")
        self._alpha, self.profile = alpha, p
        self._dp = p.diff(alpha)
        self._check_convex()

    def _check_convex(self) -> None:
        curvature = self.profile + self._dp.diff(self._alpha)
        if (self.profile.free_symbols | curvature.free_symbols) - {self._alpha}:
            return  # symbolic parameters: not checkable here
        grid = np.linspace(0.0, np.pi, 721)
        radius = sp.lambdify(self._alpha, curvature, "numpy")(grid) * np.ones_like(grid)
        height = sp.lambdify(self._alpha, self.profile, "numpy")(grid) * np.ones_like(grid)
        if not np.all(np.isfinite(radius)):
            raise SystemDefinitionError("profile: p(alpha) or p''(alpha) is not finite on [0, pi].")
        k = int(np.argmin(radius))
        if radius[k] < -1e-9:
            raise SystemDefinitionError(
                f"profile: the meridian is not convex: its radius of curvature p + p'' = {radius[k]:.4g} < 0 "
                f"at alpha = {grid[k]:.4g}; a convex body needs p + p'' >= 0 on [0, pi]."
            )
        if (
            np.min(
                height
                + sp.lambdify(self._alpha, self.profile.subs(self._alpha, sp.pi - self._alpha), "numpy")(grid)
            )
            <= 0
        ):
            raise SystemDefinitionError(
                "profile: the body has no thickness: p(alpha) + p(pi - alpha) must be > 0 (the width along each tilted normal)."
            )

    def _at(self, expr: sp.Expr, s: sp.Expr, c: sp.Expr) -> sp.Expr:
        e = sp.expand_trig(expr).xreplace({sp.sin(self._alpha): s, sp.cos(self._alpha): c})
        if e.has(self._alpha):
            e = e.xreplace({self._alpha: sp.atan2(s, c)})
        return e

    def support(self, u: Vector) -> sp.Expr:
        n = norm(u)
        s, c = norm(u[:2]) / n, -u[2] / n
        return n * self._at(self.profile, s, c)

    def contact(self, u: Vector) -> Vector:
        n, r = norm(u), norm(u[:2])
        s, c = r / n, -u[2] / n
        p, dp = self._at(self.profile, s, c), self._at(self._dp, s, c)
        rho = p * s + dp * c
        return sp.Matrix([rho * u[0] / r, rho * u[1] / r, -p * c + dp * s])


class SupportFunction(Shape):
    """Any smooth convex body by its support function ``h(u)``, homogeneous of degree one.

    ``h`` is a callable ``h(u1, u2, u3)`` returning a SymPy expression (or a ``sympy.Lambda``
    of three variables). The contact point for the outward normal ``u`` is ``∇h(u)``; the
    other shapes are special cases (a sphere: ``h = r √(u1² + u2² + u3²)``). Where ``h`` is
    numeric, homogeneity and convexity (a positive semi-definite Hessian) are checked at
    sample directions.
    """

    def __init__(self, h: Callable[..., Any] | sp.Lambda, *, lower_only: bool = False) -> None:
        if not callable(h):
            raise SystemDefinitionError(
                "h: expected a function h(u1, u2, u3) returning a SymPy expression (the support function)."
            )
        self._u = sp.symbols("u1:4", real=True)
        try:
            expr = sp.sympify(h(*self._u), strict=True)
        except (TypeError, ValueError, sp.SympifyError) as exc:
            raise SystemDefinitionError(f"h: calling it with three SymPy symbols failed ({exc}).") from None
        if not isinstance(expr, sp.Expr):
            raise SystemDefinitionError(f"h: h(u1, u2, u3) = {expr!r} is not a SymPy expression.")
        self.h = expr
        self._grad = [expr.diff(v) for v in self._u]
        self._lower = lower_only
        self._check()

    def _directions_half(self) -> bool:
        return self._lower

    def _check(self) -> None:
        if self.h.free_symbols - set(self._u):
            return
        f = sp.lambdify(self._u, self.h, "numpy")
        hess = sp.lambdify(self._u, sp.hessian(self.h, self._u), "numpy")
        for u in _directions(self._lower, 60):
            value = float(f(*u))
            if not np.isfinite(value) or abs(float(f(*(2 * u))) - 2 * value) > 1e-9 * max(1.0, abs(value)):
                raise SystemDefinitionError(
                    f"h: not homogeneous of degree one at u = {np.round(u, 3).tolist()}: h(2u) != 2 h(u). "
                    "A support function satisfies h(t u) = t h(u) for t > 0."
                )
            if np.min(np.linalg.eigvalsh(np.asarray(hess(*u), dtype=float))) < -1e-9 * max(1.0, abs(value)):
                raise SystemDefinitionError(
                    f"h: not convex at u = {np.round(u, 3).tolist()} (its Hessian has a negative eigenvalue); "
                    "the support function of a convex body is convex."
                )

    def support(self, u: Vector) -> sp.Expr:
        return self.h.xreplace(dict(zip(self._u, u)))

    def contact(self, u: Vector) -> Vector:
        return sp.Matrix([g.xreplace(dict(zip(self._u, u))) for g in self._grad])
