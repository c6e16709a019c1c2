"""The derivation cache: hits equal fresh derivations; corrupt or stale entries are never used."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from chaplygin import cache
from chaplygin.cli import app

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


def test_second_derive_reads_the_entry_and_prints_the_same(cache_dir: Path, tmp_path: Path, monkeypatch) -> None:
    f = tmp_path / "knife.toml"
    f.write_text(KNIFE)
    first = derive(f)
    (entry,) = entries(cache_dir)
    # a hit must not derive: make deriving impossible and ask again
    monkeypatch.setattr("chaplygin.cli._derive_text", lambda *a: pytest.fail("derived despite the cache"))
    assert derive(f) == first
    assert entries(cache_dir) == [entry]
    assert not list(cache_dir.glob(".*.tmp"))  # written atomically, nothing left over


def test_no_cache_neither_reads_nor_writes(cache_dir: Path, tmp_path: Path) -> None:
    f = tmp_path / "knife.toml"
    f.write_text(KNIFE)
    derive(f, "--no-cache")
    assert entries(cache_dir) == []
    first = derive(f)
    (entry,) = entries(cache_dir)
    entry.write_bytes(entry.read_bytes())  # untouched entry; --no-cache must still derive
    assert derive(f, "--no-cache") == first


def test_changed_file_or_options_miss(cache_dir: Path, tmp_path: Path) -> None:
    f = tmp_path / "knife.toml"
    f.write_text(KNIFE)
    a = derive(f)
    f.write_text(KNIFE.replace("J/2*phi'^2", "J/3*phi'^2"))
    b = derive(f)
    assert a != b
    derive(f, "--format", "json")
    assert len(entries(cache_dir)) == 3


@pytest.mark.parametrize(
    "damage",
    [
        lambda raw: raw[: len(raw) // 2],                                  # truncated
        lambda raw: raw.replace(b"phi", b"psi"),                           # edited body
        lambda raw: b"0" * 64 + raw[64:],                                  # wrong digest
        lambda raw: b"not json at all",
        lambda raw: b"",
    ],
)
def test_corrupt_entry_is_discarded_and_rebuilt(cache_dir: Path, tmp_path: Path, damage) -> None:
    f = tmp_path / "knife.toml"
    f.write_text(KNIFE)
    first = derive(f)
    (entry,) = entries(cache_dir)
    entry.write_bytes(damage(entry.read_bytes()))
    k = entry.stem
    assert cache.load(k) is None and not entry.exists()  # detected and deleted
    entry.write_bytes(damage(first.encode()))
    assert derive(f) == first  # rebuilt ...
    assert cache.load(k) + "\n" == first  # ... and stored again, valid


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


def test_unwritable_cache_is_not_an_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv("CHAPLYGIN_CACHE", str(blocker))  # a file where a folder should be
    f = tmp_path / "knife.toml"
    f.write_text(KNIFE)
    assert "Solved" in derive(f)
    assert cache.clear() == 0
