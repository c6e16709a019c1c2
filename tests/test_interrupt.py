"""Ctrl-C stops the compiled loops: ``chaplygin simulate`` piped to files, and ensembles.

Each check starts a fresh process on a warm cache, waits until it has spent half a second of CPU
time beyond what starting takes (so it is integrating), sends SIGINT, and expects it to end with
``KeyboardInterrupt`` (exit status 130) long before the integration could have finished: the runs
asked for take thousands of seconds.  On main d1d83f5 the C and numba loops heard SIGINT only when
the integration ended (a piped ``simulate`` ran on; an ensemble waited for every member).
"""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from subprocesses import SRC

pytestmark = pytest.mark.skipif(
    not Path("/proc/self/stat").exists(), reason="reads the child's CPU time from /proc (Linux)"
)

#: generous bounds for a loaded 2-core machine; an unstoppable run takes thousands of seconds
STARTUP, STOPPING = 120.0, 30.0


def _cpu(pid: int) -> float:
    """CPU seconds (user + system) that process ``pid`` has used so far."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _environment() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": SRC}


def _interrupt_when_busy(child: subprocess.Popen, beyond: float, wait: bool = True) -> None:
    """Send SIGINT once ``child`` has used ``beyond`` + 0.5 CPU seconds; then (``wait``) expect it
    to end within :data:`STOPPING` seconds."""
    deadline = time.monotonic() + STARTUP
    while _cpu(child.pid) < beyond + 0.5:
        assert child.poll() is None, "the run ended before it could be interrupted"
        assert time.monotonic() < deadline, "the run did not get going"
        time.sleep(0.05)
    child.send_signal(signal.SIGINT)
    if wait:
        try:
            child.communicate(timeout=STOPPING)
        except subprocess.TimeoutExpired:
            child.kill()
            child.communicate()
            pytest.fail(f"still running {STOPPING:g} s after SIGINT")


@pytest.mark.parametrize("backend", ["default", "numba"])
def test_ctrl_c_stops_a_piped_simulate(tmp_path: Path, backend: str) -> None:
    """The default backend, and numba (on main 1300154 its loop turned the interrupt into
    ``SystemError: CPUDispatcher(...) returned a result with an exception set``, exit 1)."""
    if backend == "numba":
        pytest.importorskip("numba")
    out = tmp_path / "disk.csv"
    command = [sys.executable, "-m", "chaplygin", "simulate", "example:rolling-disk", "--out", str(out)]
    if backend != "default":
        command += ["--backend", backend]
    before = os.times()
    warm = subprocess.run(
        [*command, "--t-end", "1"],
        capture_output=True,
        text=True,
        env=_environment(),
        timeout=600,
        check=False,
    )
    assert warm.returncode == 0, warm.stderr
    after = os.times()
    startup = after.children_user + after.children_system - before.children_user - before.children_system
    out.unlink()
    log = tmp_path / "log"
    with log.open("w") as fh:  # stdout and stderr to a file, not a terminal: no progress display
        child = subprocess.Popen(
            [*command, "--t-end", "1e8", "--time-limit", "0"], stdout=fh, stderr=fh, env=_environment()
        )
        _interrupt_when_busy(child, startup)
    assert child.returncode == 130, log.read_text()
    assert "interrupted" in log.read_text()
    assert not out.exists() and list(tmp_path.iterdir()) == [log]  # no output, not even a temporary one


ENSEMBLE = r"""
import sys
from chaplygin import examples, simulate
from chaplygin.numeric.ensemble import simulate_ensemble

entry = examples.get("rolling-disk")
system = entry.constructor()
for backend, threads in (pair.split(":") for pair in sys.argv[1:]):
    if threads == "gauss4":  # a symmetric method's compiled kernel, one long call
        run = lambda t: simulate(system, "voronets", t, entry.initial, entry.parameters, backend=backend,
                                 method="gauss4", step=1e-3, samples=3, time_limit=None)
        long = 1e6  # 10⁹ steps
    else:
        run = lambda t: simulate_ensemble(system, "voronets", t, [entry.initial] * 4, entry.parameters,
                                          backend=backend, max_steps=0, threads=int(threads), time_limit=None)
        long = 1e8  # hours
    run(0.01)
    print("ready", flush=True)
    try:
        run(long)
    except KeyboardInterrupt:
        print("interrupted", flush=True)
"""


def test_ctrl_c_stops_an_ensemble_and_a_symmetric_run() -> None:
    """The C loop on two threads, the numba loop on one (a worker thread: the main thread waits),
    the Gauss-Legendre kernel (numba; on main it held the main thread to the end)."""
    from chaplygin.numeric._ckernel import Unavailable, compiler

    runs = ["numba:1", "numba:gauss4"]
    try:
        compiler()
        runs.insert(0, "c:2")
    except Unavailable:
        pass
    child = subprocess.Popen(
        [sys.executable, "-c", ENSEMBLE, *runs],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=_environment(),
    )
    try:
        for run in runs:
            assert _line(child, STARTUP) == "ready"
            _interrupt_when_busy(child, _cpu(child.pid), wait=False)
            assert _line(child, STOPPING) == "interrupted", (
                f"{run}: still running {STOPPING:g} s after SIGINT"
            )
        assert child.wait(timeout=STOPPING) == 0
    finally:
        child.kill()
        child.communicate()


def _line(child: subprocess.Popen, timeout: float) -> str:
    """The child's next line of output, or "" if none comes within ``timeout`` seconds."""
    assert child.stdout is not None
    ready, _, _ = select.select([child.stdout], [], [], timeout)
    return child.stdout.readline().strip() if ready else ""


def test_an_interrupt_that_numba_turned_into_a_system_error_is_an_interrupt() -> None:
    """Ctrl-C inside a numba call from the main thread (numba runs Python to box its results)
    comes out as a ``SystemError`` whose context is the ``KeyboardInterrupt``: the command line
    still says "interrupted" with exit 130 (on main 1300154: "unexpected SystemError", exit 1)."""
    import typer

    from chaplygin.apps import cli

    with pytest.raises(typer.Exit) as caught, cli._errors():
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise SystemError("CPUDispatcher(<function f>) returned a result with an exception set") from None
    assert caught.value.exit_code == 130


def test_ctrl_c_while_the_command_line_starts_is_no_traceback(
    monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """A Ctrl-C during the command line's own imports (before a command handles it): one line,
    status 130, no traceback — in process, and in a child interrupted after 0.02–0.1 CPU seconds
    (its imports; a child killed before Python's handler is in place ends by the signal)."""
    import chaplygin.apps.cli as cli
    from chaplygin.__main__ import run

    def interrupted() -> int:
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "main", interrupted)
    assert run() == 130
    assert capsys.readouterr().err == "interrupted: no output was left half-written.\n"
    for cpu in (0.02, 0.05, 0.1):
        child = subprocess.Popen(
            [sys.executable, "-m", "chaplygin", "examples", "list"],
            env=_environment(),
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        deadline = time.monotonic() + STARTUP
        while child.poll() is None and _cpu(child.pid) < cpu and time.monotonic() < deadline:
            time.sleep(0.002)
        child.send_signal(signal.SIGINT)
        _, err = child.communicate(timeout=STOPPING)
        assert "Traceback" not in err, err[-800:]
        assert child.returncode in (0, 130, -signal.SIGINT), (child.returncode, err[-400:])
