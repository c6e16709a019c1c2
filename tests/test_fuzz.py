"""Grammar fuzzing of the expression parser and the file reader, at a fixed budget and seed.

The inputs (``fuzzgrammar.py``) are valid expressions of the documented grammar — numbers with
huge and tiny exponents, names, velocities, every function, nesting — plus mutations of them,
token soup and random characters.  For every input: nothing but ``SystemFileError`` comes out,
grammatical text is refused only for a limit or a value, the input finishes under an alarm
(a hang detector with a wide margin, not a speed test), and mpmath's precision and SymPy's
global parameters are unchanged; afterwards the probe expressions still evaluate.
``benchmarks/fuzz.py`` runs the same inputs 10⁶ at a time.
"""

from __future__ import annotations

import math
import signal
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import mpmath
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sympy.core.parameters import global_parameters

import fuzzgrammar as fg
from chaplygin.io.files import SystemFileError, loads
from chaplygin.io.parser import ParseError, parse_constant, parse_expression

#: Seconds an input may run before it counts as a hang: far above the milliseconds inputs take.
HANG = 10.0
FUZZ = settings(
    max_examples=300,
    derandomize=True,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)


class Hang(BaseException):
    """Raised by the alarm: a BaseException, which no ``except Exception`` in the parser catches."""


@contextmanager
def alarm(seconds: float) -> Iterator[None]:
    if sys.platform == "win32":  # pragma: no cover - no SIGALRM
        yield
        return

    def ring(signum: int, frame: Any) -> None:
        raise Hang(f"still running after {seconds} s")

    previous = signal.signal(signal.SIGALRM, ring)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def state() -> tuple[Any, ...]:
    gp = global_parameters
    return (mpmath.mp.prec, mpmath.mp.dps, mpmath.mp.trap_complex, gp.evaluate, gp.distribute, gp.exp_is_pow)


def check_probes() -> None:
    for text, expected in fg.PROBES:
        value = parse_constant(text)
        assert math.isfinite(value), text
        if expected is not None:
            assert value == pytest.approx(expected, rel=1e-12), text


class DataSource:
    """The fuzz grammar's choices, drawn by Hypothesis (so that failures shrink)."""

    def __init__(self, data: st.DataObject) -> None:
        self.data = data

    def integer(self, lo: int, hi: int) -> int:
        return self.data.draw(st.integers(lo, hi))


def check_input(family: str, text: str) -> None:
    before = state()
    try:
        with alarm(HANG):
            if family == "constant":
                parse_constant(text)
            else:
                parse_expression(text, fg.NAMES)
    except ParseError as exc:
        str(exc)  # the message renders
        assert exc.kind != "internal", f"SymPy failed on {text!r}: {exc.reason} ({exc.__cause__!r})"
        if family in ("valid", "constant"):
            assert exc.kind in fg.ALLOWED_FOR_VALID, f"valid input refused: {text!r}: {exc.reason}"
    assert state() == before, f"global state changed by {text!r}"


@FUZZ
@given(st.data())
def fuzz_expressions(data: st.DataObject) -> None:
    family, text = fg.draw(DataSource(data))
    check_input(family, text)


def test_fuzz_expressions() -> None:
    before = state()
    fuzz_expressions()
    assert state() == before
    check_probes()


# ---------------------------------------------------------------------------- whole files
FILE = """\
coordinates = ["x", "theta", "q2"]

[parameters]
m = 1.0
a = 0.5
k_1 = {constant}
Mass = 2.0

[energy]
T = "m/2*x'^2 + a*theta'^2 + Mass*q2'^2"
V = "k_1*theta^2"

[forces]
q2 = {expression}

[constraints]
"x'" = {constraint}

[initial]
theta = 0.1
"theta'" = {constant}
"""


def toml_string(text: str) -> str:
    """``text`` as a TOML basic string (JSON's escapes are TOML's)."""
    import json

    return json.dumps(text)


@settings(FUZZ, max_examples=40)
@given(st.data())
def fuzz_files(data: st.DataObject) -> None:
    source = DataSource(data)
    _, expression = fg.draw(source)
    constraint = fg.valid(source, depth=2) + "*theta'"
    constant = fg.valid(source, depth=2, names=False)
    text = FILE.format(
        expression=toml_string(expression), constraint=toml_string(constraint), constant=toml_string(constant)
    )
    before = state()
    try:
        with alarm(HANG):
            loads(text)
    except SystemFileError as exc:
        assert not (isinstance(exc, ParseError) and exc.kind == "internal"), str(exc)
        assert "could not read this" not in exc.reason, str(exc)
    assert state() == before


def test_fuzz_files() -> None:
    fuzz_files()
    check_probes()


# ---------------------------------------------------------------------------- what the fuzz found
@pytest.mark.parametrize("text", ["tan(t-tan(sinh(1e400)))", "sign(tanh(acos(E)^0.5*1e400*2 - 0.4))"])
def test_found_inputs_leave_no_trace(text: str) -> None:
    """The first escaped as OverflowError and left mpmath at ~1e400 bits; the second never ended."""
    before = state()
    with pytest.raises(ParseError) as info, alarm(HANG):
        parse_expression(text, fg.NAMES)
    assert info.value.kind in fg.ALLOWED_FOR_VALID
    assert state() == before
    check_probes()
