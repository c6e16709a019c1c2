"""The command line's polish (issue 19, item 4): the models explained in --help and by
`chaplygin models`; `derive --format pretty`; no `<bool>` after a flag; lists wrapped to the
terminal; CSV numbers that read back exactly; integration progress as t / t_end; messages that
name q, q', q'' as the files do, never SymPy's `Derivative(q(t), (t, 2))`."""

from __future__ import annotations

import io
import re
from pathlib import Path
from types import SimpleNamespace

import click
import numpy as np
import pytest
import sympy as sp
import typer
from rich.console import Console
from sympy.physics.mechanics import dynamicsymbols
from typer.testing import CliRunner

import chaplygin
import chaplygin.numeric.simulate as numeric_simulate
from chaplygin import ChaplyginError, System, examples
from chaplygin.apps import cli
from chaplygin.apps.cli import app
from chaplygin.models import registry
from chaplygin.numeric._ckernel import Unavailable, compiler

runner = CliRunner()
T_ = dynamicsymbols._t

try:
    compiler()
    LOOPS = ["numba", "c"]
except Unavailable:  # pragma: no cover - every CI machine has a C compiler
    LOOPS = ["numba"]


def run(*args: str, **kwargs):
    return runner.invoke(app, [str(a) for a in args], **kwargs)


def words(text: str) -> str:
    """``text`` with every run of white space (a wrapped line, a table's padding) one space."""
    return " ".join(text.split())


def every_command() -> list[list[str]]:
    """The argument lists of every command and group, ``[]`` for ``chaplygin`` itself."""
    found: list[list[str]] = []

    def walk(command: click.Command, path: list[str]) -> None:
        found.append(path)
        for name, sub in getattr(command, "commands", {}).items():
            walk(sub, [*path, name])

    walk(typer.main.get_command(app), [])
    return found


# ---------------------------------------------------------------- the models explained
@pytest.mark.parametrize("command", ["derive", "simulate", "export", "compare", "sweep", "report"])
def test_help_of_a_command_that_takes_a_model_has_the_glossary(command: str) -> None:
    result = run(command, "--help")
    assert result.exit_code == 0
    text = words(result.output)
    for model in registry.MODELS.values():
        assert f"{model.name}: {words(model.glossary)}" in text


def test_models_lists_every_model_with_its_titles_and_glossary() -> None:
    result = run("models")
    assert result.exit_code == 0, result.output
    text = words(result.stdout)
    for model in registry.MODELS.values():
        assert text.count(f"{model.name} ") >= 1 and words(model.glossary) in text
        for form, title in model.titles.items():
            assert f"{form}: {words(title)}" in text
    firsts = [line.split()[0] for line in result.stdout.splitlines() if line and not line[0].isspace()]
    assert firsts == list(registry.names())  # one entry per model, in the registry's order
    assert "models" in run("--help").output


# ---------------------------------------------------------------- derive --format pretty
def test_derive_pretty_prints_unicode_as_demo_does() -> None:
    result = run("derive", "example:knife-edge", "--model", "chaplygin", "--format", "pretty")
    assert result.exit_code == 0, result.output
    out = result.stdout
    assert out.startswith("Chaplygin's equations, eq. (15) - Knife edge\n")
    assert "\N{GREEK SMALL LETTER PHI}\N{COMBINING DIAERESIS}" in out  # φ with two dots
    assert "x\N{COMBINING DIAERESIS}" in out and "cos(\N{GREEK SMALL LETTER PHI})" in out
    assert "phi''" not in out and "**" not in out and "Derivative" not in out
    assert "\nSolved:\n" in out
    # the equations exactly as `chaplygin demo` prints a system's equations (Equations.pretty)
    demo_style = examples.get("knife-edge").constructor().equations("chaplygin").pretty()
    assert out.split("\nSolved:\n")[0].rstrip() == demo_style.rstrip()
    text = run("derive", "example:knife-edge", "--model", "chaplygin").stdout
    assert "phi''" in text and "φ" not in text  # -f text stays the file syntax


# ---------------------------------------------------------------- no <bool>
def test_no_bool_metavar_in_any_help() -> None:
    commands = every_command()
    assert ["simulate"] in commands and ["examples", "list"] in commands and len(commands) >= 12
    for path in commands:
        result = run(*path, "--help", env={"COLUMNS": "200"})
        assert result.exit_code == 0, path
        assert "<bool>" not in result.output, path
        assert "--help" in result.output and "Show this message and exit." in result.output
    simulate_help = run("simulate", "--help", env={"COLUMNS": "200"}).output
    assert re.search(r"--force\s+Overwrite an existing output", simulate_help)  # the flag, no type
    assert "<float>" in simulate_help  # options that take a value keep their type


# ---------------------------------------------------------------- wrapped lists
@pytest.mark.parametrize("args", [["examples", "list"], ["examples", "list", "--long"], ["models"]])
@pytest.mark.parametrize("columns", [80, 60])
def test_lists_wrap_to_the_terminal_width(args: list[str], columns: int) -> None:
    result = run(*args, env={"COLUMNS": str(columns)})
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    assert max(len(line) for line in lines) <= columns
    if args[:2] == ["examples", "list"]:
        full = "--long" in args
        text = words(result.stdout)
        for name, entry in examples.catalogue().items():
            description = entry.description if full else cli._first_sentence(entry.description)
            assert f"{name} {words(description)}" in text  # nothing lost in the wrapping
        assert full or len(lines) > len(examples.catalogue())  # (some first sentences are long)


# ---------------------------------------------------------------- CSV numbers
def test_csv_numbers_are_the_shortest_round_trip(tmp_path: Path) -> None:
    entry = examples.get("knife-edge")
    start = {**entry.initial, "x'": 0.3}
    tr = chaplygin.simulate(entry.constructor(), "chaplygin", 1.0, start, entry.parameters, samples=11)
    path = tr.to_csv(tmp_path / "knife.csv")
    lines = path.read_text().splitlines()
    assert lines[0] == ",".join(tr.columns)
    back = np.loadtxt(path, delimiter=",", skiprows=1)
    assert np.array_equal(back, tr.table())  # every float bit for bit
    first = dict(zip(lines[0].split(","), lines[1].split(",")))
    assert first["x'"] == "0.3" and first["t"] == "0.0"
    assert "0.29999999999999999" not in path.read_text()
    for line in lines[1:]:
        for field in line.split(","):
            assert repr(float(field)) == field  # the shortest text of that float


def test_simulate_command_writes_shortest_numbers(tmp_path: Path) -> None:
    out = tmp_path / "run.csv"
    args = ["simulate", "example:knife-edge", "-m", "chaplygin", "-t", "1", "-n", "11", "-o", out]
    assert run(*args, "--initial", "x'=0.3").exit_code == 0
    header, first = out.read_text().splitlines()[:2]
    assert dict(zip(header.split(","), first.split(",")))["x'"] == "0.3"


# ---------------------------------------------------------------- progress: t / t_end
@pytest.mark.parametrize("backend", ["numpy", *LOOPS])
def test_progress_reports_increasing_times_ending_at_t_end(backend: str, monkeypatch) -> None:
    entry = examples.get("rolling-disk")
    system = entry.constructor()

    def simulate(**extra):
        return chaplygin.simulate(
            system, "voronets", 12.0, entry.initial, entry.parameters, samples=301, backend=backend, **extra
        )

    quiet = simulate()
    monkeypatch.setattr(numeric_simulate, "PROGRESS_EVERY", 0.0)  # report at every chance
    seen: list[float] = []
    told = simulate(progress=seen.append)
    assert len(seen) > 2 and seen[-1] == 12.0
    assert seen == sorted(seen) and seen[0] < 12.0
    # the compiled loops run in stretches that go on exactly where they stopped: the same run
    assert told.status == quiet.status == "success"
    assert np.array_equal(told.table(), quiet.table())
    assert told.rhs_evaluations == quiet.rhs_evaluations  # a resumed stretch's f(t, y) is not counted


@pytest.mark.parametrize("backend", ["numpy", *LOOPS])
def test_progress_through_a_failed_run(backend: str, monkeypatch) -> None:
    """Through a pole (the knife edge turning across φ = π/2): the same run, reported to the end."""
    entry = examples.get("knife-edge")
    system = entry.constructor()
    start = {**entry.initial, "phi'": 1.0}
    quiet = chaplygin.simulate(
        system, "chaplygin", 3.0, start, entry.parameters, samples=301, backend=backend
    )
    monkeypatch.setattr(numeric_simulate, "PROGRESS_EVERY", 0.0)
    seen: list[float] = []
    told = chaplygin.simulate(
        system, "chaplygin", 3.0, start, entry.parameters, samples=301, backend=backend, progress=seen.append
    )
    assert quiet.status == told.status == "failed" and told.message == quiet.message
    assert np.array_equal(told.table(), quiet.table())
    assert seen and seen == sorted(seen)


def test_the_clock_shows_t_of_t_end_and_the_time_left(monkeypatch) -> None:
    now = [100.0]
    monkeypatch.setattr(cli, "time", SimpleNamespace(monotonic=lambda: now[0]))
    terminal = Console(file=io.StringIO(), force_terminal=True, width=120)
    with cli._Steps(3, "simulating", terminal) as steps:
        steps.step("deriving")
        steps.step("integrating")
        show = steps.clock("integrating chaplygin", 0.0, 20.0)
        assert show is not None
        task = steps._progress.tasks[0]
        now[0] = 100.5
        show(2.0)
        assert task.description == "integrating chaplygin: t = 2 / 20"  # no guess in the first second
        assert task.completed == pytest.approx(1.1)  # step 2 of 3, a tenth done
        now[0] = 110.0
        show(5.0)  # a quarter in 10 s: 30 s left
        assert task.description == "integrating chaplygin: t = 5 / 20, about 30 s left"
        now[0] = 400.0
        show(15.0)
        assert task.description.endswith("t = 15 / 20, about 1 min 40 s left")
    piped = Console(file=io.StringIO())
    with cli._Steps(3, "simulating", piped) as steps:
        assert steps.clock("integrating", 0.0, 1.0) is None  # nothing to show, nothing to time


@pytest.mark.parametrize("terminal", [True, False])
def test_simulate_command_reports_t_on_a_terminal_only(terminal: bool, tmp_path: Path, monkeypatch) -> None:
    console = Console(file=io.StringIO(), force_terminal=terminal, width=120)
    monkeypatch.setattr(cli, "_stderr", lambda: console)
    monkeypatch.setattr(numeric_simulate, "PROGRESS_EVERY", 0.0)
    monkeypatch.setenv("CHAPLYGIN_CACHE", str(tmp_path / "cache"))  # no run plan: the full path runs
    given: list[object] = []
    descriptions: list[str] = []
    real_simulate, real_clock = numeric_simulate.simulate, cli._Steps.clock

    def simulate(*args, **kwargs):
        given.append(kwargs.get("progress"))
        return real_simulate(*args, **kwargs)

    def clock(self, what, t0, t1):
        show = real_clock(self, what, t0, t1)
        if show is None:
            return None

        def recorded(t: float) -> None:
            show(t)
            descriptions.append(self._progress.tasks[0].description)

        return recorded

    monkeypatch.setattr(numeric_simulate, "simulate", simulate)
    monkeypatch.setattr(cli._Steps, "clock", clock)
    out = tmp_path / "disk.csv"
    result = run("simulate", "example:rolling-disk", "-t", "4", "-b", "numpy", "-o", out)
    assert result.exit_code == 0, result.output
    assert len(given) == 1
    if terminal:
        assert callable(given[0])
        assert len(descriptions) > 2 and descriptions[-1] == "integrating chaplygin: t = 4 / 4"
        assert all(re.fullmatch(r"integrating chaplygin: t = [0-9.e-]+ / 4", d) for d in descriptions)
    else:
        assert given[0] is None and not descriptions


def test_compare_command_reports_t_of_each_model_on_a_terminal(tmp_path: Path, monkeypatch) -> None:
    console = Console(file=io.StringIO(), force_terminal=True, width=120)
    monkeypatch.setattr(cli, "_stderr", lambda: console)
    monkeypatch.setattr(numeric_simulate, "PROGRESS_EVERY", 0.0)
    descriptions: list[str] = []
    real_clock = cli._Steps.clock

    def clock(self, what, t0, t1):
        show = real_clock(self, what, t0, t1)

        def recorded(t: float) -> None:
            show(t)
            descriptions.append(self._progress.tasks[0].description)

        return recorded

    monkeypatch.setattr(cli._Steps, "clock", clock)
    args = ["-m", "chaplygin,lindelof", "-t", "3", "-b", "numpy", "-o", tmp_path / "cmp"]
    result = run("compare", "example:rolling-sphere", *args)
    assert result.exit_code == 0, result.output
    for label in ("chaplygin", "lindelof"):
        mine = [d for d in descriptions if d.startswith(f"simulating {label}: ")]
        assert len(mine) > 2 and mine[-1] == f"simulating {label}: t = 3 / 3", descriptions[-3:]


# ---------------------------------------------------------------- no SymPy internals in messages
SYMPY_INTERNALS = re.compile(r"Derivative\(|\(t\)|Dummy|Symbol\(|_dd\b|\b_[a-z]")


def message(call) -> str:
    with pytest.raises(ChaplyginError) as caught:
        call()
    text = str(caught.value)
    assert not SYMPY_INTERNALS.search(text), text
    return text


@pytest.fixture
def knife() -> tuple[System, tuple[sp.Expr, ...], tuple[sp.Symbol, ...]]:
    x, y, phi = dynamicsymbols("x y phi")
    m, J = sp.symbols("m J", positive=True)
    system = System(
        coordinates=[x, y, phi],
        kinetic_energy=m / 2 * (x.diff(T_) ** 2 + y.diff(T_) ** 2) + J / 2 * phi.diff(T_) ** 2,
        constraints={y.diff(T_): sp.tan(phi) * x.diff(T_)},
    )
    return system, (x, y, phi), (m, J)


def test_do_not_determine_names_the_accelerations_as_files_do(knife) -> None:
    system, (x, _, phi), (m, _) = knife
    chap = system.equations("chaplygin")
    text = message(lambda: chaplygin.equivalent(system, [m * x.diff(T_, 2)], chap))
    assert "do not determine phi''" in text
    text = message(lambda: chaplygin.classify(system, [m * x.diff(T_, 2)]))
    assert "phi''" in text
    same = [x.diff(T_, 2) + phi.diff(T_, 2)] * 2
    text = message(lambda: chaplygin.equivalent(system, same, chap))
    assert "do not determine all of x'', phi''" in text


def test_other_messages_name_expressions_in_the_file_syntax(knife) -> None:
    system, (x, _, phi), (m, J) = knife
    chap = system.equations("chaplygin")
    assert "x'''" in message(lambda: chaplygin.equivalent(system, [x.diff(T_, 3), phi.diff(T_, 2)], chap))
    numbers = {"m": 1.0, "J": 1.0}
    assert "x''" in message(
        lambda: chaplygin.simulate(system, "chaplygin", 1.0, {x.diff(T_, 2): 1.0}, numbers)
    )
    free = {"coordinates": [x, phi], "constraints": {}}
    T = m / 2 * x.diff(T_) ** 2
    assert "x''" in message(lambda: System(**free, kinetic_energy=T + m * x.diff(T_, 2)))
    assert "forces[phi]" in message(lambda: System(**free, kinetic_energy=T, forces={phi: "J"}))
    assert "phi is not a parameter" in message(lambda: system.parameter(phi))
    state = {x: "a", "y": 0.0, "phi": 0.0, "x'": 1.0, "phi'": 0.0}
    assert "x = 'a' is not a number" in message(
        lambda: chaplygin.simulate_ensemble(system, "chaplygin", 1.0, [state], numbers)
    )


# ---------------------------------------------------------------- energy: drift or change
CART = Path(__file__).resolve().parent.parent / "docs" / "notebooks" / "cart.toml"


def test_energy_is_called_a_change_where_it_is_not_an_invariant(tmp_path: Path, monkeypatch) -> None:
    """A damped system's energy changes by physics, so no summary calls that change a 'drift'
    (the numerical error's name); a conservative one keeps 'energy drift'. The second CLI run
    comes from the run plan and says the same."""
    monkeypatch.setenv("CHAPLYGIN_CACHE", str(tmp_path / "cache"))
    cart = chaplygin.load(CART)
    assert not cart.system.conserves_energy and examples.rolling_disk().conserves_energy
    tr = chaplygin.simulate(cart.system, "chaplygin", 2.0, cart.initial, cart.parameters, samples=21)
    assert not tr.energy_conserved and tr.energy_label == "energy change"
    assert "max energy change" in tr._repr_html_() and "energy drift" not in tr._repr_html_()
    both = chaplygin.compare(cart.system, ["chaplygin", "lindelof"], 2.0, cart.initial, cart.parameters)
    assert "energy change" in both.summary() and "energy drift" not in both.summary()
    for k in range(2):  # the full path, then the run plan
        result = run("simulate", str(CART), "-t", "2", "-o", tmp_path / f"cart{k}.npz")
        assert result.exit_code == 0, result.output
        assert "; energy change " in result.stdout and "energy drift" not in result.stdout
    disk = run("simulate", "example:rolling-disk", "-t", "1", "-o", tmp_path / "disk.npz")
    assert "; energy drift " in disk.stdout


def test_the_memoised_printer_prints_what_sympys_printer_prints() -> None:
    """file_syntax prints each distinct compound subexpression once; the text must be SymPy's
    own (the same printer without the memo), whatever the nesting of Floats and shared terms."""
    from sympy.printing.printer import Printer

    from chaplygin.core import _symbols

    printer = _symbols._printer()

    class Plain(printer):  # type: ignore[misc, valid-type]
        def _print(self, expr, **kwargs):
            return Printer._print(self, expr, **kwargs)

    x, y = dynamicsymbols("x y")
    a = sp.Symbol("a")
    shared = sp.sin(x) * y.diff(T_) + sp.Float("0.125") * a
    exprs = [
        sp.Float("0.1"),  # a Float alone prints in full; nested, as short as it reads back
        sp.Float("0.1") * x + sp.cos(sp.Float("2.5") * x) ** sp.Float("1.5"),
        shared**2 + shared * sp.Abs(shared) - 1 / shared + sp.exp(shared) * sp.E,
        *examples.rolling_disk().equations("chetaev").mass_matrix,
        *examples.rolling_disk().equations("chaplygin").forcing,
    ]
    for expr in exprs:
        for order in (None, "none"):
            assert printer({"order": order}).doprint(expr) == Plain({"order": order}).doprint(expr)
    assert _symbols.file_syntax(exprs[2]).count("abs(") == 1
