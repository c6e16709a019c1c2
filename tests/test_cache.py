"""The derivation cache: hits equal fresh derivations; corrupt or stale entries are never used."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import pytest
from typer.testing import CliRunner

from chaplygin.apps.cli import app
from chaplygin.numeric import cache
from unwritable import WAYS, unwritable

runner = CliRunner()
KNIFE = """
name = "knife"
coordinates = ["x", "y", "phi"]

[parameters]
m = 1.0
J = 2.0

[energy]
T = "m/2*(x'^2 + y'^2) + J/2*phi'^2"

[constraints]
"y'" = "tan(phi)*x'"
"""


@pytest.fixture
def cache_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("CHAPLYGIN_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache" / "derivations"


def derive(path: Path, *extra: str) -> str:
    result = runner.invoke(app, ["derive", str(path), "--model", "chaplygin", *extra])
    assert result.exit_code == 0, result.output
    return result.stdout


def entries(directory: Path) -> list[Path]:
    return sorted(directory.glob("*.json")) if directory.exists() else []


@pytest.fixture
def derivations(monkeypatch: pytest.MonkeyPatch) -> list[tuple]:
    """Every derivation ``derive`` does (as its arguments); printing does not count."""
    import chaplygin.apps.cli as cli

    calls: list[tuple] = []
    real = cli._derive

    def counting(*args):
        calls.append(args)
        return real(*args)

    monkeypatch.setattr(cli, "_derive", counting)
    return calls


def test_second_derive_reads_the_entry_and_prints_the_same(
    cache_dir: Path, tmp_path: Path, derivations
) -> None:
    f = tmp_path / "knife.toml"
    f.write_text(KNIFE)
    first = derive(f)
    stored = entries(cache_dir)
    assert len(derivations) == 1 and len(stored) == 2  # the derivation, and its text
    assert derive(f) == first
    assert len(derivations) == 1 and entries(cache_dir) == stored
    assert not list(cache_dir.glob(".*.tmp"))  # written atomically, nothing left over


@pytest.mark.parametrize(
    "spec, model, form",
    [
        ("knife", "chaplygin", "classic"),
        ("example:knife-edge", "chetaev", "classic"),  # multipliers
        ("example:knife-edge", "vakonomic_family", "classic"),  # constants c_1
        ("example:rolling-sphere", "lindelof", "new"),
        ("example:turntable-ball", "voronets", "classic"),  # affine constraints
    ],
)
def test_one_derivation_serves_every_format(
    spec: str, model: str, form: str, cache_dir: Path, tmp_path: Path, derivations
) -> None:
    """json, then text, latex and --no-accelerations: derived once, printed as if never cached."""
    if spec == "knife":
        spec = str(tmp_path / "knife.toml")
        Path(spec).write_text(KNIFE)
    requests = [["--format", fmt] for fmt in ("json", "text", "latex")]
    requests += [["--format", fmt, "--no-accelerations"] for fmt in ("text", "json")]

    def run(*extra: str) -> str:
        result = runner.invoke(app, ["derive", spec, "--model", model, "--form", form, *extra])
        assert result.exit_code == 0, result.output
        return result.stdout

    cached = [run(*r) for r in requests]
    assert len(derivations) == 1
    again = [run(*r) for r in requests]  # each format from its own printed entry
    assert again == cached and len(derivations) == 1
    fresh = [run(*r, "--no-cache") for r in requests]
    assert len(derivations) == 1 + len(requests)
    assert cached == fresh
    assert json.loads(cached[0])["accelerations"] and json.loads(cached[4])["accelerations"] is None


def test_latex_is_what_equations_print(cache_dir: Path, derivations) -> None:
    """The LaTeX printed from a cached derivation is Equations.latex() of a fresh one."""
    from chaplygin import examples

    for fmt in ("text", "latex"):
        result = runner.invoke(app, ["derive", "example:rolling-sphere", "--model", "chaplygin", "-f", fmt])
        assert result.exit_code == 0, result.output
    assert len(derivations) == 1
    assert examples.rolling_sphere().equations("chaplygin").latex() in result.stdout.splitlines()


def test_no_cache_neither_reads_nor_writes(cache_dir: Path, tmp_path: Path, derivations) -> None:
    f = tmp_path / "knife.toml"
    f.write_text(KNIFE)
    derive(f, "--no-cache")
    assert entries(cache_dir) == []
    first = derive(f)
    assert derive(f, "--no-cache") == first
    assert len(derivations) == 3


def test_changed_file_or_options_miss(cache_dir: Path, tmp_path: Path, derivations) -> None:
    f = tmp_path / "knife.toml"
    f.write_text(KNIFE)
    a = derive(f)
    f.write_text(KNIFE.replace("J/2*phi'^2", "J/3*phi'^2"))
    b = derive(f)
    assert a != b and len(derivations) == 2
    derive(f, "--form", "new")
    assert len(derivations) == 3
    derive(f, "--format", "json")  # the format is not part of the derivation
    assert len(derivations) == 3


DAMAGES = [
    lambda raw: raw[: len(raw) // 2],  # truncated
    lambda raw: raw.replace(b"phi", b"psi"),  # edited body
    lambda raw: b"0" * 64 + raw[64:],  # wrong digest
    lambda raw: b"not json at all",
    lambda raw: b"",
]


@pytest.mark.parametrize("damage", DAMAGES)
def test_corrupt_entry_is_discarded_and_rebuilt(cache_dir: Path, tmp_path: Path, damage, derivations) -> None:
    f = tmp_path / "knife.toml"
    f.write_text(KNIFE)
    first = derive(f)
    stored = entries(cache_dir)
    for entry in stored:
        entry.write_bytes(damage(entry.read_bytes()))
    for entry in stored:
        assert cache.load(entry.stem) is None and not entry.exists()  # detected and deleted
        entry.write_bytes(damage(first.encode()))
    assert derive(f) == first and len(derivations) == 2  # rebuilt ...
    assert entries(cache_dir) == stored
    assert all(cache.load(entry.stem) is not None for entry in stored)  # ... and stored again, valid


@pytest.mark.parametrize("damage", DAMAGES)
def test_a_damaged_derivation_is_derived_again(cache_dir: Path, tmp_path: Path, damage, derivations) -> None:
    """A damaged derivation entry is a miss for a format not printed yet; a damaged printed entry
    is printed again from the derivation."""
    f = tmp_path / "knife.toml"
    f.write_text(KNIFE)
    first = derive(f)
    (printed,) = [e for e in entries(cache_dir) if isinstance(cache.load(e.stem), str)]
    printed.write_bytes(damage(printed.read_bytes()))
    assert derive(f) == first and len(derivations) == 1  # printed from the derivation
    (derivation,) = [e for e in entries(cache_dir) if isinstance(cache.load(e.stem), dict)]
    derivation.write_bytes(damage(derivation.read_bytes()))
    latex = derive(f, "--format", "latex")
    assert len(derivations) == 2 and latex == derive(f, "--format", "latex", "--no-cache")


def test_stale_entry_from_another_version_is_discarded(cache_dir: Path) -> None:
    k = cache.key("derive", "something")
    assert cache.store(k, "value") is not None
    assert cache.load(k) == "value"
    path = cache.directory() / f"{k}.json"
    digest, body = path.read_bytes().split(b"\n", 1)
    doc = json.loads(body)
    doc["version"] = "0.0.0+old"  # a consistent entry written by other code under this key
    body = json.dumps(doc).encode()
    import hashlib

    path.write_bytes(hashlib.sha256(body).hexdigest().encode() + b"\n" + body)
    assert cache.load(k) is None and not path.exists()


def test_keys_depend_on_every_part_and_the_version() -> None:
    assert cache.key("a", "bc") != cache.key("ab", "c")  # no ambiguity in concatenation
    assert cache.key("a") == cache.key("a")
    assert cache.key(b"x") == cache.key("x")
    assert cache._version().startswith("0.") and "+" in cache._version()


@pytest.mark.parametrize("how", WAYS)
def test_unwritable_cache_falls_back_to_a_private_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, how: str
) -> None:
    """A CHAPLYGIN_CACHE that cannot be written: generated code goes to a private temporary
    cache, with one warning that names the variable (main d1d83f5: 'Permission denied', exit 1)."""
    root = unwritable(tmp_path, how)
    monkeypatch.setenv("CHAPLYGIN_CACHE", str(root))
    out = tmp_path / "knife.csv"
    args = ["simulate", "example:knife-edge", "--t-end", "1", "--samples", "5", "--out", str(out)]
    result = runner.invoke(app, [*args, "--backend", "numpy"])
    assert result.exit_code == 0, result.output
    assert result.stderr.count(f"warning: CHAPLYGIN_CACHE={root} cannot be written") == 1
    assert len(out.read_text().splitlines()) == 6
    fallback = cache.cache_dir()
    assert fallback != root and fallback.is_dir()  # (generated code goes there, unless already imported)
    assert not root.exists() or not any(root.iterdir())
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # said once: the next use is silent
        assert cache.cache_dir() == fallback


def test_unwritable_cache_is_not_an_error_for_derivations(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("CHAPLYGIN_CACHE", str(unwritable(tmp_path, "under a file")))
    f = tmp_path / "knife.toml"
    f.write_text(KNIFE)
    assert "Solved" in derive(f)


# ---------------------------------------------------------------- expressions as data
def test_expressions_round_trip_exactly() -> None:
    import sympy as sp

    from chaplygin import examples

    eqs = examples.turntable_ball().equations("chetaev")
    exprs = [
        *eqs.equations,
        *eqs.accelerations,
        *eqs.accelerations.values(),
        sp.pi * sp.E + sp.I,
        sp.Rational(-3, 7) * sp.Abs(sp.Symbol("w", real=True)) ** sp.Rational(1, 2),
    ]
    data = cache.expressions_to_data(exprs)
    assert data is not None
    back = cache.expressions_from_data(json.loads(json.dumps(data)))
    assert back == exprs and [str(e) for e in back] == [str(e) for e in exprs]
    assert len(data["nodes"]) < sum(sp.count_ops(e, visual=False) + 1 for e in exprs)  # shared nodes once


def test_expressions_it_cannot_store_are_not_cached() -> None:
    import sympy as sp

    assert cache.expressions_to_data([sp.Dummy("x") + 1]) is None
    assert cache.expressions_to_data([sp.Float(0.5) * sp.Symbol("x")]) is None
    assert cache.expressions_to_data([sp.Heaviside(sp.Symbol("x"))]) is None


@pytest.mark.parametrize(
    "data, why",
    [
        ({"nodes": [["eval", "1"]], "roots": [0]}, "unknown kind"),
        ({"nodes": [["Symbol", "x", {}], ["Add", 0, 2]], "roots": [1]}, "out of range"),  # a later node
        ({"nodes": [["Symbol", "x", {}]], "roots": [1]}, "out of range"),
        ({"nodes": [["Symbol", "x", {"real": "yes"}]], "roots": [0]}, "assumptions"),
        ({"nodes": [["Symbol", "", {}]], "roots": [0]}, "name"),
        ({"nodes": [["Rational", 1, 0]], "roots": [0]}, "rational"),
        ({"nodes": [["Constant", "__class__"]], "roots": [0]}, "constant"),
        ({"nodes": [["Add"]]}, "KeyError"),
        ("nodes", "TypeError"),
    ],
)
def test_malformed_expression_data_is_refused(data, why: str) -> None:
    with pytest.raises(ValueError, match=why):
        cache.expressions_from_data(data)
