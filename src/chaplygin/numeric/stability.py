"""Steady motions and the linear stability of a model, from its exact linearisation.

The linearisation and the reduced variables are :mod:`chaplygin.numeric.linearization`'s: the
admissible manifold, the ignorable coordinates dropped; a **steady motion** (relative
equilibrium) is an equilibrium of the reduced system.

The verdict follows nonholonomic mechanics (Zenkov, Bloch & Marsden, *The energy-momentum method
for the stability of nonholonomic systems*, Dyn. Stab. Syst. 13 (1998)): zero eigenvalues that
come from the family of steady motions (right null vectors) are named, with the integrals whose
differentials annihilate the Jacobian (energy where it is conserved, any the caller gives), and a
motion is not called unstable for those neutral directions.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from chaplygin.errors import ChaplyginError, InputError
from chaplygin.models import registry
from chaplygin.numeric.linearization import Linearization, _name, linearize

if TYPE_CHECKING:
    from chaplygin.core.system import System

__all__ = [
    "Crossing",
    "Linearization",
    "RootLocus",
    "Stability",
    "SteadyMotion",
    "linearize",
    "root_locus",
    "stability",
    "stability_conditions",
    "steady_motions",
]

#: an eigenvalue (a singular value) below this times the Jacobian's norm counts as zero
ZERO_RTOL = 1e-7
#: eigenvalues of least modulus are a zero eigenvalue's cluster when their elementary symmetric
#: functions e_k are below this times |J|^k (rounding leaves them near ε |J|^k)
CLUSTER_RTOL = 1e-10


# ---------------------------------------------------------------------------- the verdict
def _complex(z: complex, digits: int = 6, zero: float = 0.0) -> str:
    re, im = float(np.real(z)), float(np.imag(z))
    re, im = (0.0 if abs(re) <= zero else re) + 0.0, (0.0 if abs(im) <= zero else im) + 0.0
    if abs(im) <= 1e-14 * max(1.0, abs(re)):
        return f"{re:.{digits}g}"
    return f"{re:.{digits}g} {'+' if im >= 0 else '-'} {abs(im):.{digits}g}i"


def residual_text(value: float) -> str:
    """A residual as text: rounding noise (below 1e-12) as such, not as a machine's last digits."""
    return "below 1e-12" if value < 1e-12 else f"{value:.2g}"


def _mode(vector: np.ndarray, names: Sequence[str]) -> str:
    """A mode as its largest components, the largest scaled to 1."""
    k = int(np.argmax(np.abs(vector)))
    v = vector / vector[k]
    parts = [f"{name}: {_complex(c, 3)}" for name, c in zip(names, v) if abs(c) > 1e-3]
    return "(" + ", ".join(parts) + ")"


@dataclass
class Stability:
    """The linear stability of a steady motion (see :func:`stability`).

    Attributes
    ----------
    verdict : str
        One line: ``"asymptotically stable (modulo …)"``, ``"unstable (λ = …, mode …)"``,
        ``"linearly stable: …"`` or ``"undetermined: …"``.
    kind : str
        ``"asymptotically stable"``, ``"unstable"``, ``"linearly stable"`` or ``"undetermined"``.
    eigenvalues : ndarray
        The reduced Jacobian's eigenvalues, largest real part first; ``modes`` their vectors (columns)
        on ``variables``.
    zeros : list of str
        What explains each zero eigenvalue.
    """

    system: str
    model: str
    point: dict[str, float]
    variables: tuple[str, ...]
    ignorable: dict[str, float]
    jacobian: np.ndarray
    eigenvalues: np.ndarray
    modes: np.ndarray
    family_dimension: int
    zeros: list[str]
    integrals: dict[str, bool]
    kind: str
    verdict: str
    tolerance: float
    residual: float = field(default=0.0)

    def to_dict(self) -> dict[str, Any]:
        """Plain data (JSON-ready): the point, the eigenvalues as ``[re, im]`` pairs, the zeros,
        the integrals' checks, the verdict and the tolerance."""
        return {
            "system": self.system,
            "model": self.model,
            "point": dict(self.point),
            "variables": list(self.variables),
            "ignorable_rates": dict(self.ignorable),
            "eigenvalues": [[float(z.real), float(z.imag)] for z in self.eigenvalues],
            "family_dimension": self.family_dimension,
            "zeros": list(self.zeros),
            "integrals": dict(self.integrals),
            "kind": self.kind,
            "verdict": self.verdict,
            "tolerance": self.tolerance,
            "residual": self.residual,
        }

    @property
    def stable(self) -> bool | None:
        """True (asymptotically or linearly stable), False (unstable), None (undetermined)."""
        return {"unstable": False, "undetermined": None}.get(self.kind, True)

    def _lines(self) -> list[str]:
        point = ", ".join(f"{k} = {v + 0.0:.6g}" for k, v in self.point.items())
        drift = ", ".join(f"{k}' = {_complex(v, zero=1e-12)}" for k, v in self.ignorable.items())
        out = [
            f"Stability of a steady motion of {self.system} ({self.model} model)",
            f"  point: {point}",
            f"  reduced variables: {', '.join(self.variables)}"
            + (f"; ignorable, moving uniformly: {drift}" if drift else ""),
            "  eigenvalues: " + ", ".join(_complex(z, zero=self.tolerance) for z in self.eigenvalues),
        ]
        for reason in dict.fromkeys(self.zeros):
            count = self.zeros.count(reason)
            out.append(f"  {count} zero eigenvalue{'s' if count > 1 else ''}: {reason}")
        out += [
            f"  integral {name}: {'its differential annihilates J' if ok else 'NOT annihilating J'}"
            for name, ok in self.integrals.items()
        ]
        out.append(
            f"  (zero below {self.tolerance:.2g} = rtol x |J|, J balanced; steady-motion residual "
            f"{residual_text(self.residual)})"
        )
        out.append(f"  verdict: {self.verdict}")
        return out

    def __str__(self) -> str:
        return "\n".join(self._lines())

    def _repr_html_(self) -> str:
        return _html_pre("\n".join(self._lines()))


def _balancing(J: np.ndarray) -> np.ndarray:
    """The diagonal ``D`` of ``D⁻¹ J D`` balanced (``scipy.linalg.matrix_balance``, no permutation)."""
    if not J.size:
        return np.ones(0)
    from scipy.linalg import matrix_balance

    _, T = matrix_balance(J, permute=False)
    return np.diag(T).copy()


def _nullity(m: np.ndarray, tol: float) -> int:
    return int(np.sum(np.linalg.svd(m, compute_uv=False) <= tol)) if m.size else 0


def _zero_multiplicity(J: np.ndarray, values: np.ndarray, rtol: float, scale: float) -> tuple[int, int]:
    """``(geometric, algebraic)`` multiplicity of the eigenvalue 0.

    The geometric one is the nullity of ``J`` (its singular values against ``rtol`` times its
    norm, ``scale``).  A defective zero eigenvalue (a Jordan chain over the family) comes out of ``eig`` as a
    cluster of size ``ε^(1/k)`` around 0, which no fixed tolerance on the eigenvalues recognises,
    and the nullities of ``J``'s powers confuse it with a small genuine eigenvalue beside a zero
    (the bicycle just past its capsize speed, ``λ = 0.004`` with ``|J| = 20``).  The symmetric
    functions of a rounded cluster stay as small as rounding makes them: the algebraic
    multiplicity is the largest ``m`` whose ``m`` eigenvalues of least modulus have every
    elementary symmetric function ``|e_k| ≤ CLUSTER_RTOL |J|^k`` (and at least the geometric one).
    """
    if scale == 0.0:
        return J.shape[0], J.shape[0]
    geometric = _nullity(J, rtol * scale)
    smallest = values[np.argsort(np.abs(values), kind="stable")]
    algebraic = 0
    for m in range(1, len(smallest) + 1):
        coefficients = np.abs(np.poly(smallest[:m]))[1:]  # |e_1| … |e_m|
        if np.all(coefficients <= CLUSTER_RTOL * scale ** np.arange(1, m + 1)):
            algebraic = m
    return geometric, max(geometric, algebraic)


def _html_pre(text: str) -> str:
    """A result's text for Jupyter: its first line as the heading, the rest preformatted."""
    from chaplygin import _html

    head, *rest = text.splitlines()
    return _html.heading(head) + "<pre>" + _html.escape("\n".join(r.strip() for r in rest)) + "</pre>"


def _verdict(
    J: np.ndarray,
    names: Sequence[str],
    gradients: Mapping[str, np.ndarray],
    tol_rel: float = ZERO_RTOL,
) -> tuple[np.ndarray, np.ndarray, int, list[str], dict[str, bool], str, str, float]:
    # balanced first (a diagonal similarity, LAPACK's gebal): the reduced variables mix angles,
    # rates and multipliers whose scales differ by orders of magnitude, and every tolerance below
    # is relative to the norm, which balancing brings near the spectral radius
    D = _balancing(J)
    J = J * (1.0 / D)[:, None] * D[None, :]
    gradients = {name: grad * D for name, grad in gradients.items()}
    scale = float(np.linalg.norm(J, 2)) if J.size else 0.0
    tol = tol_rel * max(scale, 1e-300)
    values, vectors = np.linalg.eig(J) if J.size else (np.zeros(0, dtype=complex), np.zeros((0, 0)))
    vectors = D[:, None] * vectors
    family, n0 = _zero_multiplicity(J, values, tol_rel, scale)
    zero = np.zeros(len(values), dtype=bool)
    zero[np.argsort(np.abs(values), kind="stable")[:n0]] = True
    values = np.where(zero, 0.0, values).astype(complex)
    real = np.where(np.abs(values.real) <= tol, 0.0, values.real)  # rounding does not order them
    order = np.lexsort((-np.imag(values), -real))
    values, vectors, zero = values[order], vectors[:, order], zero[order]
    integrals = {
        name: bool(np.linalg.norm(grad @ J) <= tol * max(float(np.linalg.norm(grad)), 1e-300))
        for name, grad in gradients.items()
        if np.linalg.norm(grad) > 0
    }
    consistent = [name for name, ok in integrals.items() if ok]
    rank = _rank([gradients[name] for name in consistent])
    from_family = min(n0, family)
    from_integrals = min(n0 - from_family, rank)
    zeros = [f"from the family of steady motions (its dimension here is {family})"] * from_family
    zeros += [
        f"a Jordan chain over the family, from the integrals {', '.join(consistent)} (changing their "
        "values moves the motion along the family)"
    ] * from_integrals
    unexplained = n0 - from_family - from_integrals
    zeros += ["not explained by the family or by an integral"] * unexplained
    rest = values[~zero]
    if rest.size and float(np.max(np.real(rest))) > tol:
        k = int(np.argmax(np.where(zero, -np.inf, np.real(values))))
        kind = "unstable"
        verdict = f"unstable (λ = {_complex(values[k])}, mode {_mode(vectors[:, k], names)})"
    elif unexplained:
        kind = "undetermined"
        verdict = (
            f"undetermined: {unexplained} zero eigenvalue(s) not explained by the family of steady "
            f"motions (dimension {family}) or by an integral"
            + (f" ({', '.join(consistent)})" if consistent else "")
        )
    elif rest.size and float(np.max(np.real(rest))) < -tol:
        kind = "asymptotically stable"
        verdict = f"asymptotically stable (modulo the family of steady motions, dimension {family})"
    elif not rest.size:
        kind = "linearly stable"
        verdict = "linearly stable: every eigenvalue is a neutral direction of the family of steady motions"
    else:
        kind = "linearly stable"
        axis = int(np.sum(np.abs(np.real(rest)) <= tol))
        verdict = (
            "linearly stable: all remaining eigenvalues on the imaginary axis (nonlinear stability not "
            "decided by the linearisation)"
            if axis == rest.size
            else f"linearly stable: {axis} remaining eigenvalue(s) on the imaginary axis, the others in the "
            "left half-plane (nonlinear stability not decided by the linearisation)"
        )
    return values, vectors, family, zeros, integrals, kind, verdict, tol


def _rank(rows: Sequence[np.ndarray]) -> int:
    """The number of independent rows (each scaled to norm 1 first)."""
    if not rows:
        return 0
    m = np.array([r / np.linalg.norm(r) for r in rows])
    singular = np.linalg.svd(m, compute_uv=False)
    return int(np.sum(singular > 1e-8 * singular[0]))


def _integral_gradients(
    lin: Linearization, y: np.ndarray, integrals: Mapping[str, Any] | None
) -> dict[str, np.ndarray]:
    out = lin.integral_gradients(y)
    for name, fn in (integrals or {}).items():
        if not callable(fn):
            raise InputError(
                f"integrals[{name!r}]: give a function of the state (a mapping of names to numbers) "
                "that returns the conserved quantity's value."
            )
        out[name] = _numeric_gradient(lin, y, fn)
    return out


def _numeric_gradient(
    lin: Linearization, y: np.ndarray, fn: Callable[[dict[str, float]], float]
) -> np.ndarray:
    """The gradient of a caller's integral along the reduced variables (central differences of the
    caller's function: the only finite differences here, on what the caller gives)."""
    _, _, P = lin._restricted(y)
    out = []
    for j in lin._kept:
        h = 1e-6 * max(1.0, abs(y[lin._free[j]]))
        values = [float(fn(dict(zip(lin.state, (y + sgn * h * P[:, j]).tolist())))) for sgn in (1, -1)]
        out.append((values[0] - values[1]) / (2 * h))
    return np.array(out)


def stability(
    system: System,
    point: Mapping[Any, Any],
    parameters: Mapping[Any, float] | None = None,
    *,
    model: str = "chetaev",
    form: str = "classic",
    integrals: Mapping[str, Callable[[dict[str, float]], float]] | None = None,
    rtol: float = ZERO_RTOL,
) -> Stability:
    """The linear stability of a steady motion of one model.

    Parameters
    ----------
    system : System
    point : mapping
        The steady motion, as initial states are written: coordinates by name (``"theta"``),
        velocities as ``"theta'"``, the vakonomic multipliers by name (``"mu_1"``); the ignorable
        coordinates may be left out, the dependent velocities follow from the constraints.
    parameters : mapping
        A number for every parameter.
    model : str
        ``"chetaev"`` (true motion; ``"chaplygin"``/``"voronets"`` give the same), ``"vakonomic"``,
        ``"lindelof"``.
    integrals : mapping, optional
        Further conserved quantities, each a function of the state (names to numbers); the energy is
        added where the system conserves it.
    rtol : float
        An eigenvalue, or a singular value, below ``rtol`` times the Jacobian's norm is zero.

    Returns
    -------
    Stability
        Eigenvalues, modes, the named zero eigenvalues and the verdict.

    Raises
    ------
    InputError
        If the point is not a steady motion of the model (the reduced rates do not vanish).
    """
    lin = linearize(system, model, parameters, form=form)
    y = lin.state_at(point)
    if isinstance(rtol, bool) or not isinstance(rtol, (int, float)) or not 0 < rtol < 1:
        raise InputError(f"rtol = {rtol!r}: give a number between 0 and 1 (the default is {ZERO_RTOL:g}).")
    return _stability_at(lin, y, integrals, rtol)


def _stability_at(
    lin: Linearization, y: np.ndarray, integrals: Mapping[str, Any] | None, rtol: float
) -> Stability:
    f, J = lin.reduced(y)
    if np.all(np.isfinite(f)) and not np.all(np.isfinite(J)):
        raise InputError(
            f"point: the Jacobian of the {lin.model} equations of {lin.system.name} does not exist "
            "there: the argument of a sign() (or of an abs() differentiated twice) of the system is 0, "
            "where the equations jump; linearise on either side of it."
        )
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(J))):
        raise InputError(
            f"point: the {lin.model} equations of {lin.system.name} are singular there (a pole of the "
            "mass matrix or of the solved constraints)."
        )
    scale = max(float(np.linalg.norm(J, 2)), 1.0) * max(1.0, float(np.max(np.abs(y))))
    residual = float(np.max(np.abs(f))) if f.size else 0.0
    if residual > 1e-8 * scale:
        worst = lin.variables[int(np.argmax(np.abs(f)))]
        raise InputError(
            f"point: not a steady motion of the {lin.model} model: the rate of {worst} is "
            f"{f[int(np.argmax(np.abs(f)))]:.3g}, not 0 (largest of the reduced rates); find one with "
            "steady_motions(system, guess=...)."
        )
    values, vectors, family, zeros, ints, kind, verdict, tol = _verdict(
        J, lin.variables, _integral_gradients(lin, y, integrals), rtol
    )
    point_f = lin._evaluate(y).f
    state = dict(zip(lin.state, y.tolist()))
    return Stability(
        system=lin.system.name,
        model=lin.model,
        point={name: state[name] for name in lin.variables},
        variables=lin.variables,
        ignorable={name: float(point_f[lin.state.index(name)]) for name in lin.ignorable},
        jacobian=J,
        eigenvalues=values,
        modes=vectors,
        family_dimension=family,
        zeros=zeros,
        integrals=ints,
        kind=kind,
        verdict=verdict,
        tolerance=tol,
        residual=residual,
    )


# ---------------------------------------------------------------------------- steady motions
@dataclass
class SteadyMotion:
    """A steady motion found by a Newton search (see :func:`steady_motions`).

    ``point`` gives the reduced variables (and the fixed ones) and the coordinates that holonomic
    relations fix; ``family_dimension`` is the dimension of the kernel of the equilibrium
    equations' Jacobian there: the number of parameters of the family of steady motions through it.
    """

    system: str
    model: str
    point: dict[str, float]
    fixed: tuple[str, ...]
    family_dimension: int
    residual: float

    def _repr_html_(self) -> str:
        return _html_pre(str(self))

    def __str__(self) -> str:
        point = ", ".join(f"{k} = {v + 0.0:.12g}" for k, v in self.point.items())
        return (
            f"Steady motion of {self.system} ({self.model} model): {point}\n"
            f"  held fixed: {', '.join(self.fixed) or 'nothing'}; family of steady motions of dimension "
            f"{self.family_dimension} through it; residual {residual_text(self.residual)}"
        )


def steady_motions(
    system: System,
    guess: Mapping[Any, Any] | None = None,
    parameters: Mapping[Any, float] | None = None,
    *,
    model: str = "chetaev",
    form: str = "classic",
    fixed: Sequence[str] | Mapping[str, Any] = (),
    solve_for: Sequence[str] | None = None,
    time_budget: float = 20.0,
) -> Any:
    """Steady motions (relative equilibria) of one model: symbolically, or by a Newton search.

    Parameters
    ----------
    system : System
    guess : mapping, optional
        A point near the steady motion, written as :func:`stability`'s ``point``.  Given: a Newton
        search (``scipy.optimize.root``, Levenberg–Marquardt, with the exact Jacobian) for the
        reduced variables not named in ``fixed``; returns a :class:`SteadyMotion`.  Omitted: the
        reduced equilibrium equations are solved with SymPy
        (:func:`chaplygin.analysis.steady.steady_family`) for ``solve_for`` (or unknowns it
        chooses) within ``time_budget`` seconds; returns a
        :class:`~chaplygin.analysis.steady.SteadyFamily`.  The symbolic route uses the reduced
        model of the motion (Chaplygin's or Voronets' equations for the true motion, Lindelöf's
        for the vakonomic one with ``c = 0``).
    parameters : mapping
        A number for every parameter (the Newton search); optional for the symbolic route.
    fixed : sequence of str, or mapping
        The Newton search: the variables kept at their guessed values (the family's parameters).
        The symbolic route: values (numbers or SymPy expressions) given to some variables before
        solving, e.g. ``{"theta": 0}``.
    solve_for : sequence of str, optional
        The symbolic route's unknowns (see :func:`chaplygin.analysis.steady.steady_family`).
    time_budget : float
        Seconds SymPy may spend solving (the symbolic route); a solve that takes longer is
        abandoned with a :class:`~chaplygin.errors.ChaplyginError` (it finishes unseen in a
        background thread, as Python cannot stop it).

    Returns
    -------
    SteadyMotion or SteadyFamily
        One steady motion (with a guess), or the family solved by SymPy (without).
    """
    if guess is None:
        from chaplygin.analysis.steady import steady_family

        reduced = _reduced_model(system, model)
        lin = linearize(system, reduced, parameters or _sample_parameters(system, reduced))
        held = dict(fixed) if isinstance(fixed, Mapping) else {}
        if fixed and not held:
            raise InputError("fixed: without a guess, give values: a mapping such as {'theta': 0}.")
        return steady_family(
            system, reduced, lin.ignorable, solve_for=solve_for, fixed=held, time_budget=time_budget
        )
    from scipy.optimize import root

    lin = linearize(system, model, parameters, form=form)
    y0 = lin.state_at(guess, guess=True)  # the relations' coordinates: where Newton starts
    fixed = list(fixed)
    for name in fixed:
        if name not in lin.variables:
            raise InputError(
                f"fixed: {name!r} is not a reduced variable of the {lin.model} model; they are "
                f"{', '.join(lin.variables)}."
            )
    positions = [lin._free[j] for j in lin._kept]
    unknown = [k for k, name in enumerate(lin.variables) if name not in fixed]

    def at(values: np.ndarray) -> np.ndarray:
        y = y0.copy()
        y[[positions[k] for k in unknown]] = values
        # the relations' coordinates from the guess's (solved) values: from 0, x² + y² = L² has no step
        return lin.admissible({i: y[i] for i in [*lin._free, *lin._hol]})

    def residual(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        f, J = lin.reduced(at(values))
        return f, J[:, unknown]

    start = y0[[positions[k] for k in unknown]]
    found = root(residual, start, jac=True, method="lm", options={"xtol": 1e-14, "ftol": 1e-14})
    y = at(found.x)
    f, J = lin.reduced(y)
    res = float(np.max(np.abs(f))) if f.size else 0.0
    finite = np.isfinite(res) and bool(np.all(np.isfinite(J)))
    scale = max(float(np.linalg.norm(J, 2)), 1.0) * max(1.0, float(np.max(np.abs(y)))) if finite else 0.0
    if not finite or res > 1e-9 * scale:
        raise ChaplyginError(
            f"steady_motions: no steady motion of the {lin.model} model near the guess (the Newton search "
            f"stopped with the largest reduced rate {res:.3g}); try another guess or fix other variables."
        )
    singular = np.linalg.svd(J, compute_uv=False)
    family = int(np.sum(singular <= ZERO_RTOL * max(float(singular[0]) if singular.size else 0.0, 1e-300)))
    state = dict(zip(lin.state, y.tolist()))
    # with the relations' coordinates, which stability() would otherwise solve again from 0
    point = {v: state[v] for v in [*lin.variables, *(lin.state[i] for i in lin._hol)]}
    return SteadyMotion(lin.system.name, lin.model, point, tuple(fixed), family, res)


def _reduced_model(system: System, model: str) -> str:
    entry = registry.get(model)
    if entry.reduced:
        return model
    if entry.is_true_motion:
        return registry.true_motion(system)
    reason = registry.get("lindelof").obstruction(system)
    if reason:
        raise ChaplyginError(
            f"steady_motions: the symbolic route needs a reduced model of the vakonomic motion "
            f"(Lindelöf's equations), which does not apply: {reason}. Give a guess for a Newton search."
        )
    return "lindelof"


def _sample_parameters(system: System, model: str) -> dict[str, float]:
    """Parameter values for the dependency structure only (random, positive)."""
    rng = np.random.default_rng(2029)
    names = [p.name for p in system.parameters] + [c.name for c in system.equations(model).constants]
    return {name: float(rng.uniform(0.5, 1.5)) for name in names}


# ---------------------------------------------------------------------------- root locus
@dataclass
class Crossing:
    """Where eigenvalues cross the imaginary axis along a root locus (see :meth:`RootLocus.crossings`).

    ``value``: the parameter there; ``eigenvalue``: the crossing eigenvalue there (``i ω`` of a
    complex pair, with ω ≥ 0, or 0); ``kind``: ``"a complex pair (oscillatory)"`` or ``"a real
    eigenvalue"``; ``change``: how many more eigenvalues have a positive real part past it, as the
    parameter increases (negative: the motion gains stability there).
    """

    value: float
    eigenvalue: complex
    kind: str
    change: int

    def __str__(self) -> str:
        where = "leave" if self.change < 0 else "enter"
        return (
            f"{self.value:.10g}: {self.kind} crosses the imaginary axis at {_complex(self.eigenvalue)} "
            f"({abs(self.change)} eigenvalue(s) {where} the right half-plane as it increases)"
        )


@dataclass
class RootLocus:
    """Eigenvalues of the reduced Jacobian along a family of steady motions (see :func:`root_locus`).

    ``values``: the parameter's values; ``eigenvalues``: one row per value, largest real part
    first; ``kinds``: the verdict's kind at each value; ``tolerances``: below what an eigenvalue
    counted as zero at each value.  :meth:`crossings` finds where eigenvalues cross the imaginary
    axis.
    """

    system: str
    model: str
    parameter: str
    values: np.ndarray
    eigenvalues: np.ndarray
    kinds: list[str]
    variables: tuple[str, ...]
    tolerances: np.ndarray = field(default_factory=lambda: np.zeros(0))
    _at: Callable[[float], np.ndarray] | None = field(default=None, repr=False, compare=False)

    def crossings(self, xtol: float = 1e-13) -> list[Crossing]:
        """Where eigenvalues cross the imaginary axis between the locus's values, refined.

        The zero eigenvalues every value has (the family of steady motions, the integrals) are
        set aside: the ``k`` eigenvalues of least modulus, ``k`` the fewest zero eigenvalues at any
        value.  Between two neighbouring values where the number of the others with a positive
        real part changes, bisection on that number (each step one evaluation of the generated
        Jacobian) narrows the interval to ``xtol`` relative; a real part counts as positive above
        ``1e-12`` times the Jacobian's scale (rounding noise of eigenvalues on the imaginary axis
        stays far below it).  Crossings between two values of the locus that cancel each other
        are not seen: give a finer grid.  The eigenvalues counted are ``eig``'s, none set to zero
        by a tolerance, so a crossing is as precise as they are: about 1e-10 relative for the
        bicycle's weave and capsize speeds; where two real eigenvalues meet the family's zeros
        (the upright coin's threshold) the four-fold cluster still leaves it near 1e-9.

        Returns
        -------
        list of Crossing
            In increasing order of the parameter (whatever the order of the locus's values).
        """
        if self._at is None or len(self.values) < 2:
            return []
        zero = np.abs(self.eigenvalues) <= self.tolerances[:, None]
        k = int(zero.sum(axis=1).min())
        scale = float(np.max(self.tolerances)) / ZERO_RTOL

        def others(values: np.ndarray) -> np.ndarray:
            return values[np.argsort(np.abs(values), kind="stable")[k:]]

        def unstable(values: np.ndarray) -> int:
            return int(np.sum(others(values).real > 1e-12 * scale))

        grid = np.unique(self.values)  # increasing: the values may be given in any order
        counts = [unstable(self._at(float(value))) for value in grid]
        found = []
        for i in np.flatnonzero(np.diff(counts)):
            lo, hi = float(grid[i]), float(grid[i + 1])
            c_lo = counts[i]
            while abs(hi - lo) > xtol * max(1.0, abs(lo)):
                mid = 0.5 * (lo + hi)
                if unstable(self._at(mid)) == c_lo:
                    lo = mid
                else:
                    hi = mid
            value = 0.5 * (lo + hi)
            if abs(value) <= 1e-9 * float(np.ptp(self.values)):
                value = 0.0  # at the grid's resolution, zero (the sleigh at rest)
            rest = others(self._at(value))
            at = complex(rest[int(np.argmin(np.abs(rest.real)))])
            # an odd change needs a real eigenvalue (conjugates cross together)
            pair = (counts[i + 1] - c_lo) % 2 == 0 and abs(at.imag) > 1e-12 * scale
            found.append(
                Crossing(
                    value,
                    complex(0.0, abs(at.imag)) if pair else 0j,
                    "a complex pair (oscillatory)" if pair else "a real eigenvalue",
                    counts[i + 1] - c_lo,
                )
            )
        return found

    def _repr_html_(self) -> str:
        return _html_pre(str(self))

    def __str__(self) -> str:
        lines = [f"Root locus of {self.system} ({self.model} model) against {self.parameter}"]
        for value, row, kind in zip(self.values, self.eigenvalues, self.kinds):
            largest = _complex(row[0], 4) if row.size else "-"
            lines.append(f"  {self.parameter} = {value:<10.4g} largest real part {largest:<20} {kind}")
        return "\n".join(lines)

    def plot(self, ax: Any = None) -> Any:
        """Real and imaginary parts of the eigenvalues against the parameter (matplotlib; imported
        here only); returns the figure."""
        import matplotlib.pyplot as plt

        if ax is None:
            fig, axes = plt.subplots(2, 1, sharex=True, figsize=(6.4, 5.6))
        else:
            axes = ax
            fig = axes[0].figure
        # one colour: the eigenvalues are sorted at each value, not followed along the locus
        along = np.repeat(self.values, self.eigenvalues.shape[1])
        axes[0].plot(along, self.eigenvalues.real.ravel(), ".", ms=3, color="C0")
        axes[1].plot(along, self.eigenvalues.imag.ravel(), ".", ms=3, color="C0")
        axes[0].axhline(0.0, color="0.5", lw=0.8)
        axes[0].set_ylabel("Re λ")
        axes[1].set_ylabel("Im λ")
        axes[1].set_xlabel(self.parameter)
        axes[0].set_title(f"{self.system}: {self.model} model")
        return fig


def root_locus(
    system: System,
    point: Mapping[Any, Any],
    vary: str,
    values: Sequence[float],
    parameters: Mapping[Any, float] | None = None,
    *,
    model: str = "chetaev",
    form: str = "classic",
    points: Callable[[float], Mapping[Any, Any]] | None = None,
) -> RootLocus:
    """The eigenvalues of the reduced Jacobian along a family of steady motions.

    Parameters
    ----------
    point : mapping
        A steady motion (as :func:`stability`'s ``point``).
    vary : str
        What changes: a variable of the point (``"phi'"``) or a parameter (``"g"``); with
        ``points``, any name (the bicycle's speed ``"v"``), a parameter's name also setting it.
    values : sequence of float
        Its values.
    points : callable, optional
        ``value -> point``: where the family's other variables change with ``vary`` (the lean of a
        turning disk), the steady motion at each value; ``point`` is then only the first guess.

    Notes
    -----
    The system is linearised once (:func:`linearize`); each further point costs one evaluation of
    the generated code, two small solves and an eigenvalue problem.  Varying a parameter
    recompiles nothing either: the generated code takes the parameters as an argument.
    """
    try:
        grid = np.asarray(values, dtype=float).ravel()
    except (TypeError, ValueError):
        raise InputError(f"values: give numbers for {vary}, not {values!r}.") from None
    if not grid.size or not np.all(np.isfinite(grid)):
        raise InputError(f"values: give at least one finite number for {vary}.")
    lin = linearize(system, model, parameters, form=form)
    is_parameter = vary in lin.parameters
    is_variable = not is_parameter
    if is_variable:
        try:
            _name(system, vary, list(lin.state))
        except InputError:
            if points is None:
                raise
            is_variable = False  # a label: points() gives the steady motion at each value

    def state(value: float) -> np.ndarray:
        where = dict(points(value)) if points is not None else dict(point)
        if is_variable:
            where[vary] = value
        return lin.state_at(where)

    def at(value: float, evaluate: Callable[[np.ndarray], Any]) -> Any:
        if is_parameter:
            lin._p[lin.layout.parameters.index(vary)] = value
        try:
            return evaluate(state(value))
        finally:
            if is_parameter:
                lin._p[:] = [lin.parameters[name] for name in lin.layout.parameters]

    def verdict(y: np.ndarray) -> Stability:
        return _stability_at(lin, y, None, ZERO_RTOL)

    def raw(y: np.ndarray) -> np.ndarray:  # no eigenvalue set to zero: for crossings()
        return np.linalg.eigvals(lin.reduced(y)[1])

    results = [at(float(value), verdict) for value in grid]
    return RootLocus(
        system.name,
        lin.model,
        vary,
        grid,
        np.array([r.eigenvalues for r in results]),
        [r.kind for r in results],
        lin.variables,
        np.array([r.tolerance for r in results]),
        lambda value: at(value, raw),
    )


def stability_conditions(system: System, point: Mapping[str, Any], *, model: str = "chetaev") -> Any:
    """The symbolic conditions for linear stability at ``point`` (names to numbers or SymPy
    expressions: ``{"theta": 0, "phi'": s, …}``), from the reduced model of the motion: see
    :func:`chaplygin.analysis.steady.stability_conditions`.  For a small reduced system."""
    from chaplygin.analysis.steady import stability_conditions as conditions

    reduced = _reduced_model(system, model)
    lin = linearize(system, reduced, _sample_parameters(system, reduced))
    return conditions(
        system, {k: v for k, v in point.items() if k not in lin.ignorable}, reduced, lin.ignorable
    )
