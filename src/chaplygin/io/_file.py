"""A loaded system file, and :func:`load`: the part of :mod:`chaplygin.io.files` a warm run needs.

Reading a file builds its :class:`~chaplygin.System` with SymPy (a quarter of a second of
imports before any work).  A file whose bytes were read, validated and run before needs none of
it to be run again: with a run plan (:mod:`chaplygin.numeric._plan`) the derivation cache keeps
a summary of the file it was made from (keyed by the file's bytes, its name's stem and the
library version; verified on read): its name, ``[parameters]``, ``[initial]``, defaulted keys
and ``[body]`` table.  :func:`load` of the same bytes returns a :class:`SystemFile` from the
summary, whose :attr:`~SystemFile.system` (and :attr:`~SystemFile.exact`) is built on first
use, and :func:`chaplygin.simulate` of it runs the plan without ever building it.  Bytes
without a summary are read (and refused) as always.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from chaplygin.numeric import _modelcache, cache
from chaplygin.numeric._plan import SUMMARY, LoadedFile, summary_key

if TYPE_CHECKING:
    import sympy as sp

    from chaplygin.core.system import System

__all__ = ["MAX_FILE_SIZE", "SystemFile", "load"]

#: Largest file, in characters (and bytes for :func:`load`).
MAX_FILE_SIZE = 1_000_000


@dataclass
class SystemFile(LoadedFile):
    """A system read from a file, with its default parameter values and initial state.

    Attributes
    ----------
    system : System
        The mechanical system; its parameters are real SymPy symbols.
    parameters : dict of str → float
        The ``[parameters]`` defaults, by name (exactly the system's parameters).
    initial : dict of str → float
        The initial state: every coordinate, then the velocities of the
        independent coordinates (``"theta'"``), in that order; values missing
        from ``[initial]`` are 0.
    name : str
        The system's name (``name = ...``, else the file's stem, else ``"system"``).
    source : str
        The path it was read from, or ``"<string>"``.
    defaulted : tuple of str
        The keys of :attr:`initial` that ``[initial]`` did not give (set to 0).
    body : dict or None
        The ``[body]`` table as read (TOML values), for a system built from a body.
    exact : dict of str → sympy.Expr
        The values of :attr:`parameters` and :attr:`initial` given as strings of constants,
        exactly as SymPy numbers (``"pi/6"`` → ``pi/6``), by key; for display: the
        computations use the floats.
    definition : bytes or None
        The file's bytes (:func:`load`), which its run plans are keyed by; None for a file
        read from a string.
    """

    system: System
    parameters: dict[str, float]
    initial: dict[str, float]
    name: str
    source: str
    defaulted: tuple[str, ...] = ()
    body: dict[str, Any] | None = None
    exact: dict[str, sp.Expr] = field(default_factory=dict)
    definition: bytes | None = field(default=None, repr=False, compare=False)

    def __getattr__(self, name: str) -> Any:
        # only for attributes not set: the system and exact values of a file loaded from its
        # summary (load()), built from its bytes on first use
        if name not in ("system", "exact") or self.definition is None or "name" not in self.__dict__:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        from chaplygin.io.files import _loads

        read = _loads(self.definition.decode("utf-8"), self.source, Path(self.source).stem)
        self.system, self.exact = read.system, read.exact
        return getattr(self, name)

    def _repr_html_(self) -> str:
        """The system (as :class:`System` shows itself), then the file's parameters and initial
        state, symbolic values as written (``pi/6``)."""
        import sympy as sp

        from chaplygin import _html

        def values(table: dict[str, float]) -> str:
            rows = [
                (
                    _html.escape(k),
                    _html.math(sp.latex(self.exact[k])) if k in self.exact else _html.escape(f"{v:g}"),
                )
                for k, v in table.items()
            ]
            return _html.table(rows, ["name", "value"]) if rows else "<p>none</p>"

        return (
            self.system._repr_html_()
            + _html.heading("parameters")
            + values(self.parameters)
            + _html.heading("initial state")
            + values(self.initial)
        )

    def dumps(self) -> str:
        """This file written back as TOML: its ``[body]`` table if it has one, else as :func:`dumps`."""
        from chaplygin.io.files import _toml_key, _toml_number, _toml_string, _toml_value, dumps

        if self.body is None:
            return dumps(self.system, self.parameters, self.initial)
        out = [f"# chaplygin system file: {self.name}", f"name = {_toml_string(self.name)}", "", "[body]"]
        out += [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in self.body.items()]
        out += ["", "[parameters]"]
        out += [
            f"{_toml_key(k)} = {_toml_number(v, f'the parameter {k}')}" for k, v in self.parameters.items()
        ]
        out += ["", "[initial]"]
        out += [
            f"{_toml_key(k)} = {_toml_number(v, f'the initial value of {k}')}"
            for k, v in self.initial.items()
        ]
        return "\n".join(out) + "\n"


def load(path: str | os.PathLike[str]) -> SystemFile:
    """Read a system file.

    Bytes read, validated and run before (a run plan made from them keeps a summary of the file:
    :mod:`chaplygin.io._file`) are not read again: the file's :attr:`~SystemFile.system` is built
    on first use.

    Raises
    ------
    SystemFileError
        If the file cannot be read, is not valid TOML, or describes an invalid system.
    """
    source = os.fspath(path)
    try:
        with open(path, "rb") as fh:
            raw = fh.read(MAX_FILE_SIZE + 1)
    except OSError as exc:
        raise _error(f"cannot read the file: {exc.strerror or exc}", source=source) from None
    return from_bytes(raw, source)


def from_bytes(raw: bytes, source: str) -> SystemFile:
    """The system file whose bytes are ``raw``, read from ``source`` (:func:`load`, for a caller
    that read the bytes itself: the command line keys its caches by them, and a file changed
    since must not be read a second time)."""
    if len(raw) > MAX_FILE_SIZE:
        raise _error(
            f"the file is larger than {MAX_FILE_SIZE} bytes",
            source=source,
            allowed=f"Limit: {MAX_FILE_SIZE} bytes per system file.",
        )
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise _error(
            f"the file is not UTF-8 text (byte {exc.start})",
            source=source,
            allowed="System files are TOML, encoded in UTF-8.",
        ) from None
    stem = Path(source).stem
    if _modelcache.enabled():  # ($CHAPLYGIN_MODEL_CACHE=off: every process reads anew)
        summary = _from_summary(cache.load(summary_key(raw, stem)), source, raw)
        if summary is not None:
            return summary
    from chaplygin.io.files import _loads

    loaded = _loads(text, source, stem)
    loaded.definition = raw
    return loaded


def _from_summary(value: Any, source: str, raw: bytes) -> SystemFile | None:
    """The :class:`SystemFile` of a stored summary (its system built on first use), or None."""
    if not isinstance(value, dict) or set(value) != set(SUMMARY):
        return None
    parameters, initial, name, defaulted, body = (value[k] for k in SUMMARY)
    numbers = all(
        isinstance(table, dict) and all(isinstance(v, (int, float)) for v in table.values())
        for table in (parameters, initial)
    )
    if not numbers or not isinstance(name, str) or not isinstance(defaulted, list):
        return None
    if body is not None and not isinstance(body, dict):
        return None
    out = SystemFile.__new__(SystemFile)
    out.__dict__.update(
        parameters={k: float(v) for k, v in parameters.items()},
        initial={k: float(v) for k, v in initial.items()},
        name=name,
        source=source,
        defaulted=tuple(defaulted),
        body=body,
        definition=raw,
    )
    return out


def _error(reason: str, **fields: Any) -> Exception:
    from chaplygin.io.parser import SystemFileError

    return SystemFileError(reason, **fields)
