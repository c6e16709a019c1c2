"""Work that cannot finish in reasonable time is refused, with the estimate, unless asked for.

On main d1d83f5 ``chaplygin simulate example:rolling-disk --t-end 1e300`` ran until killed with a
24-digit time left on its display, a sweep of 10⁶ runs started without a word, and an ensemble
asked for any amount of time or memory.  Each check here shortens the half second of pace that
the estimate waits for (``ESTIMATE_AFTER``) or sets a small ``time_limit``, to stay fast.
"""

from __future__ import annotations

import inspect
from pathlib import Path

import pytest
from typer.testing import CliRunner

import chaplygin
from chaplygin import examples
from chaplygin.apps import cli
from chaplygin.errors import ChaplyginError, InputError
from chaplygin.numeric import simulate as numeric_simulate

runner = CliRunner()
DISK = examples.get("rolling-disk")


@pytest.fixture(autouse=True)
def quick_estimates(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(numeric_simulate, "ESTIMATE_AFTER", 0.05)
    monkeypatch.setattr(numeric_simulate, "PROGRESS_EVERY", 0.02)


def test_the_default_limit_is_an_hour() -> None:
    from chaplygin.apps.sweep import sweep
    from chaplygin.numeric.ensemble import simulate_ensemble

    for api in (numeric_simulate.simulate, simulate_ensemble, sweep):
        assert inspect.signature(api).parameters["time_limit"].default == 3600.0


@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_a_run_that_cannot_finish_is_refused_with_its_estimate(backend: str) -> None:
    if backend == "c":
        from chaplygin.numeric._ckernel import Unavailable, compiler

        try:
            compiler()
        except Unavailable as exc:
            pytest.skip(f"no C compiler: {exc}")
    system = DISK.constructor()
    with pytest.raises(InputError, match=r"t_end = 1e\+300: too long to run: .* more than a year") as caught:
        chaplygin.simulate(
            system, "voronets", 1e300, DISK.initial, DISK.parameters, backend=backend, time_limit=60
        )
    assert "time_limit=None" in str(caught.value)  # the command line says --time-limit 0: test_cli_wording
    with pytest.raises(InputError, match="time_limit"):
        chaplygin.simulate(system, "voronets", 1.0, DISK.initial, DISK.parameters, time_limit=-1.0)


def test_a_symmetric_run_that_cannot_finish_is_refused_with_its_estimate() -> None:
    system = DISK.constructor()
    with pytest.raises(
        InputError, match=r"step: 5e\+09 steps of h = 0.001: too long to run: .* beyond the limit"
    ):
        chaplygin.simulate(system, "voronets", 5e6, DISK.initial, DISK.parameters, backend="numpy",
                           method="gauss4", step=1e-3, samples=3, time_limit=60)  # fmt: skip


def test_the_command_line_refuses_it_and_writes_nothing(tmp_path: Path) -> None:
    out = tmp_path / "r.csv"
    args = ["simulate", "example:rolling-disk", "--t-end", "1e300", "-o", str(out), "--time-limit", "60"]
    result = runner.invoke(cli.app, args)
    assert (
        result.exit_code == 1 and "too long to run" in result.stderr and "more than a year" in result.stderr
    )
    assert not out.exists()


def test_the_time_left_is_never_a_long_number() -> None:
    assert cli._duration(42.4) == "42 s"
    assert cli._duration(185) == "3 min 05 s"
    assert cli._duration(2 * 3600 + 7 * 60) == "2 h 07 min"
    assert cli._duration(12 * 86400) == "12 days"
    for huge in (1e9, 1e300, float("inf"), float("nan")):
        assert cli._duration(huge) == "more than a year"


def test_a_sweep_that_would_take_too_long_stops_after_its_first_runs(tmp_path: Path) -> None:
    from chaplygin.apps.sweep import read_results, sweep

    out = tmp_path / "big.parquet"
    grid = {"x'": "0.1:1:100", "phi'": "0.1:1:100"}  # 10⁴ runs
    with pytest.raises(
        ChaplyginError, match=r"10000 runs: the 9998 left would take about .* the 2 runs done are kept"
    ):
        sweep("example:knife-edge", grid, t_end=1.0, out=out, model="chaplygin", backend="numpy",
              samples=11, scheduler="serial", time_limit=0.01)  # fmt: skip
    assert read_results(out, ["run_id"]).num_rows == 2  # kept: --resume goes on from there


def test_an_ensemble_that_would_take_too_long_is_refused_before_it_starts() -> None:
    from chaplygin.numeric.ensemble import simulate_ensemble

    system = DISK.constructor()
    with pytest.raises(InputError, match=r"this ensemble would take about .* beyond the limit of 1 min 00 s"):
        simulate_ensemble(
            system, "voronets", 1e12, [DISK.initial] * 4, DISK.parameters, max_steps=0, time_limit=60
        )
    # a short one runs as before
    short = simulate_ensemble(system, "voronets", 1.0, [DISK.initial] * 4, DISK.parameters, time_limit=60)
    assert short.success.all()


def test_an_ensemble_whose_samples_would_not_fit_in_memory_is_refused() -> None:
    import os

    from chaplygin.numeric.ensemble import _check_memory

    memory = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    _check_memory(1000, 100, 8)  # 6 MB
    with pytest.raises(InputError, match=r"keep: 1000000 members × \d+ samples × 8 states need about"):
        _check_memory(10**6, memory // (8 * 8 * 10**6) + 1, 8)  # just above the machine's memory


@pytest.mark.parametrize(
    ("options", "said"),
    [
        ({"time_limit": "abc"}, "time_limit = 'abc': give a positive number of seconds, or None"),
        ({"time_limit": -1}, "time_limit = -1: give a positive number of seconds, or None"),
        ({"t_span": float("nan")}, "t_span: the end time = nan is not finite"),
        ({"phi": float("nan")}, "initial_states[0]: phi = nan is not finite; give a finite number"),
        ({"threads": 0}, "threads = 0: give a whole number of threads, 1 or more"),
        ({"threads": -2}, "threads = -2: give a whole number of threads, 1 or more"),
        ({"threads": 1.5}, "threads = 1.5: give a whole number of threads, 1 or more"),
    ],
)
def test_an_ensemble_refuses_options_no_run_can_honour(options: dict, said: str) -> None:
    """On main 1300154 the time limits and thread counts ran without a word, ``t_span = nan``
    said "must be after the start", and ``phi = nan`` said "missing phi"."""
    from chaplygin.numeric.ensemble import simulate_ensemble

    initial = {**DISK.initial, "phi": options.pop("phi", DISK.initial["phi"])}
    t_span = options.pop("t_span", 0.01)
    with pytest.raises(InputError) as caught:
        simulate_ensemble(DISK.constructor(), "voronets", t_span, [initial] * 2, DISK.parameters, **options)
    assert said in str(caught.value)


def test_simulate_names_a_time_limit_that_is_not_a_number() -> None:
    """On main 1300154: a bare ``TypeError: '>' not supported between instances of 'str' and 'int'``."""
    with pytest.raises(InputError, match=r"time_limit = 'abc': give a positive number of seconds, or None"):
        numeric_simulate.simulate(
            DISK.constructor(), "voronets", 0.01, DISK.initial, DISK.parameters, time_limit="abc"
        )


def test_a_run_that_crawls_near_a_pole_and_stops_there_is_not_refused(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Review of issue 28: ``chaplygin report`` of a sleigh on an incline (t = 3, past the pole of
    its solved constraint at θ = π/2) was refused as '249 days' from Lindelöf's run crawling
    towards the pole 0.5 s in; run anyway it ends in 4 s, stopped at the pole.  One slow stretch
    does not refuse a run: a second estimate, four times as late, must agree."""
    clock = [0.0]
    monkeypatch.setattr(numeric_simulate.time, "monotonic", lambda: clock[0])
    refusal = lambda left, pace: f"too long: {left} ({pace})"  # noqa: E731
    told = numeric_simulate.pace_check(3.0, 3600.0, refusal, "ask for a shorter time")
    for now, done in ((0.0, 1.858), (0.6, 1.8580001)):  # crawling: beyond the limit at first
        clock[0] = now
        told(done)
    for now, done in ((2.1, 2.5), (3.0, 3.0)):  # then on at a pace within it
        clock[0] = now
        told(done)
    slow = numeric_simulate.pace_check(3.0, 3600.0, refusal, "ask for a shorter time")
    for now, done in ((0.0, 0.0), (0.6, 1e-6)):
        clock[0] = now
        slow(done)
    clock[0] = 2.1
    with pytest.raises(InputError, match="too long"):
        slow(2e-6)  # still crawling: refused
