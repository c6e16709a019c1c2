"""System files: a mechanical system, its parameter values and an initial state, in TOML.

::

    name = "Knife edge"
    coordinates = ["x", "y", "phi"]

    [parameters]            # every parameter, with a default value
    m = 1.0
    J = 0.5

    [energy]
    T = "m/2*(x'^2 + y'^2) + J/2*phi'^2"
    V = "0"                 # or U = "..." (force function); both optional

    [forces]                # optional non-potential forces: coordinate = "Q"
    phi = "-0.1*phi'"

    [constraints]           # solved: dependent velocity = expression
    "y'" = "tan(phi)*x'"
    # or: implicit = ["sin(phi)*x' - cos(phi)*y'"] with dependent = ["y"]
    # nonlinear in the velocities too: "z'" = "k*sqrt(x'^2 + y'^2)", or implicit ones
    # with branch = K choosing a solution for the dependent velocities

    [holonomic]             # optional: coordinate = "f" for a relation f(q, t) = 0 fixing it
    # z = "z - a*sin(x)"

    [initial]               # coordinates and independent velocities (missing ones are 0)
    phi = 0.3
    "x'" = 1.0

:func:`load` and :func:`loads` read a file into a :class:`SystemFile`,
:func:`dumps` writes one.  Expressions are read by :mod:`chaplygin.io.parser`,
never evaluated as code; every problem is a :class:`SystemFileError` that names
the key, shows the text with a caret and says what is allowed.  The format is
described in ``docs/system-files.md``.

A rolling rigid body can be given by its shape instead, in a ``[body]`` table (no
``coordinates``, ``[energy]``, ``[forces]`` or ``[constraints]``); it is built by
:func:`chaplygin.bodies.rolling_body`::

    name = "Routh's sphere"
    [body]
    shape = "sphere"              # sphere, disk, torus, ellipsoid, paraboloid
    radius = "r"                  # the shape's keys (see BODY_SHAPES)
    mass = "m"
    inertia = ["A", "A", "C"]     # principal moments, or a 3 x 3 list of lists
    center_of_mass = [0, 0, "-e"] # optional, default the shape's origin
    angles = "euler"              # optional: cardan, edge or euler
    g = "g"                       # optional, default the parameter g
"""

from __future__ import annotations

import difflib
import json
import math
import re
import sys
from collections.abc import Mapping
from typing import Any

import sympy as sp
from sympy.core.function import AppliedUndef
from sympy.printing.str import StrPrinter

from chaplygin.bodies import Disk, Ellipsoid, Paraboloid, RollingBody, Shape, Sphere, Torus, rolling_body
from chaplygin.bodies.builder import ANGLES
from chaplygin.core._symbols import TIME, file_syntax
from chaplygin.core.system import System
from chaplygin.errors import SystemDefinitionError
from chaplygin.io._file import MAX_FILE_SIZE, SystemFile, load
from chaplygin.io.parser import (
    RESERVED,
    Names,
    ParseError,
    SystemFileError,
    check_name,
    parse_constant,
    parse_expression,
    preserved_state,
)

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = [
    "BODY_KEYS",
    "BODY_SHAPES",
    "MAX_COORDINATES",
    "MAX_FILE_SIZE",
    "MAX_PARAMETERS",
    "MAX_SYSTEM_NAME_LENGTH",
    "SECTIONS",
    "ParseError",
    "SystemFile",
    "SystemFileError",
    "dumps",
    "load",
    "loads",
]

#: Most coordinates in one system.
MAX_COORDINATES = 32
#: Most parameters in one system.
MAX_PARAMETERS = 256
#: Longest system name.
MAX_SYSTEM_NAME_LENGTH = 200

#: The top-level keys and tables of a system file.
SECTIONS = (
    "name",
    "coordinates",
    "parameters",
    "energy",
    "forces",
    "constraints",
    "holonomic",
    "initial",
    "body",
)
#: The shapes of a ``[body]`` table: shape name → (class, its keys, in the constructor's order).
BODY_SHAPES: dict[str, tuple[type[Shape], tuple[str, ...]]] = {
    "sphere": (Sphere, ("radius",)),
    "disk": (Disk, ("radius",)),
    "torus": (Torus, ("R", "r")),
    "ellipsoid": (Ellipsoid, ("a", "b", "c")),
    "paraboloid": (Paraboloid, ("rho1", "rho2")),
}
#: The keys of a ``[body]`` table besides the shape's own.
BODY_KEYS = ("shape", "mass", "inertia", "center_of_mass", "angles", "g")
#: The coordinates of a system built from a ``[body]`` table (see :func:`chaplygin.bodies.rolling_body`).
BODY_COORDINATES = ("psi", "theta", "phi", "x", "y")
_NOT_WITH_BODY = ("coordinates", "energy", "forces", "constraints", "holonomic")
_ENERGY_KEYS = ("T", "V", "U")
_IMPLICIT_KEYS = ("implicit", "dependent")
#: System's refusals of nonlinear constraints, mapped to the file's keys (_Reader.system_error)
_NONLINEAR_ERROR = re.compile(
    r"(branch|holonomic|constraints|the constraints)(?:\[(\d+)\])?: (.*(?:branch|nonlinear in the velocities|"
    r"Appell–Chetaev|cannot solve the implicit).*)$",
    re.S,
)
_FEW_CHOICES = 500  # below this many choices of dependent coordinates, System's own check is quick
_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+\Z")
_TOML_POSITION = re.compile(r"\(at line (\d+), column (\d+)\)\s*$")
_TOML_EOF = re.compile(r"\(at end of document\)\s*$")


# ---------------------------------------------------------------------------- reading
def loads(text: str, *, source: str = "<string>") -> SystemFile:
    """Read a system file from a string (see :func:`load`); ``source`` names it in messages."""
    return _loads(text, source, None)


def _loads(text: str, source: str, default_name: str | None) -> SystemFile:
    if not isinstance(text, str):
        raise SystemFileError(f"expected the text of a system file, got {type(text).__name__}", source=source)
    if len(text) > MAX_FILE_SIZE:
        raise SystemFileError(
            f"the file is {len(text)} characters long (limit {MAX_FILE_SIZE})",
            source=source,
            allowed=f"Limit: {MAX_FILE_SIZE} characters per system file.",
        )
    text = text.removeprefix("\ufeff")
    reader: _Reader | None = None
    with preserved_state():  # mpmath's precision and SymPy's flags are the same afterwards
        try:
            data = _parse_toml(text, source)
            reader = _Reader(data, source, default_name)
            return reader.read()
        except SystemFileError:
            raise
        except Exception as exc:  # the boundary between user files and SymPy: never a traceback
            key, value = (reader.where, reader.text) if reader is not None else (None, None)
            raise SystemFileError(
                f"chaplygin could not read this ({type(exc).__name__}: {str(exc)[:200]})",
                source=source,
                key=key,
                text=value,
                allowed="This is a limitation of chaplygin; please report it with the file.",
            ) from exc


def _parse_toml(text: str, source: str) -> dict[str, Any]:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        message = str(exc)
        m = _TOML_POSITION.search(message)
        reason = "invalid TOML: " + (message[: m.start()] if m else _TOML_EOF.sub("", message)).strip()
        lines = text.split("\n")
        if m:
            line, col = int(m.group(1)), int(m.group(2)) - 1
        else:
            line, col = len(lines), len(lines[-1]) if lines else 0
        shown = lines[line - 1] if 0 < line <= len(lines) else ""
        hint = "System files are TOML: key = value lines and [table] headers."
        if "'" in shown.split("=", 1)[0] and not shown.lstrip().startswith(('"', "[")):
            hint = 'Keys with a prime must be quoted: "x\'" = "...".'
        raise SystemFileError(
            reason, source=source, line=line, text=shown, column=col, allowed=hint
        ) from None
    except RecursionError:
        raise SystemFileError(
            "invalid TOML: values are nested too deeply",
            source=source,
            allowed="System files use flat tables, lists of strings and numbers.",
        ) from None
    except ValueError as exc:  # e.g. an integer with too many digits
        raise SystemFileError(f"invalid TOML: {exc}", source=source) from None


def _key(section: str | None, key: str | None = None) -> str:
    """How a key is shown in messages: ``[constraints] "x'"``, ``coordinates``."""
    if key is None:
        return str(section)
    shown = key if _BARE_KEY.match(key) else json.dumps(key, ensure_ascii=False)
    return f"[{section}] {shown}" if section else shown


def _unknown(key: str, allowed: tuple[str, ...] | list[str], where: str) -> str:
    close = difflib.get_close_matches(key, list(allowed), n=1)
    return f"unknown key {json.dumps(key, ensure_ascii=False)} in {where}" + (
        f" (did you mean {close[0]!r}?)" if close else ""
    )


class _Reader:
    def __init__(self, data: dict[str, Any], source: str, default_name: str | None) -> None:
        self.data = data
        self.source = source
        self.default_name = default_name
        # the key and text being read, for errors that escape from SymPy (see _loads)
        self.where: str | None = None
        self.text: str | None = None
        # [parameters] and [initial] values given as constant strings, exactly (SystemFile.exact)
        self.exact: dict[str, sp.Expr] = {}

    def error(self, reason: str, key: str | None = None, **fields: Any) -> SystemFileError:
        return SystemFileError(reason, source=self.source, key=key, **fields)

    def table(self, name: str, required: bool = False) -> dict[str, Any]:
        value = self.data.get(name)
        if value is None:
            if required:
                raise self.error(
                    f"the [{name}] table is missing",
                    allowed=_SECTION_HELP[name],
                )
            return {}
        if not isinstance(value, dict):
            raise self.error(
                f"{name} must be a table ([{name}] with key = value lines), got {_describe(value)}",
                name,
                allowed=_SECTION_HELP[name],
            )
        return value

    def read(self) -> SystemFile:
        for key in self.data:
            if key not in SECTIONS:
                raise self.error(
                    _unknown(key, SECTIONS, "the file"),
                    _key(None, key),
                    allowed="Allowed top-level keys and tables: " + ", ".join(SECTIONS) + ".",
                )
        name = self.read_name()
        if "body" in self.data:
            return self.read_body_file(name)
        coordinates = self.read_coordinates()
        parameters = self.read_parameters(coordinates)
        names = Names.build(parameters, coordinates)
        kwargs = self.read_energy(names)
        kwargs["forces"] = self.read_forces(names) or None
        kwargs["holonomic"] = self.read_holonomic(names) or None
        constraints, dependent = self.read_constraints(names)
        kwargs["branch"] = self.read_branch(isinstance(constraints, dict))
        system = self.build(names, constraints, dependent, name, kwargs)
        return self.finish(system, parameters, name)

    def finish(
        self, system: System, parameters: dict[str, float], name: str, body: dict[str, Any] | None = None
    ) -> SystemFile:
        used = {p.name for p in system.parameters}
        unused = [p for p in parameters if p not in used]
        if unused:
            raise self.error(
                f"{unused[0]} is not used in any expression of the system",
                _key("parameters", unused[0]),
                allowed="Every parameter in [parameters] must appear in the "
                + ("[body] table" if body is not None else "energy, forces or constraints")
                + "; remove the unused ones.",
            )
        initial = self.read_initial(system)
        if system.is_nonlinear:
            self.check_initial_real(system, initial, parameters)
        given = self.table("initial")
        return SystemFile(
            system,
            parameters,
            initial,
            name,
            self.source,
            tuple(k for k in initial if k not in given),
            body,
            self.exact,
        )

    # ------------------------------------------------------------ [body]
    def read_body_file(self, name: str) -> SystemFile:
        """A rolling body: ``[body]``, ``[parameters]`` and ``[initial]``, built by ``rolling_body``."""
        for key in _NOT_WITH_BODY:
            if key in self.data:
                raise self.error(
                    f"{key} cannot be given with a [body] table: the body's coordinates, energy and "
                    "constraints are built from its shape",
                    _key(None, key),
                    allowed="A [body] file has name, [body], [parameters] and [initial]; remove "
                    f"{key}, or remove [body] and describe the system by hand.",
                )
        body = self.table("body")
        parameters = self.read_parameters(list(BODY_COORDINATES))
        names = Names.build(parameters, time=False)
        shape_name = body.get("shape")
        if not isinstance(shape_name, str) or shape_name not in BODY_SHAPES:
            got = "missing" if shape_name is None else f"{_describe(shape_name)}, not a known shape"
            raise self.error(f"shape is {got}", "[body] shape", allowed=_SECTION_HELP["body"])
        cls, shape_keys = BODY_SHAPES[shape_name]
        allowed_keys = shape_keys + BODY_KEYS
        for key in body:
            if key not in allowed_keys:
                raise self.error(
                    _unknown(key, allowed_keys, f"[body] (shape {shape_name})"),
                    _key("body", key),
                    allowed=f"A {shape_name} has the keys "
                    + ", ".join(shape_keys)
                    + "; every shape has "
                    + ", ".join(BODY_KEYS)
                    + " (center_of_mass, angles and g optional).",
                )
        for key in (*shape_keys, "mass", "inertia"):
            if key not in body:
                raise self.error(
                    f"{key} is missing",
                    "[body]",
                    allowed=f"A {shape_name} needs " + ", ".join(shape_keys) + ", mass and inertia.",
                )
        values: dict[str, Any] = {
            k: self.expression(body[k], _key("body", k), names) for k in (*shape_keys, "mass")
        }
        values["inertia"] = self.body_list(body["inertia"], "inertia", names, nested=True)
        values["center_of_mass"] = (
            self.body_list(body["center_of_mass"], "center_of_mass", names)
            if "center_of_mass" in body
            else [0, 0, 0]
        )
        angles = body.get("angles")
        if angles is not None and angles not in ANGLES:
            raise self.error(
                f"angles = {_describe(angles)} is not an angle convention",
                "[body] angles",
                allowed="angles is one of "
                + ", ".join(map(json.dumps, ANGLES))
                + ' (default: "edge" for a disk or torus, else "cardan").',
            )
        if "g" in body:
            values["g"] = self.expression(body["g"], _key("body", "g"), names)
        elif "g" in parameters:
            values["g"] = names.parameters["g"]
        else:
            raise self.error(
                "the gravity g is not given",
                "[body] g",
                allowed='Give g in [parameters] (g = 9.81), or a value in [body] (g = 9.81 or g = "g0").',
            )
        system = self.build_body(cls, shape_keys, values, angles, name)
        numeric = {names.parameters[k]: sp.nsimplify(v) for k, v in parameters.items()}
        if system.parameters and numeric:  # the checks of rolling_body, at the [parameters] values

            def at_defaults(v: Any) -> Any:
                if isinstance(v, list):
                    return [at_defaults(e) for e in v]
                number = (
                    v if isinstance(v, sp.Basic) else sp.Integer(v) if isinstance(v, int) else sp.Float(v)
                )
                return number.xreplace(numeric)

            self.build_body(
                cls,
                shape_keys,
                {k: at_defaults(v) for k, v in values.items()},
                angles,
                name,
                " (with the values of [parameters])",
            )
        return self.finish(system, parameters, name, dict(body))

    def body_list(self, value: Any, key: str, names: Names, nested: bool = False) -> list[Any]:
        what = (
            'three principal moments ["A", "B", "C"] or a symmetric 3 x 3 list of lists '
            "(about the centre of mass, body axes)"
            if nested
            else "three coordinates [x, y, z] in the shape's axes, from its centre (a paraboloid: its vertex)"
        )
        if not isinstance(value, list) or len(value) != 3:
            got = f"a list of {len(value)}" if isinstance(value, list) else _describe(value)
            raise self.error(
                f"{key} must be a list of three, got {got}", _key("body", key), allowed=f"{key} is {what}."
            )
        out: list[Any] = []
        for i, item in enumerate(value):
            if nested and isinstance(item, list):
                if len(item) != 3 or any(isinstance(v, list) for v in item):
                    raise self.error(
                        f"{key}[{i}] must be a row of three, got {_describe(item)}",
                        f"[body] {key}[{i}]",
                        allowed=f"{key} is {what}.",
                    )
                out.append([self.expression(v, f"[body] {key}[{i}][{j}]", names) for j, v in enumerate(item)])
            else:
                out.append(self.expression(item, f"[body] {key}[{i}]", names))
        if nested and any(isinstance(v, list) for v in out) and not all(isinstance(v, list) for v in out):
            raise self.error(f"{key} mixes numbers and rows", _key("body", key), allowed=f"{key} is {what}.")
        return out

    def build_body(
        self,
        cls: type[Shape],
        shape_keys: tuple[str, ...],
        values: dict[str, Any],
        angles: str | None,
        name: str,
        note: str = "",
    ) -> System:
        try:
            shape = cls(*(values[k] for k in shape_keys))
            return rolling_body(
                shape,
                mass=values["mass"],
                inertia=values["inertia"],
                center_of_mass=values["center_of_mass"],
                g=values["g"],
                name=name,
                angles=angles,
            )
        except SystemDefinitionError as exc:
            message = str(exc)
            m = re.match(r"[A-Za-z_0-9]+(\[\d\](\[\d\])?)?", message)
            key = m.group(0) if m and m.group(0).split("[")[0] in (*shape_keys, *BODY_KEYS) else None
            message = message.removeprefix(f"{key}: ") if key else message
            raise self.error(
                message.rstrip(".") + note,
                f"[body] {key}" if key else "[body]",
                allowed=_SECTION_HELP["body"],
            ) from None

    # ------------------------------------------------------------ sections
    def read_name(self) -> str:
        if "name" not in self.data:
            return self.default_name or "system"
        name = self.data["name"]
        allowed = (
            f"name is a string of at most {MAX_SYSTEM_NAME_LENGTH} printable characters, "
            'without double quotes " or backslashes \\.'
        )
        if not isinstance(name, str):
            raise self.error(f"name must be a string, got {_describe(name)}", "name", allowed=allowed)
        if not name.strip():
            raise self.error("name is empty", "name", allowed=allowed)
        if len(name) > MAX_SYSTEM_NAME_LENGTH:
            raise self.error(
                f"name is longer than {MAX_SYSTEM_NAME_LENGTH} characters", "name", allowed=allowed
            )
        bad = next((i for i, c in enumerate(name) if not c.isprintable() or c in '"\\'), None)
        if bad is not None:
            raise self.error(
                f"name contains the character {name[bad]!r}", "name", text=name, column=bad, allowed=allowed
            )
        return name

    def read_coordinates(self) -> list[str]:
        allowed = 'coordinates = ["x", "y", "phi"]: a list of names, each a valid name.'
        if "coordinates" not in self.data:
            raise self.error("the coordinates list is missing", allowed=allowed)
        value = self.data["coordinates"]
        if not isinstance(value, list) or not value:
            raise self.error(
                f"coordinates must be a non-empty list of names, got {_describe(value)}",
                "coordinates",
                allowed=allowed,
            )
        if len(value) > MAX_COORDINATES:
            raise self.error(
                f"{len(value)} coordinates (limit {MAX_COORDINATES})",
                "coordinates",
                allowed=f"Limit: {MAX_COORDINATES} coordinates.",
            )
        seen: list[str] = []
        for k, item in enumerate(value):
            where = f"coordinates (item {k + 1})"
            try:
                check_name(item, "a coordinate")
            except ParseError as exc:
                raise exc.located(source=self.source, key=where) from None
            if item in seen:
                raise self.error(f"the coordinate {item} is listed twice", where, allowed=allowed)
            seen.append(item)
        return seen

    def read_parameters(self, coordinates: list[str]) -> dict[str, float]:
        table = self.table("parameters")
        if len(table) > MAX_PARAMETERS:
            raise self.error(
                f"{len(table)} parameters (limit {MAX_PARAMETERS})",
                "[parameters]",
                allowed=f"Limit: {MAX_PARAMETERS} parameters.",
            )
        out: dict[str, float] = {}
        for name, value in table.items():
            where = _key("parameters", name)
            try:
                check_name(name, "a parameter")
            except ParseError as exc:
                raise exc.located(source=self.source, key=where) from None
            if name in coordinates:
                raise self.error(
                    f"{name} is a coordinate; it cannot also be a parameter",
                    where,
                    allowed="Parameters are the constants of the system (masses, lengths …).",
                )
            out[name] = self.number(value, where, exact=name)
        return out

    def number(self, value: Any, where: str, exact: str | None = None) -> float:
        """A finite float; a string of constants is also kept exactly in ``self.exact[exact]``
        (unless it is a plain decimal such as ``"0.5"``)."""
        allowed = 'A number such as 1, 0.5 or -2e-3, or a string of constants such as "pi/4".'
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            raise self.error(f"expected a number, got {_describe(value)}", where, allowed=allowed)
        if isinstance(value, str):
            self.where, self.text = where, value
            try:
                number = parse_constant(value)
                symbolic = parse_expression(value, Names(time=False)) if exact is not None else None
            except ParseError as exc:
                raise exc.located(source=self.source, key=where) from None
            self.where = self.text = None
            if exact is not None and isinstance(symbolic, sp.Expr) and not symbolic.is_Float:
                self.exact[exact] = symbolic
            return number
        try:
            number = float(value)
        except OverflowError:
            raise self.error("the number is too large", where, allowed=allowed) from None
        if not math.isfinite(number):
            raise self.error(f"expected a finite number, got {value}", where, allowed=allowed)
        return number

    def expression(
        self, value: Any, where: str, names: Names, velocity_message: str | None = None
    ) -> sp.Expr:
        if isinstance(value, bool) or not isinstance(value, (str, int, float)):
            raise self.error(
                f"expected an expression in quotes, got {_describe(value)}",
                where,
                allowed='Expressions are strings, e.g. "m/2*x\'^2".',
            )
        text = value if isinstance(value, str) else repr(value)
        self.where, self.text = where, text
        try:
            expr = parse_expression(text, names, velocity_message=velocity_message)
        except ParseError as exc:
            raise exc.located(source=self.source, key=where) from None
        self.where = self.text = None
        return expr

    def read_energy(self, names: Names) -> dict[str, Any]:
        table = self.table("energy", required=True)
        for key in table:
            if key not in _ENERGY_KEYS:
                raise self.error(
                    _unknown(key, _ENERGY_KEYS, "[energy]"),
                    _key("energy", key),
                    allowed=_SECTION_HELP["energy"],
                )
        if "T" not in table:
            raise self.error("the kinetic energy T is missing", "[energy]", allowed=_SECTION_HELP["energy"])
        if "V" in table and "U" in table:
            raise self.error(
                "give the potential energy V or the force function U (U = -V), not both",
                "[energy]",
                allowed=_SECTION_HELP["energy"],
            )
        out: dict[str, Any] = {"kinetic_energy": self.expression(table["T"], _key("energy", "T"), names)}
        for key, arg in (("V", "potential_energy"), ("U", "force_function")):
            if key in table:
                message = (
                    f"{key} depends on the coordinates and t only, not on velocities; velocity-dependent "
                    "forces go in [forces]"
                )
                out[arg] = self.expression(table[key], _key("energy", key), names, message)
        return out

    def _coordinate_key(self, key: str, where: str, names: Names, allowed: str) -> None:
        """Refuse a key that is not a coordinate (a velocity written for its coordinate is named)."""
        if key not in names.coordinates:
            hint = ""
            if key.endswith("'") and key[:-1] in names.coordinates:
                hint = f" (write the coordinate, {key[:-1]}, not its velocity)"
            raise self.error(
                f"{json.dumps(key, ensure_ascii=False)} is not a coordinate{hint}", where, allowed=allowed
            )

    def read_forces(self, names: Names) -> dict[str, sp.Expr]:
        out: dict[str, sp.Expr] = {}
        for key, value in self.table("forces").items():
            where = _key("forces", key)
            self._coordinate_key(
                key,
                where,
                names,
                "[forces] keys are coordinates: "
                + ", ".join(names.coordinates)
                + "; each value is the generalized force Q along it.",
            )
            out[key] = self.expression(value, where, names)
        return out

    def read_holonomic(self, names: Names) -> dict[Any, sp.Expr]:
        """``[holonomic]``: ``coordinate = "f"``, each relation ``f(q, t) = 0`` keyed by the coordinate it fixes."""
        out: dict[Any, sp.Expr] = {}
        for key, value in self.table("holonomic").items():
            where = _key("holonomic", key)
            self._coordinate_key(key, where, names, _SECTION_HELP["holonomic"])
            out[names.coordinates[key]] = self.expression(value, where, names)
        return out

    def read_branch(self, solved: bool) -> int | None:
        """``branch = K`` of ``[constraints]``: which solution of implicit constraints nonlinear
        in the velocities gives the dependent velocities (checked against them by System)."""
        branch = self.table("constraints").get("branch")
        if branch is None:
            return None
        where = _key("constraints", "branch")
        if solved:
            raise self.error(
                "branch chooses a solution of implicit constraints; solved ones are one already",
                where,
                allowed="Remove branch, or give the constraints implicitly: implicit = [\"x'^2 + y'^2 - v^2\"], "
                'dependent = ["x"], branch = 0.',
            )
        if isinstance(branch, bool) or not isinstance(branch, int) or branch < 0:
            raise self.error(
                f"branch must be a whole number 0, 1, ..., got {_describe(branch)}",
                where,
                allowed=_SECTION_HELP["constraints"],
            )
        return branch

    def read_constraints(self, names: Names) -> tuple[Any, list[str] | None]:
        table = {k: v for k, v in self.table("constraints").items() if k != "branch"}
        implicit = [k for k in table if k in _IMPLICIT_KEYS]
        solved = [k for k in table if k not in _IMPLICIT_KEYS]
        if implicit and solved:
            raise self.error(
                'mix of solved constraints ("x\'" = ...) and implicit = [...]',
                _key("constraints", solved[0]),
                allowed=_SECTION_HELP["constraints"],
            )
        if implicit:
            return self.read_implicit(table, names)
        out: dict[str, sp.Expr] = {}
        for key in solved:
            where = _key("constraints", key)
            value = table[key]
            q = key[:-1] if key.endswith("'") else None
            if q is None or q not in names.coordinates:
                if key in names.coordinates:
                    reason = f'{key} is a coordinate; a solved constraint gives its velocity: "{key}\'" = ...'
                else:
                    reason = _unknown(
                        key, [f"{c}'" for c in names.coordinates] + list(_IMPLICIT_KEYS), "[constraints]"
                    )
                raise self.error(reason, where, allowed=_SECTION_HELP["constraints"])
            out[key] = self.expression(value, where, names)
        return out, None

    def read_implicit(self, table: dict[str, Any], names: Names) -> tuple[list[sp.Expr], list[str]]:
        help_ = _SECTION_HELP["constraints"]
        exprs = table.get("implicit")
        if not isinstance(exprs, list) or not exprs:
            raise self.error(
                f"implicit must be a non-empty list of expressions, got {_describe(exprs)}",
                _key("constraints", "implicit"),
                allowed=help_,
            )
        dependent = table.get("dependent")
        if dependent is None:
            raise self.error(
                f"implicit constraints need dependent = [...] naming {len(exprs)} dependent coordinate(s)",
                _key("constraints", "dependent"),
                allowed=help_,
            )
        if not isinstance(dependent, list):
            raise self.error(
                f"dependent must be a list of coordinate names, got {_describe(dependent)}",
                _key("constraints", "dependent"),
                allowed=help_,
            )
        for k, d in enumerate(dependent):
            if not isinstance(d, str) or d not in names.coordinates:
                raise self.error(
                    f"{_describe(d)} is not a coordinate",
                    f"[constraints] dependent (item {k + 1})",
                    allowed="The coordinates are " + ", ".join(names.coordinates) + ".",
                )
            if d in dependent[:k]:
                raise self.error(
                    f"the coordinate {d} is listed twice",
                    f"[constraints] dependent (item {k + 1})",
                    allowed=help_,
                )
        out = [
            self.expression(e, f"[constraints] implicit (item {k + 1})", names) for k, e in enumerate(exprs)
        ]
        return out, list(dependent)

    def build(
        self, names: Names, constraints: Any, dependent: list[str] | None, name: str, kwargs: dict[str, Any]
    ) -> System:
        coordinates = list(names.coordinates.values())
        if isinstance(constraints, dict):
            constraints = {names.coordinates[k[:-1]].diff(TIME): v for k, v in constraints.items()}
        elif dependent is not None and len(dependent) == len(constraints):
            self.check_dependent_block(names, constraints, dependent)
        try:
            return System(
                coordinates,
                constraints=constraints,
                dependent=None if dependent is None else [names.coordinates[d] for d in dependent],
                name=name,
                **kwargs,
            )
        except SystemDefinitionError as exc:
            raise self.system_error(str(exc), constraints) from None
        except RecursionError:
            raise self.error("the expressions are nested too deeply for SymPy") from None
        except Exception as exc:  # the boundary between user files and SymPy
            # Not expected from validated input; reported as a file error, never as a traceback
            # (the original exception stays attached as __cause__).
            raise self.error(f"chaplygin could not build the system ({type(exc).__name__}: {exc})") from exc

    def system_error(self, message: str, constraints: Any) -> SystemFileError:
        """System's refusal as a file error; those of nonlinear constraints (a branch, no
        solution, a singular block, with [holonomic]) name the key, with its text."""
        m = _NONLINEAR_ERROR.match(message)
        if m is None:
            return self.error(f"invalid system: {message}")
        section = self.table("constraints")
        head, item, reason = m.group(1), m.group(2), m.group(3)
        if head == "holonomic":
            return self.error(reason, "[holonomic]", allowed=_SECTION_HELP["holonomic"])
        if head == "branch":
            reason, _, solutions = reason.partition("; branch=0")
            return self.error(
                reason,
                _key("constraints", "branch"),
                text=f"branch = {section.get('branch')}",
                allowed=("The solutions: branch=0" + solutions) if solutions else None,
            )
        k = int(item) if item is not None else 0
        if isinstance(constraints, dict):
            key = list(section)[k] if item is not None and head == "constraints" else None
            where, text = (_key("constraints", key), str(section[key])) if key else ("[constraints]", None)
        else:
            one = item is not None and head == "constraints"
            where = f"[constraints] implicit (item {k + 1})" if one else "[constraints] implicit"
            text = str(section["implicit"][k]) if one else None
        if "cannot solve" in reason:
            reason = reason.split("; ")[0]
            dependent = section.get("dependent")
            names = [str(d) for d in dependent] if isinstance(dependent, list) and dependent else ["x"]
            keys = ", ".join(f'"{d}\'" = "..."' for d in names)
            allowed = f"Give them solved instead, {keys} (the branch you mean)."
        else:
            allowed = _SECTION_HELP["constraints"]
        return self.error(reason, where, text=text, allowed=allowed)

    def check_dependent_block(self, names: Names, exprs: list[sp.Expr], dependent: list[str]) -> None:
        """Refuse a ``dependent`` choice whose block of A is singular, suggesting one that works.

        System does this check too, but it looks for a suggestion among all choices of
        ``g`` of ``n`` coordinates, which takes very long for large systems; here a
        column-pivoted QR factorization of A at random points finds one directly.  Only
        used when there are many choices.
        """
        n, g = len(names.coordinates), len(exprs)
        if math.comb(n, g) <= _FEW_CHOICES:
            return
        import numpy as np
        from scipy.linalg import qr

        velocities = [q.diff(TIME) for q in names.coordinates.values()]
        try:
            coefficients = [[sp.diff(e, v) for v in velocities] for e in exprs]
        except (TypeError, ValueError, AttributeError, NotImplementedError):
            return  # System reports what is wrong with the expressions
        free = sorted(
            {s for row in coefficients for c in row for s in c.free_symbols}
            | set(names.coordinates.values()),
            key=str,
        )
        rng = np.random.default_rng(20000843)
        dep = [list(names.coordinates).index(d) for d in dependent]
        pivots: list[int] | None = None
        for _ in range(3):
            values = {s: sp.Float(v) for s, v in zip(free, rng.uniform(0.3, 1.3, size=len(free)))}
            try:
                a = np.array(
                    [[complex(c.xreplace(values).evalf()) for c in row] for row in coefficients],
                    dtype=complex,
                )
            except (TypeError, ValueError):  # a pole at this point: try another
                continue
            if not np.all(np.isfinite(a)):
                continue
            s_dep = np.linalg.svd(a[:, dep], compute_uv=False)
            if s_dep[-1] > 1e-10 * max(1.0, s_dep[0]):
                return
            _, r, perm = qr(a, pivoting=True)
            if abs(r[g - 1, g - 1]) > 1e-10 * max(1.0, abs(r[0, 0])):
                pivots = sorted(int(i) for i in perm[:g])
        if pivots is None:
            return  # undecided (or redundant constraints): System's own checks decide
        coords = list(names.coordinates)
        raise self.error(
            f"dependent = {json.dumps(dependent)}: the constraints cannot be solved for these velocities "
            "(their block of the constraint matrix is singular)",
            "[constraints] dependent",
            allowed=f"Choose other dependent coordinates, e.g. dependent = {json.dumps([coords[i] for i in pivots])}.",
        )

    def check_initial_real(
        self, system: System, initial: dict[str, float], parameters: dict[str, float]
    ) -> None:
        """Refuse an initial state where constraints nonlinear in the velocities give no real
        dependent velocity (a root of a negative number: no solution, or the other branch)."""
        v = system._vars
        values: dict[sp.Symbol, Any] = {TIME: 0.0, **{p: parameters[p.name] for p in system.parameters}}
        for i, q in enumerate(system.coordinates):
            values[v.x[i]] = initial[q.func.__name__]
        for i in system._ind:
            values[v.xd[i]] = initial[system.coordinates[i].func.__name__ + "'"]
        given = self.table("constraints")
        for k, phi in enumerate(system._velocity_substitution.values()):
            try:
                value = complex(phi.xreplace({s: sp.Float(x) for s, x in values.items()}).evalf())
            except (TypeError, ValueError, ZeroDivisionError):
                continue  # (a pole: the simulation says so)
            if (
                math.isfinite(value.real)
                and math.isfinite(value.imag)
                and abs(value.imag) <= 1e-12 * max(1.0, abs(value.real))
            ):
                continue
            name = system.coordinates[system._dep[k]].func.__name__
            state = ", ".join(f"{key} = {x:g}" for key, x in initial.items() if x)
            key = f'"{name}\'"' if f"{name}'" in given else "implicit"
            raise self.error(
                f"no real value of {name}' at the initial state ({state or 'all zero'}): "
                f"{name}' = {file_syntax(system.to_user(phi))} = {value.real:g}{value.imag:+g}i",
                _key("constraints", key.strip('"')),
                allowed="The initial state must satisfy the constraints: choose [initial] values where "
                "the expression is real"
                + (", or another branch." if "branch" in given or key == "implicit" else "."),
            )

    def read_initial(self, system: System) -> dict[str, float]:
        table = self.table("initial")
        coords = [q.func.__name__ for q in system.coordinates]
        independent = [q.func.__name__ + "'" for q in system.independent]
        dependent = [q.func.__name__ + "'" for q in system.dependent]
        allowed = (
            "[initial] gives coordinates ("
            + ", ".join(coords)
            + ") and independent velocities ("
            + ", ".join(independent)
            + "); missing ones are 0."
        )
        for key in table:
            where = _key("initial", key)
            if key in dependent:
                raise self.error(
                    f"{key} is the velocity of a dependent coordinate: it follows from the constraints",
                    where,
                    allowed=allowed,
                )
            if key not in coords and key not in independent:
                raise self.error(_unknown(key, coords + independent, "[initial]"), where, allowed=allowed)
        return {
            key: (self.number(table[key], _key("initial", key), exact=key) if key in table else 0.0)
            for key in coords + independent
        }


_SECTION_HELP = {
    "name": 'name = "A descriptive name".',
    "coordinates": 'coordinates = ["x", "y", "phi"].',
    "parameters": "[parameters] gives every parameter a default value: m = 1.0.",
    "energy": "[energy] has T (kinetic energy, required) and either V (potential energy) or U "
    "(force function, U = -V).",
    "forces": '[forces] gives generalized forces by coordinate: phi = "-c*phi\'".',
    "constraints": '[constraints] has either solved constraints, "y\'" = "tan(phi)*x\'" (one per dependent '
    'velocity), or implicit = ["sin(phi)*x\' - cos(phi)*y\'"] (each = 0) with dependent = ["y"]; '
    "for implicit constraints nonlinear in the velocities with several solutions, branch = K "
    "picks one.",
    "holonomic": "[holonomic] gives relations f(q, t) = 0 between the coordinates, each keyed by the "
    'coordinate it fixes (not a dependent coordinate of [constraints]): z = "z - a*sin(x)".',
    "initial": '[initial] gives coordinates and independent velocities: theta = 1.0, "theta\'" = 0.4.',
    "body": "[body] has shape = "
    + " | ".join(map(json.dumps, BODY_SHAPES))
    + " with its keys ("
    + "; ".join(f"{k}: {', '.join(v[1])}" for k, v in BODY_SHAPES.items())
    + "), mass, inertia = [A, B, C] or a 3 x 3 list, and optionally center_of_mass = [x, y, z], "
    'angles = "cardan" | "edge" | "euler" and g (default: the parameter g).',
}


def _describe(value: Any) -> str:
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return "a list"
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if value is None:
        return "nothing"
    return f"{type(value).__name__} {value}"


# ---------------------------------------------------------------------------- writing
_PRINTED_FUNCTIONS: dict[type, str] = {
    sp.sin: "sin",
    sp.cos: "cos",
    sp.tan: "tan",
    sp.asin: "asin",
    sp.acos: "acos",
    sp.atan: "atan",
    sp.atan2: "atan2",
    sp.sinh: "sinh",
    sp.cosh: "cosh",
    sp.tanh: "tanh",
    sp.exp: "exp",
    sp.log: "log",
    sp.Abs: "abs",
    sp.sign: "sign",
}


class _FilePrinter(StrPrinter):
    """Prints SymPy expressions in the file syntax (``x'`` velocities, ``^`` powers)."""

    def _print_Derivative(self, expr: sp.Derivative) -> str:
        return self._print(expr.expr) + "'"

    def _print_Function(self, expr: sp.Expr) -> str:
        if isinstance(expr, AppliedUndef):
            return expr.func.__name__
        name = _PRINTED_FUNCTIONS[type(expr)]
        return name + "(" + self.stringify(expr.args, ", ") + ")"

    def _print_Abs(self, expr: sp.Expr) -> str:
        return "abs(" + self._print(expr.args[0]) + ")"

    def _print_Pow(self, expr: sp.Pow, rational: bool = False) -> str:
        return super()._print_Pow(expr, rational).replace("**", "^")


class _Writer:
    def __init__(self, system: System) -> None:
        self.system = system
        self.coordinates = {q.func.__name__: q for q in system.coordinates}
        self.printer = _FilePrinter({"full_prec": True})

    def fail(self, reason: str, what: str) -> SystemFileError:
        return SystemFileError(f"cannot write {what}: {reason}", source=self.system.name)

    def check(self, expr: Any, what: str) -> None:
        """Refuse anything the file syntax cannot express."""
        coords = set(self.system.coordinates)
        stack = [expr]
        while stack:
            node = stack.pop()
            if isinstance(node, (sp.Add, sp.Mul, sp.Pow)) or type(node) in _PRINTED_FUNCTIONS:
                stack.extend(node.args)
                continue
            # (== TIME, not `is`: a user's t made after SymPy's cache let chaplygin's go is equal, not the same)
            if isinstance(node, (sp.Rational, sp.Float)) or node == TIME:
                continue
            if node in (sp.pi, sp.E) or node in coords:
                continue
            if isinstance(node, sp.Derivative):
                if node.expr in coords and node.variables == (TIME,):
                    continue
                raise self.fail(f"{file_syntax(node)} is not a velocity of a coordinate", what)
            if isinstance(node, sp.Symbol):
                if node.name in RESERVED or node.name in self.coordinates:
                    raise self.fail(
                        f"the parameter {node.name} has the name of a coordinate, of time or of a constant",
                        what,
                    )
                try:
                    check_name(node.name, "the parameter name")
                except ParseError as exc:
                    raise self.fail(exc.reason, what) from None
                continue
            raise self.fail(
                f"{file_syntax(node)} ({type(node).__name__}) has no equivalent in the file syntax", what
            )

    def expression(self, expr: Any, what: str, names: Names) -> str:
        expr = sp.S.Zero + expr
        self.check(expr, what)
        text = self.printer.doprint(expr)
        try:
            parse_expression(text, names)
        except ParseError as exc:
            raise self.fail(f"the printed expression is refused by the parser: {exc.reason}", what) from None
        return text


def _toml_string(text: str) -> str:
    return json.dumps(text, ensure_ascii=False)


def _toml_key(key: str) -> str:
    return key if _BARE_KEY.match(key) else _toml_string(key)


def _toml_number(value: float, what: str) -> str:
    number = float(value)
    if not math.isfinite(number):
        raise SystemFileError(f"cannot write {what}: {number} is not a finite number")
    return repr(number)


def _toml_value(value: Any) -> str:
    """A ``[body]`` value (string, number or list of them) in TOML."""
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, str):
        return _toml_string(value)
    return repr(value) if isinstance(value, int) else _toml_number(value, "a [body] value")


def _key_name(system: System, key: Any) -> str:
    """``"x"``/``"x'"`` for a coordinate or velocity given as a name or dynamicsymbol."""
    if isinstance(key, str):
        return key.strip()
    if isinstance(key, sp.Derivative) and key.variables == (TIME,) and isinstance(key.expr, AppliedUndef):
        return key.expr.func.__name__ + "'"
    if isinstance(key, AppliedUndef):
        return key.func.__name__
    if isinstance(key, sp.Symbol):
        return key.name
    return str(key)


def _system_tables(w: _Writer, system: System, names: Names) -> list[str]:
    """``[energy]``, ``[forces]`` and ``[constraints]`` of :func:`dumps`."""
    out = [
        "",
        "[energy]",
        f"T = {_toml_string(w.expression(system.kinetic_energy, 'the kinetic energy T', names))}",
    ]
    if system.potential_energy is not None:
        out.append(
            f"V = {_toml_string(w.expression(system.potential_energy, 'the potential energy V', names))}"
        )
    elif system.force_function != 0:
        out.append(f"U = {_toml_string(w.expression(system.force_function, 'the force function U', names))}")

    if system.forces:
        out += ["", "[forces]"]
        for q, value in system.forces.items():
            qn = q.func.__name__
            out.append(f"{_toml_key(qn)} = {_toml_string(w.expression(value, f'the forces ({qn})', names))}")

    velocity_g = system.velocity_g
    if velocity_g:
        out += ["", "[constraints]"]
        if system.constraint_form == "B":
            solved = system.constraints
            if system.holonomic:  # (as given: the holonomic coordinates are not independent there)
                dep = [system.coordinates[i].diff(TIME) for i in system._dep[:velocity_g]]
                solved = dict(zip(dep, system._given_constraints))
            for vel, value in solved.items():
                key = vel.expr.func.__name__ + "'"
                out.append(
                    f"{_toml_string(key)} = {_toml_string(w.expression(value, f'the constraint {key}', names))}"
                )
        else:
            velocity = system.implicit_constraints[:velocity_g]
            exprs = [w.expression(e, "the implicit constraints", names) for e in velocity]
            out.append("implicit = [")
            out += [f"    {_toml_string(e)}," for e in exprs]
            out.append("]")
            out.append(
                "dependent = ["
                + ", ".join(_toml_string(q.func.__name__) for q in system.dependent[:velocity_g])
                + "]"
            )
            if system._branch is not None:
                out.append(f"branch = {system._branch}")
    if system.holonomic:
        out += ["", "[holonomic]"]
        for q, f in system.holonomic.items():
            qn = q.func.__name__
            text = w.expression(f, f"the holonomic constraint ({qn})", names)
            out.append(f"{_toml_key(qn)} = {_toml_string(text)}")
    return out


def _body_table(w: _Writer, system: System, names: Names) -> dict[str, Any] | None:
    """The ``[body]`` table of a system built by ``rolling_body`` from a shape of :data:`BODY_SHAPES`.

    Every value is written as an expression, so that reading the file back builds the same body
    with the same parameters; ``None`` for any other system (written by its energy and constraints).
    """
    if not isinstance(system, RollingBody):
        return None
    found = [(n, keys) for n, (cls, keys) in BODY_SHAPES.items() if type(system.shape) is cls]
    if not found:  # Revolution, SupportFunction: no [body] shape
        return None
    shape, keys = found[0]

    def text(value: Any, what: str) -> str | int:
        if isinstance(value, sp.Integer):
            return int(value)
        return w.expression(value, f"the body's {what}", names)

    tensor = system.inertia
    diagonal = all(tensor[i, j] == 0 for i in range(3) for j in range(3) if i != j)
    inertia = (
        [text(tensor[k, k], "inertia") for k in range(3)]
        if diagonal
        else [[text(tensor[i, j], "inertia") for j in range(3)] for i in range(3)]
    )
    return {
        "shape": shape,
        **{k: text(vars(system.shape)[k], k) for k in keys},
        "mass": text(system.mass, "mass"),
        "inertia": inertia,
        "center_of_mass": [text(c, "center_of_mass") for c in system.center_of_mass],
        "angles": system.angles,
        "g": text(system.gravity, "g"),
    }


def dumps(
    system: System,
    parameters: Mapping[Any, float] | None = None,
    initial: Mapping[Any, float] | None = None,
) -> str:
    """Write ``system`` as a system file, so that :func:`loads` gives an equivalent system.

    A body built by :func:`chaplygin.bodies.rolling_body` from a shape of :data:`BODY_SHAPES`
    is written as its ``[body]`` table (shape, mass, inertia, centre of mass, angles, g);
    any other system by its coordinates, energy, forces and constraints.

    Parameters
    ----------
    system : System
    parameters : mapping, optional
        Default values by parameter (name or symbol).  Parameters without a
        value are written as ``1.0`` with a comment saying so.
    initial : mapping, optional
        Initial values of coordinates and independent velocities (names such as
        ``"x"``, ``"x'"`` or dynamicsymbols); velocities of dependent
        coordinates are left out (they follow from the constraints).  Without
        it, no ``[initial]`` table is written.

    Raises
    ------
    SystemFileError
        If a name or an expression of the system cannot be written in the file
        syntax (e.g. a ``Piecewise``, a parameter called ``E``), or a key of
        ``parameters``/``initial`` is unknown.
    """
    w = _Writer(system)
    coords = [q.func.__name__ for q in system.coordinates]
    for q in coords:
        try:
            check_name(q, "the coordinate name")
        except ParseError as exc:
            raise w.fail(exc.reason, "the coordinates") from None
    name = system.name
    bad = next((c for c in name if not c.isprintable() or c in '"\\'), None)
    if bad is not None or len(name) > MAX_SYSTEM_NAME_LENGTH or not name.strip():
        raise w.fail(
            f'the name {name!r} must be at most {MAX_SYSTEM_NAME_LENGTH} printable characters without " or \\',
            "the name",
        )
    pnames = [p.name for p in system.parameters]
    names = Names.build(pnames, coords)
    values: dict[str, float] = {}
    for key, value in (parameters or {}).items():
        k = key.name if isinstance(key, sp.Symbol) else str(key)
        if k not in pnames:
            raise w.fail(
                f"{k} is not a parameter of the system (its parameters are {', '.join(pnames) or 'none'})",
                "[parameters]",
            )
        values[k] = float(value)

    out = [f"# chaplygin system file: {name}", f"name = {_toml_string(name)}"]
    body = _body_table(w, system, names)
    if body is None:
        out.append("coordinates = [" + ", ".join(_toml_string(q) for q in coords) + "]")
    else:  # built by rolling_body from a shape of BODY_SHAPES: its [body] table, read back by rolling_body
        out += ["", "[body]", *(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in body.items())]
    if pnames or body is not None:  # a [body] file always has [parameters] (SystemFile.dumps)
        out += ["", "[parameters]"]
        for p in pnames:
            if p in values:
                out.append(f"{_toml_key(p)} = {_toml_number(values[p], f'the parameter {p}')}")
            else:
                out.append(f"{_toml_key(p)} = 1.0  # no value was given")

    if body is None:
        out += _system_tables(w, system, names)

    if initial is not None:
        independent = [q.func.__name__ + "'" for q in system.independent]
        dependent = [q.func.__name__ + "'" for q in system.dependent]
        given: dict[str, float] = {}
        for key, value in initial.items():
            k = _key_name(system, key)
            if k in dependent:
                continue
            if k not in coords and k not in independent:
                raise w.fail(
                    f"{k} is neither a coordinate nor an independent velocity "
                    f"({', '.join(coords + independent)})",
                    "[initial]",
                )
            given[k] = float(value)
        out += ["", "[initial]"]
        out += [
            f"{_toml_key(k)} = {_toml_number(given[k], f'the initial value of {k}')}"
            for k in coords + independent
            if k in given
        ]
    return "\n".join(out) + "\n"
