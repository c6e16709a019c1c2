"""The safe expression parser: grammar, errors, limits, and proofs that hostile text is harmless.

The property tests check three things for arbitrary input: nothing is executed (an audit
hook watches for exec/compile/process creation while the parser runs), nothing hangs
(every parse is timed), and nothing escapes but a ParseError.
"""

from __future__ import annotations

import ast
import math
import subprocess
import sys
import textwrap
import time
from contextlib import contextmanager
from pathlib import Path

import pytest
import sympy as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sympy.physics.mechanics import dynamicsymbols

from chaplygin.errors import ChaplyginError
from chaplygin.io import parser
from chaplygin.io.files import SystemFileError
from chaplygin.io.parser import (
    MAX_DEPTH,
    MAX_EXPANDED_TERMS,
    MAX_EXPONENT,
    MAX_EXPRESSION_LENGTH,
    MAX_LITERAL_DIGITS,
    MAX_NUMBER_BITS,
    MAX_TOKENS,
    Names,
    ParseError,
    check_name,
    parse_constant,
    parse_expression,
)

SRC = Path(parser.__file__).resolve().parent
t = dynamicsymbols._t
x, theta = dynamicsymbols("x theta")
m, a = sp.symbols("m a", real=True)
NAMES = Names.build(["m", "a"], ["x", "theta"])
FAST = 1.0  # seconds: generous for a slow CI machine; typical parses take milliseconds


def P(text: str, names: Names = NAMES, **kw: object) -> sp.Expr:
    return parse_expression(text, names, **kw)  # type: ignore[arg-type]


def error(text: str, names: Names = NAMES, **kw: object) -> ParseError:
    with pytest.raises(ParseError) as info:
        P(text, names, **kw)
    return info.value


# ---------------------------------------------------------------------------- audit hook
_FORBIDDEN_EVENTS = (
    "exec",
    "compile",
    "os.system",
    "subprocess.Popen",
    "os.posix_spawn",
    "os.spawn",
    "os.exec",
    "os.fork",
    "os.forkpty",
    "pty.spawn",
    "socket.connect",
    "ctypes.dlopen",
    "os.remove",
    "os.rename",
    "shutil.rmtree",
)
_AUDIT: dict = {"on": False, "seen": [], "sympy": False}


def _sympy_template(event: str, args: tuple) -> bool:
    """SymPy's polynomial code compiles monomial helpers from its own templates (no user text)."""
    if event == "compile":
        source = args[0]
        return isinstance(source, bytes) and source.startswith(b"def monomial_")
    if event == "exec":
        code = args[0]
        names = getattr(code, "co_names", ("?",))
        return bool(names) and all(n.startswith("monomial_") for n in names)
    return False


def _hook(event: str, args: tuple) -> None:
    if not _AUDIT["on"]:
        return
    if _AUDIT["sympy"] and _sympy_template(event, args):
        return
    if event.startswith(_FORBIDDEN_EVENTS) or (
        event == "open" and len(args) > 1 and isinstance(args[1], str) and any(c in args[1] for c in "wax+")
    ):
        _AUDIT["seen"].append((event, repr(args)[:200]))


sys.addaudithook(_hook)


@contextmanager
def watched(*, sympy_templates: bool = False, limit: float | None = None):
    """Fail if the block runs code, starts a process, writes a file, or takes too long.

    The parser alone must cause no compile/exec event at all.  Building a System runs SymPy's
    polynomial code, which compiles small monomial helpers from SymPy's own templates; with
    ``sympy_templates=True`` exactly those are allowed.
    """
    _AUDIT["seen"] = []
    _AUDIT["sympy"] = sympy_templates
    _AUDIT["on"] = True
    start = time.process_time()  # this process's CPU time: not stretched by other processes' load
    try:
        yield
    finally:
        _AUDIT["on"] = False
    elapsed = time.process_time() - start
    assert not _AUDIT["seen"], f"forbidden events while parsing: {_AUDIT['seen']}"
    assert elapsed < (limit or FAST), f"took {elapsed:.2f} s"


def safe_parse(text: str, names: Names = NAMES) -> sp.Expr | None:
    """Parse under the audit hook and the clock; only ParseError may come out."""
    with watched():
        try:
            return P(text, names)
        except ParseError as exc:
            assert isinstance(exc, SystemFileError) and isinstance(exc, ChaplyginError)
            str(exc)  # rendering never fails
            return None


# ---------------------------------------------------------------------------- grammar
@pytest.mark.parametrize(
    "text, expected",
    [
        ("2", sp.Integer(2)),
        ("0.1", sp.Rational(1, 10)),
        (".5", sp.Rational(1, 2)),
        ("5.", sp.Integer(5)),
        ("1.5e-3", sp.Rational(3, 2000)),
        ("2E+2", sp.Integer(200)),
        ("007", sp.Integer(7)),
        ("m", m),
        ("x", x),
        ("x'", x.diff(t)),
        ("x' ^ 2", x.diff(t) ** 2),
        ("x'**2", x.diff(t) ** 2),
        ("t", t),
        ("pi", sp.pi),
        ("E", sp.E),
        ("-x^2", -(x**2)),
        ("(-x)^2", x**2),
        ("2^3^2", sp.Integer(512)),
        ("2**3**2", sp.Integer(512)),
        ("2^-1", sp.Rational(1, 2)),
        ("2*-m", -2 * m),
        ("--m", m),
        ("+m", m),
        ("a/m/x", a / (m * x)),
        ("a-m-x", a - m - x),
        ("a - (m - x)", a - m + x),
        ("a*m^2/5", a * m**2 / 5),
        ("m/2*(x'^2 + theta'^2)", m / 2 * (x.diff(t) ** 2 + theta.diff(t) ** 2)),
        ("sin(theta)^2 + cos(theta)^2", sp.sin(theta) ** 2 + sp.cos(theta) ** 2),
        ("atan2(a, m)", sp.atan2(a, m)),
        ("sqrt(m)", sp.sqrt(m)),
        ("sqrt(8)", 2 * sp.sqrt(2)),
        ("abs(x)", sp.Abs(x)),
        ("sign(a)", sp.sign(a)),
        ("exp(1)", sp.E),
        ("E^x", sp.exp(x)),
        (
            "log(m) + tanh(a) + sinh(a) + cosh(a) + asin(a) + acos(a) + atan(a) + tan(a)",
            sp.log(m)
            + sp.tanh(a)
            + sp.sinh(a)
            + sp.cosh(a)
            + sp.asin(a)
            + sp.acos(a)
            + sp.atan(a)
            + sp.tan(a),
        ),
        ("  m\t*\n a  ", m * a),
        ("m*t + x'*t^2", m * t + x.diff(t) * t**2),
    ],
)
def test_grammar(text: str, expected: sp.Expr) -> None:
    assert P(text) == expected


def test_names_are_the_usual_objects() -> None:
    """Coordinates are dynamicsymbols, parameters real symbols, t the mechanics time."""
    assert P("x") == dynamicsymbols("x")
    assert P("m") == sp.Symbol("m", real=True)
    assert P("m").is_real
    assert P("t") == dynamicsymbols._t  # (equal; the same object only while SymPy's cache holds it)


def test_numbers_are_exact() -> None:
    value = P("0.1 + 0.2")
    assert value == sp.Rational(3, 10) and value.is_Rational
    assert P("3.14159") == sp.Rational(314159, 100000)


def test_parse_constant() -> None:
    assert parse_constant("pi/4") == pytest.approx(math.pi / 4)
    assert parse_constant("2*sqrt(2)") == pytest.approx(2 * math.sqrt(2))
    assert parse_constant("-1e-3") == -0.001
    with pytest.raises(ParseError, match="not a finite real number"):
        parse_constant("acos(2)")
    with pytest.raises(ParseError, match="unknown name 'm'"):
        parse_constant("m")
    with pytest.raises(ParseError, match="time t is not allowed here"):
        parse_constant("t")


def test_velocity_message() -> None:
    exc = error("m*x + a*theta'", velocity_message="V must not depend on velocities")
    assert exc.reason == "V must not depend on velocities"
    assert exc.column == 8
    assert P("m*x", velocity_message="no") == m * x


# ---------------------------------------------------------------------------- errors
def caret_column(exc: ParseError) -> int:
    """The column the caret points at, read from the rendered message."""
    lines = str(exc).splitlines()
    caret = next(line for line in lines if line.strip() == "^")
    return caret.index("^") - 4


@pytest.mark.parametrize(
    "text, reason, column",
    [
        ("", "the expression is empty", 0),
        ("m +", "ends too early", 3),
        ("m + * a", "expected a number, a name or '(' but found '*'", 4),
        ("(m + a", "missing ')'", 0),
        ("m + a)", "unmatched ')'", 5),
        ("2m", "missing operator before 'm'", 1),
        ("m (a)", "m is not a function: write m*(...)", 2),
        ("2 (a)", "missing operator before '('", 2),
        ("m, a", "',' only separates the arguments", 1),
        ("b + m", "unknown name 'b'", 0),
        ("thta", "did you mean 'theta'?", 0),
        ("m'", "m is a parameter: only coordinates have velocities", 1),
        ("t'", "t is time", 1),
        ("pi'", "pi is a constant", 2),
        ("x''", "derivative of order 2", 2),
        ("(x)'", "a prime ' may only follow a coordinate name", 3),
        ("'x", "a prime ' may only follow a coordinate name", 0),
        ("sin", "sin is a function: write sin(...)", 0),
        ("sin(x, m)", "sin takes 1 argument, got 2", 0),
        ("atan2(x)", "atan2 takes 2 arguments, got 1", 0),
        ("sin()", "sin takes 1 argument, got 0", 0),
        ("foo(x)", "unknown function 'foo'", 0),
        ("sinn(x)", "did you mean 'sin'?", 0),
        ("m(x)", "m is not a function: write m*(...)", 1),
        ("m.a", "attribute access is not part of the syntax", 1),
        ("x[0]", "brackets are not part of the syntax", 1),
        ("x = 1", "'=' is not part of an expression", 2),
        ("m % a", "'%' is not an operator here", 2),
        ("m; a", "';' is not part of the syntax", 1),
        ("m # note", "comments belong in the TOML file", 2),
        ("θ", "only ASCII letters, digits and operators", 0),
        ("m\x00", "unexpected character '\\x00'", 1),
        ("_x", "names may not start with _", 0),
        ("1/0", "undefined here", 1),
        ("log(0)", "undefined here", 0),
        ("tan(pi/2)", "undefined here", 0),
        ("0^-1", "undefined here", 1),
        ("atan2(m, a,)", "a trailing comma after the last argument of atan2", 10),
        ("sin(x,)", "a trailing comma", 5),
        ("x '", "a space before the prime: write x'", 1),
        ("theta\t'", "a space before the prime", 5),
        ("x' '", "a space before the prime: write x''", 2),
        ("sqrt(-1)*x", "not a finite real number", 0),
        ("m + exp(5000)", "this constant is about 10^2171 in size", 4),
        ("tan(t - tan(sinh(1e400)))", "more than 10^(10^399) in size", 12),
        ("cosh((x + t)^4)", "the argument of cosh is too large", 0),
    ],
)
def test_errors_name_the_column(text: str, reason: str, column: int) -> None:
    exc = error(text)
    assert reason in exc.reason
    assert exc.column == column
    assert exc.text == text
    assert caret_column(exc) == column
    assert isinstance(exc, SystemFileError) and isinstance(exc, ValueError)


@pytest.mark.parametrize(
    "text, kind",
    [
        ("m +", "syntax"),
        ("m x", "syntax"),
        ("sin(x,)", "syntax"),
        ("x '", "syntax"),
        ("x''", "syntax"),
        ("b", "name"),
        ("m'", "name"),
        ("foo(x)", "name"),
        ("sin", "name"),
        ("9^9^9^9", "limit"),
        ("1e401", "limit"),
        ("exp(5000)", "limit"),
        ("sinh((x + t)^4)", "limit"),
        ("sinh(theta*cosh(tanh(acos(a)^1000)))", "limit"),  # acos(a) is complex for |a| > 1
        ("(m + a + x + theta)^1000", "limit"),
        ("(" * 60 + "m" + ")" * 60, "limit"),
        ("1/0", "value"),
        ("log(0)", "value"),
        ("acos(2)", "value"),
        ("(-8)^(1/3)", "value"),
    ],
)
def test_error_kinds(text: str, kind: str) -> None:
    assert error(text).kind == kind


def test_bounded_constants_and_hyperbolic_arguments_are_accepted() -> None:
    assert P("exp(2800)") == sp.exp(2800)  # 2^4040: just below the limit
    assert P("sinh((x + t)^3)") == sp.sinh((x + t) ** 3)  # 20 terms in re/im parts
    assert P("tanh(a*x')") == sp.tanh(a * x.diff(t))
    assert P("sinh(x*acos(a)^3)") == sp.sinh(x * sp.acos(a) ** 3)
    assert P("sin(10^300)^1000") == sp.sin(sp.Integer(10) ** 300) ** 1000
    assert P("x*exp(-5000)") == x * sp.exp(-5000)  # tiny constants are fine
    # ... but not exp(-1e400): SymPy's polynomial code stores it as E^-(10^400), a list that long
    assert error("x*exp(-1e400)").kind == "limit"


def test_error_rendering() -> None:
    exc = error("m/2*x'^2 + b")
    text = str(exc)
    assert text.splitlines()[:3] == [
        "unknown name 'b'",
        "    m/2*x'^2 + b",
        "               ^",
    ]
    assert "Known names: parameters m, a; coordinates x, theta" in text
    assert "functions sin, cos" in text
    located = exc.located(source="knife.toml", key="[energy] T")
    assert str(located).startswith("knife.toml: [energy] T: unknown name 'b'")
    assert located.column == exc.column and located.allowed == exc.allowed


def test_error_excerpt_of_a_long_line() -> None:
    text = "m + " * 100 + "b" + " + m" * 100
    exc = error(text)
    shown, caret = str(exc).splitlines()[1:3]
    assert len(shown) < 90
    assert shown[caret.index("^")] == "b"


def test_error_on_a_later_line() -> None:
    exc = error("m +\n  b")
    shown, caret = str(exc).splitlines()[1:3]
    assert shown == "      b" and caret.index("^") == 6


def test_errors_pickle() -> None:
    import pickle

    exc = error("9^9^9^9").located(source="f.toml", key="[energy] T")
    again = pickle.loads(pickle.dumps(exc))
    assert type(again) is ParseError and str(again) == str(exc) and again.kind == exc.kind == "limit"


# ---------------------------------------------------------------------------- global state
def test_preserved_state_restores_mpmath_after_the_workprec_overflow() -> None:
    """The root cause of the leaked precision, without the parser: mpmath.workprec sets prec,
    then fails computing dps for an astronomically large one, and its __exit__ never runs."""
    import mpmath

    before = (mpmath.mp.prec, mpmath.mp.dps)
    with pytest.raises(OverflowError), parser.preserved_state(), mpmath.workprec(10**400):
        pass  # pragma: no cover - __enter__ raises
    assert (mpmath.mp.prec, mpmath.mp.dps) == before


def test_preserved_state_reads_with_sympy_defaults() -> None:
    from sympy.core.parameters import global_parameters

    with sp.evaluate(False):
        assert P("2*m + 3*m") == 5 * m  # evaluated although the caller's block is not
        assert global_parameters.evaluate is False
    assert global_parameters.evaluate is True


def test_sympy_failures_become_parse_errors(monkeypatch: pytest.MonkeyPatch) -> None:
    def broken(arg: sp.Expr) -> sp.Expr:
        raise ZeroDivisionError("deep inside SymPy")

    monkeypatch.setitem(parser._SYMPY_FUNCTIONS, "atan", broken)
    exc = error("m + atan(x)")
    assert exc.kind == "internal" and "ZeroDivisionError: deep inside SymPy" in exc.reason
    assert exc.column == 10 and exc.text == "m + atan(x)"
    assert isinstance(exc.__cause__, ZeroDivisionError)


@pytest.mark.parametrize(
    "name, reason",
    [
        ("t", "reserved (time)"),
        ("pi", "reserved (a constant)"),
        ("sqrt", "reserved (a function)"),
        ("_x", "names may not start with _"),
        ("__class__", "names may not start with _"),
        ("x y", "not a valid name"),
        ("x'", "not a valid name"),
        ("1x", "not a valid name"),
        ("θ", "not a valid name"),
        ("", "not a valid name"),
        ("a" * 65, "longer than 64"),
        (3, "must be a string"),
    ],
)
def test_check_name(name: object, reason: str) -> None:
    with pytest.raises(ParseError, match=reason.replace("(", r"\(").replace(")", r"\)")):
        check_name(name)


def test_check_name_accepts() -> None:
    for name in ("x", "theta_1", "X2", "lambda", "import", "a" * 64):
        assert check_name(name) == name


# ---------------------------------------------------------------------------- limits
def test_limit_length() -> None:
    n = (MAX_EXPRESSION_LENGTH + 1) // 6
    ok = "+".join(["theta"] * n)
    assert len(ok) <= MAX_EXPRESSION_LENGTH and P(ok) == n * theta
    with watched():
        exc = error("m" * (MAX_EXPRESSION_LENGTH + 1))
    assert f"limit {MAX_EXPRESSION_LENGTH}" in exc.reason


def test_limit_tokens() -> None:
    n = MAX_TOKENS // 2 + 1
    text = "+".join(["1"] * n)
    assert len(text) <= MAX_EXPRESSION_LENGTH
    with watched():
        exc = error(text)
    assert f"more than {MAX_TOKENS} tokens" in exc.reason


def test_limit_depth() -> None:
    deep_ok = "(" * (MAX_DEPTH - 1) + "m" + ")" * (MAX_DEPTH - 1)
    assert P(deep_ok) == m
    for text in (
        "(" * (MAX_DEPTH + 1) + "m" + ")" * (MAX_DEPTH + 1),
        "-" * (MAX_DEPTH + 1) + "m",
        "sin(" * (MAX_DEPTH + 1) + "m" + ")" * (MAX_DEPTH + 1),
        "^".join(["m"] * (MAX_DEPTH + 2)),
    ):
        with watched():
            exc = error(text)
        assert f"more than {MAX_DEPTH} levels" in exc.reason


def test_limit_exponent() -> None:
    assert P(f"x^{MAX_EXPONENT}") == x**MAX_EXPONENT
    assert P("2^1000") == sp.Integer(2) ** 1000
    for text in (f"x^{MAX_EXPONENT + 1}", "x^-1001", "x^(1/1001)", "2^(x + 1001)", "x^(2^11)"):
        with watched():
            exc = error(text)
        assert "the exponent is too large" in exc.reason


def test_limit_number_size() -> None:
    for text, reason in (
        ("(3^1000)^3", "about 4755 bits"),
        ("(2^1000)^5", "bits"),
        ("(2^1000*m)^5", "bits"),
        ("1" * (MAX_LITERAL_DIGITS + 1), f"more than {MAX_LITERAL_DIGITS} digits"),
        ("1e401", "exponent of a number"),
        ("1e99999999999999999", "exponent of a number"),
        ("10^300*10^300*10^300*10^300*10^300", "too large to multiply"),
        ("(2^1000*7^300)^(1/2)", "bits"),
        ("12345678901^(1/97)", "exact root of a large number"),
        ("1/3^500 + 1/5^500 + 1/7^500 + 1/11^500", f"more than {MAX_NUMBER_BITS} bits"),
    ):
        with watched():
            exc = error(text)
        assert reason in exc.reason, (text, exc.reason)


def test_limit_expansion() -> None:
    assert P("(m + a + x)^20") == (m + a + x) ** 20  # 231 terms
    for text in (
        "(m + a + x + theta)^1000",
        "(m + a)^999 * (m + x)^999",
        "(m+a+x+theta+t)^30 / 2",
        "1/(m + a + x + theta)^100",
    ):
        with watched():
            exc = error(text)
        assert f"more than {MAX_EXPANDED_TERMS} terms" in exc.reason


@pytest.mark.parametrize(
    "text",
    [
        "9^9^9^9",
        "9**9**9**9",
        "2^2^2^2^2^2",
        "(((((((9^9)^9)^9)^9)^9)^9)^9)",
        "10^10^10",
        "x^(9^9^9)",
        "(9^9^9)*x",
        "exp(exp(exp(exp(10^300))))",
        "sin(10^300)^1000",
        "sqrt(" * 40 + "2" + ")" * 40,
        "(" * 100_000 + "x" + ")" * 100_000,
        "(" * 40 + "x" + ")" * 40 + "^1000",
        "-" * 100_000 + "x",
        "x" * 1_000_000,
        "1+" * 500_000 + "1",
        "2^(1/3)*3^(1/5)*5^(1/7)*7^(1/11)*11^(1/13)*13^(1/17)*17^(1/19)*19^(1/23)",
        "(m+a+x+theta+t+1)^1000",
        "abs(sign(exp(pi*sqrt(163)) - 640320^3 - 744))",
        "atan2(0, 0)",
    ],
)
def test_hostile_input_is_refused_fast(text: str) -> None:
    safe_parse(text)


# ---------------------------------------------------------------------------- no code runs
HOSTILE = [
    "__import__('os').system('touch {canary}')",
    '__import__("os").system("touch {canary}")',
    'exec(\'open("{canary}", "w")\')',
    "eval('1')",
    "open('{canary}', 'w')",
    "().__class__.__bases__[0].__subclasses__()",
    "x.__class__",
    "x.__init__.__globals__",
    "sin.__globals__['__builtins__']",
    "lambda: 0",
    "(lambda q: q)(1)",
    "[c for c in ()]",
    "{c: 1 for c in ()}",
    "x if m else a",
    "getattr(x, 'diff')",
    "globals()",
    "__builtins__",
    "__import__",
    "import os",
    "x; import os",
    "f'{x}'",
    "b'x'",
    "m := 1",
    "x @ m",
    "Symbol('x')",
    "S('x')",
    "Function('f')(t)",
    "sympify('x')",
    "Integer(2)",
    "x.diff(t)",
    "dynamicsymbols('q')",
    "\\x41",
    "m\\\n+a",
    "ｍ",  # full-width letter
    "１",  # full-width digit
    "٣",  # Arabic-Indic digit
    "m²",
    "m\u00a0+ a",  # no-break space
    "m\u2028+ a",
    "m\x0c+ a",
    "𝐱",  # mathematical bold x
]


@pytest.mark.parametrize("template", HOSTILE)
def test_hostile_text_runs_nothing(template: str, tmp_path: Path) -> None:
    canary = tmp_path / "canary"
    text = template.replace("{canary}", str(canary))
    assert safe_parse(text) is None
    assert not canary.exists()


def test_source_calls_no_evaluator() -> None:
    """parser.py and files.py never call an evaluator or a dynamic attribute lookup."""
    banned = {
        "eval",
        "exec",
        "compile",
        "sympify",
        "parse_expr",
        "__import__",
        "getattr",
        "setattr",
        "lambdify",
        "S",
        "import_module",
        "system",
        "Popen",
        "loads_pickle",
    }
    for module in ("parser.py", "files.py"):
        tree = ast.parse((SRC / module).read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if not isinstance(node, ast.Call):
                continue
            func = node.func
            if isinstance(func, ast.Name):
                assert func.id not in banned, f"{module}:{node.lineno} calls {func.id}"
            elif isinstance(func, ast.Attribute):
                owner = func.value.id if isinstance(func.value, ast.Name) else None
                if (owner, func.attr) == ("re", "compile"):  # regular expressions only
                    continue
                assert func.attr not in banned, f"{module}:{node.lineno} calls {func.attr}"


# ---------------------------------------------------------------------------- properties
# Parsing takes milliseconds, so the safety properties run many more examples than the
# project's default profile (and scale up with HYPOTHESIS_PROFILE=thorough).
MANY = settings(max_examples=max(300, settings.default.max_examples * 10))


@MANY
@given(st.text(max_size=300))
def test_any_text_parses_or_is_refused(text: str) -> None:
    result = safe_parse(text)
    assert result is None or isinstance(result, sp.Expr)


TOKENS = [
    "x",
    "theta",
    "m",
    "a",
    "t",
    "pi",
    "E",
    "x'",
    "theta'",
    "'",
    "0",
    "1",
    "2",
    "9",
    "0.5",
    "1e3",
    "1000",
    "+",
    "-",
    "*",
    "/",
    "^",
    "**",
    "(",
    ")",
    ",",
    " ",
    "sin(",
    "sqrt(",
    "atan2(",
    "exp(",
    "log(",
    "abs(",
    "__import__",
    "os",
    ".",
    "[",
    "]",
    "lambda",
    ":",
    "=",
    "'s'",
    '"',
    "{",
    "}",
    "_",
    "b",
    "import",
]


@MANY
@given(st.lists(st.sampled_from(TOKENS), max_size=60))
def test_token_soup(tokens: list[str]) -> None:
    result = safe_parse("".join(tokens))
    assert result is None or isinstance(result, sp.Expr)


# A tiny reference interpreter: random expression trees, written out with random spelling,
# parsed, and evaluated at a point — the parser must agree with Python's float arithmetic.
VALUES = {"m": 1.3, "a": -0.7, "x": 0.4, "theta": 1.1, "x'": -0.9, "theta'": 0.6, "t": 2.5}
SUBS = {m: 1.3, a: -0.7, x.diff(t): -0.9, theta.diff(t): 0.6, x: 0.4, theta: 1.1, t: 2.5}
UNARY = {
    "sin": math.sin,
    "cos": math.cos,
    "atan": math.atan,
    "exp": math.exp,
    "tanh": math.tanh,
    "abs": abs,
    "sqrt": lambda v: math.sqrt(abs(v)),
    "sign": lambda v: float((v > 0) - (v < 0)),
}


def trees(depth: int = 4) -> st.SearchStrategy:
    leaves = st.one_of(
        st.sampled_from(sorted(VALUES)).map(lambda n: ("name", n)),
        st.integers(0, 20).map(lambda k: ("int", k)),
        st.sampled_from(["0.5", "1.25", "2e-1", ".75"]).map(lambda s: ("dec", s)),
    )

    def extend(children: st.SearchStrategy) -> st.SearchStrategy:
        return st.one_of(
            st.tuples(st.sampled_from(["+", "-", "*", "/"]), children, children),
            st.tuples(st.just("^"), children, st.integers(0, 3)),
            st.tuples(st.just("neg"), children),
            st.tuples(st.sampled_from(sorted(UNARY)), children),
        )

    return st.recursive(leaves, extend, max_leaves=12)


def render(tree: tuple, draw_space: st.DataObject) -> str:
    def sp_() -> str:
        return draw_space.draw(st.sampled_from(["", " ", "  "]))

    kind = tree[0]
    if kind in ("name", "dec"):
        return tree[1]
    if kind == "int":
        return str(tree[1])
    if kind in "+-*/":
        return f"({render(tree[1], draw_space)}{sp_()}{kind}{sp_()}{render(tree[2], draw_space)})"
    if kind == "^":
        op = draw_space.draw(st.sampled_from(["^", "**"]))
        return f"({render(tree[1], draw_space)}){op}{tree[2]}"
    if kind == "neg":
        return f"(-{render(tree[1], draw_space)})"
    arg = render(tree[1], draw_space)
    return f"{kind}(abs({arg}))" if kind == "sqrt" else f"{kind}({arg})"


def evaluate(tree: tuple) -> float:
    kind = tree[0]
    if kind == "name":
        return VALUES[tree[1]]
    if kind == "int":
        return float(tree[1])
    if kind == "dec":
        return float(tree[1])
    if kind == "neg":
        return -evaluate(tree[1])
    if kind == "^":
        return evaluate(tree[1]) ** tree[2]
    if kind in "+-*/":
        u, v = evaluate(tree[1]), evaluate(tree[2])
        return {"+": u + v, "-": u - v, "*": u * v, "/": u / v if v != 0 else math.inf}[kind]
    return UNARY[kind](evaluate(tree[1]))


@settings(
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
    max_examples=max(100, settings.default.max_examples * 5),
)
@given(trees(), st.data())
def test_parser_agrees_with_a_reference_interpreter(tree: tuple, data: st.DataObject) -> None:
    text = render(tree, data)
    try:
        expected = evaluate(tree)
    except (OverflowError, ValueError, ZeroDivisionError):
        expected = math.nan
    result = safe_parse(text)
    if result is None or not math.isfinite(expected) or abs(expected) > 1e12:
        return  # a division by zero or a limit: refused, which is fine
    value = complex(result.xreplace({k: sp.Float(v) for k, v in SUBS.items()}).evalf(30))
    assert value.imag == 0
    assert value.real == pytest.approx(expected, rel=1e-9, abs=1e-9), text


@MANY
@given(st.text(alphabet="x'()^*+-/0123456789.e sincoqrtE,", max_size=80))
def test_grammar_alphabet_fuzz(text: str) -> None:
    safe_parse(text)


# ---------------------------------------------------------------------------- atheris (optional)
def test_atheris_fuzz(tmp_path: Path) -> None:
    """Coverage-guided fuzzing of the parser when atheris is installed (skipped otherwise)."""
    pytest.importorskip("atheris")
    harness = tmp_path / "fuzz_parser.py"
    harness.write_text(
        textwrap.dedent(
            """
            import sys
            import atheris

            with atheris.instrument_imports(include=["chaplygin.io.parser"]):
                from chaplygin.io import parser

            NAMES = parser.Names.build(["m", "a"], ["x", "theta"])

            def one(data):
                text = atheris.FuzzedDataProvider(data).ConsumeUnicodeNoSurrogates(400)
                try:
                    parser.parse_expression(text, NAMES)
                except parser.ParseError:
                    pass

            atheris.Setup(sys.argv, one)
            atheris.Fuzz()
            """
        ),
        encoding="utf-8",
    )
    corpus = tmp_path / "corpus"
    corpus.mkdir()
    for k, seed in enumerate(
        ["m/2*(x'^2 + theta'^2)", "9^9^9", "sqrt(2)^(1/3)*atan2(x, 1.5e-3)", "(a+m)^10"]
    ):
        (corpus / f"seed{k}").write_text(seed, encoding="utf-8")
    run = subprocess.run(
        [
            sys.executable,
            str(harness),
            str(corpus),
            "-runs=5000",
            "-timeout=2",
            "-max_len=400",
            "-rss_limit_mb=4096",
        ],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
        check=False,
    )
    assert run.returncode == 0, run.stderr[-3000:]
