"""Warm runs of ``check``, ``compare``, ``report``, ``export`` and ``stability`` without SymPy.

A run of one of these commands on a small system spends most of its time importing SymPy and
building the system, and on a large one deriving, solving and simplifying again what an
earlier run already had.  So a command that finishes (exit status 0) stores its result in
the derivation cache (:mod:`chaplygin.numeric.cache`: JSON, written atomically, verified on
read; a damaged entry is a miss, deleted, and the command runs in full and stores it anew):
what it printed on stdout, the warnings it printed, and the bytes of every file it wrote.
The same command again finds it and replays it: the same bytes on stdout, the same warnings,
the same files, without importing SymPy, NumPy or the system.

The key (:func:`key`) is the SHA-256 of the command's name, the system file's bytes (or the
example's name), every option as given (the output paths too; not ``--force``), whether stdout
is a terminal, its width and colours (the tables of ``compare`` depend on them), the C compiler
and whether numba and JAX are installed (``--backend auto`` chooses by them), :data:`FORMAT`,
and :func:`chaplygin.numeric.cache.key`'s library version and source digest: a different file,
option, model, form, environment or chaplygin version never finds the entry.  With
``CHAPLYGIN_MODEL_CACHE=off`` nothing is replayed nor stored (every run derives anew).

A result is replayed only where the run it stands for would write the same files: every
output's folder exists (a run that creates one says so) and no output exists without
``--force`` (the full run then refuses, in its own words).  Anything else, a file that
cannot be written included, runs the command in full.
"""

from __future__ import annotations

import base64
import json
import os
import sys
import tempfile
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

from chaplygin.numeric import cache

__all__ = ["FORMAT", "REPLAYED", "key", "paused", "recording", "replay", "wrote"]

#: bumped whenever the shape of an entry changes
FORMAT = 1
#: the commands whose results are stored and replayed (``derive`` keeps its printed text
#: itself, ``simulate`` its run plans: :mod:`chaplygin.numeric._plan`)
REPLAYED = ("check", "compare", "report", "export", "stability")
#: results whose files together exceed this many bytes are not stored
LIMIT = 16 * 2**20


@dataclass
class _Recording:
    """What a command printed and wrote while it ran."""

    stdout: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    files: list[Path] = field(default_factory=list)
    paused: bool = False


#: the command being recorded (None: none)
_active: _Recording | None = None


class _Tee:
    """``sys.stdout`` while a command is recorded: writes through, and keeps a copy."""

    def __init__(self, stream: TextIO, into: _Recording) -> None:
        self._stream = stream
        self._into = into

    def write(self, text: str) -> int:
        if not self._into.paused:
            self._into.stdout.append(text)
        return self._stream.write(text)

    def __getattr__(self, name: str) -> Any:  # isatty, fileno, flush, encoding …
        return getattr(self._stream, name)


def key(command: str, definition: bytes | None, params: Mapping[str, Any]) -> str | None:
    """The key of ``command``'s result for the system ``definition`` (a file's bytes or an
    example's name) and the parsed options ``params``; None where nothing is replayed."""
    if command not in REPLAYED or definition is None:
        return None
    from chaplygin.numeric import _modelcache

    if not _modelcache.enabled():
        return None
    given = {k: getattr(v, "value", v) for k, v in params.items() if k != "force"}  # (not the result)
    options = json.dumps(given, sort_keys=True, default=str, ensure_ascii=True)
    return cache.key("command-result", str(FORMAT), command, definition, options, _terminal(), _environment())


def _terminal() -> str:
    """``"piped"``, or what rich draws a terminal's tables and colours by: its width and
    ``$TERM``, ``$COLORTERM``, ``$NO_COLOR``, ``$FORCE_COLOR``, ``$COLUMNS``."""
    try:
        if not sys.stdout.isatty():
            return "piped"
        width = os.get_terminal_size(sys.stdout.fileno()).columns
    except (OSError, ValueError, AttributeError):  # no file descriptor (a captured stream)
        return "piped"
    names = ("TERM", "COLORTERM", "NO_COLOR", "FORCE_COLOR", "COLUMNS")
    return "\0".join([f"terminal {width}", *(os.environ.get(name, "-") for name in names)])


def _environment() -> str:
    """What ``--backend auto`` and the compiled code depend on beyond the library: what chooses
    the C compiler (``$CHAPLYGIN_CC``, ``$CC``, the compilers on ``PATH``: see
    :func:`chaplygin.numeric._ckernel.compiler`, not imported here, since it imports NumPy),
    and which of numba and JAX are installed."""
    import importlib.util
    import shutil

    chosen = [os.environ.get(name, "-") for name in ("CHAPLYGIN_CC", "CC")]
    found = [shutil.which(name) or "-" for name in ("cc", "gcc", "clang")]
    found += [name for name in ("numba", "jax") if importlib.util.find_spec(name) is not None]
    return "\0".join([*chosen, *found])


def replay(k: str | None, force: bool) -> bool:
    """Replay the result stored under ``k``: its files written, its stdout and warnings printed.

    False (nothing done) where there is none, or where the run it stands for would not write
    its files as stored: an output's folder is missing, an output is a folder, or exists
    without ``force``, or cannot be written.
    """
    value = cache.load(k) if k is not None else None
    try:
        stdout, warned, files = value["stdout"], value["warnings"], value["files"]  # type: ignore[index]
        outputs = [(Path(path), base64.b64decode(data, validate=True)) for path, data in files]
        if not isinstance(stdout, str) or not all(isinstance(w, str) for w in warned):
            return False
    except (TypeError, KeyError, ValueError):
        return False
    for path, _ in outputs:
        if not path.parent.is_dir() or path.is_dir() or (path.exists() and not force):
            return False
    try:
        for path, data in outputs:
            _write(path, data)
    except OSError:
        return False
    sys.stdout.write(stdout)
    sys.stdout.flush()
    for text in warned:
        sys.stderr.write(f"warning: {text}\n")
    return True


def _write(path: Path, data: bytes) -> None:
    """Write ``data`` through a temporary file in the same folder, renamed over ``path``."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # as chaplygin.numeric.simulate writes its outputs
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


@contextmanager
def recording(k: str | None) -> Iterator[None]:
    """Record the command run inside; store its result under ``k`` if it returns normally."""
    global _active
    if k is None or _active is not None:
        yield
        return
    into = _Recording()
    stream, _active = sys.stdout, into
    sys.stdout = _Tee(stream, into)
    try:
        yield
    finally:
        sys.stdout, _active = stream, None
    try:
        files = [(str(path), path.read_bytes()) for path in dict.fromkeys(into.files)]
    except OSError:
        return
    if sum(len(data) for _, data in files) > LIMIT:
        return
    cache.store(
        k,
        {
            "stdout": "".join(into.stdout),
            "warnings": into.warnings,
            "files": [[path, base64.b64encode(data).decode("ascii")] for path, data in files],
        },
    )


def wrote(*paths: Path) -> None:
    """Note the outputs the command wrote (each is stored with its result)."""
    if _active is not None:
        _active.files += paths


def warned(text: str) -> None:
    """Note a warning the command printed (as ``warning: text``)."""
    if _active is not None:
        _active.warnings.append(text)


@contextmanager
def paused() -> Iterator[None]:
    """What is printed inside is not recorded (a line that depends on the run's folders)."""
    if _active is None:
        yield
        return
    before, _active.paused = _active.paused, True
    try:
        yield
    finally:
        _active.paused = before
