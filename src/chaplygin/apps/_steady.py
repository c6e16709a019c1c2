"""``chaplygin stability`` and the report's "Steady motion and stability" section: one steady
motion of several models, its eigenvalues and verdicts, root loci, symbolic conditions.

The command line reads the point (``--at "theta=0, phi'=2.5"``) with :func:`parse_at`; the work
is done by the public API of :mod:`chaplygin.numeric.stability` (``stability``,
``steady_motions``, ``root_locus``, ``stability_conditions``, ``linearize``), one model at a
time.  Of its results this module reads only documented attributes: ``Stability`` (``model``,
``point``, ``variables``, ``ignorable``, ``eigenvalues``, ``zeros``, ``kind``, ``verdict``,
``stable``, ``family_dimension``, ``tolerance``, ``residual``), ``SteadyMotion`` (``point``,
``fixed``, ``family_dimension``, ``residual``), ``RootLocus`` (``values``, ``eigenvalues``,
``kinds``, ``plot``), ``Linearization`` (``state``, ``variables``, ``ignorable``) and
``StabilityConditions`` (``polynomial``, ``zero_roots``, ``reduced``, ``route``, ``conditions``).

A velocity ``q'`` among a model's reduced variables whose coordinate ``q`` is one too is 0 at
every steady motion (``q`` stays constant), so it may be left out of the point; the velocity of
an ignorable coordinate (a spin, a turning rate) is a parameter of the motion and must be given.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING, Any

import numpy as np

from chaplygin.errors import ChaplyginError, InputError
from chaplygin.models import registry
from chaplygin.numeric.stability import residual_text

if TYPE_CHECKING:
    from chaplygin.core.system import System

__all__ = [
    "AT_SYNTAX",
    "SCHEMA",
    "Assessed",
    "Study",
    "assess",
    "conditions",
    "describe",
    "document",
    "eigenvalue",
    "loci",
    "locus_csv",
    "locus_figure",
    "locus_rows",
    "parse_at",
    "study",
    "text",
]

#: the ``schema`` of ``chaplygin stability --format json``
SCHEMA = "chaplygin.stability/1"
#: what ``--at`` takes, in the command line's words
AT_SYNTAX = "NAME=NUMBER pairs separated by commas, e.g. \"theta=0, psi'=0, phi'=2.5\""
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def parse_at(text: str, option: str = "--at", symbols: bool = False) -> dict[str, float | str]:
    """``"theta=0, phi'=2.5"`` → ``{"theta": 0.0, "phi'": 2.5}``.  With ``symbols`` a value may
    be a name (``phi'=w``: a symbol of the symbolic conditions), kept as the string.  Nothing is
    evaluated: a value is a float or an identifier."""
    out: dict[str, float | str] = {}
    for item in (part.strip() for part in text.split(",")):
        key, sep, value = (s.strip() for s in item.partition("="))
        accepted = AT_SYNTAX + (" (with --conditions a value may be a name: phi'=w)" if symbols else "")
        if not sep or not key or not value:
            raise InputError(f"{option}: {item!r} is not NAME=NUMBER; give {accepted}.")
        if key in out:
            raise InputError(f"{option}: {key} is given twice; give each name once.")
        try:
            number = float(value)
        except ValueError:
            if symbols and _IDENTIFIER.fullmatch(value):
                out[key] = value
                continue
            raise InputError(f"{option}: {key}={value!r} is not a number; give {accepted}.") from None
        if not math.isfinite(number):
            raise InputError(f"{option}: {key}={value} is not a finite number; give {accepted}.")
        out[key] = number
    return out


def describe(model: str) -> str:
    """``"the true motion"`` or ``"the vakonomic motion"``: what a model of the registry describes."""
    return "the true motion" if registry.get(model).is_true_motion else "the vakonomic motion"


def _point(
    system: System, lin: Any, at: Mapping[str, Any], model: str, vary: str | None = None
) -> tuple[dict[str, Any], list[str]]:
    """The point of one model from ``--at`` (names that ``lin``'s state lacks left out), and the
    velocities defaulted to 0; an :class:`InputError` naming what is missing."""
    state, variables = list(lin.state), list(lin.variables)
    point = {k: v for k, v in at.items() if k in state}
    defaulted = [
        name
        for name in variables
        if name.endswith("'") and name[:-1] in variables and name not in point and name != vary
    ]
    point.update(dict.fromkeys(defaulted, 0.0))
    missing = [name for name in variables if name not in point and name != vary]
    if missing:
        ignorable = ", ".join(lin.ignorable) or "none"
        coordinates = {q.func.__name__ for q in system.coordinates}
        multipliers = [name for name in missing if name.rstrip("'") not in coordinates]
        hint = (
            f" The multipliers {', '.join(multipliers)} have no default: give them, or use --model "
            "lindelof (the vakonomic motion with every c_β = 0, which has none)."
            if multipliers
            else ""
        )
        raise InputError(
            f"--at: no value for {', '.join(missing)}: a steady motion of the {model} model is given by "
            f"{', '.join(variables)} (a velocity q' with q among them may be left out: it is 0; the "
            f"ignorable coordinates {ignorable} may be left out).{hint}"
        )
    return point, defaulted


def _check_names(system: System, at: Mapping[str, Any], states: Mapping[str, Sequence[str]]) -> None:
    """Every name of ``--at`` belongs to the state of at least one of the models."""
    known = list(dict.fromkeys(name for state in states.values() for name in state))
    for name in at:
        if name not in known:
            raise InputError(
                f"--at: {name!r} is not a coordinate, velocity or multiplier of {system.name} in "
                f"{', '.join(states)}; the names are {', '.join(known)}."
            )


def _reworded(exc: ChaplyginError, where: str = "") -> ChaplyginError:
    """An API error in the command line's words (``point:`` is ``--at``; the API's Newton search
    is ``--find``), with ``where`` in front."""
    text = str(exc).replace("steady_motions(system, guess=...)", "--find (a Newton search from --at)")
    text = text.replace("try another guess or fix other variables", "try another --at or other --fixed")
    text = _API_NAMES.sub(lambda m: _OPTIONS[m[1]] + ": ", text)
    try:
        return type(exc)(f"{where}{text}")
    except TypeError:  # a subclass whose constructor takes more than the message
        return ChaplyginError(f"{where}{text}")


#: the API's names for what the command line calls by its options
_OPTIONS = {"point": "--at", "parameters": "--param", "fixed": "--fixed", "steady_motions": "--find"}
_API_NAMES = re.compile(rf"(?<![\w-])({'|'.join(_OPTIONS)}): ")


@dataclass
class Assessed:
    """One model's answer: the stability, the steady motion found (``--find``) and the velocities
    that were 0 by default."""

    model: str
    stability: Any
    found: Any = None
    defaulted: tuple[str, ...] = ()


def _linearizations(system: System, models: Sequence[str], parameters: Mapping[str, float]) -> dict[str, Any]:
    from chaplygin import linearize

    out = {}
    for model in models:
        try:
            out[model] = linearize(system, model, parameters)
        except ChaplyginError as exc:
            raise _reworded(exc, f"{model}: ") from None
    return out


def assess(
    system: System,
    at: Mapping[str, float],
    parameters: Mapping[str, float],
    models: Sequence[str],
    fixed: Sequence[str] | None = None,
) -> list[Assessed]:
    """The stability of the steady motion ``at`` in each model; with ``fixed`` (``--find``), of the
    steady motion a Newton search finds from ``at``, holding ``fixed``."""
    from chaplygin import stability, steady_motions

    lins = _linearizations(system, models, parameters)
    _check_names(system, at, {m: lin.state for m, lin in lins.items()})
    out = []
    for model, lin in lins.items():
        point, defaulted = _point(system, lin, at, model)
        found = None
        try:
            if fixed is not None:
                _check_fixed(fixed, lin, model)
                found = steady_motions(system, point, parameters, model=model, fixed=list(fixed))
                point = dict(found.point)
            result = stability(system, point, parameters, model=model)
        except ChaplyginError as exc:
            raise _reworded(exc, f"{model}: ") from None
        out.append(Assessed(model, result, found, tuple(defaulted)))
    return out


def _check_fixed(fixed: Sequence[str], lin: Any, model: str) -> None:
    for name in fixed:
        if name not in lin.variables:
            raise InputError(
                f"--fixed: {name!r} is not a reduced variable of the {model} model; they are "
                f"{', '.join(lin.variables)}."
            )


def loci(
    system: System,
    at: Mapping[str, float],
    parameters: Mapping[str, float],
    models: Sequence[str],
    vary: str,
    values: np.ndarray,
    fixed: Sequence[str] | None = None,
) -> dict[str, Any]:
    """A root locus per model along ``vary`` (a reduced variable or a parameter); with ``fixed``
    (``--find``), the steady motion at each value found by a Newton search from the one before,
    ``vary`` and ``fixed`` held."""
    from chaplygin import root_locus

    lins = _linearizations(system, models, parameters)
    states = {m: list(lin.state) for m, lin in lins.items()}
    if vary not in parameters and not any(vary in state for state in states.values()):
        raise InputError(
            f"--vary: {vary!r} is neither a parameter of {system.name} ({', '.join(parameters) or 'none'}) "
            f"nor a variable of {', '.join(models)} ({', '.join(dict.fromkeys(n for state in states.values() for n in state))})."
        )
    _check_names(system, at, states)
    out = {}
    for model, lin in lins.items():
        if vary not in parameters and vary not in lin.variables:
            raise InputError(
                f"--vary: {vary!r} is not a reduced variable of the {model} model (ignorable there, or "
                f"not in its state); vary one of {', '.join(lin.variables)} or a parameter."
            )
        point, _ = _point(system, lin, at, model, vary)
        follow = _Follow(system, model, point, parameters, vary, fixed)
        try:
            if fixed is not None:
                _check_fixed(fixed, lin, model)
            out[model] = root_locus(system, point, vary, list(values), parameters, model=model, points=follow)
        except ChaplyginError as exc:
            raise _reworded(exc, f"{model}: at {vary} = {follow.value:g}: ") from None
    return out


class _Follow:
    """``root_locus``'s ``points``: the steady motion at each value (without ``fixed``: the point
    as given; with it, a Newton search from the previous one, ``fixed`` and the varied variable
    held); remembers the value reached, for the error messages."""

    def __init__(
        self,
        system: System,
        model: str,
        point: Mapping[str, Any],
        parameters: Mapping[str, float],
        vary: str,
        fixed: Sequence[str] | None,
    ) -> None:
        self.system, self.model, self.guess = system, model, dict(point)
        self.parameters, self.vary, self.fixed = dict(parameters), vary, fixed
        self.value = math.nan

    def __call__(self, value: float) -> dict[str, Any]:
        from chaplygin import steady_motions

        self.value = value
        if self.fixed is None:
            return self.guess
        if self.vary in self.parameters:
            parameters, guess, held = {**self.parameters, self.vary: value}, self.guess, list(self.fixed)
        else:
            parameters, guess = self.parameters, {**self.guess, self.vary: value}
            held = list(dict.fromkeys([*self.fixed, self.vary]))
        found = steady_motions(self.system, guess, parameters, model=self.model, fixed=held)
        self.guess = {**guess, **found.point}
        return self.guess


def conditions(
    system: System, at: Mapping[str, Any], models: Sequence[str], time_limit: float | None
) -> dict[str, Any]:
    """:func:`chaplygin.stability_conditions` of each model at ``at`` (a value that is a string is
    a symbol), each within ``time_limit`` seconds (None: no limit), interruptible."""
    import sympy as sp

    from chaplygin import linearize, stability_conditions

    clashes = [str(v) for v in at.values() if isinstance(v, str) and v in {p.name for p in system.parameters}]
    if clashes:
        raise InputError(
            f"--at: {clashes[0]} is a parameter of {system.name}; name the symbol otherwise (phi'=w)."
        )
    point = {k: sp.Symbol(v, real=True) if isinstance(v, str) else v for k, v in at.items()}
    out = {}
    for model in models:
        # the reduced model's variables name what to give (numbers for the structure only)
        reduced = _reduced(system, model)
        sample = {p.name: 1.0 for p in system.parameters}
        sample.update({c.name: 1.0 for c in system.equations(reduced).constants})
        lin = linearize(system, reduced, sample)
        given, _ = _point(system, lin, {k: v for k, v in point.items() if k in lin.state}, reduced)
        given = {k: sp.nsimplify(v) if isinstance(v, float) else v for k, v in given.items()}
        try:
            out[model] = _within(
                partial(stability_conditions, system, given, model=model),
                time_limit,
                f"{model}: the symbolic conditions",
            )
        except ChaplyginError as exc:
            raise _reworded(exc, f"{model}: ") from None
    return out


def _reduced(system: System, model: str) -> str:
    """The reduced model whose variables :func:`chaplygin.stability_conditions` takes for ``model``."""
    entry = registry.get(model)
    if entry.reduced:
        return model
    return registry.true_motion(system) if entry.is_true_motion else "lindelof"


def _within(work: Callable[[], Any], seconds: float | None, what: str) -> Any:
    """``work()`` (:func:`chaplygin.analysis.steady.within`: Ctrl-C heard at once); a
    :class:`ChaplyginError` past ``seconds``."""
    from chaplygin.analysis.steady import TIMED_OUT, within

    result = within(work, seconds)
    if result is TIMED_OUT:
        raise ChaplyginError(
            f"{what} took longer than {seconds:g} s (--time-limit); give a smaller system, more "
            "numbers in --at, or --time-limit 0 for no limit."
        )
    return result


# ---------------------------------------------------------------------------- printing
def eigenvalue(z: complex, zero: float = 0.0, digits: int = 6) -> str:
    """``-1.17647``, ``0 + 2.67432i``: a real part or modulus below ``zero`` printed as 0."""
    re_, im = float(np.real(z)), float(np.imag(z))
    re_ = (0.0 if abs(re_) <= zero else re_) + 0.0
    im = (0.0 if abs(im) <= zero else im) + 0.0
    if im == 0.0:
        return f"{re_:.{digits}g}"
    return f"{re_:.{digits}g} {'+' if im > 0 else '-'} {abs(im):.{digits}g}i"


def _values(point: Mapping[str, Any]) -> str:
    return ", ".join(
        f"{k} = {v + 0.0:.12g}" if isinstance(v, float) else f"{k} = {v}" for k, v in point.items()
    )


def _block(row: Assessed) -> list[str]:
    s = row.stability
    drift = ", ".join(f"{k}' = {eigenvalue(v, 1e-12)}" for k, v in s.ignorable.items())
    lines = [f"{row.model} ({describe(row.model)}): {s.kind}"]
    if row.found is not None:
        lines.append(
            f"  found by a Newton search from --at, holding {', '.join(row.found.fixed) or 'nothing'}: "
            f"a family of steady motions of dimension {row.found.family_dimension} through it, residual "
            f"{residual_text(row.found.residual)}"
        )
    lines.append(f"  point: {_values(s.point)}")
    if row.defaulted:
        lines.append(
            f"  ({', '.join(row.defaulted)} = 0 by default: a steady motion keeps the coordinate constant)"
        )
    lines.append(
        f"  reduced variables: {', '.join(s.variables)}"
        + (f"; ignorable, moving uniformly: {drift}" if drift else "")
    )
    lines.append("  eigenvalues: " + ", ".join(eigenvalue(z, s.tolerance) for z in s.eigenvalues))
    for reason in dict.fromkeys(s.zeros):
        count = s.zeros.count(reason)
        lines.append(f"  {count} zero eigenvalue{'s' if count > 1 else ''}: {reason}")
    lines.append(f"  verdict: {s.verdict}")
    return lines


def text(
    system: System,
    parameters: Mapping[str, float],
    rows: Sequence[Assessed],
    locus: Mapping[str, Any] | None = None,
    symbolic: Mapping[str, Any] | None = None,
) -> str:
    """What ``chaplygin stability`` prints: the parameters, a block per model (the point, the
    reduced variables, eigenvalues, the named zero eigenvalues, the verdict), the root loci's
    tables and the symbolic conditions."""
    lines = [f"{system.name}: steady motion and linear stability"]
    if parameters:
        lines.append("  parameters: " + _values(dict(parameters)))
    for row in rows:
        lines += _block(row)
    if len(rows) > 1:
        width = max(len(r.model) for r in rows)
        lines.append("side by side (the largest real part, the named zero eigenvalues set aside):")
        for r in rows:
            rest = r.stability.eigenvalues[r.stability.eigenvalues != 0]  # the named zeros are exactly 0
            first = eigenvalue(rest[0], r.stability.tolerance) if rest.size else "-"
            lines.append(f"  {r.model:<{width}}  {r.stability.kind:<21}  {first}")
    for model, lc in (locus or {}).items():
        lines.append(
            f"root locus of {model} ({describe(model)}) against {lc.parameter}: eigenvalues, largest real part first"
        )
        for value, kind, roots in locus_rows(lc):
            lines.append(
                f"  {lc.parameter} = {value:<10.6g} {kind:<21}  {', '.join(eigenvalue(z, 1e-9, 5) for z in roots)}"
            )
        lines += [f"  crossing at {lc.parameter} = {c}" for c in lc.crossings()]
    for model, cond in (symbolic or {}).items():
        reduced = _reduced(system, model)
        via = f"; from the {reduced} equations" if reduced != model else ""
        via += ", the member with every c_β = 0" if via and reduced == "lindelof" else ""
        lines.append(f"stability conditions of {model} ({describe(model)}{via}):")
        lines += [f"  {line}" for line in str(cond).splitlines()]
    return "\n".join(lines)


def locus_rows(lc: Any) -> list[tuple[float, str, np.ndarray]]:
    """``(value, kind, eigenvalues)`` per value of a root locus."""
    return [(float(v), str(k), np.asarray(row)) for v, k, row in zip(lc.values, lc.kinds, lc.eigenvalues)]


def _pairs(values: Any) -> list[list[float]]:
    return [[float(np.real(z)) + 0.0, float(np.imag(z)) + 0.0] for z in values]


def document(
    system: System,
    parameters: Mapping[str, float],
    at: Mapping[str, Any],
    rows: Sequence[Assessed],
    locus: Mapping[str, Any] | None = None,
    symbolic: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """The JSON document of ``chaplygin stability --format json`` (schema :data:`SCHEMA`);
    eigenvalues are ``[real, imaginary]`` pairs."""
    from chaplygin.core._symbols import file_syntax

    models = []
    for row in rows:
        s = row.stability
        models.append(
            {
                "model": row.model,
                "motion": registry.get(row.model).motion,
                "point": {k: float(v) for k, v in s.point.items()},
                "defaulted": list(row.defaulted),
                "variables": list(s.variables),
                "ignorable": {k: float(np.real(v)) for k, v in s.ignorable.items()},
                "eigenvalues": _pairs(s.eigenvalues),
                "zeros": list(s.zeros),
                "family_dimension": int(s.family_dimension),
                "kind": s.kind,
                "stable": s.stable,
                "verdict": s.verdict,
                "tolerance": float(s.tolerance),
                "residual": float(s.residual),
                "found": None
                if row.found is None
                else {
                    "fixed": list(row.found.fixed),
                    "family_dimension": int(row.found.family_dimension),
                    "residual": float(row.found.residual),
                },
            }
        )
    return {
        "schema": SCHEMA,
        "system": system.name,
        "parameters": {k: float(v) for k, v in parameters.items()},
        "at": {k: v if isinstance(v, str) else float(v) for k, v in at.items()},
        "models": models,
        "locus": None
        if not locus
        else {
            model: {
                "parameter": lc.parameter,
                "values": [float(v) for v in lc.values],
                "kinds": list(lc.kinds),
                "eigenvalues": [_pairs(row) for row in lc.eigenvalues],
                "crossings": [
                    {
                        "value": c.value,
                        "eigenvalue": _pairs([c.eigenvalue])[0],
                        "kind": c.kind,
                        "change": c.change,
                    }
                    for c in lc.crossings()
                ],
            }
            for model, lc in locus.items()
        },
        "conditions": None
        if not symbolic
        else {
            model: {
                "from": _reduced(system, model),
                "polynomial": file_syntax(c.polynomial),
                "zero_roots": int(c.zero_roots),
                "reduced": file_syntax(c.reduced),
                "route": c.route,
                "conditions": [file_syntax(x) for x in c.conditions],
            }
            for model, c in symbolic.items()
        },
    }


def locus_csv(locus: Mapping[str, Any]) -> str:
    """The root loci as CSV: ``model, <parameter>, kind, re_1, im_1, …`` (shortest round-trip numbers)."""
    width = max(lc.eigenvalues.shape[1] for lc in locus.values())
    parameter = next(iter(locus.values())).parameter
    head = ["model", parameter, "kind"] + [f"{p}_{k}" for k in range(1, width + 1) for p in ("re", "im")]
    lines = [",".join(head)]
    for model, lc in locus.items():
        for value, kind, row in locus_rows(lc):
            cells = [model, repr(value), kind]
            for z in row:
                cells += [repr(float(np.real(z)) + 0.0), repr(float(np.imag(z)) + 0.0)]
            cells += [""] * (len(head) - len(cells))
            lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


def locus_figure(locus: Mapping[str, Any]) -> Any:
    """One column per model (``RootLocus.plot``): the real parts above, the imaginary parts below."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(5.6 * len(locus), 5.6), layout="constrained")
    axes = fig.subplots(2, len(locus), sharex=True, squeeze=False)
    for k, lc in enumerate(locus.values()):
        lc.plot(ax=axes[:, k])
    return fig


@dataclass
class Study:
    """What the report's "Steady motion and stability" section shows (:func:`study`): the point
    as given, the parameters, one :class:`Assessed` per model and the root loci (or None)."""

    at: dict[str, float]
    parameters: dict[str, float]
    rows: list[Assessed]
    locus: dict[str, Any] | None


def study(
    system: System,
    at: Mapping[str, float],
    parameters: Mapping[str, float],
    models: Sequence[str] | None = None,
    vary: tuple[str, Sequence[float]] | None = None,
    fixed: Sequence[str] | None = None,
) -> Study:
    """The stability of the steady motion ``at`` in ``models`` (default: the true motion and,
    where it applies, Lindelöf's), and with ``vary = (name, values)`` the root loci; ``fixed``
    asks for a Newton search (``--find``) holding those variables."""
    chosen = list(models or _default_models(system))
    name, values = vary if vary is not None else (None, None)
    rows: list[Assessed] = []
    if name is None or name in at or name in parameters:  # else the point lacks the varied value
        rows = assess(system, at, parameters, chosen, fixed)
    locus = None
    if name is not None:
        locus = loci(system, at, parameters, chosen, name, np.asarray(values, dtype=float), fixed)
    return Study(dict(at), dict(parameters), rows, locus)


def true_model(system: System) -> str:
    """The model of the true motion that stability linearises by default: Chaplygin's equations
    where they apply, else the Chetaev multiplier model (the same motion; Voronets' symbolic
    equations of a system like the Whipple bicycle take minutes and gigabytes)."""
    return "chaplygin" if registry.true_motion(system) == "chaplygin" else "chetaev"


def _default_models(system: System) -> list[str]:
    true = true_model(system)
    return [true, "lindelof"] if registry.get("lindelof").obstruction(system) is None else [true]
