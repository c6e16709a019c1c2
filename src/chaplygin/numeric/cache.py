"""The derivation cache: finished derivations on disk, keyed by what they were derived from.

A derivation of a large system can take minutes; asking for it again should
not.  An entry is one JSON document in ``cache_dir()/derivations`` (see
:func:`cache_dir`; ``$CHAPLYGIN_CACHE`` moves it):

* its **key** is the SHA-256 of everything the result depends on — the
  system's definition (a system file's bytes, or the example's name), the
  request (model, form, options), the library version with a digest of
  its source files, and :data:`FORMAT` — so a changed file, request or library never finds an old
  entry;
* it is **written atomically** (a temporary file in the same folder, then a
  rename), so a reader never sees half an entry;
* it is **verified on read**: the first line holds the SHA-256 of the rest,
  and the document repeats its key and version.  An entry that fails any check
  (truncated, edited, unreadable, from another version) is deleted and
  reported as a miss, so the caller derives anew and overwrites it.  Nothing
  in an entry is ever evaluated but generated source that the library itself
  stored (the run plans of :mod:`chaplygin.numeric._plan`, the compiled models of
  :mod:`chaplygin.numeric._modelcache`), once these checks passed; the rest is data.

SymPy expressions are stored as data too: :func:`expressions_to_data` writes
them as a table of nodes (a symbol, a number, or one of a fixed set of
operations and functions applied to earlier nodes), and
:func:`expressions_from_data` rebuilds exactly the same expressions from it
(unevaluated, so in time proportional to their size, less than printing them
costs), so one stored derivation can be printed in any format.
"""

from __future__ import annotations

import atexit
import functools
import hashlib
import importlib.util
import json
import os
import shutil
import sys
import tempfile
import threading
import warnings
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

from chaplygin.errors import ChaplyginError, ChaplyginWarning

__all__ = [
    "FORMAT",
    "cache_dir",
    "clear",
    "directory",
    "expressions_from_data",
    "expressions_to_data",
    "import_source",
    "key",
    "load",
    "store",
]

#: bumped whenever the shape of cached documents changes
FORMAT = 2


@functools.cache
def _version() -> str:
    """The library version and a digest of its source files (every layer's, not only this folder's).

    The digest makes an edited (e.g. editable, in-development) installation a
    different version, so no entry derived by other code is ever used.
    """
    from chaplygin._version import __version__

    package = Path(__file__).resolve().parent.parent
    h = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        h.update(path.relative_to(package).as_posix().encode() + b"\0" + path.read_bytes())
    return f"{__version__}+{h.hexdigest()[:16]}"


def cache_dir() -> Path:
    """chaplygin's cache (generated code, derivations): ``$CHAPLYGIN_CACHE``, else the
    user's cache directory (``$XDG_CACHE_HOME/chaplygin`` or ``~/.cache/chaplygin``).

    A cache that cannot be written (a read-only folder, a path under a file) is replaced, for
    this process, by a private temporary folder deleted at exit, with one
    :class:`~chaplygin.errors.ChaplyginWarning` that names the folder and ``CHAPLYGIN_CACHE``:
    generated code must be written somewhere before it can be imported or loaded.
    """
    given = os.environ.get("CHAPLYGIN_CACHE")
    root = given or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(Path.home(), ".cache"), "chaplygin"
    )
    with _CHECK_LOCK:
        if root not in _USABLE:
            _USABLE[root] = _usable(Path(root), given is not None)
        return _USABLE[root]


#: the folder used for each cache asked for (itself, or a private temporary fallback)
_USABLE: dict[str, Path] = {}
_CHECK_LOCK = threading.Lock()


def _usable(root: Path, from_variable: bool) -> Path:
    """``root`` if a file can be created in it (made if missing), else a private temporary folder."""
    try:
        root.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=root, prefix=".probe-", suffix=".tmp")
        os.close(fd)
        os.unlink(probe)
        return root
    except OSError as exc:
        why = exc.strerror or str(exc)
    fallback = Path(tempfile.mkdtemp(prefix="chaplygin-cache-"))
    atexit.register(shutil.rmtree, fallback, True)
    named = f"CHAPLYGIN_CACHE={root}" if from_variable else f"the cache folder {root}"
    warnings.warn(
        f"{named} cannot be written ({why}); this process uses a private temporary cache, "
        f"{fallback}, deleted at exit. Set CHAPLYGIN_CACHE to a writable folder to keep "
        "compiled code and derivations between runs.",
        ChaplyginWarning,
        stacklevel=3,
    )
    return fallback


def directory() -> Path:
    """The folder of cached derivations."""
    return cache_dir() / "derivations"


def key(*parts: str | bytes) -> str:
    """The SHA-256 (hex) of ``parts`` together with the library version and :data:`FORMAT`."""
    h = hashlib.sha256(f"chaplygin {_version()} cache format {FORMAT}".encode())
    for part in parts:
        data = part if isinstance(part, bytes) else part.encode("utf-8")
        h.update(len(data).to_bytes(8, "little"))  # unambiguous concatenation
        h.update(data)
    return h.hexdigest()


def _path(k: str) -> Path:
    return directory() / f"{k}.json"


def load(k: str) -> Any | None:
    """The value stored under key ``k``, or None (a miss: absent, corrupt or stale)."""
    path = _path(k)
    try:
        raw = path.read_bytes()
    except OSError:
        return None
    digest, sep, body = raw.partition(b"\n")
    try:
        ok = sep and hashlib.sha256(body).hexdigest().encode() == digest
        doc = json.loads(body) if ok else None
        ok = isinstance(doc, dict) and doc.get("key") == k and doc.get("version") == _version()
    except ValueError:  # not JSON (or not UTF-8)
        ok = False
    if not ok:
        _discard(path)
        return None
    return doc["value"]  # type: ignore[index]


def store(k: str, value: Any) -> Path | None:
    """Store the JSON-serialisable ``value`` under key ``k`` (atomically); None if it cannot.

    A cache that cannot be written (read-only or full disk) is not an error:
    the derivation was done and is returned to the user all the same.
    """
    body = json.dumps({"key": k, "version": _version(), "value": value}, ensure_ascii=False).encode()
    raw = hashlib.sha256(body).hexdigest().encode() + b"\n" + body
    path = _path(k)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    except OSError:
        return None
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(raw)
        os.replace(tmp, path)
    except OSError:
        _discard(Path(tmp))
        return None
    return path


def clear() -> int:
    """Delete every cached derivation; the number deleted."""
    count = 0
    for path in directory().glob("*.json"):
        count += _discard(path)
    return count


def _discard(path: Path) -> bool:
    try:
        path.unlink()
        return True
    except OSError:
        return False


# ====================================================================== expressions as data
#: operations and functions an expression may be made of, by class name (``Class(*args, evaluate=False)``)
_OPERATIONS = (
    "Add",
    "Mul",
    "Pow",
    "Derivative",
    "Equality",
    "sin",
    "cos",
    "tan",
    "cot",
    "sec",
    "csc",
    "asin",
    "acos",
    "atan",
    "atan2",
    "sinh",
    "cosh",
    "tanh",
    "asinh",
    "acosh",
    "atanh",
    "exp",
    "log",
    "Abs",
    "sign",
    "re",
    "im",
    "conjugate",
)
#: named constants, by class name
_CONSTANTS = ("Pi", "Exp1", "ImaginaryUnit")


def expressions_to_data(exprs: Sequence[Any]) -> dict[str, Any] | None:
    """SymPy expressions as JSON data: ``{"nodes": [...], "roots": [...]}``; None if they hold
    something this format does not know (they are then simply not cached).

    Each node is a list: ``["Symbol", name, assumptions]``, ``["Rational", p, q]``,
    ``["Constant", class name]``, ``["Function", name, assumptions, *args]`` (an undefined
    function such as a coordinate ``x(t)``), ``["Tuple", *args]`` or ``[class name, *args]`` for
    the classes of :data:`_OPERATIONS`; ``args`` are indices of earlier nodes, so a subexpression
    that occurs many times is stored once.  ``roots`` are the indices of ``exprs``.  The data is
    checked by rebuilding it: what cannot be rebuilt equal to ``exprs`` is not returned.
    """
    import sympy as sp
    from sympy.core.function import AppliedUndef

    nodes: list[list[Any]] = []
    index: dict[Any, int] = {}

    def visit(e: Any) -> int:
        i = index.get(e)
        if i is not None:
            return i
        if isinstance(e, sp.Symbol):
            if type(e) is not sp.Symbol:  # Dummy, Wild: identity beyond the name
                raise TypeError(type(e).__name__)
            node: list[Any] = ["Symbol", e.name, dict(e._assumptions_orig)]
        elif isinstance(e, sp.Rational):
            node = ["Rational", int(e.p), int(e.q)]
        elif type(e).__name__ in _CONSTANTS:
            node = ["Constant", type(e).__name__]
        elif isinstance(e, AppliedUndef):
            node = [
                "Function",
                e.func.__name__,
                dict(getattr(e.func, "_kwargs", {})),
                *[visit(a) for a in e.args],
            ]
        elif isinstance(e, sp.Tuple):
            node = ["Tuple", *[visit(a) for a in e.args]]
        elif type(e).__name__ in _OPERATIONS and type(e) is getattr(sp, type(e).__name__, None):
            node = [type(e).__name__, *[visit(a) for a in e.args]]
        else:
            raise TypeError(type(e).__name__)
        nodes.append(node)
        index[e] = len(nodes) - 1
        return len(nodes) - 1

    try:
        data = {"nodes": nodes, "roots": [visit(e) for e in exprs]}
        if expressions_from_data(json.loads(json.dumps(data))) != list(exprs):
            return None
    except (TypeError, ValueError, RecursionError):
        return None
    return data


def expressions_from_data(data: Any) -> list[Any]:
    """The expressions stored by :func:`expressions_to_data`, rebuilt exactly (nothing is evaluated).

    Raises
    ------
    ValueError
        For data that is not such a table (a node of an unknown kind, an index out of range).
    """
    import sympy as sp

    try:
        nodes, roots = data["nodes"], data["roots"]
        built: list[Any] = []
        for i, node in enumerate(nodes):
            head, rest = node[0], node[1:]
            if head == "Symbol":
                name, assumptions = rest
                value = sp.Symbol(_text(name), **_flags(assumptions))
            elif head == "Rational":
                p, q = rest
                if type(p) is not int or type(q) is not int or q < 1:
                    raise ValueError(f"node {i}: not a rational number")
                value = sp.Rational(p, q)
            elif head == "Constant":
                if len(rest) != 1 or rest[0] not in _CONSTANTS:
                    raise ValueError(f"node {i}: not a known constant")
                value = getattr(sp.S, rest[0])
            else:
                if head == "Function":
                    name, assumptions, *rest = rest
                    make = sp.Function(_text(name), **_flags(assumptions))
                elif head == "Tuple":
                    make = sp.Tuple
                elif head in _OPERATIONS:
                    make = functools.partial(getattr(sp, head), evaluate=False)
                else:
                    raise ValueError(f"node {i}: unknown kind {head!r}")
                value = make(*[built[_earlier(a, i)] for a in rest])
            built.append(value)
        return [built[_earlier(r, len(built))] for r in roots]
    except (KeyError, IndexError, TypeError, AttributeError) as exc:
        raise ValueError(f"not a table of expressions ({type(exc).__name__}: {exc})") from None


def _earlier(i: Any, before: int) -> int:
    if type(i) is not int or not 0 <= i < before:
        raise ValueError(f"node index {i!r} out of range")
    return i


def _text(name: Any) -> str:
    if not isinstance(name, str) or not name:
        raise ValueError("a name must be a non-empty string")
    return name


def _flags(assumptions: Any) -> dict[str, bool]:
    if not isinstance(assumptions, dict) or not all(
        isinstance(k, str) and isinstance(v, bool) for k, v in assumptions.items()
    ):
        raise ValueError("assumptions must map names to true/false")
    return assumptions


# ------------------------------------------------------------------ generated modules
_LOADED: dict[str, ModuleType] = {}
_LOCK = threading.Lock()


def import_source(source: str, tag: str, folder: Path | None = None) -> ModuleType:
    """Write ``source`` to the code cache (atomically, keyed by its hash) and import it.

    Each source is imported once per process.  The module is registered in
    ``sys.modules`` under its file name: numba's cache re-imports a compiled
    function's module by name when it loads it.  ``folder`` replaces the code cache's
    folder (``cache_dir()/codegen``).
    """
    digest = hashlib.sha256(source.encode()).hexdigest()[:24]
    with _LOCK:
        if digest in _LOADED:
            return _LOADED[digest]
        directory = cache_dir() / "codegen" if folder is None else folder
        directory.mkdir(parents=True, exist_ok=True)
        path = directory / f"chaplygin_{tag}_{digest}.py"
        if not path.exists() or path.read_text(encoding="utf-8") != source:
            fd, tmp = tempfile.mkstemp(dir=directory, suffix=".tmp")
            with os.fdopen(fd, "w", encoding="utf-8") as fh:
                fh.write(source)
            os.replace(tmp, path)
        spec = importlib.util.spec_from_file_location(path.stem, path)
        if spec is None or spec.loader is None:  # pragma: no cover
            raise ChaplyginError(f"cannot load generated code from {path}")
        module = importlib.util.module_from_spec(spec)
        sys.modules[path.stem] = module
        try:
            spec.loader.exec_module(module)
        except BaseException:
            sys.modules.pop(path.stem, None)
            raise
        _LOADED[digest] = module
        return module
