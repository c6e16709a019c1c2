"""Sweeps (``chaplygin.apps.sweep``, ``chaplygin sweep``): the grid, a 2-worker Dask LocalCluster against a
serial run, a worker killed mid-sweep, failed runs kept as rows, resume after an interruption, and
where the runs go (this process for small sweeps, a cluster for long ones or when asked)."""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

pa = pytest.importorskip("pyarrow")
pq = pytest.importorskip("pyarrow.parquet")
distributed = pytest.importorskip("distributed")
dask = pytest.importorskip("dask")

import cloudpickle

from chaplygin.apps.cli import app
from chaplygin.apps.sweep import (
    SCHEMA,
    SweepOutputExists,
    parse_grid,
    read_results,
    sweep,
)
from chaplygin.errors import ChaplyginError

runner = CliRunner()
DISK = "example:vertical-rolling-disk"
# J = 0 makes the mass matrix singular: those runs fail from the start
DISK_GRID = {"theta'": "0.5:1.5:3", "J": "0:0.5:3"}
FAST = {"backend": "numpy", "samples": 21}


@pytest.fixture(scope="module")
def client():
    """Two worker processes (one thread each), shared by the tests of this module."""
    cluster = distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        silence_logs=logging.CRITICAL,
    )
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


def same_rows(a: pa.Table, b: pa.Table, ignore: tuple[str, ...] = ("wall_time",), rtol: float = 0.0) -> None:
    """Equal tables, column by column, NaN equal to NaN; ``wall_time`` differs between runs."""
    assert a.column_names == b.column_names
    for name in a.column_names:
        if name in ignore:
            continue
        x, y = a.column(name).to_numpy(zero_copy_only=False), b.column(name).to_numpy(zero_copy_only=False)
        if x.dtype.kind == "f":
            assert np.allclose(x, y, rtol=rtol, atol=0.0, equal_nan=True), name
        else:
            assert list(x) == list(y), name


def statuses(table: pa.Table) -> list[str]:
    return table.column("status").to_pylist()


# ---------------------------------------------------------------- the grid
@pytest.mark.parametrize(
    "text, name, values",
    [
        ("theta=0.1:0.5:5", "theta", [0.1, 0.2, 0.3, 0.4, 0.5]),
        ("phi'=-1:1:3", "phi'", [-1.0, 0.0, 1.0]),
        ("m=1,2,4", "m", [1.0, 2.0, 4.0]),
        (" J = 0.5 ", "J", [0.5]),
        ("R=2:2:1", "R", [2.0]),
    ],
)
def test_grid_syntax(text: str, name: str, values: list[float]) -> None:
    got_name, got = parse_grid(text)
    assert got_name == name and np.allclose(got, values)


@pytest.mark.parametrize(
    "text, why",
    [
        ("theta", "expected NAME=START:STOP:COUNT"),
        ("=1:2:3", "expected NAME=START:STOP:COUNT"),
        ("theta=0.1:0.5", "expected NAME=START:STOP:COUNT"),
        ("theta=a:1:3", "START and STOP must be numbers"),
        ("theta=0:1:2.5", "COUNT must be a positive integer"),
        ("theta=0:1:0", "COUNT must be a positive integer"),
        ("theta=0:1:1", "START = STOP"),
        ("m=1,x", "expected NAME=START:STOP:COUNT"),
        ("m=1,1", "repeated values"),
        ("m=nan,1", "finite"),
    ],
)
def test_grid_syntax_errors(text: str, why: str) -> None:
    with pytest.raises(ChaplyginError, match=why):
        parse_grid(text)


def test_grid_names_are_checked(tmp_path: Path) -> None:
    def error(grid, **kw):
        with pytest.raises(ChaplyginError) as info:
            sweep(
                "example:knife-edge", grid, t_end=1, out=tmp_path / "r", scheduler="serial", **{**FAST, **kw}
            )
        return str(info.value)

    assert "sweep one of: parameters J, m; coordinates x, y, phi; independent velocities x', phi'" in error(
        {"z": "0:1:2"}
    )
    assert "follows from the constraints" in error({"y'": "0:1:2"})
    assert "also given a fixed value" in error({"m": "1:2:2"}, parameters={"m": 3})
    assert "sweeps run on 'auto', 'numpy', 'numba', 'c'" in error({"m": "1:2:2"}, backend="jax")
    assert not (tmp_path / "r").exists()  # nothing written for a refused sweep


def test_imports_without_the_extra(tmp_path: Path) -> None:
    """chaplygin (and its CLI) import without dask and pyarrow; a sweep names the extra it needs."""
    code = (
        "import sys\n"
        "for m in ('dask', 'distributed', 'pyarrow', 'pyarrow.parquet'): sys.modules[m] = None\n"
        "import chaplygin, chaplygin.apps.cli, chaplygin.apps.sweep\n"
        "from chaplygin.apps.sweep import sweep\n"
        "try:\n"
        f"    sweep('example:knife-edge', {{'m': '1:2:2'}}, t_end=1, out={str(tmp_path / 'r')!r})\n"
        "except chaplygin.ChaplyginError as exc:\n"
        "    print(exc)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False
    )
    assert done.returncode == 0, done.stderr
    assert "pip install 'chaplygin[sweep]'" in done.stdout and "pyarrow" in done.stdout


# ---------------------------------------------------------------- Dask against serial
def test_two_workers_equal_a_serial_run(client, tmp_path: Path) -> None:
    parallel = sweep(DISK, DISK_GRID, t_end=2.0, out=tmp_path / "dask.parquet", scheduler=client, **FAST)
    serial = sweep(DISK, DISK_GRID, t_end=2.0, out=tmp_path / "serial.parquet", scheduler="serial", **FAST)
    assert (parallel.runs, parallel.ran, parallel.resumed, parallel.failed) == (9, 9, 0, 3)
    a, b = parallel.table(), serial.table()
    same_rows(a, b)
    # one row per grid point, in C order (the last axis fastest); the grid's values in every row
    assert a.column("run_id").to_pylist() == list(range(9))
    assert a.column("grid.theta'").to_pylist() == [0.5] * 3 + [1.0] * 3 + [1.5] * 3
    assert a.column("grid.J").to_pylist() == [0.0, 0.25, 0.5] * 3
    assert a.column("param.J").to_pylist() == a.column("grid.J").to_pylist()
    assert a.column("initial.theta'").to_pylist() == a.column("grid.theta'").to_pylist()
    assert set(a.column("param.m").to_pylist()) == {1.0}  # the example's other values
    assert statuses(a) == ["failed", "success", "success"] * 3
    ok = [i for i in range(9) if i % 3]
    drift = a.column("energy_drift").to_numpy()
    assert np.all(drift[ok] < 1e-9) and np.all(a.column("max_constraint_residual").to_numpy()[ok] < 1e-9)
    assert np.allclose(a.column("t_reached").to_numpy()[ok], 2.0)
    # the true motion of the vertical disk: the spin rate stays, the heading turns uniformly
    assert np.allclose(a.column("final.theta'").to_numpy()[ok], a.column("grid.theta'").to_numpy()[ok])
    assert np.allclose(a.column("final.phi").to_numpy()[ok], 0.2 * 2.0)
    # one Parquet file when finished; pyarrow reads the directory as it is
    files = sorted(p.name for p in parallel.path.iterdir())
    assert files == ["_sweep.json", "_sweep.lock", "part-000001.parquet"] or [
        f for f in files if f.startswith("part-")
    ] == [files[-1]]
    raw = pq.read_table(parallel.path)
    assert raw.num_rows == 9
    assert SCHEMA in raw.schema.metadata[b"chaplygin.apps.sweep"].decode()


def test_failed_runs_are_rows(client, tmp_path: Path) -> None:
    """A run that stops (Lindelöf's knife edge reaches its pole) or raises (J = 0) is a row with its message."""
    grid = {"x'": "0.1,1.0", "J": "0,1"}
    result = sweep(
        "example:knife-edge", grid, model="lindelof", t_end=10.0, out=tmp_path / "r", scheduler=client, **FAST
    )
    table = result.table().to_pylist()
    assert len(table) == 4 and result.failed == 3
    by_point = {(r["grid.x'"], r["grid.J"]): r for r in table}
    fine = by_point[(0.1, 1.0)]
    assert fine["status"] == "success" and fine["message"] == "" and fine["t_reached"] == 10.0
    stopped = by_point[(1.0, 1.0)]
    # stopped at the sample before the pole, or by the integrator at it (which comes first depends on the steps)
    assert stopped["status"] == "failed" and (
        "pole" in stopped["message"] or "step size" in stopped["message"]
    )
    assert 5.0 <= stopped["t_reached"] < 10.0 and np.isfinite(stopped["final.phi"])  # the state it reached
    for x in (0.1, 1.0):
        singular = by_point[(x, 0.0)]
        assert singular["status"] == "failed" and singular["message"]
        assert singular["param.J"] == 0.0


def test_a_killed_worker_loses_nothing(client, tmp_path: Path) -> None:
    """SIGKILL a worker process while it runs tasks: Dask reruns them elsewhere; every run is there once."""
    grid = {"theta'": "0.5:1.5:4", "phi'": "0.1:0.4:4"}
    pids = client.run(os.getpid)
    killed: dict[str, list[str]] = {}

    def kill_one(done: int, total: int) -> None:
        if done >= 3 and not killed:
            processing = client.processing()
            address = max(processing, key=lambda a: len(processing[a]))
            killed[address] = list(processing[address])
            os.kill(pids[address], signal.SIGKILL)

    result = sweep(
        DISK,
        grid,
        t_end=100.0,
        out=tmp_path / "dask",
        scheduler=client,
        chunk_size=1,
        progress=kill_one,
        **FAST,
    )
    assert killed and next(iter(killed.values())), "the worker was killed with tasks on it"
    table = result.table()
    assert table.column("run_id").to_pylist() == list(range(16))
    assert statuses(table) == ["success"] * 16 and result.failed == 0
    serial = sweep(DISK, grid, t_end=100.0, out=tmp_path / "serial", scheduler="serial", **FAST)
    same_rows(table, serial.table())
    client.wait_for_workers(2, timeout=120)  # the nanny restarts it, for the tests after this one
    assert pids[next(iter(killed))] not in client.run(os.getpid).values()


class CrashOnRun(distributed.WorkerPlugin):
    """In every worker process, restarted ones too: the run ``run_id`` kills its process at once."""

    name = "chaplygin-test-crash"

    def __init__(self, run_id: int) -> None:
        self.run_id = run_id

    def setup(self, worker) -> None:
        import chaplygin.apps.sweep as module

        self.original = original = module._run_one
        crash_on = self.run_id

        def run_one(system, plan, run_id):
            if run_id == crash_on:
                os._exit(13)
            return original(system, plan, run_id)

        module._run_one = run_one

    def teardown(self, worker) -> None:
        import chaplygin.apps.sweep as module

        module._run_one = self.original


def test_a_run_that_kills_its_workers_is_a_failed_row(client, tmp_path: Path) -> None:
    """A run whose process dies every time (``KilledWorker``) is found in its chunk and recorded failed."""
    cloudpickle.register_pickle_by_value(sys.modules[__name__])  # the plugin travels by value
    scheduler = client.cluster.scheduler
    allowed = scheduler.allowed_failures
    scheduler.allowed_failures = 0  # KilledWorker at the first death (Dask's default: after 4)
    client.register_plugin(CrashOnRun(1))
    try:
        result = sweep(
            DISK,
            {"theta'": "0.5:1.5:3"},
            t_end=1.0,
            out=tmp_path / "r",
            scheduler=client,
            chunk_size=3,
            **FAST,
        )
    finally:
        scheduler.allowed_failures = allowed
        client.unregister_worker_plugin(CrashOnRun.name)
        cloudpickle.unregister_pickle_by_value(sys.modules[__name__])
        client.wait_for_workers(2, timeout=120)
    table = result.table().to_pylist()
    assert [r["status"] for r in table] == ["success", "failed", "success"] and result.failed == 1
    assert "the worker processes running it died (KilledWorker" in table[1]["message"]
    assert table[1]["grid.theta'"] == 1.0 and np.isnan(table[1]["final.theta"])


# ---------------------------------------------------------------- resume
def test_resume_runs_only_the_missing_runs(client, tmp_path: Path) -> None:
    out = tmp_path / "results.parquet"
    grid = {"theta'": "0.5:1.5:3", "phi'": "0.1:0.3:3"}

    def stop_after_four(done: int, total: int) -> None:
        if done == 4:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        sweep(
            DISK,
            grid,
            t_end=2.0,
            out=out,
            scheduler="serial",
            flush_seconds=0.0,
            progress=stop_after_four,
            **FAST,
        )
    before = read_results(out)
    assert before.column("run_id").to_pylist() == [0, 1, 2, 3]  # nothing finished was lost
    (out / ".part-000009.parquet.abc.tmp").write_bytes(b"a write cut short")  # a crash mid-write

    again = sweep(DISK, grid, t_end=2.0, out=tmp_path / "other", scheduler="serial", **FAST)
    with pytest.raises(SweepOutputExists, match="pass resume=True to finish it or force=True"):
        sweep(DISK, grid, t_end=2.0, out=out, scheduler="serial", **FAST)
    with pytest.raises(SweepOutputExists, match="holds a different sweep .*t_end 2.0 there, 3.0 now"):
        sweep(DISK, grid, t_end=3.0, out=out, scheduler="serial", resume=True, **FAST)

    args = [
        "sweep",
        DISK,
        "--grid",
        "theta'=0.5:1.5:3",
        "--grid",
        "phi'=0.1:0.3:3",
        "-t",
        "2",
        "-o",
        str(out),
        "-b",
        "numpy",
        "-n",
        "21",
        "--scheduler",
        client.scheduler.address,
        "--resume",
    ]
    done = runner.invoke(app, args)
    assert done.exit_code == 0, done.output
    assert "9 runs: 5 run now, 4 already there; 0 failed" in done.stdout
    after = read_results(out)
    same_rows(after, again.table())
    same_rows(after.slice(0, 4), before, ignore=())  # the first four were not run again
    assert not list(out.glob(".*.tmp")) and len(list(out.glob("part-*.parquet"))) == 1
    # resuming a finished sweep runs nothing
    assert "0 run now, 9 already there" in runner.invoke(app, args).stdout


def test_rows_never_wait_for_the_next_run(tmp_path: Path) -> None:
    """A finished row is written within flush_seconds even when no other run finishes."""
    from chaplygin.apps.sweep import _Writer

    schema = pa.schema([("run_id", pa.int64()), ("status", pa.string())])
    writer = _Writer(tmp_path, schema, flush_seconds=1.0, next_part=0)  # ≫ a busy machine's stall
    try:
        writer.add([{"run_id": 3, "status": "success"}])
        assert not list(tmp_path.glob("part-*"))  # not yet: it waits for company
        for _ in range(600):
            if list(tmp_path.glob("part-*.parquet")):
                break
            threading.Event().wait(0.05)
        assert pq.read_table(tmp_path / "part-000000.parquet").to_pylist() == [
            {"run_id": 3, "status": "success"}
        ]
        writer.add([{"run_id": 1, "status": "failed"}])
    finally:
        writer.close()
    assert len(list(tmp_path.glob("part-*.parquet"))) == 2 and writer.written == 2 and writer.failed == 1


# ---------------------------------------------------------------- the command line
def test_command_line(client, tmp_path: Path) -> None:
    out = tmp_path / "r.parquet"
    args = [
        "sweep",
        "example:knife-edge",
        "--grid",
        "x'=0.5,1",
        "--grid",
        "m=1:2:2",
        "--model",
        "chaplygin",
        "-t",
        "1",
        "-o",
        str(out),
        "-b",
        "numpy",
        "-n",
        "11",
        "--scheduler",
        client.scheduler.address,
    ]
    done = runner.invoke(app, args)
    assert done.exit_code == 0, done.output
    assert done.stdout.startswith("chaplygin [numpy], t = 0 … 1: 4 runs: 4 run now; 0 failed;")
    assert f" s on the Dask cluster at {client.scheduler.address} (" in done.stdout  # (N worker processes)
    table = read_results(out)
    assert table.column("grid.x'").to_pylist() == [0.5, 0.5, 1.0, 1.0]
    assert table.column("grid.m").to_pylist() == [1.0, 2.0, 1.0, 2.0]

    refused = runner.invoke(app, args)
    assert refused.exit_code == 1 and "pass --resume to finish it or --force" in refused.stderr
    assert runner.invoke(app, [*args, "--force"]).exit_code == 0
    both = runner.invoke(app, [*args, "--force", "--resume"])
    assert both.exit_code == 2

    bad = runner.invoke(app, ["sweep", "example:knife-edge", "--grid", "x'=0.5:1", "-t", "1", "-o", str(out)])
    assert bad.exit_code == 2 and "--grid" in bad.output and "NAME=START:STOP:COUNT" in bad.output
    unknown = runner.invoke(
        app,
        [
            "sweep",
            "example:knife-edge",
            "--grid",
            "k=0:1:2",
            "-t",
            "1",
            "-o",
            str(tmp_path / "x"),
            "--scheduler",
            "serial",
        ],
    )
    assert unknown.exit_code == 1 and "sweep one of: parameters J, m" in unknown.stderr
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        nowhere = runner.invoke(
            app,
            [
                "sweep",
                "example:knife-edge",
                "--grid",
                "m=1,2",
                "-t",
                "1",
                "-o",
                str(tmp_path / "y"),
                "--scheduler",
                "tcp://127.0.0.1:9",
            ],
        )
    assert nowhere.exit_code == 1 and "cannot reach a Dask scheduler" in nowhere.stderr
    failing = runner.invoke(
        app,
        [
            "sweep",
            "example:knife-edge",
            "--model",
            "lindelof",
            "--grid",
            "x'=0.1,1",
            "-t",
            "10",
            "-o",
            str(tmp_path / "z"),
            "-b",
            "numpy",
            "-n",
            "11",
            "--scheduler",
            "serial",
        ],
    )
    assert failing.exit_code == 3 and "1 failed" in failing.stdout  # written, a run stopped early
    # run 1 meets the pole of y' = tan(phi) x' between t = 5 and 6: whether its steps then end in
    # an underflow after the sample at t = 6 or pass it is round-off (the DOP853 ports differ)
    assert any(
        f"run 1: {why}" in failing.stderr
        for why in ("the integrator stopped", "a pole of the solved constraints between t = 5 and 6")
    ), failing.stderr
    for result in (done, refused, bad, unknown, nowhere, failing):
        assert "Traceback" not in result.output


def test_a_local_cluster_when_asked(tmp_path: Path) -> None:
    """scheduler="local": a LocalCluster of its own, closed at the end, named in the summary."""
    result = sweep(
        "example:knife-edge",
        {"m": "1,2"},
        model="chaplygin",
        t_end=1.0,
        out=tmp_path / "r",
        scheduler="local",
        workers=1,
        **FAST,
    )
    assert result.ran == 2 and statuses(result.table()) == ["success", "success"]
    assert result.where == "on a LocalCluster of 1 worker process"
    assert " s on a LocalCluster of 1 worker process -> " in result.summary()


# ---------------------------------------------------------------- where the runs go
def no_cluster(*args, **kwargs):
    pytest.fail("started or reached a Dask cluster")


def test_small_grids_run_in_this_process_by_default(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("chaplygin.apps.sweep._client", no_cluster)
    result = sweep(DISK, DISK_GRID, t_end=2.0, out=tmp_path / "auto.parquet", **FAST)
    assert result.where == "in this process" and result.ran == 9
    serial = sweep(DISK, DISK_GRID, t_end=2.0, out=tmp_path / "serial.parquet", scheduler="serial", **FAST)
    same_rows(result.table(), serial.table())
    args = [
        "sweep",
        "example:knife-edge",
        "--grid",
        "x'=0.5,1",
        "--model",
        "chaplygin",
        "-t",
        "1",
        "-o",
        str(tmp_path / "cli.parquet"),
        "-b",
        "numpy",
        "-n",
        "11",
    ]
    done = runner.invoke(app, args)
    assert done.exit_code == 0, done.output
    assert done.stdout.startswith("chaplygin [numpy], t = 0 … 1: 2 runs: 2 run now; 0 failed; ")
    assert " s in this process -> " in done.stdout
    again = runner.invoke(app, [*args, "--resume"])  # nothing to run: nowhere to say
    assert again.exit_code == 0 and "0 run now, 2 already there; 0 failed; " in again.stdout
    assert "in this process" not in again.stdout


@pytest.mark.parametrize("given", ["example", "object"])
def test_long_runs_move_to_a_local_cluster(
    given: str, client, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """With no scheduler, runs measured to take long hand the rest to a LocalCluster (here the
    module's cluster stands in for it), a System object included; the rows are a serial sweep's."""
    import chaplygin.apps.sweep as module
    from chaplygin import examples
    from chaplygin.io.files import SystemFile

    asked: list = []

    def local_cluster(scheduler, workers):
        asked.append((scheduler, workers))
        return client, []

    monkeypatch.setattr(module, "AUTO_CLUSTER_SECONDS", 0.0)  # any measured run is long
    monkeypatch.setattr(module, "_cores", lambda: 4)
    monkeypatch.setattr(module, "_client", local_cluster)
    grid = {"theta'": "0.5:1.5:3", "phi'": "0.1:0.2:2"}
    entry = examples.get("vertical-rolling-disk")
    system = (
        DISK
        if given == "example"
        else SystemFile(entry.constructor(), dict(entry.parameters), dict(entry.initial), "disk", "disk")
    )
    result = sweep(system, grid, t_end=2.0, out=tmp_path / "auto.parquet", **FAST)
    assert asked == [(None, None)]
    assert result.where.startswith("2 in this process, then 4 on the Dask cluster at ")
    assert result.ran == 6 and result.table().column("run_id").to_pylist() == list(range(6))
    serial = sweep(DISK, grid, t_end=2.0, out=tmp_path / "serial.parquet", scheduler="serial", **FAST)
    # a System object is derived anew in each worker process from its pickle: the same equations,
    # possibly with terms in another order, so the last digits may differ
    same_rows(result.table(), serial.table(), rtol=0.0 if given == "example" else 1e-12)


def test_a_machine_of_one_core_never_starts_a_cluster(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import chaplygin.apps.sweep as module

    monkeypatch.setattr(module, "AUTO_CLUSTER_SECONDS", 0.0)
    monkeypatch.setattr(module, "_cores", lambda: 1)
    monkeypatch.setattr(module, "_client", no_cluster)
    result = sweep(DISK, {"theta'": "0.5:1.5:4"}, t_end=1.0, out=tmp_path / "r", **FAST)
    assert result.where == "in this process" and result.ran == 4
