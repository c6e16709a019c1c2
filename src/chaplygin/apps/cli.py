"""The ``chaplygin`` command line (typer + rich).

Commands: ``derive``, ``check``, ``simulate``, ``compare``, ``sweep``, ``stability``, ``report``, ``demo``,
``export``, ``models`` and ``examples list|show``; the help of each command that takes a model
ends with the models' glossary (:mod:`chaplygin.models.registry`).  ``FILE`` is a TOML system
file (:mod:`chaplygin.io.files`) or ``example:NAME`` for a built-in example.

Exit status: 0 on success; 1 on a bad file, a failed run or a refused overwrite (a message on
stderr, never a traceback); 2 on wrong usage (typer's own: unknown option, missing or invalid
argument).  Long work shows rich progress on a terminal and nothing when the output is piped.
An existing output is never replaced without ``--force`` (``demo`` replaces its own report);
every output is written through a temporary file and renamed, so an interrupted run leaves the
previous file intact.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer
from rich.console import Console
from typer.core import TyperCommand, TyperGroup

from chaplygin.apps import _replay
from chaplygin.apps._wording import cli_wording
from chaplygin.errors import ChaplyginError
from chaplygin.models import registry
from chaplygin.numeric import targets

if TYPE_CHECKING:
    from chaplygin.core.system import System
    from chaplygin.models.equations import Equations
    from chaplygin.numeric.comparison import Comparison

__all__ = ["app", "check_json", "derive_json", "file_syntax", "main"]


class _FlagsWithoutType:
    """Typer's help writes a type after every option, ``<bool>`` after a flag too, which takes
    no value: a flag (``--force``, ``--help``) gets an empty metavar, so nothing is written."""

    def get_params(self, ctx: Any) -> list[Any]:
        params: list[Any] = super().get_params(ctx)  # type: ignore[misc]
        for param in params:
            if getattr(param, "is_flag", False) and param.metavar is None:
                param.metavar = ""
        return params


class _Command(_FlagsWithoutType, TyperCommand):
    """Every command of the command line (``@app.command(cls=_Command)``).

    The result of ``check``, ``compare``, ``report``, ``export`` and ``stability`` is kept in the
    cache and a second run of the same command replays it (:mod:`chaplygin.apps._replay`)."""

    def invoke(self, ctx: Any) -> Any:
        _READ.clear()  # (a command reads each file once: the bytes as they were when it began)
        k = None
        if self.name in _replay.REPLAYED:
            k = _replay.key(self.name, _definition(str(ctx.params.get("file", ""))), ctx.params)
            with _failures():  # (a stdout that cannot take the text: the full path's message)
                replayed = _replay.replay(k, bool(ctx.params.get("force")))
            if replayed:
                return None
        with _replay.recording(k):
            return super().invoke(ctx)


class _Group(_FlagsWithoutType, TyperGroup):
    """``chaplygin`` and ``chaplygin examples``."""


app = typer.Typer(
    name="chaplygin",
    help="Equations of motion of nonholonomic systems: derive, check, simulate, compare, report.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    cls=_Group,
)
examples_app = typer.Typer(
    help="The built-in examples: list them, or print one as a system file.",
    no_args_is_help=True,
    cls=_Group,
)
app.add_typer(examples_app, name="examples")


def _print_version(value: bool) -> None:
    if value:
        from chaplygin._version import __version__

        _emit(f"chaplygin {__version__}")
        raise typer.Exit()


@app.callback()
def _options(
    version: bool = typer.Option(
        False, "--version", callback=_print_version, is_eager=True, help="Print the version and exit."
    ),
) -> None:
    """Equations of motion of nonholonomic systems: derive, check, simulate, compare, report."""


DEMO_GENERATOR = "chaplygin demo"
DEMO_REPORT = Path("demo") / "report.html"
FILE_HELP = "A TOML system file, or example:NAME for a built-in example (see `chaplygin examples list`)."


def _glossary() -> str:
    """The models, one paragraph each, from the registry: the epilog of every command that takes one."""
    rows = [f"{m.name}: {m.glossary}" for m in registry.MODELS.values()]
    return "\n".join(["Models (see `chaplygin models`):", *rows])


GLOSSARY = _glossary()


def _model_name(text: str) -> str:
    """``--model``: any model of the registry (:mod:`chaplygin.models.registry`)."""
    if text not in registry.MODELS:
        raise typer.BadParameter(f"{text!r} is not a model; choose from {', '.join(registry.names())}.")
    return text


def _model_option(verb: str) -> Any:
    """``--model`` of a command whose default is the true motion (:func:`registry.true_motion`)."""
    return typer.Option(
        None,
        "--model",
        "-m",
        parser=_model_name,
        metavar="MODEL",
        help=f"The model to {verb}; default: the true motion (chaplygin for a Chaplygin system, else voronets).",
    )


def _time_limit_option() -> Any:
    return typer.Option(
        3600.0,
        "--time-limit",
        min=0.0,
        help="Refuse a run (a sweep) whose pace after half a second says it would take longer than "
        "this many seconds; 0: no limit.",
    )


def _limit(seconds: float) -> float | None:
    """``--time-limit``'s value as ``time_limit=`` (0: no limit)."""
    return seconds or None


def _param_option(verb: str = "Override") -> Any:
    """``--param NAME=NUMBER`` (repeatable; read by :func:`_overrides`)."""
    return typer.Option(
        None, "--param", "-p", metavar="NAME=NUMBER", help=f"{verb} a parameter: NAME=NUMBER (repeatable)."
    )


def _initial_option(verb: str = "Override") -> Any:
    """``--initial NAME=NUMBER`` or ``NAME'=NUMBER`` (repeatable; read by :func:`_overrides`)."""
    return typer.Option(
        None,
        "--initial",
        "-i",
        metavar="NAME=NUMBER",
        help=f"{verb} an initial value: NAME=NUMBER or NAME'=NUMBER (repeatable).",
    )


class Form(str, Enum):
    classic = "classic"
    new = "new"


class DeriveFormat(str, Enum):
    text = "text"
    pretty = "pretty"
    latex = "latex"
    json = "json"


class CheckFormat(str, Enum):
    text = "text"
    json = "json"


#: ``--backend``: "auto" and the code targets that run one trajectory (a row of
#: :data:`chaplygin.numeric.targets.TARGETS` each)
Backend = Enum("Backend", {name: name for name in ("auto", *targets.offered("simulate"))}, type=str)  # type: ignore[misc]


BACKEND_HELP = (
    "Generated-code backend; auto (default): c (generated C, built once and cached) where a C "
    "compiler is found, else numpy. The summary line says which ran."
)


class FigureFormat(str, Enum):
    svg = "svg"
    png = "png"
    pdf = "pdf"


class OutputExists(ChaplyginError):
    """An output exists and ``--force`` was not given."""


# ====================================================================== consoles, progress, errors
def _stdout() -> Console:
    return Console(file=sys.stdout, soft_wrap=True, highlight=False, emoji=False)


def _stderr() -> Console:
    return Console(file=sys.stderr, soft_wrap=True, highlight=False, emoji=False)


def _emit(text: str) -> None:
    """A command's result on stdout, exactly as given (no markup, emoji codes or wrapping)."""
    sys.stdout.write(text if text.endswith("\n") else text + "\n")
    sys.stdout.flush()


class _Steps:
    """A rich progress bar over named steps on a terminal; nothing at all when piped."""

    def __init__(self, total: int, description: str, console: Console | None = None) -> None:
        self.console = console or _stderr()
        self.total = total
        self.description = description
        self.done = -1  # steps finished; the first step() starts step 0
        self._progress: Any = None
        self._task: Any = None

    def __enter__(self) -> _Steps:
        if self.console.is_terminal:
            self._progress = _bar(self.console)
            self._progress.start()
            self._task = self._progress.add_task(self.description, total=self.total)
        return self

    def step(self, description: str) -> None:
        """Start the next step; the previous one counts as done."""
        self.done += 1
        if self._progress is not None:
            self._progress.update(self._task, description=description, completed=min(self.done, self.total))

    def clock(self, what: str, t0: float, t1: float) -> Callable[[float], None] | None:
        """A ``progress(t)`` callback for an integration from ``t0`` to ``t1`` (see
        :func:`chaplygin.numeric.simulate.simulate`): the current step reads ``what: t = … / t1``,
        with the time left once the run has taken a second, and its share of the bar fills.
        ``None`` when piped: the integration then neither times nor reports anything."""
        if self._progress is None:
            return None
        started = time.monotonic()
        span = t1 - t0

        def show(t: float) -> None:
            done = min(max((t - t0) / span, 0.0), 1.0) if span else 1.0
            elapsed, eta = time.monotonic() - started, ""
            if elapsed >= 1.0 and 0 < done < 1:  # the rest at the pace so far
                eta = f", about {_duration(elapsed * (1.0 - done) / done)} left"
            self._progress.update(
                self._task,
                description=f"{what}: t = {t:.4g} / {t1:g}{eta}",
                completed=min(max(self.done, 0) + done, self.total),
            )

        return show

    def __exit__(self, *exc: Any) -> None:
        if self._progress is not None:
            self._progress.update(self._task, completed=self.total)
            self._progress.stop()


def _duration(seconds: float) -> str:
    """``42 s``, ``3 min 05 s``, ``2 h 07 min``, ``12 days``, ``more than a year``: a time left."""
    from chaplygin.numeric.simulate import duration

    return duration(seconds)


#: the exit status of a command that wrote all its outputs but some of whose runs stopped before
#: the end time (a pole, a blow-up, a step size too small; a failed run of a sweep)
STOPPED_EARLY = 3


def _stopped_early(runs: Mapping[str, Any], where: Callable[[str], str | None]) -> None:
    """Exit with :data:`STOPPED_EARLY` if any of ``runs`` (label → trajectory) did not succeed,
    saying on stderr, for each, why and that ``where(label)`` holds it up to there (where it is
    not None: a file was written)."""
    failed = {label: tr for label, tr in runs.items() if not tr.success}
    for label, tr in failed.items():
        held = where(label)
        _stderr().print(
            f"stopped early: {label}: {cli_wording(str(tr.message))}"
            + (f"; {held} holds the run up to there." if held is not None else "."),
            markup=False,
        )
    if failed:
        raise typer.Exit(STOPPED_EARLY)


@contextmanager
def _failures() -> Iterator[None]:
    """Turn errors into a message on stderr and exit status 1 (no traceback); warnings are
    printed on stderr as ``warning: …`` lines, each once; both in the command line's wording
    (:func:`~chaplygin.apps._wording.cli_wording`: ``--model voronets``, not ``model='voronets'``)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            with _errors():
                yield
        finally:
            seen: set[str] = set()
            for w in caught:
                text = cli_wording(str(w.message))
                if text not in seen:
                    seen.add(text)
                    _stderr().print(f"warning: {text}", markup=False)
                    _replay.warned(text)


@contextmanager
def _errors() -> Iterator[None]:
    try:
        yield
    except (typer.Exit, typer.Abort, typer.BadParameter):
        raise
    except KeyboardInterrupt:
        _stderr().print("interrupted: no output was left half-written.", markup=False)
        raise typer.Exit(130) from None
    except ChaplyginError as exc:
        _stderr().print(f"error: {cli_wording(str(exc))}", markup=False)
        raise typer.Exit(1) from None
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename else ""
        _stderr().print(f"error: {where}{exc.strerror or exc}", markup=False)
        raise typer.Exit(1) from None
    except Exception as exc:
        if isinstance(exc, SystemError) and isinstance(exc.__context__, KeyboardInterrupt):
            # Ctrl-C inside numba's own Python code (a compiled call from the main thread)
            _stderr().print("interrupted: no output was left half-written.", markup=False)
            raise typer.Exit(130) from None
        if os.environ.get("CHAPLYGIN_DEBUG"):
            raise
        _stderr().print(
            f"error: unexpected {type(exc).__name__}: {exc} (set CHAPLYGIN_DEBUG=1 for the traceback)",
            markup=False,
        )
        raise typer.Exit(1) from None


def _refuse_existing(paths: Sequence[Path], force: bool) -> None:
    """Check output files before any work: none is a directory, none exists (unless ``force``),
    and each can be written (:func:`_check_writable`)."""
    existing = [p for p in paths if p.exists()]
    for p in existing:
        if p.is_dir():
            raise OutputExists(f"{p} is a directory; give a file name.")
    if existing and not force:
        names = ", ".join(str(p) for p in existing)
        raise OutputExists(
            f"{names} already exist{'s' if len(existing) == 1 else ''}; pass --force to overwrite."
        )
    for folder in dict.fromkeys(p.parent for p in paths):  # one check per folder
        _check_writable(next(p for p in paths if p.parent == folder))


def _check_writable(path: Path, folder: bool = False) -> None:
    """An output that cannot be written (a read-only folder, a file where a folder should be) is
    refused before the work starts, naming the user's path."""
    from chaplygin.numeric.simulate import check_writable

    check_writable(path, folder=folder)


# ====================================================================== loading
def _example(name: str) -> Any:
    """The catalogue entry ``name`` as a :class:`chaplygin.io.files.SystemFile`."""
    from chaplygin import examples
    from chaplygin.io.files import SystemFile

    entry = examples.get(name)
    system = entry.constructor()
    return SystemFile(system, dict(entry.parameters), dict(entry.initial), system.name, f"example:{name}")


def _load(spec: str) -> Any:
    """A system file, or ``example:NAME``; a file from the bytes :func:`_definition` read, if it
    did (the caches are keyed by those: a file changed since is not read again)."""
    if spec.startswith("example:"):
        return _example(spec[len("example:") :])
    from chaplygin.io import _file

    raw = _READ.get(spec)
    return _file.load(spec) if raw is None else _file.from_bytes(raw, spec)


def _overrides(values: list[str] | None, option: str) -> dict[str, float]:
    out: dict[str, float] = {}
    for item in values or []:
        key, sep, value = item.partition("=")
        try:
            if not sep or not key.strip():
                raise ValueError
            out[key.strip()] = float(value)
        except ValueError:
            raise typer.BadParameter(
                f"{item!r}: expected NAME=NUMBER, e.g. m=1.5", param_hint=option
            ) from None
    return out


def _numbers(
    loaded: Any, params: list[str] | None, initial: list[str] | None
) -> tuple[dict[str, float], dict[str, float]]:
    from chaplygin.numeric._plan import warn_defaulted

    given = _overrides(initial, "--initial")
    warn_defaulted(getattr(loaded, "defaulted", ()), given)
    return (
        {**dict(loaded.parameters or {}), **_overrides(params, "--param")},
        {**dict(loaded.initial or {}), **given},
    )


def _emit_created(created: str) -> None:
    """Say that writing an output created its folder (a line a replayed run never prints: it
    replays only into folders that exist, :mod:`chaplygin.apps._replay`)."""
    with _replay.paused():
        _emit(f"created {created}: it did not exist")


def _created(path: Path) -> str | None:
    """Words for the missing folders above ``path`` (which writing it will create), or None."""
    folder = path.absolute().parent
    missing = [p for p in (folder, *folder.parents) if not p.exists()]
    if not missing:
        return None
    return f"the folder {folder}" + (f" (and {len(missing) - 1} above it)" if len(missing) > 1 else "")


def _tolerance(value: float, option: str) -> float:
    import math

    if not (math.isfinite(value) and value > 0):
        raise typer.BadParameter(
            f"{value:g}: give a positive finite tolerance, e.g. 1e-10.", param_hint=option
        )
    return value


# ====================================================================== printing in the file syntax
def file_syntax(expr: Any) -> str:
    """An expression as a string in the system-file syntax (``x'`` velocities, ``**`` powers)."""
    from chaplygin.core._symbols import file_syntax as printed

    return printed(expr)


def _names(items: Sequence[Any]) -> list[str]:
    return [file_syntax(q) for q in items]


def derive_json(eqs: Equations, accelerations: dict[Any, Any] | None) -> dict[str, Any]:
    """The JSON document of ``chaplygin derive --format json`` (schema ``chaplygin.derive/2``)."""
    return _Derivation.of(eqs, accelerations).json_doc()


#: a solved form is printed when it has at most this many times the nodes of ``M`` and ``F``
SOLVED_FACTOR = 2
#: ... or at most this many nodes (symbols and operations) in all, whatever ``M`` and ``F``
SOLVED_NODES = 20_000
_FOLDED = "--full prints it whole"
_UNSOLVED = "Not solved in print (the solved form is too large to read): M*x = F with x = ({})"


def _size(exprs: Sequence[Any], limit: float = float("inf")) -> int:
    """The symbols and operations of ``exprs`` (their trees' nodes), counted up to just past ``limit``."""
    count, stack = 0, list(exprs)
    while stack and count <= limit:
        count += 1
        stack.extend(stack.pop().args)
    return count


@dataclass
class _Derivation:
    """What ``derive`` derived, apart from how it is printed: the system's names as strings
    (``head``: the keys of the JSON document before its equations) and the expressions."""

    head: dict[str, Any]
    equations: list[Any]  # sympy.Eq(expression, 0) each
    accelerations: dict[Any, Any] | None
    #: ``(M, F)`` of ``M·x = F`` where the solved form is too large to print (accelerations None)
    linear: tuple[list[list[Any]], list[Any]] | None = None

    @classmethod
    def of(cls, eqs: Equations, accelerations: dict[Any, Any] | None) -> _Derivation:
        """The derivation; a solved form much larger than ``M·x = F`` is kept as ``M`` and ``F``."""
        linear = None
        if accelerations is not None:
            budget = SOLVED_FACTOR * max(_size(list(eqs.mass_matrix) + list(eqs.forcing)), SOLVED_NODES)
            if _size(list(accelerations.values()), budget) > budget:
                M, F = eqs.linear_system()  # shown in normal form
                linear, accelerations = (M.tolist(), list(F)), None
        s = eqs.system
        head = {
            "system": s.name,
            "model": eqs.model,
            "form": eqs.form,
            "title": eqs.title,
            "coordinates": _names(s.coordinates),
            "independent": _names(s.independent),
            "dependent": _names(s.dependent),
            "parameters": [p.name for p in s.parameters],
            "constraints": {file_syntax(k): file_syntax(v) for k, v in s.constraints.items()},
            **(
                {"holonomic": {_names([q])[0]: file_syntax(f) for q, f in s.holonomic.items()}}
                if s.holonomic
                else {}
            ),
            "unknowns": _names(eqs.unknowns),
            "multipliers": _names(eqs.multipliers),
            "constants": [c.name for c in eqs.constants],
        }
        return cls(head, list(eqs.equations), None if accelerations is None else dict(accelerations), linear)

    def to_data(self) -> dict[str, Any] | None:
        """A JSON value for the derivation cache (None if the expressions cannot be stored)."""
        from chaplygin.numeric.cache import expressions_to_data

        pairs = list((self.accelerations or {}).items())
        M, F = self.linear or ([], [])
        matrix = [x for row in M for x in row]
        exprs = expressions_to_data([*self.equations, *(x for pair in pairs for x in pair), *matrix, *F])
        if exprs is None:
            return None
        return {
            "head": self.head,
            "expressions": exprs,
            "equations": len(self.equations),
            "accelerations": None if self.accelerations is None else len(pairs),
            "linear": None if self.linear is None else len(F),
        }

    @classmethod
    def from_data(cls, data: Any) -> _Derivation | None:
        """The derivation stored by :meth:`to_data`; None for anything else."""
        from chaplygin.numeric.cache import expressions_from_data

        try:
            exprs = expressions_from_data(data["expressions"])
            n, k, r = data["equations"], data["accelerations"], data["linear"]
            if not isinstance(data["head"], dict) or len(exprs) != n + 2 * (k or 0) + (r or 0) * (
                (r or 0) + 1
            ):
                return None
            pairs = exprs[n : n + 2 * (k or 0)]
            acc = None if k is None else dict(zip(pairs[0::2], pairs[1::2]))
            rest = exprs[n + 2 * (k or 0) :]
            linear = None if r is None else ([rest[i * r : (i + 1) * r] for i in range(r)], rest[r * r :])
            return cls(data["head"], exprs[:n], acc, linear)
        except (KeyError, TypeError, ValueError):
            return None

    def json_doc(self) -> dict[str, Any]:
        acc = self.accelerations
        return {
            "schema": "chaplygin.derive/2",
            **self.head,
            "equations": [{"lhs": file_syntax(e.lhs), "rhs": file_syntax(e.rhs)} for e in self.equations],
            "accelerations": None
            if acc is None
            else {file_syntax(k): file_syntax(v) for k, v in acc.items()},
            "linear_system": None
            if self.linear is None
            else {
                "mass_matrix": [[file_syntax(x) for x in row] for row in self.linear[0]],
                "forcing": [file_syntax(x) for x in self.linear[1]],
            },
        }

    def render(self, fmt: DeriveFormat, full: bool = False) -> str:
        """What ``derive --format fmt`` prints; an expression beyond a screen folded into a
        summary (:mod:`chaplygin.core._fold`) unless ``full`` (JSON: always whole)."""
        import sympy as sp

        from chaplygin.core import _fold

        head, acc = self.head, self.accelerations
        if fmt is DeriveFormat.json:
            return json.dumps(self.json_doc(), indent=2, ensure_ascii=False)
        solved = [sp.Eq(k, v, evaluate=False) for k, v in (acc or {}).items()]
        M, F = self.linear or ([], [])
        cell = "{}_{{{}}}" if fmt is DeriveFormat.latex else "{}[{}]"  # M_{1,2} in LaTeX, else M[1,2]
        entries = [
            sp.Eq(sp.Symbol(cell.format("M", f"{i + 1},{j + 1}")), x, evaluate=False)
            for i, row in enumerate(M)
            for j, x in enumerate(row)
        ]
        entries += [sp.Eq(sp.Symbol(cell.format("F", i + 1)), x, evaluate=False) for i, x in enumerate(F)]
        unsolved = _UNSOLVED.format(", ".join(head["unknowns"]))
        from chaplygin.core._brief import brief

        relations = [
            f"holonomic: {f if full else brief(f, _FOLDED)} = 0 (fixes {q})"
            for q, f in head.get("holonomic", {}).items()
        ]
        if fmt is DeriveFormat.latex:
            from sympy.physics.vector.printing import vlatex

            lines = [f"% {head['title']} - {head['system']}", *(f"% {r}" for r in relations)]
            lines.append(_fold.latex(self.equations, full=full))
            if acc is not None:
                lines += ["% solved", _fold.latex(solved, full=full)]
            if self.linear is not None:
                lines.append(f"% {unsolved}")
                if full or not any(map(_fold.folded, entries)):
                    lines += [f"M = {vlatex(sp.Matrix(M))}", f"F = {vlatex(sp.Matrix(F))}"]
                else:
                    lines.append(_fold.latex(entries, full=False))
            if not full and any(map(_fold.folded, [*self.equations, *solved, *entries])):
                lines.append(f"% {_FOLDED}")
            return "\n".join(lines)
        if fmt is DeriveFormat.pretty:
            from chaplygin.core._symbols import pretty

            text = (
                "\n".join([f"{head['title']} - {head['system']}", *relations])
                + "\n\n"
                + "\n\n".join(_fold.pretty(self.equations, full=full, hint=_FOLDED))
            )
            if acc is not None:
                text += "\n\nSolved:\n\n" + "\n\n".join(_fold.pretty(solved, full=full, hint=_FOLDED))
            if self.linear is not None:
                if full or not any(map(_fold.folded, entries)):
                    text += f"\n\n{unsolved}:\n\nM = {pretty(sp.Matrix(M))}\n\nF = {pretty(sp.Matrix(F))}"
                else:
                    text += f"\n\n{unsolved}:\n\n" + "\n".join(_fold.pretty(entries, hint=_FOLDED))
            return text
        lines = [f"{head['title']} - {head['system']}", *relations]
        lines += [f"  {_fold.text(e, full=full, hint=_FOLDED)}" for e in self.equations]
        if acc is not None:
            lines.append("Solved:")
            lines += [f"  {_fold.text(e, full=full, hint=_FOLDED)}" for e in solved]
        if self.linear is not None:
            lines.append(f"{unsolved}:")
            lines += [f"  {_fold.text(e, full=full, hint=_FOLDED)}" for e in entries]
        return "\n".join(lines)


# ====================================================================== derive
@app.command(cls=_Command, epilog=GLOSSARY)
def derive(
    file: str = typer.Argument(..., metavar="FILE", help=FILE_HELP),
    model: str | None = _model_option("derive"),
    form: Form = typer.Option(
        Form.classic, "--form", help="Form of a reduced model: classic, or the paper's new form (39)/(40)."
    ),
    fmt: DeriveFormat = typer.Option(
        DeriveFormat.text,
        "--format",
        "-f",
        help="Output format: text (the file syntax, x'' for accelerations), pretty (Unicode, as "
        "`chaplygin demo` prints), latex or json.",
    ),
    accelerations: bool = typer.Option(
        True, "--accelerations/--no-accelerations", help="Also solve for the accelerations (and multipliers)."
    ),
    no_cache: bool = typer.Option(
        False, "--no-cache", help="Derive anew: neither read nor write the derivation cache."
    ),
    simplify: bool = typer.Option(
        False,
        "--simplify",
        help="Also pass each solved acceleration through SymPy's simplify "
        "(slow; the default result is already an exact, cancelled normal form).",
    ),
    full: bool = typer.Option(
        False,
        "--full",
        help="Print every expression whole. Without it an expression beyond a screen (more than "
        "1000 symbols and operations) is folded into its size and its leading terms "
        "(--format json is always whole).",
    ),
) -> None:
    """Derive the equations of motion of one model and print them.

    The derivation is kept in the derivation cache (see `chaplygin.numeric.cache`), keyed by the
    file's contents, the model, the form, whether the accelerations are solved and the library
    version, not by the output format: asking again, in any format, prints it without deriving.
    """
    from chaplygin.numeric import cache

    with _failures():
        source = _definition(file)
        if no_cache or source is None:
            _emit(_derive(file, model, form, accelerations, simplify).render(fmt, full))
            return
        asked = model if model is not None else "true-motion"  # the entry names the model
        request = ("derive", source, asked, form.value) + (("simplified",) if simplify else ())
        out_key = cache.key(
            *request, str(accelerations), "printed as", fmt.value, "whole" if full else "folded"
        )
        printed = cache.load(out_key)  # the same request printed before: no SymPy at all
        if isinstance(printed, str):
            _emit(printed)
            return
        keys = [
            cache.key(*request, "accelerations" if solved else "equations")
            for solved in ((True,) if accelerations else (False, True))
        ]
        found = next((d for d in map(_Derivation.from_data, map(cache.load, keys)) if d is not None), None)
        if found is None:
            found = _derive(file, model, form, accelerations, simplify)
            data = found.to_data()
            if data is not None:
                cache.store(keys[0], data)
        if not accelerations:
            found.accelerations = None  # an entry with them serves a request without
        text = found.render(fmt, full)
        cache.store(out_key, text)
        _emit(text)


#: the bytes of each system file this process read (:func:`_definition`): the command's caches
#: are keyed by them and :func:`_load` builds the system from them, so that a file saved again
#: while the command runs cannot store its result under the bytes it had before
_READ: dict[str, bytes] = {}


def _definition(spec: str) -> bytes | None:
    """What a derivation from ``spec`` depends on: a file's bytes (read once a process), or an
    example's name."""
    if spec.startswith("example:"):  # examples change only with the library version
        name = spec[len("example:") :]  # normalised as examples._normalise does, without SymPy
        return f"example:{name.strip().lower().replace('_', '-').replace(' ', '-')}".encode()
    if spec not in _READ:
        try:
            _READ[spec] = Path(spec).read_bytes()
        except OSError:
            return None  # _load reports the problem
    return _READ[spec]


def _derive(
    file: str, model: str | None, form: Form, accelerations: bool, simplify: bool = False
) -> _Derivation:
    """Derive (the only place ``derive`` does symbolic work beyond printing); no ``model``: the true motion."""
    loaded = _load(file)
    system = loaded.system
    model = model or registry.true_motion(system)
    with _Steps(2 if accelerations else 1, f"deriving {model}/{form.value}") as steps:
        steps.step(f"deriving the {model} equations")
        eqs = system.equations(model, form.value)
        eqs.equations  # noqa: B018 - computed here, under the progress display
        acc = None
        if accelerations:
            steps.step("solving for the accelerations" + (" and simplifying" if simplify else ""))
            acc = eqs.solve(simplify=simplify)
    return _Derivation.of(eqs, acc)


# ====================================================================== check
def _nonlinear_json(system: System) -> dict[str, Any]:
    """What ``check`` says of constraints nonlinear in the velocities: the solved form (the
    branch chosen), where it is singular, and whether the constraint forces do work."""
    return {
        "branch": system._branch,
        "solved": {file_syntax(k): file_syntax(v) for k, v in system.constraints.items()},
        "singular_set": [file_syntax(e) for e in system.singular_set],
        "homogeneous": not system.is_affine,
    }


def _nonlinear_lines(doc: dict[str, Any]) -> list[str]:
    """The lines of ``check``'s text for constraints nonlinear in the velocities."""
    if not doc["nonlinear"]:
        return []
    solved = ", ".join(f"{k} = {v}" for k, v in doc["solved"].items())
    branch = "" if doc["branch"] is None else f" (branch {doc['branch']} of the implicit constraints)"
    work = (
        "homogeneous of degree 1 in the velocities: the constraint forces do no work"
        if doc["homogeneous"]
        else "not homogeneous of degree 1 in the velocities: the constraint forces do work (their "
        "power Σ λ_β B_β0 is not identically zero)"
    )
    where = " or ".join(f"{e} = 0" for e in doc["singular_set"])
    return [
        f"Nonlinear in the velocities: {solved}{branch}; {work}.",
        *([f"  Singular (no smooth solution for the dependent velocities) where {where}."] if where else []),
    ]


def check_json(system: System) -> dict[str, Any]:
    """The JSON document of ``chaplygin check --format json`` (schema ``chaplygin.check/1``)."""
    return _checked(system)[0]


def _checked(system: System) -> tuple[dict[str, Any], Any, Any]:
    """:func:`check_json`'s document, the model comparison (None where there is none) and the
    integrability report."""
    from chaplygin.analysis.transitions import compare_models
    from chaplygin.apps.report import applicable_models

    rep = system.integrability()

    def condition(c: Any) -> dict[str, Any]:
        return {
            "holds": c.holds,
            "note": c.note,
            "failures": [{"component": label, "value": file_syntax(e)} for label, e in c.failures],
        }

    models, reasons = applicable_models(system)
    cmp = None
    try:
        cmp = compare_models(system)
        comparison: dict[str, Any] | None = {
            "verdict": cmp.verdict,
            "coincide": cmp.coincide,
            "condition_28": cmp.condition_28,
            "defect_vanishes": cmp.defect_vanishes,
            "defect": {file_syntax(q): file_syntax(d) for q, d in cmp.defect.items()},
            **({"lindelof_obstruction": cmp.lindelof_obstruction} if cmp.lindelof_obstruction else {}),
        }
        why_not = None
    except ChaplyginError as exc:
        comparison, why_not = None, str(exc)
    return (
        {
            "schema": "chaplygin.check/1",
            "system": system.name,
            "coordinates": _names(system.coordinates),
            "independent": _names(system.independent),
            "dependent": _names(system.dependent),
            "constraint_form": system.constraint_form,
            **(
                {"holonomic": {_names([q])[0]: file_syntax(f) for q, f in system.holonomic.items()}}
                if system.holonomic
                else {}
            ),
            "affine": system.is_affine,
            "scleronomic": system.is_scleronomic,
            "nonlinear": system.is_nonlinear,
            **(_nonlinear_json(system) if system.is_nonlinear else {}),
            "integrability": {
                "integrable": rep.integrable,
                "verdict": rep.verdict,
                "condition_28": condition(rep.condition_28),
                "condition_33": condition(rep.condition_33),
                "frobenius": condition(rep.frobenius),
                "relations": [file_syntax(r) for r in rep.relations],
            },
            "chaplygin_system": {
                "is_chaplygin": system.is_chaplygin,
                "obstructions": list(system.chaplygin_obstructions),
            },
            "models": {"applicable": [f"{m}/{f}" for m, f in models], "not_applicable": reasons},
            "comparison": comparison,
            "comparison_unavailable": why_not,
        },
        cmp,
        rep,
    )


@app.command(cls=_Command)
def check(
    file: str = typer.Argument(..., metavar="FILE", help=FILE_HELP),
    fmt: CheckFormat = typer.Option(CheckFormat.text, "--format", "-f", help="Output format."),
    full: bool = typer.Option(
        False,
        "--full",
        help="Print every expression whole. Without it an expression longer than a line (300 "
        "characters) is shown as its leading terms and its size (--format json is always whole).",
    ),
) -> None:
    """Integrability of the constraints, Chaplygin-system test, and how the two models relate."""
    with _failures():
        loaded = _load(file)
        with _Steps(1, "checking"):
            doc, comparison, report = _checked(loaded.system)
        if doc["comparison_unavailable"] is not None:
            doc["comparison_unavailable"] = cli_wording(doc["comparison_unavailable"])
        if fmt is CheckFormat.json:
            _emit(json.dumps(doc, indent=2, ensure_ascii=False))
            return
        from chaplygin.core._brief import brief

        system = loaded.system
        integ = doc["integrability"]
        lines = [
            f"{system.name}: {system.n} coordinates ({', '.join(doc['coordinates'])}), "
            f"{system.g} constraint(s); dependent: {', '.join(doc['dependent']) or 'none'}",
            *(
                f"Holonomic: {f if full else brief(f, '--full prints it')} = 0 (fixes {q}; its time "
                f"derivative is constraint {system.velocity_g + k + 1})"
                for k, (q, f) in enumerate(doc.get("holonomic", {}).items())
            ),
            *_nonlinear_lines(doc),
            "Constraints: " + integ["verdict"],
        ]
        for key, name in (("condition_28", "(28)"), ("condition_33", "(33)"), ("frobenius", "Frobenius")):
            c = integ[key]
            verdict = "not applicable" if c["holds"] is None else "holds" if c["holds"] else "fails"
            line = f"  {name}: {verdict}"
            if c["failures"]:
                first = c["failures"][0]
                more = len(c["failures"]) - 1
                expr = getattr(report, key).failures[0][1]
                value = first["value"] if full else brief(expr, "--full prints it", file_syntax)
                line += f" - {first['component']} = {value}" + (f" (and {more} more)" if more else "")
            lines.append(f"{line}. {c['note']}")
        if integ["integrable"]:
            lines.append(
                "  Finite relations (each = constant): " + (", ".join(integ["relations"]) or "none found")
            )
        chap = doc["chaplygin_system"]
        lines.append(
            "Chaplygin system: yes (T, U, forces and B free of the dependent coordinates)"
            if chap["is_chaplygin"]
            else "Chaplygin system: no - " + "; ".join(chap["obstructions"])
        )
        lines.append("Models that apply: " + ", ".join(doc["models"]["applicable"]))
        if comparison is not None and comparison.verdict == "differ":  # a defect may run to pages
            lines.append(str(comparison).splitlines()[0])
            lines += [
                f"  {file_syntax(q)}: {file_syntax(d) if full else brief(d, '--full prints it', file_syntax)}"
                for q, d in comparison.defect.items()
            ]
        elif comparison is not None:
            lines.append(str(comparison))
        else:
            lines.append(f"Chetaev vs Lindelöf: not compared - {doc['comparison_unavailable']}")
        _emit("\n".join(lines))


# ====================================================================== simulate
def _model_spec(text: str) -> tuple[str, str]:
    name, _, form = text.strip().partition("/")
    form = form or "classic"
    if name not in registry.MODELS or form not in registry.MODELS[name].forms:
        choices = ", ".join(
            f"{m.name}[/{'|'.join(m.forms)}]" if len(m.forms) > 1 else m.name
            for m in registry.MODELS.values()
        )
        raise typer.BadParameter(f"{text!r} is not a model; choose from {choices}.", param_hint="--models")
    return name, form


#: what ``--constants`` takes, in the command line's own words
CONSTANTS_SYNTAX = (
    "give match (μ(0) = 0: the vakonomic motion starts with the accelerations of the true one), "
    "zero (every c_β = 0), or one number per constraint, by name (c_1=0.5,c_2=-1) or in order (0.5,-1)"
)
CONSTANTS_HELP = (
    "Vakonomic models: the constants c_β, the momenta of the dependent coordinates: match (μ(0) = 0), "
    "zero, or numbers by name (c_1=0.5,c_2=-1) or in order (0.5,-1)."
)

#: ``simulate --constants``: its default is zero (``compare``'s is match)
SIMULATE_CONSTANTS_HELP = (
    CONSTANTS_HELP.replace("zero,", "zero (the default: every c_β = 0),")
    + " For a speed constraint (the isokinetic particle's x'^2 + y'^2 = v^2) c = 0 is a degenerate "
    "start (the vakonomic Lagrangian is singular there): use match."
)


def _constants(text: str | None) -> Any:
    """``--constants`` as written: ``"match"``, ``"zero"``, numbers in order (a list) or by name
    (a dict); anything else is a :class:`typer.BadParameter` in the command line's syntax."""
    if text is None:
        return None
    if text.strip() in ("match", "zero"):
        return text.strip()
    items = [item.strip() for item in text.split(",")]
    named = ["=" in item for item in items]
    if any(named) and not all(named):
        raise typer.BadParameter(
            f"{text!r}: give every constant by name or none; {CONSTANTS_SYNTAX}.", param_hint="--constants"
        )
    values: dict[str, float] = {}
    for k, item in enumerate(items, 1):
        name, _, value = item.rpartition("=")
        try:
            number = float(value)
        except ValueError:
            number = math.nan
        if not math.isfinite(number) or (named[0] and not name.strip()):
            raise typer.BadParameter(
                f"{item!r} is not {'NAME=NUMBER' if named[0] else 'a finite number'}; {CONSTANTS_SYNTAX}.",
                param_hint="--constants",
            )
        key = name.strip() if named[0] else str(k)
        if key in values:
            raise typer.BadParameter(f"{key} is given twice; {CONSTANTS_SYNTAX}.", param_hint="--constants")
        values[key] = number
    return values if named[0] else list(values.values())


def _check_constants(c: Any, system: Any) -> None:
    """``--constants`` (from :func:`_constants`) against ``system``: one value per constraint,
    names among its constants; else a :class:`typer.BadParameter` naming them."""
    from chaplygin.models.vakonomic import constant_symbols

    if c is None or isinstance(c, str):
        return
    names = [x.name for x in constant_symbols(system)]
    plural = "s" if len(names) > 1 else ""
    accepted = (
        f"give match, zero, or {','.join(f'{name}=NUMBER' for name in names)} "
        f"(or {len(names)} number{plural} in order)"
    )
    what = f"{system.name} has {len(names)} constraint{plural}, so {len(names)} constant{plural} c_β"
    if isinstance(c, dict):
        unknown = [key for key in c if key not in names]
        missing = [name for name in names if name not in c]
        if unknown or missing:
            problem = f"no constant {unknown[0]}" if unknown else f"no value for {', '.join(missing)}"
            raise typer.BadParameter(
                f"{problem}: {what} ({', '.join(names)}); {accepted}.", param_hint="--constants"
            )
    elif len(c) != len(names):
        raise typer.BadParameter(
            f"{len(c)} number{'s' if len(c) > 1 else ''} given: {what}; {accepted}.", param_hint="--constants"
        )


def _summary_line(label: str, tr: Any, auto: bool = False) -> str:
    return (
        f"{label} [{'auto: ' if auto else ''}{tr.backend}]: {tr.status}, {len(tr.t)} samples to t = "
        f"{(tr.t[-1] if len(tr.t) else float('nan')):g}; {tr.energy_label} {tr.energy_drift():.3g}, "
        f"max constraint residual {max(tr.constraint_residual, default=0.0):.3g}"
        + (f", max holonomic residual {max(tr.holonomic_residual):.3g}" if tr.holonomic_residual.size else "")
    )


@app.command(cls=_Command, epilog=GLOSSARY)
def simulate(
    file: str = typer.Argument(..., metavar="FILE", help=FILE_HELP),
    model: str | None = _model_option("simulate"),
    t_end: float = typer.Option(..., "--t-end", "-t", help="End time (the run starts at t = 0)."),
    out: Path = typer.Option(
        ..., "--out", "-o", help="Output file: .csv or .npz (missing folders are created)."
    ),
    form: Form = typer.Option(Form.classic, "--form", help="Form of a reduced model."),
    samples: int = typer.Option(1001, "--samples", "-n", min=2, help="Number of equally spaced samples."),
    backend: Backend = typer.Option(Backend["auto"], "--backend", "-b", help=BACKEND_HELP),
    constants: str | None = typer.Option(None, "--constants", help=SIMULATE_CONSTANTS_HELP),
    param: list[str] | None = _param_option(),
    initial: list[str] | None = _initial_option(),
    force: bool = typer.Option(False, "--force", help="Overwrite an existing output."),
    method: str = typer.Option(
        "DOP853",
        "--method",
        help="Integrator: DOP853 (adaptive, the default), RK45, RK23, Radau, BDF, LSODA; or, for the true motion (chetaev, chaplygin, voronets), a symmetric fixed-step method that keeps the energy error bounded: midpoint, gauss4, gauss6 (needs --step).",
    ),
    step: float | None = typer.Option(
        None,
        "--step",
        help="Step size of midpoint, gauss4 and gauss6 (the largest step that puts every sample on the grid is used).",
    ),
    rtol: float = typer.Option(
        1e-10, "--rtol", help="Relative tolerance of the adaptive integrators (positive)."
    ),
    atol: float = typer.Option(
        1e-12, "--atol", help="Absolute tolerance of the adaptive integrators (positive)."
    ),
    time_limit: float = _time_limit_option(),
) -> None:
    """Simulate one model from the file's initial state; write every column to CSV or NPZ."""
    from chaplygin.numeric.simulate import METHODS, SYMMETRIC_METHODS

    suffix = out.suffix.lower()
    if suffix not in (".csv", ".npz"):
        raise typer.BadParameter(f"{out}: the output must end in .csv or .npz.", param_hint="--out")
    if method not in METHODS:
        raise typer.BadParameter(
            f"{method!r} is not a method; choose from {', '.join(METHODS)}.", param_hint="--method"
        )
    if method in SYMMETRIC_METHODS and step is None:
        raise typer.BadParameter(
            f"method {method} takes a fixed step: give --step, e.g. --step 0.01.", param_hint="--step"
        )
    c = _constants(constants)
    rtol, atol = _tolerance(rtol, "--rtol"), _tolerance(atol, "--atol")
    _overrides(param, "--param"), _overrides(initial, "--initial")  # syntax first: exit 2
    with _failures():
        _refuse_existing([out], force)
        from chaplygin.numeric import _plan

        definition = _definition(file)
        asked = model if model is not None else _plan.TRUE_MOTION

        def named(name: str) -> str:
            return name if form is Form.classic else f"{name}/{form.value}"

        wanted = named(model or "the true motion")
        with _Steps(3, f"simulating {wanted}") as steps:
            steps.step(f"deriving {wanted}")
            # a run plan in the cache answers without SymPy (chaplygin.numeric._plan); else the full path
            tr = _plan.run(
                definition,
                asked,
                form.value,
                t_end,
                samples,
                backend.value,
                method,
                c,
                step,
                _overrides(param, "--param"),
                _overrides(initial, "--initial"),
                rtol,
                atol,
                progress=steps.clock(f"integrating {wanted}", 0.0, t_end),
                time_limit=_limit(time_limit),
            )
            if tr is None:
                loaded = _load(file)
                params, start = _numbers(loaded, param, initial)
                system = loaded.system
                _check_constants(c, system)
                model = model or registry.true_motion(system)
                from chaplygin.numeric.codegen import reduces_numerically

                # derived here, before the run, unless the family (derived with its constants) or a
                # numeric reduction, which needs only the Chetaev matrices (the Whipple bicycle's
                # symbolic Voronets equations would take minutes)
                if not registry.get(model).constants and not reduces_numerically(
                    system, model, form.value, backend.value
                ):
                    system.equations(model, form.value)
                steps.step(f"integrating {named(model)} to t = {t_end:g} [{backend.value}]")
                options: dict[str, Any] = {
                    "form": form.value,
                    "samples": samples,
                    "backend": backend.value,
                    "method": method,
                    "rtol": rtol,
                    "atol": atol,
                    "progress": steps.clock(f"integrating {named(model)}", 0.0, t_end),
                    "time_limit": _limit(time_limit),
                }
                if c is not None:
                    options["constants"] = c
                if step is not None:
                    options["step"] = step
                from chaplygin.numeric.simulate import simulate as run

                tr = run(system, model, t_end, start, params, **options)
                _plan.remember(definition, asked, form.value, loaded, tr)
            else:
                model = tr.model
            steps.step(f"writing {out}")
            created = _created(out)
            (tr.to_csv if suffix == ".csv" else tr.to_npz)(out)
        label = named(model)
        _emit(f"{_summary_line(label, tr, backend is Backend['auto'])} -> {out}")
        for note in tr.notes:
            _emit(f"  note: {note}")
        if created is not None:
            _emit_created(created)
        _stopped_early({label: tr}, lambda _label: str(out))


# ====================================================================== compare
def _comparison_outputs(
    directory: Path, labels: Sequence[str], figure_format: str, with_path: bool
) -> list[Path]:
    from chaplygin.numeric.comparison import FIGURES

    files = [directory / "summary.txt", directory / "summary.json"]
    files += [directory / f"{_safe(label)}.csv" for label in labels]
    files += [directory / f"{k}.{figure_format}" for k in FIGURES if with_path or k != "paths"]
    return files


def _safe(label: str) -> str:
    return label.replace("/", "-")


def _comparison_json(comparison: Comparison) -> dict[str, Any]:
    import numpy as np

    rows = {}
    for label, tr in comparison.trajectories.items():
        d = comparison.distance(label)
        k = int(np.argmax(d)) if len(d) else 0
        rows[label] = {
            "status": tr.status,
            "message": tr.message,
            "backend": tr.backend,
            "samples": len(tr.t),
            "t_end": float(tr.t[-1]) if len(tr.t) else None,
            "max_distance": float(d[k]) if len(d) else None,
            "at_t": float(tr.t[k]) if len(d) else None,
            "final_distance": float(d[-1]) if len(d) else None,
            "energy_drift": tr.energy_drift(),
            "max_constraint_residual": float(np.max(tr.constraint_residual, initial=0.0)),
            **(
                {"max_holonomic_residual": float(np.max(tr.holonomic_residual))}
                if tr.holonomic_residual.size
                else {}
            ),
        }
    return {
        "schema": "chaplygin.compare/1",
        "system": comparison.system_name,
        "reference": comparison.reference,
        "path": list(comparison.path or []),
        "models": rows,
        "notes": list(comparison.notes),
    }


def _print_comparison(comparison: Comparison) -> None:
    from rich.table import Table

    doc = _comparison_json(comparison)
    what = f"path ({', '.join(doc['path'])})" if doc["path"] else "coordinates"
    table = Table(
        title=f"{comparison.system_name}: compared with {comparison.reference} from the same initial state"
    )
    for col in (
        "model",
        f"max distance of {what}",
        "at t",
        comparison.energy_label,
        "max residual",
        "status",
    ):
        table.add_column(col, justify="left" if col in ("model", "status") else "right")
    for label, row in doc["models"].items():
        table.add_row(
            label,
            f"{row['max_distance']:.6g}",
            f"{row['at_t']:.4g}",
            f"{row['energy_drift']:.3g}",
            f"{row['max_constraint_residual']:.3g}",
            row["status"],
        )
    out = _stdout()
    if out.is_terminal:
        out.print(table)
        for note in comparison.notes:
            out.print(f"note: {note}", markup=False)
    else:
        _emit(comparison.summary())


@app.command(cls=_Command, epilog=GLOSSARY)
def compare(
    file: str = typer.Argument(..., metavar="FILE", help=FILE_HELP),
    t_end: float = typer.Option(..., "--t-end", "-t", help="End time (the runs start at t = 0)."),
    out: Path | None = typer.Option(
        None,
        "--out",
        "-o",
        help="Output directory (created if missing) for the summary, one CSV per model and the figures; without it only the table is printed.",
    ),
    models: str | None = typer.Option(
        None,
        "--models",
        "-m",
        help="Comma-separated models (model or model/form), the reference first; default: the true motion, the vakonomic motion from the same state and, on a Chaplygin system, Lindelöf's.",
    ),
    constants: str | None = typer.Option(
        None, "--constants", help=CONSTANTS_HELP.replace("match (μ(0) = 0)", "match (the default: μ(0) = 0)")
    ),
    samples: int = typer.Option(401, "--samples", "-n", min=2, help="Number of equally spaced samples."),
    backend: Backend = typer.Option(Backend["auto"], "--backend", "-b", help=BACKEND_HELP),
    figure_format: FigureFormat = typer.Option(
        FigureFormat.svg, "--figure-format", help="Format of the figures."
    ),
    param: list[str] | None = _param_option(),
    initial: list[str] | None = _initial_option(),
    force: bool = typer.Option(False, "--force", help="Overwrite existing outputs in the directory."),
    rtol: float = typer.Option(1e-10, "--rtol", help="Relative tolerance of the integrator (positive)."),
    atol: float = typer.Option(1e-12, "--atol", help="Absolute tolerance of the integrator (positive)."),
    time_limit: float = _time_limit_option(),
) -> None:
    """Simulate several models from one initial state: a summary table; with --out, trajectories and figures.

    The constants go to the vakonomic models only; two names of one motion are noted. A reduced
    model whose solved constraints have a pole on the path is replaced by the same motion with
    multipliers (chetaev; vakonomic for the family), with a warning and a note.
    """
    specs = [_model_spec(m) for m in models.split(",")] if models else None
    listed = specs or []
    twice = next((s for k, s in enumerate(listed) if s in listed[:k]), None)
    if twice is not None:
        named = twice[0] if twice[1] == "classic" else "/".join(twice)
        raise typer.BadParameter(
            f"{named} is listed twice; name each model (and form) once.", param_hint="--models"
        )
    c = _constants(constants)
    rtol, atol = _tolerance(rtol, "--rtol"), _tolerance(atol, "--atol")
    _overrides(param, "--param"), _overrides(initial, "--initial")
    with _failures():
        if out is not None and out.exists() and not out.is_dir():
            raise OutputExists(f"{out} exists and is not a directory.")
        if out is not None:
            _check_writable(out, folder=True)
        loaded = _load(file)
        params, start = _numbers(loaded, param, initial)
        system = loaded.system
        from chaplygin.numeric.comparison import (
            Comparison,
            _default_path,
            _takes_constants,
            default_models,
            motion_notes,
        )
        from chaplygin.numeric.comparison import compare as run_compare

        chosen = [f"{n}/{f}" if f != "classic" else n for n, f in specs] if specs else default_models(system)
        vakonomic = [label for label in chosen if _takes_constants(label.partition("/")[0])]
        if c is not None and not vakonomic:
            raise typer.BadParameter(
                f"none of the models {','.join(chosen)} takes constants; they are for the vakonomic "
                "models vakonomic and vakonomic_family (lindelof is the one with every c_β = 0).",
                param_hint="--constants",
            )
        _check_constants(c, system)
        c = "match" if c is None else c
        if out is not None:
            _refuse_existing(
                _comparison_outputs(out, chosen, figure_format.value, _default_path(system) is not None),
                force,
            )
        notes = motion_notes(system, chosen, t_end, start, params, constants=c)
        with _Steps(len(chosen) + (2 if out is not None else 0), "comparing") as steps:
            runs = {}
            for label in chosen:
                steps.step(f"simulating {label}")
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always")
                    part = run_compare(
                        system,
                        [label],
                        t_end,
                        start,
                        params,
                        samples=samples,
                        backend=backend.value,
                        rtol=rtol,
                        atol=atol,
                        progress=steps.clock(f"simulating {label}", 0.0, t_end),
                        time_limit=_limit(time_limit),
                        constants=c if label in vakonomic else None,
                    )
                # the note of a run that stopped early (a pole, no multiplier form) is printed with
                # the summary and in its 'stopped early:' line, not a third time as a warning; a
                # model shown instead of another, and any other warning, is passed on
                stopped = not all(tr.success for tr in part.trajectories.values())
                for w in caught:
                    if not (stopped and str(w.message) in part.notes):
                        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
                runs.update(part.trajectories)
                notes += [note for note in part.notes if note not in notes]
            comparison = Comparison(system.name, runs, chosen[0], part.path, notes)
            if out is not None:
                steps.step("writing trajectories and summary")
                created = _created(out / "summary.txt")
                _write_comparison(comparison, out)
                steps.step("drawing figures")
                written = comparison.save_figures(out, fmt=figure_format.value)
                _replay.wrote(*written)
        _print_comparison(comparison)
        if out is None:
            _stopped_early(runs, lambda label: None)
            return
        _emit(
            f"wrote {out}/: summary.txt, summary.json, "
            + ", ".join(f"{_safe(k)}.csv" for k in runs)
            + ", "
            + ", ".join(p.name for p in written)
        )
        if created is not None:
            _emit_created(created)
        _stopped_early(runs, lambda label: str(out / f"{_safe(label)}.csv"))


def _write_comparison(comparison: Comparison, directory: Path) -> None:
    from chaplygin.numeric.simulate import _atomic_write

    directory.mkdir(parents=True, exist_ok=True)
    for label, tr in comparison.trajectories.items():
        _replay.wrote(tr.to_csv(directory / f"{_safe(label)}.csv"))
    summary = comparison.summary() + "\n"
    _atomic_write(directory / "summary.txt", lambda fh: fh.write(summary.encode("utf-8")), text=False)
    doc = json.dumps(_comparison_json(comparison), indent=2, ensure_ascii=False) + "\n"
    _atomic_write(directory / "summary.json", lambda fh: fh.write(doc.encode("utf-8")), text=False)
    _replay.wrote(directory / "summary.txt", directory / "summary.json")


# ====================================================================== sweep
#: ``sweep --backend``: "auto" and the code targets that sweeps run on (a row of
#: :data:`~chaplygin.numeric.targets.TARGETS` with ``sweep=True``)
SweepBackend = Enum("SweepBackend", {name: name for name in ("auto", *targets.offered("sweep"))}, type=str)  # type: ignore[misc]


def _bar(console: Any, *extra: Any) -> Any:
    """The command line's rich progress bar (description, bar, n/N, elapsed; then ``extra`` columns)."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        SpinnerColumn,
        TextColumn,
        TimeElapsedColumn,
    )

    return Progress(
        SpinnerColumn(),
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        *extra,
        console=console,
        transient=True,
    )


@contextmanager
def _run_counter(description: str) -> Iterator[Any]:
    """A rich bar of finished runs on a terminal (a ``progress(done, total)`` callback); nothing when piped."""
    console = _stderr()
    if not console.is_terminal:
        yield lambda done, total: None
        return
    from rich.progress import TimeRemainingColumn

    with _bar(console, TimeRemainingColumn()) as bar:
        task = bar.add_task(description, total=None)
        yield lambda done, total: bar.update(task, completed=done, total=total)


@app.command(cls=_Command, epilog=GLOSSARY)
def sweep(
    file: str = typer.Argument(..., metavar="FILE", help=FILE_HELP),
    grid: list[str] = typer.Option(
        ...,
        "--grid",
        "-g",
        help="NAME=START:STOP:COUNT (or NAME=V1,V2,…): a parameter, coordinate or independent velocity to sweep; several make the Cartesian product.",
    ),
    t_end: float = typer.Option(..., "--t-end", "-t", help="End time of every run (from t = 0)."),
    out: Path = typer.Option(
        ...,
        "--out",
        "-o",
        help="The results: a Parquet dataset, a directory named NAME.parquet or NAME (no other suffix).",
    ),
    model: str | None = _model_option("simulate"),
    form: Form = typer.Option(Form.classic, "--form", help="Form of a reduced model."),
    samples: int = typer.Option(
        201,
        "--samples",
        "-n",
        min=2,
        help="Samples per run, where the energy drift and the constraint residual are measured.",
    ),
    backend: SweepBackend = typer.Option(
        SweepBackend["auto"],
        "--backend",
        "-b",
        help=BACKEND_HELP,
    ),
    constants: str | None = typer.Option(None, "--constants", help=CONSTANTS_HELP),
    param: list[str] | None = _param_option("Fix"),
    initial: list[str] | None = _initial_option("Fix"),
    scheduler: str | None = typer.Option(
        None,
        "--scheduler",
        help="Where the runs go: 'serial' (this process), 'local' (a Dask LocalCluster) or the address of a running Dask scheduler (tcp://HOST:8786); default: this process, and a LocalCluster only when the runs would take long (see docs/sweeps.md).",
    ),
    workers: int | None = typer.Option(
        None,
        "--workers",
        "-w",
        min=1,
        help="Worker processes of a LocalCluster; giving it asks for one (default: one per core).",
    ),
    chunk_size: int | None = typer.Option(
        None, "--chunk-size", min=1, help="Runs per Dask task (default: about four tasks per worker)."
    ),
    resume: bool = typer.Option(
        False, "--resume", help="Finish the sweep in --out: run only the runs it lacks."
    ),
    force: bool = typer.Option(False, "--force", help="Replace an existing sweep (or file) at --out."),
    time_limit: float = _time_limit_option(),
) -> None:
    """Simulate a model over a grid of parameters and initial values; one Parquet row per run.

    Small sweeps run in this process; long ones, or when asked (--scheduler, --workers), on Dask.
    The summary says where the runs ran.
    """
    from chaplygin.apps.sweep import _out_problem, parse_grid

    wrong = _out_problem(out)
    if wrong is not None:
        raise typer.BadParameter(f"{out}: {wrong}", param_hint="--out")
    axes: dict[str, Any] = {}
    for item in grid:
        try:
            name, values = parse_grid(item)
        except ChaplyginError as exc:
            raise typer.BadParameter(str(exc).removeprefix("--grid "), param_hint="--grid") from None
        if name in axes:
            raise typer.BadParameter(f"{name!r} is given twice; each name is one axis.", param_hint="--grid")
        axes[name] = values
    if resume and force:
        raise typer.BadParameter(
            "--resume keeps the runs there and --force deletes them: give one.", param_hint="--resume/--force"
        )
    c = _constants(constants)
    fixed_params, fixed_initial = _overrides(param, "--param"), _overrides(initial, "--initial")
    with _failures():
        from chaplygin.apps.sweep import read_results
        from chaplygin.apps.sweep import sweep as run_sweep

        _check_writable(out, folder=True)

        def named(name: str) -> str:
            return name if form is Form.classic else f"{name}/{form.value}"

        try:
            with _run_counter(f"sweeping {named(model or 'the true motion')} [{backend.value}]") as progress:
                result = run_sweep(
                    file,
                    axes,
                    t_end=t_end,
                    out=out,
                    model=model,
                    form=form.value,
                    parameters=fixed_params,
                    initial=fixed_initial,
                    scheduler=scheduler,
                    workers=workers,
                    resume=resume,
                    force=force,
                    backend=backend.value,
                    samples=samples,
                    constants=c,
                    chunk_size=chunk_size,
                    progress=progress,
                    time_limit=_limit(time_limit),
                    notice=lambda words: _stderr().print(words, markup=False),
                )
        except KeyboardInterrupt:
            _stderr().print(
                f"interrupted: the finished runs are saved in {out}; run the same command "
                "with --resume to finish the sweep.",
                markup=False,
            )
            raise typer.Exit(130) from None
        auto = "auto: " if backend is SweepBackend["auto"] else ""
        _emit(f"{named(result.model)} [{auto}{result.backend}], t = 0 … {t_end:g}: {result.summary()}")
        if result.failed:
            table = read_results(out, ["status", "message"]).to_pylist()
            first = [r for r in table if r["status"] != "success"][:3]
            _stderr().print(
                f"stopped early: {result.failed} run{'s' if result.failed > 1 else ''} (status 'failed' "
                f"in {out}, with the state reached), e.g.:\n"
                + "\n".join(f"  run {r['run_id']}: {cli_wording(r['message'])}" for r in first),
                markup=False,
            )
            raise typer.Exit(STOPPED_EARLY)


# ====================================================================== stability
class StabilityFormat(str, Enum):
    text = "text"
    json = "json"


def _stability_models(text: str | None, system: Any) -> list[str]:
    """``--model a,b``: models of the registry, each once; default the true motion."""
    if text is None:
        from chaplygin.apps import _steady

        return [_steady.true_model(system)]
    names = [m.strip() for m in text.split(",")]
    for name in names:
        _model_name(name)
    twice = next((n for k, n in enumerate(names) if n in names[:k]), None)
    if twice is not None:
        raise typer.BadParameter(f"{twice} is listed twice; name each model once.", param_hint="--model")
    return names


def _vary(text: str | None) -> tuple[str, Any] | None:
    """``--vary NAME=START:STOP:COUNT`` (or ``NAME=V1,V2,…``), in the syntax of ``sweep --grid``."""
    if text is None:
        return None
    from chaplygin.apps.sweep import parse_grid

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # linspace to inf: refused below
            return parse_grid(text)
    except ChaplyginError as exc:
        words = str(exc).replace("--grid ", "")
        raise typer.BadParameter(words, param_hint="--vary") from None


def _stability_outputs(out: Path | None, plot: Path | None, vary: Any) -> None:
    """``--out`` ends in .json or .csv (a root locus), ``--plot`` in .png, .svg or .pdf (a root locus)."""
    if out is not None and out.suffix.lower() not in (".json", ".csv"):
        raise typer.BadParameter(f"{out}: give a .json or .csv file.", param_hint="--out")
    if out is not None and out.suffix.lower() == ".csv" and vary is None:
        raise typer.BadParameter(
            f"{out}: a .csv holds a root locus; give --vary, or a .json file.", param_hint="--out"
        )
    if plot is not None and plot.suffix.lower().lstrip(".") not in {f.value for f in FigureFormat}:
        raise typer.BadParameter(f"{plot}: give a .png, .svg or .pdf file.", param_hint="--plot")
    if plot is not None and vary is None:
        raise typer.BadParameter(
            "the figure is a root locus: give --vary NAME=START:STOP:COUNT.", param_hint="--plot"
        )


def _steady_request(
    at: str | None, vary: str | None, find: bool, fixed: str | None
) -> tuple[dict[str, float], Any, list[str] | None] | None:
    """``report``'s ``--at``, ``--vary``, ``--find`` and ``--fixed``: the point, the root locus's
    ``(name, values)`` and the variables held (None: no Newton search); None without ``--at``."""
    from chaplygin.apps import _steady

    if at is None:
        for name, given in (("--vary", vary), ("--fixed", fixed), ("--find", find or None)):
            if given is not None:
                raise typer.BadParameter(f"{name} goes with --at (the steady motion).", param_hint=name)
        return None
    try:
        point = _steady.parse_at(at)
    except ChaplyginError as exc:
        raise typer.BadParameter(str(exc).removeprefix("--at: "), param_hint="--at") from None
    if fixed is not None and not find:
        raise typer.BadParameter("--fixed goes with --find (a Newton search).", param_hint="--fixed")
    held = [n.strip() for n in fixed.split(",")] if fixed else []
    return {k: float(v) for k, v in point.items()}, _vary(vary), held if find else None


@app.command(cls=_Command, epilog=GLOSSARY)
def stability(
    file: str = typer.Argument(..., metavar="FILE", help=FILE_HELP),
    at: str = typer.Option(
        ...,
        "--at",
        "-a",
        metavar="NAME=NUMBER,...",
        help="The steady motion: coordinates, velocities (NAME') and multipliers, e.g. \"theta=0, psi'=0, "
        "phi'=2.5\"; a velocity q' of a coordinate q that is not ignorable may be left out (it is 0), "
        "an ignorable coordinate too.",
    ),
    model: str | None = typer.Option(
        None,
        "--model",
        "-m",
        metavar="MODEL,...",
        help="The models, comma-separated, side by side (chetaev,vakonomic,lindelof); default: the true "
        "motion (chaplygin for a Chaplygin system, else voronets).",
    ),
    param: list[str] | None = _param_option(),
    find: bool = typer.Option(
        False, "--find", help="Find the steady motion by a Newton search from --at, holding --fixed."
    ),
    fixed: str | None = typer.Option(
        None, "--fixed", metavar="NAME,...", help="With --find: the variables held at their --at values."
    ),
    vary: str | None = typer.Option(
        None,
        "--vary",
        metavar="NAME=START:STOP:COUNT",
        help="A root locus: the eigenvalues at each value of a variable of the point or a parameter "
        "(or NAME=V1,V2,...); with --find the steady motion is found at each value.",
    ),
    plot: Path | None = typer.Option(
        None, "--plot", help="With --vary: the root locus as a figure (.png, .svg, .pdf)."
    ),
    conditions: bool = typer.Option(
        False,
        "--conditions",
        help="Also the characteristic polynomial and the stability conditions, symbolically; a value "
        "of --at may then be a name (phi'=w).",
    ),
    time_limit: float = typer.Option(
        60.0, "--time-limit", min=0.0, help="Seconds SymPy may spend on --conditions per model; 0: no limit."
    ),
    fmt: StabilityFormat = typer.Option(StabilityFormat.text, "--format", "-f", help="Output format."),
    out: Path | None = typer.Option(
        None,
        "--out",
        "-o",
        help="Also write the result: .json (the --format json document) or .csv (the root locus).",
    ),
    force: bool = typer.Option(False, "--force", help="Overwrite existing outputs."),
) -> None:
    """The linear stability of a steady motion in one or more models: eigenvalues, the zero
    eigenvalues named (the family of steady motions, integrals), the verdict; root loci.
    """
    from chaplygin.apps import _steady

    _overrides(param, "--param")
    try:
        given = _steady.parse_at(at, symbols=conditions)
    except ChaplyginError as exc:
        raise typer.BadParameter(str(exc).removeprefix("--at: "), param_hint="--at") from None
    if fixed is not None and not find:
        raise typer.BadParameter("--fixed goes with --find (a Newton search).", param_hint="--fixed")
    held = [n.strip() for n in fixed.split(",")] if fixed else []
    grid = _vary(vary)
    _stability_outputs(out, plot, grid)
    symbolic = [k for k, v in given.items() if isinstance(v, str)]
    if symbolic and (find or grid is not None):
        raise typer.BadParameter(
            f"{symbolic[0]} is given a name: the numerical part needs numbers (drop --find/--vary).",
            param_hint="--at",
        )
    with _failures():
        _refuse_existing([p for p in (out, plot) if p is not None], force)
        loaded = _load(file)
        system = loaded.system
        params = {**dict(loaded.parameters or {}), **_overrides(param, "--param")}
        models = _stability_models(model, system)
        numbers = {k: float(v) for k, v in given.items() if not isinstance(v, str)}
        with _Steps(len(models) * (1 + (grid is not None) + conditions), "stability") as steps:
            rows: list[Any] = []
            if not symbolic and (grid is None or grid[0] in numbers or grid[0] in params):
                steps.step(f"linearising {', '.join(models)}")
                rows = _steady.assess(system, numbers, params, models, held if find else None)
            locus = None
            if grid is not None:
                steps.step(f"root locus against {grid[0]}")
                locus = _steady.loci(
                    system, numbers, params, models, grid[0], grid[1], held if find else None
                )
            found = None
            if conditions:
                steps.step("the symbolic stability conditions")
                found = _steady.conditions(system, given, models, time_limit or None)
        doc = _steady.document(system, params, given, rows, locus, found)
        written = []
        if out is not None:
            from chaplygin.numeric.simulate import _atomic_write

            body = (
                json.dumps(doc, indent=2, ensure_ascii=False) + "\n"
                if out.suffix.lower() == ".json"
                else _steady.locus_csv(locus or {})
            )
            _atomic_write(out, lambda fh: fh.write(body.encode("utf-8")), text=False)
            written.append(out)
        if plot is not None and locus is not None:
            from chaplygin.numeric.simulate import _atomic_write

            fig = _steady.locus_figure(locus)
            fmt_ = plot.suffix.lower().lstrip(".")
            _atomic_write(
                plot, lambda fh: fig.savefig(fh, format=fmt_, metadata=_figure_metadata(fmt_)), text=False
            )
            written.append(plot)
        if fmt is StabilityFormat.json:
            _emit(json.dumps(doc, indent=2, ensure_ascii=False))
        else:
            _emit(_steady.text(system, params, rows, locus, found))
        _replay.wrote(*written)
        for path in written:
            _emit(f"wrote {path}")


def _figure_metadata(fmt: str) -> dict[str, Any]:
    """No date in an SVG or PDF figure: the same command writes the same file."""
    return {"Date": None} if fmt in ("svg", "pdf") else {}


# ====================================================================== report
def _report_progress(steps: _Steps) -> Any:
    return lambda stage: steps.step(f"report: {stage}")


@app.command(cls=_Command, epilog=GLOSSARY)
def report(
    file: str = typer.Argument(..., metavar="FILE", help=FILE_HELP),
    out: Path = typer.Option(..., "--out", "-o", help="The HTML file to write."),
    models: str | None = typer.Option(
        None, "--models", "-m", help="Models to simulate and compare (comma-separated), the reference first."
    ),
    t_end: float = typer.Option(20.0, "--t-end", "-t", help="End time of the simulations."),
    samples: int = typer.Option(401, "--samples", "-n", min=2, help="Number of samples."),
    backend: Backend = typer.Option(Backend["numpy"], "--backend", "-b", help="Generated-code backend."),
    param: list[str] | None = _param_option(),
    initial: list[str] | None = _initial_option(),
    force: bool = typer.Option(False, "--force", help="Overwrite an existing report."),
    time_limit: float = _time_limit_option(),
    at: str | None = typer.Option(
        None,
        "--at",
        "-a",
        metavar="NAME=NUMBER,...",
        help="Add the section 'Steady motion and stability': the steady motion there (as `chaplygin "
        "stability --at`), in the --models or the true motion and Lindelöf's.",
    ),
    vary: str | None = typer.Option(
        None, "--vary", metavar="NAME=START:STOP:COUNT", help="With --at: a root locus in that section."
    ),
    find: bool = typer.Option(False, "--find", help="With --at: find the steady motion by a Newton search."),
    fixed: str | None = typer.Option(
        None, "--fixed", metavar="NAME,...", help="With --find: the variables held at their --at values."
    ),
) -> None:
    """Write one self-contained HTML report: system, integrability, equations, simulations; with
    --at, a steady motion's stability."""
    from chaplygin.apps.report import STAGES, report_comparison, write_report

    specs = [_model_spec(m) for m in models.split(",")] if models else None
    _overrides(param, "--param"), _overrides(initial, "--initial")
    steady = _steady_request(at, vary, find, fixed)
    with _failures():
        _refuse_existing([out], force)
        loaded = _load(file)
        params, start = _numbers(loaded, param, initial)
        chosen = [f"{n}/{f}" if f != "classic" else n for n, f in specs] if specs else None
        created = _created(out)
        found = None
        if steady is not None:
            from chaplygin.apps._steady import study

            with _Steps(1, "report: stability") as steps:
                steps.step("report: the steady motion's stability")
                names = list(dict.fromkeys(n for n, _ in specs)) if specs else None
                found = study(loaded.system, steady[0], params, names, steady[1], steady[2])
        with _Steps(len(STAGES) + 1, "report") as steps:
            steps.step("report: simulating")  # first, to know whether every run reaches t_end
            comparison = report_comparison(
                loaded,
                models=chosen,
                t_end=t_end,
                samples=samples,
                backend=backend.value,
                parameters=params,
                initial=start,
                time_limit=_limit(time_limit),
            )
            write_report(
                loaded,
                out,
                models=chosen,
                t_end=t_end,
                samples=samples,
                backend=backend.value,
                parameters=params,
                initial=start,
                comparison=comparison,
                progress=_report_progress(steps),
                stability=found,
            )
        _replay.wrote(out)
        _emit(f"wrote {out}: the simulations run to t = {t_end:g} ({samples} samples)")
        if created is not None:
            _emit_created(created)
        if comparison is not None:
            _stopped_early(comparison.trajectories, lambda _label: str(out))


# ====================================================================== demo
def _is_demo_report(path: Path) -> bool:
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            head = fh.read(4096)
    except OSError:
        return False
    return f'<meta name="generator" content="{DEMO_GENERATOR}">' in head


@app.command(cls=_Command)
def demo(
    out: Path = typer.Option(
        DEMO_REPORT, "--out", "-o", help="Where the report goes (a previous demo report there is replaced)."
    ),
    t_end: float = typer.Option(20.0, "--t-end", "-t", help="End time of the simulations."),
    force: bool = typer.Option(
        False, "--force", help="Overwrite the output even if it is not a demo report."
    ),
) -> None:
    """The paper's sphere end to end: both models derived, checked, simulated; the report written."""
    from chaplygin import compare_models, equivalent
    from chaplygin.apps.report import STAGES, is_paper_sphere, paper_table, write_report
    from chaplygin.numeric.comparison import compare as run_compare

    with _failures():
        if out.exists() and not force and not _is_demo_report(out):
            raise OutputExists(f"{out} exists and is not a chaplygin demo report; pass --force to overwrite.")
        if out.is_dir():
            raise OutputExists(f"{out} is a directory; give a file name.")
        _check_writable(out)
        loaded = _load("example:rolling-sphere")
        system = loaded.system
        params, start = loaded.parameters, loaded.initial
        with _Steps(8 + len(STAGES), "demo") as steps:
            steps.step("deriving Chetaev, Chaplygin (15), (40), Lindelöf (22), (39)")
            chetaev = system.equations("chetaev")
            chap, chap_new = system.equations("chaplygin"), system.equations("chaplygin", "new")
            lind, lind_new = system.equations("lindelof"), system.equations("lindelof", "new")
            steps.step("checking the true motion")
            true_ok = [equivalent(system, chap, chetaev), equivalent(system, chap_new, chetaev)]
            steps.step("checking Lindelöf's equations")
            lind_ok = equivalent(system, lind, lind_new, symbolic=False)
            lind_vs_true = equivalent(system, lind, chap, symbolic=False)
            steps.step("integrability")
            integrable = system.integrability().integrable
            steps.step("comparing the models")
            relation = compare_models(system)
            steps.step("simulating both models from the same initial state")
            comparison = run_compare(system, ["chaplygin", "lindelof"], t_end, start, params, samples=401)
            steps.step("the paper's printed equations (49)-(62)")
            table = paper_table() if is_paper_sphere(system) else None
            steps.step("writing the report")
            write_report(
                loaded,
                out,
                comparison=comparison,
                paper=table if table is not None else False,
                parameters=params,
                initial=start,
                generator=DEMO_GENERATOR,
                progress=_report_progress(steps),
            )

        def speed_change(tr: Any) -> float:
            import numpy as np

            return float(max(np.ptp(tr["x'"]), np.ptp(tr["y'"])))

        dist = comparison.distance("lindelof")
        true_tr, lind_tr = comparison.trajectories["chaplygin"], comparison.trajectories["lindelof"]
        k = int(dist.argmax())
        state = ", ".join(f"{k_}={v:g}" for k_, v in start.items())
        lines = [
            f"{system.name} - the seed paper's §4 example (Liang & Chen 2000)",
            f"  constraints (41)-(42): {'integrable' if integrable else 'not integrable (nonholonomic)'} by the Frobenius test; condition (28) {'holds' if relation.condition_28 else 'fails'}",
            f"  true motion:  Chaplygin (15) = new form (40) = Chetaev multipliers (6): "
            f"{'yes' if all(true_ok) else 'NO'} ({true_ok[0].method})",
            f"  vakonomic:    Lindelöf (22) = new form (39): {'yes' if lind_ok else 'NO'}",
            f"  the models {'coincide' if relation.verdict == 'coincide' else 'differ'}: "
            f"Lindelöf (22) vs Chaplygin (15): {'equivalent' if lind_vs_true else 'not equivalent'} "
            f"(largest relative difference {lind_vs_true.max_residual:.2g}); verdict {relation.verdict!r}",
            f"  simulated t in [0, {t_end:g}] from {state} (m={params.get('m', 1):g}, a={params.get('a', 1):g}):",
            f"    Lindelöf's centre drifts from the true path: {dist[-1]:.4g} at t = {true_tr.t[-1]:g} "
            f"(largest {dist[k]:.4g}, at t = {true_tr.t[k]:g})",
            f"    the centre's velocity changes by {speed_change(true_tr):.2g} in the true motion "
            f"(uniform straight line, Routh §243), by {speed_change(lind_tr):.2g} in Lindelöf's",
            f"    energy drift: true {true_tr.energy_drift():.2g}, Lindelöf {lind_tr.energy_drift():.2g}",
        ]
        if table is not None:
            lines.append(f"  {table.summary()}")
        lines.append(f"  report: {out}")
        _emit(chap.pretty() + "\n")  # Chaplygin's equations (15) of the sphere, readable
        _emit("\n".join(lines))
        if not (all(true_ok) and lind_ok and true_tr.success and lind_tr.success):
            raise ChaplyginError("the demo's checks failed; see above.")


# ====================================================================== examples
def _first_sentence(text: str) -> str:
    end = text.find(". ")
    return text if end < 0 else text[: end + 1]


def _listing(rows: Sequence[tuple[str, Sequence[str]]]) -> str:
    """A list of names and their paragraphs, each paragraph wrapped to the terminal's width
    (``COLUMNS``; 80 where there is no terminal) and indented under the name's column."""
    import shutil
    import textwrap

    first = max(len(name) for name, _ in rows) + 2
    width = max(shutil.get_terminal_size().columns - first, 20)
    lines = []
    for name, paragraphs in rows:
        head = name  # on the first line only
        for text in paragraphs:
            for line in textwrap.wrap(text, width, break_on_hyphens=False) or [""]:
                lines.append(f"{head:<{first}}{line}".rstrip())
                head = ""
    return "\n".join(lines)


@examples_app.command("list", cls=_Command)
def examples_list(
    long: bool = typer.Option(False, "--long", "-l", help="Full descriptions."),
) -> None:
    """List the built-in examples (use them as FILE: example:NAME)."""
    from chaplygin import examples

    with _failures():
        rows = [
            (name, [entry.description if long else _first_sentence(entry.description)])
            for name, entry in examples.catalogue().items()
        ]
        _emit(_listing(rows))


@examples_app.command("show", cls=_Command)
def examples_show(
    name: str = typer.Argument(
        ..., metavar="NAME", help="The example's name (see `chaplygin examples list`)."
    ),
) -> None:
    """Print an example as a TOML system file (`chaplygin examples show NAME > mine.toml`)."""
    from chaplygin import examples

    try:
        entry = examples.get(name)
    except ChaplyginError as exc:
        raise typer.BadParameter(str(exc), param_hint="NAME") from None
    with _failures():
        text = entry.dumps()
        sys.stdout.write(text if text.endswith("\n") else text + "\n")


# ====================================================================== export
class ExportTarget(str, Enum):
    c = "c"
    python = "python"


@app.command(cls=_Command, epilog=GLOSSARY)
def export(
    file: str = typer.Argument(..., metavar="FILE", help=FILE_HELP),
    to: ExportTarget = typer.Option(
        ..., "--to", help="c: one C99 file; python: a module that needs only numpy."
    ),
    model: str | None = _model_option("export"),
    form: Form = typer.Option(Form.classic, "--form", help="Form of a reduced model."),
    out: Path | None = typer.Option(
        None,
        "--out",
        "-o",
        help="The file to write (missing folders are created); default: print the source.",
    ),
    jacobian: bool = typer.Option(
        False, "--jacobian", help="Also generate jacobian(t, y, p), the exact df/dy."
    ),
    prefix: str = typer.Option("", "--prefix", help="Put before the names rhs and jacobian (e.g. sphere_)."),
    force: bool = typer.Option(False, "--force", help="Overwrite an existing output."),
) -> None:
    """Write one model's dy/dt = f(t, y, p) (and df/dy) as standalone C or Python source.

    The header comment of the generated file lists the entries of y and p in order.
    """
    import re

    if prefix and not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", prefix):
        raise typer.BadParameter(
            f"{prefix!r}: give letters, digits and '_' (not starting with a digit), e.g. sphere_.",
            param_hint="--prefix",
        )
    with _failures():
        if out is not None:
            _refuse_existing([out], force)
        loaded = _load(file)
        system = loaded.system
        model = model or registry.true_motion(system)
        from chaplygin.io.export import export as generate

        with _Steps(1, f"exporting {model}/{form.value}") as steps:
            steps.step(f"generating {to.value} for {model}/{form.value}")
            source = generate(system, model, to.value, form=form.value, jacobian=jacobian, prefix=prefix)
        if out is None:
            _emit(source)
            return
        from chaplygin.numeric.simulate import _atomic_write

        created = _created(out)
        _atomic_write(out, lambda fh: fh.write(source.encode("utf-8")), text=False)
        _replay.wrote(out)
        _emit(
            f"wrote {out}: {prefix}rhs{f' and {prefix}jacobian' if jacobian else ''} of "
            f"{model}/{form.value} in {to.value}"
        )
        if created is not None:
            _emit_created(created)


# ====================================================================== models
@app.command(cls=_Command)
def models() -> None:
    """List the models (--model, --models): what each one is, and the title of each form."""
    rows = []
    for m in registry.MODELS.values():
        titles = [f"{form}: {title}" for form, title in m.titles.items()]
        rows.append((m.name, [m.glossary, *titles]))
    _emit(_listing(rows))


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit status."""
    try:
        app(args=argv, prog_name="chaplygin")
    except SystemExit as exc:
        code = exc.code
        if code is None:
            return 0
        return code if isinstance(code, int) else 1
    return 0
