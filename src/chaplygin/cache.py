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
  in an entry is ever evaluated: it is data (JSON) only.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import tempfile
from pathlib import Path
from typing import Any

__all__ = ["FORMAT", "key", "load", "store", "clear", "directory", "cache_dir"]

#: bumped whenever the shape of cached documents changes
FORMAT = 1


@functools.cache
def _version() -> str:
    """The library version and a digest of its source files.

    The digest makes an edited (e.g. editable, in-development) installation a
    different version, so no entry derived by other code is ever used.
    """
    from . import __version__

    h = hashlib.sha256()
    for path in sorted(Path(__file__).parent.glob("*.py")):
        h.update(path.name.encode() + b"\0" + path.read_bytes())
    return f"{__version__}+{h.hexdigest()[:16]}"


def cache_dir() -> Path:
    """chaplygin's cache (generated code, derivations): ``$CHAPLYGIN_CACHE``, else the
    user's cache directory (``$XDG_CACHE_HOME/chaplygin`` or ``~/.cache/chaplygin``)."""
    root = os.environ.get("CHAPLYGIN_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(Path.home(), ".cache"), "chaplygin"
    )
    return Path(root)


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
