"""Every command's warm run: the same bytes as the cold one, without loading the system again.

A second run of ``check``, ``compare``, ``report``, ``export`` and ``stability`` replays the
result the first stored (chaplygin.apps._replay); ``derive`` prints its stored text and
``simulate`` runs its stored plan.  Each check runs a command cold in an empty cache, then
warm with the loading of the system file made to fail: the warm run must succeed with the same
stdout, stderr and output files, so it derived nothing (it never even read the system).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

import chaplygin.apps.cli as cli
from chaplygin.apps.cli import app
from chaplygin.numeric import cache

runner = CliRunner()


@pytest.fixture
def sleigh(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The gallery's Chaplygin sleigh as a system file, and an empty cache."""
    monkeypatch.setenv("CHAPLYGIN_CACHE", str(tmp_path / "cache"))
    result = runner.invoke(app, ["examples", "show", "chaplygin-sleigh"])
    assert result.exit_code == 0, result.output
    path = tmp_path / "sleigh.toml"
    path.write_text(result.stdout, encoding="utf-8")
    return path


def commands(file: Path, out: Path) -> dict[str, list[str]]:
    f = str(file)
    return {
        "check": ["check", f],
        "derive": ["derive", f],
        "simulate": ["simulate", f, "-t", "2", "-n", "21", "-o", str(out / "run.csv")],
        "compare": ["compare", f, "-t", "1", "-n", "21", "-o", str(out / "compare")],
        "report": ["report", f, "-t", "1", "-n", "21", "-o", str(out / "report.html")],
        "export": ["export", f, "--to", "c", "--jacobian", "-o", str(out / "model.c")],
        "stability": ["stability", f, "--at", "theta=0,x'=1.5,theta'=0", "-o", str(out / "stability.json")],
    }


def outputs(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def run(args: list[str]) -> tuple[int, str, str]:
    result = runner.invoke(app, args)
    return result.exit_code, result.stdout, result.stderr


class Loads:
    """Counts the loads of a system file (``cli._load``); ``fail`` makes each one raise."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, fail: bool = False) -> None:
        self.count, real = 0, cli._load

        def load(spec: str) -> object:
            self.count += 1
            if fail:
                raise AssertionError(f"the warm run loaded {spec}")
            return real(spec)

        monkeypatch.setattr(cli, "_load", load)


@pytest.mark.parametrize(
    "command", ["check", "derive", "simulate", "compare", "report", "export", "stability"]
)
def test_a_warm_run_prints_and_writes_the_same_bytes_without_loading_the_system(
    sleigh: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, command: str
) -> None:
    """main e48c17f: check, compare, report, export and stability loaded and derived again."""
    out = tmp_path / "out"
    (out / "compare").mkdir(parents=True)  # (a run that creates its folder says so: not replayed)
    args = commands(sleigh, out)[command]
    cold = run(args)
    assert cold[0] == 0, cold
    written = outputs(out)
    Loads(monkeypatch, fail=True)
    warm = run([*args, "--force"] if command not in ("check", "derive") else args)
    assert warm == cold
    assert outputs(out) == written


def test_a_changed_file_option_or_version_misses(
    sleigh: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    loads = Loads(monkeypatch)
    args = ["export", str(sleigh), "--to", "python"]
    first = run(args)
    assert first[0] == 0 and loads.count == 1
    assert run(args) == first and loads.count == 1  # the hit
    assert run([*args, "--prefix", "sleigh_"])[1] != first[1] and loads.count == 2  # another option
    assert run([*args, "--form", "new"])[0] == 0 and loads.count == 3  # another form
    assert run([*args, "--model", "voronets"])[0] == 0 and loads.count == 4  # another model
    sleigh.write_text(sleigh.read_text(encoding="utf-8").replace("m = 1.0", "m = 2.0"), encoding="utf-8")
    assert run(args)[0] == 0 and loads.count == 5  # another file
    monkeypatch.setattr(cache, "_version", lambda: "another version")
    assert run(args)[0] == 0 and loads.count == 6  # another chaplygin
    monkeypatch.setenv("CHAPLYGIN_MODEL_CACHE", "off")  # the caches switched off: nothing replayed
    assert run(args)[0] == 0 and run(args)[0] == 0 and loads.count == 8


@pytest.mark.parametrize("damage", ["truncate", "garbage", "edit"])
def test_a_damaged_entry_is_ignored_and_rebuilt(
    sleigh: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, damage: str
) -> None:
    loads = Loads(monkeypatch)
    args = ["check", str(sleigh)]
    first = run(args)
    entries = sorted((tmp_path / "cache" / "derivations").glob("*.json"))
    assert first[0] == 0 and entries
    for entry in entries:
        raw = entry.read_bytes()
        entry.write_bytes(
            raw[: len(raw) // 2]
            if damage == "truncate"
            else b"\x00garbage"
            if damage == "garbage"
            # a changed answer under a valid-looking head: the digest no longer matches
            else raw.replace(b"Chaplygin system", b"Chetaev system")
        )
    assert run(args) == first and loads.count == 2  # run in full, the same answer
    assert run(args) == first and loads.count == 2  # and stored again


def test_an_existing_output_without_force_is_refused_as_before(
    sleigh: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    target = tmp_path / "model.c"
    args = ["export", str(sleigh), "--to", "c", "-o", str(target)]
    assert run(args)[0] == 0
    target.write_text("mine", encoding="utf-8")
    code, _, err = run(args)
    assert code == 1 and "already exists; pass --force to overwrite" in err
    assert target.read_text(encoding="utf-8") == "mine"


def test_a_missing_output_folder_is_created_and_said(
    sleigh: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The line 'created the folder …' belongs to the run that creates it, cold or warm."""
    args = ["export", str(sleigh), "--to", "c"]
    first = run([*args, "-o", str(tmp_path / "a" / "model.c")])
    assert first[0] == 0 and "created the folder" in first[1]
    again = run([*args, "-o", str(tmp_path / "a" / "model.c"), "--force"])
    assert again[0] == 0 and "created" not in again[1]
    assert again[1] == first[1].split("created")[0]
    loads = Loads(monkeypatch)
    elsewhere = run([*args, "-o", str(tmp_path / "b" / "model.c")])  # another path: another key
    assert elsewhere[0] == 0 and "created the folder" in elsewhere[1] and loads.count == 1


def test_warnings_are_replayed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A file without initial velocities: the warning that they are 0, cold and warm."""
    monkeypatch.setenv("CHAPLYGIN_CACHE", str(tmp_path / "cache"))
    path = tmp_path / "knife.toml"
    path.write_text(
        'name = "knife"\ncoordinates = ["x", "y", "phi"]\n[parameters]\nm = 1.0\nJ = 2.0\n'
        '[energy]\nT = "m/2*(x\'^2 + y\'^2) + J/2*phi\'^2"\n[constraints]\n"y\'" = "tan(phi)*x\'"\n'
        "[initial]\nphi = 0.1\n",
        encoding="utf-8",
    )
    args = ["compare", str(path), "-t", "1", "-n", "11"]
    cold = run(args)
    assert cold[0] == 0 and "warning:" in cold[2], cold
    Loads(monkeypatch, fail=True)
    assert run(args) == cold


def test_a_warm_sweep_derives_nothing(sleigh: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A sweep whose model is compiled in the cache runs it without deriving its equations (main
    e48c17f derived them again to see that the model applies). Its summary and rows hold wall
    times, so a sweep is run, not replayed: the rows but those are the same."""
    import pyarrow.parquet as pq

    from chaplygin.core.system import System

    out = tmp_path / "sweep.parquet"
    args = ["sweep", str(sleigh), "-g", "theta'=0.1,0.2", "-t", "1", "-n", "11", "-o", str(out), "--force"]
    assert run(args)[0] == 0
    cold = pq.read_table(out).drop(["wall_time"])

    def derive(*args: object, **kwargs: object) -> object:
        raise AssertionError("the warm sweep derived")

    monkeypatch.setattr(System, "equations", derive)
    warm = run(args)
    assert warm[0] == 0, warm
    assert pq.read_table(out).drop(["wall_time"]).equals(cold)


@pytest.mark.parametrize("command", ["check", "simulate"])
def test_a_file_saved_again_during_a_command_leaves_no_result_under_its_old_bytes(
    command: str, sleigh: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The file is saved again (another name, another start) just after the command read the bytes
    its cache key is made of: the command answers for those bytes, and a later run of them
    replays that answer, not the other file's (the system was read a second time, from the new
    bytes, and stored under the old ones)."""
    out = tmp_path / "out"
    out.mkdir()
    args = commands(sleigh, out)[command] + (["--force"] if command != "check" else [])
    original = sleigh.read_text(encoding="utf-8")
    assert 'name = "Chaplygin sleigh' in original and "\ntheta = 0.0\n" in original
    edited = original.replace('name = "Chaplygin sleigh', 'name = "EDITED sleigh').replace(
        "\ntheta = 0.0\n", "\ntheta = 0.5\n"
    )
    assert edited != original
    clean = run(args), outputs(out)  # the original bytes, alone in a fresh cache
    monkeypatch.setenv("CHAPLYGIN_CACHE", str(tmp_path / "raced"))
    real = cli._definition

    def saved_meanwhile(spec: str) -> bytes | None:
        raw = real(spec)
        sleigh.write_text(edited, encoding="utf-8")
        return raw

    monkeypatch.setattr(cli, "_definition", saved_meanwhile)
    raced = run(args), outputs(out)
    monkeypatch.setattr(cli, "_definition", real)
    sleigh.write_text(original, encoding="utf-8")
    assert raced == clean
    assert (run(args), outputs(out)) == clean  # warm: the original's answer


def test_model_cache_off_makes_no_plan_and_reads_no_summary(
    sleigh: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``CHAPLYGIN_MODEL_CACHE=off``: every process derives anew, a loaded file included (a run
    plan and a file summary were stored and used all the same)."""
    import chaplygin
    from chaplygin.io import _file

    monkeypatch.setenv("CHAPLYGIN_MODEL_CACHE", "off")
    for _ in range(2):
        loaded = _file.load(sleigh)
        assert "system" in vars(loaded)  # read and validated, not a stored summary
        chaplygin.simulate(loaded, "chaplygin", 1.0)
    monkeypatch.setenv("CHAPLYGIN_MODEL_CACHE", "on")
    chaplygin.simulate(_file.load(sleigh), "chaplygin", 1.0)  # the cache on again: a summary is kept
    assert "system" not in vars(_file.load(sleigh))


def test_a_replay_onto_a_stdout_that_cannot_take_the_text_says_so(sleigh: Path, tmp_path: Path) -> None:
    """A replayed result printed to an ASCII-only stdout: the full path's one-line error, not a
    traceback from the replay."""
    import os
    import subprocess
    import sys

    board = tmp_path / "board.toml"  # (its integrability conditions print ∂)
    board.write_bytes((Path(__file__).parents[1] / "benchmarks/systems/snakeboard_spring.toml").read_bytes())
    cmd = [sys.executable, "-m", "chaplygin", "check", str(board)]
    stored = subprocess.run(cmd, capture_output=True, text=True, encoding="utf-8", check=False)
    assert stored.returncode == 0 and "∂" in stored.stdout, stored.stderr[-600:]
    env = {**os.environ, "PYTHONIOENCODING": "ascii"}
    for _ in range(2):  # the replay, and (stored nothing) the full path after it
        r = subprocess.run(cmd, capture_output=True, text=True, env=env, check=False)
        assert r.returncode == 1 and r.stderr.startswith("error: unexpected UnicodeEncodeError"), r.stderr[
            -600:
        ]
        assert "Traceback" not in r.stderr
